//! GPU backend of the element stage: the WGSL kernels `shaders/beam_force.wgsl` (f, K,
//! strain energy) and `shaders/beam_inertia.wgsl` (M, S, C) run through `wgpu` on every
//! element of a batch; assembly and the sparse factorization stay on the CPU.
//!
//! - [`adapters`] lists what the machine offers (Vulkan and OpenGL ES backends) with
//!   device type and SHADER_F64 support; [`select`] picks one for `--backend`.
//! - [`GpuContext`] owns device, pipelines and grow-only buffers, and evaluates one batch:
//!   one upload, one dispatch per kernel, one download. Every output word is overwritten
//!   each dispatch and nothing is accumulated on the GPU, so results are reproducible.
//! - [`GpuEval`] is an [`ElementEval`] over a context (one solver at a time);
//!   [`batch::Batcher`] shares one context among many solver threads, one round trip per
//!   Newton iteration of many variants.

pub mod batch;
pub mod layout;

use std::sync::Mutex;
use std::time::Instant;

use crate::element::{ElemData, ElemIn, ElemOut, ElemState, ElementEval, EvalError, NDOF};
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
    let e2 = ElemData {
        props: e.props,
        frame0: I3,
        chord0: [e.l0, 0.0, 0.0],
        l0: e.l0,
    };
    let chord = mat_vec(&q, add(e.chord0, sub(i.state.u2, i.state.u1)));
    let mut v12 = [0.0; NDOF];
    for b in 0..4 {
        let v = mat_vec(&q, [i.v12[3 * b], i.v12[3 * b + 1], i.v12[3 * b + 2]]);
        v12[3 * b..3 * b + 3].copy_from_slice(&v);
    }
    let i2 = ElemIn {
        state: ElemState {
            u1: [0.0; 3],
            r1: I3,
            u2: sub(chord, [e.l0, 0.0, 0.0]),
            r2: mat_mul(&q, &t2),
        },
        v12,
        // the kernels do not use it: M·acc is formed on the host (`products_from_m`)
        acc: [0.0; NDOF],
    };
    (e2, i2, q)
}

