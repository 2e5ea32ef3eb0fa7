//! The WGSL element kernels against their CPU twins (src/element/beam.rs), on every
//! adapter this machine has and in every precision it supports; then whole simulations
//! with the GPU element stage against the CPU path.
//!
//! Without an adapter each test prints `SKIPPED <name>: no adapter` (on the real stderr,
//! past the test harness's capture) and returns; with `LATDYN_REQUIRE_GPU=1` (set by
//! .ci/run, which installs the Vulkan software driver) it fails instead, so CI cannot pass
//! GPU tests that never ran.
//!
//! Errors are normwise per array: max|gpu − cpu| / max|cpu| over the entries of f, K, M,
//! S or C of one element (entry-wise relative errors of entries that are zero up to
//! round-off mean nothing), with max|cpu| floored by the size of the terms an array is
//! a cancellation of where that is larger (see `errors`).

mod common;

use std::io::Write;
use std::sync::{Arc, Mutex};

use latdyn::element::{
    CpuEval, ElemData, ElemIn, ElemOut, ElemState, ElementEval, EvalError, EvalRequest,
};
use latdyn::gpu::{self, GpuContext, Precision};
use latdyn::math::*;
use latdyn::model::BeamProps;

/// Report that `test` (or a part of it) cannot run here, by name on the real stderr; or
/// fail under LATDYN_REQUIRE_GPU=1.
fn skip(test: &str, why: &str) {
    if std::env::var("LATDYN_REQUIRE_GPU").is_ok_and(|v| v == "1") {
        panic!("{test}: {why}, and LATDYN_REQUIRE_GPU=1 forbids skipping");
    }
    let _ = writeln!(std::io::stderr(), "SKIPPED {test}: {why}");
}

/// Adapters to test on, or none after reporting the skip (or failing under
/// LATDYN_REQUIRE_GPU=1).
fn adapters_or_skip(test: &str) -> Vec<(wgpu::Adapter, gpu::AdapterSummary)> {
    let list = gpu::adapters();
    if list.is_empty() {
        skip(test, "no adapter");
    }
    list
}

/// (context, label) for every adapter × supported precision.
fn contexts(test: &str) -> Vec<GpuContext> {
    let mut out = Vec::new();
    for (a, s) in adapters_or_skip(test) {
        let precisions: &[Precision] = if s.shader_f64 {
            &[Precision::F32, Precision::F64]
        } else {
            &[Precision::F32]
        };
        for &p in precisions {
            // a fresh adapter handle per device: wgpu adapters are cheap clones
            match GpuContext::new(a.clone(), s.clone(), p) {
                Ok(c) => out.push(c),
                Err(e) => panic!("{test}: {} {}: {e}", s.label(), p.as_str()),
            }
        }
    }
    out
}

/// xorshift64*: reproducible random numbers without a dependency
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64) / (1u64 << 53) as f64
    }
    fn sym(&mut self, a: f64) -> f64 {
        a * (2.0 * self.next() - 1.0)
    }
    fn vec(&mut self, a: f64) -> Vec3 {
        [self.sym(a), self.sym(a), self.sym(a)]
    }
    /// log-uniform in [lo, hi]
    fn log(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + self.next() * (hi.ln() - lo.ln())).exp()
    }
}

/// A random element in a random large rigid motion (rotation up to π about a random
/// axis, reference coordinates up to 1e3 m, so displacements are large) plus a small
/// deformation: strain up to `strain`, node rotations up to `strain` rad against the
/// rigid motion, nodal velocities up to 10 m/s and 10 rad/s.
fn random_element(rng: &mut Rng, strain: f64) -> (ElemData, ElemIn) {
    let props = BeamProps {
        ea: rng.log(1e5, 1e8),
        eiy: rng.log(1e1, 1e4),
        eiz: rng.log(1e1, 1e4),
        gj: rng.log(1e1, 1e4),
        rho_a: rng.log(0.1, 10.0),
        rho_iy: rng.log(1e-6, 1e-2),
        rho_iz: rng.log(1e-6, 1e-2),
    };
    let l0 = rng.log(0.1, 3.0);
    let frame0 = rot_exp(rng.vec(3.0));
    let x1_0 = rng.vec(1e3);
    let chord0 = scale(col(&frame0, 0), l0);
    let x2_0 = add(x1_0, chord0);
    let e = ElemData::new(props, frame0, x1_0, x2_0);
    let r = rot_exp(scale(
        normalize(rng.vec(1.0)),
        rng.next() * std::f64::consts::PI,
    ));
    let c = rng.vec(1e3);
    let x1 = add(mat_vec(&r, x1_0), c);
    let x2 = add(
        mat_vec(&r, add(add(x1_0, chord0), scale(rng.vec(1.0), strain * l0))),
        c,
    );
    let state = ElemState {
        u1: sub(x1, x1_0),
        r1: mat_mul(&r, &rot_exp(rng.vec(strain))),
        u2: sub(x2, x2_0),
        r2: mat_mul(&r, &rot_exp(rng.vec(strain))),
    };
    let mut v12 = [0.0; 12];
    for v in v12.iter_mut() {
        *v = rng.sym(10.0);
    }
    // derived, not drawn: keeps the random sequence (and so every case) as it was
    let acc = std::array::from_fn(|k| 0.3 * v12[(k + 5) % 12]);
    (e, ElemIn { state, v12, acc })
}

