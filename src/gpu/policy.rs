//! `--backend auto`: whether the GPU element stage is predicted to beat the CPU for a
//! campaign, from a roofline model of the kernels (docs/gpu-roofline.md). A prediction,
//! not a measurement: this project has had no hardware GPU to measure the break-even on;
//! the kernel counts are from the WGSL, the device figures from the vendor's data sheet,
//! the CPU costs measured on the development machine (`cargo bench --bench gpu`).
//!
//! Per Newton round of B element evaluations (a round is one batch of the batch driver:
//! every variant of a worker's batch, one dispatch per kernel):
//! - CPU: B·c / cores, c the mean element-evaluation cost of one thread;
//! - GPU: L + B·(g + h): a fixed round-trip latency L, per element the larger of the
//!   kernel's compute and device-memory time plus the host-link transfer (g), and the
//!   host-side record conversion on the worker thread that holds the device (h).
//!
//! The GPU overtakes at B* = L / (c/cores − g − h). With the elements on the GPU the CPU
//! still assembles and factorizes (cost r per element-iteration); that work is the bound
//! once the GPU's round is shorter than the CPU's share, from B = L / (r/cores − g − h):
//! beyond it a campaign runs at cores/r element-iterations per second whatever the GPU.

use super::Precision;

/// Executed floating-point operations and words per element of each kernel, counted
/// from the WGSL (docs/gpu-roofline.md, "Counting"). Words are of the kernel scalar.
#[derive(Clone, Copy, Debug)]
pub struct KernelCounts {
    pub flops: f64,
    /// per-iteration inputs sent to the device
    pub words_up: f64,
    /// results read back
    pub words_down: f64,
    /// device-memory words read and written by the kernel (model table, inputs, outputs)
    pub words_device: f64,
}

/// beam_force (one invocation per element: the closed-form gradient 1 300, force and
/// energy 240, the closed-form tangent 5 900) plus beam_inertia (the node frames and the
/// gradient in dual numbers along v 3 950, the field-gradient rows g and ġ 15 100,
/// M 6 050, C = 2P + M·skew 11 700, S's hyper-dual pass 4 300). Before the kernels were
/// put on the production routes: 129 000 (12 dual-number column passes for K, 13
/// hyper-dual passes).
pub const FULL: KernelCounts = KernelCounts {
    flops: 48_600.0,
    words_up: 36.0,
    words_down: 460.0,
    words_device: 20.0 + 36.0 + 460.0,
};

/// beam_residual with inertia: force and energy from the plain gradient 1 530, the
/// field-gradient rows 5 240, S (one hyper-dual pass and its projection) 4 300, M·a and
/// M·v without M 3 530 (before: 22 000, the force in dual numbers with zero lanes).
pub const RESIDUAL: KernelCounts = KernelCounts {
    flops: 14_700.0,
    words_up: 48.0,
    words_down: 52.0,
    words_device: 20.0 + 48.0 + 52.0,
};

/// Newton iterations of a step that are residual-only per full one (modified Newton,
/// measured on the blade: 2.2 iterations per step, one with a fresh tangent).
pub const RESIDUAL_PER_FULL: f64 = 1.2;

/// A GPU as the model sees it.
#[derive(Clone, Copy, Debug)]
pub struct GpuSpec {
    /// vector (non-tensor) peaks [flop/s]
    pub f64_flops: f64,
    pub f32_flops: f64,
    /// device memory bandwidth [B/s]
    pub mem_bw: f64,
    /// host link bandwidth per direction [B/s]
    pub link_bw: f64,
    /// fraction of the vector peak the kernels reach (one thread per element, private
    /// arrays spilled, branches): an assumption, see the doc
    pub efficiency: f64,
    /// one round trip: submit, fence wait, two transfers' set-up, map [s]
    pub latency_s: f64,
}

/// NVIDIA H100 SXM5 (data sheet, nvidia.com/en-us/data-center/h100): FP64 34 TFLOP/s,
/// FP32 67 TFLOP/s (vector, not tensor cores), HBM3 3.35 TB/s; PCIe Gen5 ×16 64 GB/s per
/// direction. Efficiency 25 % and latency 50 µs are this model's assumptions.
pub const H100: GpuSpec = GpuSpec {
    f64_flops: 34e12,
    f32_flops: 67e12,
    mem_bw: 3.35e12,
    link_bw: 64e9,
    efficiency: 0.25,
    latency_s: 50e-6,
};

/// Costs on the CPU side [s per element, one thread].
#[derive(Clone, Copy, Debug)]
pub struct CpuSpec {
    /// a full element evaluation (f, K, M, S, C)
    pub full_s: f64,
    /// a residual-only one
    pub residual_s: f64,
    /// assembly, factorization and integrator per element-iteration
    pub rest_s: f64,
    /// host-side record conversion of the GPU path (per element of a round), full /
    /// residual
    pub host_full_s: f64,
    pub host_residual_s: f64,
}

/// Measured on the development machine with `cargo bench --bench gpu -- quick` (2 cores,
/// other builds running): the blade at 100 variants (1000 elements), one thread: full
/// 79 000 evaluations/s, residual 439 000/s; the CPU run's assembly 7 µs and
/// factorization + integrator 8 µs per evaluation of 10 elements; host-side conversion
/// from lavapipe's upload + download per element (f32/f64: 0.1 + 1.1 µs full, 0.1 + 0.25
/// µs residual), an upper bound since lavapipe's map is a memory copy too. See
/// docs/gpu-roofline.md "CPU side".
pub const THIS_CPU: CpuSpec = CpuSpec {
    full_s: 12.7e-6,
    residual_s: 2.3e-6,
    rest_s: 1.5e-6,
    host_full_s: 1.2e-6,
    host_residual_s: 0.35e-6,
};

