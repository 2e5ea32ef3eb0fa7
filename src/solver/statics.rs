//! Statics: Newton iterations with automatic load stepping (the step grows after easy
//! increments, halves after a failed one), large rotations through multiplicative updates.

use super::linear::{norm_inf, Convergence, NewtonSystem};
use crate::assembly::{Assembler, Coeffs};
use crate::joint::{self, State};
use crate::model::Model;

#[derive(Debug, thiserror::Error)]
pub enum StaticsError {
    #[error(
        "statics did not converge: stalled at load factor {lambda:.6} after {iterations} \
         Newton iterations in {steps} load steps (worst residual {residual:.3e} at dof \
         `{dof}`, [solver] tol = {tol:e}){cause}"
    )]
    NoConvergence {
        lambda: f64,
        residual: f64,
        dof: String,
        iterations: usize,
        steps: usize,
        tol: f64,
        /// why Newton could not proceed where that is known (empty otherwise)
        cause: String,
    },
    #[error(
        "statics: {situation}: free motion{plural} (coordinate: share) {motions}. Hold the \
         model (supports, drivers, a hinge stiffness) or give it stiffness in these \
         directions{hint}"
    )]
    FreeMotion {
        motions: String,
        plural: &'static str,
        /// where the motion was found free: [`NOT_HELD_AT_REFERENCE`] or
        /// [`NOT_HELD_AT_SOLUTION`]
        situation: &'static str,
        hint: &'static str,
    },
    #[error(
        "statics: limit point at load factor {lambda:.6} (the loads reached are {lambda:.6} × \
         the model's loads): the tangent stiffness there {what}, so the structure cannot \
         carry more load along this path (buckling or snap-through){element}"
    )]
    LimitPoint {
        lambda: f64,
        what: String,
        /// an element beyond its small-deformation range there (empty if none)
        element: String,
    },
    #[error(
        "statics interrupted (SIGINT, SIGTERM or SIGHUP) at load factor {lambda:.6}, before \
         the equilibrium under the full loads"
    )]
    Interrupted { lambda: f64 },
    #[error("linear solver: {0}")]
    Linear(#[from] crate::linalg::LinalgError),
}

#[derive(Debug, Clone)]
pub struct StaticsReport {
    pub load_steps: usize,
    pub newton_iterations: usize,
    pub rejected_steps: usize,
    /// notes on the solution that do not stop it (an element deformed beyond the
    /// element's small-deformation range: [`crate::assembly::deformation_angle_warning`])
    pub warnings: Vec<String>,
}

/// No load step converged from the reference, whose stiffness is singular. Newton did
/// start there (see [`SINGULAR_SHIFT`]), so the message says it found no equilibrium,
/// not that it could not start (as it did until session 47).
pub const NOT_HELD_AT_REFERENCE: &str = "the stiffness is singular at the reference state (a \
     mechanism or a body that is not held), and Newton, started from it by steps that only \
     strain the structure, found no equilibrium under the loads, nor did a damped relaxation \
     from it";
/// What the loads leave free where Newton converged from a singular reference.
pub const NOT_HELD_AT_SOLUTION: &str = "the loads do not hold the model: the stiffness at the \
     equilibrium found is singular (a mechanism or a body that is not held)";
/// A load-held mechanism far from its reference is the case Newton's linear update of the
/// nodes does not reach (a hinged beam pushed through 0.8 rad on 32 elements: a swing
/// clipped to 0.5 rad stretches it 12 %); [`relax`] reaches most such (see its tests),
/// and where it too fails the advice names the case.
const FAR_SWING_HINT: &str = "; if the loads do hold it, but far from the reference (a hinged \
     member they swing through a large angle), start the model nearer that equilibrium";

/// The equilibrium found holds every point, but members may turn about their own axes
/// at no cost (see `solve_until`).
pub const NEUTRAL_TURN: &str = "the equilibrium is neutral in a turn: a member can turn about \
     its own axis with no stiffness and no work of the loads (a straight beam under a \
     spherical joint), so the positions are determined but that turn is not; `modes` lists \
     it at 0 Hz; a torsional spring or a hinge in place of the joint holds it";

/// Largest angle change of one Newton iteration [rad].
pub const MAX_NEWTON_ANGLE: f64 = 0.5;

/// Newton corrections after the first adding up to more than this multiple of the first
/// (the tangent prediction) mean a jump to another equilibrium branch. Quadratic
/// convergence from a good prediction travels less than the prediction; large-rotation
/// steps that need more travel are simply halved.
pub const BRANCH_JUMP: f64 = 10.0;

