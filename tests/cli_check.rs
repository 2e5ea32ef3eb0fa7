//! The `latdyn` binary: `check` on every example model, and failures as exit code 2.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn latdyn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run latdyn")
}

fn models() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    assert!(!v.is_empty());
    v
}

#[test]
fn check_accepts_every_example_model() {
    for m in models() {
        let m = m.to_str().unwrap();
        let out = latdyn(&["check", m]);
        assert!(
            out.status.success(),
            "{m}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(String::from_utf8_lossy(&out.stdout).contains("elements"));

        let out = latdyn(&["check", "--json", m]);
        assert!(out.status.success(), "{m}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("stdout is JSON");
        for key in [
            "model",
            "nodes",
            "elements",
            "bodies",
            "hinges",
            "dofs",
            "free_dofs",
        ] {
            assert!(v.get(key).is_some(), "{m}: no `{key}` in {v}");
        }
        assert!(v["sensors"].is_array());
    }
}

#[test]
fn check_json_reports_counts_and_overrides() {
    let out = latdyn(&[
        "check",
        "models/cantilever.toml",
        "--json",
        "--set",
        "elements=4",
    ]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["model"], "cantilever");
    assert_eq!(v["nodes"], 5);
    assert_eq!(v["elements"], 4);
    assert_eq!(v["free_dofs"], 24);
    assert_eq!(v["sensors"], serde_json::json!(["tip", "root_moment"]));
}

#[test]
fn broken_models_and_bad_arguments_exit_with_2() {
    let out = latdyn(&["check", "tests/bad_models/negative_stiffness.toml"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.starts_with("error: "), "{err}");
    assert!(err.contains("negative_stiffness.toml:8:"), "{err}");
    assert!(out.stdout.is_empty());

    let out = latdyn(&["check", "--json", "tests/bad_models/syntax_error.toml"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty());

    let out = latdyn(&["check", "models/cantilever.toml", "--set", "nope=1"]);
    assert_eq!(out.status.code(), Some(2));
    let out = latdyn(&["check", "models/cantilever.toml", "--set", "nope"]);
    assert_eq!(out.status.code(), Some(2));
    let out = latdyn(&["check", "does/not/exist.toml"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn simulation_verbs_print_only_their_json_object_on_stdout() {
    let cases: [(&[&str], &str); 3] = [
        (
            &["statics", "models/bend45.toml", "--set", "P=300", "--json"],
            "sensors",
        ),
        (
            &["modes", "models/cantilever.toml", "--count", "3", "--json"],
            "frequencies_hz",
        ),
        (
            &[
                "run",
                "models/pendulum.toml",
                "--set",
                "t_end=0.05",
                "--json",
            ],
            "sensors",
        ),
    ];
    for (args, key) in cases {
        let out = latdyn(args);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout)
            .unwrap_or_else(|e| panic!("{args:?}: stdout is not one JSON object: {e}"));
        assert!(v.get(key).is_some(), "{args:?}: no `{key}` in {v}");
    }
    let out = latdyn(&["modes", "models/cantilever.toml", "--count", "3", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frequencies_hz"].as_array().unwrap().len(), 3);
}

#[test]
fn simulation_verbs_reject_broken_models_with_exit_code_2() {
    for verb in ["statics", "modes", "run"] {
        let out = latdyn(&[verb, "tests/bad_models/negative_stiffness.toml", "--json"]);
        assert_eq!(out.status.code(), Some(2), "{verb}");
        assert!(
            out.stdout.is_empty(),
            "{verb}: stdout must stay empty on error"
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("negative_stiffness.toml:"), "{verb}: {err}");
    }
    let out = latdyn(&["run", "tests/bad_models/dt_zero.toml", "-o", "x.out"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("solver.dt"));
}

/// `run --json`'s `stage_times_s` splits the Newton system's assembly time into the
/// element stage and the rest: a beam scene spends time in both (the element stage was
/// reported as 0 while the assembler's own split was never carried into the run's
/// stats). Timings are only compared with zero and with each other's sum, never bounded.
#[test]
fn run_json_reports_the_element_stage_time_of_a_beam_scene() {
    let out = latdyn(&[
        "run",
        "models/flapping_blade.toml",
        "--set",
        "t_end=0.5",
        "--json",
    ]);
    assert_eq!(out.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let st = &v["stage_times_s"];
    let el = st["element"].as_f64().expect("stage_times_s.element");
    let asm = st["assembly"].as_f64().expect("stage_times_s.assembly");
    assert!(el > 0.0, "element stage time {el} in {st}");
    assert!(asm >= 0.0, "assembly time {asm} in {st}");
}

/// `--backend auto` that chooses the CPU (f64 only) says that `--precision f32` does not
/// apply; it ran f64 without a word (the JSON recorded it; a probe, session 46).
#[test]
fn auto_backend_on_the_cpu_says_an_f32_request_does_not_apply() {
    let out = latdyn(&[
        "run",
        "models/pendulum.toml",
        "--set",
        "t_end=0.01",
        "--precision",
        "f32",
        "--json",
    ]);
    assert!(out.status.success(), "{out:?}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    if v["backend"] == "cpu" {
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--precision f32 does not apply"), "{err}");
        assert_eq!(v["precision"], "f64", "{v}");
    }
}
