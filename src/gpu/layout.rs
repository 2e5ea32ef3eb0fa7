//! Buffer records shared with the WGSL kernels (`shaders/beam_common.wgsl`,
//! `beam_force.wgsl`, `beam_inertia.wgsl`), one set per precision. Every record holds only
//! arrays of the scalar, so WGSL inserts no padding and the layout is `#[repr(C)]`'s; the
//! sizes are asserted at compile time here and the member offsets against naga's layouter
//! on the real shader source in the tests below.

use bytemuck::{Pod, Zeroable};

use crate::element::{ElemData, ElemIn, ElemOut, NDOF};

/// The `Params` uniform (same in both precisions).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct Params {
    pub n_elem: u32,
    /// beam_residual: nonzero when the inertial forces are asked for
    pub inertia: u32,
    // separate words: a uniform-buffer array would need a 16-byte element stride
    pub pad1: u32,
    pub pad2: u32,
}

/// Scalar of the kernels (f32 or f64), converted from and to the CPU's f64.
pub trait GpuReal: Pod + Copy + Default + 'static {
    const NAME: &'static str;
    fn of(x: f64) -> Self;
    fn to(self) -> f64;
}
impl GpuReal for f32 {
    const NAME: &'static str = "f32";
    #[inline]
    fn of(x: f64) -> Self {
        x as f32
    }
    #[inline]
    fn to(self) -> f64 {
        self as f64
    }
}
impl GpuReal for f64 {
    const NAME: &'static str = "f64";
    #[inline]
    fn of(x: f64) -> Self {
        x
    }
    #[inline]
    fn to(self) -> f64 {
        self
    }
}

macro_rules! records {
    ($m:ident, $t:ty) => {
        /// Records in this precision (see the module docs).
        pub mod $m {
            use bytemuck::{Pod, Zeroable};
            /// WGSL `ElemData`
            #[repr(C)]
            #[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
            pub struct ElemData {
                /// EA, EIy, EIz, GJ, ρA, ρIy, ρIz
                pub props: [$t; 7],
                /// row-major
                pub frame0: [$t; 9],
                pub chord0: [$t; 3],
                pub l0: $t,
            }
            /// WGSL `ElemIn`
            #[repr(C)]
            #[derive(Clone, Copy, Debug, Pod, Zeroable)]
            pub struct ElemIn {
                pub u1: [$t; 3],
                pub r1: [$t; 9],
                pub u2: [$t; 3],
                pub r2: [$t; 9],
                pub v12: [$t; 12],
            }
            /// WGSL `ForceOut` (beam_force.wgsl)
            #[repr(C)]
            #[derive(Clone, Copy, Debug, Pod, Zeroable)]
            pub struct ForceOut {
                pub f: [$t; 12],
                pub k: [$t; 144],
                pub energy: $t,
                pub pad: [$t; 3],
            }
            /// WGSL `InertiaOut` (beam_inertia.wgsl)
            #[repr(C)]
            #[derive(Clone, Copy, Debug, Pod, Zeroable)]
            pub struct InertiaOut {
                pub m: [$t; 144],
                pub s: [$t; 12],
                pub c: [$t; 144],
            }
            /// WGSL `ResidualOut` (beam_residual.wgsl)
            #[repr(C)]
            #[derive(Clone, Copy, Debug, Pod, Zeroable)]
            pub struct ResidualOut {
                pub f: [$t; 12],
                pub s: [$t; 12],
                pub finert: [$t; 12],
                pub mv: [$t; 12],
                pub energy: $t,
                pub pad: [$t; 3],
            }
            /// WGSL `Acc` (beam_residual.wgsl)
            #[repr(C)]
            #[derive(Clone, Copy, Debug, Pod, Zeroable)]
            pub struct Acc {
                pub a: [$t; 12],
            }
            const W: usize = std::mem::size_of::<$t>();
            const _: () = assert!(std::mem::size_of::<ResidualOut>() == 52 * W);
            const _: () = assert!(std::mem::size_of::<Acc>() == 12 * W);
            const _: () = assert!(std::mem::size_of::<ElemData>() == 20 * W);
            const _: () = assert!(std::mem::size_of::<ElemIn>() == 36 * W);
            const _: () = assert!(std::mem::size_of::<ForceOut>() == 160 * W);
            const _: () = assert!(std::mem::size_of::<InertiaOut>() == 300 * W);
        }
    };
}
records!(f32s, f32);
records!(f64s, f64);