/// Newton at a fixed load factor; returns iterations used, or None if it diverged.
pub fn newton(
    model: &Model,
    asm: &Assembler,
    sys: &mut NewtonSystem,
    s: &mut State,
    lambda: f64,
    mut shift: Option<&mut bool>,
) -> Result<Option<usize>, StaticsError> {
    let c = Coeffs::statics(lambda);
    let mut dx = vec![0.0; model.n_eq];
    let mut conv = Convergence::new(model.solver.tol, asm.eval.unit_roundoff());
    // first (tangent) prediction and the distance Newton travels after it
    let (mut first, mut travel) = (0.0f64, 0.0f64);
    let mut predicted = false;
    // coordinate change of the last correction, and the corrections above the
    // coordinates' round-off (the iterations reported: an unloaded curved mesh takes one
    // correction at round-off and is still the reference configuration)
    let mut last_correction = f64::INFINITY;
    // the correction at the last state whose residual passed but whose correction did not
    let mut pending = None;
    let mut counted = 0;
    let roundoff = Convergence::ROUNDOFF_CORRECTION * asm.eval.unit_roundoff() * coord_scale(model);
    // whether the last factor was of the shifted tangent (see `SINGULAR_SHIFT`)
    let mut shifted_factor = false;
    // whether the last correction was such a step
    let mut last_shifted = false;
    for _ in 0..model.solver.max_iter.max(1) {
        joint::update_kinematics(model, s);
        let (info, factored) = match shift.as_deref_mut() {
            Some(_) => {
                let (info, factor) = sys.evaluate_shifting(model, asm, s, c, SINGULAR_SHIFT);
                shifted_factor = factor == Some(false);
                (info, factor.is_some())
            }
            None => match sys.evaluate(model, asm, s, c, true) {
                Ok(i) => (Some(i), true),
                Err(_) => (None, false),
            },
        };
        let res = norm_inf(&sys.r);
        if !res.is_finite() {
            return Ok(None);
        }
        // a singular Jacobian does not matter once the residual is converged (a stiff
        // model at zero load, EA = 1e18: the residual is exactly 0)
        let scale = info.map_or(0.0, |i| i.force_scale);
        // or a residual that stopped falling after a correction below the coordinates'
        // round-off: no representable state is closer to equilibrium (the stress-free
        // reference of a curved mesh at zero load, whose residual is round-off of the
        // element forces with no force scale to compare to). The correction is applied
        // first: on a stiff model (EI = 1e14 under 1 N) the whole deflection is a few
        // ulps of the coordinates, and returning before it reported the unloaded state,
        // reactions 0
        // (not after a step without the free motions: its residual along them is what
        // that step leaves, not round-off; a free beam under a tip force "converged"
        // at tiny loads that way)
        let stalled =
            !last_shifted && conv.stalled_at_roundoff(last_correction, coord_scale(model));
        if (conv.converged(res, scale)
            && (!factored || settled(model, sys, &mut dx, first + travel, roundoff, &mut pending)))
            || stalled
        {
            return Ok(crate::assembly::deformation_in_range(model, s).then_some(counted));
        }
        let solved = if shifted_factor {
            sys.solve_neg_residual_without_free(&mut dx, SINGULAR_SHIFT)
        } else {
            sys.solve_neg_residual(&mut dx)
        };
        if !factored || solved.is_err() {
            return Ok(None);
        }
        crate::assembly::limit_rotation_step(model, &mut dx, MAX_NEWTON_ANGLE);
        let step = norm_inf(&dx);
        last_correction = step;
        last_shifted = shifted_factor;
        if step > roundoff {
            counted += 1;
            // a correction the tangent itself could not give (a zero-load mechanism at
            // rest takes none, and its reference is its equilibrium, as before)
            if let Some(used) = shift.as_deref_mut() {
                *used |= shifted_factor;
            }
        }
        if shifted_factor {
            // a step without the free motions is no tangent prediction of the path: the
            // first one the tangent itself gives is (a pendulum tilted from hanging
            // swings back by its whole tilt there)
        } else if !predicted {
            first = step;
            predicted = true;
        } else {
            travel += step;
            // Newton has gone far beyond the tangent prediction: past a limit point it
            // jumps to another equilibrium branch (a shallow arch snapping through under
            // load control), which would be reported as if the path were continuous;
            // reject, the smaller step either follows the path or ends at the limit
            if travel > BRANCH_JUMP * first {
                return Ok(None);
            }
        }
        joint::apply_increment(model, s, &dx);
    }
    joint::update_kinematics(model, s);
    Ok(None)
}

/// Whether the Newton correction at a state whose residual passed the force test is
/// also small: at most `tol` of the distance this solve has moved the coordinates
/// (`moved`), or their round-off. The residual is judged against the largest force, so
/// a small load beside a large one can be wholly unconverged: a cantilever under 200 N
/// axially and 1e-6 N across stopped after the first correction, its transverse
/// residual 3e-9 of the axial force, with the tip deflection 79 % off the beam-column
/// formula (the axial load's geometric stiffness not yet applied to it). The factor at
/// that state is at hand, so the test costs one solve; where it fails Newton goes on,
/// and `pending` keeps that correction. A correction that then no longer falls below
/// half the pending one is the solve's round-off, not an unconverged load (an
/// ill-conditioned K turns the residual's noise into corrections above the coordinates'
/// round-off): settled too, so the test never turns a converged solve into a failed
/// one. It is compared with the pending correction, not the last one: at EA = 1e9 the
/// first correction (the axial shortening, 2.4e-7 m) and the second (the side load's
/// deflection under the axial force, 1.9e-7) are of one size, and a comparison with the
/// first stopped at the linear deflection, 36× too small near the buckling load.
fn settled(
    model: &Model,
    sys: &mut NewtonSystem,
    dx: &mut [f64],
    moved: f64,
    roundoff: f64,
    pending: &mut Option<f64>,
) -> bool {
    if sys.solve_neg_residual(dx).is_err() {
        return true;
    }
    crate::assembly::limit_rotation_step(model, dx, MAX_NEWTON_ANGLE);
    let step = norm_inf(dx);
    if step <= (model.solver.tol * moved).max(roundoff) || pending.is_some_and(|p| step > 0.5 * p) {
        return true;
    }
    *pending = Some(step);
    false
}

/// Largest distance of a node from the first: the size of the model's coordinates.
pub(crate) fn coord_scale(model: &Model) -> f64 {
    model.x0.first().map_or(1.0, |o| {
        model.x0.iter().fold(1.0f64, |m, x| {
            m.max(crate::math::norm(crate::math::sub(*x, *o)))
        })
    })
}

/// A tangent that is singular at the reference (a hinged beam hanging under its weight,
/// a four-bar standing in gravity: mechanisms whose stiffness along the motion comes
/// only from the axial forces the loads cause) cannot start Newton, though the loads
/// hold it: the reference has no axial force yet. Newton's steps from the reference then
/// factor the tangent with this share of each diagonal entry added to it, and each such
/// step is taken without its part along the free motions
/// ([`NewtonSystem::solve_neg_residual_without_free`]): it only strains the structure,
/// after which the axial forces stiffen (or, compressed, destabilise) the motion and
/// Newton goes on with the tangent itself. Small against every real stiffness
/// after the LU's unit scaling, far above the LU's singularity limit (n ε); an error in
/// the soft directions of the one shifted step is Newton's to correct. A motion still
/// free at the solution is reported as before (see `solve_until`).
pub const SINGULAR_SHIFT: f64 = 1e-6;

