//! Rigid pendulum through a hinge against the exact elliptic-integral period
//! (references.md §8), and the energy behaviour of the integrator.

mod common;
use common::*;
use latdyn::solver::dynamics::run;

/// Complete elliptic integral of the first kind by the arithmetic-geometric mean.
fn ellip_k(k: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    for _ in 0..30 {
        let an = 0.5 * (a + b);
        b = (a * b).sqrt();
        a = an;
    }
    std::f64::consts::PI / (2.0 * a)
}

/// Times where the signal crosses zero going down, by cubic-free linear interpolation on
/// a fine grid (the grid is every step: interpolation error O(h²θ'') ≪ tolerance).
fn down_crossings(t: &[f64], x: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    for i in 1..x.len() {
        if x[i - 1] > 0.0 && x[i] <= 0.0 {
            out.push(t[i - 1] + (t[i] - t[i - 1]) * x[i - 1] / (x[i - 1] - x[i]));
        }
    }
    out
}

#[test]
fn large_amplitude_pendulum_period_matches_the_elliptic_integral() {
    let (m, d, ic, g, th0): (f64, f64, f64, f64, f64) = (2.0, 0.5, 0.01, 9.81, 2.5);
    let model = shipped(
        "pendulum.toml",
        &[
            ("theta0", th0),
            ("t_end", 8.0),
            ("dt", 5e-4),
            ("rho_inf", 1.0),
        ],
    );
    let (hist, stats, err) = run(&model, |_, _| {});
    assert!(err.is_none(), "{err:?}");
    let k = model.sensor_index("angle").unwrap();
    let ang: Vec<f64> = hist.values[k].iter().map(|v| v[4]).collect();
    let cross = down_crossings(&hist.t, &ang);
    assert!(cross.len() >= 3);
    let period = (cross[cross.len() - 1] - cross[0]) / (cross.len() - 1) as f64;
    let i = ic + m * d * d;
    let exact = 4.0 * (i / (m * g * d)).sqrt() * ellip_k((th0 / 2.0).sin());
    let e = rel(period, exact);
    eprintln!(
        "pendulum θ0={th0}: period {period:.8} s, exact {exact:.8} s, error {e:.2e}, {} steps",
        stats.steps
    );
    // trapezoidal-like phase error (ωh)²/12 ≈ 1e-6 at h = 5e-4 s; the crossing
    // interpolation adds O(h²): 2e-5 leaves a factor ~10
    assert!(e < 2e-5, "period error {e}");
}

#[test]
fn pendulum_energy_drift_is_bounded_for_rho_inf_one() {
    // ρ∞ = 1 has no numerical dissipation; its energy error oscillates with O(h²)
    // amplitude rather than drifting. Report it and bound it at 1e-4 of the swing energy.
    for (dt, bound) in [(2e-3, 4e-4), (1e-3, 1e-4)] {
        let model = shipped(
            "pendulum.toml",
            &[
                ("theta0", 2.0),
                ("t_end", 10.0),
                ("dt", dt),
                ("rho_inf", 1.0),
            ],
        );
        let (hist, _, err) = run(&model, |_, _| {});
        assert!(err.is_none());
        let k = model.sensor_index("energy").unwrap();
        let tot: Vec<f64> = hist.values[k].iter().map(|v| v[4]).collect();
        let swing = 2.0 * 9.81 * 0.5 * (1.0 - 2.0f64.cos());
        let drift = tot.iter().map(|e| (e - tot[0]).abs()).fold(0.0, f64::max) / swing;
        eprintln!("pendulum energy, ρ∞=1, dt={dt}: max |E−E0|/E_swing = {drift:.2e}");
        assert!(drift < bound, "dt {dt}: energy drift {drift}");
    }
}

/// Rigid compound double pendulum (uniform rods L1, L2 of masses m1, m2, hinged at the
/// origin and at the elbow, angles from the horizontal, positive downwards), released
/// horizontal from rest: the tip position at `t_end` by classical RK4 at 2e-6 s (error
/// far below 1e-9 m over 1 s).
fn rigid_double_pendulum_tip(t_end: f64) -> (f64, f64) {
    let (l1, l2, m1, m2, g) = (1.0f64, 0.7f64, 1.0f64, 2.0f64, 9.81f64);
    let (i1, i2, c) = (m1 * l1 * l1 / 12.0, m2 * l2 * l2 / 12.0, m2 * l1 * l2 / 2.0);
    let rhs = |y: [f64; 4]| -> [f64; 4] {
        let [a1, a2, w1, w2] = y;
        let (m11, m22, m12) = (
            i1 + m1 * l1 * l1 / 4.0 + m2 * l1 * l1,
            i2 + m2 * l2 * l2 / 4.0,
            c * (a1 - a2).cos(),
        );
        let f1 = -c * (a1 - a2).sin() * w2 * w2 + (m1 * l1 / 2.0 + m2 * l1) * g * a1.cos();
        let f2 = c * (a1 - a2).sin() * w1 * w1 + m2 * l2 / 2.0 * g * a2.cos();
        let det = m11 * m22 - m12 * m12;
        [
            w1,
            w2,
            (m22 * f1 - m12 * f2) / det,
            (m11 * f2 - m12 * f1) / det,
        ]
    };
    let n = (t_end / 2e-6).round() as usize;
    let h = t_end / n as f64;
    let mut y = [0.0; 4];
    let add = |y: [f64; 4], k: [f64; 4], s: f64| std::array::from_fn(|i| y[i] + s * k[i]);
    for _ in 0..n {
        let k1 = rhs(y);
        let k2 = rhs(add(y, k1, h / 2.0));
        let k3 = rhs(add(y, k2, h / 2.0));
        let k4 = rhs(add(y, k3, h));
        y = std::array::from_fn(|i| y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
    }
    (
        l1 * y[0].cos() + l2 * y[1].cos(),
        -l1 * y[0].sin() - l2 * y[1].sin(),
    )
}

#[test]
fn a_start_with_massless_coordinates_keeps_second_order_against_the_rigid_double_pendulum() {
    // Sections without rotary inertia (the default) leave the torsion coordinates
    // massless and M singular. Until session 28 the start then took a₀ = 0 everywhere and
    // the run converged at first order: 3.9e-3 and 1.95e-3 m off at dt = 1e-3 and 5e-4
    // (ratio 2.0). Measured since: 4.5e-5 and 1.2e-5 m (ratio 3.8). The beams are nearly
    // rigid (gravity sag below 1e-6 m). Bounds: 2e-4 m at 1e-3 s, and a ratio of at
    // least 3 (second order gives 4; first order 2).
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/models/double_pendulum_beams.toml");
    let (rx, rz) = rigid_double_pendulum_tip(1.0);
    let err = |dt: f64| {
        let sets = vec![("dt".to_string(), dt), ("t_end".to_string(), 1.0)];
        let m = latdyn::model::load(&path, &sets).unwrap();
        let (h, _, e) = run(&m, |_, _| {});
        assert!(e.is_none(), "{e:?}");
        let k = m.sensors.iter().position(|s| s.name == "tip").unwrap();
        let tip = h.values[k].last().unwrap();
        (tip[0] - rx).hypot(tip[2] - rz)
    };
    let (e1, e2) = (err(1e-3), err(5e-4));
    assert!(e1 < 2e-4, "tip {e1} m off at dt = 1e-3");
    assert!(e1 / e2 > 3.0, "order: {e1} / {e2} = {}", e1 / e2);
}
