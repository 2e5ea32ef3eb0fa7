//! The `run` verb: one transient run, its samples streamed to HDF5 or CSV.

use anyhow::anyhow;
use latdyn::model::Model;

use crate::backend::choose_stage;
use crate::cli::RunArgs;
use crate::{
    claim_optional_output, emit, fail, is_csv, stop_flag, EXIT_FAILED, EXIT_INTERRUPTED,
    EXIT_OUTPUT,
};

/// Where `run -o` puts its samples as they come: the campaign layout with one variant,
/// or CSV. Both are rewritten atomically at most every [`RUN_FLUSH_S`] and at the end.
pub(crate) enum RunSink {
    H5(Box<latdyn::output::CampaignWriter>),
    Csv {
        target: latdyn::output::OutputTarget,
        text: String,
    },
}

/// Shortest time between two rewrites of the `run -o` file [s] (as a sweep).
pub(crate) const RUN_FLUSH_S: f64 = 2.0;

impl RunSink {
    pub(crate) fn open(
        m: &Model,
        target: latdyn::output::OutputTarget,
        stage: &latdyn::ensemble::Stage,
    ) -> Result<RunSink, latdyn::output::OutputError> {
        if is_csv(target.path()) {
            let text = csv_header(m);
            // written at once: the path is shown writable before the run
            target.replace_with((text.clone() + CSV_RUNNING).as_bytes())?;
            Ok(RunSink::Csv { target, text })
        } else {
            crate::note_hdf5_name(target.path());
            let mut w = latdyn::output::CampaignWriter::create_at(
                target,
                &latdyn::output::CampaignMeta::single_run(m, stage, latdyn::output::command_line()),
            )?;
            let running = latdyn::output::VariantStatus {
                state: latdyn::output::VariantState::Running,
                ..Default::default()
            };
            w.set_status(0, &running)?;
            Ok(RunSink::H5(Box::new(w)))
        }
    }

    pub(crate) fn sample(
        &mut self,
        i: usize,
        t: f64,
        vals: &[Vec<f64>],
    ) -> Result<(), latdyn::output::OutputError> {
        match self {
            RunSink::H5(w) => w.write_samples(0, i, vals),
            RunSink::Csv { text, .. } => {
                csv_row(text, t, vals);
                Ok(())
            }
        }
    }

    pub(crate) fn flush(&mut self) -> Result<(), latdyn::output::OutputError> {
        match self {
            RunSink::H5(w) => w.flush(),
            // the last line says the rows stop short, should the process be killed
            RunSink::Csv { target, text } => {
                target.replace_with((text.clone() + CSV_RUNNING).as_bytes())
            }
        }
    }

    pub(crate) fn finish(
        self,
        status: &latdyn::output::VariantStatus,
    ) -> Result<(), latdyn::output::OutputError> {
        use latdyn::output::VariantState;
        match self {
            RunSink::H5(mut w) => {
                w.set_status(0, status)?;
                w.finish(if status.state == VariantState::Interrupted {
                    "interrupted"
                } else {
                    "complete"
                })
            }
            RunSink::Csv { target, mut text } => {
                if status.state != VariantState::Completed {
                    text += &csv_trailer(status);
                }
                target.replace_with(text.as_bytes())
            }
        }
    }
}

/// The last line of a `run -o FILE.csv` written mid-run: a CSV has no status field, so a
/// file whose rows stop short says so where a reader meets it (numpy's `loadtxt` and
/// `genfromtxt` skip `#` lines, pandas with `comment="#"`; a reader that does not fails
/// on it rather than taking the rows for a finished run). A completed run has none.
const CSV_RUNNING: &str =
    "# running: the run had not finished when this file was written; the rows stop short\n";

