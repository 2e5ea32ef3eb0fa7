// Consistent mass matrix M, quadratic-velocity vector S and its velocity derivative C of
// every element: the WGSL twin of inertia::inertia_full (src/element/inertia.rs), the CPU's
// production route, function by function: the field-gradient rows g (and their time
// derivatives ġ) from one dual-number pass of the closed-form gradient along the nodal
// velocities (GradRows::new: beam_common's gradient_d, then `field_rows_d`; `gradient` and
// `field_rows` when the element is at rest), M = Σ w gᵀg (`mass_from_rows`),
// C = 2P + M·blockdiag(0, skew ω1, 0, skew ω2) with P = Σ w gᵀġ, and S from one hyper-dual
// pass of the position fields along (v, v) (`field_derivs`, GradRows::quadratic).
// inertia_full's inertial forces M·acc + S and M·v are formed by the host from M and S
// (ElemOut::products_from_m: the full kernel gets no accelerations); the residual kernel
// forms them as the CPU does (`mass_times`, `forces_from_rows`).
//
// One invocation per element. The reference route (one hyper-dual pass per column of C,
// reference::inertia_columns) is what this kernel mirrored before. Every output word is
// written on every dispatch, no atomics. (beam_common.wgsl is prepended by the host; the
// residual kernel includes the functions above the entry marker.)

struct InertiaOut {
    m: array<real, 144>, // row-major
    s: array<real, 12>,
    c: array<real, 144>, // row-major
}

// GradRows: the field gradients g and their rates ġ as 36 rows (Gauss point, field,
// component) of 12 dofs, and the μ-weights of the rows
var<private> rows_g: array<array<real, 12>, 36>;
var<private> rows_gd: array<array<real, 12>, 36>;
var<private> rows_w: array<real, 36>;
// second derivatives H[gp][field] of one hyper-dual pass (field_derivs)
var<private> hh: array<array<vec3<real>, 3>, 4>;
// the mass matrix of the invocation's element (mass_from_rows)
var<private> mm: array<array<real, 12>, 12>;

// inertia::field_weights: ρA for a, ρI_z for b, ρI_y for c
fn field_weights(p: array<real, 7>) -> vec3<real> {
    return vec3<real>(p[4], p[6], p[5]);
}

// the row weights of GradRows::new / from_gradient: GAUSS_W[gp] · μ_field · l0
fn row_weights(ed: ElemData) {
    let wf = field_weights(ed.props);
    for (var q = 0u; q < 36u; q++) {
        rows_w[q] = GAUSS_W[q / 9u] * wf[(q / 3u) % 3u] * ed.l0;
    }
}

// Hermite shape values at station ξ: n1, n2, d1, d2 (kinematics::section_fields)
fn shape(xi: real) -> vec4<real> {
    return vec4<real>(
        xi - 2.0 * xi * xi + xi * xi * xi,
        -xi * xi + xi * xi * xi,
        1.0 - 4.0 * xi + 3.0 * xi * xi,
        -2.0 * xi + 3.0 * xi * xi,
    );
}

