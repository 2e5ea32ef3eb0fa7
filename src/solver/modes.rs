//! Linearised free vibration about a state (the reference, or the static equilibrium
//! under the model's loads): K φ = ω² M φ with K the full tangent (material and
//! geometric stiffness, so preloads stiffen or soften) and M the consistent mass.
//!
//! Method (see [`solve_pencil`]):
//! 1. The null space of M is found from M's symmetric eigendecomposition, not from its
//!    diagonal: a section without rotary inertia has no mass in the twist about its own
//!    axis, and when that axis is not a global axis (a curved beam, or a preloaded,
//!    slightly rotated one) the massless direction is a combination of coordinates each
//!    of which has diagonal mass.
//! 2. In M's eigenbasis the massless subspace is condensed statically (Guyan, exact for
//!    massless coordinates), with a pseudo-inverse where the massless block of K is
//!    singular: a motion with neither mass nor stiffness (the rigid twist of a free beam
//!    without rotary inertia) is not a vibration mode and is left out.
//! 3. The reduced problem (diagonal mass) gives first estimates; the lowest modes are then
//!    refined by shift-invert subspace iteration in the original coordinates with a dense
//!    partial-pivoting LU of K − σM, which keeps the accuracy of graded matrices (an axial
//!    stiffness 1e16 times the bending one) that the similarity transforms of step 1-2
//!    lose, and which is exact for massless coordinates by construction ((K − σM)⁻¹M
//!    maps into the statically condensed subspace).
//! 4. Each mode gets an a-posteriori error estimate of ω²: iteration residual + backward
//!    error of the LU + round-off of the assembled K and M, to first order. A mode whose
//!    ω² is within its own error estimate of 0 is a zero-frequency (rigid-body or
//!    mechanism) mode, reported as 0 Hz and flagged; a frequency whose estimated relative
//!    error exceeds [`WARN_RELATIVE_ERROR`] gets a warning.

use crate::assembly::{Assembler, Coeffs, DenseSink};
use crate::joint::{self, State};
use crate::linalg::{jacobi_scale, pow2_exponent, pow2_near, sym_eig, DenseLu, LinalgError};
use crate::model::Model;

#[derive(Debug, thiserror::Error)]
pub enum ModesError {
    #[error("the model has no free coordinates (every node is held): there is nothing to vibrate")]
    NoFreeDofs,
    #[error(
        "the model has no mass (its mass matrix is zero): natural frequencies are undefined; \
         give the sections a `rhoA` or the bodies a mass"
    )]
    NoMass,
    #[error("the mass matrix is not positive semi-definite (eigenvalue {0:.3e})")]
    IndefiniteMass(f64),
    #[error("linear algebra: {0}")]
    Linalg(#[from] LinalgError),
    #[error("{0}")]
    TooLarge(String),
    #[error("{0}")]
    OutOfRange(String),
}

/// n×n matrices [`lowest_modes`] holds at its peak, rounded up: K and M, their symmetrised
/// copies, the eigenvectors of M, the transformed K, the LU of K − σM and its scratch.
pub const DENSE_MATRICES: f64 = 8.0;
/// n×n matrices the rotating-frame analysis holds at its peak, rounded up: K, C, M and the
/// steady-state metric; the condensed copies and M⁻¹K, M⁻¹C; the 2n×2n first-order form
/// (4) and the eigen-solver's copy of it (4).
pub const DENSE_MATRICES_ROTATING: f64 = 16.0;

/// Refuses, before anything of that size is allocated, a dense modal analysis of `n`
/// coordinates whose matrices would exceed the `LATDYN_LIMITS` key `dense_bytes` (see
/// [`crate::model::limits`]; an unreadable `LATDYN_LIMITS` is refused too); the message
/// names the size, the limit, the key that raises it and what else to do.
pub fn check_dense_size(n: usize, rotating: bool) -> Result<(), String> {
    let limit = crate::model::Limits::from_env()?.dense_bytes;
    check_dense_size_within(n, rotating, limit)
}

/// [`check_dense_size`] against a limit of `limit` bytes.
///
/// The memory is estimated as [`DENSE_MATRICES`] or [`DENSE_MATRICES_ROTATING`] n×n f64
/// matrices (their peak). The solvers are dense: memory grows as n² and time as n³ (3564
/// coordinates, the 18-bay Mini-Mast, take about 8 minutes), so beyond the limit the run
/// would either abort on a failed allocation or not finish. At the default 2 GiB: 5792
/// coordinates at rest or preloaded, 4096 in the rotating frame.
pub fn check_dense_size_within(n: usize, rotating: bool, limit: u64) -> Result<(), String> {
    let mats = if rotating {
        DENSE_MATRICES_ROTATING
    } else {
        DENSE_MATRICES
    };
    let bytes = mats * 8.0 * (n as f64) * (n as f64);
    if bytes <= limit as f64 {
        return Ok(());
    }
    let n_max = (limit as f64 / (mats * 8.0)).sqrt().floor();
    let kind = if rotating {
        "rotating-frame modal analysis (first-order form 2n×2n)"
    } else {
        "modal analysis"
    };
    let over = crate::model::limits::exceeded(
        &format!(
            "{n} free coordinates need {mats} dense {n}×{n} matrices, about {}; in bytes",
            approx_bytes(bytes)
        ),
        bytes,
        "dense_bytes",
        limit,
    );
    Err(format!(
        "model too large for the dense {kind}: {over}; that limit ({}) allows {} free \
         coordinates. Or, better, use fewer elements (e.g. a smaller `--set elements=...`): \
         the lowest modes converge long before that size",
        approx_bytes(limit as f64),
        n_max as u64
    ))
}

