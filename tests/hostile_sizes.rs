//! Sizes claimed by a file or a model are checked before anything is allocated: a 16 KB
//! results file whose sensor claims 10⁹ components is refused by `plot` (exit 2, no
//! abort), and a sensor name too long to read back is rejected by `check` with its
//! location.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("latdyn_sizes_{}_{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run latdyn")
}

fn pendulum() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models/pendulum.toml")
        .display()
        .to_string()
}

#[test]
fn plot_refuses_a_sensor_claiming_a_billion_components_before_allocating() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("bigcomp");
    let m = pendulum();
    let out = run(&dir, &["run", &m, "--set", "t_end=0.05", "-o", "base.h5"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let script = "import h5py, shutil\nshutil.copy('base.h5', 'big.h5')\nwith h5py.File('big.h5', 'r+') as f:\n    d = f['sensors/angle']; at = dict(d.attrs); n = f['time'].shape[0]\n    del f['sensors/angle']\n    ds = f.create_dataset('sensors/angle', shape=(1, n, 1_000_000_000), dtype='f8', chunks=(1, 1, 1 << 16))\n    for k, v in at.items(): ds.attrs[k] = v\n";
    assert!(Command::new("python3")
        .args(["-c", script])
        .current_dir(&dir)
        .status()
        .unwrap()
        .success());
    assert!(std::fs::metadata(dir.join("big.h5")).unwrap().len() < 1 << 20);
    for sel in ["angle", "angle.c0"] {
        let out = run(&dir, &["plot", "big.h5", "--sensor", sel, "-o", "p.svg"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{sel}: {err}");
        assert!(
            err.contains("big.h5") && err.contains("/sensors/angle"),
            "{sel}: {err}"
        );
        assert!(err.contains("1000000000 components"), "{sel}: {err}");
    }
    assert!(!dir.join("p.svg.lock").exists(), "lock file left behind");
    let _ = std::fs::remove_dir_all(&dir);
}

fn model_with_sensor_name(dir: &Path, len: usize) -> String {
    let src = std::fs::read_to_string(pendulum()).unwrap();
    let name = "a".repeat(len);
    let text = src.replacen("name = \"angle\"", &format!("name = \"{name}\""), 1);
    assert_ne!(text, src, "models/pendulum.toml has no sensor named angle");
    let file = format!("long{len}.toml");
    std::fs::write(dir.join(&file), text).unwrap();
    file
}

#[test]
fn sensor_names_longer_than_255_bytes_are_rejected_at_compile_time_with_their_location() {
    let dir = scratch("names");
    // 255 bytes: accepted, written and read back by plot
    let ok = model_with_sensor_name(&dir, latdyn::output::MAX_NAME_BYTES);
    let out = run(&dir, &["run", &ok, "--set", "t_end=0.01", "-o", "ok.h5"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let long_name = "a".repeat(latdyn::output::MAX_NAME_BYTES);
    let out = run(
        &dir,
        &["plot", "ok.h5", "--sensor", &long_name, "-o", "ok.svg"],
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for len in [256, 65_536, 70_000] {
        let bad = model_with_sensor_name(&dir, len);
        for verb in [
            vec!["check", bad.as_str()],
            vec!["run", bad.as_str(), "--set", "t_end=0.01", "-o", "bad.h5"],
            vec![
                "sweep",
                bad.as_str(),
                "--set",
                "t_end=0.01",
                "--vary",
                "theta0=0.1:0.2:2",
                "-o",
                "bad.h5",
            ],
        ] {
            let out = run(&dir, &verb);
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{len} {}: {err}", verb[0]);
            assert!(
                err.contains(&bad) && err.contains("sensors[0].name"),
                "{len}: {err}"
            );
            assert!(
                err.contains(&format!("{len} bytes")) && err.contains("255"),
                "{len}: {err}"
            );
            assert!(
                err.len() < 1000,
                "{len}: the message repeats the whole name ({} bytes)",
                err.len()
            );
            assert!(!dir.join("bad.h5").exists());
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
