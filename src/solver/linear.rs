//! The Newton system: a fixed sparsity pattern discovered once by a pattern-only assembly,
//! values refilled every iteration, faer sparse LU with the symbolic analysis reused.

use crate::assembly::{Assembler, AssemblyInfo, Coeffs, PatternSink, Sink};
use crate::joint::State;
use crate::linalg::{LinalgError, SparseLu, SparseLuSymbolic, SparsePattern};
use crate::model::Model;
use crate::solver::batch::block_on;
use std::sync::Arc;
use std::time::Instant;

/// Scatters into the pattern's value array. The assembly adds its entries in the same
/// order on every call (same model, same code path), so the slot of the i-th add is
/// remembered and reused after checking that (row, col) match: one comparison instead of
/// a binary search per entry. A changed order (a hinge locked) just re-searches.
struct SparseSink<'a> {
    pattern: &'a SparsePattern,
    values: &'a mut [f64],
    cache: &'a mut Vec<(u32, u32, u32)>,
    next: usize,
}
impl Sink for SparseSink<'_> {
    #[inline]
    fn add(&mut self, row: usize, col: usize, v: f64) {
        let i = self.next;
        self.next += 1;
        if let Some(&(r, c, k)) = self.cache.get(i) {
            if r as usize == row && c as usize == col {
                self.values[k as usize] += v;
                return;
            }
        }
        // the pattern came from the same assembly code, so every entry has a slot
        let k = self
            .pattern
            .slot(row, col)
            .expect("entry outside the assembled pattern");
        let e = (row as u32, col as u32, k as u32);
        if i < self.cache.len() {
            self.cache[i] = e;
        } else {
            self.cache.push(e);
        }
        self.values[k] += v;
    }
}

/// Wall time spent per stage of the Newton iterations, accumulated over a run.
#[derive(Clone, Copy, Debug, Default)]
pub struct StageTimes {
    /// element arrays (mass, internal force, tangent, quadratic-velocity terms)
    pub element_s: f64,
    /// everything else of the residual/Jacobian assembly (kinematics chains, scatter)
    pub assembly_s: f64,
    /// sparse numeric LU and the solves
    pub factorization_s: f64,
    /// sensor sampling and result writing
    pub output_s: f64,
}

impl StageTimes {
    pub fn add(&mut self, o: &StageTimes) {
        self.element_s += o.element_s;
        self.assembly_s += o.assembly_s;
        self.factorization_s += o.factorization_s;
        self.output_s += o.output_s;
    }
}

/// Newton convergence test on the residual's max norm, aware of the element stage's
/// precision.
///
/// Converged: res ≤ tol · scale, with `tol` the model's `[solver] tol` and `scale` the
/// largest single force contribution of the assembly. An element stage of unit round-off
/// u (f32 GPU kernels: 6e-8, see [`crate::element::ElementEval::unit_roundoff`]) returns
/// arrays with errors of some multiple of u relative to the terms they are computed from,
/// and those can be much larger than the residual (moments whose difference is a shear
/// force, centripetal inertia of which a small part is left): the residual has a noise
/// floor, Newton converges quadratically down to it and then wanders about it. So
/// - `tol` is raised to at least [`Convergence::TIGHT`]·u (f64: 1.8e-15, below any
///   sensible tol, so f64 stages converge exactly as before); and
/// - once the residual stops decreasing (more than half the previous iteration's, relative
///   to the force scale) while within [`Convergence::NOISE`]·u of the force scale, it is
///   at the stage's noise floor and the iterate is accepted: more iterations only resample
///   the noise (then the step was halved, and halved again, as if Newton had diverged).
#[derive(Clone, Copy, Debug)]
pub struct Convergence {
    tol: f64,
    noise: f64,
    prev: f64,
    u: f64,
    stalled: bool,
}

impl Convergence {
    /// Tolerance floor in units of u: the residual carries u-relative errors of a few
    /// element arrays per equation, each tens of operations deep.
    pub const TIGHT: f64 = 16.0;
    /// Largest residual, in units of u relative to the force scale, accepted as the noise
    /// floor: two element arrays (f, and M a + S) of two elements per node equation, each
    /// within the kernels' derived ~150u normwise bound (tests/gpu.rs, F32_TOL) of that
    /// element's largest contribution, rounded up to 1024u. Measured on the rotating
    /// cantilever at rest with f32 kernels: up to 130u (the shear of a vibrating beam is
    /// the difference of its end moments).
    pub const NOISE: f64 = 1024.0;

    /// Test for one Newton solve with tolerance `tol` on a stage of unit round-off `u`.
    pub fn new(tol: f64, u: f64) -> Convergence {
        Convergence {
            tol: tol.max(Self::TIGHT * u),
            noise: Self::NOISE * u,
            prev: f64::INFINITY,
            u,
            stalled: false,
        }
    }

