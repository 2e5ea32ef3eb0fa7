//! The command line as clap parses it: one `Args` struct per verb, and the value parsers
//! that check a flag's value before any work.

use std::path::PathBuf;

use anyhow::anyhow;
use clap::{Args, Parser, Subcommand};
use latdyn::model::{self, Model};

#[derive(Parser)]
#[command(
    name = "latdyn",
    version,
    about = "Large-angle transient dynamics of flexible multibody systems"
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub(crate) verb: Verb,
}

#[derive(Subcommand)]
pub(crate) enum Verb {
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
pub(crate) struct MergeArgs {
    /// shard files of one campaign (`sweep --shard K/N -o ...`), in any order
    #[arg(required = true, value_name = "SHARD.h5")]
    pub(crate) shards: Vec<PathBuf>,
    /// the merged campaign file (HDF5)
    #[arg(short, long, value_name = "PATH")]
    pub(crate) output: PathBuf,
    /// print the report object as JSON on stdout
    #[arg(long)]
    pub(crate) json: bool,
}

#[derive(Args)]
pub(crate) struct BenchArgs {
    /// shorter ladders and at most 100 ensemble variants (a few minutes)
    #[arg(long)]
    pub(crate) quick: bool,
    /// run only these problems (repeatable): rotating_cantilever, rollup, bend45, spinup,
    /// minimast, time_error, accuracy (not in a bare `bench`: ~35 min), ensemble
    #[arg(long = "only", value_name = "PROBLEM")]
    pub(crate) only: Vec<String>,
    /// `--accuracy` targets of problem `accuracy` (repeatable; default 1e-2): each scene's
    /// `--accuracy` run and its cheapest fixed step meeting the target, per target
    #[arg(long = "target", value_name = "TOL", value_parser = parse_accuracy)]
    pub(crate) targets: Vec<f64>,
    /// scenes of problems `time_error` and `accuracy` (repeatable; default all)
    #[arg(long = "scene", value_name = "SCENE",
          value_parser = clap::builder::PossibleValuesParser::new(crate::bench::TIME_ERROR_SCENES))]
    pub(crate) scenes: Vec<String>,
    /// directory of the shipped models
    #[arg(long, default_value = "models")]
    pub(crate) models: PathBuf,
    /// where results.md, results.json and work_precision.png go
    #[arg(long, default_value = "docs/bench")]
    pub(crate) out: PathBuf,
    /// threads for the ensemble rows (default: all cores; at most 4 per core or 256)
    #[arg(long, value_parser = latdyn::model::limits::parse_threads)]
    pub(crate) threads: Option<usize>,
    /// print the report object as JSON on stdout
    #[arg(long)]
    pub(crate) json: bool,
}

#[derive(Args)]
pub(crate) struct ModelArgs {
    /// model file (TOML)
    pub(crate) model: PathBuf,
    /// override a parameter: --set NAME=VALUE (repeatable; VALUE may be `2*pi`)
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = model::parse_set)]
    pub(crate) set: Vec<(String, f64)>,
    /// machine-readable output (JSON on stdout)
    #[arg(long)]
    pub(crate) json: bool,
}

impl ModelArgs {
    pub(crate) fn load(&self) -> anyhow::Result<Model> {
        Ok(model::load(&self.model, &self.set)?)
    }
}

#[derive(Args)]
pub(crate) struct StaticsArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    #[command(flatten)]
    pub(crate) path: PathArgs,
    /// with --path: the path in the campaign layout (HDF5), the path parameter as time
    #[arg(short, long, value_name = "PATH")]
    pub(crate) output: Option<PathBuf>,
}

