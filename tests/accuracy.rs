//! Time-discretisation error: the estimate every run reports, the warning it raises, and
//! the adaptive step controller behind `--accuracy` (README "Accuracy").

mod common;

use common::{latdyn, rel};
use serde_json::Value;

fn run_json(args: &[&str]) -> Value {
    let mut a = vec!["run"];
    a.extend_from_slice(args);
    a.push("--json");
    let out = latdyn(&a);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

fn warnings(v: &Value) -> Vec<String> {
    v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_string())
        .collect()
}

/// A shipped model with `from` replaced by `to` (which must occur), written to a file of
/// its own under the temporary directory; the path is returned.
fn shipped_with(model: &str, from: &str, to: &str, tag: &str) -> std::path::PathBuf {
    shipped_with_all(model, &[(from, to)], tag)
}

/// [`shipped_with`] for several replacements, made in order.
fn shipped_with_all(model: &str, edits: &[(&str, &str)], tag: &str) -> std::path::PathBuf {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut text = std::fs::read_to_string(root.join("models").join(model)).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{model} has no `{from}`");
        text = text.replace(from, to);
    }
    let dir = std::env::temp_dir().join(format!("latdyn-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(model);
    std::fs::write(&path, text).unwrap();
    path
}

/// The shipped four-bar with its cranks at rest while the coupler moves at v0, as it
/// was shipped until session 20 (`consistent_velocity = false`): the coupler strikes the
/// cranks at t = 0 and they ring above 1/dt at every practical step, a hard case for the
/// estimate that the shipped scene no longer is.
fn fourbar_at_rest(tag: &str) -> std::path::PathBuf {
    shipped_with(
        "fourbar.toml",
        "consistent_velocity = true",
        "consistent_velocity = false",
        tag,
    )
}

/// Largest difference of a sensor's samples from a reference run's samples at the same
/// times, over the reference's range (the same measure the estimate reports).
fn history_error(run: &Value, reference: &Value, sensor: &str) -> f64 {
    let (a, b) = (&run["sensors"][sensor], &reference["sensors"][sensor]);
    let tb: Vec<f64> = b["t"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let vb = b["values"].as_array().unwrap();
    let nc = vb[0].as_array().unwrap().len();
    let mut worst = 0.0f64;
    for c in 0..nc {
        let col: Vec<f64> = vb.iter().map(|v| v[c].as_f64().unwrap()).collect();
        let range = col.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - col.iter().cloned().fold(f64::INFINITY, f64::min);
        if range <= 0.0 {
            continue;
        }
        for (t, v) in a["t"]
            .as_array()
            .unwrap()
            .iter()
            .zip(a["values"].as_array().unwrap())
        {
            let t = t.as_f64().unwrap();
            let i = tb.partition_point(|x| *x < t - 1e-9);
            if i < tb.len() && (tb[i] - t).abs() < 1e-7 {
                worst = worst.max((v[c].as_f64().unwrap() - col[i]).abs() / range);
            }
        }
    }
    worst
}

#[test]
fn the_issue_runs_at_ten_times_the_step_warn_that_the_step_is_too_large() {
    // each of these is 7 % to 17× off the converged answer (issue 14); each must say so
    let at_rest = fourbar_at_rest("issue-runs");
    let at_rest = at_rest.to_str().unwrap();
    let cases: [(&str, Vec<&str>, &[&str]); 5] = [
        (
            "models/spinup_beam.toml",
            vec!["dt=0.05", "t_end=16"],
            // both are off (the issue: tip 0.24 m against 0.0037, hub torque 191 N·m
            // against −0.46); the warning names the worse estimate
            &["tip_deflection", "hub_torque"],
        ),
        // the smooth 0.05 s tip pulse falls between the steps' ends at dt = 0.1: the run
        // sees no load at all, its response and so its time-error estimate are 0, and the
        // warning is the missed impulse's, naming the load's node
        ("models/rotating_cantilever.toml", vec!["dt=0.1"], &["tip"]),
        // the issue's step: the scene shipped with dt = 0.01 until session 23
        (
            "models/rotating_cantilever.toml",
            vec!["omega=20", "t_end=3", "dt=0.01"],
            &["root_moment"],
        ),
        (
            "models/flapping_blade.toml",
            vec!["dt=0.05"],
            &["mid_moment"],
        ),
        // the four-bar as the issue ran it, its cranks at rest while the coupler moves
        // (see `fourbar_at_rest`): at 10× its step the hinge histories are 0.2-0.5 of
        // their range off; that error is in the rates, so only the velocity part of the
        // estimate sees it. Every sensor is off by far more than 1 % (against
        // dt = 1.25e-3 s, g1 and g2 0.37, c1 and c2 0.46, the coupler 0.35), so any may
        // be named (session 42: g1, 39 %; with the band caps on the reading alone, tried
        // then, the coupler, 62 %)
        (
            at_rest,
            vec!["dt=0.02"],
            &["g1", "g2", "c1", "c2", "coupler"],
        ),
    ];
    for (model, sets, sensor) in cases {
        let mut args = vec![model];
        for s in &sets {
            args.extend(["--set", s]);
        }
        let v = run_json(&args);
        let w = warnings(&v);
        assert!(
            w.iter().any(|w| w.contains("time step too large")
                && sensor.iter().any(|s| w.contains(&format!("`{s}`")))),
            "{model} {sets:?}: {w:?}"
        );
        let missed_load = w.iter().any(|w| w.contains("too large for the loads"));
        assert!(
            v["time_error_estimate"].as_f64().unwrap() > 1e-2 || missed_load,
            "{v}"
        );
    }
}

#[test]
fn converged_runs_carry_no_time_error_warning() {
    // the spin-up beam and the pendulum at their shipped steps are within 1e-3 of dt/4;
    // the four-bar, started consistently, within 6e-5 of dt = 3.1e-5 (its estimate
    // 1.1e-3 over-reads, below the 1 % limit)
    for model in [
        "models/spinup_beam.toml",
        "models/pendulum.toml",
        "models/fourbar.toml",
    ] {
        let v = run_json(&[model]);
        assert!(warnings(&v).is_empty(), "{model}: {:?}", warnings(&v));
        assert!(v["time_error_estimate"].as_f64().unwrap() < 1e-2, "{v}");
    }
}

#[test]
fn every_shipped_scene_but_the_mini_mast_runs_without_a_warning_at_its_shipped_settings() {
    // Issue 14: no warning on a shipped scene at its shipped settings, and the estimate
    // behind that silence under 1 %. Until session 23 the blade (0.005 s), the rotating
    // cantilever (0.01 s) and the dynamic runs of the two statics scenes bend45 and
    // lee_frame (0.01 s) warned, truly: their histories were 0.11, 0.50, 0.013 and 0.115
    // of a range off (bend45's estimate, 1.04, over-read 78×). They ship since at the
    // steps that meet 1 %, measured against a quarter of the step or finer
    // (`examples/time_error_ladder.py`): blade 0.001 s, mid-span moment
    // 6.6e-3 (estimate 9.0e-3); rotating cantilever 1e-4 s, root moment 7.0e-3 (8.2e-3);
    // bend45 2e-4 s, tip 2.7e-4 (7.5e-3); lee_frame 1e-4 s, knee moment 5.4e-3 (6.1e-3).
    // The Mini-Mast bays still warn, truly: their locks ring the members, which no step
    // tried resolves (`a_time_error_after_a_hinge_lock_names_the_lock_as_its_likely_cause`).
    // Since session 49 each run also measures its mesh error (a twin on twice the
    // elements): the rotating cantilever (then 10 elements, 18 % estimated), the blade
    // (10, 1.31 %) and the Lee frame (a step load, 7.4 %) were warned; they ship since
    // on 30 and 20 elements and with the Lee frame's load ramped over 0.2 s.
    let names: Vec<_> = common::shipped_model_paths()
        .into_iter()
        .filter(|p| {
            !p.file_name()
                .unwrap()
                .to_str()
                .unwrap()
                .starts_with("minimast")
        })
        .collect();
    assert!(names.len() >= 8, "{names:?}");
    let runs: Vec<_> = names
        .into_iter()
        .map(|p| std::thread::spawn(move || (run_json(&[p.to_str().unwrap()]), p)))
        .collect();
    for r in runs {
        let (v, p) = r.join().unwrap();
        let est = v["time_error_estimate"].as_f64().unwrap();
        eprintln!("{}: estimate {est:.2e}, {} steps", p.display(), v["steps"]);
        assert!(
            warnings(&v).is_empty(),
            "{}: {:?}",
            p.display(),
            warnings(&v)
        );
        assert!(est < 1e-2, "{}: {est}", p.display());
        let mesh = v["mesh_error_estimate"].as_f64();
        eprintln!("{}: mesh error estimate {mesh:?}", p.display());
        assert!(mesh.is_none_or(|x| x < 1e-2), "{}: {mesh:?}", p.display());
    }
}

#[test]
fn the_blade_at_its_shipped_step_is_within_one_percent_of_a_run_at_an_eighth_of_it() {
    // The silence of the shipped blade checked against the truth, over 4 s of flapping
    // (the mid-span moment's error grows along the run: 6.6e-3 of its range over the
    // shipped 10 s). Tolerance: the 1 % the warning promises.
    let base = run_json(&["models/flapping_blade.toml", "--set", "t_end=4"]);
    let fine = run_json(&[
        "models/flapping_blade.toml",
        "--set",
        "t_end=4",
        "--set",
        "dt=0.000125",
    ]);
    for sensor in ["flap_angle", "tip", "mid_moment"] {
        let off = history_error(&base, &fine, sensor);
        eprintln!("{sensor}: {off:.2e} of its range off");
        assert!(off < 1e-2, "{sensor}: {off:.3e}");
    }
}

#[test]
fn the_four_bar_started_consistently_is_within_one_percent_at_ten_times_its_step() {
    // Issue 14 listed the four-bar at 10× its step 7-12 % off and silent. Its hinge
    // error was the cranks' ringing from the inconsistent start; started consistently
    // (the shipped scene since session 20) the hinge histories at dt = 0.02 (run as steps
    // of 0.01, the output interval) are within 1.4e-3 of their range of a run at
    // 1.25e-4 s, whose own error is below 2e-5 (measured: 6e-5 at 0.002, 9e-6 at 5e-4
    // against 3.1e-5). Its estimate still reads 0.35 and warns: a false alarm on the safe
    // side (the four-bar's hinge rates over-read, README "Accuracy").
    let base = run_json(&["models/fourbar.toml", "--set", "dt=0.02"]);
    let fine = run_json(&["models/fourbar.toml", "--set", "dt=0.000125"]);
    for sensor in ["g1", "g2", "c1", "c2"] {
        let off = history_error(&base, &fine, sensor);
        assert!(off < 1e-2, "{sensor}: {off:.3e} of its range off");
    }
}

#[test]
fn the_estimate_is_within_a_factor_three_of_the_true_time_error() {
    // truth: the same run at dt/4, whose own error is 1/16 of the base run's (second
    // order), so the difference is the base run's error within 7 %. Factor 3 is the
    // issue's bar for an error estimate. Measured: flap angle 4.7e-4 vs 2.6e-4, mid
    // moment 3.5e-2 vs 4.6e-2 (the tip sensor is 3.6× over and is not asserted). The
    // base is the blade's step until session 23 (it ships at 0.001 s since).
    let base = run_json(&[
        "models/flapping_blade.toml",
        "--set",
        "t_end=3",
        "--set",
        "dt=0.005",
    ]);
    let fine = run_json(&[
        "models/flapping_blade.toml",
        "--set",
        "t_end=3",
        "--set",
        "dt=0.00125",
    ]);
    for sensor in ["flap_angle", "mid_moment"] {
        let truth = history_error(&base, &fine, sensor) * 16.0 / 15.0;
        let est = base["time_error_by_sensor"][sensor].as_f64().unwrap();
        assert!(
            est > truth / 3.0 && est < truth * 3.0,
            "{sensor}: estimate {est:.3e}, true {truth:.3e}"
        );
    }
}

#[test]
fn the_estimate_of_hinge_rates_does_not_under_read_where_the_step_misses_the_vibration() {
    // At 10x its step the four-bar launched with its cranks at rest (`fourbar_at_rest`)
    // has hinge rates that carry the cranks' vibration above 1/dt,
    // and their error does not converge with dt (0.23-0.37 of the range from dt = 0.01 to
    // 0.00125 against dt = 0.0003125): the estimate must say "large", not how large. The
    // transported error of a vibration whose phase is lost grows past the truth (a linear
    // estimate has no saturation, and the transport's step matrix is not the exact
    // linearisation); it is capped at twice the range. Measured: g1 and c1 at the cap, 2,
    // against 0.31 and 0.38. Hinge rates in a converging run are checked by the blade's
    // flap angle above (its second component is the rate).
    let at_rest = fourbar_at_rest("hinge-rates");
    let at_rest = at_rest.to_str().unwrap();
    let base = run_json(&[at_rest, "--set", "v0=0.2", "--set", "dt=0.02"]);
    let fine = run_json(&[at_rest, "--set", "v0=0.2", "--set", "dt=0.00125"]);
    for sensor in ["g1", "c1"] {
        let truth = history_error(&base, &fine, sensor);
        let est = base["time_error_by_sensor"][sensor].as_f64().unwrap();
        assert!(
            est > truth / 3.0 && est <= 2.0 + 1e-12,
            "{sensor}: estimate {est:.3e}, true {truth:.3e}"
        );
    }
}

#[test]
fn the_estimate_matches_the_closed_form_error_of_a_linear_oscillator() {
    // The pendulum at 0.01 rad is a linear oscillator, θ = θ0 cos ωt, ω² = m g d / I:
    // the transported error must be its error, not a bound (measured 0.985-0.990 of it at
    // dt = 0.02 for each ρ∞; the small-angle model's own period error is 1 % of the time
    // error here). The per-step sum it replaced read 0.6 of it.
    let (m, d, ic, g, th0) = (2.0f64, 0.5f64, 0.01f64, 9.81f64, 0.01f64);
    let w = (m * g * d / (ic + m * d * d)).sqrt();
    for rho in ["0.6", "0.8", "1.0"] {
        let rho_set = format!("rho_inf={rho}");
        let v = run_json(&[
            "models/pendulum.toml",
            "--set",
            "theta0=0.01",
            "--set",
            &rho_set,
            "--set",
            "dt=0.02",
            "--set",
            "t_end=5",
        ]);
        let s = &v["sensors"]["angle"];
        let truth = s["t"]
            .as_array()
            .unwrap()
            .iter()
            .zip(s["values"].as_array().unwrap())
            .map(|(t, y)| {
                (y[4].as_f64().unwrap() - th0 * (w * t.as_f64().unwrap()).cos()).abs() / (2.0 * th0)
            })
            .fold(0.0f64, f64::max);
        let est = v["time_error_by_sensor"]["angle"].as_f64().unwrap();
        assert!(
            est > 0.9 * truth && est < 1.1 * truth,
            "rho_inf {rho}: estimate {est:.4e}, true {truth:.4e}"
        );
    }
}

/// The shipped cantilever given a rotary inertia (1e-4), run for 0.3 s under its tip
/// force of 1 N applied at t = 0, with `solver` (its `dt` and `output_dt` lines and what
/// else the test sets) and with or without its tip sensor.
fn step_loaded_cantilever(solver: &str, tip_sensor: bool, tag: &str) -> Value {
    let mut edits = vec![
        (
            "rhoA = \"rhoA\"\n",
            "rhoA = \"rhoA\"\nrhoIy = 1e-4\nrhoIz = 1e-4\n",
        ),
        ("t_end = 1.0", "t_end = 0.3"),
        ("dt = 1e-3\noutput_dt = 0.01", solver),
    ];
    if !tip_sensor {
        edits.push((
            "[[sensors]]\nname = \"tip\"\ntype = \"node\"\nnode = \"tip\"\n",
            "",
        ));
    }
    let path = shipped_with_all("cantilever.toml", &edits, tag);
    run_json(&[path.to_str().unwrap(), "--set", "P=1"])
}

/// The estimate on many modes at once, against an independent model of it: the shipped
/// cantilever (8 elements, given a rotary inertia, its tip sensor left out: the model is
/// linear and has no axial tip motion) under its tip force applied at t = 0, which excites
/// every bending mode about equally in the root moment, and `tests/estimator_model.py`,
/// the same scheme, estimator and band caps written from the README's formulas in
/// modal-free matrix form on linear Hermite elements. Without the band caps both read
/// 0.0426, 0.0819, 0.498 at ρ∞ = 0.3, 0.6, 0.9 (the model 0.0427, 0.0820, 0.499), 22×
/// the truth at ρ∞ = 0.9; with them (since session 42 four bands, capped where the error
/// is read) 0.03687, 0.03720, 0.03958 here against 0.03685, 0.03721, 0.03958 in the model
/// (truth 0.028, 0.027, 0.022 against dt = 1e-6; with two bands capped in the carried
/// error, until session 41, 0.04219, 0.03352, 0.03622 here and in the model). Bound
/// 2 %: the two element models differ (co-rotational with a 4-point mass rule, 1 %
/// nonlinear at this load, against the linear closed forms), and latdyn moves its state
/// by each band to read the sensor.
#[test]
fn the_estimate_on_a_step_loaded_cantilever_is_that_of_an_independent_model_of_the_estimator() {
    if !common::h5py_available() {
        eprintln!("SKIPPED: numpy (with h5py) is not installed");
        return;
    }
    for rho in [0.3, 0.6, 0.9] {
        let v = step_loaded_cantilever(
            &format!("dt = 1e-4\noutput_dt = 0.01\nrho_inf = {rho}"),
            false,
            &format!("estimator-model-{rho}"),
        );
        let est = v["time_error_by_sensor"]["root_moment"].as_f64().unwrap();
        let model = common::python_json(
            "tests/estimator_model.py",
            &[&rho.to_string(), "1e-4", "0.3"],
        );
        let want = model["estimate"].as_f64().unwrap();
        eprintln!("rho_inf {rho}: latdyn {est:.5}, the model {want:.5}");
        assert!(
            (est / want - 1.0).abs() < 0.02,
            "rho_inf {rho}: latdyn {est:.4e}, the model {want:.4e}"
        );
    }
}

/// A linear response's estimate, relative to its range, does not depend on the load's
/// size. The transport linearises the step by a finite difference; until session 35 its
/// step was 1e-6 of the model's size, larger than the motion under a tip force of 1e-6 N
/// (deflection 7e-9 m), and the tip (whose axial component, quadratic in the load, spans
/// 3e-17 m) read 105 % over these 0.1 s where the same run under 1 N reads 3.8 %. Now the
/// step is scaled on the run's motion: measured equal to 3e-4 (the 1 N run is slightly
/// nonlinear); bound 1 %.
#[test]
fn the_estimate_of_a_linear_response_does_not_depend_on_the_size_of_the_load() {
    let path = shipped_with_all(
        "cantilever.toml",
        &[("t_end = 1.0", "t_end = 0.1"), ("dt = 1e-3", "dt = 1e-4")],
        "estimate-load-size",
    );
    let est = |p: &str| {
        let v = run_json(&[path.to_str().unwrap(), "--set", &format!("P={p}")]);
        ["tip", "root_moment"].map(|s| v["time_error_by_sensor"][s].as_f64().unwrap())
    };
    let unit = est("1");
    assert!(unit[0] > 1e-3 && unit[1] > 1e-3, "{unit:?}");
    for p in ["1e-3", "1e-6"] {
        let small = est(p);
        for (a, b) in small.iter().zip(&unit) {
            assert!(
                (a / b - 1.0).abs() < 0.01,
                "P = {p}: {small:?} against {unit:?} at P = 1"
            );
        }
    }
}

/// A step load rings every mode of a fine structure, and ρ∞ = 0.9 leaves those near
/// ωh ≈ 1 undamped: their phase is lost within the run, their true error stays within
/// their small amplitude, and their linearised error grew without bound. Until the band
/// caps (`cap_error_bands`) the estimate read 15.6× and 22× the true error at dt = 1e-3
/// and 1e-4; now 0.133 against 0.0756 and 0.0396 against 0.0226 (1.75× and 1.75×;
/// 2.0× and 1.5× with the caps on the carried error until session 42). Truth:
/// the same run at dt = 1e-5, whose own error (4.6e-3 of the range against dt = 1e-6) is
/// a fifth of the closer one's. Bound: the issue's factor 3.
#[test]
fn the_estimate_on_a_step_loaded_cantilever_is_within_three_times_its_true_error() {
    let at = |dt: &str| {
        step_loaded_cantilever(
            &format!("dt = {dt}\noutput_dt = 1e-3\nrho_inf = 0.9"),
            true,
            &format!("step-load-{dt}"),
        )
    };
    let fine = at("1e-5");
    for dt in ["1e-3", "1e-4"] {
        let v = at(dt);
        let truth = history_error(&v, &fine, "root_moment");
        let est = v["time_error_by_sensor"]["root_moment"].as_f64().unwrap();
        eprintln!("dt {dt}: estimate {est:.4e}, true {truth:.4e}");
        assert!(
            est > truth / 3.0 && est < truth * 3.0,
            "dt {dt}: estimate {est:.3e}, true {truth:.3e}"
        );
    }
}

#[test]
fn samples_interpolated_between_steps_that_miss_the_output_grid_keep_the_schemes_error() {
    // Under `--accuracy` a step that does not divide the output interval is kept (the
    // samples are the cubic through the four step ends around them) instead of rounded
    // down to a divisor. On the linear oscillator θ0 cos ωt the samples' error must then
    // be the scheme's, which the estimate reads at 0.985-0.99 of the truth on the grid at
    // fixed steps: measured here 0.955 and 0.958 (the cubic's own error is O(h⁴), a few
    // per cent of the scheme's O(h²) at these steps), so 10 % of slack.
    let (m, d, ic, g, th0) = (2.0f64, 0.5f64, 0.01f64, 9.81f64, 0.01f64);
    let w = (m * g * d / (ic + m * d * d)).sqrt();
    for target in [1e-2, 2e-3] {
        let acc = format!("{target}");
        let v = run_json(&[
            "models/pendulum.toml",
            "--set",
            "theta0=0.01",
            "--set",
            "dt=0.05",
            "--set",
            "t_end=5",
            "--accuracy",
            &acc,
        ]);
        let h = v["accuracy"]["dt"].as_f64().unwrap();
        let per_interval = 0.05 / h;
        assert!(
            (per_interval - per_interval.round()).abs() > 1e-3,
            "{target}: the step {h} divides the output interval"
        );
        let s = &v["sensors"]["angle"];
        let t = s["t"].as_array().unwrap();
        assert_eq!(t.len(), 101, "every output sample, on the grid");
        let truth = t
            .iter()
            .zip(s["values"].as_array().unwrap())
            .map(|(t, y)| {
                let t = t.as_f64().unwrap();
                assert!((t / 0.05 - (t / 0.05).round()).abs() < 1e-9, "{t}");
                (y[4].as_f64().unwrap() - th0 * (w * t).cos()).abs() / (2.0 * th0)
            })
            .fold(0.0f64, f64::max);
        let est = v["time_error_estimate"].as_f64().unwrap();
        eprintln!("{target}: step {h:.4e}, estimate {est:.4e}, true {truth:.4e}");
        assert!(truth <= target, "{target}: true error {truth:.3e}");
        assert!(
            est > 0.9 * truth && est < 1.1 * truth,
            "{target}: estimate {est:.4e}, true {truth:.4e}"
        );
    }
}

/// The spin-up beam over 12 s (the tests below) at step `dt`, with `more` arguments.
fn spin_up_over_12_s(dt: &str, more: &[&str]) -> Value {
    let dt = format!("dt={dt}");
    let mut args = vec!["models/spinup_beam.toml", "--set", &dt, "--set", "t_end=12"];
    args.extend_from_slice(more);
    run_json(&args)
}

/// The spin-up beam over 12 s at dt = 0.00125 (1/8 of the step the tests below compare),
/// run once for them all.
fn spin_up_reference() -> &'static Value {
    static REFERENCE: std::sync::OnceLock<Value> = std::sync::OnceLock::new();
    REFERENCE.get_or_init(|| spin_up_over_12_s("0.00125", &[]))
}

/// The spin-up beam over 12 s with `--accuracy 1e-2` from dt = 0.04 (steps of 0.04 s,
/// the samples interpolated between them).
fn spin_up_with_accuracy() -> &'static Value {
    static RUN: std::sync::OnceLock<Value> = std::sync::OnceLock::new();
    RUN.get_or_init(|| spin_up_over_12_s("0.04", &["--accuracy", "1e-2"]))
}

