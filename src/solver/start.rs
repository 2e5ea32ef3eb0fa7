//! A consistent initial velocity (`[initial] consistent_velocity = true`).
//!
//! A model file sets some initial rates (`initial_rate` of a body coordinate or a hinge,
//! the drives' rates at t = 0) and leaves the rest at zero. Launched like that, a flexible
//! member between a moving body and one at rest is strained at a finite rate from the
//! first instant: the four-bar's coupler at v0 with its cranks at rest strikes every crank
//! mode, a vibration no step resolves, that the user never asked for. This start keeps
//! the rates that are set and gives every other free coordinate the velocity that strains
//! nothing: v = v0 + δ, δ zero on the set rates, K v = 0 on the others (K the stiffness
//! at the initial configuration), with δ the smallest such change in the weights W below.
//!
//! A motion that K does not resist (a hinge the set rates leave free, a free body) is not
//! fixed by K v = 0; W decides it: such a motion keeps its given rate. W weighs the
//! joint and body coordinates (hinge angles, a body's translations and rotations) as the
//! heaviest coordinate, and the beams' node coordinates by 1e-4 of their mass-matrix
//! diagonal: a beam hung on a free hinge of a moving cart moves with the cart and does
//! not swing (with equal weights the smallest change would turn it, to carry its nodes'
//! given rest along). A free-floating beam's rigid motion, which only node coordinates
//! carry, keeps its given rate too.
//!
//! It is solved by iterated regularisation (proximal point):
//! δ ← δ − (K + ε W)⁻¹ K (v0 + δ). Each pass leaves the fraction ε / (λ + ε) of an elastic mode of eigenvalue λ
//! (of K against W) and does not touch the motions K does not resist, so the iteration
//! converges to the W-smallest strain-free change while K + ε W stays well conditioned.
//! K v0 includes the drives' rates (a driven hub spinning at t = 0 moves the nodes
//! attached to it): it is the central difference of the static residual along the
//! initial motion, which needs no stiffness column of a driven coordinate; K δ is the
//! assembled stiffness times δ.

use super::linear::NewtonSystem;
use crate::assembly::{Assembler, Coeffs};
use crate::joint::{self, State};
use crate::model::{ChainLink, DofMode, Model};

/// ε as a fraction of the mean of the stiffness-to-weight ratios on the diagonal: K + ε W
/// keeps a condition number near 1e6 (plus the node weights' 1e4), and an elastic mode
/// loses at least 1 − ε/(λ + ε) of its strain rate per pass.
const EPS_REL: f64 = 1e-6;

/// Weight of a beam node's coordinate against a joint or body coordinate of the same
/// mass (see the module doc).
const NODE_WEIGHT: f64 = 1e-4;

/// The passes stop when the strain-rate force K v is this fraction of K v0 ...
const STRAIN_RATE_LEFT: f64 = 1e-10;
/// ... or after this many passes (the fraction left is then reported).
const MAX_PASSES: usize = 100;

/// Step of the central difference along the initial motion, as the largest rotation
/// [rad] or displacement over the model's size it makes. Not the cube root of the unit
/// round-off that balances truncation and round-off for a generic function: along an
/// inconsistent motion the residual is strongly nonlinear (on the four-bar a step of 4e-3,
/// that cube root in f32, put the start 3 % off), while the elements' cancellation-free
/// strains keep their forces accurate relative to the deformation, so a small step costs
/// no accuracy even in f32 (measured on the four-bar: 1e-7 gives the f64 answer to 2e-9,
/// the f32 GPU kernels' to 6e-8).
const PROBE: f64 = 1e-7;

/// A start not asked to be consistent whose velocity would change by more than this
/// share of its kinetic energy is warned: the members it strains ring with about the
/// square root of that share of the given velocities, and 1e-4 is the 1 % a sensor's
/// estimate is held to.
pub const KINETIC_SHARE_WARN: f64 = 1e-4;

/// A start that leaves more of the strain rate than this is warned (the passes stopped
/// at [`MAX_PASSES`]).
pub const STRAIN_RATE_WARN: f64 = 1e-6;

