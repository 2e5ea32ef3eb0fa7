//! Linear algebra for the solver: a fixed sparse pattern with a scatter map, sparse LU
//! (symbolic analysis once per pattern, numeric factorisation per Newton iteration), and
//! small dense helpers (LU solve, generalised symmetric eigenproblem, general eigenvalues).
//! Everything is a thin layer over `faer` 0.24.
//!
//! # Sparse LU in a nutshell
//!
//! ```text
//! SparsePattern::new(n, &pairs)          once per model: CSC structure, slot() scatter map
//! SparseLuSymbolic::new(&pattern)        once per pattern: COLAMD ordering + symbolic LU
//!   -> Arc<SparseLuSymbolic>             shared by every variant / thread
//! SparseLu::from_symbolic(arc)           once per variant: numeric storage + scratch
//! lu.factor(&values)?                    per iteration: numeric LU with partial pivoting
//! lu.solve_in_place(&mut rhs)            per right-hand side (try_solve_in_place: checked)
//! ```
//!
//! `values` is a caller-owned `Vec<f64>` of length [`SparsePattern::nnz`]; an element's
//! entries are added at the indices returned by [`SparsePattern::slot`] (look the slots up
//! once, keep them as the element's scatter map).
//!
//! # Singularity detection
//!
//! faer's numeric sparse LU reports only *structural* singularity (no candidate pivot at
//! all); an exactly zero or tiny numeric pivot silently produces `inf`/`NaN` or garbage,
//! and faer's API gives no access to the pivots. So [`SparseLu::factor`]
//!
//! 1. rejects NaN/inf values ([`LinalgError::NonFinite`]) and all-zero rows/columns
//!    ([`LinalgError::Singular`] with that index) in one O(nnz) pass;
//! 2. maps faer's structural singularity to [`LinalgError::Singular`];
//! 3. ends with a *probe solve* `X = A⁻¹X*` for two fixed generic right-hand sides
//!    (entries of magnitude in `[1, 2)`, one all positive, one with pseudo-random
//!    signs; for a singular A they have components outside the range of A). The
//!    condition estimate `‖A‖∞ max|X| / max|X*|` (a lower bound of κ∞(A)) must not
//!    exceed [`SINGULAR_COND_LIMIT`] (1e15) and X must be finite; otherwise
//!    [`LinalgError::Singular`].
//!
//!    1e15 is a little stricter than the usual "singular to working precision" limit
//!    κ ≈ 1/ε ≈ 4.5e15, to allow for the estimate being a lower bound. Calibration
//!    (temporary test harness, both kernels): random weighted graph Laplacians (spring
//!    networks with a rigid-body mode, symmetric and unsymmetric, n = 4…2000, 240
//!    matrices) all gave estimates ≥ 1.6e16 or inf/NaN; the same matrices shifted to
//!    κ = 1e8, 1e12, 1e14 gave estimates of 1.46–1.62 κ and were all accepted. Random
//!    dense matrices made rank deficient by a rounded linear combination of rows or
//!    columns (n = 3…60, 1857 matrices; true κ₂ ≥ 5e15, checked by SVD on a subset):
//!    6 (0.3%) were estimated below 1e15 (lowest 2.3e14) and accepted, a rare miss
//!    inherent to a lower-bound estimator (with one probe column instead of two: 20). A
//!    forward-error probe (`A⁻¹(A x*)` vs `x*`) was tried and dropped: on exactly
//!    singular matrices its error was sometimes only 4e-3, because `A x*` lies in the
//!    range of A. The probe costs a 2-column solve plus one O(nnz) pass over the values
//!    (fused with the finiteness check); see the timings below.
//!
//! **Units.** A model's unknowns come in units (metres, radians) whose choice scales
//! rows and columns: a 10 µm beam element's translation rows are 1e10 times its rotation
//! rows in metres. With [`SparseLu::set_unit_groups`] (the solver's Newton systems put
//! translations in one group, angles in another) the matrix factored is B = D A D, D
//! constant on each group, a power of two near 1/√(the group's largest diagonal entry):
//! the pivots are chosen and the condition measured in consistent units, and a solve
//! scales its right-hand side and solution back. Without groups D = I (the calibration
//! above). What no choice of units removes, a stiffness disparity within one unit (EA
//! far above EI/L², whose axial round-off the residual feels), still counts.
//!
//! On failure the offending DOF is reported: the index of the largest entry of X, which
//! is dominated by the (near-)null vector; if that solution is non-finite (an exactly zero
//! pivot), one extra factorisation of A + √ε·max|A|·I and solve (error path only,
//! allocates) estimates the null vector instead.
//! [`SparseLu::try_solve_in_place`] rejects non-finite right-hand sides and non-finite
//! results; the unchecked [`SparseLu::solve_in_place`] lets them propagate.
//!
//! # Allocation
//!
//! * `SparsePattern::new`, `SparseLuSymbolic::new`, `SparseLu::from_symbolic` allocate
//!   (once).
//! * `SparseLu::factor`: the scratch workspace (faer `MemBuffer`) and the probe vector are
//!   sized once in `from_symbolic`. faer's numeric storage (`NumericLu`) is grown on the
//!   first factorisation and only grows afterwards, so:
//!   - [`LuVariant::Simplicial`]: no allocation in steady state. The L/U fill depends on
//!     the pivot sequence, so a factorisation that pivots differently from all previous
//!     ones may grow the L/U vectors once more.
//!   - [`LuVariant::Dense`] (the default up to [`LuVariant::DENSE_MAX_N`] unknowns): no
//!     allocation after `from_symbolic` (the n×n array, the profile and the permuted
//!     right-hand side are sized there).
//!   - [`LuVariant::Supernodal`] (the default above it): faer allocates inside every numeric
//!     factorisation (a `Vec` of per-supernode work records and per-supernode
//!     contribution-block buffers, see `factorize_supernodal_numeric_lu`); this cannot
//!     be avoided from outside. Measured: 109 allocations per factorisation for the
//!     600×600 band below, 145 for a 100-node (600-DOF) beam chain, 1495 for a 1000-node
//!     (6000-DOF) chain, i.e. ~0.2 per unknown.
//! * `SparseLu::solve_in_place` / `try_solve_in_place`: no allocation (scratch behind a
//!   `Mutex`, sized once); only if two threads solve with the *same* `SparseLu` at the
//!   same moment does the second one allocate a temporary scratch buffer instead of
//!   waiting.
//! * Error paths allocate for `LinalgError::Other(String)`.
//! * The dense helpers allocate freely (they are meant for small problems).
//!
//! All faer calls in the sparse path use `Par::Seq`: parallelism belongs one level up
//! (many variants factorised concurrently, one `SparseLu` each). The dense helpers set
//! faer's global parallelism to `Par::Seq` too ([`dense_sequential`]): its default splits
//! the work by the calling rayon pool's thread count, so a sweep's rotating-frame
//! eigenvalue (`first_bending_eig_hz`) differed in its last bits between `--threads 2`
//! and shards run on 1 and 3 threads (30-element rotating cantilever, session 49).
//!
//! # Timings (`cargo bench --bench linalg`, release, `Par::Seq`, median of repeats)
//!
//! 600×600 banded, half-bandwidth 12 (|i−j| ≤ 12, nnz = 14 844), diagonally dominant,
//! unsymmetric values. "factor" includes the checks and the probe; "faer" is faer alone
//! (same ordering and kernel, no checks) for reference:
//!
//! ```text
//! variant      symbolic   factor     solve      factor+solve   faer factor+solve
//! supernodal   1.21 ms    0.220 ms   0.018 ms   0.241 ms       0.200 ms
//! simplicial   1.09 ms    0.409 ms   0.011 ms   0.419 ms       0.410 ms
//! ```
//!
//! 6-DOF beam chains (block tridiagonal 6×6 blocks), factor+solve: 100 nodes (n = 600)
//! supernodal 0.18 ms / simplicial 0.22 ms; 1000 nodes (n = 6000) 1.99 ms / 2.29 ms.
//! Supernodal factorisation is 1.2–1.9× faster than simplicial on every pattern
//! measured, its solve ~2× slower; faer's `Auto` heuristic picks simplicial for all of
//! them, hence the explicit supernodal default. The checks + probe add 2–25% to faer's
//! factorisation time (mostly the 2-column probe solve).

use std::sync::{Arc, Mutex, TryLockError};

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::lu::{
    factorize_symbolic_lu, LuRef, LuSymbolicParams, NumericLu, SymbolicLu,
};
use faer::sparse::linalg::{LuError, SupernodalThreshold};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, Mat, MatMut, MatRef, Par, Side};

/// Condition-number estimate (∞-norm lower bound from the probe solve) above which
/// [`SparseLu::factor`] declares the matrix numerically singular.
pub const SINGULAR_COND_LIMIT: f64 = 1e15;

/// Errors from the linear-algebra layer.
#[derive(thiserror::Error, Debug)]
pub enum LinalgError {
    /// Singular (structurally or numerically) matrix, or a non-finite solution.
    ///
    /// `pivot` is a row/column index in the caller's (original) numbering pointing at the
    /// trouble. Sparse LU: an all-zero row or column (smallest such index); else the
    /// column for which faer found no pivot candidate (structural); else the unknown with
    /// the largest component of the estimated (near-)null vector (e.g. a DOF of an
    /// unrestrained body; see the module docs). Dense solve: the column whose pivot is
    /// zero/tiny (it depends linearly on the preceding ones). A solve producing inf/NaN:
    /// the first non-finite component.
    #[error("singular matrix (pivot/DOF {pivot})")]
    Singular { pivot: usize },
    /// Cholesky factorisation of a matrix required to be symmetric positive definite failed.
    #[error("matrix is not positive definite")]
    NotPositiveDefinite,
    /// An input value (matrix entry or right-hand side) is NaN or infinite.
    #[error("non-finite value (NaN or infinity) in input")]
    NonFinite,
    /// Anything else: dimension mismatch, use before factorisation, faer failure.
    #[error("{0}")]
    Other(String),
}

// ---------------------------------------------------------------------------------------
// Sparse pattern
// ---------------------------------------------------------------------------------------

/// Fixed sparsity pattern of an n×n matrix in compressed sparse column (CSC) form, row
/// indices sorted and unique within each column. Values live in a separate caller-owned
/// `&[f64]` of length [`nnz`](Self::nnz), indexed by [`slot`](Self::slot); many value
/// arrays (variants) can share one pattern.
#[derive(Clone, Debug)]
pub struct SparsePattern {
    n: usize,
    structure: SymbolicSparseColMat<usize>,
}

impl SparsePattern {
    /// Builds the pattern from (row, col) pairs; duplicates are merged, order is irrelevant.
    ///
    /// # Panics
    /// If a row or column index is `>= n` (a programming error in the caller).
    pub fn new(n: usize, entries: &[(usize, usize)]) -> SparsePattern {
        let mut counts = vec![0usize; n + 1];
        for &(r, c) in entries {
            assert!(
                r < n && c < n,
                "SparsePattern::new: entry ({r}, {c}) out of range for n = {n}"
            );
            counts[c + 1] += 1;
        }
        // bucket by column, then sort + dedup each column
        for j in 0..n {
            counts[j + 1] += counts[j];
        }
        let mut next = counts.clone();
        let mut rows = vec![0usize; entries.len()];
        for &(r, c) in entries {
            rows[next[c]] = r;
            next[c] += 1;
        }
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::with_capacity(entries.len());
        col_ptr.push(0);
        for j in 0..n {
            let col = &mut rows[counts[j]..counts[j + 1]];
            col.sort_unstable();
            let start = row_idx.len();
            for &r in col.iter() {
                if row_idx.len() == start || *row_idx.last().unwrap() != r {
                    row_idx.push(r);
                }
            }
            col_ptr.push(row_idx.len());
        }
        row_idx.shrink_to_fit();
        let structure = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        SparsePattern { n, structure }
    }

    /// Index into the values array of entry (row, col), or `None` if it is not in the
    /// pattern (or out of range).
    pub fn slot(&self, row: usize, col: usize) -> Option<usize> {
        if row >= self.n || col >= self.n {
            return None;
        }
        csc_slot(&self.structure, row, col)
    }

    /// `values` restricted to the equations `keep`: every entry in a row or column not
    /// kept becomes that of the identity (1 on the diagonal, else 0), so a system of the
    /// kept equations can be factored and solved in the full pattern.
    pub fn identity_outside(&self, values: &mut [f64], keep: &[bool]) {
        let (cp, ri) = (self.col_ptr(), self.row_idx());
        for j in 0..self.n {
            for slot in cp[j]..cp[j + 1] {
                let i = ri[slot];
                if !(keep[i] && keep[j]) {
                    values[slot] = f64::from(u8::from(i == j));
                }
            }
        }
    }

    /// Number of stored entries (length of a values array).
    pub fn nnz(&self) -> usize {
        self.structure.row_idx().len()
    }

    /// Matrix dimension n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// CSC column pointers (length n + 1).
    pub fn col_ptr(&self) -> &[usize] {
        self.structure.col_ptr()
    }

    /// CSC row indices (length nnz), sorted within each column.
    pub fn row_idx(&self) -> &[usize] {
        self.structure.row_idx()
    }

    /// y = A x, with A given by this pattern and `values`.
    ///
    /// # Panics
    /// On length mismatch.
    pub fn mul_vec(&self, values: &[f64], x: &[f64], y: &mut [f64]) {
        csc_mul_vec(&self.structure, values, x, y);
    }

