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
//! The production route of [`super::CpuEval`]: M and C from the 36 gradient rows
//! ([`GradRows`]), S from one second-order jet pass ([`field_second`]), the inertial forces
//! M·a + S and M·v from the factored gradients ([`FieldMaps`], no rows). Its WGSL twin is
//! `shaders/beam_inertia.wgsl` (S there still by the hyper-dual pass, the same numbers).

use super::ad::{mvec, vadd, vcross, vsub, Dual, HyperDual, Lane, Real, M3, V3};
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

/// The position fields (a, b, c) at the Gauss points for node displacements `u1`, `u2`
/// and node frames `t1`, `t2` in any scalar (only their derivatives are used, so node 1's
/// displacement stands in for its position).
#[inline]
fn gauss_fields<R: Real>(
    e: &ElemData<R::Base>,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
) -> [[[R; 3]; 3]; 4] {
    gauss_fields_as(e, u1, u2, t1, t2, |f| f)
}

/// [`gauss_fields`] with each Gauss point's three fields passed through `keep` as they
/// are formed (so a caller that needs part of them never stages the whole).
#[inline(always)]
fn gauss_fields_as<R: Real, T>(
    e: &ElemData<R::Base>,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
    keep: impl Fn([V3<R>; 3]) -> T,
) -> [T; 4] {
    let kin = kinematics(e.chord0, e.l0, u1, u2, t1, t2);
    let chord = vadd(e.chord0.map(R::lift), vsub(u2, u1));
    std::array::from_fn(|g| keep(section_fields(&kin, u1, chord, GAUSS4[g].0)))
}

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
    let (u1, tt1) = perturb(s.u1, t1, &da[0..6], &db[0..6]);
    let (u2, tt2) = perturb(s.u2, t2, &da[6..12], &db[6..12]);
    gauss_fields(e, u1, u2, &tt1, &tt2)
}

/// The position fields at the Gauss points as second-order jets along `v`: their `.dd`
/// parts are H(v, v), bit-identical to the `.ab` parts of [`field_derivs`] along (v, v)
/// (the same products in the same order, each once instead of twice). Production takes
/// only the `.dd` parts, from [`field_second`]; the whole jets are for the tests.
#[cfg(test)]
pub(super) fn field_jets<B: Lane>(
    e: &ElemData<B>,
    (u1, u2, t1, t2): Positions<'_, B>,
    v: &[B; NDOF],
) -> [[[super::ad::Jet2<B>; 3]; 3]; 4] {
    let (u1, tt1) = perturb_jet(u1, t1, &v[0..6]);
    let (u2, tt2) = perturb_jet(u2, t2, &v[6..12]);
    gauss_fields(e, u1, u2, &tt1, &tt2)
}

/// The second-order parts H(v, v) of the position fields' jets along `v`, each Gauss
/// point's jets reduced to their `.dd` parts as they are formed (so the 3.4 kB of jets in
/// lanes are never staged or copied).
#[inline(always)]
pub(super) fn field_second<B: Lane>(
    e: &ElemData<B>,
    (u1, u2, t1, t2): Positions<'_, B>,
    v: &[B; NDOF],
) -> [[V3<B>; 3]; 4] {
    let (u1, tt1) = perturb_jet(u1, t1, &v[0..6]);
    let (u2, tt2) = perturb_jet(u2, t2, &v[6..12]);
    gauss_fields_as(e, u1, u2, &tt1, &tt2, |f| f.map(|c| c.map(|x| x.dd)))
}

/// An element's node displacements and node frames (u1, u2, T1, T2), in any lanes.
pub(super) type Positions<'a, B> = (V3<B>, V3<B>, &'a M3<B>, &'a M3<B>);