/// A size in bytes for messages, in kB, MB or GB.
fn approx_bytes(b: f64) -> String {
    if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.1} MB", b / 1e6)
    } else {
        format!("{:.1} kB", b / 1e3)
    }
}

#[derive(Debug, Clone)]
pub struct Modes {
    /// natural frequencies [Hz], ascending; a negative value means an unstable
    /// (negative-stiffness) mode of that |frequency|; zero-frequency modes are exactly 0
    pub frequencies_hz: Vec<f64>,
    /// mode shapes by equation index (column k = mode k), mass-normalised
    pub shapes: Vec<Vec<f64>>,
    /// per mode: estimated bound on the relative error of the frequency (half that of ω²);
    /// for a zero-frequency mode, the bound on |ω| in Hz instead
    pub error_estimates: Vec<f64>,
    /// per mode: ω² is zero within its error estimate (a rigid-body or mechanism motion)
    pub zero_frequency: Vec<bool>,
    /// frequencies that may be inaccurate, with the reason
    pub warnings: Vec<String>,
}

/// Modes computed by [`modes`].
pub const DEFAULT_COUNT: usize = 10;
/// Estimated relative frequency error above which a mode gets a warning.
pub const WARN_RELATIVE_ERROR: f64 = 1e-6;
/// Eigenvalues of M at or below this fraction of its largest are massless directions. The
/// computed eigenvalues of the assembled M carry absolute errors of a few n·ε·max μ
/// (the floor below is 64 n ε); a genuine mass this small relative to the largest
/// (a radius of gyration 1e-6 of an element length) would only add a direction whose
/// frequency is 1e6 times that of the same stiffness at full mass, and condensing it
/// changes the low modes by O(1e-12).
pub const MASS_NULL_REL: f64 = 1e-12;
/// Eigenvalues of the massless block of K at or below this fraction of its largest are
/// motions with neither mass nor stiffness (left out). The massless directions are
/// rotations of beams without rotary inertia, whose stiffnesses (GJ/h, EI/h) differ by
/// far less than 1e10 in any real section.
pub const STIFF_NULL_REL: f64 = 1e-10;
/// A mode is zero-frequency when |ω²| is within its error estimate and that estimate is
/// below this fraction of the largest ω² of the refined subspace (rigid-body modes of a
/// free beam: estimates ~1e-12 of it); a larger estimate means the mode is unresolved.
/// (Not max|K|/max eig(M) as the scale: on a graded model that is the axial stiffness,
/// and an unresolved bending mode would pass as a zero-frequency one.)
pub const ZERO_SCALE_REL: f64 = 1e-6;
/// Round-off of the assembled K and M as a share of each entry (the Rayleigh quotient's
/// own sums are carried in twice the precision, `dot2`): 8 ε per entry (a sum of
/// element contributions a few operations deep) times a confidence of 8. The
/// eigenvalue's error is the sum Σ δᵢⱼ Kᵢⱼ φᵢ φⱼ over the entries' errors δᵢⱼ; taken as
/// independent with zero mean and
/// |δᵢⱼ| ≤ 8 ε, it exceeds 8 × 8 ε √Σ (Kᵢⱼ φᵢ φⱼ)² with probability below 2e^(−32)
/// (Hoeffding; the probabilistic rounding analysis of Higham and Mary, SIAM J. Sci.
/// Comput. 41, 2019). The worst case, the same share of Σ |Kᵢⱼ φᵢ φⱼ|, is kept for
/// deciding whether ω² is zero, where only a bound will do.
pub const DATA_ROUNDOFF: f64 = 64.0 * f64::EPSILON;

/// Dense K (tangent at load factor 1) and M at state `s`, row-major n_eq × n_eq.
pub fn matrices(model: &Model, s: &State) -> (Vec<f64>, Vec<f64>) {
    let asm = Assembler::new(model);
    let n = model.n_eq;
    let mut gen = vec![0.0; model.dofs.len()];
    let mut k = vec![0.0; n * n];
    let mut m = vec![0.0; n * n];
    let mut s0 = s.clone();
    joint::update_kinematics(model, &mut s0);
    // stiffness: static forces only (no inertia), so the geometric terms see the preload
    asm.evaluate(
        model,
        &s0,
        Coeffs::statics(1.0),
        &mut gen,
        Some(&mut DenseSink { n, a: &mut k }),
    );
    let mut sm = s0.clone();
    sm.v.iter_mut().for_each(|x| *x = 0.0);
    sm.a.iter_mut().for_each(|x| *x = 0.0);
    asm.evaluate(
        model,
        &sm,
        Coeffs::dynamic(0.0, 0.0, 1.0),
        &mut gen,
        Some(&mut DenseSink { n, a: &mut m }),
    );
    (k, m)
}

