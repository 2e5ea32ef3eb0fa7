//! The element stage: every element's arrays (internal force, tangent, strain energy, and
//! when asked the mass matrix, quadratic-velocity vector and its velocity derivative) from
//! gathered per-element inputs, behind one trait so the same assembly runs on the CPU
//! functions of [`super::beam`] or on the WGSL kernels of `crate::gpu`.
//!
//! Inputs and outputs are flat per-element records, so a backend sees one contiguous batch
//! per Newton iteration; the assembly gathers them before and scatters them after.

use super::ad::{Lane, F4, M3, V3};
use super::{force, inertia, kinematics, ElemData, ElemState, Mat12, Vec12, NDOF};
use crate::model::BeamProps;

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
    let mut k = [0u64; 36];
    memo_key_into(i, &mut k);
    k
}

/// [`memo_key`] written over `k`.
#[inline(always)]
fn memo_key_into(i: &ElemIn, k: &mut [u64; 36]) {
    let s = &i.state;
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
}

/// Mark `o`'s forces as those of `i`'s positions and velocities: the key written over
/// the one `o` holds (as it does after every evaluation with inertia), else built.
#[inline(always)]
fn memoise(o: &mut ElemOut, i: &ElemIn) {
    match &mut o.forces_of {
        Some(k) => memo_key_into(i, k),
        None => o.forces_of = Some(memo_key(i)),
    }
}

/// Whether `o`'s forces are those of `i`'s positions and velocities.
#[inline(always)]
fn is_memo_of(o: &ElemOut, i: &ElemIn) -> bool {
    o.forces_of.as_ref().is_some_and(|k| *k == memo_key(i))
}

impl ElemOut {
    /// The outputs of an evaluation without inertia: S, M·acc + S and M·v zero.
    fn no_inertial_forces(&mut self) {
        self.s = [0.0; NDOF];
        self.finert = [0.0; NDOF];
        self.mv = [0.0; NDOF];
    }

    /// A full evaluation without inertia: M, C and the inertial forces zero, nothing
    /// memoised.
    fn no_inertia(&mut self) {
        self.forces_of = None;
        self.m = [[0.0; NDOF]; NDOF];
        self.c = [[0.0; NDOF]; NDOF];
        self.no_inertial_forces();
    }

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
            memoise(o, i);
        } else {
            o.no_inertia();
        }
    }

    /// A residual whose f, energy, s and mv are those of these positions and velocities
    /// already (`o.forces_of` is `i`'s key): only M·acc is formed.
    #[inline]
    fn mass_product(e: &ElemData, i: &ElemIn, o: &mut ElemOut) {
        let (t1, t2) = kinematics::node_frames(e, &i.state);
        let g = force::gradient(e.chord0, e.l0, i.state.u1, i.state.u2, &t1, &t2);
        let ma = inertia::mass_times(e, &g, &i.acc);
        o.finert = std::array::from_fn(|k| ma[k] + o.s[k]);
    }

    /// One element without the matrices: the closed-form force (no tangent) and the
    /// inertial forces from the f64 field gradients (M never formed); K, M and C are left
    /// as they were.
    #[inline]
    pub fn one_residual(e: &ElemData, i: &ElemIn, inertia: bool, o: &mut ElemOut) {
        if inertia && is_memo_of(o, i) {
            Self::mass_product(e, i, o);
            return;
        }
        // one gradient for the force, the energy and the inertial forces
        let (frames, g, f, u) = force::residual_parts(e, &i.state);
        o.f = f;
        o.energy = u;
        if inertia {
            memoise(o, i);
            let r = inertia::inertia_forces(e, &i.state, &g, &frames, &i.v12, &i.acc);
            o.s = r.s;
            o.finert = r.finert;
            o.mv = r.mv;
        } else {
            o.forces_of = None;
            o.no_inertial_forces();
        }
    }
}