/// Flat-record conversions, generic over the kernel scalar through these four types.
pub trait Records: Sized {
    type R: GpuReal;
    type Data: Pod + Default;
    type In: Pod;
    type Force: Pod;
    type Inertia: Pod;
    type Residual: Pod;
    type Acc: Pod;
    fn data(e: &ElemData) -> Self::Data;
    fn input(i: &ElemIn) -> Self::In;
    fn acc(i: &ElemIn) -> Self::Acc;
    /// write f, energy, s, finert, mv (zeros when the kernel ran without inertia) and
    /// zero K, M, C, as `CpuEval::one_residual`
    fn residual_output(r: &Self::Residual, o: &mut ElemOut);
    /// write f, K, energy (and M, S, C when `inertia` is Some, zeros otherwise)
    fn output(f: &Self::Force, inertia: Option<&Self::Inertia>, o: &mut ElemOut);
}

fn flat9(m: &[[f64; 3]; 3]) -> [f64; 9] {
    [
        m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2],
    ]
}

macro_rules! impl_records {
    ($name:ident, $m:ident, $t:ty) => {
        /// Conversions for the records of this precision.
        pub struct $name;
        impl Records for $name {
            type R = $t;
            type Data = $m::ElemData;
            type In = $m::ElemIn;
            type Force = $m::ForceOut;
            type Inertia = $m::InertiaOut;
            type Residual = $m::ResidualOut;
            type Acc = $m::Acc;
            fn acc(i: &ElemIn) -> $m::Acc {
                $m::Acc {
                    a: i.acc.map(|x| <$t as GpuReal>::of(x)),
                }
            }
            fn residual_output(r: &$m::ResidualOut, o: &mut ElemOut) {
                for j in 0..NDOF {
                    o.f[j] = r.f[j].to();
                    o.s[j] = r.s[j].to();
                    o.finert[j] = r.finert[j].to();
                    o.mv[j] = r.mv[j].to();
                }
                o.energy = r.energy.to();
                o.forces_of = None;
                o.k = [[0.0; NDOF]; NDOF];
                o.m = [[0.0; NDOF]; NDOF];
                o.c = [[0.0; NDOF]; NDOF];
            }
            fn data(e: &ElemData) -> $m::ElemData {
                let p = &e.props;
                let c = |x: f64| <$t as GpuReal>::of(x);
                $m::ElemData {
                    props: [p.ea, p.eiy, p.eiz, p.gj, p.rho_a, p.rho_iy, p.rho_iz].map(c),
                    frame0: flat9(&e.frame0).map(c),
                    chord0: e.chord0.map(c),
                    l0: c(e.l0),
                }
            }
            fn input(i: &ElemIn) -> $m::ElemIn {
                let c = |x: f64| <$t as GpuReal>::of(x);
                $m::ElemIn {
                    u1: i.state.u1.map(c),
                    r1: flat9(&i.state.r1).map(c),
                    u2: i.state.u2.map(c),
                    r2: flat9(&i.state.r2).map(c),
                    v12: i.v12.map(c),
                }
            }
            fn output(f: &$m::ForceOut, inertia: Option<&$m::InertiaOut>, o: &mut ElemOut) {
                for r in 0..NDOF {
                    o.f[r] = f.f[r].to();
                    for c in 0..NDOF {
                        o.k[r][c] = f.k[r * NDOF + c].to();
                    }
                }
                o.energy = f.energy.to();
                o.forces_of = None;
                match inertia {
                    Some(x) => {
                        for r in 0..NDOF {
                            o.s[r] = x.s[r].to();
                            for c in 0..NDOF {
                                o.m[r][c] = x.m[r * NDOF + c].to();
                                o.c[r][c] = x.c[r * NDOF + c].to();
                            }
                        }
                    }
                    None => {
                        o.m = [[0.0; NDOF]; NDOF];
                        o.s = [0.0; NDOF];
                        o.c = [[0.0; NDOF]; NDOF];
                    }
                }
            }
        }
    };
}
impl_records!(F32, f32s, f32);
impl_records!(F64, f64s, f64);

/// Marker in beam_force.wgsl and beam_inertia.wgsl: above it the functions the residual
/// kernel shares, below it the kernel's own bindings and entry point.
const ENTRY_MARK: &str = "// ---- kernel entry:";

