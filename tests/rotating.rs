//! Rotating cantilever (references.md §2): centrifugal stiffening of the flapwise modes,
//! from the linearisation about the steady rotating state and from the transient
//! response.

mod common;
use common::*;
use latdyn::solver::rotating::{find_spin, rotating_modes};
use std::path::Path;

/// (Ω̄, ω̄₁, ω̄₂, ω̄₃) from references.md §2.
const TABLE: [(f64, [f64; 3]); 8] = [
    (0.0, [3.5160, 22.0345, 61.6972]),
    (1.0, [3.6816, 22.1810, 61.8418]),
    (2.0, [4.1373, 22.6149, 62.2732]),
    (3.0, [4.7973, 23.3203, 62.9850]),
    (4.0, [5.5850, 24.2733, 63.9668]),
    (6.0, [7.3604, 26.8091, 66.6839]),
    (8.0, [9.2568, 29.9954, 70.2930]),
    (10.0, [11.2023, 33.6404, 74.6493]),
];

#[test]
fn rotating_frame_flapwise_frequencies_match_the_published_table() {
    // L = EI = ρA = 1, so ω̄ = 2π f. In-plane bending is made 1e4 times stiffer so the
    // first three rotating-frame modes are the flapwise ones. 12 elements: measured
    // errors ≤ 1.3e-4 (mesh error of Hermite elements ~1e-5 for mode 1, 1e-4 for mode 3;
    // rotary inertia 1e-6 ρAL² and the axial stretch under EA = 1e5 add ~1e-5); the
    // table has 5 digits. Tolerance 0.1 %, a factor 7 above the worst measured error.
    for (wbar, want) in TABLE {
        let m = shipped(
            "rotating_cantilever.toml",
            &[
                ("omega", wbar.max(1e-9)),
                ("EIlag", 1e4),
                ("elements", 12.0),
            ],
        );
        let spin = find_spin(&m).expect("constant-speed hub");
        let rm = rotating_modes(&m, spin).unwrap();
        for (k, w) in want.iter().enumerate() {
            let got = rm.frequencies_hz[k] * 2.0 * std::f64::consts::PI;
            let e = rel(got, *w);
            eprintln!(
                "Ω̄={wbar:>4}: mode {} ω̄ = {got:.4} (table {w:.4}), error {e:.1e}",
                k + 1
            );
            assert!(e < 1e-3, "Ω̄={wbar} mode {}: {got} vs {w}", k + 1);
        }
    }
}

#[test]
fn transient_flapwise_frequency_rises_with_speed_as_the_table_says() {
    // The simulated tip response after a flapwise tip impulse, in steady rotation at
    // Ω̄ = 0, 2, 5 and 10: the strongest spectral peak below 3 Hz (ω̄ < 19, below the
    // second flap mode) is the first flapwise mode. Errors measured: 1.3e-4 to 4.3e-4
    // (dt = 0.01 with ρ∞ = 0.6 lowers the frequency slightly; the 12 s record holds 6.7
    // to 21 periods). Tolerance 1 % as the issue asks, a factor 20 above.
    // Table values at Ω̄ = 5 interpolated by Southwell's form from Ω̄ = 4 and 6.
    let southwell5 = {
        let (w0, w4, w6): (f64, f64, f64) = (3.5160, 5.5850, 7.3604);
        let k = 0.5 * ((w4 * w4 - w0 * w0) / 16.0 + (w6 * w6 - w0 * w0) / 36.0);
        (w0 * w0 + 25.0 * k).sqrt()
    };
    for (wbar, want) in [
        (0.0, 3.5160),
        (2.0, 4.1373),
        (5.0, southwell5),
        (10.0, 11.2023),
    ] {
        let m = shipped("rotating_cantilever.toml", &[("omega", wbar), ("dt", 0.01)]);
        let (h, stats, err) = latdyn::solver::dynamics::run(&m, |_, _| {});
        assert!(err.is_none(), "Ω̄={wbar}: {err:?}");
        let k = m.sensor_index("tip_flap").unwrap();
        let x: Vec<f64> = h.values[k].iter().map(|v| v[0]).collect();
        let dt = h.t[1] - h.t[0];
        let f = latdyn::signal::dominant_frequency(&x, dt, 0.05, 3.0).unwrap();
        let got = 2.0 * std::f64::consts::PI * f;
        let e = rel(got, want);
        eprintln!(
            "Ω̄={wbar:>4}: transient ω̄₁ = {got:.4} (reference {want:.4}), error {e:.2e}, {} steps",
            stats.steps
        );
        assert!(e < 0.01, "Ω̄={wbar}: {got} vs {want}");
    }
}