/// Worst relative errors over a batch: [f, K, energy, M, S, C], normwise: max|gpu − cpu|
/// over the element's array divided by a scale, max|cpu| or, where the array is a
/// cancellation of larger terms, the size of those terms (a floor), because round-off is
/// relative to them and not to the result:
///
/// - f and the energy vanish for an undeformed element (the CPU's f is then round-off):
///   floor max|K|·L0·eps, the force of a strain `eps` (the kernel scalar's unit
///   round-off), and that force times L0 for the energy. With the co-rotated upload the
///   host forms the chord change d' = Q(X + d) − X' in f64 from coordinates of size L0, so
///   the kernel's state differs from the CPU's by an absolute strain `CHANGE_OF_FRAME`
///   (below); f then moves by max|K|·max(L0, 1)·CHANGE_OF_FRAME (per metre of
///   translation, per radian of rotation: the node frames are rotated too) and the
///   energy by max|f|·L0·CHANGE_OF_FRAME. Those are absolute errors no kernel can
///   avoid, so the floor is that size divided by the tolerance `tol`.
/// - S is quadratic in the velocities and C linear, but in a rigid rotation at rate Ω
///   they are what is left of the second derivatives of the position fields (terms of
///   size Ω²·L0 per unit mass, e.g. the deformation angles' Ω² parts, which cancel
///   exactly in a rigid motion) once projected on the gradients: an element of a
///   spinning beam has S ~ ρI·Ω²·L0 or the deformation's share, orders of magnitude below
///   its centripetal terms max|M|·Ω²·L0. Round-off in the kernel is relative to those
///   terms, so they are the floors: max|M|·Ω²·L0 for S and max|M|·Ω for C, with
///   Ω = max(|ω1|, |ω2|, |ẋ2 − ẋ1|/L0) the element's rate of rotation.
fn errors(
    elems: &[ElemData],
    inputs: &[ElemIn],
    cpu: &[ElemOut],
    gpu: &[ElemOut],
    eps: f64,
    corotate: bool,
    tol: &[f64; 8],
) -> ([f64; 8], [usize; 8]) {
    fn maxabs<'a>(a: impl Iterator<Item = &'a f64>) -> f64 {
        a.fold(0.0f64, |m, x| m.max(x.abs()))
    }
    fn diff<'a>(a: impl Iterator<Item = &'a f64>, b: impl Iterator<Item = &'a f64>) -> f64 {
        a.zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
    }
    let rel = |d: f64, s: f64| if s == 0.0 { d } else { d / s };
    let frame = if corotate { CHANGE_OF_FRAME } else { 0.0 };
    let mut w = [0.0f64; 8];
    let mut at = [0usize; 8];
    for (ie, (((e, i), c), g)) in elems.iter().zip(inputs).zip(cpu).zip(gpu).enumerate() {
        let kmax = maxabs(c.k.iter().flatten());
        let fmax = maxabs(c.f.iter());
        let mmax = maxabs(c.m.iter().flatten());
        let floor = kmax * e.l0 * eps;
        let fscale = fmax.max(floor).max(kmax * e.l0.max(1.0) * frame / tol[0]);
        let escale = c
            .energy
            .abs()
            .max(floor * e.l0)
            .max(fmax * e.l0 * frame / tol[2]);
        let v = &i.v12;
        let omega = norm([v[3], v[4], v[5]])
            .max(norm([v[9], v[10], v[11]]))
            .max(norm(sub([v[6], v[7], v[8]], [v[0], v[1], v[2]])) / e.l0);
        let sfloor = mmax * omega * omega * e.l0;
        let err = [
            rel(diff(c.f.iter(), g.f.iter()), fscale),
            rel(diff(c.k.iter().flatten(), g.k.iter().flatten()), kmax),
            rel((c.energy - g.energy).abs(), escale),
            rel(diff(c.m.iter().flatten(), g.m.iter().flatten()), mmax),
            rel(diff(c.s.iter(), g.s.iter()), maxabs(c.s.iter()).max(sfloor)),
            rel(
                diff(c.c.iter().flatten(), g.c.iter().flatten()),
                maxabs(c.c.iter().flatten()).max(mmax * omega),
            ),
            // the host forms them from the kernel's M and S (ElemOut::products_from_m),
            // the CPU as Σ w g (g·x): floors as in `check_residual`
            rel(
                diff(c.finert.iter(), g.finert.iter()),
                maxabs(c.finert.iter()).max(mmax * maxabs(i.acc.iter()) + sfloor),
            ),
            rel(
                diff(c.mv.iter(), g.mv.iter()),
                maxabs(c.mv.iter()).max(mmax * maxabs(v.iter())),
            ),
        ];
        for i in 0..8 {
            if err[i] > w[i] {
                w[i] = err[i];
                at[i] = ie;
            }
        }
    }
    (w, at)
}

/// Absolute strain by which the co-rotated upload's state differs from the CPU's, in
/// units of L0, from the f64 rounding of (unit round-off u = 1.1e-16): X + d (u), the
/// product with Q (3 products and 2 sums per component, √3·γ3 ≈ 5u), Q's departure from
/// orthogonality after r1·frame0 (≈ 4u), the kernel's and the CPU's own elongation
/// (2X·d + d·d)/(ℓ + L0), whose d includes the rigid motion (|d| ≤ 2 L0: γ3·8L0²/2L0 =
/// 12u on the CPU, ≈ 2u on the co-rotated side): ≈ 25u in all, rounded up to 32u. The
/// state itself is only known to that: its displacements are differences of coordinates.
/// Measured: 1.2u (the f error 2.0e-10 of an element strained by 6.3e-7).
const CHANGE_OF_FRAME: f64 = 32.0 * f64::EPSILON / 2.0;

const FIELDS: [&str; 8] = ["f", "K", "energy", "M", "S", "C", "finert", "mv"];

/// f64 kernels: the same formulas in the same order as the CPU, so only the rounding of
/// fused multiply-adds and of the shader compiler's reassociation differs: 1e-12 of each
/// array's largest entry leaves three orders of magnitude above the measured ≤ 1.3e-15
/// (f of the co-rotated upload aside, see `CHANGE_OF_FRAME`).
const F64_TOL: f64 = 1e-12;

/// f32 kernels on co-rotated inputs (see `corotate` in src/gpu/mod.rs): the inputs are
/// the deformation itself (chord change, near-identity frames), rounded once to f32, so
/// every deformation measure carries a relative error of order eps32 = 6e-8 per
/// operation on its path; the deepest paths (hyper-dual kinematics, then the 4-point
/// quadrature of products of gradients) are ~150 operations long, so a linear worst
/// case is 150·eps32 ≈ 1e-5. No cancellation in the inputs is left to amplify it: that
/// is what the co-rotated upload removed (without it a rigid rotation left an absolute
/// eps32 on every angle, and the chord change of an element 1e3 m from the origin lost
/// all its digits); the cancellation inside S and C of a spinning element is measured
/// against the terms it cancels (see `errors`). Measured worst cases on lavapipe and
/// llvmpipe/GL with the kernels on the production routes (closed-form tangent,
/// `inertia_full`): f 1.8e-6, K 1.1e-6, energy 5.2e-7, M 9.5e-7, S 6.0e-7, C 1.25e-6,
/// finert 6.0e-7, mv 7.0e-7 over 4096 random states; f 1.8e-6, the rest ≤ 4.5e-7 on the
/// 12 770 states of the two simulations.
const F32_TOL: [f64; 8] = [1e-5; 8];

