within TMDInerter;
package PendulumTMD "A base oscillator with a pendulum TMD (a mass on a massless rod, pivot damper)"
  extends TMDInerter.Icons.Package;

  model BaseWithPendulum "(M + m) xdd + m L (thdd cos th - thd^2 sin th) + C xd + K x = F cos(w t), m L^2 thdd + m L xdd cos th + c_p thd + m g L sin th = 0"
    // <generated params pendulum_tmd>
    // </generated>
    parameter TMDInerter.Units.AngularFrequency w = TMDInerter.Defaults.w "w: excitation angular frequency (rad/s)";
    constant TMDInerter.Units.Acceleration g = 9.81 "Acceleration of gravity";
    // the positions first, then the velocities (rumoca solves the two coupled accelerations as one
    // block, and wants their states side by side)
    TMDInerter.Units.Position x(start = 0, fixed = true) "Main mass position";
    TMDInerter.Units.Angle th(start = 0, fixed = true) "Pendulum angle from the hanging position";
    TMDInerter.Units.Velocity xd(start = 0, fixed = true) "Main mass velocity";
    TMDInerter.Units.AngularVelocity thd(start = 0, fixed = true) "Pendulum angular velocity";
  equation
    der(x) = xd;
    der(th) = thd;
    (M + m) * der(xd) + m * L * (der(thd) * cos(th) - thd ^ 2 * sin(th)) + C * xd + K * x = F * cos(w * time);
    m * L ^ 2 * der(thd) + m * L * der(xd) * cos(th) + c_p * thd + m * g * L * sin(th) = 0;
  end BaseWithPendulum;
end PendulumTMD;