    /// Largest coordinate correction, in units of u relative to the coordinates' scale,
    /// that still counts as round-off of the coordinates themselves.
    pub const ROUNDOFF_CORRECTION: f64 = 64.0;

    /// Whether the last residual given to [`converged`](Self::converged) stalled while the
    /// Newton correction that produced it, `correction` (in coordinate units, max norm),
    /// was already at the round-off of coordinates of size `coord_scale`: no representable
    /// change of the state can lower the residual further. This is the noise floor of a
    /// stiff f64 model whose force scale understates its round-off (an axial stiffness
    /// EA = 1e8 N turns 1e-16 m of position round-off into 1e-8 N, ~1e-12 of the forces),
    /// where a `tol` below that floor would otherwise halve every step down to `dt_min`.
    pub fn stalled_at_roundoff(&self, correction: f64, coord_scale: f64) -> bool {
        self.stalled && correction <= Self::ROUNDOFF_CORRECTION * self.u * coord_scale
    }

    /// Whether residual `res` (max norm) at force scale `scale` is converged; call once
    /// per iteration, in order.
    pub fn converged(&mut self, res: f64, scale: f64) -> bool {
        // forces that overflowed (a stiffness or a load near f64's largest) compare with
        // nothing: every residual would pass against an infinite scale
        if !scale.is_finite() {
            self.stalled = false;
            return false;
        }
        let scale = scale.max(f64::MIN_POSITIVE);
        let rel = res / scale;
        let stalled = rel > 0.5 * self.prev;
        self.stalled = stalled;
        self.prev = rel;
        res <= self.tol * scale || res == 0.0 || (stalled && rel <= self.noise)
    }
}

pub struct NewtonSystem {
    pub pattern: SparsePattern,
    pub values: Vec<f64>,
    lu: SparseLu,
    /// by-dof generalized forces of the last evaluation
    pub gen: Vec<f64>,
    /// residual by equation
    pub r: Vec<f64>,
    pub times: StageTimes,
    /// (row, col, slot) of each scatter call in assembly order (see `SparseSink`)
    slot_cache: Vec<(u32, u32, u32)>,
}

impl NewtonSystem {
    pub fn new(model: &Model, asm: &Assembler, s: &State) -> Result<NewtonSystem, LinalgError> {
        Self::with_symbolic(model, asm, s, None)
    }

    /// As [`NewtonSystem::new`], reusing `symbolic` when it was analysed for this very
    /// pattern (the COLAMD ordering and symbolic LU then happen once per campaign).
    pub fn with_symbolic(
        model: &Model,
        asm: &Assembler,
        s: &State,
        symbolic: Option<&Arc<SparseLuSymbolic>>,
    ) -> Result<NewtonSystem, LinalgError> {
        Self::build(model, asm, s, symbolic, true)
    }

    /// [`NewtonSystem::with_symbolic`] with the pattern from [`Assembler::pattern`] (no
    /// element stage) and `gen` left zero: for a caller whose first use is an
    /// [`NewtonSystem::evaluate_async`], which overwrites `gen` (the integrator, once per
    /// run and campaign variant).
    pub(crate) fn with_symbolic_unevaluated(
        model: &Model,
        asm: &Assembler,
        s: &State,
        symbolic: Option<&Arc<SparseLuSymbolic>>,
    ) -> Result<NewtonSystem, LinalgError> {
        Self::build(model, asm, s, symbolic, false)
    }

    fn build(
        model: &Model,
        asm: &Assembler,
        s: &State,
        symbolic: Option<&Arc<SparseLuSymbolic>>,
        evaluate: bool,
    ) -> Result<NewtonSystem, LinalgError> {
        let mut ps = PatternSink::default();
        let mut gen = vec![0.0; model.dofs.len()];
        if evaluate {
            let all = Coeffs::dynamic(1.0, 1.0, 1.0);
            asm.evaluate(model, s, all, &mut gen, Some(&mut ps));
        } else {
            asm.pattern(model, s, &mut ps);
        }
        for i in 0..model.n_eq {
            ps.entries.push((i, i));
        }
        let pattern = SparsePattern::new(model.n_eq, &ps.entries);
        let mut lu = match symbolic {
            Some(sym) if sym.analyses(&pattern) => SparseLu::from_symbolic(Arc::clone(sym)),
            _ => SparseLu::new(&pattern)?,
        };
        // translations in one unit, angles in another: the LU works in consistent units,
        // so a model in millimetres or of 10 µm elements factors as the same in metres
        let groups: Vec<usize> = model.rot_eq.iter().map(|&r| usize::from(r)).collect();
        lu.set_unit_groups(&groups)?;
        Ok(NewtonSystem {
            values: vec![0.0; pattern.nnz()],
            slot_cache: Vec::new(),
            pattern,
            lu,
            gen,
            r: vec![0.0; model.n_eq],
            times: StageTimes::default(),
        })
    }

