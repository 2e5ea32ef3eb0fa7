//! The campaign verbs: `sweep` (with `--plan`, `--resume`, `--path`) and `merge`.

use anyhow::{anyhow, bail};
use latdyn::model::{self, Model};

use crate::backend::{choose_stage, gpu_default_batch};
use crate::cli::{MergeArgs, SweepArgs};
use crate::{
    claim_optional_output, claim_output, emit, fail, injected_panic, stop_flag, EXIT_FAILED,
    EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_OUTPUT, EXIT_USAGE,
};

/// The files a sweep reads, for [`claim_output`]: the model and the `--variants` table
/// (not `--resume`'s campaign, which it completes in place).
fn sweep_inputs(args: &SweepArgs) -> Vec<(&std::path::Path, &'static str)> {
    let mut v = vec![(args.model.model.as_path(), "the model file")];
    if let Some(csv) = &args.variants {
        v.push((csv.as_path(), "the --variants file"));
    }
    v
}

/// `latdyn merge`: exit 0 when every variant completed, 3 when all ran and some failed,
/// 4 when some are missing or interrupted (resume the merged file), 2 when refused
/// (another campaign, repeated indices, unreadable input), 5 when the output failed.
pub(crate) fn merge(args: &MergeArgs) -> anyhow::Result<()> {
    use latdyn::campaign::{self, MergeError, MergeReport};
    let shards: Vec<_> = args
        .shards
        .iter()
        .map(|p| (p.as_path(), "one of the shard files"))
        .collect();
    let stop = crate::stop_flag();
    let target = claim_output(&args.output, &shards)?;
    crate::note_campaign_format(Some(&args.output));
    let mut report = MergeReport::default();
    let command_line = latdyn::output::command_line();
    let result = campaign::merge(
        &args.shards,
        target,
        &command_line,
        &mut report,
        Some(&stop),
    );
    let (code, message) = match &result {
        Ok(()) if !report.missing.is_empty() || !report.interrupted.is_empty() => (
            EXIT_INTERRUPTED,
            format!(
                "campaign incomplete: {} missing, {} interrupted, {} failed of {} variants; complete it with `latdyn sweep ... --resume {}`",
                report.missing.len(),
                report.interrupted.len(),
                report.failed.len(),
                report.variants,
                args.output.display()
            ),
        ),
        Ok(()) if !report.failed.is_empty() => (
            EXIT_FAILED,
            format!(
                "{} of {} variants failed (see their status and message in {})",
                report.failed.len(),
                report.variants,
                args.output.display()
            ),
        ),
        Ok(()) => (0, String::new()),
        Err(MergeError::Output(e)) => (EXIT_OUTPUT, e.to_string()),
        Err(MergeError::Interrupted(m)) => (EXIT_INTERRUPTED, m.clone()),
        Err(e) => (EXIT_USAGE, e.to_string()),
    };
    report.status = match &result {
        Ok(()) => report.status.clone(),
        Err(MergeError::Output(_)) => "output_failed".into(),
        Err(MergeError::Interrupted(_)) => "interrupted".into(),
        Err(_) => "refused".into(),
    };
    report.message = message.clone();
    let list = |v: &[usize]| {
        let shown: Vec<String> = v.iter().take(30).map(|g| g.to_string()).collect();
        format!(
            "{}{}",
            shown.join(", "),
            if v.len() > shown.len() { ", …" } else { "" }
        )
    };
    if result.is_ok() {
        eprintln!(
            "merge: campaign {} ({} variants) from {} shard file(s) into {} in {:.2} s: {} completed, {} failed, {} interrupted, {} missing",
            report.campaign_id,
            report.variants,
            report.shards.len(),
            args.output.display(),
            report.wall_s,
            report.completed,
            report.failed.len(),
            report.interrupted.len(),
            report.missing.len()
        );
        for (what, v) in [
            ("missing", &report.missing),
            ("interrupted", &report.interrupted),
            ("failed", &report.failed),
        ] {
            if !v.is_empty() {
                eprintln!("merge: {what} global indices: {}", list(v));
            }
        }
        if !report.verification_not_merged.is_empty() {
            eprintln!(
                "warning: merge: {} have /verification (sweep --verify verifies in shard 1 \
                 only); the merged file carries none of them",
                report.verification_not_merged.join(", ")
            );
        }
    }
    if args.json {
        emit(&format!(
            "{}\n",
            serde_json::to_string(&report).map_err(|e| anyhow!("{e}"))?
        ))?;
    }
    match code {
        0 => Ok(()),
        c => Err(fail(c, message)),
    }
}

