//! Long fuzz campaign (issue 15):
//!
//! ```text
//! cargo build --release          # the CLI cases run target/release/latdyn
//! cargo run --release --example fuzz -- --cases 1000000 --seed 1 --out fuzz-out
//! ```
//!
//! Options: `--cases N` (default 1 000 000), `--seed S` (default 1), `--out DIR` (finding
//! inputs, one per distinct cause; default `fuzz-out`), `--seconds T` (stop earlier),
//! `--cli-every K` (one case in K runs the binary, a process each; default 100; 0 = none), `--bin PATH`
//! (default: `latdyn` beside the examples directory), `--case FILE` (run one saved input
//! and print its outcome), `--no-replay` (skip `tests/fuzz_regressions/`).
//! Prints the rate and the count of every outcome class; exits 1 when anything was found.
//! The generator, mutators and oracle are in `tests/fuzz/gen.rs`, shared with the CI run
//! `tests/fuzz.rs`.

#[path = "../tests/fuzz/gen.rs"]
mod gen;

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    if args.iter().any(|a| a == "--worker") {
        gen::worker_main();
        return ExitCode::SUCCESS;
    }
    let exe = std::env::current_exe().expect("own executable path");
    let mut cases: u64 = 1_000_000;
    let mut seed: u64 = 1;
    let mut out = PathBuf::from("fuzz-out");
    let mut seconds: Option<f64> = None;
    let mut cli_every: u64 = 100;
    let mut bin: Option<PathBuf> = exe
        .parent()
        .and_then(|p| p.parent())
        .map(|p| p.join("latdyn"));
    let mut one_case: Option<PathBuf> = None;
    let mut replay = true;
    let mut it = args.iter().skip(1);
    while let Some(a) = it.next() {
        let mut val = |name: &str| -> String {
            match it.next() {
                Some(v) => v.clone(),
                None => {
                    eprintln!("error: {name} needs a value");
                    std::process::exit(2)
                }
            }
        };
        let num = |s: String, name: &str| -> u64 {
            s.parse().unwrap_or_else(|_| {
                eprintln!("error: {name}: expected a non-negative integer, got `{s}`");
                std::process::exit(2)
            })
        };
        match a.as_str() {
            "--cases" => cases = num(val("--cases"), "--cases"),
            "--seed" => seed = num(val("--seed"), "--seed"),
            "--out" => out = PathBuf::from(val("--out")),
            "--seconds" => seconds = Some(num(val("--seconds"), "--seconds") as f64),
            "--cli-every" => cli_every = num(val("--cli-every"), "--cli-every"),
            "--bin" => bin = Some(PathBuf::from(val("--bin"))),
            "--case" => one_case = Some(PathBuf::from(val("--case"))),
            "--no-replay" => replay = false,
            other => {
                eprintln!("error: unknown option `{other}` (see the header of examples/fuzz.rs)");
                return ExitCode::from(2);
            }
        }
    }
    if cli_every == 0 {
        bin = None;
    }
    if let Some(b) = &bin {
        if !b.is_file() {
            eprintln!(
                "error: CLI cases need the latdyn binary at {} (cargo build --release, or --bin PATH, or --cli-every 0)",
                b.display()
            );
            return ExitCode::from(2);
        }
    }
    let mut replay_cases = Vec::new();
    let load = |dir: &std::path::Path| {
        gen::load_cases(dir).unwrap_or_else(|e| {
            eprintln!("error: {e}");
            std::process::exit(2)
        })
    };
    if let Some(p) = &one_case {
        let text = std::fs::read_to_string(p).unwrap_or_default();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap_or_default();
        match gen::Case::from_json(&v) {
            Ok(c) => replay_cases.push(c),
            Err(e) => {
                eprintln!("error: {}: {e}", p.display());
                return ExitCode::from(2);
            }
        }
        cases = 0;
    } else if replay {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
        replay_cases = load(&dir).into_iter().map(|(_, c)| c).collect();
    }
    let cfg = gen::Config {
        seed,
        cases,
        duration: seconds.map(Duration::from_secs_f64),
        cli_every,
        bin,
        worker_cmd: vec![exe.display().to_string(), "--worker".into()],
        worker_env: Vec::new(),
        out,
        hang_limit: gen::HANG_LIMIT,
        progress: true,
    };
    eprintln!(
        "fuzz: seed {seed}, {cases} cases after {} regression inputs, one in {cli_every} a CLI case",
        replay_cases.len()
    );
    match gen::campaign(&cfg, &replay_cases) {
        Ok(rep) => {
            println!("{}", rep.summary());
            if rep.findings.is_empty() {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(1)
            }
        }
        Err(e) => {
            eprintln!("error: cannot start the fuzz worker: {e}");
            ExitCode::from(2)
        }
    }
}
