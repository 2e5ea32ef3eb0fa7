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