pub(crate) fn sweep(args: &SweepArgs) -> anyhow::Result<()> {
    use latdyn::ensemble::{self, Campaign};
    use std::io::IsTerminal;
    use std::sync::atomic::Ordering;
    if args.path.path {
        return sweep_path(args);
    }
    if args.path.any_option() {
        bail!("sweep: --control, --lambda-max, --until, --limit-points, --max-length, --max-points and --first-step need --path");
    }
    // The signal handler first, before the output is claimed and the variants compiled:
    // a large campaign spends seconds in its preparation, and a signal there killed the
    // process, leaving no summary and a stale lock file. The preparation checks the flag
    // between variants (see `interrupted_in_preparation`). `--plan` writes nothing and
    // keeps the default behaviour (a signal ends it at once).
    let stop = if args.plan {
        std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false))
    } else {
        stop_flag()
    };
    let t_prepare = std::time::Instant::now();
    // `origin` names a variant that breaks the model by its CSV line or grid point
    let (variants, origin) = ensemble::variants_with_origin(
        &args.model.model,
        &args.model.set,
        &args.vary,
        args.variants.as_deref(),
    )?;
    let frequency_sensor = match &args.frequency {
        None => None,
        Some(spec) => {
            let m = args.model.load()?;
            let (name, comp) = spec.split_once('.').unwrap_or((spec.as_str(), ""));
            let k = m
                .sensor_index(name)
                .ok_or_else(|| anyhow!("--frequency: the model has no sensor `{name}`"))?;
            let comps = latdyn::sensors::components(&m.sensors[k].kind);
            let c = if spec.ends_with('.') {
                return Err(anyhow!(
                    "--frequency: `{spec}` names no component after the `.` (sensor `{name}` \
                     has {})",
                    comps.join(", ")
                ));
            } else if comp.is_empty() {
                if comps.len() > 1 {
                    eprintln!(
                        "note: --frequency {name}: the spectrum of its first component, \
                         `{}`; name another with {name}.COMPONENT ({})",
                        comps[0],
                        comps.join(", ")
                    );
                }
                0
            } else {
                comps.iter().position(|c| *c == comp).ok_or_else(|| {
                    anyhow!(
                        "--frequency: sensor `{name}` has no component `{comp}` (it has {})",
                        comps.join(", ")
                    )
                })?
            };
            Some((name.to_string(), c))
        }
    };
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    // the element count decides `auto`; the model is compiled again per variant later
    let mut base_model = args.model.load()?;
    let n_elem = base_model.elements.len();
    if let Some(a) = args.accuracy {
        crate::run::check_accuracy(a, &base_model)?;
    }
    base_model.solver.accuracy = args.accuracy.or(base_model.solver.accuracy);
    if let Some(note) = crate::run::spread_note(&base_model) {
        eprintln!(
            "{note} (the base model; a variant whose own dt does not divide its interval is \
             spread the same way)"
        );
    }
    // before compiling the variants: a refused path costs nothing
    let mut target = claim_optional_output(
        args.output.as_deref().or(args.resume.as_deref()),
        &sweep_inputs(args),
    )?;
    crate::note_campaign_format(args.output.as_deref());
    let n_var = variants.len().max(1);
    let (stage, gpu_eval) = choose_stage(&args.backend, n_var, n_elem, cores)?;
    // GPU too: one worker per core, each driving its batch; while one worker's round is
    // on the device, the others assemble and factorize
    let threads = args.threads.unwrap_or(cores);
    let c = Campaign {
        model_path: args.model.model.clone(),
        base: args.model.set.clone(),
        variants,
        threads,
        batch: args.batch.map_or(
            // GPU: each round is one dispatch per kernel over its batch, so the batch is
            // every variant of a worker, bounded in elements (see `gpu_default_batch`)
            if stage.make.is_some() {
                gpu_default_batch(n_elem)
            } else {
                latdyn::ensemble::DEFAULT_BATCH
            },
            |b| b as usize,
        ),
        output: args.output.clone().or(args.resume.clone()),
        shard: args.shard,
        accuracy: args.accuracy,
        frequency_sensor,
        command_line: latdyn::output::command_line(),
    };
    if args.plan {
        return sweep_plan(args, &c, &stage, &origin);
    }
    // --verify K: K variants of shard 1 (the whole campaign when not sharded), checked
    // before any variant runs
    let verify_chosen: Option<Vec<usize>> = match (args.verify, args.shard) {
        (None, _) => None,
        (Some(k), shard) => {
            let (s, n) = shard.unwrap_or((1, 1));
            let shard1: Vec<usize> = (0..c.variants.len()).filter(|i| i % n == 0).collect();
            let total = c.variants.len();
            let mut note = format!(
                "the campaign has {total} variant{}",
                if total == 1 { "" } else { "s" }
            );
            if n > 1 {
                note += &format!(
                    "; verification runs in shard 1/{n}, which has {}",
                    shard1.len()
                );
            }
            latdyn::verify::check_count(k, shard1.len(), &note).map_err(|e| anyhow!(e))?;
            if s == 1 {
                Some(latdyn::verify::select(&shard1, k).map_err(|e| anyhow!(e))?)
            } else {
                eprintln!("note: --verify: verification runs in shard 1/{n} only; not in this shard {s}/{n}");
                None
            }
        }
    };
    // --mesh-check: the variants whose mesh twin runs after the campaign, chosen over
    // the whole campaign so that shards measure the rows the single sweep would (none
    // where the model has no beams: the variants share its topology)
    let mesh_plan = mesh_plan(args, c.variants.len(), &base_model);
    if let Some(plan) = &mesh_plan {
        check_kept_histories(&base_model, plan.variants.len())?;
    }
    let (prepared, resume) = match (&args.resume, target.take()) {
        (Some(path), Some(t)) => {
            let r = match latdyn::campaign::resume_until(
                t,
                &c,
                &stage,
                &origin,
                &stop,
                mesh_plan.as_ref(),
            ) {
                Ok(r) => r,
                Err(latdyn::campaign::MergeError::Interrupted(message)) => {
                    return interrupted_in_preparation(args, &c, &stage, t_prepare, message)
                }
                Err(e) => return Err(anyhow!("{e}")),
            };
            eprintln!(
                "sweep --resume {}: {} variant(s) to run (not completed) of {} in the file",
                path.display(),
                r.rows.len(),
                r.writer.n_variants()
            );
            (r.prepared, Some((r.writer, r.rows)))
        }
        (_, t) => match ensemble::prepare_until(&c, &stop) {
            Ok(p) => {
                target = t;
                (p, None)
            }
            Err(e @ ensemble::EnsembleError::Interrupted { .. }) => {
                // nothing was written yet: release the claim (and its lock file) and
                // leave the path as it was
                drop(t);
                let message = format!(
                    "{e}; no variant ran{}",
                    c.output
                        .as_ref()
                        .map(|p| format!(
                            " and {} was not written (a file already there is left as it was)",
                            p.display()
                        ))
                        .unwrap_or_default()
                );
                return interrupted_in_preparation(args, &c, &stage, t_prepare, message);
            }
            Err(e) => return Err(origin.name(e, &c.variants).into()),
        },
    };
    // a varied dt (or a parameter it depends on) that does not divide its output
    // interval is spread as the base model's note says, but said per variant: until
    // session 47 only the base model's was (a probe: `--vary dt=3e-4:3e-4:2` ran
    // 2.94e-4 s steps with no note)
    let base_note = crate::run::spread_note(&base_model);
    let spread: Vec<(usize, String)> = prepared
        .models
        .iter()
        .zip(&prepared.global_index)
        .filter_map(|(m, &g)| crate::run::spread_note(m).map(|n| (g, n)))
        .filter(|(_, n)| Some(n) != base_note.as_ref())
        .collect();
    if let Some((g, first)) = spread.first() {
        let shown: Vec<String> = spread.iter().take(20).map(|(g, _)| g.to_string()).collect();
        eprintln!(
            "note: {} variant(s) step other than their dt: indices {}{} (variant {g}: {})",
            spread.len(),
            shown.join(", "),
            if spread.len() > shown.len() {
                ", …"
            } else {
                ""
            },
            first.trim_start_matches("note: ")
        );
    }
    let bar = if std::io::stderr().is_terminal() {
        let b = indicatif::ProgressBar::new(prepared.models.len() as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} variants, {elapsed} elapsed, ETA {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Some(b)
    } else {
        None
    };
    let t0 = std::time::Instant::now();
    let ensemble::CampaignRun {
        outcomes,
        output_error,
        verification,
        mesh,
        batch: batch_counts,
    } = {
        let progress = |done: usize, _: usize| {
            if let Some(b) = &bar {
                b.set_position(done as u64);
            }
            if injected_panic("worker") {
                panic!("injected panic in a sweep worker (LATDYN_FAULT_PANIC=worker)");
            }
        };
        // a panic outside the variants (they catch their own) is a bug in the sweep's
        // own code: the file is left marked interrupted (its writer's drop) and
        // `--resume` completes it, and `--json` still gets its object (until session 47
        // stdout stayed empty; a probe)
        let ran = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match resume {
            Some((writer, rows)) => ensemble::run_resume(
                &c,
                &prepared,
                &stop,
                &progress,
                &stage,
                writer,
                &rows,
                mesh_plan.as_ref(),
            ),
            None => ensemble::run_verified_to(
                &c,
                &prepared,
                &stop,
                false,
                &progress,
                &stage,
                target,
                verify_chosen.as_deref(),
                mesh_plan.as_ref(),
            ),
        }));
        match ran {
            Ok(r) => r,
            Err(payload) => {
                let message = format!(
                    "internal error: {} (this is a bug in latdyn; please report it); the \
                     sweep stopped{}",
                    crate::panic_text(payload.as_ref()),
                    c.output
                        .as_ref()
                        .map(|p| format!(
                            ", {} is marked interrupted and `sweep --resume` completes it",
                            p.display()
                        ))
                        .unwrap_or_default()
                );
                if args.model.json {
                    let v = serde_json::json!({
                        "status": "internal_error",
                        "message": message,
                        "variants": [],
                        "wall_s": t_prepare.elapsed().as_secs_f64(),
                        "backend": stage.backend,
                        "precision": stage.precision,
                        "threads": c.threads,
                    });
                    emit(&format!("{v}\n"))?;
                }
                // the panic hook has printed the error line
                return Err(fail(EXIT_INTERNAL, String::new()));
            }
        }
    }
    .map_err(|e| anyhow!("{e}"))?;
    let gpu_stats = gpu_eval.as_ref().map(|g| (g.times(), g.model_uploads()));
    if let (Some(g), Some((t, model))) = (&gpu_eval, &gpu_stats) {
        eprintln!(
            "{}: {} rounds, {:.2} dispatches per round ({} residual-only), {:.1} requests per \
             round; upload {:.3} s, kernels {:.3} s, download {:.3} s; model data {} upload(s) \
             of {} B",
            latdyn::element::ElementEval::name(&**g),
            t.batches,
            t.dispatches as f64 / t.batches.max(1) as f64,
            t.residual_dispatches,
            t.requests as f64 / t.batches.max(1) as f64,
            t.upload_s,
            t.kernel_s,
            t.download_s,
            model.uploads,
            model.bytes
        );
    }
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let wall = t0.elapsed().as_secs_f64();
    let failed = outcomes
        .iter()
        .filter(|o| o.state != latdyn::output::VariantState::Completed)
        .count();
    let n_failed = outcomes
        .iter()
        .filter(|o| o.state == latdyn::output::VariantState::Failed)
        .count();
    let interrupted = stop.load(Ordering::SeqCst) && output_error.is_none();
    let not_in_file = outcomes.iter().filter(|o| o.in_file == Some(false)).count();
    let (status, message) = match &output_error {
        Some(e) => (
            "output_failed",
            format!(
                "{e}; the campaign stopped (variants not run are marked not_run){}",
                c.output
                    .as_ref()
                    .map(|p| format!(
                        ", {} keeps its last flush{}",
                        p.display(),
                        if not_in_file > 0 {
                            format!(
                                ", which lacks {not_in_file} variant(s) that ran after it \
                                 (\"in_file\": false; `sweep --resume` reruns them)"
                            )
                        } else {
                            String::new()
                        }
                    ))
                    .unwrap_or_default()
            ),
        ),
        // every variant done: the signal stopped the mesh twins or the refined runs of
        // --verify only, and the file is complete
        None if interrupted
            && outcomes.iter().all(|o| {
                matches!(
                    o.state,
                    latdyn::output::VariantState::Completed | latdyn::output::VariantState::Failed
                )
            }) =>
        {
            (
                "interrupted",
                "interrupted by a signal during the mesh checks or the --verify runs: every \
                 variant ran and the campaign file is complete; the mesh error and the \
                 verification cover only the runs that finished"
                    .to_string(),
            )
        }
        None if interrupted => (
            "interrupted",
            "interrupted by a signal; the campaign file is marked interrupted".to_string(),
        ),
        None => ("complete", String::new()),
    };
    let batch = ensemble::batch_size(c.batch, prepared.models.len(), threads);
    let per_call = batch_counts.requests as f64 / batch_counts.calls.max(1) as f64;
    eprintln!(
        "sweep {}: {} variants ({} not completed) in {:.2} s on {} threads, in batches of {} \
         ({} element-stage calls, {:.2} variants per call){}",
        c.model_path.display(),
        outcomes.len(),
        failed,
        wall,
        threads,
        batch,
        batch_counts.calls,
        per_call,
        match (&c.output, &output_error) {
            (Some(p), None) => format!(", written to {}", p.display()),
            (Some(p), Some(_)) => format!(", writing {} failed", p.display()),
            (None, _) => String::new(),
        }
    );
    report_warning_kinds(
        outcomes
            .iter()
            .map(|o| (o.global_index, o.warnings.clone())),
    );
    let has_mesh = prepared
        .models
        .first()
        .is_some_and(|m| !m.elem_data.is_empty());
    let mesh_json = has_mesh
        .then(|| mesh_summary(mesh.as_ref(), mesh_plan.as_ref(), c.variants.len()))
        .flatten();
    if let Some(v) = &verification {
        eprintln!("{}", v.summary());
        for w in &v.warnings {
            eprintln!("warning: verify: {w}");
        }
    }
    if args.model.json {
        let m0 = prepared.models.first();
        let vs: Vec<serde_json::Value> = outcomes
            .iter()
            .map(|o| {
                let sensors: serde_json::Map<String, serde_json::Value> = m0
                    .map(|m| {
                        m.sensors
                            .iter()
                            .zip(&o.sensors)
                            .map(|(s, x)| {
                                (
                                    s.name.clone(),
                                    serde_json::json!({"min": x.min, "max": x.max, "final": x.last}),
                                )
                            })
                            .collect()
                    })
                    .unwrap_or_default();
                let params: serde_json::Map<String, serde_json::Value> = o
                    .parameters
                    .iter()
                    .map(|(n, v)| (n.clone(), serde_json::json!(v)))
                    .collect();
                let derived: serde_json::Map<String, serde_json::Value> = o
                    .derived
                    .iter()
                    .map(|(n, v)| (n.clone(), serde_json::json!(v)))
                    .collect();
                serde_json::json!({
                    "index": o.global_index,
                    "parameters": params,
                    "status": match o.state {
                        latdyn::output::VariantState::Completed => "completed",
                        latdyn::output::VariantState::Interrupted => "interrupted",
                        latdyn::output::VariantState::Pending => "not_run",
                        _ => "failed",
                    },
                    "message": o.message,
                    "steps": o.steps,
                    "rejected_steps": o.rejected_steps,
                    "accuracy_runs": o.accuracy_runs,
                    "accuracy_steps_all_runs": o.accuracy_steps,
                    "wall_s": o.wall_s,
                    "energy_growth": o.energy_growth,
                    "energy_loss": o.energy_loss,
                    "time_error_estimate": o.time_error_estimate,
                    "time_error_before_first_lock": o.time_error_before_first_lock,
                    "mesh_error_estimate": o.mesh_error_estimate,
                    "warnings": o.warnings,
                    "in_file": o.in_file,
                    "sensors": sensors,
                    "derived": derived,
                })
            })
            .collect();
        let mut v = serde_json::json!({
            "status": status,
            "message": message,
            "failed_variants": n_failed,
            "variants": vs,
            "wall_s": wall,
            "backend": stage.backend,
            "precision": stage.precision,
            "adapter": stage.adapter,
            "threads": threads,
            "batch": batch,
            "element_stage_calls": batch_counts.calls,
            "requests_per_call": per_call,
        });
        if let Some((t, model)) = &gpu_stats {
            v["gpu"] = serde_json::json!({
                "rounds": t.batches,
                "dispatches": t.dispatches,
                "residual_dispatches": t.residual_dispatches,
                "requests": t.requests,
                "elements": t.elements,
                "upload_s": t.upload_s,
                "kernel_s": t.kernel_s,
                "download_s": t.download_s,
                "bytes_up": t.bytes_up,
                "bytes_down": t.bytes_down,
                "model_uploads": model.uploads,
                "model_bytes": model.bytes,
            });
        }
        if let Some(m) = mesh_json {
            v["mesh_check"] = m;
        }
        if args.verify.is_some() {
            v["verification"] = match &verification {
                Some(x) => x.to_json(),
                None if verify_chosen.is_none() => serde_json::json!({
                    "skipped": "verification runs in shard 1 only"
                }),
                None => serde_json::json!({
                    "skipped": "the campaign did not finish (interrupted or output failed)"
                }),
            };
        }
        emit(&format!("{v}\n"))?;
    }
    let panicked: Vec<String> = outcomes
        .iter()
        .filter(|o| o.panicked)
        .map(|o| o.global_index.to_string())
        .collect();
    if !panicked.is_empty() {
        // each panic printed its own line (the hook); this one says which variants
        return Err(fail(
            EXIT_INTERNAL,
            format!(
                "internal error in variant(s) {} (marked failed; this is a bug in latdyn; \
                 please report it)",
                panicked.join(", ")
            ),
        ));
    }
    if output_error.is_some() {
        return Err(fail(EXIT_OUTPUT, message));
    }
    if interrupted {
        return Err(fail(EXIT_INTERRUPTED, message));
    }
    if n_failed > 0 {
        return Err(fail(
            EXIT_FAILED,
            format!(
                "{n_failed} of {} variants failed (see their status and message{})",
                outcomes.len(),
                c.output
                    .as_ref()
                    .map(|p| format!(" in {}", p.display()))
                    .unwrap_or_default()
            ),
        ));
    }
    Ok(())
}

