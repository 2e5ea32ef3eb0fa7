//! The `latdyn` command line: one verb per analysis, all reading a model file.
//!
//! Every failure is reported once as `error: <message>` on stderr, with an exit code a
//! script can trust (README "Exit codes"): 0 success; 2 model, input or usage error
//! (clap's usage errors use 2 as well), an output path refused before the run included;
//! 3 finished, but the run or some variant failed; 4 interrupted (SIGINT, SIGTERM,
//! SIGHUP), the output file left valid and marked interrupted (a sweep stopped while
//! compiling its variants writes nothing and leaves the path as it was); 5 the output could not be
//! written mid-run (the last valid flush is kept); 70 internal error (a panic: a bug).

mod backend;
mod bench;
mod charts;
mod check;
mod cli;
mod modes;
mod plot;
mod run;
mod statics;
mod sweep;

use std::io::Write;
use std::process::ExitCode;

use anyhow::{anyhow, Context};
use clap::Parser;

use crate::cli::{Cli, Verb};

/// Exit codes (README "Exit codes").
pub(crate) const EXIT_USAGE: u8 = 2;
pub(crate) const EXIT_FAILED: u8 = 3;
pub(crate) const EXIT_INTERRUPTED: u8 = 4;
pub(crate) const EXIT_OUTPUT: u8 = 5;
pub(crate) const EXIT_INTERNAL: u8 = 70;

/// An error with an exit code other than [`EXIT_USAGE`]; an empty message was already
/// reported (the panic hook prints its own line).
#[derive(Debug)]
pub(crate) struct Fail {
    pub(crate) code: u8,
    pub(crate) message: String,
}

impl std::fmt::Display for Fail {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Fail {}

pub(crate) fn fail(code: u8, message: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(Fail {
        code,
        message: message.into(),
    })
}

/// The text of a panic payload (`panic!` gives a `&str` or a `String`).
pub(crate) fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// One clean line per panic instead of Rust's dump; `RUST_BACKTRACE=1` adds the trace.
pub(crate) fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let msg = panic_text(info.payload());
        let at = info
            .location()
            .map(|l| format!(" at {}:{}:{}", l.file(), l.line(), l.column()))
            .unwrap_or_default();
        // the same panic on several worker threads is one error (a sweep's workers
        // printed it twice; a probe, session 47)
        static SEEN: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
        let line = format!("{msg}{at}");
        if let Ok(mut seen) = SEEN.lock() {
            if seen.contains(&line) {
                return;
            }
            seen.push(line);
        }
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
    if let Some(missing) = missing_cpu_feature() {
        let _ = writeln!(
            std::io::stderr(),
            "error: this latdyn was built for x86-64-v3 (.cargo/config.toml) and this CPU lacks \
             {missing}; rebuild with RUSTFLAGS=\"-C target-cpu=x86-64\" (same numbers, slower)"
        );
        return ExitCode::from(EXIT_INTERNAL);
    }
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

/// The first vector feature the build was compiled for that this CPU lacks: such a binary
/// would otherwise die of SIGILL somewhere in the first element evaluation, without a word.
/// Checked first thing in `main`, before any engine code runs.
fn missing_cpu_feature() -> Option<&'static str> {
    #[cfg(target_arch = "x86_64")]
    {
        macro_rules! need {
            ($($f:tt),*) => {$(
                if cfg!(target_feature = $f) && !std::is_x86_feature_detected!($f) {
                    return Some($f);
                }
            )*};
        }
        need!("avx", "avx2", "fma", "bmi1", "bmi2", "lzcnt", "f16c", "movbe");
    }
    None
}

/// Fault injection for tests/output_faults.rs: `LATDYN_FAULT_PANIC=main` panics before
/// the verb runs, `=worker` in a sweep's worker thread after its first variant, so the
/// tests see a real panic cross each boundary. Unset, nothing happens.
pub(crate) fn injected_panic(site: &str) -> bool {
    std::env::var_os("LATDYN_FAULT_PANIC").is_some_and(|v| v == site)
}

