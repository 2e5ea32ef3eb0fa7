//! The element stage a run or sweep uses: `--backend` / `--precision` resolved, with the
//! `auto` policy.

use anyhow::anyhow;

use crate::cli::BackendArgs;

/// Solver threads of a GPU sweep (variants in flight, each waiting on the batcher).
pub(crate) const GPU_BATCH_THREADS: usize = 128;

/// Resolve `--backend`/`--precision` into an element stage (and the batcher behind it).
pub(crate) fn choose_stage(
    b: &BackendArgs,
    n_variants: usize,
    n_elem: usize,
    cores: usize,
) -> anyhow::Result<(
    latdyn::ensemble::Stage,
    Option<std::sync::Arc<latdyn::gpu::batch::Batcher>>,
)> {
    use latdyn::ensemble::Stage;
    use latdyn::gpu::{self, batch::Batcher, GpuContext, Precision};
    let precision = Precision::parse(&b.precision).map_err(|e| anyhow!(e))?;
    let want_gpu = match b.backend.as_str() {
        "cpu" => {
            if precision == Precision::F32 {
                return Err(anyhow!(
                    "--backend cpu --precision f32: the CPU path is f64 only; use --precision f64 or --backend gpu"
                ));
            }
            false
        }
        "gpu" => true,
        _ => {
            let in_flight = n_variants.min(GPU_BATCH_THREADS.max(cores));
            // the roofline model of docs/gpu-roofline.md: a prediction (no hardware GPU
            // measured), for an H100-class device against this CPU's measured element cost
            if !gpu::policy::prefer_gpu(n_elem, in_flight, cores, precision) {
                false
            } else {
                // hardware only; a missing adapter or f64 support just means the CPU
                gpu::select(precision, false).is_ok()
            }
        }
    };
    if !want_gpu {
        return Ok((Stage::cpu(), None));
    }
    let ctx = GpuContext::open(precision, b.backend == "gpu")
        .map_err(|e| anyhow!("--backend {}: {e}", b.backend))?;
    let adapter = ctx.adapter.label();
    eprintln!("element stage: gpu on {adapter}, {}", precision.as_str());
    let batcher = Batcher::start(ctx, std::time::Duration::from_millis(2));
    let bb = batcher.clone();
    let stage = Stage {
        backend: "gpu".into(),
        precision: precision.as_str().into(),
        adapter,
        make: Some(std::sync::Arc::new(move || {
            bb.client() as std::sync::Arc<dyn latdyn::element::ElementEval>
        })),
    };
    Ok((stage, Some(batcher)))
}
