//! The `plot` and `bench` verbs: charts of a results file, and the speed-against-error
//! suite with its report files.

use std::path::PathBuf;

use anyhow::anyhow;

use crate::cli::{BenchArgs, PlotArgs};
use crate::{claim_output, emit, fail, EXIT_OUTPUT};

/// The speed-against-error suite (bench.rs); the report files are written even when
/// `--json` prints the report.
pub(crate) fn bench(args: &BenchArgs) -> anyhow::Result<()> {
    use crate::bench;
    let threads = args.threads.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    if threads == 0 {
        return Err(anyhow!("--threads: must be at least 1"));
    }
    if !args.models.is_dir() {
        return Err(anyhow!(
            "{}: --models: not a directory (run from the repository root or pass --models)",
            args.models.display()
        ));
    }
    let opts = bench::BenchOptions {
        models: args.models.clone(),
        quick: args.quick,
        only: args.only.clone(),
        threads,
        // (a target named twice is run once)
        targets: if args.targets.is_empty() {
            bench::ACCURACY_TARGETS.to_vec()
        } else {
            let mut t: Vec<f64> = Vec::new();
            for &a in &args.targets {
                if !t.contains(&a) {
                    t.push(a);
                }
            }
            t
        },
        scenes: args.scenes.clone(),
    };
    match std::fs::symlink_metadata(&args.out) {
        Ok(m) if !m.is_dir() => anyhow::bail!(
            "{}: --out: not a directory ({}); give a directory for the results",
            args.out.display(),
            if m.file_type().is_symlink() {
                "a symbolic link"
            } else {
                "it exists and is something else"
            }
        ),
        _ => std::fs::create_dir_all(&args.out).map_err(|e| {
            anyhow!(
                "{}: --out: cannot create the directory: {e}",
                args.out.display()
            )
        })?,
    }
    // the three files follow the output policy of run, sweep and plot (no symlinks or
    // special files, locked, shown writable before the suite runs, replaced atomically):
    // a results.md symlinked to a model file was written through, a FIFO hung the
    // bench, a read-only directory failed after the whole suite (a probe, session 46)
    let claim = |name: &str| claim_output(&args.out.join(name), &[]);
    let (md_target, json_target, png_target) = (
        claim("results.md")?,
        claim("results.json")?,
        claim("work_precision.png")?,
    );
    let report = bench::run_suite(&opts, &|line| eprintln!("{line}"))?;
    let command = std::env::args_os()
        .skip(1)
        .fold("latdyn".to_string(), |a, b| a + " " + &b.to_string_lossy());
    let has_runs = report.problems.iter().any(|p| !p.runs.is_empty());
    if has_runs {
        let staging = Staging(staging_path(png_target.path()));
        bench::plot(&report, &staging.0)?;
        let bytes = std::fs::read(&staging.0)
            .map_err(|e| anyhow!("{}: cannot read the drawn chart: {e}", staging.0.display()))?;
        png_target
            .replace_with(&bytes)
            .map_err(|e| fail(EXIT_OUTPUT, e.to_string()))?;
    }
    let md = bench::markdown(&report, &command, has_runs.then_some("work_precision.png"));
    let write = |target: &latdyn::output::OutputTarget, text: &str| {
        target
            .replace_with(text.as_bytes())
            .map_err(|e| fail(EXIT_OUTPUT, e.to_string()))
    };
    write(&md_target, &md)?;
    let json = serde_json::to_string_pretty(&report)?;
    write(&json_target, &json)?;
    eprintln!(
        "wrote {} (and results.json{})",
        args.out.join("results.md").display(),
        if has_runs { ", work_precision.png" } else { "" }
    );
    if args.json {
        emit(&format!("{json}\n"))?;
    }
    Ok(())
}