/// What the start did or would do: the largest change of a rate over the largest rate
/// (rates of translations divided by the model's size), the kinetic energy of the change
/// over that of the given velocity (δᵀMδ / v0ᵀMv0 over the free coordinates; infinite
/// when only driven coordinates move), the coordinates it solved for, the passes, the
/// strain-rate force left over the initial one (|K v|∞ / |K v0|∞), and whether the
/// change was applied (`consistent_velocity = true`) or only measured (not written).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ConsistentStart {
    pub largest_change: f64,
    pub kinetic_share: f64,
    pub solved: usize,
    pub passes: usize,
    pub strain_rate_left: f64,
    pub applied: bool,
}

/// What `[initial]` asks of the start's velocity: with `consistent_velocity = true`,
/// make `s.v` consistent; where it is not written, measure on a copy what that would
/// change (for the warning) and leave `s` as it is; with `= false`, or a steady start
/// (which strains nothing), nothing. A measurement that cannot be made is no reason not
/// to run as given (`Ok(None)`); a start asked for that cannot be made is an error.
pub(crate) async fn start_velocity(
    model: &Model,
    asm: &Assembler,
    sys: &mut NewtonSystem,
    s: &mut State,
) -> Result<Option<ConsistentStart>, String> {
    if model.initial_steady {
        return Ok(None);
    }
    match model.initial_consistent_velocity {
        Some(false) => Ok(None),
        Some(true) => {
            let mut c = consistent_velocity(model, asm, sys, s).await?;
            c.applied = true;
            Ok(Some(c))
        }
        None => Ok(consistent_velocity(model, asm, sys, &mut s.clone())
            .await
            .ok()),
    }
}