/// The last line of the CSV of a run that ended short of `t_end` (see [`CSV_RUNNING`]).
fn csv_trailer(status: &latdyn::output::VariantStatus) -> String {
    let message = status.message.replace(['\n', '\r'], " ");
    let what = match (message.is_empty(), status.t_fail.is_finite()) {
        (false, _) => message,
        (true, true) => format!("{} at t = {} s", status.state.label(), status.t_fail),
        (true, false) => status.state.label().to_string(),
    };
    format!("# {what}; the rows stop there\n")
}

/// The stderr note for a fixed step that does not divide the output interval (the run
/// spreads it evenly, `dynamics::spread_step`); `None` with an accuracy target, whose runs
/// choose their own dividing steps.
pub(crate) fn spread_note(m: &latdyn::model::Model) -> Option<String> {
    if m.solver.accuracy.is_some() {
        return None;
    }
    let (dt, out, t_end) = (m.solver.dt, m.solver.output_dt, m.solver.t_end);
    // an output interval longer than the run ends at t_end: the steps spread over that
    let (span, what) = if out > t_end && t_end > 0.0 {
        (
            t_end,
            format!("the run's span t_end = {t_end:e} s (the output interval is {out:e} s)"),
        )
    } else {
        (out, format!("the output interval {out:e} s"))
    };
    let (n, h) = latdyn::solver::dynamics::spread_over(dt, span)?;
    Some(if dt > span {
        format!(
            "note: {}: dt = {dt:e} s exceeds {what}; each step is the interval",
            m.path
        )
    } else {
        format!(
            "note: {}: dt = {dt:e} s does not divide {what}; each interval is {n} equal \
             steps of {h:.6e} s",
            m.path
        )
    })
}

/// `--accuracy` against the model's Newton tolerance (see `accuracy_floor`).
/// Bytes of memory one output value takes in `run --json`: its f64 in the history and
/// its node in the JSON tree (measured by a probe in session 48: 322 MB against 54 MB
/// without `--json` at 3e6 values, 89 bytes more each).
const JSON_BYTES_PER_VALUE: f64 = 100.0;

/// `run --json` holds every sample of every sensor in its JSON object: at the
/// `output_values` limit (1e8) that is about 10 GB, and a machine with less memory
/// aborted in the allocator (a probe in session 48, under a 3 GB address limit). Refused
/// before the run where the object would not fit in the machine's memory.
///
/// With `twin` (the mesh check will run), the twin's history is counted too
/// (`latdyn::verify::HISTORY_BYTES_PER_VALUE` each): it is held beside the run's.
fn check_json_size(m: &latdyn::model::Model, twin: bool) -> anyhow::Result<()> {
    let Some(mem) = latdyn::model::limits::memory_bytes() else {
        return Ok(());
    };
    let components: usize = m
        .sensors
        .iter()
        .map(|x| latdyn::sensors::components(&x.kind).len() + 1)
        .sum();
    let s = &m.solver;
    let dt_out = if s.output_dt > 0.0 { s.output_dt } else { s.dt };
    let samples = latdyn::model::output_intervals(s.t_end, dt_out) + 1;
    let values = samples as f64 * components as f64;
    let per_value = JSON_BYTES_PER_VALUE
        + if twin {
            latdyn::verify::HISTORY_BYTES_PER_VALUE
        } else {
            0.0
        };
    let bytes = values * per_value;
    if bytes <= mem as f64 {
        return Ok(());
    }
    Err(anyhow!(
        "{}: `--json` would hold {} sensor values in memory, about {:.1} GB at {} bytes \
         each{}, more than this machine's {:.1} GiB: write the histories to a file (`-o \
         FILE.h5`, without `--json`) or sample less often (`[solver] output_dt`)",
        m.path,
        latdyn::model::limits::count(values),
        bytes / 1e9,
        per_value,
        if twin {
            " with the mesh check's history (`--mesh-check never` drops it)"
        } else {
            ""
        },
        mem as f64 / f64::from(1u32 << 30)
    ))
}