/// Natural frequencies and the lowest [`DEFAULT_COUNT`] mode shapes about state `s`.
pub fn modes(model: &Model, s: &State) -> Result<Modes, ModesError> {
    lowest_modes(model, s, DEFAULT_COUNT)
}

/// The lowest `count` modes about state `s` (fewer if the model has fewer massive
/// directions).
pub fn lowest_modes(model: &Model, s: &State, count: usize) -> Result<Modes, ModesError> {
    check_dense_size(model.n_eq, false).map_err(ModesError::TooLarge)?;
    let (k, m) = matrices(model, s);
    solve_pencil(&k, &m, model.n_eq, count)
}

fn symmetrised(a: &[f64], n: usize) -> Vec<f64> {
    let mut o = a.to_vec();
    for i in 0..n {
        for j in 0..i {
            let v = 0.5 * (a[i * n + j] + a[j * n + i]);
            o[i * n + j] = v;
            o[j * n + i] = v;
        }
    }
    o
}

fn matvec(a: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
    for i in 0..n {
        y[i] = a[i * n..(i + 1) * n]
            .iter()
            .zip(x)
            .map(|(p, q)| p * q)
            .sum();
    }
}

/// (|x|ᵀ |A| |x|, √Σᵢⱼ (Aᵢⱼ xᵢ xⱼ)²): the worst-case and the probabilistic size of a
/// quadratic form's round-off, per unit relative error of the entries
fn form_sizes(a: &[f64], n: usize, x: &[f64]) -> (f64, f64) {
    let terms = || {
        (0..n).flat_map(move |i| {
            a[i * n..(i + 1) * n]
                .iter()
                .zip(x)
                .map(move |(p, q)| p * q * x[i])
        })
    };
    let sum: f64 = terms().map(f64::abs).sum();
    if sum == 0.0 || !sum.is_finite() {
        return (sum, sum);
    }
    // squares of terms taken relative to their sum, which cannot overflow where the
    // terms themselves do not (K of 1e200 N·m²)
    let sq: f64 = terms().map(|t| (t / sum) * (t / sum)).sum();
    (sum, sum * sq.sqrt())
}

/// a·b with the error of every product and sum carried in a second word (Ogita, Rump and
/// Oishi's Dot2, SIAM J. Sci. Comput. 26, 2005): as accurate as if computed in twice
/// the precision, then rounded. A smooth mode's K φ is a sum of terms 1e8-1e10 times
/// larger than itself (12EI/h³ against ω²ρAh), and its round-off, ε times those terms,
/// moved a 300-element cantilever's Rayleigh quotient by 6e-8 from one refined shape to
/// another within 1e-9 of it.
fn dot2(a: &[f64], b: &[f64]) -> f64 {
    let (mut s, mut c) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(b) {
        let p = x * y;
        let pe = x.mul_add(*y, -p);
        let t = s + p;
        let z = t - s;
        c += (s - (t - z)) + (p - z) + pe;
        s = t;
    }
    s + c
}

fn matvec2(a: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
    for i in 0..n {
        y[i] = dot2(&a[i * n..(i + 1) * n], x);
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(p, q)| p * q).sum()
}

/// M-orthonormalises the columns of `y` (n × p, column-major) by modified Gram-Schmidt,
/// twice; columns that vanish (dependent) are dropped. Returns (X, M X).
fn m_orthonormal(m: &[f64], n: usize, y: &[Vec<f64>]) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let mut xs: Vec<Vec<f64>> = Vec::new();
    let mut mxs: Vec<Vec<f64>> = Vec::new();
    let mut mv = vec![0.0; n];
    for col in y {
        let mut v = col.clone();
        matvec(m, n, &v, &mut mv);
        let norm0 = dot(&v, &mv).max(0.0).sqrt();
        for _ in 0..2 {
            for (x, mx) in xs.iter().zip(&mxs) {
                let c = dot(mx, &v);
                v.iter_mut().zip(x).for_each(|(a, b)| *a -= c * b);
            }
        }
        matvec(m, n, &v, &mut mv);
        let norm = dot(&v, &mv).max(0.0).sqrt();
        if norm.is_nan() || norm <= 1e-10 * norm0 || !norm.is_finite() {
            continue;
        }
        v.iter_mut().for_each(|a| *a /= norm);
        mv.iter_mut().for_each(|a| *a /= norm);
        xs.push(v);
        mxs.push(mv.clone());
    }
    (xs, mxs)
}

