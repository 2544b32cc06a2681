within TMDInerter;
package Interfaces "Connector and partial link"
  extends TMDInerter.Icons.Package;

  connector Flange "1-D translational flange: position, velocity and acceleration, cut force"
    TMDInerter.Units.Position s "Absolute position";
    TMDInerter.Units.Velocity v "Absolute velocity";
    TMDInerter.Units.Acceleration a "Absolute acceleration";
    flow TMDInerter.Units.Force f "Cut force, positive when it acts on the component";
    annotation(Documentation(info = "<html><p>Velocity and acceleration travel with the
position so that links need no differentiation of connector variables (no index reduction
is needed by any tool). The mass that owns a node sets all three.</p></html>"));
  end Flange;

  partial model PartialLink "Link between the base (flange_a) and the TMD (flange_b)"
    TMDInerter.Interfaces.Flange flange_a "Base side";
    TMDInerter.Interfaces.Flange flange_b "TMD side";
    TMDInerter.Units.Force f "Link force: on the TMD side in +s, on the base side in -s";
    TMDInerter.Units.Position s_rel "flange_a.s - flange_b.s (x - y)";
    TMDInerter.Units.Velocity v_rel "flange_a.v - flange_b.v (xd - yd)";
    TMDInerter.Units.Acceleration a_rel "flange_a.a - flange_b.a (xdd - ydd)";
  equation
    s_rel = flange_a.s - flange_b.s;
    v_rel = flange_a.v - flange_b.v;
    a_rel = flange_a.a - flange_b.a;
    flange_a.f = f;
    flange_b.f = -f;
  end PartialLink;
end Interfaces;
