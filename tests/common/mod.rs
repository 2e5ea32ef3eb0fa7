//! Shared helpers for the integration tests: models built from the shipped files or from a
//! small straight-beam template, and sensor access by name.
#![allow(dead_code)]

use latdyn::model::{compile_str, load, Model};
use std::path::Path;

/// The shipped model files (models/*.toml), sorted.
pub fn shipped_model_paths() -> Vec<std::path::PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    names.sort();
    names
}

pub fn shipped(name: &str, sets: &[(&str, f64)]) -> Model {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models")
        .join(name);
    let o: Vec<(String, f64)> = sets.iter().map(|(k, v)| (k.to_string(), *v)).collect();
    load(&path, &o).unwrap_or_else(|e| panic!("{e}"))
}

/// Straight beam along +x, length L, from `root` to `tip`, with `support` at the root,
/// a dead tip force and moment, and sensors `tip` (node) and `tipx` (position).
/// `extra` is the body of the `[solver]` table.
pub fn straight_beam(
    support: &str,
    elements: usize,
    props: &str,
    force: [f64; 3],
    moment: [f64; 3],
    extra: &str,
) -> Model {
    let text = format!(
        r#"
[parameters]
L = 1.0
elements = {elements}

[sections.s]
{props}

[[nodes]]
name = "root"
position = [0, 0, 0]

[[nodes]]
name = "tip"
position = ["L", 0, 0]

[[beams]]
name = "beam"
from = "root"
to = "tip"
elements = "elements"
section = "s"

[[supports]]
node = "root"
type = "{support}"

[[loads]]
node = "tip"
force = [{}, {}, {}]
moment = [{}, {}, {}]

[[sensors]]
name = "tip"
type = "node"
node = "tip"

[[sensors]]
name = "tipx"
type = "position"
node = "tip"

[solver]
{extra}
"#,
        force[0], force[1], force[2], moment[0], moment[1], moment[2]
    );
    compile_str(&text, "straight_beam.toml", &[]).unwrap_or_else(|e| panic!("{e}"))
}

pub fn sensor<'a>(model: &Model, vals: &'a [Vec<f64>], name: &str) -> &'a [f64] {
    &vals[model.sensor_index(name).expect("sensor")]
}

pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// The `latdyn` binary run from the repository root with `args`.
pub fn latdyn(args: &[&str]) -> std::process::Output {
    latdyn_env(args, &[])
}

/// [`latdyn`] with `env` added to its environment.
pub fn latdyn_env(args: &[&str], env: &[(&str, &str)]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .envs(env.iter().copied())
        .output()
        .expect("run latdyn")
}

/// [`latdyn`] that must succeed (its stderr in the failure message), its stdout parsed
/// as the `--json` result object.
pub fn latdyn_json(args: &[&str]) -> serde_json::Value {
    latdyn_json_env(args, &[])
}

/// [`latdyn_json`] with `env` added to the environment.
pub fn latdyn_json_env(args: &[&str], env: &[(&str, &str)]) -> serde_json::Value {
    let out = latdyn_env(args, env);
    assert!(
        out.status.success(),
        "latdyn {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("--json prints one JSON object")
}

/// Section of the [`straight_beam`] tests: EI = 100 in both planes, GJ = 80, EA = 1e7,
/// ρA = 1 (a 1 m beam's end moment of 100 N·m bends it by 1 rad).
pub const BEAM_PROPS: &str = r#"EA = 1.0e7
EIy = 100.0
EIz = 100.0
GJ = 80.0
rhoA = 1.0"#;

pub fn h5py_available() -> bool {
    let ok = std::process::Command::new("python3")
        .args(["-c", "import h5py"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !ok && std::env::var_os("CI").is_some() {
        panic!("h5py is not installed, but CI is set: .ci/run must install h5py");
    }
    ok
}

/// `python3 SCRIPT ARGS` (SCRIPT relative to the crate root), which must succeed; its
/// stdout parsed as JSON.
pub fn python_json(script: &str, args: &[&str]) -> serde_json::Value {
    let out = std::process::Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join(script))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{script} {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

/// `a` and `b` hold the same campaign, bit for bit (tests/compare_campaigns.py); false
/// (with a SKIPPED line) only where h5py is missing outside CI.
pub fn assert_same_campaign(a: &Path, b: &Path) {
    if !h5py_available() {
        println!("SKIPPED (comparison): h5py not installed");
        return;
    }
    let out = std::process::Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/compare_campaigns.py"))
        .arg(a)
        .arg(b)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.trim_end() == "OK",
        "{} and {} differ:\n{text}{}",
        a.display(),
        b.display(),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Variants a campaign file marks completed (0 while the file does not exist or cannot be
/// read yet, e.g. between a writer's flushes).
pub fn completed_variants(path: &Path) -> usize {
    if !path.exists() {
        return 0;
    }
    rust_hdf5::H5File::open(path)
        .ok()
        .and_then(|f| f.dataset("status/state").ok())
        .and_then(|d| d.read_raw::<i32>().ok())
        .map_or(0, |st| st.iter().filter(|&&x| x == 2).count())
}

/// Poll until `cond` holds (at most `secs`).
pub fn wait_until(secs: u64, what: &str, mut cond: impl FnMut() -> bool) {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(secs);
    while !cond() {
        assert!(
            std::time::Instant::now() < deadline,
            "timed out waiting for {what}"
        );
        std::thread::sleep(std::time::Duration::from_millis(25));
    }
}
