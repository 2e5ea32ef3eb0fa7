// Shared part of the beam kernels: buffer structs, dual and hyper-dual scalars, and the
// element kinematics and closed-form gradient, line by line the CPU functions of
// src/element/kinematics.rs, force.rs (`gradient`) and ad.rs. Functions carry the name of
// the Rust function they mirror; `_d` / `_h` are its instances in dual / hyper-dual
// numbers (the Rust functions are generic over the scalar).
//
// `real` is f32 or f64: the host replaces the alias line below before compiling, so one
// source serves both precisions. Every struct holds only arrays of `real`, so WGSL adds no
// padding and the layout is the Rust #[repr(C)] one (asserted in src/gpu/layout tests).

alias real = f32; // LATDYN_REAL

// Rust: gpu::ElemData. props = [EA, EIy, EIz, GJ, rhoA, rhoIy, rhoIz]; matrices row-major.
struct ElemData {
    props: array<real, 7>,
    frame0: array<real, 9>,
    chord0: array<real, 3>,
    l0: real,
}

// Rust: gpu::ElemIn. Nodal displacements, node rotations (row-major) and velocities.
struct ElemIn {
    u1: array<real, 3>,
    r1: array<real, 9>,
    u2: array<real, 3>,
    r2: array<real, 9>,
    v12: array<real, 12>,
}

struct Params {
    n_elem: u32,
    // beam_residual: nonzero when the inertial forces are asked for
    inertia: u32,
    pad1: u32,
    pad2: u32,
}

const GAUSS_X = array<real, 4>(0.06943184420297371, 0.33000947820757187, 0.6699905217924281, 0.9305681557970263);
const GAUSS_W = array<real, 4>(0.17392742256872693, 0.32607257743127307, 0.32607257743127307, 0.17392742256872693);

// ---------------------------------------------------------------- plain real helpers
alias M3 = array<array<real, 3>, 3>; // [row][col]

fn m3_load(a: array<real, 9>) -> M3 {
    return M3(
        array<real, 3>(a[0], a[1], a[2]),
        array<real, 3>(a[3], a[4], a[5]),
        array<real, 3>(a[6], a[7], a[8]),
    );
}