/// Path following options of `statics --path` and `sweep --path` (README "Path following").
#[derive(Args, Clone)]
pub(crate) struct PathArgs {
    /// follow the equilibrium path by arc-length continuation through limit points and
    /// snap-backs, instead of one equilibrium
    #[arg(long)]
    pub(crate) path: bool,
    /// what the path parameter λ scales: `load` (the model's loads × λ), `drivers` (drive
    /// expressions at pseudo-time λ, loads at full value), `auto` (drivers when a drive
    /// changes over [0, t_end], else load)
    #[arg(long, default_value = "auto", value_parser = ["auto", "load", "drivers"])]
    pub(crate) control: String,
    /// end the path where λ reaches this value (default: 1 for load control without
    /// --until, t_end for drivers, else no bound)
    #[arg(long, value_name = "LAMBDA", value_parser = parse_positive)]
    pub(crate) lambda_max: Option<f64>,
    /// end the path where a sensor component crosses a value, e.g. load_point.y=-80
    #[arg(long, value_name = "SENSOR.COMPONENT=VALUE")]
    pub(crate) until: Option<String>,
    /// end the path at its K-th limit point (at the first point past it)
    #[arg(long, value_name = "K", value_parser = parse_limit_count)]
    pub(crate) limit_points: Option<usize>,
    /// end the path after this arc length (scaled (u, ψλ) norm, see README)
    #[arg(long, value_name = "S", value_parser = parse_positive)]
    pub(crate) max_length: Option<f64>,
    /// most path points (1 to 100000)
    #[arg(long, default_value_t = 2000, value_parser = parse_max_points)]
    pub(crate) max_points: usize,
    /// first increment of λ (default: λ_max/50, at most 0.02 for load control and
    /// t_end/50 for drivers); later increments follow from the arc length, adapted to the
    /// Newton iteration counts
    #[arg(long, value_name = "DLAMBDA", value_parser = parse_positive)]
    pub(crate) first_step: Option<f64>,
}

pub(crate) fn parse_positive(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a finite positive number")),
    }
}

pub(crate) fn parse_limit_count(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(v) if (1..=1000).contains(&v) => Ok(v),
        _ => Err(format!("`{s}` is not a count from 1 to 1000")),
    }
}

pub(crate) fn parse_max_points(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(v) if (1..=100_000).contains(&v) => Ok(v),
        _ => Err(format!("`{s}` is not a point count from 1 to 100000")),
    }
}

impl PathArgs {
    /// Whether any path option was given (they need --path).
    pub(crate) fn any_option(&self) -> bool {
        self.control != "auto"
            || self.lambda_max.is_some()
            || self.until.is_some()
            || self.limit_points.is_some()
            || self.max_length.is_some()
            || self.max_points != 2000
            || self.first_step.is_some()
    }

    pub(crate) fn options(&self, m: &Model) -> anyhow::Result<latdyn::solver::path::PathOptions> {
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
        // the first step: 2 % of λ_max, but at most 2 % of the load factor's scale (the
        // loads as written) or of the drivers' stroke (t_end): see `with_scale`
        let scale = match control {
            Control::Load => 1.0,
            Control::Drivers => m.solver.t_end,
        };
        let mut o = PathOptions::with_scale(control, max_param, scale);
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
pub(crate) struct CheckArgs {
    /// model file (TOML); optional with --gpu
    #[arg(required_unless_present = "gpu")]
    pub(crate) model: Option<PathBuf>,
    /// override a parameter: --set NAME=VALUE (repeatable; VALUE may be `2*pi`)
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = model::parse_set)]
    pub(crate) set: Vec<(String, f64)>,
    /// machine-readable output (JSON on stdout)
    #[arg(long)]
    pub(crate) json: bool,
    /// list the GPU adapters found (backend, device type, f64 support) and which one
    /// each --backend choice would use
    #[arg(long)]
    pub(crate) gpu: bool,
}

/// `--backend` and `--precision` of `run` and `sweep`.
#[derive(Args, Clone)]
pub(crate) struct BackendArgs {
    /// element evaluation: `cpu` (f64 reference), `gpu` (WGSL kernels on any adapter,
    /// software ones included), `auto` (a hardware GPU when present and the batch is
    /// large enough, else cpu)
    #[arg(long, default_value = "auto", value_parser = ["auto", "cpu", "gpu"])]
    pub(crate) backend: String,
    /// scalar of the GPU kernels; f64 needs an adapter with SHADER_F64 (the CPU is f64).
    /// With f32, Newton stops at the kernels' round-off when `[solver] tol` is below it
    /// (16 u of the force scale, or where the residual stops decreasing within 1024 u)
    #[arg(long, default_value = "f64", value_parser = ["f64", "f32"])]
    pub(crate) precision: String,
}

