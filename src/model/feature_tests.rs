//! Tests of `[initial]`, time-scaled loads, driver and beam_nodes sensors and the section
//! sensor's `frame`: compilation, and their effect on the initial state, the assembly and
//! sensor sampling.

use super::*;
use crate::assembly::{Assembler, Coeffs};
use crate::joint::State;
use crate::math::*;
use crate::sensors;

fn compile(text: &str) -> Model {
    compile_str(text, "t.toml", &[]).unwrap_or_else(|e| panic!("{e}"))
}

fn fails(text: &str) -> ModelError {
    compile_str(text, "t.toml", &[]).expect_err("should not compile")
}

/// a straight free-free beam a → b along x (2 elements) and whatever `extra` adds
fn with_beam(extra: &str) -> String {
    format!(
        "[sections.s]\nEA = 1\nEIy = 1\nEIz = 1\nGJ = 1\nrhoA = 1\n\
         [[nodes]]\nname = \"a\"\nposition = [0, 0, 0]\n\
         [[nodes]]\nname = \"b\"\nposition = [2, 0, 0]\n\
         [[beams]]\nname = \"bm\"\nfrom = \"a\"\nto = \"b\"\nelements = 2\nsection = \"s\"\n{extra}"
    )
}

fn close(a: Vec3, b: Vec3, tol: f64) -> bool {
    norm(sub(a, b)) <= tol
}

fn dof_index(m: &Model, name: &str) -> usize {
    m.dofs
        .iter()
        .position(|d| d.name == name)
        .unwrap_or_else(|| panic!("no dof {name}"))
}

#[test]
fn initial_rotation_compiles_with_default_center() {
    let m = compile(&with_beam(
        "[parameters]\nw = 2\n[initial]\nangular_velocity = [0, 0, \"w\"]\n",
    ));
    assert_eq!(m.initial_rotation, Some(([0.0, 0.0, 2.0], [0.0; 3])));
    let m = compile(&with_beam(
        "[initial]\nangular_velocity = [1, 0, 0]\ncenter = [0, \"1+1\", 0]\n",
    ));
    assert_eq!(m.initial_rotation, Some(([1.0, 0.0, 0.0], [0.0, 2.0, 0.0])));
    assert_eq!(compile(&with_beam("")).initial_rotation, None);

    let e = fails(&with_beam("[initial]\ncenter = [0, 0, 0]\n"));
    assert_eq!(e.field.as_deref(), Some("initial.angular_velocity"), "{e}");
    let e = fails(&with_beam("[initial]\nangular_velocity = [0, 1]\n"));
    assert_eq!(e.field.as_deref(), Some("initial.angular_velocity"), "{e}");
    let e = fails(&with_beam(
        "[initial]\nangular_velocity = [0, 0, 1]\ncenter = [0, \"q\", 0]\n",
    ));
    assert_eq!(e.field.as_deref(), Some("initial.center[1]"), "{e}");
    let e = fails(&with_beam(
        "[initial]\nangular_velocity = [0, 0, 1]\nvelocity = [0, 0, 0]\n",
    ));
    assert_eq!(e.field.as_deref(), Some("initial.velocity"), "{e}");

    // a steady start: alone, and only on a model with a constant-speed hub
    let e = fails(&with_beam(
        "[initial]\nangular_velocity = [0, 0, 1]\nsteady = true\n",
    ));
    assert_eq!(e.field.as_deref(), Some("initial.angular_velocity"), "{e}");
    assert!(e.to_string().contains("not both"), "{e}");
    let e = fails(&with_beam("[initial]\nsteady = true\ncenter = [0, 0, 0]\n"));
    assert_eq!(e.field.as_deref(), Some("initial.center"), "{e}");
    let e = fails(&with_beam("[initial]\nsteady = true\n"));
    assert_eq!(e.field.as_deref(), Some("initial.steady"), "{e}");
    let e = fails(&with_beam("[initial]\nsteady = 1\n"));
    assert_eq!(e.field.as_deref(), Some("initial.steady"), "{e}");
    // `steady = false` is no start at all: the section then needs a rotation
    let e = fails(&with_beam("[initial]\nsteady = false\n"));
    assert_eq!(e.field.as_deref(), Some("initial.angular_velocity"), "{e}");
}