    /// Dense row-major n×n copy of A (for debugging and small problems).
    ///
    /// # Panics
    /// If `values.len() != nnz`.
    pub fn to_dense(&self, values: &[f64]) -> Vec<f64> {
        assert_eq!(values.len(), self.nnz(), "values length != nnz");
        let n = self.n;
        let mut a = vec![0.0; n * n];
        let cp = self.col_ptr();
        let ri = self.row_idx();
        for j in 0..n {
            for k in cp[j]..cp[j + 1] {
                a[ri[k] * n + j] = values[k];
            }
        }
        a
    }
}

impl SparsePattern {
    /// (xᵀAx, Σ |Aᵢⱼ xᵢ xⱼ|): a quadratic form and the sum its round-off is relative to.
    pub fn quadratic_form(&self, values: &[f64], x: &[f64]) -> (f64, f64) {
        let (cp, ri) = (self.col_ptr(), self.row_idx());
        let (mut q, mut size) = (0.0, 0.0);
        for j in 0..self.n {
            for k in cp[j]..cp[j + 1] {
                let t = values[k] * x[ri[k]] * x[j];
                q += t;
                size += t.abs();
            }
        }
        (q, size)
    }
}

fn csc_mul_vec(s: &SymbolicSparseColMat<usize>, values: &[f64], x: &[f64], y: &mut [f64]) {
    let n = s.ncols();
    assert!(values.len() == s.row_idx().len() && x.len() == n && y.len() == s.nrows());
    y.fill(0.0);
    let cp = s.col_ptr();
    let ri = s.row_idx();
    for j in 0..n {
        let xj = x[j];
        for k in cp[j]..cp[j + 1] {
            y[ri[k]] += values[k] * xj;
        }
    }
}

fn csc_slot(s: &SymbolicSparseColMat<usize>, row: usize, col: usize) -> Option<usize> {
    let cp = s.col_ptr();
    let (start, end) = (cp[col], cp[col + 1]);
    s.row_idx()[start..end]
        .binary_search(&row)
        .ok()
        .map(|k| start + k)
}

// ---------------------------------------------------------------------------------------
// Sparse LU
// ---------------------------------------------------------------------------------------

/// Which faer numeric kernel the symbolic analysis selects.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LuVariant {
    /// Dense-block (supernodal) kernel; fastest factorisation on the patterns measured,
    /// allocates inside faer per factorisation.
    #[default]
    Supernodal,
    /// Column-by-column (left-looking) kernel; no allocation in steady state, faster solve.
    Simplicial,
    /// faer's flop-ratio heuristic picks one of the two.
    Auto,
    /// Dense LU with partial pivoting in a row-major n×n array, the unknowns in the
    /// analysis' fill-reducing order, row updates confined to the rows' extents
    /// ([`lu_rows_in_place`]). For small systems faer's sparse kernels spend most of their
    /// time on bookkeeping: on the 10-element blade (61 unknowns) the supernodal
    /// factorisation with its probe took 266 k instructions and each solve 27 k
    /// (callgrind). Singularity is detected as for the sparse kernels (the probe), and
    /// the error path's null-vector search uses the supernodal kernel.
    Dense,
}

impl LuVariant {
    /// Largest dimension for which [`SparseLuSymbolic::new`] picks [`LuVariant::Dense`]
    /// (its n² array stays below 131 kB). Measured factorisation time per run, dense
    /// against supernodal: blade 61 unknowns 8 / 13 ms, 121: 24 / 31 ms, 241: 59 / 70 ms;
    /// spin-up beam (60) 47 / 92 ms; Mini-Mast bay (196, a truss, wider profile) 177 /
    /// 183 ms.
    pub const DENSE_MAX_N: usize = 128;

    /// The kernel [`SparseLuSymbolic::new`] uses for an n×n matrix.
    pub fn for_dimension(n: usize) -> LuVariant {
        if n <= Self::DENSE_MAX_N {
            LuVariant::Dense
        } else {
            LuVariant::Supernodal
        }
    }
}

/// Sign of det(U) with the permutations', how many diagonal entries of U are negative,
/// and the smallest and largest |U_jj| ([`SparseLuSymbolic::pivots`]).
struct Pivots {
    sign: i8,
    negative: usize,
    smallest: f64,
    largest: f64,
}

/// Symbolic sparse LU analysis of one [`SparsePattern`]: fill-reducing column ordering
/// (COLAMD) and the factor structure. Immutable; share it through `Arc` between any number
/// of [`SparseLu`] numeric factorisations (it is `Send + Sync`).
#[derive(Debug)]
pub struct SparseLuSymbolic {
    n: usize,
    structure: SymbolicSparseColMat<usize>,
    symbolic: SymbolicLu<usize>,
    variant: LuVariant,
    /// workspace for numeric factorisation, and for the 2-column probe solve after it
    factor_req: StackReq,
    solve_req: StackReq,
    /// probe right-hand sides, n×2 column-major: x* with entries in [1, 2), and the same
    /// magnitudes with pseudo-random signs; and their max
    probe_x: Vec<f64>,
    probe_x_max: f64,
}

impl SparseLuSymbolic {
    /// Symbolic analysis with the kernel suited to the dimension
    /// ([`LuVariant::for_dimension`]).
    pub fn new(pattern: &SparsePattern) -> Result<Self, LinalgError> {
        Self::with_variant(pattern, LuVariant::for_dimension(pattern.n))
    }

    /// Symbolic analysis with an explicit kernel choice.
    pub fn with_variant(pattern: &SparsePattern, variant: LuVariant) -> Result<Self, LinalgError> {
        let n = pattern.n;
        let structure = pattern.structure.clone();
        let threshold = match variant {
            LuVariant::Supernodal | LuVariant::Dense => SupernodalThreshold::FORCE_SUPERNODAL,
            LuVariant::Simplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
            LuVariant::Auto => SupernodalThreshold::AUTO,
        };
        let params = LuSymbolicParams {
            supernodal_flop_ratio_threshold: threshold,
            ..Default::default()
        };
        let symbolic = factorize_symbolic_lu(structure.as_ref(), params)
            .map_err(|e| LinalgError::Other(format!("sparse LU symbolic analysis: {e:?}")))?;
        let factor_req = symbolic.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default());
        // (the dense kernel's permuted right-hand side: n more)
        let solve_req = symbolic
            .solve_in_place_scratch::<f64>(1, Par::Seq)
            .or(StackReq::new::<f64>(n));
        let probe_req = symbolic.solve_in_place_scratch::<f64>(2, Par::Seq);
        // golden-ratio sequence: well spread in [1, 2), deterministic, no two equal
        let mag = |i: usize| 1.0 + (i as f64 * 0.618_033_988_749_894_9).fract();
        let sign = |i: usize| {
            let h = (i as u64 ^ 0x5DEE_CE66_D1CE_4E5B).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            if (h >> 40) & 1 == 0 {
                1.0
            } else {
                -1.0
            }
        };
        let probe_x: Vec<f64> = (0..n)
            .map(mag)
            .chain((0..n).map(|i| sign(i) * mag(i)))
            .collect();
        let probe_x_max = probe_x.iter().fold(0.0f64, |m, &v| m.max(v.abs()));
        Ok(SparseLuSymbolic {
            n,
            structure,
            symbolic,
            variant,
            factor_req: factor_req.or(probe_req),
            solve_req,
            probe_x,
            probe_x_max,
        })
    }

    /// Matrix dimension n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of stored entries of the pattern (required length of the values array).
    pub fn nnz(&self) -> usize {
        self.structure.row_idx().len()
    }

    /// Whether this analysis belongs to `pattern` (same dimension and nonzero structure).
    pub fn analyses(&self, pattern: &SparsePattern) -> bool {
        self.n == pattern.n
            && self.structure.col_ptr() == pattern.structure.col_ptr()
            && self.structure.row_idx() == pattern.structure.row_idx()
    }

    /// The kernel requested at analysis time.
    pub fn variant(&self) -> LuVariant {
        self.variant
    }

    /// A left-looking LU with partial pivoting of the matrix with this pattern and
    /// `values`, on this analysis' fill-reducing column order, with its row permutation;
    /// `None` for an empty matrix. faer's supernodal factor exposes neither its diagonal
    /// nor its structure, so the determinant's sign and the factor's size come from this
    /// one (`what` names the caller in errors).
    fn simplicial_lu(
        &self,
        values: &[f64],
        what: &str,
    ) -> Result<Option<(SimplicialLuF64, Vec<usize>)>, LinalgError> {
        use faer::sparse::linalg::lu::simplicial::{
            factorize_simplicial_numeric_lu, factorize_simplicial_numeric_lu_scratch, SimplicialLu,
        };
        let n = self.n;
        if values.len() != self.nnz() {
            return Err(LinalgError::Other(format!(
                "{what}: values has length {}, pattern nnz is {}",
                values.len(),
                self.nnz()
            )));
        }
        if !values.iter().all(|v| v.is_finite()) {
            return Err(LinalgError::NonFinite);
        }
        if n == 0 {
            return Ok(None);
        }
        let mut rp = vec![0usize; n];
        let mut rpi = vec![0usize; n];
        let mut lu = SimplicialLu::<usize, f64>::new();
        let a = SparseColMatRef::new(self.structure.as_ref(), values);
        let mut mem = MemBuffer::new(factorize_simplicial_numeric_lu_scratch::<usize, f64>(n, n));
        factorize_simplicial_numeric_lu(
            &mut rp,
            &mut rpi,
            &mut lu,
            a,
            self.symbolic.col_perm(),
            MemStack::new(&mut mem),
        )
        .map_err(|e| LinalgError::Other(format!("sparse LU ({what}): {e:?}")))?;
        Ok(Some((lu, rp)))
    }

    /// Sign of det(A) and the number of negative diagonal entries of U, for the matrix
    /// with this pattern and `values`, from [`simplicial_lu`](Self::simplicial_lu):
    /// det(A) = sign(P_r)·sign(P_c)·∏ U_jj (L has a unit diagonal). Path following calls it
    /// once per converged point (the bifurcation indicator), not per Newton iteration. A
    /// zero pivot gives sign 0.
    pub fn det_sign(&self, values: &[f64]) -> Result<(i8, usize), LinalgError> {
        Ok(self
            .pivots(values)?
            .map_or((1, 0), |p| (p.sign, p.negative)))
    }

    /// The walk over U's diagonal behind [`det_sign`](Self::det_sign) and
    /// [`det_sign_clear`](Self::det_sign_clear); `None` for an empty matrix.
    fn pivots(&self, values: &[f64]) -> Result<Option<Pivots>, LinalgError> {
        let Some((lu, rp)) = self.simplicial_lu(values, "determinant sign")? else {
            return Ok(None);
        };
        let u = lu.u_factor_unsorted();
        let (cp, ri, uv) = (u.col_ptr(), u.row_idx(), u.val());
        let mut p = Pivots {
            sign: perm_sign(&rp) * perm_sign(self.symbolic.col_perm().arrays().0),
            negative: 0,
            smallest: f64::INFINITY,
            largest: 0.0,
        };
        for j in 0..self.n {
            let d = (cp[j]..cp[j + 1])
                .find(|&k| ri[k] == j)
                .map_or(0.0, |k| uv[k]);
            p.smallest = p.smallest.min(d.abs());
            p.largest = p.largest.max(d.abs());
            if d == 0.0 {
                p.sign = 0;
            } else if d < 0.0 {
                p.negative += 1;
                p.sign = -p.sign;
            }
        }
        Ok(Some(p))
    }

    /// [`det_sign`](Self::det_sign) where it means something: `None` when the smallest
    /// pivot of U is below `rel_tol` of the largest, where the sign is round-off (a free
    /// hinge at rest has a zero stiffness, and its pivot's sign is noise: the flapping
    /// blade's tangent at rest read det < 0).
    pub fn det_sign_clear(&self, values: &[f64], rel_tol: f64) -> Result<Option<i8>, LinalgError> {
        Ok(match self.pivots(values)? {
            None => Some(1),
            Some(p) => (p.smallest > rel_tol * p.largest).then_some(p.sign),
        })
    }

    /// For a matrix with this pattern and `values` that is symmetric to `rel_tol` of its
    /// largest entry, whether it is positive definite (its sparse Cholesky factorization
    /// exists once its diagonal is raised by `rel_tol` of the largest diagonal entry, so
    /// that a zero eigenvalue passes): for a conservative structure's tangent stiffness,
    /// whether an equilibrium is stable. Unlike the sign of det A it also sees an even
    /// number of negative directions (a column past its buckling load in two planes at
    /// once). `None` for a matrix that is not symmetric (dead moments turned by large
    /// rotations are not conservative, and the definiteness of a symmetric part says
    /// nothing there).
    pub fn symmetric_positive_definite(
        &self,
        values: &[f64],
        rel_tol: f64,
    ) -> Result<Option<bool>, LinalgError> {
        if values.len() != self.nnz() || !values.iter().all(|v| v.is_finite()) {
            return Err(LinalgError::NonFinite);
        }
        let (cp, ri) = (self.structure.col_ptr(), self.structure.row_idx());
        let mut entries = std::collections::HashMap::with_capacity(values.len());
        for j in 0..self.n {
            for k in cp[j]..cp[j + 1] {
                entries.insert((ri[k], j), values[k]);
            }
        }
        let largest = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        // no stiffness at all (a body's free rotation at rest, no load): every direction
        // is neutral; a relative raise of the diagonal would add nothing, and the
        // factorization of zero would fail and read as a negative direction
        if largest == 0.0 {
            return Ok(Some(true));
        }
        let skew = entries
            .iter()
            .map(|(&(i, j), v)| (v - entries.get(&(j, i)).copied().unwrap_or(0.0)).abs())
            .fold(0.0f64, f64::max);
        if skew > rel_tol * largest {
            return Ok(None);
        }
        let mut triplets = Vec::with_capacity(2 * values.len());
        for j in 0..self.n {
            for k in cp[j]..cp[j + 1] {
                let i = ri[k];
                // the lower triangle of A + Aᵀ, halved
                let (r, c) = if i >= j { (i, j) } else { (j, i) };
                let v = if i == j { values[k] } else { 0.5 * values[k] };
                triplets.push(faer::sparse::Triplet::new(r, c, v));
            }
        }
        // a zero-stiffness direction (a free hinge at rest) is neutral, not unstable: the
        // diagonal is raised by `rel_tol` of its largest entry so that only a negative
        // stiffness larger than that fails the factorization
        let diag = (0..self.n)
            .flat_map(|j| (cp[j]..cp[j + 1]).filter(move |&k| ri[k] == j))
            .fold(0.0f64, |m, k| m.max(values[k].abs()));
        triplets.extend((0..self.n).map(|i| faer::sparse::Triplet::new(i, i, rel_tol * diag)));
        let sym = faer::sparse::SparseColMat::<usize, f64>::try_new_from_triplets(
            self.n, self.n, &triplets,
        )
        .map_err(|e| LinalgError::Other(format!("symmetric part: {e:?}")))?;
        Ok(Some(sym.sp_cholesky(Side::Lower).is_ok()))
    }

    /// Stored nonzeros of L and U (L's unit diagonal counted once, in L) of
    /// [`simplicial_lu`](Self::simplicial_lu) (faer's supernodal factor also stores the
    /// explicit zeros of its dense supernode blocks, so it holds at least this many). For
    /// reports (`run --json`, the bench tables), not for the solve.
    pub fn factor_nnz(&self, values: &[f64]) -> Result<usize, LinalgError> {
        Ok(self
            .simplicial_lu(values, "factor size")?
            .map_or(0, |(lu, _)| {
                lu.l_factor_unsorted().row_idx().len() + lu.u_factor_unsorted().row_idx().len()
            }))
    }

    /// Original column eliminated at step `step` of the factorisation.
    fn original_col(&self, step: usize) -> usize {
        let (fwd, _) = self.symbolic.col_perm().arrays();
        fwd.get(step).copied().unwrap_or(step)
    }
}