pub(crate) fn check_accuracy(target: f64, m: &latdyn::model::Model) -> anyhow::Result<()> {
    use latdyn::model::compile::{accuracy_below_floor, accuracy_floor};
    if target < accuracy_floor(m.solver.tol) {
        anyhow::bail!(
            "--accuracy {target:e}: {}",
            accuracy_below_floor(target, m.solver.tol)
        );
    }
    Ok(())
}

pub(crate) fn run(args: &RunArgs) -> anyhow::Result<()> {
    use latdyn::output::{VariantState, VariantStatus};
    use std::sync::atomic::Ordering;
    // installed before the model is compiled (a large one takes seconds): a signal then
    // ends the run before its first step, exit 4 with its file and JSON marked
    // interrupted, where it killed the process with nothing said (a probe, session 46)
    let stop = stop_flag();
    let mut m = args.model.load()?;
    if let Some(a) = args.accuracy {
        check_accuracy(a, &m)?;
        m.solver.accuracy = Some(a);
    }
    if args.model.json {
        check_json_size(&m, args.mesh_check != "never" && !m.elem_data.is_empty())?;
    }
    if let Some(note) = spread_note(&m) {
        eprintln!("{note}");
    }
    let model_file = [(args.model.model.as_path(), "the model file")];
    let target = claim_optional_output(args.output.as_deref(), &model_file)?;
    let (stage, _gpu) = choose_stage(&args.backend, 1, m.elements.len(), 1)?;
    let mut sink = match target {
        Some(t) => Some(RunSink::open(&m, t, &stage).map_err(|e| anyhow!("{e}"))?),
        None => None,
    };
    let mut out_err: Option<latdyn::output::OutputError> = None;
    let mut n_samples = 0usize;
    let mut last_flush = std::time::Instant::now();
    let t0 = std::time::Instant::now();
    // the mesh twin of a fixed-step run runs alongside it (on the second core); under an
    // accuracy target it needs the step the target chose, so it follows the run
    let mut early = MeshCheck::default();
    let twin = match m.solver.accuracy {
        None => prepare_twin(args, &m, m.solver.dt, &mut early),
        Some(_) => None,
    };
    let (hist, stats, err, twin_run, wall) = std::thread::scope(|scope| {
        let handle = twin.as_ref().map(|t| {
            announce_twin(t, &m, "alongside the run");
            let (stop, stage) = (stop.as_ref(), &stage);
            scope.spawn(move || latdyn::verify::run_twin(t, &stage.run_context(stop)))
        });
        let on_sample = |t: f64, vals: &[Vec<f64>]| {
            let i = n_samples;
            n_samples += 1;
            let (Some(s), None) = (sink.as_mut(), out_err.as_ref()) else {
                return;
            };
            let mut r = s.sample(i, t, vals);
            if r.is_ok() && last_flush.elapsed().as_secs_f64() >= RUN_FLUSH_S {
                r = s.flush();
                last_flush = std::time::Instant::now();
            }
            if let Err(e) = r {
                // the file keeps its last flush; stop rather than compute what cannot be kept
                out_err = Some(e);
                stop.store(true, Ordering::SeqCst);
            }
        };
        let ctx = stage.run_context(&stop);
        let (hist, stats, err) = latdyn::solver::dynamics::run_in(&m, &ctx, on_sample);
        // the run's own time, not its wait for the twin
        let wall = t0.elapsed().as_secs_f64();
        if err.is_some() {
            // nothing left to compare: end the twin (the run is over, the flag is free)
            stop.store(true, Ordering::SeqCst);
        } else if out_err.is_none() {
            // the samples are kept while the twin still runs
            if let Some(s) = sink.as_mut() {
                if let Err(e) = s.flush() {
                    out_err = Some(e);
                }
            }
        }
        let twin_run = handle.map(|h| {
            h.join().unwrap_or_else(|_| {
                Err(latdyn::verify::MeshTwinSkip::Failed(
                    "the run on twice the elements panicked (a bug in latdyn)".into(),
                ))
            })
        });
        (hist, stats, err, twin_run, wall)
    });
    let interrupted = matches!(
        err,
        Some(latdyn::solver::dynamics::DynamicsError::Interrupted { .. })
    );
    let mut warnings: Vec<String> = stats.warnings();
    let mut check = early;
    if err.is_none() && out_err.is_none() {
        match (twin, twin_run) {
            (Some(t), Some(r)) => check.measured(&m, &hist, &t, r),
            _ if m.solver.accuracy.is_some() => {
                let dt = stats.accuracy_dt.unwrap_or(m.solver.dt);
                if let Some(t) = prepare_twin(args, &m, dt, &mut check) {
                    announce_twin(&t, &m, "after the run");
                    let r = latdyn::verify::run_twin(&t, &stage.run_context(&stop));
                    check.measured(&m, &hist, &t, r);
                }
            }
            _ => {}
        }
        warnings.extend(check.warning.clone());
    }
    let (mesh, mesh_interrupted) = (check.error, check.interrupted);
    if let Some(s) = sink {
        let status = VariantStatus::of_run(
            match &err {
                None => VariantState::Completed,
                Some(_) if interrupted => VariantState::Interrupted,
                Some(_) => VariantState::Failed,
            },
            err.as_ref().map(|e| e.to_string()).unwrap_or_default(),
            err.as_ref().map(|e| e.time()).unwrap_or(f64::NAN),
            &stats,
            wall,
            warnings.join("\n"),
        );
        let status = latdyn::output::VariantStatus {
            mesh_error_estimate: mesh.as_ref().map_or(f64::NAN, |e| e.estimate),
            ..status
        };
        // after an output error the last good flush is what stays
        if out_err.is_none() {
            if let Err(e) = s.finish(&status) {
                out_err = Some(e);
            }
        }
    }
    for w in &warnings {
        eprintln!("warning: {}: {w}", m.path);
    }
    let (status, message) = match (&out_err, &err) {
        (Some(e), _) => ("output_failed", e.to_string()),
        (None, Some(e)) if interrupted => ("interrupted", e.to_string()),
        (None, Some(e)) => ("failed", e.to_string()),
        (None, None) if mesh_interrupted => ("interrupted", MESH_INTERRUPTED.to_string()),
        (None, None) => ("completed", String::new()),
    };
    if args.model.json {
        let mut sensors = serde_json::Map::new();
        let summaries = latdyn::ensemble::summarize(&m, &hist);
        for ((k, sn), sum) in m.sensors.iter().enumerate().zip(&summaries) {
            let vals = &hist.values[k];
            // before its first sample a run has no extremes ([]) and no final value (null)
            let none: &[f64] = &[];
            let (min, max) = match vals.is_empty() {
                true => (none, none),
                false => (&sum.min[..], &sum.max[..]),
            };
            sensors.insert(
                sn.name.clone(),
                serde_json::json!({
                    "t": hist.t,
                    "values": vals,
                    "min": min,
                    "max": max,
                    "final": vals.last(),
                    "components": latdyn::sensors::components(&sn.kind),
                }),
            );
        }
        let v = serde_json::json!({
            "sensors": sensors,
            "steps": stats.steps,
            "rejected_steps": stats.rejected_steps,
            "newton_iterations": stats.newton_iterations,
            "free_dofs": m.n_eq,
            "matrix_nnz": stats.matrix_nnz,
            "factor_nnz": stats.factor_nnz,
            "stage_times_s": {
                "element": stats.times.element_s,
                "assembly": stats.times.assembly_s,
                "factorization": stats.times.factorization_s,
                "output": stats.times.output_s,
            },
            "energy_growth": stats.energy_growth,
            "energy_loss": stats.energy_loss,
            "accuracy": m.solver.accuracy.map(|tol| serde_json::json!({
                "target": tol,
                "runs": stats.accuracy_runs,
                "dt": stats.accuracy_dt,
                "steps_all_runs": stats.accuracy_steps,
                "newton_iterations_all_runs": stats.accuracy_newton_iterations,
                "history": stats.accuracy_history.iter().map(|r| serde_json::json!({
                    "dt": r.dt, "estimate": r.estimate, "steps": r.steps, "from": r.from,
                    "stopped_at": r.stopped_at.map(|(t, _)| t),
                    "error_when_stopped": r.stopped_at.map(|(_, e)| e),
                })).collect::<Vec<_>>(),
            })),
            "time_error_estimate": stats.time_error_estimate,
            "time_error_before_first_lock": stats.time_error_before_first_lock,
            "load_impulse_error": stats.load_impulse_error,
            "load_sampling_error": stats.load_sampling_error,
            "drive_rate_error": stats.drive_rate_error,
            "consistent_start": stats.consistent_start.map(|c| serde_json::json!({
                "applied": c.applied,
                "largest_change": c.largest_change,
                "kinetic_share": c.kinetic_share,
                "solved": c.solved,
                "passes": c.passes,
                "strain_rate_left": c.strain_rate_left,
            })),
            "time_error_by_sensor": m.sensors.iter().map(|s| s.name.as_str()).zip(&stats.time_error_by_sensor).collect::<std::collections::BTreeMap<_, _>>(),
            "mesh_error_estimate": mesh.as_ref().map(|e| e.estimate),
            "mesh_error_by_sensor": mesh.as_ref().map(|e| m.sensors.iter().map(|s| s.name.as_str()).zip(&e.by_sensor).collect::<std::collections::BTreeMap<_, _>>()),
            "mesh_elements": mesh.as_ref().map(|e| [e.elements.0, e.elements.1]),
            "mesh_check_wall_s": mesh.as_ref().map(|e| e.wall_s),
            "warnings": warnings,
            "wall_s": wall,
            "status": status,
            "message": message,
            "backend": stage.backend,
            "precision": stage.precision,
            "adapter": stage.adapter,
        });
        emit(&format!("{v}\n"))?;
    } else {
        eprintln!(
            "run {}: {} steps ({} rejected, {} Newton iterations) in {:.3} s",
            m.name, stats.steps, stats.rejected_steps, stats.newton_iterations, wall
        );
        if let Some(e) = &mesh {
            eprintln!(
                "mesh check: {} → {} elements at dt {:e} s, {} steps in {:.3} s; mesh error \
                 estimate {:.3e} ({})",
                e.elements.0, e.elements.1, e.dt, e.steps, e.wall_s, e.estimate, e.worst
            );
        }
        if let Some(tol) = m.solver.accuracy {
            eprintln!(
                "accuracy {tol:e}: {} run(s), {} steps in all; the result's step {:e} s",
                stats.accuracy_runs,
                stats.accuracy_steps,
                stats.accuracy_dt.unwrap_or(f64::NAN)
            );
            for r in &stats.accuracy_history {
                let stopped = r.stopped_at.map_or(String::new(), |(t, e)| {
                    format!(", stopped at t = {t} s with {e:.3e} so far")
                });
                eprintln!(
                    "  dt {:e} s from t = {} s: {} steps, estimate {:.3e}{stopped}",
                    r.dt, r.from, r.steps, r.estimate
                );
            }
        }
    }
    let written = args
        .output
        .as_ref()
        .map(|p| format!("; {} holds the samples so far", p.display()))
        .unwrap_or_default();
    if let Some(e) = out_err {
        let kept = args
            .output
            .as_ref()
            .map(|p| format!(" (the run stopped; {} keeps its last flush)", p.display()))
            .unwrap_or_default();
        return Err(fail(EXIT_OUTPUT, format!("{e}{kept}")));
    }
    match err {
        None if mesh_interrupted => Err(fail(
            EXIT_INTERRUPTED,
            format!("{}: {MESH_INTERRUPTED}{written}", m.path),
        )),
        Some(e) if interrupted => Err(fail(EXIT_INTERRUPTED, format!("{}: {e}{written}", m.path))),
        Some(e) => Err(fail(EXIT_FAILED, format!("{}: {e}", m.path))),
        None => Ok(()),
    }
}

