//! `merge` and `sweep --resume` copy sensor chunks as stored: a shard whose /sensors
//! datasets were rewritten by another tool (no shuffle, no compression, fewer components,
//! a sensor missing) is refused with exit 2 and the file, dataset and difference named,
//! never merged into garbage (exit 0 with denormals) nor reported as exit 5.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("latdyn_foreign_{}_{name}", std::process::id()));
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

fn model() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models/pendulum.toml")
        .display()
        .to_string()
}

const SWEEP: [&str; 4] = ["--set", "t_end=0.05", "--vary", "theta0=0.1:0.5:4"];

fn shards(dir: &Path) {
    let m = model();
    for k in ["1/2", "2/2"] {
        let out_name = format!("sh{}.h5", &k[..1]);
        let mut args = vec!["sweep", m.as_str()];
        args.extend(SWEEP);
        args.extend(["--shard", k, "-o", out_name.as_str()]);
        let out = run(dir, &args);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

/// Copy `src` to `dst`, rewriting every /sensors dataset with h5py as `how` says.
fn rewrite(dir: &Path, src: &str, dst: &str, how: &str) {
    let body = match how {
        "noshuffle" => "ds = f.create_dataset(n, data=a, chunks=ch, compression='gzip', compression_opts=4, shuffle=False)",
        "uncompressed" => "ds = f.create_dataset(n, data=a, chunks=ch)",
        "fewer_components" => "a = a[:, :, :3]; ds = f.create_dataset(n, data=a, chunks=(1,) + a.shape[1:], compression='gzip', shuffle=True)",
        "other_chunks" => "ds = f.create_dataset(n, data=a, chunks=(1, 1, a.shape[2]), compression='gzip', shuffle=True)",
        _ => unreachable!(),
    };
    let script = format!(
        "import h5py, shutil\nshutil.copy('{src}', '{dst}')\nwith h5py.File('{dst}', 'r+') as f:\n    for s in list(f['sensors'].keys()):\n        n = 'sensors/' + s; d = f[n]; a = d[:]; at = dict(d.attrs); ch = d.chunks\n        del f[n]\n        {body}\n        for k, v in at.items(): ds.attrs[k] = v\n"
    );
    h5py(dir, &script);
}

/// Runs the Python `script` (h5py edits of the files) in `dir`.
fn h5py(dir: &Path, script: &str) {
    let st = Command::new("python3")
        .args(["-c", script])
        .current_dir(dir)
        .status()
        .unwrap();
    assert!(st.success(), "h5py: {script}");
}

fn refused(out: &Output, what: &str, needles: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{what}: {err}");
    for n in needles {
        assert!(err.contains(n), "{what}: no {n:?} in {err}");
    }
    assert!(!err.contains("internal error"), "{what}: {err}");
}

#[test]
fn merge_refuses_shards_whose_sensor_layout_differs_with_exit_2() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("merge");
    shards(&dir);
    for (how, needle) in [
        ("noshuffle", "filter pipeline is [deflate]"),
        ("uncompressed", "filter pipeline is empty"),
        ("fewer_components", "components"),
        ("other_chunks", "chunks"),
    ] {
        let bad = format!("{how}.h5");
        rewrite(&dir, "sh2.h5", &bad, how);
        let out = run(&dir, &["merge", "sh1.h5", &bad, "-o", "m.h5", "--json"]);
        refused(&out, how, &[&bad, "/sensors/"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{how}: no {needle:?} in {err}");
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["status"], "refused", "{how}");
        assert!(
            !dir.join("m.h5").exists(),
            "{how}: a merged file was written"
        );
    }
    // the shards as latdyn wrote them still merge
    let out = run(&dir, &["merge", "sh1.h5", "sh2.h5", "-o", "m.h5"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn merge_refuses_a_shard_without_a_sensor_with_exit_2() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("missing");
    shards(&dir);
    let script = "import h5py, shutil\nshutil.copy('sh2.h5', 'ms.h5')\nwith h5py.File('ms.h5', 'r+') as f:\n    del f['sensors/energy']\n";
    h5py(&dir, script);
    let out = run(&dir, &["merge", "sh1.h5", "ms.h5", "-o", "m.h5"]);
    refused(&out, "missing sensor", &["ms.h5", "energy"]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn resume_refuses_a_file_whose_sensors_were_rewritten_without_shuffle() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("resume");
    shards(&dir);
    let out = run(&dir, &["merge", "sh1.h5", "sh2.h5", "-o", "m.h5"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    rewrite(&dir, "m.h5", "r.h5", "noshuffle");
    let before = std::fs::read(dir.join("r.h5")).unwrap();
    let m = model();
    let mut args = vec!["sweep", m.as_str()];
    args.extend(SWEEP);
    args.extend(["--resume", "r.h5"]);
    let out = run(&dir, &args);
    refused(&out, "resume", &["r.h5", "/sensors/", "filter pipeline"]);
    assert_eq!(
        std::fs::read(dir.join("r.h5")).unwrap(),
        before,
        "the file was changed"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The campaign's hash fixes its output grid, so a shard whose /time was edited after
/// the sweep wrote it (one sample moved by 1 ms, or the first shard's) is refused with
/// the sample named, by merge and by `sweep --resume`; until session 34 both took the
/// stored /time as it was and every sample could carry a wrong time.
#[test]
fn merge_refuses_a_shard_whose_time_grid_was_altered_with_exit_2() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("time");
    shards(&dir);
    for (src, bad) in [("sh2.h5", "t2.h5"), ("sh1.h5", "t1.h5")] {
        let script = format!(
            "import h5py, shutil\nshutil.copy('{src}', '{bad}')\nwith h5py.File('{bad}', 'r+') as f:\n    t = f['time'][:]; t[3] += 1e-3; f['time'][:] = t\n"
        );
        h5py(&dir, &script);
        let pair = if src == "sh2.h5" {
            ["sh1.h5", bad]
        } else {
            [bad, "sh2.h5"]
        };
        let out = run(&dir, &["merge", pair[0], pair[1], "-o", "m.h5"]);
        refused(&out, bad, &[bad, "/time", "sample 3"]);
        assert!(
            !dir.join("m.h5").exists(),
            "{bad}: a merged file was written"
        );
        // `sweep --resume` reads the file as merge does
        let m = model();
        let mut args = vec!["sweep", m.as_str()];
        args.extend(SWEEP);
        args.extend(["--resume", bad]);
        refused(&run(&dir, &args), bad, &[bad, "/time", "sample 3"]);
    }
    let out = run(&dir, &["merge", "sh1.h5", "sh2.h5", "-o", "m.h5"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A shard whose parameter table was edited (names replaced or emptied, values set to
/// NaN or moved off the campaign's definition) is refused with exit 2, naming the file
/// and the parameter: `merge` copies the values as stored, so until session 44 it merged
/// NaN parameters and foreign names with exit 0, and an emptied table failed as an
/// output fault (exit 5).
#[test]
fn merge_refuses_a_shard_whose_parameter_table_was_edited_with_exit_2() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("params");
    shards(&dir);
    for (name, edit, needles) in [
        (
            "names",
            "n = f['parameters/names'][...]; del f['parameters/names']; \
             f['parameters/names'] = [b'a'] * len(n)",
            &["/parameters/names differ"][..],
        ),
        (
            "nan",
            "v = f['parameters/values'][...]; v[:] = float('nan'); f['parameters/values'][...] = v",
            &["/parameters/values of variant", "`theta0` is NaN"][..],
        ),
        (
            "off",
            "v = f['parameters/values'][...]; v[:, 0] += 1.0; f['parameters/values'][...] = v",
            &["`theta0`", "the campaign's definition gives"][..],
        ),
        (
            "empty",
            "del f['parameters/names']; del f['parameters/values']\n        \
             f.create_dataset('parameters/names', shape=(0,), dtype=h5py.string_dtype())\n        \
             f.create_dataset('parameters/values', shape=(2, 0), dtype='f8')",
            &["/parameters/names differ"][..],
        ),
    ] {
        let bad = format!("{name}.h5");
        let script = format!(
            "import h5py, shutil\nshutil.copy('sh2.h5', '{bad}')\nwith h5py.File('{bad}', 'r+') as f:\n        {edit}\n"
        );
        h5py(&dir, &script);
        let out = run(&dir, &["merge", "sh1.h5", &bad, "-o", "m.h5", "--json"]);
        refused(&out, name, needles);
        assert!(
            !dir.join("m.h5").exists(),
            "{name}: a merged file was written"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A shard whose root `campaign_hash` was edited is refused, exit 2, naming the file:
/// the hash must be that of the stored definition (a merge carried `deadbeef` on into
/// its output, and a resume of that then said the definition changed naming one id
/// twice; a probe, session 46).
#[test]
fn merge_refuses_a_shard_whose_campaign_hash_is_not_its_definitions() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("hash");
    shards(&dir);
    h5py(
        &dir,
        "import h5py, shutil\nshutil.copy('sh2.h5', 'bad.h5')\nwith h5py.File('bad.h5', 'r+') as f:\n    f.attrs['campaign_hash'] = 'deadbeef'\n",
    );
    let out = run(&dir, &["merge", "sh1.h5", "bad.h5", "-o", "m.h5", "--json"]);
    refused(&out, "hash", &["bad.h5", "campaign_hash", "not the hash"]);
    assert!(!dir.join("m.h5").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// h5py stores a Python str as a variable-length string; a shard whose definition,
/// model source and model path were rewritten so (same text) merges into a file whose
/// texts are those texts. They were read as their raw heap-reference bytes: the merged
/// definition was garbage with exit 0, the model source "did not compile", a chart's
/// title held NUL bytes (a probe, session 46).
#[test]
fn merge_reads_texts_that_h5py_rewrote_as_variable_length_strings() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("vlen");
    shards(&dir);
    h5py(
        &dir,
        "import h5py, shutil\nshutil.copy('sh2.h5', 'vlen.h5')\nwith h5py.File('vlen.h5', 'r+') as f:\n    for n in ['campaign/definition', 'model/source', 'model/path']:\n        t = f[n][()]\n        t = t.decode() if isinstance(t, bytes) else str(t)\n        del f[n]\n        f[n] = t\n",
    );
    let out = run(&dir, &["merge", "sh1.h5", "vlen.h5", "-o", "m.h5"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    h5py(
        &dir,
        "import h5py\nwith h5py.File('m.h5') as m, h5py.File('sh1.h5') as a:\n    for n in ['campaign/definition', 'model/source', 'model/path']:\n        x, y = m[n][()], a[n][()]\n        x = x.decode() if isinstance(x, bytes) else x\n        y = y.decode() if isinstance(y, bytes) else y\n        assert x == y, (n, x[:80], y[:80])\n",
    );
    let png = run(
        &dir,
        &["plot", "vlen.h5", "--sensor", "angle", "-o", "c.svg"],
    );
    assert_eq!(
        png.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&png.stderr)
    );
    let svg = std::fs::read_to_string(dir.join("c.svg")).unwrap();
    assert!(!svg.contains('\0'), "a NUL in the chart");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A missing variant of a merge, or one `--resume` reruns, is compiled from the stored
/// model text: one edited in the file (here a comment appended; the probe changed
/// g = 9.81 to 1.0) must be refused as the campaign definition's model_sha256 is not its
/// hash. Until session 47 the merge exited 4 and gave the missing rows g = 1 (a probe).
#[test]
fn merge_and_resume_refuse_a_file_whose_model_text_is_not_the_definitions() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("source");
    shards(&dir);
    h5py(
        &dir,
        "import h5py, shutil\nshutil.copy('sh2.h5', 'bad.h5')\nwith h5py.File('bad.h5', 'r+') as f:\n    s = f['model/source'][()]\n    s = s.decode() if isinstance(s, bytes) else s\n    del f['model/source']\n    f['model/source'] = s + '\\n# edited\\n'\n",
    );
    let out = run(&dir, &["merge", "sh1.h5", "bad.h5", "-o", "m.h5", "--json"]);
    refused(&out, "source", &["bad.h5", "model text", "model_sha256"]);
    assert!(!dir.join("m.h5").exists());
    let m = model();
    let mut args = vec!["sweep", m.as_str()];
    args.extend(SWEEP);
    args.extend(["--resume", "bad.h5"]);
    refused(&run(&dir, &args), "resume", &["bad.h5", "model text"]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--resume` keeps a completed row as stored, so a parameter value edited there would
/// label its samples wrongly: refused as `merge` refuses it. Until session 47 the resume
/// exited 0 and marked the file complete with theta0 = 77 on the samples of the row's
/// own value (a probe, on the rotating cantilever's omega).
#[test]
fn resume_refuses_an_edited_parameter_value_in_a_completed_row() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: h5py is not installed");
        return;
    }
    let dir = scratch("resume_values");
    shards(&dir);
    h5py(
        &dir,
        "import h5py, shutil\nshutil.copy('sh1.h5', 'bad.h5')\nwith h5py.File('bad.h5', 'r+') as f:\n    names = [n.decode() if isinstance(n, bytes) else n for n in f['parameters/names'][:]]\n    v = f['parameters/values'][:]\n    v[0, names.index('theta0')] = 77.0\n    f['parameters/values'][:] = v\n",
    );
    let m = model();
    let mut args = vec!["sweep", m.as_str()];
    args.extend(SWEEP);
    args.extend(["--resume", "bad.h5"]);
    refused(
        &run(&dir, &args),
        "resume",
        &["bad.h5", "theta0", "77", "edited"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}