/// Elements evaluated together in the four lanes of [`F4`]: the same generic code as
/// [`CpuEval::one`] and [`CpuEval::one_residual`] run in `f64` (the scalar path is this
/// code at width one), every lane doing the IEEE operations its element does alone. So an
/// element's outputs are bit-identical whichever elements share its lanes, and a variant's
/// results do not depend on the batch it ran in.
pub const LANES: usize = <F4 as Lane>::WIDTH;

/// A lane's element, input and output. Lanes past the end of a group repeat its last
/// element and are not written back.
type Item<'x> = (&'x ElemData, &'x ElemIn, &'x mut ElemOut);

/// `f(k)` for the four lanes.
#[inline(always)]
fn lanes(f: impl Fn(usize) -> f64) -> F4 {
    F4::new([f(0), f(1), f(2), f(3)])
}

/// Lane k of entry j is `row(k)[j]`: four entries at a time, the 4 × 4 block transposed
/// in registers (as [`put`] writes them back), the rest one by one.
#[inline(always)]
fn gather<'x, const N: usize>(row: impl Fn(usize) -> &'x [f64]) -> [F4; N] {
    let rows = [row(0), row(1), row(2), row(3)];
    let mut x = [F4::ZERO; N];
    let blocks = N / LANES;
    for b in 0..blocks {
        let r = LANES * b;
        let t = F4::transpose(rows.map(|w| F4::from(<[f64; 4]>::try_from(&w[r..r + 4]).unwrap())));
        x[r..r + LANES].copy_from_slice(&t);
    }
    for (j, xj) in x.iter_mut().enumerate().skip(LANES * blocks) {
        *xj = lanes(|k| rows[k][j]);
    }
    x
}

/// A 3 × 3 matrix from its rows' nine entries.
#[inline(always)]
fn m3(x: [F4; 9]) -> M3<F4> {
    [[x[0], x[1], x[2]], [x[3], x[4], x[5]], [x[6], x[7], x[8]]]
}

/// The inputs of up to four elements in lanes: constants, node displacements and
/// frames, velocities and accelerations.
struct Packed {
    e: ElemData<F4>,
    u1: V3<F4>,
    u2: V3<F4>,
    t1: M3<F4>,
    t2: M3<F4>,
    v: [F4; NDOF],
    acc: [F4; NDOF],
    /// per lane: whether its nodes move (else its velocity terms are exact zeros)
    moving: [bool; LANES],
}

