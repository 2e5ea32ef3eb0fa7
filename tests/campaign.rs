//! Campaigns split into shards and made one again (README "Campaigns on a cluster"):
//! `latdyn merge` of `sweep --shard K/N` files and `sweep --resume`, run as the real
//! binary. The reference for every merged or resumed file is a single-process sweep of
//! the same campaign; tests/compare_campaigns.py (h5py, the reference reader) checks
//! that every dataset and attribute is equal, floats bit for bit, except the command
//! line, the thread count and the wall times.

mod common;

use common::assert_same_campaign;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("campaign")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn latdyn(args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_latdyn"));
    c.args(args)
        .current_dir(root())
        .env_remove("LATDYN_FAULT_PANIC")
        .env_remove("RAYON_NUM_THREADS");
    c
}

fn run(mut c: Command) -> Output {
    c.output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn json(o: &Output) -> serde_json::Value {
    serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|e| panic!("stdout is not JSON ({e}); stderr:\n{}", stderr(o)))
}

fn indices(v: &serde_json::Value) -> Vec<usize> {
    v.as_array()
        .unwrap_or_else(|| panic!("not a list: {v}"))
        .iter()
        .map(|x| x.as_u64().unwrap() as usize)
        .collect()
}

const PENDULUM: &[&str] = &[
    "models/pendulum.toml",
    "--vary",
    "theta0=0.3:2.5:10",
    "--set",
    "t_end=0.5",
];

fn sweep(base: &[&str], extra: &[&str]) -> Command {
    let mut args = vec!["sweep"];
    args.extend_from_slice(base);
    args.extend_from_slice(extra);
    latdyn(&args)
}

/// Shard `k` of `n` of the sweep `base` (plus `extra`) into `dir/s{k}.h5`; it must complete.
fn shard(dir: &Path, base: &[&str], k: usize, n: usize, extra: &[&str]) -> PathBuf {
    let p = dir.join(format!("s{k}.h5"));
    let shard = format!("{k}/{n}");
    let mut e = vec!["--shard", &shard, "-o", s(&p)];
    e.extend_from_slice(extra);
    let o = run(sweep(base, &e));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    p
}

/// `latdyn merge SHARDS... -o OUT` plus `extra`.
fn merge(shards: &[&Path], out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["merge"];
    args.extend(shards.iter().map(|p| s(p)));
    args.extend_from_slice(&["-o", s(out)]);
    args.extend_from_slice(extra);
    run(latdyn(&args))
}

