//! HDF5 campaign output: write a small campaign, read it back with rust-hdf5 and (when
//! available) with h5py through tests/read_campaign.py.

use std::path::{Path, PathBuf};
use std::process::Command;

use latdyn::output::{
    CampaignMeta, CampaignWriter, OutputError, OutputTarget, SensorMeta, VariantState,
    VariantStatus,
};
use rust_hdf5::H5File;

const N_TIME: usize = 5;
/// Variant 1 fails after this many output times.
const FAILED_SAMPLES: usize = 3;

/// Expected sample of (variant, time index, sensor, component); tests/read_campaign.py
/// uses the same formula.
fn value(v: usize, t: usize, s: usize, c: usize) -> f64 {
    100.0 * v as f64 + 10.0 * t as f64 + s as f64 + 0.1 * c as f64 + 0.5
}

fn out_path(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("hdf5_output");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    let _ = std::fs::remove_file(&p);
    p
}

fn meta() -> CampaignMeta {
    CampaignMeta {
        command_line: "latdyn run models/beam.toml --sweep E=1e9,2e9 -o out.h5".into(),
        model_path: "models/beam.toml".into(),
        model_source: "# a beam\n[model]\nname = \"beam\" # ünïcode\n".into(),
        backend: "cpu".into(),
        precision: "f64".into(),
        adapter: String::new(),
        threads: 2,
        parameter_names: vec!["E".into(), "L".into()],
        parameter_values: vec![vec![1e9, 2.0], vec![2e9, 3.0]],
        global_index: vec![4, 7],
        time: (0..N_TIME).map(|i| 0.1 * i as f64).collect(),
        sensors: vec![
            SensorMeta {
                name: "tip".into(),
                components: vec!["z".into()],
                units: vec!["m".into()],
            },
            SensorMeta {
                name: "pose".into(),
                components: vec!["x".into(), "y".into(), "rz".into()],
                units: vec!["m".into(), "m".into(), "rad".into()],
            },
        ],
    }
}

fn samples(v: usize, t: usize) -> Vec<Vec<f64>> {
    vec![
        vec![value(v, t, 0, 0)],
        (0..3).map(|c| value(v, t, 1, c)).collect(),
    ]
}

/// Write the reference campaign (also checks the state of the file at a mid-run flush).
fn write_campaign(path: &Path) {
    let mut w = CampaignWriter::create(path, &meta()).unwrap();
    assert!(path.exists(), "create writes the file at once");

    let running = VariantStatus {
        state: VariantState::Running,
        ..Default::default()
    };
    w.set_status(0, &running).unwrap();
    w.set_status(1, &running).unwrap();
    for t in 0..N_TIME {
        w.write_samples(0, t, &samples(0, t)).unwrap();
        if t < FAILED_SAMPLES {
            w.write_samples(1, t, &samples(1, t)).unwrap();
        }
        if t == 1 {
            w.flush().unwrap();
            // Mid-run: the file on disk is complete and valid, with what was written.
            let f = H5File::open(path).unwrap();
            assert_eq!(f.attr_string("status").unwrap(), "running");
            let tip = f.dataset("sensors/tip").unwrap().read_raw::<f64>().unwrap();
            assert_eq!(tip[1], value(0, 1, 0, 0));
            assert!(tip[2].is_nan());
        }
    }
    w.set_status(
        0,
        &VariantStatus {
            state: VariantState::Completed,
            message: String::new(),
            t_fail: f64::NAN,
            steps: 100,
            rejected_steps: 3,
            wall_s: 0.5,
            energy_growth: 2e-7,
            energy_loss: 4e-4,
            time_error_estimate: 3e-4,
            time_error_before_first_lock: 2e-4,
            mesh_error_estimate: 5e-3,
            warnings: String::new(),
        },
    )
    .unwrap();
    w.set_derived("first_bending_hz", 0, 1.25).unwrap();
    w.set_status(
        1,
        &VariantStatus {
            state: VariantState::Failed,
            message: "Newton iteration diverged at t = 0.25 s".into(),
            t_fail: 0.25,
            steps: 42,
            rejected_steps: 7,
            wall_s: 0.25,
            energy_growth: f64::NAN,
            energy_loss: f64::NAN,
            time_error_estimate: f64::NAN,
            time_error_before_first_lock: f64::NAN,
            mesh_error_estimate: f64::NAN,
            warnings: "first line\nsecond line".into(),
        },
    )
    .unwrap();
    w.finish("complete").unwrap();
}