/// First load steps that may fail on the shifted tangent (see `solve_until`) before the
/// solve stops halving and diagnoses: the full load, a half and a quarter.
const SHIFTED_TRIES: usize = 3;

/// Most load steps (accepted + rejected) of one solve: 20 halvings below the smallest
/// step are already a stall; this bounds a solve that creeps at tiny steps (each
/// converging, none growing) instead of letting it run for 1e7 steps.
pub const MAX_LOAD_STEPS: usize = 10_000;

/// Load steps over which the progress of λ is measured for the creep test.
const CREEP_WINDOW: usize = 1000;
/// Load stepping: the increment grows by this factor after an easy step (Newton in at most
/// `EASY_STEP_ITERS` iterations), is halved after a failed one, and the stepping gives up
/// below `MIN_LOAD_STEP` (a fraction of the full load).
const LOAD_STEP_GROWTH: f64 = 1.5;
const EASY_STEP_ITERS: usize = 5;
const MIN_LOAD_STEP: f64 = 1e-7;

/// [`relax`]: the largest angle one of its steps may turn [rad]. Newton's update moves
/// the nodes of a swinging member along the tangents of their arcs, which stretches it
/// by θ²/2 of its length: 0.165 rad stretched a hinged beam of EA = 1e7 N by 2e5 N where
/// the residual had been 52 N, and the next correction swung it back (session 51). At
/// 0.05 rad the stretch (1.25e-3) is one Newton correction of the stiff directions, and
/// a swing of 1.5 rad takes 30 steps.
const RELAX_ANGLE: f64 = 0.05;
/// [`relax`] gives up once its steps have turned the model through this many radians
/// in all (two whole turns): an equilibrium that far is no equilibrium of this state
/// (a mechanism its loads drive round, which the diagnosis then names).
const RELAX_TURN: f64 = 4.0 * std::f64::consts::PI;
/// [`relax`]'s pseudo-mass: the first one tried [1/s²], and the one below which it is
/// dropped (Newton itself, converging quadratically).
const RELAX_MASS: f64 = 1.0;
const RELAX_MASS_MIN: f64 = 1e-12 * RELAX_MASS;
/// [`relax`] on a model too large to name its free motions (where the reference may be
/// singular only to working precision, not a mechanism) stops after this many steps if
/// they have not turned the model by `RELAX_ANGLE` in all: the cantilever on 6 000
/// elements, which relaxes at 20 % of its residual in three factorizations, took 21 s more
/// to fail without it.
const RELAX_SWING_STEPS: usize = 8;
/// [`relax`]'s iterations at most (a steady 0.05 rad per step covers `RELAX_TURN` in 250).
const RELAX_MAX_ITERS: usize = 2000;

/// Pseudo-transient continuation (Kelley and Keyes 1998) for a mechanism its loads hold
/// far from its reference, where Newton from the reference fails (a hinged beam tilted
/// 0.5 rad from hanging, on 32 elements or more; it had solved on 8 and 16, erratically):
/// each step solves (K + c M) Δ = −r, the mass term slowing the soft motions (the swing)
/// and leaving the stiff ones (stretch, bending) Newton's. c is raised (by the turn's
/// excess over 0.8 `RELAX_ANGLE`, at least twofold; the step solved again) while the step
/// would turn anything by more than `RELAX_ANGLE`, and lowered fourfold after two steps in
/// a row under a quarter of it, down to 0: near the equilibrium the steps are Newton's.
/// The equilibrium reached is the one the structure settles into when released under its
/// loads with its motion damped out (stable where one is near; the report checks it). Once the residual converges, [`newton`] confirms it
/// with the plain tangent. Some(iterations) if it converged, None where it turned through
/// `RELAX_TURN` (or moved points as far), turned nothing in `RELAX_SWING_STEPS` steps
/// (with `swing_test`), ran `RELAX_MAX_ITERS` steps, or Newton at c = 0 failed for
/// `max_iter`.
fn relax(
    model: &Model,
    asm: &Assembler,
    sys: &mut NewtonSystem,
    s: &mut State,
    lambda: f64,
    stop: Option<&std::sync::atomic::AtomicBool>,
    swing_test: bool,
) -> Result<Option<usize>, StaticsError> {
    let mut dx = vec![0.0; model.n_eq];
    let mut conv = Convergence::new(model.solver.tol, asm.eval.unit_roundoff());
    let mut cm = RELAX_MASS;
    let (mut turned, mut plain, mut small) = (0.0f64, 0usize, 0usize);
    let mut last_correction = f64::INFINITY;
    let (mut moved, size) = (0.0f64, coord_scale(model));
    let mut applied = 0;
    for iter in 0..RELAX_MAX_ITERS {
        // (a step a factorization: thousands on a large model, so a signal is heard here)
        if stop.is_some_and(|f| f.load(std::sync::atomic::Ordering::SeqCst)) {
            return Err(StaticsError::Interrupted { lambda: 0.0 });
        }
        joint::update_kinematics(model, s);
        let c = Coeffs {
            cm,
            ..Coeffs::statics(lambda)
        };
        let info = sys.evaluate(model, asm, s, c, true);
        let res = norm_inf(&sys.r);
        if !res.is_finite() {
            return Ok(None);
        }
        let scale = info.as_ref().map_or(0.0, |i| i.force_scale);
        // (or stalled at the coordinates' round-off, as in `newton`: a stiff member's
        // residual has a floor above `tol` there)
        if conv.converged(res, scale) || conv.stalled_at_roundoff(last_correction, size) {
            return Ok(newton(model, asm, sys, s, lambda, None)?.map(|n| iter + n));
        }
        // a pseudo-mass too small to make K + c M regular (a free motion at the state) is
        // raised like one whose step turns too far
        let solved = info.is_ok() && sys.solve_neg_residual(&mut dx).is_ok();
        let turn = crate::assembly::largest_step(model, &dx, true);
        if !solved || !turn.is_finite() || turn > RELAX_ANGLE {
            // where the mass term dominates the turn falls as 1/c: aim at 0.8 of the bound
            let raise = match solved && turn.is_finite() {
                true => (turn / (0.8 * RELAX_ANGLE)).max(2.0),
                false => 4.0,
            };
            cm = if cm == 0.0 {
                RELAX_MASS_MIN
            } else {
                raise * cm
            };
            (plain, small) = (0, 0);
            continue;
        }
        joint::apply_increment(model, s, &dx);
        last_correction = norm_inf(&dx);
        turned += turn;
        moved += crate::assembly::largest_step(model, &dx, false);
        // a member swung through `RELAX_TURN` moves its points by as many lengths of
        // the model at most: a body that went further is not held (it drifts off)
        if turned > RELAX_TURN || moved > RELAX_TURN * size {
            return Ok(None);
        }
        // nothing swings: the reference's singularity may not be a mechanism's (a
        // tangent too ill-conditioned to factor), which the mass term only creeps through
        applied += 1;
        if swing_test && applied == RELAX_SWING_STEPS && turned < RELAX_ANGLE {
            return Ok(None);
        }
        if cm == 0.0 {
            plain += 1;
            if plain >= model.solver.max_iter.max(1) {
                return Ok(None);
            }
        } else if turn < 0.25 * RELAX_ANGLE {
            // two in a row: one alone is the stiff directions' correction after a swing
            // (the stretch it caused), which turns little whatever c is
            small += 1;
            if small >= 2 {
                cm *= 0.25;
                if cm < RELAX_MASS_MIN {
                    cm = 0.0;
                }
            }
        } else {
            small = 0;
        }
    }
    Ok(None)
}

