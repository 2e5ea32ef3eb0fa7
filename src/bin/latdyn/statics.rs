//! The `statics` verb, with and without `--path`.

use anyhow::{anyhow, bail};
use latdyn::model::Model;

use crate::cli::StaticsArgs;
use crate::{claim_optional_output, emit, fail, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OUTPUT};

pub(crate) fn sensor_map(
    m: &Model,
    vals: &[Vec<f64>],
) -> serde_json::Map<String, serde_json::Value> {
    m.sensors
        .iter()
        .zip(vals)
        .map(|(sn, v)| (sn.name.clone(), serde_json::json!(v)))
        .collect()
}

pub(crate) fn statics(sargs: &StaticsArgs) -> anyhow::Result<()> {
    // a signal from here on ends the solve before its next (load or path) step, exit 4:
    // installed before the model is compiled, which takes long for a large one
    let stop = crate::stop_flag();
    if sargs.path.path {
        return statics_path(sargs, stop);
    }
    if sargs.path.any_option() || sargs.output.is_some() {
        bail!("statics: --control, --lambda-max, --until, --limit-points, --max-length, --max-points, --first-step and -o need --path");
    }
    let args = &sargs.model;
    let m = args.load()?;
    let t0 = std::time::Instant::now();
    // a signal during the mesh check keeps the equilibrium found, reported with the
    // check not measured
    let interrupted = || stop.load(std::sync::atomic::Ordering::SeqCst);
    let mut sol = match latdyn::solver::solve_statics_until(&m, Some(&stop)) {
        Ok(sol) => sol,
        Err(e @ latdyn::solver::statics::StaticsError::Interrupted { .. }) => {
            return Err(fail(EXIT_INTERRUPTED, format!("{}: {e}", m.path)))
        }
        Err(e) => return Err(anyhow::Error::new(e).context(m.path.clone())),
    };
    // measure what the mesh costs the reported numbers
    let mesh = latdyn::solver::check_statics_mesh(
        &m,
        &mut sol,
        || {
            latdyn::model::load_refined(&args.model, &args.set, latdyn::solver::MESH_REFINE)
                .map_err(|e| e.to_string())
        },
        Some(&stop),
    );
    let wall = t0.elapsed().as_secs_f64();
    let warnings = &sol.report.warnings;
    for w in warnings {
        eprintln!("warning: {}: {w}", m.path);
    }
    if args.json {
        let v = serde_json::json!({
            "sensors": sensor_map(&m, &sol.sensors),
            "strain_energy": sol.strain_energy,
            "load_steps": sol.report.load_steps,
            "newton_iterations": sol.report.newton_iterations,
            "rejected_steps": sol.report.rejected_steps,
            "mesh_error_estimate": mesh.as_ref().map(|c| c.estimate),
            "mesh_error_by_sensor": mesh.as_ref().map(|c| {
                m.sensors
                    .iter()
                    .zip(&c.by_sensor)
                    .map(|(sn, e)| (sn.name.clone(), serde_json::json!(e)))
                    .collect::<serde_json::Map<_, _>>()
            }),
            "mesh_error_strain_energy": mesh.as_ref().map(|c| c.strain_energy),
            "warnings": warnings,
            "wall_s": wall,
        });
        emit(&format!("{v}\n"))?;
    } else {
        let mut s = format!(
            "statics {}: {} load steps, {} Newton iterations, {:.3} s\n",
            m.name, sol.report.load_steps, sol.report.newton_iterations, wall
        );
        for (sn, v) in m.sensors.iter().zip(&sol.sensors) {
            let comps = latdyn::sensors::components(&sn.kind);
            let parts: Vec<String> = comps
                .iter()
                .zip(v)
                .map(|(c, x)| format!("{c}={x:.6e}"))
                .collect();
            s += &format!("  {:<16} {}\n", sn.name, parts.join(" "));
        }
        if let Some(c) = &mesh {
            s += &format!(
                "  mesh error estimate {:.3e} ({}; from {} and {} elements in all)\n",
                c.estimate, c.worst, c.elements.0, c.elements.1
            );
        }
        emit(&s)?;
    }
    if interrupted() {
        return Err(fail(
            EXIT_INTERRUPTED,
            format!(
                "{}: interrupted (SIGINT, SIGTERM or SIGHUP) during the mesh check; the \
                 equilibrium above is complete, its mesh error not measured",
                m.path
            ),
        ));
    }
    Ok(())
}

