//! Internal force and tangent of the beam element: the closed-form gradient of the
//! Bernoulli strain energy and its derivative, also in closed form (material part
//! Bᵀ H B plus the geometric part of the moments and the axial force). The production
//! route of [`super::CpuEval`]; its WGSL twin is `shaders/beam_force.wgsl` (the
//! dual-number derivative of the force, column by column, is kept for the tests as
//! [`super::reference::internal_force_tangent_dual`]).

use super::ad::{mcol, vcross, vdot, Lane, Real, M3, V3};
use super::kinematics::*;
use crate::math::Mat3;
use crate::model::BeamProps;

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
    /// the frame spin in convected components [θx, θy, θz] per dof (T_Cᵀ `dtheta`)
    pub spin: [[R; NDOF]; 3],
    /// a/b of n = a e + b t_c2 (n node 1's y axis)
    pub ab: R,
    /// D_i = T_Cᵀ T_i of node 1 and node 2
    pub rel: [M3<R>; 2],
    /// ψ_i = T_Cᵀ(δπ_i − δθ_C) per node i and dof (2 × 3 × 12)
    pub psi: [[[R; NDOF]; 3]; 2],
}

/// Deformation measures and their first derivatives (generic: in [`Dual`] numbers the
/// derivative of this gradient gives the tangent).
#[inline(always)]
pub fn gradient<R: Real>(
    chord0: V3<R::Base>,
    l0: R::Base,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
) -> Grad<R> {
    let mut g = Grad::zero();
    gradient_into(chord0, l0, u1, u2, t1, t2, &mut g);
    g
}

impl<R: Real> Grad<R> {
    /// Every entry +0: a gradient to overwrite with [`gradient_into`].
    pub fn zero() -> Self {
        let z = R::cst(0.0);
        Grad {
            kin: Kin {
                tc: [[z; 3]; 3],
                phi: [z; 6],
                u1: z,
                len: z,
            },
            dtheta: [[z; NDOF]; 3],
            dphi: [[z; NDOF]; 6],
            dlen: [z; NDOF],
            spin: [[z; NDOF]; 3],
            ab: z,
            rel: [[[z; 3]; 3]; 2],
            psi: [[[z; NDOF]; 3]; 2],
        }
    }
}

/// [`gradient`] written over `g` (every entry): a stage keeps one per call and overwrites
/// it group by group, so its kilobytes (eight in four lanes, sixteen in their dual
/// numbers) are neither zeroed nor copied on the hot path.
#[inline(always)]
pub fn gradient_into<R: Real>(
    chord0: V3<R::Base>,
    l0: R::Base,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
    g: &mut Grad<R>,
) {
    g.kin = kinematics(chord0, l0, u1, u2, t1, t2);
    let tcm = g.kin.tc;
    let z = R::cst(0.0);
    let e = mcol(&tcm, 0);
    let tc2 = mcol(&tcm, 1);
    let tc3 = mcol(&tcm, 2);
    let n = mcol(t1, 1);
    let ab = vdot(n, e) / vdot(n, tc2);
    let il = R::cst(1.0) / g.kin.len;
    // convected components of the frame spin, as rows over the 12 dofs
    let [thx, thy, thz] = &mut g.spin;
    let dlen = &mut g.dlen;
    for k in 0..3 {
        dlen[k] = -e[k];
        dlen[3 + k] = z;
        dlen[6 + k] = e[k];
        dlen[9 + k] = z;
        thz[k] = -tc2[k] * il;
        thz[3 + k] = z;
        thz[6 + k] = tc2[k] * il;
        thz[9 + k] = z;
        thy[k] = tc3[k] * il;
        thy[3 + k] = z;
        thy[6 + k] = -tc3[k] * il;
        thy[9 + k] = z;
    }
    for j in 0..NDOF {
        thx[j] = ab * thy[j];
    }
    for k in 0..3 {
        thx[3 + k] = thx[3 + k] + e[k] - ab * tc2[k];
    }
    let dtheta = &mut g.dtheta;
    for r in 0..3 {
        for j in 0..NDOF {
            dtheta[r][j] = e[r] * thx[j] + tc2[r] * thy[j] + tc3[r] * thz[j];
        }
    }
    for (i, t) in [t1, t2].iter().enumerate() {
        // D = T_Cᵀ T_i and G = ½(tr D I − D)
        let mut d = [[z; 3]; 3];
        for r in 0..3 {
            for c in 0..3 {
                d[r][c] = vdot(mcol(&tcm, r), mcol(t, c));
            }
        }
        let half = R::cst(0.5);
        let tr = d[0][0] + d[1][1] + d[2][2];
        let mut gm = [[z; 3]; 3];
        for r in 0..3 {
            for c in 0..3 {
                gm[r][c] = -(half * d[r][c]);
            }
            gm[r][r] = gm[r][r] + half * tr;
        }
        // ψ = T_Cᵀ(δπ_i − δθ_C), per dof column j
        for j in 0..NDOF {
            let mut w = [-dtheta[0][j], -dtheta[1][j], -dtheta[2][j]];
            if j / 3 == 1 + 2 * i {
                w[j % 3] = w[j % 3] + R::cst(1.0);
            }
            let psi = [vdot(e, w), vdot(tc2, w), vdot(tc3, w)];
            for r in 0..3 {
                g.dphi[3 * i + r][j] = gm[r][0] * psi[0] + gm[r][1] * psi[1] + gm[r][2] * psi[2];
                g.psi[i][r][j] = psi[r];
            }
        }
        g.rel[i] = d;
    }
    g.ab = ab;
}