/// The sampled variants' histories are kept in memory until their twins run, after the
/// campaign (`--mesh-check always`: every variant's). Refused before anything runs where
/// they would take more than half this machine's memory: the campaign's own values are
/// held to `output_values` at 8 bytes each, a kept history takes 8 times that.
fn check_kept_histories(m: &latdyn::model::Model, kept: usize) -> anyhow::Result<()> {
    let Some(mem) = latdyn::model::limits::memory_bytes() else {
        return Ok(());
    };
    let per_variant = latdyn::solver::dynamics::output_times(m).len() as f64
        * m.sensors
            .iter()
            .map(|s| latdyn::sensors::components(&s.kind).len() as f64)
            .sum::<f64>();
    let bytes = per_variant * kept as f64 * latdyn::verify::HISTORY_BYTES_PER_VALUE;
    if bytes <= 0.5 * mem as f64 {
        return Ok(());
    }
    bail!(
        "{}: --mesh-check keeps the histories of {kept} variant(s) until their twins run, {} \
         values, about {:.1} GB at {} bytes each, more than half this machine's {:.1} \
         GiB: `--mesh-check auto` measures three, or sample less often \
         (`[solver] output_dt`)",
        m.path,
        latdyn::model::limits::count(per_variant * kept as f64),
        bytes / 1e9,
        latdyn::verify::HISTORY_BYTES_PER_VALUE,
        mem as f64 / f64::from(1u32 << 30)
    )
}

