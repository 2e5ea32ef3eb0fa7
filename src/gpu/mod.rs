//! GPU backend of the element stage: the WGSL kernels `shaders/beam_force.wgsl` (f, K,
//! strain energy), `shaders/beam_inertia.wgsl` (M, S, C) and `shaders/beam_residual.wgsl`
//! (f, energy, S, M·a + S, M·v) run through `wgpu` on every element of a batch, one
//! invocation per element each; assembly and the sparse factorization stay on the CPU.
//! Each kernel is the twin of the CPU's production function (closed-form tangent
//! `force::internal_force_tangent_energy`, `inertia::inertia_full`,
//! `CpuEval::one_residual`), function for function.
//!
//! - [`adapters`] lists what the machine offers (Vulkan and OpenGL ES backends) with
//!   device type and SHADER_F64 support; [`select`] picks one for `--backend`.
//! - [`GpuContext`] owns device, pipelines, the resident model data and grow-only
//!   buffers, and evaluates one round: every request of a batch (each variant's elements,
//!   full or residual-only) in one upload, one submission with one dispatch per kernel,
//!   one readback. Every output word is overwritten each dispatch and nothing is
//!   accumulated on the GPU, so results are reproducible.
//! - [`GpuEval`] is an [`ElementEval`] over a context: one shared by every worker of a
//!   campaign, whose batch driver (`crate::solver::batch`) hands it one round per Newton
//!   iteration of its batch's variants.

pub mod layout;
pub mod policy;

use std::sync::Mutex;
use std::time::Instant;

use crate::element::{
    ElemData, ElemIn, ElemOut, ElemState, ElementEval, EvalError, EvalRequest, NDOF,
};
use crate::math::{add, mat_mul, mat_vec, sub, transpose, Mat3, I3};
use layout::{Params, Records};

/// The element seen from node 1's current frame T₁ = r₁·frame0 (Q = T₁ᵀ): node 1 at the
/// origin with the identity frame, node 2's frame Q·T₂, velocities rotated by Q, and the
/// reference chord X' = (L0, 0, 0) with node 2 at X' + d', d' = Q(X + u2 − u1) − X'.
/// The element functions are objective and see X only through |X| = L0 and the current
/// chord X + d, so this is the same element; but rounded to f32 it keeps what matters:
/// d' is the deformation only (formed in f64, so rounding is relative to the stretch,
/// not to the coordinates, which may be 1e3 m, nor to a rigid rotation of the chord),
/// and the deformation angles come from near-identity frames, whose small off-diagonal
/// entries keep their relative precision (a rigid rotation would otherwise leave eps32
/// absolute error on every angle).
fn corotate(e: &ElemData, i: &ElemIn) -> (ElemData, ElemIn, Mat3) {
    let t1 = mat_mul(&i.state.r1, &e.frame0);
    let t2 = mat_mul(&i.state.r2, &e.frame0);
    let q = transpose(&t1);
    let e2 = corotated_data(e);
    let chord = mat_vec(&q, add(e.chord0, sub(i.state.u2, i.state.u1)));
    let rotate = |x: &[f64; NDOF]| {
        let mut y = [0.0; NDOF];
        for b in 0..4 {
            let v = mat_vec(&q, [x[3 * b], x[3 * b + 1], x[3 * b + 2]]);
            y[3 * b..3 * b + 3].copy_from_slice(&v);
        }
        y
    };
    let v12 = rotate(&i.v12);
    let acc = rotate(&i.acc);
    let i2 = ElemIn {
        state: ElemState {
            u1: [0.0; 3],
            r1: I3,
            u2: sub(chord, [e.l0, 0.0, 0.0]),
            r2: mat_mul(&q, &t2),
        },
        v12,
        // used by the residual kernel only (the full path forms M·acc on the host)
        acc,
    };
    (e2, i2, q)
}

/// Back from [`corotate`]'s frame: vectors Qᵀv per 3-block, matrices QᵀA_ab Q per block
/// (after a residual evaluation: the vectors f, s, finert, mv; the matrices are zero).
fn corotate_back(q: &Mat3, o: &mut ElemOut, residual: bool) {
    let qt = transpose(q);
    let vec_back = |v: &mut [f64; NDOF]| {
        for b in 0..4 {
            let x = mat_vec(&qt, [v[3 * b], v[3 * b + 1], v[3 * b + 2]]);
            v[3 * b..3 * b + 3].copy_from_slice(&x);
        }
    };
    let mat_back = |m: &mut [[f64; NDOF]; NDOF]| {
        for a in 0..4 {
            for b in 0..4 {
                let mut blk = [[0.0; 3]; 3];
                for r in 0..3 {
                    for c in 0..3 {
                        blk[r][c] = m[3 * a + r][3 * b + c];
                    }
                }
                let x = mat_mul(&mat_mul(&qt, &blk), q);
                for r in 0..3 {
                    for c in 0..3 {
                        m[3 * a + r][3 * b + c] = x[r][c];
                    }
                }
            }
        }
    };
    vec_back(&mut o.f);
    vec_back(&mut o.s);
    if residual {
        vec_back(&mut o.finert);
        vec_back(&mut o.mv);
        return;
    }
    mat_back(&mut o.k);
    mat_back(&mut o.m);
    mat_back(&mut o.c);
}

/// Scalar type of the kernels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Precision {
    F32,
    F64,
}

