//! The LATDYN 3D beam element (Wu, Chang & Housner 1989, section 2) as pure functions of
//! (element data, nodal state).
//!
//! Element dofs, 12 in this order: node-1 position increment (3), node-1 spatial rotation
//! increment (3), node-2 position (3), node-2 rotation (3). Rotation increments are
//! spatial (global-frame) spins: a node's frame is updated as T ← exp(skew(δπ)) T, so no
//! Euler-angle singularities exist anywhere.
//!
//! Kinematics (paper eqs. 5-10): the convected frame T_C has X_C along the chord
//! node 1 → node 2 and Y_C in the plane of X_C and node 1's y axis; deformation angles
//! from D_i = T_Cᵀ T_i, taken from its skew part (φ_xi = (t_c3·t_i2 − t_c2·t_i3)/2, …),
//! which equals the paper's single-entry form (eqs. 5-7) to first order and is exact to
//! second order (see `kinematics`). Internal forces come from the
//! Bernoulli strain energy (eq. 21) with cubic Hermite bending, linear torsion and the
//! chord stretch, computed cancellation-free as (2 X·d + d·d)/(|X+d| + |X|).
//!
//! Inertia (eq. 19): the position of a material point (ξ, y, z) is
//! x_P = x1 + ξ (x2 − x1) + T_C (u + θ × (0, y, z)) with u the Hermite bending field and θ
//! the section rotation, so x_P = a(ξ) + y b(ξ) + z c(ξ). With principal centroidal
//! section axes ∫y = ∫z = ∫yz = 0, and ∫μ gᵀg dΩ = ∫ (ρA a'ᵀa' + ρI_z b'ᵀb' + ρI_y c'ᵀc')
//! dx exactly; the remaining integral along the element is polynomial of degree ≤ 6 in ξ
//! and is done with 4-point Gauss-Legendre, which is exact for degree 7.

use super::ad::{
    mcol, mvec, vadd, vcross, vdot, vscale, vsub, Dual, DualVec, HyperDual, Real, M3, V3,
};
use crate::math::{Mat3, Vec3};
use crate::model::BeamProps;

pub const NDOF: usize = 12;
pub type Vec12 = [f64; NDOF];
pub type Mat12 = [[f64; NDOF]; NDOF];

/// Undeformed data of one element.
#[derive(Clone, Copy, Debug)]
pub struct ElemData {
    pub props: BeamProps,
    /// initial convected frame (columns x along the chord, y, z), global
    pub frame0: Mat3,
    /// initial chord x2 − x1
    pub chord0: Vec3,
    /// initial length |chord0|
    pub l0: f64,
}

impl ElemData {
    pub fn new(props: BeamProps, frame0: Mat3, x1: Vec3, x2: Vec3) -> Self {
        let chord0 = crate::math::sub(x2, x1);
        ElemData {
            props,
            frame0,
            chord0,
            l0: crate::math::norm(chord0),
        }
    }
}

/// Current state of the element's two nodes: displacements and rotations from the
/// reference configuration (the node's frame for this element is `r · frame0`).
/// Displacements, not positions, so the chord change d = u2 − u1 carries no round-off from
/// large coordinates (decisive in f32, harmless in f64).
#[derive(Clone, Copy, Debug)]
pub struct ElemState {
    pub u1: Vec3,
    pub r1: Mat3,
    pub u2: Vec3,
    pub r2: Mat3,
}

/// Deformation measures in the convected frame.
#[derive(Clone, Copy, Debug)]
pub struct Kin<R> {
    pub tc: M3<R>,
    /// [φx1, φy1, φz1, φx2, φy2, φz2]
    pub phi: [R; 6],
    /// chord stretch ℓ − L0
    pub u1: R,
    /// current chord length ℓ
    pub len: R,
}

