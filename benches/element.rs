//! Element kernel timings (prints, never asserts): calls per second of the internal
//! force + tangent and of the inertia terms, on a deformed, rotated element.

use latdyn::element::reference::{
    inertia_columns, internal_force_tangent_columns, internal_force_tangent_dual,
};
use latdyn::element::*;
use latdyn::math::*;
use latdyn::model::BeamProps;
use std::time::Instant;

fn main() {
    let props = BeamProps {
        ea: 1e7,
        eiy: 1e3,
        eiz: 2e3,
        gj: 8e2,
        rho_a: 2.0,
        rho_iy: 1e-3,
        rho_iz: 2e-3,
    };
    let x1 = [0.1, 0.2, 0.3];
    let dir = normalize([1.0, 0.2, -0.1]);
    let x2 = add(x1, dir);
    let y = perpendicular(dir, [0.0, 0.0, 1.0]);
    let e = ElemData::new(props, from_cols(dir, y, cross(dir, y)), x1, x2);
    let q = rot_exp([0.3, -0.4, 0.5]);
    let s = ElemState {
        u1: [0.01, 0.0, 0.0],
        r1: mat_mul(&rot_exp([0.01, 0.02, -0.01]), &q),
        u2: sub(mat_vec(&q, e.chord0), e.chord0),
        r2: mat_mul(&rot_exp([-0.02, 0.01, 0.03]), &q),
    };
    let v = [0.1, 0.2, 0.3, 1.0, -1.0, 0.5, 0.0, 0.1, 0.2, 0.9, -1.1, 0.4];
    let n = 20000;
    let t = Instant::now();
    let mut acc = 0.0;
    for _ in 0..n {
        let (f, k) = internal_force_tangent(&e, std::hint::black_box(&s));
        acc += f[0] + k[3][4];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    let t_tangent = dt;
    println!(
        "internal_force_tangent: {:.2} us/call   (closed form)",
        dt * 1e6
    );
    let t = Instant::now();
    for _ in 0..n {
        let (f, k) = internal_force_tangent_dual(&e, std::hint::black_box(&s));
        acc += f[0] + k[3][4];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    let t_dual = dt;
    println!("  (9-lane dual pass:    {:.2} us/call)", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let (f, k) = internal_force_tangent_columns(&e, std::hint::black_box(&s));
        acc += f[0] + k[3][4];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!("  (12 dual passes:      {:.2} us/call)", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let (m, sv, c) = inertia(&e, std::hint::black_box(&s), &v);
        acc += m[0][0] + sv[1] + c[2][3];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    let t_inertia = dt;
    println!("inertia (M, S, C):      {:.2} us/call", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let (m, sv, c) = inertia_columns(&e, std::hint::black_box(&s), &v);
        acc += m[0][0] + sv[1] + c[2][3];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!("  (C by 12 passes:      {:.2} us/call)", dt * 1e6);
    let a = [
        0.5, -0.3, 0.2, 0.1, 0.4, -0.2, 0.3, 0.1, -0.4, 0.2, 0.0, 0.3,
    ];
    let t = Instant::now();
    for _ in 0..n {
        let r = inertia_residual(&e, std::hint::black_box(&s), &v, &a);
        acc += r.finert[0] + r.mv[1];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    let t_residual = dt;
    println!("inertia_residual (M a + S, M v): {:.2} us/call", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let m = mass_matrix(&e, std::hint::black_box(&s));
        acc += m[0][0];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!("mass_matrix (M):        {:.2} us/call", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let f = internal_force(&e, std::hint::black_box(&s));
        acc += f[0];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!(
        "internal_force:         {:.2} us/call   ({acc:.1})",
        dt * 1e6
    );
    stage_parts(&e, &s, &v, &a);
    let [t_full, t_res] = stage_report(&e, &s, &v, &a);
    let [t_full_b, t_res_b] = batch_report(&e, &s, &v, &a);
    flop_report(
        &e,
        &s,
        [
            t_tangent, t_dual, t_inertia, t_residual, t_full, t_res, t_full_b, t_res_b,
        ],
    );
}

/// The full evaluation's four parts, each timed alone on one element: where a faster
/// stage has to come from (the doc comments of the functions say what each computes).
fn stage_parts(e: &ElemData, s: &ElemState, v: &Vec12, a: &Vec12) {
    let n = 20000;
    let mut rows = GradRows::default();
    let (mut m, mut c) = ([[0.0; 12]; 12], [[0.0; 12]; 12]);
    let mut acc = 0.0;
    let time = |f: &mut dyn FnMut()| {
        let t = Instant::now();
        for _ in 0..n {
            f();
        }
        t.elapsed().as_secs_f64() / n as f64 * 1e6
    };
    let t_force = time(&mut || {
        let (_, _, f, k, _) = tangent_parts(e, std::hint::black_box(s));
        acc += f[0] + k[1][2];
    });
    let t_rows = time(&mut || rows.fill_with_rates(e, std::hint::black_box(s), v));
    let t_mc = time(&mut || {
        mass_and_rates(std::hint::black_box(&rows), v, &mut m, &mut c);
        acc += m[1][1] + c[2][2];
    });
    let (frames, g, _, _, _) = tangent_parts(e, s);
    let t_forces = time(&mut || {
        let r = inertia_forces(e, std::hint::black_box(s), &g, &frames, v, a);
        acc += r.finert[0];
    });
    println!(
        "stage parts [us]: force + tangent {t_force:.2}, gradient rows g and g-dot \
         {t_rows:.2}, M and C {t_mc:.2}, inertial forces {t_forces:.2}   ({acc:.1})"
    );
}

/// `ne` copies of the element and its input.
fn copies(
    e: &ElemData,
    s: &ElemState,
    v: &Vec12,
    a: &Vec12,
    ne: usize,
) -> (Vec<ElemData>, Vec<ElemIn>) {
    let input = ElemIn {
        state: *s,
        v12: *v,
        acc: *a,
    };
    (vec![*e; ne], vec![input; ne])
}

/// What a Newton iteration pays per element: the stage's full evaluation (force, K,
/// energy, M, S, C and the inertial products) and its residual-only one, over a batch of
/// ten elements as the blade has, outputs written in place.
fn stage_report(e: &ElemData, s: &ElemState, v: &Vec12, a: &Vec12) -> [f64; 2] {
    let ne = 10;
    let (elems, inputs) = copies(e, s, v, a, ne);
    let mut out = vec![ElemOut::default(); ne];
    let n = 4000;
    let mut times = [0.0; 3];
    // a Newton iteration moves the nodes, so the residual-only timing forgets the last
    // evaluation's positions; the mass products of the time-error estimate (same
    // positions and velocities, new accelerations) are timed apart
    for (k, (name, residual, moved)) in [
        ("full", false, true),
        ("residual-only", true, true),
        ("mass product", true, false),
    ]
    .into_iter()
    .enumerate()
    {
        let t = Instant::now();
        let mut acc = 0.0;
        for _ in 0..n {
            if moved {
                out.iter_mut().for_each(|o| o.forces_of = None);
            }
            let r = if residual {
                CpuEval.evaluate_residual(&elems, std::hint::black_box(&inputs), true, &mut out)
            } else {
                CpuEval.evaluate(&elems, std::hint::black_box(&inputs), true, &mut out)
            };
            r.expect("the CPU stage does not fail");
            acc += out[3].finert[2] + out[7].f[1];
        }
        let dt = t.elapsed().as_secs_f64() / (n * ne) as f64;
        times[k] = dt;
        println!(
            "stage, {name:<14} {:.2} us/element   (CpuEval, 10 elements; {acc:.1})",
            dt * 1e6
        );
    }
    [times[0], times[1]]
}

/// The stage as a campaign calls it: the variants of a batch (8 here, the blade's 10
/// elements each) in one call, so the four SIMD lanes are filled across the variants
/// and no lane is idle (10 elements alone fill 3 groups of 4 with 12 lanes).
fn batch_report(e: &ElemData, s: &ElemState, v: &Vec12, a: &Vec12) -> [f64; 2] {
    let (nv, ne) = (8, 10);
    let (elems, inputs) = copies(e, s, v, a, ne);
    let mut outs = vec![vec![ElemOut::default(); ne]; nv];
    // best of several repetitions: on a shared machine a single pass reads the
    // neighbours' load as much as the stage (the median is printed beside it)
    let (n, reps) = (300, 9);
    let mut times = [0.0; 2];
    for (k, (name, residual)) in [("full", false), ("residual-only", true)]
        .into_iter()
        .enumerate()
    {
        let mut acc = 0.0;
        let mut per_rep = Vec::with_capacity(reps);
        for _ in 0..reps {
            let t = Instant::now();
            for _ in 0..n {
                let mut reqs: Vec<EvalRequest<'_>> = outs
                    .iter_mut()
                    .map(|out| {
                        out.iter_mut().for_each(|o| o.forces_of = None);
                        EvalRequest {
                            elems: &elems,
                            inputs: std::hint::black_box(&inputs),
                            out,
                            residual,
                            inertia: true,
                        }
                    })
                    .collect();
                CpuEval
                    .evaluate_batch(&mut reqs)
                    .expect("the CPU stage does not fail");
                acc += outs[3][2].finert[2] + outs[7][9].f[1];
            }
            per_rep.push(t.elapsed().as_secs_f64() / (n * ne * nv) as f64);
        }
        per_rep.sort_by(f64::total_cmp);
        let (best, median) = (per_rep[0], per_rep[reps / 2]);
        times[k] = best;
        println!(
            "stage, {name:<14} {:.2} us/element, best of {reps} (median {:.2})   (CpuEval batch, {nv} variants x {ne} elements; {acc:.1})",
            best * 1e6,
            median * 1e6
        );
    }
    times
}

// ---------------------------------------------------------------------------------------
// Floating-point operation count against the machine's peak.
//
// No hardware counters in this VM (perf reports `cycles` as not supported), so the flops
// are counted by running the generic element code on a counting scalar, per operation
// kind, and converting each kind to flops for the number type the real pass uses (a
// [`DualVec<9>`] multiply is 1 + 3·9 flops, …); the plain-f64 loops around them (rank
// updates over the field-gradient rows) are counted from their loop bounds. The peak is measured, not taken from a data sheet: independent AVX2 FMA chains.
// ---------------------------------------------------------------------------------------

use latdyn::element::ad::{Real, M3, V3};
use std::cell::Cell;
use std::ops::{Add, Div, Mul, Neg, Sub};

thread_local! {
    /// [add/sub/neg, mul, div, sqrt]
    static OPS: Cell<[u64; 4]> = const { Cell::new([0; 4]) };
}
fn bump(k: usize) {
    OPS.with(|c| {
        let mut v = c.get();
        v[k] += 1;
        c.set(v);
    });
}
fn take_ops() -> [u64; 4] {
    OPS.with(|c| c.replace([0; 4]))
}

#[derive(Clone, Copy, Debug)]
struct Cnt(f64);
impl Add for Cnt {
    type Output = Cnt;
    fn add(self, o: Cnt) -> Cnt {
        bump(0);
        Cnt(self.0 + o.0)
    }
}
impl Sub for Cnt {
    type Output = Cnt;
    fn sub(self, o: Cnt) -> Cnt {
        bump(0);
        Cnt(self.0 - o.0)
    }
}
impl Neg for Cnt {
    type Output = Cnt;
    fn neg(self) -> Cnt {
        bump(0);
        Cnt(-self.0)
    }
}
impl Mul for Cnt {
    type Output = Cnt;
    fn mul(self, o: Cnt) -> Cnt {
        bump(1);
        Cnt(self.0 * o.0)
    }
}
impl Div for Cnt {
    type Output = Cnt;
    fn div(self, o: Cnt) -> Cnt {
        bump(2);
        Cnt(self.0 / o.0)
    }
}
// the element constants (stiffness over length, …) are computed in f64, uncounted, as
// the stage computes them once per element
impl Real for Cnt {
    type Base = f64;
    fn cst(v: f64) -> Cnt {
        Cnt(v)
    }
    fn lift(b: f64) -> Cnt {
        Cnt(b)
    }
    // a fused multiply-add is two flops, as the peak counts it
    fn madd(self, a: Cnt, b: Cnt) -> Cnt {
        bump(1);
        bump(0);
        Cnt(self.0 * a.0 + b.0)
    }
    fn sqrt(self) -> Cnt {
        bump(3);
        Cnt(self.0.sqrt())
    }
}

/// Flops of one pass given its operation counts, per number type: [add, mul, div, sqrt]
/// costs as written in `latdyn::element::ad`.
fn flops(ops: [u64; 4], cost: [u64; 4]) -> u64 {
    ops.iter().zip(cost).map(|(o, c)| o * c).sum()
}
const F64: [u64; 4] = [1, 1, 1, 1];
/// a dual multiply is v·v and v·d + d·v: 3 multiplications and an addition
const DUAL: [u64; 4] = [2, 4, 7, 3];
const fn dual_vec(n: u64) -> [u64; 4] {
    [1 + n, 1 + 3 * n, 2 + 5 * n, 1 + 2 * n]
}
/// second-order jet (value, first, second derivative): mul 6 mul + 4 add, div 11 + a mul,
/// sqrt 9
const JET2: [u64; 4] = [3, 10, 21, 9];
/// `FieldMaps::apply` (g·x at the 12 (Gauss point, field) pairs): 10 dot products of length
/// 12 (240) and per Gauss point the local field changes (20), three 3 × 3 products (45),
/// three cross products (27) and the sums (21)
const FIELD_APPLY: u64 = 240 + 4 * (20 + 45 + 27 + 21);
/// `FieldMaps::project` (gᵀy): per Gauss point three cross products (27), the moment and
/// chord sums (21), three Tᵀ products (45) and the coefficient updates (32); then 12 dofs
/// × (10 multiply-adds) and the chord shares (6)
const FIELD_PROJECT: u64 = 4 * (27 + 21 + 45 + 32) + 12 * 20 + 6;

fn counted_frames(e: &ElemData, s: &ElemState) -> (V3<Cnt>, V3<Cnt>, M3<Cnt>, M3<Cnt>) {
    let t1 = mat_mul(&s.r1, &e.frame0);
    let t2 = mat_mul(&s.r2, &e.frame0);
    let c = |t: Mat3| t.map(|r| r.map(Cnt));
    (s.u1.map(Cnt), s.u2.map(Cnt), c(t1), c(t2))
}

/// Operations of the closed-form internal force (one scalar pass).
fn force_ops(e: &ElemData, s: &ElemState) -> [u64; 4] {
    let (u1, u2, t1, t2) = counted_frames(e, s);
    take_ops();
    std::hint::black_box(force_generic(e, u1, u2, &t1, &t2));
    take_ops()
}

/// Operations of the closed-form internal force and tangent (one scalar pass).
fn tangent_ops(e: &ElemData, s: &ElemState) -> [u64; 4] {
    let (u1, u2, t1, t2) = counted_frames(e, s);
    take_ops();
    std::hint::black_box(force_tangent_generic(e, u1, u2, &t1, &t2));
    take_ops()
}

/// Operations of one pass of the position fields at the 4 Gauss points.
fn field_ops(e: &ElemData, s: &ElemState) -> [u64; 4] {
    let (u1, u2, t1, t2) = counted_frames(e, s);
    take_ops();
    let kin = kinematics(e.chord0, e.l0, u1, u2, &t1, &t2);
    let chord = [0, 1, 2].map(|i| Cnt(e.chord0[i]) + (u2[i] - u1[i]));
    for (xi, _) in GAUSS4 {
        std::hint::black_box(section_fields(&kin, u1, chord, xi));
    }
    take_ops()
}

/// Operations of the element's closed-form gradient alone (one scalar pass).
fn grad_only_ops(e: &ElemData, s: &ElemState) -> [u64; 4] {
    let (u1, u2, t1, t2) = counted_frames(e, s);
    take_ops();
    std::hint::black_box(gradient(e.chord0, e.l0, u1, u2, &t1, &t2));
    take_ops()
}

/// Operations of the closed-form field gradients at the Gauss points, all 12 dofs
/// (`gradients_closed_generic`, one scalar pass).
fn gradient_ops(e: &ElemData, s: &ElemState) -> [u64; 4] {
    let (u1, u2, t1, t2) = counted_frames(e, s);
    take_ops();
    std::hint::black_box(gradients_closed_generic(e, u1, u2, &t1, &t2));
    take_ops()
}

/// Sustained f64 FMA throughput of one core: 12 independent 4-wide FMA chains (enough
/// to cover the FMA latency on two FMA ports); the best of three runs, as the batched
/// stage's time is its best of several.
fn peak_gflops() -> Option<f64> {
    #[cfg(target_arch = "x86_64")]
    {
        if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
            // SAFETY: the features were detected at run time
            let runs: Vec<f64> = (0..3).map(|_| unsafe { fma_peak() }).collect();
            println!(
                "  peak runs: {}",
                runs.iter()
                    .map(|p| format!("{p:.1}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            return runs.into_iter().reduce(f64::max);
        }
    }
    None
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn fma_peak() -> f64 {
    use std::arch::x86_64::*;
    let n = 50_000_000u64;
    let a = _mm256_set1_pd(0.999_999_9);
    let b = _mm256_set1_pd(1e-9);
    let mut acc = [_mm256_set1_pd(1.0); 12];
    let t = Instant::now();
    for _ in 0..n / 12 {
        for x in acc.iter_mut() {
            *x = _mm256_fmadd_pd(*x, a, b);
        }
    }
    let dt = t.elapsed().as_secs_f64();
    let mut sum = 0.0;
    for x in acc {
        let mut o = [0.0; 4];
        _mm256_storeu_pd(o.as_mut_ptr(), x);
        sum += o.iter().sum::<f64>();
    }
    std::hint::black_box(sum);
    // one FMA = 2 flops on 4 lanes
    ((n / 12) * 12 * 8) as f64 / dt * 1e-9
}

/// Sustained throughput of the operations the element code issues: separate 4-wide
/// multiplies and adds (Rust never fuses a·b + c, which keeps every number bit-identical
/// to the scalar and baseline builds), 7 independent multiply chains beside 7 independent
/// add chains so neither latency binds; the best of three runs. Where multiplies and
/// adds share ports with each other (Intel's Golden Cove: multiplies on two ports, adds
/// on two, one port shared) this is below the FMA peak; where they have pipes of their
/// own (AMD's Zen 4) it should be at it (not measured there): context for the stage's
/// fraction of the FMA peak.
fn unfused_gflops() -> Option<f64> {
    #[cfg(target_arch = "x86_64")]
    {
        if is_x86_feature_detected!("avx2") {
            // SAFETY: the feature was detected at run time
            return (0..3).map(|_| unsafe { mul_add_peak() }).reduce(f64::max);
        }
    }
    None
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn mul_add_peak() -> f64 {
    use std::arch::x86_64::*;
    let n = 50_000_000u64 / 7;
    let a = _mm256_set1_pd(0.999_999_99);
    let b = _mm256_set1_pd(1e-9);
    let mut m = [_mm256_set1_pd(1.0); 7];
    let mut s = [_mm256_set1_pd(1.0); 7];
    let t = Instant::now();
    for _ in 0..n {
        for (x, y) in m.iter_mut().zip(s.iter_mut()) {
            *x = _mm256_mul_pd(*x, a);
            *y = _mm256_add_pd(*y, b);
        }
    }
    let dt = t.elapsed().as_secs_f64();
    let mut sum = 0.0;
    for x in m.into_iter().chain(s) {
        let mut o = [0.0; 4];
        _mm256_storeu_pd(o.as_mut_ptr(), x);
        sum += o.iter().sum::<f64>();
    }
    std::hint::black_box(sum);
    // 14 operations of one flop on 4 lanes per pass
    (n * 14 * 4) as f64 / dt * 1e-9
}

/// Print flops per call, GFLOP/s at the measured call times, and the fraction of the peak.
fn flop_report(e: &ElemData, s: &ElemState, times: [f64; 8]) {
    let [t_tangent, t_dual, t_inertia, t_residual, t_full, t_res, t_full_b, t_res_b] = times;
    let f = force_ops(e, s);
    let fld = field_ops(e, s);
    let grad = gradient_ops(e, s);
    // internal force + tangent in closed form: one f64 pass
    let tangent = flops(tangent_ops(e, s), F64);
    // the dual reference: one f64 pass and one 9-lane vector-dual pass
    let dual = flops(f, F64) + flops(f, dual_vec(9));
    // rank-1 updates over the 36 (Gauss point, field, component) rows of 12 dofs
    let rank = |per_row: u64| 36 * per_row;
    // the inertial forces from the factored gradients: one f64 gradient, S's jet pass of
    // the position fields, g·x for acc and v, gᵀy for M acc, M v and S (weights: 36 each)
    let forces = flops(grad_only_ops(e, s), F64)
        + flops(fld, JET2)
        + 2 * FIELD_APPLY
        + 3 * (FIELD_PROJECT + 36)
        + 12;
    // full: g and ġ from one dual pass of the gradient rows; M (12 rows of M × 36
    // updates), P for C (likewise, ×2 folded in), the spin-ordering correction (2 nodes ×
    // 12 × 3 × 3 mul-add), and the forces as above
    let inertia = flops(grad, DUAL)
        + 12 * rank(1 + 2 * 12)
        + 12 * rank(2 + 2 * 12)
        + 2 * 12 * 3 * 3 * 2
        + forces;
    let residual = forces;
    // the stage shares one f64 gradient between the force and the inertial forces (the
    // strain energy's few flops are not counted)
    let grad_f64 = flops(grad_only_ops(e, s), F64);
    let stage_full = tangent + inertia - grad_f64;
    let stage_res = flops(f, F64) + forces - grad_f64;
    let peak = peak_gflops();
    println!("\nfloating-point work per element call (counted) and achieved rate, one core:");
    for (name, fl, t) in [
        ("internal_force_tangent", tangent, t_tangent),
        ("  (9-lane dual reference)", dual, t_dual),
        ("inertia (M, S, C)", inertia, t_inertia),
        ("inertia_residual (M a + S, M v)", residual, t_residual),
        ("stage, full evaluation", stage_full, t_full),
        ("stage, residual-only evaluation", stage_res, t_res),
        ("stage, full, batch of 8 variants", stage_full, t_full_b),
        ("stage, residual-only, batch of 8", stage_res, t_res_b),
    ] {
        let g = fl as f64 / t * 1e-9;
        let frac = peak.map_or("n/a".to_string(), |p| format!("{:.1} %", 100.0 * g / p));
        println!(
            "  {name:<32} {fl:>7} flop  {:>6.2} us  {g:>5.2} GFLOP/s  {frac} of peak",
            t * 1e6
        );
    }
    if let (Some(p), Some(u)) = (peak, unfused_gflops()) {
        let g = stage_full as f64 / t_full_b * 1e-9;
        println!(
            "  unfused multiply + add throughput (measured, best of 3): {u:.1} GFLOP/s = {:.0} % \
             of the FMA peak (the ceiling of code without FMA; the stage fuses its multiply-add \
             streams since session 24); the batched full stage runs at {:.1} % of it",
            100.0 * u / p,
            100.0 * g / u
        );
    }
    match peak {
        Some(p) => {
            println!(
                "  peak (12 independent AVX2 FMA chains, measured, best of 3): {p:.1} GFLOP/s per core"
            )
        }
        None => println!("  peak: AVX2/FMA not available, not measured"),
    }
}
