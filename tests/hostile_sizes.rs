//! Sizes claimed by a file or a model are checked before anything is allocated: a 16 KB
//! results file whose sensor claims 10⁹ components, or whose `/time` or
//! `/parameters/*` claim 10¹⁰ values, is refused by `plot`, `merge` and `sweep --resume`
//! (exit 2, no abort), and a sensor name too long to read back is rejected by `check`
//! with its location.

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

/// `base.h5` in `dir`: the pendulum over 0.05 s, the file the hostile copies start from.
fn base_file(dir: &Path) {
    let m = pendulum();
    let out = run(dir, &["run", &m, "--set", "t_end=0.05", "-o", "base.h5"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn plot_refuses_a_sensor_claiming_a_billion_components_before_allocating() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("bigcomp");
    base_file(&dir);
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

/// A copy `to` of `from` in `dir`, rewritten by h5py: `edit` is Python run with `f` the
/// file open for writing.
fn h5py_edit(dir: &Path, from: &str, to: &str, edit: &str) {
    std::fs::copy(dir.join(from), dir.join(to)).unwrap();
    let body: String = edit.lines().map(|l| format!("    {l}\n")).collect();
    let script = format!("import h5py\nwith h5py.File('{to}', 'r+') as f:\n{body}");
    let out = Command::new("python3")
        .args(["-c", &script])
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "h5py edit {to}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let len = std::fs::metadata(dir.join(to)).unwrap().len();
    assert!(len < 1 << 20, "{to}: {len} bytes, not a small file");
}

/// /time replaced by a dataset of 10¹⁰ samples, none written: chunked, compressed, or
/// resizable (written at its real size, then extended).
const HUGE_TIME: [(&str, &str); 3] = [
    (
        "time_chunked.h5",
        "a = dict(f['time'].attrs); del f['time']\n\
         d = f.create_dataset('time', shape=(10**10,), dtype='f8', chunks=(1 << 16,))\n\
         for k, v in a.items(): d.attrs[k] = v",
    ),
    (
        "time_gzip.h5",
        "a = dict(f['time'].attrs); del f['time']\n\
         d = f.create_dataset('time', shape=(10**10,), dtype='f8', chunks=(1 << 16,), \
         compression='gzip')\n\
         for k, v in a.items(): d.attrs[k] = v",
    ),
    (
        "time_resizable.h5",
        "a = dict(f['time'].attrs); t = f['time'][:]; del f['time']\n\
         d = f.create_dataset('time', data=t, maxshape=(None,), chunks=(1024,))\n\
         d.resize((10**10,))\n\
         for k, v in a.items(): d.attrs[k] = v",
    ),
];

/// /parameters/values claiming 1.25·10⁹ variants (10¹⁰ values).
const HUGE_VALUES: &str = "p = f['parameters/values'].shape[1]; del f['parameters/values']\n\
     f.create_dataset('parameters/values', shape=(1_250_000_000, p), dtype='f8', \
     chunks=(4096, p))";

/// Exit 2 within 30 s, naming `file` and each of `needles`, without reading the claim
/// (the HDF5 crate's own refusal, "cannot allocate", means the read was attempted).
fn refused(dir: &Path, args: &[&str], file: &str, needles: &[&str]) {
    let t0 = std::time::Instant::now();
    let out = run(dir, args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(
        t0.elapsed() < std::time::Duration::from_secs(30),
        "{args:?}: took {:?}",
        t0.elapsed()
    );
    assert!(err.contains(file), "{args:?}: names the file: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: lacks {n:?}: {err}");
    }
    assert!(
        !err.contains("cannot allocate") && !err.contains("internal error"),
        "{args:?}: {err}"
    );
}

#[test]
fn plot_refuses_time_and_parameters_claiming_ten_billion_values_before_allocating() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("bigtime");
    base_file(&dir);
    for (file, edit) in HUGE_TIME {
        h5py_edit(&dir, "base.h5", file, edit);
        refused(
            &dir,
            &["plot", file, "--sensor", "angle", "-o", "p.svg"],
            file,
            &[
                "/time claims 10000000000 output times",
                "refused before reading",
                "LATDYN_LIMITS key `output_values`",
            ],
        );
    }
    h5py_edit(&dir, "base.h5", "values.h5", HUGE_VALUES);
    refused(
        &dir,
        &["plot", "values.h5", "--sensor", "angle", "-o", "p.svg"],
        "values.h5",
        &[
            "/parameters/values claims 1250000000 variants",
            "LATDYN_LIMITS key `variants`",
        ],
    );
    // as many values in one row: more than the limit of one dataset's values
    h5py_edit(
        &dir,
        "base.h5",
        "wide.h5",
        "del f['parameters/values']\n\
         f.create_dataset('parameters/values', shape=(1, 10**10), dtype='f8', \
         chunks=(1, 1 << 16))",
    );
    refused(
        &dir,
        &["plot", "wide.h5", "--sensor", "angle", "-o", "p.svg"],
        "wide.h5",
        &[
            "/parameters/values claims 10000000000 values",
            "LATDYN_LIMITS key `output_values`",
        ],
    );
    h5py_edit(
        &dir,
        "base.h5",
        "names.h5",
        "del f['parameters/names']\n\
         f.create_dataset('parameters/names', shape=(10**10,), \
         dtype=h5py.string_dtype(), chunks=(4096,))",
    );
    refused(
        &dir,
        &["plot", "names.h5", "--sensor", "angle", "-o", "p.svg"],
        "names.h5",
        &["/parameters/names claims 10000000000 values"],
    );
    // the bound is the limit of LATDYN_LIMITS: lowered below the 51 output times of the
    // real file, it refuses that too, and says how to raise it
    let out = Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args(["plot", "base.h5", "--sensor", "angle", "-o", "p.svg"])
        .env("LATDYN_LIMITS", "output_values=50")
        .current_dir(&dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("/time claims 51 output times")
            && err.contains("limit 50")
            && err.contains("LATDYN_LIMITS=output_values=51"),
        "{err}"
    );
    assert!(!dir.join("p.svg").exists());
    assert!(!dir.join("p.svg.lock").exists(), "lock file left behind");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn merge_and_resume_refuse_time_and_parameters_claiming_ten_billion_values() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("bigtime_merge");
    let m = pendulum();
    let sweep = |extra: &[&str]| {
        let mut args = vec![
            "sweep",
            m.as_str(),
            "--set",
            "t_end=0.05",
            "--vary",
            "theta0=0.1:0.3:3",
        ];
        args.extend_from_slice(extra);
        run(&dir, &args)
    };
    let out = sweep(&["-o", "sw.h5"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cases = [
        (
            HUGE_TIME[1].0,
            HUGE_TIME[1].1,
            "/time claims 10000000000 output times",
        ),
        (
            "values.h5",
            HUGE_VALUES,
            "/parameters/values claims 1250000000 variants",
        ),
    ];
    for (file, edit, needle) in cases {
        h5py_edit(&dir, "sw.h5", file, edit);
        refused(
            &dir,
            &["merge", file, "-o", "merged.h5"],
            file,
            &[needle, "refused before reading"],
        );
        assert!(!dir.join("merged.h5").exists());
        let out = sweep(&["--resume", file]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "--resume {file}: {err}");
        assert!(
            err.contains(file) && err.contains(needle),
            "--resume {file}: {err}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A file whose /parameters/values is gone (deleted, or hidden by a damaged object
/// header) while /parameters/names is there: `plot` panicked labelling the lines
/// (index out of bounds, exit 70; found by a byte-flipping probe in session 44); now
/// exit 2 naming both datasets.
#[test]
fn plot_refuses_parameter_names_without_their_values() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("novalues");
    base_file(&dir);
    h5py_edit(&dir, "base.h5", "novalues.h5", "del f['parameters/values']");
    refused(
        &dir,
        &["plot", "novalues.h5", "--sensor", "angle", "-o", "p.svg"],
        "novalues.h5",
        &[
            "/parameters/names holds",
            "/parameters/values is missing or unreadable",
        ],
    );
    let _ = std::fs::remove_dir_all(&dir);
}