/// Convected frame, deformation angles and stretch (paper eqs. 5-10).
#[inline]
pub fn kinematics<R: Real>(
    chord0: Vec3,
    l0: f64,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
) -> Kin<R> {
    let big_x = [R::cst(chord0[0]), R::cst(chord0[1]), R::cst(chord0[2])];
    let d = vsub(u2, u1);
    let lvec = vadd(big_x, d);
    let len = vdot(lvec, lvec).sqrt();
    // cancellation-free ℓ − L0: small strains on long elements stay exact in f32 too
    let u1 = (R::cst(2.0) * vdot(big_x, d) + vdot(d, d)) / (len + R::cst(l0));
    let e = vscale(lvec, R::cst(1.0) / len);
    let c = vcross(e, mcol(t1, 1));
    let tc3 = vscale(c, R::cst(1.0) / vdot(c, c).sqrt());
    let tc2 = vcross(tc3, e);
    let tc = [
        [e[0], tc2[0], tc3[0]],
        [e[1], tc2[1], tc3[1]],
        [e[2], tc2[2], tc3[2]],
    ];
    // The paper reads each angle from one entry of D = T_Cᵀ T_i (eqs. 5-7); that is exact
    // to first order only, and its second-order error (a bending-bending product leaking
    // into the twist) accumulates over a curved mesh into an O(h) global error (45° bend:
    // first-order convergence). The skew part of D, (D − Dᵀ)/2 = sin θ · axis, is exact to
    // second order and restores O(h²) convergence; to first order it is the paper's angle.
    let half = R::cst(0.5);
    let ang = |t: &M3<R>| {
        let (t1, t2, t3) = (mcol(t, 0), mcol(t, 1), mcol(t, 2));
        [
            half * (vdot(tc3, t2) - vdot(tc2, t3)),
            half * (vdot(e, t3) - vdot(tc3, t1)),
            half * (vdot(tc2, t1) - vdot(e, t2)),
        ]
    };
    let a1 = ang(t1);
    let a2 = ang(t2);
    Kin {
        tc,
        phi: [a1[0], a1[1], a1[2], a2[0], a2[1], a2[2]],
        u1,
        len,
    }
}

/// Bernoulli strain energy (paper eq. 21) of the deformation measures.
#[inline]
pub fn energy<R: Real>(p: &BeamProps, l0: f64, k: &Kin<R>) -> R {
    let [fx1, fy1, fz1, fx2, fy2, fz2] = k.phi;
    let half = R::cst(0.5);
    let tw = fx2 - fx1;
    // ∫ EI v''² dx / 2 for Hermite v with end slopes θ1, θ2 = (2EI/L)(θ1² + θ1θ2 + θ2²)
    let bz = fz1 * fz1 + fz1 * fz2 + fz2 * fz2;
    let by = fy1 * fy1 + fy1 * fy2 + fy2 * fy2;
    let s = stretch(l0, k);
    half * R::cst(p.ea / l0) * s * s
        + half * R::cst(p.gj / l0) * tw * tw
        + R::cst(2.0 * p.eiz / l0) * bz
        + R::cst(2.0 * p.eiy / l0) * by
}

/// Mean axial stretch of the neutral axis: the chord change plus the length the bending
/// shape adds, ∫½(v'² + w'²) dx = (L/30)(2θ1² − θ1θ2 + 2θ2²) per plane for Hermite v, w
/// with end slopes θ relative to the chord (the Bernoulli strain u' + ½w'² averaged over
/// the element). Without it an axial force only stiffens the chord rotation, like a
/// string: tension-stiffened frequencies (rotating beams) then converge from below at
/// O(h²) with a large constant (−0.6 % on the third flap mode of a rotating cantilever at
/// Ω̄ = 10 with 12 elements); with it they match the published tables to 1e-4.
#[inline]
pub fn stretch<R: Real>(l0: f64, k: &Kin<R>) -> R {
    let [_, fy1, fz1, _, fy2, fz2] = k.phi;
    let two = R::cst(2.0);
    let q = two * fy1 * fy1 - fy1 * fy2 + two * fy2 * fy2 + two * fz1 * fz1 - fz1 * fz2
        + two * fz2 * fz2;
    k.u1 + R::cst(l0 / 30.0) * q
}

/// Position field x_P = a + y b + z c at station ξ (see module docs), with `x1` node 1's
/// position and `chord` = x2 − x1.
#[inline]
pub fn section_fields<R: Real>(k: &Kin<R>, x1: V3<R>, chord: V3<R>, xi: f64) -> [V3<R>; 3] {
    let [fx1, fy1, fz1, fx2, fy2, fz2] = k.phi;
    let n1 = R::cst(xi - 2.0 * xi * xi + xi * xi * xi);
    let n2 = R::cst(-xi * xi + xi * xi * xi);
    let d1 = R::cst(1.0 - 4.0 * xi + 3.0 * xi * xi);
    let d2 = R::cst(-2.0 * xi + 3.0 * xi * xi);
    let uy = k.len * (n1 * fz1 + n2 * fz2);
    let uz = -(k.len * (n1 * fy1 + n2 * fy2));
    let thx = R::cst(1.0 - xi) * fx1 + R::cst(xi) * fx2;
    let thy = d1 * fy1 + d2 * fy2;
    let thz = d1 * fz1 + d2 * fz2;
    let zero = R::cst(0.0);
    let one = R::cst(1.0);
    let a = vadd(
        vadd(x1, vscale(chord, R::cst(xi))),
        mvec(&k.tc, [zero, uy, uz]),
    );
    let b = mvec(&k.tc, [-thz, one, thx]);
    let c = mvec(&k.tc, [thy, -thx, one]);
    [a, b, c]
}

