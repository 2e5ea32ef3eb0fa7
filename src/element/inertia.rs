//! Inertia of the beam element (Wu, Chang & Housner 1989, eq. 19): mass matrix,
//! quadratic-velocity vector S and its velocity derivative C, from the closed-form
//! gradients of the position field.
//! Inertia (eq. 19): the position of a material point (ξ, y, z) is
//! x_P = x1 + ξ (x2 − x1) + T_C (u + θ × (0, y, z)) with u the Hermite bending field and θ
//! the section rotation, so x_P = a(ξ) + y b(ξ) + z c(ξ). With principal centroidal
//! section axes ∫y = ∫z = ∫yz = 0, and ∫μ gᵀg dΩ = ∫ (ρA a'ᵀa' + ρI_z b'ᵀb' + ρI_y c'ᵀc')
//! dx exactly; the remaining integral along the element is polynomial of degree ≤ 6 in ξ
//! and is done with 4-point Gauss-Legendre, which is exact for degree 7.

//!
//! The production route of [`super::CpuEval`]; its WGSL twin is `shaders/beam_inertia.wgsl`.

use super::ad::{mvec, vadd, vsub, Dual, HyperDual, Jet2, Real, M3, V3};
use super::force::*;
use super::kinematics::*;
use crate::math::{Mat3, Vec3};
use crate::model::BeamProps;

/// 4-point Gauss-Legendre on [0, 1]
pub const GAUSS4: [(f64, f64); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_93),
    (0.330_009_478_207_571_87, 0.326_072_577_431_273_07),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_07),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_93),
];

/// Derivatives of the position fields (a, b, c) at the Gauss points along `da` (the `.a`
/// part), and the mixed second derivative along (`da`, `db`) (the `.ab` part).
pub(super) fn field_derivs(
    e: &ElemData,
    s: &ElemState,
    t1: &Mat3,
    t2: &Mat3,
    da: &Vec12,
    db: &Vec12,
) -> [[[HyperDual; 3]; 3]; 4] {
    // only derivatives are used here, so node 1's displacement stands in for its position
    let (kin, u1, u2) = kin_hd(e, s, t1, t2, da, db);
    let c0 = e.chord0.map(HyperDual::cst);
    let chord = vadd(c0, vsub(u2, u1));
    let mut out = [[[HyperDual::default(); 3]; 3]; 4];
    for (g, (xi, _)) in GAUSS4.iter().enumerate() {
        out[g] = section_fields(&kin, u1, chord, *xi);
    }
    out
}

/// The position fields at the Gauss points as second-order jets along `v`: their `.dd`
/// parts are H(v, v), bit-identical to the `.ab` parts of [`field_derivs`] along (v, v)
/// (the same products in the same order, each once instead of twice).
pub(super) fn field_jets(
    e: &ElemData,
    s: &ElemState,
    t1: &Mat3,
    t2: &Mat3,
    v: &Vec12,
) -> [[[Jet2; 3]; 3]; 4] {
    let (u1, tt1) = perturb_jet(s.u1, t1, &v[0..6]);
    let (u2, tt2) = perturb_jet(s.u2, t2, &v[6..12]);
    let kin = kinematics(e.chord0, e.l0, u1, u2, &tt1, &tt2);
    let c0 = e.chord0.map(Jet2::cst);
    let chord = vadd(c0, vsub(u2, u1));
    let mut out = [[[Jet2::default(); 3]; 3]; 4];
    for (g, (xi, _)) in GAUSS4.iter().enumerate() {
        out[g] = section_fields(&kin, u1, chord, *xi);
    }
    out
}

/// μ-weights of the three position fields per unit length: ρA for a, ρI_z for b
/// (multiplies y), ρI_y for c (multiplies z).
#[inline]
pub(super) fn field_weights(p: &BeamProps) -> [f64; 3] {
    [p.rho_a, p.rho_iz, p.rho_iy]
}