    /// Evaluate residual and Jacobian at `s`; factor the Jacobian when `factor` is set.
    /// The element stage runs on the spot (see [`Assembler::evaluate`]).
    pub fn evaluate(
        &mut self,
        model: &Model,
        asm: &Assembler,
        s: &State,
        c: Coeffs,
        factor: bool,
    ) -> Result<AssemblyInfo, LinalgError> {
        block_on(self.evaluate_in(model, asm, s, c, factor, false))
    }

    /// [`NewtonSystem::evaluate`] with the element stage as an await point (see
    /// [`Assembler::evaluate_async`]).
    pub async fn evaluate_async(
        &mut self,
        model: &Model,
        asm: &Assembler,
        s: &State,
        c: Coeffs,
        factor: bool,
    ) -> Result<AssemblyInfo, LinalgError> {
        self.evaluate_in(model, asm, s, c, factor, true).await
    }

    /// Evaluate residual and Jacobian at `s` into `r` and `values` without factoring
    /// them (the last factorization stays): for a caller that factors the values in a
    /// factorization of its own ([`NewtonSystem::new_lu`]).
    pub async fn assemble_async(
        &mut self,
        model: &Model,
        asm: &Assembler,
        s: &State,
        c: Coeffs,
    ) -> Result<AssemblyInfo, LinalgError> {
        self.evaluate_matrix(model, asm, s, c, true, false, true)
            .await
    }

    async fn evaluate_in(
        &mut self,
        model: &Model,
        asm: &Assembler,
        s: &State,
        c: Coeffs,
        factor: bool,
        batched: bool,
    ) -> Result<AssemblyInfo, LinalgError> {
        self.evaluate_matrix(model, asm, s, c, factor, factor, batched)
            .await
    }

    #[allow(clippy::too_many_arguments)]
    async fn evaluate_matrix(
        &mut self,
        model: &Model,
        asm: &Assembler,
        s: &State,
        c: Coeffs,
        assemble: bool,
        factor: bool,
        batched: bool,
    ) -> Result<AssemblyInfo, LinalgError> {
        let t0 = Instant::now();
        let before = asm.stage_times();
        let info = if assemble {
            // (a residual-only evaluation leaves the last factored values alone)
            self.values.iter_mut().for_each(|v| *v = 0.0);
            let mut sink = SparseSink {
                pattern: &self.pattern,
                values: &mut self.values,
                cache: &mut self.slot_cache,
                next: 0,
            };
            asm.evaluate_in(batched, model, s, c, &mut self.gen, Some(&mut sink))
                .await
        } else {
            asm.evaluate_in(batched, model, s, c, &mut self.gen, None)
                .await
        };
        crate::assembly::gather(model, s, &self.gen, &mut self.r);
        let t1 = Instant::now();
        // the assembler times its element stage (a batch member: its share of the round)
        // and its wait for the other members; the rest of this span is assembly
        let after = asm.stage_times();
        let element = after.element_s - before.element_s;
        let waiting = after.waiting_s - before.waiting_s;
        self.times.element_s += element;
        self.times.assembly_s += ((t1 - t0).as_secs_f64() - element - waiting).max(0.0);
        if factor {
            let r = self.lu.factor(&self.values);
            self.times.factorization_s += t1.elapsed().as_secs_f64();
            r?;
        }
        Ok(info)
    }

    /// [`NewtonSystem::evaluate`] with factoring, where a singular Jacobian is factored
    /// with `shift` times each diagonal entry's magnitude added to that entry instead (the
    /// largest of its unit group where the entry is zero). Returns the assembly and
    /// whether the factor is of the Jacobian itself (`Some(false)`: shifted; `None`: not
    /// even that could be factored, or the evaluation failed before it). See
    /// [`crate::solver::statics::SINGULAR_SHIFT`] for why statics takes such a step.
    pub fn evaluate_shifting(
        &mut self,
        model: &Model,
        asm: &Assembler,
        s: &State,
        c: Coeffs,
        shift: f64,
    ) -> (Option<AssemblyInfo>, Option<bool>) {
        let info = match block_on(self.evaluate_matrix(model, asm, s, c, true, false, false)) {
            Ok(i) => i,
            Err(_) => return (None, None),
        };
        let t0 = Instant::now();
        let plain = self.lu.factor(&self.values);
        let factored = match plain {
            Ok(()) => Some(true),
            Err(LinalgError::Singular { .. }) => {
                let shifted = self.shifted_values(shift);
                self.lu.factor(&shifted).ok().map(|_| false)
            }
            Err(_) => None,
        };
        self.times.factorization_s += t0.elapsed().as_secs_f64();
        (Some(info), factored)
    }