/// Node frames for this element from the node rotations.
#[inline]
fn node_frames(e: &ElemData, s: &ElemState) -> (Mat3, Mat3) {
    (
        crate::math::mat_mul(&s.r1, &e.frame0),
        crate::math::mat_mul(&s.r2, &e.frame0),
    )
}

/// Node position and frame perturbed along two element-dof directions `da`, `db`:
/// x + ε₁ a + ε₂ b, and (I + ε₁A + ε₂B + ε₁ε₂ (AB + BA)/2) T with A = skew(a_rot).
#[inline]
fn perturb(x: Vec3, t: &Mat3, da: &[f64], db: &[f64]) -> (V3<HyperDual>, M3<HyperDual>) {
    let xp = [0, 1, 2].map(|i| HyperDual::new(x[i], da[i], db[i], 0.0));
    let wa = [da[3], da[4], da[5]];
    let wb = [db[3], db[4], db[5]];
    let mut tp = [[HyperDual::default(); 3]; 3];
    for j in 0..3 {
        let tj = crate::math::col(t, j);
        let a = crate::math::cross(wa, tj);
        let b = crate::math::cross(wb, tj);
        let ab = crate::math::cross(wa, b);
        let ba = crate::math::cross(wb, a);
        for i in 0..3 {
            tp[i][j] = HyperDual::new(tj[i], a[i], b[i], 0.5 * (ab[i] + ba[i]));
        }
    }
    (xp, tp)
}

/// Evaluate the kinematics in hyper-dual numbers along element directions `da`, `db`.
#[inline]
fn kin_hd(
    e: &ElemData,
    s: &ElemState,
    t1: &Mat3,
    t2: &Mat3,
    da: &Vec12,
    db: &Vec12,
) -> (Kin<HyperDual>, V3<HyperDual>, V3<HyperDual>) {
    let (u1, tt1) = perturb(s.u1, t1, &da[0..6], &db[0..6]);
    let (u2, tt2) = perturb(s.u2, t2, &da[6..12], &db[6..12]);
    (kinematics(e.chord0, e.l0, u1, u2, &tt1, &tt2), u1, u2)
}

#[inline]
fn unit(j: usize) -> Vec12 {
    let mut u = [0.0; NDOF];
    u[j] = 1.0;
    u
}

/// Deformation measures of the current state (f64).
pub fn deformation(e: &ElemData, s: &ElemState) -> Kin<f64> {
    let (t1, t2) = node_frames(e, s);
    kinematics(e.chord0, e.l0, s.u1, s.u2, &t1, &t2)
}

/// Whether both node frames stay within the element's small-deformation range of the
/// convected frame: every diagonal entry of D_i = T_Cᵀ T_i above cos 60°. Beyond it the
/// deformation angles (sines) stop identifying the rotation, e.g. a node flipped by π
/// looks undeformed, so a Newton iterate there is a spurious equilibrium, not a solution.
pub fn deformation_in_range(e: &ElemData, s: &ElemState) -> bool {
    let (t1, t2) = node_frames(e, s);
    let k = kinematics(e.chord0, e.l0, s.u1, s.u2, &t1, &t2);
    [t1, t2]
        .iter()
        .all(|t| (0..3).all(|j| crate::math::dot(mcol(&k.tc, j), crate::math::col(t, j)) > 0.5))
}

/// Strain energy of the current state.
pub fn strain_energy(e: &ElemData, s: &ElemState) -> f64 {
    energy(&e.props, e.l0, &deformation(e, s))
}

/// Reference implementation by hyper-dual differentiation of the strain energy (12 passes),
/// kept to test the analytic [`internal_force`].
/// Internal force vector f = ∂U/∂q (forces and moments the element needs from its
/// nodes; the nodal residual is f_int − f_ext).
pub fn internal_force_ad(e: &ElemData, s: &ElemState) -> Vec12 {
    let (t1, t2) = node_frames(e, s);
    let zero = [0.0; NDOF];
    let mut f = [0.0; NDOF];
    for (j, fj) in f.iter_mut().enumerate() {
        let (k, _, _) = kin_hd(e, s, &t1, &t2, &unit(j), &zero);
        *fj = energy(&e.props, e.l0, &k).a;
    }
    f
}

