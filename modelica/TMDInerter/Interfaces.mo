within TMDInerter;
package Interfaces "Connector and partial link"
  extends TMDInerter.Icons.Package;

  connector BodyFlange "Flange of the body that owns a node: it sets the node's motion"
    TMDInerter.Units.Position s "Absolute position";
    output TMDInerter.Units.Velocity v "Absolute velocity (set by the body)";
    output TMDInerter.Units.Acceleration a "Absolute acceleration (set by the body)";
    flow TMDInerter.Units.Force f "Cut force, positive when it acts on the component";
    annotation(Documentation(info = "<html><p>Velocity and acceleration travel with the
position as causal signals so that links need no differentiation of connector variables: no
tool has to do index reduction, and the connector is balanced (one potential variable s, one
flow variable f; v and a are outputs of the body that owns the node).</p></html>"));
  end BodyFlange;

  connector LinkFlange "Flange of a link: it reads the node's motion"
    TMDInerter.Units.Position s "Absolute position";
    input TMDInerter.Units.Velocity v "Absolute velocity (set by the body)";
    input TMDInerter.Units.Acceleration a "Absolute acceleration (set by the body)";
    flow TMDInerter.Units.Force f "Cut force, positive when it acts on the component";
  end LinkFlange;

  partial model PartialLink "Link between the base (flange_a) and the TMD (flange_b)"
    TMDInerter.Interfaces.LinkFlange flange_a "Base side";
    TMDInerter.Interfaces.LinkFlange flange_b "TMD side";
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