/// The spin-up beam over 12 s at dt = 0.01, run once for the estimate tests below.
fn spin_up_at_a_hundredth() -> &'static Value {
    static RUN: std::sync::OnceLock<Value> = std::sync::OnceLock::new();
    RUN.get_or_init(|| spin_up_over_12_s("0.01", &[]))
}

#[test]
fn the_spin_up_estimate_is_its_true_error_not_a_third_of_it() {
    // The driven hub's rigid motion: the per-step sum had to leave its truncation error
    // out and then read 0.25-0.33 of the truth; the transport carries it through the
    // beam's dynamics. Truth: dt/8 (its own error 1/64). Measured at dt = 0.01: 2.26e-3
    // against 2.00e-3 (t_end = 20); at 0.005 1.07, 0.0025 1.05.
    let base = spin_up_at_a_hundredth();
    estimate_within(
        base,
        spin_up_reference(),
        64.0 / 63.0,
        &["tip_deflection"],
        1.5,
    );
}

#[test]
fn a_spin_up_at_ten_times_its_step_reads_its_error_not_the_cap() {
    // The issue's step, dt = 0.05, lands on the samples. Newton refreshes its Jacobian
    // mid-step at most of these steps, and the transport and band filters solved with that
    // matrix, whose geometric stiffness was still the iterate's: the estimate read the
    // cap, 2.0, against true errors of 0.069 (hub torque) and 0.056 (tip). Refactored at
    // the converged state, 0.18 and 0.14. Truth: dt/40 (its own error 1/1600).
    let base = spin_up_over_12_s("0.05", &[]);
    estimate_within(
        &base,
        spin_up_reference(),
        1.0,
        &["tip_deflection", "hub_torque"],
        3.0,
    );
}

