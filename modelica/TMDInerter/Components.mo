within TMDInerter;
package Components "Masses, links and sources"
  extends TMDInerter.Icons.Package;

  model Mass "Point mass: m der(v) = sum of the forces on its flange"
    parameter TMDInerter.Units.Mass m "Mass";
    TMDInerter.Units.Position s(start = 0, fixed = true) "Position";
    TMDInerter.Units.Velocity v(start = 0, fixed = true) "Velocity";
    TMDInerter.Units.Acceleration a "Acceleration";
    TMDInerter.Interfaces.BodyFlange flange;
  equation
    der(s) = v;
    der(v) = a;
    flange.s = s;
    flange.v = v;
    flange.a = a;
    m * a = flange.f;
  end Mass;

  model Fixed "Fixed point (the support)"
    TMDInerter.Interfaces.BodyFlange flange;
  equation
    flange.s = 0;
    flange.v = 0;
    flange.a = 0;
  end Fixed;

  model HarmonicForce "External force F cos(w t) on its flange, w in rad/s"
    parameter TMDInerter.Units.Force F "Amplitude";
    parameter TMDInerter.Units.AngularFrequency w "Excitation frequency (rad/s)";
    TMDInerter.Units.Force force "Applied force";
    TMDInerter.Interfaces.LinkFlange flange;
  equation
    force = F * cos(w * time);
    flange.f = -force;
  end HarmonicForce;

  model Spring "Spring with a cubic term: f = k (x - y) + k3 (x - y)^3"
    extends TMDInerter.Interfaces.PartialLink;
    parameter TMDInerter.Units.TranslationalSpringConstant k "Linear stiffness";
    parameter TMDInerter.Units.CubicSpringConstant k3 = 0 "Cubic stiffness (> 0 hardening)";
  equation
    f = k * s_rel + k3 * s_rel ^ 3;
  end Spring;

  model Damper "Viscous damper: f = c (xd - yd)"
    extends TMDInerter.Interfaces.PartialLink;
    parameter TMDInerter.Units.TranslationalDampingConstant c "Damping coefficient";
  equation
    f = c * v_rel;
  end Damper;

  model DryFriction "Regularised Coulomb friction: f = df (2/pi) atan(slope (xd - yd))"
    extends TMDInerter.Interfaces.PartialLink;
    parameter TMDInerter.Units.Force df "Friction force amplitude";
    parameter TMDInerter.Units.InverseVelocity slope "Regularisation slope (1e6 s/m in the paper)";
  equation
    f = df * (2 / TMDInerter.pi) * atan(slope * v_rel);
  end DryFriction;

  model Inerter "Ideal inerter: f = I (xdd - ydd)"
    extends TMDInerter.Interfaces.PartialLink;
    parameter TMDInerter.Units.Inertance I "Inertance";
  equation
    f = I * a_rel;
  end Inerter;

  model InerterWithPlay "Inerter with play in its gear (Scheibe & Smith 2009)"
    extends TMDInerter.Interfaces.PartialLink;
    parameter TMDInerter.Units.Inertance I "Inertance";
    parameter TMDInerter.Units.TranslationalSpringConstant ki "Gear mesh stiffness";
    parameter TMDInerter.Units.TranslationalDampingConstant ci "Gear mesh damping";
    parameter TMDInerter.Units.Position eps(min = 0) "Half the backlash (the gear is free while |d| < eps)";
    TMDInerter.Units.Position d(start = 0, fixed = true) "d = r - y, inerter node r relative to the TMD side";
    TMDInerter.Units.Velocity dd(start = 0, fixed = true) "der(d)";
    Real contact "Contact mode: +1 engaged in compression, -1 in extension, 0 free";
  equation
    der(d) = dd;
    // chain force: I (xdd - rdd) = ki (r - u) + ci (rd - ud), the gap node u massless
    f = if eps <= 0 then ki * d + ci * dd
        elseif d > eps then max(0, ki * (d - eps) + ci * dd)
        elseif d < -eps then min(0, ki * (d + eps) + ci * dd)
        else 0;
    // rdd = xdd - f / I  and  d = r - y
    der(dd) = a_rel - f / I;
    contact = if d > eps then 1 elseif d < -eps then -1 else 0;
    annotation(Documentation(info = "<html><p>Chain: base -[inerter I]- node r -[ki || ci]- node u
-[gap +-eps]- TMD. Engaged in compression (d &gt; eps): f = max(0, ki (d - eps) + ci der(d)); in
extension (d &lt; -eps): f = min(0, ki (d + eps) + ci der(d)); free otherwise (f = 0, the
flywheel coasts). The massless gap node u is set to r while free (exact to ~ci/ki = 5e-10 s).
With eps = 0 the chain is the linear inerter in series with a spring, f = ki d + ci der(d).</p></html>"));
  end InerterWithPlay;
end Components;
