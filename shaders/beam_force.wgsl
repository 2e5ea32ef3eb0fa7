// Internal force f, consistent tangent K and strain energy of every element: the WGSL twin
// of force::internal_force_tangent + kinematics::strain_energy (src/element/force.rs, kinematics.rs).
//
// One invocation per (element, column c): the closed-form force is evaluated in dual
// numbers along element dof c, so its value part is f and its derivative part is column c
// of K (exactly the CPU's dual-number tangent, rotation increments multiplicative). The
// 12 invocations of an element each write their own column; invocation c = 0 also writes
// f and the energy. Every output word is written on every dispatch, no atomics.
// (beam_common.wgsl is prepended by the host.)

struct ForceOut {
    f: array<real, 12>,
    k: array<real, 144>, // row-major K[r][c]
    energy: real,
    pad: array<real, 3>,
}

// kinematics::stretch: chord change plus the length the bending shape adds
fn stretch_d(l0: real, k: KinD) -> D {
    let fy1 = k.phi[1];
    let fz1 = k.phi[2];
    let fy2 = k.phi[4];
    let fz2 = k.phi[5];
    let q = dmul(2.0 * fy1, fy1) - dmul(fy1, fy2) + dmul(2.0 * fy2, fy2) + dmul(2.0 * fz1, fz1)
        - dmul(fz1, fz2) + dmul(2.0 * fz2, fz2);
    return k.u1 + (l0 / 30.0) * q;
}

// force::energy_partials: ∂U/∂φ (6) and the axial force N = ∂U/∂ℓ (last entry)
fn energy_partials_d(p: array<real, 7>, l0: real, k: KinD) -> array<D, 7> {
    let fx1 = k.phi[0];
    let fy1 = k.phi[1];
    let fz1 = k.phi[2];
    let fx2 = k.phi[3];
    let fy2 = k.phi[4];
    let fz2 = k.phi[5];
    let t = (p[3] / l0) * (fx2 - fx1);
    let cy = dc(2.0 * p[1] / l0);
    let cz = dc(2.0 * p[2] / l0);
    let n = (p[0] / l0) * stretch_d(l0, k);
    let g = dmul(n, dc(l0 / 30.0));
    return array<D, 7>(
        -t,
        dmul(cy, 2.0 * fy1 + fy2) + dmul(g, 4.0 * fy1 - fy2),
        dmul(cz, 2.0 * fz1 + fz2) + dmul(g, 4.0 * fz1 - fz2),
        t,
        dmul(cy, fy1 + 2.0 * fy2) + dmul(g, 4.0 * fy2 - fy1),
        dmul(cz, fz1 + 2.0 * fz2) + dmul(g, 4.0 * fz2 - fz1),
        n,
    );
}

// kinematics::energy (value part only)
fn energy_value(p: array<real, 7>, l0: real, k: KinD) -> real {
    let fx1 = k.phi[0].x;
    let fy1 = k.phi[1].x;
    let fz1 = k.phi[2].x;
    let fx2 = k.phi[3].x;
    let fy2 = k.phi[4].x;
    let fz2 = k.phi[5].x;
    let tw = fx2 - fx1;
    let bz = fz1 * fz1 + fz1 * fz2 + fz2 * fz2;
    let by = fy1 * fy1 + fy1 * fy2 + fy2 * fy2;
    let s = stretch_d(l0, k).x;
    return 0.5 * (p[0] / l0) * s * s + 0.5 * (p[3] / l0) * tw * tw + (2.0 * p[2] / l0) * bz
        + (2.0 * p[1] / l0) * by;
}

// ---- kernel entry: everything below is this kernel's own (bindings and main); the
// residual kernel (beam_residual.wgsl) includes only the functions above.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> elems: array<ElemData>;
@group(0) @binding(2) var<storage, read> inputs: array<ElemIn>;
@group(0) @binding(3) var<storage, read_write> force_out: array<ForceOut>;
// table slot of each element of the batch (the model's data stays on the device)
@group(0) @binding(4) var<storage, read> index: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let ie = gid.x / 12u;
    let col = gid.x % 12u;
    if ie >= params.n_elem {
        return;
    }
    let ed = elems[index[ie]];
    let inp = inputs[ie];
    let f0 = m3_load(ed.frame0);
    let t1 = m3_mul(m3_load(inp.r1), f0);
    let t2 = m3_mul(m3_load(inp.r2), f0);
    let node = col / 6u;
    let comp = col % 6u;
    let u1 = pos_dual(inp.u1, comp, node == 0u);
    let u2 = pos_dual(inp.u2, comp, node == 1u);
    let tt1 = frame_dual(t1, comp, node == 0u);
    let tt2 = frame_dual(t2, comp, node == 1u);
    var g = gradient_d(ed.chord0, ed.l0, u1, u2, tt1, tt2);
    var mn = energy_partials_d(ed.props, ed.l0, g.kin);
    for (var j = 0u; j < 12u; j++) {
        var acc = dmul(mn[6], g.dlen[j]);
        for (var a = 0u; a < 6u; a++) {
            acc = acc + dmul(mn[a], g.dphi[a][j]);
        }
        force_out[ie].k[j * 12u + col] = acc.y;
        if col == 0u {
            force_out[ie].f[j] = acc.x;
        }
    }
    if col == 0u {
        force_out[ie].energy = energy_value(ed.props, ed.l0, g.kin);
        force_out[ie].pad = array<real, 3>(0.0, 0.0, 0.0);
    }
}
