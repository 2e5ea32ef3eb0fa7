//! The element stage a run or sweep uses: `--backend` / `--precision` resolved, with the
//! `auto` policy.

use std::sync::Arc;

use anyhow::anyhow;

use crate::cli::BackendArgs;

/// Default variants per batch of a GPU sweep (`--batch`), before `batch_size` caps it at
/// the variants per worker. A GPU round costs a fixed round trip plus a little per
/// element, so the batch should be as large as the campaign allows: all of a worker's
/// variants. The cap bounds what a worker holds at once (each variant of a batch keeps
/// its state, history and LU in memory until the batch ends) and keeps the round within
/// one dispatch (the dispatch limit is about 350 000 elements on lavapipe and larger on
/// hardware).
pub(crate) const GPU_DEFAULT_BATCH: usize = 1024;

/// Most elements (variants × elements per variant) a default GPU batch holds. A variant
/// of a batch keeps its state, history and LU until the batch ends (a few kB per
/// element), so without this bound a 1024-variant batch of a large model would hold
/// hundreds of GB; 262 144 elements is about 1 GB per worker and stays within one
/// dispatch (about 350 000 elements on lavapipe).
const GPU_BATCH_ELEMENTS: usize = 1 << 18;

/// The default GPU batch for a model of `n_elem` elements: [`GPU_DEFAULT_BATCH`] variants,
/// fewer where they would hold more than [`GPU_BATCH_ELEMENTS`] elements (at least 1).
pub(crate) fn gpu_default_batch(n_elem: usize) -> usize {
    GPU_DEFAULT_BATCH.min((GPU_BATCH_ELEMENTS / n_elem.max(1)).max(1))
}

/// Resolve `--backend`/`--precision` into an element stage, with the GPU evaluator
/// behind it (shared by every worker: its statistics are the campaign's).
pub(crate) fn choose_stage(
    b: &BackendArgs,
    n_variants: usize,
    n_elem: usize,
    cores: usize,
) -> anyhow::Result<(latdyn::ensemble::Stage, Option<Arc<latdyn::gpu::GpuEval>>)> {
    use latdyn::ensemble::Stage;
    use latdyn::gpu::{self, GpuContext, GpuEval, Precision};
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
            // a round is one batch: the variants per worker, as `sweep` defaults them
            let per_round =
                latdyn::ensemble::batch_size(gpu_default_batch(n_elem), n_variants, cores);
            // the roofline model of docs/gpu-roofline.md: a prediction (no hardware GPU
            // measured), for an H100-class device against this CPU's measured element cost
            if !gpu::policy::prefer_gpu(n_elem, per_round, cores, precision) {
                false
            } else {
                // hardware only; a missing adapter or f64 support just means the CPU
                gpu::select(precision, false).is_ok()
            }
        }
    };
    if !want_gpu {
        // auto chose the CPU, which is f64 only: an f32 asked for is not what runs, and
        // that went unsaid (the JSON and the file record cpu/f64; a probe, session 46)
        if precision == Precision::F32 {
            eprintln!(
                "note: --backend auto chose the CPU element stage, which is f64 only: \
                 --precision f32 does not apply (--backend gpu runs f32)"
            );
        }
        return Ok((Stage::cpu(), None));
    }
    // a software adapter (llvmpipe, lavapipe) compiles the kernels on first use, which
    // took 140 s with an empty Mesa shader cache (1.3 s once cached): say what the wait is
    eprintln!(
        "element stage: opening the GPU and compiling its kernels ({})...",
        precision.as_str()
    );
    let t0 = std::time::Instant::now();
    let ctx = GpuContext::open(precision, b.backend == "gpu")
        .map_err(|e| anyhow!("--backend {}: {e}", b.backend))?;
    let adapter = ctx.adapter.label();
    let took = t0.elapsed().as_secs_f64();
    let slow = if took > 5.0 {
        format!(
            " (opening and compiling took {took:.0} s: a software adapter compiles the \
             kernels on first use and its driver caches them for the next run)"
        )
    } else {
        String::new()
    };
    eprintln!(
        "element stage: gpu on {adapter}, {}{slow}",
        precision.as_str()
    );
    let eval = Arc::new(GpuEval::new(ctx));
    let shared = eval.clone();
    let stage = Stage {
        backend: "gpu".into(),
        precision: precision.as_str().into(),
        adapter,
        make: Some(Arc::new(move || {
            shared.clone() as Arc<dyn latdyn::element::ElementEval>
        })),
    };
    Ok((stage, Some(eval)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_gpu_batch_holds_at_most_the_element_bound_and_at_least_one_variant() {
        // the blade (10 elements): the whole 1024 variants fit
        assert_eq!(gpu_default_batch(10), GPU_DEFAULT_BATCH);
        // a large model gets fewer variants per batch, never more elements than the bound
        for n_elem in [300, 1000, 12_345, 100_000] {
            let b = gpu_default_batch(n_elem);
            assert!(b >= 1 && b * n_elem <= GPU_BATCH_ELEMENTS, "{n_elem}: {b}");
            assert!((b + 1) * n_elem > GPU_BATCH_ELEMENTS || b == GPU_DEFAULT_BATCH);
        }
        // a model larger than the bound still runs, one variant at a time
        assert_eq!(gpu_default_batch(1 << 20), 1);
        assert_eq!(gpu_default_batch(0), GPU_DEFAULT_BATCH);
    }
}