// inertia::field_rows: g_j = ∂(a, b, c)/∂q_j at the Gauss points from the gradient, into rows_g
fn field_rows(gv: Grad) {
    var g = gv;
    var tc = g.kin.tc;
    let fx1 = g.kin.phi[0];
    let fy1 = g.kin.phi[1];
    let fz1 = g.kin.phi[2];
    let fx2 = g.kin.phi[3];
    let fy2 = g.kin.phi[4];
    let fz2 = g.kin.phi[5];
    let len = g.kin.len;
    for (var gp = 0u; gp < 4u; gp++) {
        let xi = GAUSS_X[gp];
        let sh = shape(xi);
        let n1 = sh[0];
        let n2 = sh[1];
        let d1 = sh[2];
        let d2 = sh[3];
        let c0 = 1.0 - xi;
        let c1 = xi;
        let wz = n1 * fz1 + n2 * fz2;
        let wy = n1 * fy1 + n2 * fy2;
        let uy = len * wz;
        let uz = -(len * wy);
        let thx = c0 * fx1 + c1 * fx2;
        let thy = d1 * fy1 + d2 * fy2;
        let thz = d1 * fz1 + d2 * fz2;
        // current field offsets in the convected frame (ad::mvec)
        var ra: vec3<real>;
        var rb: vec3<real>;
        var rc: vec3<real>;
        for (var r = 0u; r < 3u; r++) {
            ra[r] = tc[r][0] * 0.0 + tc[r][1] * uy + tc[r][2] * uz;
            rb[r] = tc[r][0] * (-thz) + tc[r][1] * 1.0 + tc[r][2] * thx;
            rc[r] = tc[r][0] * thy + tc[r][1] * (-thx) + tc[r][2] * 1.0;
        }
        for (var j = 0u; j < 12u; j++) {
            let duy = g.dlen[j] * wz + len * (n1 * g.dphi[2][j] + n2 * g.dphi[5][j]);
            let duz = -(g.dlen[j] * wy + len * (n1 * g.dphi[1][j] + n2 * g.dphi[4][j]));
            let dthx = c0 * g.dphi[0][j] + c1 * g.dphi[3][j];
            let dthy = d1 * g.dphi[1][j] + d2 * g.dphi[4][j];
            let dthz = d1 * g.dphi[2][j] + d2 * g.dphi[5][j];
            // δa = δθ_C × ra + T_C [0, δu_y, δu_z] (+ the chord share below),
            // δb = δθ_C × rb + T_C [−δθz, 0, δθx], δc = δθ_C × rc + T_C [δθy, −δθx, 0]
            for (var c = 0u; c < 3u; c++) {
                let p = (c + 1u) % 3u;
                let q = (c + 2u) % 3u;
                let base = 9u * gp + c;
                let dp = g.dtheta[p][j];
                let dq = g.dtheta[q][j];
                rows_g[base][j] = (dp * ra[q] - dq * ra[p])
                    + (tc[c][0] * 0.0 + tc[c][1] * duy + tc[c][2] * duz);
                rows_g[base + 3u][j] = (dp * rb[q] - dq * rb[p])
                    + (tc[c][0] * (-dthz) + tc[c][1] * 0.0 + tc[c][2] * dthx);
                rows_g[base + 6u][j] = (dp * rc[q] - dq * rc[p])
                    + (tc[c][0] * dthy + tc[c][1] * (-dthx) + tc[c][2] * 0.0);
            }
        }
        for (var c = 0u; c < 3u; c++) {
            rows_g[9u * gp + c][c] = rows_g[9u * gp + c][c] + c0;
            rows_g[9u * gp + c][6u + c] = rows_g[9u * gp + c][6u + c] + c1;
        }
    }
}

