//! `latdyn modes` refuses a model too large for its dense eigen-solvers before allocating
//! (it used to abort on a failed allocation of 2.9 TB: SIGABRT, no message), with a usage
//! exit code and a message naming the size, the limit and what to do.

mod common;
use common::*;
use std::time::Instant;

fn refused(args: &[&str], what: &str) {
    let t = Instant::now();
    let out = latdyn(args);
    let secs = t.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("{args:?}: {:?} in {secs:.2} s\n{err}", out.status.code());
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("error:") && err.contains("too large"), "{err}");
    assert!(err.contains(what), "{err}");
    assert!(
        err.contains("limit") && err.contains("fewer elements"),
        "{err}"
    );
    assert!(
        !err.contains("panicked") && !err.contains("internal error"),
        "{err}"
    );
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(secs < 30.0, "took {secs} s");
}

#[test]
fn modes_of_a_model_too_large_for_dense_matrices_exit_2_before_allocating() {
    // 100 000 elements: 600 000 coordinates, 2.9e12 bytes per dense matrix
    refused(
        &[
            "modes",
            "models/cantilever.toml",
            "--set",
            "elements=100000",
            "--json",
        ],
        "600000 free coordinates",
    );
    // the rotating-frame path (first-order form 2n×2n): 3000 elements, 18 000
    // coordinates, used to ask for 2.6 GB per matrix and abort under an 8 GB ulimit
    refused(
        &[
            "modes",
            "models/rotating_cantilever.toml",
            "--set",
            "elements=3000",
        ],
        "rotating-frame",
    );
    refused(
        &[
            "modes",
            "models/rotating_cantilever.toml",
            "--set",
            "elements=3000",
            "--vary",
            "omega=1:2:3",
            "--json",
        ],
        "rotating-frame",
    );
}

#[test]
fn a_steady_start_too_large_for_its_dense_solve_fails_at_once_not_after_an_hour() {
    // `[initial] steady = true` finds the steady rotation by Newton on dense matrices:
    // with 3 000 elements (18 000 coordinates) a run spent 40 minutes in it before its
    // first step; it now fails at once as a run that could not start (exit 3)
    let t = Instant::now();
    let out = latdyn(&[
        "run",
        "models/rotating_cantilever.toml",
        "--set",
        "elements=3000",
        "--set",
        "t_end=0.001",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(
        err.contains("`[initial] steady`") && err.contains("too large") && err.contains("18000"),
        "{err}"
    );
    assert!(t.elapsed().as_secs_f64() < 30.0);
}

/// `latdyn` with `LATDYN_LIMITS` set to `limits` (None: removed).
fn latdyn_limits(args: &[&str], limits: Option<&str>) -> std::process::Output {
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_latdyn"));
    cmd.args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("LATDYN_LIMITS");
    if let Some(l) = limits {
        cmd.env("LATDYN_LIMITS", l);
    }
    cmd.output().expect("run latdyn")
}

#[test]
fn the_dense_size_limit_is_the_limits_key_dense_bytes() {
    // it was a fixed 2 GiB: a model that needed more could not raise it, and
    // the message did not say how
    let refused_by_key = |args: &[&str], limits: Option<&str>, what: &str| {
        let out = latdyn_limits(args, limits);
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("too large") && err.contains(what), "{err}");
        assert!(
            err.contains("LATDYN_LIMITS, key `dense_bytes`")
                && err.contains("LATDYN_LIMITS=dense_bytes="),
            "{err}"
        );
        assert!(out.stdout.is_empty());
        err
    };
    // lowered: the 8-element cantilever (48 coordinates, 147 456 bytes at rest) is refused
    let e = refused_by_key(
        &["modes", "models/cantilever.toml"],
        Some("dense_bytes=1e5"),
        "48 free coordinates",
    );
    assert!(e.contains("exceeds the limit of 100000"), "{e}");
    // the rotating frame and `--vary`: refused by the analysis itself (the CLI's repeat
    // of the check was removed)
    refused_by_key(
        &["modes", "models/rotating_cantilever.toml"],
        Some("dense_bytes=1e5"),
        "rotating-frame",
    );
    refused_by_key(
        &[
            "modes",
            "models/rotating_cantilever.toml",
            "--vary",
            "omega=1:2:2",
        ],
        Some("dense_bytes=1e5"),
        "rotating-frame modes at omega=1",
    );
    // and the steady start's Newton: a run that could not start
    let out = latdyn_limits(
        &[
            "run",
            "models/rotating_cantilever.toml",
            "--set",
            "t_end=0.001",
        ],
        Some("dense_bytes=1e5"),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(
        err.contains("`[initial] steady`") && err.contains("key `dense_bytes`"),
        "{err}"
    );
    // at the default the same commands run
    let out = latdyn_limits(&["modes", "models/cantilever.toml", "--json"], None);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // raised: a free beam of 1000 elements (6006 coordinates, 2.31e9 bytes) is refused
    // at the default; with the limit raised the check passes, and its static equilibrium
    // (a free beam under a tip load) fails at once, so nothing dense is allocated
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/cantilever.toml"),
    )
    .unwrap()
    .replace("[[supports]]\nnode = \"root\"\ntype = \"clamped\"\n", "");
    assert!(!text.contains("[[supports]]"));
    let free = std::env::temp_dir().join(format!("latdyn_dense_{}_free.toml", std::process::id()));
    std::fs::write(&free, text).unwrap();
    let f = free.to_str().unwrap();
    let args = ["modes", f, "--set", "elements=1000", "--set", "P=1"];
    let e = refused_by_key(&args, None, "6006 free coordinates");
    assert!(e.contains("exceeds the limit of 2147483648"), "{e}");
    let t = Instant::now();
    let out = latdyn_limits(&args, Some("dense_bytes=3e9"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        !err.contains("too large") && !err.contains("dense_bytes"),
        "{err}"
    );
    assert!(err.contains("static equilibrium for the modes"), "{err}");
    assert!(t.elapsed().as_secs_f64() < 30.0);
    let _ = std::fs::remove_file(&free);
}

#[test]
fn the_dense_size_check_reads_its_limit_through_limits() {
    use latdyn::model::Limits;
    use latdyn::solver::modes::check_dense_size_within;
    // the default, 2 GiB: 5792 coordinates at rest, 4096 in the rotating frame
    let default = Limits::default().dense_bytes;
    assert_eq!(default, 2 << 30);
    assert!(check_dense_size_within(5792, false, default).is_ok());
    assert!(check_dense_size_within(5793, false, default).is_err());
    assert!(check_dense_size_within(4096, true, default).is_ok());
    let e = check_dense_size_within(4097, true, default).unwrap_err();
    assert!(
        e.contains("key `dense_bytes`") && e.contains("4096 free"),
        "{e}"
    );
    // as `LATDYN_LIMITS` gives it
    let raised = Limits::parse("dense_bytes=3e9").unwrap().dense_bytes;
    assert!(check_dense_size_within(6006, false, raised).is_ok());
    let lowered = Limits::parse("elements=10, dense_bytes=1e5")
        .unwrap()
        .dense_bytes;
    assert!(check_dense_size_within(48, false, lowered).is_err());
    assert!(check_dense_size_within(39, false, lowered).is_ok());
}
