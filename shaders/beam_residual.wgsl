// Residual-only evaluation for modified-Newton iterations (ElementEval::evaluate_residual):
// the internal force f and the strain energy, and when asked the inertial force
// finert = M·acc + S and M·v12, but neither K nor M, S's derivative C: the WGSL twin of
// CpuEval::one_residual (src/element/stage.rs), function by function: force::residual_parts
// (the node frames, beam_common's `gradient`, `energy_partials`, `force_from`, `energy`),
// then inertia::inertia_residual_from on the same gradient (GradRows::from_gradient:
// `field_rows`; forces_from_rows: `quadratic`, `mass_times`).
//
// One invocation per element, in plain `real` arithmetic but for S's one hyper-dual pass
// along (v, v). M is never formed: M·x = Σ_q w_q g_q (g_q·x) (`mass_times`). The download
// is 52 words per element instead of 460. (beam_common.wgsl and the functions of
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

// GradRows::mass_times: (M x, M y) = Σ_q w_q g_q (g_q · x), likewise y
struct MassTimes {
    mx: array<real, 12>,
    my: array<real, 12>,
}

fn mass_times(xv: array<real, 12>, yv: array<real, 12>) -> MassTimes {
    var x = xv;
    var y = yv;
    var out: MassTimes;
    for (var q = 0u; q < 36u; q++) {
        var gx: real = 0.0;
        var gy: real = 0.0;
        for (var k = 0u; k < 12u; k++) {
            gx = gx + rows_g[q][k] * x[k];
            gy = gy + rows_g[q][k] * y[k];
        }
        let a = rows_w[q] * gx;
        let b = rows_w[q] * gy;
        for (var k = 0u; k < 12u; k++) {
            out.mx[k] = out.mx[k] + a * rows_g[q][k];
            out.my[k] = out.my[k] + b * rows_g[q][k];
        }
    }
    return out;
}

// CpuEval::one_residual, one invocation per element
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let ie = gid.x;
    if ie >= params.n_elem {
        return;
    }
    let ed = elems[index[ie]];
    let inp = inputs[ie];
    // force::residual_parts: frames, gradient, force, energy
    let f0 = m3_load(ed.frame0);
    let t1 = m3_mul(m3_load(inp.r1), f0);
    let t2 = m3_mul(m3_load(inp.r2), f0);
    let u1 = vec3<real>(inp.u1[0], inp.u1[1], inp.u1[2]);
    let u2 = vec3<real>(inp.u2[0], inp.u2[1], inp.u2[2]);
    let g = gradient(ed.chord0, ed.l0, u1, u2, t1, t2);
    let mn = energy_partials(ed.props, ed.l0, g.kin);
    residual_out[ie].f = force_from(g, mn);
    residual_out[ie].energy = energy(ed.props, ed.l0, g.kin);
    residual_out[ie].pad = array<real, 3>(0.0, 0.0, 0.0);
    if params.inertia == 0u {
        for (var j = 0u; j < 12u; j++) {
            residual_out[ie].s[j] = 0.0;
            residual_out[ie].finert[j] = 0.0;
            residual_out[ie].mv[j] = 0.0;
        }
        return;
    }
    // inertia::inertia_residual_from: GradRows::from_gradient, then forces_from_rows
    row_weights(ed);
    field_rows(g);
    let sv = quadratic(ed, inp, t1, t2, inp.v12);
    let prod = mass_times(accs[ie].a, inp.v12);
    for (var j = 0u; j < 12u; j++) {
        residual_out[ie].s[j] = sv[j];
        residual_out[ie].finert[j] = prod.mx[j] + sv[j];
        residual_out[ie].mv[j] = prod.my[j];
    }
}