/// Solve for static equilibrium under the full loads, starting from `s`.
pub fn solve(model: &Model, s: &mut State) -> Result<StaticsReport, StaticsError> {
    solve_until(model, s, None)
}

/// [`solve`], ending with [`StaticsError::Interrupted`] before the next load step once
/// `stop` is set (a signal: a large model's statics takes seconds, and its mesh check
/// as long again).
pub fn solve_until(
    model: &Model,
    s: &mut State,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> Result<StaticsReport, StaticsError> {
    let asm = Assembler::new(model);
    let mut sys = NewtonSystem::new(model, &asm, s)?;
    let mut lambda = 0.0;
    let mut dl = 1.0 / model.solver.load_steps.max(1) as f64;
    let mut rep = StaticsReport {
        load_steps: 0,
        newton_iterations: 0,
        rejected_steps: 0,
        warnings: Vec::new(),
    };
    // zero loads (every load and gravity zero or scaled to zero): the reference is the
    // equilibrium, one Newton solve at full load confirms it (0 iterations when it is)
    if loads_vanish(model, &asm, s) {
        dl = 1.0;
    }
    // a solve creeping at a rate that cannot reach λ = 1 within MAX_LOAD_STEPS is a
    // stall now, not after the whole budget (a fuzzer input took 21 s to reach the cap)
    let mut window = (0usize, lambda);
    // whether a Newton step from the reference was taken with a shifted tangent, and how
    // many first steps failed on it
    let mut shifted = false;
    let mut shifted_failures = 0;
    while lambda < 1.0 {
        if stop.is_some_and(|f| f.load(std::sync::atomic::Ordering::SeqCst)) {
            return Err(StaticsError::Interrupted { lambda });
        }
        let used = rep.load_steps + rep.rejected_steps;
        if used >= MAX_LOAD_STEPS {
            return Err(stall(model, &asm, &mut sys, s, (lambda, lambda), &rep));
        }
        if used >= window.0 + CREEP_WINDOW {
            let rate = (lambda - window.1) / (used - window.0) as f64;
            if rate * ((MAX_LOAD_STEPS - used) as f64) < 1.0 - lambda {
                return Err(stall(model, &asm, &mut sys, s, (lambda, lambda), &rep));
            }
            window = (used, lambda);
        }
        let target = (lambda + dl).min(1.0);
        let saved = s.clone();
        // from the reference only: a mechanism that its loads hold (see `SINGULAR_SHIFT`)
        let mut used = false;
        let shift = (rep.load_steps == 0).then_some(&mut used);
        let outcome = newton(model, &asm, &mut sys, s, target, shift)?;
        shifted |= used;
        // A first step that failed on the shifted tangent fails alike at any smaller
        // load: the reference's tangent does not depend on the load, so neither does its
        // conditioning (a cantilever of 6 000 elements, past the LU's condition limit,
        // took 25 shifted iterations at each of 24 halvings, 75 s, to say so), nor does a
        // load-held mechanism's swing when all its loads scale together. After
        // `SHIFTED_TRIES` such failures the solve goes to its diagnosis.
        if outcome.is_none() && used && rep.load_steps == 0 {
            shifted_failures += 1;
        }
        match outcome {
            Some(iters) => {
                lambda = target;
                rep.load_steps += 1;
                rep.newton_iterations += iters;
                if iters <= EASY_STEP_ITERS {
                    dl *= LOAD_STEP_GROWTH;
                }
            }
            None => {
                *s = saved;
                rep.rejected_steps += 1;
                dl *= 0.5;
                if dl < MIN_LOAD_STEP || shifted_failures >= SHIFTED_TRIES {
                    joint::update_kinematics(model, s);
                    let diagnosis = diagnose(model, s, lambda);
                    // no step from the reference, where the model is a mechanism: the
                    // loads may hold it far from there (`relax`, under the full loads at
                    // once, as a released structure feels them). Not where the reference
                    // is only too ill-conditioned to factor, which `relax` would creep
                    // through at a factorization a step (see `RELAX_SWING_STEPS`); a model
                    // too large to name its free motions is told by its first steps' turns
                    let named = matches!(diagnosis, Some(StaticsError::FreeMotion { .. }));
                    if rep.load_steps == 0 && shifted && (named || model.n_eq > MAX_DIAGNOSIS_DOFS)
                    {
                        let start = s.clone();
                        if let Some(iters) = relax(model, &asm, &mut sys, s, 1.0, stop, !named)? {
                            lambda = 1.0;
                            rep.load_steps += 1;
                            rep.newton_iterations += iters;
                            continue;
                        }
                        *s = start;
                        joint::update_kinematics(model, s);
                    }
                    if let Some(e) = diagnosis {
                        return Err(e);
                    }
                    // with no step carried, the residual of the last one tried, which
                    // Newton could not reduce (at λ = 0 it is zero and says nothing);
                    // after some, the one left at the last equilibrium (round-off)
                    let tried = if rep.load_steps == 0 { target } else { lambda };
                    return Err(stall(model, &asm, &mut sys, s, (lambda, tried), &rep));
                }
            }
        }
    }
    joint::update_kinematics(model, s);
    if shifted {
        // the loads must hold what the reference's stiffness did not: a motion still
        // free at the solution leaves the equilibrium undetermined (a free body at rest,
        // a mechanism whose loads do no work along it), which is the error it was
        if sys
            .evaluate(model, &asm, s, Coeffs::statics(1.0), true)
            .is_err()
        {
            match free_motions_unless_turns(model, s, 1.0, true) {
                // members that can turn about their own axes, with no stiffness and no
                // load work along the turn (a straight beam under a spherical joint, a
                // probe in session 48: refused as "not held" while its positions are
                // determined): the equilibrium stands, its turn about those axes does not
                Ok(true) => rep.warnings.push(NEUTRAL_TURN.to_string()),
                Err(Some(e)) => return Err(e),
                Ok(false) | Err(None) if model.n_eq <= MAX_DIAGNOSIS_DOFS => {}
                Ok(false) | Err(None) => rep.warnings.push(
                    "the tangent stiffness at the equilibrium found is singular to working \
                     precision (a motion the loads do not hold, or stiffnesses too far apart \
                     to factor), and the model is too large to name its free motions: the \
                     equilibrium may not be the only one"
                        .to_string(),
                ),
            }
        }
    }
    rep.warnings
        .extend(crate::assembly::deformation_angle_warning(model, s));
    rep.warnings.extend(passed_locks(model, s));
    rep.warnings.extend(unstable(model, &asm, &mut sys, s));
    Ok(rep)
}

/// Newton finds the equilibrium nearest its start, stable or not: the pendulum started
/// past horizontal converged to the inverted state, a column loaded past its buckling
/// load stayed straight, both without a word (found by a probe in session 44). A
/// negative det K at the solution (with no pivot near zero, whose sign would be
/// round-off) means an odd number of negative (real) eigenvalues of the tangent; a
/// symmetric tangent that is not positive definite (no Cholesky factor) also sees an
/// even number (a column of equal bending stiffnesses buckles in both planes at once):
/// either way the equilibrium is unstable. Both judge against 1e-9 of the largest
/// entry, which a stiff or finely meshed column's buckling direction falls below; a
/// symmetric tangent is therefore also searched for a direction of negative stiffness
/// ([`negative_direction`]). Cost: one assembly, two sparse LUs, one sparse Cholesky
/// and 24 solves with the factor.
fn unstable(model: &Model, asm: &Assembler, sys: &mut NewtonSystem, s: &State) -> Option<String> {
    // factored for the Krylov search; a tangent that cannot be factored (a free hinge
    // at rest) leaves the last Newton factor, of a K next to this one, which serves the
    // search as well: only the form of the assembled K itself decides
    sys.evaluate(model, asm, s, Coeffs::statics(1.0), true)
        .or_else(|_| sys.evaluate(model, asm, s, Coeffs::statics(1.0), false))
        .ok()?;
    let sign = sys.symbolic().det_sign_clear(&sys.values, 1e-9).ok()?;
    // (symmetric to 1e-9 of the largest entry: round-off of the assembly, far below the
    // asymmetry of a dead moment's tangent)
    let definite = sys
        .symbolic()
        .symmetric_positive_definite(&sys.values, 1e-9)
        .ok()?;
    let negative = definite.is_some() && model.n_eq > 0 && negative_direction(sys, model.n_eq);
    (sign == Some(-1) || definite == Some(false) || negative).then(|| {
        "the equilibrium found is unstable: the tangent stiffness there is not positive \
         definite (it has negative-stiffness directions), so the structure would leave it \
         (an inverted pendulum, a column past its buckling load); `latdyn modes` names the \
         unstable modes, and `statics --path` follows the loads onto the stable branch"
            .to_string()
    })
}

/// Dimension of the Krylov space of K⁻¹ that [`negative_direction`] searches: the
/// negative eigenvalues of K are the negative end of K⁻¹'s spectrum, which such a space
/// resolves in a few dozen vectors even where a positive direction of smaller |λ| (the
/// torsion of a column, 25 against the buckling's −280 at 3.2 P_cr per unit coordinate)
/// would hold plain inverse iteration.
const KRYLOV_DIMENSION: usize = 24;

/// Whether the symmetric tangent (factored by `sys`) has a direction x with
/// xᵀKx < −64 ε Σ|Kᵢⱼ xᵢ xⱼ|: negative beyond the form's worst-case round-off (the
/// margin of [`crate::solver::modes::DATA_ROUNDOFF`]), which a free hinge's zero
/// stiffness never is. The candidates are the negative Ritz vectors of K on the Krylov
/// space of K⁻¹ (Rayleigh-Ritz; the Lanczos vectors orthogonalised twice). The
/// determinant's sign and the shifted Cholesky judge pivots and eigenvalues against
/// 1e-9 of the largest entry, and a column of EA/EI = 1e8 (or of 64 elements, whose
/// smallest eigenvalue falls as h⁴) puts its buckling direction below that: a probe
/// found columns at 1.05 to 3.2 P_cr passed as stable. Here the form of the assembled K
/// itself decides, so neither the factor's round-off nor the search's can make a stable
/// state unstable. False when the tangent cannot be solved.
fn negative_direction(sys: &mut NewtonSystem, n: usize) -> bool {
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(p, q)| p * q).sum::<f64>();
    // a start with a component along every eigenvector: not a multiple of a symmetric
    // pattern (all ones would miss the antisymmetric buckling mode of a symmetric frame)
    let mut x: Vec<f64> = (0..n)
        .map(|i| 1.0 + 0.5 * ((i as f64) * 0.618_033_988_75).fract())
        .collect();
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for _ in 0..KRYLOV_DIMENSION.min(n) {
        if sys.solve_tangent(&mut x).is_err() {
            break;
        }
        let before = dot(&x, &x).sqrt();
        for _ in 0..2 {
            for b in &basis {
                let d = dot(b, &x);
                x.iter_mut().zip(b).for_each(|(v, w)| *v -= d * w);
            }
        }
        let after = dot(&x, &x).sqrt();
        // nothing new (the space is invariant) or not finite
        if !(after > 1e-10 * before && after.is_finite()) {
            break;
        }
        x.iter_mut().for_each(|v| *v /= after);
        basis.push(x.clone());
    }
    let m = basis.len();
    if m == 0 {
        return false;
    }
    let kb: Vec<Vec<f64>> = basis
        .iter()
        .map(|b| {
            let mut y = vec![0.0; n];
            sys.pattern.mul_vec(&sys.values, b, &mut y);
            y
        })
        .collect();
    let mut t = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..m {
            t[i * m + j] = dot(&basis[i], &kb[j]);
        }
    }
    let Ok((ritz, z)) = crate::linalg::sym_eig(&t, m) else {
        return false;
    };
    (0..m).take_while(|&k| ritz[k] < 0.0).any(|k| {
        let mut y = vec![0.0; n];
        for (j, b) in basis.iter().enumerate() {
            let c = z[k * m + j];
            y.iter_mut().zip(b).for_each(|(v, w)| *v += c * w);
        }
        let (q, size) = sys.pattern.quadratic_form(&sys.values, &y);
        q < -crate::solver::modes::DATA_ROUNDOFF * size
    })
}