/// faer's simplicial LU factor, as [`SparseLuSymbolic`]'s reporting routines use it.
type SimplicialLuF64 = faer::sparse::linalg::lu::simplicial::SimplicialLu<usize, f64>;

/// Parity of a permutation given as its forward array: +1 even, −1 odd.
fn perm_sign(fwd: &[usize]) -> i8 {
    let mut seen = vec![false; fwd.len()];
    let mut sign = 1i8;
    for start in 0..fwd.len() {
        if seen[start] {
            continue;
        }
        let (mut i, mut len) = (start, 0usize);
        while !seen[i] {
            seen[i] = true;
            i = fwd[i];
            len += 1;
        }
        if len % 2 == 0 {
            sign = -sign;
        }
    }
    sign
}

/// Numeric sparse LU factorisation (partial pivoting) of one matrix on a shared
/// [`SparseLuSymbolic`]. Refactorise with new values on the same pattern via
/// [`factor`](Self::factor). `Send + Sync`.
pub struct SparseLu {
    symbolic: Arc<SparseLuSymbolic>,
    numeric: NumericLu<usize, f64>,
    factor_mem: MemBuffer,
    solve_mem: Mutex<MemBuffer>,
    /// probe solve (n×2) / row-sum (n) workspace
    probe: Vec<f64>,
    /// D = diag(1/scale), constant on each unit group (all 1 without groups)
    scale: Vec<f64>,
    /// each unknown's unit group (empty: one group, the unscaled condition)
    groups: Vec<usize>,
    /// per group: the largest |diagonal entry|, then (after the groups) the largest row sum
    group_max: Vec<f64>,
    /// D A D, the matrix factored when there are unit groups (sized by `set_unit_groups`)
    scaled_values: Vec<f64>,
    /// the factors of [`LuVariant::Dense`] (empty for the sparse kernels)
    dense: DenseFactor,
    factored: bool,
}

/// A [`LuVariant::Dense`] factorisation, allocated once: Q A Qᵀ (Q the analysis'
/// fill-reducing order, applied to rows and columns) factored in place by
/// [`lu_rows_in_place`].
#[derive(Default)]
struct DenseFactor {
    n: usize,
    lu: Vec<f64>,
    perm: Vec<usize>,
    prof: Profile,
    /// q[i]: the unknown at position i; qinv its inverse
    q: Vec<usize>,
    qinv: Vec<usize>,
    /// permuted right-hand side
    y: Vec<f64>,
}

impl DenseFactor {
    fn new(sym: &SparseLuSymbolic) -> DenseFactor {
        let n = sym.n;
        let q: Vec<usize> = (0..n).map(|i| sym.original_col(i)).collect();
        let mut qinv = vec![0; n];
        for (i, &c) in q.iter().enumerate() {
            qinv[c] = i;
        }
        DenseFactor {
            n,
            lu: vec![0.0; n * n],
            perm: vec![0; n],
            prof: Profile::new(n),
            q,
            qinv,
            y: vec![0.0; n],
        }
    }

    /// Factor the matrix with `structure` and `values`; Err(original column) for an
    /// exactly zero or non-finite pivot.
    fn factor(
        &mut self,
        structure: &SymbolicSparseColMat<usize>,
        values: &[f64],
    ) -> Result<(), usize> {
        let n = self.n;
        // every nonzero of the last factors (or of a factorisation stopped at a zero
        // pivot) lies within its row's extent
        for (i, e) in self.prof.end.iter().enumerate() {
            self.lu[i * n..=i * n + e].fill(0.0);
        }
        let (cp, ri) = (structure.col_ptr(), structure.row_idx());
        self.prof.clear();
        for j in 0..n {
            let pj = self.qinv[j];
            for k in cp[j]..cp[j + 1] {
                let pi = self.qinv[ri[k]];
                self.lu[pi * n + pj] = values[k];
                if values[k] != 0.0 {
                    self.prof.note(pi, pj);
                }
            }
        }
        for (i, p) in self.perm.iter_mut().enumerate() {
            *p = i;
        }
        lu_rows_in_place(&mut self.lu, n, &mut self.perm, &mut self.prof).map_err(|k| self.q[k])
    }

    /// Solve A x = b for the n-vector `b` in place.
    fn solve(&self, b: &mut [f64], y: &mut [f64]) {
        for (yi, &p) in y.iter_mut().zip(&self.perm) {
            *yi = b[self.q[p]];
        }
        substitute(&self.lu, self.n, &self.prof, y);
        for (yi, &c) in y.iter().zip(&self.q) {
            b[c] = *yi;
        }
    }
}

impl std::fmt::Debug for SparseLu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseLu")
            .field("n", &self.symbolic.n)
            .field("nnz", &self.symbolic.nnz())
            .field("variant", &self.symbolic.variant)
            .field("factored", &self.factored)
            .finish_non_exhaustive()
    }
}

impl SparseLu {
    /// Symbolic analysis of `pattern` (default variant) plus numeric storage. To share the
    /// analysis between several factorisations use [`SparseLuSymbolic::new`] and
    /// [`SparseLu::from_symbolic`] instead.
    pub fn new(pattern: &SparsePattern) -> Result<Self, LinalgError> {
        Ok(Self::from_symbolic(Arc::new(SparseLuSymbolic::new(
            pattern,
        )?)))
    }

    /// Numeric factorisation storage for a shared symbolic analysis. Allocates the scratch
    /// workspace once.
    pub fn from_symbolic(symbolic: Arc<SparseLuSymbolic>) -> Self {
        let factor_mem = MemBuffer::new(symbolic.factor_req);
        let solve_mem = Mutex::new(MemBuffer::new(symbolic.solve_req));
        let probe = vec![0.0; 2 * symbolic.n];
        let scale = vec![1.0; symbolic.n];
        let dense = if symbolic.variant == LuVariant::Dense {
            DenseFactor::new(&symbolic)
        } else {
            DenseFactor::default()
        };
        SparseLu {
            symbolic,
            numeric: NumericLu::new(),
            factor_mem,
            solve_mem,
            probe,
            scale,
            groups: Vec::new(),
            group_max: vec![0.0; 2],
            scaled_values: Vec::new(),
            dense,
            factored: false,
        }
    }

    /// Unknowns in one group share one unit (the translations of a model are in metres,
    /// its angles in radians): [`SparseLu::factor`] then factors D A D, each group scaled
    /// by a power of two near 1/√(its largest diagonal entry), so that a change of units
    /// (a 10 µm element, a model in millimetres) changes neither the pivots nor the
    /// singularity verdict, while a stiffness disparity within one unit (EA far above
    /// EI/L², which no rescaling of the units removes and which the residual's round-off
    /// feels) still counts. `groups[i]` is unknown i's group; without a call, A is
    /// factored as it is.
    pub fn set_unit_groups(&mut self, groups: &[usize]) -> Result<(), LinalgError> {
        if groups.len() != self.symbolic.n {
            return Err(LinalgError::Other(format!(
                "SparseLu::set_unit_groups: {} groups for {} unknowns",
                groups.len(),
                self.symbolic.n
            )));
        }
        self.groups = groups.to_vec();
        self.scaled_values = vec![0.0; self.symbolic.nnz()];
        self.group_max = vec![0.0; 2 * groups.iter().max().map_or(1, |g| g + 1)];
        Ok(())
    }

    /// `scale` from A's `values` and row sums `row_abs`: per group, the power of two
    /// nearest the square root of its largest |diagonal entry| (a row sum of a
    /// small-unit group is dominated by its couplings to large-unit groups and would not
    /// recover its unit), or of its largest row sum for a group without a diagonal.
    fn set_scale(&mut self, values: &[f64], row_abs: &[f64]) {
        let structure = &self.symbolic.structure;
        let ng = self.group_max.len() / 2;
        self.group_max.fill(0.0);
        for (j, &g) in self.groups.iter().enumerate() {
            if let Some(k) = csc_slot(structure, j, j) {
                self.group_max[g] = self.group_max[g].max(values[k].abs());
            }
            self.group_max[ng + g] = self.group_max[ng + g].max(row_abs[j]);
        }
        for (s, &g) in self.scale.iter_mut().zip(&self.groups) {
            let unit = if self.group_max[g] > 0.0 {
                self.group_max[g]
            } else {
                self.group_max[ng + g]
            };
            *s = pow2_near(unit.sqrt());
        }
    }

    /// The unit groups set by [`SparseLu::set_unit_groups`] (empty: one group).
    pub fn unit_groups(&self) -> &[usize] {
        &self.groups
    }

    /// The shared symbolic analysis (clone the `Arc` to build more factorisations).
    pub fn symbolic(&self) -> &Arc<SparseLuSymbolic> {
        &self.symbolic
    }

    /// Matrix dimension n.
    pub fn n(&self) -> usize {
        self.symbolic.n
    }

    /// True after a successful [`factor`](Self::factor) (false after a failed one).
    pub fn is_factored(&self) -> bool {
        self.factored
    }

    /// Numeric LU of the matrix with the symbolic pattern and these `values` (length
    /// nnz, indexed by [`SparsePattern::slot`]).
    ///
    /// Errors: [`LinalgError::NonFinite`] for a NaN/inf value, [`LinalgError::Singular`]
    /// for a structurally or numerically singular matrix (see the module docs for the
    /// probe test), [`LinalgError::Other`] for a wrong `values` length. On error the
    /// previous factorisation is discarded.
    pub fn factor(&mut self, values: &[f64]) -> Result<(), LinalgError> {
        self.factored = false;
        let symbolic = Arc::clone(&self.symbolic);
        let sym = &*symbolic;
        let n = sym.n;
        if values.len() != sym.nnz() {
            return Err(LinalgError::Other(format!(
                "SparseLu::factor: values has length {}, pattern nnz is {}",
                values.len(),
                sym.nnz()
            )));
        }
        // one pass: finiteness, and all-zero columns / rows (the commonest modelling
        // error, an unconnected DOF, reported by index without any factorisation)
        let cp = sym.structure.col_ptr();
        let ri = sym.structure.row_idx();
        let row_abs = &mut self.probe[..n];
        row_abs.fill(0.0);
        let mut finite = true;
        let mut zero_col = None;
        for j in 0..n {
            let mut col_abs = 0.0;
            for k in cp[j]..cp[j + 1] {
                let v = values[k];
                finite &= v.is_finite();
                col_abs += v.abs();
                row_abs[ri[k]] += v.abs();
            }
            if col_abs == 0.0 && zero_col.is_none() {
                zero_col = Some(j);
            }
        }
        if !finite {
            return Err(LinalgError::NonFinite);
        }
        let zero_row = row_abs.iter().position(|&r| r == 0.0);
        if let Some(pivot) = zero_col.into_iter().chain(zero_row).min() {
            return Err(LinalgError::Singular { pivot });
        }
        if n == 0 {
            self.factored = true;
            return Ok(());
        }
        // with unit groups (see `set_unit_groups`) the factored matrix is B = D A D,
        // D constant on each group and a power of two (B's entries keep A's mantissas):
        // the pivots are chosen and the condition measured in consistent units
        let scaled = !self.groups.is_empty();
        if scaled {
            let row_abs = std::mem::take(&mut self.probe);
            self.set_scale(values, &row_abs[..n]);
            self.probe = row_abs;
            let (scale, b, b_row) = (&self.scale, &mut self.scaled_values, &mut self.probe);
            b_row[..n].fill(0.0);
            for j in 0..n {
                for k in cp[j]..cp[j + 1] {
                    b[k] = values[k] / (scale[ri[k]] * scale[j]);
                    b_row[ri[k]] += b[k].abs();
                }
            }
        }
        let a_norm_inf = self.probe[..n].iter().fold(0.0f64, |m, &r| m.max(r));
        let a: &[f64] = if scaled { &self.scaled_values } else { values };

        let verdict = if sym.variant == LuVariant::Dense {
            match self.dense.factor(&sym.structure, a) {
                Err(col) => Probe::NonFinite(col),
                Ok(()) => {
                    self.probe.copy_from_slice(&sym.probe_x);
                    let mut y = std::mem::take(&mut self.dense.y);
                    for col in self.probe.chunks_exact_mut(n) {
                        self.dense.solve(col, &mut y);
                    }
                    self.dense.y = y;
                    probe_verdict(sym, &self.probe, a_norm_inf)
                }
            }
        } else {
            factor_and_probe(
                sym,
                &mut self.numeric,
                &mut self.factor_mem,
                &mut self.probe,
                a,
                a_norm_inf,
            )
        };
        match verdict {
            Probe::Ok => {
                self.factored = true;
                Ok(())
            }
            Probe::Structural(pivot) | Probe::Singular(pivot) => {
                Err(LinalgError::Singular { pivot })
            }
            Probe::NonFinite(first) => {
                let b = std::mem::take(&mut self.scaled_values);
                let pivot = self
                    .locate_null_dof(if scaled { &b } else { values })
                    .unwrap_or(first);
                self.scaled_values = b;
                Err(LinalgError::Singular { pivot })
            }
            Probe::Failed(msg) => Err(LinalgError::Other(msg)),
        }
    }

