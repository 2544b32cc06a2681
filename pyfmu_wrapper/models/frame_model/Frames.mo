within TMDInerter;
package Frames "Multi-storey shear frames with the paper's TMD-inerter on any storey (TMDI included)"
  extends TMDInerter.Icons.Package;

  model ShearFrame "n storeys: storey i joined to storey i-1 (storey 1 to the ground) by a spring and a viscous damper, F cos(w t) on one storey"
    parameter Integer n(min = 1, max = 20) = 1 "Number of storeys (1 = the lowest)";
    parameter TMDInerter.Units.Mass Ms[n] = fill(TMDInerter.Defaults.M, n) "M_i: storey masses";
    parameter TMDInerter.Units.TranslationalSpringConstant Ks[n] = fill(TMDInerter.Defaults.K, n) "K_i: inter-storey stiffnesses, storey i to i-1";
    parameter TMDInerter.Units.TranslationalDampingConstant Cs[n] = fill(TMDInerter.Defaults.C, n) "C_i: inter-storey viscous dampers, storey i to i-1";
    parameter TMDInerter.Units.Force F = TMDInerter.Defaults.F "F: amplitude of the excitation F cos(w t)";
    parameter TMDInerter.Units.AngularFrequency w = TMDInerter.Defaults.w "w: excitation angular frequency (rad/s)";
    parameter Integer force_storey(min = 1, max = n) = n "The storey the force acts on";
    TMDInerter.Components.Mass storey[n](m = Ms);
    TMDInerter.Components.Spring spring[n](k = Ks);
    TMDInerter.Components.Damper damper[n](c = Cs);
    TMDInerter.Components.Fixed support;
    TMDInerter.Components.HarmonicForce excitation(F = F, w = w);
    TMDInerter.Interfaces.BodyFlange flange[n] "Each storey's node (attach a TMD or an inerter here)";
    TMDInerter.Interfaces.BodyFlange flange_ground "The ground (an inerter's second terminal)";
  equation
    connect(storey[1].flange, spring[1].flange_a);
    connect(spring[1].flange_b, support.flange);
    connect(storey[1].flange, damper[1].flange_a);
    connect(damper[1].flange_b, support.flange);
    for i in 2:n loop
      connect(storey[i].flange, spring[i].flange_a);
      connect(spring[i].flange_b, storey[i - 1].flange);
      connect(storey[i].flange, damper[i].flange_a);
      connect(damper[i].flange_b, storey[i - 1].flange);
    end for;
    connect(excitation.flange, storey[force_storey].flange);
    for i in 1:n loop
      connect(storey[i].flange, flange[i]);
    end for;
    connect(support.flange, flange_ground);
  end ShearFrame;

  partial model PartialFrameTMD "Shear frame with the TMD mass on storey tmd_storey by its spring, viscous damper and dry friction; x[i], xd[i] of the storeys, y, yd of the TMD"
    parameter Integer n(min = 1, max = 20) = 1 "Number of storeys (1 = the lowest)";
    parameter TMDInerter.Units.Mass Ms[n] = fill(TMDInerter.Defaults.M, n) "M_i: storey masses";
    parameter TMDInerter.Units.TranslationalSpringConstant Ks[n] = fill(TMDInerter.Defaults.K, n) "K_i: inter-storey stiffnesses, storey i to i-1";
    parameter TMDInerter.Units.TranslationalDampingConstant Cs[n] = fill(TMDInerter.Defaults.C, n) "C_i: inter-storey viscous dampers, storey i to i-1";
    parameter TMDInerter.Units.Force F = TMDInerter.Defaults.F "F: amplitude of the excitation F cos(w t)";
    parameter TMDInerter.Units.AngularFrequency w = TMDInerter.Defaults.w "w: excitation angular frequency (rad/s)";
    parameter Integer force_storey(min = 1, max = n) = n "The storey the force acts on";
    parameter Integer tmd_storey(min = 1, max = n) = n "The storey the TMD hangs on";
    parameter Integer inerter_to(min = 0, max = n) = tmd_storey "The inerter's second terminal: a storey, or 0 for the ground (the TMDI)";
    // <generated params tmd-all>
    // </generated>
    TMDInerter.Frames.ShearFrame frame(n = n, Ms = Ms, Ks = Ks, Cs = Cs, F = F, w = w, force_storey = force_storey);
    TMDInerter.Components.Mass mass(m = m) "The TMD mass";
    TMDInerter.Components.Spring spring(k = k, k3 = k3);
    TMDInerter.Components.Damper damper(c = c);
    TMDInerter.Components.DryFriction friction(df = df, slope = slope);
    TMDInerter.Units.Position x[n] "Storey positions";
    TMDInerter.Units.Velocity xd[n] "Storey velocities";
    TMDInerter.Units.Position y "TMD position";
    TMDInerter.Units.Velocity yd "TMD velocity";
  equation
    connect(frame.flange[tmd_storey], spring.flange_a);
    connect(spring.flange_b, mass.flange);
    connect(frame.flange[tmd_storey], damper.flange_a);
    connect(damper.flange_b, mass.flange);
    connect(frame.flange[tmd_storey], friction.flange_a);
    connect(friction.flange_b, mass.flange);
    x = frame.storey.s;
    xd = frame.storey.v;
    y = mass.s;
    yd = mass.v;
  end PartialFrameTMD;

  model FrameNoInerter "Shear frame with a classical TMD (no inerter)"
    extends PartialFrameTMD;
  end FrameNoInerter;

  model FrameIdealInerter "Shear frame with the TMD and its ideal inerter from the TMD mass to storey inerter_to (the TMD's own storey: the TMD-inerter; another storey or the ground: the TMDI)"
    extends PartialFrameTMD;
    // <generated params tmd-ideal>
    // </generated>
    TMDInerter.Components.Inerter inerter(I = I);
    TMDInerter.Units.Force P "Inerter force";
  equation
    if inerter_to == 0 then
      connect(frame.flange_ground, inerter.flange_a);
    else
      connect(frame.flange[inerter_to], inerter.flange_a);
    end if;
    connect(inerter.flange_b, mass.flange);
    P = inerter.f;
  end FrameIdealInerter;

  model FramePlayInerter "Shear frame with the TMD and its inerter with play from the TMD mass to storey inerter_to (or the ground); d = r - y"
    extends PartialFrameTMD;
    // <generated params tmd-play>
    // </generated>
    TMDInerter.Components.InerterWithPlay inerter(I = I, ki = ki, ci = ci, eps = eps);
    TMDInerter.Units.Position d "r - y";
    TMDInerter.Units.Velocity dd "der(d)";
    TMDInerter.Units.Force P "Chain force";
  equation
    if inerter_to == 0 then
      connect(frame.flange_ground, inerter.flange_a);
    else
      connect(frame.flange[inerter_to], inerter.flange_a);
    end if;
    connect(inerter.flange_b, mass.flange);
    d = inerter.d;
    dd = inerter.dd;
    P = inerter.f;
  end FramePlayInerter;
end Frames;
