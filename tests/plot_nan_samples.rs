//! `plot` says on stderr how many samples of which line it leaves out because they are
//! NaN, when the NaN is data: inside what a variant wrote (a completed variant, or before
//! a failure). The NaN that stands for samples never written is not noted: the tail of a
//! failed, interrupted or pending variant after its `/status/t_fail` (its legend says
//! so), and the padding of the shorter paths of `sweep --path`.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use latdyn::output::{CampaignMeta, CampaignWriter, SensorMeta, VariantState, VariantStatus};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("latdyn_plotnan_{}_{name}", std::process::id()));
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

/// `plot` of `args` succeeds; its stderr.
fn plot_ok(dir: &Path, args: &[&str]) -> String {
    let mut all = vec!["plot"];
    all.extend_from_slice(args);
    let out = run(dir, &all);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(0), "plot {args:?}: {err}");
    err
}

fn nan_notes(err: &str) -> Vec<&str> {
    err.lines().filter(|l| l.contains("NaN")).collect()
}

/// The cantilever with its tip load scaled by sqrt(t_bad - t), over 0.2 s (output every
/// 0.01 s): the variant with t_bad = 0.1 fails there (a non-finite load factor), the one
/// with t_bad = 10 completes.
fn failing_sweep(dir: &Path) {
    let src = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/cantilever.toml"),
    )
    .unwrap();
    let text = src
        .replacen("M = { value = 0.0", "t_bad = 10.0\nM = { value = 0.0", 1)
        .replacen(
            "moment = [0, \"M\", 0]",
            "moment = [0, \"M\", 0]\nscale = \"sqrt(t_bad - t)\"",
            1,
        )
        .replacen("t_end = 1.0", "t_end = 0.2", 1);
    assert_eq!(
        text.matches("t_bad").count() + text.matches("t_end = 0.2").count(),
        3,
        "models/cantilever.toml changed: the edits did not apply"
    );
    std::fs::write(dir.join("bad.toml"), text).unwrap();
    let out = run(
        dir,
        &[
            "sweep",
            "bad.toml",
            "--set",
            "P=1",
            "--vary",
            "t_bad=0.1:10:2",
            "-o",
            "fs.h5",
        ],
    );
    assert_eq!(
        out.status.code(),
        Some(3),
        "one variant fails: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Set /sensors/tip[variant, sample, 0] (tip.x) to NaN in a copy `to` of fs.h5.
fn inject_nan(dir: &Path, to: &str, variant: usize, sample: usize) {
    std::fs::copy(dir.join("fs.h5"), dir.join(to)).unwrap();
    let script = format!(
        "import h5py\nwith h5py.File('{to}', 'r+') as f:\n    d = f['sensors/tip']; x = d[:]\n    \
         assert x[{variant}, {sample}, 0] == x[{variant}, {sample}, 0], 'already NaN'\n    \
         x[{variant}, {sample}, 0] = float('nan'); d[...] = x\n"
    );
    let ok = Command::new("python3")
        .args(["-c", &script])
        .current_dir(dir)
        .status()
        .unwrap();
    assert!(ok.success(), "h5py edit failed");
}

#[test]
fn a_nan_inside_written_samples_is_noted_the_tail_of_a_failed_variant_is_not() {
    let dir = scratch("failing");
    failing_sweep(&dir);
    // the normal case: variant 0 failed at t = 0.101 (its samples after it read NaN),
    // variant 1 completed: no note, for the components and for the cross plot
    for args in [
        vec!["fs.h5", "--sensor", "tip", "-o", "a.svg"],
        vec!["fs.h5", "--x", "tip.x", "--y", "tip.z", "-o", "b.svg"],
    ] {
        let err = plot_ok(&dir, &args);
        assert!(nan_notes(&err).is_empty(), "{args:?}: {err}");
    }
    if !common::h5py_available() {
        eprintln!("SKIPPED (injected NaN): h5py is not installed");
        return;
    }
    // a NaN in the middle of the completed variant: one note naming it
    inject_nan(&dir, "mid.h5", 1, 7);
    for args in [
        vec!["mid.h5", "--sensor", "tip", "-o", "a.svg"],
        vec!["mid.h5", "--sensor", "tip.x", "-o", "a.svg"],
        vec!["mid.h5", "--x", "tip.x", "--y", "tip.z", "-o", "b.svg"],
    ] {
        let err = plot_ok(&dir, &args);
        let notes = nan_notes(&err);
        assert_eq!(notes.len(), 1, "{args:?}: {err}");
        assert!(
            notes[0].starts_with("note: 1 NaN sample(s) of tip.x in variant 1 (t_bad=10)")
                && notes[0].contains("not drawn")
                && notes[0].contains("t = 0.07 s"),
            "{args:?}: {err}"
        );
    }
    // the other components of the same variant have no NaN: no note
    let err = plot_ok(&dir, &["mid.h5", "--sensor", "tip.z", "-o", "a.svg"]);
    assert!(nan_notes(&err).is_empty(), "{err}");
    // a NaN before the failure is data too: noted, the tail after t_fail still is not
    inject_nan(&dir, "early.h5", 0, 3);
    let err = plot_ok(&dir, &["early.h5", "--sensor", "tip.x", "-o", "a.svg"]);
    let notes = nan_notes(&err);
    assert_eq!(notes.len(), 1, "{err}");
    assert!(
        notes[0].starts_with("note: 1 NaN sample(s) of tip.x in variant 0 (t_bad=0.1, failed)")
            && notes[0].contains("t = 0.03 s"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Variants over 0..1 s (11 samples) of sensor `s` (components a, b): 0 completed,
/// 1 interrupted at t = 0.4 (samples to 0.4), 2 failed at the start (t_fail = 0, nothing
/// written), 3 pending, 4 failed by a panic (t_fail NaN, nothing written); with
/// `nan_in_5`, a variant 5, completed, whose s.b is NaN at t = 0.5 and 0.6.
fn unfinished_campaign(path: &Path, nan_in_5: bool) {
    let time: Vec<f64> = (0..11).map(|i| 0.1 * i as f64).collect();
    let meta = CampaignMeta {
        command_line: "latdyn sweep m.toml -o u.h5".into(),
        model_path: "m.toml".into(),
        model_source: "# m\n".into(),
        backend: "cpu".into(),
        precision: "f64".into(),
        adapter: String::new(),
        threads: 1,
        parameter_names: vec!["k".into()],
        parameter_values: (0..5 + usize::from(nan_in_5))
            .map(|v| vec![v as f64])
            .collect(),
        global_index: Vec::new(),
        time: time.clone(),
        sensors: vec![SensorMeta {
            name: "s".into(),
            components: vec!["a".into(), "b".into()],
            units: vec!["m".into(), "m".into()],
        }],
    };
    let mut w = CampaignWriter::create(path, &meta).unwrap();
    let write = |w: &mut CampaignWriter, v: usize, upto: usize| {
        for (i, t) in time.iter().enumerate().take(upto) {
            w.write_samples(v, i, &[vec![t.sin(), t.cos() + v as f64]])
                .unwrap();
        }
    };
    let status = |state, t_fail| VariantStatus {
        state,
        t_fail,
        ..Default::default()
    };
    write(&mut w, 0, 11);
    w.set_status(0, &status(VariantState::Completed, f64::NAN))
        .unwrap();
    write(&mut w, 1, 5);
    w.set_status(1, &status(VariantState::Interrupted, 0.4))
        .unwrap();
    w.set_status(2, &status(VariantState::Failed, 0.0)).unwrap();
    w.set_status(3, &status(VariantState::Pending, f64::NAN))
        .unwrap();
    w.set_status(4, &status(VariantState::Failed, f64::NAN))
        .unwrap();
    if nan_in_5 {
        for (i, t) in time.iter().enumerate() {
            let b = if i == 5 || i == 6 { f64::NAN } else { t.cos() };
            w.write_samples(5, i, &[vec![t.sin(), b]]).unwrap();
        }
        w.set_status(5, &status(VariantState::Completed, f64::NAN))
            .unwrap();
    }
    w.finish("interrupted").unwrap();
}

#[test]
fn samples_never_written_get_no_note_a_nan_written_does() {
    let dir = scratch("unwritten");
    unfinished_campaign(&dir.join("u.h5"), false);
    for args in [
        vec!["u.h5", "--sensor", "s", "-o", "a.svg"],
        vec!["u.h5", "--x", "s.a", "--y", "s.b", "-o", "b.svg"],
    ] {
        let err = plot_ok(&dir, &args);
        assert!(nan_notes(&err).is_empty(), "{args:?}: {err}");
        assert!(err.contains("plot: wrote"), "{err}");
    }
    // beside them, a completed variant with NaN written: noted, and only it
    unfinished_campaign(&dir.join("u5.h5"), true);
    let err = plot_ok(&dir, &["u5.h5", "--sensor", "s", "-o", "a.svg"]);
    let notes = nan_notes(&err);
    assert_eq!(
        notes,
        ["note: 2 NaN sample(s) of s.b in variant 5 (k=5) not drawn \
         (the line breaks there; the first at t = 0.5 s)"],
        "{err}"
    );
    // the paths of `sweep --path` differ in length: the shorter are NaN-padded to the
    // longest (/time is the point index there)
    let lee = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/lee_frame.toml");
    let out = run(
        &dir,
        &[
            "sweep",
            lee.to_str().unwrap(),
            "--path",
            "--until",
            "load_point.y=-30",
            "--vary",
            "P=8000:12000:3",
            "-o",
            "path.h5",
        ],
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lambda = rust_hdf5::H5File::open(dir.join("path.h5"))
        .unwrap()
        .dataset("sensors/path_lambda")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    assert!(
        lambda.iter().any(|l| l.is_nan()),
        "the paths have one length: nothing padded, nothing tested"
    );
    for args in [
        vec!["path.h5", "--sensor", "load_point.y", "-o", "p.svg"],
        vec![
            "path.h5",
            "--x",
            "load_point.y",
            "--y",
            "path_lambda",
            "-o",
            "q.svg",
        ],
    ] {
        let err = plot_ok(&dir, &args);
        assert!(nan_notes(&err).is_empty(), "{args:?}: {err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