#[test]
fn initial_rotation_sets_free_rates_from_the_rigid_field() {
    let m = compile(&with_beam(
        "[initial]\nangular_velocity = [0, 0, 3]\ncenter = [1, 1, 0]\n\
         [[nodes]]\nname = \"p\"\nposition = [5, 0, 0]\n\
         [[nodes]]\nname = \"q\"\nposition = [5, 0, 1]\n\
         [[beams]]\nname = \"pq\"\nfrom = \"p\"\nto = \"q\"\nelements = 1\nsection = \"s\"\n\
         [[supports]]\nnode = \"p\"\ntype = \"pinned\"\n\
         [[bodies]]\nname = \"hub\"\nposition = [0, 4, 0]\nmass = 1\ninertia = [1, 1, 1]\n\
         [[bodies.dofs]]\ntype = \"translation\"\naxis = [1, 0, 0]\n\
         [[bodies.dofs]]\ntype = \"translation\"\naxis = [0, 1, 0]\ninitial = 1\n\
         [[bodies.dofs]]\ntype = \"translation\"\naxis = [0, 0, 1]\ninitial_rate = 0.5\n\
         [[bodies.dofs]]\ntype = \"rotation\"\naxis = [0, 0, 1]\n\
         [[bodies]]\nname = \"drv\"\nposition = [0, -4, 0]\nmass = 1\ninertia = [1, 1, 1]\n\
         [[bodies.dofs]]\ntype = \"translation\"\naxis = [1, 0, 0]\ndrive = \"0.25*t\"\n\
         [[bodies.dofs]]\ntype = \"free_rotation\"\n\
         [[bodies]]\nname = \"spun\"\nposition = [0, 0, 9]\nmass = 1\ninertia = [1, 1, 1]\n\
         [[bodies.dofs]]\ntype = \"free_rotation\"\ninitial_rate = [1, 0, 0]\n\
         [[joints]]\nname = \"flap\"\nnode = \"a\"\nbody = \"hub\"\ntype = \"hinge\"\naxis = [0, 1, 0]\n\
         [[joints]]\nname = \"flop\"\nnode = \"q\"\nbody = \"drv\"\ntype = \"hinge\"\naxis = [0, 1, 0]\ninitial_rate = 0.75\n",
    ));
    let omega = [0.0, 0.0, 3.0];
    let c = [1.0, 1.0, 0.0];
    let field = |x: Vec3| cross(omega, sub(x, c));
    let s = State::new(&m);
    let v = |name: &str| s.v[dof_index(&m, name)];

    // free node b (2, 0, 0) and interior node bm:1 (1, 0, 0)
    for node in ["b", "bm:1"] {
        let n = m.node_index(node).unwrap();
        let vel = field(m.x0[n]);
        assert_eq!(
            [
                v(&format!("{node}.x")),
                v(&format!("{node}.y")),
                v(&format!("{node}.z"))
            ],
            vel
        );
        assert_eq!(
            [
                v(&format!("{node}.rx")),
                v(&format!("{node}.ry")),
                v(&format!("{node}.rz"))
            ],
            omega
        );
    }
    // pinned node: spin only
    assert_eq!([v("p.rx"), v("p.ry"), v("p.rz")], omega);

    // hub: reference point at (0, 4, 0) moved by its initial y translation to (0, 5, 0)
    let vh = field([0.0, 5.0, 0.0]);
    assert_eq!(v("hub.dofs[0]"), vh[0]);
    assert_eq!(v("hub.dofs[1]"), vh[1]);
    assert_eq!(v("hub.dofs[2]"), 0.5, "explicit initial_rate wins");
    assert_eq!(v("hub.dofs[3]"), 3.0, "axis · omega");
    assert_eq!(
        v("flap.angle"),
        0.0,
        "hinges start at rest relative to the parent"
    );
    assert_eq!(v("flop.angle"), 0.75, "explicit hinge rate wins");

    // driven dof keeps the driver's rate; a free rotation gets omega
    assert_eq!(v("drv.dofs[0]"), 0.25);
    assert_eq!(
        [v("drv.dofs[1].x"), v("drv.dofs[1].y"), v("drv.dofs[1].z")],
        omega
    );
    // an explicit free_rotation rate wins
    assert_eq!(
        [
            v("spun.dofs[0].x"),
            v("spun.dofs[0].y"),
            v("spun.dofs[0].z")
        ],
        [1.0, 0.0, 0.0]
    );

    // the resulting node velocity of a node on the hub (through its chain) is rigid
    let a = m.node_index("a").unwrap();
    let ch = crate::joint::node_chain(&m, &s, a);
    let (lin, ang) = ch.velocity(crate::joint::node_position(&m, &s, a), &s.v);
    // the hub's z translation rate is explicitly 0.5
    let expect = add(
        field(crate::joint::node_position(&m, &s, a)),
        [0.0, 0.0, 0.5],
    );
    assert!(close(lin, expect, 1e-12), "{lin:?} vs {expect:?}");
    assert!(close(ang, omega, 1e-12));

    // without [initial] nothing changes
    let plain = compile(&with_beam(""));
    assert!(State::new(&plain).v.iter().all(|&x| x == 0.0));
}