/// Hinges whose angle went from the reference to the equilibrium across their
/// `lock_angle`: one equilibrium under the full loads does not see a lock, which is an
/// event along the way (`statics --path` follows the loads and locks there), so its
/// numbers past a lock are those of a hinge that never locked.
fn passed_locks(model: &Model, s: &State) -> Vec<String> {
    model
        .hinges
        .iter()
        .filter_map(|h| {
            let la = h.lock_angle?;
            h.reaches_lock_angle(model.dofs[h.dof].q0, s.q[h.dof])
                .then(|| {
                    format!(
                        "hinge `{}` turned past its lock angle ({la:.6} rad) to {:.6} rad: one \
                     equilibrium under the full loads does not lock hinges, so these numbers \
                     are those of a hinge that never locked; `statics --path` follows the \
                     loads and locks it where it reaches the angle",
                        h.name, s.q[h.dof]
                    )
                })
        })
        .collect()
}

/// Whether the applied loads are all zero: the residual at full load equals the one at
/// zero load bit for bit.
fn loads_vanish(model: &Model, asm: &Assembler, s: &State) -> bool {
    let mut s0 = s.clone();
    joint::update_kinematics(model, &mut s0);
    let n = model.dofs.len();
    let (mut g0, mut g1) = (vec![0.0; n], vec![0.0; n]);
    asm.evaluate(model, &s0, Coeffs::statics(0.0), &mut g0, None);
    asm.evaluate(model, &s0, Coeffs::statics(1.0), &mut g1, None);
    g0 == g1
}

