//! Internal force and tangent of the beam element: the closed-form gradient of the
//! Bernoulli strain energy and its derivative in vector-dual lanes. The production route
//! of [`super::CpuEval`]; its WGSL twin is `shaders/beam_force.wgsl`.

use super::ad::{mcol, vdot, DualVec, Real, M3, V3};
use super::kinematics::*;
use crate::math::{Mat3, Vec3};
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
pub(super) fn energy_partials<R: Real>(p: &BeamProps, l0: f64, k: &Kin<R>) -> ([R; 6], R) {
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

/// Derivative lanes of the vector-dual passes: node 2's translation (3), node 1's spin
/// (3), node 2's spin (3). Node 1's translation needs no lanes: the element sees the node
/// positions only through the chord change u2 − u1 (and, in the position field, linearly
/// through u1), so every derivative along u1 that the tangents use is the negated one
/// along u2, exactly (negating the seeds negates every lane bit for bit).
pub(super) const LANES: usize = 9;
pub(super) const LANE_T2: usize = 0;
pub(super) const LANE_R1: usize = 3;
pub(super) const LANE_R2: usize = 6;

/// The element-dof column of each K/C column from lane results: (lane, sign).
#[inline]
pub(super) fn lane_of_dof(j: usize) -> (usize, f64) {
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
pub(super) fn perturb_lanes(
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