/// Make `s.v` consistent (see the module doc).
async fn consistent_velocity(
    model: &Model,
    asm: &Assembler,
    sys: &mut NewtonSystem,
    s: &mut State,
) -> Result<ConsistentStart, String> {
    let n = model.n_eq;
    // the equations the start solves for: free, active, without an explicit rate
    let mut solve = vec![false; n];
    for (d, dof) in model.dofs.iter().enumerate() {
        if let Some(e) = dof.eq {
            solve[e] = s.is_active(model, d) && !dof.v0_explicit;
        }
    }
    let solved = solve.iter().filter(|x| **x).count();
    let scale = rate_scales(model, super::statics::coord_scale(model));
    let vmax =
        s.v.iter()
            .zip(&scale)
            .fold(0.0f64, |m, (v, sc)| m.max(v.abs() / sc));
    let mut done = ConsistentStart {
        solved,
        ..ConsistentStart::default()
    };
    if solved == 0 || vmax == 0.0 {
        return Ok(done);
    }
    let tau = PROBE / vmax;
    // K v0 by a central difference of the static residual along the initial motion
    let mut kv = vec![0.0; n];
    for (sign, w) in [(1.0, 0.5 / tau), (-1.0, -0.5 / tau)] {
        let moved = along(model, s, sign * tau);
        sys.evaluate_async(model, asm, &moved, Coeffs::statics(1.0), false)
            .await
            .map_err(|e| e.to_string())?;
        for ((k, r), on) in kv.iter_mut().zip(&sys.r).zip(&solve) {
            if *on {
                *k += w * r;
            }
        }
    }
    if kv.iter().any(|k| !k.is_finite()) {
        return Err("the residual is not finite near the initial state".to_string());
    }
    let kv0 = super::linear::norm_inf(&kv);
    if kv0 == 0.0 {
        return Ok(done);
    }
    // K and the mass diagonal at the initial configuration (a failed factorization of
    // either alone is expected: the assembled values are what is wanted)
    let mut at_rest = s.clone();
    at_rest.v.iter_mut().for_each(|v| *v = 0.0);
    at_rest.a.iter_mut().for_each(|a| *a = 0.0);
    let _ = sys
        .evaluate_async(model, asm, &at_rest, Coeffs::dynamic(0.0, 0.0, 1.0), true)
        .await;
    let m_values = sys.values.clone();
    let mass: Vec<f64> = (0..n)
        .map(|e| sys.pattern.slot(e, e).map_or(0.0, |k| m_values[k].abs()))
        .collect();
    let _ = sys
        .evaluate_async(model, asm, &at_rest, Coeffs::statics(1.0), true)
        .await;
    let k = sys.values.clone();
    let weights = weights(model, &solve, &mass);
    let (mut ksum, mut wsum) = (0.0, 0.0);
    for e in (0..n).filter(|e| solve[*e] && weights[*e] > 0.0) {
        if let Some(slot) = sys.pattern.slot(e, e) {
            ksum += k[slot].abs();
            wsum += weights[e];
        }
    }
    if ksum == 0.0 || wsum == 0.0 {
        // nothing stiff, or nothing with mass, among the coordinates to solve for
        return Ok(done);
    }
    let eps = EPS_REL * ksum / wsum;
    // K + ε W on the solved equations, the identity on the others
    let (cp, ri) = (sys.pattern.col_ptr(), sys.pattern.row_idx());
    let mut a = k.clone();
    sys.pattern.identity_outside(&mut a, &solve);
    for e in (0..n).filter(|e| solve[*e]) {
        if let Some(slot) = sys.pattern.slot(e, e) {
            a[slot] += eps * weights[e];
        }
    }
    let mut lu = sys.new_lu();
    // the cause named as statics names it: on a fine mesh the stiffness alone (unlike a
    // step's matrix, which its mass regularises) is past the LU's condition limit (the
    // four-bar on 1 500 elements, a probe in session 48, read "a coordinate with neither
    // stiffness nor mass?")
    lu.factor(&a).map_err(|e| {
        format!(
            "the stiffness of the coordinates without an initial rate cannot be factored \
             ({e}): it is singular to working precision (condition estimate above {:e}), \
             as when a coordinate has neither stiffness nor mass, or in a model of {} \
             coordinates whose stiffest and softest directions differ by more (many \
             elements, or EA far above EI/L²): fewer elements may solve it, or start \
             without `consistent_velocity`",
            crate::linalg::SINGULAR_COND_LIMIT,
            model.n_eq
        )
    })?;
    // K restricted to the solved equations, for K δ
    let mut kuu = k;
    for j in 0..n {
        for slot in cp[j]..cp[j + 1] {
            if !(solve[ri[slot]] && solve[j]) {
                kuu[slot] = 0.0;
            }
        }
    }
    let mut delta = vec![0.0; n];
    let mut r = kv.clone();
    let mut kd = vec![0.0; n];
    let mut step = vec![0.0; n];
    loop {
        let left = super::linear::norm_inf(&r) / kv0;
        done.strain_rate_left = left;
        if left <= STRAIN_RATE_LEFT || done.passes == MAX_PASSES {
            break;
        }
        for (x, ri) in step.iter_mut().zip(&r) {
            *x = -ri;
        }
        lu.try_solve_in_place(&mut step)
            .map_err(|e| format!("the consistent-velocity solve failed: {e}"))?;
        for (d, x) in delta.iter_mut().zip(&step) {
            *d += x;
        }
        sys.pattern.mul_vec(&kuu, &delta, &mut kd);
        for ((ri, k0), kx) in r.iter_mut().zip(&kv).zip(&kd) {
            *ri = k0 + kx;
        }
        done.passes += 1;
    }
    let mut largest = 0.0f64;
    for (d, dof) in model.dofs.iter().enumerate() {
        if let Some(e) = dof.eq {
            if solve[e] {
                s.v[d] += delta[e];
                largest = largest.max(delta[e].abs() / scale[d]);
            }
        }
    }
    done.largest_change = largest / vmax;
    let v0: Vec<f64> = {
        let mut v0 = vec![0.0; n];
        for (d, dof) in model.dofs.iter().enumerate() {
            if let Some(e) = dof.eq {
                v0[e] = s.v[d] - delta[e];
            }
        }
        v0
    };
    let energy = |x: &[f64], mx: &mut Vec<f64>| {
        sys.pattern.mul_vec(&m_values, x, mx);
        x.iter().zip(mx.iter()).map(|(a, b)| a * b).sum::<f64>()
    };
    let (e_change, e_given) = (energy(&delta, &mut kd), energy(&v0, &mut kd));
    done.kinetic_share = match e_given > 0.0 {
        true => e_change / e_given,
        false => f64::INFINITY,
    };
    Ok(done)
}

