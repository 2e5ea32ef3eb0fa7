//! `sweep --verify K`: refined reruns of K variants and the measured discretisation
//! error (README "Verification").

mod common;

use common::latdyn;
use latdyn::model::{load, load_refined};
use latdyn::solver::dynamics::output_times;
use std::path::{Path, PathBuf};
use std::process::Command;

fn json(out: &std::process::Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "latdyn failed ({}): {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

fn out_path(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("verify");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    let _ = std::fs::remove_file(&p);
    p
}

#[test]
fn refinement_doubles_every_beams_elements_and_halves_dt_on_the_same_outputs() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 8, "{files:?}");
    for f in &files {
        let b = load(f, &[]).unwrap();
        let r = load_refined(f, &[], 2).unwrap();
        let name = f.display();
        assert_eq!(r.elements.len(), 2 * b.elements.len(), "{name}");
        for (bb, rb) in b.beams.iter().zip(&r.beams) {
            assert_eq!(
                rb.elements.len(),
                2 * bb.elements.len(),
                "{name}: {}",
                bb.name
            );
        }
        assert_eq!(r.solver.dt, b.solver.dt / 2.0, "{name}");
        assert_eq!(r.solver.dt_min, b.solver.dt_min / 2.0, "{name}");
        assert_eq!(output_times(&r), output_times(&b), "{name}");
        // every node of the base model is in the refined one, at the same place
        for (i, n) in b.node_names.iter().enumerate() {
            let j = r
                .node_index(n)
                .unwrap_or_else(|| panic!("{name}: node {n} lost"));
            assert_eq!(r.x0[j], b.x0[i], "{name}: node {n}");
        }
        // the same sensors with the same components
        let layout = |m: &latdyn::model::Model| -> Vec<(String, usize)> {
            m.sensors
                .iter()
                .map(|s| (s.name.clone(), latdyn::sensors::components(&s.kind).len()))
                .collect()
        };
        assert_eq!(layout(&r), layout(&b), "{name}");
    }
    // a model without beams: only dt is refined
    let p = dir.join("pendulum.toml");
    let r = load_refined(&p, &[("dt".into(), 0.004)], 2).unwrap();
    assert_eq!((r.elements.len(), r.solver.dt), (0, 0.002));
}

