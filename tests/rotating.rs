//! Rotating cantilever (references.md §2): centrifugal stiffening of the flapwise modes,
//! from the linearisation about the steady rotating state and from the transient
//! response.

mod common;
use common::*;
use latdyn::solver::rotating::{find_spin, rotating_modes};

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
        let m = shipped("rotating_cantilever.toml", &[("omega", wbar)]);
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