/// One context per adapter × precision for the whole test binary: compiling the
/// kernels on a software adapter takes seconds, so the tests share them.
fn shared_contexts(test: &str) -> &'static [Mutex<GpuContext>] {
    static CTXS: std::sync::OnceLock<Vec<Mutex<GpuContext>>> = std::sync::OnceLock::new();
    if adapters_or_skip(test).is_empty() {
        return &[];
    }
    CTXS.get_or_init(|| contexts(test).into_iter().map(Mutex::new).collect())
}

/// Lock a shared context even if another test panicked while holding it (a failing
/// test must not fail the others): the context itself is left consistent by every
/// evaluation, only `corotate` may have been left switched, so it is reset to the default.
fn lock(ctx: &Mutex<GpuContext>) -> std::sync::MutexGuard<'_, GpuContext> {
    ctx.lock().unwrap_or_else(|poisoned| {
        ctx.clear_poison();
        let mut g = poisoned.into_inner();
        g.corotate = g.precision == Precision::F32;
        g
    })
}

fn check_batch(
    test: &str,
    ctx: &mut GpuContext,
    elems: &[ElemData],
    inputs: &[ElemIn],
) -> [f64; 8] {
    let n = elems.len();
    let mut cpu = vec![ElemOut::default(); n];
    CpuEval.evaluate(elems, inputs, true, &mut cpu).unwrap();
    let mut out = vec![ElemOut::default(); n];
    ctx.evaluate(elems, inputs, true, &mut out)
        .unwrap_or_else(|e| panic!("{test}: {e}"));
    let eps = match ctx.precision {
        Precision::F64 => f64::EPSILON / 2.0,
        Precision::F32 => f32::EPSILON as f64 / 2.0,
    };
    let tol = match ctx.precision {
        Precision::F64 => [F64_TOL; 8],
        Precision::F32 => F32_TOL,
    };
    let (err, at) = errors(elems, inputs, &cpu, &out, eps, ctx.corotate, &tol);
    let _ = writeln!(
        std::io::stderr(),
        "{test}: {} {} corotate={} n={n}: {}",
        ctx.adapter.label(),
        ctx.precision.as_str(),
        ctx.corotate,
        FIELDS
            .iter()
            .zip(err)
            .map(|(f, e)| format!("{f} {e:.2e}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    for i in 0..8 {
        if err[i] > tol[i] {
            let j = at[i];
            let _ =
                writeln!(
                std::io::stderr(),
                "worst element for {}: {:?}\n{:?}\ncpu f {:?}\ngpu f {:?}\ncpu s {:?}\ngpu s {:?}",
                FIELDS[i], elems[j], inputs[j], cpu[j].f, out[j].f, cpu[j].s, out[j].s
            );
        }
        assert!(
            err[i] <= tol[i],
            "{test}: {} {}: {} error {:.3e} above {:.1e}",
            ctx.adapter.label(),
            ctx.precision.as_str(),
            FIELDS[i],
            err[i],
            tol[i]
        );
    }
    // without inertia the kernel must still overwrite M, S, C (with zeros), as the CPU
    let mut out2 = vec![ElemOut::default(); n];
    for o in out2.iter_mut() {
        o.m[0][0] = f64::NAN;
        o.s[3] = f64::NAN;
    }
    ctx.evaluate(elems, inputs, false, &mut out2).unwrap();
    assert!(out2.iter().all(|o| o.m[0][0] == 0.0 && o.s[3] == 0.0));
    err
}

const RESIDUAL_FIELDS: [&str; 5] = ["f", "energy", "S", "finert", "mv"];

/// The residual kernel (beam_residual.wgsl) against `CpuEval::one_residual`, normwise per
/// array as in [`errors`]: f and the energy with the same floors; S with the floor
/// max|M|·Ω²·L0; finert = M·acc + S and mv = M·v12 with the floors max|M|·max|acc| (plus
/// S's) and max|M|·max|v12|, the size of the products they sum (M from the CPU's full
/// evaluation). Tolerances are the full kernels' (`F64_TOL`, `F32_TOL`): the residual
/// kernel runs the same functions (the force kernel's closed-form gradient and force,
/// the inertia kernel's field-gradient rows and hyper-dual pass) and forms M·x as
/// Σ w g (g·x), as the CPU's residual route does.
fn check_residual(
    test: &str,
    ctx: &mut GpuContext,
    elems: &[ElemData],
    inputs: &[ElemIn],
) -> [f64; 5] {
    let n = elems.len();
    let mut full = vec![ElemOut::default(); n];
    CpuEval.evaluate(elems, inputs, true, &mut full).unwrap();
    let mut cpu = vec![ElemOut::default(); n];
    CpuEval
        .evaluate_residual(elems, inputs, true, &mut cpu)
        .unwrap();
    let mut out = vec![ElemOut::default(); n];
    for o in out.iter_mut() {
        o.k[1][2] = f64::NAN;
        o.m[0][0] = f64::NAN;
        o.c[3][4] = f64::NAN;
    }
    let t = ctx
        .evaluate_residual(elems, inputs, true, &mut out)
        .unwrap_or_else(|e| panic!("{test}: {e}"));
    let (eps, tol) = match ctx.precision {
        Precision::F64 => (f64::EPSILON / 2.0, F64_TOL),
        Precision::F32 => (f32::EPSILON as f64 / 2.0, F32_TOL[0]),
    };
    let frame = if ctx.corotate { CHANGE_OF_FRAME } else { 0.0 };
    let maxabs = |a: &[f64]| a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
    };
    let rel = |d: f64, s: f64| if s == 0.0 { d } else { d / s };
    let mut w = [0.0f64; 5];
    for (((e, i), (c, f)), g) in elems
        .iter()
        .zip(inputs)
        .zip(cpu.iter().zip(&full))
        .zip(&out)
    {
        let kmax = maxabs(f.k.as_flattened());
        let mmax = maxabs(f.m.as_flattened());
        let fmax = maxabs(&c.f);
        let floor = kmax * e.l0 * eps;
        let fscale = fmax.max(floor).max(kmax * e.l0.max(1.0) * frame / tol);
        let escale = c
            .energy
            .abs()
            .max(floor * e.l0)
            .max(fmax * e.l0 * frame / tol);
        let v = &i.v12;
        let omega = norm([v[3], v[4], v[5]])
            .max(norm([v[9], v[10], v[11]]))
            .max(norm(sub([v[6], v[7], v[8]], [v[0], v[1], v[2]])) / e.l0);
        let sfloor = mmax * omega * omega * e.l0;
        let err = [
            rel(diff(&c.f, &g.f), fscale),
            rel((c.energy - g.energy).abs(), escale),
            rel(diff(&c.s, &g.s), maxabs(&c.s).max(sfloor)),
            rel(
                diff(&c.finert, &g.finert),
                maxabs(&c.finert).max(mmax * maxabs(&i.acc) + sfloor),
            ),
            rel(diff(&c.mv, &g.mv), maxabs(&c.mv).max(mmax * maxabs(v))),
        ];
        for k in 0..5 {
            w[k] = w[k].max(err[k]);
        }
        // a residual evaluation writes the matrices as zero, like the CPU's
        assert!(
            g.k.as_flattened().iter().all(|x| *x == 0.0)
                && g.m.as_flattened().iter().all(|x| *x == 0.0)
                && g.c.as_flattened().iter().all(|x| *x == 0.0),
            "{test}: residual evaluation left K, M or C nonzero"
        );
    }
    let _ =
        writeln!(
        std::io::stderr(),
        "{test}: residual {} {} corotate={} n={n}: {}; downloaded {} B (a full evaluation: {} B)",
        ctx.adapter.label(),
        ctx.precision.as_str(),
        ctx.corotate,
        RESIDUAL_FIELDS
            .iter()
            .zip(w)
            .map(|(f, e)| format!("{f} {e:.2e}"))
            .collect::<Vec<_>>()
            .join(", "),
        t.bytes_down,
        n * 460 * if ctx.precision == Precision::F64 { 8 } else { 4 }
    );
    for k in 0..5 {
        assert!(
            w[k] <= tol,
            "{test}: {} {}: residual {} error {:.3e} above {:.1e}",
            ctx.adapter.label(),
            ctx.precision.as_str(),
            RESIDUAL_FIELDS[k],
            w[k],
            tol
        );
    }
    // only 52 words per element come back, not the 460 of f, K, M, S, C
    let word = if ctx.precision == Precision::F64 {
        8
    } else {
        4
    };
    assert_eq!(t.bytes_down, (n * 52 * word) as u64);
    // without inertia: f and energy as before, the inertial forces zero
    let mut out2 = vec![ElemOut::default(); n];
    for o in out2.iter_mut() {
        o.finert[2] = f64::NAN;
        o.s[3] = f64::NAN;
        o.mv[5] = f64::NAN;
    }
    ctx.evaluate_residual(elems, inputs, false, &mut out2)
        .unwrap();
    for (a, b) in out.iter().zip(&out2) {
        assert_eq!(a.f, b.f, "{test}: f depends on the inertia flag");
        assert!(b.finert[2] == 0.0 && b.s[3] == 0.0 && b.mv[5] == 0.0);
    }
    w
}

#[test]
fn residual_kernel_matches_cpu_residual_on_4096_random_states_in_f64_and_f32() {
    let test = "residual_kernel_matches_cpu_residual_on_4096_random_states_in_f64_and_f32";
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (elems, inputs): (Vec<_>, Vec<_>) = (0..4096)
        .map(|i| random_element(&mut rng, [1e-3, 1e-4, 1e-5][i % 3]))
        .unzip();
    for ctx in shared_contexts(test) {
        check_residual(test, &mut lock(ctx), &elems, &inputs);
    }
}

/// The model data (element records) goes to the device once, not with every dispatch:
/// repeated evaluations of the same element data (same content; here also a fresh copy
/// in another allocation) upload only the per-iteration inputs; changed data is uploaded
/// once more. Counts, not times.
#[test]
fn model_data_is_uploaded_once_not_per_dispatch() {
    let test = "model_data_is_uploaded_once_not_per_dispatch";
    let mut rng = Rng(7);
    let (elems, inputs): (Vec<_>, Vec<_>) =
        (0..300).map(|_| random_element(&mut rng, 1e-4)).unzip();
    let n = elems.len();
    for ctx in shared_contexts(test) {
        let mut ctx = lock(ctx);
        let word = if ctx.precision == Precision::F64 {
            8
        } else {
            4
        };
        let before = ctx.model_uploads();
        let mut out = vec![ElemOut::default(); n];
        let mut bytes = Vec::new();
        // the first dispatch uploads this data; it may also rewrite other tests' resident
        // segments of this shared context, when a test before it switched `corotate`
        // (`lock` resets it), so the count that must stay flat starts after it
        let mut first = before;
        for it in 0..6 {
            if it == 1 {
                first = ctx.model_uploads();
                assert!(
                    first.uploads > before.uploads && first.elements - before.elements >= n as u64,
                    "{test}: the first dispatch uploads the model data"
                );
            }
            let copy = elems.clone();
            let t = if it % 2 == 0 {
                ctx.evaluate(&copy, &inputs, true, &mut out)
            } else {
                ctx.evaluate_residual(&copy, &inputs, true, &mut out)
            }
            .unwrap_or_else(|e| panic!("{test}: {e}"));
            bytes.push(t.bytes_up);
        }
        let after = ctx.model_uploads();
        assert_eq!(
            after.uploads - first.uploads,
            0,
            "{test}: model uploads after the first of 6 dispatches"
        );
        assert_eq!(after.elements - first.elements, 0);
        // per dispatch: parameters (16 B) and the 36-word inputs, plus the 12-word
        // accelerations for the residual kernel; the slot indices only when they changed,
        // in the full kernels' index or the residual kernel's own (written by the first
        // residual dispatch, 4 B per element)
        let inp = (16 + n * 36 * word) as u64;
        let acc = (n * 12 * word) as u64;
        for (it, b) in bytes.iter().enumerate().skip(1) {
            let want = match it {
                1 => inp + acc + 4 * n as u64,
                _ if it % 2 == 0 => inp,
                _ => inp + acc,
            };
            assert_eq!(*b, want, "{test}: bytes uploaded by dispatch {it}");
        }
        let _ = writeln!(
            std::io::stderr(),
            "{test}: {} {}: {} model upload(s) of {} B for 6 dispatches; per dispatch {:?} B",
            ctx.adapter.label(),
            ctx.precision.as_str(),
            after.uploads - before.uploads,
            after.bytes - before.bytes,
            bytes
        );
        // different content: uploaded (once) again
        let mut changed = elems.clone();
        changed[17].props.ea *= 2.0;
        ctx.evaluate(&changed, &inputs, false, &mut out).unwrap();
        ctx.evaluate(&changed, &inputs, false, &mut out).unwrap();
        assert_eq!(ctx.model_uploads().uploads - after.uploads, 1);
    }
}

/// Bit patterns of every output field, for bitwise comparison (NaN equal to NaN, −0
/// different from +0).
fn out_bits(o: &[ElemOut]) -> Vec<u64> {
    let mut w = Vec::new();
    for e in o {
        w.extend(e.f.iter().map(|x| x.to_bits()));
        w.extend(e.k.iter().flatten().map(|x| x.to_bits()));
        w.push(e.energy.to_bits());
        w.extend(e.m.iter().flatten().map(|x| x.to_bits()));
        w.extend(e.s.iter().map(|x| x.to_bits()));
        w.extend(e.c.iter().flatten().map(|x| x.to_bits()));
        w.extend(e.finert.iter().map(|x| x.to_bits()));
        w.extend(e.mv.iter().map(|x| x.to_bits()));
    }
    w
}

/// One round of requests of every kind (full with and without inertia, residual-only
/// with and without, an empty one, two sharing element data) is one submission with one
/// dispatch per kernel, and every request's outputs are bit-identical to evaluating it
/// alone, in both upload forms (`corotate`).
#[test]
fn a_mixed_round_is_one_submission_and_each_request_is_bit_identical_to_alone() {
    let test = "a_mixed_round_is_one_submission_and_each_request_is_bit_identical_to_alone";
    let mut rng = Rng(0x5eed_0017);
    // (residual, inertia, elements)
    let kinds = [
        (false, true, 7),
        (true, true, 5),
        (false, false, 3),
        (true, false, 6),
        (false, true, 0),
        (true, true, 4),
        (false, true, 7),
    ];
    let data: Vec<(Vec<ElemData>, Vec<ElemIn>)> = kinds
        .iter()
        .map(|&(_, _, n)| (0..n).map(|_| random_element(&mut rng, 1e-4)).unzip())
        .collect();
    // the last request evaluates the first one's elements in another state
    let mut data = data;
    data[6].0 = data[0].0.clone();
    for ctx in shared_contexts(test) {
        let mut ctx = lock(ctx);
        for corotate in [false, true] {
            ctx.corotate = corotate;
            let label = format!(
                "{test}: {} {} corotate={corotate}",
                ctx.adapter.label(),
                ctx.precision.as_str()
            );
            let alone: Vec<Vec<ElemOut>> = kinds
                .iter()
                .zip(&data)
                .map(|(&(residual, inertia, n), (e, i))| {
                    let mut out = vec![ElemOut::default(); n];
                    let r = if residual {
                        ctx.evaluate_residual(e, i, inertia, &mut out)
                    } else {
                        ctx.evaluate(e, i, inertia, &mut out)
                    };
                    r.unwrap_or_else(|e| panic!("{label}: {e}"));
                    out
                })
                .collect();
            let mut outs: Vec<Vec<ElemOut>> = kinds
                .iter()
                .map(|&(_, _, n)| vec![ElemOut::default(); n])
                .collect();
            let mut reqs: Vec<EvalRequest<'_>> = kinds
                .iter()
                .zip(&data)
                .zip(outs.iter_mut())
                .map(|((&(residual, inertia, _), (e, i)), out)| EvalRequest {
                    elems: e,
                    inputs: i,
                    out,
                    residual,
                    inertia,
                })
                .collect();
            let t = ctx
                .evaluate_batch(&mut reqs)
                .unwrap_or_else(|e| panic!("{label}: {e}"));
            assert_eq!(t.batches, 1, "{label}: submissions");
            // beam_force and beam_inertia over the full requests, beam_residual over
            // the residual-only ones
            assert_eq!(t.dispatches, 3, "{label}: dispatches");
            assert_eq!(t.residual_dispatches, 1, "{label}");
            assert_eq!(t.requests, 6, "{label}: requests with elements");
            assert_eq!(t.elements, 32, "{label}");
            for (k, (a, b)) in alone.iter().zip(&outs).enumerate() {
                assert!(
                    out_bits(a) == out_bits(b),
                    "{label}: request {k} {:?} differs from its lone evaluation",
                    kinds[k]
                );
            }
            // a round of full requests only: no residual dispatch; of residual only: one
            let mut outs2: Vec<Vec<ElemOut>> = vec![vec![ElemOut::default(); 7]; 2];
            let [o0, o1] = &mut outs2[..] else {
                unreachable!()
            };
            let mut reqs = [
                EvalRequest {
                    elems: &data[0].0,
                    inputs: &data[0].1,
                    out: o0,
                    residual: false,
                    inertia: true,
                },
                EvalRequest {
                    elems: &data[6].0,
                    inputs: &data[6].1,
                    out: o1,
                    residual: false,
                    inertia: true,
                },
            ];
            let t = ctx.evaluate_batch(&mut reqs).unwrap();
            assert_eq!((t.batches, t.dispatches, t.residual_dispatches), (1, 2, 0));
            assert!(out_bits(&outs2[0]) == out_bits(&alone[0]), "{label}");
            assert!(out_bits(&outs2[1]) == out_bits(&alone[6]), "{label}");
        }
        ctx.corotate = ctx.precision == Precision::F32;
    }
}

#[test]
fn kernels_match_cpu_on_4096_random_large_motion_small_strain_states() {
    let test = "kernels_match_cpu_on_4096_random_large_motion_small_strain_states";
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (elems, inputs): (Vec<_>, Vec<_>) = (0..4096)
        .map(|i| random_element(&mut rng, [1e-3, 1e-4, 1e-5][i % 3]))
        .unzip();
    for ctx in shared_contexts(test) {
        check_batch(test, &mut lock(ctx), &elems, &inputs);
    }
}

#[test]
fn f64_kernels_match_cpu_with_the_corotated_upload_too() {
    // the f32 path's host-side change of frame is exact algebra up to its f64 rounding of
    // the state (CHANGE_OF_FRAME, the floor of f and the energy); K, M, S, C to 1e-12
    let test = "f64_kernels_match_cpu_with_the_corotated_upload_too";
    let mut rng = Rng(42);
    let (elems, inputs): (Vec<_>, Vec<_>) =
        (0..1024).map(|_| random_element(&mut rng, 1e-3)).unzip();
    let ctxs = shared_contexts(test);
    if ctxs.is_empty() {
        return;
    }
    let mut ran = false;
    for ctx in ctxs {
        let mut ctx = lock(ctx);
        if ctx.precision == Precision::F64 {
            ctx.corotate = true;
            check_batch(test, &mut ctx, &elems, &inputs);
            ctx.corotate = false;
            ran = true;
        }
    }
    if !ran {
        skip(test, "no adapter with f64 shaders");
    }
}

/// Records every element batch the solver evaluates (on the CPU).
struct Recorder {
    seen: Mutex<(Vec<ElemData>, Vec<ElemIn>)>,
}
impl ElementEval for Recorder {
    fn evaluate(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        let mut g = self.seen.lock().unwrap();
        if g.1.len() < 20_000 {
            g.0.extend_from_slice(elems);
            g.1.extend_from_slice(inputs);
        }
        CpuEval.evaluate(elems, inputs, inertia, out)
    }
    fn name(&self) -> String {
        "recorder".into()
    }
}

#[test]
fn kernels_match_cpu_on_the_states_of_real_simulations() {
    let test = "kernels_match_cpu_on_the_states_of_real_simulations";
    let ctxs = shared_contexts(test);
    if ctxs.is_empty() {
        return;
    }
    let rec = Arc::new(Recorder {
        seen: Mutex::new((Vec::new(), Vec::new())),
    });
    for (file, sets) in [
        (
            "rotating_cantilever.toml",
            vec![("t_end", 1.0), ("omega", 8.0), ("dt", 0.01)],
        ),
        ("flapping_blade.toml", vec![("t_end", 0.5)]),
    ] {
        let m = common::shipped(file, &sets);
        let ctx = latdyn::solver::dynamics::RunContext {
            eval: Some(rec.clone()),
            ..Default::default()
        };
        let (_, _, err) = latdyn::solver::dynamics::run_in(&m, &ctx, |_, _| {});
        assert!(err.is_none(), "{file}: {err:?}");
    }
    let (elems, inputs) = rec.seen.lock().unwrap().clone();
    for ctx in ctxs {
        check_batch(test, &mut lock(ctx), &elems, &inputs);
        check_residual(test, &mut lock(ctx), &elems, &inputs);
    }
}

/// The adapter `--backend gpu` would take for precision `p`; None (reported as skipped)
/// when no adapter has f64 shaders.
fn preferred_context(test: &str, p: Precision) -> Option<GpuContext> {
    match GpuContext::open(p, true) {
        Ok(c) => Some(c),
        Err(gpu::GpuError::NoF64(_)) => {
            skip(test, "no adapter with f64 shaders, f64 part not run");
            None
        }
        Err(e) => panic!("{test}: {e}"),
    }
}

/// A GPU stage as `sweep --backend gpu` makes it: one evaluator shared by every worker.
fn gpu_stage(eval: &Arc<gpu::GpuEval>, label: &str) -> latdyn::ensemble::Stage {
    let e = eval.clone();
    latdyn::ensemble::Stage {
        backend: "gpu".into(),
        precision: label.rsplit(' ').next().unwrap_or_default().into(),
        adapter: label.into(),
        make: Some(Arc::new(move || e.clone() as Arc<dyn ElementEval>)),
    }
}

/// The rotating-beam campaign of the README (Ω̄ = 0, 5, 10, flapwise tip impulse, 12 s)
/// in one batch (as `sweep --backend gpu` on one worker), against the CPU path.
fn sweep(stage: &latdyn::ensemble::Stage, threads: usize) -> latdyn::ensemble::CampaignRun {
    use latdyn::ensemble::{self, Campaign};
    let c = Campaign {
        model_path: std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("models/rotating_cantilever.toml"),
        base: vec![("dt".to_string(), 0.01)],
        variants: [0.0, 5.0, 10.0]
            .iter()
            .map(|w| vec![("omega".to_string(), *w)])
            .collect(),
        threads,
        batch: 3,
        output: None,
        shard: None,
        accuracy: None,
        frequency_sensor: Some(("tip_flap".into(), 0)),
        command_line: "test".into(),
    };
    let p = ensemble::prepare(&c).unwrap();
    let stop = std::sync::atomic::AtomicBool::new(false);
    ensemble::run_to(&c, &p, &stop, false, &|_, _| {}, stage, None).unwrap()
}

#[test]
fn rotating_beam_sweep_on_the_gpu_gives_the_cpu_frequencies_and_sensors() {
    let test = "rotating_beam_sweep_on_the_gpu_gives_the_cpu_frequencies_and_sensors";
    let list = adapters_or_skip(test);
    if list.is_empty() {
        return;
    }
    let t_cpu = std::time::Instant::now();
    let cpu = sweep(&latdyn::ensemble::Stage::cpu(), 2).outcomes;
    let _ = writeln!(
        std::io::stderr(),
        "{test}: cpu: {:.1} s",
        t_cpu.elapsed().as_secs_f64()
    );
    // one adapter per precision: the preferred one (what `--backend gpu` would take)
    for p in [Precision::F32, Precision::F64] {
        let t_open = std::time::Instant::now();
        let Some(ctx) = preferred_context(test, p) else {
            continue;
        };
        let label = format!("{} {}", ctx.adapter.label(), p.as_str());
        let _ = writeln!(
            std::io::stderr(),
            "{test}: {label}: context (kernel compilation) {:.1} s",
            t_open.elapsed().as_secs_f64()
        );
        let eval = Arc::new(gpu::GpuEval::new(ctx));
        let stage = gpu_stage(&eval, &label);
        let t0 = std::time::Instant::now();
        let run = sweep(&stage, 1);
        let out = run.outcomes;
        let (st, model) = (eval.times(), eval.model_uploads());
        let _ = writeln!(
            std::io::stderr(),
            "{test}: {label}: {:.1} s, {} rounds, {:.2} dispatches and {:.2} requests per round ({} residual-only dispatches); model data {} upload(s) of {} B; GPU upload {:.1} s, kernels {:.1} s, download {:.1} s",
            t0.elapsed().as_secs_f64(),
            st.batches,
            st.dispatches as f64 / st.batches.max(1) as f64,
            st.requests as f64 / st.batches.max(1) as f64,
            st.residual_dispatches,
            model.uploads,
            model.bytes,
            st.upload_s,
            st.kernel_s,
            st.download_s
        );
        // one submission per round of the batch driver, at most one dispatch per kernel
        // (the integrator finds its sparse pattern without an element evaluation)
        assert_eq!(st.batches, run.batch.calls, "{label}: rounds");
        assert_eq!(st.requests, run.batch.requests, "{label}: requests");
        assert!(st.dispatches <= 3 * st.batches, "{label}: {st:?}");
        // modified Newton: residual-only rounds use the residual kernel
        assert!(st.residual_dispatches > 0, "{label}: {st:?}");
        // the variants share their element data (Ω varies, the beam does not): one
        // upload for the campaign
        assert_eq!(model.uploads, 1, "{label}: model data uploads {model:?}");
        for (c, g) in cpu.iter().zip(&out) {
            assert_eq!(
                g.state,
                latdyn::output::VariantState::Completed,
                "{label}: {}",
                g.message
            );
            let fc = c.derived[0].1;
            let fg = g.derived[0].1;
            let ef = ((fg - fc) / fc).abs();
            // sensors: largest difference over min, max, final of every component,
            // relative to the sensor's own range
            let mut es = 0.0f64;
            for (sc, sg) in c.sensors.iter().zip(&g.sensors) {
                let range = sc
                    .max
                    .iter()
                    .zip(&sc.min)
                    .fold(0.0f64, |m, (a, b)| m.max(a.abs()).max(b.abs()));
                for (a, b) in [(&sc.min, &sg.min), (&sc.max, &sg.max), (&sc.last, &sg.last)] {
                    for (x, y) in a.iter().zip(b.iter()) {
                        if range > 0.0 {
                            es = es.max((x - y).abs() / range);
                        }
                    }
                }
            }
            let _ = writeln!(
                std::io::stderr(),
                "{test}: {label}: {:?}: first flap {fg:.6} Hz vs CPU {fc:.6} Hz (rel {ef:.2e}), sensors rel {es:.2e}; Newton iterations {} vs CPU {}, rejected steps {} vs CPU {}",
                c.parameters,
                g.newton_iterations,
                c.newton_iterations,
                g.rejected_steps,
                c.rejected_steps
            );
            // The Newton test knows the element stage's precision (solver::linear::
            // Convergence): f32 noise must not cost iterations or halved steps. Measured
            // f32/CPU iterations: 1.33 at Ω̄ = 0 (one more iteration to see the noise
            // floor), 0.68 and 0.59 at Ω̄ = 5, 10 (tolerance floor 16u above tol);
            // before, f32 at Ω̄ = 0 halved 3367 steps and took 141 s.
            assert!(
                g.rejected_steps <= c.rejected_steps,
                "{label}: {} rejected steps, CPU {}",
                g.rejected_steps,
                c.rejected_steps
            );
            assert!(
                g.newton_iterations as f64 <= 1.5 * c.newton_iterations as f64,
                "{label}: {} Newton iterations, CPU {}",
                g.newton_iterations,
                c.newton_iterations
            );
            match p {
                // f64: the same arithmetic up to fused multiply-adds, over 1200 steps
                Precision::F64 => assert!(es < 1e-9, "{label}: sensors differ by {es:.2e}"),
                // f32: element arrays to ~1e-5 (see F32_TOL) perturb the Newton
                // residual, not the converged physics beyond that; the frequency comes
                // from the FFT peak refined by least squares, 1e-4 is 10× the measured.
                // Sensors: measured 7.6e-7, 9.4e-6, 7.3e-5 of their range at Ω̄ = 0, 5,
                // 10 over 1200 steps; 1e-3 is a guard against a solver that stops at the
                // noise too early or wanders (the Ω̄ = 0 tip was 2 % off before).
                Precision::F32 => {
                    assert!(ef < 1e-4, "{label}: frequency differs by {ef:.2e}");
                    assert!(es < 1e-3, "{label}: sensors differ by {es:.2e}");
                }
            }
        }
    }
}

/// A batch of variants on the GPU stage (one round, one submission per Newton iteration
/// of all of them) gives every variant bit-identical histories to that variant run alone
/// on the same GPU stage: the variants differ in speed (the same element data) and in
/// stiffness (their own), so rounds mix full and residual-only requests of different
/// segments, and variants need different iteration counts.
#[test]
fn a_gpu_batch_gives_each_variant_its_lone_gpu_history_bit_for_bit() {
    use latdyn::ensemble::{self, Campaign};
    let test = "a_gpu_batch_gives_each_variant_its_lone_gpu_history_bit_for_bit";
    if adapters_or_skip(test).is_empty() {
        return;
    }
    let variants: Vec<Vec<(String, f64)>> = [(0.0, 1.0), (5.0, 1.0), (10.0, 2.0), (5.0, 0.5)]
        .iter()
        .map(|&(w, ei)| vec![("omega".to_string(), w), ("EI".to_string(), ei)])
        .collect();
    let campaign = |batch: usize| Campaign {
        model_path: std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("models/rotating_cantilever.toml"),
        base: vec![("t_end".to_string(), 1.5), ("dt".to_string(), 0.01)],
        variants: variants.clone(),
        threads: 1,
        batch,
        output: None,
        shard: None,
        accuracy: None,
        frequency_sensor: None,
        command_line: "test".into(),
    };
    for p in [Precision::F32, Precision::F64] {
        let Some(ctx) = preferred_context(test, p) else {
            continue;
        };
        let label = format!("{} {}", ctx.adapter.label(), p.as_str());
        let eval = Arc::new(gpu::GpuEval::new(ctx));
        let stage = gpu_stage(&eval, &label);
        let stop = std::sync::atomic::AtomicBool::new(false);
        let run = |batch: usize| {
            let c = campaign(batch);
            let prep = ensemble::prepare(&c).unwrap();
            let before = (eval.times(), eval.model_uploads());
            let r = ensemble::run_to(&c, &prep, &stop, true, &|_, _| {}, &stage, None).unwrap();
            let (t, m) = (eval.times(), eval.model_uploads());
            (
                r,
                t.batches - before.0.batches,
                m.uploads - before.1.uploads,
            )
        };
        let (batched, rounds, uploads) = run(4);
        // omega does not change the element data, EI does: three different tables
        assert_eq!(uploads, 3, "{label}: model data uploads of the batch");
        // one submission per round (the sparse pattern needs no element evaluation)
        assert_eq!(
            rounds, batched.batch.calls,
            "{label}: one submission per round"
        );
        assert!(
            batched.batch.requests > 2 * batched.batch.calls,
            "{label}: rounds carry the batch ({:?})",
            batched.batch
        );
        let (alone, ..) = run(1);
        assert_eq!(alone.batch.requests, alone.batch.calls, "{label}");
        let _ = writeln!(
            std::io::stderr(),
            "{test}: {label}: batch of 4: {} rounds for {} requests; alone: {} rounds",
            batched.batch.calls,
            batched.batch.requests,
            alone.batch.calls
        );
        for (b, a) in batched.outcomes.iter().zip(&alone.outcomes) {
            let what = format!("{label}: variant {}", b.global_index);
            assert_eq!(b.global_index, a.global_index);
            assert_eq!(
                b.state,
                latdyn::output::VariantState::Completed,
                "{what}: {}",
                b.message
            );
            let (hb, ha) = (b.history.as_ref().unwrap(), a.history.as_ref().unwrap());
            let bits = |v: &Vec<Vec<Vec<f64>>>| -> Vec<u64> {
                v.iter().flatten().flatten().map(|x| x.to_bits()).collect()
            };
            assert!(!ha.t.is_empty(), "{what}: no samples");
            assert_eq!(hb.t, ha.t, "{what}: times");
            assert!(
                bits(&hb.values) == bits(&ha.values),
                "{what}: sensor histories"
            );
            assert_eq!(b.steps, a.steps, "{what}");
            assert_eq!(b.newton_iterations, a.newton_iterations, "{what}");
            assert_eq!(b.rejected_steps, a.rejected_steps, "{what}");
        }
    }
}

#[test]
fn a_consistent_start_on_the_f32_kernels_gives_the_cpu_start() {
    // The start differences the static residual along the initial motion: in f32 that is
    // only as good as the kernels' forces relative to the deformation (cancellation-free
    // strains). Measured on the four-bar: the f32 start's largest rate change 6e-8 off
    // the CPU's, and the first sample of the hinge rate 1e-7 off; 1e-5 leaves room for
    // another adapter's rounding and is 3000× below the 3 % a too-large difference step
    // gave (src/solver/start.rs, `PROBE`).
    let test = "a_consistent_start_on_the_f32_kernels_gives_the_cpu_start";
    if adapters_or_skip(test).is_empty() {
        return;
    }
    let Some(ctx) = preferred_context(test, Precision::F32) else {
        return;
    };
    let m = common::shipped("fourbar.toml", &[("t_end", 0.02)]);
    let run = |eval: Option<Arc<dyn ElementEval>>| {
        let ctx = latdyn::solver::dynamics::RunContext {
            eval,
            ..Default::default()
        };
        let (h, stats, err) = latdyn::solver::dynamics::run_in(&m, &ctx, |_, _| {});
        assert!(err.is_none(), "{err:?}");
        let g1 = h.values[m.sensor_index("g1").unwrap()][1][1];
        (stats.consistent_start.unwrap(), g1)
    };
    let (cpu, g1_cpu) = run(None);
    let gpu_eval: Arc<dyn ElementEval> = Arc::new(gpu::GpuEval::new(ctx));
    let (f32s, g1_f32) = run(Some(gpu_eval.clone()));
    // The time-error estimate does not read f32 round-off as an error: the coupler
    // translates without turning, and its rz, 1.6e-12 rad of f32 noise against 0.2 rad
    // of hinge angles, was estimated at the cap, 200 %, with a warning blaming the step
    // (a probe, session 46; the CPU reads 3.6e-3). Bound: within 2× of the CPU's figure.
    let longer = common::shipped("fourbar.toml", &[("t_end", 0.2)]);
    let estimate = |eval: Option<Arc<dyn ElementEval>>| {
        let ctx = latdyn::solver::dynamics::RunContext {
            eval,
            ..Default::default()
        };
        let (_, stats, err) = latdyn::solver::dynamics::run_in(&longer, &ctx, |_, _| {});
        assert!(err.is_none(), "{err:?}");
        stats.time_error_estimate.unwrap()
    };
    let (e_cpu, e_f32) = (estimate(None), estimate(Some(gpu_eval)));
    assert!(
        e_f32 < 2.0 * e_cpu,
        "f32 estimate {e_f32} against the CPU's {e_cpu}"
    );
    assert!(cpu.applied && f32s.applied);
    let off = (f32s.largest_change - cpu.largest_change).abs() / cpu.largest_change;
    assert!(
        off < 1e-5,
        "largest change {} against {}",
        f32s.largest_change,
        cpu.largest_change
    );
    assert!(
        (g1_f32 - g1_cpu).abs() < 1e-5 * g1_cpu.abs(),
        "{g1_f32} against {g1_cpu}"
    );
}
