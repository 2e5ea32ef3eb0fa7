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
fn unwired_verbs_fail_cleanly() {
    for verb in ["statics", "modes", "run", "sweep", "bench"] {
        let out = latdyn(&[verb, "models/cantilever.toml"]);
        assert_eq!(out.status.code(), Some(2), "{verb}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("not available"), "{verb}: {err}");
    }
    let out = latdyn(&["run", "tests/bad_models/dt_zero.toml", "-o", "x.out"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("solver.dt"));
}