/// The message of a run whose mesh check a signal stopped.
const MESH_INTERRUPTED: &str = "interrupted (SIGINT, SIGTERM or SIGHUP) during the mesh \
    check, after the run completed: the results are the run's, its mesh error is not measured";

/// What `run`'s mesh check gave: the measurement, the warning it raises (mesh too
/// coarse, or not measured and why), and whether a signal stopped it.
#[derive(Default)]
struct MeshCheck {
    error: Option<latdyn::verify::RunMeshError>,
    warning: Option<String>,
    interrupted: bool,
}

impl MeshCheck {
    /// Takes the twin's run `r` of a completed run of `m` (samples `hist`): the
    /// measurement, warned above `MESH_ERROR_WARN` naming the worst sensor component, or
    /// why it was not measured.
    fn measured(
        &mut self,
        m: &Model,
        hist: &latdyn::solver::dynamics::History,
        twin: &Model,
        r: Result<latdyn::verify::TwinRun, latdyn::verify::MeshTwinSkip>,
    ) {
        use latdyn::verify::MeshTwinSkip;
        match r.and_then(|r| latdyn::verify::compare_twin(m, hist, twin, &r)) {
            Ok(e) => {
                self.warning = e.warning();
                self.error = Some(e);
            }
            Err(MeshTwinSkip::Interrupted) => {
                self.interrupted = true;
                self.warning = not_measured("a signal stopped the check");
            }
            Err(MeshTwinSkip::Failed(why)) => self.warning = not_measured(&why),
        }
    }
}