#[test]
fn the_rotating_cantilevers_estimate_is_measured_in_the_hubs_frame_within_a_factor_three() {
    // The band caps' window motion is taken against the window's start carried along by
    // the hub (`follow_window`); summed increments held the hub's turn, 0.4 rad per window
    // at dt = 0.01, which strains the root once applied with the hub held, so the caps
    // barely bound and the root moment read 3.2 times its true error (1.4 now, tip 2.2 and
    // 1.1). Truth: dt/128, its own error about 1 % of this one's.
    let args = |dt: &'static str| ["models/rotating_cantilever.toml", "--set", dt];
    let base = run_json(&args("dt=0.01"));
    let fine = run_json(&args("dt=7.8125e-5"));
    estimate_within(&base, &fine, 1.0, &["tip_flap", "root_moment"], 3.0);
}

/// Each sensor's estimate in `run` is at least 0.7 and at most `over` times its true
/// error: the difference from `reference` times `own` (the correction for the
/// reference's own error, 64/63 for a second-order run at 1/8 of the step; 0.7: the
/// estimate may fall a little short of a truth so measured, not by a third).
fn estimate_within(run: &Value, reference: &Value, own: f64, sensors: &[&str], over: f64) {
    for sensor in sensors {
        let truth = history_error(run, reference, sensor) * own;
        let est = run["time_error_by_sensor"][sensor].as_f64().unwrap();
        assert!(
            est > 0.7 * truth && est < over * truth,
            "{sensor}: estimate {est:.3e}, true {truth:.3e}"
        );
    }
}

#[test]
fn the_hub_torque_of_a_driven_spin_up_gets_an_estimate_near_its_true_error() {
    // A driver reaction is a row of the residual (accelerations included), read at the
    // state moved by the transported error. Until session 37 it got no estimate (null).
    // Truth: dt/8 (its own error 1/64). Measured over 20 s: 1.07, 1.13, 1.29 times the
    // truth at dt = 0.005, 0.01, 0.02; the tip's own bounds hold it.
    let base = spin_up_at_a_hundredth();
    estimate_within(base, spin_up_reference(), 64.0 / 63.0, &["hub_torque"], 1.5);
}

#[test]
fn a_hub_torque_off_by_more_than_one_percent_is_warned_by_its_own_estimate() {
    // The spin-up beam, softer and faster (ws = 10, EI = GJ = 5e3), at dt = 0.01: its hub
    // torque is 1.1 % of its range off a run at 6.25e-4 s while the tip is 0.53 % off
    // and read 0.83 %, so before the reactions had estimates it finished with no
    // warning. Measured: hub torque estimate 1.76 % (1.58 times the truth).
    let sets = |dt: &'static str| {
        [
            "models/spinup_beam.toml",
            "--set",
            "ws=10",
            "--set",
            "EI=5e3",
            "--set",
            "GJ=5e3",
            "--set",
            dt,
        ]
    };
    let v = run_json(&sets("dt=0.01"));
    let reference = run_json(&sets("dt=6.25e-4"));
    let truth = history_error(&v, &reference, "hub_torque");
    assert!(
        truth > 0.01,
        "the case must be off by more than 1 %: {truth:.3e}"
    );
    assert!(history_error(&v, &reference, "tip_deflection") < 0.01);
    let est = v["time_error_by_sensor"]["hub_torque"].as_f64().unwrap();
    assert!(est >= truth, "estimate {est:.3e}, true {truth:.3e}");
    let w = warnings(&v);
    assert!(
        w.iter()
            .any(|w| w.contains("step too large") && w.contains("`hub_torque`")),
        "{w:?}"
    );
}