/// The variants `--mesh-check` (default `auto`) samples among `n`, none where the model
/// `m` has no beams (the variants share its topology).
fn mesh_plan(
    args: &SweepArgs,
    n: usize,
    m: &latdyn::model::Model,
) -> Option<latdyn::verify::MeshSample> {
    latdyn::verify::MeshSample::plan(args.mesh_check.as_deref().unwrap_or("auto"), n)
        .filter(|_| !m.elem_data.is_empty())
}

/// Variant indices for a message: the first 20 (`--mesh-check always` samples every
/// variant, up to a million).
fn indices(v: &[usize]) -> String {
    let shown: Vec<String> = v.iter().take(20).map(|g| g.to_string()).collect();
    shown.join(", ") + if v.len() > 20 { ", …" } else { "" }
}

/// What a sweep's `--mesh-check` measured (`mesh`: the sampled variants of this shard
/// and the twins' wall time), said on stderr, with the `mesh_check` object of
/// `sweep --json`. The campaign's rows that were not sampled carry no figure: where a
/// sampled one passes the limit, the warning says they are likely as coarse.
fn mesh_summary(
    mesh: Option<&(Vec<latdyn::verify::VariantMesh>, f64)>,
    plan: Option<&latdyn::verify::MeshSample>,
    n_variants: usize,
) -> Option<serde_json::Value> {
    use latdyn::verify::MeshTwinSkip;
    let Some(plan) = plan else {
        eprintln!(
            "note: --mesh-check never: the variants' mesh error is not measured (`latdyn \
             run` with a variant's --set measures that one's)"
        );
        return Some(serde_json::json!({"mode": "never", "sampled": []}));
    };
    let Some((checks, wall)) = mesh else {
        return Some(serde_json::json!({
            "mode": plan.mode,
            "sampled": plan.variants,
            "measured": [],
            "skipped": "the campaign did not finish (interrupted or output failed)",
        }));
    };
    let limit = latdyn::solver::MESH_ERROR_WARN;
    let measured: Vec<(usize, &latdyn::verify::RunMeshError)> = checks
        .iter()
        .filter_map(|c| c.result.as_ref().ok().map(|e| (c.global_index, e)))
        .collect();
    let not_measured: Vec<serde_json::Value> = checks
        .iter()
        .filter_map(|c| match &c.result {
            Ok(_) => None,
            Err(MeshTwinSkip::Interrupted) => Some(serde_json::json!({
                "index": c.global_index, "why": "a signal stopped the check"
            })),
            Err(MeshTwinSkip::Failed(why)) => Some(serde_json::json!({
                "index": c.global_index, "why": why
            })),
        })
        .collect();
    let worst = measured
        .iter()
        .copied()
        .max_by(|a, b| a.1.estimate.total_cmp(&b.1.estimate));
    let above: Vec<usize> = measured
        .iter()
        .filter(|(_, e)| e.estimate > limit)
        .map(|(g, _)| *g)
        .collect();
    let here: Vec<usize> = checks.iter().map(|c| c.global_index).collect();
    match worst {
        Some((g, e)) => {
            eprintln!(
            "mesh check: {} of {} sampled variant(s) here ({}) run again on {} elements (their \
             {} doubled) at their step in {wall:.2} s: largest mesh error estimate {:.2} % \
             ({}, variant {g}){}",
            measured.len(),
            here.len(),
            indices(&here),
            e.elements.1,
            e.elements.0,
            100.0 * e.estimate,
            e.worst,
            if e.estimate > limit { ", above 1 %" } else { "" }
        )
        }
        None if here.is_empty() => eprintln!(
            "mesh check: none of the sampled variants ({}) ran here (another shard's, or \
             completed before this resume)",
            indices(&plan.variants)
        ),
        None => eprintln!(
            "mesh check: no sampled variant measured ({}; see their warnings)",
            indices(&here)
        ),
    }
    let unmeasured = n_variants.saturating_sub(plan.variants.len());
    if !above.is_empty() {
        eprintln!(
            "warning: mesh: variant(s) {} are estimated above 1 % of a sensor's range off the \
             converged mesh (their warnings name the sensor); {}add elements",
            indices(&above),
            if unmeasured > 0 {
                format!(
                    "the {unmeasured} variant(s) not sampled were not measured and are likely as \
                     coarse; "
                )
            } else {
                String::new()
            }
        );
    } else if unmeasured > 0 && !measured.is_empty() {
        eprintln!(
            "note: mesh: {unmeasured} variant(s) not sampled are not measured (`--mesh-check \
             always` measures every one)"
        );
    }
    let num = |x: f64| {
        if x.is_finite() {
            serde_json::json!(x)
        } else {
            serde_json::json!(null)
        }
    };
    Some(serde_json::json!({
        "mode": plan.mode,
        "sampled": plan.variants,
        "measured": measured.iter().map(|(g, _)| *g).collect::<Vec<_>>(),
        "not_measured": not_measured,
        "limit": limit,
        "max_estimate": worst.map(|(_, e)| num(e.estimate)),
        "worst": worst.map(|(g, e)| serde_json::json!({"index": g, "sensor": e.worst})),
        "above_limit": above,
        "elements": worst.map(|(_, e)| [e.elements.0, e.elements.1]),
        "wall_s": wall,
    }))
}