fn stall(
    model: &Model,
    asm: &Assembler,
    sys: &mut NewtonSystem,
    s: &mut State,
    (lambda, tried): (f64, f64),
    rep: &StaticsReport,
) -> StaticsError {
    joint::update_kinematics(model, s);
    let target = tried.max(f64::MIN_POSITIVE);
    // a tangent that cannot be factored stops Newton before its first iteration; the
    // residual then says nothing of why (a mesh of 3 000 elements of the shipped
    // cantilever: condition above the LU's limit, "stalled ... residual 2.2e-308")
    let evaluated = sys.evaluate(model, asm, s, Coeffs::statics(target), true);
    let (worst, val) = worst_dof(model, &sys.r);
    let cause = match evaluated {
        _ if !val.is_finite() => super::FORCES_NOT_FINITE.to_string(),
        Err(e) => format!(
            "; the tangent stiffness could not be factored ({e}): it is singular to working \
             precision (condition estimate above {:e}), as a mechanism's is, or as that of \
             a model of {} coordinates whose stiffest and softest directions differ by more \
             (many elements, or EA far above EI/L²): fewer elements may solve it",
            crate::linalg::SINGULAR_COND_LIMIT,
            model.n_eq
        ),
        // nothing carried at all: round-off is not the reason (a gravity of 1e30 read
        // "residual 5.6e-279 ... a tolerance below the model's round-off")
        Ok(_) if lambda == 0.0 && rep.load_steps == 0 => format!(
            "; Newton diverged from the start at every load step down to {:.1e} of the \
             load: even that much deforms the structure too far for Newton to \
             converge from its reference shape, so the loads (or gravity) are likely far \
             beyond what it carries, or a stiffness far too small; check their magnitudes",
            // the smallest step tried (below `MIN_LOAD_STEP` after halving, a quarter of
            // the load after `SHIFTED_TRIES`)
            tried - lambda
        ),
        // converged here, and `diagnose` found the tangent neither singular nor
        // indefinite: what stopped the steps lies beyond this state, not in the tolerance
        // (a column twisted by a tip torque on 4 elements stalled at 0.8 "residual
        // 8.5e-14 ... tol = 1e-8; a tolerance below the model's round-off"; a probe,
        // session 47)
        Ok(info) if val <= model.solver.tol * info.force_scale => {
            let element = crate::assembly::largest_deformation_angle(model, s)
                .filter(|d| d.angle > crate::assembly::DEFORMATION_ANGLE_WARN)
                .map(|d| {
                    format!(
                        "; element {} of beam `{}` ({} elements) is already turned {:.3} rad \
                         from its chord here, beyond its small-deformation range: more \
                         elements on that beam may pass",
                        d.index_in_beam, d.beam, d.beam_elements, d.angle
                    )
                })
                .unwrap_or_default();
            format!(
                "; the equilibrium at this load factor is converged and its stiffness is \
                 neither singular nor unstable, but Newton converged at no load step beyond \
                 it down to {MIN_LOAD_STEP:e} of the load: the path turns too sharply there \
                 (a snap, a bifurcation), which `statics --path` follows{element}"
            )
        }
        Ok(_) => "; a tolerance below the model's round-off cannot be reached".to_string(),
    };
    StaticsError::NoConvergence {
        lambda,
        residual: val,
        dof: worst,
        iterations: rep.newton_iterations,
        steps: rep.load_steps + rep.rejected_steps,
        tol: model.solver.tol,
        cause,
    }
}

