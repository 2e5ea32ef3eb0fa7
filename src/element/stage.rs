//! The element stage: every element's arrays (internal force, tangent, strain energy, and
//! when asked the mass matrix, quadratic-velocity vector and its velocity derivative) from
//! gathered per-element inputs, behind one trait so the same assembly runs on the CPU
//! functions of [`super::beam`] or on the WGSL kernels of `crate::gpu`.
//!
//! Inputs and outputs are flat per-element records, so a backend sees one contiguous batch
//! per Newton iteration; the assembly gathers them before and scatters them after.

use super::{force, inertia, kinematics, ElemData, ElemState, Mat12, Vec12, NDOF};

/// Per-element input of the element stage.
#[derive(Clone, Copy, Debug)]
pub struct ElemIn {
    pub state: ElemState,
    /// nodal velocities (ẋ1, ω1, ẋ2, ω2) for the quadratic-velocity terms (zero in statics)
    pub v12: Vec12,
    /// what multiplies M in the inertial force M·acc + S: the nodal accelerations
    /// (ẍ1, α1, ẍ2, α2), minus the gravity field as a rigid translation (its consistent
    /// load is −M g)
    pub acc: Vec12,
}

/// Per-element output of the element stage. A full evaluation writes every field (the
/// inertia fields are zero when inertia was not asked for); a residual-only one writes
/// f, energy, s, finert and mv and leaves K, M and C as they were (nothing reads them
/// then, and the zeros were 3.4 kB of stores per element and evaluation).
#[derive(Clone, Copy, Debug)]
pub struct ElemOut {
    pub f: Vec12,
    pub k: Mat12,
    pub energy: f64,
    pub m: Mat12,
    pub s: Vec12,
    pub c: Mat12,
    /// inertial force M·acc + S
    pub finert: Vec12,
    /// M·v12 (kinetic energy, mass-proportional damping)
    pub mv: Vec12,
    /// The positions and velocities (`ElemIn::state`, `v12`, as [`memo_key`]) from which
    /// the CPU stage computed f, energy, s and mv with inertia; `None` after any other
    /// writer (a GPU backend). A residual-only evaluation at the same positions and
    /// velocities (the time-error estimate's mass products, which change only the
    /// accelerations) then forms only M·acc.
    pub forces_of: Option<[u64; 36]>,
}

/// The bits of an input's positions, frames and velocities.
pub fn memo_key(i: &ElemIn) -> [u64; 36] {
    let s = &i.state;
    let mut k = [0u64; 36];
    for c in 0..3 {
        k[c] = s.u1[c].to_bits();
        k[12 + c] = s.u2[c].to_bits();
        for r in 0..3 {
            k[3 + 3 * r + c] = s.r1[r][c].to_bits();
            k[15 + 3 * r + c] = s.r2[r][c].to_bits();
        }
    }
    for (x, v) in k[24..].iter_mut().zip(&i.v12) {
        *x = v.to_bits();
    }
    k
}

impl ElemOut {
    /// `finert` and `mv` from M and S, for backends that return the matrices only.
    pub fn products_from_m(&mut self, i: &ElemIn) {
        for r in 0..NDOF {
            let (mut a, mut b) = (0.0, 0.0);
            for c in 0..NDOF {
                a += self.m[r][c] * i.acc[c];
                b += self.m[r][c] * i.v12[c];
            }
            self.finert[r] = a + self.s[r];
            self.mv[r] = b;
        }
    }
}

impl Default for ElemOut {
    fn default() -> Self {
        ElemOut {
            f: [0.0; NDOF],
            k: [[0.0; NDOF]; NDOF],
            energy: 0.0,
            m: [[0.0; NDOF]; NDOF],
            s: [0.0; NDOF],
            c: [[0.0; NDOF]; NDOF],
            finert: [0.0; NDOF],
            mv: [0.0; NDOF],
            forces_of: None,
        }
    }
}

/// Error of an element-stage backend (a lost GPU device, a failed dispatch).
#[derive(Debug, Clone, thiserror::Error)]
#[error("element evaluation on {backend}: {message}")]
pub struct EvalError {
    pub backend: String,
    pub message: String,
}

/// One variant's elements in a batched call of the element stage
/// ([`ElementEval::evaluate_batch`]): what [`ElementEval::evaluate`] (or
/// [`ElementEval::evaluate_residual`] when `residual`) takes for one variant.
pub struct EvalRequest<'a> {
    pub elems: &'a [ElemData],
    pub inputs: &'a [ElemIn],
    pub out: &'a mut [ElemOut],
    /// residual-only (a modified-Newton iteration): K, M and C may be skipped
    pub residual: bool,
    /// M, S, C as well
    pub inertia: bool,
}

