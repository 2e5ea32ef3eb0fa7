//! The `latdyn` command line: one verb per analysis, all reading a model file.
//!
//! Every failure is reported as `error: <message>` on stderr with exit code 2 (clap's
//! own usage errors use 2 as well), so scripts can tell model or usage errors from
//! success.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{anyhow, Context};
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
    /// Load and compile a model and print a summary
    Check(ModelArgs),
    /// Static equilibrium under the model's loads
    Statics(ModelArgs),
    /// Natural frequencies and mode shapes about the initial configuration
    Modes(ModelArgs),
    /// Time integration from 0 to t_end
    Run(RunArgs),
    /// Runs over a range of parameter values
    Sweep(RunArgs),
    /// Plot sensor histories of a results file
    Plot(PlotArgs),
    /// Time the stages of a run
    Bench(ModelArgs),
}

impl Verb {
    fn name(&self) -> &'static str {
        match self {
            Verb::Check(_) => "check",
            Verb::Statics(_) => "statics",
            Verb::Modes(_) => "modes",
            Verb::Run(_) => "run",
            Verb::Sweep(_) => "sweep",
            Verb::Plot(_) => "plot",
            Verb::Bench(_) => "bench",
        }
    }
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
struct RunArgs {
    #[command(flatten)]
    model: ModelArgs,
    /// output file
    #[arg(short, long, value_name = "PATH")]
    output: Option<PathBuf>,
}

#[derive(Args)]
struct PlotArgs {
    /// results file written by `run` or `sweep`
    input: PathBuf,
    /// image file to write
    #[arg(short, long, value_name = "PATH")]
    output: Option<PathBuf>,
    #[arg(long)]
    json: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.verb {
        Verb::Check(a) => check(a),
        other => run_verb(other),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

/// The analysis verbs; not part of this build yet.
fn run_verb(verb: &Verb) -> anyhow::Result<()> {
    // a broken model is worth reporting even where the verb itself is missing
    match verb {
        Verb::Statics(a) | Verb::Modes(a) | Verb::Bench(a) => {
            a.load()?;
        }
        Verb::Run(a) | Verb::Sweep(a) => {
            a.model.load()?;
        }
        Verb::Check(_) | Verb::Plot(_) => {}
    }
    Err(anyhow!("verb {}: not available in this build", verb.name()))
}

fn check(args: &ModelArgs) -> anyhow::Result<()> {
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