/// Dense tangent at `s` and load factor `lambda`, Jacobi-scaled: D K D with
/// D = diag(1/√|K_ii|), so that a graded model (EA 1e16 times the bending stiffness) does
/// not hide its soft directions below a relative threshold. Returns (scaled K, D).
fn scaled_tangent(model: &Model, s: &State, lambda: f64) -> (Vec<f64>, Vec<f64>) {
    let asm = Assembler::new(model);
    let n = model.n_eq;
    let mut gen = vec![0.0; model.dofs.len()];
    let mut k = vec![0.0; n * n];
    asm.evaluate(
        model,
        s,
        Coeffs::statics(lambda),
        &mut gen,
        Some(&mut crate::assembly::DenseSink { n, a: &mut k }),
    );
    let d = crate::linalg::jacobi_scale(&mut k, n, |a| 1.0 / a.sqrt());
    (k, d)
}

/// Eigenvalues of the scaled tangent at or below this (its diagonal is 1, so its largest
/// eigenvalue is O(1)..O(coordinates per node)) are free motions: 1e-8 is far above the
/// round-off of a stiffness assembled from terms of relative error ~1e-14, and far below
/// any real stiffness ratio after Jacobi scaling.
const FREE_MOTION_TOL: f64 = 1e-8;

/// Largest model (free coordinates) whose failed statics gets the dense free-motion /
/// limit-point diagnosis (two n×n symmetric eigendecompositions); larger ones report the
/// stall only.
pub const MAX_DIAGNOSIS_DOFS: usize = 1500;

/// The tangent at the last converged state is at a limit point when its smallest scaled
/// eigenvalue fell below this fraction of the unloaded one: step halving stops within 1e-7
/// of the load factor of a fold, where the eigenvalue ∝ √(λ_c − λ) is ~1e-3 of its
/// unloaded size.
const LIMIT_SOFTENING: f64 = 0.05;

/// Why statics failed: a free motion at the reference (λ = 0), or a limit point (the
/// tangent singular or indefinite at the last converged state). None if neither.
fn diagnose(model: &Model, s: &State, lambda: f64) -> Option<StaticsError> {
    let n = model.n_eq;
    // dense diagnosis only up to a size whose two eigendecompositions take seconds
    if n == 0 || n > MAX_DIAGNOSIS_DOFS {
        return None;
    }
    let (k, d) = scaled_tangent(model, s, lambda);
    let (ev, vecs) = crate::linalg::sym_eig(&k, n).ok()?;
    let scale = ev.iter().fold(0.0f64, |a, b| a.max(b.abs())).max(1e-300);
    let free: Vec<usize> = (0..n)
        .filter(|&j| ev[j].abs() <= FREE_MOTION_TOL * scale)
        .collect();
    if lambda == 0.0 {
        return name_free_motions(
            model,
            &free,
            &vecs,
            &d,
            NOT_HELD_AT_REFERENCE,
            FAR_SWING_HINT,
        );
    }
    let min = ev.first().copied().unwrap_or(0.0);
    // the reference state's smallest scaled eigenvalue: the stiffness before the loads
    let s_ref = State::new(model);
    let (k0, _) = scaled_tangent(model, &s_ref, 0.0);
    let min0 = crate::linalg::sym_eig(&k0, n)
        .ok()?
        .0
        .first()
        .copied()
        .unwrap_or(0.0);
    // an element past its range softens (its end moments follow sin 2θ / 2): a limit
    // point there may be the element's, not the structure's
    let element = crate::assembly::largest_deformation_angle(model, s)
        .filter(|d| d.angle > crate::assembly::DEFORMATION_ANGLE_WARN)
        .map(|d| {
            format!(
                ". But element {} of beam `{}` ({} elements) is turned {:.3} rad from its \
                 chord there, beyond its small-deformation range, where its measure of the \
                 angles softens its end moments by about {:.0} %: the limit may be the \
                 element's, not the structure's (more elements on that beam tell)",
                d.index_in_beam,
                d.beam,
                d.beam_elements,
                d.angle,
                100.0 * d.force_error()
            )
        })
        .unwrap_or_default();
    if min < -FREE_MOTION_TOL * scale {
        Some(StaticsError::LimitPoint {
            lambda,
            element: element.clone(),
            what: format!(
                "has a negative eigenvalue (scaled {min:.2e}): the equilibrium path is past \
                 a limit or bifurcation point"
            ),
        })
    } else if !free.is_empty() || (min0 > 0.0 && min < LIMIT_SOFTENING * min0) {
        Some(StaticsError::LimitPoint {
            lambda,
            element: element.clone(),
            what: format!(
                "is (nearly) singular: its smallest scaled eigenvalue fell to {min:.2e} from \
                 {min0:.2e} unloaded"
            ),
        })
    } else {
        None
    }
}