impl Precision {
    pub fn parse(s: &str) -> Result<Precision, String> {
        match s {
            "f32" => Ok(Precision::F32),
            "f64" => Ok(Precision::F64),
            _ => Err(format!("--precision {s}: expected f64 or f32")),
        }
    }
    pub fn as_str(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
    /// unit round-off of the kernels' scalar (see [`ElementEval::unit_roundoff`])
    pub fn unit_roundoff(self) -> f64 {
        match self {
            Precision::F32 => f32::EPSILON as f64 / 2.0,
            Precision::F64 => f64::EPSILON / 2.0,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter found (Vulkan or OpenGL ES); on Debian `apt-get install mesa-vulkan-drivers libvulkan1` gives the lavapipe software adapter, or use --backend cpu")]
    NoAdapter,
    #[error("no GPU adapter supports f64 shaders (SHADER_F64); adapters found: {0}; use --precision f32")]
    NoF64(String),
    #[error("GPU device request on {adapter}: {message}")]
    Device { adapter: String, message: String },
    #[error("GPU shader {kernel} on {adapter}: {message}")]
    Shader {
        kernel: String,
        adapter: String,
        message: String,
    },
    #[error("GPU batch of {0} elements exceeds the dispatch limit of {1}")]
    TooLarge(usize, usize),
    #[error("GPU: {0}")]
    Other(String),
}

/// One adapter as found on this machine.
#[derive(Clone, Debug)]
pub struct AdapterSummary {
    pub name: String,
    /// "Vulkan" or "Gl"
    pub backend: String,
    /// "DiscreteGpu", "IntegratedGpu", "VirtualGpu", "Cpu" (software) or "Other"
    pub device_type: String,
    pub driver: String,
    pub shader_f64: bool,
}

impl AdapterSummary {
    fn of(a: &wgpu::Adapter) -> AdapterSummary {
        let i = a.get_info();
        AdapterSummary {
            name: i.name.clone(),
            backend: format!("{:?}", i.backend),
            device_type: format!("{:?}", i.device_type),
            driver: format!("{} {}", i.driver, i.driver_info).trim().to_string(),
            shader_f64: a.features().contains(wgpu::Features::SHADER_F64),
        }
    }
    /// software rasterizer (llvmpipe, lavapipe, SwiftShader): device type Cpu
    pub fn is_software(&self) -> bool {
        self.device_type == "Cpu"
    }
    /// "name (backend, device type)" for logs and the campaign metadata
    pub fn label(&self) -> String {
        format!("{} ({}, {})", self.name, self.backend, self.device_type)
    }
}

fn instance(backends: wgpu::Backends) -> wgpu::Instance {
    quiet_device_select();
    wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    })
}

/// Mesa's Vulkan device-select layer (installed with mesa-vulkan-drivers) calls
/// `wl_display_connect` when an instance enables `VK_KHR_wayland_surface`, which wgpu
/// always does, and libwayland then prints "error: XDG_RUNTIME_DIR is invalid or not set
/// in the environment" on a machine without a Wayland session, on every successful GPU
/// run. The layer only reorders devices for presentation; latdyn computes headless and
/// picks its adapter itself (`select`), so the layer is switched off with its documented
/// `NODEVICE_SELECT` unless the user set that variable. Set once, on the thread that
/// creates the first instance, before any GPU thread exists.
fn quiet_device_select() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        if std::env::var_os("NODEVICE_SELECT").is_none() {
            std::env::set_var("NODEVICE_SELECT", "1");
        }
    });
}

/// Every adapter wgpu finds (Vulkan and OpenGL ES backends). Never panics: a machine
/// without drivers simply has none.
pub fn adapters() -> Vec<(wgpu::Adapter, AdapterSummary)> {
    adapters_on(wgpu::Backends::VULKAN | wgpu::Backends::GL)
}

/// The adapters of `backends` only.
fn adapters_on(backends: wgpu::Backends) -> Vec<(wgpu::Adapter, AdapterSummary)> {
    let found = std::panic::catch_unwind(|| {
        let inst = instance(backends);
        pollster::block_on(inst.enumerate_adapters(backends))
    })
    .unwrap_or_default();
    found
        .into_iter()
        .map(|a| {
            let s = AdapterSummary::of(&a);
            (a, s)
        })
        .collect()
}

/// Summaries only (for `latdyn check --gpu`).
pub fn adapter_summaries() -> Vec<AdapterSummary> {
    adapters().into_iter().map(|(_, s)| s).collect()
}

/// Preference among adapters: hardware before software, discrete before integrated,
/// Vulkan before OpenGL (f64 support, better compute drivers).
fn rank(s: &AdapterSummary) -> (u8, u8) {
    let t = match s.device_type.as_str() {
        "DiscreteGpu" => 0,
        "IntegratedGpu" => 1,
        "VirtualGpu" => 2,
        "Other" => 3,
        _ => 4,
    };
    (t, if s.backend == "Vulkan" { 0 } else { 1 })
}

/// Pick an adapter: `allow_software` (explicit `--backend gpu`) admits llvmpipe/lavapipe;
/// f64 needs SHADER_F64. `LATDYN_ADAPTER=substring` restricts the choice by name or
/// backend (e.g. `Gl`, `llvmpipe`).
pub fn select(
    precision: Precision,
    allow_software: bool,
) -> Result<(wgpu::Adapter, AdapterSummary), GpuError> {
    let filter = std::env::var("LATDYN_ADAPTER").ok();
    // OpenGL ES has no f64 shaders: an f64 search does not start its drivers (on a
    // machine without a GPU that start-up is most of the ~0.1 s `--backend auto` costs)
    let backends = match precision {
        Precision::F64 => wgpu::Backends::VULKAN,
        Precision::F32 => wgpu::Backends::VULKAN | wgpu::Backends::GL,
    };
    let mut all: Vec<_> = adapters_on(backends)
        .into_iter()
        .filter(|(_, s)| allow_software || !s.is_software())
        .filter(|(_, s)| {
            filter.as_deref().is_none_or(|f| {
                let f = f.to_lowercase();
                s.name.to_lowercase().contains(&f) || s.backend.to_lowercase().contains(&f)
            })
        })
        .collect();
    if all.is_empty() {
        return Err(GpuError::NoAdapter);
    }
    all.sort_by_key(|(_, s)| rank(s));
    if precision == Precision::F64 {
        let names: Vec<String> = all.iter().map(|(_, s)| s.label()).collect();
        return all
            .into_iter()
            .find(|(_, s)| s.shader_f64)
            .ok_or_else(|| GpuError::NoF64(names.join("; ")));
    }
    Ok(all.remove(0))
}

