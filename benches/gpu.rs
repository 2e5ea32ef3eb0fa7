//! GPU element stage against the CPU (prints, never asserts): for the rotating blade
//! (models/flapping_blade.toml) and the Mini-Mast bay (models/minimast_bay.toml) at
//! 1, 10, 100, 1000 variants, element evaluations per second on the CPU (f64, one thread)
//! and on every adapter × precision found, for the full evaluation (f, K, M, S, C) and the
//! residual-only one (f and the inertial forces, modified-Newton iterations): the time
//! split of a GPU batch (upload of the per-iteration inputs, of which the content check of
//! the resident model data; kernel; download), the bytes sent and read back per element,
//! the model data uploads over all repetitions (once: it stays on the device), the error
//! against the f64 CPU result, and the per-Newton-iteration split of a real CPU run
//! (element stage, assembly, factorization + integrator).
//!
//! The variants' element states are states recorded from a short real simulation of the
//! model (different time steps standing in for different variants), so the batch holds
//! realistic deformations. `cargo bench --bench gpu` (add `-- quick` for 1…100 only).

use std::sync::{Arc, Mutex};
use std::time::Instant;

use latdyn::element::{CpuEval, ElemData, ElemIn, ElemOut, ElementEval, EvalError};
use latdyn::gpu::{self, GpuContext, GpuTimes, Precision};

struct Recorder {
    seen: Mutex<Vec<(Vec<ElemData>, Vec<ElemIn>)>>,
}
impl ElementEval for Recorder {
    fn evaluate(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        self.seen
            .lock()
            .unwrap()
            .push((elems.to_vec(), inputs.to_vec()));
        CpuEval.evaluate(elems, inputs, inertia, out)
    }
    fn name(&self) -> String {
        "recorder".into()
    }
}