// crate::math::mat_mul, same summation order
fn m3_mul(a: M3, b: M3) -> M3 {
    var c: M3;
    for (var i = 0u; i < 3u; i++) {
        for (var j = 0u; j < 3u; j++) {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    return c;
}

fn m3_col(m: M3, j: u32) -> vec3<real> {
    var mm = m;
    return vec3<real>(mm[0][j], mm[1][j], mm[2][j]);
}

// crate::math::cross, written out so the rounding is the CPU's
fn cross3(a: vec3<real>, b: vec3<real>) -> vec3<real> {
    return vec3<real>(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

fn dot3(a: vec3<real>, b: vec3<real>) -> real {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// ---------------------------------------------------------------- dual numbers (v, d)
alias D = vec2<real>;
alias DV = array<D, 3>;
alias DM = array<array<D, 3>, 3>;

fn dc(x: real) -> D {
    return D(x, 0.0);
}
fn dmul(a: D, b: D) -> D {
    return D(a.x * b.x, a.x * b.y + a.y * b.x);
}
fn ddiv(a: D, b: D) -> D {
    let inv = 1.0 / b.x;
    return D(a.x * inv, (a.y * b.x - a.x * b.y) * inv * inv);
}
fn dsqrt(a: D) -> D {
    let s = sqrt(a.x);
    return D(s, 0.5 * a.y / s);
}
fn dv_add(a: DV, b: DV) -> DV {
    return DV(a[0] + b[0], a[1] + b[1], a[2] + b[2]);
}
fn dv_sub(a: DV, b: DV) -> DV {
    return DV(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}
fn dv_scale(a: DV, s: D) -> DV {
    return DV(dmul(a[0], s), dmul(a[1], s), dmul(a[2], s));
}
fn dv_dot(a: DV, b: DV) -> D {
    return dmul(a[0], b[0]) + dmul(a[1], b[1]) + dmul(a[2], b[2]);
}
fn dv_cross(a: DV, b: DV) -> DV {
    return DV(
        dmul(a[1], b[2]) - dmul(a[2], b[1]),
        dmul(a[2], b[0]) - dmul(a[0], b[2]),
        dmul(a[0], b[1]) - dmul(a[1], b[0]),
    );
}
fn dm_col(m: DM, j: u32) -> DV {
    var mm = m;
    return DV(mm[0][j], mm[1][j], mm[2][j]);
}

// ------------------------------------------------- hyper-dual numbers (v, a, b, ab)
alias H = vec4<real>;
alias HV = array<H, 3>;
alias HM = array<array<H, 3>, 3>;

fn hc(x: real) -> H {
    return H(x, 0.0, 0.0, 0.0);
}
fn hmul(x: H, y: H) -> H {
    return H(
        x.x * y.x,
        x.x * y.y + x.y * y.x,
        x.x * y.z + x.z * y.x,
        x.x * y.w + x.y * y.z + x.z * y.y + x.w * y.x,
    );
}
// f(x) given f, f', f'' at x.v (ad.rs HyperDual::lift)
fn hlift(x: H, f: real, f1: real, f2: real) -> H {
    return H(f, f1 * x.y, f1 * x.z, f1 * x.w + f2 * x.y * x.z);
}
fn hdiv(x: H, y: H) -> H {
    let inv = 1.0 / y.x;
    return hmul(x, hlift(y, inv, -inv * inv, 2.0 * inv * inv * inv));
}
fn hsqrt(x: H) -> H {
    let s = sqrt(x.x);
    return hlift(x, s, 0.5 / s, -0.25 / (s * x.x));
}
fn hv_add(a: HV, b: HV) -> HV {
    return HV(a[0] + b[0], a[1] + b[1], a[2] + b[2]);
}
fn hv_sub(a: HV, b: HV) -> HV {
    return HV(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}
fn hv_scale(a: HV, s: H) -> HV {
    return HV(hmul(a[0], s), hmul(a[1], s), hmul(a[2], s));
}
fn hv_dot(a: HV, b: HV) -> H {
    return hmul(a[0], b[0]) + hmul(a[1], b[1]) + hmul(a[2], b[2]);
}
fn hv_cross(a: HV, b: HV) -> HV {
    return HV(
        hmul(a[1], b[2]) - hmul(a[2], b[1]),
        hmul(a[2], b[0]) - hmul(a[0], b[2]),
        hmul(a[0], b[1]) - hmul(a[1], b[0]),
    );
}
fn hm_col(m: HM, j: u32) -> HV {
    var mm = m;
    return HV(mm[0][j], mm[1][j], mm[2][j]);
}
fn hm_vec(m: HM, v: HV) -> HV {
    return HV(
        hmul(m[0][0], v[0]) + hmul(m[0][1], v[1]) + hmul(m[0][2], v[2]),
        hmul(m[1][0], v[0]) + hmul(m[1][1], v[1]) + hmul(m[1][2], v[2]),
        hmul(m[2][0], v[0]) + hmul(m[2][1], v[1]) + hmul(m[2][2], v[2]),
    );
}

// ------------------------------------------------------------ kinematics (kinematics.rs)
// kinematics::Kin
struct Kin {
    tc: M3,
    phi: array<real, 6>,
    u1: real,
    len: real,
}

fn ang(e: vec3<real>, tc2: vec3<real>, tc3: vec3<real>, t: M3) -> vec3<real> {
    let t1 = m3_col(t, 0u);
    let t2 = m3_col(t, 1u);
    let t3 = m3_col(t, 2u);
    return vec3<real>(
        0.5 * (dot3(tc3, t2) - dot3(tc2, t3)),
        0.5 * (dot3(e, t3) - dot3(tc3, t1)),
        0.5 * (dot3(tc2, t1) - dot3(e, t2)),
    );
}

// kinematics::kinematics
fn kinematics(chord0: array<real, 3>, l0: real, u1: vec3<real>, u2: vec3<real>, t1: M3, t2: M3) -> Kin {
    let bx = vec3<real>(chord0[0], chord0[1], chord0[2]);
    let d = vec3<real>(u2.x - u1.x, u2.y - u1.y, u2.z - u1.z);
    let lvec = vec3<real>(bx.x + d.x, bx.y + d.y, bx.z + d.z);
    let len = sqrt(dot3(lvec, lvec));
    // cancellation-free ℓ − L0 (as on the CPU): decisive in f32
    let s1 = (2.0 * dot3(bx, d) + dot3(d, d)) / (len + l0);
    let il = 1.0 / len;
    let e = vec3<real>(lvec.x * il, lvec.y * il, lvec.z * il);
    let c = cross3(e, m3_col(t1, 1u));
    let ic = 1.0 / sqrt(dot3(c, c));
    let tc3 = vec3<real>(c.x * ic, c.y * ic, c.z * ic);
    let tc2 = cross3(tc3, e);
    let a1 = ang(e, tc2, tc3, t1);
    let a2 = ang(e, tc2, tc3, t2);
    var k: Kin;
    k.tc = M3(
        array<real, 3>(e.x, tc2.x, tc3.x),
        array<real, 3>(e.y, tc2.y, tc3.y),
        array<real, 3>(e.z, tc2.z, tc3.z),
    );
    k.phi = array<real, 6>(a1.x, a1.y, a1.z, a2.x, a2.y, a2.z);
    k.u1 = s1;
    k.len = len;
    return k;
}

// kinematics::stretch: chord change plus the length the bending shape adds
fn stretch(l0: real, k: Kin) -> real {
    let fy1 = k.phi[1];
    let fz1 = k.phi[2];
    let fy2 = k.phi[4];
    let fz2 = k.phi[5];
    let q = 2.0 * fy1 * fy1 - fy1 * fy2 + 2.0 * fy2 * fy2 + 2.0 * fz1 * fz1 - fz1 * fz2
        + 2.0 * fz2 * fz2;
    return k.u1 + (l0 / 30.0) * q;
}

// kinematics::SectionTurn: the section's axes turned by a quarter of the end twists' sum,
// [ψ, α, β, dα/dψ, dβ/dψ, d²α/dψ², d²β/dψ², S_yz]
const TURN_SHARE: real = 0.25;
fn section_turn(phi: array<real, 6>) -> array<real, 8> {
    let psi = TURN_SHARE * (phi[0] + phi[3]);
    let p2 = psi * psi;
    let id = 1.0 / (1.0 + p2);
    let id2 = id * id;
    let id3 = id2 * id;
    return array<real, 8>(
        psi,
        -(2.0 * p2) * id,
        2.0 * psi * id,
        -(4.0 * psi) * id2,
        2.0 * (1.0 - p2) * id2,
        (12.0 * p2 - 4.0) * id3,
        (4.0 * p2 - 12.0) * psi * id3,
        2.0 * phi[1] * phi[2] + phi[1] * phi[5] + phi[4] * phi[2] + 2.0 * phi[4] * phi[5],
    );
}

// kinematics::energy: Bernoulli strain energy
fn energy(p: array<real, 7>, l0: real, k: Kin) -> real {
    let fx1 = k.phi[0];
    let fy1 = k.phi[1];
    let fz1 = k.phi[2];
    let fx2 = k.phi[3];
    let fy2 = k.phi[4];
    let fz2 = k.phi[5];
    let tw = fx2 - fx1;
    let bz = fz1 * fz1 + fz1 * fz2 + fz2 * fz2;
    let by = fy1 * fy1 + fy1 * fy2 + fy2 * fy2;
    let s = stretch(l0, k);
    let t = section_turn(k.phi);
    return 0.5 * (p[0] / l0) * s * s + 0.5 * (p[3] / l0) * tw * tw + (2.0 * p[2] / l0) * bz
        + (2.0 * p[1] / l0) * by + ((p[1] - p[2]) / l0) * (t[1] * (by - bz) + t[2] * t[7]);
}

// force::Grad: the deformation measures' first derivatives over the 12 element dofs
struct Grad {
    kin: Kin,
    dtheta: array<array<real, 12>, 3>,
    dphi: array<array<real, 12>, 6>,
    dlen: array<real, 12>,
    // the frame spin in convected components [θx, θy, θz] per dof
    spin: array<array<real, 12>, 3>,
    ab: real,
    // D_i = T_Cᵀ T_i
    rel: array<M3, 2>,
    // ψ_i = T_Cᵀ(δπ_i − δθ_C) per node, component and dof
    psi: array<array<array<real, 12>, 3>, 2>,
}

// force::gradient (closed form)
fn gradient(chord0: array<real, 3>, l0: real, u1: vec3<real>, u2: vec3<real>, t1: M3, t2: M3) -> Grad {
    var g: Grad;
    g.kin = kinematics(chord0, l0, u1, u2, t1, t2);
    let e = m3_col(g.kin.tc, 0u);
    let tc2 = m3_col(g.kin.tc, 1u);
    let tc3 = m3_col(g.kin.tc, 2u);
    let n = m3_col(t1, 1u);
    let ab = dot3(n, e) / dot3(n, tc2);
    let il = 1.0 / g.kin.len;
    var thx: array<real, 12>;
    var thy: array<real, 12>;
    var thz: array<real, 12>;
    for (var k = 0u; k < 3u; k++) {
        g.dlen[k] = -e[k];
        g.dlen[6u + k] = e[k];
        thz[k] = -tc2[k] * il;
        thz[6u + k] = tc2[k] * il;
        thy[k] = tc3[k] * il;
        thy[6u + k] = -tc3[k] * il;
    }
    for (var j = 0u; j < 12u; j++) {
        thx[j] = ab * thy[j];
    }
    for (var k = 0u; k < 3u; k++) {
        thx[3u + k] = thx[3u + k] + e[k] - ab * tc2[k];
    }
    for (var r = 0u; r < 3u; r++) {
        for (var j = 0u; j < 12u; j++) {
            g.dtheta[r][j] = e[r] * thx[j] + tc2[r] * thy[j] + tc3[r] * thz[j];
        }
    }
    for (var i = 0u; i < 2u; i++) {
        var t = t1;
        if i == 1u {
            t = t2;
        }
        // D = T_Cᵀ T_i and G = ½(tr D I − D)
        var dd: M3;
        for (var r = 0u; r < 3u; r++) {
            for (var c = 0u; c < 3u; c++) {
                dd[r][c] = dot3(m3_col(g.kin.tc, r), m3_col(t, c));
            }
        }
        let tr = dd[0][0] + dd[1][1] + dd[2][2];
        var gg: M3;
        for (var r = 0u; r < 3u; r++) {
            for (var c = 0u; c < 3u; c++) {
                gg[r][c] = -(0.5 * dd[r][c]);
            }
            gg[r][r] = gg[r][r] + 0.5 * tr;
        }
        // ψ = T_Cᵀ(δπ_i − δθ_C), per dof column j
        for (var j = 0u; j < 12u; j++) {
            var w = vec3<real>(-g.dtheta[0][j], -g.dtheta[1][j], -g.dtheta[2][j]);
            if j / 3u == 1u + 2u * i {
                w[j % 3u] = w[j % 3u] + 1.0;
            }
            let psi = vec3<real>(dot3(e, w), dot3(tc2, w), dot3(tc3, w));
            for (var r = 0u; r < 3u; r++) {
                g.dphi[3u * i + r][j] = gg[r][0] * psi[0] + gg[r][1] * psi[1] + gg[r][2] * psi[2];
                g.psi[i][r][j] = psi[r];
            }
        }
        g.rel[i] = dd;
    }
    g.spin = array<array<real, 12>, 3>(thx, thy, thz);
    g.ab = ab;
    return g;
}

// ---------------------------------------------------- the same in dual numbers
struct KinD {
    tc: DM,
    phi: array<D, 6>,
    u1: D,
    len: D,
}

fn ang_d(e: DV, tc2: DV, tc3: DV, t: DM) -> DV {
    let t1 = dm_col(t, 0u);
    let t2 = dm_col(t, 1u);
    let t3 = dm_col(t, 2u);
    return DV(
        0.5 * (dv_dot(tc3, t2) - dv_dot(tc2, t3)),
        0.5 * (dv_dot(e, t3) - dv_dot(tc3, t1)),
        0.5 * (dv_dot(tc2, t1) - dv_dot(e, t2)),
    );
}

// kinematics::kinematics in dual numbers
fn kin_d(chord0: array<real, 3>, l0: real, u1: DV, u2: DV, t1: DM, t2: DM) -> KinD {
    let bx = DV(dc(chord0[0]), dc(chord0[1]), dc(chord0[2]));
    let d = dv_sub(u2, u1);
    let lvec = dv_add(bx, d);
    let len = dsqrt(dv_dot(lvec, lvec));
    // cancellation-free ℓ − L0 (as on the CPU): decisive in f32
    let s1 = ddiv(2.0 * dv_dot(bx, d) + dv_dot(d, d), len + dc(l0));
    let e = dv_scale(lvec, ddiv(dc(1.0), len));
    let c = dv_cross(e, dm_col(t1, 1u));
    let tc3 = dv_scale(c, ddiv(dc(1.0), dsqrt(dv_dot(c, c))));
    let tc2 = dv_cross(tc3, e);
    let a1 = ang_d(e, tc2, tc3, t1);
    let a2 = ang_d(e, tc2, tc3, t2);
    var k: KinD;
    k.tc = DM(DV(e[0], tc2[0], tc3[0]), DV(e[1], tc2[1], tc3[1]), DV(e[2], tc2[2], tc3[2]));
    k.phi = array<D, 6>(a1[0], a1[1], a1[2], a2[0], a2[1], a2[2]);
    k.u1 = s1;
    k.len = len;
    return k;
}

struct KinH {
    tc: HM,
    phi: array<H, 6>,
    u1: H,
    len: H,
}

fn ang_h(e: HV, tc2: HV, tc3: HV, t: HM) -> HV {
    let t1 = hm_col(t, 0u);
    let t2 = hm_col(t, 1u);
    let t3 = hm_col(t, 2u);
    return HV(
        0.5 * (hv_dot(tc3, t2) - hv_dot(tc2, t3)),
        0.5 * (hv_dot(e, t3) - hv_dot(tc3, t1)),
        0.5 * (hv_dot(tc2, t1) - hv_dot(e, t2)),
    );
}

// kinematics::kinematics in hyper-dual numbers
fn kin_h(chord0: array<real, 3>, l0: real, u1: HV, u2: HV, t1: HM, t2: HM) -> KinH {
    let bx = HV(hc(chord0[0]), hc(chord0[1]), hc(chord0[2]));
    let d = hv_sub(u2, u1);
    let lvec = hv_add(bx, d);
    let len = hsqrt(hv_dot(lvec, lvec));
    let s1 = hdiv(2.0 * hv_dot(bx, d) + hv_dot(d, d), len + hc(l0));
    let e = hv_scale(lvec, hdiv(hc(1.0), len));
    let c = hv_cross(e, hm_col(t1, 1u));
    let tc3 = hv_scale(c, hdiv(hc(1.0), hsqrt(hv_dot(c, c))));
    let tc2 = hv_cross(tc3, e);
    let a1 = ang_h(e, tc2, tc3, t1);
    let a2 = ang_h(e, tc2, tc3, t2);
    var k: KinH;
    k.tc = HM(HV(e[0], tc2[0], tc3[0]), HV(e[1], tc2[1], tc3[1]), HV(e[2], tc2[2], tc3[2]));
    k.phi = array<H, 6>(a1[0], a1[1], a1[2], a2[0], a2[1], a2[2]);
    k.u1 = s1;
    k.len = len;
    return k;
}

// force::gradient in dual numbers (its kin, dtheta, dphi and dlen: what
// inertia::field_rows uses). On inputs moving along the nodal velocities
// (perturb_dual) the derivative parts are the gradient's time derivative, which gives ġ.
struct GradD {
    kin: KinD,
    dtheta: array<array<D, 12>, 3>,
    dphi: array<array<D, 12>, 6>,
    dlen: array<D, 12>,
}

fn gradient_d(chord0: array<real, 3>, l0: real, u1: DV, u2: DV, t1: DM, t2: DM) -> GradD {
    var g: GradD;
    g.kin = kin_d(chord0, l0, u1, u2, t1, t2);
    var e = dm_col(g.kin.tc, 0u);
    var tc2 = dm_col(g.kin.tc, 1u);
    var tc3 = dm_col(g.kin.tc, 2u);
    let n = dm_col(t1, 1u);
    let ab = ddiv(dv_dot(n, e), dv_dot(n, tc2));
    let il = ddiv(dc(1.0), g.kin.len);
    var thx: array<D, 12>;
    var thy: array<D, 12>;
    var thz: array<D, 12>;
    for (var k = 0u; k < 3u; k++) {
        g.dlen[k] = -e[k];
        g.dlen[6u + k] = e[k];
        thz[k] = dmul(-tc2[k], il);
        thz[6u + k] = dmul(tc2[k], il);
        thy[k] = dmul(tc3[k], il);
        thy[6u + k] = dmul(-tc3[k], il);
    }
    for (var j = 0u; j < 12u; j++) {
        thx[j] = dmul(ab, thy[j]);
    }
    for (var k = 0u; k < 3u; k++) {
        thx[3u + k] = thx[3u + k] + e[k] - dmul(ab, tc2[k]);
    }
    for (var r = 0u; r < 3u; r++) {
        for (var j = 0u; j < 12u; j++) {
            g.dtheta[r][j] = dmul(e[r], thx[j]) + dmul(tc2[r], thy[j]) + dmul(tc3[r], thz[j]);
        }
    }
    for (var i = 0u; i < 2u; i++) {
        var t = t1;
        if i == 1u {
            t = t2;
        }
        // D = T_Cᵀ T_i and G = ½(tr D I − D)
        var dd: DM;
        for (var r = 0u; r < 3u; r++) {
            for (var c = 0u; c < 3u; c++) {
                dd[r][c] = dv_dot(dm_col(g.kin.tc, r), dm_col(t, c));
            }
        }
        let tr = dd[0][0] + dd[1][1] + dd[2][2];
        var gg: DM;
        for (var r = 0u; r < 3u; r++) {
            for (var c = 0u; c < 3u; c++) {
                gg[r][c] = -(0.5 * dd[r][c]);
            }
            gg[r][r] = gg[r][r] + 0.5 * tr;
        }
        for (var j = 0u; j < 12u; j++) {
            var w = DV(-g.dtheta[0][j], -g.dtheta[1][j], -g.dtheta[2][j]);
            if j / 3u == 1u + 2u * i {
                w[j % 3u] = w[j % 3u] + dc(1.0);
            }
            var psi = DV(dv_dot(e, w), dv_dot(tc2, w), dv_dot(tc3, w));
            for (var r = 0u; r < 3u; r++) {
                g.dphi[3u * i + r][j] = dmul(gg[r][0], psi[0]) + dmul(gg[r][1], psi[1]) + dmul(gg[r][2], psi[2]);
            }
        }
    }
    return g;
}

// kinematics::perturb_dual: node position and frame moving along one element-dof
// direction d (translation d[0..3], spatial spin d[3..6]), in dual numbers
struct NodeD {
    x: DV,
    t: DM,
}

fn perturb_dual(x: vec3<real>, t: M3, d: array<real, 6>) -> NodeD {
    var out: NodeD;
    out.x = DV(D(x.x, d[0]), D(x.y, d[1]), D(x.z, d[2]));
    let w = vec3<real>(d[3], d[4], d[5]);
    for (var j = 0u; j < 3u; j++) {
        let tj = m3_col(t, j);
        let a = cross3(w, tj);
        for (var i = 0u; i < 3u; i++) {
            out.t[i][j] = D(tj[i], a[i]);
        }
    }
    return out;
}