/// M = Σ over the 12 (Gauss point, field) pairs q of w_q G_qᵀ G_q, G_q the 3 × 12 field
/// gradient. Laid out as 36 rows of 12 contiguous dofs, each row of M is 36 length-12
/// multiply-adds kept in registers: this vectorises, where per-entry 3-term dot products
/// did not. Exactly symmetric (the two triangles round differently, so one is copied).
pub(super) fn mass_from_rows(rows: &[[f64; NDOF]; 36], wq: &[f64; 36]) -> Mat12 {
    let mut m = [[0.0; NDOF]; NDOF];
    mass_into(rows, wq, &mut m);
    m
}

/// [`mass_from_rows`] written over `m` (every entry).
fn mass_into(rows: &[[f64; NDOF]; 36], wq: &[f64; 36], m: &mut Mat12) {
    for (j, mj) in m.iter_mut().enumerate() {
        let mut acc = [0.0; NDOF];
        for (r, wr) in rows.iter().zip(wq) {
            let a = wr * r[j];
            for (x, y) in acc.iter_mut().zip(r) {
                *x += a * y;
            }
        }
        *mj = acc;
    }
    for j in 0..NDOF {
        for k in j + 1..NDOF {
            m[k][j] = m[j][k];
        }
    }
}

/// Field gradients g at the Gauss points (all 12 dofs).
pub(super) type FieldGrads = [[[Vec3; 3]; 4]; NDOF];

/// ∫ μ g_j · h over the element for every dof j, with h the `.ab` (mixed second
/// derivative) parts of the position fields at the Gauss points.
pub(super) fn project_ab(e: &ElemData, g: &FieldGrads, h: &[[[HyperDual; 3]; 3]; 4]) -> Vec12 {
    let w = field_weights(&e.props);
    std::array::from_fn(|j| {
        let mut acc = 0.0;
        for (gp, (_, wg)) in GAUSS4.iter().enumerate() {
            for f in 0..3 {
                let hv = [h[gp][f][0].ab, h[gp][f][1].ab, h[gp][f][2].ab];
                acc += wg * w[f] * crate::math::dot(g[j][gp][f], hv);
            }
        }
        acc * e.l0
    })
}

/// μ-weights of the 36 rows (Gauss point, field, component): Gauss weight × field
/// weight × L0.
#[inline]
fn row_weights(e: &ElemData) -> [f64; 36] {
    let wf = field_weights(&e.props);
    std::array::from_fn(|q| GAUSS4[q / 9].1 * wf[(q / 3) % 3] * e.l0)
}

/// Field gradients g (and, in the full evaluation of a moving element, their time
/// derivatives ġ along the nodal velocities) laid out as 36 rows (Gauss point, field,
/// component) of 12 dofs, with the μ-weights of the rows: every inertia quantity is a
/// sum over these rows. A stage keeps one per batch and overwrites it element by element
/// (every entry it reads is written), so the hot path neither zeroes nor moves the rows.
pub struct GradRows {
    g: [[f64; NDOF]; 36],
    gdot: [[f64; NDOF]; 36],
    w: [f64; 36],
    /// the node frames the rows were taken at
    frames: (Mat3, Mat3),
    /// whether `gdot` holds the rates (else C = 0)
    rates: bool,
}

impl Default for GradRows {
    fn default() -> Self {
        GradRows {
            g: [[0.0; NDOF]; 36],
            gdot: [[0.0; NDOF]; 36],
            w: [0.0; 36],
            frames: ([[0.0; 3]; 3], [[0.0; 3]; 3]),
            rates: false,
        }
    }
}

impl GradRows {
    /// Overwrite with the rows of g from the element's f64 gradient at frames `frames`
    /// (bit-identical to the value part of [`GradRows::fill_with_rates`]).
    pub(super) fn fill_from(&mut self, e: &ElemData, g: &Grad<f64>, frames: (Mat3, Mat3)) {
        field_rows_into(g, &mut self.g);
        self.w = row_weights(e);
        self.frames = frames;
        self.rates = false;
    }

