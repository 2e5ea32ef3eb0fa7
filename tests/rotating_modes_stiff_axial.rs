//! Rotating-frame modes of axially stiff, finely meshed blades (`latdyn modes` about the
//! steady rotation). The stiffness used to be central differences of the whole residual
//! (step 1e-6): stretching an element of length ℓ by a transverse step h puts a
//! truncation error ~EA·h²/ℓ³ into its transverse stiffness, against the centrifugal
//! stiffness ~T/ℓ that sets these modes — a relative error growing as EA·n², silent.
//! Before the fix (elastic part from the assembler's analytic tangent) the rigid flap of
//! the hinged blade below read +3.6 % (32 elements) and +13.8 % (64) at EA = 1e10, and
//! the rotating cantilever at EA = 1e10, 40 elements, Ω = 1 read 1.1267 / 1.1376 Hz
//! for 0.5639 / 0.5860.

mod common;
use common::*;
use latdyn::model::compile_str;
use latdyn::solver::rotating::{find_spin, rotating_modes};

/// A blade hinged (flap, no offset) on a hub at constant speed Ω: its rigid flap mode is
/// at exactly Ω in the rotating frame (references.md §3), whatever EA and the mesh.
const HINGED_BLADE: &str = r#"
[parameters]
L = 1.7
EI = 250.0
EA = 1.0e10
rhoA = 3.1
elements = 32
omega = 3.107356      # Obar = 1
[sections.blade]
EA = "EA"
EIy = "EI"
EIz = "2.4*EI"
GJ = 200.0
rhoA = "rhoA"
rhoIy = "1e-6*rhoA*L^2"
rhoIz = "1e-6*rhoA*L^2"
[[nodes]]
name = "root"
position = [0, 0, 0]
[[nodes]]
name = "tip"
position = ["L", 0, 0]
[[beams]]
name = "beam"
from = "root"
to = "tip"
elements = "elements"
section = "blade"
orientation = [0, 1, 0]
[[bodies]]
name = "hub"
position = [0, 0, 0]
mass = 1.0
inertia = [1, 1, 1]
  [[bodies.dofs]]
  type = "rotation"
  axis = [0, 0, 1]
  drive = "omega*t"
[[joints]]
name = "flap"
node = "root"
body = "hub"
type = "hinge"
axis = [0, 1, 0]
[solver]
t_end = 1.0
dt = 1e-3
"#;

#[test]
fn rigid_flap_of_an_axially_stiff_hinged_blade_is_the_hub_speed_on_fine_meshes() {
    // Tolerance 1e-4: measured after the fix within 6e-6 of Ω at 8 to 64 elements and EA
    // from 1e6 to 1e12 (the rotary inertia 1e-6 ρAL² moves the exact value by ~3e-6;
    // the rest is the round-off of the dense first-order eigen-solver); before it,
    // +3.6e-2 and +1.4e-1.
    for (ea, n, omega) in [
        (1e10, 32.0, 3.107356),
        (1e10, 64.0, 3.107356),
        (1e10, 32.0, 1.553678),
    ] {
        let sets = [
            ("EA".to_string(), ea),
            ("elements".to_string(), n),
            ("omega".to_string(), omega),
        ];
        let m =
            compile_str(HINGED_BLADE, "hinged_blade.toml", &sets).unwrap_or_else(|e| panic!("{e}"));
        let rm = rotating_modes(&m, find_spin(&m).unwrap()).unwrap();
        assert!(rm.steady_converged, "steady state not found");
        let want = omega / (2.0 * std::f64::consts::PI);
        let got = rm.frequencies_hz[0];
        let e = rel(got, want);
        eprintln!("EA {ea:e}, {n} elements, Ω {omega}: rigid flap {got:.9} Hz (Ω/2π {want:.9}), error {e:.1e}");
        assert!(e < 1e-4, "EA {ea:e}, {n} elements: {got} Hz, want {want}");
    }
}