/// Worst relative error over f, K, M, normwise; the scale of f has the floor
/// max|K|·L0·eps, the force of a strain `eps` (see tests/gpu.rs).
fn worst(elems: &[ElemData], cpu: &[ElemOut], g: &[ElemOut], eps: f64) -> f64 {
    let mut w = 0.0f64;
    for ((e, c), o) in elems.iter().zip(cpu).zip(g) {
        let maxabs = |a: &[f64]| a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        };
        let kmax = maxabs(c.k.as_flattened());
        let scales = [
            maxabs(&c.f).max(kmax * e.l0 * eps),
            kmax,
            maxabs(c.m.as_flattened()),
        ];
        let diffs = [
            diff(&c.f, &o.f),
            diff(c.k.as_flattened(), o.k.as_flattened()),
            diff(c.m.as_flattened(), o.m.as_flattened()),
        ];
        for (d, s) in diffs.iter().zip(scales) {
            if s > 0.0 {
                w = w.max(d / s);
            }
        }
    }
    w
}

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    let counts: &[usize] = if quick {
        &[1, 10, 100]
    } else {
        &[1, 10, 100, 1000]
    };
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let mut ctxs: Vec<GpuContext> = Vec::new();
    for (a, s) in gpu::adapters() {
        for p in [Precision::F32, Precision::F64] {
            if p == Precision::F64 && !s.shader_f64 {
                continue;
            }
            match GpuContext::new(a.clone(), s.clone(), p) {
                Ok(c) => ctxs.push(c),
                Err(e) => println!("{} {}: {e}", s.label(), p.as_str()),
            }
        }
    }
    if ctxs.is_empty() {
        println!("no GPU adapter: CPU numbers only");
    }
    for (file, sets) in [
        (
            "flapping_blade.toml",
            vec![("t_end".to_string(), 0.25), ("dt".to_string(), 0.005)],
        ),
        ("minimast_bay.toml", vec![("t_end".to_string(), 0.02)]),
    ] {
        let m = latdyn::model::load(&root.join(file), &sets).expect("model");
        // a real CPU run: the per-iteration stage split, and the recorded states
        let rec = Arc::new(Recorder {
            seen: Mutex::new(Vec::new()),
        });
        let t0 = Instant::now();
        let (split, stats) = {
            let ctx = latdyn::solver::dynamics::RunContext {
                eval: Some(rec.clone()),
                ..Default::default()
            };
            let mut it =
                latdyn::solver::dynamics::Integrator::with_context(&m, &ctx).expect("integrator");
            let _ = it.advance_to(m.solver.t_end);
            (it.asm.stage_times(), it.stats.clone())
        };
        let wall = t0.elapsed().as_secs_f64();
        let rest = (wall - split.element_s - split.assembly_s).max(0.0);
        let per = |x: f64| 1e6 * x / split.calls.max(1) as f64;
        println!(
            "\n{file}: {} elements; CPU run of {} steps, {} evaluations: per evaluation \
             element stage {:.0} us, assembly {:.0} us, factorization + integrator {:.0} us",
            m.elements.len(),
            stats.steps,
            split.calls,
            per(split.element_s),
            per(split.assembly_s),
            per(rest)
        );
        let seen = rec.seen.lock().unwrap().clone();
        println!(
            "{:>9} {:>8} | {:<44} {:<8} {:>12} {:>9} {:>9} {:>9} {:>9} {:>11} {:>9}",
            "variants",
            "elements",
            "backend",
            "eval",
            "evals/s",
            "upload",
            "(check)",
            "kernel",
            "download",
            "B up/dn/el",
            "error"
        );
        for &nv in counts {
            let mut elems = Vec::new();
            let mut inputs = Vec::new();
            for v in 0..nv {
                let (e, i) = &seen[(v * 7919) % seen.len()];
                elems.extend_from_slice(e);
                inputs.extend_from_slice(i);
            }
            let n = elems.len();
            let mut cpu = vec![ElemOut::default(); n];
            for residual in [false, true] {
                let kind = if residual { "residual" } else { "full" };
                let reps = (20_000 / n).max(1);
                let t = Instant::now();
                for _ in 0..reps {
                    if residual {
                        CpuEval.evaluate_residual(&elems, &inputs, true, &mut cpu)
                    } else {
                        CpuEval.evaluate(&elems, &inputs, true, &mut cpu)
                    }
                    .unwrap();
                }
                let dt = t.elapsed().as_secs_f64() / reps as f64;
                println!(
                    "{nv:>9} {n:>8} | {:<44} {kind:<8} {:>12.0} {:>9} {:>9} {:>9} {:>9} {:>11} {:>9}",
                    "cpu f64 (1 thread)",
                    n as f64 / dt,
                    "-",
                    "-",
                    "-",
                    "-",
                    "-",
                    "ref"
                );
                for ctx in ctxs.iter_mut() {
                    let mut out = vec![ElemOut::default(); n];
                    let run = |ctx: &mut GpuContext, out: &mut [ElemOut]| {
                        if residual {
                            ctx.evaluate_residual(&elems, &inputs, true, out)
                        } else {
                            ctx.evaluate(&elems, &inputs, true, out)
                        }
                    };
                    // warm-up: buffer allocation, pipeline first use, model data upload
                    if let Err(e) = run(ctx, &mut out) {
                        println!("{}: {e}", ctx.adapter.label());
                        continue;
                    }
                    let uploads0 = ctx.model_uploads();
                    let mut tt = GpuTimes::default();
                    let reps = (2_000 / n).clamp(1, 20);
                    let t = Instant::now();
                    for _ in 0..reps {
                        tt.add(&run(ctx, &mut out).unwrap());
                    }
                    let dt = t.elapsed().as_secs_f64() / reps as f64;
                    let r = reps as f64;
                    let ups = ctx.model_uploads().uploads - uploads0.uploads;
                    let err = if residual {
                        worst_residual(&cpu, &out)
                    } else {
                        worst(
                            &elems,
                            &cpu,
                            &out,
                            match ctx.precision {
                                Precision::F32 => f32::EPSILON as f64 / 2.0,
                                Precision::F64 => f64::EPSILON / 2.0,
                            },
                        )
                    };
                    println!(
                        "{nv:>9} {n:>8} | {:<44} {kind:<8} {:>12.0} {:>7.2}ms {:>7.3}ms {:>7.2}ms {:>7.2}ms {:>5}/{:<5} {:>9.1e}{}",
                        format!("{} {}", ctx.adapter.label(), ctx.precision.as_str()),
                        n as f64 / dt,
                        1e3 * tt.upload_s / r,
                        1e3 * tt.check_s / r,
                        1e3 * tt.kernel_s / r,
                        1e3 * tt.download_s / r,
                        tt.bytes_up / (reps * n) as u64,
                        tt.bytes_down / (reps * n) as u64,
                        err,
                        if ups > 0 {
                            format!("  ({ups} model uploads in {reps} reps)")
                        } else {
                            String::new()
                        }
                    );
                }
            }
        }
    }
}

/// Worst relative error of f, finert and mv against the CPU's residual evaluation,
/// normwise over the batch (max difference / max |cpu| of each array): elements at rest
/// have f and finert zero up to round-off, so per-element ratios would mean nothing.
fn worst_residual(cpu: &[ElemOut], g: &[ElemOut]) -> f64 {
    let mut w = 0.0f64;
    for pick in [
        |o: &ElemOut| o.f,
        |o: &ElemOut| o.finert,
        |o: &ElemOut| o.mv,
    ] {
        let (mut d, mut s) = (0.0f64, 0.0f64);
        for (c, o) in cpu.iter().zip(g) {
            for (x, y) in pick(c).iter().zip(pick(o).iter()) {
                s = s.max(x.abs());
                d = d.max((x - y).abs());
            }
        }
        if s > 0.0 {
            w = w.max(d / s);
        }
    }
    w
}