/// Chart a results file: time histories, a cross plot or a Campbell diagram.
pub(crate) fn plot(args: &PlotArgs) -> anyhow::Result<()> {
    use crate::plot as lp;
    let opts = lp::PlotOptions {
        title: args.title.clone(),
        size: args.size,
        variants: (!args.variants.is_empty()).then(|| args.variants.clone()),
    };
    lp::ImageFormat::from_path(&args.output)?;
    let c = lp::Campaign::open(&args.input)?;
    // the chart follows the output policy of run and sweep (no symlinks or special files,
    // locked, atomic replace): it is drawn to a sibling and moved into place at the end
    let target = claim_output(&args.output, &[(args.input.as_path(), "the campaign file")])?;
    let staging = Staging(staging_path(&args.output));
    let summary =
        plot_to(args, &opts, &c, &staging.0).map_err(|e| match e.downcast::<lp::PlotError>() {
            Ok(lp::PlotError::Data(m)) => anyhow!("{}: {m}", args.input.display()),
            Ok(other) => other.into(),
            Err(e) => e,
        })?;
    let bytes = std::fs::read(&staging.0)
        .map_err(|e| anyhow!("{}: cannot read the drawn chart: {e}", staging.0.display()))?;
    target
        .replace_with(&bytes)
        .map_err(|e| fail(EXIT_OUTPUT, e.to_string()))?;
    for n in &summary.notes {
        eprintln!("note: {n}");
    }
    if args.json && args.campbell.is_none() {
        let v = serde_json::json!({
            "output": args.output.display().to_string(),
            "lines": summary.lines,
        });
        emit(&format!("{v}\n"))?;
    }
    eprintln!(
        "plot: wrote {} ({} lines)",
        args.output.display(),
        summary.lines.len()
    );
    Ok(())
}

/// A chart's drawing file beside its destination, removed however `plot` ends.
pub(crate) struct Staging(PathBuf);

impl Drop for Staging {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// `.<name>.<pid>.draw.<ext>` in the destination's directory (the extension picks the
/// format; the same directory makes the final move a rename on one file system).
pub(crate) fn staging_path(out: &std::path::Path) -> PathBuf {
    let name = out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = out
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    let p = out.with_file_name(format!(".{name}.{}.draw.{ext}", std::process::id()));
    let _ = std::fs::remove_file(&p);
    p
}

/// Draws the chart `args` asks for into `path`.
pub(crate) fn plot_to(
    args: &PlotArgs,
    opts: &crate::plot::PlotOptions,
    c: &crate::plot::Campaign,
    path: &std::path::Path,
) -> anyhow::Result<crate::plot::PlotSummary> {
    use crate::plot as lp;
    let summary = if let Some(param) = &args.campbell {
        let derived = args
            .derived
            .as_deref()
            .ok_or_else(|| anyhow!("--campbell needs --derived NAME"))?;
        let spec = lp::CampbellSpec {
            parameter: param.clone(),
            derived: derived.to_string(),
            units: lp::FreqUnits::parse(&args.units)?,
            southwell: args.southwell,
            harmonics: args.harmonics,
            branches: match &args.modes {
                Some(p) => lp::read_branches(p)?,
                None => Vec::new(),
            },
        };
        let r = lp::plot_campbell(c, &spec, opts, path)?;
        for (n, om) in &r.crossings {
            eprintln!("crossing: {n}Ω at {param} = {om:.6} rad/s");
        }
        if r.crossings.is_empty() {
            eprintln!("no crossing with the harmonics 1..{}", args.harmonics);
        }
        for (b, n, om) in &r.branch_crossings {
            eprintln!("eigenvalue branch {b} crosses {n}Ω at {param} = {om:.6} rad/s");
        }
        if args.json {
            let list: Vec<serde_json::Value> = r
                .crossings
                .iter()
                .map(|(n, om)| serde_json::json!({"harmonic": n, "omega": om}))
                .collect();
            let mut v = serde_json::json!({ "crossings": list });
            if args.modes.is_some() {
                v["branch_crossings"] = r
                    .branch_crossings
                    .iter()
                    .map(|(b, n, om)| serde_json::json!({"branch": b, "harmonic": n, "omega": om}))
                    .collect();
            }
            emit(&format!("{v}\n"))?;
        }
        r.summary
    } else if let (Some(x), Some(y)) = (&args.x, &args.y) {
        lp::plot_phase(c, x, y, opts, path)?
    } else {
        lp::plot_sensors(c, &args.sensor, opts, path)?
    };
    Ok(summary)
}