#[test]
fn explicit_rates_are_tracked() {
    let m = compile(&with_beam(
        "[[bodies]]\nname = \"h\"\nmass = 1\ninertia = [1, 1, 1]\n\
         [[bodies.dofs]]\ntype = \"translation\"\naxis = [1, 0, 0]\ninitial_rate = 0\n\
         [[bodies.dofs]]\ntype = \"rotation\"\naxis = [0, 0, 1]\n\
         [[joints]]\nname = \"j\"\nnode = \"a\"\nbody = \"h\"\ntype = \"hinge\"\naxis = [0, 1, 0]\ninitial_rate = 0\n",
    ));
    let explicit: Vec<&str> = m
        .dofs
        .iter()
        .filter(|d| d.v0_explicit)
        .map(|d| d.name.as_str())
        .collect();
    assert_eq!(explicit, ["h.dofs[0]", "j.angle"]);
}

#[test]
fn time_scaled_loads_apply_in_dynamics_only() {
    let m = compile(&with_beam(
        "[parameters]\nw = 2\n\
         [[loads]]\nnode = \"b\"\nforce = [0, 0, 10]\nmoment = [0, 4, 0]\nscale = \"sin(w*t)\"\nfollower = false\n\
         [[loads]]\nnode = \"b\"\nforce = [1, 0, 0]\n\
         [[loads]]\nnode = \"b\"\nforce = [0, 1, 0]\nscale = 0.5\n",
    ));
    let sc = m.loads[0].scale.as_ref().unwrap();
    assert!((sc.eval(0.3)[0] - (0.6f64).sin()).abs() < 1e-15);
    assert!(m.loads[1].scale.is_none());
    assert_eq!(m.loads[2].scale.as_ref().unwrap().eval(7.0)[0], 0.5);

    let asm = Assembler::new(&m);
    let mut s = State::new(&m);
    s.t = 0.3;
    let (bx, by, bz, bry) = (
        dof_index(&m, "b.x"),
        dof_index(&m, "b.y"),
        dof_index(&m, "b.z"),
        dof_index(&m, "b.ry"),
    );
    let mut gen = vec![0.0; m.dofs.len()];
    let coeffs = |inertia| Coeffs {
        load_factor: 1.0,
        inertia,
        ck: 0.0,
        cc: 0.0,
        cm: 0.0,
    };
    // at rest in the reference configuration: gen = −external
    asm.evaluate(&m, &s, coeffs(true), &mut gen, None);
    let f = (0.6f64).sin();
    assert!((gen[bz] + 10.0 * f).abs() < 1e-12, "{}", gen[bz]);
    assert!((gen[bry] + 4.0 * f).abs() < 1e-12);
    assert!((gen[bx] + 1.0).abs() < 1e-12, "unscaled load");
    assert!((gen[by] + 0.5).abs() < 1e-12);
    // statics: full value
    asm.evaluate(&m, &s, coeffs(false), &mut gen, None);
    assert!((gen[bz] + 10.0).abs() < 1e-12);
    assert!((gen[bry] + 4.0).abs() < 1e-12);
    assert!((gen[by] + 1.0).abs() < 1e-12);

    let e = fails(&with_beam(
        "[[loads]]\nnode = \"b\"\nforce = [0, 0, 1]\nfollower = true\n",
    ));
    assert_eq!(e.field.as_deref(), Some("loads[0].follower"));
    assert!(e.message.contains("not supported yet"), "{e}");
    let e = fails(&with_beam(
        "[[loads]]\nnode = \"b\"\nforce = [0, 0, 1]\nscale = \"k*t\"\n",
    ));
    assert_eq!(e.field.as_deref(), Some("loads[0].scale"));
    assert!(e.message.contains("`k`"), "{e}");
    let e = fails(&with_beam(
        "[[loads]]\nnode = \"b\"\nforce = [0, 0, 1]\nscale = \"1/t\"\n",
    ));
    assert_eq!(e.field.as_deref(), Some("loads[0].scale"));
}

/// a body driven along z (dof 0) and about z (dof 1) holding a cantilever a → b, and a
/// body with a free dof
fn driven_body(extra: &str) -> String {
    with_beam(&format!(
        "[[bodies]]\nname = \"hub\"\nmass = 2\ninertia = [1, 1, 1]\n\
         [[bodies.dofs]]\ntype = \"translation\"\naxis = [0, 0, 1]\ndrive = \"0\"\n\
         [[bodies.dofs]]\ntype = \"rotation\"\naxis = [0, 0, 1]\ndrive = \"0.1*t^2\"\n\
         [[bodies]]\nname = \"loose\"\nmass = 1\n\
         [[bodies.dofs]]\ntype = \"translation\"\naxis = [0, 1, 0]\n\
         [[joints]]\nname = \"root\"\nnode = \"a\"\nbody = \"hub\"\ntype = \"rigid\"\n{extra}"
    ))
}

