within TMDInerter;
package LinearTMD "A base oscillator with a plain linear TMD (mass, spring, viscous damper; no inerter)"
  extends TMDInerter.Icons.Package;

  model BaseWithTMD "M xdd = F cos(w t) - K x - C xd + k (y - x) + c (yd - xd), m ydd = -k (y - x) - c (yd - xd)"
    // <generated params linear_tmd>
    // </generated>
    parameter TMDInerter.Units.AngularFrequency w = TMDInerter.Defaults.w "w: excitation angular frequency (rad/s)";
    TMDInerter.Components.Mass main(m = M) "The main mass";
    TMDInerter.Components.Spring spring(k = K);
    TMDInerter.Components.Damper damper(c = C);
    TMDInerter.Components.Fixed support;
    TMDInerter.Components.HarmonicForce excitation(F = F, w = w);
    TMDInerter.Components.Mass absorber(m = m) "The TMD mass";
    TMDInerter.Components.Spring absorber_spring(k = k);
    TMDInerter.Components.Damper absorber_damper(c = c);
    TMDInerter.Units.Position x "Main mass position";
    TMDInerter.Units.Velocity xd "Main mass velocity";
    TMDInerter.Units.Position y "TMD position";
    TMDInerter.Units.Velocity yd "TMD velocity";
  equation
    connect(main.flange, spring.flange_a);
    connect(spring.flange_b, support.flange);
    connect(main.flange, damper.flange_a);
    connect(damper.flange_b, support.flange);
    connect(excitation.flange, main.flange);
    connect(main.flange, absorber_spring.flange_a);
    connect(absorber_spring.flange_b, absorber.flange);
    connect(main.flange, absorber_damper.flange_a);
    connect(absorber_damper.flange_b, absorber.flange);
    x = main.s;
    xd = main.v;
    y = absorber.s;
    yd = absorber.v;
  end BaseWithTMD;
end LinearTMD;