/// What the model predicts for one Newton round.
#[derive(Clone, Copy, Debug)]
pub struct Prediction {
    /// element evaluations per round
    pub batch: usize,
    /// mean round time of the element stage on the CPU and on the GPU [s]
    pub cpu_s: f64,
    pub gpu_s: f64,
    /// batch from which the GPU is faster (None: never)
    pub overtake_batch: Option<f64>,
    /// batch from which the CPU's assembly and factorization bound the campaign (None:
    /// never, the GPU path's per-element time, host conversion included, stays above
    /// the CPU's own per-element work)
    pub cpu_bound_batch: Option<f64>,
}

/// Per element, averaged over a step's iterations: (CPU evaluation, GPU g, host h).
fn per_element(p: Precision, gpu: &GpuSpec, cpu: &CpuSpec) -> (f64, f64, f64) {
    let (flops, word) = match p {
        Precision::F64 => (gpu.f64_flops, 8.0),
        Precision::F32 => (gpu.f32_flops, 4.0),
    };
    let g = |k: &KernelCounts| {
        let compute = k.flops / (flops * gpu.efficiency);
        let memory = k.words_device * word / gpu.mem_bw;
        compute.max(memory) + (k.words_up + k.words_down) * word / gpu.link_bw
    };
    let w = 1.0 + RESIDUAL_PER_FULL;
    let mean = |a: f64, b: f64| (a + RESIDUAL_PER_FULL * b) / w;
    (
        mean(cpu.full_s, cpu.residual_s),
        mean(g(&FULL), g(&RESIDUAL)),
        mean(cpu.host_full_s, cpu.host_residual_s),
    )
}

/// The model for a round of `batch` element evaluations on `cores` CPU threads.
pub fn predict(
    batch: usize,
    cores: usize,
    p: Precision,
    gpu: &GpuSpec,
    cpu: &CpuSpec,
) -> Prediction {
    let cores = cores.max(1) as f64;
    let (c, g, h) = per_element(p, gpu, cpu);
    let b = batch as f64;
    let from = |cost: f64| {
        let d = cost / cores - g - h;
        (d > 0.0).then(|| gpu.latency_s / d)
    };
    Prediction {
        batch,
        cpu_s: b * c / cores,
        gpu_s: gpu.latency_s + b * (g + h),
        overtake_batch: from(c),
        cpu_bound_batch: from(cpu.rest_s),
    }
}

/// `--backend auto`'s choice for a hardware adapter: true when the model predicts the
/// GPU element stage faster than the CPU's for this campaign: `variants_per_round` (the
/// batch size, see `crate::ensemble::batch_size`) of `elements` each in one round;
/// H100-class device, this machine's CPU costs. Software adapters are never chosen by
/// `auto` (the caller checks).
pub fn prefer_gpu(
    elements: usize,
    variants_per_round: usize,
    cores: usize,
    precision: Precision,
) -> bool {
    let batch = elements * variants_per_round.max(1);
    let m = predict(batch, cores, precision, &H100, &THIS_CPU);
    m.gpu_s < m.cpu_s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefer_gpu_switches_at_the_predicted_overtake_batch() {
        for p in [Precision::F64, Precision::F32] {
            let m = predict(1, 2, p, &H100, &THIS_CPU);
            let b = m.overtake_batch.expect("the H100 model overtakes the CPU");
            // batch = elements × variants per round: one variant of `e` elements
            let below = b.floor() as usize;
            let above = b.ceil() as usize + 1;
            if below >= 1 {
                assert!(
                    !prefer_gpu(below, 1, 2, p),
                    "{p:?}: batch {below} below {b}"
                );
            }
            assert!(prefer_gpu(above, 1, 2, p), "{p:?}: batch {above} above {b}");
            let at = predict(above, 2, p, &H100, &THIS_CPU);
            assert!(at.gpu_s < at.cpu_s);
            // one element never pays for a round trip
            assert!(!prefer_gpu(1, 1, 2, p));
            // the CPU's own work (cheaper per element than the element stage) can bound
            // only after the GPU has overtaken; on one core it does, on two the GPU
            // path's host-side conversion is the slower part and it never does
            let one = predict(1, 1, p, &H100, &THIS_CPU);
            let lu = one
                .cpu_bound_batch
                .expect("one core: the CPU's own work bounds");
            assert!(lu > one.overtake_batch.unwrap(), "{p:?}: {lu}");
            assert!(
                m.cpu_bound_batch.is_none(),
                "{p:?}: {:?}",
                m.cpu_bound_batch
            );
        }
        // f32 halves the words and doubles the peak: never later than f64
        let o = |p| predict(1, 2, p, &H100, &THIS_CPU).overtake_batch.unwrap();
        assert!(o(Precision::F32) <= o(Precision::F64));
        // more CPU cores push the break-even out proportionally (or further)
        let m2 = predict(1, 2, Precision::F64, &H100, &THIS_CPU);
        let m64 = predict(1, 64, Precision::F64, &H100, &THIS_CPU);
        assert!(m64.overtake_batch.unwrap_or(f64::INFINITY) > 30.0 * m2.overtake_batch.unwrap());
    }
}
