//! Micro benchmark of the sparse LU in `latdyn::linalg` (harness = false; prints only,
//! asserts nothing about timing).
//!
//! Run: `cargo bench --bench linalg`
//!
//! Cases: 600×600 banded matrix with half-bandwidth 12 (|i−j| ≤ 12), and a chain of
//! 6-DOF beam nodes (block tridiagonal, 6×6 blocks) with 100 and 1000 nodes. Values are
//! unsymmetric and diagonally dominant. For every kernel variant it reports the median
//! time of symbolic analysis, `factor` (includes the finiteness / zero-row pass and the
//! 2-column singularity probe solve), `solve`, and `factor + solve`, and the number of
//! heap allocations per steady-state call (counted by a wrapping global allocator).
//! Rows marked "(faer)" call faer directly, without any checks, as the reference for the
//! wrapper's overhead.

use std::alloc::{GlobalAlloc, Layout, System};
use std::hint::black_box;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuSymbolicParams, NumericLu};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par};
use latdyn::linalg::{LuVariant, SparseLu, SparseLuSymbolic, SparsePattern};

struct CountingAlloc;
static ALLOCS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

struct Lcg(u64);
impl Lcg {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn banded(n: usize, hbw: usize) -> Vec<(usize, usize)> {
    let mut pairs = Vec::new();
    for i in 0..n {
        for j in i.saturating_sub(hbw)..=(i + hbw).min(n - 1) {
            pairs.push((i, j));
        }
    }
    pairs
}

fn beam_chain(nodes: usize) -> Vec<(usize, usize)> {
    let mut pairs = Vec::new();
    for e in 0..nodes - 1 {
        for a in 0..12 {
            for b in 0..12 {
                pairs.push((6 * e + a, 6 * e + b));
            }
        }
    }
    pairs
}

fn dd_values(p: &SparsePattern, rng: &mut Lcg) -> Vec<f64> {
    let n = p.n();
    let mut v: Vec<f64> = (0..p.nnz()).map(|_| rng.uniform() - 0.5).collect();
    let mut rowsum = vec![0.0; n];
    for j in 0..n {
        for k in p.col_ptr()[j]..p.col_ptr()[j + 1] {
            rowsum[p.row_idx()[k]] += v[k].abs();
        }
    }
    for (i, s) in rowsum.iter().enumerate() {
        v[p.slot(i, i).unwrap()] = s + 1.0;
    }
    v
}

fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Median seconds per call of `f`, and heap allocations per call (after warm-up).
fn measure(reps: usize, mut f: impl FnMut()) -> (f64, f64) {
    for _ in 0..3 {
        f();
    }
    let a0 = ALLOCS.load(Ordering::Relaxed);
    f();
    let allocs = (ALLOCS.load(Ordering::Relaxed) - a0) as f64;
    let times = (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    (median(times), allocs)
}

/// faer alone: numeric factorisation and one solve, same ordering and kernel, no checks.
fn raw_faer(p: &SparsePattern, values: &[f64], rhs0: &[f64], variant: LuVariant, reps: usize) {
    let n = p.n();
    let sym = SymbolicSparseColMatRef::new_checked(n, n, p.col_ptr(), None, p.row_idx());
    let a = SparseColMatRef::new(sym, values);
    let threshold = match variant {
        LuVariant::Supernodal => SupernodalThreshold::FORCE_SUPERNODAL,
        LuVariant::Simplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
        LuVariant::Auto => SupernodalThreshold::AUTO,
        LuVariant::Dense => return,
    };
    let s = factorize_symbolic_lu(
        sym,
        LuSymbolicParams {
            supernodal_flop_ratio_threshold: threshold,
            ..Default::default()
        },
    )
    .unwrap();
    let req = s
        .factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default())
        .or(s.solve_in_place_scratch::<f64>(1, Par::Seq));
    let mut mem = MemBuffer::new(req);
    let mut num = NumericLu::<usize, f64>::new();
    let (t_f, a_f) = measure(reps, || {
        s.factorize_numeric_lu(
            &mut num,
            a,
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .unwrap();
    });
    let mut rhs = rhs0.to_vec();
    let lu = s
        .factorize_numeric_lu(
            &mut num,
            a,
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .unwrap();
    let (t_s, a_s) = measure(reps, || {
        rhs.copy_from_slice(rhs0);
        lu.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut rhs, n, 1),
            Par::Seq,
            MemStack::new(&mut mem),
        );
    });
    let ms = |s: f64| format!("{:.4} ms", s * 1e3);
    println!(
        "{:<17} {:>11} {:>14} {:>11} {:>14} {:>16} {:>15}",
        format!("{variant:?}(faer)"),
        "",
        ms(t_f),
        ms(t_s),
        ms(t_f + t_s),
        a_f,
        a_s
    );
}

fn run_case(name: &str, n: usize, pairs: &[(usize, usize)]) {
    let p = SparsePattern::new(n, pairs);
    let mut rng = Lcg(42);
    let values = dd_values(&p, &mut rng);
    let rhs0: Vec<f64> = (0..n).map(|_| rng.uniform() - 0.5).collect();
    let reps = (20_000_000 / p.nnz()).clamp(20, 2000);
    println!("\n{name}: n = {n}, nnz = {}, {reps} reps", p.nnz());
    println!(
        "{:<17} {:>11} {:>14} {:>11} {:>14} {:>16} {:>15}",
        "variant", "symbolic", "factor", "solve", "factor+solve", "allocs/factor", "allocs/solve"
    );
    for variant in [
        LuVariant::Supernodal,
        LuVariant::Simplicial,
        LuVariant::Auto,
        LuVariant::Dense,
    ] {
        // the dense kernel's n² array: only where it is meant to be used and a little past
        if variant == LuVariant::Dense && n > 8 * LuVariant::DENSE_MAX_N {
            continue;
        }
        let t = Instant::now();
        let sym = Arc::new(SparseLuSymbolic::with_variant(&p, variant).unwrap());
        let t_sym = t.elapsed().as_secs_f64();
        let mut lu = SparseLu::from_symbolic(Arc::clone(&sym));
        let (t_f, a_f) = measure(reps, || lu.factor(black_box(&values)).unwrap());
        let mut rhs = rhs0.clone();
        let (t_s, a_s) = measure(reps, || {
            rhs.copy_from_slice(&rhs0);
            lu.solve_in_place(black_box(&mut rhs));
        });
        let (t_fs, _) = measure(reps, || {
            lu.factor(black_box(&values)).unwrap();
            rhs.copy_from_slice(&rhs0);
            lu.solve_in_place(black_box(&mut rhs));
        });
        // sanity: residual of the last solve
        let mut r = vec![0.0; n];
        p.mul_vec(&values, &rhs, &mut r);
        let res = r
            .iter()
            .zip(&rhs0)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(res < 1e-10, "residual {res}");
        let ms = |s: f64| format!("{:.4} ms", s * 1e3);
        println!(
            "{:<17} {:>11} {:>14} {:>11} {:>14} {:>16} {:>15}",
            format!("{variant:?}"),
            ms(t_sym),
            ms(t_f),
            ms(t_s),
            ms(t_fs),
            a_f,
            a_s
        );
        if variant != LuVariant::Auto {
            raw_faer(&p, &values, &rhs0, variant, reps);
        }
    }
}

fn main() {
    // `cargo bench` passes `--bench`; nothing to parse
    run_case("6-DOF beam chain, 10 nodes", 60, &beam_chain(10));
    run_case("banded, half-bandwidth 12", 600, &banded(600, 12));
    run_case("6-DOF beam chain, 100 nodes", 600, &beam_chain(100));
    run_case("6-DOF beam chain, 1000 nodes", 6000, &beam_chain(1000));
}