/// ∂U/∂φ and ∂U/∂ℓ (= the axial force N) of the Bernoulli energy (see [`energy`]).
#[inline]
pub(super) fn energy_partials<R: Real>(
    p: &BeamProps<R::Base>,
    l0: R::Base,
    k: &Kin<R>,
) -> ([R; 6], R) {
    let [fx1, fy1, fz1, fx2, fy2, fz2] = k.phi;
    let two_b: R::Base = Real::cst(2.0);
    let t = R::lift(p.gj / l0) * (fx2 - fx1);
    let cy = R::lift(two_b * p.eiy / l0);
    let cz = R::lift(two_b * p.eiz / l0);
    let two = R::cst(2.0);
    let four = R::cst(4.0);
    let n = R::lift(p.ea / l0) * stretch(l0, k);
    let g = n * R::lift(l0 / Real::cst(30.0));
    // the section's axes turned (see `SectionTurn`)
    let st = SectionTurn::of(&k.phi);
    let dc = R::lift((p.eiy - p.eiz) / l0);
    let (ay, az) = (dc * st.alpha, dc * st.beta);
    let (y1, y2) = (two * fy1 + fy2, fy1 + two * fy2);
    let (z1, z2) = (two * fz1 + fz2, fz1 + two * fz2);
    // ∂U/∂φx1 = ∂U/∂φx2 = TURN_SHARE ∂U/∂ψ
    let dpsi = R::cst(TURN_SHARE) * dc * (st.dalpha * (st.by - st.bz) + st.dbeta * st.syz);
    (
        [
            dpsi - t,
            cy * y1 + g * (four * fy1 - fy2) + (ay * y1 + az * z1),
            cz * z1 + g * (four * fz1 - fz2) + (az * y1 - ay * z1),
            t + dpsi,
            cy * y2 + g * (four * fy2 - fy1) + (ay * y2 + az * z2),
            cz * z2 + g * (four * fz2 - fz1) + (az * y2 - ay * z2),
        ],
        n,
    )
}

