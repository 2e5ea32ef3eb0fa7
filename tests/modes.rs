//! Free vibration against the Euler-Bernoulli closed forms (references.md §1), with the
//! mesh convergence of each mode reported and its order asserted.

mod common;
use common::*;
use latdyn::joint::State;
use latdyn::solver::modes::modes;

/// In-plane bending EIz = 100 is the one studied; out-of-plane and axial stiffness are
/// made large so the first four modes are the in-plane bending ones.
const PROPS: &str = r#"EA = 1.0e9
EIy = 1.0e6
EIz = 100.0
GJ = 80.0
rhoA = 1.0"#;

fn bending_hz(beta_l: f64) -> f64 {
    // ω = (βL)² √(EI/(ρA L⁴)) with L = 1
    beta_l * beta_l * (100.0f64).sqrt() / (2.0 * std::f64::consts::PI)
}

fn elastic_frequencies(support: &str, n: usize) -> Vec<f64> {
    let m = straight_beam(support, n, PROPS, [0.0; 3], [0.0; 3], "");
    let md = modes(&m, &State::new(&m)).unwrap();
    // rigid-body modes of the free-free beam come out at round-off level, λ ≈ 1e-12 of
    // the largest eigenvalue (axial, EA = 1e9): below 0.05 Hz; the first elastic mode is
    // at 35.6 Hz
    md.frequencies_hz
        .into_iter()
        .filter(|f| f.abs() > 1.0)
        .collect()
}

fn check(support: &str, beta: &[f64]) {
    let mut errs = vec![Vec::new(); beta.len()];
    for n in [4, 8, 16] {
        let f = elastic_frequencies(support, n);
        for (k, b) in beta.iter().enumerate() {
            let e = (f[k] - bending_hz(*b)) / bending_hz(*b);
            errs[k].push(e);
            eprintln!(
                "{support} mode {} with {n:>2} elements: {:.6} Hz, error {e:+.2e}",
                k + 1,
                f[k]
            );
        }
    }
    for (k, e) in errs.iter().enumerate() {
        // consistent-mass Hermite elements converge at O(h⁴) from above: the 16-element
        // error is below 5e-4 for the first four modes (worst: free-free mode 4, 4.0e-4, with
        // about four elements per half-wave),
        // and halving h divides the error by well over 8 (asymptotically 16)
        assert!(
            e.iter().all(|x| *x > -1e-9),
            "mode {} converges from above: {e:?}",
            k + 1
        );
        assert!(
            e[2] < 5e-4,
            "mode {} with 16 elements: error {}",
            k + 1,
            e[2]
        );
        assert!(e[1] / e[2] > 8.0, "mode {} order: {e:?}", k + 1);
    }
}

#[test]
fn cantilever_frequencies_converge_at_fourth_order_to_beta_l_closed_form() {
    check(
        "clamped",
        &[1.8751040687, 4.6940911330, 7.8547574382, 10.9955407349],
    );
}

#[test]
fn free_free_frequencies_converge_at_fourth_order_to_beta_l_closed_form() {
    check(
        "free",
        &[4.7300407449, 7.8532046241, 10.9956078380, 14.1371654913],
    );
}