/// Reference implementation (78 hyper-dual passes over the energy), kept to test
/// [`internal_force_tangent`].
/// Internal force and its consistent tangent K_jk = ∂f_j/∂q_k, where the state is
/// perturbed multiplicatively (T ← exp(δπ̃) T). K is the symmetric second derivative plus
/// −½ skew(m) on each node's rotation block, m that node's internal moment: the
/// non-commutativity of spatial spins. K is symmetric at equilibrium states only.
pub fn internal_force_tangent_ad(e: &ElemData, s: &ElemState) -> (Vec12, Mat12) {
    let (t1, t2) = node_frames(e, s);
    let mut f = [0.0; NDOF];
    let mut k = [[0.0; NDOF]; NDOF];
    for j in 0..NDOF {
        let uj = unit(j);
        for kk in j..NDOF {
            let (kin, _, _) = kin_hd(e, s, &t1, &t2, &uj, &unit(kk));
            let u = energy(&e.props, e.l0, &kin);
            if kk == j {
                f[j] = u.a;
            }
            k[j][kk] = u.ab;
            k[kk][j] = u.ab;
        }
    }
    for node in 0..2 {
        let o = 6 * node + 3;
        let m = [f[o], f[o + 1], f[o + 2]];
        let sk = crate::math::skew(m);
        for a in 0..3 {
            for b in 0..3 {
                k[o + a][o + b] -= 0.5 * sk[a][b];
            }
        }
    }
    (f, k)
}

/// 4-point Gauss-Legendre on [0, 1]
pub const GAUSS4: [(f64, f64); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_93),
    (0.330_009_478_207_571_87, 0.326_072_577_431_273_07),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_07),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_93),
];