/// Every joint and body coordinate, with whether it is an angle: hinge angles and the
/// coordinates of the bodies' chains (translations are not angles).
fn joint_coordinates(model: &Model) -> impl Iterator<Item = (usize, bool)> + '_ {
    let hinges = model.hinges.iter().map(|h| (h.dof, true));
    let bodies = model.bodies.iter().flat_map(|b| {
        b.chain
            .iter()
            .map(|l| (l.dof(), !matches!(l, ChainLink::Translate { .. })))
    });
    hinges.chain(bodies)
}

/// W of the module doc by equation: the largest mass-matrix diagonal for a joint or body
/// coordinate, the coordinate's own diagonal times [`NODE_WEIGHT`] for a beam node's. Not
/// a joint coordinate's own diagonal: a hinge angle alone turns only its end node (the
/// other nodes have coordinates of their own), so its diagonal is that node's small
/// rotary inertia, and a beam on a free hinge would be turned to spare its nodes'
/// weights. A massless node coordinate takes the smallest positive diagonal.
fn weights(model: &Model, solve: &[bool], mass: &[f64]) -> Vec<f64> {
    let mut joint = vec![false; model.n_eq];
    for (d, _) in joint_coordinates(model) {
        if let Some(e) = model.dofs[d].eq {
            joint[e] = true;
        }
    }
    let solved = || mass.iter().zip(solve).filter(|(m, on)| **on && **m > 0.0);
    let floor = solved().fold(f64::INFINITY, |f, (m, _)| f.min(*m));
    let floor = if floor.is_finite() { floor } else { 0.0 };
    let heaviest = solved().fold(0.0f64, |f, (m, _)| f.max(*m));
    (0..model.n_eq)
        .map(|e| {
            if joint[e] {
                heaviest
            } else {
                NODE_WEIGHT * if mass[e] > 0.0 { mass[e] } else { floor }
            }
        })
        .collect()
}

/// The rate of each coordinate that moves the model as much as a rotation of 1 rad/s:
/// 1 for angles and spin components (free or driven), the model's size for translations.
fn rate_scales(model: &Model, coord_scale: f64) -> Vec<f64> {
    let mut scale = vec![coord_scale.max(f64::MIN_POSITIVE); model.dofs.len()];
    for sp in &model.spins {
        sp.dofs.iter().for_each(|&d| scale[d] = 1.0);
    }
    for (d, angle) in joint_coordinates(model) {
        if angle {
            scale[d] = 1.0;
        }
    }
    scale
}

/// `s` moved by `dt` along its velocity, free and driven coordinates alike (at the same
/// time t, so a load's time factor does not change), at rest.
fn along(model: &Model, s: &State, dt: f64) -> State {
    let mut m = s.clone();
    let dx: Vec<f64> = {
        let mut dx = vec![0.0; model.n_eq];
        for (d, dof) in model.dofs.iter().enumerate() {
            if let Some(e) = dof.eq {
                dx[e] = dt * s.v[d];
            }
        }
        dx
    };
    joint::apply_increment(model, &mut m, &dx);
    for (d, dof) in model.dofs.iter().enumerate() {
        if matches!(dof.mode, DofMode::Driven(_)) {
            m.q[d] += dt * s.v[d];
        }
    }
    m.v.iter_mut().for_each(|v| *v = 0.0);
    m.a.iter_mut().for_each(|a| *a = 0.0);
    joint::update_kinematics(model, &mut m);
    m
}

#[cfg(test)]
mod tests {
    use super::consistent_velocity;
    use crate::assembly::Assembler;
    use crate::joint::State;
    use crate::model::{compile_str, Model};
    use crate::solver::batch::block_on;
    use crate::solver::linear::NewtonSystem;

    fn compile(text: &str) -> Model {
        compile_str(text, "start-test.toml", &[]).unwrap_or_else(|e| panic!("{e}"))
    }