impl Packed {
    fn new(items: &[Item<'_>]) -> Packed {
        let n = items.len();
        let at = |k: usize| &items[k.min(n - 1)];
        let p = |f: fn(&BeamProps) -> f64| lanes(|k| f(&at(k).0.props));
        let v3 = |f: &dyn Fn(usize) -> crate::math::Vec3| -> V3<F4> {
            std::array::from_fn(|c| lanes(|k| f(k)[c]))
        };
        let frame0 = m3(gather(|k| at(k).0.frame0.as_flattened()));
        // the node frames R_i · frame0 in lanes, as `crate::math::mat_mul` forms them
        let frame = |r: M3<F4>| -> M3<F4> {
            std::array::from_fn(|i| {
                std::array::from_fn(|j| {
                    r[i][0] * frame0[0][j] + r[i][1] * frame0[1][j] + r[i][2] * frame0[2][j]
                })
            })
        };
        Packed {
            t1: frame(m3(gather(|k| at(k).1.state.r1.as_flattened()))),
            t2: frame(m3(gather(|k| at(k).1.state.r2.as_flattened()))),
            e: ElemData {
                props: BeamProps {
                    ea: p(|q| q.ea),
                    eiy: p(|q| q.eiy),
                    eiz: p(|q| q.eiz),
                    gj: p(|q| q.gj),
                    rho_a: p(|q| q.rho_a),
                    rho_iy: p(|q| q.rho_iy),
                    rho_iz: p(|q| q.rho_iz),
                },
                frame0,
                chord0: v3(&|k| at(k).0.chord0),
                l0: lanes(|k| at(k).0.l0),
            },
            u1: v3(&|k| at(k).1.state.u1),
            u2: v3(&|k| at(k).1.state.u2),
            v: gather(|k| &at(k).1.v12),
            acc: gather(|k| &at(k).1.acc),
            moving: std::array::from_fn(|k| at(k).1.v12.iter().any(|x| *x != 0.0)),
        }
    }

    /// The lanes' gradient, written over `g`.
    #[inline(always)]
    fn gradient_into(&self, g: &mut force::Grad<F4>) {
        let e = &self.e;
        force::gradient_into(e.chord0, e.l0, self.u1, self.u2, &self.t1, &self.t2, g);
    }

    /// `None` when no lane moves, else the bit mask of the moving lanes.
    fn moving_mask(&self) -> Option<F4> {
        let all = inertia::ALL_LANES;
        self.moving
            .iter()
            .any(|m| *m)
            .then(|| lanes(|k| if self.moving[k] { all } else { 0.0 }))
    }
}

/// Lane l of `x` into `field` of item l's output, for every item, written in place
/// (building each output's array first and moving it in cost about 4 % of the stage):
/// four entries at a time, the 4 × 4 block transposed in registers so each element gets
/// one four-wide store instead of four scalar ones.
#[inline(always)]
fn put<const N: usize>(
    x: &[F4; N],
    items: &mut [Item<'_>],
    field: impl Fn(&mut ElemOut) -> &mut [f64; N],
) {
    for (j, block) in x.chunks_exact(LANES).enumerate() {
        let t = F4::transpose([block[0], block[1], block[2], block[3]]);
        for (it, tl) in items.iter_mut().zip(&t) {
            field(it.2)[LANES * j..LANES * (j + 1)].copy_from_slice(tl.as_array());
        }
    }
    for (j, xj) in x.chunks_exact(LANES).remainder().iter().enumerate() {
        let a = xj.as_array();
        let j = N - N % LANES + j;
        for (l, it) in items.iter_mut().enumerate() {
            field(it.2)[j] = a[l];
        }
    }
}

/// [`put`] for a 12 × 12 matrix.
#[inline(always)]
fn put_mat(
    x: &[[F4; NDOF]; NDOF],
    items: &mut [Item<'_>],
    field: impl Fn(&mut ElemOut) -> &mut Mat12,
) {
    for (r, xr) in x.iter().enumerate() {
        put(xr, items, |o| &mut field(o)[r]);
    }
}

/// The full evaluation ([`CpuEval::one`]) of up to four elements.
fn full_lanes(items: &mut [Item<'_>], inertia: bool, sc: &mut LaneScratch) {
    let p = Packed::new(items);
    let pos = (p.u1, p.u2, &p.t1, &p.t2);
    p.gradient_into(&mut sc.grad);
    let g = &sc.grad;
    let ((m, n), f, u) = force::force_parts(&p.e, g);
    force::tangent_into(&p.e.props, p.e.l0, g, &m, n, &mut sc.k);
    put(&f, items, |o| &mut o.f);
    put_mat(&sc.k, items, |o| &mut o.k);
    for (l, (_, i, o)) in items.iter_mut().enumerate() {
        o.energy = u.as_array()[l];
        if inertia {
            memoise(o, i);
        } else {
            o.no_inertia();
        }
    }
    if !inertia {
        return;
    }
    let mask = p.moving_mask();
    match mask {
        Some(mask) => sc.rows.fill_rates_at(&p.e, pos, &p.v, mask),
        None => sc.rows.fill_from(&p.e, g),
    }
    inertia::mass_and_rates(&sc.rows, &p.v, &mut sc.m, &mut sc.c);
    let (finert, mv, sv) = inertia::inertia_forces_at(&p.e, g, pos, &p.v, &p.acc, mask);
    put_mat(&sc.m, items, |o| &mut o.m);
    put_mat(&sc.c, items, |o| &mut o.c);
    put(&sv, items, |o| &mut o.s);
    put(&finert, items, |o| &mut o.finert);
    put(&mv, items, |o| &mut o.mv);
}

/// The full evaluation's workspace: the gradient, K, the gradient rows and M and C in
/// lanes, every entry written before it is read (kept across the groups of a call, so
/// zeroed once a call).
struct LaneScratch {
    grad: force::Grad<F4>,
    k: [[F4; NDOF]; NDOF],
    rows: inertia::GradRows<F4>,
    m: [[F4; NDOF]; NDOF],
    c: [[F4; NDOF]; NDOF],
}

impl Default for LaneScratch {
    fn default() -> Self {
        let z = [[F4::ZERO; NDOF]; NDOF];
        LaneScratch {
            grad: force::Grad::zero(),
            k: z,
            rows: Default::default(),
            m: z,
            c: z,
        }
    }
}

/// The residual-only evaluation ([`CpuEval::one_residual`]) of up to four elements whose
/// forces are not memoised.
fn residual_lanes(items: &mut [Item<'_>], inertia: bool, g: &mut force::Grad<F4>) {
    let p = Packed::new(items);
    p.gradient_into(g);
    let (_, f, u) = force::force_parts(&p.e, g);
    let forces = inertia.then(|| {
        let pos = (p.u1, p.u2, &p.t1, &p.t2);
        inertia::inertia_forces_at(&p.e, g, pos, &p.v, &p.acc, p.moving_mask())
    });
    put(&f, items, |o| &mut o.f);
    if let Some((finert, mv, sv)) = &forces {
        put(sv, items, |o| &mut o.s);
        put(finert, items, |o| &mut o.finert);
        put(mv, items, |o| &mut o.mv);
    }
    for (l, (_, i, o)) in items.iter_mut().enumerate() {
        o.energy = u.as_array()[l];
        if forces.is_some() {
            memoise(o, i);
        } else {
            o.forces_of = None;
            o.no_inertial_forces();
        }
    }
}

/// Evaluate one group of elements four at a time: a full evaluation, or a residual-only
/// one (whose memoised elements form only M·acc, one by one, and leave the lanes).
fn lanes_over(mut items: Vec<Item<'_>>, residual: bool, inertia: bool) {
    if residual {
        // the memoised ones: f, energy, s and mv are those of these positions already
        items.retain_mut(|(e, i, o)| {
            let memo = inertia && is_memo_of(o, i);
            if memo {
                CpuEval::mass_product(e, i, o);
            }
            !memo
        });
        let mut g = force::Grad::zero();
        for chunk in items.chunks_mut(LANES) {
            residual_lanes(chunk, inertia, &mut g);
        }
    } else {
        let mut sc = LaneScratch::default();
        for chunk in items.chunks_mut(LANES) {
            full_lanes(chunk, inertia, &mut sc);
        }
    }
}

/// One call's elements as lane items.
fn items<'x>(
    elems: &'x [ElemData],
    inputs: &'x [ElemIn],
    out: &'x mut [ElemOut],
) -> impl Iterator<Item = Item<'x>> {
    elems
        .iter()
        .zip(inputs)
        .zip(out.iter_mut())
        .map(|((e, i), o)| (e, i, o))
}

impl ElementEval for CpuEval {
    fn evaluate(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        lanes_over(items(elems, inputs, out).collect(), false, inertia);
        Ok(())
    }
    fn evaluate_residual(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        lanes_over(items(elems, inputs, out).collect(), true, inertia);
        Ok(())
    }
    /// Lanes filled across the requests: one group per kind of evaluation (full or
    /// residual-only, with or without inertia).
    fn evaluate_batch(&self, reqs: &mut [EvalRequest<'_>]) -> Result<(), EvalError> {
        let mut groups: [Vec<Item<'_>>; 4] = Default::default();
        for r in reqs.iter_mut() {
            let g = &mut groups[2 * usize::from(r.residual) + usize::from(r.inertia)];
            g.extend(items(r.elems, r.inputs, r.out));
        }
        for (kind, g) in groups.into_iter().enumerate() {
            if !g.is_empty() {
                lanes_over(g, kind >= 2, kind % 2 == 1);
            }
        }
        Ok(())
    }
    fn name(&self) -> String {
        "cpu".into()
    }
}