/// the same without the loose body (whose free dof has no stiffness: statics)
fn driven_body_only(extra: &str) -> String {
    driven_body(extra).replace(
        "[[bodies]]\nname = \"loose\"\nmass = 1\n\
         [[bodies.dofs]]\ntype = \"translation\"\naxis = [0, 1, 0]\n",
        "",
    )
}

#[test]
fn driver_sensor_compiles_to_the_global_dof() {
    let m = compile(&driven_body(
        "[[sensors]]\nname = \"fz\"\ntype = \"driver\"\nbody = \"hub\"\ndof = 0\n\
         [[sensors]]\nname = \"mz\"\ntype = \"driver\"\nbody = \"hub\"\ndof = 1\n",
    ));
    let z = dof_index(&m, "hub.dofs[0]");
    let rz = dof_index(&m, "hub.dofs[1]");
    assert_eq!(
        m.sensors[0].kind,
        SensorKind::DriverForce {
            dof: z,
            rotational: false
        }
    );
    assert_eq!(
        m.sensors[1].kind,
        SensorKind::DriverForce {
            dof: rz,
            rotational: true
        }
    );
    assert_eq!(sensors::components(&m.sensors[0].kind), ["force"]);
    assert_eq!(sensors::units(&m.sensors[0].kind), ["N"]);
    assert_eq!(sensors::units(&m.sensors[1].kind), ["N*m"]);

    let s = State::new(&m);
    let mut forces = vec![0.0; m.dofs.len()];
    forces[rz] = -7.5;
    let v = sensors::sample(&m, &s, &m.sensors[1].kind, &Default::default(), &forces);
    assert_eq!(v, [-7.5]);

    let sensor = |body: &str, dof: &str| {
        driven_body(&format!(
            "[[sensors]]\nname = \"f\"\ntype = \"driver\"\nbody = \"{body}\"\n{dof}"
        ))
    };
    let e = fails(&sensor("loose", "dof = 0\n"));
    assert_eq!(e.field.as_deref(), Some("sensors[0].dof"));
    assert!(e.message.contains("free, not driven"), "{e}");
    let e = fails(&sensor("hub", "dof = 2\n"));
    assert_eq!(e.field.as_deref(), Some("sensors[0].dof"));
    assert!(e.message.contains("has 2 dofs"), "{e}");
    let e = fails(&sensor("hub", "dof = 0.5\n"));
    assert_eq!(e.field.as_deref(), Some("sensors[0].dof"));
    let e = fails(&sensor("hub", "dof = -1\n"));
    assert_eq!(e.field.as_deref(), Some("sensors[0].dof"));
    let e = fails(&sensor("hub", ""));
    assert_eq!(e.field.as_deref(), Some("sensors[0].dof"));
    assert!(e.message.contains("missing"), "{e}");
    let e = fails(&sensor("nobody", "dof = 0\n"));
    assert_eq!(e.field.as_deref(), Some("sensors[0].body"));
    let e = fails(&sensor("hub", "dof = 0\nnode = \"a\"\n"));
    assert_eq!(e.field.as_deref(), Some("sensors[0].node"));
    let e = fails(&with_beam(
        "[[sensors]]\nname = \"f\"\ntype = \"node\"\nnode = \"b\"\ndof = 0\n",
    ));
    assert_eq!(e.field.as_deref(), Some("sensors[0].dof"));
}

#[test]
fn driver_sensor_reports_the_static_reaction() {
    // tip force P along z on the cantilever held by the z-driven hub: the driver holds
    // it with −P; the force has no moment about the z axis
    let m = compile(&driven_body_only(
        "[[loads]]\nnode = \"b\"\nforce = [0, 0, 0.01]\n\
         [[sensors]]\nname = \"fz\"\ntype = \"driver\"\nbody = \"hub\"\ndof = 0\n\
         [[sensors]]\nname = \"mz\"\ntype = \"driver\"\nbody = \"hub\"\ndof = 1\n",
    ));
    assert_eq!(m.bodies.len(), 1);
    let sol = crate::solver::solve_statics(&m).unwrap_or_else(|e| panic!("{e:?}"));
    assert!((sol.sensors[0][0] + 0.01).abs() < 1e-9, "{:?}", sol.sensors);
    assert!(sol.sensors[1][0].abs() < 1e-9, "{:?}", sol.sensors);
}

