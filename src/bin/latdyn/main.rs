//! The `latdyn` command line: one verb per analysis, all reading a model file.
//!
//! Every failure is reported once as `error: <message>` on stderr, with an exit code a
//! script can trust (README "Exit codes"): 0 success; 2 model, input or usage error
//! (clap's usage errors use 2 as well), an output path refused before the run included;
//! 3 finished, but the run or some variant failed; 4 interrupted (SIGINT, SIGTERM,
//! SIGHUP), the output file left valid and marked interrupted; 5 the output could not be
//! written mid-run (the last valid flush is kept); 70 internal error (a panic: a bug).

mod bench;
mod plot;

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{anyhow, bail, Context};
use clap::{Args, Parser, Subcommand};
use latdyn::model::{self, DofMode, Model};

#[derive(Parser)]
#[command(
    name = "latdyn",
    version,
    about = "Large-angle transient dynamics of flexible multibody systems"
)]
struct Cli {
    #[command(subcommand)]
    verb: Verb,
}

#[derive(Subcommand)]
enum Verb {
    /// Load and compile a model and print a summary; `--gpu` lists the GPU adapters
    Check(CheckArgs),
    /// Static equilibrium under the model's loads; `--path` follows the equilibrium path
    /// (arc length in the load factor or the drivers' pseudo-time)
    Statics(StaticsArgs),
    /// Natural frequencies and mode shapes (about the static equilibrium under the model's
    /// loads, or the reference configuration)
    Modes(ModesArgs),
    /// Time integration from 0 to t_end
    Run(RunArgs),
    /// Runs over a range of parameter values
    Sweep(SweepArgs),
    /// Merge the shard files of one campaign (`sweep --shard K/N`) into one campaign file
    Merge(MergeArgs),
    /// Plot sensor histories of a results file
    Plot(PlotArgs),
    /// The speed-against-error suite: reference problems at several resolutions, wall
    /// time beside error, ensemble throughput; writes docs/bench/results.{md,json} and work_precision.png
    Bench(BenchArgs),
}

#[derive(Args)]
struct MergeArgs {
    /// shard files of one campaign (`sweep --shard K/N -o ...`), in any order
    #[arg(required = true, value_name = "SHARD.h5")]
    shards: Vec<PathBuf>,
    /// the merged campaign file (HDF5)
    #[arg(short, long, value_name = "PATH")]
    output: PathBuf,
    /// print the report object as JSON on stdout
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct BenchArgs {
    /// shorter ladders and at most 100 ensemble variants (a few minutes)
    #[arg(long)]
    quick: bool,
    /// run only these problems (repeatable): rotating_cantilever, rollup, bend45, spinup,
    /// minimast, time_error, accuracy (not in a bare `bench`: ~35 min), ensemble
    #[arg(long = "only", value_name = "PROBLEM")]
    only: Vec<String>,
    /// directory of the shipped models
    #[arg(long, default_value = "models")]
    models: PathBuf,
    /// where results.md, results.json and work_precision.png go
    #[arg(long, default_value = "docs/bench")]
    out: PathBuf,
    /// threads for the ensemble rows (default: all cores; at most 4 per core or 256)
    #[arg(long, value_parser = latdyn::model::limits::parse_threads)]
    threads: Option<usize>,
    /// print the report object as JSON on stdout
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct ModelArgs {
    /// model file (TOML)
    model: PathBuf,
    /// override a parameter: --set NAME=VALUE (repeatable; VALUE may be `2*pi`)
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = model::parse_set)]
    set: Vec<(String, f64)>,
    /// machine-readable output (JSON on stdout)
    #[arg(long)]
    json: bool,
}

impl ModelArgs {
    fn load(&self) -> anyhow::Result<Model> {
        Ok(model::load(&self.model, &self.set)?)
    }
}

#[derive(Args)]
struct StaticsArgs {
    #[command(flatten)]
    model: ModelArgs,
    #[command(flatten)]
    path: PathArgs,
    /// with --path: the path in the campaign layout (HDF5), the path parameter as time
    #[arg(short, long, value_name = "PATH")]
    output: Option<PathBuf>,
}

/// Path following options of `statics --path` and `sweep --path` (README "Path following").
#[derive(Args, Clone)]
struct PathArgs {
    /// follow the equilibrium path by arc-length continuation through limit points and
    /// snap-backs, instead of one equilibrium
    #[arg(long)]
    path: bool,
    /// what the path parameter λ scales: `load` (the model's loads × λ), `drivers` (drive
    /// expressions at pseudo-time λ, loads at full value), `auto` (drivers when a drive
    /// changes over [0, t_end], else load)
    #[arg(long, default_value = "auto", value_parser = ["auto", "load", "drivers"])]
    control: String,
    /// end the path where λ reaches this value (default: 1 for load control without
    /// --until, t_end for drivers, else no bound)
    #[arg(long, value_name = "LAMBDA", value_parser = parse_positive)]
    lambda_max: Option<f64>,
    /// end the path where a sensor component crosses a value, e.g. load_point.y=-80
    #[arg(long, value_name = "SENSOR.COMPONENT=VALUE")]
    until: Option<String>,
    /// end the path at its K-th limit point (at the first point past it)
    #[arg(long, value_name = "K", value_parser = parse_limit_count)]
    limit_points: Option<usize>,
    /// end the path after this arc length (scaled (u, ψλ) norm, see README)
    #[arg(long, value_name = "S", value_parser = parse_positive)]
    max_length: Option<f64>,
    /// most path points (1 to 100000)
    #[arg(long, default_value_t = 2000, value_parser = parse_max_points)]
    max_points: usize,
    /// first increment of λ (default: λ_max/50, or 0.02 without a bound); later
    /// increments follow from the arc length, adapted to the Newton iteration counts
    #[arg(long, value_name = "DLAMBDA", value_parser = parse_positive)]
    first_step: Option<f64>,
}

fn parse_positive(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a finite positive number")),
    }
}

fn parse_limit_count(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(v) if (1..=1000).contains(&v) => Ok(v),
        _ => Err(format!("`{s}` is not a count from 1 to 1000")),
    }
}

fn parse_max_points(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(v) if (1..=100_000).contains(&v) => Ok(v),
        _ => Err(format!("`{s}` is not a point count from 1 to 100000")),
    }
}

impl PathArgs {
    /// Whether any path option was given (they need --path).
    fn any_option(&self) -> bool {
        self.control != "auto"
            || self.lambda_max.is_some()
            || self.until.is_some()
            || self.limit_points.is_some()
            || self.max_length.is_some()
            || self.max_points != 2000
            || self.first_step.is_some()
    }