#[derive(Args)]
pub(crate) struct ModesArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// number of modes to report (1 to 100000; default 10, or all the model has if fewer)
    #[arg(long = "count", value_name = "COUNT", value_parser = parse_mode_count)]
    pub(crate) count_arg: Option<usize>,
    /// linearise about `static` equilibrium under the loads, or the `reference`
    /// configuration; `auto` = static when the model has loads or gravity
    #[arg(long, default_value = "auto", value_parser = ["auto", "static", "reference"])]
    pub(crate) about: String,
    /// include mode shapes (by node: displacement and rotation) in the JSON output
    #[arg(long)]
    pub(crate) shapes: bool,
    /// rotating models: modes at each value NAME=START:STOP:COUNT (e.g. omega=1:9:33),
    /// followed across the values by their shapes (MAC), so crossing branches keep
    /// their identity
    #[arg(long, value_name = "NAME=START:STOP:COUNT", value_parser = latdyn::ensemble::Range::parse)]
    pub(crate) vary: Option<latdyn::ensemble::Range>,
    /// measure each frequency's mesh error by solving again with every beam's elements
    /// doubled: `auto` where the refined model has at most 1 500 free coordinates (900 in
    /// the rotating frame), `always`, or `never`
    #[arg(long, default_value = "auto", value_parser = ["auto", "always", "never"])]
    pub(crate) mesh_check: String,
}

impl ModesArgs {
    /// The modes to report: `--count`, else 10. Only an explicit `--count` above what the
    /// model has is warned; the default simply reports them all (the pendulum's one mode
    /// was reported with the warning "--count 10: the model has only 1 modes", a count
    /// nobody asked for).
    pub(crate) fn count(&self) -> usize {
        self.count_arg.unwrap_or(10)
    }
}

#[derive(Args)]
pub(crate) struct SweepArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    #[command(flatten)]
    pub(crate) path: PathArgs,
    /// vary a parameter: NAME=START:STOP:COUNT (repeatable; several make a full grid)
    #[arg(long = "vary", value_name = "NAME=START:STOP:COUNT", value_parser = latdyn::ensemble::Range::parse)]
    pub(crate) vary: Vec<latdyn::ensemble::Range>,
    /// explicit variants: CSV with a header of parameter names, one row per variant
    #[arg(long, value_name = "CSV")]
    pub(crate) variants: Option<PathBuf>,
    /// campaign file (HDF5)
    #[arg(short, long, value_name = "PATH")]
    pub(crate) output: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) backend: BackendArgs,
    /// worker threads (default: all cores); from 1 to 4 per core or 256, whichever is more
    #[arg(long, value_parser = latdyn::model::limits::parse_threads)]
    pub(crate) threads: Option<usize>,
    /// variants per batch: a batch's variants advance in lockstep on one thread and their
    /// Newton iterations' element stages are evaluated together, one call per round
    /// (default: 8 on the CPU; with a GPU backend 1024, one dispatch per kernel for the
    /// whole batch; never more than the variants per thread). Results do not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub(crate) batch: Option<u32>,
    /// run only the K-th of N interleaved subsets of the variants: K/N
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    pub(crate) shard: Option<(usize, usize)>,
    /// global error control: fixed-step runs at smaller steps until the estimated time
    /// error is at most TOL of each sensor's range (overrides `[solver] accuracy`; `dt`
    /// is the first run's step, `dt_max` the largest, `dt_min` the smallest)
    #[arg(long, value_name = "TOL", value_parser = parse_accuracy)]
    pub(crate) accuracy: Option<f64>,
    /// sensor (SENSOR or SENSOR.COMPONENT) whose dominant frequency is reported as
    /// derived.first_bending_hz
    #[arg(long, value_name = "SENSOR[.COMPONENT]")]
    pub(crate) frequency: Option<String>,
    /// after the campaign, rerun K of its variants (spread over it) with dt halved and
    /// twice the elements, and report how much every sensor's extremes change: the
    /// campaign's measured discretisation error (README "Verification"); with --shard,
    /// only shard 1 verifies
    #[arg(long, value_name = "K")]
    pub(crate) verify: Option<usize>,
    /// complete this campaign file in place: run only its variants that are not
    /// completed (missing, failed, interrupted); refused when the campaign definition
    /// (model, --vary/--variants, --set, --accuracy, --frequency, backend, precision,
    /// latdyn version) differs from the file's
    #[arg(long, value_name = "CAMPAIGN.h5", conflicts_with_all = ["output", "shard", "verify"])]
    pub(crate) resume: Option<PathBuf>,
    /// print the campaign's plan instead of running it: the variant table, the shard of
    /// each variant for --shards N, and the cost per variant from a short probe run
    #[arg(long, conflicts_with_all = ["output", "shard", "verify", "resume"])]
    pub(crate) plan: bool,
    /// measure the mesh error of sampled variants by running each again with every
    /// beam's elements doubled at its step: `auto` (default) 3 variants spread over the
    /// campaign (first, middle, last) where the doubled model has at most 20 000 free
    /// coordinates, `always` every variant at any size, `never` none
    #[arg(long, value_parser = ["auto", "always", "never"])]
    pub(crate) mesh_check: Option<String>,
    /// with --plan: the number of shards (array tasks) to plan for
    #[arg(long, value_name = "N", default_value_t = 1, requires = "plan", value_parser = parse_shards)]
    pub(crate) shards: usize,
    /// with --plan: variants probed (spread over the table, each run for 10 % of its
    /// t_end on one thread); 0 = no probe
    #[arg(long, value_name = "K", default_value_t = 3, requires = "plan")]
    pub(crate) probe: usize,
}