#[test]
fn campaign_round_trip_rust() {
    let path = out_path("campaign_rust.h5");
    write_campaign(&path);

    let f = H5File::open(&path).unwrap();
    assert_eq!(f.attr_string("status").unwrap(), "complete");
    // "complete" with a failed variant says so beside it (h5py checks the count: 1)
    assert!(f
        .attr_names()
        .unwrap()
        .contains(&"failed_variants".to_string()));
    assert_eq!(
        f.attr_string("latdyn_version").unwrap(),
        env!("CARGO_PKG_VERSION")
    );
    assert_eq!(f.attr_string("backend").unwrap(), "cpu");
    assert_eq!(f.attr_string("precision").unwrap(), "f64");
    assert_eq!(f.attr_string("command_line").unwrap(), meta().command_line);

    let names = f
        .dataset("parameters/names")
        .unwrap()
        .read_strings()
        .unwrap();
    assert_eq!(names, ["E", "L"]);
    let pv = f.dataset("parameters/values").unwrap();
    assert_eq!(pv.shape(), [2, 2]);
    assert_eq!(pv.read_raw::<f64>().unwrap(), [1e9, 2.0, 2e9, 3.0]);
    assert_eq!(
        f.dataset("time").unwrap().read_raw::<f64>().unwrap(),
        meta().time
    );

    for (s, n_comp) in [(0usize, 1usize), (1, 3)] {
        let name = &meta().sensors[s].name;
        let ds = f.dataset(&format!("sensors/{name}")).unwrap();
        assert_eq!(ds.shape(), [2, N_TIME, n_comp]);
        assert!(ds.is_chunked());
        assert!(
            ds.filters().unwrap().iter().any(|fl| fl.id == 1),
            "deflate filter on /sensors/{name}"
        );
        let data = ds.read_raw::<f64>().unwrap();
        for v in 0..2 {
            for t in 0..N_TIME {
                for c in 0..n_comp {
                    let x = data[(v * N_TIME + t) * n_comp + c];
                    if v == 1 && t >= FAILED_SAMPLES {
                        assert!(x.is_nan(), "unwritten sample {name}[{v},{t},{c}] = {x}");
                    } else {
                        assert_eq!(x, value(v, t, s, c), "{name}[{v},{t},{c}]");
                    }
                }
            }
        }
        let attrs = ds.attr_names().unwrap();
        assert!(attrs.iter().any(|a| a == "components"), "{attrs:?}");
        assert!(attrs.iter().any(|a| a == "units"), "{attrs:?}");
    }

    let st = |n: &str| f.dataset(&format!("status/{n}")).unwrap();
    assert_eq!(st("state").read_raw::<i32>().unwrap(), [2, 3]);
    assert_eq!(
        st("message").read_strings().unwrap(),
        ["", "Newton iteration diverged at t = 0.25 s"]
    );
    let t_fail = st("t_fail").read_raw::<f64>().unwrap();
    assert!(t_fail[0].is_nan());
    assert_eq!(t_fail[1], 0.25);
    assert_eq!(st("steps").read_raw::<i64>().unwrap(), [100, 42]);
    assert_eq!(st("rejected_steps").read_raw::<i64>().unwrap(), [3, 7]);
    assert_eq!(st("wall_s").read_raw::<f64>().unwrap(), [0.5, 0.25]);
    let eg = st("energy_growth").read_raw::<f64>().unwrap();
    assert!(eg[0] == 2e-7 && eg[1].is_nan(), "{eg:?}");
    let el = st("energy_loss").read_raw::<f64>().unwrap();
    assert!(el[0] == 4e-4 && el[1].is_nan(), "{el:?}");
    let te = st("time_error_estimate").read_raw::<f64>().unwrap();
    assert!(te[0] == 3e-4 && te[1].is_nan(), "{te:?}");
    let tl = st("time_error_before_first_lock")
        .read_raw::<f64>()
        .unwrap();
    assert!(tl[0] == 2e-4 && tl[1].is_nan(), "{tl:?}");
    assert_eq!(
        st("warnings").read_strings().unwrap(),
        ["", "first line\nsecond line"]
    );
    assert_eq!(st("global_index").read_raw::<i64>().unwrap(), [4, 7]);

    let d = f
        .dataset("derived/first_bending_hz")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    assert_eq!(d[0], 1.25);
    assert!(d[1].is_nan());

    // No temporary file is left next to the output.
    let leftovers: Vec<_> = std::fs::read_dir(path.parent().unwrap())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

fn h5py_available() -> bool {
    Command::new("python3")
        .args(["-c", "import h5py"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false)
}

#[test]
fn campaign_read_by_h5py() {
    if !h5py_available() {
        if std::env::var_os("CI").is_some() {
            panic!("h5py is not installed, but CI is set: .ci/run must pip-install h5py");
        }
        println!("SKIPPED: h5py not installed");
        return;
    }
    let path = out_path("campaign_h5py.h5");
    write_campaign(&path);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/read_campaign.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg(&path)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && stdout.trim_end().ends_with("OK"),
        "read_campaign.py failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
}

/// The HDF5 command-line tools read the file too (skipped where h5dump is absent).
#[test]
fn campaign_read_by_h5dump() {
    let path = out_path("campaign_h5dump.h5");
    write_campaign(&path);
    let Ok(out) = Command::new("h5dump").arg("-H").arg(&path).output() else {
        println!("SKIPPED: h5dump not installed");
        return;
    };
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "h5dump failed:\n{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for needle in [
        "/sensors/pose",
        "\"status\"",
        "first_bending_hz",
        "H5T_IEEE_F64LE",
    ] {
        assert!(
            text.contains(needle) || text.contains(needle.trim_start_matches("/sensors/")),
            "h5dump -H output lacks {needle}:\n{text}"
        );
    }
}

#[test]
fn create_fails_early_on_unwritable_path() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("hdf5_output_missing_dir");
    let _ = std::fs::remove_dir_all(&dir);
    let path = dir.join("out.h5");
    let err = CampaignWriter::create(&path, &meta())
        .err()
        .expect("missing directory must fail");
    assert!(matches!(err, OutputError::Io { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("out.h5"), "{msg}");

    // A directory in place of the file.
    let as_dir = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let err = CampaignWriter::create(as_dir, &meta())
        .err()
        .expect("a directory is not a file");
    assert!(matches!(err, OutputError::Io { .. }), "{err:?}");
}

#[test]
fn invalid_arguments_are_errors() {
    let path = out_path("campaign_invalid.h5");
    let mut bad = meta();
    bad.parameter_values[1].pop();
    assert!(matches!(
        CampaignWriter::create(&path, &bad),
        Err(OutputError::Invalid(_))
    ));
    let mut bad = meta();
    bad.sensors[1].units.pop();
    assert!(matches!(
        CampaignWriter::create(&path, &bad),
        Err(OutputError::Invalid(_))
    ));
    let mut bad = meta();
    bad.sensors[1].name = "tip".into();
    assert!(CampaignWriter::create(&path, &bad).is_err());
    let mut bad = meta();
    bad.global_index = vec![0];
    assert!(CampaignWriter::create(&path, &bad).is_err());

    let mut w = CampaignWriter::create(&path, &meta()).unwrap();
    assert!(w.write_samples(2, 0, &samples(0, 0)).is_err());
    assert!(w.write_samples(0, N_TIME, &samples(0, 0)).is_err());
    assert!(w.write_samples(0, 0, &samples(0, 0)[..1]).is_err());
    assert!(w.write_samples(0, 0, &[vec![1.0], vec![1.0]]).is_err());
    assert!(w.set_derived("a/b", 0, 1.0).is_err());
    assert!(w.set_status(5, &VariantStatus::default()).is_err());
    // An unknown finish status is reported, but the data still reaches the file.
    w.write_samples(0, 0, &samples(0, 0)).unwrap();
    assert!(w.finish("done").is_err());
    let f = H5File::open(&path).unwrap();
    assert_eq!(f.attr_string("status").unwrap(), "interrupted");
    let tip = f.dataset("sensors/tip").unwrap().read_raw::<f64>().unwrap();
    assert_eq!(tip[0], value(0, 0, 0, 0));
}

/// A writer dropped without `finish` (a crash) leaves the last flushed file; a variant
/// marked Interrupted makes the flushed file's status "interrupted".
#[test]
fn crash_after_flush_keeps_flushed_data() {
    let path = out_path("campaign_crash.h5");
    let mut w = CampaignWriter::create(&path, &meta()).unwrap();
    w.write_samples(0, 0, &samples(0, 0)).unwrap();
    w.flush().unwrap();
    w.write_samples(0, 1, &samples(0, 1)).unwrap();
    drop(w);
    let f = H5File::open(&path).unwrap();
    assert_eq!(f.attr_string("status").unwrap(), "running");
    let tip = f.dataset("sensors/tip").unwrap().read_raw::<f64>().unwrap();
    assert_eq!(tip[0], value(0, 0, 0, 0));
    assert!(tip[1].is_nan(), "written after the last flush: lost");
    drop(f);

    let mut w = CampaignWriter::create(&path, &meta()).unwrap();
    w.write_samples(1, 0, &samples(1, 0)).unwrap();
    w.set_status(
        1,
        &VariantStatus {
            state: VariantState::Interrupted,
            message: "interrupted by user".into(),
            ..Default::default()
        },
    )
    .unwrap();
    w.flush().unwrap();
    let f = H5File::open(&path).unwrap();
    assert_eq!(f.attr_string("status").unwrap(), "interrupted");
    let st = f
        .dataset("status/state")
        .unwrap()
        .read_raw::<i32>()
        .unwrap();
    assert_eq!(st, [0, 4]);
    drop(f);
    w.finish("interrupted").unwrap();
}

/// Degenerate sizes: no parameters, no variants, a long time grid spanning chunks.
#[test]
fn degenerate_and_multi_chunk_shapes() {
    let path = out_path("campaign_empty.h5");
    let mut m = meta();
    m.parameter_names.clear();
    m.parameter_values.clear();
    m.global_index.clear();
    CampaignWriter::create(&path, &m)
        .unwrap()
        .finish("complete")
        .unwrap();
    let f = H5File::open(&path).unwrap();
    assert_eq!(f.dataset("sensors/pose").unwrap().shape(), [0, N_TIME, 3]);
    assert!(f
        .dataset("parameters/names")
        .unwrap()
        .read_strings()
        .unwrap()
        .is_empty());
    drop(f);
    // h5py refused the empty string lists (/parameters/names, /status/message) with
    // "invalid dataset size" before they were written without a data block
    if h5py_available() {
        let out = Command::new("python3")
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/read_campaign.py"))
            .arg("--any")
            .arg(&path)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "h5py cannot read the empty campaign:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["parameter_names"], serde_json::json!([]));
        assert_eq!(v["messages"], serde_json::json!([]));
    } else {
        println!("SKIPPED (h5py part): h5py not installed");
    }

    // 70 000 times of a 3-component sensor: several chunks along time, the last partial.
    let path = out_path("campaign_long.h5");
    let n = 70_000;
    let mut m = meta();
    m.parameter_names.clear();
    m.parameter_values = vec![vec![]; 2];
    m.global_index.clear();
    m.time = (0..n).map(|i| i as f64 * 1e-3).collect();
    let mut w = CampaignWriter::create(&path, &m).unwrap();
    for t in (0..n).step_by(7) {
        w.write_samples(1, t, &[vec![t as f64], vec![t as f64, -(t as f64), 1.0]])
            .unwrap();
    }
    w.finish("complete").unwrap();
    let f = H5File::open(&path).unwrap();
    let pose = f.dataset("sensors/pose").unwrap();
    assert_eq!(pose.shape(), [2, n, 3]);
    let data = pose.read_raw::<f64>().unwrap();
    assert!(
        data[..n * 3].iter().all(|x| x.is_nan()),
        "variant 0 unwritten"
    );
    for t in 0..n {
        let row = &data[(n + t) * 3..(n + t + 1) * 3];
        if t % 7 == 0 {
            assert_eq!(row, [t as f64, -(t as f64), 1.0]);
        } else {
            assert!(row.iter().all(|x| x.is_nan()));
        }
    }
    let gi = f
        .dataset("status/global_index")
        .unwrap()
        .read_raw::<i64>()
        .unwrap();
    assert_eq!(gi, [0, 1]);
}

#[test]
fn writer_is_send_and_sync() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<CampaignWriter>();
}

/// One writer per path: a second claim (another process, or this one) is refused while
/// the first holds the lock, naming the holder, and succeeds once it is released.
#[test]
fn a_claimed_path_is_locked_until_its_writer_ends() {
    let path = out_path("campaign_locked.h5");
    let w = CampaignWriter::create(&path, &meta()).unwrap();
    let err = OutputTarget::claim(&path).expect_err("second claim refused");
    let msg = err.to_string();
    assert!(
        msg.contains("another latdyn process is writing it")
            && msg.contains(&format!("pid {}", std::process::id())),
        "{msg}"
    );
    let lock = path.with_file_name("campaign_locked.h5.lock");
    assert!(lock.exists());
    w.finish("complete").unwrap();
    assert!(!lock.exists(), "the lock file goes with its writer");
    drop(OutputTarget::claim(&path).unwrap());
}

/// One symlink policy for every format: refused, and the link's target untouched.
#[cfg(unix)]
#[test]
fn symlinks_are_refused_not_followed_or_replaced() {
    let real = out_path("campaign_real.h5");
    std::fs::write(&real, "precious").unwrap();
    let link = out_path("campaign_link.h5");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let err = CampaignWriter::create(&link, &meta())
        .err()
        .expect("a symlink is refused");
    assert!(err.to_string().contains("symbolic link"), "{err}");
    assert!(OutputTarget::claim(&link).is_err());
    assert_eq!(std::fs::read_to_string(&real).unwrap(), "precious");
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
}