#[test]
fn axially_stiff_rotating_cantilever_matches_the_reference_lag_and_flap_frequencies() {
    // Reference (Hermite beam FE, independent: /tmp/probeB ritz.py, the shipped section):
    // lag 0.563924 Hz, flap 0.585952 Hz at Ω = 1. Tolerance 1e-3: measured after the fix
    // −0.7e-4 to −1.9e-4 (lag, depending on where the steady Newton stops within its
    // round-off floor) and −2e-6 (flap) at EA = 1e10 — the lag mode's remainder is the
    // round-off of the dense first-order eigen-solver, ~ε‖M⁻¹K‖ with the axial stiffness
    // in K (at EA = 1e8 it is −1e-6) — and before the fix +100 % (1.1267 / 1.1376 Hz).
    let m = shipped(
        "rotating_cantilever.toml",
        &[("EA", 1e10), ("elements", 40.0), ("omega", 1.0)],
    );
    let rm = rotating_modes(&m, find_spin(&m).unwrap()).unwrap();
    assert!(rm.steady_converged, "steady state not found");
    for (k, want) in [(0, 0.563924), (1, 0.585952)] {
        let got = rm.frequencies_hz[k];
        let e = rel(got, want);
        eprintln!(
            "mode {}: {got:.6} Hz (reference {want}), error {e:.1e}",
            k + 1
        );
        assert!(e < 1e-3, "mode {}: {got} Hz, reference {want}", k + 1);
    }
}

#[test]
fn a_small_hub_speed_changes_the_modes_continuously() {
    // Ω = 0.01 rad/s against the hub at rest (EA = 1e8, 40 elements): the first bending
    // frequency may move by O(Ω²/ω²) ~ 1e-5, not jump. Before the fix: 0.559601 Hz at
    // rest, 0.569568 Hz (+1.8 %) at Ω = 0.01.
    let at = |omega: f64| {
        let m = shipped(
            "rotating_cantilever.toml",
            &[("EA", 1e8), ("elements", 40.0), ("omega", omega)],
        );
        let rm = rotating_modes(&m, find_spin(&m).unwrap()).unwrap();
        assert!(rm.steady_converged);
        rm.frequencies_hz[0]
    };
    let (slow, faster) = (at(0.01), at(0.02));
    let rest = 0.559601;
    eprintln!("Ω 0.01: {slow:.6} Hz, Ω 0.02: {faster:.6} Hz, at rest {rest}");
    assert!(rel(slow, rest) < 1e-4, "{slow} vs {rest}");
    assert!(rel(faster, rest) < 1e-4, "{faster} vs {rest}");
}

/// Rotating-frame modes depend on Ω̄ = Ω √(ρA L⁴/EI), not on Ω in rad/s. The eigen-solve
/// used the unshifted first-order form, whose round-off is absolute on the scale of the
/// stiffest mode's ω²; with EI = 1e6 (Ω = 1000 Ω̄) and 40 elements the first frequencies
/// read 228.6 and 286.3 Hz with damping ratios of ±0.95 for 563.9 (lag) and 585.9 Hz
/// (flap), with no warning. Reference: references.md §"rotating cantilever" (Ω̄ = 1:
/// 3.6816, 22.1810; Ω̄ = 10: 11.2023, 33.6404; the flap modes, second and fourth of the
/// list, each above its lag mode), for an inextensible beam: EA·L²/EI = 1e6 here
/// (centrifugal strain 5e-5 at Ω̄ = 10; at 1e4 the second flap mode read 1.1e-3 low).
/// Tolerance 5e-4, measured below; damping ratios of an undamped gyroscopic system are
/// round-off.
#[test]
fn rotating_frame_modes_depend_on_the_nondimensional_speed_not_on_rad_per_s() {
    for (obar, flap) in [(1.0, [3.6816, 22.1810]), (10.0, [11.2023, 33.6404])] {
        for n in [20.0, 40.0] {
            let m = shipped(
                "rotating_cantilever.toml",
                &[
                    ("EI", 1e6),
                    ("GJ", 8e5),
                    ("EA", 1e12),
                    ("elements", n),
                    ("omega", 1000.0 * obar),
                ],
            );
            let rm = rotating_modes(&m, find_spin(&m).unwrap()).unwrap();
            assert!(rm.steady_converged, "steady state not found");
            for (k, wbar) in [(1, flap[0]), (3, flap[1])] {
                let want = wbar * 1000.0 / (2.0 * std::f64::consts::PI);
                let got = rm.frequencies_hz[k];
                eprintln!(
                    "Ω̄ {obar}, {n} elements: mode {}: {got:.4} Hz (reference {want:.4})",
                    k + 1
                );
                assert!(
                    rel(got, want) < 5e-4,
                    "Ω̄ {obar}, {n} elements, mode {}: {got} vs {want}",
                    k + 1
                );
            }
            for z in &rm.damping[..4] {
                assert!(z.abs() < 1e-8, "Ω̄ {obar}, {n} elements: damping ratio {z}");
            }
        }
    }
}