    /// Overwrite with the rows of g at the element's node frames and, when the nodes move
    /// along `v`, of ġ: one dual-number pass of the closed-form gradients, whose value
    /// parts do exactly the f64 arithmetic, so g is bit-identical either way.
    pub(super) fn fill_with_rates(&mut self, e: &ElemData, s: &ElemState, v: &Vec12) {
        let (t1, t2) = node_frames(e, s);
        if !v.iter().any(|x| *x != 0.0) {
            self.fill_from(e, &gradient(e.chord0, e.l0, s.u1, s.u2, &t1, &t2), (t1, t2));
            return;
        }
        let (u1, tt1) = perturb_dual(s.u1, &t1, &v[0..6]);
        let (u2, tt2) = perturb_dual(s.u2, &t2, &v[6..12]);
        let mut split = SplitRows {
            g: &mut self.g,
            gdot: &mut self.gdot,
        };
        field_rows_into(&gradient(e.chord0, e.l0, u1, u2, &tt1, &tt2), &mut split);
        self.w = row_weights(e);
        self.frames = (t1, t2);
        self.rates = true;
    }

    /// S = ∫ μ gᵀ H(v, v), H the symmetric second derivative of the position field, from
    /// one second-order jet pass along v ([`field_jets`]; cheaper than ġ when only S is
    /// wanted, and the same whichever way the rows were filled).
    fn quadratic(&self, e: &ElemData, s: &ElemState, v: &Vec12) -> Vec12 {
        let mut sv = [0.0; NDOF];
        if v.iter().all(|x| *x == 0.0) {
            return sv;
        }
        let (t1, t2) = &self.frames;
        let h = field_jets(e, s, t1, t2, v);
        for (q, (row, wr)) in self.g.iter().zip(&self.w).enumerate() {
            let a = wr * h[q / 9][(q / 3) % 3][q % 3].dd;
            for (x, y) in sv.iter_mut().zip(row) {
                *x += a * y;
            }
        }
        sv
    }

    /// (M x, M y) = Σ_q w_q g_q (g_q · x), likewise y: products with M without forming it.
    fn mass_times(&self, x: &Vec12, y: &Vec12) -> (Vec12, Vec12) {
        let (mut mx, mut my) = ([0.0; NDOF], [0.0; NDOF]);
        for (row, wr) in self.g.iter().zip(&self.w) {
            let (mut gx, mut gy) = (0.0, 0.0);
            for ((r, xa), ya) in row.iter().zip(x).zip(y) {
                gx += r * xa;
                gy += r * ya;
            }
            let (a, b) = (wr * gx, wr * gy);
            for ((p, q), r) in mx.iter_mut().zip(my.iter_mut()).zip(row) {
                *p += a * r;
                *q += b * r;
            }
        }
        (mx, my)
    }
}

/// What the residual needs of an element's inertia: the inertial force M·acc + S and
/// M·v (kinetic energy, mass-proportional damping), and S itself.
#[derive(Clone, Copy, Debug)]
pub struct InertiaForces {
    pub finert: Vec12,
    pub mv: Vec12,
    pub s: Vec12,
}

/// The inertia quantities of the full (Jacobian) evaluation.
#[derive(Clone, Copy, Debug)]
pub struct Inertia {
    pub m: Mat12,
    pub c: Mat12,
    pub forces: InertiaForces,
}

fn forces_from_rows(
    r: &GradRows,
    e: &ElemData,
    s: &ElemState,
    v: &Vec12,
    acc: &Vec12,
) -> InertiaForces {
    let sv = r.quadratic(e, s, v);
    let (ma, mv) = r.mass_times(acc, v);
    InertiaForces {
        finert: std::array::from_fn(|i| ma[i] + sv[i]),
        mv,
        s: sv,
    }
}

