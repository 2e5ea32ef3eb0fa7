//! Statics: Newton iterations with automatic load stepping (the step grows after easy
//! increments, halves after a failed one), large rotations through multiplicative updates.

use super::linear::{norm_inf, Convergence, NewtonSystem};
use crate::assembly::{Assembler, Coeffs};
use crate::joint::{self, State};
use crate::model::Model;

#[derive(Debug, thiserror::Error)]
pub enum StaticsError {
    #[error("statics did not converge: load factor stuck at {lambda:.6} (worst residual {residual:.3e} at dof `{dof}`)")]
    NoConvergence {
        lambda: f64,
        residual: f64,
        dof: String,
    },
    #[error("linear solver: {0}")]
    Linear(#[from] crate::linalg::LinalgError),
}

#[derive(Debug, Clone)]
pub struct StaticsReport {
    pub load_steps: usize,
    pub newton_iterations: usize,
    pub rejected_steps: usize,
}

/// Largest angle change of one Newton iteration [rad].
pub const MAX_NEWTON_ANGLE: f64 = 0.5;

/// Newton at a fixed load factor; returns iterations used, or None if it diverged.
pub fn newton(
    model: &Model,
    asm: &Assembler,
    sys: &mut NewtonSystem,
    s: &mut State,
    lambda: f64,
) -> Result<Option<usize>, StaticsError> {
    let c = Coeffs::statics(lambda);
    let mut dx = vec![0.0; asm.n_eq];
    let mut conv = Convergence::new(model.solver.tol, asm.eval.unit_roundoff());
    for it in 0..model.solver.max_iter.max(1) {
        joint::update_kinematics(model, s);
        let info = match sys.evaluate(model, asm, s, c, true) {
            Ok(i) => i,
            Err(_) => return Ok(None),
        };
        let res = norm_inf(&sys.r);
        if !res.is_finite() {
            return Ok(None);
        }
        if conv.converged(res, info.force_scale) {
            return Ok(asm.deformation_in_range(model, s).then_some(it));
        }
        if sys.solve_neg_residual(&mut dx).is_err() {
            return Ok(None);
        }
        asm.limit_rotation_step(&mut dx, MAX_NEWTON_ANGLE);
        joint::apply_increment(model, s, &dx);
    }
    joint::update_kinematics(model, s);
    Ok(None)
}

/// Solve for static equilibrium under the full loads, starting from `s`.
pub fn solve(model: &Model, s: &mut State) -> Result<StaticsReport, StaticsError> {
    let asm = Assembler::new(model);
    let mut sys = NewtonSystem::new(model, &asm, s)?;
    let mut lambda = 0.0;
    let mut dl = 1.0 / model.solver.load_steps.max(1) as f64;
    let mut rep = StaticsReport {
        load_steps: 0,
        newton_iterations: 0,
        rejected_steps: 0,
    };
    while lambda < 1.0 {
        let target = (lambda + dl).min(1.0);
        let saved = s.clone();
        match newton(model, &asm, &mut sys, s, target)? {
            Some(iters) => {
                lambda = target;
                rep.load_steps += 1;
                rep.newton_iterations += iters;
                if iters <= 5 {
                    dl *= 1.5;
                }
            }
            None => {
                *s = saved;
                rep.rejected_steps += 1;
                dl *= 0.5;
                if dl < 1e-7 {
                    joint::update_kinematics(model, s);
                    let _ = sys.evaluate(model, &asm, s, Coeffs::statics(target), false);
                    let (worst, val) = worst_dof(model, &sys.r);
                    return Err(StaticsError::NoConvergence {
                        lambda,
                        residual: val,
                        dof: worst,
                    });
                }
            }
        }
    }
    joint::update_kinematics(model, s);
    Ok(rep)
}

/// Name and magnitude of the equation with the largest residual.
pub fn worst_dof(model: &Model, r: &[f64]) -> (String, f64) {
    let mut best = (String::from("?"), 0.0);
    for d in &model.dofs {
        if let Some(e) = d.eq {
            if r[e].abs() >= best.1 {
                best = (d.name.clone(), r[e].abs());
            }
        }
    }
    best
}