#[test]
fn driver_sensor_in_dynamics_matches_the_integrators_driver_forces() {
    let m = compile(&driven_body_only(
        "[[sensors]]\nname = \"mz\"\ntype = \"driver\"\nbody = \"hub\"\ndof = 1\n",
    ));
    let it = crate::solver::dynamics::Integrator::new(&m).unwrap_or_else(|e| panic!("{e:?}"));
    let rz = dof_index(&m, "hub.dofs[1]");
    let v = it.sample();
    assert_eq!(v[0], [it.driver_forces()[rz]]);
    assert!(v[0][0] > 0.0, "spinning up the hub takes a positive moment");
}

#[test]
fn section_sensor_frame() {
    let m = compile(&with_beam(
        "[[sensors]]\nname = \"s\"\ntype = \"section\"\nbeam = \"bm\"\nat = 0\nframe = \"local\"\n",
    ));
    assert_eq!(
        m.sensors[0].kind,
        SensorKind::Section {
            element: 0,
            xi: 0.0
        }
    );
    let e = fails(&with_beam(
        "[[sensors]]\nname = \"s\"\ntype = \"section\"\nbeam = \"bm\"\nat = 0\nframe = \"global\"\n",
    ));
    assert_eq!(e.field.as_deref(), Some("sensors[0].frame"));
    assert!(e.message.contains("only `local`"), "{e}");
    let e = fails(&with_beam(
        "[[sensors]]\nname = \"s\"\ntype = \"node\"\nnode = \"b\"\nframe = \"local\"\n",
    ));
    assert_eq!(e.field.as_deref(), Some("sensors[0].frame"));
    // optional keys are not listed as needed
    let e = fails(&with_beam(
        "[[sensors]]\nname = \"s\"\ntype = \"section\"\nbeam = \"bm\"\n",
    ));
    assert!(e.message.ends_with("needs beam, at)"), "{e}");
}

#[test]
fn beam_nodes_sensor() {
    let m = compile(&with_beam(
        "[[sensors]]\nname = \"w\"\ntype = \"beam_nodes\"\nbeam = \"bm\"\ncomponent = \"z\"\n\
         [[sensors]]\nname = \"u\"\ntype = \"beam_nodes\"\nbeam = \"bm\"\ncomponent = \"x\"\n",
    ));
    let nodes = vec![0, 2, 1]; // a, bm:1, b
    assert_eq!(
        m.sensors[0].kind,
        SensorKind::BeamDisplacement {
            nodes: nodes.clone(),
            axis: 2
        }
    );
    assert_eq!(
        m.sensors[1].kind,
        SensorKind::BeamDisplacement { nodes, axis: 0 }
    );
    let k = &m.sensors[0].kind;
    assert_eq!(sensors::components(k), ["n0", "n1", "n2"]);
    assert_eq!(sensors::units(k), ["m", "m", "m"]);

    let mut s = State::new(&m);
    s.node_u[0] = [1.0, 2.0, 3.0];
    s.node_u[2] = [4.0, 5.0, 6.0];
    s.node_u[1] = [7.0, 8.0, 9.0];
    let sample = |k: &SensorKind| sensors::sample(&m, &s, k, &Default::default(), &[]);
    assert_eq!(sample(k), [3.0, 6.0, 9.0]);
    assert_eq!(sample(&m.sensors[1].kind), [1.0, 4.0, 7.0]);

    let e = fails(&with_beam(
        "[[sensors]]\nname = \"w\"\ntype = \"beam_nodes\"\nbeam = \"bm\"\ncomponent = \"rz\"\n",
    ));
    assert_eq!(e.field.as_deref(), Some("sensors[0].component"));
    let e = fails(&with_beam(
        "[[sensors]]\nname = \"w\"\ntype = \"beam_nodes\"\nbeam = \"bm\"\n",
    ));
    assert_eq!(e.field.as_deref(), Some("sensors[0].component"));
    let e = fails(&with_beam(
        "[[sensors]]\nname = \"w\"\ntype = \"beam_nodes\"\nbeam = \"nope\"\ncomponent = \"z\"\n",
    ));
    assert_eq!(e.field.as_deref(), Some("sensors[0].beam"));
    let e = fails(&with_beam(
        "[[sensors]]\nname = \"w\"\ntype = \"beam_nodes\"\nbeam = \"bm\"\ncomponent = \"z\"\nat = 0.5\n",
    ));
    assert_eq!(e.field.as_deref(), Some("sensors[0].at"));
}
