// Consistent mass matrix M, quadratic-velocity vector S and its velocity derivative C of
// every element: the WGSL twin of reference::inertia_columns (src/element/reference.rs), the
// per-column hyper-dual route that the CPU keeps as the reference of its faster
// inertia::inertia_full (C from the gradients' time derivatives; the same C to 1e-12).
//
// One invocation per element. M = ∫μ gᵀg from the closed-form field gradients g at the
// four Gauss points (inertia::gradients_closed); S_j = ∫μ g_j·H(v, v) and
// C_jk = 2∫μ g_j·H(v, e_k), with H the mixed second derivative of the position field,
// evaluated in hyper-dual numbers (inertia::field_derivs). Every output word is written on
// every dispatch, no atomics. (beam_common.wgsl is prepended by the host.)

struct InertiaOut {
    m: array<real, 144>, // row-major
    s: array<real, 12>,
    c: array<real, 144>, // row-major
}

// field gradients g[j][gp][field], fields (a, b, c)
var<private> gr: array<array<array<vec3<real>, 3>, 4>, 12>;
// second derivatives H[gp][field] of one hyper-dual pass
var<private> hh: array<array<vec3<real>, 3>, 4>;

fn dv_value(v: DV) -> vec3<real> {
    return vec3<real>(v[0].x, v[1].x, v[2].x);
}

fn m3_vec(m: M3, v: vec3<real>) -> vec3<real> {
    return vec3<real>(
        m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
        m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
        m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
    );
}

// inertia::gradients_closed into `gr`
fn gradients_closed(ed: ElemData, inp: ElemIn, t1: M3, t2: M3) {
    let u1 = pos_dual(inp.u1, 0u, false);
    let u2 = pos_dual(inp.u2, 0u, false);
    var g = gradient_d(ed.chord0, ed.l0, u1, u2, frame_dual(t1, 0u, false), frame_dual(t2, 0u, false));
    var tc: M3;
    for (var i = 0u; i < 3u; i++) {
        for (var j = 0u; j < 3u; j++) {
            tc[i][j] = g.kin.tc[i][j].x;
        }
    }
    let fx1 = g.kin.phi[0].x;
    let fy1 = g.kin.phi[1].x;
    let fz1 = g.kin.phi[2].x;
    let fx2 = g.kin.phi[3].x;
    let fy2 = g.kin.phi[4].x;
    let fz2 = g.kin.phi[5].x;
    let len = g.kin.len.x;
    for (var gp = 0u; gp < 4u; gp++) {
        let xi = GAUSS_X[gp];
        let n1 = xi - 2.0 * xi * xi + xi * xi * xi;
        let n2 = -xi * xi + xi * xi * xi;
        let d1 = 1.0 - 4.0 * xi + 3.0 * xi * xi;
        let d2 = -2.0 * xi + 3.0 * xi * xi;
        let uy = len * (n1 * fz1 + n2 * fz2);
        let uz = -len * (n1 * fy1 + n2 * fy2);
        let thx = (1.0 - xi) * fx1 + xi * fx2;
        let thy = d1 * fy1 + d2 * fy2;
        let thz = d1 * fz1 + d2 * fz2;
        let ra = m3_vec(tc, vec3<real>(0.0, uy, uz));
        let rb = m3_vec(tc, vec3<real>(-thz, 1.0, thx));
        let rc = m3_vec(tc, vec3<real>(thy, -thx, 1.0));
        for (var j = 0u; j < 12u; j++) {
            let dth = vec3<real>(g.dtheta[0][j].x, g.dtheta[1][j].x, g.dtheta[2][j].x);
            let dp0 = g.dphi[0][j].x;
            let dp1 = g.dphi[1][j].x;
            let dp2 = g.dphi[2][j].x;
            let dp3 = g.dphi[3][j].x;
            let dp4 = g.dphi[4][j].x;
            let dp5 = g.dphi[5][j].x;
            let dl = g.dlen[j].x;
            let duy = dl * (n1 * fz1 + n2 * fz2) + len * (n1 * dp2 + n2 * dp5);
            let duz = -(dl * (n1 * fy1 + n2 * fy2) + len * (n1 * dp1 + n2 * dp4));
            let dthx = (1.0 - xi) * dp0 + xi * dp3;
            let dthy = d1 * dp1 + d2 * dp4;
            let dthz = d1 * dp2 + d2 * dp5;
            var da = cross3(dth, ra) + m3_vec(tc, vec3<real>(0.0, duy, duz));
            if j < 3u {
                da[j] += 1.0 - xi;
            } else if j >= 6u && j < 9u {
                da[j - 6u] += xi;
            }
            let db = cross3(dth, rb) + m3_vec(tc, vec3<real>(-dthz, 0.0, dthx));
            let dcv = cross3(dth, rc) + m3_vec(tc, vec3<real>(dthy, -dthx, 0.0));
            gr[j][gp][0] = da;
            gr[j][gp][1] = db;
            gr[j][gp][2] = dcv;
        }
    }
}

