// Residual-only evaluation for modified-Newton iterations (ElementEval::evaluate_residual):
// the internal force f and the strain energy, and when asked the inertial force
// finert = M·acc + S and M·v12, but neither K nor M, S's derivative C: the WGSL twin of
// CpuEval::one_residual (force::internal_force, inertia::inertia_residual).
//
// One invocation per element. f is the force kernel's value part (gradient_d with no
// perturbation: the derivative lanes stay zero). M is never formed: M·x = ∫μ gᵀ(g·x), so
// the field rates g·acc and g·v12 at the four Gauss points are formed first (12 products
// per field) and projected on each gradient, as the CPU's inertia_residual does. S is the
// inertia kernel's one hyper-dual pass along (v, v). The 12 hyper-dual passes of C, the
// inertia kernel's main cost, and the 12 dual columns of K are skipped, and the download is
// 52 words per element instead of 460. (beam_common.wgsl and the functions of
// beam_force.wgsl and beam_inertia.wgsl are prepended by the host.)

struct ResidualOut {
    f: array<real, 12>,
    s: array<real, 12>,
    finert: array<real, 12>,
    mv: array<real, 12>,
    energy: real,
    pad: array<real, 3>,
}

// nodal accelerations of one element (ElemIn::acc), uploaded only for this kernel
struct Acc {
    a: array<real, 12>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> elems: array<ElemData>;
@group(0) @binding(2) var<storage, read> inputs: array<ElemIn>;
@group(0) @binding(3) var<storage, read_write> residual_out: array<ResidualOut>;
@group(0) @binding(4) var<storage, read> index: array<u32>;
@group(0) @binding(5) var<storage, read> accs: array<Acc>;

// Σ_gp Σ_field w_gp μ_field g_j · x[gp][field], times l0
fn project_on(j: u32, wv: array<real, 3>, l0: real, x: array<array<vec3<real>, 3>, 4>) -> real {
    var w = wv;
    var xx = x;
    var acc: real = 0.0;
    for (var gp = 0u; gp < 4u; gp++) {
        let wg = GAUSS_W[gp];
        for (var f = 0u; f < 3u; f++) {
            acc += wg * w[f] * dot3(gr[j][gp][f], xx[gp][f]);
        }
    }
    return acc * l0;
}

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
    let u1 = pos_dual(inp.u1, 0u, false);
    let u2 = pos_dual(inp.u2, 0u, false);
    var g = gradient_d(ed.chord0, ed.l0, u1, u2, frame_dual(t1, 0u, false), frame_dual(t2, 0u, false));
    var mn = energy_partials_d(ed.props, ed.l0, g.kin);
    for (var j = 0u; j < 12u; j++) {
        var acc = mn[6].x * g.dlen[j].x;
        for (var a = 0u; a < 6u; a++) {
            acc = acc + mn[a].x * g.dphi[a][j].x;
        }
        residual_out[ie].f[j] = acc;
    }
    residual_out[ie].energy = energy_value(ed.props, ed.l0, g.kin);
    residual_out[ie].pad = array<real, 3>(0.0, 0.0, 0.0);
    if params.inertia == 0u {
        for (var j = 0u; j < 12u; j++) {
            residual_out[ie].s[j] = 0.0;
            residual_out[ie].finert[j] = 0.0;
            residual_out[ie].mv[j] = 0.0;
        }
        return;
    }
    var w = array<real, 3>(ed.props[4], ed.props[6], ed.props[5]);
    gradients_closed(ed, inp, t1, t2);
    var v = inp.v12;
    var a = accs[ie].a;
    // field rates g·v12 and g·acc at every Gauss point
    var rv: array<array<vec3<real>, 3>, 4>;
    var ra: array<array<vec3<real>, 3>, 4>;
    for (var gp = 0u; gp < 4u; gp++) {
        for (var f = 0u; f < 3u; f++) {
            var sv = vec3<real>(0.0, 0.0, 0.0);
            var sa = vec3<real>(0.0, 0.0, 0.0);
            for (var k = 0u; k < 12u; k++) {
                sv += gr[k][gp][f] * v[k];
                sa += gr[k][gp][f] * a[k];
            }
            rv[gp][f] = sv;
            ra[gp][f] = sa;
        }
    }
    field_derivs(ed, inp, t1, t2, v, v);
    for (var j = 0u; j < 12u; j++) {
        let s = project(j, w, ed.l0, 1.0);
        residual_out[ie].s[j] = s;
        residual_out[ie].finert[j] = project_on(j, w, ed.l0, ra) + s;
        residual_out[ie].mv[j] = project_on(j, w, ed.l0, rv);
    }
}