/// `--shards N`: at least one, at most the variant limit.
pub(crate) fn parse_shards(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if (1..=1_000_000).contains(&n) => Ok(n),
        _ => Err(format!(
            "`{s}`: need a whole number of shards from 1 to 1000000"
        )),
    }
}

/// `--count`: at least one mode, and bounded so that `count + spares` cannot overflow.
pub(crate) fn parse_mode_count(s: &str) -> Result<usize, String> {
    const MAX: usize = 100_000;
    match s.trim().parse::<usize>() {
        Ok(n) if (1..=MAX).contains(&n) => Ok(n),
        _ => Err(format!(
            "`{s}`: need a whole number of modes from 1 to {MAX}"
        )),
    }
}

/// `--accuracy`: a relative error target in (0, MAX_ACCURACY].
pub(crate) fn parse_accuracy(s: &str) -> Result<f64, String> {
    let max = latdyn::model::compile::MAX_ACCURACY;
    match s.trim().parse::<f64>() {
        Ok(a) if a > 0.0 && a <= max => Ok(a),
        _ => Err(format!(
            "`{s}`: need a relative error target greater than 0 and at most {max}"
        )),
    }
}

pub(crate) fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let (k, n) = s.split_once('/').ok_or("expected K/N")?;
    let k: usize = k.trim().parse().map_err(|_| "K must be an integer")?;
    let n: usize = n.trim().parse().map_err(|_| "N must be an integer")?;
    if n == 0 || k == 0 || k > n {
        return Err(format!("{s}: need 1 ≤ K ≤ N"));
    }
    Ok((k, n))
}

#[derive(Args)]
pub(crate) struct RunArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// output file
    #[arg(short, long, value_name = "PATH")]
    pub(crate) output: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) backend: BackendArgs,
    /// global error control: fixed-step runs at smaller steps until the estimated time
    /// error is at most TOL of each sensor's range (overrides `[solver] accuracy`; `dt`
    /// is the first run's step, `dt_max` the largest, `dt_min` the smallest)
    #[arg(long, value_name = "TOL", value_parser = parse_accuracy)]
    pub(crate) accuracy: Option<f64>,
    /// measure the run's mesh error by running it again with every beam's elements
    /// doubled at the same step (about twice the run's cost again): `auto` where the
    /// doubled model has at most 20 000 free coordinates, `always`, or `never`
    #[arg(long, default_value = "auto", value_parser = ["auto", "always", "never"])]
    pub(crate) mesh_check: String,
}