/// Inertia terms at nodal velocities `v` = (ẋ1, ω1, ẋ2, ω2) (spatial angular velocities)
/// and accelerations `acc` = (ẍ1, α1, ẍ2, α2): the mass matrix M = ∫ μ gᵀ g, the
/// quadratic-velocity vector S = ∫ μ gᵀ ġ q̇ dΩ (paper eq. 19), its velocity derivative
/// C = ∂S/∂v (gyroscopic/Coriolis matrix for the Newton Jacobian), and the inertial nodal
/// force M acc + S.
///
/// With H(·,·) the symmetric second derivative of the position field (spins composed
/// symmetrically), S = ∫ μ gᵀ H(v, v) and C = 2 ∫ μ gᵀ H(v, e_k). The time derivative of
/// a gradient column along the motion, ġ_k, differs from H(v, e_k) only by the order in
/// which the spin of column k and the nodal angular velocity ω are composed:
/// ġ_k = H(v, e_k) + ½ g (e_k × ω) for a spin column k of a node (zero otherwise). So with
/// P = ∫ μ gᵀ ġ, C = 2P + M · blockdiag(0, skew ω1, 0, skew ω2): one dual-number pass of
/// the closed-form gradients gives g and ġ. Checked against one hyper-dual pass per column
/// ([`inertia_columns`]) and against finite differences of S.
pub fn inertia_full(e: &ElemData, s: &ElemState, v: &Vec12, acc: &Vec12) -> Inertia {
    let mut r = GradRows::default();
    let (mut m, mut c) = ([[0.0; NDOF]; NDOF], [[0.0; NDOF]; NDOF]);
    r.fill_with_rates(e, s, v);
    let forces = inertia_from_rows(&r, e, s, v, acc, &mut m, &mut c);
    Inertia { m, c, forces }
}

/// [`inertia_full`] from rows filled by [`GradRows::fill_with_rates`] at the element's
/// state and `v`, M and C written over `m` and `c`: what the stage calls, so the
/// matrices go straight to its output.
pub(super) fn inertia_from_rows(
    r: &GradRows,
    e: &ElemData,
    s: &ElemState,
    v: &Vec12,
    acc: &Vec12,
    m: &mut Mat12,
    c: &mut Mat12,
) -> InertiaForces {
    mass_into(&r.g, &r.w, m);
    if r.rates {
        for (j, cj) in c.iter_mut().enumerate() {
            let mut acc_c = [0.0; NDOF];
            for ((row, rowd), wr) in r.g.iter().zip(&r.gdot).zip(&r.w) {
                let a = 2.0 * wr * row[j];
                for (x, y) in acc_c.iter_mut().zip(rowd) {
                    *x += a * y;
                }
            }
            *cj = acc_c;
        }
        for node in 0..2 {
            let o = 6 * node + 3;
            let sk = crate::math::skew([v[o], v[o + 1], v[o + 2]]);
            for (j, cj) in c.iter_mut().enumerate() {
                for k in 0..3 {
                    cj[o + k] += (0..3).map(|i| m[j][o + i] * sk[i][k]).sum::<f64>();
                }
            }
        }
    } else {
        *c = [[0.0; NDOF]; NDOF];
    }
    forces_from_rows(r, e, s, v, acc)
}

/// M, S and C of [`inertia_full`].
pub fn inertia(e: &ElemData, s: &ElemState, v: &Vec12) -> (Mat12, Vec12, Mat12) {
    let r = inertia_full(e, s, v, &[0.0; NDOF]);
    (r.m, r.forces.s, r.c)
}

/// The inertial forces of [`inertia_full`] without M and C (for residual-only Newton
/// iterations): from the f64 gradients and the same arithmetic as there, so they are
/// bit-identical to [`inertia_full`]'s, and M is never formed (a product with M costs
/// 2 × 36 × 12 multiply-adds, forming it 36 × 144).
pub fn inertia_residual(e: &ElemData, s: &ElemState, v: &Vec12, acc: &Vec12) -> InertiaForces {
    let (t1, t2) = node_frames(e, s);
    let g = gradient(e.chord0, e.l0, s.u1, s.u2, &t1, &t2);
    let mut r = GradRows::default();
    inertia_residual_from(e, s, &g, (t1, t2), v, acc, &mut r)
}

