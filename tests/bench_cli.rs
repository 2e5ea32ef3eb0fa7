//! `latdyn bench`: the report it writes is complete and its errors behave as the
//! references say (no timing is asserted: timing is what the bench prints).

use std::process::Command;

fn latdyn(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run latdyn")
}

#[test]
fn bench_statics_ladders_write_the_report_and_converge_at_second_order() {
    let dir = std::env::temp_dir().join(format!("latdyn-bench-{}", std::process::id()));
    let out = latdyn(&[
        "bench",
        "--quick",
        "--only",
        "rollup",
        "--only",
        "bend45",
        "--out",
        dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("stdout is JSON");
    for f in ["results.md", "results.json", "work_precision.png"] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    let md = std::fs::read_to_string(dir.join("results.md")).unwrap();
    assert!(md.contains("Roll-up") && md.contains("45° bend"), "{md}");
    let problems = v["problems"].as_array().unwrap();
    assert_eq!(problems.len(), 2);
    for p in problems {
        let runs = p["runs"].as_array().unwrap();
        let err: Vec<f64> = runs.iter().map(|r| r["error"].as_f64().unwrap()).collect();
        let n: Vec<f64> = runs
            .iter()
            .map(|r| r["elements"].as_f64().unwrap())
            .collect();
        for r in runs {
            assert!(r["wall_s"].as_f64().unwrap() > 0.0);
            assert!(r["newton_iterations"].as_u64().unwrap() > 0);
        }
        // The roll-up gap is the O(h²) chord error of the circle (reference 0, exact), so
        // it falls by ~4 per halving: measured 4.7 and 4.1 from 8→16→32 elements. The 45°
        // bend converges at O(h²) towards a reference printed to 0.01 (1e-4 relative):
        // measured ratios 3.9 and 3.7 at 4→8→16 elements, where the error (≥ 1e-3) is
        // still well above that rounding. Bound: each halving at least 3 times smaller.
        for i in 1..err.len() {
            assert_eq!(n[i], 2.0 * n[i - 1]);
            assert!(
                err[i - 1] / err[i] > 3.0,
                "{}: errors {err:?} over {n:?} elements",
                p["name"]
            );
        }
    }
    // an unknown problem is refused by name, before anything runs
    let bad = latdyn(&["bench", "--only", "nope", "--out", dir.to_str().unwrap()]);
    assert_eq!(bad.status.code(), Some(2));
    let e = String::from_utf8_lossy(&bad.stderr);
    assert!(e.contains("unknown benchmark problem 'nope'"), "{e}");
    assert!(bad.stdout.is_empty());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The bench's three files follow the output policy of `run`, `sweep` and `plot`: a
/// `results.md` that is a symlink (here to a model file) or a FIFO is refused before
/// the suite runs, exit 2, and the symlink's target is left as it was. Until session 46
/// the bench wrote through the symlink (replacing the model with its report) and hung
/// on the FIFO.
#[test]
fn bench_refuses_a_symlinked_or_special_results_file_before_running() {
    use std::os::unix::fs::symlink;
    let dir = std::env::temp_dir().join(format!("latdyn-bench-out-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("linked")).unwrap();
    let victim = dir.join("victim.toml");
    std::fs::write(&victim, "# a model\n").unwrap();
    symlink(&victim, dir.join("linked/results.md")).unwrap();
    let args = |out: &str| {
        vec![
            "bench".to_string(),
            "--quick".into(),
            "--only".into(),
            "rollup".into(),
            "--out".into(),
            dir.join(out).to_string_lossy().into_owned(),
        ]
    };
    let a = args("linked");
    let out = latdyn(&a.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("symbolic link") && !e.contains("Roll-up"), "{e}");
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "# a model\n");

    std::fs::create_dir_all(dir.join("fifo")).unwrap();
    let fifo = dir.join("fifo/results.json");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let a = args("fifo");
    let out = latdyn(&a.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("FIFO"),
        "{out:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