/// A sweep stopped by a signal while its variants were being compiled (before any
/// variant ran, see `ensemble::prepare_until`): the output path is left as it was (no
/// file is written: a file marked interrupted would need every variant compiled, the work
/// the signal stopped; `--resume`'s file is not touched), its lock is released, the
/// `--json` summary says `"status": "interrupted"` with no variants, and the exit code is
/// [`EXIT_INTERRUPTED`] as for a sweep interrupted while running.
fn interrupted_in_preparation(
    args: &SweepArgs,
    c: &latdyn::ensemble::Campaign,
    stage: &latdyn::ensemble::Stage,
    t_prepare: std::time::Instant,
    message: String,
) -> anyhow::Result<()> {
    if args.model.json {
        let (k, n) = c.shard.unwrap_or((1, 1));
        let in_shard = (0..c.variants.len()).filter(|i| i % n == k - 1).count();
        let mut v = serde_json::json!({
            "status": "interrupted",
            "message": message,
            "failed_variants": 0,
            "variants": [],
            "wall_s": t_prepare.elapsed().as_secs_f64(),
            "backend": stage.backend,
            "precision": stage.precision,
            "adapter": stage.adapter,
            "threads": c.threads,
            "batch": latdyn::ensemble::batch_size(c.batch, in_shard, c.threads),
            "element_stage_calls": 0,
            "requests_per_call": 0.0,
        });
        if args.verify.is_some() {
            v["verification"] = serde_json::json!({
                "skipped": "the campaign did not finish (interrupted or output failed)"
            });
        }
        emit(&format!("{v}\n"))?;
    }
    Err(fail(EXIT_INTERRUPTED, message))
}