/// [`inertia_residual`] from the element's f64 gradient at its node frames (as
/// [`super::force::residual_parts`] returns them), the rows written into `rows`:
/// bit-identical, one gradient fewer.
pub(super) fn inertia_residual_from(
    e: &ElemData,
    s: &ElemState,
    g: &Grad<f64>,
    frames: (Mat3, Mat3),
    v: &Vec12,
    acc: &Vec12,
    rows: &mut GradRows,
) -> InertiaForces {
    rows.fill_from(e, g, frames);
    forces_from_rows(rows, e, s, v, acc)
}

/// g_j = ∂(a, b, c)/∂q_j at the Gauss points, in closed form from [`gradient`], as 36 rows
/// (Gauss point, field, component) of 12 dofs:
/// δa = δx1 + ξ δl + δθ_C × (a − x1 − ξ l) + T_C δ[0, u_y, u_z],
/// δb = δθ_C × b + T_C δ[−θz, 0, θx], δc = δθ_C × c + T_C δ[θy, −θx, 0].
/// Generic: in [`Dual`] numbers along the nodal velocities it also gives their time
/// derivatives ġ_j (see [`inertia_full`]); public so the element bench can count its
/// floating-point operations.
#[inline]
pub fn gradients_closed_generic<R: Real>(
    e: &ElemData,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
) -> [[R; NDOF]; 36] {
    field_rows(&gradient(e.chord0, e.l0, u1, u2, t1, t2))
}

/// The rows of [`gradients_closed_generic`] from the element's [`gradient`] (so a caller
/// that has it for the force does not compute it twice).
#[inline]
pub(super) fn field_rows<R: Real>(g: &Grad<R>) -> [[R; NDOF]; 36] {
    let mut out = [[R::cst(0.0); NDOF]; 36];
    field_rows_into(g, &mut out);
    out
}

/// Where [`field_rows_into`] writes its rows: an array of `R`, or for dual numbers
/// ([`SplitRows`]) their value and derivative parts into two f64 arrays.
pub(super) trait RowSink<R> {
    fn set(&mut self, q: usize, j: usize, x: R);
    /// add a constant (the chord's share) to an entry already set
    fn add_cst(&mut self, q: usize, j: usize, c: f64);
}

impl<R: Real> RowSink<R> for [[R; NDOF]; 36] {
    #[inline(always)]
    fn set(&mut self, q: usize, j: usize, x: R) {
        self[q][j] = x;
    }
    #[inline(always)]
    fn add_cst(&mut self, q: usize, j: usize, c: f64) {
        self[q][j] = self[q][j] + R::cst(c);
    }
}

/// Dual-number rows g + ε ġ written straight into g and ġ (the same additions a [`Dual`]
/// does, so both are bit-identical to splitting a dual array afterwards).
pub(super) struct SplitRows<'a> {
    g: &'a mut [[f64; NDOF]; 36],
    gdot: &'a mut [[f64; NDOF]; 36],
}

impl RowSink<Dual> for SplitRows<'_> {
    #[inline(always)]
    fn set(&mut self, q: usize, j: usize, x: Dual) {
        self.g[q][j] = x.v;
        self.gdot[q][j] = x.d;
    }
    #[inline(always)]
    fn add_cst(&mut self, q: usize, j: usize, c: f64) {
        self.g[q][j] += c;
        self.gdot[q][j] += 0.0;
    }
}