#[test]
fn a_steady_start_is_stretched_as_the_closed_form_and_stays_at_rest_in_the_rotating_frame() {
    // EA u'' + ρA Ω² (x + u) = 0, u(0) = 0, u'(L) = 0: u(L) = tan(kL)/k − L, k² = ρA Ω²/EA
    // (the centrifugal load on the stretched radius). Ω̄ = 50 with EA = 1e5 (kL = 0.16)
    // stretches the tip by 0.84 %, of which 1 % comes from the load on the stretch (the
    // (kL)⁴ term), so a tolerance of 1e-4 relative tests it.
    let (w, ea) = (50.0, 1e5);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/rotating_cantilever.toml");
    let text = std::fs::read_to_string(&path).unwrap()
        + "\n[[sensors]]\nname = \"tip_position\"\ntype = \"position\"\nnode = \"tip\"\n";
    let sets = [
        ("omega", w),
        ("EA", ea),
        ("disturbance", 0.0),
        ("t_end", 0.5),
        ("dt", 1e-3),
    ];
    let o: Vec<(String, f64)> = sets.iter().map(|(k, v)| (k.to_string(), *v)).collect();
    let m = latdyn::model::compile_str(&text, "rotating_cantilever.toml", &o).unwrap();
    let k = w / ea.sqrt();
    let want = (k.tan() / k - 1.0) + 1.0;
    let s = latdyn::solver::rotating::steady_start(&m, None).unwrap();
    let tip = m.node_names.iter().position(|n| n == "tip").unwrap();
    let got = 1.0 + s.node_u[tip][0];
    eprintln!("steady tip radius {got:.9} (closed form {want:.9})");
    assert!(rel(got - 1.0, want - 1.0) < 1e-4, "{got} vs {want}");
    // Over 0.5 s (4 turns) the tip keeps that radius up to the integrator's error on the
    // rigid rotation, which falls at second order (measured 1.09e-5 m at dt = 1e-3 and
    // 2.74e-6 m at 5e-4: 0.13 % of the stretch); the unstretched start rings the axial
    // mode with about the stretch as its amplitude.
    let swing = |m: &latdyn::model::Model| -> f64 {
        let (h, _, err) = latdyn::solver::dynamics::run(m, |_, _| {});
        assert!(err.is_none(), "{err:?}");
        let p = m.sensor_index("tip_position").unwrap();
        h.values[p]
            .iter()
            .map(|x| ((x[0] * x[0] + x[1] * x[1]).sqrt() - got).abs())
            .fold(0.0f64, f64::max)
    };
    let coarse = swing(&m);
    let mut fine = m.clone();
    fine.solver.dt = 5e-4;
    let fine = swing(&fine);
    let mut unstretched = m.clone();
    unstretched.initial_steady = false;
    unstretched.initial_rotation = Some(([0.0, 0.0, w], [0.0; 3]));
    let ringing = swing(&unstretched);
    let stretch = want - 1.0;
    eprintln!(
        "tip radius swing: steady start {coarse:.3e} m (dt 1e-3), {fine:.3e} m (dt 5e-4); \
         unstretched start {ringing:.3e} m; stretch {stretch:.3e} m"
    );
    assert!(coarse < 1e-2 * stretch, "{coarse}");
    assert!(coarse / fine > 3.5, "not second order: {coarse} {fine}");
    assert!(
        ringing > 0.5 * stretch,
        "the unstretched start should ring: {ringing}"
    );
}