/// Derivatives of the position fields (a, b, c) at the Gauss points along `da` (the `.a`
/// part), and the mixed second derivative along (`da`, `db`) (the `.ab` part).
fn field_derivs(
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

/// μ-weights of the three position fields per unit length: ρA for a, ρI_z for b
/// (multiplies y), ρI_y for c (multiplies z).
#[inline]
fn field_weights(p: &BeamProps) -> [f64; 3] {
    [p.rho_a, p.rho_iz, p.rho_iy]
}

/// g_j = ∂(a, b, c)/∂q_j at the Gauss points, for all 12 dofs.
fn gradients(e: &ElemData, s: &ElemState, t1: &Mat3, t2: &Mat3) -> [[[Vec3; 3]; 4]; NDOF] {
    let zero = [0.0; NDOF];
    let mut g = [[[[0.0; 3]; 3]; 4]; NDOF];
    for (j, gj) in g.iter_mut().enumerate() {
        let d = field_derivs(e, s, t1, t2, &unit(j), &zero);
        for gp in 0..4 {
            for f in 0..3 {
                gj[gp][f] = [d[gp][f][0].a, d[gp][f][1].a, d[gp][f][2].a];
            }
        }
    }
    g
}

fn mass_from_gradients(e: &ElemData, g: &[[[Vec3; 3]; 4]; NDOF]) -> Mat12 {
    let w = field_weights(&e.props);
    let mut rows = [[0.0; NDOF]; 36];
    let mut wq = [0.0; 36];
    for (gp, (_, wg)) in GAUSS4.iter().enumerate() {
        for (f, wf) in w.iter().enumerate() {
            for c in 0..3 {
                let q = 9 * gp + 3 * f + c;
                wq[q] = wg * wf * e.l0;
                for (j, r) in rows[q].iter_mut().enumerate() {
                    *r = g[j][gp][f][c];
                }
            }
        }
    }
    mass_from_rows(&rows, &wq)
}

/// M = Σ over the 12 (Gauss point, field) pairs q of w_q G_qᵀ G_q, G_q the 3 × 12 field
/// gradient. Laid out as 36 rows of 12 contiguous dofs, each row of M is 36 length-12
/// multiply-adds kept in registers: this vectorises, where per-entry 3-term dot products
/// did not. Exactly symmetric (the two triangles round differently, so one is copied).
fn mass_from_rows(rows: &[[f64; NDOF]; 36], wq: &[f64; 36]) -> Mat12 {
    let mut m = [[0.0; NDOF]; NDOF];
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
    m
}

/// Reference implementation of [`mass_matrix`] by dual-number differentiation of the
/// position field.
pub fn mass_matrix_ad(e: &ElemData, s: &ElemState) -> Mat12 {
    let (t1, t2) = node_frames(e, s);
    mass_from_gradients(e, &gradients(e, s, &t1, &t2))
}

/// Field gradients g at the Gauss points (all 12 dofs).
type FieldGrads = [[[Vec3; 3]; 4]; NDOF];

/// ∫ μ g_j · h over the element for every dof j, with h the `.ab` (mixed second
/// derivative) parts of the position fields at the Gauss points.
fn project_ab(e: &ElemData, g: &FieldGrads, h: &[[[HyperDual; 3]; 3]; 4]) -> Vec12 {
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

/// Field gradients g (and, in the full evaluation, their time derivatives ġ along the
/// nodal velocities) laid out as 36 rows (Gauss point, field, component) of 12 dofs,
/// with the μ-weights of the rows: every inertia quantity is a sum over these rows.
struct GradRows {
    g: [[f64; NDOF]; 36],
    gdot: [[f64; NDOF]; 36],
    w: [f64; 36],
    /// the node frames the rows were taken at
    frames: (Mat3, Mat3),
}

impl GradRows {
    /// Rows of g from the f64 gradients, or of g and ġ from one dual-number pass with the
    /// nodes moving along `v` (`with_rates`; the value parts of that pass do exactly the
    /// f64 arithmetic, so g is bit-identical either way).
    fn new(e: &ElemData, s: &ElemState, v: &Vec12, with_rates: bool) -> Self {
        let (t1, t2) = node_frames(e, s);
        let wf = field_weights(&e.props);
        let w = std::array::from_fn(|q| GAUSS4[q / 9].1 * wf[(q / 3) % 3] * e.l0);
        if with_rates {
            let (u1, tt1) = perturb_dual(s.u1, &t1, &v[0..6]);
            let (u2, tt2) = perturb_dual(s.u2, &t2, &v[6..12]);
            let gd = gradients_closed_generic(e, u1, u2, &tt1, &tt2);
            GradRows {
                g: gd.map(|r| r.map(|x| x.v)),
                gdot: gd.map(|r| r.map(|x| x.d)),
                w,
                frames: (t1, t2),
            }
        } else {
            GradRows {
                g: gradients_closed_generic(e, s.u1, s.u2, &t1, &t2),
                gdot: [[0.0; NDOF]; 36],
                w,
                frames: (t1, t2),
            }
        }
    }

    /// S = ∫ μ gᵀ H(v, v), H the symmetric second derivative of the position field, from
    /// one hyper-dual pass (cheaper than ġ when only S is wanted).
    fn quadratic(&self, e: &ElemData, s: &ElemState, v: &Vec12) -> Vec12 {
        let mut sv = [0.0; NDOF];
        if v.iter().all(|x| *x == 0.0) {
            return sv;
        }
        let (t1, t2) = &self.frames;
        let h = field_derivs(e, s, t1, t2, v, v);
        for (q, (row, wr)) in self.g.iter().zip(&self.w).enumerate() {
            let a = wr * h[q / 9][(q / 3) % 3][q % 3].ab;
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
    let moving = v.iter().any(|x| *x != 0.0);
    let r = GradRows::new(e, s, v, moving);
    let m = mass_from_rows(&r.g, &r.w);
    let mut c = [[0.0; NDOF]; NDOF];
    if moving {
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
    }
    Inertia {
        m,
        c,
        forces: forces_from_rows(&r, e, s, v, acc),
    }
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
    forces_from_rows(&GradRows::new(e, s, v, false), e, s, v, acc)
}

/// Reference for [`inertia`]: M from the f64 closed-form gradients, S and each column of
/// C from one hyper-dual pass over the position field (no time derivatives of gradients).
pub fn inertia_columns(e: &ElemData, s: &ElemState, v: &Vec12) -> (Mat12, Vec12, Mat12) {
    let (t1, t2) = node_frames(e, s);
    let g = gradients_closed(e, s, &t1, &t2);
    let m = mass_from_gradients(e, &g);
    let sv = project_ab(e, &g, &field_derivs(e, s, &t1, &t2, v, v));
    let mut c = [[0.0; NDOF]; NDOF];
    if v.iter().any(|x| *x != 0.0) {
        for k in 0..NDOF {
            let colk = project_ab(e, &g, &field_derivs(e, s, &t1, &t2, v, &unit(k)));
            for j in 0..NDOF {
                c[j][k] = 2.0 * colk[j];
            }
        }
    }
    (m, sv, c)
}

/// Section forces at station ξ ∈ [0, 1], convected frame: [N, Vy, Vz, T, My, Mz].
/// N = EA s/L0 with s the mean stretch ([`stretch`], tension positive), T = GJ (φx2 − φx1)/L0, My = EI_y κ_y and
/// Mz = EI_z κ_z with κ = dθ/dx of the Hermite section rotation, Vy = dMz/dx,
/// Vz = dMy/dx.
pub fn section_forces(e: &ElemData, s: &ElemState, xi: f64) -> [f64; 6] {
    let k = deformation(e, s);
    let [fx1, fy1, fz1, fx2, fy2, fz2] = k.phi;
    let p = &e.props;
    let l = e.l0;
    let c1 = -4.0 + 6.0 * xi;
    let c2 = -2.0 + 6.0 * xi;
    [
        p.ea * stretch(l, &k) / l,
        p.eiz * 6.0 * (fz1 + fz2) / (l * l),
        p.eiy * 6.0 * (fy1 + fy2) / (l * l),
        p.gj * (fx2 - fx1) / l,
        p.eiy * (c1 * fy1 + c2 * fy2) / l,
        p.eiz * (c1 * fz1 + c2 * fz2) / l,
    ]
}

/// Position of the material point at (ξ, y, z) of the section (f64), for output; `x1_0`
/// is node 1's reference position.
pub fn material_point(e: &ElemData, s: &ElemState, x1_0: Vec3, xi: f64, y: f64, z: f64) -> Vec3 {
    let k = deformation(e, s);
    let x1 = crate::math::add(x1_0, s.u1);
    let chord = crate::math::add(e.chord0, crate::math::sub(s.u2, s.u1));
    let [a, b, c] = section_fields(&k, x1, chord, xi);
    crate::math::add(
        a,
        crate::math::add(crate::math::scale(b, y), crate::math::scale(c, z)),
    )
}

/// Potential energy of a uniform gravity field g, −∫ ρA g·x dx (the section's first
/// moments vanish), by the same 4-point rule as the mass matrix; `x1_0` is node 1's
/// reference position.
pub fn gravity_energy(e: &ElemData, s: &ElemState, x1_0: Vec3, g: Vec3) -> f64 {
    let k = deformation(e, s);
    let x1 = crate::math::add(x1_0, s.u1);
    let chord = crate::math::add(e.chord0, crate::math::sub(s.u2, s.u1));
    let mut acc = 0.0;
    for (xi, w) in GAUSS4 {
        let [a, _, _] = section_fields(&k, x1, chord, xi);
        acc += w * crate::math::dot(g, a);
    }
    -e.props.rho_a * e.l0 * acc
}

/// First derivatives of the deformation measures with respect to the 12 element dofs
/// (spatial spins), in closed form: the convected frame turns by
/// δθ_C = e θx + t_c2 θy + t_c3 θz with θz = t_c2·δl/ℓ, θy = −t_c3·δl/ℓ and, from
/// t_c3·n = 0 (n = node 1's y axis, n = a e + b t_c2), θx = e·δπ1 + (a/b)(θy − t_c2·δπ1);
/// then δD_i = skew(ψ_i) D_i with ψ_i = T_Cᵀ(δπ_i − δθ_C), and the skew-part angles vary
/// as δφ_i = ½(tr D_i I − D_i) ψ_i.
#[derive(Clone, Copy, Debug)]
pub struct Grad<R> {
    pub kin: Kin<R>,
    /// spatial spin of the convected frame per dof (3 × 12)
    pub dtheta: [[R; NDOF]; 3],
    /// [φx1, φy1, φz1, φx2, φy2, φz2] per dof (6 × 12)
    pub dphi: [[R; NDOF]; 6],
    /// chord length ℓ per dof
    pub dlen: [R; NDOF],
}

/// Deformation measures and their first derivatives (generic: in [`Dual`] numbers the
/// derivative of this gradient gives the tangent).
#[inline]
pub fn gradient<R: Real>(
    chord0: Vec3,
    l0: f64,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
) -> Grad<R> {
    let kin = kinematics(chord0, l0, u1, u2, t1, t2);
    let z = R::cst(0.0);
    let e = mcol(&kin.tc, 0);
    let tc2 = mcol(&kin.tc, 1);
    let tc3 = mcol(&kin.tc, 2);
    let n = mcol(t1, 1);
    let ab = vdot(n, e) / vdot(n, tc2);
    let il = R::cst(1.0) / kin.len;
    let mut dlen = [z; NDOF];
    // convected components of the frame spin, as rows over the 12 dofs
    let mut thx = [z; NDOF];
    let mut thy = [z; NDOF];
    let mut thz = [z; NDOF];
    for k in 0..3 {
        dlen[k] = -e[k];
        dlen[6 + k] = e[k];
        thz[k] = -tc2[k] * il;
        thz[6 + k] = tc2[k] * il;
        thy[k] = tc3[k] * il;
        thy[6 + k] = -tc3[k] * il;
    }
    for j in 0..NDOF {
        thx[j] = ab * thy[j];
    }
    for k in 0..3 {
        thx[3 + k] = thx[3 + k] + e[k] - ab * tc2[k];
    }
    let mut dtheta = [[z; NDOF]; 3];
    for r in 0..3 {
        for j in 0..NDOF {
            dtheta[r][j] = e[r] * thx[j] + tc2[r] * thy[j] + tc3[r] * thz[j];
        }
    }
    let mut dphi = [[z; NDOF]; 6];
    for (i, t) in [t1, t2].iter().enumerate() {
        // D = T_Cᵀ T_i and G = ½(tr D I − D)
        let mut d = [[z; 3]; 3];
        for r in 0..3 {
            for c in 0..3 {
                d[r][c] = vdot(mcol(&kin.tc, r), mcol(t, c));
            }
        }
        let half = R::cst(0.5);
        let tr = d[0][0] + d[1][1] + d[2][2];
        let mut g = [[z; 3]; 3];
        for r in 0..3 {
            for c in 0..3 {
                g[r][c] = -(half * d[r][c]);
            }
            g[r][r] = g[r][r] + half * tr;
        }
        // ψ = T_Cᵀ(δπ_i − δθ_C), per dof column j
        for j in 0..NDOF {
            let mut w = [-dtheta[0][j], -dtheta[1][j], -dtheta[2][j]];
            if j / 3 == 1 + 2 * i {
                w[j % 3] = w[j % 3] + R::cst(1.0);
            }
            let psi = [vdot(e, w), vdot(tc2, w), vdot(tc3, w)];
            for r in 0..3 {
                dphi[3 * i + r][j] = g[r][0] * psi[0] + g[r][1] * psi[1] + g[r][2] * psi[2];
            }
        }
    }
    Grad {
        kin,
        dtheta,
        dphi,
        dlen,
    }
}

/// ∂U/∂φ and ∂U/∂ℓ (= the axial force N) of the Bernoulli energy (see [`energy`]).
#[inline]
fn energy_partials<R: Real>(p: &BeamProps, l0: f64, k: &Kin<R>) -> ([R; 6], R) {
    let [fx1, fy1, fz1, fx2, fy2, fz2] = k.phi;
    let t = R::cst(p.gj / l0) * (fx2 - fx1);
    let cy = R::cst(2.0 * p.eiy / l0);
    let cz = R::cst(2.0 * p.eiz / l0);
    let two = R::cst(2.0);
    let four = R::cst(4.0);
    let n = R::cst(p.ea / l0) * stretch(l0, k);
    let g = n * R::cst(l0 / 30.0);
    (
        [
            -t,
            cy * (two * fy1 + fy2) + g * (four * fy1 - fy2),
            cz * (two * fz1 + fz2) + g * (four * fz1 - fz2),
            t,
            cy * (fy1 + two * fy2) + g * (four * fy2 - fy1),
            cz * (fz1 + two * fz2) + g * (four * fz2 - fz1),
        ],
        n,
    )
}

/// Internal force f = ∂U/∂q from the closed-form gradient, generic over the scalar (public
/// so the element bench can count its floating-point operations).
#[inline]
pub fn force_generic<R: Real>(
    e: &ElemData,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
) -> [R; NDOF] {
    let g = gradient(e.chord0, e.l0, u1, u2, t1, t2);
    let (m, n) = energy_partials(&e.props, e.l0, &g.kin);
    let mut f = [R::cst(0.0); NDOF];
    for (j, fj) in f.iter_mut().enumerate() {
        let mut acc = n * g.dlen[j];
        for a in 0..6 {
            acc = acc + m[a] * g.dphi[a][j];
        }
        *fj = acc;
    }
    f
}

/// Internal force vector f = ∂U/∂q: the forces and moments the element needs from its
/// nodes (the nodal residual is f_int − f_ext).
pub fn internal_force(e: &ElemData, s: &ElemState) -> Vec12 {
    let (t1, t2) = node_frames(e, s);
    force_generic(e, s.u1, s.u2, &t1, &t2)
}

/// Node position and frame perturbed along one element-dof direction in dual numbers.
#[inline]
fn perturb_dual(x: Vec3, t: &Mat3, d: &[f64]) -> (V3<Dual>, M3<Dual>) {
    let xp = [0, 1, 2].map(|i| Dual::new(x[i], d[i]));
    let w = [d[3], d[4], d[5]];
    let mut tp = [[Dual::default(); 3]; 3];
    for j in 0..3 {
        let tj = crate::math::col(t, j);
        let a = crate::math::cross(w, tj);
        for i in 0..3 {
            tp[i][j] = Dual::new(tj[i], a[i]);
        }
    }
    (xp, tp)
}

/// Derivative lanes of the vector-dual passes: node 2's translation (3), node 1's spin
/// (3), node 2's spin (3). Node 1's translation needs no lanes: the element sees the node
/// positions only through the chord change u2 − u1 (and, in the position field, linearly
/// through u1), so every derivative along u1 that the tangents use is the negated one
/// along u2, exactly (negating the seeds negates every lane bit for bit).
const LANES: usize = 9;
const LANE_T2: usize = 0;
const LANE_R1: usize = 3;
const LANE_R2: usize = 6;

/// The element-dof column of each K/C column from lane results: (lane, sign).
#[inline]
fn lane_of_dof(j: usize) -> (usize, f64) {
    match j / 3 {
        0 => (LANE_T2 + j % 3, -1.0),
        1 => (LANE_R1 + j % 3, 1.0),
        2 => (LANE_T2 + j % 3, 1.0),
        _ => (LANE_R2 + j % 3, 1.0),
    }
}

/// Node position and frame with the vector-dual lanes of [`LANES`]: `tr` the lane of the
/// position's x axis (None: no position lanes), `rot` the lane of the spin about x.
#[inline]
fn perturb_lanes(
    x: Vec3,
    t: &Mat3,
    tr: Option<usize>,
    rot: usize,
) -> (V3<DualVec<LANES>>, M3<DualVec<LANES>>) {
    let xp = [0, 1, 2].map(|i| {
        let mut d = [0.0; LANES];
        if let Some(l) = tr {
            d[l + i] = 1.0;
        }
        DualVec::new(x[i], d)
    });
    let mut tp = [[DualVec::new(0.0, [0.0; LANES]); 3]; 3];
    for j in 0..3 {
        let tj = crate::math::col(t, j);
        for i in 0..3 {
            tp[i][j].v = tj[i];
        }
        for m in 0..3 {
            let mut w = [0.0; 3];
            w[m] = 1.0;
            let a = crate::math::cross(w, tj);
            for i in 0..3 {
                tp[i][j].d[rot + m] = a[i];
            }
        }
    }
    (xp, tp)
}

/// Internal force and its consistent tangent K_jk = ∂f_j/∂q_k, the state perturbed
/// multiplicatively (T ← exp(δπ̃) T): column k is the derivative of the closed-form force
/// along dof k (one vector-dual pass for all columns), so the non-commutativity of
/// spatial spins is included. K is symmetric at equilibrium states only. Bit-identical
/// to [`internal_force_tangent_columns`].
pub fn internal_force_tangent(e: &ElemData, s: &ElemState) -> (Vec12, Mat12) {
    let (t1, t2) = node_frames(e, s);
    let f = force_generic(e, s.u1, s.u2, &t1, &t2);
    let (u1, tt1) = perturb_lanes(s.u1, &t1, None, LANE_R1);
    let (u2, tt2) = perturb_lanes(s.u2, &t2, Some(LANE_T2), LANE_R2);
    let fd = force_generic(e, u1, u2, &tt1, &tt2);
    let k = std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            let (l, sg) = lane_of_dof(c);
            sg * fd[r].d[l]
        })
    });
    (f, k)
}