/// One element stage: `out[i]` from `elems[i]` and `inputs[i]` for every i. `inertia`
/// asks for M, S, C as well. Implementations must write every field of every output in
/// a full evaluation; a residual-only one may leave K, M and C as they were.
pub trait ElementEval: Send + Sync {
    fn evaluate(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError>;
    /// As [`evaluate`](Self::evaluate) for a residual-only Newton iteration (modified
    /// Newton): only f, energy, finert and mv are used, so K, M and C may be skipped
    /// (left as they were). The default evaluates everything.
    fn evaluate_residual(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        self.evaluate(elems, inputs, inertia, out)
    }
    /// Several requests (the variants of a batch advancing in lockstep) in one call: one
    /// dispatch on a GPU, SIMD lanes filled across request boundaries on the CPU. Every
    /// request's outputs must be bit-identical to evaluating that request alone, so a
    /// variant's results do not depend on the batch it ran in. The default evaluates the
    /// requests one by one.
    fn evaluate_batch(&self, reqs: &mut [EvalRequest<'_>]) -> Result<(), EvalError> {
        for r in reqs.iter_mut() {
            if r.residual {
                self.evaluate_residual(r.elems, r.inputs, r.inertia, r.out)?;
            } else {
                self.evaluate(r.elems, r.inputs, r.inertia, r.out)?;
            }
        }
        Ok(())
    }
    /// short name for logs and metadata, e.g. "cpu" or "gpu:llvmpipe f32"
    fn name(&self) -> String;
    /// Unit round-off of the arithmetic the arrays are computed in: 2⁻⁵³ for f64, 2⁻²⁴
    /// for an f32 GPU stage. The arrays carry relative errors of some multiple of it, so
    /// solvers bound their residual tolerances by it (see
    /// `crate::solver::linear::Convergence`).
    fn unit_roundoff(&self) -> f64 {
        f64::EPSILON / 2.0
    }
}

/// The reference: the CPU element functions, f64.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuEval;

impl CpuEval {
    /// One element: the closed-form force and tangent, and the inertia with M and C
    /// written straight into the output.
    #[inline]
    pub fn one(e: &ElemData, i: &ElemIn, inertia: bool, o: &mut ElemOut) {
        Self::one_in(e, i, inertia, o, &mut inertia::GradRows::default());
    }

    #[inline]
    fn one_in(
        e: &ElemData,
        i: &ElemIn,
        inertia: bool,
        o: &mut ElemOut,
        sc: &mut inertia::GradRows,
    ) {
        // one f64 gradient for the force, the tangent, the energy and the inertial forces
        let (frames, g, f, k, u) = force::tangent_parts(e, &i.state);
        o.f = f;
        o.k = k;
        o.energy = u;
        if inertia {
            sc.fill_with_rates(e, &i.state, &i.v12);
            inertia::mass_and_rates(sc, &i.v12, &mut o.m, &mut o.c);
            let r = inertia::inertia_forces(e, &i.state, &g, &frames, &i.v12, &i.acc);
            o.s = r.s;
            o.finert = r.finert;
            o.mv = r.mv;
            o.forces_of = Some(memo_key(i));
        } else {
            o.forces_of = None;
            o.m = [[0.0; NDOF]; NDOF];
            o.s = [0.0; NDOF];
            o.c = [[0.0; NDOF]; NDOF];
            o.finert = [0.0; NDOF];
            o.mv = [0.0; NDOF];
        }
    }

    /// One element without the matrices: the closed-form force (no tangent) and the
    /// inertial forces from the f64 field gradients (M never formed); K, M and C are left
    /// as they were.
    #[inline]
    pub fn one_residual(e: &ElemData, i: &ElemIn, inertia: bool, o: &mut ElemOut) {
        let key = if inertia { Some(memo_key(i)) } else { None };
        if key.is_some() && o.forces_of == key {
            // f, energy, s and mv are those of these positions and velocities already
            let (t1, t2) = kinematics::node_frames(e, &i.state);
            let g = force::gradient(e.chord0, e.l0, i.state.u1, i.state.u2, &t1, &t2);
            let ma = inertia::mass_times(e, &g, &i.acc);
            o.finert = std::array::from_fn(|k| ma[k] + o.s[k]);
            return;
        }
        // one gradient for the force, the energy and the inertial forces
        let (frames, g, f, u) = force::residual_parts(e, &i.state);
        o.f = f;
        o.energy = u;
        o.forces_of = key;
        if inertia {
            let r = inertia::inertia_forces(e, &i.state, &g, &frames, &i.v12, &i.acc);
            o.s = r.s;
            o.finert = r.finert;
            o.mv = r.mv;
        } else {
            o.s = [0.0; NDOF];
            o.finert = [0.0; NDOF];
            o.mv = [0.0; NDOF];
        }
    }
}

/// Apply the full per-element evaluation to every element of a batch, with one inertia
/// workspace for all of them.
fn each_full(elems: &[ElemData], inputs: &[ElemIn], inertia: bool, out: &mut [ElemOut]) {
    let mut sc = inertia::GradRows::default();
    for ((e, i), o) in elems.iter().zip(inputs).zip(out.iter_mut()) {
        CpuEval::one_in(e, i, inertia, o, &mut sc);
    }
}

impl ElementEval for CpuEval {
    fn evaluate(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        each_full(elems, inputs, inertia, out);
        Ok(())
    }
    fn evaluate_residual(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        for ((e, i), o) in elems.iter().zip(inputs).zip(out.iter_mut()) {
            CpuEval::one_residual(e, i, inertia, o);
        }
        Ok(())
    }
    fn name(&self) -> String {
        "cpu".into()
    }
}
