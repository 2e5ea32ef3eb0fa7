// Internal force f, consistent tangent K and strain energy of every element: the WGSL twin
// of force::internal_force_tangent_energy (src/element/force.rs), the CPU's production
// route, function by function: beam_common's `gradient` (force::gradient, closed form),
// `energy_partials`, `force_from`, `tangent` (K = Bᵀ H B + N D∂ℓ + Σ m_a D∂φ_a in closed
// form, from the convected-frame spin derivatives) and `energy` (kinematics::energy).
//
// One invocation per element, in plain `real` arithmetic (no dual numbers): the dual
// derivative of the force, column by column, is the reference route
// (reference::internal_force_tangent_dual), which this kernel mirrored before. Every output
// word is written on every dispatch, no atomics. (beam_common.wgsl is prepended by the
// host; the residual kernel includes the functions above the entry marker.)

struct ForceOut {
    f: array<real, 12>,
    k: array<real, 144>, // row-major K[r][c]
    energy: real,
    pad: array<real, 3>,
}

alias A12 = array<real, 12>;

// force::energy_partials: ∂U/∂φ (6) and the axial force N = ∂U/∂ℓ (last entry)
fn energy_partials(p: array<real, 7>, l0: real, k: Kin) -> array<real, 7> {
    let fx1 = k.phi[0];
    let fy1 = k.phi[1];
    let fz1 = k.phi[2];
    let fx2 = k.phi[3];
    let fy2 = k.phi[4];
    let fz2 = k.phi[5];
    let t = (p[3] / l0) * (fx2 - fx1);
    let cy = 2.0 * p[1] / l0;
    let cz = 2.0 * p[2] / l0;
    let n = (p[0] / l0) * stretch(l0, k);
    let g = n * (l0 / 30.0);
    // the section's axes turned (kinematics::SectionTurn)
    let st = section_turn(k.phi);
    let dc = (p[1] - p[2]) / l0;
    let ay = dc * st[1];
    let az = dc * st[2];
    let y1 = 2.0 * fy1 + fy2;
    let y2 = fy1 + 2.0 * fy2;
    let z1 = 2.0 * fz1 + fz2;
    let z2 = fz1 + 2.0 * fz2;
    let by = fy1 * fy1 + fy1 * fy2 + fy2 * fy2;
    let bz = fz1 * fz1 + fz1 * fz2 + fz2 * fz2;
    let dpsi = TURN_SHARE * dc * (st[3] * (by - bz) + st[4] * st[7]);
    return array<real, 7>(
        dpsi - t,
        cy * y1 + g * (4.0 * fy1 - fy2) + (ay * y1 + az * z1),
        cz * z1 + g * (4.0 * fz1 - fz2) + (az * y1 - ay * z1),
        t + dpsi,
        cy * y2 + g * (4.0 * fy2 - fy1) + (ay * y2 + az * z2),
        cz * z2 + g * (4.0 * fz2 - fz1) + (az * y2 - ay * z2),
        n,
    );
}

// force::force_from: f_j = N ∂ℓ/∂q_j + Σ_a m_a ∂φ_a/∂q_j
fn force_from(gv: Grad, mv: array<real, 7>) -> A12 {
    var g = gv;
    var m = mv;
    var f: A12;
    for (var j = 0u; j < 12u; j++) {
        var acc = m[6] * g.dlen[j];
        for (var a = 0u; a < 6u; a++) {
            acc = acc + m[a] * g.dphi[a][j];
        }
        f[j] = acc;
    }
    return f;
}

// K of the invocation's element (force::tangent accumulates into its local k)
var<private> kk: array<array<real, 12>, 12>;

// force::rank1: K += a bᵀ over the rows r0..r1
fn rank1(r0: u32, r1: u32, av: A12, bv: A12) {
    var a = av;
    var b = bv;
    for (var r = r0; r < r1; r++) {
        let ar = a[r];
        for (var c = 0u; c < 12u; c++) {
            kk[r][c] = kk[r][c] + ar * b[c];
        }
    }
}

