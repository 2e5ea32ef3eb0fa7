//! Reference routes of the beam element by automatic differentiation (hyper-dual numbers
//! over the strain energy and the position field, one dual pass per column). No solver
//! calls them: they exist so that tests and the element bench can check the closed-form
//! production routes of [`super::force`] and [`super::inertia`] against an independent
//! derivation.

use super::ad::{DualVec, M3, V3};
use super::force::*;
use super::inertia::*;
use super::kinematics::*;
use crate::math::{Mat3, Vec3};

#[inline]
pub(super) fn unit(j: usize) -> Vec12 {
    let mut u = [0.0; NDOF];
    u[j] = 1.0;
    u
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

/// g_j = ∂(a, b, c)/∂q_j at the Gauss points, for all 12 dofs.
pub(super) fn gradients(
    e: &ElemData,
    s: &ElemState,
    t1: &Mat3,
    t2: &Mat3,
) -> [[[Vec3; 3]; 4]; NDOF] {
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

pub(super) fn mass_from_gradients(e: &ElemData, g: &[[[Vec3; 3]; 4]; NDOF]) -> Mat12 {
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

/// Reference implementation of [`mass_matrix`] by dual-number differentiation of the
/// position field.
pub fn mass_matrix_ad(e: &ElemData, s: &ElemState) -> Mat12 {
    let (t1, t2) = node_frames(e, s);
    mass_from_gradients(e, &gradients(e, s, &t1, &t2))
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

/// Reference for the closed-form [`internal_force_tangent`] (and the production route
/// before it): K_jk = ∂f_j/∂q_k as the derivative of the closed-form force along every
/// dof in one vector-dual pass (state perturbed multiplicatively, T ← exp(δπ̃) T).
/// Bit-identical to [`internal_force_tangent_columns`]; the WGSL force kernel does the
/// same per column.
pub fn internal_force_tangent_dual(e: &ElemData, s: &ElemState) -> (Vec12, Mat12) {
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