// inertia::field_rows in dual numbers (from gradient_d along the nodal velocities): the
// value parts into rows_g, the derivative parts (ġ) into rows_gd
fn field_rows_d(gv: GradD) {
    var g = gv;
    var tc = g.kin.tc;
    let fx1 = g.kin.phi[0];
    let fy1 = g.kin.phi[1];
    let fz1 = g.kin.phi[2];
    let fx2 = g.kin.phi[3];
    let fy2 = g.kin.phi[4];
    let fz2 = g.kin.phi[5];
    let len = g.kin.len;
    let z = dc(0.0);
    for (var gp = 0u; gp < 4u; gp++) {
        let xi = GAUSS_X[gp];
        let sh = shape(xi);
        let n1 = sh[0];
        let n2 = sh[1];
        let d1 = sh[2];
        let d2 = sh[3];
        let c0 = 1.0 - xi;
        let c1 = xi;
        let wz = n1 * fz1 + n2 * fz2;
        let wy = n1 * fy1 + n2 * fy2;
        let uy = dmul(len, wz);
        let uz = -dmul(len, wy);
        let thx = c0 * fx1 + c1 * fx2;
        let thy = d1 * fy1 + d2 * fy2;
        let thz = d1 * fz1 + d2 * fz2;
        var ra: DV;
        var rb: DV;
        var rc: DV;
        for (var r = 0u; r < 3u; r++) {
            ra[r] = dmul(tc[r][0], z) + dmul(tc[r][1], uy) + dmul(tc[r][2], uz);
            rb[r] = dmul(tc[r][0], -thz) + tc[r][1] + dmul(tc[r][2], thx);
            rc[r] = dmul(tc[r][0], thy) + dmul(tc[r][1], -thx) + tc[r][2];
        }
        for (var j = 0u; j < 12u; j++) {
            let duy = dmul(g.dlen[j], wz) + dmul(len, n1 * g.dphi[2][j] + n2 * g.dphi[5][j]);
            let duz = -(dmul(g.dlen[j], wy) + dmul(len, n1 * g.dphi[1][j] + n2 * g.dphi[4][j]));
            let dthx = c0 * g.dphi[0][j] + c1 * g.dphi[3][j];
            let dthy = d1 * g.dphi[1][j] + d2 * g.dphi[4][j];
            let dthz = d1 * g.dphi[2][j] + d2 * g.dphi[5][j];
            for (var c = 0u; c < 3u; c++) {
                let p = (c + 1u) % 3u;
                let q = (c + 2u) % 3u;
                let base = 9u * gp + c;
                let dp = g.dtheta[p][j];
                let dq = g.dtheta[q][j];
                let a = (dmul(dp, ra[q]) - dmul(dq, ra[p]))
                    + (dmul(tc[c][0], z) + dmul(tc[c][1], duy) + dmul(tc[c][2], duz));
                let b = (dmul(dp, rb[q]) - dmul(dq, rb[p]))
                    + (dmul(tc[c][0], -dthz) + dmul(tc[c][1], z) + dmul(tc[c][2], dthx));
                let cc = (dmul(dp, rc[q]) - dmul(dq, rc[p]))
                    + (dmul(tc[c][0], dthy) + dmul(tc[c][1], -dthx) + dmul(tc[c][2], z));
                rows_g[base][j] = a.x;
                rows_gd[base][j] = a.y;
                rows_g[base + 3u][j] = b.x;
                rows_gd[base + 3u][j] = b.y;
                rows_g[base + 6u][j] = cc.x;
                rows_gd[base + 6u][j] = cc.y;
            }
        }
        for (var c = 0u; c < 3u; c++) {
            rows_g[9u * gp + c][c] = rows_g[9u * gp + c][c] + c0;
            rows_g[9u * gp + c][6u + c] = rows_g[9u * gp + c][6u + c] + c1;
        }
    }
}