    fn options(&self, m: &Model) -> anyhow::Result<latdyn::solver::path::PathOptions> {
        use latdyn::solver::path::{self, Control, PathOptions};
        let control = match self.control.as_str() {
            "load" => Control::Load,
            "drivers" => Control::Drivers,
            _ => path::default_control(m),
        };
        let until = self
            .until
            .as_deref()
            .map(|u| path::parse_until(m, u))
            .transpose()
            .map_err(|e| anyhow!("{}: {e}", m.path))?;
        let max_param = self.lambda_max.unwrap_or(match control {
            Control::Load if until.is_none() => 1.0,
            Control::Load => f64::INFINITY,
            Control::Drivers => m.solver.t_end,
        });
        let mut o = PathOptions::new(control, max_param);
        if let Some(f) = self.first_step {
            o.first_step = f;
        }
        o.max_length = self.max_length.unwrap_or(f64::INFINITY);
        o.max_points = self.max_points;
        o.until = until;
        o.limit_points = self.limit_points;
        Ok(o)
    }
}

#[derive(Args)]
struct CheckArgs {
    /// model file (TOML); optional with --gpu
    #[arg(required_unless_present = "gpu")]
    model: Option<PathBuf>,
    /// override a parameter: --set NAME=VALUE (repeatable; VALUE may be `2*pi`)
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = model::parse_set)]
    set: Vec<(String, f64)>,
    /// machine-readable output (JSON on stdout)
    #[arg(long)]
    json: bool,
    /// list the GPU adapters found (backend, device type, f64 support) and which one
    /// each --backend choice would use
    #[arg(long)]
    gpu: bool,
}

/// `--backend` and `--precision` of `run` and `sweep`.
#[derive(Args, Clone)]
struct BackendArgs {
    /// element evaluation: `cpu` (f64 reference), `gpu` (WGSL kernels on any adapter,
    /// software ones included), `auto` (a hardware GPU when present and the batch is
    /// large enough, else cpu)
    #[arg(long, default_value = "auto", value_parser = ["auto", "cpu", "gpu"])]
    backend: String,
    /// scalar of the GPU kernels; f64 needs an adapter with SHADER_F64 (the CPU is f64).
    /// With f32, Newton stops at the kernels' round-off when `[solver] tol` is below it
    /// (16 u of the force scale, or where the residual stops decreasing within 1024 u)
    #[arg(long, default_value = "f64", value_parser = ["f64", "f32"])]
    precision: String,
}

#[derive(Args)]
struct ModesArgs {
    #[command(flatten)]
    model: ModelArgs,
    /// number of modes to report (1 to 100000)
    #[arg(long, default_value_t = 10, value_parser = parse_mode_count)]
    count: usize,
    /// linearise about `static` equilibrium under the loads, or the `reference`
    /// configuration; `auto` = static when the model has loads or gravity
    #[arg(long, default_value = "auto", value_parser = ["auto", "static", "reference"])]
    about: String,
    /// include mode shapes (by node: displacement and rotation) in the JSON output
    #[arg(long)]
    shapes: bool,
    /// rotating models: modes at each value NAME=START:STOP:COUNT (e.g. omega=1:9:33),
    /// followed across the values by their shapes (MAC), so crossing branches keep
    /// their identity
    #[arg(long, value_name = "NAME=START:STOP:COUNT", value_parser = latdyn::ensemble::Range::parse)]
    vary: Option<latdyn::ensemble::Range>,
}

#[derive(Args)]
struct SweepArgs {
    #[command(flatten)]
    model: ModelArgs,
    #[command(flatten)]
    path: PathArgs,
    /// vary a parameter: NAME=START:STOP:COUNT (repeatable; several make a full grid)
    #[arg(long = "vary", value_name = "NAME=START:STOP:COUNT", value_parser = latdyn::ensemble::Range::parse)]
    vary: Vec<latdyn::ensemble::Range>,
    /// explicit variants: CSV with a header of parameter names, one row per variant
    #[arg(long, value_name = "CSV")]
    variants: Option<PathBuf>,
    /// campaign file (HDF5)
    #[arg(short, long, value_name = "PATH")]
    output: Option<PathBuf>,
    #[command(flatten)]
    backend: BackendArgs,
    /// worker threads (default: all cores; with a GPU backend, one per variant in flight,
    /// up to 128); from 1 to 4 per core or 256, whichever is more
    #[arg(long, value_parser = latdyn::model::limits::parse_threads)]
    threads: Option<usize>,
    /// run only the K-th of N interleaved subsets of the variants: K/N
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    shard: Option<(usize, usize)>,
    /// adaptive time steps meeting this relative local error (overrides `[solver]
    /// accuracy`; `dt` becomes the first step, `dt_max` the largest)
    #[arg(long, value_name = "TOL", value_parser = parse_accuracy)]
    accuracy: Option<f64>,
    /// sensor (SENSOR or SENSOR.COMPONENT) whose dominant frequency is reported as
    /// derived.first_bending_hz
    #[arg(long, value_name = "SENSOR[.COMPONENT]")]
    frequency: Option<String>,
    /// after the campaign, rerun K of its variants (spread over it) with dt halved and
    /// twice the elements, and report how much every sensor's extremes change: the
    /// campaign's measured discretisation error (README "Verification"); with --shard,
    /// only shard 1 verifies
    #[arg(long, value_name = "K")]
    verify: Option<usize>,
    /// complete this campaign file in place: run only its variants that are not
    /// completed (missing, failed, interrupted); refused when the campaign definition
    /// (model, --vary/--variants, --set, --accuracy, --frequency, backend, precision,
    /// latdyn version) differs from the file's
    #[arg(long, value_name = "CAMPAIGN.h5", conflicts_with_all = ["output", "shard", "verify"])]
    resume: Option<PathBuf>,
    /// print the campaign's plan instead of running it: the variant table, the shard of
    /// each variant for --shards N, and the cost per variant from a short probe run
    #[arg(long, conflicts_with_all = ["output", "shard", "verify", "resume"])]
    plan: bool,
    /// with --plan: the number of shards (array tasks) to plan for
    #[arg(long, value_name = "N", default_value_t = 1, requires = "plan", value_parser = parse_shards)]
    shards: usize,
    /// with --plan: variants probed (spread over the table, each run for 10 % of its
    /// t_end on one thread); 0 = no probe
    #[arg(long, value_name = "K", default_value_t = 3, requires = "plan")]
    probe: usize,
}

/// `--shards N`: at least one, at most the variant limit.
fn parse_shards(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if (1..=1_000_000).contains(&n) => Ok(n),
        _ => Err(format!(
            "`{s}`: need a whole number of shards from 1 to 1000000"
        )),
    }
}

/// `--count`: at least one mode, and bounded so that `count + spares` cannot overflow.
fn parse_mode_count(s: &str) -> Result<usize, String> {
    const MAX: usize = 100_000;
    match s.trim().parse::<usize>() {
        Ok(n) if (1..=MAX).contains(&n) => Ok(n),
        _ => Err(format!(
            "`{s}`: need a whole number of modes from 1 to {MAX}"
        )),
    }
}

/// `--accuracy`: a relative error target in (0, MAX_ACCURACY].
fn parse_accuracy(s: &str) -> Result<f64, String> {
    let max = latdyn::model::compile::MAX_ACCURACY;
    match s.trim().parse::<f64>() {
        Ok(a) if a > 0.0 && a <= max => Ok(a),
        _ => Err(format!(
            "`{s}`: need a relative error target greater than 0 and at most {max}"
        )),
    }
}

fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let (k, n) = s.split_once('/').ok_or("expected K/N")?;
    let k: usize = k.trim().parse().map_err(|_| "K must be an integer")?;
    let n: usize = n.trim().parse().map_err(|_| "N must be an integer")?;
    if n == 0 || k == 0 || k > n {
        return Err(format!("{s}: need 1 ≤ K ≤ N"));
    }
    Ok((k, n))
}

#[derive(Args)]
struct RunArgs {
    #[command(flatten)]
    model: ModelArgs,
    /// output file
    #[arg(short, long, value_name = "PATH")]
    output: Option<PathBuf>,
    #[command(flatten)]
    backend: BackendArgs,
    /// adaptive time steps meeting this relative local error (overrides `[solver]
    /// accuracy`; `dt` becomes the first step, `dt_max` the largest)
    #[arg(long, value_name = "TOL", value_parser = parse_accuracy)]
    accuracy: Option<f64>,
}

/// `latdyn plot FILE.h5 (--sensor S... | --x S --y S | --campbell P --derived D) -o OUT`
#[derive(Args)]
#[command(group(clap::ArgGroup::new("kind").required(true).args(["sensor", "x", "campbell"])))]
struct PlotArgs {
    /// results file (HDF5) written by `run` or `sweep`
    input: PathBuf,
    /// image file to write; the format follows the extension: .svg or .png
    #[arg(short, long, value_name = "OUT.svg|png")]
    output: PathBuf,
    /// time histories of a sensor, one line per variant; all its components unless one
    /// is named (repeatable)
    #[arg(long, value_name = "NAME[.COMPONENT]")]
    sensor: Vec<String>,
    /// cross plot: this sensor component on the x axis (with --y)
    #[arg(long, value_name = "NAME[.COMPONENT]", requires = "y")]
    x: Option<String>,
    /// cross plot: this sensor component on the y axis (with --x)
    #[arg(long, value_name = "NAME[.COMPONENT]", requires = "x")]
    y: Option<String>,
    /// Campbell diagram against this parameter (rotor speed, rad/s); needs --derived
    #[arg(long, value_name = "PARAM", requires = "derived")]
    campbell: Option<String>,
    /// Campbell diagram: the frequency (Hz) of each variant, /derived/NAME
    #[arg(long, value_name = "NAME", requires = "campbell")]
    derived: Option<String>,
    /// Campbell diagram: frequency axis in rad/s (2π·f) or Hz
    #[arg(long, default_value = "rad", value_parser = ["rad", "hz"], requires = "campbell")]
    units: String,
    /// Campbell diagram: Southwell curve sqrt(W0² + K·Ω²), W0 in the axis units
    #[arg(
        long,
        value_name = "W0,K",
        requires = "campbell",
        allow_hyphen_values = true,
        value_parser = crate::plot::parse_pair
    )]
    southwell: Option<(f64, f64)>,
    /// Campbell diagram: eigenvalue branches from `latdyn modes MODEL --vary omega=A:B:N
    /// --json > FILE.json`, drawn beside the data
    #[arg(long, value_name = "FILE.json", requires = "campbell")]
    modes: Option<PathBuf>,
    /// Campbell diagram: rotor harmonics n·Ω drawn, n = 1..N
    #[arg(long, value_name = "N", default_value_t = 6, requires = "campbell")]
    harmonics: usize,
    /// variants (row indices) to plot, e.g. 0,3,5; default all (at most 20 lines)
    #[arg(long, value_name = "I,J,...", value_delimiter = ',')]
    variants: Vec<usize>,
    /// chart title (default: the model path stored in the file)
    #[arg(long)]
    title: Option<String>,
    /// image size in pixels
    #[arg(long, value_name = "WxH", default_value = "1000x640", value_parser = crate::plot::parse_size)]
    size: (u32, u32),
    /// machine-readable output on stdout (Campbell: the crossings)
    #[arg(long)]
    json: bool,
}

/// Exit codes (README "Exit codes").
const EXIT_USAGE: u8 = 2;
const EXIT_FAILED: u8 = 3;
const EXIT_INTERRUPTED: u8 = 4;
const EXIT_OUTPUT: u8 = 5;
const EXIT_INTERNAL: u8 = 70;

/// An error with an exit code other than [`EXIT_USAGE`]; an empty message was already
/// reported (the panic hook prints its own line).
#[derive(Debug)]
struct Fail {
    code: u8,
    message: String,
}

impl std::fmt::Display for Fail {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Fail {}

fn fail(code: u8, message: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(Fail {
        code,
        message: message.into(),
    })
}

/// The text of a panic payload (`panic!` gives a `&str` or a `String`).
fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// One clean line per panic instead of Rust's dump; `RUST_BACKTRACE=1` adds the trace.
fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let msg = panic_text(info.payload());
        let at = info
            .location()
            .map(|l| format!(" at {}:{}:{}", l.file(), l.line(), l.column()))
            .unwrap_or_default();
        let mut err = std::io::stderr().lock();
        // a closed stderr must not turn the report into an abort
        let _ = writeln!(
            err,
            "error: internal error: {msg}{at} (this is a bug in latdyn; please report it)"
        );
        if std::env::var_os("RUST_BACKTRACE").is_some_and(|v| v != "0") {
            let _ = writeln!(err, "{}", std::backtrace::Backtrace::force_capture());
        }
    }));
}

fn main() -> ExitCode {
    install_panic_hook();
    let cli = Cli::parse();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        if injected_panic("main") {
            panic!("injected panic (LATDYN_FAULT_PANIC=main)");
        }
        dispatch(&cli)
    }));
    match result {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(e)) => {
            let code = e.downcast_ref::<Fail>().map_or(EXIT_USAGE, |f| f.code);
            let text = error_chain(&e);
            if !text.is_empty() {
                let _ = writeln!(std::io::stderr(), "error: {text}");
            }
            ExitCode::from(code)
        }
        // the hook has printed the message and where
        Err(_) => ExitCode::from(EXIT_INTERNAL),
    }
}

/// Fault injection for tests/output_faults.rs: `LATDYN_FAULT_PANIC=main` panics before
/// the verb runs, `=worker` in a sweep's worker thread after its first variant, so the
/// tests see a real panic cross each boundary. Unset, nothing happens.
fn injected_panic(site: &str) -> bool {
    std::env::var_os("LATDYN_FAULT_PANIC").is_some_and(|v| v == site)
}

fn dispatch(cli: &Cli) -> anyhow::Result<()> {
    match &cli.verb {
        Verb::Check(a) => check(a),
        Verb::Statics(a) => statics(a),
        Verb::Modes(a) => modes(a),
        Verb::Run(a) => run(a),
        Verb::Sweep(a) => sweep(a),
        Verb::Merge(a) => merge(a),
        Verb::Plot(a) => plot(a),
        Verb::Bench(a) => bench(a),
    }
}

