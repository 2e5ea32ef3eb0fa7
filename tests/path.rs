//! Path following (`statics --path`): Lee's frame against an independent solution and
//! under refinement, the Mini-Mast bay as a quasi-static deployment, sweeps bit for bit,
//! mechanisms and bad options.

mod common;
use common::*;
use latdyn::solver::path::{self, Control, PathOptions};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_latdyn"))
}

fn models(name: &str) -> String {
    format!("{}/models/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// Lee frame path at `elements` per 24 until the load point's vertical deflection
/// crosses `until`.
fn lee_path(elements: f64, until: f64) -> (latdyn::model::Model, path::PathResult) {
    let m = shipped("lee_frame.toml", &[("elements", elements)]);
    let mut o = PathOptions::new(Control::Load, f64::INFINITY);
    o.until = Some(path::parse_until(&m, &format!("load_point.y={until}")).unwrap());
    let r = path::follow(&m, &o);
    assert!(r.error.is_none(), "{:?}", r.error.map(|e| e.to_string()));
    (m, r)
}

/// The limit load of the frame (P = 1e4 reference load) at the fold.
fn limit_load(r: &path::PathResult) -> f64 {
    let lp = r
        .limit_points
        .iter()
        .find(|l| l.kind == "max")
        .expect("a maximum of the load");
    lp.lambda_fit * 1e4
}

/// Independent reference: examples/lee_frame_reference.py (a planar co-rotational
/// Euler-Bernoulli frame in numpy, traced by switching displacement control, no code or
/// algorithm shared with latdyn), limit loads of its 20/40/80-element meshes
/// 18658.773, 18582.467, 18563.176: observed order 1.98, Richardson-extrapolated limit
/// load 18556.65.
const REFERENCE_LIMIT_LOAD: f64 = 18556.65;

#[test]
fn lee_frame_limit_load_converges_at_second_order_to_the_independent_solution() {
    // Meshes of 10, 20 and 40 elements (elements = 1, 2, 4 per length 24). Measured
    // (release, same code): 17493.47, 18276.58, 18485.74, and 18538.92, 18552.27 at 80
    // and 160 elements: differences shrink ×3.74, ×3.93, ×3.98, second order.
    let l: Vec<f64> = [1.0, 2.0, 4.0]
        .iter()
        .map(|&n| limit_load(&lee_path(n, -52.0).1))
        .collect();
    let order = ((l[1] - l[0]) / (l[2] - l[1])).log2();
    // the coarsest pair still carries higher-order terms (measured 1.90; 1.98 and 1.99
    // on the finer triples): second order within ±0.2
    assert!(
        (order - 2.0).abs() < 0.2,
        "observed order {order} from {l:?}"
    );
    // p = 2 Richardson extrapolation of the 20/40-element pair; its remaining error is
    // the next term, (1.98 → 2) of a 209 difference ≈ 1 part in 1e4 of the load (measured
    // 18555.46); the reference itself is extrapolated to ~0.1. Bound: 3e-4.
    let ext = l[2] + (l[2] - l[1]) / 3.0;
    assert!(
        (ext / REFERENCE_LIMIT_LOAD - 1.0).abs() < 3e-4,
        "extrapolated {ext} vs independent {REFERENCE_LIMIT_LOAD} ({l:?})"
    );
    // the literature's ~1.85e4 (Schweizerhof & Wriggers 1986; Simo & Vu-Quoc 1986) is
    // met by every mesh from 20 elements up within 1.5 %
    assert!(l[1..].iter().all(|&x| (x / 1.85e4 - 1.0).abs() < 0.015));
}

/// The reference path (u, v, load) of the 80-element independent solution.
fn reference_curve() -> Vec<[f64; 3]> {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/lee_frame_reference_80el.csv"
    ))
    .unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

/// Distance of (u, v) from the reference polyline and the load interpolated there.
fn on_reference(curve: &[[f64; 3]], u: f64, v: f64) -> (f64, f64) {
    let mut best = (f64::INFINITY, f64::NAN);
    for w in curve.windows(2) {
        let (a, b) = (w[0], w[1]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let t = (((u - a[0]) * dx + (v - a[1]) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
        let (px, py) = (a[0] + t * dx, a[1] + t * dy);
        let d = ((px - u).powi(2) + (py - v).powi(2)).sqrt();
        if d < best.0 {
            best = (d, a[2] + t * (b[2] - a[2]));
        }
    }
    best
}

#[test]
fn lee_frame_path_passes_limit_point_and_snap_back_to_deflection_80_on_the_independent_curve() {
    let (m, r) = lee_path(2.0, -80.0);
    let k = m.sensor_index("load_point").unwrap();
    let uv: Vec<(f64, f64)> = r.sensors.iter().map(|p| (p[k][0], p[k][1])).collect();
    // reached the deflection 80
    assert!(uv.last().unwrap().1 <= -80.0, "{:?}", uv.last());
    assert_eq!(r.stopped_by, "until");
    // a maximum of the load, then a minimum (negative: the frame pulls back)
    let kinds: Vec<&str> = r.limit_points.iter().map(|l| l.kind).collect();
    assert_eq!(kinds, ["max", "min"], "{:?}", r.limit_points);
    assert!(r.limit_points[1].lambda < 0.0);
    // snap-back: the deflection turns back (|v| falls by more than 5 after its first
    // extreme beyond the limit point) before it grows to 80
    let i_min = (1..uv.len() - 1)
        .find(|&i| uv[i].1 < uv[i - 1].1 && uv[i].1 < uv[i + 1].1)
        .expect("v turns back");
    let back = uv[i_min..]
        .iter()
        .map(|p| p.1)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(
        back - uv[i_min].1 > 5.0,
        "v min {} back to {back}",
        uv[i_min].1
    );
    // det K changes sign at each fold, and nothing else is called a bifurcation
    let changes = r.det_sign.windows(2).filter(|w| w[0] != w[1]).count();
    assert_eq!(changes, 2, "{:?}", r.det_sign);
    assert!(r.bifurcations.is_empty(), "{:?}", r.bifurcations);
    // Every point on the independent 80-element curve: within 1.0 in (u, v) and 5 % of
    // the limit load in load. The 20-element mesh's own discretisation error is the
    // difference (measured 0.63 and 3.5 %; at 80 elements 0.044 and 0.27 %), largest in
    // the post-buckling arc where the curvature concentrates at the knee.
    let curve = reference_curve();
    for (i, (&(u, v), lam)) in uv.iter().zip(&r.lambda).enumerate() {
        let (d, load) = on_reference(&curve, u, v);
        assert!(d < 1.0, "point {i} (u {u}, v {v}) is {d} off the reference");
        assert!(
            (lam * 1e4 - load).abs() < 0.05 * REFERENCE_LIMIT_LOAD,
            "point {i}: load {} vs reference {load}",
            lam * 1e4
        );
    }
}

#[test]
fn minimast_bay_quasi_static_stroke_has_the_dynamic_moment_humps_and_a_fold_before_lock() {
    // The drivers' pseudo-time is the path parameter: the stroke Z(t) at equilibrium, no
    // inertia. The issue's description of the T = 1 s dynamic run (longeron upper-end
    // bending humps near 80 and 115 N·m, near-zero crossing at ~44° of longeron
    // rotation) is a quasi-static feature; the measured quasi-static path: 76.8 N·m at
    // 15°, 9.7 at 44.7°, 114.9 at 75°. Bounds: ±10 % on the humps (the dynamic run
    // overshoots them by up to 8 %, docs/studies/minimast_quasistatic.md), the crossing
    // within 40..48°.
    let m = shipped("minimast_bay.toml", &[]);
    let mut o = PathOptions::new(Control::Drivers, m.solver.t_end);
    o.limit_points = Some(1);
    let r = path::follow(&m, &o);
    assert!(r.error.is_none(), "{:?}", r.error.map(|e| e.to_string()));
    let top = m.sensor_index("longeron_top").unwrap();
    let rot = m.sensor_index("longeron_rotation").unwrap();
    let pts: Vec<(f64, f64)> = r
        .sensors
        .iter()
        .map(|p| {
            (
                p[rot][0].to_degrees(),
                (p[top][4].powi(2) + p[top][5].powi(2)).sqrt(),
            )
        })
        .collect();
    let peak = |lo: f64, hi: f64| {
        pts.iter()
            .filter(|p| p.0 >= lo && p.0 <= hi)
            .map(|p| p.1)
            .fold(0.0f64, f64::max)
    };
    let (h1, h2) = (peak(0.0, 30.0), peak(55.0, 95.0));
    assert!((h1 / 80.0 - 1.0).abs() < 0.1, "first hump {h1}");
    assert!((h2 / 115.0 - 1.0).abs() < 0.1, "second hump {h2}");
    let low = pts
        .iter()
        .filter(|p| p.0 > 30.0 && p.0 < 60.0)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    assert!(low.0 > 40.0 && low.0 < 48.0 && low.1 < 15.0, "{low:?}");
    // The stroke has a fold (a limit point in the pseudo-time) at 96.4 % of T: the
    // mid-hinges at ~170°, the upper triangle turned ~99.3°. Past it, equilibria need a
    // shorter stroke (the diagonals toggle over centre): the dynamic deployment snaps
    // through it and locks the mid-hinges at 180°, the quasi-static path cannot.
    assert_eq!(r.stopped_by, "limit_points");
    let fold = r.limit_points[0].lambda_fit;
    assert!(fold > 0.95 && fold < 0.98, "fold at t/T = {fold}");
    assert!(r.locks.is_empty());
    // (det K's sign does not mark this fold: in the 3-fold symmetric bay an even number
    // of eigenvalues may cross zero near it; the fold is found from Δλ turning)

    // A slow dynamic deployment (T = 4 s, 1000 steps of 4 ms) follows the path: at equal
    // stroke (t = τ·T; the drive is a function of t/T), up to 1 % of T before the fold
    // (where dq/dτ is infinite), every member moment within 0.2 % of its quasi-static
    // peak. Measured 0.031 % (diagonal A mid), 0.020 % (longeron top); the inertia part
    // falls as 1/T² (docs/studies/minimast_quasistatic.md: 0.32 %, 0.020 %, 0.001 % at
    // T = 1, 4, 16 s with dt = 1 ms).
    let (t_dyn, dt) = (4.0, 4e-3);
    let md = shipped(
        "minimast_bay.toml",
        &[("T", t_dyn), ("t_end", t_dyn), ("dt", dt)],
    );
    let (hist, _, err) = latdyn::solver::dynamics::run(&md, |_, _| {});
    assert!(err.is_none(), "{:?}", err.map(|e| e.to_string()));
    for name in ["longeron_top", "longeron_mid", "diagonal_a_mid"] {
        let k = m.sensor_index(name).unwrap();
        let bend = |v: &[f64]| (v[4].powi(2) + v[5].powi(2)).sqrt();
        let qs: Vec<f64> = r.sensors.iter().map(|p| bend(&p[k])).collect();
        let peak = qs.iter().fold(0.0f64, |a, &b| a.max(b));
        let dynv: Vec<f64> = hist.values[k].iter().map(|v| bend(v)).collect();
        let mut worst = 0.0f64;
        for (tau, q) in r.lambda.iter().zip(&qs) {
            if *tau > fold - 0.01 {
                continue;
            }
            let t = tau * t_dyn;
            let j = hist
                .t
                .partition_point(|&x| x < t)
                .clamp(1, hist.t.len() - 1);
            let w = (t - hist.t[j - 1]) / (hist.t[j] - hist.t[j - 1]);
            let d = dynv[j - 1] + w * (dynv[j] - dynv[j - 1]);
            worst = worst.max((d - q).abs() / peak);
        }
        assert!(
            worst < 2e-3,
            "{name}: dynamic − quasi-static up to {worst:.2e} of {peak}"
        );
    }
}

fn tmp(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("path_h5");
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join(name);
    let _ = std::fs::remove_file(&f);
    f
}

fn read(f: &std::path::Path, name: &str) -> Vec<f64> {
    let h5 = rust_hdf5::H5File::open(f).unwrap();
    h5.dataset(name).unwrap().read_raw::<f64>().unwrap()
}

#[test]
fn sweep_path_variants_are_bit_identical_to_the_same_path_alone() {
    // compared in the campaign files (binary f64), not through JSON text
    let lee = models("lee_frame.toml");
    let fs = tmp("sweep.h5");
    let common = ["--set", "elements=1", "--lambda-max", "1"];
    let out = bin()
        .args(["sweep", &lee, "--path", "--vary", "P=9000:12000:3"])
        .args(common)
        .args(["--threads", "2", "--json", "-o"])
        .arg(&fs)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let sweep: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let vs = sweep["variants"].as_array().unwrap();
    assert_eq!(vs.len(), 3);
    let n_time = read(&fs, "time").len();
    for (k, p) in ["9000", "10500", "12000"].iter().enumerate() {
        let f1 = tmp(&format!("alone{k}.h5"));
        let alone = bin()
            .args(["statics", &lee, "--path", "--set", &format!("P={p}")])
            .args(common)
            .arg("-o")
            .arg(&f1)
            .output()
            .unwrap();
        assert!(alone.status.success());
        let n = read(&f1, "time").len();
        assert_eq!(vs[k]["points"], n);
        for name in ["path_lambda", "load_point", "knee", "knee_moment"] {
            let a = read(&f1, &format!("sensors/{name}"));
            let all = read(&fs, &format!("sensors/{name}"));
            let nc = a.len() / n;
            let b = &all[k * n_time * nc..(k * n_time + n) * nc];
            let same = a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
            assert!(same, "variant {k} (P = {p}): {name} differs");
        }
        assert_eq!(vs[k]["stopped_by"], "max_param");
    }
}

#[test]
fn path_through_an_undriven_mechanism_names_its_free_coordinate() {
    // the four-bar has no driver and no hinge stiffness: a one-degree-of-freedom
    // mechanism that no load factor can hold
    let out = bin()
        .args(["statics", &models("fourbar.toml"), "--path", "--json"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["status"], "failed");
    let msg = v["message"].as_str().unwrap();
    assert!(
        msg.contains("zero-stiffness motion") && msg.contains("g1.angle"),
        "{msg}"
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("fourbar.toml"), "{err}");
}

#[test]
fn path_options_are_checked_and_named() {
    let lee = models("lee_frame.toml");
    let cases: [(&[&str], &str); 4] = [
        (&["--lambda-max", "2"], "need --path"),
        (&["--path", "--until", "nosuch.y=1"], "no sensor `nosuch`"),
        (&["--path", "--until", "load_point.w=1"], "no component `w`"),
        (
            &["--path", "--lambda-max=-1"],
            "not a finite positive number",
        ),
    ];
    for (args, want) in cases {
        let out = bin().arg("statics").arg(&lee).args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
    }
    // the points a path may keep count against the output limit before it runs
    let out = bin()
        .args(["statics", &lee, "--path"])
        .env("LATDYN_LIMITS", "output_values=20000")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--max-points") && err.contains("output_values"),
        "{err}"
    );
}

#[test]
fn path_campaign_file_holds_the_path_parameter_as_time() {
    let f = tmp("lee.h5");
    let out = bin()
        .args(["statics", &models("lee_frame.toml"), "--path"])
        .args(["--set", "elements=1", "--lambda-max", "1", "--json", "-o"])
        .arg(&f)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let lam: Vec<f64> = serde_json::from_value(v["lambda"].clone()).unwrap();
    let time = read(&f, "time");
    assert_eq!(time, read(&f, "sensors/path_lambda"));
    // JSON text → f64 is within an ulp (serde_json's default float parsing)
    assert_eq!(time.len(), lam.len());
    for (a, b) in time.iter().zip(&lam) {
        assert!((a - b).abs() <= 2.0 * f64::EPSILON * a.abs(), "{a} vs {b}");
    }
    assert_eq!(*time.last().unwrap(), 1.0);
}

#[test]
fn euler_column_bifurcation_is_reported_at_the_buckling_load_without_a_limit_point() {
    // A perfect cantilever column under a compressive tip force stays straight: the path
    // is the trivial branch with λ rising, and det K changes sign where the first
    // buckling mode loses its stiffness, P_cr = π²EI/(4L²) (EIy = 100 → 246.74; the
    // other plane, EIz = 200, buckles at 493.5, beyond λ_max). Reported as a bifurcation
    // (λ still rising), bracketed by the two path points around it. The 16-element
    // Hermite mesh's buckling load is within 1e-6 of the closed form (O(h⁴)), far inside
    // the bracket; the axial shortening P/EA = 3e-5 shifts it by as much.
    let props = "EA = 1.0e7\nEIy = 100.0\nEIz = 200.0\nGJ = 80.0\nrhoA = 1.0";
    let m = straight_beam("clamped", 16, props, [-300.0, 0.0, 0.0], [0.0; 3], "");
    let mut o = PathOptions::new(Control::Load, 1.0);
    o.first_step = 0.01;
    let r = path::follow(&m, &o);
    assert!(r.error.is_none(), "{:?}", r.error.map(|e| e.to_string()));
    assert!(r.limit_points.is_empty(), "{:?}", r.limit_points);
    assert_eq!(r.bifurcations.len(), 1, "{:?}", r.bifurcations);
    let i = r.bifurcations[0].index;
    let p_cr = std::f64::consts::PI.powi(2) * 100.0 / 4.0 / 300.0;
    assert!(
        r.lambda[i - 1] < p_cr && p_cr <= r.lambda[i],
        "bracket {} .. {} vs {p_cr}",
        r.lambda[i - 1],
        r.lambda[i]
    );
    assert_eq!(r.det_sign[i - 1], 1);
    assert_eq!(r.det_sign[i], -1);
}

#[test]
fn hinge_locks_along_a_path_at_its_lock_angle_and_the_beam_then_bends_as_clamped() {
    // A beam on a root hinge with a torsional spring k; a tip load −P·λ along y turns
    // the hinge (θ ≈ −PLλ/k, reaching −0.05 at λ ≈ 0.5) until it locks at −0.05, after
    // which the root is clamped: at λ = 1 the tip is at −L sin(0.05) − PL³/(3EI) to first
    // order (−0.08331). Bound 1 % of it: the geometric nonlinearity at a 0.05 rad turn and
    // 0.033 deflection is ~0.3 %.
    let text = r#"
[parameters]
P = 10.0
[sections.s]
EA = 1.0e7
EIy = 100.0
EIz = 100.0
GJ = 80.0
rhoA = 1.0
[[nodes]]
name = "root"
position = [0, 0, 0]
[[nodes]]
name = "tip"
position = [1, 0, 0]
[[beams]]
name = "beam"
from = "root"
to = "tip"
elements = 8
section = "s"
orientation = [0, 0, 1]
[[joints]]
name = "root_hinge"
node = "root"
body = "ground"
type = "hinge"
axis = [0, 0, 1]
stiffness = 100.0
lock_angle = -0.05
[[loads]]
node = "tip"
force = [0, "-P", 0]
[[sensors]]
name = "tip"
type = "node"
node = "tip"
[[sensors]]
name = "hinge"
type = "hinge"
joint = "root_hinge"
"#;
    let m = latdyn::model::compile_str(text, "locking_beam.toml", &[]).unwrap();
    let r = path::follow(&m, &PathOptions::new(Control::Load, 1.0));
    assert!(r.error.is_none(), "{:?}", r.error.map(|e| e.to_string()));
    assert_eq!(r.locks.len(), 1, "{:?}", r.locks);
    let (h, at) = (m.sensor_index("hinge").unwrap(), r.locks[0].1);
    // before the lock the angle had not reached it; from the lock on it stays there exactly
    assert!(r.sensors[at - 1][h][0] > -0.05);
    for p in &r.sensors[at..] {
        assert_eq!(p[h][0], -0.05);
    }
    let tip = m.sensor_index("tip").unwrap();
    let y = r.sensors.last().unwrap()[tip][1];
    let want = -(0.05f64).sin() - 10.0 / (3.0 * 100.0);
    assert!((y / want - 1.0).abs() < 0.01, "tip y {y} vs {want}");
    assert_eq!(*r.lambda.last().unwrap(), 1.0);
}

/// `statics --path --json` of Lee's frame with these extra arguments: exit code, JSON.
fn lee_json(args: &[&str]) -> (Option<i32>, serde_json::Value, String) {
    let out = bin()
        .args(["statics", &models("lee_frame.toml"), "--path", "--json"])
        .args(args)
        .env_remove("LATDYN_LIMITS")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    let v = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("{args:?}: no JSON ({e}): {err}"));
    (out.status.code(), v, err)
}

fn lambdas(v: &serde_json::Value) -> Vec<f64> {
    v["lambda"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn a_huge_lambda_max_starts_like_an_unbounded_path_and_a_small_one_keeps_its_two_percent() {
    // --lambda-max 1e15 (a bound meant as "none") made the first step 2e13 load factors:
    // 30 halvings reached only 9.3e3, and the path failed at once (exit 3)
    let (code, huge, err) = lee_json(&["--lambda-max", "1e15", "--max-points", "5"]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(huge["stopped_by"], "max_points", "{huge}");
    // a path cut short by its point limit says so (`--first-step 1e-300` ran 2 000
    // points at λ = 1e-300 and reported them with no word)
    assert!(
        huge["warnings"]
            .to_string()
            .contains("stopped at its point limit (5 points"),
        "{huge}"
    );
    let l = lambdas(&huge);
    assert_eq!(l.len(), 5);
    assert_eq!(l[1], 0.02, "first step 2 % of the loads as written: {l:?}");
    // any bound above the natural scale λ = 1 starts the same path: the bound is where
    // to stop, not a step size
    let (code, big, err) = lee_json(&["--lambda-max", "50", "--max-points", "5"]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(lambdas(&big), l);
    // at or below it, the first step stays 2 % of λ_max, as before
    for (lmax, first) in [("1", 0.02), ("0.5", 0.01)] {
        let (code, v, err) = lee_json(&["--lambda-max", lmax, "--max-points", "3"]);
        assert_eq!(code, Some(0), "{err}");
        assert!((lambdas(&v)[1] - first).abs() < 1e-15, "λ_max {lmax}: {v}");
    }
}

#[test]
fn a_path_whose_first_step_never_converges_says_so_and_suggests_first_step() {
    // the message reported the untouched start (λ = 0, "worst residual 0.000e0 at dof
    // ...") as if it explained the failure
    let (code, v, err) = lee_json(&[
        "--lambda-max",
        "1e15",
        "--first-step",
        "1e15",
        "--max-points",
        "5",
    ]);
    assert_eq!(code, Some(3), "{err}");
    let msg = v["message"].as_str().unwrap();
    assert!(msg.contains("no first step converged"), "{msg}");
    assert!(msg.contains("30 halvings down to 9.313e5"), "{msg}");
    assert!(msg.contains("--first-step"), "{msg}");
    assert!(!msg.contains("residual"), "{msg}");
    assert_eq!(v["points"], 1);
    assert!(err.contains(msg), "{err}");
}

#[test]
fn path_warns_at_its_most_deformed_point_not_only_its_last() {
    // The tip is turned 0.8 rad and back: with 2 elements the tip element's node frame
    // turns 0.61 rad from its chord at t ≈ 0.47 (beyond the element's small-deformation
    // range), and the path ends undeformed, where the check used to look only.
    let path = format!(
        "{}/tests/models/bent_and_released.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let m = latdyn::model::load(std::path::Path::new(&path), &[]).unwrap();
    let r = path::follow(&m, &PathOptions::new(Control::Drivers, 1.0));
    assert!(r.error.is_none(), "{:?}", r.error.map(|e| e.to_string()));
    let (k, lambda, d) = r.largest_deformation.clone().expect("a deformation angle");
    assert!(
        k > 0 && k + 1 < r.lambda.len(),
        "point {k} of {}",
        r.lambda.len()
    );
    assert!(
        (lambda - 0.5).abs() < 0.1 && d.angle > 0.5,
        "{lambda} {d:?}"
    );
    let last = latdyn::assembly::largest_deformation_angle(&m, &r.state).unwrap();
    assert!(last.angle < 1e-6, "{last:?}");

    let v = latdyn_json(&["statics", "--path", &path, "--json"]);
    let w = v["warnings"].as_array().unwrap();
    assert_eq!(w.len(), 1, "{v}");
    let w = w[0].as_str().unwrap();
    for part in [
        &format!("at path point {k} of {}", r.lambda.len()),
        "large deformation per element",
        &format!("{:.3} rad", d.angle),
    ] {
        assert!(w.contains(part), "`{part}` not in: {w}");
    }
}

#[test]
fn sweep_path_warns_per_variant_in_json_the_file_and_a_count_on_stderr() {
    // The same check for every path of a sweep: until session 30 `sweep --path` reported
    // no warning at all. peak 0.8 on 2 elements turns the tip element 0.61 rad; peak 0.1
    // stays within the range (0.08 rad).
    let path = format!(
        "{}/tests/models/bent_and_released.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("sweep_path_warns");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let h5 = dir.join("c.h5");
    let out = latdyn(&[
        "sweep",
        &path,
        "--path",
        "--vary",
        "peak=0.1:0.8:3",
        "--json",
        "-o",
        h5.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{out:?}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let warned: Vec<usize> = v["variants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x["warnings"].as_array().unwrap().len())
        .collect();
    assert_eq!(warned, [0, 1, 1], "{v}");
    let w = v["variants"][2]["warnings"][0].as_str().unwrap();
    assert!(
        w.contains("large deformation per element") && w.contains("at path point"),
        "{w}"
    );
    // one kind, counted once for both variants (their points and λ differ)
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("warning: 2 variant(s): large deformation per element")
            && err.contains("indices 1, 2"),
        "{err}"
    );
    let f = rust_hdf5::H5File::open(&h5).unwrap();
    let stored = f
        .dataset("status/warnings")
        .unwrap()
        .read_strings()
        .unwrap();
    assert_eq!(stored.len(), 3);
    assert!(stored[0].is_empty() && stored[2] == w, "{stored:?}");
}

#[test]
fn sweep_path_refuses_what_a_path_campaign_cannot_do_before_computing() {
    // --resume was ignored (every path computed again, the file left interrupted) and
    // --plan ran the whole sweep; a varied mesh with a `beam_nodes` sensor was found
    // only when writing (exit 5, a file left "running"). All three are refused first.
    let model = format!(
        "{}/tests/models/bent_and_released.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("sweep_path_refuses");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let h5 = dir.join("c.h5");
    let h5s = h5.to_str().unwrap();
    for extra in [&["--resume", h5s][..], &["--plan"][..]] {
        let mut args = vec!["sweep", &model, "--path", "--vary", "peak=0.1:0.8:2"];
        args.extend_from_slice(extra);
        let out = latdyn(&args);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {out:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--resume and --plan apply to dynamic campaigns only"),
            "{err}"
        );
    }
    let text = std::fs::read_to_string(&model).unwrap()
        + "\n[[sensors]]\nname = \"shape\"\ntype = \"beam_nodes\"\nbeam = \"beam\"\ncomponent = \"z\"\n";
    let nodes = dir.join("nodes.toml");
    std::fs::write(&nodes, text).unwrap();
    let out = latdyn(&[
        "sweep",
        nodes.to_str().unwrap(),
        "--path",
        "--vary",
        "elements=2:4:2",
        "-o",
        h5s,
    ]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("sensor `shape` has 5 components where variant 0 has 3"),
        "{err}"
    );
    assert!(!h5.exists(), "nothing written");
}

#[test]
fn driver_control_without_a_changing_drive_is_warned() {
    // Lee's frame has loads and no drive: `--control drivers` then repeats one
    // equilibrium at every point (16 of them), which was printed without a word.
    let v = latdyn_json(&[
        "statics",
        "models/lee_frame.toml",
        "--path",
        "--control",
        "drivers",
        "--json",
    ]);
    let w = v["warnings"].as_array().unwrap();
    assert!(
        w.iter().any(|w| w
            .as_str()
            .unwrap()
            .starts_with("--control drivers, but no drive changes")),
        "{v}"
    );
    // a model whose drive moves is not warned so
    let v = latdyn_json(&[
        "statics",
        "tests/models/bent_and_released.toml",
        "--path",
        "--json",
    ]);
    assert_eq!(v["control"], "drivers");
    assert!(
        !v["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("no drive changes")),
        "{v}"
    );
}

#[test]
fn a_path_campaign_named_csv_is_said_to_be_hdf5() {
    // `run -o x.csv` writes CSV; a path (or any campaign) wrote HDF5 under that name
    // without a word.
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("path_csv_name");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let out_file = dir.join("p.csv");
    let out = latdyn(&[
        "statics",
        "tests/models/bent_and_released.toml",
        "--path",
        "-o",
        out_file.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("is written as HDF5"), "{err}");
    let head = std::fs::read(&out_file).unwrap();
    assert_eq!(&head[..8], b"\x89HDF\r\n\x1a\n", "an HDF5 file");
}
