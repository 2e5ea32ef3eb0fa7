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
//!
//! This file: element data and state, the convected-frame kinematics, strain energy,
//! section forces and gravity energy, shared by the force and inertia routes.

use super::ad::{
    mcol, mvec, vadd, vcross, vdot, vscale, vsub, Dual, HyperDual, Jet2, Lane, Real, M3, V3,
};
use super::inertia::*;
use crate::math::{Mat3, Vec3};
use crate::model::BeamProps;

pub const NDOF: usize = 12;
pub type Vec12 = [f64; NDOF];
pub type Mat12 = [[f64; NDOF]; NDOF];

/// Undeformed data of one element (of four in [`super::ad::F4`] lanes: `ElemData<F4>`).
#[derive(Clone, Copy, Debug)]
pub struct ElemData<B = f64> {
    pub props: BeamProps<B>,
    /// initial convected frame (columns x along the chord, y, z), global
    pub frame0: M3<B>,
    /// initial chord x2 − x1
    pub chord0: V3<B>,
    /// initial length |chord0|
    pub l0: B,
}

impl ElemData<f64> {
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
    chord0: V3<R::Base>,
    l0: R::Base,
    u1: V3<R>,
    u2: V3<R>,
    t1: &M3<R>,
    t2: &M3<R>,
) -> Kin<R> {
    let big_x = chord0.map(R::lift);
    let d = vsub(u2, u1);
    let lvec = vadd(big_x, d);
    let len = vdot(lvec, lvec).sqrt();
    // cancellation-free ℓ − L0: small strains on long elements stay exact in f32 too
    let u1 = (R::cst(2.0) * vdot(big_x, d) + vdot(d, d)) / (len + R::lift(l0));
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
pub fn energy<R: Real>(p: &BeamProps<R::Base>, l0: R::Base, k: &Kin<R>) -> R {
    let [fx1, _, _, fx2, _, _] = k.phi;
    let half = R::cst(0.5);
    let tw = fx2 - fx1;
    // ∫ EI v''² dx / 2 for Hermite v with end slopes θ1, θ2 = (2EI/L)(θ1² + θ1θ2 + θ2²)
    let t = SectionTurn::of(&k.phi);
    let (by, bz) = (t.by, t.bz);
    let s = stretch(l0, k);
    let two: R::Base = Real::cst(2.0);
    half * R::lift(p.ea / l0) * s * s
        + half * R::lift(p.gj / l0) * tw * tw
        + R::lift(two * p.eiz / l0) * bz
        + R::lift(two * p.eiy / l0) * by
        + R::lift((p.eiy - p.eiz) / l0) * (t.alpha * (by - bz) + t.beta * t.syz)
}

/// The section's principal axes, as the energy's bending angles see them, turned about
/// the chord by ψ = (φx1 + φx2)/4.
///
/// The convected frame takes its y axis from node 1's (paper eq. 5), and each end's
/// bending angles are the skew part of D_i = T_Cᵀ T_i, the axis of the whole rotation
/// from the frame to the node. For a node twisted by φx and bent by θ about its own y
/// axis that axis is θ R_x(φx/2) ŷ to first order in φx (Baker-Campbell-Hausdorff: the
/// log of exp(θ R_x(φx) ŷ) exp(φx x̂) adds −½θφx ẑ to θ R_x(φx) ŷ), so at each end the
/// measured bending vector stands turned by half that end's twist from the frame's axes,
/// in which the energy applies EIy and EIz. With EIy ≠ EIz the stiffnesses must be
/// applied in the turned axes; the two ends' turns averaged give ψ. The bending part
/// becomes ½ Σ_ij h_ij v_iᵀ Rᵀ diag(Cy, Cz) R v_j (v_i = (φy_i, φz_i), h = [[2, 1], [1, 2]],
/// C = 2EI/L, R the turn by ψ): the unturned energy plus ΔC (α (b_y − b_z) + β S_yz) with
/// ΔC = (EIy − EIz)/L, α = cos 2θ − 1, β = sin 2θ.
///
/// Without it (until session 47) the stiffnesses followed node 1's section, so the
/// results of a twisted beam with EIy ≠ EIz depended on the beam's direction and
/// converged at O(h): a cantilever's first frequency near its lateral-torsional buckling
/// load (EIy/EIz = 1000, 300 N against 359) read +15 % on 8 elements from root to tip and
/// −8 % on 16 from tip to root (a probe, session 47). With it both directions agree to
/// 3e-6 and converge at O(h²) (`tests/element_accuracy.rs`). A turn by half the twists'
/// sum, the mid-element section's, was tried first: it mirrored the error (the ends'
/// measured vectors are already turned by half their twists).
///
/// θ = atan ψ rather than ψ keeps R exactly orthogonal with no trigonometry (the dual and
/// SIMD number types have none), so the turned stiffnesses stay Cy and Cz however far an
/// iterate twists; atan ψ − ψ is O(ψ³), below the element's own error. Isotropic
/// sections (ΔC = 0) add an exact zero.
pub const TURN_SHARE: f64 = 0.25;

/// [`TURN_SHARE`]'s turn and the derivatives the tangent needs.
#[derive(Clone, Copy, Debug)]
pub struct SectionTurn<R> {
    /// ψ = `TURN_SHARE` (φx1 + φx2)
    pub psi: R,
    /// cos 2θ − 1 = −2ψ²/(1 + ψ²) (cancellation-free)
    pub alpha: R,
    /// sin 2θ = 2ψ/(1 + ψ²)
    pub beta: R,
    /// dα/dψ = −4ψ/(1 + ψ²)², dβ/dψ = 2(1 − ψ²)/(1 + ψ²)²
    pub dalpha: R,
    pub dbeta: R,
    /// d²α/dψ² = (12ψ² − 4)/(1 + ψ²)³, d²β/dψ² = (4ψ³ − 12ψ)/(1 + ψ²)³
    pub ddalpha: R,
    pub ddbeta: R,
    /// the bending forms of the angles it was made from: b_y = φy1² + φy1 φy2 + φy2²,
    /// b_z likewise, S_yz = Σ_ij h_ij φy_i φz_j
    pub by: R,
    pub bz: R,
    pub syz: R,
}

impl<R: Real> SectionTurn<R> {
    #[inline]
    pub fn of(phi: &[R; 6]) -> Self {
        let [fx1, fy1, fz1, fx2, fy2, fz2] = *phi;
        let (one, two, four) = (R::cst(1.0), R::cst(2.0), R::cst(4.0));
        let psi = R::cst(TURN_SHARE) * (fx1 + fx2);
        let p2 = psi * psi;
        let d = one + p2;
        let id = one / d;
        let id2 = id * id;
        let id3 = id2 * id;
        SectionTurn {
            psi,
            alpha: -(two * p2) * id,
            beta: two * psi * id,
            dalpha: -(four * psi) * id2,
            dbeta: two * (one - p2) * id2,
            ddalpha: (R::cst(12.0) * p2 - four) * id3,
            ddbeta: (four * p2 - R::cst(12.0)) * psi * id3,
            by: fy1 * fy1 + fy1 * fy2 + fy2 * fy2,
            bz: fz1 * fz1 + fz1 * fz2 + fz2 * fz2,
            syz: two * fy1 * fz1 + fy1 * fz2 + fy2 * fz1 + two * fy2 * fz2,
        }
    }
}

/// Mean axial stretch of the neutral axis: the chord change plus the length the bending
/// shape adds, ∫½(v'² + w'²) dx = (L/30)(2θ1² − θ1θ2 + 2θ2²) per plane for Hermite v, w
/// with end slopes θ relative to the chord (the Bernoulli strain u' + ½w'² averaged over
/// the element). Without it an axial force only stiffens the chord rotation, like a
/// string: tension-stiffened frequencies (rotating beams) then converge from below at
/// O(h²) with a large constant (−0.6 % on the third flap mode of a rotating cantilever at
/// Ω̄ = 10 with 12 elements); with it they match the published tables to 1e-4.
#[inline]
pub fn stretch<R: Real>(l0: R::Base, k: &Kin<R>) -> R {
    let [_, fy1, fz1, _, fy2, fz2] = k.phi;
    let two = R::cst(2.0);
    let q = two * fy1 * fy1 - fy1 * fy2 + two * fy2 * fy2 + two * fz1 * fz1 - fz1 * fz2
        + two * fz2 * fz2;
    k.u1 + R::lift(l0 / Real::cst(30.0)) * q
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
pub(super) fn node_frames(e: &ElemData, s: &ElemState) -> (Mat3, Mat3) {
    (
        crate::math::mat_mul(&s.r1, &e.frame0),
        crate::math::mat_mul(&s.r2, &e.frame0),
    )
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

/// Section forces at station ξ ∈ [0, 1] in the section's own frame there: [N, Vy, Vz, T,
/// My, Mz], each the resultant that the part beyond the section (towards node 2) exerts
/// on the part before it. They are the element's own end loads carried to the station:
/// the force f₂ the element takes from node 2 (its elastic forces are self-equilibrated,
/// so f₂ = −f₁ throughout), and the moment m₂ + (x₂ − x(ξ)) × f₂ about the section's
/// centre x(ξ) on the Hermite centreline. The section's frame is the chord frame turned
/// by the Hermite section rotation θ(ξ) of [`section_fields`] (at an element end, exactly
/// the node's frame) and, on an arc, further by the arc's own turn from the chord at ξ,
/// (ξ − ½) `arc` (see [`crate::model::Element::arc`]).
///
/// Until session 47 they were N = EA s/L, T = GJ Δφx/L, M = EI κ and V = dM/dx in the
/// chord frame (probes): the frame's turn mixed the components at O(h) (a cantilever's
/// root shear under tension plus a transverse load read 36.2 for 40 on 8 elements; a
/// quarter circle's root torque and moment 1.2 % off on 64), and V = dM/dx leaves out
/// the moment vector's own turn along a twisted and bent element, which does not vanish
/// under refinement: the 45° bend's root shear across its plane read −27.6 N on 128
/// elements where equilibrium gives 0 (the tip force is 600 N), estimated 0.27 %. Now
/// a clamped root reads the tip load and its moment exactly in statics.
pub fn section_forces(e: &ElemData, s: &ElemState, xi: f64, arc: Vec3) -> [f64; 6] {
    use crate::math::{add, cross, mat_mul, mat_vec, rot_exp, scale, sub, transpose};
    let (t1, t2) = node_frames(e, s);
    let k = kinematics(e.chord0, e.l0, s.u1, s.u2, &t1, &t2);
    let f = super::force::internal_force(e, s);
    let force = [f[6], f[7], f[8]];
    let chord = add(e.chord0, sub(s.u2, s.u1));
    // the section's centre relative to node 1, so the lever to node 2 is chord − it
    let [centre, _, _] = section_fields(&k, [0.0; 3], chord, xi);
    let moment = add([f[9], f[10], f[11]], cross(sub(chord, centre), force));
    // the Hermite section rotation from the ends' exact rotation vectors (the angles
    // `phi` are their sines' axes: at a node turned 0.18 rad from the chord the frame
    // read from them missed the node's by 6.6e-4 rad, which showed as 0.4 N of the
    // 45° bend's 600 N tip force in its root's axial force)
    let tct = transpose(&k.tc);
    let [fx1, fy1, fz1] = crate::math::rot_log(&mat_mul(&tct, &t1));
    let [fx2, fy2, fz2] = crate::math::rot_log(&mat_mul(&tct, &t2));
    let d1 = 1.0 - 4.0 * xi + 3.0 * xi * xi;
    let d2 = -2.0 * xi + 3.0 * xi * xi;
    let theta = [
        (1.0 - xi) * fx1 + xi * fx2,
        d1 * fy1 + d2 * fy2,
        d1 * fz1 + d2 * fz2,
    ];
    let frame = mat_mul(
        &k.tc,
        &mat_mul(&rot_exp(theta), &rot_exp(scale(arc, xi - 0.5))),
    );
    let to_section = transpose(&frame);
    let [n, vy, vz] = mat_vec(&to_section, force);
    let [tx, my, mz] = mat_vec(&to_section, moment);
    [n, vy, vz, tx, my, mz]
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

/// Node position and frame perturbed along two element-dof directions `da`, `db`:
/// x + ε₁ a + ε₂ b, and (I + ε₁A + ε₂B + ε₁ε₂ (AB + BA)/2) T with A = skew(a_rot).
#[inline]
pub(super) fn perturb(x: Vec3, t: &Mat3, da: &[f64], db: &[f64]) -> (V3<HyperDual>, M3<HyperDual>) {
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

/// Node position and frame perturbed along one element-dof direction `d` to second order
/// in [`Jet2`] numbers: bit-identical to [`perturb`] along (d, d), whose mixed part
/// ½(w × (w × t) + w × (w × t)) is w × (w × t) exactly.
#[inline]
pub(super) fn perturb_jet<T: Lane>(x: V3<T>, t: &M3<T>, d: &[T]) -> (V3<Jet2<T>>, M3<Jet2<T>>) {
    let xp = [0, 1, 2].map(|i| Jet2::new(x[i], d[i], T::cst(0.0)));
    let w = [d[3], d[4], d[5]];
    let mut tp = [[Jet2::<T>::default(); 3]; 3];
    for j in 0..3 {
        let tj = mcol(t, j);
        let a = vcross(w, tj);
        let aa = vcross(w, a);
        for i in 0..3 {
            tp[i][j] = Jet2::new(tj[i], a[i], aa[i]);
        }
    }
    (xp, tp)
}

/// Evaluate the kinematics in hyper-dual numbers along element directions `da`, `db`.
#[inline]
pub(super) fn kin_hd(
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

/// Node position and frame perturbed along one element-dof direction in dual numbers.
#[inline]
pub(super) fn perturb_dual<T: Lane>(x: V3<T>, t: &M3<T>, d: &[T]) -> (V3<Dual<T>>, M3<Dual<T>>) {
    let xp = [0, 1, 2].map(|i| Dual::new(x[i], d[i]));
    let w = [d[3], d[4], d[5]];
    let mut tp = [[Dual::<T>::default(); 3]; 3];
    for j in 0..3 {
        let tj = mcol(t, j);
        let a = vcross(w, tj);
        for i in 0..3 {
            tp[i][j] = Dual::new(tj[i], a[i]);
        }
    }
    (xp, tp)
}

/// Rotation angles [rad] of the two node frames from the convected frame: θ_i of
/// D_i = T_Cᵀ T_i, the angles whose sines the deformation angles are (the skew part of a
/// rotation D is sin θ · axis, so |(φx_i, φy_i, φz_i)| = sin θ_i), here exact at any size
/// from atan2(sin θ_i, (tr D_i − 1)/2). The strain energy is quadratic in the sines, so the
/// element's end forces follow k sin θ cos θ = k sin(2θ)/2 where the small-deformation
/// theory has k θ: [`crate::assembly::largest_deformation_angle`] tells how far that is.
pub fn deformation_rotation_angles(e: &ElemData, s: &ElemState) -> [f64; 2] {
    let (t1, t2) = node_frames(e, s);
    let k = kinematics(e.chord0, e.l0, s.u1, s.u2, &t1, &t2);
    let angle = |t: &Mat3, phi: &[f64]| {
        let trace: f64 = (0..3)
            .map(|j| crate::math::dot(mcol(&k.tc, j), crate::math::col(t, j)))
            .sum();
        let sin = (phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]).sqrt();
        sin.atan2(0.5 * (trace - 1.0))
    };
    [angle(&t1, &k.phi[0..3]), angle(&t2, &k.phi[3..6])]
}