/// Fraction of t_end a `sweep --plan` probe runs.
pub(crate) const PROBE_FRACTION: f64 = 0.1;

/// `sweep --plan`: the variant table with each variant's shard, and the cost estimate.
pub(crate) fn sweep_plan(
    args: &SweepArgs,
    c: &latdyn::ensemble::Campaign,
    stage: &latdyn::ensemble::Stage,
    origin: &latdyn::ensemble::Origin,
) -> anyhow::Result<()> {
    use latdyn::campaign;
    let n = c.variants.len();
    let shards = args.shards;
    // one compiled variant gives the time grid and sensors of the identity
    let p = latdyn::ensemble::prepare_rows(c, vec![0]).map_err(|e| origin.name(e, &c.variants))?;
    let info = latdyn::ensemble::identify(c, &p, stage)?;
    let m0 = &p.models[0];
    let n_time = p.time.len();
    let values_per_variant: usize = m0
        .sensors
        .iter()
        .map(|s| latdyn::sensors::components(&s.kind).len())
        .sum::<usize>()
        * n_time;
    let probes = campaign::probe(c, &campaign::probe_indices(n, args.probe), PROBE_FRACTION)
        .map_err(|e| origin.name(e, &c.variants))?;
    let ok: Vec<f64> = probes
        .iter()
        .filter(|x| x.status == "completed")
        .map(|x| x.per_variant_s)
        .collect();
    // the median: the first run of a process pays for cold caches and page faults
    let mean = (!ok.is_empty()).then(|| {
        let mut v = ok.clone();
        v.sort_by(f64::total_cmp);
        if v.len() % 2 == 1 {
            v[v.len() / 2]
        } else {
            (v[v.len() / 2 - 1] + v[v.len() / 2]) / 2.0
        }
    });
    let max = ok
        .iter()
        .copied()
        .fold(None, |a: Option<f64>, x| Some(a.map_or(x, |a| a.max(x))));
    let per_shard = n.div_ceil(shards);
    let threads = args.threads.unwrap_or(1);
    // the mesh twins the sweep runs after its variants (`--mesh-check`): one probed (the
    // middle sampled variant), its cost charged to each sampled variant's shard
    let mesh_plan = mesh_plan(args, n, m0);
    let twin = match &mesh_plan {
        Some(plan) if !plan.variants.is_empty() => {
            let g = plan.variants[plan.variants.len() / 2];
            campaign::probe_twin(c, g, PROBE_FRACTION, plan.max_dofs)
                .map_err(|e| origin.name(e, &c.variants))?
        }
        _ => None,
    };
    let twin_s = twin
        .as_ref()
        .filter(|x| x.status == "completed")
        .map(|x| x.per_variant_s);
    let sampled = mesh_plan.as_ref().map_or(&[][..], |p| &p.variants[..]);
    // the longest task: its variants and its twins, spread over its threads
    // (one pass each: shards and variants are both up to a million)
    let mut twins_in = vec![0usize; shards];
    for g in sampled {
        twins_in[g % shards] += 1;
    }
    let per_task = mean.map(|x| {
        (0..shards)
            .map(|k| {
                let variants = n / shards + usize::from(k < n % shards);
                (variants as f64 * x + twins_in[k] as f64 * twin_s.unwrap_or(0.0)) / threads as f64
            })
            .fold(0.0, f64::max)
    });
    let twins_cpu = twin_s.map_or(0.0, |t| t * sampled.len() as f64);
    let table: Vec<serde_json::Value> = c
        .variants
        .iter()
        .enumerate()
        .map(|(g, row)| {
            let params: serde_json::Map<String, serde_json::Value> = row
                .iter()
                .map(|(k, v)| (k.clone(), serde_json::json!(v)))
                .collect();
            serde_json::json!({"index": g, "parameters": params, "shard": g % shards + 1})
        })
        .collect();
    let counts: Vec<usize> = (0..shards)
        .map(|k| n / shards + usize::from(k < n % shards))
        .collect();
    let v = serde_json::json!({
        "campaign_id": info.id,
        "campaign_hash": info.hash,
        "variants": n,
        "varied": info.varied,
        "shards": shards,
        "variants_per_shard": counts,
        "table": table,
        "probe": {
            "fraction_of_t_end": PROBE_FRACTION,
            "runs": probes,
            "per_variant_s": mean,
            "per_variant_is": "median of the runs",
            "max_per_variant_s": max,
        },
        "estimate": {
            "threads_per_task": threads,
            "cpu_s": mean.map(|x| x * n as f64 + twins_cpu),
            "per_task_wall_s": per_task,
            "mesh_check": {
                "mode": mesh_plan.as_ref().map_or("never", |p| p.mode.as_str()),
                "sampled": sampled,
                "twin_probe": twin,
                "twin_per_variant_s": twin_s,
                "cpu_s": twins_cpu,
            },
            "output_values": values_per_variant * n,
            "output_mb_uncompressed": (values_per_variant * n) as f64 * 8.0 / 1e6,
        },
        "backend": stage.backend,
        "precision": stage.precision,
    });
    if args.model.json {
        emit(&format!("{v}\n"))?;
    } else {
        println!(
            "campaign {} ({}): {n} variants, {shards} shard(s) of ≤ {per_shard}",
            info.id,
            c.model_path.display()
        );
        for x in &probes {
            println!(
                "probe variant {}: {} steps to t = {:.6} in {:.4} s ({}), about {:.4} s per variant",
                x.index, x.steps, x.t_probe, x.wall_s, x.status, x.per_variant_s
            );
        }
        if let Some(x) = &twin {
            println!(
                "probe of the mesh twin of variant {} ({} → {} elements): {} steps to t = \
                 {:.6} in {:.4} s ({}), about {:.4} s per twin",
                x.index,
                m0.elements.len(),
                m0.elements.len() * latdyn::solver::MESH_REFINE,
                x.steps,
                x.t_probe,
                x.wall_s,
                x.status,
                x.per_variant_s
            );
        }
        if let (Some(mean), Some(task)) = (mean, per_task) {
            let twins = match twin_s {
                Some(_) => format!(
                    " ({twins_cpu:.1} of them the mesh twins of variant(s) {})",
                    indices(sampled)
                ),
                None => String::new(),
            };
            println!(
                "estimate: {:.1} CPU-s in all{twins}; {task:.1} s for the longest task on \
                 {threads} thread(s), plus the merge",
                mean * n as f64 + twins_cpu,
            );
        }
    }
    Ok(())
}