    /// Error path only (allocates): factorise A + δI with δ = √ε·max|A| on the diagonal
    /// entries present in the pattern and solve with a generic right-hand side; the
    /// solution is dominated by the (near-)null vector of A, whose largest component is
    /// returned.
    fn locate_null_dof(&mut self, values: &[f64]) -> Option<usize> {
        let sym = &*self.symbolic;
        let n = sym.n;
        let amax = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let delta = f64::EPSILON.sqrt() * amax;
        let mut shifted = values.to_vec();
        for j in 0..n {
            if let Some(s) = csc_slot(&sym.structure, j, j) {
                shifted[s] += delta;
            }
        }
        let a = SparseColMatRef::new(sym.structure.as_ref(), &shifted);
        let lu = sym
            .symbolic
            .factorize_numeric_lu(
                &mut self.numeric,
                a,
                Par::Seq,
                MemStack::new(&mut self.factor_mem),
                Default::default(),
            )
            .ok()?;
        let x = &mut self.probe[..n];
        x.copy_from_slice(&sym.probe_x[..n]);
        lu.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(x, n, 1),
            Par::Seq,
            MemStack::new(&mut self.factor_mem),
        );
        if !x.iter().all(|v| v.is_finite()) {
            return None;
        }
        (0..n).max_by(|&i, &j| x[i].abs().total_cmp(&x[j].abs()))
    }

    /// Solves A x = rhs in place with the current factorisation (unchecked fast path).
    ///
    /// Does not allocate and never fails: NaN/inf in `rhs` propagate to the result, and
    /// without a successful [`factor`](Self::factor) `rhs` is filled with NaN. Callers
    /// check the result for finiteness, or use
    /// [`try_solve_in_place`](Self::try_solve_in_place), which does it for them.
    ///
    /// # Panics
    /// If `rhs.len() != n` (a programming error).
    pub fn solve_in_place(&self, rhs: &mut [f64]) {
        let n = self.symbolic.n;
        assert_eq!(
            rhs.len(),
            n,
            "SparseLu::solve_in_place: rhs length does not match the matrix dimension"
        );
        if !self.factored {
            rhs.fill(f64::NAN);
            return;
        }
        if n == 0 {
            return;
        }
        let dense = self.symbolic.variant == LuVariant::Dense;
        let run = |mem: &mut MemBuffer, rhs: &mut [f64]| {
            if dense {
                // the permuted right-hand side lives in the scratch buffer
                let (mut y, _) = MemStack::new(mem).make_with(n, |_| 0.0f64);
                self.dense.solve(rhs, &mut y);
                return;
            }
            let lu = LuRef::new_unchecked(&self.symbolic.symbolic, &self.numeric);
            lu.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(rhs, n, 1),
                Par::Seq,
                MemStack::new(mem),
            )
        };
        // B = D A D is factored: A x = b is B (D⁻¹x) = D b, D = diag(1/scale)
        let scaled = !self.groups.is_empty();
        if scaled {
            rhs.iter_mut().zip(&self.scale).for_each(|(b, s)| *b /= s);
        }
        match self.solve_mem.try_lock() {
            Ok(mut mem) => run(&mut mem, rhs),
            Err(TryLockError::Poisoned(p)) => run(&mut p.into_inner(), rhs),
            Err(TryLockError::WouldBlock) => run(&mut MemBuffer::new(self.symbolic.solve_req), rhs),
        }
        if scaled {
            rhs.iter_mut().zip(&self.scale).for_each(|(z, s)| *z /= s);
        }
    }

    /// Checked [`solve_in_place`](Self::solve_in_place): never panics, no allocation on
    /// success.
    ///
    /// Errors: [`LinalgError::NonFinite`] for a NaN/inf in `rhs` (left unchanged),
    /// [`LinalgError::Singular`] if the solution is not finite (overflow; `pivot` is the
    /// first non-finite component), [`LinalgError::Other`] for a wrong length or if there
    /// is no valid factorisation.
    pub fn try_solve_in_place(&self, rhs: &mut [f64]) -> Result<(), LinalgError> {
        let n = self.symbolic.n;
        if rhs.len() != n {
            return Err(LinalgError::Other(format!(
                "SparseLu::try_solve_in_place: rhs has length {}, matrix is {n}×{n}",
                rhs.len()
            )));
        }
        if !self.factored {
            return Err(LinalgError::Other(
                "SparseLu::try_solve_in_place called without a successful factor()".into(),
            ));
        }
        if !rhs.iter().all(|v| v.is_finite()) {
            return Err(LinalgError::NonFinite);
        }
        self.solve_in_place(rhs);
        match rhs.iter().position(|v| !v.is_finite()) {
            Some(i) => Err(LinalgError::Singular { pivot: i }),
            None => Ok(()),
        }
    }
}

/// Outcome of a numeric factorisation followed by the probe solve.
enum Probe {
    Ok,
    /// faer found no pivot candidate; original column index
    Structural(usize),
    /// finite probe solution failing the test; index of its largest component
    Singular(usize),
    /// non-finite probe solution (exact zero pivot); first non-finite index
    NonFinite(usize),
    Failed(String),
}

/// Numeric factorisation into `numeric`, then the probe solve (see module docs):
/// X = A⁻¹X* for two generic right-hand sides, condition estimate
/// ‖A‖∞‖X‖max/‖X*‖max ≤ κ∞(A). For a (near-)singular A the columns of X* have components
/// outside the range of A, so X is dominated by the null vector.
fn factor_and_probe(
    sym: &SparseLuSymbolic,
    numeric: &mut NumericLu<usize, f64>,
    mem: &mut MemBuffer,
    probe: &mut [f64],
    values: &[f64],
    a_norm_inf: f64,
) -> Probe {
    let n = sym.n;
    let a = SparseColMatRef::new(sym.structure.as_ref(), values);
    let lu = match sym.symbolic.factorize_numeric_lu(
        numeric,
        a,
        Par::Seq,
        MemStack::new(mem),
        Default::default(),
    ) {
        Ok(lu) => lu,
        Err(LuError::SymbolicSingular { index }) => {
            return Probe::Structural(sym.original_col(index))
        }
        Err(LuError::Generic(e)) => {
            return Probe::Failed(format!("sparse LU factorisation: {e:?}"))
        }
    };
    probe.copy_from_slice(&sym.probe_x);
    lu.solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(probe, n, 2),
        Par::Seq,
        MemStack::new(mem),
    );
    probe_verdict(sym, probe, a_norm_inf)
}

/// The probe test on the solutions `probe` (n×2) of the two probe right-hand sides.
fn probe_verdict(sym: &SparseLuSymbolic, probe: &[f64], a_norm_inf: f64) -> Probe {
    let n = sym.n;
    let mut big = 0;
    let mut x_max = 0.0f64;
    for (i, x) in probe.iter().enumerate() {
        if !x.is_finite() {
            return Probe::NonFinite(i % n);
        }
        if x.abs() > x_max {
            (big, x_max) = (i % n, x.abs());
        }
    }
    if a_norm_inf * x_max > SINGULAR_COND_LIMIT * sym.probe_x_max {
        return Probe::Singular(big);
    }
    Probe::Ok
}

// ---------------------------------------------------------------------------------------
// Dense helpers (small problems; allocate freely)
// ---------------------------------------------------------------------------------------

fn check_square(name: &str, a: &[f64], n: usize) -> Result<(), LinalgError> {
    if a.len() != n * n {
        return Err(LinalgError::Other(format!(
            "{name}: matrix has {} entries, expected {n}×{n} = {}",
            a.len(),
            n * n
        )));
    }
    if !a.iter().all(|v| v.is_finite()) {
        return Err(LinalgError::NonFinite);
    }
    Ok(())
}

/// Solves A x = b in place for a dense row-major n×n `a` (LU with partial pivoting).
///
/// [`LinalgError::Singular`] if a pivot is zero or below `n·ε·max|A|` (numerically
/// singular; `pivot` is that column), or the solution is not finite.
pub fn dense_solve(a: &[f64], n: usize, b: &mut [f64]) -> Result<(), LinalgError> {
    check_square("dense_solve", a, n)?;
    if b.len() != n {
        return Err(LinalgError::Other(format!(
            "dense_solve: rhs has length {}, matrix is {n}×{n}",
            b.len()
        )));
    }
    if !b.iter().all(|v| v.is_finite()) {
        return Err(LinalgError::NonFinite);
    }
    if n == 0 {
        return Ok(());
    }
    dense_sequential();
    let amat = MatRef::from_row_major_slice(a, n, n);
    let lu = amat.partial_piv_lu();
    let amax = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let tol = n as f64 * f64::EPSILON * amax;
    let u = lu.U();
    for i in 0..n {
        let p = u[(i, i)];
        if !p.is_finite() || p.abs() <= tol {
            return Err(LinalgError::Singular { pivot: i });
        }
    }
    lu.solve_in_place(MatMut::from_column_major_slice_mut(b, n, 1));
    match b.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(LinalgError::Singular { pivot: i }),
        None => Ok(()),
    }
}

/// Generalised symmetric-definite eigenproblem K φ = λ M φ.
///
/// `k` symmetric, `m` symmetric positive definite, both row-major n×n (symmetrised as
/// (A + Aᵀ)/2 before use). Returns `(eigenvalues, eigenvectors)`: eigenvalues ascending;
/// eigenvectors column-major n×n (column j, i.e. `phi[j*n..(j+1)*n]`, belongs to
/// eigenvalue j), M-normalised (φᵀMφ = 1) and sign-fixed so that each vector's
/// largest-magnitude component is positive. Method: M = L Lᵀ (Cholesky), symmetric
/// eigendecomposition of L⁻¹ K L⁻ᵀ = U Λ Uᵀ, φ = L⁻ᵀ U.
///
/// [`LinalgError::NotPositiveDefinite`] if the Cholesky factorisation of M fails.
pub fn generalized_sym_eig(
    k: &[f64],
    m: &[f64],
    n: usize,
) -> Result<(Vec<f64>, Vec<f64>), LinalgError> {
    dense_sequential();
    check_square("generalized_sym_eig (K)", k, n)?;
    check_square("generalized_sym_eig (M)", m, n)?;
    if n == 0 {
        return Ok((Vec::new(), Vec::new()));
    }
    let sym = |a: &[f64]| Mat::<f64>::from_fn(n, n, |i, j| 0.5 * (a[i * n + j] + a[j * n + i]));
    let kk = sym(k);
    let mm = sym(m);
    let llt = mm
        .llt(Side::Lower)
        .map_err(|_| LinalgError::NotPositiveDefinite)?;
    let l = llt.L();
    if !(0..n).all(|i| l[(i, i)].is_finite() && l[(i, i)] > 0.0) {
        return Err(LinalgError::NotPositiveDefinite);
    }
    // X = L⁻¹ K; Y = L⁻¹ Xᵀ = L⁻¹ K L⁻ᵀ
    let mut x = kk;
    l.solve_lower_triangular_in_place(x.as_mut());
    let mut y = x.transpose().to_owned();
    l.solve_lower_triangular_in_place(y.as_mut());
    let c = Mat::<f64>::from_fn(n, n, |i, j| 0.5 * (y[(i, j)] + y[(j, i)]));
    let (up, down) = unit_scale((0..n * n).map(|q| c[(q / n, q % n)]));
    let c = Mat::<f64>::from_fn(n, n, |i, j| c[(i, j)] * up);
    let eig = c
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| LinalgError::Other(format!("symmetric eigensolver: {e:?}")))?;
    let s = eig.S().column_vector();
    let lambda: Vec<f64> = (0..n).map(|i| s[i] * down).collect();
    let mut phi = eig.U().to_owned();
    l.transpose().solve_upper_triangular_in_place(phi.as_mut());

    let mut out = vec![0.0; n * n];
    for j in 0..n {
        let col = &mut out[j * n..(j + 1) * n];
        let mut big = 0.0f64;
        for (i, c) in col.iter_mut().enumerate() {
            *c = phi[(i, j)];
            if c.abs() > big.abs() {
                big = *c;
            }
        }
        if big < 0.0 {
            col.iter_mut().for_each(|c| *c = -*c);
        }
    }
    if !lambda.iter().chain(&out).all(|v| v.is_finite()) {
        return Err(LinalgError::NonFinite);
    }
    Ok((lambda, out))
}