/// Wall time split of GPU batches [s], and what crossed the host link.
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuTimes {
    /// conversion of the per-iteration inputs to GPU records and buffer writes (and the
    /// content check of [`GpuContext::evaluate`]'s model-data cache, also in `check_s`)
    pub upload_s: f64,
    /// dispatch of the kernels until the GPU finished
    pub kernel_s: f64,
    /// copy to the staging buffer, map, conversion back to f64
    pub download_s: f64,
    /// of `upload_s`: comparing the caller's element data with the resident copy
    pub check_s: f64,
    /// rounds: one upload, one queue submission and one readback each
    pub batches: u64,
    /// kernel dispatches in those rounds: beam_force and beam_inertia for the full
    /// requests of a round (beam_inertia only with inertia), beam_residual for its
    /// residual-only requests
    pub dispatches: u64,
    /// of `dispatches`: beam_residual ones (modified-Newton iterations)
    pub residual_dispatches: u64,
    /// requests (one variant's elements each) over all rounds
    pub requests: u64,
    pub elements: u64,
    /// bytes written to the device per dispatch (inputs, accelerations, changed slot
    /// indices, parameters), summed; model data is counted in [`ModelUploads`]
    pub bytes_up: u64,
    /// bytes read back, summed
    pub bytes_down: u64,
}

impl GpuTimes {
    pub fn add(&mut self, o: &GpuTimes) {
        self.upload_s += o.upload_s;
        self.kernel_s += o.kernel_s;
        self.download_s += o.download_s;
        self.check_s += o.check_s;
        self.batches += o.batches;
        self.dispatches += o.dispatches;
        self.residual_dispatches += o.residual_dispatches;
        self.requests += o.requests;
        self.elements += o.elements;
        self.bytes_up += o.bytes_up;
        self.bytes_down += o.bytes_down;
    }
}

/// Model data written to a context's device table since it was opened.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ModelUploads {
    /// write operations (one per registration, plus one per live segment when the table
    /// is rewritten in the other form after `corotate` was switched)
    pub uploads: u64,
    /// element records written
    pub elements: u64,
    pub bytes: u64,
}

/// A run of table slots holding one caller's element data on the device (from
/// [`GpuContext::register`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Segment(usize);

#[derive(Clone, Copy, Debug)]
struct Seg {
    offset: usize,
    cap: usize,
    n: usize,
    live: bool,
}

/// The model's constant per-element data, resident on the device: one table of `Data`
/// records that the kernels index with a per-element slot (`index` buffer), filled once
/// per registered segment; a host mirror in f64 for the co-rotated upload (which needs
/// each element's frame0 and chord0) and for the content check.
struct Table {
    buf: Option<wgpu::Buffer>,
    /// slots the buffer holds
    capacity: usize,
    mirror: Vec<ElemData>,
    segs: Vec<Seg>,
    /// the form the records on the device were written in (`corotate`)
    corotated: bool,
    /// bumped when the buffer is replaced (bind groups then rebuilt)
    generation: u64,
    counts: ModelUploads,
}

/// Calls of [`GpuContext::evaluate_batch`] a resident segment survives unused. Several
/// worker threads share one context, each with its own batch of variants, so a batch's
/// segments must outlive the other workers' calls in between (a worker's next round
/// comes after its CPU work, while the others take their turns); a finished variant's
/// segment is released this many calls later and its slots go to the next registration,
/// so a stream of different batches does not grow the table.
const STALE_CALLS: u64 = 16;

/// A resident segment of [`GpuContext::evaluate_batch`]'s content-checked cache.
#[derive(Clone, Copy, Debug)]
struct Cached {
    seg: Segment,
    /// address of the caller's element data when last matched: checked first (a batch's
    /// variants keep their model's data in place), the content decides
    addr: usize,
    /// the call that last used it
    used: u64,
}

/// Bitwise equality of element data (a NaN equals itself; -0 differs from +0): the cache
/// may reuse the device copy only if the conversion would write the same bytes.
pub(crate) fn same_data(a: &[ElemData], b: &[ElemData]) -> bool {
    fn words(e: &ElemData) -> [u64; 20] {
        let p = &e.props;
        let f = &e.frame0;
        [
            p.ea,
            p.eiy,
            p.eiz,
            p.gj,
            p.rho_a,
            p.rho_iy,
            p.rho_iz,
            f[0][0],
            f[0][1],
            f[0][2],
            f[1][0],
            f[1][1],
            f[1][2],
            f[2][0],
            f[2][1],
            f[2][2],
            e.chord0[0],
            e.chord0[1],
            e.chord0[2],
            e.l0,
        ]
        .map(f64::to_bits)
    }
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| words(x) == words(y))
}

/// The element data as the kernels see it in the co-rotated upload ([`corotate`]):
/// props and L0 only, so it is as constant as the element.
fn corotated_data(e: &ElemData) -> ElemData {
    ElemData {
        props: e.props,
        frame0: I3,
        chord0: [e.l0, 0.0, 0.0],
        l0: e.l0,
    }
}

struct Buffers {
    capacity: usize,
    /// full requests' inputs and slots
    inputs: wgpu::Buffer,
    index: wgpu::Buffer,
    /// residual-only requests' inputs, slots and accelerations
    inputs_res: wgpu::Buffer,
    index_res: wgpu::Buffer,
    accs: wgpu::Buffer,
    force: wgpu::Buffer,
    inertia: wgpu::Buffer,
    residual: wgpu::Buffer,
    staging_force: wgpu::Buffer,
    staging_inertia: wgpu::Buffer,
    staging_residual: wgpu::Buffer,
}