#[test]
fn accuracy_target_is_met_from_a_step_twenty_times_too_large() {
    // pendulum released at 1 rad, first step 0.05 s (its fixed-step error there is
    // 0.036): the runs must bring the history within the target, judged against a
    // reference 100x finer than the result's step; the estimate reads 0.94-0.99 of the
    // truth on this model, so 10 % of slack on the truth
    let reference = run_json(&["models/pendulum.toml", "--set", "dt=1e-4"]);
    for acc in ["1e-2", "1e-3"] {
        let v = run_json(&[
            "models/pendulum.toml",
            "--set",
            "dt=0.05",
            "--accuracy",
            acc,
        ]);
        let target: f64 = acc.parse().unwrap();
        let truth = history_error(&v, &reference, "angle");
        assert!(
            truth < 1.1 * target,
            "accuracy {acc}: true error {truth:.3e}"
        );
        assert!(v["time_error_estimate"].as_f64().unwrap() <= target, "{v}");
        assert!(warnings(&v).is_empty(), "{:?}", warnings(&v));
        assert!(
            v["accuracy"]["runs"].as_u64().unwrap() <= 3,
            "{}",
            v["accuracy"]
        );
    }
}

#[test]
fn accuracy_on_the_spin_up_meets_the_target_within_one_and_a_half_times_the_cheapest_fixed_step() {
    // Issue 14's cost bar: 1.5× the cheapest fixed step of the halving ladder that meets
    // the same error. Spread evenly over the 0.05 s output interval, dt = 0.02 (steps of
    // 1/60 s) meets it; `--accuracy` from dt = 0.04 reads 7.0e-2 and aims the second run
    // at 0.7 of the target, 0.0126 s, which it keeps since session 27 (its samples
    // interpolated; before, rounded down to a divisor of the interval, 0.0125 s from a
    // first run at 0.025 s). Until session 26 that second run started from t = 0 (2.0× the
    // cheapest); it now resumes the first from the checkpoint where the error so far is
    // within a quarter of the target (t = 4.8 s here), so the quiet start is not stepped
    // again. Measured over these 12 s: 1 068 steps, 1.48× (868 steps, 1.21× until the hub
    // torque got an estimate in session 37: its first run now reads 0.128, not the
    // tip's 0.070, and aims the second at 0.0093 s; 1.33× in session 26). (The
    // shipped 20 s, in `latdyn bench --only accuracy`: 1.47×, 1.61× in session 26; the
    // longer the steady rotation after the spin-up, the more of the run the fine step
    // covers.)
    // The cheapest fixed step is measured, not assumed (against dt = 0.00125), on both
    // sensors (the hub torque since session 37, when it got an estimate).
    let spin_up_error = |v: &Value| {
        ["tip_deflection", "hub_torque"]
            .map(|s| history_error(v, spin_up_reference(), s))
            .into_iter()
            .fold(0.0f64, f64::max)
    };
    let ladder = ["0.04", "0.02", "0.01", "0.005"];
    let cheapest = ladder
        .iter()
        .find_map(|dt| {
            let v = spin_up_over_12_s(dt, &[]);
            let e = spin_up_error(&v);
            eprintln!("fixed dt = {dt}: {} steps, true error {e:.3e}", v["steps"]);
            (e < 1e-2).then(|| v["steps"].as_u64().unwrap())
        })
        .expect("a fixed step of the ladder meets 1e-2");
    let v = spin_up_with_accuracy();
    let truth = spin_up_error(v);
    assert!(truth < 1e-2, "true error {truth:.3e}");
    let all = v["accuracy"]["steps_all_runs"].as_u64().unwrap();
    eprintln!(
        "--accuracy 1e-2: {all} steps in all runs, {:.2}× the cheapest fixed ({cheapest})",
        all as f64 / cheapest as f64
    );
    assert!(2 * all <= 3 * cheapest, "{}", v["accuracy"]);
    assert!(warnings(v).is_empty(), "{:?}", warnings(v));
}

#[test]
fn a_resumed_run_repeats_no_step_before_its_checkpoint_and_adds_at_most_its_budget() {
    // The second `--accuracy` run on the spin-up beam resumes the first (steps of
    // 0.03 s) where the error so far is within a quarter of the target. So: its samples
    // up to there are the first run's, bit for bit (the first run is what a looser
    // target, met at once, returns); the steps it counts are its own after the
    // checkpoint; and its true error exceeds that of a run at its step from t = 0 by at
    // most that quarter (measured in session 37: resumed at 5.25 s, 4.8e-3 against
    // 3.4e-3; in session 26, from 0.04 s: 4.4e-3 against 3.1e-3).
    // The first step is 0.03 s (it was 0.04 s, `spin_up_with_accuracy`, until session
    // 37): since the hub torque has an estimate, the first run at 0.04 s reads 0.128,
    // over the loosest target allowed (0.1), so no looser target returns it alone.
    let target = 1e-2;
    let first = 0.03;
    let spin_up_from = |acc: &str| spin_up_over_12_s(&first.to_string(), &["--accuracy", acc]);
    let v = &spin_up_from("1e-2");
    let hist = v["accuracy"]["history"].as_array().unwrap();
    assert_eq!(hist.len(), 2, "{}", v["accuracy"]);
    let from = hist[1]["from"].as_f64().unwrap();
    assert!(from > 0.0 && from < 12.0, "{}", v["accuracy"]);
    let h = hist[1]["dt"].as_f64().unwrap();
    let coarse = spin_up_from("0.1");
    assert_eq!(coarse["accuracy"]["runs"], 1, "{}", coarse["accuracy"]);
    for sensor in ["tip_deflection", "hub_torque"] {
        let (a, b) = (&v["sensors"][sensor], &coarse["sensors"][sensor]);
        let t = a["t"].as_array().unwrap();
        // the samples interpolated from step ends before the checkpoint (those of the
        // last two steps before it take step ends after it too)
        let kept = t
            .iter()
            .take_while(|x| x.as_f64().unwrap() <= from - 2.0 * first + 1e-9)
            .count();
        assert!(kept > 1);
        assert_eq!(
            a["values"].as_array().unwrap()[..kept],
            b["values"].as_array().unwrap()[..kept],
            "{sensor} up to t = {from}"
        );
        assert_ne!(a["values"], b["values"], "{sensor} after t = {from}");
    }
    let own = hist[1]["steps"].as_u64().unwrap();
    // steps of h spread evenly over the rest of the run
    assert_eq!(
        own,
        ((12.0 - from) / h * (1.0 - 1e-6)).ceil() as u64,
        "{}",
        v["accuracy"]
    );
    assert_eq!(
        v["accuracy"]["steps_all_runs"].as_u64().unwrap(),
        hist[0]["steps"].as_u64().unwrap() + own
    );
    assert_eq!(
        v["steps"].as_u64().unwrap(),
        (from / first).round() as u64 + own,
        "the result's steps are the kept part's and its own"
    );
    // the same steps from t = 0: one run at h (a loose target is met at once)
    let fine = spin_up_over_12_s(&h.to_string(), &["--accuracy", "0.1"]);
    assert_eq!(fine["accuracy"]["runs"], 1, "{}", fine["accuracy"]);
    let truth = history_error(v, spin_up_reference(), "tip_deflection");
    let truth_fine = history_error(&fine, spin_up_reference(), "tip_deflection");
    eprintln!("resumed at t = {from}: true {truth:.3e}; from t = 0 at {h}: {truth_fine:.3e}");
    assert!(
        truth <= truth_fine + 0.25 * target,
        "{truth:.3e} {truth_fine:.3e}"
    );
    // the estimate still counts the kept part's error
    let est = v["time_error_estimate"].as_f64().unwrap();
    assert!(est >= truth && est <= 3.0 * truth, "{est:.3e} {truth:.3e}");
}

#[test]
fn a_resumed_run_whose_error_does_not_fall_sends_the_next_back_to_t_zero_at_its_step() {
    // A pendulum released 0.0116 rad from upright: the error of the first seconds is
    // amplified as the motion leaves the unstable equilibrium. The first run (0.02 s)
    // reads 8.5e-3; the second resumes it at 0.96 s at 5.7e-3 s, and its estimate (0.45)
    // does not fall, because what grows is the kept part's error. So the third starts from
    // t = 0 at the second's step (predicted for the whole run), and meets the target
    // (measured: 785 steps, estimate 1.94e-4; before that rule the third run took the
    // second's estimate for its own). Until session 39 this was the case at a target of
    // 1e-2, when the first run read 0.25 (true 2.2e-3): the leading-term local error and
    // the body's dead-load tangent read this motion 8-57× high. Until session 42 the run
    // lasted 5 s; a kept part of 0.96 s is now too short a share of that to resume
    // (`ACCURACY_RESUME_SAVING`), and the second run from t = 0 meets the target.
    let sets = ["--set", "theta0=3.13", "--set", "t_end=4.5"];
    let reference =
        run_json(&[&["models/pendulum.toml"], &sets[..], &["--set", "dt=1e-4"]].concat());
    let v = run_json(
        &[
            &["models/pendulum.toml"],
            &sets[..],
            &["--set", "dt=0.02", "--accuracy", "1e-3"],
        ]
        .concat(),
    );
    let hist = v["accuracy"]["history"].as_array().unwrap();
    assert_eq!(hist.len(), 3, "{}", v["accuracy"]);
    assert!(hist[1]["from"].as_f64().unwrap() > 0.0, "{}", v["accuracy"]);
    assert_eq!(hist[2]["from"].as_f64().unwrap(), 0.0, "{}", v["accuracy"]);
    assert_eq!(hist[2]["dt"], hist[1]["dt"], "{}", v["accuracy"]);
    let truth = history_error(&v, &reference, "angle");
    let est = v["time_error_estimate"].as_f64().unwrap();
    // (the reference's own error, about 6e-8 of the range at dt = 1e-4, is far below
    // the 7 % between them)
    assert!(
        truth < 1e-3 && est <= 1e-3 && est >= truth && est <= 3.0 * truth,
        "{truth:.3e} {est:.3e}"
    );
    assert!(warnings(&v).is_empty(), "{:?}", warnings(&v));
}