    /// The assembled values with `shift` times each diagonal entry's magnitude added to
    /// it (the largest of its unit group where the entry is zero), with the entry's own
    /// sign: a negative pivot (a compressed mechanism) is not pushed through zero.
    fn shifted_values(&self, shift: f64) -> Vec<f64> {
        let groups = self.lu.unit_groups();
        let n = self.pattern.n();
        let diag: Vec<usize> = (0..n)
            .map(|i| {
                self.pattern
                    .slot(i, i)
                    .expect("the pattern holds the diagonal")
            })
            .collect();
        let mut group_max = vec![0.0f64; groups.iter().max().map_or(1, |g| g + 1)];
        for (i, &k) in diag.iter().enumerate() {
            let g = groups.get(i).copied().unwrap_or(0);
            group_max[g] = group_max[g].max(self.values[k].abs());
        }
        let mut shifted = self.values.clone();
        for (i, &k) in diag.iter().enumerate() {
            let g = groups.get(i).copied().unwrap_or(0);
            let a = self.values[k].abs();
            let size = if a > 0.0 { a } else { group_max[g] };
            shifted[k] += shift * size * if self.values[k] < 0.0 { -1.0 } else { 1.0 };
        }
        shifted
    }

    /// After [`NewtonSystem::evaluate_shifting`] factored the shifted Jacobian J + μD:
    /// the Newton correction without its part along J's free motions. The shifted solve
    /// gives that part as c/μ (and the rest to O(μ)), so the corrections for μ and 2μ
    /// combine as 2 Δ(2μ) − Δ(μ), which cancels it and keeps the rest (Richardson in μ).
    /// A load that does work along a free motion at the reference (a hanging beam pushed
    /// sideways, a pendulum tilted from its hanging state) would otherwise move it by
    /// c/μ; without that part, the step only strains the structure, and the tangent at
    /// the strained state has the axial forces that give the motion its stiffness.
    /// Leaves the factor of J + 2μD.
    pub fn solve_neg_residual_without_free(
        &mut self,
        dx: &mut [f64],
        shift: f64,
    ) -> Result<(), LinalgError> {
        self.solve_neg_residual(dx)?;
        let t0 = Instant::now();
        let shifted = self.shifted_values(2.0 * shift);
        let r = self.lu.factor(&shifted);
        self.times.factorization_s += t0.elapsed().as_secs_f64();
        r?;
        let mut d2 = vec![0.0; dx.len()];
        self.solve_neg_residual(&mut d2)?;
        for (d, e) in dx.iter_mut().zip(&d2) {
            *d = 2.0 * e - *d;
        }
        Ok(())
    }

    /// Nonzeros of the Jacobian pattern and of its LU factor (L + U) for the values last
    /// assembled (see [`SparseLuSymbolic::factor_nnz`]); `None` for the factor when those
    /// values cannot be factored.
    pub fn factor_size(&self) -> (usize, Option<usize>) {
        let sym = self.lu.symbolic();
        (sym.nnz(), sym.factor_nnz(&self.values).ok())
    }

    /// The symbolic factorization, for sharing with other variants of the same pattern.
    pub fn symbolic(&self) -> &Arc<SparseLuSymbolic> {
        self.lu.symbolic()
    }

    /// A factorisation of another matrix on this pattern, in the same unit groups.
    pub fn new_lu(&self) -> SparseLu {
        let mut lu = SparseLu::from_symbolic(Arc::clone(self.lu.symbolic()));
        lu.set_unit_groups(self.lu.unit_groups())
            .expect("the groups were checked against this pattern");
        lu
    }

    /// Solve J x = b in place with the last factorization (path following's tangent
    /// solves); non-finite results are an error.
    pub fn solve_tangent(&mut self, b: &mut [f64]) -> Result<(), LinalgError> {
        let t0 = Instant::now();
        let r = self.lu.try_solve_in_place(b);
        self.times.factorization_s += t0.elapsed().as_secs_f64();
        r
    }

    /// Solve J Δ = −r with the last factorization.
    pub fn solve_neg_residual(&mut self, dx: &mut [f64]) -> Result<(), LinalgError> {
        let t0 = Instant::now();
        for (d, r) in dx.iter_mut().zip(&self.r) {
            *d = -r;
        }
        self.lu.solve_in_place(dx);
        self.times.factorization_s += t0.elapsed().as_secs_f64();
        if dx.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(LinalgError::NonFinite)
        }
    }
}

/// Infinity norm: the largest magnitude; NaN if any entry is NaN (`f64::max` would pass over it, and a
/// residual of NaN forces read as 0, converged: EA = 1e308 "solved" with no deflection).
pub fn norm_inf(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m: f64, x| {
        if x.is_nan() || m.is_nan() {
            f64::NAN
        } else {
            m.max(x.abs())
        }
    })
}