pub(crate) fn dispatch(cli: &Cli) -> anyhow::Result<()> {
    let sets = match &cli.verb {
        Verb::Check(a) => &a.set[..],
        Verb::Statics(a) => &a.model.set[..],
        Verb::Modes(a) => &a.model.set[..],
        Verb::Run(a) => &a.model.set[..],
        Verb::Sweep(a) => &a.model.set[..],
        Verb::Merge(_) | Verb::Plot(_) | Verb::Bench(_) => &[][..],
    };
    // the last of two values wins (scripts extend a base command line), and says so
    for (i, (name, v)) in sets.iter().enumerate() {
        if let Some((_, w)) = sets[..i].iter().rev().find(|(n, w)| n == name && w != v) {
            if !sets[i + 1..].iter().any(|(n, _)| n == name) {
                eprintln!("note: --set {name} given more than once: the last, {v}, replaces {w}");
            }
        }
    }
    match &cli.verb {
        Verb::Check(a) => check::check(a),
        Verb::Statics(a) => statics::statics(a),
        Verb::Modes(a) => modes::modes(a),
        Verb::Run(a) => run::run(a),
        Verb::Sweep(a) => sweep::sweep(a),
        Verb::Merge(a) => sweep::merge(a),
        Verb::Plot(a) => charts::plot(a),
        Verb::Bench(a) => charts::bench(a),
    }
}

/// Set on SIGINT, SIGTERM or SIGHUP (what a terminal, a scheduler or a closed session
/// sends): runs and sweeps stop before their next time step and finish their file as
/// interrupted. A handler can be installed once per process; failing to install one
/// (not possible on this platform) leaves the default behaviour.
pub(crate) fn stop_flag() -> std::sync::Arc<std::sync::atomic::AtomicBool> {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    let _ = ctrlc::set_handler(move || s.store(true, Ordering::SeqCst));
    stop
}

/// Claim an output path before any simulation; a refusal is a usage error (exit 2).
/// `inputs` are the files the command reads, each with what it is ("the model file"):
/// an output that is one of them (the same file, by any name or hard link) is refused,
/// as `run m.toml -o m.toml` replaced the model with the results.
pub(crate) fn claim_output(
    path: &std::path::Path,
    inputs: &[(&std::path::Path, &str)],
) -> anyhow::Result<latdyn::output::OutputTarget> {
    for (input, what) in inputs {
        if same_file(path, input) {
            anyhow::bail!(
                "cannot write output {}: it is {what} ({}); write the output elsewhere",
                path.display(),
                input.display()
            );
        }
    }
    latdyn::output::OutputTarget::claim(path).map_err(|e| anyhow!("{e}"))
}

/// [`claim_output`] of an optional `-o`.
pub(crate) fn claim_optional_output(
    path: Option<&std::path::Path>,
    inputs: &[(&std::path::Path, &str)],
) -> anyhow::Result<Option<latdyn::output::OutputTarget>> {
    path.map(|p| claim_output(p, inputs)).transpose()
}

/// Whether two paths name one existing file (same device and inode).
fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

pub(crate) fn is_csv(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
}

/// A campaign file (sweep, merge, path) is HDF5 whatever its name: a `.csv` name, which
/// makes `run -o` write CSV, is said on stderr instead of written over silently.
pub(crate) fn note_campaign_format(path: Option<&std::path::Path>) {
    if let Some(p) = path.filter(|p| is_csv(p)) {
        eprintln!(
            "note: {}: a campaign is written as HDF5 (the campaign layout, README \
             \"Campaign output\") whatever the file's extension; `run -o FILE.csv` writes CSV",
            p.display()
        );
    } else if let Some(p) = path {
        note_hdf5_name(p);
    }
}

/// An output written as HDF5 under a name that does not say so (`-o out.txt`, `-o
/// notes`) gets a note on stderr: a reader going by the name would not expect it.
pub(crate) fn note_hdf5_name(path: &std::path::Path) {
    let hdf5 = path.extension().is_some_and(|e| {
        ["h5", "hdf5", "hdf", "he5", "nc"]
            .iter()
            .any(|x| e.eq_ignore_ascii_case(x))
    });
    if !hdf5 {
        eprintln!(
            "note: {}: written as HDF5 (README \"Campaign output\"), whatever the name says; \
             name it .h5 to say so",
            path.display()
        );
    }
}

/// Write text to stdout; a closed pipe is an error, not a panic.
pub(crate) fn emit(text: &str) -> anyhow::Result<()> {
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .context("writing to stdout")
}

/// An error and its causes joined by `: `, leaving out a cause whose text is already
/// shown: wrappers that print their source (`"cannot write {path}: {source}"`) and
/// context that repeats the message made `{e:#}` print errors two or three times.
pub(crate) fn error_chain(e: &anyhow::Error) -> String {
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
