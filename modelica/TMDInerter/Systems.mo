within TMDInerter;
package Systems "Base oscillator, TMD-inerter subsystems and the coupled systems"
  extends TMDInerter.Icons.Package;

  model BaseOscillator "M xdd + C xd + K x = F cos(w t) + (force of the links on flange)"
    parameter TMDInerter.Units.Mass M = TMDInerter.Defaults.M "Base mass";
    parameter TMDInerter.Units.TranslationalSpringConstant K = TMDInerter.Defaults.K "Base stiffness";
    parameter TMDInerter.Units.TranslationalDampingConstant C = TMDInerter.Defaults.C "Base damping";
    parameter TMDInerter.Units.Force F = TMDInerter.Defaults.F "Force amplitude";
    parameter TMDInerter.Units.AngularFrequency w = TMDInerter.Defaults.w "Excitation frequency (rad/s)";
    TMDInerter.Components.Mass mass(m = M);
    TMDInerter.Components.Spring spring(k = K);
    TMDInerter.Components.Damper damper(c = C);
    TMDInerter.Components.Fixed support;
    TMDInerter.Components.HarmonicForce excitation(F = F, w = w);
    TMDInerter.Interfaces.BodyFlange flange "Attachment point of the TMD (moves with the base mass)";
  equation
    connect(mass.flange, spring.flange_a);
    connect(spring.flange_b, support.flange);
    connect(mass.flange, damper.flange_a);
    connect(damper.flange_b, support.flange);
    connect(excitation.flange, mass.flange);
    connect(mass.flange, flange);
  end BaseOscillator;

  partial model PartialTMD "TMD mass m with spring, viscous damper and dry friction to the base"
    parameter TMDInerter.Units.Mass m = TMDInerter.Defaults.m "TMD mass";
    parameter TMDInerter.Units.TranslationalSpringConstant k = TMDInerter.Defaults.k "TMD stiffness";
    parameter TMDInerter.Units.TranslationalDampingConstant c = TMDInerter.Defaults.c "Viscous damping";
    parameter TMDInerter.Units.Force df = TMDInerter.Defaults.df "Dry friction amplitude";
    parameter TMDInerter.Units.InverseVelocity slope = TMDInerter.Defaults.slope "Friction regularisation slope";
    TMDInerter.Components.Mass mass(m = m);
    TMDInerter.Components.Spring spring(k = k);
    TMDInerter.Components.Damper damper(c = c);
    TMDInerter.Components.DryFriction friction(df = df, slope = slope);
    TMDInerter.Interfaces.LinkFlange flange_base "Connect to the base oscillator";
    TMDInerter.Units.Force f_base "Force of all the links on the base, acting in -x";
  equation
    connect(flange_base, spring.flange_a);
    connect(spring.flange_b, mass.flange);
    connect(flange_base, damper.flange_a);
    connect(damper.flange_b, mass.flange);
    connect(flange_base, friction.flange_a);
    connect(friction.flange_b, mass.flange);
    f_base = flange_base.f;
  end PartialTMD;

  model TMDNoInerter "Classical TMD (Iratio = 0)"
    extends PartialTMD;
  end TMDNoInerter;

  model TMDIdealInerter "TMD with an ideal inerter"
    extends PartialTMD;
    parameter TMDInerter.Units.Inertance I = TMDInerter.Defaults.I "Inertance";
    TMDInerter.Components.Inerter inerter(I = I);
  equation
    connect(flange_base, inerter.flange_a);
    connect(inerter.flange_b, mass.flange);
  end TMDIdealInerter;

  model TMDPlayInerter "TMD with an inerter with play in its gear"
    extends PartialTMD;
    parameter TMDInerter.Units.Inertance I = TMDInerter.Defaults.I "Inertance";
    parameter TMDInerter.Units.TranslationalSpringConstant ki = TMDInerter.Defaults.ki "Gear mesh stiffness";
    parameter TMDInerter.Units.TranslationalDampingConstant ci = TMDInerter.Defaults.ci "Gear mesh damping";
    parameter TMDInerter.Units.Position eps = TMDInerter.Defaults.eps "Half the backlash";
    TMDInerter.Components.InerterWithPlay inerter(I = I, ki = ki, ci = ci, eps = eps);
  equation
    connect(flange_base, inerter.flange_a);
    connect(inerter.flange_b, mass.flange);
  end TMDPlayInerter;

  partial model PartialCoupled "Base oscillator and TMD; x, xd, y, yd of the paper"
    parameter TMDInerter.Units.Mass M = TMDInerter.Defaults.M "Base mass";
    parameter TMDInerter.Units.TranslationalSpringConstant K = TMDInerter.Defaults.K "Base stiffness";
    parameter TMDInerter.Units.TranslationalDampingConstant C = TMDInerter.Defaults.C "Base damping";
    parameter TMDInerter.Units.Force F = TMDInerter.Defaults.F "Force amplitude";
    parameter TMDInerter.Units.AngularFrequency w = TMDInerter.Defaults.w "Excitation frequency (rad/s)";
    parameter TMDInerter.Units.Mass m = TMDInerter.Defaults.m "TMD mass";
    parameter TMDInerter.Units.TranslationalSpringConstant k = TMDInerter.Defaults.k "TMD stiffness";
    parameter TMDInerter.Units.TranslationalDampingConstant c = TMDInerter.Defaults.c "Viscous damping";
    parameter TMDInerter.Units.Force df = TMDInerter.Defaults.df "Dry friction amplitude";
    parameter TMDInerter.Units.InverseVelocity slope = TMDInerter.Defaults.slope "Friction regularisation slope";
    TMDInerter.Systems.BaseOscillator base(M = M, K = K, C = C, F = F, w = w);
    TMDInerter.Units.Position x "Base position";
    TMDInerter.Units.Velocity xd "Base velocity";
    TMDInerter.Units.Position y "TMD position";
    TMDInerter.Units.Velocity yd "TMD velocity";
  equation
    x = base.mass.s;
    xd = base.mass.v;
  end PartialCoupled;

  model CoupledNoInerter "Base + classical TMD"
    extends PartialCoupled;
    TMDInerter.Systems.TMDNoInerter tmd(m = m, k = k, c = c, df = df, slope = slope);
  equation
    connect(base.flange, tmd.flange_base);
    y = tmd.mass.s;
    yd = tmd.mass.v;
  end CoupledNoInerter;

  model CoupledIdealInerter "Base + TMD with an ideal inerter"
    extends PartialCoupled;
    parameter TMDInerter.Units.Inertance I = TMDInerter.Defaults.I "Inertance";
    TMDInerter.Systems.TMDIdealInerter tmd(m = m, k = k, c = c, df = df, slope = slope, I = I);
    TMDInerter.Units.Force P "Inerter force";
  equation
    connect(base.flange, tmd.flange_base);
    y = tmd.mass.s;
    yd = tmd.mass.v;
    P = tmd.inerter.f;
  end CoupledIdealInerter;

  model CoupledPlayInerter "Base + TMD with an inerter with play; d = r - y"
    extends PartialCoupled;
    parameter TMDInerter.Units.Inertance I = TMDInerter.Defaults.I "Inertance";
    parameter TMDInerter.Units.TranslationalSpringConstant ki = TMDInerter.Defaults.ki "Gear mesh stiffness";
    parameter TMDInerter.Units.TranslationalDampingConstant ci = TMDInerter.Defaults.ci "Gear mesh damping";
    parameter TMDInerter.Units.Position eps = TMDInerter.Defaults.eps "Half the backlash";
    TMDInerter.Systems.TMDPlayInerter tmd(m = m, k = k, c = c, df = df, slope = slope, I = I, ki = ki, ci = ci, eps = eps);
    TMDInerter.Units.Position d "r - y";
    TMDInerter.Units.Velocity dd "der(d)";
    TMDInerter.Units.Force P "Chain force";
  equation
    connect(base.flange, tmd.flange_base);
    y = tmd.mass.s;
    yd = tmd.mass.v;
    d = tmd.inerter.d;
    dd = tmd.inerter.dd;
    P = tmd.inerter.f;
  end CoupledPlayInerter;
end Systems;