// force::tangent: the closed-form K from the gradient and the energy partials (m, N), into kk
fn tangent(p: array<real, 7>, l0: real, gv: Grad, mv: array<real, 7>) {
    var g = gv;
    var m = mv;
    let n = m[6];
    for (var r = 0u; r < 12u; r++) {
        for (var c = 0u; c < 12u; c++) {
            kk[r][c] = 0.0;
        }
    }
    var phi = g.kin.phi;
    // material part
    let c30 = l0 / 30.0;
    let h = array<real, 6>(
        0.0,
        c30 * (4.0 * phi[1] - phi[4]),
        c30 * (4.0 * phi[2] - phi[5]),
        0.0,
        c30 * (4.0 * phi[4] - phi[1]),
        c30 * (4.0 * phi[5] - phi[2]),
    );
    var ds: A12;
    var eads: A12;
    let ea = p[0] / l0;
    for (var j = 0u; j < 12u; j++) {
        ds[j] = g.dlen[j] + h[1] * g.dphi[1][j] + h[2] * g.dphi[2][j] + h[4] * g.dphi[4][j]
            + h[5] * g.dphi[5][j];
        eads[j] = ea * ds[j];
    }
    rank1(0u, 12u, ds, eads);
    var tw: A12;
    var gjtw: A12;
    let gj = p[3] / l0;
    for (var j = 0u; j < 12u; j++) {
        tw[j] = g.dphi[3][j] - g.dphi[0][j];
        gjtw[j] = gj * tw[j];
    }
    rank1(0u, 12u, tw, gjtw);
    let gn = n * c30;
    // the section's axes turned (kinematics::SectionTurn): stiffnesses Cy + ΔC α and
    // Cz − ΔC α, the planes' cross term ΔC β h and the couplings with ψ
    let st = section_turn(phi);
    let dc = (p[1] - p[2]) / l0;
    let cross = dc * st[2];
    var dpsi: A12;
    for (var j = 0u; j < 12u; j++) {
        dpsi[j] = TURN_SHARE * (g.dphi[0][j] + g.dphi[3][j]);
    }
    let y1 = 2.0 * phi[1] + phi[4];
    let y2 = phi[1] + 2.0 * phi[4];
    let z1 = 2.0 * phi[2] + phi[5];
    let z2 = phi[2] + 2.0 * phi[5];
    // ∂²U/∂ψ ∂φ for φy1, φz1, φy2, φz2
    let q = array<real, 4>(
        dc * (st[3] * y1 + st[4] * z1),
        dc * (st[4] * y1 - st[3] * z1),
        dc * (st[3] * y2 + st[4] * z2),
        dc * (st[4] * y2 - st[3] * z2),
    );
    let by = phi[1] * phi[1] + phi[1] * phi[4] + phi[4] * phi[4];
    let bz = phi[2] * phi[2] + phi[2] * phi[5] + phi[5] * phi[5];
    let hpp = dc * (st[5] * (by - bz) + st[6] * st[7]);
    let sgn = array<real, 2>(1.0, -1.0);
    for (var plane = 0u; plane < 2u; plane++) {
        // (2EI_y/L0, φy1, φy2), then (2EI_z/L0, φz1, φz2), turned
        let c = 2.0 * p[1u + plane] / l0 + sgn[plane] * dc * st[1];
        let a1 = 1u + plane;
        let a2 = 4u + plane;
        let o1 = 2u - plane;
        let o2 = 5u - plane;
        let d11 = 2.0 * c + 4.0 * gn;
        let d12 = c - gn;
        let e11 = 2.0 * cross;
        let e12 = cross;
        let q1 = q[plane];
        let q2 = q[2u + plane];
        var r1: A12;
        var r2: A12;
        for (var j = 0u; j < 12u; j++) {
            r1[j] = d11 * g.dphi[a1][j] + d12 * g.dphi[a2][j] + e11 * g.dphi[o1][j]
                + e12 * g.dphi[o2][j] + q1 * dpsi[j];
            r2[j] = d12 * g.dphi[a1][j] + d11 * g.dphi[a2][j] + e12 * g.dphi[o1][j]
                + e11 * g.dphi[o2][j] + q2 * dpsi[j];
        }
        rank1(0u, 12u, g.dphi[a1], r1);
        rank1(0u, 12u, g.dphi[a2], r2);
    }
    // ψ's row
    var prow: A12;
    for (var j = 0u; j < 12u; j++) {
        prow[j] = q[0] * g.dphi[1][j] + q[1] * g.dphi[2][j] + q[2] * g.dphi[4][j]
            + q[3] * g.dphi[5][j] + hpp * dpsi[j];
    }
    rank1(0u, 12u, dpsi, prow);
    // geometric part: the moments' share, Σ_i ψ_iᵀ A_i ψ_i + the rotation rows' −(c × ν_i)·Θ
    // (ε_m = T_Cᵀ x̂_m is row m of T_C)
    var tc = g.kin.tc;
    var nu = vec3<real>(0.0, 0.0, 0.0);
    for (var i = 0u; i < 2u; i++) {
        let mu = vec3<real>(m[3u * i], m[3u * i + 1u], m[3u * i + 2u]);
        let ph = vec3<real>(phi[3u * i], phi[3u * i + 1u], phi[3u * i + 2u]);
        var d = g.rel[i];
        // G_iᵀ μ_i = ½(tr D μ − Dᵀ μ)
        let tr = d[0][0] + d[1][1] + d[2][2];
        var nui: vec3<real>;
        for (var c = 0u; c < 3u; c++) {
            nui[c] = 0.5 * (tr * mu[c] - (d[0][c] * mu[0] + d[1][c] * mu[1] + d[2][c] * mu[2]));
        }
        // A = −μ φᵀ − ½ Dᵀ skew(μ)
        var sk = M3(
            array<real, 3>(0.0, -mu[2], mu[1]),
            array<real, 3>(mu[2], 0.0, -mu[0]),
            array<real, 3>(-mu[1], mu[0], 0.0),
        );
        var a: M3;
        for (var r = 0u; r < 3u; r++) {
            for (var c = 0u; c < 3u; c++) {
                a[r][c] = -(mu[r] * ph[c])
                    - 0.5 * (d[0][r] * sk[0][c] + d[1][r] * sk[1][c] + d[2][r] * sk[2][c]);
            }
        }
        for (var r = 0u; r < 3u; r++) {
            var pr: A12;
            for (var j = 0u; j < 12u; j++) {
                pr[j] = a[r][0] * g.psi[i][0][j] + a[r][1] * g.psi[i][1][j] + a[r][2] * g.psi[i][2][j];
            }
            rank1(0u, 12u, g.psi[i][r], pr);
        }
        // rows of node i's spins: −(ε_m × ν_i) · Θ_k
        for (var mm = 0u; mm < 3u; mm++) {
            let c = cross3(vec3<real>(tc[mm][0], tc[mm][1], tc[mm][2]), nui);
            let row = 6u * i + 3u + mm;
            for (var j = 0u; j < 12u; j++) {
                kk[row][j] = kk[row][j] - (c[0] * g.spin[0][j] + c[1] * g.spin[1][j] + c[2] * g.spin[2][j]);
            }
        }
        nu = vec3<real>(nu[0] + nui[0], nu[1] + nui[1], nu[2] + nui[2]);
    }
    // D_k(a/b): a/b = n_x/n_y, n = D_1 ŷ in convected components, D_k n = ψ_1k × n
    let nc = vec3<real>(g.rel[0][0][1], g.rel[0][1][1], g.rel[0][2][1]);
    let ab = g.ab;
    let inc = 1.0 / nc[1];
    var dab: A12;
    for (var j = 0u; j < 12u; j++) {
        let cx = g.psi[0][1][j] * nc[2] - g.psi[0][2][j] * nc[1];
        let cy = g.psi[0][2][j] * nc[0] - g.psi[0][0][j] * nc[2];
        dab[j] = (cx - ab * cy) * inc;
    }
    // the translation rows: N D_k ∂ℓ_j − ν · D_k Θ_j as three rank-one terms
    let il = 1.0 / g.kin.len;
    let il2 = il * il;
    let alpha = nu[0] * ab + nu[1];
    var ev: A12;
    var c2: A12;
    var c3: A12;
    for (var mm = 0u; mm < 3u; mm++) {
        ev[mm] = -tc[mm][0];
        c2[mm] = -tc[mm][1];
        c3[mm] = -tc[mm][2];
        ev[6u + mm] = tc[mm][0];
        c2[6u + mm] = tc[mm][1];
        c3[6u + mm] = tc[mm][2];
    }
    let nx = nu[0];
    let nz = nu[2];
    var be: A12;
    var b2: A12;
    var b3: A12;
    for (var j = 0u; j < 12u; j++) {
        let sx = g.spin[0][j];
        let sy = g.spin[1][j];
        let sz = g.spin[2][j];
        be[j] = (alpha * sy + nz * sz) * il;
        b2[j] = n * sz - alpha * sx * il + nz * g.dlen[j] * il2;
        b3[j] = -(n * sy) - nz * sx * il - alpha * g.dlen[j] * il2 + nx * dab[j] * il;
    }
    for (var blk = 0u; blk < 2u; blk++) {
        let r0 = 6u * blk;
        rank1(r0, r0 + 3u, ev, be);
        rank1(r0, r0 + 3u, c2, b2);
        rank1(r0, r0 + 3u, c3, b3);
    }
    // node 1's spin rows: θx_j = e_m − (a/b) t_c2,m, so −ν_x D_k θx_j
    var r_e: A12;
    var r_2: A12;
    var r_3: A12;
    for (var j = 0u; j < 12u; j++) {
        r_e[j] = -(nx * ab * g.spin[2][j]);
        r_2[j] = -(nx * (g.spin[2][j] - dab[j]));
        r_3[j] = nx * (g.spin[1][j] + ab * g.spin[0][j]);
    }
    for (var mm = 0u; mm < 3u; mm++) {
        let row = 3u + mm;
        for (var j = 0u; j < 12u; j++) {
            kk[row][j] = kk[row][j] + (tc[mm][0] * r_e[j] + tc[mm][1] * r_2[j] + tc[mm][2] * r_3[j]);
        }
    }
}

// ---- kernel entry: everything below is this kernel's own (bindings and main); the
// residual kernel (beam_residual.wgsl) includes only the functions above.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> elems: array<ElemData>;
@group(0) @binding(2) var<storage, read> inputs: array<ElemIn>;
@group(0) @binding(3) var<storage, read_write> force_out: array<ForceOut>;
// table slot of each element of the batch (the model's data stays on the device)
@group(0) @binding(4) var<storage, read> index: array<u32>;

// force::internal_force_tangent_energy, one invocation per element
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
    let g = gradient(ed.chord0, ed.l0, u1, u2, t1, t2);
    let mn = energy_partials(ed.props, ed.l0, g.kin);
    force_out[ie].f = force_from(g, mn);
    tangent(ed.props, ed.l0, g, mn);
    for (var r = 0u; r < 12u; r++) {
        for (var c = 0u; c < 12u; c++) {
            force_out[ie].k[r * 12u + c] = kk[r][c];
        }
    }
    force_out[ie].energy = energy(ed.props, ed.l0, g.kin);
    force_out[ie].pad = array<real, 3>(0.0, 0.0, 0.0);
}