/// The LU of K − σM in consistent units: D A D with D a power of two near 1/√|Aᵢᵢ| per
/// coordinate (Jacobi scaling, near-optimal for a positive definite A, as K − σM is
/// with σ below the lowest ω²; van der Sluis, Numer. Math. 14, 1969). In metres and
/// radians a beam's translation rows are 3/h² times its rotation rows, 1e14 for a
/// 0.1 µm element, and pivoting on the unscaled matrix left a 10 µm cantilever's
/// residual at 1e-6. Powers of two change no mantissa.
struct ScaledLu {
    lu: DenseLu,
    d: Vec<f64>,
}

impl ScaledLu {
    fn new(mut a: Vec<f64>, n: usize) -> Result<Self, LinalgError> {
        let d = jacobi_scale(&mut a, n, |q| pow2_near(1.0 / q.sqrt()));
        Ok(ScaledLu {
            lu: DenseLu::new(&a, n)?,
            d,
        })
    }

    /// b ← (K − σM)⁻¹ b
    fn solve(&self, b: &mut [f64]) -> Result<(), LinalgError> {
        b.iter_mut().zip(&self.d).for_each(|(x, d)| *x *= d);
        self.lu.solve(b)?;
        b.iter_mut().zip(&self.d).for_each(|(x, d)| *x *= d);
        Ok(())
    }
}

/// A Ritz pair of the shift-invert operator A = (K − σM)⁻¹M: (θ, z, ‖A z − θ z‖_M, A z).
type Ritz = (f64, Vec<f64>, f64, Vec<f64>);