/// WGSL sources of the kernels with the scalar alias set to `real` ("f32" or "f64"):
/// beam_common, then the kernel file; `beam_residual` gets the functions of beam_force and
/// beam_inertia (the parts above their entry marker) in between.
/// `LATDYN_SHADER_DIR=shaders` reads the files at run time instead of the copies built
/// into the binary (shader development without recompiling).
pub fn shader_source(kernel: &str, real: &str) -> String {
    let built = |name: &str| -> &'static str {
        match name {
            "beam_common" => include_str!("../../shaders/beam_common.wgsl"),
            "beam_force" => include_str!("../../shaders/beam_force.wgsl"),
            "beam_residual" => include_str!("../../shaders/beam_residual.wgsl"),
            _ => include_str!("../../shaders/beam_inertia.wgsl"),
        }
    };
    let read = |name: &str| -> String {
        std::env::var("LATDYN_SHADER_DIR")
            .ok()
            .and_then(|d| std::fs::read_to_string(format!("{d}/{name}.wgsl")).ok())
            .unwrap_or_else(|| built(name).to_string())
    };
    let functions = |name: &str| -> String {
        let s = read(name);
        match s.find(ENTRY_MARK) {
            Some(i) => s[..i].to_string(),
            None => s,
        }
    };
    let common = read("beam_common").replace(
        "alias real = f32; // LATDYN_REAL",
        &format!("alias real = {real};"),
    );
    if kernel == "beam_residual" {
        format!(
            "{common}\n{}\n{}\n{}",
            functions("beam_force"),
            functions("beam_inertia"),
            read(kernel)
        )
    } else {
        format!("{common}\n{}", read(kernel))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wgpu::naga;

    /// Member offsets and sizes of each WGSL struct, by naga's layouter on the real shader
    /// source, equal the Rust `#[repr(C)]` records: a hand-copied layout that drifted
    /// would otherwise read shifted data without any error.
    fn wgsl_layout(src: &str, name: &str) -> (u32, Vec<(String, u32)>) {
        let module = naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{e}"));
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        for (h, ty) in module.types.iter() {
            if ty.name.as_deref() == Some(name) {
                if let naga::TypeInner::Struct { members, span } = &ty.inner {
                    let _ = layouter[h];
                    return (
                        *span,
                        members
                            .iter()
                            .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                            .collect(),
                    );
                }
            }
        }
        panic!("struct {name} not in the shader");
    }

    macro_rules! check {
        ($src:expr, $name:literal, $ty:ty, [$($field:ident),*]) => {{
            let (span, members) = wgsl_layout($src, $name);
            assert_eq!(span as usize, std::mem::size_of::<$ty>(), "size of {}", $name);
            let rust = vec![$((stringify!($field).to_string(), std::mem::offset_of!($ty, $field) as u32)),*];
            assert_eq!(members, rust, "members of {}", $name);
        }};
    }

    #[test]
    fn wgsl_struct_layouts_equal_rust_records_in_both_precisions() {
        for real in ["f32", "f64"] {
            let force = shader_source("beam_force", real);
            let inertia = shader_source("beam_inertia", real);
            let residual = shader_source("beam_residual", real);
            if real == "f32" {
                check!(
                    &force,
                    "ElemData",
                    f32s::ElemData,
                    [props, frame0, chord0, l0]
                );
                check!(&force, "ElemIn", f32s::ElemIn, [u1, r1, u2, r2, v12]);
                check!(&force, "ForceOut", f32s::ForceOut, [f, k, energy, pad]);
                check!(&inertia, "InertiaOut", f32s::InertiaOut, [m, s, c]);
                check!(&force, "Params", Params, [n_elem, inertia, pad1, pad2]);
                check!(
                    &residual,
                    "ResidualOut",
                    f32s::ResidualOut,
                    [f, s, finert, mv, energy, pad]
                );
                check!(&residual, "Acc", f32s::Acc, [a]);
            } else {
                check!(
                    &force,
                    "ElemData",
                    f64s::ElemData,
                    [props, frame0, chord0, l0]
                );
                check!(&force, "ElemIn", f64s::ElemIn, [u1, r1, u2, r2, v12]);
                check!(&force, "ForceOut", f64s::ForceOut, [f, k, energy, pad]);
                check!(&inertia, "InertiaOut", f64s::InertiaOut, [m, s, c]);
                check!(
                    &residual,
                    "ResidualOut",
                    f64s::ResidualOut,
                    [f, s, finert, mv, energy, pad]
                );
                check!(&residual, "Acc", f64s::Acc, [a]);
            }
        }
    }
}