/// On stderr, per kind of warning: how many variants, which (first 20), and the first
/// text in full. `warned`: (global variant index, its warnings), in campaign order.
fn report_warning_kinds(warned: impl Iterator<Item = (usize, Vec<String>)>) {
    let mut kinds: Vec<(String, Vec<usize>, String)> = Vec::new();
    for (gi, warnings) in warned {
        for w in &warnings {
            let kind = latdyn::frequency::warning_kind(w);
            match kinds.iter_mut().find(|(k, _, _)| *k == kind) {
                Some((_, idx, _)) => {
                    if idx.last() != Some(&gi) {
                        idx.push(gi)
                    }
                }
                None => kinds.push((kind, vec![gi], w.clone())),
            }
        }
    }
    for (kind, idx, first) in &kinds {
        let shown: Vec<String> = idx.iter().take(20).map(|i| i.to_string()).collect();
        eprintln!(
            "warning: {} variant(s): {kind}: indices {}{} (variant {}: {first})",
            idx.len(),
            shown.join(", "),
            if idx.len() > shown.len() { ", …" } else { "" },
            idx[0]
        );
    }
}

/// `sweep --path`: a path per variant, in parallel; JSON per variant, optional campaign
/// file with the point index as time and λ in `path_lambda`.
pub(crate) fn sweep_path(args: &SweepArgs) -> anyhow::Result<()> {
    use latdyn::solver::path;
    if args.accuracy.is_some()
        || args.frequency.is_some()
        || args.verify.is_some()
        || args.mesh_check.is_some()
    {
        bail!(
            "sweep --path: --accuracy, --frequency, --verify and --mesh-check apply to \
             dynamic runs only"
        );
    }
    // path campaign files carry no campaign identity (README "Not built yet"): they
    // cannot be resumed or planned, and a --resume was silently ignored (all paths
    // computed again, the file left as it was)
    if args.resume.is_some() || args.plan {
        bail!(
            "sweep --path: --resume and --plan apply to dynamic campaigns only (a path \
             campaign's file has no campaign identity to resume from or plan for); run the \
             paths again with -o"
        );
    }
    let (variants, origin) = latdyn::ensemble::variants_with_origin(
        &args.model.model,
        &args.model.set,
        &args.vary,
        args.variants.as_deref(),
    )?;
    let (k, n) = args.shard.unwrap_or((1, 1));
    let chosen: Vec<usize> = (0..variants.len()).filter(|i| i % n == k - 1).collect();
    {
        let m0 = args.model.load()?;
        path::check_output_size(&m0, args.path.max_points, chosen.len())
            .map_err(|e| anyhow!("{}: {e}", m0.path))?;
    }
    let mut models = Vec::with_capacity(chosen.len());
    let mut opts = Vec::with_capacity(chosen.len());
    // a signal ends every path before its next step (those not started yet after their
    // first); the points so far are written, the file marked interrupted (exit 4)
    let stop = crate::stop_flag();
    for &gi in &chosen {
        let mut sets = args.model.set.clone();
        sets.extend(variants[gi].iter().cloned());
        let m = model::load(&args.model.model, &sets)
            .map_err(|e| anyhow!("{}: {e}", origin.describe(gi, &variants[gi])))?;
        let mut o = args.path.options(&m)?;
        o.stop = Some(stop.clone());
        opts.push(o);
        models.push(m);
    }
    // the file holds every variant's sensors with the first's components: a variant
    // whose mesh changes a sensor's size (`beam_nodes` under a varied `elements`) is
    // refused before any path is computed, not found when writing
    if args.output.is_some() {
        if let Some(m0) = models.first() {
            for (m, &gi) in models.iter().zip(&chosen) {
                for (a, b) in m0.sensors.iter().zip(&m.sensors) {
                    let (na, nb) = (
                        latdyn::sensors::components(&a.kind).len(),
                        latdyn::sensors::components(&b.kind).len(),
                    );
                    if na != nb {
                        bail!(
                            "{}: sensor `{}` has {nb} components where variant {} has {na}: \
                             the variation changes the model's topology, which one campaign \
                             file cannot hold; vary it in separate sweeps",
                            origin.describe(gi, &variants[gi]),
                            b.name,
                            chosen[0]
                        );
                    }
                }
            }
        }
    }
    let target = claim_optional_output(args.output.as_deref(), &sweep_inputs(args))?;
    crate::note_campaign_format(args.output.as_deref());
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let threads = args.threads.unwrap_or(cores);
    let t0 = std::time::Instant::now();
    let results = path::follow_all(&models, &opts, threads);
    let wall = t0.elapsed().as_secs_f64();
    let failed = results.iter().filter(|(r, _)| r.error.is_some()).count();
    let interrupted = results.iter().filter(|(r, _)| r.interrupted()).count();
    let mut out_err = None;
    if let (Some(t), false) = (target, models.is_empty()) {
        let npts = results
            .iter()
            .map(|(r, _)| r.lambda.len())
            .max()
            .unwrap_or(0);
        let refs: Vec<&Model> = models.iter().collect();
        let mut meta = path::campaign_meta(
            &refs,
            (0..npts).map(|i| i as f64).collect(),
            latdyn::output::command_line(),
            threads,
        );
        meta.global_index = chosen.clone();
        let written = latdyn::output::CampaignWriter::create_at(t, &meta).and_then(|mut w| {
            for (v, (r, ws)) in results.iter().enumerate() {
                path::write_variant(&mut w, v, r, *ws)?;
            }
            w.finish(if interrupted > 0 {
                "interrupted"
            } else {
                "complete"
            })
        });
        out_err = written.err();
    }
    if args.model.json {
        let vs: Vec<serde_json::Value> = results
            .iter()
            .zip(&models)
            .zip(&chosen)
            .map(|(((r, ws), m), gi)| {
                let mut v = path::to_json(m, r, *ws);
                v["index"] = serde_json::json!(gi);
                v["parameters"] = serde_json::json!(variants[*gi]
                    .iter()
                    .map(|(k, x)| (k.clone(), *x))
                    .collect::<std::collections::BTreeMap<_, _>>());
                v
            })
            .collect();
        let v = serde_json::json!({
            "variants": vs,
            "failed": failed,
            "interrupted": interrupted,
            "output_error": out_err.as_ref().map(|e| e.to_string()),
            "threads": threads,
            "wall_s": wall,
        });
        emit(&format!("{v}\n"))?;
    } else {
        eprintln!(
            "sweep --path {}: {} variants ({} failed, {} interrupted) on {} threads in {:.3} s",
            args.model.model.display(),
            results.len(),
            failed,
            interrupted,
            threads,
            wall
        );
    }
    report_warning_kinds(
        results
            .iter()
            .zip(&chosen)
            .map(|((r, _), &gi)| (gi, r.warnings())),
    );
    if let Some(e) = out_err {
        return Err(fail(EXIT_OUTPUT, e.to_string()));
    }
    if interrupted > 0 {
        return Err(fail(
            EXIT_INTERRUPTED,
            format!(
                "sweep --path: interrupted (SIGINT, SIGTERM or SIGHUP): {interrupted} of {} \
                 paths stopped before their end, {failed} failed; the points so far are kept",
                results.len()
            ),
        ));
    }
    if failed > 0 {
        return Err(fail(
            EXIT_FAILED,
            format!(
                "sweep --path: {failed} of {} variants failed",
                results.len()
            ),
        ));
    }
    Ok(())
}