/// Lowest `count` eigenpairs of K φ = ω² M φ for row-major n×n K (symmetric up to
/// round-off) and M (symmetric positive semi-definite).
pub fn solve_pencil(k: &[f64], m: &[f64], n: usize, count: usize) -> Result<Modes, ModesError> {
    if n == 0 {
        return Err(ModesError::NoFreeDofs);
    }
    if k.len() != n * n || m.len() != n * n {
        return Err(LinalgError::Other(format!("K and M must be {n}×{n}")).into());
    }
    if !k.iter().chain(m).all(|v| v.is_finite()) {
        return Err(LinalgError::NonFinite.into());
    }
    // K and M to unit size by powers of two (exact), the eigenvalues and shapes scaled
    // back at the end: the condensation and the refinement form products of entries
    // (g gᵀ/κ, Σ K φ φ) that left the range of double precision on a beam of EI = 1e200
    // or ρA = 1e-200, which was refused as "non-finite value in input"
    let (k_size, m_size) = (super::linear::norm_inf(k), super::linear::norm_inf(m));
    let k_unit = 2f64.powi(-pow2_exponent(k_size));
    // an even power, so that the shapes' factor √m_unit is exact too
    let m_half = 2f64.powi(-pow2_exponent(m_size) / 2);
    let m_unit = m_half * m_half;
    let mut k = symmetrised(k, n);
    let mut m = symmetrised(m, n);
    k.iter_mut().for_each(|x| *x *= k_unit);
    m.iter_mut().for_each(|x| *x *= m_unit);
    // λ = λ' m_unit / k_unit, in that order: the ratio alone may overflow where λ does not
    let unscale = |x: f64| x * m_unit / k_unit;

    // 1. massless directions: the null space of M
    let (mu, v) = sym_eig(&m, n)?;
    let mu_max = mu.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    if mu_max == 0.0 {
        return Err(ModesError::NoMass);
    }
    let tol_m = MASS_NULL_REL.max(64.0 * n as f64 * f64::EPSILON) * mu_max;
    if let Some(&bad) = mu.iter().find(|&&x| x < -tol_m) {
        return Err(ModesError::IndefiniteMass(bad / m_unit));
    }
    let rr: Vec<usize> = (0..n).filter(|&j| mu[j] > tol_m).collect();
    let zz: Vec<usize> = (0..n).filter(|&j| mu[j] <= tol_m).collect();
    let (nr, nz) = (rr.len(), zz.len());
    let vcol = |j: usize| &v[j * n..(j + 1) * n];

    // 2. K in M's eigenbasis, massless block condensed with a pseudo-inverse
    let mut kv = vec![vec![0.0; n]; n];
    for (j, c) in kv.iter_mut().enumerate() {
        matvec(&k, n, vcol(j), c);
    }
    let kt = |a: usize, b: usize| dot(vcol(a), &kv[b]);
    let mut krr = vec![0.0; nr * nr];
    for (i, &a) in rr.iter().enumerate() {
        for (j, &b) in rr.iter().enumerate() {
            krr[i * nr + j] = kt(a, b);
        }
    }
    // free motions with neither mass nor stiffness, in the original coordinates
    let mut null_free: Vec<Vec<f64>> = Vec::new();
    let mut kzz_max = 0.0f64;
    if nz > 0 {
        let mut kzz = vec![0.0; nz * nz];
        for (i, &a) in zz.iter().enumerate() {
            for (j, &b) in zz.iter().enumerate() {
                kzz[i * nz + j] = kt(a, b);
            }
        }
        let (kap, w) = sym_eig(&kzz, nz)?;
        kzz_max = kap.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        let tol_k = STIFF_NULL_REL * kzz_max;
        // krz[i][c] = (Vrᵀ K Vz)(i, c)
        let krz: Vec<Vec<f64>> = rr
            .iter()
            .map(|&a| zz.iter().map(|&b| kt(a, b)).collect())
            .collect();
        for (c, &kc) in kap.iter().enumerate() {
            let wc = &w[c * nz..(c + 1) * nz];
            if kc.abs() <= tol_k {
                let mut z = vec![0.0; n];
                for (r, &b) in zz.iter().enumerate() {
                    z.iter_mut().zip(vcol(b)).for_each(|(a, q)| *a += wc[r] * q);
                }
                null_free.push(z);
                continue;
            }
            // Krr −= (Krz w)(Krz w)ᵀ / κ
            let g: Vec<f64> = krz.iter().map(|row| dot(row, wc)).collect();
            for i in 0..nr {
                for j in 0..nr {
                    krr[i * nr + j] -= g[i] * g[j] / kc;
                }
            }
        }
    }
    let krr = symmetrised(&krr, nr);
    let mut c = vec![0.0; nr * nr];
    for i in 0..nr {
        for j in 0..nr {
            c[i * nr + j] = krr[i * nr + j] / (mu[rr[i]] * mu[rr[j]]).sqrt();
        }
    }
    let (lam0, u0) = sym_eig(&c, nr)?;
    let count = count.min(nr);
    if count == 0 {
        return Ok(Modes {
            frequencies_hz: Vec::new(),
            shapes: Vec::new(),
            error_estimates: Vec::new(),
            zero_frequency: Vec::new(),
            warnings: Vec::new(),
        });
    }
    let p = nr.min((count + 8).max(2 * count));
    // first estimates of the shapes: the massive part only; the refinement's first solve
    // supplies the massless part (M kills it)
    let start: Vec<Vec<f64>> = (0..p)
        .map(|c| {
            let mut x = vec![0.0; n];
            for (i, &a) in rr.iter().enumerate() {
                let q = u0[c * nr + i] / mu[a].sqrt();
                x.iter_mut().zip(vcol(a)).for_each(|(s, t)| *s += q * t);
            }
            x
        })
        .collect();

    // 3. shift-invert subspace iteration in the original coordinates
    let kdiag_max = (0..n).fold(0.0f64, |a, i| a.max(k[i * n + i].abs()));
    let rho = if kzz_max > 0.0 {
        kzz_max
    } else {
        kdiag_max.max(1.0)
    };
    let mut kp = k.clone();
    for z in &null_free {
        for i in 0..n {
            for j in 0..n {
                kp[i * n + j] += rho * z[i] * z[j];
            }
        }
    }
    // the shift's scale is the lowest modes', not the whole subspace's: with p near nr
    // the subspace reaches the axial and torsion modes (1e10 times the lowest ω² and
    // more), and a shift that far below puts every low 1/(λ − σ) within round-off of
    // the others (a cantilever's `--count 70` of 160 read a 0 Hz mode and 0.3 % off);
    // the higher wanted modes converge as fast with the shift near the bottom
    let spread = lam0[..count.min(10)]
        .iter()
        .fold(0.0f64, |a, &b| a.max(b.abs()));
    let spread = if spread > 0.0 { spread } else { 1.0 };
    let mut sigma = lam0[0].min(0.0) - 0.05 * spread;
    let mut lu = None;
    for _ in 0..6 {
        let a: Vec<f64> = kp.iter().zip(&m).map(|(x, y)| x - sigma * y).collect();
        match ScaledLu::new(a, n) {
            Ok(f) => {
                lu = Some(f);
                break;
            }
            Err(_) => sigma -= spread,
        }
    }
    let lu = lu.ok_or(LinalgError::Singular { pivot: 0 })?;
    let (mut x, mut mx) = m_orthonormal(&m, n, &start);
    let mut ritz: Vec<Ritz> = Vec::new();
    let mut prev_worst = f64::INFINITY;
    // the iterate with the smallest worst residual: past the round-off floor of a wide
    // subspace (its top modes' residuals stay near 1e-6) further sweeps only stir the
    // low modes (a cantilever's `--count 70` drifted 2.7e-4 off in 100 of them)
    let mut best: Option<(f64, Vec<Ritz>)> = None;
    let mut since_best = 0;
    for it in 0..100 {
        // Y = (K − σM)⁻¹ M X
        let mut y = mx.clone();
        for col in y.iter_mut() {
            lu.solve(col)?;
        }
        let q = x.len();
        let mut h = vec![0.0; q * q];
        for i in 0..q {
            for j in 0..q {
                h[i * q + j] = dot(&mx[i], &y[j]);
            }
        }
        let (th, uh) = sym_eig(&h, q)?;
        // largest θ = 1/(λ − σ) first: σ lies below the wanted eigenvalues
        ritz.clear();
        let mut worst = 0.0f64;
        for c in (0..q).rev() {
            let uc = &uh[c * q..(c + 1) * q];
            let mut z = vec![0.0; n];
            let mut az = vec![0.0; n];
            for j in 0..q {
                z.iter_mut().zip(&x[j]).for_each(|(a, b)| *a += uc[j] * b);
                az.iter_mut().zip(&y[j]).for_each(|(a, b)| *a += uc[j] * b);
            }
            let s: Vec<f64> = az.iter().zip(&z).map(|(a, b)| a - th[c] * b).collect();
            let mut ms = vec![0.0; n];
            matvec(&m, n, &s, &mut ms);
            let snorm = dot(&s, &ms).max(0.0).sqrt();
            if ritz.len() < count {
                worst = worst.max(snorm / th[c].abs());
            }
            ritz.push((th[c], z, snorm, az));
        }
        // the start holds the massive part of the shapes only, and the M-norm residual
        // cannot see what it lacks (a bent cantilever's start read 1e-14 there and its
        // Rayleigh quotients 5.9e5 for −1.8e4): only shapes that went through the
        // operator, which supplies the massless part, can be kept or end the sweeps
        if it > 0 {
            if best.as_ref().is_none_or(|b| worst < b.0) {
                best = Some((worst, ritz.clone()));
                since_best = 0;
            } else {
                since_best += 1;
            }
        }
        // converged to round-off, no longer improving after the start, or stagnant
        if (it > 0 && worst <= 1e-14)
            || (it > 5 && worst > 0.5 * prev_worst && worst < 1e-10)
            || since_best >= 5
        {
            break;
        }
        prev_worst = worst;
        // next subspace: the Ritz vectors pushed through the operator (A z, ordered)
        let ny: Vec<Vec<f64>> = ritz.iter().map(|r| r.3.clone()).collect();
        (x, mx) = m_orthonormal(&m, n, &ny);
        if x.is_empty() {
            return Err(LinalgError::Other("mode refinement lost its subspace".into()).into());
        }
    }

    if let Some((_, b)) = best {
        ritz = b;
    }

    // 4. eigenvalues, error estimates, classification. Each eigenvalue is the Rayleigh
    // quotient of the pencil itself at its Ritz vector, bounded through the explicit
    // residual r = K z − λ M z: with e = (K − σM)⁻¹ r, the operator (K − σM)⁻¹M has the
    // residual −e/(λ − σ) at z, so λ is within |λ − σ|·‖e‖_M of an eigenvalue. The
    // value σ + 1/θ and its residual through the factors carried the factors' round-off
    // (γ_n |L||U|, a bound 20 times the true error: a 100-element cantilever's first
    // mode was warned at 2.9e-5 as ill-conditioned); the solve's round-off only
    // perturbs e, a correction already small.
    let mut out: Vec<(f64, Vec<f64>, f64, f64)> = Vec::new();
    let (mut kz, mut mz) = (vec![0.0; n], vec![0.0; n]);
    for (_, z, _, _) in ritz.iter().filter(|r| r.0 != 0.0) {
        matvec2(&kp, n, z, &mut kz);
        matvec2(&m, n, z, &mut mz);
        let zmz = dot2(z, &mz);
        let lam = dot2(z, &kz) / zmz;
        if !lam.is_finite() {
            continue;
        }
        let mut e: Vec<f64> = kz.iter().zip(&mz).map(|(a, b)| a - lam * b).collect();
        lu.solve(&mut e)?;
        matvec(&m, n, &e, &mut mz);
        let resid = (lam - sigma).abs() * (dot(&e, &mz).max(0.0) / zmz).sqrt();
        let ((k_sum, k_sq), (m_sum, m_sq)) = (form_sizes(&k, n, z), form_sizes(&m, n, z));
        let floor = resid + 4.0 * f64::EPSILON * (sigma.abs() + lam.abs());
        let worst = floor + DATA_ROUNDOFF * (k_sum + lam.abs() * m_sum) / zmz;
        let likely = floor + DATA_ROUNDOFF * k_sq.hypot(lam * m_sq) / zmz;
        let shape = z.iter().map(|x| x * m_half).collect();
        out.push((unscale(lam), shape, unscale(worst), unscale(likely)));
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    let sizes = || format!("stiffness entries up to {k_size:.1e}, mass entries up to {m_size:.1e}");
    if out.iter().take(count).any(|r| !r.0.is_finite()) {
        return Err(ModesError::OutOfRange(format!(
            "the model's ω² (stiffness over mass) leave the range of double precision \
             ({}): choose units nearer the model's size",
            sizes()
        )));
    }
    if out.iter().take(count).any(|r| !r.2.is_finite()) {
        return Err(ModesError::OutOfRange(format!(
            "the modes cannot be resolved in double precision: their round-off estimate \
             overflows ({}), as when the stiffnesses span too many orders of \
             magnitude (e.g. EI far above EA L²)",
            sizes()
        )));
    }
    // (the refined subspace's top, past the wanted modes, may overflow: left out)
    out.retain(|r| r.0.is_finite() && r.2.is_finite() && r.3.is_finite());
    let two_pi = 2.0 * std::f64::consts::PI;
    let mut res = Modes {
        frequencies_hz: Vec::new(),
        shapes: Vec::new(),
        error_estimates: Vec::new(),
        zero_frequency: Vec::new(),
        warnings: Vec::new(),
    };
    // the largest eigenvalue of the refined subspace sets the scale: an ω² within its
    // error of 0 is a zero-frequency mode only if that error is itself negligible on
    // this scale; otherwise the mode is unresolved (warned, frequency as computed)
    // (and K = 0 altogether: every mode is a free motion)
    let lam_scale = out.iter().fold(0.0f64, |a, r| a.max(r.0.abs()));
    out.truncate(count);
    for (idx, (lam, mut z, worst, likely)) in out.into_iter().enumerate() {
        let zero = k_size == 0.0 || (lam.abs() <= worst && worst <= ZERO_SCALE_REL * lam_scale);
        // an ω² farther from zero than its worst-case round-off is a vibration, and its
        // likely error is the one to report; one within it (but unresolved) keeps the bound
        let err = if lam.abs() > worst { likely } else { worst };
        let f = if zero {
            0.0
        } else {
            lam.signum() * lam.abs().sqrt() / two_pi
        };
        let rel = if zero {
            err.sqrt() / two_pi
        } else {
            0.5 * err / lam.abs().max(f64::MIN_POSITIVE)
        };
        if !zero && rel > WARN_RELATIVE_ERROR {
            res.warnings.push(format!(
                "mode {} ({f:.6} Hz): estimated relative error {rel:.1e} (ill-conditioned: \
                 the stiffness spans too many orders of magnitude for double precision, \
                 e.g. a very large EA)",
                idx + 1
            ));
        }
        if !zero && f < 0.0 {
            res.warnings.push(format!(
                "mode {} ({f:.6} Hz): negative stiffness (ω² < 0, reported as −|f|), no \
                 vibration: the state the modes are about is not stable in this mode (its \
                 linearised motion grows at {:.6} 1/s), or a load that is not conservative \
                 (a fixed-direction moment on large rotations) makes the symmetric \
                 analysis inexact there",
                idx + 1,
                -f * two_pi
            ));
        }
        let big = z
            .iter()
            .fold(0.0f64, |a, &b| if b.abs() > a.abs() { b } else { a });
        if big < 0.0 {
            z.iter_mut().for_each(|a| *a = -*a);
        }
        res.frequencies_hz.push(f);
        res.shapes.push(z);
        res.error_estimates.push(rel);
        res.zero_frequency.push(zero);
    }
    Ok(res)
}

/// The order of a frequency's mesh error, for its Richardson estimate: 4 for a bending
/// mode (cubic interpolation; the shipped cantilever's third bending frequency on 4 … 64
/// elements: differences falling by 6.7, 14.6, 15.6), 2 for every other (axial and
/// torsion are interpolated linearly: its torsion mode, 251.61, 250.40, 250.10, 250.025,
/// 250.006 Hz, differences falling by 4.0). A mode is a bending one when at least
/// [`BENDING_DOMINANT`] of its strain energy is bending ([`bending_share`]); a mixed mode
/// takes order 2, which overstates a bending-dominated error by at most 1.25× (4/3
/// against 16/15) and never understates an axial or torsional one.
pub fn mesh_order(bending_share: Option<f64>) -> i32 {
    match bending_share {
        Some(b) if b >= BENDING_DOMINANT => 4,
        _ => 2,
    }
}

/// Bending share of the strain energy from which a mode's mesh error is taken to
/// converge at order 4 ([`mesh_order`]): a torsion or axial part of 1 % of the energy
/// whose own error is at most (2⁴ − 1)/(2² − 1) = 5 times the bending part's moves the
/// estimate by at most 5 %.
pub const BENDING_DOMINANT: f64 = 0.99;

/// Per mode, the estimated relative mesh error of each of the ascending frequencies
/// `coarse` from those of the same model with every beam's elements doubled (`fine`),
/// by Richardson's rule: |f_n − f_2n| / (1 − 2⁻ᵖ) / |f_2n| with p = `order(k)`
/// ([`mesh_order`]). Modes are compared by their place in the order, not by shape: the
/// k-th frequency reported is what is read, and on a coarse mesh a mode that is far too
/// stiff passes others (the 2-element cantilever's 4th bending pair, +80 %, comes after
/// its torsion mode). None where `order(k)` is None (a zero-frequency mode: a rigid-body
/// or mechanism motion whose 0 Hz no mesh changes) or `fine` has no k-th frequency.
pub fn mesh_error_by_mode(
    coarse: &[f64],
    fine: &[f64],
    order: impl Fn(usize) -> Option<i32>,
) -> Vec<Option<f64>> {
    coarse
        .iter()
        .enumerate()
        .map(|(k, &fc)| {
            let ff = *fine.get(k)?;
            let p = order(k)?;
            if ff == 0.0 || !ff.is_finite() || !fc.is_finite() {
                return None;
            }
            Some((fc - ff).abs() / (1.0 - 0.5f64.powi(p)) / ff.abs())
        })
        .collect()
}

/// Modes named one by one in the mesh warning ([`mesh_warning`]); the rest are counted.
pub const MESH_WARNING_NAMED: usize = 6;

/// The first [`MESH_WARNING_NAMED`] of `items` joined by commas, and how many are left
/// out (a mesh warning names a few and counts the rest).
pub fn first_named(items: &[String]) -> (String, usize) {
    let shown = MESH_WARNING_NAMED.min(items.len());
    (items[..shown].join(", "), items.len() - shown)
}

/// The warning naming the modes whose estimated mesh error ([`mesh_error_by_mode`]) is
/// above [`crate::solver::MESH_ERROR_WARN`], or None; `elements` = (base, refined)
/// element count, `what` a prefix for the modes ("" or "at omega=3: ").
pub fn mesh_warning(
    frequencies_hz: &[f64],
    estimates: &[Option<f64>],
    elements: (usize, usize),
    what: &str,
) -> Option<String> {
    let limit = crate::solver::MESH_ERROR_WARN;
    let over: Vec<String> = estimates
        .iter()
        .enumerate()
        .filter_map(|(k, e)| {
            let e = (*e)?;
            (e > limit).then(|| {
                format!(
                    "{} ({:.6} Hz, {:.2} %)",
                    k + 1,
                    frequencies_hz[k],
                    100.0 * e
                )
            })
        })
        .collect();
    // the first few by name, the rest counted with their largest (`mesh_error_estimates`
    // holds them all): 160 modes of a 32-element cantilever made a 4 kB line
    let worst = estimates
        .iter()
        .flatten()
        .fold(0.0f64, |a, &e| if e > limit { a.max(e) } else { a });
    let (mut list, more) = first_named(&over);
    if more > 0 {
        list += &format!(" and {more} more (the largest {:.2} %)", 100.0 * worst);
    }
    (!over.is_empty()).then(|| {
        format!(
            "{what}mesh too coarse for mode{} {list}: the estimated mesh error of the frequency \
             is above the {} % limit (measured by solving again with twice the elements, {} \
             in all against {}; Richardson). Use more elements (halving the element length \
             divides a bending frequency's error by about 16, an axial or torsional one's \
             by 4)",
            if over.len() > 1 { "s" } else { "" },
            100.0 * limit,
            elements.1,
            elements.0,
        )
    })
}

/// Share of a mode's strain energy that is bending (0 to 1), with the mode's shape
/// `parts` (its real and, in the rotating frame, imaginary part, by equation index)
/// linearised about `base` by central differences: each element's deformation angles
/// and stretch change at the rates (δφ, δs), whose energy is EA δs²/2L (axial),
/// GJ (δφx2 − δφx1)²/2L (torsion) and 2EI/L (δφ1² + δφ1 δφ2 + δφ2²) per bending plane
/// (the element's own [`crate::element::energy`]). None where the mode deforms no
/// element (a rigid-body or hinge motion).
pub fn bending_share(model: &Model, base: &State, parts: &[&[f64]]) -> Option<f64> {
    let (mut bend, mut total) = (0.0, 0.0);
    for p in parts {
        let Some((sp, sm, h)) = joint::poses_about(model, base, p) else {
            continue;
        };
        for (ie, e) in model.elem_data.iter().enumerate() {
            let kp = crate::element::deformation(e, &joint::elem_state(model, &sp, ie));
            let km = crate::element::deformation(e, &joint::elem_state(model, &sm, ie));
            let rate = |a: f64, b: f64| (a - b) * 0.5 / h;
            let f: Vec<f64> = (0..6).map(|c| rate(kp.phi[c], km.phi[c])).collect();
            let ds = rate(
                crate::element::stretch(e.l0, &kp),
                crate::element::stretch(e.l0, &km),
            );
            let pr = &e.props;
            // in the section's axes, turned as at the base state (`SectionTurn`)
            let base_phi: [f64; 6] = std::array::from_fn(|c| 0.5 * (kp.phi[c] + km.phi[c]));
            let t = crate::element::SectionTurn::of(&base_phi);
            // the rates' bending forms
            let r = crate::element::SectionTurn::of(&std::array::from_fn(|c| f[c]));
            let b = 2.0 / e.l0 * (pr.eiy * r.by + pr.eiz * r.bz)
                + (pr.eiy - pr.eiz) / e.l0 * (t.alpha * (r.by - r.bz) + t.beta * r.syz);
            let other = 0.5 / e.l0 * (pr.ea * ds * ds + pr.gj * (f[3] - f[0]).powi(2));
            bend += b;
            total += b + other;
        }
    }
    (total > 0.0 && total.is_finite()).then(|| bend / total)
}
