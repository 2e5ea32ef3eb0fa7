//! Paths that are not valid UTF-8 (a Latin-1 byte in a file name) are ordinary paths:
//! every verb that claims an output path handles them, and no `.lock` file is left.
#![cfg(unix)]

use std::ffi::OsString;
use std::os::unix::ffi::OsStringExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn latdyn_in(dir: &Path, args: &[OsString]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run latdyn")
}

/// A name with the byte 0xFF, which no UTF-8 string holds.
fn bad(prefix: &str, suffix: &str) -> OsString {
    let mut b = prefix.as_bytes().to_vec();
    b.push(0xff);
    b.extend_from_slice(suffix.as_bytes());
    OsString::from_vec(b)
}

fn os(s: &str) -> OsString {
    OsString::from(s)
}

fn ok(out: &Output, what: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{what}: {err}");
    assert!(!err.contains("internal error"), "{what}: {err}");
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("latdyn_nonutf8_{}_{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn no_lock_files(dir: &Path) {
    let left: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name())
        .filter(|n| {
            let n = n.as_encoded_bytes();
            n.ends_with(b".lock") || n.ends_with(b".tmp")
        })
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn non_utf8_paths_are_accepted_by_every_output_verb_and_leave_no_lock() {
    let dir = scratch("verbs");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let model = bad("p", ".toml");
    std::fs::copy(root.join("models/pendulum.toml"), dir.join(&model)).unwrap();

    // a model path that is not UTF-8, then an output path that is not
    let out = latdyn_in(
        &dir,
        &[
            os("run"),
            model.clone(),
            os("--set"),
            os("t_end=0.01"),
            os("-o"),
            os("out.h5"),
        ],
    );
    ok(&out, "run with a non-UTF-8 model path");
    let h5 = bad("o", ".h5");
    let out = latdyn_in(
        &dir,
        &[
            os("run"),
            model.clone(),
            os("--set"),
            os("t_end=0.01"),
            os("-o"),
            h5.clone(),
        ],
    );
    ok(&out, "run -o non-UTF-8");
    assert!(dir.join(&h5).is_file());

    let svg = bad("q", ".svg");
    let out = latdyn_in(
        &dir,
        &[
            os("plot"),
            h5.clone(),
            os("--sensor"),
            os("angle"),
            os("-o"),
            svg.clone(),
        ],
    );
    ok(&out, "plot -o non-UTF-8");
    assert!(dir.join(&svg).is_file());

    let shard = bad("s", ".h5");
    let out = latdyn_in(
        &dir,
        &[
            os("sweep"),
            model.clone(),
            os("--set"),
            os("t_end=0.01"),
            os("--vary"),
            os("theta0=0.1:0.2:2"),
            os("-o"),
            shard.clone(),
        ],
    );
    ok(&out, "sweep -o non-UTF-8");
    let merged = bad("m", ".h5");
    let out = latdyn_in(
        &dir,
        &[os("merge"), shard.clone(), os("-o"), merged.clone()],
    );
    ok(&out, "merge -o non-UTF-8");
    assert!(dir.join(&merged).is_file());

    let bend = bad("b", ".toml");
    std::fs::copy(root.join("models/bend45.toml"), dir.join(&bend)).unwrap();
    let path_out = bad("st", ".h5");
    let out = latdyn_in(
        &dir,
        &[
            os("statics"),
            bend,
            os("--path"),
            os("--set"),
            os("P=600"),
            os("-o"),
            path_out.clone(),
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("internal error"), "statics --path -o: {err}");
    assert_ne!(out.status.code(), Some(70), "statics --path -o: {err}");

    no_lock_files(&dir);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Two names that differ only in their invalid bytes are two files with two lock files
/// (a lossy name would have given both the same `.lock`).
#[test]
fn non_utf8_output_names_keep_their_bytes_in_the_lock_and_temporary_files() {
    let dir = scratch("bytes");
    let a = latdyn::output::OutputTarget::claim(&dir.join(bad("x", ".h5"))).unwrap();
    let mut other = b"x".to_vec();
    other.push(0xfe);
    other.extend_from_slice(b".h5");
    let b = latdyn::output::OutputTarget::claim(&dir.join(OsString::from_vec(other)));
    assert!(
        b.is_ok(),
        "a second name was refused: {:?}",
        b.err().map(|e| e.to_string())
    );
    drop(a);
    drop(b);
    no_lock_files(&dir);
    let _ = std::fs::remove_dir_all(&dir);
}