/// μ-weights of the three position fields per unit length: ρA for a, ρI_z for b
/// (multiplies y), ρI_y for c (multiplies z).
#[inline]
pub(super) fn field_weights<B: Lane>(p: &BeamProps<B>) -> [B; 3] {
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
fn mass_into<B: Lane>(rows: &[[B; NDOF]; 36], wq: &[B; 36], m: &mut [[B; NDOF]; NDOF]) {
    for (j, mj) in m.iter_mut().enumerate() {
        let mut acc = [B::cst(0.0); NDOF];
        for (r, wr) in rows.iter().zip(wq) {
            let a = *wr * r[j];
            for (x, y) in acc.iter_mut().zip(r) {
                *x = a.madd(*y, *x);
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
fn row_weights<B: Lane>(e: &ElemData<B>) -> [B; 36] {
    let wf = field_weights(&e.props);
    std::array::from_fn(|q| B::cst(GAUSS4[q / 9].1) * wf[(q / 3) % 3] * e.l0)
}

/// Field gradients g (and, in the full evaluation of a moving element, their time
/// derivatives ġ along the nodal velocities) laid out as 36 rows (Gauss point, field,
/// component) of 12 dofs, with the μ-weights of the rows: every inertia quantity is a
/// sum over these rows. A stage keeps one per batch and overwrites it element by element
/// (every entry it reads is written), so the hot path neither zeroes nor moves the rows.
pub struct GradRows<B = f64> {
    g: [[B; NDOF]; 36],
    gdot: [[B; NDOF]; 36],
    w: [B; 36],
    /// `None`: `gdot` holds no rates and C = 0; else the bit mask of the lanes whose
    /// rates it holds ([`Lane::keep`]; the others are at rest and get C = +0)
    rates: Option<B>,
    /// the dual-number gradient the rows of g and ġ are read from (workspace)
    dual: Grad<Dual<B>>,
}

impl<B: Lane> Default for GradRows<B> {
    fn default() -> Self {
        GradRows {
            g: [[B::cst(0.0); NDOF]; 36],
            gdot: [[B::cst(0.0); NDOF]; 36],
            w: [B::cst(0.0); 36],
            rates: None,
            dual: Grad::zero(),
        }
    }
}

impl<B: Lane> GradRows<B> {
    /// Overwrite with the rows of g from the element's gradient
    /// (bit-identical to the value part of [`GradRows::fill_with_rates`]).
    pub(super) fn fill_from(&mut self, e: &ElemData<B>, g: &Grad<B>) {
        field_rows_into(g, &mut self.g);
        self.w = row_weights(e);
        self.rates = None;
    }

    /// Overwrite with the rows of g and ġ along `v` at the given positions: one
    /// dual-number pass of the closed-form gradients, whose value parts do exactly the
    /// plain arithmetic, so g is bit-identical to [`GradRows::fill_from`]'s. `moving` is
    /// the bit mask of the lanes that move.
    pub(super) fn fill_rates_at(
        &mut self,
        e: &ElemData<B>,
        pos: Positions<'_, B>,
        v: &[B; NDOF],
        moving: B,
    ) {
        let (u1, u2, t1, t2) = pos;
        let (u1, tt1) = perturb_dual(u1, t1, &v[0..6]);
        let (u2, tt2) = perturb_dual(u2, t2, &v[6..12]);
        gradient_into(e.chord0, e.l0, u1, u2, &tt1, &tt2, &mut self.dual);
        let mut split = SplitRows {
            g: &mut self.g,
            gdot: &mut self.gdot,
        };
        field_rows_into(&self.dual, &mut split);
        self.w = row_weights(e);
        self.rates = Some(moving);
    }
}

impl GradRows<f64> {
    /// Overwrite with the rows of g at the element's node frames and, when the nodes move
    /// along `v`, of ġ: one dual-number pass of the closed-form gradients, whose value
    /// parts do exactly the f64 arithmetic, so g is bit-identical either way.
    /// (public for the element bench's split of the stage)
    pub fn fill_with_rates(&mut self, e: &ElemData, s: &ElemState, v: &Vec12) {
        let (t1, t2) = node_frames(e, s);
        if !v.iter().any(|x| *x != 0.0) {
            self.fill_from(e, &gradient(e.chord0, e.l0, s.u1, s.u2, &t1, &t2));
            return;
        }
        self.fill_rates_at(e, (s.u1, s.u2, &t1, &t2), v, ALL_LANES);
    }
}

/// The position fields' gradients g_q (q = Gauss point, field) in factored form: the
/// element's [`Grad`] and, per Gauss point, the field offsets the frame spin turns.
/// Products g·x and gᵀy then cost a few dot products of length 12 instead of forming the
/// 36 × 12 rows ([`field_rows`]): g_q x = δθ × r_q + T_C δ(local field) + chord share,
/// with δθ = ∂θ_C x, δφ = ∂φ x, δℓ = ∂ℓ x, and gᵀy gathers, over the Gauss points,
/// Σ r × y against ∂θ_C, the local components T_Cᵀ y against ∂φ and ∂ℓ, and the chord
/// shares against the node translations.
pub(super) struct FieldMaps<'g, B = f64> {
    g: &'g Grad<B>,
    /// ra, rb, rc per Gauss point (spatial)
    r: [[V3<B>; 3]; 4],
    /// wz, wy per Gauss point (the bending shapes' values)
    w: [[B; 2]; 4],
}

/// `Σ a_k b_k` as `Iterator::sum` adds in f64 (from −0.0, left to right), so the lanes
/// give the bits the scalar code gave.
#[inline(always)]
fn dot12<B: Lane>(a: &[B; NDOF], b: &[B; NDOF]) -> B {
    a.iter()
        .zip(b)
        .fold(B::cst(-0.0), |acc, (x, y)| x.madd(*y, acc))
}

/// Shape-function values at Gauss point ξ: n1, n2 (Hermite, bending), d1, d2 (their
/// derivatives), c0, c1 (linear, twist and chord).
const fn shapes(xi: f64) -> [f64; 6] {
    [
        xi - 2.0 * xi * xi + xi * xi * xi,
        -xi * xi + xi * xi * xi,
        1.0 - 4.0 * xi + 3.0 * xi * xi,
        -2.0 * xi + 3.0 * xi * xi,
        1.0 - xi,
        xi,
    ]
}

/// [`shapes`] at the four Gauss points, evaluated once at compile time (the same IEEE
/// arithmetic as at run time, so the same values).
const GAUSS_SHAPES: [[f64; 6]; 4] = [
    shapes(GAUSS4[0].0),
    shapes(GAUSS4[1].0),
    shapes(GAUSS4[2].0),
    shapes(GAUSS4[3].0),
];

impl<'g, B: Lane> FieldMaps<'g, B> {
    pub(super) fn new(g: &'g Grad<B>) -> Self {
        let k = &g.kin;
        let [fx1, fy1, fz1, fx2, fy2, fz2] = k.phi;
        let z = B::cst(0.0);
        // filled in place: the maps are what is returned, so nothing is staged and moved
        let mut maps = FieldMaps {
            g,
            r: [[[z; 3]; 3]; 4],
            w: [[z; 2]; 4],
        };
        for (gp, sh) in GAUSS_SHAPES.iter().enumerate() {
            let [n1, n2, d1, d2, c0, c1] = sh.map(B::cst);
            let wz = n1 * fz1 + n2 * fz2;
            let wy = n1 * fy1 + n2 * fy2;
            let thx = c0 * fx1 + c1 * fx2;
            let thy = d1 * fy1 + d2 * fy2;
            let thz = d1 * fz1 + d2 * fz2;
            maps.r[gp] = [
                mvec(&k.tc, [z, k.len * wz, -(k.len * wy)]),
                mvec(&k.tc, [-thz, B::cst(1.0), thx]),
                mvec(&k.tc, [thy, -thx, B::cst(1.0)]),
            ];
            maps.w[gp] = [wz, wy];
        }
        maps
    }

    /// w_q (g_q · x) for every (Gauss point, field) q, with w the μ-weights of
    /// [`gauss_field_weights`] (each component weighed as it is formed), written over
    /// `out` (a caller's buffer: returned, it was staged and copied).
    fn apply(&self, x: &[B; NDOF], w: &[[B; 3]; 4], out: &mut [[V3<B>; 3]; 4]) {
        let g = self.g;
        let th = [
            dot12(&g.dtheta[0], x),
            dot12(&g.dtheta[1], x),
            dot12(&g.dtheta[2], x),
        ];
        let ph: [B; 6] = std::array::from_fn(|k| dot12(&g.dphi[k], x));
        let l = dot12(&g.dlen, x);
        let (x1, x2) = ([x[0], x[1], x[2]], [x[6], x[7], x[8]]);
        let tc = &g.kin.tc;
        let len = g.kin.len;
        let z = B::cst(0.0);
        for (gp, og) in out.iter_mut().enumerate() {
            let [n1, n2, d1, d2, c0, c1] = GAUSS_SHAPES[gp].map(B::cst);
            let [wz, wy] = self.w[gp];
            let duy = l * wz + len * (n1 * ph[2] + n2 * ph[5]);
            let duz = -(l * wy + len * (n1 * ph[1] + n2 * ph[4]));
            let dthx = c0 * ph[0] + c1 * ph[3];
            let dthy = d1 * ph[1] + d2 * ph[4];
            let dthz = d1 * ph[2] + d2 * ph[5];
            let [ra, rb, rc] = &self.r[gp];
            let la = mvec(tc, [z, duy, duz]);
            let lb = mvec(tc, [-dthz, z, dthx]);
            let lc = mvec(tc, [dthy, -dthx, z]);
            let (ca, cb, cc) = (vcross(th, *ra), vcross(th, *rb), vcross(th, *rc));
            let [wa, wb, wc] = w[gp];
            for i in 0..3 {
                og[0][i] = (ca[i] + la[i] + (c0 * x1[i] + c1 * x2[i])) * wa;
                og[1][i] = (cb[i] + lb[i]) * wb;
                og[2][i] = (cc[i] + lc[i]) * wc;
            }
        }
    }

    /// Σ_q g_qj · y_q for every dof j.
    fn project(&self, y: &[[V3<B>; 3]; 4]) -> [B; NDOF] {
        let g = self.g;
        let tc = &g.kin.tc;
        let len = g.kin.len;
        let z = B::cst(0.0);
        let mut mth = [z; 3];
        let mut cph = [z; 6];
        let mut cl = z;
        let (mut f1, mut f2) = ([z; 3], [z; 3]);
        for gp in 0..4 {
            let [n1, n2, d1, d2, c0, c1] = GAUSS_SHAPES[gp].map(B::cst);
            let [wz, wy] = self.w[gp];
            let [ya, yb, yc] = &y[gp];
            let [ra, rb, rc] = &self.r[gp];
            let (ma, mb, mc) = (vcross(*ra, *ya), vcross(*rb, *yb), vcross(*rc, *yc));
            for i in 0..3 {
                mth[i] = mth[i] + (ma[i] + mb[i] + mc[i]);
                f1[i] = f1[i] + c0 * ya[i];
                f2[i] = f2[i] + c1 * ya[i];
            }
            // local components T_Cᵀ y
            let tt = |v: &V3<B>| -> V3<B> {
                std::array::from_fn(|c| tc[0][c] * v[0] + tc[1][c] * v[1] + tc[2][c] * v[2])
            };
            let (za, zb, zc) = (tt(ya), tt(yb), tt(yc));
            // field a: duy za1 + duz za2
            cl = cl + (za[1] * wz - za[2] * wy);
            cph[2] = cph[2] + za[1] * len * n1;
            cph[5] = cph[5] + za[1] * len * n2;
            cph[1] = cph[1] - za[2] * len * n1;
            cph[4] = cph[4] - za[2] * len * n2;
            // field b: −dthz zb0 + dthx zb2; field c: dthy zc0 − dthx zc1
            cph[2] = cph[2] - zb[0] * d1;
            cph[5] = cph[5] - zb[0] * d2;
            cph[1] = cph[1] + zc[0] * d1;
            cph[4] = cph[4] + zc[0] * d2;
            cph[0] = cph[0] + (zb[2] - zc[1]) * c0;
            cph[3] = cph[3] + (zb[2] - zc[1]) * c1;
        }
        let mut out: [B; NDOF] = std::array::from_fn(|j| {
            mth[0] * g.dtheta[0][j]
                + mth[1] * g.dtheta[1][j]
                + mth[2] * g.dtheta[2][j]
                + (0..6).fold(B::cst(-0.0), |acc, k| cph[k].madd(g.dphi[k][j], acc))
                + cl * g.dlen[j]
        });
        for i in 0..3 {
            out[i] = out[i] + f1[i];
            out[6 + i] = out[6 + i] + f2[i];
        }
        out
    }
}

/// The inertial forces from the factored gradients: M x = gᵀ(w ⊙ g x) for x = acc and v,
/// S = gᵀ(w ⊙ H(v, v)) with H from one second-order jet pass ([`field_second`]), the
/// node frames `frames` those of the gradient. The full and the residual-only evaluation
/// both call this with the same f64 gradient, so their forces are bit-identical.
/// (public for the element bench's split of the stage)
pub fn inertia_forces(
    e: &ElemData,
    s: &ElemState,
    g: &Grad<f64>,
    frames: &(Mat3, Mat3),
    v: &Vec12,
    acc: &Vec12,
) -> InertiaForces {
    let moving = v.iter().any(|x| *x != 0.0);
    let pos = (s.u1, s.u2, &frames.0, &frames.1);
    let (finert, mv, sv) = inertia_forces_at(e, g, pos, v, acc, moving.then_some(ALL_LANES));
    InertiaForces { finert, mv, s: sv }
}

/// Every bit set: [`inertia_forces_at`] keeps every lane's velocity terms.
pub(super) const ALL_LANES: f64 = f64::from_bits(u64::MAX);

/// [`inertia_forces`] in any lanes: (M·acc + S, M·v, S). `moving` is `None` when no
/// lane moves (M·v and S are then +0 and the jet pass is skipped, as the scalar code
/// does), else a bit mask per lane ([`Lane::keep`]): lanes whose mask is zero are at
/// rest and get +0 for M·v and S as they would alone.
#[allow(clippy::type_complexity)]
#[inline(always)]
pub(super) fn inertia_forces_at<B: Lane>(
    e: &ElemData<B>,
    g: &Grad<B>,
    pos: Positions<'_, B>,
    v: &[B; NDOF],
    acc: &[B; NDOF],
    moving: Option<B>,
) -> ([B; NDOF], [B; NDOF], [B; NDOF]) {
    let maps = FieldMaps::new(g);
    let w = gauss_field_weights(e);
    let z = B::cst(0.0);
    let mut y = [[[z; 3]; 3]; 4];
    maps.apply(acc, &w, &mut y);
    let ma = maps.project(&y);
    let (mv, sv) = if let Some(mask) = moving {
        maps.apply(v, &w, &mut y);
        let mv = maps.project(&y).map(|x| x.keep(mask));
        let mut hv = field_second(e, pos, v);
        weigh_fields(&w, &mut hv);
        (mv, maps.project(&hv).map(|x| x.keep(mask)))
    } else {
        ([B::cst(0.0); NDOF], [B::cst(0.0); NDOF])
    };
    (std::array::from_fn(|i| ma[i] + sv[i]), mv, sv)
}

/// Gauss weight × field weight × L0 per (Gauss point, field).
#[inline]
fn gauss_field_weights<B: Lane>(e: &ElemData<B>) -> [[B; 3]; 4] {
    let wf = field_weights(&e.props);
    std::array::from_fn(|gp| std::array::from_fn(|f| B::cst(GAUSS4[gp].1) * wf[f] * e.l0))
}

/// `y` weighed in place by the μ-weights of [`gauss_field_weights`].
#[inline]
fn weigh_fields<B: Lane>(w: &[[B; 3]; 4], y: &mut [[V3<B>; 3]; 4]) {
    for (yg, wg) in y.iter_mut().zip(w) {
        for (yf, wf) in yg.iter_mut().zip(wg) {
            yf.iter_mut().for_each(|x| *x = *x * *wf);
        }
    }
}

/// M·x from the factored gradients, as [`inertia_forces`] forms M·acc (the same
/// operations, so the same bits).
pub(super) fn mass_times<B: Lane>(e: &ElemData<B>, g: &Grad<B>, x: &[B; NDOF]) -> [B; NDOF] {
    let maps = FieldMaps::new(g);
    let w = gauss_field_weights(e);
    let mut y = [[[B::cst(0.0); 3]; 3]; 4];
    maps.apply(x, &w, &mut y);
    maps.project(&y)
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
    mass_and_rates(&r, v, &mut m, &mut c);
    Inertia {
        m,
        c,
        forces: inertia_residual(e, s, v, acc),
    }
}

/// M and C of [`inertia_full`] from rows filled by [`GradRows::fill_with_rates`] at the
/// element's state and `v`, written over `m` and `c`: what the stage calls, so the
/// matrices go straight to its output.
/// (public for the element bench's split of the stage)
pub fn mass_and_rates<B: Lane>(
    r: &GradRows<B>,
    v: &[B; NDOF],
    m: &mut [[B; NDOF]; NDOF],
    c: &mut [[B; NDOF]; NDOF],
) {
    mass_into(&r.g, &r.w, m);
    let z = B::cst(0.0);
    if let Some(mask) = r.rates {
        for (j, cj) in c.iter_mut().enumerate() {
            let mut acc_c = [z; NDOF];
            for ((row, rowd), wr) in r.g.iter().zip(&r.gdot).zip(&r.w) {
                let a = B::cst(2.0) * *wr * row[j];
                for (x, y) in acc_c.iter_mut().zip(rowd) {
                    *x = a.madd(*y, *x);
                }
            }
            *cj = acc_c;
        }
        for node in 0..2 {
            let o = 6 * node + 3;
            let (x, y, w) = (v[o], v[o + 1], v[o + 2]);
            // skew(ω), as `crate::math::skew` writes it
            let sk = [[z, -w, y], [w, z, -x], [-y, x, z]];
            for (j, cj) in c.iter_mut().enumerate() {
                for k in 0..3 {
                    let t = (0..3).fold(B::cst(-0.0), |a, i| m[j][o + i].madd(sk[i][k], a));
                    cj[o + k] = cj[o + k] + t;
                }
            }
        }
        for x in c.iter_mut().flatten() {
            *x = x.keep(mask);
        }
    } else {
        *c = [[z; NDOF]; NDOF];
    }
}

/// M, S and C of [`inertia_full`].
pub fn inertia(e: &ElemData, s: &ElemState, v: &Vec12) -> (Mat12, Vec12, Mat12) {
    let r = inertia_full(e, s, v, &[0.0; NDOF]);
    (r.m, r.forces.s, r.c)
}

/// The inertial forces of [`inertia_full`] without M and C (for residual-only Newton
/// iterations): [`inertia_forces`] from the f64 gradient, as both stage evaluations
/// compute them (bit-identical), and M is never formed.
pub fn inertia_residual(e: &ElemData, s: &ElemState, v: &Vec12, acc: &Vec12) -> InertiaForces {
    let (t1, t2) = node_frames(e, s);
    let g = gradient(e.chord0, e.l0, s.u1, s.u2, &t1, &t2);
    inertia_forces(e, s, &g, &(t1, t2), v, acc)
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
    e: &ElemData<R::Base>,
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
pub(super) struct SplitRows<'a, B> {
    g: &'a mut [[B; NDOF]; 36],
    gdot: &'a mut [[B; NDOF]; 36],
}

impl<B: Lane> RowSink<Dual<B>> for SplitRows<'_, B> {
    #[inline(always)]
    fn set(&mut self, q: usize, j: usize, x: Dual<B>) {
        self.g[q][j] = x.v;
        self.gdot[q][j] = x.d;
    }
    #[inline(always)]
    fn add_cst(&mut self, q: usize, j: usize, c: f64) {
        self.g[q][j] = self.g[q][j] + B::cst(c);
        self.gdot[q][j] = self.gdot[q][j] + B::cst(0.0);
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
    for (gp, sh) in GAUSS_SHAPES.iter().enumerate() {
        let [n1, n2, d1, d2, c0, c1] = sh.map(R::cst);
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
        // per dof j: the derivatives of the bending and twist fields, then
        // δa = δθ_C × ra + T_C [0, δu_y, δu_z] (+ the chord share below),
        // δb = δθ_C × rb + T_C [−δθz, 0, δθx], δc = δθ_C × rc + T_C [δθy, −δθx, 0]
        // (dof by dof, so nothing is staged in memory between the two)
        let dp = &g.dphi;
        let dth = &g.dtheta;
        for j in 0..NDOF {
            let duy = g.dlen[j] * wz + len * (n1 * dp[2][j] + n2 * dp[5][j]);
            let duz = -(g.dlen[j] * wy + len * (n1 * dp[1][j] + n2 * dp[4][j]));
            let dthx = c0 * dp[0][j] + c1 * dp[3][j];
            let dthy = d1 * dp[1][j] + d2 * dp[4][j];
            let dthz = d1 * dp[2][j] + d2 * dp[5][j];
            for c in 0..3 {
                let (p, q) = ((c + 1) % 3, (c + 2) % 3);
                let t = tc[c];
                let base = 9 * gp + c;
                out.set(
                    base,
                    j,
                    (dth[p][j] * ra[q] - dth[q][j] * ra[p]) + (t[0] * z + t[1] * duy + t[2] * duz),
                );
                out.set(
                    base + 3,
                    j,
                    (dth[p][j] * rb[q] - dth[q][j] * rb[p])
                        + (t[0] * (-dthz) + t[1] * z + t[2] * dthx),
                );
                out.set(
                    base + 6,
                    j,
                    (dth[p][j] * rc[q] - dth[q][j] * rc[p])
                        + (t[0] * dthy + t[1] * (-dthx) + t[2] * z),
                );
            }
        }
        for c in 0..3 {
            out.add_cst(9 * gp + c, c, sh[4]);
            out.add_cst(9 * gp + c, 6 + c, sh[5]);
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
    r.fill_from(e, &gradient(e.chord0, e.l0, s.u1, s.u2, &t1, &t2));
    mass_from_rows(&r.g, &r.w)
}