/// models/cantilever.toml (a step tip load) with `t_end` (0.2 s) and `dt` as
/// parameters, output at every step (`output_dt = 0`) and only the `tip` sensor.
fn beam_model() -> PathBuf {
    let src = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/cantilever.toml"),
    )
    .unwrap();
    let mut text = src.clone();
    for (from, to) in [
        ("elements = 8\n", "elements = 8\nt_end = 0.2\ndt = 1e-3\n"),
        ("t_end = 1.0\n", "t_end = \"t_end\"\n"),
        (
            "dt = 1e-3\noutput_dt = 0.01\n",
            "dt = \"dt\"\noutput_dt = 0\n",
        ),
    ] {
        assert!(
            text.contains(from),
            "models/cantilever.toml changed: {from:?}"
        );
        text = text.replacen(from, to, 1);
    }
    let at = text.find("[[sensors]]\nname = \"root_moment\"").unwrap();
    let end = at + text[at..].find("[solver]").unwrap();
    text.replace_range(at..end, "");
    let p = Path::new(env!("CARGO_TARGET_TMPDIR")).join("verify_beam.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// A sweep of the beam over 5 tip loads at (elements, dt).
fn beam_sweep(
    elements: &str,
    dt: &str,
    extra: &[&str],
    out: Option<&Path>,
) -> std::process::Output {
    let model = beam_model();
    let model = model.display().to_string();
    let e = format!("elements={elements}");
    let d = format!("dt={dt}");
    let mut args = vec![
        "sweep",
        &model,
        "--vary",
        "P=1:2:5",
        "--set",
        &e,
        "--set",
        &d,
        "--threads",
        "2",
        "--json",
    ];
    args.extend_from_slice(extra);
    let o = out.map(|p| p.display().to_string());
    if let Some(o) = &o {
        args.extend(["-o", o]);
    }
    latdyn(&args)
}

/// Fine: 8 elements, dt = 1 ms (measured: 0.54 % at most). Coarse: 2 elements, dt =
/// 40 ms (5.3 %). (Until session 28 the coarse case was dt = 20 ms, 5.0 % off; most of
/// that was the start's zero acceleration where the massless torsion made M singular:
/// with a consistent start it is 0.86 %.)
const FINE: (&str, &str) = ("8", "1e-3");
const COARSE: (&str, &str) = ("2", "0.04");

#[test]
fn verify_fine_campaign_reports_small_differences_without_warning() {
    let out = beam_sweep(FINE.0, FINE.1, &["--verify", "2"], None);
    let v = json(&out);
    let ver = &v["verification"];
    assert_eq!(ver["variants"], serde_json::json!([0, 4]), "{ver}");
    assert_eq!(ver["target"], 1e-2);
    assert_eq!(ver["target_source"], "default");
    let worst = ver["max_rel_diff"].as_f64().unwrap();
    assert!(worst > 1e-4 && worst < 1e-2, "{ver}");
    assert_eq!(ver["warnings"], serde_json::json!([]), "{ver}");
    for pv in ver["per_variant"].as_array().unwrap() {
        assert_eq!(pv["status"], "verified", "{pv}");
        assert_eq!(pv["elements"], serde_json::json!([8, 16]));
        assert_eq!(pv["dt"], serde_json::json!([1e-3, 5e-4]));
    }
    assert!(
        ver["per_sensor"]["tip"]["per_component"]["z"]
            .as_f64()
            .unwrap()
            < 1e-2
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("verify: 2 of 2 variant(s) (0, 4)"),
        "{stderr}"
    );
    assert!(stderr.contains("target 1.00 % (default)"), "{stderr}");
    assert!(!stderr.contains("warning: verify"), "{stderr}");
}

#[test]
fn verify_coarse_campaign_warns_naming_sensor_and_variant() {
    let out = beam_sweep(COARSE.0, COARSE.1, &["--verify", "2"], None);
    let v = json(&out);
    let ver = &v["verification"];
    let worst = ver["max_rel_diff"].as_f64().unwrap();
    assert!(worst > 2e-2, "{ver}");
    let warnings = ver["warnings"].as_array().unwrap();
    assert!(!warnings.is_empty(), "{ver}");
    let w = warnings[0].as_str().unwrap();
    assert!(
        w.contains("variant 0 (P=1)") && w.contains("sensor `tip`"),
        "{w}"
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("warning: verify: variant"), "{stderr}");
    assert!(stderr.contains("EXCEEDED"), "{stderr}");
    // the campaign's own target replaces the default: 10 % is met (at dt = 20 ms; at
    // 40 ms the axial tip.x moves 12 % of its small range)
    let v = json(&beam_sweep(
        COARSE.0,
        "0.02",
        &["--verify", "1", "--accuracy", "0.1"],
        None,
    ));
    let ver = &v["verification"];
    assert_eq!(ver["target"], 0.1);
    assert_eq!(ver["target_source"], "--accuracy");
    assert_eq!(ver["variants"], serde_json::json!([2]));
    assert_eq!(ver["warnings"], serde_json::json!([]), "{ver}");
}

#[test]
fn verify_leaves_the_campaign_results_bit_identical() {
    let strip = |out: std::process::Output| {
        let mut v = json(&out);
        for x in v["variants"].as_array_mut().unwrap() {
            x.as_object_mut().unwrap().remove("wall_s");
        }
        v["variants"].clone()
    };
    let plain = strip(beam_sweep(COARSE.0, COARSE.1, &[], None));
    let verified = strip(beam_sweep(COARSE.0, COARSE.1, &["--verify", "5"], None));
    assert_eq!(plain, verified);
}

#[test]
fn verify_count_out_of_range_is_a_usage_error() {
    for k in ["0", "6"] {
        let out = latdyn(&[
            "sweep",
            "models/pendulum.toml",
            "--vary",
            "theta0=0.5:1:5",
            "--verify",
            k,
        ]);
        assert_eq!(out.status.code(), Some(2), "--verify {k}");
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(
            e.contains(&format!("--verify {k}: need from 1 to 5 variants")),
            "{e}"
        );
    }
    // sharded: K is bounded by shard 1's variants, in every shard
    let out = latdyn(&[
        "sweep",
        "models/pendulum.toml",
        "--vary",
        "theta0=0.5:1:5",
        "--shard",
        "2/2",
        "--verify",
        "4",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("shard 1/2, which has 3"), "{e}");
}

#[test]
fn verify_runs_in_shard_one_only() {
    let run = |shard: &str| {
        json(&latdyn(&[
            "sweep",
            "models/pendulum.toml",
            "--vary",
            "theta0=0.5:1:5",
            "--set",
            "t_end=0.5",
            "--set",
            "dt=0.01",
            "--shard",
            shard,
            "--verify",
            "2",
            "--json",
        ]))
    };
    let v1 = run("1/2");
    assert_eq!(v1["verification"]["variants"], serde_json::json!([0, 4]));
    let v2 = run("2/2");
    assert!(
        v2["verification"]["skipped"].is_string(),
        "{}",
        v2["verification"]
    );
}

fn h5py_available() -> bool {
    Command::new("python3")
        .args(["-c", "import h5py"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false)
}

#[test]
fn verification_group_in_the_campaign_file_reads_with_h5py() {
    let path = out_path("verify.h5");
    let v = json(&beam_sweep(
        COARSE.0,
        COARSE.1,
        &["--verify", "2"],
        Some(&path),
    ));
    let n_warnings = v["verification"]["warnings"].as_array().unwrap().len();
    assert!(n_warnings > 0);
    let worst = v["verification"]["max_rel_diff"].as_f64().unwrap();
    if !h5py_available() {
        if std::env::var_os("CI").is_some() {
            panic!("h5py is not installed, but CI is set");
        }
        println!("SKIPPED: h5py not installed");
        return;
    }
    let script = r#"
import sys, json, h5py
with h5py.File(sys.argv[1], "r") as f:
    g = f["verification"]
    out = {
        "target": float(g["target"][()]),
        "target_source": g["target_source"].asstr()[()],
        "variants": [int(x) for x in g["variants"][:]],
        "status": list(g["status"].asstr()[:]),
        "dt": g["dt"][:].tolist(),
        "elements": g["elements"][:].tolist(),
        "max_rel_diff": float(g["max_rel_diff"][()]),
        "warnings": list(g["warnings"].asstr()[:]),
        "rel_diff_tip": list(g["rel_diff/tip"].shape),
        "components": [c.decode() if isinstance(c, bytes) else c for c in g["rel_diff/tip"].attrs["components"]],
        "refined_max": list(g["refined_max/tip"].shape),
        "status_root": f.attrs["status"].decode() if isinstance(f.attrs["status"], bytes) else f.attrs["status"],
    }
print(json.dumps(out))
"#;
    let out = Command::new("python3")
        .args(["-c", script])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let h: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(h["target"], 1e-2);
    assert_eq!(h["target_source"], "default");
    assert_eq!(h["variants"], serde_json::json!([0, 4]));
    assert_eq!(h["status"], serde_json::json!(["verified", "verified"]));
    assert_eq!(h["dt"], serde_json::json!([[0.04, 0.02], [0.04, 0.02]]));
    assert_eq!(h["elements"], serde_json::json!([[2, 4], [2, 4]]));
    assert_eq!(h["max_rel_diff"].as_f64().unwrap(), worst);
    assert_eq!(h["warnings"].as_array().unwrap().len(), n_warnings);
    assert_eq!(h["rel_diff_tip"], serde_json::json!([2, 6]));
    assert_eq!(h["refined_max"], serde_json::json!([2, 6]));
    assert_eq!(h["status_root"], "complete");
}

/// `--verify` measures a component at rest against the largest magnitude in its unit
/// over the whole model: the shipped four-bar's coupler keeps its orientation, and its
/// rz (1e-13 rad of round-off, the other angles of its sensor 0 too) read 175 %
/// "exceeded" beside hinge angles of 0.5 rad (a probe, session 46).
#[test]
fn verify_does_not_read_a_round_off_rotation_as_discretisation_error() {
    let o = Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args([
            "sweep",
            "models/fourbar.toml",
            "--vary",
            "v0=0.5:2:3",
            "--verify",
            "2",
            "--json",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let v = json(&o);
    let ver = &v["verification"];
    assert!(ver["max_rel_diff"].as_f64().unwrap() < 1e-2, "{ver}");
    assert_eq!(ver["warnings"], serde_json::json!([]), "{ver}");
}