fn name_free_motions(
    model: &Model,
    free: &[usize],
    vecs: &[f64],
    d: &[f64],
    situation: &'static str,
    hint: &'static str,
) -> Option<StaticsError> {
    let n = model.n_eq;
    if free.is_empty() {
        return None;
    }
    let mut parts = Vec::new();
    for (c, &j) in free.iter().take(6).enumerate() {
        // back to coordinates: x = D w
        let x: Vec<f64> = (0..n).map(|i| d[i] * vecs[j * n + i]).collect();
        parts.push(format!("{}: {}", c + 1, describe(model, &x)));
    }
    if free.len() > 6 {
        parts.push(format!("and {} more", free.len() - 6));
    }
    Some(StaticsError::FreeMotion {
        motions: parts.join("; "),
        plural: if free.len() > 1 { "s" } else { "" },
        situation,
        hint,
    })
}

/// The zero-stiffness motions of the tangent at `s` (loads at `load_factor`), named by
/// coordinate as in [`StaticsError::FreeMotion`]; None when there are none or the model
/// is too large for the dense diagnosis. Path following uses it wherever the stiffness
/// turns singular (at the start, or along the path when no step size passes).
pub fn free_motions(model: &Model, s: &State, load_factor: f64) -> Option<StaticsError> {
    free_motions_unless_turns(model, s, load_factor, false).err()?
}

/// [`free_motions`]; with `turns_allowed`, Ok(true) where every free motion only turns
/// members about their own axes, moving no point (see [`turns_in_place`]).
fn free_motions_unless_turns(
    model: &Model,
    s: &State,
    load_factor: f64,
    turns_allowed: bool,
) -> Result<bool, Option<StaticsError>> {
    let n = model.n_eq;
    if n == 0 || n > MAX_DIAGNOSIS_DOFS {
        return Err(None);
    }
    let (k, d) = scaled_tangent(model, s, load_factor);
    let (ev, vecs) = crate::linalg::sym_eig(&k, n).map_err(|_| None)?;
    let scale = ev.iter().fold(0.0f64, |a, b| a.max(b.abs())).max(1e-300);
    let free: Vec<usize> = (0..n)
        .filter(|&j| ev[j].abs() <= FREE_MOTION_TOL * scale)
        .collect();
    if free.is_empty() {
        return Ok(false);
    }
    let coords = |j: usize| -> Vec<f64> { (0..n).map(|i| d[i] * vecs[j * n + i]).collect() };
    if turns_allowed && free.iter().all(|&j| turns_in_place(model, s, &coords(j))) {
        return Ok(true);
    }
    Err(name_free_motions(
        model,
        &free,
        &vecs,
        &d,
        NOT_HELD_AT_SOLUTION,
        "",
    ))
}

/// Whether a motion (by equation) moves no point of the model: the largest displacement
/// it gives any node, body reference point or centre of mass is below 1e-6 of its
/// largest angle times the model's size.
/// A straight member on a spherical joint turning about its own axis is such a motion: it
/// has no stiffness and the loads do no work along it, yet the positions are determined.
fn turns_in_place(model: &Model, s: &State, x: &[f64]) -> bool {
    let Some((plus, minus, h)) = joint::poses_about(model, s, x) else {
        return false;
    };
    let angle = x
        .iter()
        .zip(&model.rot_eq)
        .filter(|(_, r)| **r)
        .fold(0.0f64, |a, (v, _)| a.max(v.abs()));
    let nodes = (0..model.x0.len()).fold(0.0f64, |a, nd| {
        let dx = crate::math::sub(
            joint::node_position(model, &plus, nd),
            joint::node_position(model, &minus, nd),
        );
        a.max(crate::math::norm(dx) / (2.0 * h))
    });
    // a body's reference point and centre of mass count as points too (a body turning
    // freely about an axis off its centre of mass is not determined)
    let bodies = model
        .bodies
        .iter()
        .enumerate()
        .fold(0.0f64, |a, (b, body)| {
            let at = |st: &State| {
                let com = crate::math::mat_vec(&st.body_r[b], body.com);
                [st.body_x[b], crate::math::add(st.body_x[b], com)]
            };
            let (p, m) = (at(&plus), at(&minus));
            (0..2).fold(a, |a, k| {
                a.max(crate::math::norm(crate::math::sub(p[k], m[k])) / (2.0 * h))
            })
        });
    let moved = nodes.max(bodies);
    angle > 0.0 && moved <= 1e-6 * angle * coord_scale(model)
}

/// The largest components of a free motion, by coordinate name, as shares of the largest.
fn describe(model: &Model, x: &[f64]) -> String {
    let big = x.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    let mut comps: Vec<(usize, f64)> = x
        .iter()
        .enumerate()
        .filter(|(_, v)| v.abs() >= 0.1 * big)
        .map(|(i, v)| (i, v / big))
        .collect();
    comps.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    let mut names = vec![String::new(); model.n_eq];
    for d in &model.dofs {
        if let Some(e) = d.eq {
            names[e] = d.name.clone();
        }
    }
    let shown: Vec<String> = comps
        .iter()
        .take(8)
        .map(|(i, v)| format!("{} {v:+.2}", names[*i]))
        .collect();
    let more = if comps.len() > 8 {
        format!(" (+{} more)", comps.len() - 8)
    } else {
        String::new()
    };
    format!("[{}{more}]", shown.join(", "))
}

/// Name and magnitude of the equation with the largest residual.
pub fn worst_dof(model: &Model, r: &[f64]) -> (String, f64) {
    let mut best = (String::from("?"), 0.0);
    for d in &model.dofs {
        if let Some(e) = d.eq {
            // a NaN compares false with everything: name the first non-finite entry
            if !r[e].is_finite() {
                return (d.name.clone(), r[e]);
            }
            if r[e].abs() >= best.1 {
                best = (d.name.clone(), r[e].abs());
            }
        }
    }
    best
}