struct Groups {
    table_generation: u64,
    force: wgpu::BindGroup,
    inertia: wgpu::BindGroup,
    residual: wgpu::BindGroup,
}

/// Device, queue, the pipelines, the resident element table and grow-only buffers on
/// one adapter.
pub struct GpuContext {
    pub adapter: AdapterSummary,
    pub precision: Precision,
    device: wgpu::Device,
    queue: wgpu::Queue,
    force_pipe: wgpu::ComputePipeline,
    inertia_pipe: wgpu::ComputePipeline,
    residual_pipe: wgpu::ComputePipeline,
    /// uniforms of the full kernels and of the residual kernel (both may run in a round)
    params: wgpu::Buffer,
    params_res: wgpu::Buffer,
    bufs: Option<Buffers>,
    groups: Option<Groups>,
    table: Table,
    /// resident segments of [`GpuContext::evaluate_batch`]'s content-checked cache
    cache: Vec<Cached>,
    /// calls of [`GpuContext::evaluate_batch`] so far
    calls: u64,
    /// slot indices of the last round as on the device (rewritten only when changed)
    last_index: Vec<u32>,
    last_index_res: Vec<u32>,
    /// slot scratch of a round
    index: Vec<u32>,
    index_res: Vec<u32>,
    /// host-side record scratch, reused across rounds
    up_in: Vec<u8>,
    up_res: Vec<u8>,
    up_acc: Vec<u8>,
    /// per-element Q of [`corotate`] in the current batch
    rot: Vec<Mat3>,
    max_groups: u32,
    max_binding: u64,
    /// upload each element in node 1's frame ([`corotate`]); default: on for f32 (where
    /// it decides the precision), off for f64 (the kernels then see exactly the CPU
    /// functions' inputs). Switching it rewrites the resident table on the next dispatch.
    pub corotate: bool,
}

const WORKGROUP: u32 = 64;