/// Set on SIGINT, SIGTERM or SIGHUP (what a terminal, a scheduler or a closed session
/// sends): runs and sweeps stop before their next time step and finish their file as
/// interrupted. A handler can be installed once per process; failing to install one
/// (not possible on this platform) leaves the default behaviour.
fn stop_flag() -> std::sync::Arc<std::sync::atomic::AtomicBool> {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    let _ = ctrlc::set_handler(move || s.store(true, Ordering::SeqCst));
    stop
}

/// Claim an output path before any simulation; a refusal is a usage error (exit 2).
fn claim_output(path: &std::path::Path) -> anyhow::Result<latdyn::output::OutputTarget> {
    latdyn::output::OutputTarget::claim(path).map_err(|e| anyhow!("{e}"))
}

fn is_csv(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
}

/// The speed-against-error suite (bench.rs); the report files are written even when
/// `--json` prints the report.
fn bench(args: &BenchArgs) -> anyhow::Result<()> {
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
    };
    std::fs::create_dir_all(&args.out).map_err(|e| {
        anyhow!(
            "{}: --out: cannot create the directory: {e}",
            args.out.display()
        )
    })?;
    let report = bench::run_suite(&opts, &|line| eprintln!("{line}"))?;
    let command = std::env::args()
        .skip(1)
        .fold("latdyn".to_string(), |a, b| a + " " + &b);
    let svg = args.out.join("work_precision.png");
    let has_runs = report.problems.iter().any(|p| !p.runs.is_empty());
    if has_runs {
        bench::plot(&report, &svg)?;
    }
    let md = bench::markdown(&report, &command, has_runs.then_some("work_precision.png"));
    let write = |name: &str, text: &str| {
        let p = args.out.join(name);
        std::fs::write(&p, text).map_err(|e| anyhow!("{}: cannot write: {e}", p.display()))
    };
    write("results.md", &md)?;
    let json = serde_json::to_string_pretty(&report)?;
    write("results.json", &json)?;
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
fn plot(args: &PlotArgs) -> anyhow::Result<()> {
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
    let target = claim_output(&args.output)?;
    let staging = Staging(staging_path(&args.output));
    let summary = plot_to(args, &opts, &c, &staging.0)?;
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
struct Staging(PathBuf);

impl Drop for Staging {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// `.<name>.<pid>.draw.<ext>` in the destination's directory (the extension picks the
/// format; the same directory makes the final move a rename on one file system).
fn staging_path(out: &std::path::Path) -> PathBuf {
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
fn plot_to(
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

/// Write text to stdout; a closed pipe is an error, not a panic.
fn emit(text: &str) -> anyhow::Result<()> {
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .context("writing to stdout")
}

fn sensor_map(m: &Model, vals: &[Vec<f64>]) -> serde_json::Map<String, serde_json::Value> {
    m.sensors
        .iter()
        .zip(vals)
        .map(|(sn, v)| (sn.name.clone(), serde_json::json!(v)))
        .collect()
}

fn statics(sargs: &StaticsArgs) -> anyhow::Result<()> {
    if sargs.path.path {
        return statics_path(sargs);
    }
    if sargs.path.any_option() || sargs.output.is_some() {
        bail!("statics: --control, --lambda-max, --until, --limit-points, --max-length, --max-points, --first-step and -o need --path");
    }
    let args = &sargs.model;
    let m = args.load()?;
    let t0 = std::time::Instant::now();
    let sol = latdyn::solver::solve_statics(&m).with_context(|| m.path.clone())?;
    let wall = t0.elapsed().as_secs_f64();
    if args.json {
        let v = serde_json::json!({
            "sensors": sensor_map(&m, &sol.sensors),
            "strain_energy": sol.strain_energy,
            "load_steps": sol.report.load_steps,
            "newton_iterations": sol.report.newton_iterations,
            "rejected_steps": sol.report.rejected_steps,
            "wall_s": wall,
        });
        emit(&format!("{v}\n"))
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
        emit(&s)
    }
}

fn modes(args: &ModesArgs) -> anyhow::Result<()> {
    if let Some(range) = &args.vary {
        return modes_vary(args, range);
    }
    let m = args.model.load()?;
    if let Some(spin) = latdyn::solver::rotating::find_spin(&m) {
        return rotating_modes(args, &m, spin);
    }
    let preload = match args.about.as_str() {
        "static" => true,
        "reference" => false,
        _ => !m.loads.is_empty() || m.gravity != [0.0; 3],
    };
    let state = if preload {
        latdyn::solver::solve_statics(&m)
            .with_context(|| format!("{}: static equilibrium for the modes", m.path))?
            .state
    } else {
        latdyn::joint::State::new(&m)
    };
    let md = latdyn::solver::modes::lowest_modes(&m, &state, args.count)
        .with_context(|| format!("{}: modes", m.path))?;
    let count = args.count.min(md.frequencies_hz.len());
    let f = &md.frequencies_hz[..count];
    for w in &md.warnings {
        eprintln!("warning: {w}");
    }
    if args.model.json {
        let mut v = serde_json::json!({
            "frequencies_hz": f,
            "zero_frequency": &md.zero_frequency[..count],
            "error_estimates": &md.error_estimates[..count],
            "warnings": md.warnings,
            "about": if preload { "static" } else { "reference" },
            "free_dofs": m.n_eq,
        });
        if args.shapes {
            v["shapes"] = serde_json::json!(md.shapes[..count]
                .iter()
                .map(|sh| {
                    m.dofs
                        .iter()
                        .map(|d| {
                            (
                                d.name.clone(),
                                serde_json::json!(d.eq.map(|e| sh[e]).unwrap_or(0.0)),
                            )
                        })
                        .collect::<serde_json::Map<String, serde_json::Value>>()
                })
                .collect::<Vec<_>>());
        }
        emit(&format!("{v}\n"))
    } else {
        let mut s = format!(
            "modes {} about the {} configuration ({} free dofs)\n",
            m.name,
            if preload {
                "static equilibrium"
            } else {
                "reference"
            },
            m.n_eq
        );
        for (k, x) in f.iter().enumerate() {
            let tag = if md.zero_frequency[k] {
                "  (zero frequency: rigid-body or mechanism motion)"
            } else {
                ""
            };
            s += &format!("  {:>3}  {:>14.6} Hz{tag}\n", k + 1, x);
        }
        emit(&s)
    }
}

/// Modes of a model with a hub at constant speed: about the steady rotating state, in
/// the rotating frame.
fn rotating_modes(
    args: &ModesArgs,
    m: &Model,
    spin: latdyn::solver::rotating::Spin,
) -> anyhow::Result<()> {
    let rm = latdyn::solver::rotating::rotating_modes(m, spin)
        .with_context(|| format!("{}: rotating-frame modes", m.path))?;
    let count = args.count.min(rm.frequencies_hz.len());
    let f = &rm.frequencies_hz[..count];
    if args.model.json {
        let v = serde_json::json!({
            "frequencies_hz": f,
            "damping_ratios": &rm.damping[..count],
            "about": "steady_rotation",
            "omega_rad_s": rm.omega,
            "free_dofs": m.n_eq,
        });
        emit(&format!("{v}\n"))
    } else {
        let mut s = format!(
            "modes {} in the frame rotating at {:.6} rad/s, about the steady state ({} free dofs)\n",
            m.name, rm.omega, m.n_eq
        );
        for (k, x) in f.iter().enumerate() {
            s += &format!("  {:>3}  {:>14.6} Hz\n", k + 1, x);
        }
        emit(&s)
    }
}

/// `modes --vary`: rotating-frame modes at each value of one parameter, tracked into
/// branches by MAC against the previous value's shapes.
fn modes_vary(args: &ModesArgs, range: &latdyn::ensemble::Range) -> anyhow::Result<()> {
    use latdyn::solver::rotating;
    if args.count == 0 {
        return Err(anyhow!("--count must be at least 1"));
    }
    let base = model::load(&args.model.model, &args.model.set)?;
    if base.param(&range.name).is_none() {
        let names: Vec<&str> = base.params.iter().map(|(n, _)| n.as_str()).collect();
        return Err(anyhow!(
            "--vary {}: the model has no parameter `{}` (parameters: {})",
            range.name,
            range.name,
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        ));
    }
    let values = range.values();
    // a few spare shapes per value: a branch whose mode has moved past others must
    // still find it among the candidates
    let want = args.count + 4;
    let mut steps = Vec::with_capacity(values.len());
    let mut free_dofs = 0;
    for &v in &values {
        let mut set = args.model.set.clone();
        set.retain(|(n, _)| *n != range.name);
        set.push((range.name.clone(), v));
        let m = model::load(&args.model.model, &set)?;
        if m.param(&range.name).is_none() {
            return Err(anyhow!(
                "--vary {}: the model has no parameter `{}`",
                range.name,
                range.name
            ));
        }
        let spin = rotating::find_spin(&m).ok_or_else(|| {
            anyhow!(
                "--vary {}={v}: no body of {} turns at a constant nonzero speed; --vary \
                 follows rotating-frame modes, so every value must give a spinning hub \
                 (start a speed range just above 0, e.g. 1e-6)",
                range.name,
                m.path
            )
        })?;
        if free_dofs != 0 && free_dofs != m.n_eq {
            return Err(anyhow!(
                "--vary {}={v}: the number of free coordinates changes ({} → {}); modes \
                 can only be followed across values of the same topology",
                range.name,
                free_dofs,
                m.n_eq
            ));
        }
        free_dofs = m.n_eq;
        let rm = rotating::rotating_modes_with_shapes(&m, spin, want)
            .with_context(|| format!("{}: rotating-frame modes at {}={v}", m.path, range.name))?;
        steps.push(rm);
    }
    let branches = rotating::track_branches(&steps, args.count);
    let speeds: Vec<f64> = steps.iter().map(|s| s.omega).collect();
    if args.model.json {
        let list: Vec<serde_json::Value> = branches
            .iter()
            .enumerate()
            .map(|(k, b)| {
                serde_json::json!({
                    "branch": k + 1,
                    "frequencies_hz": b.frequencies_hz.iter().map(|x| x.is_finite().then_some(*x)).collect::<Vec<_>>(),
                    "damping_ratios": b.damping.iter().map(|x| x.is_finite().then_some(*x)).collect::<Vec<_>>(),
                    "mac": b.mac,
                })
            })
            .collect();
        let sorted: Vec<Vec<f64>> = steps
            .iter()
            .map(|s| s.frequencies_hz[..args.count.min(s.frequencies_hz.len())].to_vec())
            .collect();
        let v = serde_json::json!({
            "about": "steady_rotation",
            "parameter": range.name,
            "values": values,
            "omega_rad_s": speeds,
            "branches": list,
            "sorted_frequencies_hz": sorted,
            "free_dofs": free_dofs,
        });
        emit(&format!("{v}\n"))
    } else {
        let mut s = format!(
            "rotating-frame modes of {} followed by shape (MAC) over {} = {}..{} ({} values)\n",
            args.model.model.display(),
            range.name,
            range.start,
            range.stop,
            values.len()
        );
        s += &format!("  {:>12}", range.name);
        for k in 0..branches.len() {
            s += &format!("  {:>12}", format!("branch {} Hz", k + 1));
        }
        s += "  min MAC\n";
        for (i, v) in values.iter().enumerate() {
            s += &format!("  {v:>12.6}");
            let mut worst = 1.0f64;
            for b in &branches {
                s += &format!("  {:>12.6}", b.frequencies_hz[i]);
                worst = worst.min(b.mac[i]);
            }
            s += &format!("  {worst:.3}\n");
        }
        emit(&s)
    }
}

/// Where `run -o` puts its samples as they come: the campaign layout with one variant,
/// or CSV. Both are rewritten atomically at most every [`RUN_FLUSH_S`] and at the end.
enum RunSink {
    H5(Box<latdyn::output::CampaignWriter>),
    Csv {
        target: latdyn::output::OutputTarget,
        text: String,
    },
}

/// Shortest time between two rewrites of the `run -o` file [s] (as a sweep).
const RUN_FLUSH_S: f64 = 2.0;

impl RunSink {
    fn open(
        m: &Model,
        target: latdyn::output::OutputTarget,
        stage: &latdyn::ensemble::Stage,
    ) -> Result<RunSink, latdyn::output::OutputError> {
        if is_csv(target.path()) {
            let text = csv_header(m);
            // written at once: the path is shown writable before the run
            target.replace_with(text.as_bytes())?;
            Ok(RunSink::Csv { target, text })
        } else {
            let mut w = latdyn::output::CampaignWriter::create_at(target, &single_meta(m, stage))?;
            let running = latdyn::output::VariantStatus {
                state: latdyn::output::VariantState::Running,
                ..Default::default()
            };
            w.set_status(0, &running)?;
            Ok(RunSink::H5(Box::new(w)))
        }
    }

    fn sample(
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

    fn flush(&mut self) -> Result<(), latdyn::output::OutputError> {
        match self {
            RunSink::H5(w) => w.flush(),
            RunSink::Csv { target, text } => target.replace_with(text.as_bytes()),
        }
    }

    fn finish(
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
            RunSink::Csv { target, text } => target.replace_with(text.as_bytes()),
        }
    }
}

fn run(args: &RunArgs) -> anyhow::Result<()> {
    use latdyn::output::{VariantState, VariantStatus};
    use std::sync::atomic::Ordering;
    let mut m = args.model.load()?;
    if args.accuracy.is_some() {
        m.solver.accuracy = args.accuracy;
    }
    let target = args.output.as_deref().map(claim_output).transpose()?;
    let (stage, _batcher) = choose_stage(&args.backend, 1, m.elements.len(), 1)?;
    let mut sink = match target {
        Some(t) => Some(RunSink::open(&m, t, &stage).map_err(|e| anyhow!("{e}"))?),
        None => None,
    };
    let stop = stop_flag();
    let mut out_err: Option<latdyn::output::OutputError> = None;
    let mut n_samples = 0usize;
    let mut last_flush = std::time::Instant::now();
    let t0 = std::time::Instant::now();
    let (hist, stats, err) = {
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
        let simulate = || latdyn::solver::dynamics::run_until(&m, Some(stop.as_ref()), on_sample);
        match &stage.make {
            Some(make) => latdyn::assembly::with_evaluator(make(), simulate),
            None => simulate(),
        }
    };
    let wall = t0.elapsed().as_secs_f64();
    let interrupted = matches!(
        err,
        Some(latdyn::solver::dynamics::DynamicsError::Interrupted { .. })
    );
    if let Some(s) = sink {
        let status = VariantStatus {
            state: match &err {
                None => VariantState::Completed,
                Some(_) if interrupted => VariantState::Interrupted,
                Some(_) => VariantState::Failed,
            },
            message: err.as_ref().map(|e| e.to_string()).unwrap_or_default(),
            t_fail: err.as_ref().map(|e| e.time()).unwrap_or(f64::NAN),
            steps: stats.steps as u64,
            rejected_steps: stats.rejected_steps as u64,
            wall_s: wall,
            energy_growth: stats.energy_growth.unwrap_or(f64::NAN),
            energy_loss: stats.energy_loss.unwrap_or(f64::NAN),
            time_error_estimate: stats.time_error_estimate.unwrap_or(f64::NAN),
            warnings: stats.warnings().join("\n"),
        };
        // after an output error the last good flush is what stays
        if out_err.is_none() {
            if let Err(e) = s.finish(&status) {
                out_err = Some(e);
            }
        }
    }
    let warnings: Vec<String> = stats.warnings();
    for w in &warnings {
        eprintln!("warning: {}: {w}", m.path);
    }
    let (status, message) = match (&out_err, &err) {
        (Some(e), _) => ("output_failed", e.to_string()),
        (None, Some(e)) if interrupted => ("interrupted", e.to_string()),
        (None, Some(e)) => ("failed", e.to_string()),
        (None, None) => ("completed", String::new()),
    };
    if args.model.json {
        let mut sensors = serde_json::Map::new();
        for (k, sn) in m.sensors.iter().enumerate() {
            let vals = &hist.values[k];
            let nc = vals.first().map(|v| v.len()).unwrap_or(0);
            let fold = |f: fn(f64, f64) -> f64, init: f64| -> Vec<f64> {
                (0..nc)
                    .map(|c| vals.iter().map(|v| v[c]).fold(init, f))
                    .collect()
            };
            sensors.insert(
                sn.name.clone(),
                serde_json::json!({
                    "t": hist.t,
                    "values": vals,
                    "min": fold(f64::min, f64::INFINITY),
                    "max": fold(f64::max, f64::NEG_INFINITY),
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
            "time_error_estimate": stats.time_error_estimate,
            "time_error_by_sensor": m.sensors.iter().map(|s| s.name.as_str()).zip(&stats.time_error_by_sensor).collect::<std::collections::BTreeMap<_, _>>(),
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
        Some(e) if interrupted => Err(fail(EXIT_INTERRUPTED, format!("{}: {e}{written}", m.path))),
        Some(e) => Err(fail(EXIT_FAILED, format!("{}: {e}", m.path))),
        None => Ok(()),
    }
}

/// `latdyn merge`: exit 0 when every variant completed, 3 when all ran and some failed,
/// 4 when some are missing or interrupted (resume the merged file), 2 when refused
/// (another campaign, repeated indices, unreadable input), 5 when the output failed.
fn merge(args: &MergeArgs) -> anyhow::Result<()> {
    use latdyn::campaign::{self, MergeError, MergeReport};
    let out_canon = std::fs::canonicalize(&args.output).ok();
    for s in &args.shards {
        if out_canon.is_some() && std::fs::canonicalize(s).ok() == out_canon {
            bail!(
                "merge: -o {} is one of the shard files; write the merged campaign elsewhere",
                args.output.display()
            );
        }
    }
    let target = claim_output(&args.output)?;
    let mut report = MergeReport::default();
    let command_line = std::env::args().collect::<Vec<_>>().join(" ");
    let result = campaign::merge(&args.shards, target, &command_line, &mut report);
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
        Err(e) => (EXIT_USAGE, e.to_string()),
    };
    if result.is_err() {
        report.status = "refused".into();
    }
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

/// The campaign layout of a single run (one variant, the model's parameters).
fn single_meta(m: &Model, stage: &latdyn::ensemble::Stage) -> latdyn::output::CampaignMeta {
    use latdyn::output::*;
    CampaignMeta {
        command_line: std::env::args().collect::<Vec<_>>().join(" "),
        model_path: m.path.clone(),
        model_source: m.source.clone(),
        backend: stage.backend.clone(),
        precision: stage.precision.clone(),
        adapter: stage.adapter.clone(),
        threads: 1,
        parameter_names: m.params.iter().map(|(n, _)| n.clone()).collect(),
        parameter_values: vec![m.params.iter().map(|(_, v)| *v).collect()],
        global_index: vec![0],
        time: latdyn::solver::dynamics::output_times(m),
        sensors: SensorMeta::of_model(m),
    }
}

fn sweep(args: &SweepArgs) -> anyhow::Result<()> {
    use latdyn::ensemble::{self, Campaign};
    use std::io::IsTerminal;
    use std::sync::atomic::Ordering;
    if args.path.path {
        return sweep_path(args);
    }
    if args.path.any_option() {
        bail!("sweep: --control, --lambda-max, --until, --limit-points, --max-length, --max-points and --first-step need --path");
    }
    let variants = ensemble::variants(
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
            let c = if comp.is_empty() {
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
    let n_elem = args.model.load()?.elements.len();
    // before compiling the variants: a refused path costs nothing
    let mut target = args
        .output
        .as_deref()
        .or(args.resume.as_deref())
        .map(claim_output)
        .transpose()?;
    let n_var = variants.len().max(1);
    let (stage, batcher) = choose_stage(&args.backend, n_var, n_elem, cores)?;
    let threads = args.threads.unwrap_or(if stage.make.is_some() {
        // GPU: one solver thread per variant in flight; they sleep while the batcher
        // evaluates their elements, so many more than cores keeps the batches large
        n_var.clamp(1, GPU_BATCH_THREADS)
    } else {
        cores
    });
    let c = Campaign {
        model_path: args.model.model.clone(),
        base: args.model.set.clone(),
        variants,
        threads,
        output: args.output.clone().or(args.resume.clone()),
        shard: args.shard,
        accuracy: args.accuracy,
        frequency_sensor,
        command_line: std::env::args().collect::<Vec<_>>().join(" "),
    };
    if args.plan {
        return sweep_plan(args, &c, &stage);
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
    let (prepared, resume) = match (&args.resume, target.take()) {
        (Some(path), Some(t)) => {
            let r = latdyn::campaign::resume(t, &c, &stage).map_err(|e| anyhow!("{e}"))?;
            eprintln!(
                "sweep --resume {}: {} variant(s) to run (not completed) of {} in the file",
                path.display(),
                r.rows.len(),
                r.writer.n_variants()
            );
            (r.prepared, Some((r.writer, r.rows)))
        }
        (_, t) => {
            target = t;
            (ensemble::prepare(&c)?, None)
        }
    };
    let stop = stop_flag();
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
    } = {
        let progress = |done: usize, _: usize| {
            if let Some(b) = &bar {
                b.set_position(done as u64);
            }
            if injected_panic("worker") {
                panic!("injected panic in a sweep worker (LATDYN_FAULT_PANIC=worker)");
            }
        };
        match resume {
            Some((writer, rows)) => {
                ensemble::run_resume(&c, &prepared, &stop, &progress, &stage, writer, &rows)
            }
            None => ensemble::run_verified_to(
                &c,
                &prepared,
                &stop,
                false,
                &progress,
                &stage,
                target,
                verify_chosen.as_deref(),
            ),
        }
    }
    .map_err(|e| anyhow!("{e}"))?;
    if let Some(b) = &batcher {
        let st = b.stats();
        eprintln!(
            "gpu {}: {} rounds, {:.1} requests per round, upload {:.3} s, kernels {:.3} s, download {:.3} s",
            b.name(),
            st.rounds,
            st.requests as f64 / st.rounds.max(1) as f64,
            st.gpu.upload_s,
            st.gpu.kernel_s,
            st.gpu.download_s
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
    let (status, message) = match &output_error {
        Some(e) => (
            "output_failed",
            format!(
                "{e}; the campaign stopped (variants not run are marked not_run){}",
                c.output
                    .as_ref()
                    .map(|p| format!(", {} keeps its last flush", p.display()))
                    .unwrap_or_default()
            ),
        ),
        None if interrupted => (
            "interrupted",
            "interrupted by a signal; the campaign file is marked interrupted".to_string(),
        ),
        None => ("complete", String::new()),
    };
    eprintln!(
        "sweep {}: {} variants ({} not completed) in {:.2} s on {} threads{}",
        c.model_path.display(),
        outcomes.len(),
        failed,
        wall,
        threads,
        match (&c.output, &output_error) {
            (Some(p), None) => format!(", written to {}", p.display()),
            (Some(p), Some(_)) => format!(", writing {} failed", p.display()),
            (None, _) => String::new(),
        }
    );
    // per kind of warning: how many variants, which (first 20), and the first text in full
    let mut kinds: Vec<(String, Vec<usize>, String)> = Vec::new();
    for o in &outcomes {
        for w in &o.warnings {
            let kind = latdyn::frequency::warning_kind(w);
            match kinds.iter_mut().find(|(k, _, _)| *k == kind) {
                Some((_, idx, _)) => {
                    if idx.last() != Some(&o.global_index) {
                        idx.push(o.global_index)
                    }
                }
                None => kinds.push((kind, vec![o.global_index], w.clone())),
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
                    "wall_s": o.wall_s,
                    "energy_growth": o.energy_growth,
                    "energy_loss": o.energy_loss,
                    "time_error_estimate": o.time_error_estimate,
                    "warnings": o.warnings,
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
        });
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

/// Fraction of t_end a `sweep --plan` probe runs.
const PROBE_FRACTION: f64 = 0.1;

/// `sweep --plan`: the variant table with each variant's shard, and the cost estimate.
fn sweep_plan(
    args: &SweepArgs,
    c: &latdyn::ensemble::Campaign,
    stage: &latdyn::ensemble::Stage,
) -> anyhow::Result<()> {
    use latdyn::campaign;
    let n = c.variants.len();
    let shards = args.shards;
    // one compiled variant gives the time grid and sensors of the identity
    let p = latdyn::ensemble::prepare_rows(c, vec![0])?;
    let info = latdyn::ensemble::identify(c, &p, stage)?;
    let m0 = &p.models[0];
    let n_time = p.time.len();
    let values_per_variant: usize = m0
        .sensors
        .iter()
        .map(|s| latdyn::sensors::components(&s.kind).len())
        .sum::<usize>()
        * n_time;
    let probes = campaign::probe(c, &campaign::probe_indices(n, args.probe), PROBE_FRACTION)?;
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
        .map(|k| (0..n).filter(|g| g % shards == k).count())
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
            "cpu_s": mean.map(|x| x * n as f64),
            "per_task_wall_s": mean.map(|x| x * per_shard as f64 / threads as f64),
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
        if let Some(mean) = mean {
            println!(
                "estimate: {:.1} CPU-s in all; {:.1} s per task on {threads} thread(s), plus \
                 the merge",
                mean * n as f64,
                mean * per_shard as f64 / threads as f64
            );
        }
    }
    Ok(())
}

/// CSV of the sensor histories: the header (time, then every sensor component).
fn csv_header(m: &Model) -> String {
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
fn csv_row(s: &mut String, t: f64, vals: &[Vec<f64>]) {
    use std::fmt::Write as _;
    let _ = write!(s, "{t}");
    for v in vals {
        for x in v {
            let _ = write!(s, ",{x}");
        }
    }
    s.push('\n');
}

/// Solver threads of a GPU sweep (variants in flight, each waiting on the batcher).
const GPU_BATCH_THREADS: usize = 128;

/// `--backend auto` uses a hardware GPU only from this many element evaluations per
/// Newton round (variants in flight × elements) on: below it one round trip's fixed
/// latency exceeds the CPU's time for the batch. See README "GPU backend".
const AUTO_GPU_MIN_ELEMENTS: usize = 4096;

/// Resolve `--backend`/`--precision` into an element stage (and the batcher behind it).
fn choose_stage(
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
            if in_flight * n_elem < AUTO_GPU_MIN_ELEMENTS {
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

/// `latdyn check --gpu`: the adapters and what each backend choice would use.
fn check_gpu(json: bool) -> anyhow::Result<()> {
    use latdyn::gpu::{self, Precision};
    let list = gpu::adapter_summaries();
    let pick = |p: Precision, soft: bool| {
        gpu::select(p, soft)
            .map(|(_, s)| s.label())
            .unwrap_or_else(|e| format!("none ({e})"))
    };
    let text = if json {
        let v = serde_json::json!({
            "adapters": list.iter().map(|a| serde_json::json!({
                "name": a.name, "backend": a.backend, "device_type": a.device_type,
                "driver": a.driver, "shader_f64": a.shader_f64, "software": a.is_software(),
            })).collect::<Vec<_>>(),
            "gpu_f32": pick(Precision::F32, true),
            "gpu_f64": pick(Precision::F64, true),
            "auto_hardware": pick(Precision::F32, false),
        });
        format!("{v}\n")
    } else {
        let mut s = format!("GPU adapters: {}\n", list.len());
        for a in &list {
            s += &format!(
                "  {:<40} {:<7} {:<14} f64 {:<3} {}\n",
                a.name,
                a.backend,
                a.device_type,
                if a.shader_f64 { "yes" } else { "no" },
                a.driver
            );
        }
        s += &format!(
            "  --backend gpu --precision f32: {}\n",
            pick(Precision::F32, true)
        );
        s += &format!(
            "  --backend gpu --precision f64: {}\n",
            pick(Precision::F64, true)
        );
        s += &format!(
            "  --backend auto (hardware only, large batches): {}\n",
            pick(Precision::F32, false)
        );
        s
    };
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .context("writing to stdout")
}

fn check(a: &CheckArgs) -> anyhow::Result<()> {
    if a.gpu {
        check_gpu(a.json)?;
    }
    match &a.model {
        Some(model) => check_model(&ModelArgs {
            model: model.clone(),
            set: a.set.clone(),
            json: a.json,
        }),
        None => Ok(()),
    }
}

fn check_model(args: &ModelArgs) -> anyhow::Result<()> {
    let m = args.load()?;
    let driven = m
        .dofs
        .iter()
        .filter(|d| matches!(d.mode, DofMode::Driven(_)))
        .count();
    let sensors: Vec<&str> = m.sensors.iter().map(|s| s.name.as_str()).collect();
    let text = if args.json {
        let v = serde_json::json!({
            "model": m.name,
            "nodes": m.x0.len(),
            "elements": m.elements.len(),
            "bodies": m.bodies.len(),
            "hinges": m.hinges.len(),
            "dofs": m.dofs.len(),
            "free_dofs": m.n_eq,
            "sensors": sensors,
        });
        let mut v = v;
        if !m.repeats.is_empty() {
            // only for files with repeats: the output of every other file is unchanged
            v["beams"] = serde_json::json!(m.beams.len());
            v["repeats"] = serde_json::json!(m
                .repeats
                .iter()
                .map(|r| {
                    let mut o = serde_json::json!({
                        "path": r.path,
                        "index": r.index,
                        "from": r.from,
                        "to": r.to,
                        "iterations": r.iterations,
                    });
                    for (k, n) in latdyn::model::repeat::KINDS.iter().zip(r.counts) {
                        o[*k] = serde_json::json!(n);
                    }
                    o
                })
                .collect::<Vec<_>>());
        }
        format!("{v}\n")
    } else {
        let mut s = format!("model {} ({})\n", m.name, m.path);
        s += &format!("  nodes     {}\n", m.x0.len());
        s += &format!(
            "  elements  {} in {} beams\n",
            m.elements.len(),
            m.beams.len()
        );
        s += &format!("  bodies    {}\n", m.bodies.len());
        s += &format!("  hinges    {}\n", m.hinges.len());
        s += &format!(
            "  dofs      {} ({} free, {} driven)\n",
            m.dofs.len(),
            m.n_eq,
            driven
        );
        s += &format!("  loads     {}\n", m.loads.len());
        s += &format!("  sensors   {} [{}]\n", sensors.len(), sensors.join(", "));
        for r in &m.repeats {
            let made: Vec<String> = latdyn::model::repeat::KINDS
                .iter()
                .zip(r.counts)
                .filter(|(_, n)| *n > 0)
                .map(|(k, n)| format!("{n} {k}"))
                .collect();
            s += &format!(
                "  repeat    {} {} = {}..{}: {} iterations, generated {}\n",
                r.path,
                r.index,
                r.from,
                r.to,
                r.iterations,
                if made.is_empty() {
                    "nothing of its own".to_string()
                } else {
                    made.join(", ")
                }
            );
        }
        if !m.params.is_empty() {
            let p: Vec<String> = m.params.iter().map(|(n, v)| format!("{n}={v}")).collect();
            s += &format!("  params    {}\n", p.join(" "));
        }
        s
    };
    // write! rather than println!: a closed pipe must not panic
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .context("writing to stdout")
}

/// An error and its causes joined by `: `, leaving out a cause whose text is already
/// shown: wrappers that print their source (`"cannot write {path}: {source}"`) and
/// context that repeats the message made `{e:#}` print errors two or three times.
fn error_chain(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let s = cause.to_string();
        if s.is_empty() || out.contains(&s) {
            continue;
        }
        if !out.is_empty() {
            out += ": ";
        }
        out += &s;
    }
    out
}

/// `statics --path`: one equilibrium path, JSON / text summary, optional campaign file.
fn statics_path(args: &StaticsArgs) -> anyhow::Result<()> {
    use latdyn::solver::path;
    let m = args.model.load()?;
    let opts = args.path.options(&m)?;
    path::check_output_size(&m, opts.max_points, 1).map_err(|e| anyhow!("{}: {e}", m.path))?;
    let target = args.output.as_deref().map(claim_output).transpose()?;
    let t0 = std::time::Instant::now();
    let r = path::follow(&m, &opts);
    let wall = t0.elapsed().as_secs_f64();
    let mut out_err = None;
    if let Some(t) = target {
        let meta = path::campaign_meta(
            &[&m],
            r.lambda.clone(),
            std::env::args().collect::<Vec<_>>().join(" "),
            1,
        );
        let written = latdyn::output::CampaignWriter::create_at(t, &meta).and_then(|mut w| {
            path::write_variant(&mut w, 0, &r, wall)?;
            w.finish("complete")
        });
        out_err = written.err();
    }
    if args.model.json {
        emit(&format!("{}\n", path::to_json(&m, &r, wall)))?;
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
        None => Ok(()),
    }
}

/// `sweep --path`: a path per variant, in parallel; JSON per variant, optional campaign
/// file with the point index as time and λ in `path_lambda`.
fn sweep_path(args: &SweepArgs) -> anyhow::Result<()> {
    use latdyn::solver::path;
    if args.accuracy.is_some() || args.frequency.is_some() || args.verify.is_some() {
        bail!("sweep --path: --accuracy, --frequency and --verify apply to dynamic runs only");
    }
    let variants = latdyn::ensemble::variants(
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
    for &gi in &chosen {
        let mut sets = args.model.set.clone();
        sets.extend(variants[gi].iter().cloned());
        let m = model::load(&args.model.model, &sets)?;
        opts.push(args.path.options(&m)?);
        models.push(m);
    }
    let target = args.output.as_deref().map(claim_output).transpose()?;
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let threads = args.threads.unwrap_or(cores);
    let t0 = std::time::Instant::now();
    let results = path::follow_all(&models, &opts, threads);
    let wall = t0.elapsed().as_secs_f64();
    let failed = results.iter().filter(|(r, _)| r.error.is_some()).count();
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
            std::env::args().collect::<Vec<_>>().join(" "),
            threads,
        );
        meta.global_index = chosen.clone();
        let written = latdyn::output::CampaignWriter::create_at(t, &meta).and_then(|mut w| {
            for (v, (r, ws)) in results.iter().enumerate() {
                path::write_variant(&mut w, v, r, *ws)?;
            }
            w.finish("complete")
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
            "threads": threads,
            "wall_s": wall,
        });
        emit(&format!("{v}\n"))?;
    } else {
        eprintln!(
            "sweep --path {}: {} variants ({} failed) on {} threads in {:.3} s",
            args.model.model.display(),
            results.len(),
            failed,
            threads,
            wall
        );
    }
    if let Some(e) = out_err {
        return Err(fail(EXIT_OUTPUT, e.to_string()));
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