/// [`field_rows`] written over `out` (every entry; no zeroing needed).
#[inline]
pub(super) fn field_rows_into<R: Real, S: RowSink<R>>(g: &Grad<R>, out: &mut S) {
    let k = &g.kin;
    let tc = &k.tc;
    let [fx1, fy1, fz1, fx2, fy2, fz2] = k.phi;
    let len = k.len;
    let z = R::cst(0.0);
    for (gp, (xi, _)) in GAUSS4.iter().enumerate() {
        let xi = *xi;
        let n1 = R::cst(xi - 2.0 * xi * xi + xi * xi * xi);
        let n2 = R::cst(-xi * xi + xi * xi * xi);
        let d1 = R::cst(1.0 - 4.0 * xi + 3.0 * xi * xi);
        let d2 = R::cst(-2.0 * xi + 3.0 * xi * xi);
        let (c0, c1) = (R::cst(1.0 - xi), R::cst(xi));
        let wz = n1 * fz1 + n2 * fz2;
        let wy = n1 * fy1 + n2 * fy2;
        let uy = len * wz;
        let uz = -(len * wy);
        let thx = c0 * fx1 + c1 * fx2;
        let thy = d1 * fy1 + d2 * fy2;
        let thz = d1 * fz1 + d2 * fz2;
        // current field offsets in the convected frame
        let ra = mvec(tc, [z, uy, uz]);
        let rb = mvec(tc, [-thz, R::cst(1.0), thx]);
        let rc = mvec(tc, [thy, -thx, R::cst(1.0)]);
        // the derivatives of the bending and twist fields, dof by dof (loops over the 12
        // dofs with scalar coefficients: they vectorise)
        let (mut duy, mut duz) = ([z; NDOF], [z; NDOF]);
        let (mut dthx, mut dthy, mut dthz) = ([z; NDOF], [z; NDOF], [z; NDOF]);
        let dp = &g.dphi;
        for j in 0..NDOF {
            duy[j] = g.dlen[j] * wz + len * (n1 * dp[2][j] + n2 * dp[5][j]);
            duz[j] = -(g.dlen[j] * wy + len * (n1 * dp[1][j] + n2 * dp[4][j]));
            dthx[j] = c0 * dp[0][j] + c1 * dp[3][j];
            dthy[j] = d1 * dp[1][j] + d2 * dp[4][j];
            dthz[j] = d1 * dp[2][j] + d2 * dp[5][j];
        }
        // δa = δθ_C × ra + T_C [0, δu_y, δu_z] (+ the chord share below),
        // δb = δθ_C × rb + T_C [−δθz, 0, δθx], δc = δθ_C × rc + T_C [δθy, −δθx, 0]
        let dth = &g.dtheta;
        for c in 0..3 {
            let (p, q) = ((c + 1) % 3, (c + 2) % 3);
            let t = tc[c];
            let base = 9 * gp + c;
            for j in 0..NDOF {
                out.set(
                    base,
                    j,
                    (dth[p][j] * ra[q] - dth[q][j] * ra[p])
                        + (t[0] * z + t[1] * duy[j] + t[2] * duz[j]),
                );
                out.set(
                    base + 3,
                    j,
                    (dth[p][j] * rb[q] - dth[q][j] * rb[p])
                        + (t[0] * (-dthz[j]) + t[1] * z + t[2] * dthx[j]),
                );
                out.set(
                    base + 6,
                    j,
                    (dth[p][j] * rc[q] - dth[q][j] * rc[p])
                        + (t[0] * dthy[j] + t[1] * (-dthx[j]) + t[2] * z),
                );
            }
        }
        for c in 0..3 {
            out.add_cst(9 * gp + c, c, 1.0 - xi);
            out.add_cst(9 * gp + c, 6 + c, xi);
        }
    }
}

/// [`gradients_closed_generic`] in f64, laid out by dof (for the reference routes).
pub(super) fn gradients_closed(e: &ElemData, s: &ElemState, t1: &Mat3, t2: &Mat3) -> FieldGrads {
    let rows = gradients_closed_generic(e, s.u1, s.u2, t1, t2);
    std::array::from_fn(|j| {
        std::array::from_fn(|gp| {
            std::array::from_fn(|f| std::array::from_fn(|c| rows[9 * gp + 3 * f + c][j]))
        })
    })
}

/// Consistent, configuration-dependent mass matrix M = ∫ μ gᵀ g dΩ (paper eq. 19).
pub fn mass_matrix(e: &ElemData, s: &ElemState) -> Mat12 {
    let (t1, t2) = node_frames(e, s);
    let mut r = GradRows::default();
    r.fill_from(e, &gradient(e.chord0, e.l0, s.u1, s.u2, &t1, &t2), (t1, t2));
    mass_from_rows(&r.g, &r.w)
}