/// Back from [`corotate`]'s frame: vectors Qᵀv per 3-block, matrices QᵀA_ab Q per block.
fn corotate_back(q: &Mat3, o: &mut ElemOut) {
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

fn instance() -> wgpu::Instance {
    quiet_device_select();
    wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN | wgpu::Backends::GL,
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
    let found = std::panic::catch_unwind(|| {
        let inst = instance();
        pollster::block_on(inst.enumerate_adapters(wgpu::Backends::VULKAN | wgpu::Backends::GL))
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
    let mut all: Vec<_> = adapters()
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

/// Wall time split of GPU batches [s].
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuTimes {
    /// conversion to GPU records and buffer writes
    pub upload_s: f64,
    /// dispatch of the kernels until the GPU finished
    pub kernel_s: f64,
    /// copy to the staging buffer, map, conversion back to f64
    pub download_s: f64,
    pub batches: u64,
    pub elements: u64,
}

impl GpuTimes {
    pub fn add(&mut self, o: &GpuTimes) {
        self.upload_s += o.upload_s;
        self.kernel_s += o.kernel_s;
        self.download_s += o.download_s;
        self.batches += o.batches;
        self.elements += o.elements;
    }
}

struct Buffers {
    capacity: usize,
    elems: wgpu::Buffer,
    inputs: wgpu::Buffer,
    force: wgpu::Buffer,
    inertia: wgpu::Buffer,
    staging_force: wgpu::Buffer,
    staging_inertia: wgpu::Buffer,
    force_group: wgpu::BindGroup,
    inertia_group: wgpu::BindGroup,
}

/// Device, queue, the two pipelines and grow-only buffers on one adapter.
pub struct GpuContext {
    pub adapter: AdapterSummary,
    pub precision: Precision,
    device: wgpu::Device,
    queue: wgpu::Queue,
    force_pipe: wgpu::ComputePipeline,
    inertia_pipe: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bufs: Option<Buffers>,
    /// host-side record scratch, reused across batches
    up_data: Vec<u8>,
    up_in: Vec<u8>,
    /// per-element Q of [`corotate`] in the current batch
    rot: Vec<Mat3>,
    max_groups: u32,
    /// upload each element in node 1's frame ([`corotate`]); default: on for f32 (where
    /// it decides the precision), off for f64 (the kernels then see exactly the CPU
    /// functions' inputs)
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
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(GpuContext {
            adapter: summary,
            precision,
            device,
            queue,
            force_pipe,
            inertia_pipe,
            params,
            bufs: None,
            up_data: Vec::new(),
            up_in: Vec::new(),
            rot: Vec::new(),
            max_groups: limits.max_compute_workgroups_per_dimension,
            corotate: precision == Precision::F32,
        })
    }

    /// Select an adapter (see [`select`]) and open it.
    pub fn open(precision: Precision, allow_software: bool) -> Result<GpuContext, GpuError> {
        let (a, s) = select(precision, allow_software)?;
        GpuContext::new(a, s, precision)
    }

    /// Largest batch one dispatch can take (12 invocations per element in beam_force).
    pub fn max_elements(&self) -> usize {
        (self.max_groups as usize * WORKGROUP as usize) / 12
    }

    fn ensure(&mut self, n: usize, sizes: [usize; 4]) {
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
        let elems = storage("elems", sizes[0], U::STORAGE | U::COPY_DST);
        let inputs = storage("inputs", sizes[1], U::STORAGE | U::COPY_DST);
        let force = storage("force_out", sizes[2], U::STORAGE | U::COPY_SRC);
        let inertia = storage("inertia_out", sizes[3], U::STORAGE | U::COPY_SRC);
        let staging_force = storage("staging_force", sizes[2], U::MAP_READ | U::COPY_DST);
        let staging_inertia = storage("staging_inertia", sizes[3], U::MAP_READ | U::COPY_DST);
        let group = |pipe: &wgpu::ComputePipeline, out: &wgpu::Buffer| {
            dev.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &pipe.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.params.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: elems.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: inputs.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: out.as_entire_binding(),
                    },
                ],
            })
        };
        let force_group = group(&self.force_pipe, &force);
        let inertia_group = group(&self.inertia_pipe, &inertia);
        self.bufs = Some(Buffers {
            capacity: cap,
            elems,
            inputs,
            force,
            inertia,
            staging_force,
            staging_inertia,
            force_group,
            inertia_group,
        });
    }

    /// Evaluate one batch: `out[i]` from `elems[i]`, `inputs[i]`.
    pub fn evaluate(
        &mut self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<GpuTimes, GpuError> {
        match self.precision {
            Precision::F32 => self.evaluate_as::<layout::F32>(elems, inputs, inertia, out),
            Precision::F64 => self.evaluate_as::<layout::F64>(elems, inputs, inertia, out),
        }
    }

    fn evaluate_as<P: Records>(
        &mut self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<GpuTimes, GpuError> {
        let n = elems.len();
        if n == 0 {
            return Ok(GpuTimes::default());
        }
        if n > self.max_elements() {
            return Err(GpuError::TooLarge(n, self.max_elements()));
        }
        let sz = |b: usize| b;
        let sizes = [
            sz(std::mem::size_of::<P::Data>()),
            sz(std::mem::size_of::<P::In>()),
            sz(std::mem::size_of::<P::Force>()),
            sz(std::mem::size_of::<P::Inertia>()),
        ];
        let t0 = Instant::now();
        self.ensure(n, sizes);
        self.up_data.clear();
        self.up_in.clear();
        self.rot.clear();
        for (e, i) in elems.iter().zip(inputs) {
            if self.corotate {
                let (e2, i2, q) = corotate(e, i);
                self.up_data
                    .extend_from_slice(bytemuck::bytes_of(&P::data(&e2)));
                self.up_in
                    .extend_from_slice(bytemuck::bytes_of(&P::input(&i2)));
                self.rot.push(q);
            } else {
                self.up_data
                    .extend_from_slice(bytemuck::bytes_of(&P::data(e)));
                self.up_in
                    .extend_from_slice(bytemuck::bytes_of(&P::input(i)));
            }
        }
        let b = self.bufs.as_ref().expect("buffers sized above");
        let params = Params {
            n_elem: n as u32,
            ..Default::default()
        };
        self.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        self.queue.write_buffer(&b.elems, 0, &self.up_data);
        self.queue.write_buffer(&b.inputs, 0, &self.up_in);
        let t1 = Instant::now();
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&self.force_pipe);
            pass.set_bind_group(0, &b.force_group, &[]);
            pass.dispatch_workgroups((n as u32 * 12).div_ceil(WORKGROUP), 1, 1);
            if inertia {
                pass.set_pipeline(&self.inertia_pipe);
                pass.set_bind_group(0, &b.inertia_group, &[]);
                pass.dispatch_workgroups((n as u32).div_ceil(WORKGROUP), 1, 1);
            }
        }
        self.queue.submit([enc.finish()]);
        self.wait()?;
        let t2 = Instant::now();
        let fbytes = (n * sizes[2]) as u64;
        let ibytes = (n * sizes[3]) as u64;
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        enc.copy_buffer_to_buffer(&b.force, 0, &b.staging_force, 0, fbytes);
        if inertia {
            enc.copy_buffer_to_buffer(&b.inertia, 0, &b.staging_inertia, 0, ibytes);
        }
        self.queue.submit([enc.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        let tx2 = tx.clone();
        b.staging_force
            .slice(0..fbytes)
            .map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send(r);
            });
        if inertia {
            b.staging_inertia
                .slice(0..ibytes)
                .map_async(wgpu::MapMode::Read, move |r| {
                    let _ = tx2.send(r);
                });
        } else {
            drop(tx2);
        }
        self.wait()?;
        for _ in 0..(1 + inertia as usize) {
            rx.recv()
                .map_err(|e| GpuError::Other(format!("map: {e}")))?
                .map_err(|e| GpuError::Other(format!("map: {e}")))?;
        }
        {
            let fview = b
                .staging_force
                .slice(0..fbytes)
                .get_mapped_range()
                .map_err(|e| GpuError::Other(format!("map range: {e}")))?;
            let fo: &[P::Force] = bytemuck::cast_slice(&fview);
            if inertia {
                let iview = b
                    .staging_inertia
                    .slice(0..ibytes)
                    .get_mapped_range()
                    .map_err(|e| GpuError::Other(format!("map range: {e}")))?;
                let io: &[P::Inertia] = bytemuck::cast_slice(&iview);
                for i in 0..n {
                    P::output(&fo[i], Some(&io[i]), &mut out[i]);
                }
            } else {
                for i in 0..n {
                    P::output(&fo[i], None, &mut out[i]);
                }
            }
        }
        b.staging_force.unmap();
        if inertia {
            b.staging_inertia.unmap();
        }
        if self.corotate {
            for (o, q) in out.iter_mut().zip(&self.rot) {
                corotate_back(q, o);
            }
        }
        if inertia {
            for (o, i) in out.iter_mut().zip(inputs) {
                o.products_from_m(i);
            }
        } else {
            for o in out.iter_mut() {
                o.finert = [0.0; NDOF];
                o.mv = [0.0; NDOF];
            }
        }
        let t3 = Instant::now();
        Ok(GpuTimes {
            upload_s: (t1 - t0).as_secs_f64(),
            kernel_s: (t2 - t1).as_secs_f64(),
            download_s: (t3 - t2).as_secs_f64(),
            batches: 1,
            elements: n as u64,
        })
    }

    fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Other(format!("poll: {e}")))
    }
}

/// An [`ElementEval`] on one GPU context, for a single solver (tests, `run`).
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
}

impl ElementEval for GpuEval {
    fn evaluate(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        let mut ctx = self.ctx.lock().unwrap_or_else(|p| p.into_inner());
        let t = ctx
            .evaluate(elems, inputs, inertia, out)
            .map_err(|e| EvalError {
                backend: self.name.clone(),
                message: e.to_string(),
            })?;
        self.times.lock().unwrap_or_else(|p| p.into_inner()).add(&t);
        Ok(())
    }
    fn name(&self) -> String {
        self.name.clone()
    }
    fn unit_roundoff(&self) -> f64 {
        self.precision.unit_roundoff()
    }
}