// kinematics::perturb: node position and frame along two directions (da, db) of that node
fn perturb_h(x: array<real, 3>, t: M3, da: array<real, 6>, db: array<real, 6>) -> HM {
    let wa = vec3<real>(da[3], da[4], da[5]);
    let wb = vec3<real>(db[3], db[4], db[5]);
    var tp: HM;
    for (var j = 0u; j < 3u; j++) {
        let tj = m3_col(t, j);
        let a = cross3(wa, tj);
        let b = cross3(wb, tj);
        let ab = cross3(wa, b);
        let ba = cross3(wb, a);
        for (var i = 0u; i < 3u; i++) {
            tp[i][j] = H(tj[i], a[i], b[i], 0.5 * (ab[i] + ba[i]));
        }
    }
    return tp;
}

// inertia::field_derivs: the ab parts of the position fields at the Gauss points into `hh`
fn field_derivs(ed: ElemData, inp: ElemIn, t1: M3, t2: M3, da: array<real, 12>, db: array<real, 12>) {
    let u1 = HV(H(inp.u1[0], da[0], db[0], 0.0), H(inp.u1[1], da[1], db[1], 0.0), H(inp.u1[2], da[2], db[2], 0.0));
    let u2 = HV(H(inp.u2[0], da[6], db[6], 0.0), H(inp.u2[1], da[7], db[7], 0.0), H(inp.u2[2], da[8], db[8], 0.0));
    let tt1 = perturb_h(inp.u1, t1, array<real, 6>(da[0], da[1], da[2], da[3], da[4], da[5]), array<real, 6>(db[0], db[1], db[2], db[3], db[4], db[5]));
    let tt2 = perturb_h(inp.u2, t2, array<real, 6>(da[6], da[7], da[8], da[9], da[10], da[11]), array<real, 6>(db[6], db[7], db[8], db[9], db[10], db[11]));
    let k = kin_h(ed.chord0, ed.l0, u1, u2, tt1, tt2);
    let c0 = HV(hc(ed.chord0[0]), hc(ed.chord0[1]), hc(ed.chord0[2]));
    let chord = hv_add(c0, hv_sub(u2, u1));
    let fx1 = k.phi[0];
    let fy1 = k.phi[1];
    let fz1 = k.phi[2];
    let fx2 = k.phi[3];
    let fy2 = k.phi[4];
    let fz2 = k.phi[5];
    for (var gp = 0u; gp < 4u; gp++) {
        // kinematics::section_fields
        let xi = GAUSS_X[gp];
        let n1 = xi - 2.0 * xi * xi + xi * xi * xi;
        let n2 = -xi * xi + xi * xi * xi;
        let d1 = 1.0 - 4.0 * xi + 3.0 * xi * xi;
        let d2 = -2.0 * xi + 3.0 * xi * xi;
        let uy = hmul(k.len, n1 * fz1 + n2 * fz2);
        let uz = -hmul(k.len, n1 * fy1 + n2 * fy2);
        let thx = (1.0 - xi) * fx1 + xi * fx2;
        let thy = d1 * fy1 + d2 * fy2;
        let thz = d1 * fz1 + d2 * fz2;
        let zero = hc(0.0);
        let one = hc(1.0);
        let a = hv_add(hv_add(u1, hv_scale(chord, hc(xi))), hm_vec(k.tc, HV(zero, uy, uz)));
        let b = hm_vec(k.tc, HV(-thz, one, thx));
        let c = hm_vec(k.tc, HV(thy, -thx, one));
        hh[gp][0] = vec3<real>(a[0].w, a[1].w, a[2].w);
        hh[gp][1] = vec3<real>(b[0].w, b[1].w, b[2].w);
        hh[gp][2] = vec3<real>(c[0].w, c[1].w, c[2].w);
    }
}

