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