/// `latdyn plot FILE.h5 (--sensor S... | --x S --y S | --campbell P --derived D) -o OUT`
#[derive(Args)]
#[command(group(clap::ArgGroup::new("kind").required(true).args(["sensor", "x", "campbell"])))]
pub(crate) struct PlotArgs {
    /// results file (HDF5) written by `run` or `sweep`
    pub(crate) input: PathBuf,
    /// image file to write; the format follows the extension: .svg or .png
    #[arg(short, long, value_name = "OUT.svg|png")]
    pub(crate) output: PathBuf,
    /// time histories of a sensor, one line per variant; all its components unless one
    /// is named (repeatable)
    #[arg(long, value_name = "NAME[.COMPONENT]")]
    pub(crate) sensor: Vec<String>,
    /// cross plot: this sensor component on the x axis (with --y)
    #[arg(long, value_name = "NAME[.COMPONENT]", requires = "y")]
    pub(crate) x: Option<String>,
    /// cross plot: this sensor component on the y axis (with --x)
    #[arg(long, value_name = "NAME[.COMPONENT]", requires = "x")]
    pub(crate) y: Option<String>,
    /// Campbell diagram against this parameter (rotor speed, rad/s); needs --derived
    #[arg(long, value_name = "PARAM", requires = "derived")]
    pub(crate) campbell: Option<String>,
    /// Campbell diagram: the frequency (Hz) of each variant, /derived/NAME
    #[arg(long, value_name = "NAME", requires = "campbell")]
    pub(crate) derived: Option<String>,
    /// Campbell diagram: frequency axis in rad/s (2π·f) or Hz
    #[arg(long, default_value = "rad", value_parser = ["rad", "hz"], requires = "campbell")]
    pub(crate) units: String,
    /// Campbell diagram: Southwell curve sqrt(W0² + K·Ω²), W0 in the axis units
    #[arg(
        long,
        value_name = "W0,K",
        requires = "campbell",
        allow_hyphen_values = true,
        value_parser = crate::plot::parse_pair
    )]
    pub(crate) southwell: Option<(f64, f64)>,
    /// Campbell diagram: eigenvalue branches from `latdyn modes MODEL --vary omega=A:B:N
    /// --json > FILE.json`, drawn beside the data
    #[arg(long, value_name = "FILE.json", requires = "campbell")]
    pub(crate) modes: Option<PathBuf>,
    /// Campbell diagram: rotor harmonics n·Ω drawn, n = 1..N (N at most 100)
    #[arg(long, value_name = "N", default_value_t = 6, requires = "campbell", value_parser = parse_harmonics)]
    pub(crate) harmonics: usize,
    /// variants (row indices) to plot, e.g. 0,3,5; default all (at most 20 lines)
    #[arg(long, value_name = "I,J,...", value_delimiter = ',')]
    pub(crate) variants: Vec<usize>,
    /// chart title (default: the model path stored in the file)
    #[arg(long)]
    pub(crate) title: Option<String>,
    /// image size in pixels
    #[arg(long, value_name = "WxH", default_value = "1000x640", value_parser = crate::plot::parse_size)]
    pub(crate) size: (u32, u32),
    /// machine-readable output on stdout (Campbell: the crossings)
    #[arg(long)]
    pub(crate) json: bool,
}

/// Rotor harmonics of a Campbell diagram: 1 to `MAX_HARMONICS`. Each is a line and a
/// search for crossings; 1e9 of them asked for 56 GB and aborted.
fn parse_harmonics(v: &str) -> Result<usize, String> {
    const MAX_HARMONICS: usize = 100;
    match v.trim().parse::<usize>() {
        Ok(n) if (1..=MAX_HARMONICS).contains(&n) => Ok(n),
        _ => Err(format!(
            "must be a whole number from 1 to {MAX_HARMONICS} (harmonics drawn), is `{v}`"
        )),
    }
}