impl GpuContext {
    /// Open `adapter` and compile the kernels in `precision`.
    pub fn new(
        adapter: wgpu::Adapter,
        summary: AdapterSummary,
        precision: Precision,
    ) -> Result<GpuContext, GpuError> {
        if precision == Precision::F64 && !summary.shader_f64 {
            return Err(GpuError::NoF64(summary.label()));
        }
        let features = if precision == Precision::F64 {
            wgpu::Features::SHADER_F64
        } else {
            wgpu::Features::empty()
        };
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("latdyn"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device {
            adapter: summary.label(),
            message: e.to_string(),
        })?;
        let real = precision.as_str();
        let make = |kernel: &str| -> Result<wgpu::ComputePipeline, GpuError> {
            let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(kernel),
                source: wgpu::ShaderSource::Wgsl(layout::shader_source(kernel, real).into()),
            });
            let pipe = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(kernel),
                layout: None,
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            });
            match pollster::block_on(scope.pop()) {
                None => Ok(pipe),
                Some(e) => Err(GpuError::Shader {
                    kernel: kernel.into(),
                    adapter: summary.label(),
                    message: e.to_string(),
                }),
            }
        };
        let force_pipe = make("beam_force")?;
        let inertia_pipe = make("beam_inertia")?;
        let residual_pipe = make("beam_residual")?;
        let uniform = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: std::mem::size_of::<Params>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let params = uniform("params");
        let params_res = uniform("params_res");
        let corotate = precision == Precision::F32;
        Ok(GpuContext {
            adapter: summary,
            precision,
            device,
            queue,
            force_pipe,
            inertia_pipe,
            residual_pipe,
            params,
            params_res,
            bufs: None,
            groups: None,
            table: Table {
                buf: None,
                capacity: 0,
                mirror: Vec::new(),
                segs: Vec::new(),
                corotated: corotate,
                generation: 0,
                counts: ModelUploads::default(),
            },
            cache: Vec::new(),
            calls: 0,
            last_index: Vec::new(),
            last_index_res: Vec::new(),
            index: Vec::new(),
            index_res: Vec::new(),
            up_in: Vec::new(),
            up_res: Vec::new(),
            up_acc: Vec::new(),
            rot: Vec::new(),
            max_groups: limits.max_compute_workgroups_per_dimension,
            max_binding: limits.max_storage_buffer_binding_size,
            corotate,
        })
    }

    /// Select an adapter (see [`select`]) and open it.
    pub fn open(precision: Precision, allow_software: bool) -> Result<GpuContext, GpuError> {
        let (a, s) = select(precision, allow_software)?;
        GpuContext::new(a, s, precision)
    }

    /// Largest batch one dispatch can take (one invocation per element in every kernel).
    pub fn max_elements(&self) -> usize {
        self.max_groups as usize * WORKGROUP as usize
    }

    /// Model data written to the device so far.
    pub fn model_uploads(&self) -> ModelUploads {
        self.table.counts
    }

    fn data_size(&self) -> usize {
        match self.precision {
            Precision::F32 => std::mem::size_of::<layout::f32s::ElemData>(),
            Precision::F64 => std::mem::size_of::<layout::f64s::ElemData>(),
        }
    }

    /// Put `elems` on the device once: the returned segment stays resident until
    /// [`release`](Self::release)d, and a round refers to its elements by slot
    /// ([`slots`](Self::slots)).
    fn register(&mut self, elems: &[ElemData]) -> Result<Segment, GpuError> {
        let n = elems.len();
        let t = &mut self.table;
        // first fit among released segments (the clients of one campaign share a model,
        // so a released segment is the size of the next registration)
        let reuse = t.segs.iter().position(|s| !s.live && s.cap >= n);
        let id = match reuse {
            Some(k) => {
                let seg = &mut t.segs[k];
                seg.live = true;
                seg.n = n;
                t.mirror[seg.offset..seg.offset + n].copy_from_slice(elems);
                k
            }
            None => {
                t.segs.push(Seg {
                    offset: t.mirror.len(),
                    cap: n,
                    n,
                    live: true,
                });
                t.mirror.extend_from_slice(elems);
                t.segs.len() - 1
            }
        };
        let off = t.segs[id].offset;
        if let Err(e) = self.grow_table(off + n) {
            // not on the device: the slots must not be used
            self.table.segs[id].live = false;
            return Err(e);
        }
        self.write_segment(id);
        Ok(Segment(id))
    }

    /// Give a segment's slots back (its device data is left and overwritten by a later
    /// registration).
    fn release(&mut self, s: Segment) {
        if let Some(seg) = self.table.segs.get_mut(s.0) {
            seg.live = false;
        }
        self.cache.retain(|c| c.seg != s);
    }

    /// The table slots of a segment's elements, in order.
    fn slots(&self, s: Segment) -> std::ops::Range<u32> {
        let seg = self.table.segs[s.0];
        seg.offset as u32..(seg.offset + seg.n) as u32
    }

    /// Grow the device table to hold `slots` records, keeping its content (copied on the
    /// device: growing uploads no model data).
    fn grow_table(&mut self, slots: usize) -> Result<(), GpuError> {
        if self.table.buf.is_some() && self.table.capacity >= slots {
            return Ok(());
        }
        let cap = slots.next_power_of_two().max(64);
        let size = (cap * self.data_size()) as u64;
        if size > self.max_binding {
            return Err(GpuError::TooLarge(
                slots,
                self.max_binding as usize / self.data_size(),
            ));
        }
        let buf = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("elem_table"),
            size,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        if let Some(old) = &self.table.buf {
            let mut enc = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
            enc.copy_buffer_to_buffer(old, 0, &buf, 0, old.size());
            self.queue.submit([enc.finish()]);
        }
        self.table.buf = Some(buf);
        self.table.capacity = cap;
        self.table.generation += 1;
        Ok(())
    }

    /// Write one segment's records in the current form (`corotate`).
    fn write_segment(&mut self, id: usize) {
        match self.precision {
            Precision::F32 => self.write_segment_as::<layout::F32>(id),
            Precision::F64 => self.write_segment_as::<layout::F64>(id),
        }
    }

    fn write_segment_as<P: Records>(&mut self, id: usize) {
        let t = &mut self.table;
        let seg = t.segs[id];
        let mut bytes = Vec::with_capacity(seg.n * std::mem::size_of::<P::Data>());
        for e in &t.mirror[seg.offset..seg.offset + seg.n] {
            let rec = if t.corotated {
                P::data(&corotated_data(e))
            } else {
                P::data(e)
            };
            bytes.extend_from_slice(bytemuck::bytes_of(&rec));
        }
        if let Some(buf) = &t.buf {
            let at = (seg.offset * std::mem::size_of::<P::Data>()) as u64;
            self.queue.write_buffer(buf, at, &bytes);
        }
        t.counts.uploads += 1;
        t.counts.elements += seg.n as u64;
        t.counts.bytes += bytes.len() as u64;
    }

    /// The resident segment holding exactly `elems` (content-checked), registering it
    /// when none does.
    fn resident(&mut self, elems: &[ElemData]) -> Result<Segment, GpuError> {
        let addr = elems.as_ptr() as usize;
        let holds = |t: &Table, s: Segment| {
            let seg = t.segs[s.0];
            seg.live
                && seg.n == elems.len()
                && same_data(&t.mirror[seg.offset..seg.offset + seg.n], elems)
        };
        let found = self
            .cache
            .iter()
            .position(|c| c.addr == addr && holds(&self.table, c.seg))
            .or_else(|| self.cache.iter().position(|c| holds(&self.table, c.seg)));
        let call = self.calls;
        match found {
            Some(k) => {
                let c = &mut self.cache[k];
                c.addr = addr;
                c.used = call;
                Ok(c.seg)
            }
            None => {
                let seg = self.register(elems)?;
                self.cache.push(Cached {
                    seg,
                    addr,
                    used: call,
                });
                Ok(seg)
            }
        }
    }

    /// Release the segments no call used for [`STALE_CALLS`] calls.
    fn evict_stale(&mut self) {
        let call = self.calls;
        let stale: Vec<Segment> = self
            .cache
            .iter()
            .filter(|c| call - c.used > STALE_CALLS)
            .map(|c| c.seg)
            .collect();
        for s in stale {
            self.release(s);
        }
    }

    fn ensure(&mut self, n: usize, sizes: [usize; 5]) {
        if self.bufs.as_ref().is_some_and(|b| b.capacity >= n) {
            return;
        }
        let cap = n.next_power_of_two().max(64);
        let dev = &self.device;
        let storage = |label: &str, bytes: usize, usage: wgpu::BufferUsages| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (bytes * cap) as u64,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let [s_in, s_force, s_inertia, s_res, s_acc] = sizes;
        self.bufs = Some(Buffers {
            capacity: cap,
            inputs: storage("inputs", s_in, U::STORAGE | U::COPY_DST),
            index: storage("index", 4, U::STORAGE | U::COPY_DST),
            inputs_res: storage("inputs_res", s_in, U::STORAGE | U::COPY_DST),
            index_res: storage("index_res", 4, U::STORAGE | U::COPY_DST),
            accs: storage("accs", s_acc, U::STORAGE | U::COPY_DST),
            force: storage("force_out", s_force, U::STORAGE | U::COPY_SRC),
            inertia: storage("inertia_out", s_inertia, U::STORAGE | U::COPY_SRC),
            residual: storage("residual_out", s_res, U::STORAGE | U::COPY_SRC),
            staging_force: storage("staging_force", s_force, U::MAP_READ | U::COPY_DST),
            staging_inertia: storage("staging_inertia", s_inertia, U::MAP_READ | U::COPY_DST),
            staging_residual: storage("staging_residual", s_res, U::MAP_READ | U::COPY_DST),
        });
        // the new index buffers hold nothing yet
        self.last_index.clear();
        self.last_index_res.clear();
        self.groups = None;
    }

    /// Bind groups over the current table and buffers (rebuilt when either was replaced).
    fn ensure_groups(&mut self) {
        let gen = self.table.generation;
        if self
            .groups
            .as_ref()
            .is_some_and(|g| g.table_generation == gen)
        {
            return;
        }
        let (Some(b), Some(table)) = (self.bufs.as_ref(), self.table.buf.as_ref()) else {
            return;
        };
        fn entry(binding: u32, buf: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: buf.as_entire_binding(),
            }
        }
        // the residual kernel has its own uniform, inputs and slots: it may run in the
        // same submission as the full kernels, over other elements
        let group = |pipe: &wgpu::ComputePipeline, out: &wgpu::Buffer, residual: bool| {
            let (params, inputs, index) = if residual {
                (&self.params_res, &b.inputs_res, &b.index_res)
            } else {
                (&self.params, &b.inputs, &b.index)
            };
            let mut entries = vec![
                entry(0, params),
                entry(1, table),
                entry(2, inputs),
                entry(3, out),
                entry(4, index),
            ];
            if residual {
                entries.push(entry(5, &b.accs));
            }
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &pipe.get_bind_group_layout(0),
                entries: &entries,
            })
        };
        self.groups = Some(Groups {
            table_generation: gen,
            force: group(&self.force_pipe, &b.force, false),
            inertia: group(&self.inertia_pipe, &b.inertia, false),
            residual: group(&self.residual_pipe, &b.residual, true),
        });
    }

    /// Evaluate one batch: `out[i]` from `elems[i]`, `inputs[i]`. The element data goes
    /// to the device only when it differs (bitwise) from a resident copy: a caller that
    /// passes the same model data every Newton iteration uploads it once.
    pub fn evaluate(
        &mut self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<GpuTimes, GpuError> {
        self.evaluate_batch(&mut [EvalRequest {
            elems,
            inputs,
            out,
            residual: false,
            inertia,
        }])
    }

    /// As [`evaluate`](Self::evaluate) for a residual-only iteration: f, energy and
    /// (with `inertia`) s, finert, mv from the residual kernel; K, M, C zero.
    pub fn evaluate_residual(
        &mut self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<GpuTimes, GpuError> {
        self.evaluate_batch(&mut [EvalRequest {
            elems,
            inputs,
            out,
            residual: true,
            inertia,
        }])
    }

    /// Evaluate several requests (the variants of a batch) in one round: one upload, one
    /// command submission holding one dispatch per kernel the round needs (beam_force and
    /// beam_inertia over every full request's elements, beam_residual over every
    /// residual-only one's), one readback. Each request's element data is made resident
    /// as in [`evaluate`](Self::evaluate). Only a round beyond the dispatch limit
    /// ([`max_elements`](Self::max_elements)) is split, at request boundaries.
    ///
    /// A request's outputs are bit-identical to evaluating it alone: every element is
    /// its own kernel invocation, and what differs from a lone call (the inertia kernel
    /// run for another request, the residual kernel's inertial forces computed for
    /// another one) is dropped on the host exactly as the lone call's kernels would have
    /// left it.
    pub fn evaluate_batch(&mut self, reqs: &mut [EvalRequest<'_>]) -> Result<GpuTimes, GpuError> {
        let t0 = Instant::now();
        self.calls += 1;
        let mut segs = Vec::with_capacity(reqs.len());
        for r in reqs.iter() {
            let n = r.inputs.len();
            if r.elems.len() != n || r.out.len() < n {
                return Err(GpuError::Other(format!(
                    "batch of {n} inputs with {} elements and {} outputs",
                    r.elems.len(),
                    r.out.len()
                )));
            }
            segs.push(if n == 0 {
                None
            } else {
                Some(self.resident(r.elems)?)
            });
        }
        self.evict_stale();
        let check_s = t0.elapsed().as_secs_f64();
        let max = self.max_elements();
        let mut t = GpuTimes::default();
        let mut start = 0;
        while start < reqs.len() {
            let (mut end, mut nf, mut nr) = (start, 0, 0);
            while end < reqs.len() {
                let n = reqs[end].inputs.len();
                let (f, r) = if reqs[end].residual {
                    (nf, nr + n)
                } else {
                    (nf + n, nr)
                };
                if f > max || r > max {
                    if end == start {
                        return Err(GpuError::TooLarge(n, max));
                    }
                    break;
                }
                (nf, nr, end) = (f, r, end + 1);
            }
            let tt = match self.precision {
                Precision::F32 => {
                    self.round_as::<layout::F32>(&mut reqs[start..end], &segs[start..end])
                }
                Precision::F64 => {
                    self.round_as::<layout::F64>(&mut reqs[start..end], &segs[start..end])
                }
            }?;
            t.add(&tt);
            start = end;
        }
        t.check_s += check_s;
        t.upload_s += check_s;
        Ok(t)
    }

    /// One round: the requests fit the dispatch limit; `segs[k]` holds request k's
    /// element data (None: no elements).
    fn round_as<P: Records>(
        &mut self,
        reqs: &mut [EvalRequest<'_>],
        segs: &[Option<Segment>],
    ) -> Result<GpuTimes, GpuError> {
        let t0 = Instant::now();
        // `corotate` was switched since the table was written: rewrite it in the new form
        if self.table.corotated != self.corotate {
            self.table.corotated = self.corotate;
            for id in 0..self.table.segs.len() {
                if self.table.segs[id].live {
                    self.write_segment(id);
                }
            }
        }
        let mut idx_full = std::mem::take(&mut self.index);
        let mut idx_res = std::mem::take(&mut self.index_res);
        idx_full.clear();
        idx_res.clear();
        for (r, s) in reqs.iter().zip(segs) {
            if let Some(s) = s {
                let slots = self.slots(*s);
                if r.residual {
                    idx_res.extend(slots);
                } else {
                    idx_full.extend(slots);
                }
            }
        }
        let r = self.round_slots::<P>(reqs, &idx_full, &idx_res, t0);
        self.index = idx_full;
        self.index_res = idx_res;
        r
    }

    fn round_slots<P: Records>(
        &mut self,
        reqs: &mut [EvalRequest<'_>],
        idx_full: &[u32],
        idx_res: &[u32],
        t0: Instant,
    ) -> Result<GpuTimes, GpuError> {
        let (nf, nr) = (idx_full.len(), idx_res.len());
        if nf + nr == 0 {
            return Ok(GpuTimes::default());
        }
        let live = |r: &&EvalRequest<'_>| !r.inputs.is_empty();
        let inertia_full = reqs.iter().filter(live).any(|r| !r.residual && r.inertia);
        let inertia_res = reqs.iter().filter(live).any(|r| r.residual && r.inertia);
        let sizes = [
            std::mem::size_of::<P::In>(),
            std::mem::size_of::<P::Force>(),
            std::mem::size_of::<P::Inertia>(),
            std::mem::size_of::<P::Residual>(),
            std::mem::size_of::<P::Acc>(),
        ];
        self.ensure(nf.max(nr), sizes);
        self.ensure_groups();
        self.up_in.clear();
        self.up_res.clear();
        self.up_acc.clear();
        self.rot.clear();
        // in request order; each request's elements go to the full or the residual records
        for r in reqs.iter() {
            let (up, acc) = if r.residual {
                (&mut self.up_res, inertia_res)
            } else {
                (&mut self.up_in, false)
            };
            let seg_elems = r.elems;
            for (e, i) in seg_elems.iter().zip(r.inputs) {
                if self.corotate {
                    let (_, i2, q) = corotate(e, i);
                    up.extend_from_slice(bytemuck::bytes_of(&P::input(&i2)));
                    if acc {
                        self.up_acc
                            .extend_from_slice(bytemuck::bytes_of(&P::acc(&i2)));
                    }
                    self.rot.push(q);
                } else {
                    up.extend_from_slice(bytemuck::bytes_of(&P::input(i)));
                    if acc {
                        self.up_acc
                            .extend_from_slice(bytemuck::bytes_of(&P::acc(i)));
                    }
                }
            }
        }
        let b = self.bufs.as_ref().expect("buffers sized above");
        let g = self.groups.as_ref().expect("bind groups made above");
        let mut bytes_up = 0u64;
        let mut write_params = |buf: &wgpu::Buffer, n: usize, inertia: bool| {
            let params = Params {
                n_elem: n as u32,
                inertia: inertia as u32,
                ..Default::default()
            };
            self.queue.write_buffer(buf, 0, bytemuck::bytes_of(&params));
            bytes_up += std::mem::size_of::<Params>() as u64;
        };
        if nf > 0 {
            write_params(&self.params, nf, inertia_full);
        }
        if nr > 0 {
            write_params(&self.params_res, nr, inertia_res);
        }
        if nf > 0 {
            self.queue.write_buffer(&b.inputs, 0, &self.up_in);
            bytes_up += self.up_in.len() as u64;
        }
        if nr > 0 {
            self.queue.write_buffer(&b.inputs_res, 0, &self.up_res);
            bytes_up += self.up_res.len() as u64;
        }
        if inertia_res {
            self.queue.write_buffer(&b.accs, 0, &self.up_acc);
            bytes_up += self.up_acc.len() as u64;
        }
        // the slots stay the same from one Newton iteration to the next unless the batch
        // changed composition: write them only then
        if nf > 0 && self.last_index.as_slice() != idx_full {
            self.queue
                .write_buffer(&b.index, 0, bytemuck::cast_slice(idx_full));
            self.last_index.clear();
            self.last_index.extend_from_slice(idx_full);
            bytes_up += 4 * nf as u64;
        }
        if nr > 0 && self.last_index_res.as_slice() != idx_res {
            self.queue
                .write_buffer(&b.index_res, 0, bytemuck::cast_slice(idx_res));
            self.last_index_res.clear();
            self.last_index_res.extend_from_slice(idx_res);
            bytes_up += 4 * nr as u64;
        }
        let t1 = Instant::now();
        // (device buffer, staging buffer, bytes) of each output read back
        let mut reads: Vec<(&wgpu::Buffer, &wgpu::Buffer, u64)> = Vec::with_capacity(3);
        let mut dispatches = 0u64;
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            if nf > 0 {
                pass.set_pipeline(&self.force_pipe);
                pass.set_bind_group(0, &g.force, &[]);
                pass.dispatch_workgroups((nf as u32).div_ceil(WORKGROUP), 1, 1);
                reads.push((&b.force, &b.staging_force, (nf * sizes[1]) as u64));
                dispatches += 1;
                if inertia_full {
                    pass.set_pipeline(&self.inertia_pipe);
                    pass.set_bind_group(0, &g.inertia, &[]);
                    pass.dispatch_workgroups((nf as u32).div_ceil(WORKGROUP), 1, 1);
                    reads.push((&b.inertia, &b.staging_inertia, (nf * sizes[2]) as u64));
                    dispatches += 1;
                }
            }
            if nr > 0 {
                pass.set_pipeline(&self.residual_pipe);
                pass.set_bind_group(0, &g.residual, &[]);
                pass.dispatch_workgroups((nr as u32).div_ceil(WORKGROUP), 1, 1);
                reads.push((&b.residual, &b.staging_residual, (nr * sizes[3]) as u64));
                dispatches += 1;
            }
        }
        // the copies to the staging buffers ride in the same submission: one round trip
        for &(src, dst, bytes) in &reads {
            enc.copy_buffer_to_buffer(src, 0, dst, 0, bytes);
        }
        self.queue.submit([enc.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        for &(_, dst, bytes) in &reads {
            let tx = tx.clone();
            dst.slice(0..bytes)
                .map_async(wgpu::MapMode::Read, move |r| {
                    let _ = tx.send(r);
                });
        }
        drop(tx);
        self.wait()?;
        for _ in 0..reads.len() {
            rx.recv()
                .map_err(|e| GpuError::Other(format!("map: {e}")))?
                .map_err(|e| GpuError::Other(format!("map: {e}")))?;
        }
        let t2 = Instant::now();
        let bytes_down: u64 = reads.iter().map(|r| r.2).sum();
        {
            let view = |buf: &wgpu::Buffer, bytes: usize| {
                buf.slice(0..bytes as u64)
                    .get_mapped_range()
                    .map_err(|e| GpuError::Other(format!("map range: {e}")))
            };
            let fview = if nf > 0 {
                Some(view(&b.staging_force, nf * sizes[1])?)
            } else {
                None
            };
            let iview = if nf > 0 && inertia_full {
                Some(view(&b.staging_inertia, nf * sizes[2])?)
            } else {
                None
            };
            let rview = if nr > 0 {
                Some(view(&b.staging_residual, nr * sizes[3])?)
            } else {
                None
            };
            let fo: &[P::Force] = fview.as_deref().map_or(&[][..], bytemuck::cast_slice);
            let io: &[P::Inertia] = iview.as_deref().map_or(&[][..], bytemuck::cast_slice);
            let ro: &[P::Residual] = rview.as_deref().map_or(&[][..], bytemuck::cast_slice);
            let (mut of, mut or, mut oq) = (0, 0, 0);
            for r in reqs.iter_mut() {
                let n = r.inputs.len();
                let out = &mut r.out[..n];
                if r.residual {
                    for (k, o) in out.iter_mut().enumerate() {
                        P::residual_output(&ro[or + k], o);
                        if !r.inertia {
                            // the kernel ran with inertia for another request; alone it
                            // would have written these zeros
                            o.s = [0.0; NDOF];
                            o.finert = [0.0; NDOF];
                            o.mv = [0.0; NDOF];
                        }
                    }
                    or += n;
                } else {
                    for (k, o) in out.iter_mut().enumerate() {
                        let inert = if r.inertia { Some(&io[of + k]) } else { None };
                        P::output(&fo[of + k], inert, o);
                    }
                    of += n;
                }
                if self.corotate {
                    for (o, q) in out.iter_mut().zip(&self.rot[oq..oq + n]) {
                        corotate_back(q, o, r.residual);
                    }
                }
                oq += n;
                match (r.residual, r.inertia) {
                    (false, true) => {
                        for (o, i) in out.iter_mut().zip(r.inputs) {
                            o.products_from_m(i);
                        }
                    }
                    (false, false) => {
                        for o in out.iter_mut() {
                            o.finert = [0.0; NDOF];
                            o.mv = [0.0; NDOF];
                        }
                    }
                    // the kernel wrote finert and mv (zeros without inertia)
                    (true, _) => {}
                }
            }
        }
        for &(_, dst, _) in &reads {
            dst.unmap();
        }
        let t3 = Instant::now();
        Ok(GpuTimes {
            upload_s: (t1 - t0).as_secs_f64(),
            kernel_s: (t2 - t1).as_secs_f64(),
            download_s: (t3 - t2).as_secs_f64(),
            check_s: 0.0,
            batches: 1,
            dispatches,
            residual_dispatches: (nr > 0) as u64,
            requests: reqs.iter().filter(live).count() as u64,
            elements: (nf + nr) as u64,
            bytes_up,
            bytes_down,
        })
    }

    fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Other(format!("poll: {e}")))
    }
}

/// An [`ElementEval`] on one GPU context. Shared by the workers of a campaign: the
/// context's lock serialises their rounds, so one worker's assembly and factorization
/// overlap another's round on the device.
pub struct GpuEval {
    ctx: Mutex<GpuContext>,
    times: Mutex<GpuTimes>,
    name: String,
    precision: Precision,
}

impl GpuEval {
    pub fn new(ctx: GpuContext) -> GpuEval {
        let name = format!("gpu {} {}", ctx.adapter.label(), ctx.precision.as_str());
        GpuEval {
            precision: ctx.precision,
            ctx: Mutex::new(ctx),
            times: Mutex::new(GpuTimes::default()),
            name,
        }
    }
    pub fn times(&self) -> GpuTimes {
        *self.times.lock().unwrap_or_else(|p| p.into_inner())
    }
    /// Model data written to the device so far (see [`GpuContext::evaluate`]'s cache).
    pub fn model_uploads(&self) -> ModelUploads {
        self.ctx
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .model_uploads()
    }
    /// One request as a batch of one: the same round as in a campaign's batch.
    fn one(
        &self,
        residual: bool,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        self.evaluate_batch(&mut [EvalRequest {
            elems,
            inputs,
            out,
            residual,
            inertia,
        }])
    }
}

impl ElementEval for GpuEval {
    fn evaluate_batch(&self, reqs: &mut [EvalRequest<'_>]) -> Result<(), EvalError> {
        let mut ctx = self.ctx.lock().unwrap_or_else(|p| p.into_inner());
        let t = ctx.evaluate_batch(reqs).map_err(|e| EvalError {
            backend: self.name.clone(),
            message: e.to_string(),
        })?;
        self.times.lock().unwrap_or_else(|p| p.into_inner()).add(&t);
        Ok(())
    }
    fn evaluate(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        self.one(false, elems, inputs, inertia, out)
    }
    fn evaluate_residual(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        self.one(true, elems, inputs, inertia, out)
    }
    fn name(&self) -> String {
        self.name.clone()
    }
    fn unit_roundoff(&self) -> f64 {
        self.precision.unit_roundoff()
    }
}