#[test]
fn merged_shards_run_on_different_thread_counts_equal_the_single_sweep_bit_for_bit() {
    let dir = scratch("merge_threads");
    // spinning hub + --frequency: sensors, status and derived quantities all merge
    let base = &[
        "models/rotating_cantilever.toml",
        "--set",
        "dt=0.01",
        "--vary",
        "omega=1:5:7",
        "--set",
        "t_end=0.5",
        "--frequency",
        "tip_flap",
    ];
    let full = dir.join("full.h5");
    let o = run(sweep(base, &["--threads", "2", "-o", s(&full)]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let mut shards = Vec::new();
    for (k, threads) in [(1, "1"), (2, "2"), (3, "3")] {
        let p = dir.join(format!("s{k}.h5"));
        let shard = format!("{k}/3");
        let mut c = sweep(
            base,
            &["--shard", &shard, "--threads", threads, "-o", s(&p)],
        );
        if k == 3 {
            // rayon's own variable too: the thread pool of the sweep is explicit
            c.env("RAYON_NUM_THREADS", "1");
        }
        let o = run(c);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        shards.push(p);
    }
    let merged = dir.join("merged.h5");
    // shards in another order than their index: the merge places rows by global index
    let o = run(latdyn(&[
        "merge",
        s(&shards[2]),
        s(&shards[0]),
        s(&shards[1]),
        "-o",
        s(&merged),
        "--json",
    ]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = json(&o);
    assert_eq!(r["status"], "complete");
    assert_eq!(r["variants"], 7);
    assert_eq!(r["completed"], 7);
    for k in [
        "missing",
        "failed",
        "interrupted",
        "duplicated",
        "to_resume",
    ] {
        assert!(indices(&r[k]).is_empty(), "{k}: {}", r[k]);
    }
    assert_same_campaign(&full, &merged);
}

#[test]
fn merge_reports_missing_indices_and_refuses_repeated_shards_and_other_campaigns() {
    let dir = scratch("merge_checks");
    let sh = |k: usize, extra: &[&str]| {
        let p = dir.join(format!("s{k}{}.h5", extra.len()));
        let shard = format!("{k}/3");
        let mut e = vec!["--shard", &shard, "-o", s(&p)];
        e.extend_from_slice(extra);
        let o = run(sweep(PENDULUM, &e));
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        p
    };
    let (s1, s3) = (sh(1, &[]), sh(3, &[]));
    let merged = dir.join("m.h5");
    let o = run(latdyn(&[
        "merge",
        s(&s1),
        s(&s3),
        "-o",
        s(&merged),
        "--json",
    ]));
    assert_eq!(o.status.code(), Some(4), "incomplete: {}", stderr(&o));
    let r = json(&o);
    // shard 2/3 holds the global indices ≡ 1 (mod 3)
    assert_eq!(indices(&r["missing"]), vec![1, 4, 7]);
    assert_eq!(indices(&r["to_resume"]), vec![1, 4, 7]);
    assert_eq!(r["completed"], 7);
    assert_eq!(r["status"], "incomplete");
    let f = rust_hdf5::H5File::open(&merged).unwrap();
    assert_eq!(f.attr_string("status").unwrap(), "interrupted");
    let state = f
        .dataset("status/state")
        .unwrap()
        .read_raw::<i32>()
        .unwrap();
    assert_eq!(state, vec![2, 0, 2, 2, 0, 2, 2, 0, 2, 2]);

    // the same shard twice: refused, the repeated indices named, nothing written
    let twice = dir.join("twice.h5");
    let o = run(latdyn(&[
        "merge",
        s(&s1),
        s(&s3),
        s(&s1),
        "-o",
        s(&twice),
        "--json",
    ]));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(indices(&json(&o)["duplicated"]), vec![0, 3, 6, 9]);
    assert!(stderr(&o).contains("more than one shard"), "{}", stderr(&o));
    assert!(!twice.exists());

    // a shard of another campaign (another --set): refused, naming what differs
    let other = sh(2, &["--set", "m=2"]);
    let o = run(latdyn(&["merge", s(&s1), s(&other), "-o", s(&twice)]));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("another campaign") && e.contains("set:"), "{e}");
    assert!(!twice.exists());

    // a file without a campaign identity (a `run`) is refused with that reason
    let single = dir.join("run.h5");
    let o = run(latdyn(&[
        "run",
        "models/pendulum.toml",
        "--set",
        "t_end=0.1",
        "-o",
        s(&single),
    ]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = run(latdyn(&["merge", s(&s1), s(&single), "-o", s(&twice)]));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("no campaign identity"),
        "{}",
        stderr(&o)
    );

    // the output cannot be one of the inputs
    let o = run(latdyn(&["merge", s(&s1), s(&s3), "-o", s(&s1)]));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn resume_completes_a_merge_with_gaps_to_the_single_sweep_and_refuses_a_changed_campaign() {
    let dir = scratch("resume_merge");
    let full = dir.join("full.h5");
    let o = run(sweep(PENDULUM, &["-o", s(&full)]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let (s1, s3) = (
        shard(&dir, PENDULUM, 1, 3, &[]),
        shard(&dir, PENDULUM, 3, 3, &[]),
    );
    let merged = dir.join("m.h5");
    let o = merge(&[&s1, &s3], &merged, &[]);
    assert_eq!(o.status.code(), Some(4), "{}", stderr(&o));
    let before = std::fs::read(&merged).unwrap();

    // another t_end is another campaign: refused, the file untouched
    let changed = [
        "models/pendulum.toml",
        "--vary",
        "theta0=0.3:2.5:10",
        "--set",
        "t_end=0.6",
    ];
    let o = run(sweep(&changed, &["--resume", s(&merged)]));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("definition changed") && stderr(&o).contains("set:"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(&merged).unwrap(), before, "file untouched");

    let o = run(sweep(
        PENDULUM,
        &["--resume", s(&merged), "--json", "--threads", "1"],
    ));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let ran: Vec<u64> = json(&o)["variants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["index"].as_u64().unwrap())
        .collect();
    assert_eq!(ran, vec![1, 4, 7], "only the missing variants run");
    assert_same_campaign(&full, &merged);
}

fn spawn(mut c: Command) -> Child {
    c.stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

#[test]
fn resume_completes_a_shard_stopped_by_sigterm_to_the_values_of_an_uninterrupted_shard() {
    let dir = scratch("resume_sigterm");
    // 40 variants of ~0.15 s on one thread, a flush at most every 2 s: SIGTERM after the
    // first flush lands mid-shard. With t_end = 2 the shard took 1.56 s once the solver
    // got faster and ended before its first flush, so t_end = 8 (about 6 s) keeps a
    // margin of 3 over the flush interval. `--batch 1`: variants end one by one (a
    // batch's variants end together, so the first flush could come with the last)
    let base = &[
        "models/rotating_cantilever.toml",
        "--set",
        "dt=0.01",
        "--vary",
        "omega=1:5:80",
        "--set",
        "t_end=8",
    ];
    let whole = dir.join("whole.h5");
    let o = run(sweep(base, &["--shard", "1/2", "-o", s(&whole)]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let cut = dir.join("cut.h5");
    let child = spawn(sweep(
        base,
        &[
            "--shard",
            "1/2",
            "--threads",
            "1",
            "--batch",
            "1",
            "-o",
            s(&cut),
        ],
    ));
    common::wait_until(60, "a flushed variant", || {
        common::completed_variants(&cut) > 0
    });
    let st = Command::new("kill")
        .args(["-s", "TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(4), "{}", stderr(&out));
    let done = common::completed_variants(&cut);
    assert!(
        done > 0 && done < 40,
        "stopped mid-shard: {done} of 40 completed"
    );
    let o = run(latdyn(&[
        "merge",
        s(&cut),
        "-o",
        s(&dir.join("m.h5")),
        "--json",
    ]));
    assert_eq!(o.status.code(), Some(4), "{}", stderr(&o));
    let r = json(&o);
    let mut open = indices(&r["missing"]);
    open.extend(indices(&r["interrupted"]));
    open.sort_unstable();
    assert_eq!(open, indices(&r["to_resume"]));
    // the other shard's indices (odd) are missing too; of this shard, the unfinished
    let mine: Vec<usize> = open.iter().copied().filter(|g| g % 2 == 0).collect();
    assert_eq!(mine.len(), 40 - done, "{r}");
    assert!(
        !indices(&r["interrupted"]).is_empty(),
        "a variant was in flight: {r}"
    );

    let o = run(sweep(base, &["--resume", s(&cut)]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_same_campaign(&whole, &cut);
}

#[test]
fn merged_campaign_opens_in_xarray_with_named_dimensions_and_parameter_coordinates() {
    let ok = Command::new("python3")
        .args(["-c", "import h5py, xarray, h5netcdf"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        if std::env::var_os("CI").is_some() {
            panic!("xarray or h5netcdf is not installed, but CI is set: .ci/run installs them");
        }
        println!("SKIPPED: python3 -c 'import h5py, xarray, h5netcdf' failed");
        return;
    }
    let dir = scratch("xarray");
    let base = &[
        "models/rotating_cantilever.toml",
        "--set",
        "dt=0.01",
        "--vary",
        "omega=1:5:9",
        "--set",
        "t_end=0.3",
    ];
    let shards = [shard(&dir, base, 1, 2, &[]), shard(&dir, base, 2, 2, &[])];
    let merged = dir.join("m.h5");
    let o = merge(&[&shards[0], &shards[1]], &merged, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // two varied parameters in a table out of order: the axis stays `variant`, and omega
    // is a coordinate on it (set_xindex, then sel)
    let table = dir.join("table.csv");
    std::fs::write(&table, "omega,EI\n3,1\n1,1.2\n5,0.9\n").unwrap();
    let from_table = dir.join("t.h5");
    let o = run(latdyn(&[
        "sweep",
        "models/rotating_cantilever.toml",
        "--set",
        "dt=0.01",
        "--variants",
        s(&table),
        "--set",
        "t_end=0.3",
        "-o",
        s(&from_table),
    ]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // omega = 3.1 is nearest to the grid value 3 (variant 4); shard 2/2 has it too; the
    // --vary range names the axis `omega`, so `ds.sel(omega=3.1, method="nearest")` works
    // as it stands
    for (file, axis) in [
        (&merged, "omega"),
        (&shards[1], "omega"),
        (&from_table, "variant"),
    ] {
        let out = Command::new("python3")
            .args(["-W", "ignore"])
            .arg(root().join("tests/xarray_campaign.py"))
            .arg(file)
            .args(["omega", "3.1", "tip_flap"])
            .output()
            .unwrap();
        assert!(
            out.status.success()
                && String::from_utf8_lossy(&out.stdout).trim_end() == format!("OK {axis}"),
            "{}: {}{}",
            file.display(),
            String::from_utf8_lossy(&out.stdout),
            stderr(&out)
        );
    }
}

#[test]
fn plan_lists_each_variants_shard_as_the_sweep_writes_it_and_a_probe_cost() {
    let dir = scratch("plan");
    let o = run(sweep(
        PENDULUM,
        &["--plan", "--shards", "3", "--probe", "2", "--json"],
    ));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let p = json(&o);
    assert_eq!(p["variants"], 10);
    assert_eq!(p["variants_per_shard"], serde_json::json!([4, 3, 3]));
    let table = p["table"].as_array().unwrap();
    assert_eq!(table.len(), 10);
    let runs = p["probe"]["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    for r in runs {
        assert_eq!(r["status"], "completed");
        assert!(r["per_variant_s"].as_f64().unwrap() > 0.0);
    }
    assert!(p["estimate"]["cpu_s"].as_f64().unwrap() > 0.0);
    // what --shard 2/3 writes is what the plan says shard 2 holds, same campaign
    let shard = dir.join("s2.h5");
    let o = run(sweep(PENDULUM, &["--shard", "2/3", "-o", s(&shard)]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let f = rust_hdf5::H5File::open(&shard).unwrap();
    let gi = f
        .dataset("status/global_index")
        .unwrap()
        .read_raw::<i64>()
        .unwrap();
    let planned: Vec<i64> = table
        .iter()
        .filter(|r| r["shard"] == 2)
        .map(|r| r["index"].as_i64().unwrap())
        .collect();
    assert_eq!(gi, planned);
    assert_eq!(f.attr_string("campaign_hash").unwrap(), p["campaign_hash"]);
    let theta = table[4]["parameters"]["theta0"].as_f64().unwrap();
    assert!((theta - (0.3 + 4.0 * 2.2 / 9.0)).abs() < 1e-12, "{theta}");
}

/// The plan charges the mesh twins the sweep will run (`--mesh-check`, auto: the first,
/// middle and last variant) at the cost of one probed twin, each to its shard's task;
/// `never` charges none.
#[test]
fn plan_charges_the_mesh_twins_of_the_sampled_variants_to_their_shards() {
    let base = &[
        "models/rotating_cantilever.toml",
        "--set",
        "t_end=0.5",
        "--set",
        "elements=10",
        "--vary",
        "omega=1:3:5",
    ];
    let plan = |extra: &[&str]| {
        let mut a = vec!["--plan", "--shards", "2", "--probe", "1", "--json"];
        a.extend_from_slice(extra);
        let o = run(sweep(base, &a));
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        json(&o)
    };
    let p = plan(&[]);
    let e = &p["estimate"];
    let m = &e["mesh_check"];
    assert_eq!(m["sampled"], serde_json::json!([0, 2, 4]), "{e}");
    assert_eq!(m["twin_probe"]["index"], 2);
    assert_eq!(m["twin_probe"]["status"], "completed");
    let twin = m["twin_per_variant_s"].as_f64().unwrap();
    let per_variant = p["probe"]["per_variant_s"].as_f64().unwrap();
    assert!(twin > 0.0 && per_variant > 0.0, "{e}");
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1.0);
    assert!(close(m["cpu_s"].as_f64().unwrap(), 3.0 * twin), "{e}");
    assert!(
        close(e["cpu_s"].as_f64().unwrap(), 5.0 * per_variant + 3.0 * twin),
        "{e}"
    );
    // shard 1 holds variants 0, 2, 4 and all three twins
    assert!(
        close(
            e["per_task_wall_s"].as_f64().unwrap(),
            3.0 * per_variant + 3.0 * twin
        ),
        "{e}"
    );
    let p = plan(&["--mesh-check", "never"]);
    let e = &p["estimate"];
    assert_eq!(e["mesh_check"]["mode"], "never");
    assert_eq!(e["mesh_check"]["twin_probe"], serde_json::Value::Null);
    let per_variant = p["probe"]["per_variant_s"].as_f64().unwrap();
    assert!(
        close(e["cpu_s"].as_f64().unwrap(), 5.0 * per_variant),
        "{e}"
    );
}

#[test]
fn merge_of_more_shards_than_variants_skips_the_empty_ones_and_equals_the_single_sweep() {
    let dir = scratch("merge_empty");
    let base = &[
        "models/pendulum.toml",
        "--vary",
        "theta0=0.5:2:3",
        "--set",
        "t_end=0.2",
    ];
    let full = dir.join("full.h5");
    let o = run(sweep(base, &["-o", s(&full)]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let shards: Vec<PathBuf> = (1..=5).map(|k| shard(&dir, base, k, 5, &[])).collect();
    let merged = dir.join("m.h5");
    let refs: Vec<&Path> = shards.iter().map(PathBuf::as_path).collect();
    let o = merge(&refs, &merged, &["--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = json(&o);
    assert_eq!(r["completed"], 3);
    assert_eq!(r["shards"][4]["variants"], 0, "{r}");
    assert_same_campaign(&full, &merged);
}

#[test]
fn merge_and_resume_carry_the_verification_of_shard_1() {
    let dir = scratch("merge_verify");
    let verify = ["--verify", "2"];
    let shards = [
        shard(&dir, PENDULUM, 1, 2, &verify),
        shard(&dir, PENDULUM, 2, 2, &verify),
    ];
    let merged = dir.join("m.h5");
    let o = merge(&[&shards[1], &shards[0]], &merged, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let read = |p: &Path, name: &str| -> Vec<f64> {
        rust_hdf5::H5File::open(p)
            .unwrap()
            .dataset(name)
            .unwrap()
            .read_numeric_as::<f64>()
            .unwrap()
    };
    let variants = |p: &Path| -> Vec<i64> {
        rust_hdf5::H5File::open(p)
            .unwrap()
            .dataset("verification/variants")
            .unwrap()
            .read_raw::<i64>()
            .unwrap()
    };
    assert_eq!(variants(&shards[0]).len(), 2);
    assert_eq!(variants(&shards[0]), variants(&merged));
    for name in [
        "verification/max_rel_diff",
        "verification/rel_diff/angle",
        "verification/refined_max/energy",
        "verification/dt",
    ] {
        let (a, b) = (read(&shards[0], name), read(&merged, name));
        assert!(!a.is_empty(), "{name}");
        assert!(
            a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()) && a.len() == b.len(),
            "{name}: {a:?} vs {b:?}"
        );
    }
    // a resume that reruns nothing keeps the file as it was
    let before = dir.join("before.h5");
    std::fs::copy(&merged, &before).unwrap();
    let o = run(sweep(PENDULUM, &["--resume", s(&merged)]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_same_campaign(&before, &merged);
}

/// A varied dt that does not divide the output interval is stepped as `run` steps it
/// (the fewest equal steps per interval) and said so per variant, as `run` says it; until
/// session 47 only the base model's note was printed (a probe: `--vary dt=3e-4:3e-4:2`
/// ran steps of 2.94e-4 s silently).
#[test]
fn a_varied_step_that_does_not_divide_the_output_interval_is_noted_per_variant() {
    let dir = std::env::temp_dir().join(format!("latdyn_spread_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("spread.h5");
    let o = common::latdyn(&[
        "sweep",
        "models/rotating_cantilever.toml",
        "--vary",
        "dt=1e-3:2.5e-4:4",
        "--set",
        "t_end=0.02",
        "-o",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    // 1e-3, 7.5e-4, 5e-4, 2.5e-4: only 7.5e-4 does not divide 1e-2
    assert!(
        err.contains("1 variant(s) step other than their dt: indices 1 (")
            && err.contains("14 equal steps"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
