within TMDInerter;
package Systems "Base oscillator, TMD-inerter subsystems and the coupled systems"
  extends TMDInerter.Icons.Package;

  model BaseOscillator "M xdd + C xd + K x = F cos(w t) + (force of the links on flange)"
    // <generated params base>
    parameter TMDInerter.Units.Mass M = TMDInerter.Defaults.M "M: base mass";
    parameter TMDInerter.Units.TranslationalSpringConstant K = TMDInerter.Defaults.K "K: base stiffness";
    parameter TMDInerter.Units.TranslationalDampingConstant C = TMDInerter.Defaults.C "C: base viscous damping";
    parameter TMDInerter.Units.Force F = TMDInerter.Defaults.F "F: amplitude F of the excitation F cos(w t)";
    parameter TMDInerter.Units.AngularFrequency w = TMDInerter.Defaults.w "w: excitation angular frequency (the paper's 'Hz' are rad/s); passed to the solvers, not a field";
    // </generated>
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
    // <generated params tmd-all>
    parameter TMDInerter.Units.Mass m = TMDInerter.Defaults.m "m: TMD mass";
    parameter TMDInerter.Units.TranslationalSpringConstant k = TMDInerter.Defaults.k "k: linear stiffness of the TMD spring";
    parameter TMDInerter.Units.TranslationalDampingConstant c = TMDInerter.Defaults.c "c: viscous damping of the TMD link";
    parameter TMDInerter.Units.Force df = TMDInerter.Defaults.df "df: dry friction force amplitude, df (2/pi) atan(s (xd - yd))";
    parameter TMDInerter.Units.InverseVelocity slope = TMDInerter.Defaults.slope "s: regularisation slope of the friction law (1e6 in the paper)";
    parameter TMDInerter.Units.CubicSpringConstant k3 = TMDInerter.Defaults.k3 "k3: cubic term of the TMD spring, k3 (x - y)^3 (> 0 hardening, < 0 softening)";
    // </generated>
    TMDInerter.Components.Mass mass(m = m);
    TMDInerter.Components.Spring spring(k = k, k3 = k3);
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
    // <generated params tmd-ideal>
    parameter TMDInerter.Units.Inertance I = TMDInerter.Defaults.I "I: inertance of the inerter (0 without inerter)";
    // </generated>
    TMDInerter.Components.Inerter inerter(I = I);
  equation
    connect(flange_base, inerter.flange_a);
    connect(inerter.flange_b, mass.flange);
  end TMDIdealInerter;

  model TMDPlayInerter "TMD with an inerter with play in its gear"
    extends PartialTMD;
    // <generated params tmd-play>
    parameter TMDInerter.Units.Inertance I = TMDInerter.Defaults.I "I: inertance of the inerter (0 without inerter)";
    parameter TMDInerter.Units.TranslationalSpringConstant ki = TMDInerter.Defaults.ki "ki: gear mesh stiffness of the play chain";
    parameter TMDInerter.Units.TranslationalDampingConstant ci = TMDInerter.Defaults.ci "ci: gear mesh damping of the play chain";
    parameter TMDInerter.Units.Position eps = TMDInerter.Defaults.eps "eps: half the backlash of the gear (free while |r - y| < eps)";
    // </generated>
    TMDInerter.Components.InerterWithPlay inerter(I = I, ki = ki, ci = ci, eps = eps);
  equation
    connect(flange_base, inerter.flange_a);
    connect(inerter.flange_b, mass.flange);
  end TMDPlayInerter;

  partial model PartialCoupled "Base oscillator and TMD; x, xd, y, yd of the paper"
    // <generated params base>
    parameter TMDInerter.Units.Mass M = TMDInerter.Defaults.M "M: base mass";
    parameter TMDInerter.Units.TranslationalSpringConstant K = TMDInerter.Defaults.K "K: base stiffness";
    parameter TMDInerter.Units.TranslationalDampingConstant C = TMDInerter.Defaults.C "C: base viscous damping";
    parameter TMDInerter.Units.Force F = TMDInerter.Defaults.F "F: amplitude F of the excitation F cos(w t)";
    parameter TMDInerter.Units.AngularFrequency w = TMDInerter.Defaults.w "w: excitation angular frequency (the paper's 'Hz' are rad/s); passed to the solvers, not a field";
    // </generated>
    // <generated params tmd-all>
    parameter TMDInerter.Units.Mass m = TMDInerter.Defaults.m "m: TMD mass";
    parameter TMDInerter.Units.TranslationalSpringConstant k = TMDInerter.Defaults.k "k: linear stiffness of the TMD spring";
    parameter TMDInerter.Units.TranslationalDampingConstant c = TMDInerter.Defaults.c "c: viscous damping of the TMD link";
    parameter TMDInerter.Units.Force df = TMDInerter.Defaults.df "df: dry friction force amplitude, df (2/pi) atan(s (xd - yd))";
    parameter TMDInerter.Units.InverseVelocity slope = TMDInerter.Defaults.slope "s: regularisation slope of the friction law (1e6 in the paper)";
    parameter TMDInerter.Units.CubicSpringConstant k3 = TMDInerter.Defaults.k3 "k3: cubic term of the TMD spring, k3 (x - y)^3 (> 0 hardening, < 0 softening)";
    // </generated>
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
    // <generated instance none>
    TMDInerter.Systems.TMDNoInerter tmd(m = m, k = k, c = c, df = df, slope = slope, k3 = k3);
    // </generated>
  equation
    connect(base.flange, tmd.flange_base);
    y = tmd.mass.s;
    yd = tmd.mass.v;
  end CoupledNoInerter;

  model CoupledIdealInerter "Base + TMD with an ideal inerter"
    extends PartialCoupled;
    // <generated params tmd-ideal>
    parameter TMDInerter.Units.Inertance I = TMDInerter.Defaults.I "I: inertance of the inerter (0 without inerter)";
    // </generated>
    // <generated instance ideal>
    TMDInerter.Systems.TMDIdealInerter tmd(m = m, k = k, c = c, df = df, slope = slope, I = I, k3 = k3);
    // </generated>
    TMDInerter.Units.Force P "Inerter force";
  equation
    connect(base.flange, tmd.flange_base);
    y = tmd.mass.s;
    yd = tmd.mass.v;
    P = tmd.inerter.f;
  end CoupledIdealInerter;

  model CoupledPlayInerter "Base + TMD with an inerter with play; d = r - y"
    extends PartialCoupled;
    // <generated params tmd-play>
    parameter TMDInerter.Units.Inertance I = TMDInerter.Defaults.I "I: inertance of the inerter (0 without inerter)";
    parameter TMDInerter.Units.TranslationalSpringConstant ki = TMDInerter.Defaults.ki "ki: gear mesh stiffness of the play chain";
    parameter TMDInerter.Units.TranslationalDampingConstant ci = TMDInerter.Defaults.ci "ci: gear mesh damping of the play chain";
    parameter TMDInerter.Units.Position eps = TMDInerter.Defaults.eps "eps: half the backlash of the gear (free while |r - y| < eps)";
    // </generated>
    // <generated instance play>
    TMDInerter.Systems.TMDPlayInerter tmd(m = m, k = k, c = c, df = df, slope = slope, I = I, ki = ki, ci = ci, eps = eps, k3 = k3);
    // </generated>
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