/// `statics --path`: one equilibrium path, JSON / text summary, optional campaign file.
pub(crate) fn statics_path(
    args: &StaticsArgs,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
) -> anyhow::Result<()> {
    use latdyn::solver::path;
    let m = args.model.load()?;
    let mut opts = args.path.options(&m)?;
    // a signal ends the path before its next step; its points so far are printed and
    // written, the file marked interrupted (exit 4), as an interrupted run's are
    opts.stop = Some(stop);
    path::check_output_size(&m, opts.max_points, 1).map_err(|e| anyhow!("{}: {e}", m.path))?;
    let model_file = [(args.model.model.as_path(), "the model file")];
    let target = claim_optional_output(args.output.as_deref(), &model_file)?;
    crate::note_campaign_format(args.output.as_deref());
    let t0 = std::time::Instant::now();
    let r = path::follow(&m, &opts);
    let wall = t0.elapsed().as_secs_f64();
    let warnings = r.warnings();
    for w in &warnings {
        eprintln!("warning: {}: {w}", m.path);
    }
    let mut out_err = None;
    if let Some(t) = target {
        let meta = path::campaign_meta(&[&m], r.lambda.clone(), latdyn::output::command_line(), 1);
        let written = latdyn::output::CampaignWriter::create_at(t, &meta).and_then(|mut w| {
            path::write_variant(&mut w, 0, &r, wall)?;
            w.finish(if r.interrupted() {
                "interrupted"
            } else {
                "complete"
            })
        });
        out_err = written.err();
    }
    if args.model.json {
        // the path's status is the computation's; a file that could not be written is
        // said beside it (exit 5), not hidden behind "completed"
        let mut v = path::to_json(&m, &r, wall);
        v["output_error"] = serde_json::json!(out_err.as_ref().map(|e| e.to_string()));
        emit(&format!("{v}\n"))?;
    } else {
        let mut s = format!(
            "path {} ({} control): {} points, {} Newton iterations, {} rejected steps, {:.3} s; \
             λ from {:.6e} to {:.6e}, stopped by {}\n",
            m.name,
            r.control.label(),
            r.lambda.len(),
            r.newton_iterations,
            r.rejected_steps,
            wall,
            r.lambda.first().copied().unwrap_or(0.0),
            r.lambda.last().copied().unwrap_or(0.0),
            r.stopped_by
        );
        for lp in &r.limit_points {
            s += &format!(
                "  limit point ({}) at λ = {:.6e} (point {}; parabola through its neighbours: \
                 {:.6e})\n",
                lp.kind, lp.lambda, lp.index, lp.lambda_fit
            );
        }
        for b in &r.bifurcations {
            s += &format!("  det K changes sign at λ = {:.6e} (point {}) with λ still moving the same way: bifurcation\n", b.lambda, b.index);
        }
        emit(&s)?;
    }
    if let Some(e) = out_err {
        return Err(fail(EXIT_OUTPUT, e.to_string()));
    }
    match &r.error {
        Some(path::PathError::Input(msg)) => bail!("{}: {msg}", m.path),
        Some(e) => Err(fail(EXIT_FAILED, format!("{}: {e}", m.path))),
        None if r.interrupted() => Err(fail(
            EXIT_INTERRUPTED,
            format!("{}: path {}", m.path, r.message()),
        )),
        None => Ok(()),
    }
}