/// A cantilever shaft clamped to a hub spinning about the shaft's own axis, bending
/// stiffnesses EIy ≠ EIz, no rotary inertia: each mode pair decouples, and in the
/// rotating frame its eigenvalues λ² (x ∝ e^{iλt}) solve
/// (ω₁² − Ω² − λ²)(ω₂² − Ω² − λ²) = 4Ω²λ², ω₁,₂ the clamped-free frequencies of the two
/// planes. Between ω₁ and ω₂ one root λ² is negative: the shaft diverges without
/// oscillating. Until session 46 `modes` left that root out and warned nothing (a probe
/// found it: 15.22, 33.03, 62.70 Hz listed, "stable"). Tolerance 1e-5: the 16 elements'
/// error of ω₁,₂ (about 1e-7) and the rotating analysis's round-off.
#[test]
fn a_shaft_spinning_between_its_two_critical_speeds_is_reported_divergent() {
    let text = |omega: f64| {
        format!(
            r#"[parameters]
omega = {omega}
[sections.main]
EA = 1.0e6
EIy = 100.0
EIz = 300.0
GJ = 80.0
rhoA = 1.0
rhoIy = 0.0
rhoIz = 0.0
[[nodes]]
name = "root"
position = [0, 0, 0]
[[nodes]]
name = "tip"
position = [1, 0, 0]
[[beams]]
name = "shaft"
from = "root"
to = "tip"
elements = 16
section = "main"
[[bodies]]
name = "hub"
position = [0, 0, 0]
mass = 1.0
inertia = [1, 1, 1]
  [[bodies.dofs]]
  type = "rotation"
  axis = [1, 0, 0]
  drive = "omega*t"
[[joints]]
name = "clamp"
node = "root"
body = "hub"
type = "rigid"
[[sensors]]
name = "tip"
type = "node"
node = "tip"
[solver]
t_end = 1.0
dt = 1e-3
"#
        )
    };
    let dir = std::env::temp_dir().join(format!("latdyn-shaft-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // clamped-free first bending: (1.87510407)² √(EI / ρA L⁴)
    let beta2 = 1.875_104_068_711_961f64.powi(2);
    let (w1, w2) = (beta2 * 100f64.sqrt(), beta2 * 300f64.sqrt());
    let two_pi = 2.0 * std::f64::consts::PI;
    for omega in [30.0f64, 45.0, 80.0] {
        let p = dir.join(format!("shaft_{omega}.toml"));
        std::fs::write(&p, text(omega)).unwrap();
        let v = latdyn_json(&["modes", p.to_str().unwrap(), "--count", "2", "--json"]);
        let f: Vec<f64> = v["frequencies_hz"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        let (a, b) = (w1 * w1 - omega * omega, w2 * w2 - omega * omega);
        let sum = a + b + 4.0 * omega * omega;
        let disc = (sum * sum - 4.0 * a * b).sqrt();
        let (x1, x2) = (0.5 * (sum - disc), 0.5 * (sum + disc));
        // a negative λ² is a growth rate √(−λ²), reported as −√(−λ²)/2π
        let want = |x: f64| x.signum() * x.abs().sqrt() / two_pi;
        let warned = v["warnings"].to_string();
        eprintln!("Ω = {omega}: {f:?}, λ² = {x1}, {x2}");
        assert!(
            rel(f[0], want(x1)) < 1e-5,
            "Ω = {omega}: {f:?} against {}",
            want(x1)
        );
        assert!(
            rel(f[1], want(x2)) < 1e-5,
            "Ω = {omega}: {f:?} against {}",
            want(x2)
        );
        if x1 < 0.0 {
            assert!(warned.contains("unstable in mode 1 (divergence"), "{v}");
            assert_eq!(v["damping_ratios"][0].as_f64(), Some(-1.0), "{v}");
        } else {
            assert!(!warned.contains("unstable"), "{v}");
        }
    }
}

/// Gravity across the spin axis turns once per revolution as seen from the rotor: there
/// is no steady rotating state with it. Until session 48 the analysis held it fixed in
/// the rotating frame, so the first mode of the rotating cantilever on a hub of radius
/// 0.5 at Ω = 10 rad/s read 1.4767 Hz with g along −x and 1.7108 Hz along +x (1.5981
/// without gravity), and at g = 100 a divergence, all without a word (a probe). Now the
/// analysis keeps its average over a revolution (the axial part) and says so.
#[test]
fn gravity_across_the_spin_axis_is_averaged_over_a_revolution_and_said() {
    let base = shipped(
        "rotating_cantilever.toml",
        &[("omega", 10.0), ("elements", 10.0)],
    );
    let spin = find_spin(&base).expect("constant-speed hub");
    let modes = |g: [f64; 3]| {
        let mut m = base.clone();
        m.gravity = g;
        rotating_modes(&m, spin).unwrap()
    };
    let free = modes([0.0; 3]);
    assert!(free.turning_loads.is_none());
    // the spin axis is z: along it gravity is steady, and no note is given
    let axial = modes([0.0, 0.0, -9.81]);
    assert!(axial.turning_loads.is_none(), "{:?}", axial.turning_loads);
    for (g, same_as) in [
        ([-9.81, 0.0, 0.0], &free),
        ([100.0, 0.0, 0.0], &free),
        ([0.0, 9.81, 0.0], &free),
        ([3.0, -4.0, -9.81], &axial),
    ] {
        let rm = modes(g);
        let note = rm.turning_loads.as_deref().unwrap_or_default();
        assert!(
            note.contains("across the spin axis") && note.contains("average over a revolution"),
            "g = {g:?}: {note:?}"
        );
        for k in 0..3 {
            assert!(
                rel(rm.frequencies_hz[k], same_as.frequencies_hz[k]) < 1e-9,
                "g = {g:?}, mode {}: {} Hz against {} Hz",
                k + 1,
                rm.frequencies_hz[k],
                same_as.frequencies_hz[k]
            );
        }
        assert!(rm.instability_warning(3).is_none(), "g = {g:?}");
    }
}

/// A lag hinge at the spin axis with no spring: the rigid lag motion has zero frequency
/// in the rotating frame. The rotating-frame JSON flags it as the static one does (until
/// session 48 it had no `zero_frequency` field, and the round-off warning spoke only of
/// a slow hub).
#[test]
fn a_free_lag_hinge_at_the_axis_is_flagged_zero_frequency_in_the_rotating_frame() {
    let v = latdyn_json(&[
        "modes",
        "tests/models/lag_hinge_no_offset.toml",
        "--count",
        "3",
        "--json",
    ]);
    assert_eq!(v["about"], "steady_rotation");
    let z: Vec<bool> = v["zero_frequency"]
        .as_array()
        .expect("zero_frequency")
        .iter()
        .map(|b| b.as_bool().unwrap())
        .collect();
    assert_eq!(z, [true, false, false], "{v}");
    assert!(v["warnings"][0]
        .as_str()
        .unwrap()
        .contains("a motion of zero frequency"));
}