/// f_j = N ∂ℓ/∂q_j + Σ_a m_a ∂φ_a/∂q_j from the gradient and the energy partials.
#[inline]
fn force_from<R: Real>(g: &Grad<R>, m: &[R; 6], n: R) -> [R; NDOF] {
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

/// Internal force f = ∂U/∂q from the closed-form gradient, generic over the scalar (public
/// so the element bench can count its floating-point operations).
#[inline]
pub fn force_generic<R: Real>(
    e: &ElemData<R::Base>,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
) -> [R; NDOF] {
    let g = gradient(e.chord0, e.l0, u1, u2, t1, t2);
    let (m, n) = energy_partials(&e.props, e.l0, &g.kin);
    force_from(&g, &m, n)
}

/// Internal force vector f = ∂U/∂q: the forces and moments the element needs from its
/// nodes (the nodal residual is f_int − f_ext).
pub fn internal_force(e: &ElemData, s: &ElemState) -> Vec12 {
    let (t1, t2) = node_frames(e, s);
    force_generic(e, s.u1, s.u2, &t1, &t2)
}

/// The residual-only evaluation's shared pieces: the node frames, the f64 gradient, the
/// internal force and the strain energy, each bit-identical to [`node_frames`],
/// [`gradient`], [`internal_force`] and [`strain_energy`] (which would compute the frames
/// and the kinematics again).
pub(super) fn residual_parts(e: &ElemData, s: &ElemState) -> ((Mat3, Mat3), Grad<f64>, Vec12, f64) {
    let (t1, t2) = node_frames(e, s);
    let g = gradient(e.chord0, e.l0, s.u1, s.u2, &t1, &t2);
    let (_, f, u) = force_parts(e, &g);
    ((t1, t2), g, f, u)
}

/// From an element's gradient, in any lanes: the energy's partials (moments, axial
/// force) the tangent needs, the internal force and the strain energy. The gradient is
/// the caller's: returned beside these, its 8 kB in lanes were copied once more.
#[allow(clippy::type_complexity)]
#[inline(always)]
pub(super) fn force_parts<B: Lane>(e: &ElemData<B>, g: &Grad<B>) -> (([B; 6], B), [B; NDOF], B) {
    let (m, n) = energy_partials(&e.props, e.l0, &g.kin);
    let f = force_from(g, &m, n);
    let u = energy(&e.props, e.l0, &g.kin);
    ((m, n), f, u)
}

/// [`internal_force_tangent`] and the strain energy (bit-identical to [`strain_energy`],
/// from the same kinematics instead of computing them again).
pub fn internal_force_tangent_energy(e: &ElemData, s: &ElemState) -> (Vec12, Mat12, f64) {
    let (_, _, f, k, u) = tangent_parts(e, s);
    (f, k, u)
}

/// The full evaluation's shared pieces: [`residual_parts`] and the tangent K.
/// (public for the element bench's split of the stage)
pub fn tangent_parts(e: &ElemData, s: &ElemState) -> ((Mat3, Mat3), Grad<f64>, Vec12, Mat12, f64) {
    let (t1, t2) = node_frames(e, s);
    let g = gradient(e.chord0, e.l0, s.u1, s.u2, &t1, &t2);
    let ((m, n), f, u) = force_parts(e, &g);
    let k = tangent(&e.props, e.l0, &g, &m, n);
    ((t1, t2), g, f, k, u)
}

/// Internal force and its consistent tangent K_jk = ∂f_j/∂q_k in closed form, the state
/// perturbed multiplicatively (T ← exp(δπ̃) T) so the non-commutativity of spatial spins
/// is included; K is symmetric at equilibrium states only. f is bit-identical to
/// [`internal_force`]; K equals the vector-dual derivative of the force
/// ([`super::reference::internal_force_tangent_dual`]) to round-off, at a fraction of its
/// cost (that pass carries 10-word duals through every operation of the gradient).
///
/// With f_j = N ∂ℓ_j + Σ_a m_a ∂φ_a,j (∂ = ∂/∂q_j; [`Grad`]), D_k the derivative along dof k:
/// - material part Bᵀ H B: the Hessian of U in (φ, ℓ), i.e. EA/L0 ∂s ∂sᵀ (∂s = ∂ℓ + Σ h_a
///   ∂φ_a, h = ∂s/∂φ the bending-stretch term of [`stretch`]), GJ/L0 on the twist, and per
///   bending plane the 2 × 2 block (2EI/L0)[[2, 1], [1, 2]] + g [[4, −1], [−1, 4]], g = N L0/30;
/// - N D_k ∂ℓ_j: ∂ℓ_j = ±e_m for a translation, and D_k e = δθ_C × e;
/// - Σ_a m_a D_k ∂φ_a,j, from ∂φ_i = G_i ψ_i (G_i = ½(tr D_i I − D_i)): with μ_i node i's
///   three moments and ν_i = G_iᵀ μ_i,
///   μ_i · (D_k G_i) ψ_ij = ψ_ijᵀ A_i ψ_ik, A_i = −μ_i φ_iᵀ − ½ D_iᵀ skew(μ_i)
///   (δD_i = skew(ψ_ik) D_i, and tr(skew(a) D_i) = −2 a·φ_i), and
///   ν_i · D_k ψ_ij = −Θ_k · (c_ij × ν_i) − ν_i · D_k Θ_j, with Θ the frame spin in
///   convected components ([`Grad::spin`]) and c_ij = T_Cᵀ (unit spin of dof j if it turns
///   node i). D_k Θ_j differentiates θz = t_c2·δl/ℓ, θy = −t_c3·δl/ℓ, θx = (a/b)θy (+ e −
///   (a/b)t_c2 on node 1's spins): the convected axes turn by Θ_k (D_k t_c2 = T_C(Θ_k × ŷ),
///   …), D_k(1/ℓ) = −∂ℓ_k/ℓ², and a/b = n_x/n_y with n = D_1 ŷ, D_k n = ψ_1k × n.
pub fn internal_force_tangent(e: &ElemData, s: &ElemState) -> (Vec12, Mat12) {
    let (t1, t2) = node_frames(e, s);
    force_tangent_generic(e, s.u1, s.u2, &t1, &t2)
}

/// [`internal_force_tangent`] generic over the scalar (public so the element bench can
/// count its floating-point operations).
#[inline]
pub fn force_tangent_generic<R: Real>(
    e: &ElemData<R::Base>,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
) -> ([R; NDOF], [[R; NDOF]; NDOF]) {
    let g = gradient(e.chord0, e.l0, u1, u2, t1, t2);
    let (m, n) = energy_partials(&e.props, e.l0, &g.kin);
    let f = force_from(&g, &m, n);
    (f, tangent(&e.props, e.l0, &g, &m, n))
}

/// The closed-form K of [`internal_force_tangent`] from the gradient and the energy partials.
#[inline]
fn tangent<R: Real>(
    p: &BeamProps<R::Base>,
    l0: R::Base,
    g: &Grad<R>,
    m: &[R; 6],
    n: R,
) -> [[R; NDOF]; NDOF] {
    let mut k = [[R::cst(0.0); NDOF]; NDOF];
    tangent_into(p, l0, g, m, n, &mut k);
    k
}

/// [`tangent`] written over `k` (every entry).
///
/// K is a sum of rank-one terms a bᵀ (the material part, the moments' ψ terms and the
/// translation rows) and of row corrections (the spin rows). It is formed row by row: a
/// row's 12 entries stay in registers while every term is added in one fixed order, so
/// each entry is the same sum, in the same order, as adding whole rank-one matrices one
/// after the other gives, without zeroing K and passing it through memory once per term.
#[inline(always)]
pub(super) fn tangent_into<R: Real>(
    p: &BeamProps<R::Base>,
    l0: R::Base,
    g: &Grad<R>,
    m: &[R; 6],
    n: R,
    k: &mut [[R; NDOF]; NDOF],
) {
    let z = R::cst(0.0);
    let half = R::cst(0.5);
    let four = R::cst(4.0);
    let two_b: R::Base = Real::cst(2.0);
    let phi = g.kin.phi;
    let dp = &g.dphi;
    // material part: the rank-one terms of EA ∂s ∂sᵀ, GJ on the twist and the two bending
    // planes
    let c30 = R::lift(l0 / Real::cst(30.0));
    let h = [
        z,
        c30 * (four * phi[1] - phi[4]),
        c30 * (four * phi[2] - phi[5]),
        z,
        c30 * (four * phi[4] - phi[1]),
        c30 * (four * phi[5] - phi[2]),
    ];
    let ds: [R; NDOF] = std::array::from_fn(|j| {
        g.dlen[j] + h[1] * dp[1][j] + h[2] * dp[2][j] + h[4] * dp[4][j] + h[5] * dp[5][j]
    });
    let ea = R::lift(p.ea / l0);
    let eads = ds.map(|x| ea * x);
    let gj = R::lift(p.gj / l0);
    let tw: [R; NDOF] = std::array::from_fn(|j| dp[3][j] - dp[0][j]);
    let gjtw = tw.map(|x| gj * x);
    let gn = n * c30;
    // the section's axes turned (see `SectionTurn`): the bending stiffnesses Cy + ΔC α
    // and Cz − ΔC α, the cross term ΔC β h between the planes, and the couplings with ψ,
    // whose gradient is dψ = TURN_SHARE (∂φx1 + ∂φx2)
    let st = SectionTurn::of(&phi);
    let dc = R::lift((p.eiy - p.eiz) / l0);
    let two = R::cst(2.0);
    let cross = dc * st.beta;
    let dpsi: [R; NDOF] = std::array::from_fn(|j| R::cst(TURN_SHARE) * (dp[0][j] + dp[3][j]));
    let (fy1, fz1, fy2, fz2) = (phi[1], phi[2], phi[4], phi[5]);
    let (y1, y2) = (two * fy1 + fy2, fy1 + two * fy2);
    let (z1, z2) = (two * fz1 + fz2, fz1 + two * fz2);
    // ∂²U/∂ψ ∂φ for φy1, φz1, φy2, φz2
    let q = [
        dc * (st.dalpha * y1 + st.dbeta * z1),
        dc * (st.dbeta * y1 - st.dalpha * z1),
        dc * (st.dalpha * y2 + st.dbeta * z2),
        dc * (st.dbeta * y2 - st.dalpha * z2),
    ];
    let hpp = dc * (st.ddalpha * (st.by - st.bz) + st.ddbeta * st.syz);
    // per bending plane (y: φy1, φy2; z: φz1, φz2) the rows that multiply ∂φ_a1 and ∂φ_a2
    let mut bend = [[z; NDOF]; 4];
    for (pl, c) in [
        R::lift(two_b * p.eiy / l0) + dc * st.alpha,
        R::lift(two_b * p.eiz / l0) - dc * st.alpha,
    ]
    .into_iter()
    .enumerate()
    {
        let (a1, a2) = (1 + pl, 4 + pl);
        // the other plane's angles
        let (o1, o2) = (2 - pl, 5 - pl);
        let (d11, d12) = (two * c + four * gn, c - gn);
        let (e11, e12) = (two * cross, cross);
        let (q1, q2) = (q[pl], q[2 + pl]);
        bend[2 * pl] = std::array::from_fn(|j| {
            d11 * dp[a1][j] + d12 * dp[a2][j] + e11 * dp[o1][j] + e12 * dp[o2][j] + q1 * dpsi[j]
        });
        bend[2 * pl + 1] = std::array::from_fn(|j| {
            d12 * dp[a1][j] + d11 * dp[a2][j] + e12 * dp[o1][j] + e11 * dp[o2][j] + q2 * dpsi[j]
        });
    }
    // ψ's row: Σ_φ ∂²U/∂ψ∂φ ∂φ + ∂²U/∂ψ² dψ, multiplying dψ
    let psi_row: [R; NDOF] = std::array::from_fn(|j| {
        q[0] * dp[1][j] + q[1] * dp[2][j] + q[2] * dp[4][j] + q[3] * dp[5][j] + hpp * dpsi[j]
    });
    // geometric part: the moments' share, Σ_i ψ_iᵀ A_i ψ_i + the rotation rows' −(c × ν_i)·Θ
    let tc = &g.kin.tc;
    // ε_m = T_Cᵀ x̂_m: row m of T_C
    let eps = |mm: usize| tc[mm];
    let [sx, sy, sz] = &g.spin;
    let mut nu = [z; 3];
    let mut pr = [[[z; NDOF]; 3]; 2];
    let mut spin_rows = [[[z; NDOF]; 3]; 2];
    for i in 0..2 {
        let mu = [m[3 * i], m[3 * i + 1], m[3 * i + 2]];
        let ph = [phi[3 * i], phi[3 * i + 1], phi[3 * i + 2]];
        let d = &g.rel[i];
        // G_iᵀ μ_i = ½(tr D μ − Dᵀ μ)
        let tr = d[0][0] + d[1][1] + d[2][2];
        let nui: [R; 3] = std::array::from_fn(|c| {
            half * (tr * mu[c] - (d[0][c] * mu[0] + d[1][c] * mu[1] + d[2][c] * mu[2]))
        });
        // A = −μ φᵀ − ½ Dᵀ skew(μ), with (Dᵀ skew μ)[r][c] = Σ_s D[s][r] (skew μ)[s][c]
        let sk = [[z, -mu[2], mu[1]], [mu[2], z, -mu[0]], [-mu[1], mu[0], z]];
        let a: [[R; 3]; 3] = std::array::from_fn(|r| {
            std::array::from_fn(|c| {
                -(mu[r] * ph[c])
                    - half * (d[0][r] * sk[0][c] + d[1][r] * sk[1][c] + d[2][r] * sk[2][c])
            })
        });
        let ps = &g.psi[i];
        for r in 0..3 {
            pr[i][r] = std::array::from_fn(|j| {
                a[r][0] * ps[0][j] + a[r][1] * ps[1][j] + a[r][2] * ps[2][j]
            });
        }
        // rows of node i's spins: −(ε_m × ν_i) · Θ_k
        for mm in 0..3 {
            let c = vcross(eps(mm), nui);
            spin_rows[i][mm] = std::array::from_fn(|j| c[0] * sx[j] + c[1] * sy[j] + c[2] * sz[j]);
        }
        for c in 0..3 {
            nu[c] = nu[c] + nui[c];
        }
    }
    // D_k(a/b): a/b = n_x/n_y, n = D_1 ŷ in convected components, D_k n = ψ_1k × n
    let nc = [g.rel[0][0][1], g.rel[0][1][1], g.rel[0][2][1]];
    let ab = g.ab;
    let inc = R::cst(1.0) / nc[1];
    let ps1 = &g.psi[0];
    let dab: [R; NDOF] = std::array::from_fn(|j| {
        let cx = ps1[1][j] * nc[2] - ps1[2][j] * nc[1];
        let cy = ps1[2][j] * nc[0] - ps1[0][j] * nc[2];
        (cx - ab * cy) * inc
    });
    // the translation rows: ∂ℓ_j = E_j, θz_j = C2_j/ℓ, θy_j = −C3_j/ℓ with E, C2, C3 the
    // signed components of e, t_c2, t_c3; N D_k ∂ℓ_j − ν · D_k Θ_j as three rank-one terms
    let il = R::cst(1.0) / g.kin.len;
    let il2 = il * il;
    let alpha = nu[0] * ab + nu[1];
    let mut ev = [z; NDOF];
    let mut c2 = [z; NDOF];
    let mut c3 = [z; NDOF];
    for mm in 0..3 {
        let t = eps(mm);
        ev[mm] = -t[0];
        c2[mm] = -t[1];
        c3[mm] = -t[2];
        ev[6 + mm] = t[0];
        c2[6 + mm] = t[1];
        c3[6 + mm] = t[2];
    }
    let (nx, nz) = (nu[0], nu[2]);
    let be: [R; NDOF] = std::array::from_fn(|j| (alpha * sy[j] + nz * sz[j]) * il);
    let b2: [R; NDOF] =
        std::array::from_fn(|j| n * sz[j] - alpha * sx[j] * il + nz * g.dlen[j] * il2);
    let b3: [R; NDOF] = std::array::from_fn(|j| {
        -(n * sy[j]) - nz * sx[j] * il - alpha * g.dlen[j] * il2 + nx * dab[j] * il
    });
    // node 1's spin rows: θx_j = e_m − (a/b) t_c2,m, so −ν_x D_k θx_j
    let r_e: [R; NDOF] = std::array::from_fn(|j| -(nx * ab * sz[j]));
    let r_2: [R; NDOF] = std::array::from_fn(|j| -(nx * (sz[j] - dab[j])));
    let r_3: [R; NDOF] = std::array::from_fn(|j| nx * (sy[j] + ab * sx[j]));
    // K row by row, the terms in the order above
    let add = |row: &mut [R; NDOF], a: R, b: &[R; NDOF]| {
        for (x, y) in row.iter_mut().zip(b) {
            *x = a.madd(*y, *x);
        }
    };
    for (r, kr) in k.iter_mut().enumerate() {
        let mut row = [z; NDOF];
        add(&mut row, ds[r], &eads);
        add(&mut row, tw[r], &gjtw);
        for pl in 0..2 {
            add(&mut row, dp[1 + pl][r], &bend[2 * pl]);
            add(&mut row, dp[4 + pl][r], &bend[2 * pl + 1]);
        }
        add(&mut row, dpsi[r], &psi_row);
        for i in 0..2 {
            for q in 0..3 {
                add(&mut row, g.psi[i][q][r], &pr[i][q]);
            }
            if r / 3 == 2 * i + 1 {
                for (x, y) in row.iter_mut().zip(&spin_rows[i][r % 3]) {
                    *x = *x - *y;
                }
            }
        }
        if r / 3 == 0 || r / 3 == 2 {
            add(&mut row, ev[r], &be);
            add(&mut row, c2[r], &b2);
            add(&mut row, c3[r], &b3);
        }
        if r / 3 == 1 {
            let t = eps(r % 3);
            for j in 0..NDOF {
                row[j] = row[j] + (t[0] * r_e[j] + t[1] * r_2[j] + t[2] * r_3[j]);
            }
        }
        *kr = row;
    }
}