#[test]
fn a_hinged_body_near_upright_reads_its_error_and_takes_one_newton_iteration_per_step() {
    // The pendulum released 0.0116 rad from upright: its error passes near zero as it
    // turns back at the top and grows again, so its estimate needs the error transport's
    // matrix right to about 1e-3. Until session 39 the body's tangent took its inertial
    // force as a dead load turned by the hinge (m ω² d² of stiffness I θ̈ does not have):
    // Newton took 4 937 iterations for these 4 000 steps and the estimate read 0.56× the
    // error (4.8e-6 against 8.6e-6); with the leading-term local error, 15×. Measured now:
    // 4 000 iterations, 1.005× (8.66e-6 against 8.62e-6 against dt = 3.9e-5, whose own
    // error is 1e-3 of that). Bounds: 0.9-1.2×, and 5 % of extra iterations.
    let sets = [
        "models/pendulum.toml",
        "--set",
        "theta0=3.13",
        "--set",
        "t_end=5",
        "--set",
    ];
    let reference = run_json(&[&sets[..], &["dt=3.90625e-5"]].concat());
    let v = run_json(&[&sets[..], &["dt=0.00125"]].concat());
    let truth = history_error(&v, &reference, "angle");
    let est = v["time_error_estimate"].as_f64().unwrap();
    assert!(
        est >= 0.9 * truth && est <= 1.2 * truth,
        "{est:.3e} {truth:.3e}"
    );
    let (steps, newton) = (
        v["steps"].as_u64().unwrap(),
        v["newton_iterations"].as_u64().unwrap(),
    );
    assert!(
        newton as f64 <= 1.05 * steps as f64,
        "{newton} for {steps} steps"
    );
}