/// Powers of two `(up, down)`, up·down = 1, that bring the largest |entry| of `a` near 1
/// (both 1 for a zero or non-finite matrix). faer's symmetric eigensolver is not
/// invariant to the matrix's scale: above 128 rows it divides and conquers, and its
/// deflation tolerance, 8ε·max(max|d|, max|z|) (faer 0.24, `tridiag_evd.rs`), mixes the
/// diagonal with the unit-norm update vector, so for a matrix whose norm is far below 1
/// it is an absolute 8ε and merges eigenvalues that differ by less. LAPACK's `dstedc`
/// scales the tridiagonal to unit norm first; this does the same. A 600-coordinate mass
/// matrix of 1e-8 kg read 299 eigenvalues of −1.6e-17 (1.6e-9 of its norm) unscaled and
/// −3.8e-24 scaled. Powers of two change no mantissa.
fn unit_scale(a: impl IntoIterator<Item = f64>) -> (f64, f64) {
    let amax = a.into_iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let down = pow2_near(amax);
    (1.0 / down, down)
}

/// The power of two nearest `x` (to the nearest exponent, see [`pow2_exponent`]).
/// Scaling by it changes no mantissa.
pub fn pow2_near(x: f64) -> f64 {
    2f64.powi(pow2_exponent(x))
}

/// round(log2 |x|), clamped to ±1000 so that 2^e and its inverse stay normal (a matrix
/// whose entries reach 1e306 is scaled as far as that allows, not left as it is); 0 where
/// `x` is zero or not finite.
pub fn pow2_exponent(x: f64) -> i32 {
    let e = x.abs().log2().round();
    if e.is_finite() {
        e.clamp(-1000.0, 1000.0) as i32
    } else {
        0
    }
}

/// Jacobi scaling in place: A ← D A D with dᵢ = `d_of`(|Aᵢᵢ|) (1 where Aᵢᵢ is zero or not
/// finite). Returns D's diagonal.
pub fn jacobi_scale(a: &mut [f64], n: usize, d_of: impl Fn(f64) -> f64) -> Vec<f64> {
    let d: Vec<f64> = (0..n)
        .map(|i| {
            let q = a[i * n + i].abs();
            if q > 0.0 && q.is_finite() {
                d_of(q)
            } else {
                1.0
            }
        })
        .collect();
    for i in 0..n {
        for j in 0..n {
            a[i * n + j] *= d[i] * d[j];
        }
    }
    d
}

/// Makes faer's dense routines run on the calling thread: the same bits whatever the
/// thread count of the pool they are called from (see the module documentation).
fn dense_sequential() {
    faer::set_global_parallelism(Par::Seq);
}

/// Symmetric eigendecomposition of the row-major n×n `a` (symmetrised as (A + Aᵀ)/2):
/// eigenvalues ascending, eigenvectors orthonormal, column-major (column j is
/// `u[j*n..(j+1)*n]`).
pub fn sym_eig(a: &[f64], n: usize) -> Result<(Vec<f64>, Vec<f64>), LinalgError> {
    dense_sequential();
    check_square("sym_eig", a, n)?;
    if n == 0 {
        return Ok((Vec::new(), Vec::new()));
    }
    let (up, down) = unit_scale(a.iter().copied());
    let c = Mat::<f64>::from_fn(n, n, |i, j| 0.5 * (a[i * n + j] + a[j * n + i]) * up);
    let eig = c
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| LinalgError::Other(format!("symmetric eigensolver: {e:?}")))?;
    let s = eig.S().column_vector();
    let lambda: Vec<f64> = (0..n).map(|i| s[i] * down).collect();
    let u = eig.U();
    let mut out = vec![0.0; n * n];
    for j in 0..n {
        for i in 0..n {
            out[j * n + i] = u[(i, j)];
        }
    }
    if !lambda.iter().chain(&out).all(|v| v.is_finite()) {
        return Err(LinalgError::NonFinite);
    }
    Ok((lambda, out))
}

/// Where the nonzeros of a row-major n×n matrix under elimination can be: row i's last
/// nonzero column `end[i]` (0 for an empty row), its first multiplier column `start[i]`
/// (n while it has none), and column j's last nonzero row `cend[j]`. Upper bounds that
/// [`lu_rows_in_place`] keeps valid through its swaps and fill, so that it and
/// [`substitute`] visit only the profile of a banded or bordered matrix.
#[derive(Clone, Debug, Default)]
struct Profile {
    end: Vec<usize>,
    start: Vec<usize>,
    cend: Vec<usize>,
}

impl Profile {
    fn new(n: usize) -> Profile {
        Profile {
            end: vec![0; n],
            start: vec![n; n],
            cend: vec![0; n],
        }
    }

    /// Empty: no nonzero seen yet.
    fn clear(&mut self) {
        let n = self.end.len();
        self.end.fill(0);
        self.start.fill(n);
        self.cend.fill(0);
    }

    /// A nonzero at (i, j) of the matrix about to be factored.
    #[inline]
    fn note(&mut self, i: usize, j: usize) {
        self.end[i] = self.end[i].max(j);
        self.cend[j] = self.cend[j].max(i);
    }

    fn of_dense(a: &[f64], n: usize) -> Profile {
        let mut p = Profile::new(n);
        for (k, _) in a.iter().enumerate().filter(|(_, x)| **x != 0.0) {
            p.note(k / n, k % n);
        }
        p
    }
}

/// LU with partial pivoting of the row-major n×n `lu` in place: P A = L U with the unit
/// lower L below the diagonal, `perm[i]` the row of A that became row i (`perm` enters as
/// the identity, or any row order). Only the rows with a nonzero in the pivot column
/// (down to `prof.cend`) are updated, and only up to the pivot row's last nonzero
/// (`prof.end`): the skipped terms are products with exact zeros, so the factors are
/// those of the plain dense algorithm while a banded matrix costs O(n·b²), not O(n³).
/// Err(k) for an exactly zero or non-finite pivot in column k.
fn lu_rows_in_place(
    lu: &mut [f64],
    n: usize,
    perm: &mut [usize],
    prof: &mut Profile,
) -> Result<(), usize> {
    for k in 0..n {
        let last = prof.cend[k].max(k);
        let mut p = k;
        for i in k + 1..=last {
            if lu[i * n + k].abs() > lu[p * n + k].abs() {
                p = i;
            }
        }
        let piv = lu[p * n + k];
        if piv == 0.0 || !piv.is_finite() {
            return Err(k);
        }
        if p != k {
            let w = prof.end[k].max(prof.end[p]);
            // both rows' multipliers (columns < k) move with them; before the first
            // multiplier and past w both are zero
            let lo = prof.start[k].min(prof.start[p]).min(k);
            let (upper, lower) = lu.split_at_mut(p * n);
            upper[k * n + lo..=k * n + w].swap_with_slice(&mut lower[lo..=w]);
            perm.swap(k, p);
            prof.end.swap(k, p);
            prof.start.swap(k, p);
            // row k's old entries now sit in row p
            for c in k + 1..=prof.end[p] {
                prof.cend[c] = prof.cend[c].max(p);
            }
        }
        let ek = prof.end[k];
        let (top, rest) = lu.split_at_mut((k + 1) * n);
        let rowk = &top[k * n + k + 1..k * n + ek + 1];
        for i in k + 1..=last {
            let row = &mut rest[(i - k - 1) * n..(i - k) * n];
            if row[k] == 0.0 {
                continue;
            }
            let l = row[k] / piv;
            row[k] = l;
            for (x, y) in row[k + 1..=ek].iter_mut().zip(rowk) {
                *x -= l * y;
            }
            prof.end[i] = prof.end[i].max(ek);
            prof.start[i] = prof.start[i].min(k);
        }
        // the fill of rows k+1..=last reaches columns k+1..=ek
        for c in k + 1..=ek {
            prof.cend[c] = prof.cend[c].max(last);
        }
    }
    Ok(())
}

/// Forward and back substitution with factors and profile from [`lu_rows_in_place`] for
/// the already permuted right-hand side `y` (y[i] = b[perm[i]]), in place.
fn substitute(lu: &[f64], n: usize, prof: &Profile, y: &mut [f64]) {
    for i in 0..n {
        let s = prof.start[i].min(i);
        let row = &lu[i * n + s..i * n + i];
        y[i] = row
            .iter()
            .zip(&y[s..i])
            .fold(y[i], |acc, (l, x)| acc - l * x);
    }
    for i in (0..n).rev() {
        let e = prof.end[i].max(i);
        let row = &lu[i * n + i + 1..i * n + e + 1];
        let acc = row
            .iter()
            .zip(&y[i + 1..=e])
            .fold(y[i], |acc, (u, x)| acc - u * x);
        y[i] = acc / lu[i * n + i];
    }
}

/// Dense LU with partial pivoting, P A = L U, kept in one row-major array (unit lower L
/// below the diagonal). Unlike [`dense_solve`] it rejects only exactly zero or
/// non-finite pivots: a graded matrix (axial rows 1e16 times the bending rows) has
/// legitimate pivots far below n·ε·max|A|, and partial pivoting solves such matrices
/// accurately in the small rows.
pub struct DenseLu {
    n: usize,
    lu: Vec<f64>,
    /// row i of P A is row `perm[i]` of A
    perm: Vec<usize>,
    prof: Profile,
}

impl DenseLu {
    pub fn new(a: &[f64], n: usize) -> Result<DenseLu, LinalgError> {
        check_square("DenseLu", a, n)?;
        let mut lu = a.to_vec();
        let mut perm: Vec<usize> = (0..n).collect();
        let mut prof = Profile::of_dense(&lu, n);
        lu_rows_in_place(&mut lu, n, &mut perm, &mut prof)
            .map_err(|pivot| LinalgError::Singular { pivot })?;
        Ok(DenseLu { n, lu, perm, prof })
    }

    /// Solves A x = b in place; an error if the result is not finite.
    pub fn solve(&self, b: &mut [f64]) -> Result<(), LinalgError> {
        let n = self.n;
        if b.len() != n {
            return Err(LinalgError::Other(format!(
                "DenseLu::solve: rhs has length {}, matrix is {n}×{n}",
                b.len()
            )));
        }
        let mut y: Vec<f64> = self.perm.iter().map(|&p| b[p]).collect();
        substitute(&self.lu, n, &self.prof, &mut y);
        if !y.iter().all(|v| v.is_finite()) {
            return Err(LinalgError::NonFinite);
        }
        b.copy_from_slice(&y);
        Ok(())
    }
}

/// Balances the row-major n×n `a` in place by a diagonal similarity D⁻¹ A D in powers of
/// two, so that each row and its column have comparable norms (Parlett and Reinsch,
/// Numer. Math. 13, 1969: EISPACK `balanc`, LAPACK `dgebal` without its permutations).
/// The eigenvalues do not change, and no mantissa does. A nonsymmetric eigen-solver's
/// error is absolute on the scale of ‖A‖, and a matrix whose coordinates have different
/// units (a beam's translations in metres beside its angles in radians) has entries
/// that scale with the unit, so unbalanced, a 0.5 mm blade's flap mode read 3.8e-5 to
/// 4.4e-4 off and its round-off scale above the frequencies. faer 0.24's `eigenvalues` does
/// not balance.
pub fn balance(a: &mut [f64], n: usize) {
    if a.len() != n * n || !a.iter().all(|v| v.is_finite()) {
        return;
    }
    // a fixed number of sweeps: each converges geometrically, and a pathological matrix
    // must not loop
    for _ in 0..64 {
        let mut done = true;
        for i in 0..n {
            let (mut c, mut r) = (0.0f64, 0.0f64);
            for j in (0..n).filter(|&j| j != i) {
                c += a[j * n + i].abs();
                r += a[i * n + j].abs();
            }
            if c == 0.0 || r == 0.0 {
                continue;
            }
            let s = c + r;
            // f: the power of two that brings the column's norm (c f) within a factor 2
            // of the row's (r / f); c tracks c f²
            let mut f = 1.0f64;
            while c < r / 2.0 && f < 1e150 {
                f *= 2.0;
                c *= 4.0;
            }
            while c >= r * 2.0 && f > 1e-150 {
                f /= 2.0;
                c /= 4.0;
            }
            // only a scaling that shrinks the two norms' sum by 5 % is worth a change
            if (c + r) / f < 0.95 * s {
                done = false;
                for j in 0..n {
                    a[i * n + j] /= f;
                    a[j * n + i] *= f;
                }
            }
        }
        if done {
            break;
        }
    }
}

/// Eigenvalues `(re, im)` of a general real row-major n×n matrix, sorted by modulus
/// ascending, then by imaginary part ascending (so a conjugate pair ±iω appears as
/// `(0, -ω), (0, ω)`). Complex eigenvalues come in conjugate pairs. The matrix is
/// [`balance`]d first.
pub fn general_eig(a: &[f64], n: usize) -> Result<Vec<(f64, f64)>, LinalgError> {
    general_eig_balancing(&mut a.to_vec(), n)
}