    /// The initial velocity of `model` after the consistent start.
    fn started(model: &Model) -> (State, super::ConsistentStart) {
        let asm = Assembler::new(model);
        let mut s = State::new(model);
        let mut sys = NewtonSystem::new(model, &asm, &s).unwrap();
        let r = block_on(consistent_velocity(model, &asm, &mut sys, &mut s)).unwrap();
        (s, r)
    }

    const BEAM: &str = r#"
[sections.s]
EA = 1e7
EIy = 1e3
EIz = 2e3
GJ = 8e2
rhoA = 2.0
rhoIy = 1e-3
rhoIz = 1e-3

[[nodes]]
name = "a"
position = [0, 0, 0]
[[nodes]]
name = "b"
position = [1.5, 0.3, 0]

[[beams]]
name = "beam"
from = "a"
to = "b"
elements = 4
section = "s"
"#;

    #[test]
    fn a_beam_on_a_hub_spinning_at_the_start_gets_the_rigid_rotation() {
        // The hub's drive has rate Ω at t = 0 and the beam's nodes are left at rest: the
        // strain-free velocity is the rigid rotation the `[initial] angular_velocity`
        // field writes down in closed form (v = Ω × x, ω = Ω). The difference is the
        // central difference's and the ε M term's (both far below 1e-6 of ΩL).
        let hub = r#"
[[bodies]]
name = "hub"
position = [0, 0, 0]
mass = 1.0
inertia = [1, 1, 1]
  [[bodies.dofs]]
  type = "rotation"
  axis = [0, 0, 1]
  drive = "3*t + t^2"

[[joints]]
name = "clamp"
node = "a"
body = "hub"
type = "rigid"
"#;
        let m = compile(&format!("{BEAM}{hub}"));
        let (s, r) = started(&m);
        let rigid = compile(&format!(
            "{BEAM}{hub}\n[initial]\nangular_velocity = [0, 0, 3]\n"
        ));
        let want = State::new(&rigid);
        let worst =
            s.v.iter()
                .zip(&want.v)
                .fold(0.0f64, |w, (a, b)| w.max((a - b).abs()));
        assert!(worst < 1e-6 * 3.0 * 1.53, "{worst:e}");
        assert!(r.largest_change > 0.9, "{r:?}");
        assert!(want.v.iter().any(|v| v.abs() > 1.0));
    }

    #[test]
    fn a_hinged_beam_on_a_moving_cart_translates_and_its_free_hinge_keeps_its_rate() {
        // Only the cart's rate is set. The beam hangs on a free hinge, a motion no
        // stiffness resists: the start must leave its rate at the given 0 and carry the
        // beam along with the cart (no strain), not leave it at rest. The node weights
        // (1e-4 of a joint's) still pull the hinge by that share: measured 1.1e-4 rad/s
        // against the 1.3 rad/s that would carry the beam's tip at the cart's speed,
        // hence 1e-3 of the cart's rate.
        let cart = r#"
[[bodies]]
name = "cart"
position = [0, 0, 0]
mass = 1.0
inertia = [1, 1, 1]
  [[bodies.dofs]]
  type = "translation"
  axis = [1, 0, 0]
  initial_rate = 2.0

[[joints]]
name = "pin"
node = "a"
body = "cart"
type = "hinge"
axis = [0, 0, 1]
"#;
        let m = compile(&format!("{BEAM}{cart}"));
        let (s, r) = started(&m);
        let name = |d: usize| m.dofs[d].name.as_str();
        for (d, v) in s.v.iter().enumerate() {
            let want = if name(d).ends_with(".x") || name(d).starts_with("cart") {
                2.0
            } else {
                0.0
            };
            assert!((v - want).abs() < 2e-3, "{}: {v} (want {want})", name(d));
        }
        assert_eq!(r.solved, m.n_eq - 1);
        assert!(r.strain_rate_left < 1e-10, "{r:?}");
    }

    #[test]
    fn nothing_moving_leaves_the_model_at_rest() {
        let m = compile(&format!(
            "{BEAM}\n[[supports]]\nnode = \"a\"\ntype = \"clamped\"\n"
        ));
        let (s, r) = started(&m);
        assert!(s.v.iter().all(|v| *v == 0.0));
        assert_eq!(r.largest_change, 0.0);
    }
}