/// Reference for [`internal_force_tangent`]: one [`Dual`] pass per column.
pub fn internal_force_tangent_columns(e: &ElemData, s: &ElemState) -> (Vec12, Mat12) {
    let (t1, t2) = node_frames(e, s);
    let f = force_generic(e, s.u1, s.u2, &t1, &t2);
    let mut k = [[0.0; NDOF]; NDOF];
    for c in 0..NDOF {
        let d = unit(c);
        let (u1, tt1) = perturb_dual(s.u1, &t1, &d[0..6]);
        let (u2, tt2) = perturb_dual(s.u2, &t2, &d[6..12]);
        let fd = force_generic(e, u1, u2, &tt1, &tt2);
        for r in 0..NDOF {
            k[r][c] = fd[r].d;
        }
    }
    (f, k)
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
    let g = gradient(e.chord0, e.l0, u1, u2, t1, t2);
    let k = &g.kin;
    let tc = &k.tc;
    let [fx1, fy1, fz1, fx2, fy2, fz2] = k.phi;
    let len = k.len;
    let z = R::cst(0.0);
    let mut out = [[z; NDOF]; 36];
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
                out[base][j] = (dth[p][j] * ra[q] - dth[q][j] * ra[p])
                    + (t[0] * z + t[1] * duy[j] + t[2] * duz[j]);
                out[base + 3][j] = (dth[p][j] * rb[q] - dth[q][j] * rb[p])
                    + (t[0] * (-dthz[j]) + t[1] * z + t[2] * dthx[j]);
                out[base + 6][j] = (dth[p][j] * rc[q] - dth[q][j] * rc[p])
                    + (t[0] * dthy[j] + t[1] * (-dthx[j]) + t[2] * z);
            }
        }
        for c in 0..3 {
            out[9 * gp + c][c] = out[9 * gp + c][c] + c0;
            out[9 * gp + c][6 + c] = out[9 * gp + c][6 + c] + c1;
        }
    }
    out
}

/// [`gradients_closed_generic`] in f64, laid out by dof (for the reference routes).
fn gradients_closed(e: &ElemData, s: &ElemState, t1: &Mat3, t2: &Mat3) -> FieldGrads {
    let rows = gradients_closed_generic(e, s.u1, s.u2, t1, t2);
    std::array::from_fn(|j| {
        std::array::from_fn(|gp| {
            std::array::from_fn(|f| std::array::from_fn(|c| rows[9 * gp + 3 * f + c][j]))
        })
    })
}

/// Consistent, configuration-dependent mass matrix M = ∫ μ gᵀ g dΩ (paper eq. 19).
pub fn mass_matrix(e: &ElemData, s: &ElemState) -> Mat12 {
    let r = GradRows::new(e, s, &[0.0; NDOF], false);
    mass_from_rows(&r.g, &r.w)
}