// Σ_gp Σ_field w_gp μ_field g_j · hh, times l0 (inertia::inertia_columns.s `project`)
fn project(j: u32, wv: array<real, 3>, l0: real, scale: real) -> real {
    var w = wv;
    var acc: real = 0.0;
    for (var gp = 0u; gp < 4u; gp++) {
        let wg = GAUSS_W[gp];
        for (var f = 0u; f < 3u; f++) {
            acc += wg * w[f] * dot3(gr[j][gp][f], hh[gp][f]);
        }
    }
    return scale * acc * l0;
}

// ---- kernel entry: everything below is this kernel's own (bindings and main); the
// residual kernel (beam_residual.wgsl) includes only the functions above.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> elems: array<ElemData>;
@group(0) @binding(2) var<storage, read> inputs: array<ElemIn>;
@group(0) @binding(3) var<storage, read_write> inertia_out: array<InertiaOut>;
@group(0) @binding(4) var<storage, read> index: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let ie = gid.x;
    if ie >= params.n_elem {
        return;
    }
    let ed = elems[index[ie]];
    let inp = inputs[ie];
    let f0 = m3_load(ed.frame0);
    let t1 = m3_mul(m3_load(inp.r1), f0);
    let t2 = m3_mul(m3_load(inp.r2), f0);
    // μ-weights of the fields: ρA for a, ρI_z for b, ρI_y for c
    var w = array<real, 3>(ed.props[4], ed.props[6], ed.props[5]);
    gradients_closed(ed, inp, t1, t2);
    for (var j = 0u; j < 12u; j++) {
        for (var k = j; k < 12u; k++) {
            var acc: real = 0.0;
            for (var gp = 0u; gp < 4u; gp++) {
                let wg = GAUSS_W[gp];
                for (var f = 0u; f < 3u; f++) {
                    acc += wg * w[f] * dot3(gr[j][gp][f], gr[k][gp][f]);
                }
            }
            inertia_out[ie].m[j * 12u + k] = acc * ed.l0;
            inertia_out[ie].m[k * 12u + j] = acc * ed.l0;
        }
    }
    var v = inp.v12;
    field_derivs(ed, inp, t1, t2, v, v);
    for (var j = 0u; j < 12u; j++) {
        inertia_out[ie].s[j] = project(j, w, ed.l0, 1.0);
    }
    var moving = false;
    for (var j = 0u; j < 12u; j++) {
        moving = moving || v[j] != 0.0;
    }
    for (var k = 0u; k < 12u; k++) {
        if moving {
            var ek: array<real, 12>;
            ek[k] = 1.0;
            field_derivs(ed, inp, t1, t2, v, ek);
        }
        for (var j = 0u; j < 12u; j++) {
            var cjk: real = 0.0;
            if moving {
                cjk = project(j, w, ed.l0, 2.0);
            }
            inertia_out[ie].c[j * 12u + k] = cjk;
        }
    }
}