fn not_measured(why: &str) -> Option<String> {
    Some(latdyn::verify::mesh_not_measured(why))
}

/// The mesh twin of a run of `m` at step `dt` (`latdyn::verify::mesh_twin_model`: every
/// beam with twice its elements), or None where there is none to run: a model without
/// beams has no mesh, `--mesh-check never` skips it, and where it cannot be built or
/// `auto` declines its size `check` gets the warning saying so.
fn prepare_twin(args: &RunArgs, m: &Model, dt: f64, check: &mut MeshCheck) -> Option<Model> {
    if m.elem_data.is_empty() || args.mesh_check == "never" {
        return None;
    }
    let twin = match latdyn::verify::mesh_twin_model(&args.model.model, &args.model.set, m, dt) {
        Ok(t) => t,
        Err(e) => {
            check.warning = not_measured(&e);
            return None;
        }
    };
    if args.mesh_check == "auto" && twin.n_eq > latdyn::verify::MESH_CHECK_AUTO_DOFS {
        check.warning = not_measured(&latdyn::verify::too_large_for_auto(
            &twin,
            latdyn::verify::MESH_CHECK_AUTO_DOFS,
        ));
        return None;
    }
    Some(twin)
}

fn announce_twin(twin: &Model, m: &Model, when: &str) {
    eprintln!(
        "mesh check: the run again on {} elements (its {} doubled) at dt {:e} s, {when}; \
         `--mesh-check never` skips it",
        twin.elements.len(),
        m.elements.len(),
        twin.solver.dt
    );
}

/// CSV of the sensor histories: the header (time, then every sensor component).
pub(crate) fn csv_header(m: &Model) -> String {
    let mut s = String::from("t");
    for sn in &m.sensors {
        for c in latdyn::sensors::components(&sn.kind) {
            s += &format!(",{}.{c}", sn.name);
        }
    }
    s.push('\n');
    s
}

/// One CSV row: the time, then every sensor component.
pub(crate) fn csv_row(s: &mut String, t: f64, vals: &[Vec<f64>]) {
    use std::fmt::Write as _;
    let _ = write!(s, "{t}");
    for v in vals {
        for x in v {
            let _ = write!(s, ",{x}");
        }
    }
    s.push('\n');
}
