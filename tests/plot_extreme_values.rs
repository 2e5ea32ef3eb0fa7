//! `plot` on values no chart axis can span (a valid file latdyn wrote with a body at
//! z = 1.7e308, a hand-edited one with ±1e308) exits 2 naming the file and the line
//! instead of hanging in the tick computation; samples that are all infinite are called
//! non-finite, not NaN.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("latdyn_plotext_{}_{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Run latdyn in `dir`, killing it (and failing) after `secs`: the bug was a hang.
fn latdyn_timed(dir: &Path, args: &[&str], secs: u64) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run latdyn");
    let t0 = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return child.wait_with_output().unwrap();
        }
        if t0.elapsed() > Duration::from_secs(secs) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("latdyn {args:?} did not end within {secs} s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn far_pendulum(dir: &Path) {
    let src =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("models/pendulum.toml"))
            .unwrap();
    let far = src.replacen("position = [0, 0, 0]", "position = [0, 0, 1.7e308]", 1);
    assert_ne!(
        far, src,
        "models/pendulum.toml changed: no body position [0, 0, 0]"
    );
    std::fs::write(dir.join("far.toml"), far).unwrap();
    let out = latdyn_timed(
        dir,
        &["run", "far.toml", "--set", "t_end=0.1", "-o", "far.h5"],
        60,
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn plot_refuses_values_beyond_an_axis_span_instead_of_hanging() {
    let dir = scratch("far");
    far_pendulum(&dir);
    let out = latdyn_timed(
        &dir,
        &["plot", "far.h5", "--sensor", "angle", "-o", "pf.svg"],
        30,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("far.h5"), "names the file: {err}");
    assert!(err.contains("angle.z"), "names the line: {err}");
    assert!(err.contains("1.7e308"), "names the value: {err}");
    assert!(!dir.join("pf.svg").exists());
    assert!(!dir.join("pf.svg.lock").exists(), "lock file left behind");
    // the components that stay small still plot
    let out = latdyn_timed(
        &dir,
        &["plot", "far.h5", "--sensor", "angle.ry", "-o", "pf.svg"],
        30,
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Rewrite every sample of /sensors/angle: `a` at even time steps, `b` at odd ones.
fn edit_values(dir: &Path, a: &str, b: &str) -> bool {
    let script = format!(
        "import h5py\nwith h5py.File('v.h5', 'r+') as f:\n    d = f['sensors/angle']; x = d[:]\n    x[:] = float('{b}'); x[0, ::2, :] = float('{a}'); d[...] = x\n"
    );
    std::fs::copy(dir.join("base.h5"), dir.join("v.h5")).unwrap();
    let ok = Command::new("python3")
        .args(["-c", &script])
        .current_dir(dir)
        .status()
        .unwrap();
    ok.success()
}

#[test]
fn plot_of_hand_edited_extreme_or_infinite_values_ends_with_a_clear_message() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("edit");
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/pendulum.toml");
    let out = latdyn_timed(
        &dir,
        &[
            "run",
            model.to_str().unwrap(),
            "--set",
            "t_end=0.1",
            "-o",
            "base.h5",
        ],
        60,
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for (a, b) in [("1.7e308", "0"), ("1e308", "-1e308")] {
        assert!(edit_values(&dir, a, b));
        let out = latdyn_timed(
            &dir,
            &["plot", "v.h5", "--sensor", "angle", "-o", "v.svg"],
            30,
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{a}, {b}: {err}");
        assert!(
            err.contains("v.h5") && err.contains("cannot draw"),
            "{a}, {b}: {err}"
        );
    }
    // large but drawable
    assert!(edit_values(&dir, "1e300", "-1e300"));
    let out = latdyn_timed(
        &dir,
        &["plot", "v.h5", "--sensor", "angle", "-o", "v.svg"],
        30,
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // all infinite: non-finite, not "NaN"
    assert!(edit_values(&dir, "inf", "-inf"));
    let out = latdyn_timed(
        &dir,
        &["plot", "v.h5", "--sensor", "angle", "-o", "v.svg"],
        30,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("no selected sample is finite")
            && !err.contains("every selected sample is NaN"),
        "{err}"
    );
    // some infinite: drawn, with a note saying so
    assert!(edit_values(&dir, "inf", "0.5"));
    let out = latdyn_timed(
        &dir,
        &["plot", "v.h5", "--sensor", "angle", "-o", "v.svg"],
        30,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(err.contains("infinite sample"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