/// [`general_eig`] on `a` balanced in place: a caller that needs the balanced matrix
/// (its scale, for the eigenvalues' round-off) reads it afterwards instead of balancing
/// twice.
pub fn general_eig_balancing(a: &mut [f64], n: usize) -> Result<Vec<(f64, f64)>, LinalgError> {
    dense_sequential();
    check_square("general_eig", a, n)?;
    if n == 0 {
        return Ok(Vec::new());
    }
    balance(a, n);
    let amat = MatRef::from_row_major_slice(a, n, n);
    let ev = amat
        .eigenvalues()
        .map_err(|e| LinalgError::Other(format!("general eigensolver: {e:?}")))?;
    let mut out: Vec<(f64, f64)> = ev.iter().map(|z| (z.re, z.im)).collect();
    if !out.iter().all(|(re, im)| re.is_finite() && im.is_finite()) {
        return Err(LinalgError::NonFinite);
    }
    out.sort_by(|p, q| {
        p.0.hypot(p.1)
            .total_cmp(&q.0.hypot(q.1))
            .then(p.1.total_cmp(&q.1))
            .then(p.0.total_cmp(&q.0))
    });
    Ok(out)
}

// ---------------------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;

    /// Tiny deterministic LCG (Knuth MMIX constants), uniform f64 in [0, 1).
    struct Lcg(u64);
    impl Lcg {
        fn next_u64(&mut self) -> u64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            self.0
        }
        fn uniform(&mut self) -> f64 {
            (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
        }
        fn below(&mut self, n: usize) -> usize {
            ((self.next_u64() >> 33) % n as u64) as usize
        }
    }

    const VARIANTS: [LuVariant; 4] = [
        LuVariant::Supernodal,
        LuVariant::Simplicial,
        LuVariant::Auto,
        LuVariant::Dense,
    ];

    /// Random structurally symmetric pattern with full diagonal, some duplicate pairs.
    fn random_pattern(
        rng: &mut Lcg,
        n: usize,
        per_row: usize,
    ) -> (SparsePattern, Vec<(usize, usize)>) {
        let mut pairs: Vec<(usize, usize)> = (0..n).map(|i| (i, i)).collect();
        for i in 0..n {
            for _ in 0..per_row {
                let j = rng.below(n);
                pairs.push((i, j));
                pairs.push((j, i));
            }
        }
        // a few explicit duplicates
        for k in 0..n.min(5) {
            pairs.push((k, k));
        }
        (SparsePattern::new(n, &pairs), pairs)
    }

    /// Unsymmetric values, strictly diagonally dominant by rows.
    fn random_dd_values(rng: &mut Lcg, p: &SparsePattern) -> Vec<f64> {
        let n = p.n();
        let mut v: Vec<f64> = (0..p.nnz()).map(|_| 2.0 * rng.uniform() - 1.0).collect();
        let mut rowsum = vec![0.0; n];
        for (j, w) in p.col_ptr().windows(2).enumerate() {
            for (&i, x) in p.row_idx()[w[0]..w[1]].iter().zip(&v[w[0]..w[1]]) {
                if i != j {
                    rowsum[i] += x.abs();
                }
            }
        }
        for (i, rs) in rowsum.iter().enumerate() {
            let s = p.slot(i, i).unwrap();
            let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
            v[s] = sign * (rs + 0.5 + rng.uniform());
        }
        v
    }

    /// det_sign against a closed form: a strictly diagonally dominant matrix keeps its
    /// determinant's sign while its off-diagonal part is scaled to zero (it stays
    /// nonsingular), so sign det A = ∏ sign(a_ii). Exact (a sign), for every kernel
    /// variant's column order, with pivoting that need not keep the diagonal in place.
    #[test]
    fn det_sign_of_diagonally_dominant_matrices_is_the_product_of_diagonal_signs() {
        let mut rng = Lcg(0x05ee_dd37);
        for &variant in &VARIANTS {
            for &(n, per_row) in &[(1, 0), (2, 1), (7, 2), (40, 3), (200, 4)] {
                for _ in 0..5 {
                    let (p, _) = random_pattern(&mut rng, n, per_row);
                    let v = random_dd_values(&mut rng, &p);
                    let want: i8 = (0..n)
                        .map(|i| {
                            if v[p.slot(i, i).unwrap()] < 0.0 {
                                -1i8
                            } else {
                                1
                            }
                        })
                        .product();
                    let sym = SparseLuSymbolic::with_variant(&p, variant).unwrap();
                    let (sign, _) = sym.det_sign(&v).unwrap();
                    assert_eq!(sign, want, "n={n} variant={variant:?}");
                }
            }
        }
    }

    fn rel_err(x: &[f64], y: &[f64]) -> f64 {
        let d = x
            .iter()
            .zip(y)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let s = y.iter().fold(0.0f64, |m, b| m.max(b.abs()));
        d / s
    }

    fn check_against_dense(lu: &SparseLu, p: &SparsePattern, v: &[f64], rng: &mut Lcg) {
        let n = p.n();
        let b: Vec<f64> = (0..n).map(|_| 2.0 * rng.uniform() - 1.0).collect();
        let mut x = b.clone();
        lu.try_solve_in_place(&mut x).unwrap();
        let mut xd = b.clone();
        dense_solve(&p.to_dense(v), n, &mut xd).unwrap();
        let e = rel_err(&x, &xd);
        assert!(e <= 1e-12, "n={n} rel err {e:e}");
        // and the residual
        let mut r = vec![0.0; n];
        p.mul_vec(v, &x, &mut r);
        assert!(rel_err(&r, &b) <= 1e-12);
    }

    #[test]
    fn linalg_pattern_slots_and_duplicates() {
        let p = SparsePattern::new(4, &[(0, 0), (1, 0), (0, 0), (3, 3), (2, 1), (1, 0), (0, 3)]);
        assert_eq!(p.nnz(), 5);
        assert_eq!(p.col_ptr(), &[0, 2, 3, 3, 5]);
        assert_eq!(p.row_idx(), &[0, 1, 2, 0, 3]);
        assert_eq!(p.slot(0, 0), Some(0));
        assert_eq!(p.slot(1, 0), Some(1));
        assert_eq!(p.slot(2, 1), Some(2));
        assert_eq!(p.slot(0, 3), Some(3));
        assert_eq!(p.slot(3, 3), Some(4));
        assert_eq!(p.slot(2, 2), None);
        assert_eq!(p.slot(0, 1), None);
        assert_eq!(p.slot(9, 0), None);
        // scatter with a duplicate slot accumulates
        let mut v = vec![0.0; p.nnz()];
        for &(r, c, x) in &[(0, 0, 1.0), (0, 0, 2.0), (3, 3, 5.0)] {
            v[p.slot(r, c).unwrap()] += x;
        }
        assert_eq!(v, vec![3.0, 0.0, 0.0, 0.0, 5.0]);
    }

    #[test]
    #[should_panic(expected = "out of range")]
    fn linalg_pattern_rejects_out_of_range() {
        SparsePattern::new(3, &[(0, 3)]);
    }

    #[test]
    fn linalg_sparse_lu_matches_dense_and_refactors() {
        let mut rng = Lcg(0x1a7d_1234_5678_9abc);
        for &(n, per_row) in &[
            (1usize, 0usize),
            (2, 1),
            (7, 2),
            (40, 3),
            (200, 4),
            (600, 3),
        ] {
            let (p, _) = random_pattern(&mut rng, n, per_row);
            for variant in VARIANTS {
                let sym = Arc::new(SparseLuSymbolic::with_variant(&p, variant).unwrap());
                assert_eq!(sym.variant(), variant);
                let mut lu = SparseLu::from_symbolic(sym);
                for _refactor in 0..3 {
                    let v = random_dd_values(&mut rng, &p);
                    lu.factor(&v).unwrap();
                    assert!(lu.is_factored());
                    check_against_dense(&lu, &p, &v, &mut rng);
                    check_against_dense(&lu, &p, &v, &mut rng);
                }
            }
        }
    }

    /// The textbook row-major LU with partial pivoting (first largest pivot, every row
    /// and column visited), against which the profile-confined kernel is checked.
    fn plain_lu(a: &mut [f64], n: usize, perm: &mut [usize]) {
        for k in 0..n {
            let mut p = k;
            for i in k + 1..n {
                if a[i * n + k].abs() > a[p * n + k].abs() {
                    p = i;
                }
            }
            for j in 0..n {
                a.swap(k * n + j, p * n + j);
            }
            perm.swap(k, p);
            for i in k + 1..n {
                let l = a[i * n + k] / a[k * n + k];
                a[i * n + k] = l;
                for j in k + 1..n {
                    a[i * n + j] -= l * a[k * n + j];
                }
            }
        }
    }

    #[test]
    fn profile_lu_gives_the_plain_dense_factors_bit_for_bit() {
        // banded matrices with a dense border (a hinge coupled to every node), random
        // values and holes, weak diagonals so that partial pivoting swaps rows
        let mut rng = Lcg(7);
        for &(n, b) in &[
            (1usize, 0usize),
            (5, 1),
            (40, 3),
            (61, 11),
            (90, 20),
            (50, 49),
        ] {
            for border in [false, true] {
                let mut a = vec![0.0; n * n];
                for i in 0..n {
                    for j in 0..n {
                        let inside = i.abs_diff(j) <= b || (border && (i == n - 1 || j == n - 1));
                        if inside && rng.uniform() > 0.2 {
                            a[i * n + j] = rng.uniform() - 0.5;
                        }
                    }
                    a[i * n + i] += 0.1;
                }
                let mut plain = a.clone();
                let mut perm0: Vec<usize> = (0..n).collect();
                plain_lu(&mut plain, n, &mut perm0);
                let lu = DenseLu::new(&a, n).unwrap();
                assert_eq!(lu.perm, perm0, "n={n} b={b} border={border}");
                for (k, (x, y)) in lu.lu.iter().zip(&plain).enumerate() {
                    assert!(x == y, "n={n} b={b} border={border} entry {k}: {x} vs {y}");
                }
                // and the sparse front end's dense variant solves with them
                let pairs: Vec<(usize, usize)> = (0..n * n)
                    .filter(|&k| a[k] != 0.0)
                    .map(|k| (k / n, k % n))
                    .collect();
                let p = SparsePattern::new(n, &pairs);
                let mut v = vec![0.0; p.nnz()];
                for &(i, j) in &pairs {
                    v[p.slot(i, j).unwrap()] = a[i * n + j];
                }
                let mut slu = SparseLu::from_symbolic(Arc::new(
                    SparseLuSymbolic::with_variant(&p, LuVariant::Dense).unwrap(),
                ));
                slu.factor(&v).unwrap();
                check_against_dense(&slu, &p, &v, &mut rng);
            }
        }
    }

    #[test]
    fn linalg_sparse_lu_needs_pivoting() {
        // zero diagonal blocks force row interchanges: [[0, B], [Bᵀ, 0]] with B diag-dominant
        let mut rng = Lcg(99);
        let h = 30;
        let n = 2 * h;
        let mut pairs = Vec::new();
        for i in 0..h {
            for d in [0usize, 1] {
                let j = (i + d) % h;
                pairs.push((i, h + j));
                pairs.push((h + j, i));
            }
        }
        let p = SparsePattern::new(n, &pairs);
        let mut v = vec![0.0; p.nnz()];
        for i in 0..h {
            v[p.slot(i, h + i).unwrap()] = 3.0 + rng.uniform();
            v[p.slot(h + i, i).unwrap()] = 2.0 + rng.uniform();
            let j = (i + 1) % h;
            v[p.slot(i, h + j).unwrap()] = rng.uniform();
            v[p.slot(h + j, i).unwrap()] = -rng.uniform();
        }
        for variant in VARIANTS {
            let mut lu = SparseLu::from_symbolic(Arc::new(
                SparseLuSymbolic::with_variant(&p, variant).unwrap(),
            ));
            lu.factor(&v).unwrap();
            check_against_dense(&lu, &p, &v, &mut rng);
        }
    }

    #[test]
    fn linalg_shared_symbolic_across_threads() {
        fn assert_send_sync<T: Send + Sync>() {}
        assert_send_sync::<SparseLu>();
        assert_send_sync::<SparseLuSymbolic>();

        let mut rng = Lcg(7);
        let (p, _) = random_pattern(&mut rng, 150, 3);
        let sym = Arc::new(SparseLuSymbolic::new(&p).unwrap());
        let inputs: Vec<Vec<f64>> = (0..4).map(|_| random_dd_values(&mut rng, &p)).collect();
        std::thread::scope(|s| {
            for (t, v) in inputs.iter().enumerate() {
                let sym = Arc::clone(&sym);
                let p = &p;
                s.spawn(move || {
                    let mut rng = Lcg(1000 + t as u64);
                    let mut lu = SparseLu::from_symbolic(sym);
                    for _ in 0..3 {
                        lu.factor(v).unwrap();
                        check_against_dense(&lu, p, v, &mut rng);
                    }
                });
            }
        });
    }

    fn singular_cases() -> Vec<(&'static str, SparsePattern, Vec<f64>)> {
        let mut cases = Vec::new();
        // structurally singular: column 2 has no entries at all
        let p = SparsePattern::new(3, &[(0, 0), (1, 1), (2, 1), (0, 1)]);
        let v = vec![1.0; p.nnz()];
        cases.push(("empty column", p, v));
        // structurally rank deficient without zero rows/columns: columns 0 and 1 only
        // have row 0, rows 1 and 2 only have column 2
        let p = SparsePattern::new(3, &[(0, 0), (0, 1), (1, 2), (2, 2)]);
        let v = vec![1.5, -2.0, 3.0, 0.5];
        cases.push(("structural rank 2", p, v));
        // numerically singular: an explicit zero row in a full pattern
        let n = 5;
        let pairs: Vec<_> = (0..n).flat_map(|i| (0..n).map(move |j| (i, j))).collect();
        let p = SparsePattern::new(n, &pairs);
        let mut v: Vec<f64> = (0..p.nnz()).map(|k| 1.0 + (k % 7) as f64).collect();
        for j in 0..n {
            v[p.slot(3, j).unwrap()] = 0.0;
        }
        cases.push(("zero row", p.clone(), v));
        // numerically singular: row 4 = row 1 (exact duplicate)
        let mut rng = Lcg(5);
        let mut v: Vec<f64> = (0..p.nnz()).map(|_| rng.uniform() + 0.1).collect();
        for j in 0..n {
            v[p.slot(4, j).unwrap()] = v[p.slot(1, j).unwrap()];
        }
        cases.push(("duplicate row", p.clone(), v));
        // rank-deficient by roundoff: row 2 = 0.1·row 0 + 0.3·row 1 (inexact in binary)
        let mut v: Vec<f64> = (0..p.nnz()).map(|_| rng.uniform() + 0.1).collect();
        for j in 0..n {
            v[p.slot(2, j).unwrap()] =
                0.1 * v[p.slot(0, j).unwrap()] + 0.3 * v[p.slot(1, j).unwrap()];
        }
        cases.push(("linear combination", p.clone(), v));
        // free-free spring chain (rigid-body mode), banded: K·1 = 0
        let n = 50;
        let mut pairs = Vec::new();
        for i in 0..n - 1 {
            pairs.extend([(i, i), (i, i + 1), (i + 1, i), (i + 1, i + 1)]);
        }
        let p = SparsePattern::new(n, &pairs);
        let mut v = vec![0.0; p.nnz()];
        for i in 0..n - 1 {
            let k = 1.0 + 0.37 * i as f64;
            v[p.slot(i, i).unwrap()] += k;
            v[p.slot(i + 1, i + 1).unwrap()] += k;
            v[p.slot(i, i + 1).unwrap()] -= k;
            v[p.slot(i + 1, i).unwrap()] -= k;
        }
        cases.push(("free-free chain", p, v));
        // all-zero matrix
        let p = SparsePattern::new(4, &[(0, 0), (1, 1), (2, 2), (3, 3), (0, 3)]);
        let v = vec![0.0; p.nnz()];
        cases.push(("zero matrix", p, v));
        cases
    }

    #[test]
    fn linalg_singular_is_err_not_panic() {
        for (name, p, v) in singular_cases() {
            for variant in VARIANTS {
                let mut lu = SparseLu::from_symbolic(Arc::new(
                    SparseLuSymbolic::with_variant(&p, variant).unwrap(),
                ));
                let r = lu.factor(&v);
                assert!(
                    matches!(r, Err(LinalgError::Singular { pivot }) if pivot < p.n()),
                    "{name} / {variant:?}: expected Singular, got {r:?}"
                );
                assert!(!lu.is_factored());
                let mut rhs = vec![1.0; p.n()];
                assert!(matches!(
                    lu.try_solve_in_place(&mut rhs),
                    Err(LinalgError::Other(_))
                ));
                lu.solve_in_place(&mut rhs);
                assert!(rhs.iter().all(|v| v.is_nan()));
            }
            let mut b = vec![1.0; p.n()];
            let r = dense_solve(&p.to_dense(&v), p.n(), &mut b);
            assert!(
                matches!(r, Err(LinalgError::Singular { .. })),
                "{name} dense: {r:?}"
            );
        }
    }

    #[test]
    fn linalg_free_chain_reports_dof() {
        // chain grounded at node 0 except the last spring is missing: the tail node is
        // unrestrained, its DOF should be reported
        let n = 20;
        let mut pairs = Vec::new();
        for i in 0..n - 1 {
            pairs.extend([(i, i), (i, i + 1), (i + 1, i), (i + 1, i + 1)]);
        }
        let p = SparsePattern::new(n, &pairs);
        let mut v = vec![0.0; p.nnz()];
        v[p.slot(0, 0).unwrap()] += 1.0; // ground spring
        for i in 0..n - 2 {
            // springs between i and i+1, except the last pair (n-2, n-1)
            v[p.slot(i, i).unwrap()] += 1.0;
            v[p.slot(i + 1, i + 1).unwrap()] += 1.0;
            v[p.slot(i, i + 1).unwrap()] -= 1.0;
            v[p.slot(i + 1, i).unwrap()] -= 1.0;
        }
        for variant in VARIANTS {
            let mut lu = SparseLu::from_symbolic(Arc::new(
                SparseLuSymbolic::with_variant(&p, variant).unwrap(),
            ));
            let r = lu.factor(&v);
            assert!(
                matches!(r, Err(LinalgError::Singular { pivot }) if pivot == n - 1),
                "{variant:?}: {r:?}"
            );
        }
    }

    #[test]
    fn linalg_floating_subchain_reports_dof() {
        // nodes 0..10 form a grounded chain; nodes 10..15 are connected to each other only
        // (a floating body: K·1 = 0 on that block); nodes 15..20 another grounded chain.
        // No zero rows, so the probe / shifted re-solve must find the floating block.
        let n = 20;
        let mut pairs = Vec::new();
        let mut springs = Vec::new();
        for i in 0..n - 1 {
            if i != 9 && i != 14 {
                springs.push((i, i + 1, 1.0 + 0.37 * i as f64));
            }
        }
        for i in 0..n - 1 {
            pairs.extend([(i, i), (i, i + 1), (i + 1, i), (i + 1, i + 1)]);
        }
        let p = SparsePattern::new(n, &pairs);
        let mut v = vec![0.0; p.nnz()];
        for g in [0usize, 15] {
            v[p.slot(g, g).unwrap()] += 2.5; // ground springs
        }
        for &(i, j, k) in &springs {
            v[p.slot(i, i).unwrap()] += k;
            v[p.slot(j, j).unwrap()] += k;
            v[p.slot(i, j).unwrap()] -= k;
            v[p.slot(j, i).unwrap()] -= k;
        }
        for variant in VARIANTS {
            let mut lu = SparseLu::from_symbolic(Arc::new(
                SparseLuSymbolic::with_variant(&p, variant).unwrap(),
            ));
            let r = lu.factor(&v);
            assert!(
                matches!(r, Err(LinalgError::Singular { pivot }) if (10..15).contains(&pivot)),
                "{variant:?}: {r:?}"
            );
        }
    }

    /// Weighted graph Laplacian of a random connected graph (spring network, free-free):
    /// singular with null vector 1. `unsym` scales the two off-diagonal copies
    /// differently (row sums stay zero, so A·1 = 0 still).
    fn spring_network(rng: &mut Lcg, n: usize, unsym: bool) -> (SparsePattern, Vec<f64>) {
        let mut edges: Vec<(usize, usize)> = (1..n).map(|i| (rng.below(i), i)).collect();
        for _ in 0..n {
            let (a, b) = (rng.below(n), rng.below(n));
            if a != b {
                edges.push((a, b));
            }
        }
        let mut pairs: Vec<_> = (0..n).map(|i| (i, i)).collect();
        for &(a, b) in &edges {
            pairs.extend([(a, b), (b, a)]);
        }
        let p = SparsePattern::new(n, &pairs);
        let mut v = vec![0.0; p.nnz()];
        for &(a, b) in &edges {
            let w = 0.1 + 10.0 * rng.uniform();
            let w2 = if unsym { w * (0.5 + rng.uniform()) } else { w };
            v[p.slot(a, b).unwrap()] -= w;
            v[p.slot(a, a).unwrap()] += w;
            v[p.slot(b, a).unwrap()] -= w2;
            v[p.slot(b, b).unwrap()] += w2;
        }
        (p, v)
    }

    #[test]
    fn linalg_singular_vs_ill_conditioned() {
        let mut rng = Lcg(2024);
        for variant in [
            LuVariant::Supernodal,
            LuVariant::Simplicial,
            LuVariant::Dense,
        ] {
            for &n in &[3usize, 10, 60, 300] {
                for unsym in [false, true] {
                    let (p, v) = spring_network(&mut rng, n, unsym);
                    let mut lu = SparseLu::from_symbolic(Arc::new(
                        SparseLuSymbolic::with_variant(&p, variant).unwrap(),
                    ));
                    let r = lu.factor(&v);
                    assert!(
                        matches!(r, Err(LinalgError::Singular { pivot }) if pivot < n),
                        "{variant:?} n={n} unsym={unsym}: {r:?}"
                    );
                    // grounded (diagonal shift), κ ≈ 1e10: accepted and accurate to ~κε
                    let amax = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                    let mut v2 = v.clone();
                    for i in 0..n {
                        v2[p.slot(i, i).unwrap()] += 1e-10 * amax;
                    }
                    lu.factor(&v2).unwrap();
                    let x: Vec<f64> = (0..n).map(|i| (i % 3) as f64 - 1.0).collect();
                    let mut b = vec![0.0; n];
                    p.mul_vec(&v2, &x, &mut b);
                    lu.try_solve_in_place(&mut b).unwrap();
                    assert!(
                        rel_err(&b, &x) < 1e-4,
                        "{variant:?} n={n}: {}",
                        rel_err(&b, &x)
                    );
                }
            }
        }
    }

    /// A change of units scales the rows and columns of each unit group (D A D); the
    /// verdict must not change with it. Before the probe measured D A D, a 1 mm
    /// cantilever of 100 elements (translation rows ~1e17 beside rotation rows ~1e7) was
    /// refused as a mechanism.
    #[test]
    fn the_singularity_verdict_does_not_change_with_the_units() {
        let mut rng = Lcg(77);
        for variant in VARIANTS {
            for &n in &[10usize, 60, 300] {
                for unsym in [false, true] {
                    let (p, v) = spring_network(&mut rng, n, unsym);
                    // three units, scattered over the unknowns, scaled 2^-17, 1, 2^17
                    // (~1e∓5; powers of two leave every entry's mantissa as it was, so
                    // the scaled singular matrix is exactly as singular)
                    let groups: Vec<usize> = (0..n).map(|i| (i * 7) % 3).collect();
                    let d: Vec<f64> = groups
                        .iter()
                        .map(|&g| 2f64.powi(17 * (g as i32 - 1)))
                        .collect();
                    let scaled = |v: &[f64]| -> Vec<f64> {
                        let mut w = v.to_vec();
                        for j in 0..n {
                            for i in 0..n {
                                if let Some(k) = p.slot(i, j) {
                                    w[k] = v[k] * d[i] * d[j];
                                }
                            }
                        }
                        w
                    };
                    let mut lu = SparseLu::from_symbolic(Arc::new(
                        SparseLuSymbolic::with_variant(&p, variant).unwrap(),
                    ));
                    lu.set_unit_groups(&groups).unwrap();
                    let r = lu.factor(&scaled(&v));
                    assert!(
                        matches!(r, Err(LinalgError::Singular { .. })),
                        "{variant:?} n={n} unsym={unsym}: the scaled singular network: {r:?}"
                    );
                    let amax = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                    let mut v2 = v.clone();
                    for i in 0..n {
                        v2[p.slot(i, i).unwrap()] += 1e-8 * amax;
                    }
                    let a = scaled(&v2);
                    lu.factor(&a).unwrap_or_else(|e| {
                        panic!("{variant:?} n={n} unsym={unsym}: κ(DAD) ≈ 1e8 refused: {e:?}")
                    });
                    // the solution is accurate componentwise to ~κ(DAD)ε in D's units
                    let x: Vec<f64> = (0..n).map(|i| ((i % 3) as f64 - 1.5) / d[i]).collect();
                    let mut b = vec![0.0; n];
                    p.mul_vec(&a, &x, &mut b);
                    lu.try_solve_in_place(&mut b).unwrap();
                    let worst = (0..n)
                        .map(|i| ((b[i] - x[i]) * d[i]).abs())
                        .fold(0.0f64, f64::max);
                    assert!(worst < 1e-5, "{variant:?} n={n} unsym={unsym}: {worst:e}");
                    // one group (the default) is the unscaled condition, κ ≈ 1e28 here
                    lu.set_unit_groups(&vec![0; n]).unwrap();
                    assert!(
                        matches!(lu.factor(&a), Err(LinalgError::Singular { .. })),
                        "{variant:?} n={n} unsym={unsym}: one unit group accepted κ ≈ 1e28"
                    );
                }
            }
        }
    }

    #[test]
    fn linalg_non_finite_and_bad_lengths() {
        let mut rng = Lcg(11);
        let (p, _) = random_pattern(&mut rng, 30, 2);
        let good = random_dd_values(&mut rng, &p);
        for variant in VARIANTS {
            let mut lu = SparseLu::from_symbolic(Arc::new(
                SparseLuSymbolic::with_variant(&p, variant).unwrap(),
            ));
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut v = good.clone();
                v[17] = bad;
                assert!(matches!(lu.factor(&v), Err(LinalgError::NonFinite)));
                assert!(!lu.is_factored());
            }
            assert!(matches!(lu.factor(&good[1..]), Err(LinalgError::Other(_))));
            lu.factor(&good).unwrap();
            let mut rhs = vec![1.0; 30];
            rhs[3] = f64::NAN;
            assert!(matches!(
                lu.try_solve_in_place(&mut rhs),
                Err(LinalgError::NonFinite)
            ));
            assert!(
                rhs[3].is_nan() && rhs[4] == 1.0,
                "rhs must be left unchanged"
            );
            lu.solve_in_place(&mut rhs); // unchecked: NaN propagates, no panic
            assert!(rhs.iter().any(|v| v.is_nan()));
            let mut short = vec![1.0; 29];
            assert!(matches!(
                lu.try_solve_in_place(&mut short),
                Err(LinalgError::Other(_))
            ));
            // still usable after rejected inputs
            check_against_dense(&lu, &p, &good, &mut rng);
        }
        let mut b = vec![1.0, f64::NAN];
        assert!(matches!(
            dense_solve(&[1.0, 0.0, 0.0, 1.0], 2, &mut b),
            Err(LinalgError::NonFinite)
        ));
        let mut b = vec![1.0, 1.0];
        assert!(matches!(
            dense_solve(&[1.0, f64::NAN, 0.0, 1.0], 2, &mut b),
            Err(LinalgError::NonFinite)
        ));
        assert!(matches!(
            dense_solve(&[1.0; 3], 2, &mut b),
            Err(LinalgError::Other(_))
        ));
    }

    #[test]
    fn linalg_empty_matrix() {
        let p = SparsePattern::new(0, &[]);
        let mut lu = SparseLu::new(&p).unwrap();
        lu.factor(&[]).unwrap();
        lu.solve_in_place(&mut []);
        lu.try_solve_in_place(&mut []).unwrap();
        dense_solve(&[], 0, &mut []).unwrap();
        assert_eq!(generalized_sym_eig(&[], &[], 0).unwrap(), (vec![], vec![]));
        assert!(general_eig(&[], 0).unwrap().is_empty());
    }

    #[test]
    fn linalg_dense_solve_small() {
        // needs a row swap
        let a = [0.0, 2.0, 1.0, 3.0, 1.0, 0.0, 1.0, 1.0, 1.0];
        let x = [1.0, -2.0, 0.5];
        let mut b: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| a[i * 3 + j] * x[j]).sum())
            .collect();
        dense_solve(&a, 3, &mut b).unwrap();
        assert!(rel_err(&b, &x) < 1e-14);
    }

    fn mat_vec(a: &[f64], n: usize, x: &[f64]) -> Vec<f64> {
        (0..n)
            .map(|i| (0..n).map(|j| a[i * n + j] * x[j]).sum())
            .collect()
    }

    #[test]
    fn linalg_two_dof_spring_mass() {
        // ground -k1- m1 -k2- m2
        let (k1, k2, m1, m2): (f64, f64, f64, f64) = (3.0e4, 1.2e4, 2.0, 0.5);
        let k = [k1 + k2, -k2, -k2, k2];
        let m = [m1, 0.0, 0.0, m2];
        // det(K - λM) = 0: m1 m2 λ² - (m1 k2 + m2 (k1 + k2)) λ + k1 k2 = 0
        let bq = m1 * k2 + m2 * (k1 + k2);
        let disc = (bq * bq - 4.0 * m1 * m2 * k1 * k2).sqrt();
        let exact = [(bq - disc) / (2.0 * m1 * m2), (bq + disc) / (2.0 * m1 * m2)];
        let (lam, phi) = generalized_sym_eig(&k, &m, 2).unwrap();
        for i in 0..2 {
            assert!(
                (lam[i] - exact[i]).abs() <= 1e-12 * exact[i],
                "{lam:?} vs {exact:?}"
            );
        }
        // frequencies in Hz, for the record: f = sqrt(λ)/2π
        assert!(lam[0] < lam[1]);
        check_modes(&k, &m, 2, &lam, &phi);

        // equal masses and springs: λ = (k/m)(3 ∓ √5)/2
        let (kk, mm) = (100.0, 4.0);
        let (lam, phi) =
            generalized_sym_eig(&[2.0 * kk, -kk, -kk, kk], &[mm, 0.0, 0.0, mm], 2).unwrap();
        let s5 = 5.0f64.sqrt();
        assert!((lam[0] - kk / mm * (3.0 - s5) / 2.0).abs() < 1e-12 * lam[0]);
        assert!((lam[1] - kk / mm * (3.0 + s5) / 2.0).abs() < 1e-12 * lam[1]);
        // first mode in phase, second out of phase; sign convention: largest component > 0
        assert!(phi[0] > 0.0 && phi[1] > 0.0);
        assert!(phi[2] * phi[3] < 0.0);
        check_modes(
            &[2.0 * kk, -kk, -kk, kk],
            &[mm, 0.0, 0.0, mm],
            2,
            &lam,
            &phi,
        );
    }

    /// A symmetric matrix and its multiples by 2^∓60 (a beam's mass matrix in kg is
    /// 1e-8 for a 1 cm beam of 100 elements): the eigenvalues scale exactly and stay
    /// within the backward error of the matrix's own norm. 300 rows take faer's
    /// divide-and-conquer path, whose deflation tolerance was absolute below unit norm.
    #[test]
    fn symmetric_eigenvalues_do_not_depend_on_the_matrix_scale() {
        let n = 300;
        // A = Q Λ Qᵀ with Q three Householder reflections and Λ holding 40 exact zeros
        // (the massless directions) below eigenvalues spread over six decades
        let mut rng = Lcg(11);
        let lam: Vec<f64> = (0..n)
            .map(|i| {
                if i < 40 {
                    0.0
                } else {
                    10f64.powf(-6.0 * rng.uniform())
                }
            })
            .collect();
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            a[i * n + i] = lam[i];
        }
        for _ in 0..3 {
            let v: Vec<f64> = (0..n).map(|_| rng.uniform() - 0.5).collect();
            let vv: f64 = v.iter().map(|x| x * x).sum();
            // A ← H A H, H = I − 2 v vᵀ / vᵀv
            let av = mat_vec(&a, n, &v);
            let vav: f64 = v.iter().zip(&av).map(|(p, q)| p * q).sum();
            for i in 0..n {
                for j in 0..n {
                    a[i * n + j] += -2.0 * (v[i] * av[j] + av[i] * v[j]) / vv
                        + 4.0 * vav * v[i] * v[j] / (vv * vv);
                }
            }
        }
        let mut want = lam.clone();
        want.sort_by(f64::total_cmp);
        for e in [-60, 0, 60] {
            let s = 2f64.powi(e);
            let sa: Vec<f64> = a.iter().map(|x| x * s).collect();
            let (got, u) = sym_eig(&sa, n).unwrap();
            // backward stable: |Δλ| ≤ c n ε ‖A‖ (c = 4; the construction's round-off in A
            // is a few ε ‖A‖ itself)
            let worst = got
                .iter()
                .zip(&want)
                .fold(0.0f64, |m, (g, w)| m.max((g / s - w).abs()));
            assert!(
                worst <= 4.0 * n as f64 * f64::EPSILON,
                "scale 2^{e}: eigenvalues off by {worst:e} of the norm"
            );
            // the eigenvectors stay orthonormal
            let d: f64 = u[..n].iter().zip(&u[n..2 * n]).map(|(p, q)| p * q).sum();
            assert!(d.abs() < 1e-12, "scale 2^{e}: u0·u1 = {d:e}");
        }
    }

    fn check_modes(k: &[f64], m: &[f64], n: usize, lam: &[f64], phi: &[f64]) {
        let knorm = k.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for i in 0..n {
            let pi = &phi[i * n..(i + 1) * n];
            let kp = mat_vec(k, n, pi);
            let mp = mat_vec(m, n, pi);
            for r in 0..n {
                assert!((kp[r] - lam[i] * mp[r]).abs() <= 1e-10 * knorm);
            }
            for j in 0..n {
                let pj = &phi[j * n..(j + 1) * n];
                let mpj = mat_vec(m, n, pj);
                let g: f64 = pi.iter().zip(&mpj).map(|(a, b)| a * b).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((g - want).abs() < 1e-12, "φ{i}ᵀMφ{j} = {g}");
            }
        }
    }

    #[test]
    fn linalg_generalized_eig_consistent_mass_and_errors() {
        // two-element bar, consistent mass, fixed at one end: 2 DOF, full M
        let (ea_l, rho_al) = (7.0e3, 0.6);
        let k = [2.0 * ea_l, -ea_l, -ea_l, ea_l];
        let c = rho_al / 6.0;
        let m = [4.0 * c, c, c, 2.0 * c];
        let (lam, phi) = generalized_sym_eig(&k, &m, 2).unwrap();
        check_modes(&k, &m, 2, &lam, &phi);
        // compare with characteristic polynomial det(K - λM)
        let a = m[0] * m[3] - m[1] * m[2];
        let b = -(k[0] * m[3] + k[3] * m[0] - k[1] * m[2] - k[2] * m[1]);
        let cc = k[0] * k[3] - k[1] * k[2];
        let d = (b * b - 4.0 * a * cc).sqrt();
        let exact = [(-b - d) / (2.0 * a), (-b + d) / (2.0 * a)];
        assert!((lam[0] - exact[0]).abs() < 1e-12 * exact[1]);
        assert!((lam[1] - exact[1]).abs() < 1e-12 * exact[1]);

        // random 12×12: K = AᵀA - 2I (indefinite), M = BᵀB + I
        let mut rng = Lcg(3);
        let n = 12;
        let ra: Vec<f64> = (0..n * n).map(|_| rng.uniform() - 0.5).collect();
        let rb: Vec<f64> = (0..n * n).map(|_| rng.uniform() - 0.5).collect();
        let gram = |r: &[f64], shift: f64| -> Vec<f64> {
            let mut g = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    g[i * n + j] = (0..n).map(|l| r[l * n + i] * r[l * n + j]).sum::<f64>()
                        + if i == j { shift } else { 0.0 };
                }
            }
            g
        };
        let (k, m) = (gram(&ra, -2.0), gram(&rb, 1.0));
        let (lam, phi) = generalized_sym_eig(&k, &m, n).unwrap();
        assert!(lam.windows(2).all(|w| w[0] <= w[1]));
        check_modes(&k, &m, n, &lam, &phi);

        // M not positive definite
        assert!(matches!(
            generalized_sym_eig(&[1.0, 0.0, 0.0, 1.0], &[1.0, 0.0, 0.0, -1.0], 2),
            Err(LinalgError::NotPositiveDefinite)
        ));
        assert!(matches!(
            generalized_sym_eig(&[1.0, 0.0, 0.0, 1.0], &[1.0, 1.0, 1.0, 1.0], 2),
            Err(LinalgError::NotPositiveDefinite)
        ));
        assert!(matches!(
            generalized_sym_eig(&[1.0, 0.0, 0.0, f64::NAN], &[1.0, 0.0, 0.0, 1.0], 2),
            Err(LinalgError::NonFinite)
        ));
    }

    /// A nonsymmetric matrix and its similarity D A D⁻¹ with D spanning 2^±30 (what a
    /// change of units does to a first-order form: metres against micrometres) have the
    /// same eigenvalues; unbalanced, faer's error is ε·max|D A D⁻¹|, 2^60 times A's.
    #[test]
    fn general_eigenvalues_do_not_depend_on_the_units_of_the_coordinates() {
        let n = 40;
        let mut rng = Lcg(5);
        let a: Vec<f64> = (0..n * n).map(|_| rng.uniform() - 0.5).collect();
        let d: Vec<f64> = (0..n)
            .map(|_| 2f64.powi((60.0 * rng.uniform()) as i32 - 30))
            .collect();
        let scaled: Vec<f64> = (0..n * n).map(|ij| a[ij] * d[ij / n] / d[ij % n]).collect();
        let want = general_eig(&a, n).unwrap();
        let got = general_eig(&scaled, n).unwrap();
        // eigenvalues of a random matrix have condition numbers of tens: 1e-10 of ‖A‖
        // (about 3) is a hundred times their round-off
        for (g, w) in got.iter().zip(&want) {
            assert!((g.0 - w.0).hypot(g.1 - w.1) < 1e-10, "{g:?} vs {w:?}");
        }
        // balancing changes no eigenvalue of a matrix already balanced
        let mut b = a.clone();
        balance(&mut b, n);
        let again = general_eig(&b, n).unwrap();
        for (g, w) in again.iter().zip(&want) {
            assert!((g.0 - w.0).hypot(g.1 - w.1) < 1e-12, "{g:?} vs {w:?}");
        }
    }

    #[test]
    fn linalg_general_eig_rotation() {
        let w = 3.7;
        let ev = general_eig(&[0.0, -w, w, 0.0], 2).unwrap();
        assert_eq!(ev.len(), 2);
        assert!(
            ev[0].0.abs() < 1e-14 && (ev[0].1 + w).abs() < 1e-14,
            "{ev:?}"
        );
        assert!(
            ev[1].0.abs() < 1e-14 && (ev[1].1 - w).abs() < 1e-14,
            "{ev:?}"
        );

        // gyroscopic rotor, first-order form z' = A z with z = (x, y, ẋ, ẏ):
        // ẍ - g ẏ + k x = 0, ÿ + g ẋ + k y = 0  →  λ = ±i(√(k + g²/4) ± g/2)
        let (k, g) = (4.0, 1.5);
        #[rustfmt::skip]
        let a = [
            0.0, 0.0, 1.0, 0.0,
            0.0, 0.0, 0.0, 1.0,
            -k, 0.0, 0.0, g,
            0.0, -k, -g, 0.0,
        ];
        let ev = general_eig(&a, 4).unwrap();
        let r = (k + g * g / 4.0).sqrt();
        let (w1, w2) = (r - g / 2.0, r + g / 2.0);
        let want = [(0.0, -w1), (0.0, w1), (0.0, -w2), (0.0, w2)];
        for (got, want) in ev.iter().zip(&want) {
            assert!(
                (got.0 - want.0).abs() < 1e-12 && (got.1 - want.1).abs() < 1e-12,
                "{ev:?}"
            );
        }

        // real spectrum: upper triangular
        let ev = general_eig(&[2.0, 5.0, 0.0, -1.0], 2).unwrap();
        assert_eq!(ev, vec![(-1.0, 0.0), (2.0, 0.0)]);
    }
}