#[test]
fn accuracy_out_of_range_is_a_usage_error() {
    // 1e-300: below 100 × the model's Newton tolerance, where the estimate stops falling
    // with the step (`accuracy_floor`; it ran a 21-million-step run on the blade)
    for bad in ["0", "-1", "0.5", "nan", "x", "1e-300"] {
        let arg = format!("--accuracy={bad}");
        let out = latdyn(&["run", "models/pendulum.toml", &arg]);
        assert_eq!(out.status.code(), Some(2), "--accuracy {bad}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("--accuracy"));
    }
}

/// An output interval longer than the run ends at t_end, and the steps spread over
/// that span: the stderr note must count those steps (session 44: it counted them over
/// the whole output interval, "7 equal steps" for a run of 3, and for an interval of
/// 1e308 s printed a saturated 18446744073709551615).
#[test]
fn the_spread_note_counts_the_steps_the_run_takes_when_the_output_interval_outlasts_it() {
    let note_and_steps = |t_end: &str| {
        let out = latdyn(&[
            "run",
            "models/rotating_cantilever.toml",
            "--set",
            &format!("t_end={t_end}"),
            "--set",
            "dt=0.0015",
            "--json",
        ]);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        (err, v["steps"].as_u64().unwrap())
    };
    // 0.0045 s is three steps of 0.0015 s: nothing to note
    let (err, steps) = note_and_steps("0.0045");
    assert_eq!(steps, 3);
    assert!(!err.contains("does not divide"), "{err}");
    // 0.005 s is four equal steps of 1.25e-3 s, as the note says
    let (err, steps) = note_and_steps("0.005");
    assert_eq!(steps, 4);
    assert!(
        err.contains("the run's span t_end = 5e-3 s") && err.contains("4 equal steps of 1.25"),
        "{err}"
    );
}

#[test]
fn a_step_that_does_not_divide_the_output_interval_is_spread_evenly_not_ended_by_a_sliver() {
    // dt = 0.00111111111 leaves 1e-11 s of each 0.01 s output interval: taken as a step
    // of its own, that sliver (step ratio 1e-8) quadrupled the blade's true flap error and
    // sent every sensor's time-error estimate to the cap (2.0, measured before the fix).
    // Spread evenly, the run is the run at dt = 0.01/9 up to round-off.
    let common = ["models/flapping_blade.toml", "--set", "t_end=2", "--set"];
    let mut sliver = common.to_vec();
    sliver.push("dt=0.00111111111");
    let mut even = common.to_vec();
    even.push("dt=0.0011111111111111111");
    let (a, b) = (run_json(&sliver), run_json(&even));
    assert_eq!(a["steps"], b["steps"]);
    // the user is told, on stderr (stdout stays the JSON object)
    let mut args = vec!["run"];
    args.extend_from_slice(&sliver);
    args.push("--json");
    let out = latdyn(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("does not divide the output interval") && err.contains("9 equal steps"),
        "{err}"
    );
    for sensor in ["flap_angle", "mid_moment", "tip"] {
        let diff = history_error(&a, &b, sensor);
        assert!(
            diff < 1e-6,
            "{sensor}: samples differ by {diff:.2e} of the range"
        );
        let (ea, eb) = (
            a["time_error_by_sensor"][sensor].as_f64().unwrap(),
            b["time_error_by_sensor"][sensor].as_f64().unwrap(),
        );
        assert!(
            (ea - eb).abs() <= 1e-4 * eb,
            "{sensor}: estimate {ea:.4e} against {eb:.4e}"
        );
    }
}

#[test]
fn the_rotating_cantilever_at_high_speed_converges_under_accuracy_control_from_a_coarse_step() {
    // Issue 14: at Ω̄ = 20 the shipped step read the tip peak 17× and the root moment peak
    // 160× low. `--accuracy 1e-2` from that step, dt = 0.01 (the scene ships at 1e-4 s
    // since session 23), no step chosen by hand,
    // against a fixed step of 3.9e-5 s (itself within 7.4e-4 of a run at half of it,
    // measured). Measured over 4 s: Ω̄ = 20, 3 runs, 27 200 steps, largest difference
    // 6.3e-3 of the range (root moment); Ω̄ = 50, 3 runs, 39 172 steps, 7.3e-3. The
    // tolerance is the request itself. (Until session 18 the beam started unstretched:
    // its axial ringing pumped the flap motion and no step made the history converge.)
    let cases: Vec<_> = [20.0, 50.0]
        .into_iter()
        .map(|w| {
            std::thread::spawn(move || {
                let o = format!("omega={w}");
                let base = [
                    "models/rotating_cantilever.toml",
                    "--set",
                    &o,
                    "--set",
                    "dt=0.01",
                ];
                let mut a = base.to_vec();
                a.extend(["--set", "t_end=4", "--accuracy", "1e-2"]);
                let adaptive = run_json(&a);
                let mut r = base.to_vec();
                r.extend(["--set", "t_end=4", "--set", "dt=3.90625e-5"]);
                (w, adaptive, run_json(&r))
            })
        })
        .collect();
    for c in cases {
        let (w, adaptive, reference) = c.join().unwrap();
        assert!(warnings(&adaptive).is_empty(), "Ω̄ = {w}: {adaptive}");
        assert!(adaptive["accuracy"]["runs"].as_u64().unwrap() >= 2);
        for s in ["tip_flap", "root_moment"] {
            let e = history_error(&adaptive, &reference, s);
            eprintln!(
                "Ω̄ = {w}: {s} differs by {e:.2e} of its range ({} steps in all runs)",
                adaptive["accuracy"]["steps_all_runs"]
            );
            assert!(e <= 1e-2, "Ω̄ = {w}, {s}: {e}");
        }
    }
}

/// The rotating cantilever on 10 elements over 4 s, without its mesh twin: the scene of
/// the tests of runs that stop.
const CANTILEVER_4S: [&str; 7] = [
    "models/rotating_cantilever.toml",
    "--set",
    "elements=10",
    "--set",
    "t_end=4",
    "--mesh-check",
    "never",
];

/// The runs `--accuracy` made, from `run --json`'s `accuracy.history`.
fn accuracy_runs(v: &Value) -> &Vec<Value> {
    v["accuracy"]["history"].as_array().unwrap()
}

#[test]
fn a_run_that_cannot_meet_its_target_stops_early_and_the_result_still_meets_it() {
    // The rotating cantilever (10 elements, 4 s) from dt = 0.08 at 5e-3: its third run,
    // at 3.1e-4 s, reads 2.2e-2 whole (measured) and passes twice the target at 1.6 s,
    // after a quarter of its span: it stops there, and the fourth run is predicted from
    // its error so far grown over the rest (`ACCURACY_STOP`). The result must meet the
    // target against a run at 3.9e-5 s (itself within 7.4e-4 of a run at half of it on
    // the 30-element scene; the tolerance is the request itself), and the stopped run
    // must have made fewer steps than it would whole.
    let tol = 5e-3;
    let mut a = CANTILEVER_4S.to_vec();
    a.extend(["--set", "dt=0.08", "--accuracy", "5e-3"]);
    let adaptive = run_json(&a);
    let mut r = CANTILEVER_4S.to_vec();
    r.extend(["--set", "dt=3.90625e-5"]);
    let reference = run_json(&r);
    assert!(warnings(&adaptive).is_empty(), "{adaptive}");
    let runs = accuracy_runs(&adaptive);
    let stopped: Vec<&Value> = runs.iter().filter(|h| !h["stopped_at"].is_null()).collect();
    assert!(!stopped.is_empty(), "no run stopped: {runs:?}");
    for h in &stopped {
        let (t, e, dt) = (
            h["stopped_at"].as_f64().unwrap(),
            h["error_when_stopped"].as_f64().unwrap(),
            h["dt"].as_f64().unwrap(),
        );
        assert!(
            (1.0..4.0).contains(&t),
            "stopped before a quarter or at the end: {h}"
        );
        assert!(e > 2.0 * tol, "stopped below twice the target: {h}");
        assert!(
            h["estimate"].as_f64().unwrap() >= e,
            "projected below its error so far: {h}"
        );
        let whole = (4.0 / dt).ceil() as u64;
        assert!(
            h["steps"].as_u64().unwrap() < whole,
            "{h}: not fewer than {whole} steps"
        );
    }
    let last = runs.last().unwrap();
    assert!(
        last["stopped_at"].is_null(),
        "the result is a stopped run: {runs:?}"
    );
    let all: u64 = runs.iter().map(|h| h["steps"].as_u64().unwrap()).sum();
    assert_eq!(adaptive["accuracy"]["steps_all_runs"].as_u64(), Some(all));
    for s in ["tip_flap", "root_moment"] {
        let e = history_error(&adaptive, &reference, s);
        eprintln!("{s}: {e:.2e} of its range off dt = 3.9e-5 s ({all} steps in all runs)");
        assert!(e <= tol, "{s}: {e}");
    }
}

#[test]
fn a_stopped_run_that_must_be_the_result_is_finished_as_the_same_run_whole() {
    // Under a step limit of 20 000 the run after the stopped one (35 267 steps,
    // measured) is not made: the stopped run, at 3.125e-4 s, is the result after all and
    // goes on from where it stopped. It must be whole (12 800 steps), its estimate the
    // same run's at that fixed step without `--accuracy` (to round-off: its transported
    // error is restored from the checkpoint, not restarted), and the target warned unmet.
    let mut a = vec!["run"];
    a.extend(CANTILEVER_4S);
    a.extend(["--set", "dt=0.08", "--accuracy", "5e-3", "--json"]);
    let adaptive = common::latdyn_json_env(&a, &[("LATDYN_LIMITS", "steps=20000")]);
    let mut f = CANTILEVER_4S.to_vec();
    f.extend(["--set", "dt=3.125e-4"]);
    let fixed = run_json(&f);
    let w = warnings(&adaptive).join("\n");
    assert!(
        w.contains("was not met") && w.contains("over the limit"),
        "{w}"
    );
    let last = accuracy_runs(&adaptive).last().unwrap();
    assert_eq!(last["dt"].as_f64(), Some(3.125e-4), "{last}");
    assert!(last["stopped_at"].is_null(), "{last}");
    assert_eq!(last["steps"].as_u64(), Some(12_800), "{last}");
    assert_eq!(adaptive["steps"].as_u64(), Some(12_800));
    let (e, e_fixed) = (
        adaptive["time_error_estimate"].as_f64().unwrap(),
        fixed["time_error_estimate"].as_f64().unwrap(),
    );
    assert_eq!(last["estimate"].as_f64(), Some(e));
    assert!(
        (e - e_fixed).abs() <= 1e-9 * e_fixed,
        "{e} against {e_fixed}"
    );
}

#[test]
fn a_load_pulse_that_falls_between_the_steps_is_warned_and_refined_under_accuracy_control() {
    // The rotating cantilever's smooth 0.05 s tip pulse at dt = 0.1: both ends of the first
    // step see a zero time factor, so the run applies no load, its response is zero and so
    // is its time-error estimate. The missed impulse (100 %) is the warning and, under
    // `--accuracy`, the first run's error (measured: 5 runs, from dt = 0.1 to 5.6e-4, tip
    // peak 7.58e-4 m against 7.64e-4 m at dt = 5e-4; tolerance: the request, 5 % of the
    // peak-to-peak range 1.5e-3 m).
    let base = [
        "models/rotating_cantilever.toml",
        "--set",
        "t_end=2",
        "--set",
        "dt=0.1",
    ];
    let fixed = run_json(&base);
    let w = warnings(&fixed);
    assert!(
        w.iter()
            .any(|w| w.contains("too large for the loads") && w.contains("100.0 % less")),
        "{w:?}"
    );
    let mut a = base.to_vec();
    a.extend(["--accuracy", "0.05"]);
    let adaptive = run_json(&a);
    assert!(warnings(&adaptive).is_empty(), "{adaptive}");
    let hist = adaptive["accuracy"]["history"].as_array().unwrap();
    assert_eq!(hist[0]["estimate"].as_f64(), Some(1.0), "{hist:?}");
    let mut r = base.to_vec();
    r.extend(["--set", "dt=5e-4"]);
    let reference = run_json(&r);
    let peak = |v: &Value| v["sensors"]["tip_flap"]["max"][0].as_f64().unwrap();
    let range = peak(&reference) - reference["sensors"]["tip_flap"]["min"][0].as_f64().unwrap();
    eprintln!("tip peak {} against {}", peak(&adaptive), peak(&reference));
    assert!((peak(&adaptive) - peak(&reference)).abs() <= 0.05 * range);
}

#[test]
fn a_load_of_zero_force_and_moment_is_not_warned_for_the_impulse_its_factor_misses() {
    // The same pulse switched off (`disturbance = 0`): the factor still falls between the
    // steps, but a load of zero applies nothing to miss. Until session 39 it warned of
    // 44.7 % of its impulse missed at dt = 0.08 and `--accuracy` counted that as error.
    let zero = run_json(&[
        "models/rotating_cantilever.toml",
        "--set",
        "t_end=2",
        "--set",
        "dt=0.08",
        "--set",
        "disturbance=0",
    ]);
    assert!(warnings(&zero).is_empty(), "{:?}", warnings(&zero));
    assert!(zero["load_impulse_error"].is_null(), "{zero}");
    // and the same step with the load on is still warned
    let on = run_json(&[
        "models/rotating_cantilever.toml",
        "--set",
        "t_end=2",
        "--set",
        "dt=0.08",
    ]);
    assert!(
        warnings(&on)
            .iter()
            .any(|w| w.contains("too large for the loads")),
        "{:?}",
        warnings(&on)
    );
}

#[test]
fn a_pulse_narrower_than_the_sampling_of_a_step_is_still_warned_and_refined() {
    // t_pulse = 1e-3 at dt = 0.01: the pulse lies between all nine points at which each
    // step's time factor used to be sampled, so the run applied no load, reported a zero
    // response and no warning. The factor's interval enclosure now finds it (100 % missed);
    // under `--accuracy` the steps shrink until they apply it. Measured: 6 runs down to
    // dt = 2.0e-5 (the last from t = 0), estimate 0.038, tip peak 7.96e-4 m against
    // 7.88e-4 m at dt = 1e-5, 0.8 % of the range (8.9e-4 m); before the band caps 5 runs
    // down to 1.5e-5, estimate 0.035, 5.3 % of the range. Tolerance: 3× the request of 5 %, the factor within which
    // the estimate tracks the true error (README "Accuracy"); a missed pulse is 100 % off.
    // On the 10 elements these figures were measured on (the shipped mesh until session
    // 49), and without the mesh check: a 1 ms pulse rings modes no mesh here resolves
    // (its root moment is 53 % off on 30 elements, estimated and warned), while this
    // test is about the steps.
    let base = [
        "models/rotating_cantilever.toml",
        "--set",
        "t_end=0.5",
        "--set",
        "dt=0.01",
        "--set",
        "t_pulse=1e-3",
        "--set",
        "elements=10",
        "--mesh-check",
        "never",
    ];
    for tp in ["1e-3", "1e-8"] {
        let set = format!("t_pulse={tp}");
        let mut a = base.to_vec();
        a.extend(["--set", &set]);
        let fixed = run_json(&a);
        assert_eq!(
            fixed["load_impulse_error"].as_f64(),
            Some(1.0),
            "{tp}: {fixed}"
        );
        assert!(
            warnings(&fixed)
                .iter()
                .any(|w| w.contains("too large for the loads") && w.contains("100.0 % less")),
            "{tp}: {fixed}"
        );
    }
    let mut a = base.to_vec();
    a.extend(["--accuracy", "0.05"]);
    let adaptive = run_json(&a);
    assert!(warnings(&adaptive).is_empty(), "{adaptive}");
    let mut r = base.to_vec();
    r.extend(["--set", "dt=1e-5"]);
    let reference = run_json(&r);
    let peak = |v: &Value| v["sensors"]["tip_flap"]["max"][0].as_f64().unwrap();
    let range = peak(&reference) - reference["sensors"]["tip_flap"]["min"][0].as_f64().unwrap();
    eprintln!(
        "tip peak {} against {} (range {range}), runs {}",
        peak(&adaptive),
        peak(&reference),
        adaptive["accuracy"]["history"]
    );
    assert!(range > 0.0 && (peak(&adaptive) - peak(&reference)).abs() <= 0.15 * range);
}

#[test]
fn a_drive_jerk_between_the_steps_is_warned_and_a_smooth_drive_is_not() {
    // The spin-up beam's hub with a 0.05 rad, 0.4 ms jerk at t = 2.0025 s, between two
    // step ends at dt = 0.005: the steps see the drive only at their ends, so the run never
    // applied the jerk (hub torque peak 176 N·m against 1106 at dt = 1e-4, which resolves
    // it) and warned nothing. Now the drive check finds it (measured 0.9996 of the jerk's
    // rate). The shipped drive departs by round-off only (measured 1.2e-11).
    let path = shipped_with(
        "spinup_beam.toml",
        "ws*(t - min(t,Ts))\"",
        "ws*(t - min(t,Ts)) + 0.05*exp(-(((t - 2.0025)/2e-4)^2))\"",
        "drive-jerk",
    );
    let v = run_json(&[path.to_str().unwrap(), "--set", "t_end=3"]);
    assert!(v["drive_rate_error"].as_f64().unwrap() > 0.5, "{v}");
    assert!(
        warnings(&v)
            .iter()
            .any(|w| w.contains("too large for the drives") && w.contains("hub.dofs[0]")),
        "{:?}",
        warnings(&v)
    );
    let shipped = run_json(&["models/spinup_beam.toml", "--set", "t_end=3"]);
    assert!(
        shipped["drive_rate_error"].as_f64().unwrap() < 1e-6,
        "{shipped}"
    );
    assert!(warnings(&shipped).is_empty(), "{:?}", warnings(&shipped));
    std::fs::remove_dir_all(path.parent().unwrap()).ok();
}

#[test]
fn a_load_faster_than_the_steps_sample_it_is_warned_not_applied_at_an_alias() {
    // A 99 Hz tip force on the rotating cantilever at dt = 0.01 (100 samples per second):
    // the steps see sin(2π·99 t_n) = −sin(2π t_n), a 1 Hz load. The run reported a tip
    // peak of 0.023 m (2.7e-5 m at dt = 5e-4), its impulse check read 1e-15 (the aliased
    // samples cancel over the run) and it warned nothing. The factor's distance from the
    // straight lines between the steps' ends reads 1.27 of its ∫|s| dt (limit 0.5; a
    // resolved sinusoid at 20 samples per period reads 0.008).
    let path = shipped_with(
        "rotating_cantilever.toml",
        "scale = \"(1 - signum(t - t_pulse)) * sin(pi*t/t_pulse)^2\"",
        "scale = \"sin(2*pi*99*t)\"",
        "alias",
    );
    let p = path.to_str().unwrap();
    let coarse = run_json(&[p, "--set", "t_end=1", "--set", "dt=0.01"]);
    assert!(
        coarse["load_sampling_error"].as_f64().unwrap() > 1.0,
        "{coarse}"
    );
    assert!(
        warnings(&coarse)
            .iter()
            .any(|w| w.contains("too large for the loads") && w.contains("faster than the steps")),
        "{:?}",
        warnings(&coarse)
    );
    let fine = run_json(&[p, "--set", "t_end=1", "--set", "dt=5e-4"]);
    assert!(
        fine["load_sampling_error"].as_f64().unwrap() < 0.05,
        "{fine}"
    );
    assert!(
        !warnings(&fine).iter().any(|w| w.contains("for the loads")),
        "{:?}",
        warnings(&fine)
    );
    // the shipped pulse at dt = 0.01 (5 steps per pulse) reads 0.08: not aliased
    let shipped = run_json(&[
        "models/rotating_cantilever.toml",
        "--set",
        "t_end=1",
        "--set",
        "dt=0.01",
    ]);
    let e = shipped["load_sampling_error"].as_f64().unwrap();
    assert!(e > 0.05 && e < 0.15, "{e}");
    std::fs::remove_dir_all(path.parent().unwrap()).ok();
}

#[test]
fn a_time_error_after_a_hinge_lock_names_the_lock_as_its_likely_cause() {
    // The Mini-Mast bay's diagonal mid-hinges lock at t ≈ 0.985 s; the member forces the
    // lock sets ringing do not converge at any step tried (README "Accuracy"). The
    // warning must say so, not only "reduce dt". Before the lock, nothing to add.
    let v = run_json(&["models/minimast_bay.toml"]);
    let w = warnings(&v);
    let time = w
        .iter()
        .find(|w| w.contains("time step too large for the frequencies"))
        .unwrap_or_else(|| panic!("{w:?}"));
    assert!(
        time.contains("locked at t = 0.98") && time.contains("a lock is an impact"),
        "{time}"
    );
    // The estimate up to the lock is reported beside it, and it is the run's error up to
    // the lock: measured (session 23) 2.7e-2 against a true 2.4e-2 (longeron mid-span
    // moment up to t = 0.98 s against dt = 6.25e-5 s, which the mid-hinges' snap in the
    // last 30 ms before the lock dominates). Bounds: the factor 3 of an estimate, against
    // a run over the same span at 1/8 of the step (whose own error is 1/64 of it).
    let before = v["time_error_before_first_lock"].as_f64().unwrap();
    assert!(
        time.contains(&format!(
            "up to that lock the estimate was {:.2} %",
            100.0 * before
        )),
        "{time}"
    );
    let sets = ["t_end=0.98", "dt=0.000125"];
    let span = run_json(&["models/minimast_bay.toml", "--set", sets[0]]);
    let fine = run_json(&[
        "models/minimast_bay.toml",
        "--set",
        sets[0],
        "--set",
        sets[1],
    ]);
    let truth = [
        "longeron_mid",
        "longeron_top",
        "diagonal_a_mid",
        "longeron_rotation",
    ]
    .iter()
    .map(|s| history_error(&span, &fine, s))
    .fold(0.0, f64::max);
    eprintln!("up to the lock: estimate {before:.3e}, error against dt/8 {truth:.3e}");
    assert!(
        before > truth / 3.0 && before < 3.0 * truth,
        "{before} vs {truth}"
    );
    let early = run_json(&["models/minimast_bay.toml", "--set", "t_end=0.5"]);
    assert!(
        warnings(&early).iter().all(|w| !w.contains("locked at")),
        "{:?}",
        warnings(&early)
    );
}

#[test]
fn a_sweep_reports_each_variants_estimate_before_its_first_lock_in_json_and_hdf5() {
    // A campaign is read as a table, so the figure `run --json` gives beside a lock
    // warning (above) must reach it too: per variant in `sweep --json` and in
    // /status/time_error_before_first_lock, each bit-identical to the variant run alone;
    // null (NaN in the file) where nothing locks.
    let dir = std::env::temp_dir().join(format!("latdyn-lock-sweep-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let sweep = |model: &str, vary: &str, file: &str| -> (Value, Vec<f64>) {
        let path = dir.join(file);
        let _ = std::fs::remove_file(&path);
        let out = latdyn(&[
            "sweep",
            model,
            "--vary",
            vary,
            // the time error's columns are the subject here (the mesh twins would double
            // the Mini-Mast's cost)
            "--mesh-check",
            "never",
            "-o",
            path.to_str().unwrap(),
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        let f = rust_hdf5::H5File::open(&path).unwrap();
        let col = f
            .dataset("status/time_error_before_first_lock")
            .unwrap()
            .read_raw::<f64>()
            .unwrap();
        (v, col)
    };
    let (v, col) = sweep("models/minimast_bay.toml", "T=0.9:1.1:2", "locks.h5");
    let variants = v["variants"].as_array().unwrap();
    assert_eq!((variants.len(), col.len()), (2, 2));
    for (k, var) in variants.iter().enumerate() {
        let t = var["parameters"]["T"].as_f64().unwrap();
        let alone = run_json(&["models/minimast_bay.toml", "--set", &format!("T={t}")]);
        let before = var["time_error_before_first_lock"].as_f64().unwrap();
        assert_eq!(
            before.to_bits(),
            alone["time_error_before_first_lock"]
                .as_f64()
                .unwrap()
                .to_bits(),
            "T = {t}"
        );
        assert_eq!(col[k].to_bits(), before.to_bits(), "T = {t}");
        // the whole run's estimate is at its cap after the lock, the span before it is not
        assert!(before > 0.0 && before < var["time_error_estimate"].as_f64().unwrap());
    }
    let (v, col) = sweep("models/pendulum.toml", "theta0=0.1:0.2:2", "no_locks.h5");
    for var in v["variants"].as_array().unwrap() {
        assert!(var["time_error_before_first_lock"].is_null(), "{var}");
    }
    assert!(col.iter().all(|x| x.is_nan()), "{col:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Tip deflection of the spin-up beam as shipped (spun up to 6 rad/s in 15 s, then
/// held) at the output times 0.05 s apart, stepped at `coarse` except for
/// 16 s ≤ t < 18 s at `fine`; `accuracy` switches the accuracy-controlled arithmetic on.
/// With the run's time-error estimate.
fn spin_up_with_a_window(coarse: f64, fine: f64, accuracy: bool) -> (Vec<f64>, f64) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/spinup_beam.toml");
    let mut model = latdyn::model::compile::load(&path, &[("dt".to_string(), fine)]).unwrap();
    model.solver.accuracy = accuracy.then_some(0.1);
    let k = model.sensor_index("tip_deflection").unwrap();
    let mut it = latdyn::solver::dynamics::Integrator::new(&model).unwrap();
    let mut tip = vec![it.sample()[k][0]];
    for i in 1..=400 {
        let t = 0.05 * i as f64;
        it.h = if (16.0..18.0).contains(&(t - 0.025)) {
            fine
        } else {
            coarse
        };
        it.advance_to(t).unwrap();
        tip.push(it.sample()[k][0]);
    }
    (tip, it.run_stats().time_error_estimate.unwrap())
}

#[test]
fn a_change_of_step_size_on_a_rotor_adds_no_error_of_its_own() {
    // At a fixed step the scheme's velocity lies O(h²) off the exact one (by c h² y‴), and
    // on a rotor y‴ is Ω² times the rigid-body velocity: a step of another size used to
    // start from the old size's velocity, a kick on the lag mode. Reference: 1/16 of the
    // coarse step (its own error under 1/256 of the coarse one's). Measured: coarse
    // throughout 3.1e-3 of the range, coarse with a fine window 3.1e-3 as accuracy
    // control steps it (2.2e-2 with the auxiliary acceleration moved but not the
    // velocity), 2.6e-2 with the fixed-step arithmetic (which changes steps only after a
    // failed one and keeps its old numbers). The estimate follows the moved
    // velocity (its transported error moves with it): 4.8e-3 against the true 3.1e-3,
    // within the estimate's factor 3 (`the_estimate_is_within_a_factor_three_...`).
    let (coarse, fine) = (0.0125, 0.00625);
    let (reference, _) = spin_up_with_a_window(coarse / 16.0, coarse / 16.0, true);
    let range = reference.iter().cloned().fold(f64::MIN, f64::max)
        - reference.iter().cloned().fold(f64::MAX, f64::min);
    let error = |y: &[f64]| {
        y.iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs() / range)
            .fold(0.0, f64::max)
    };
    let uniform = error(&spin_up_with_a_window(coarse, coarse, true).0);
    let (window, estimate) = spin_up_with_a_window(coarse, fine, true);
    let moved = error(&window);
    let kicked = error(&spin_up_with_a_window(coarse, fine, false).0);
    eprintln!(
        "coarse {uniform:.2e}, with a fine window {moved:.2e} (estimate {estimate:.2e}), \
         fixed-step arithmetic {kicked:.2e}"
    );
    // 1.2: the window's own steps cut the error a little, the moves must not add to it
    assert!(
        moved <= 1.2 * uniform,
        "window {moved:.2e} against {uniform:.2e}"
    );
    assert!(
        estimate >= moved && estimate <= 3.0 * moved,
        "estimate {estimate:.2e} against the true {moved:.2e}"
    );
    assert!(
        kicked > 3.0 * uniform,
        "the case no longer tests the kick: {kicked:.2e}"
    );
}

#[test]
fn accuracy_stops_after_two_runs_whose_estimate_does_not_fall_with_the_step() {
    // The four-bar launched with its cranks at rest (`fourbar_at_rest`): the cranks vibrate
    // above 1/dt at every practical step, and the error does not converge (0.23-0.37 of the
    // range from dt = 0.01 to 0.00125). Its estimate reads that: 0.20, 0.24, 0.42 at
    // 0.01, 1.1e-3, 1.0e-4 s (session 42), which says nothing about the step needed: each
    // further run would only multiply the cost (it ran for 14 minutes). Until session 42
    // the estimate read the size of the signal here (1.02 at 0.01 s, 1.38 at 8.3e-4 s),
    // and the rule for two runs at that size stopped it.
    let at_rest = fourbar_at_rest("stuck");
    let v = run_json(&[
        at_rest.to_str().unwrap(),
        "--set",
        "v0=0.2",
        "--set",
        "dt=0.02",
        "--accuracy",
        "1e-2",
    ]);
    let a = &v["accuracy"];
    assert_eq!(a["runs"], 3, "{a}");
    let hist = a["history"].as_array().unwrap();
    for pair in hist.windows(2) {
        let (h0, e0) = (
            pair[0]["dt"].as_f64().unwrap(),
            pair[0]["estimate"].as_f64().unwrap(),
        );
        let (h1, e1) = (
            pair[1]["dt"].as_f64().unwrap(),
            pair[1]["estimate"].as_f64().unwrap(),
        );
        assert!(h1 < h0 && e1 >= e0 * (h1 / h0).powf(0.1), "{a}");
    }
    let w = warnings(&v);
    assert!(
        w.iter()
            .any(|w| w.contains("was not met")
                && w.contains("the estimate does not fall with the step")),
        "{w:?}"
    );
}

/// The estimate transports the error with the step's iteration matrix. A loose Newton
/// tolerance ends most steps of a coarse rotor run before modified Newton refreshes the
/// Jacobian of its predictor, whose forces (and geometric stiffness) are far off; the
/// estimate then read its cap, 2.0, for a run 2e-3 of its range off the tight one. The
/// matrix is now refactored at the converged state for such steps. Bound: the loose run's
/// estimate within 1.5x of the tight run's (measured 1.22x: 2.25e-2 against 1.84e-2, the
/// difference the looser Newton's own error, 2e-3 of the range, plus its transport).
#[test]
fn a_loose_newton_tolerance_does_not_inflate_the_time_error_estimate() {
    let loose = shipped_with(
        "spinup_beam.toml",
        "[solver]\n",
        "[solver]\ntol = 1e-4\n",
        "loose-tol",
    );
    let tight = run_json(&["models/spinup_beam.toml", "--set", "dt=0.04"]);
    let l = run_json(&[loose.to_str().unwrap(), "--set", "dt=0.04"]);
    let (et, el) = (
        tight["time_error_estimate"].as_f64().unwrap(),
        l["time_error_estimate"].as_f64().unwrap(),
    );
    assert!(et > 5e-3 && et < 5e-2, "tight estimate {et}");
    assert!(el < 1.5 * et, "loose {el} against tight {et}");
    // and the loose run is as accurate as the tight one at the level that matters
    let diff = history_error(&l, &tight, "tip_deflection");
    assert!(diff < 1e-2, "loose run off the tight one by {diff}");
}

/// A load whose time factor has a pole inside a step (finite at every step end) made
/// both load checks NaN, reported as null ("no time factors"), with no word. Now warned.
#[test]
fn a_load_factor_that_is_not_finite_inside_a_step_is_warned() {
    let path = shipped_with(
        "cantilever.toml",
        "moment = [0, \"M\", 0]\n",
        "moment = [0, \"M\", 0]\nscale = \"1e-3/(t-0.0205)\"\n",
        "load-pole",
    );
    let v = run_json(&[path.to_str().unwrap(), "--set", "P=1"]);
    let w = warnings(&v);
    assert!(
        w.iter()
            .any(|w| w.contains("is not finite somewhere between two step ends")),
        "{w:?}"
    );
}

/// The four-bar's coupler translates without turning: its rz drifts by round-off, 9e-14
/// rad over 0.1 s, which the estimate divided by and read as 200 % (and a warning
/// naming the coupler). Rotation components below 1e-12 rad are now round-off.
#[test]
fn a_rotation_component_at_round_off_is_not_read_as_a_time_error() {
    let v = run_json(&["models/fourbar.toml", "--set", "t_end=0.1"]);
    let coupler = v["time_error_by_sensor"]["coupler"].as_f64().unwrap();
    assert!(coupler < 0.05, "coupler estimate {coupler}: {v}");
}

/// The estimate's figure is capped at twice the range (`GLOBAL_ERROR_CAP`) for every
/// component: a cantilever of EI = 1e12 stepped at 1e-3 s (its vibration at 3.5e6 rad/s
/// unresolved: the warning is true) read 57 730 % through a component whose range was
/// still round-off when the cap was applied.
#[test]
fn the_time_error_figure_never_exceeds_its_cap() {
    let v = run_json(&[
        "models/cantilever.toml",
        "--set",
        "EI=1e12",
        "--set",
        "EA=1e12",
        "--set",
        "GJ=1e12",
        "--set",
        "P=1",
    ]);
    let e = v["time_error_estimate"].as_f64().unwrap();
    assert!(e <= 2.0 + 1e-12, "{e}");
    assert!(!warnings(&v).is_empty());
}

#[test]
fn a_checkpoint_that_would_save_under_a_tenth_of_the_run_is_not_resumed() {
    // The rotating cantilever's tip pulse (t < 0.05 s) rings its flap modes for the whole
    // record. From dt = 0.08 at a target of 2e-2 over 4 s, the third run (4.6e-4 s) reads
    // 4.2e-2. Its latest checkpoint within the kept part's budget is at 0.32 s, 8 % of
    // the span: resumed there at 2.7e-4 s the run read 2.4e-2 (the pulse's ringing kept
    // from the coarser step adds up later to more than it showed at the checkpoint) and
    // a fifth run followed (44 870 steps in all). A saving under a tenth of the run is
    // not worth that risk (`ACCURACY_RESUME_SAVING`): the fourth run starts from t = 0
    // and meets the target (measured: 24 499 steps, estimate 1.72e-2).
    let sets = ["--set", "t_end=4"];
    let v = run_json(
        &[
            &["models/rotating_cantilever.toml"],
            &sets[..],
            &["--set", "dt=0.08", "--accuracy", "2e-2"],
        ]
        .concat(),
    );
    let hist = v["accuracy"]["history"].as_array().unwrap();
    for run in hist {
        let from = run["from"].as_f64().unwrap();
        assert!(from == 0.0 || from >= 0.4, "{}", v["accuracy"]);
    }
    assert!(hist.len() <= 4, "{}", v["accuracy"]);
    let est = v["time_error_estimate"].as_f64().unwrap();
    assert!(est <= 2e-2, "{}", v["accuracy"]);
    // and what it reports holds on its output grid (0.08 s, `max(dt, 0.01)`): against a
    // run at 5e-5 s (itself 6.0e-4 of the range off one at 1.25e-5 s, a thirtieth of the
    // target) both sensors are within the target (measured: root moment 1.03e-2)
    let reference = run_json(
        &[
            &["models/rotating_cantilever.toml"],
            &sets[..],
            &["--set", "dt=5e-5"],
        ]
        .concat(),
    );
    for sensor in ["root_moment", "tip_flap"] {
        let truth = history_error(&v, &reference, sensor);
        assert!(truth <= 2e-2, "{sensor}: {truth:.3e}");
    }
}

/// Turning a scene in space changes no answer, its time-error estimate included. A
/// cantilever sagging under gravity (dt = 1e-3 s, 1.46 % estimated, 1.9 % true against
/// 5e-5 s) has a second tip sensor across the sag whose truth is zero; turned by
/// (0.7, −1.1, 2.3) rad it reads 1.4e-15 m of round-off. That sensor was warned at
/// 200 %, and the global cap (its deviation over its range) scaled the whole carried
/// error down, so the sag read 5.9e-5 (a probe in session 46). Now the round-off sensor
/// has no figure (a range below 1e-12 of the largest range in metres) and the sag reads
/// the same turned or not, moved 1e6 m away or not (to 1e-6 of itself: the turned
/// model's round-off).
#[test]
fn turning_or_moving_a_scene_leaves_its_time_error_estimate_unchanged() {
    let model = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/models/cantilever_turned.toml"
    );
    let run = |extra: &[&str]| {
        let mut args = vec![
            model, "--set", "gon=1", "--set", "t_end=3", "--set", "dt=1e-3",
        ];
        args.extend_from_slice(extra);
        run_json(&args)
    };
    let plain = run(&[]);
    let sag = plain["time_error_by_sensor"]["tip_z"].as_f64().unwrap();
    assert!(sag > 1e-2 && sag < 2e-2, "{plain}");
    for extra in [
        &["--set", "a=0.7", "--set", "b=-1.1", "--set", "c=2.3"][..],
        &[
            "--set", "a=0.7", "--set", "b=-1.1", "--set", "c=2.3", "--set", "X0=1e6",
        ][..],
    ] {
        let v = run(extra);
        let turned = v["time_error_by_sensor"]["tip_z"].as_f64().unwrap();
        assert!(rel(turned, sag) < 1e-6, "{extra:?}: {turned} against {sag}");
        let w = warnings(&v);
        assert!(w.len() == 1 && w[0].contains("`tip_z`"), "{extra:?}: {w:?}");
    }
}

/// Round-off accumulates over the steps: the shipped four-bar's coupler, which keeps
/// its orientation, reads 2e-12 rad in its rz on 16 elements at dt = 5e-4 s against
/// 0.5 rad of hinge angles, and that was estimated at 88 % and warned (a probe, session
/// 46). A range below 1e-9 of the largest in its unit is round-off: no figure, no
/// warning.
#[test]
fn an_accumulated_round_off_rotation_is_not_warned_as_a_time_error() {
    let v = run_json(&[
        "models/fourbar.toml",
        "--set",
        "elements=16",
        "--set",
        "dt=5e-4",
    ]);
    assert!(warnings(&v).is_empty(), "{v}");
    assert!(
        v["time_error_by_sensor"]["coupler"].as_f64().unwrap() < 1e-2,
        "{v}"
    );
}

/// A run whose span is whole output intervals but for a sliver (3e-8 of one) ends its
/// last interval at t_end instead of adding a 1e-10 s interval, whose step could not be
/// factored: the run failed (exit 3) until session 48 (a probe).
#[test]
fn a_last_output_interval_of_a_sliver_is_merged_into_the_one_before() {
    let v = run_json(&["tests/models/output_interval_sliver.toml", "--set", "P=10"]);
    assert_eq!(v["status"], "completed", "{v}");
    let t: Vec<f64> = v["sensors"]["tip"]["t"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(t, [0.0, 0.0033333333, 0.0066666666, 0.01], "{v}");
    assert!(v["sensors"]["tip"]["final"][2].as_f64().unwrap() != 0.0);
    let m = latdyn::model::load(
        std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/models/output_interval_sliver.toml"
        )),
        &[],
    )
    .unwrap();
    let t = latdyn::solver::dynamics::output_times(&m);
    assert_eq!(t.len(), 4);
    assert_eq!(*t.last().unwrap(), 0.01);
}