// inertia::mass_from_rows: M = Σ_q w_q g_qᵀ g_q, row j accumulated over the 36 rows; the
// CPU copies the upper triangle onto the lower, so only k ≥ j is formed here and mirrored
fn mass_from_rows() {
    for (var j = 0u; j < 12u; j++) {
        var acc: array<real, 12>;
        for (var r = 0u; r < 36u; r++) {
            let a = rows_w[r] * rows_g[r][j];
            for (var k = j; k < 12u; k++) {
                acc[k] = acc[k] + a * rows_g[r][k];
            }
        }
        for (var k = j; k < 12u; k++) {
            mm[j][k] = acc[k];
            mm[k][j] = acc[k];
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

// GradRows::quadratic: S = Σ_q w_q g_q H_q(v, v), from one hyper-dual pass (field_derivs);
// zero at rest
fn quadratic(ed: ElemData, inp: ElemIn, t1: M3, t2: M3, vv: array<real, 12>) -> array<real, 12> {
    var v = vv;
    var sv: array<real, 12>;
    var moving = false;
    for (var j = 0u; j < 12u; j++) {
        moving = moving || v[j] != 0.0;
    }
    if !moving {
        return sv;
    }
    field_derivs(ed, inp, t1, t2, v, v);
    for (var q = 0u; q < 36u; q++) {
        let a = rows_w[q] * hh[q / 9u][(q / 3u) % 3u][q % 3u];
        for (var k = 0u; k < 12u; k++) {
            sv[k] = sv[k] + a * rows_g[q][k];
        }
    }
    return sv;
}

// ---- kernel entry: everything below is this kernel's own (bindings and main); the
// residual kernel (beam_residual.wgsl) includes only the functions above.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> elems: array<ElemData>;
@group(0) @binding(2) var<storage, read> inputs: array<ElemIn>;
@group(0) @binding(3) var<storage, read_write> inertia_out: array<InertiaOut>;
@group(0) @binding(4) var<storage, read> index: array<u32>;

// inertia::inertia_full (M, S, C), one invocation per element
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let ie = gid.x;
    if ie >= params.n_elem {
        return;
    }
    let ed = elems[index[ie]];
    let inp = inputs[ie];
    // kinematics::node_frames
    let f0 = m3_load(ed.frame0);
    let t1 = m3_mul(m3_load(inp.r1), f0);
    let t2 = m3_mul(m3_load(inp.r2), f0);
    let u1 = vec3<real>(inp.u1[0], inp.u1[1], inp.u1[2]);
    let u2 = vec3<real>(inp.u2[0], inp.u2[1], inp.u2[2]);
    var v = inp.v12;
    var moving = false;
    for (var j = 0u; j < 12u; j++) {
        moving = moving || v[j] != 0.0;
    }
    // GradRows::new: g and ġ from one dual pass along v, or g alone at rest
    row_weights(ed);
    if moving {
        let n1 = perturb_dual(u1, t1, array<real, 6>(v[0], v[1], v[2], v[3], v[4], v[5]));
        let n2 = perturb_dual(u2, t2, array<real, 6>(v[6], v[7], v[8], v[9], v[10], v[11]));
        field_rows_d(gradient_d(ed.chord0, ed.l0, n1.x, n2.x, n1.t, n2.t));
    } else {
        field_rows(gradient(ed.chord0, ed.l0, u1, u2, t1, t2));
    }
    mass_from_rows();
    for (var j = 0u; j < 12u; j++) {
        for (var k = 0u; k < 12u; k++) {
            inertia_out[ie].m[j * 12u + k] = mm[j][k];
        }
    }
    // C = 2 Σ_q w_q g_qᵀ ġ_q + M · blockdiag(0, skew ω1, 0, skew ω2); zero at rest
    for (var j = 0u; j < 12u; j++) {
        var cj: array<real, 12>;
        if moving {
            for (var r = 0u; r < 36u; r++) {
                let a = 2.0 * rows_w[r] * rows_g[r][j];
                for (var k = 0u; k < 12u; k++) {
                    cj[k] = cj[k] + a * rows_gd[r][k];
                }
            }
            for (var node = 0u; node < 2u; node++) {
                let o = 6u * node + 3u;
                // crate::math::skew(ω)
                var sk = M3(
                    array<real, 3>(0.0, -v[o + 2u], v[o + 1u]),
                    array<real, 3>(v[o + 2u], 0.0, -v[o]),
                    array<real, 3>(-v[o + 1u], v[o], 0.0),
                );
                for (var k = 0u; k < 3u; k++) {
                    cj[o + k] = cj[o + k]
                        + (mm[j][o] * sk[0][k] + mm[j][o + 1u] * sk[1][k] + mm[j][o + 2u] * sk[2][k]);
                }
            }
        }
        for (var k = 0u; k < 12u; k++) {
            inertia_out[ie].c[j * 12u + k] = cj[k];
        }
    }
    inertia_out[ie].s = quadratic(ed, inp, t1, t2, v);
}
