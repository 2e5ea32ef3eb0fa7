//! Diagnoses instead of symptoms (issue 15): singular statics names the free motion, a
//! limit point says so with the load reached, zero load succeeds at once, an unreachable
//! tolerance stops; a drive or load that turns NaN names its expression and the time.

mod common;
use common::*;
use latdyn::solver::{solve_statics, statics::StaticsError};

const PROPS: &str = r#"EA = 1.0e7
EIy = 100.0
EIz = 100.0
GJ = 80.0
rhoA = 1.0"#;

fn free_motion(e: StaticsError) -> String {
    match e {
        StaticsError::FreeMotion { motions, .. } => motions,
        other => panic!("expected a free motion, got: {other}"),
    }
}

/// A beam with no support: six rigid-body motions, named by coordinate (was "load
/// factor stuck at 0.000000 ... residual 0.000e0").
#[test]
fn free_floating_statics_names_six_rigid_motions() {
    let m = straight_beam("free", 4, PROPS, [0.0, 0.0, 1.0], [0.0; 3], "");
    let e = solve_statics(&m)
        .err()
        .expect("a free body has no static equilibrium");
    let msg = e.to_string();
    let motions = free_motion(e);
    eprintln!("{msg}");
    assert!(msg.contains("free motions"), "{msg}");
    assert!(
        motions.contains("6: [") && !motions.contains("7: ["),
        "{motions}"
    );
}

/// A pinned cantilever (translations held, rotations free at the root) swings rigidly
/// about the pin: three free motions, one of them the pure twist about the beam axis
/// (every node's `rx` and nothing else).
#[test]
fn pinned_cantilever_statics_names_the_three_rotations_about_the_pin() {
    let m = straight_beam("pinned", 4, PROPS, [0.0, 0.0, 1.0], [0.0; 3], "");
    let motions = free_motion(solve_statics(&m).err().expect("singular"));
    eprintln!("{motions}");
    assert!(
        motions.contains("3: [") && !motions.contains("4: ["),
        "{motions}"
    );
    let twist = motions
        .split("; ")
        .find(|p| p.contains(".rx") && !p.contains(".ry") && !p.contains(".rz"))
        .unwrap_or_else(|| panic!("no pure twist among {motions}"));
    assert_eq!(twist.matches(".rx").count(), 5, "{twist}");
}

/// Zero load on the curved bend: the reference is the equilibrium, zero Newton
/// iterations (was "load factor stuck at 0.000000", the residual being round-off of a
/// curved mesh with no force scale to compare it to).
#[test]
fn zero_load_statics_on_the_curved_bend_succeeds_with_zero_iterations() {
    let v = latdyn_json(&["statics", "models/bend45.toml", "--set", "P=0", "--json"]);
    assert_eq!(v["newton_iterations"], 0, "{v}");
    let tip = v["sensors"]["tip"].as_array().unwrap();
    // the tip stays at R sin 45°, R (1 − cos 45°), 0
    let r = 100.0f64;
    let want = [r * 0.5f64.sqrt(), r * (1.0 - 0.5f64.sqrt()), 0.0];
    for (g, w) in tip.iter().zip(want) {
        assert!((g.as_f64().unwrap() - w).abs() < 1e-9, "{tip:?}");
    }
}

/// A stiff model at zero load (EA = 1e18): the residual is exactly 0, which counts even
/// though the factorization calls the Jacobian singular.
#[test]
fn zero_load_statics_of_a_stiff_cantilever_succeeds() {
    let out = latdyn(&["statics", "models/cantilever.toml", "--set", "EA=1e18"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A shallow arch loaded past its limit point (symmetric limit load ≈ 1.18, P = 3): load
/// control used to jump to the snapped-through branch and report it as if the path were
/// continuous; now Newton steps that travel far beyond the tangent prediction are
/// rejected and the solve ends at the limit with the load reached. The reached load
/// factor times P must be the same limit load whatever P is (1e-3 relative: the step
/// halving stops within 1e-7 of the load factor, the branch-jump guard a little earlier).
#[test]
fn statics_past_a_limit_point_says_so_with_the_load_reached() {
    let mut reached = Vec::new();
    for p in ["3", "8"] {
        let out = latdyn(&[
            "statics",
            "tests/models/shallow_arch.toml",
            "--set",
            &format!("P={p}"),
        ]);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        eprintln!("{err}");
        assert!(err.contains("limit point at load factor"), "{err}");
        assert!(!err.contains("stuck"), "{err}");
        // the arch's limit is the structure's: no element is blamed
        assert!(!err.contains("may be the element's"), "{err}");
        let lam: f64 = err
            .split("load factor ")
            .nth(1)
            .and_then(|t| t.split_whitespace().next())
            .and_then(|t| t.parse().ok())
            .expect("load factor in the message");
        reached.push(lam * p.parse::<f64>().unwrap());
    }
    assert!(
        (reached[0] - reached[1]).abs() < 1e-3 * reached[0],
        "limit load {reached:?}"
    );
    assert!(reached[0] > 0.5 && reached[0] < 2.0, "{reached:?}");
}

/// A tolerance far below round-off (1e-30) stops: accepted at the round-off of the
/// coordinates (corrections below 64 u of the model size), with the same answer as the
/// default tolerance to 1e-9 of the tip displacement. It used to run without end.
#[test]
fn unreachable_tolerance_statics_stops_at_the_roundoff_floor() {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/bend45.toml"),
    )
    .unwrap()
    .replace("load_steps = 20", "load_steps = 20\ntol = 1e-30");
    let m = latdyn::model::compile_str(&text, "bend45_tol.toml", &[]).unwrap();
    let t0 = std::time::Instant::now();
    let sol = solve_statics(&m).expect("converges at the round-off floor");
    assert!(t0.elapsed().as_secs() < 60);
    let base = solve_statics(&shipped("bend45.toml", &[])).unwrap();
    let (a, b) = (
        sensor(&m, &sol.sensors, "tip"),
        sensor(&m, &base.sensors, "tip"),
    );
    for k in 0..3 {
        assert!((a[k] - b[k]).abs() < 1e-9 * 100.0, "{a:?} vs {b:?}");
    }
}

/// A hinge or body axis with huge components ([1e308, 1e308, 0]) used to overflow its
/// norm and become the zero vector (the hinge then acted as a clamp); it must give the
/// same axis as [1, 1, 0]. The pendulum's rotation axis is turned into the x-y diagonal;
/// its frequency (gravity along z) must be the same to round-off either way, and so
/// must it with tiny and subnormal components.
#[test]
fn huge_tiny_and_subnormal_axis_components_normalise_without_overflow() {
    let base = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/pendulum.toml"),
    )
    .unwrap();
    assert!(base.contains("axis = [0, 1, 0]"));
    let freq = |axis: &str| {
        let text = base.replace("axis = [0, 1, 0]", &format!("axis = {axis}"));
        let m = latdyn::model::compile_str(&text, "pendulum_axis.toml", &[]).unwrap();
        let st = solve_statics(&m).unwrap().state;
        latdyn::solver::modes::modes(&m, &st)
            .unwrap()
            .frequencies_hz[0]
    };
    let b = freq("[1, 1, 0]");
    assert!(b > 0.1, "{b}");
    // huge, tiny and subnormal components: 1/5e-324 overflows, so a normalisation that
    // multiplies by the reciprocal of the largest component turned these into NaN
    for axis in [
        "[1e308, 1e308, 0]",
        "[1e-320, 1e-320, 0]",
        "[5e-324, 5e-324, 0]",
    ] {
        let a = freq(axis);
        assert!((a - b).abs() <= 1e-12 * b, "{axis}: {a} vs {b}");
    }
    // zero and non-finite axes are located errors
    for bad in ["[0, 0, 0]", "[0, inf, 0]", "[1e-320, 0, 0]"] {
        let text = base.replace("axis = [0, 1, 0]", &format!("axis = {bad}"));
        let r = latdyn::model::compile_str(&text, "pendulum_axis.toml", &[]);
        if bad == "[1e-320, 0, 0]" {
            // tiny but nonzero: a valid direction (+x), scaled before normalising
            assert!(r.is_ok(), "{bad}: {:?}", r.err().map(|e| e.to_string()));
        } else {
            let e = r
                .err()
                .unwrap_or_else(|| panic!("{bad} accepted"))
                .to_string();
            assert!(
                e.contains("axis") && e.contains("pendulum_axis.toml:32:"),
                "{bad}: {e}"
            );
        }
    }
}

/// `[solver] tol` is a relative residual: tol >= 1 (or 1e300) accepted the undeformed
/// state as converged under any load, and anything above 1e-2 accepts states out of
/// equilibrium by more than 1 % of the largest force; these and tol <= 0 are located
/// errors (exit 2). 1e-2 itself and tight values are accepted.
#[test]
fn solver_tolerance_outside_its_range_is_a_located_error() {
    let base = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/cantilever.toml"),
    )
    .unwrap();
    let with = |tol: &str| {
        base.replace(
            "output_dt = 0.01",
            &format!("output_dt = 0.01\ntol = {tol}"),
        )
    };
    for bad in ["2", "1e300", "0.05", "0", "-1e-8"] {
        let r = latdyn::model::compile_str(&with(bad), "cantilever_tol.toml", &[]);
        let e = r
            .err()
            .unwrap_or_else(|| panic!("tol = {bad} accepted"))
            .to_string();
        assert!(
            e.contains("solver.tol") && e.contains("cantilever_tol.toml:66:"),
            "tol = {bad}: {e}"
        );
    }
    for good in ["1e-2", "1e-8", "1e-14"] {
        assert!(latdyn::model::compile_str(&with(good), "cantilever_tol.toml", &[]).is_ok());
    }
    // through the CLI: exit 2 before any solve
    let dir = std::env::temp_dir().join(format!("latdyn_tol_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("cantilever_tol.toml");
    std::fs::write(&path, with("2")).unwrap();
    let out = latdyn(&["statics", path.to_str().unwrap(), "--set", "P=1"]);
    assert_eq!(out.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A drive that turns NaN mid-run (`0*sqrt(1 - t)` added to the hub drive: the same
/// motion until t = 1, where its rate is 0·∞ = NaN, and NaN after) is named with its coordinate, text and the time, not blamed on Newton.
#[test]
fn nan_drive_mid_run_names_the_expression_and_time() {
    let base = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/rotating_cantilever.toml"),
    )
    .unwrap();
    assert!(base.contains("drive = \"omega*t\""));
    let text = base.replace("drive = \"omega*t\"", "drive = \"omega*t + 0*sqrt(1 - t)\"");
    let sets = [("t_end".into(), 1.5), ("dt".into(), 0.01)];
    let m = latdyn::model::compile_str(&text, "nan_drive.toml", &sets)
        .unwrap_or_else(|e| panic!("{e}"));
    let (_, _, err) = latdyn::solver::dynamics::run(&m, |_, _| {});
    let e = err.expect("the run must fail").to_string();
    eprintln!("{e}");
    assert!(e.contains("sqrt(1 - t)") && e.contains("drive of"), "{e}");
    assert!(!e.contains("Newton"), "{e}");
    let t: f64 = e
        .split("t = ")
        .nth(1)
        .and_then(|x| x.split_whitespace().next())
        .and_then(|x| x.parse().ok())
        .expect("time in the message");
    // the first step end at or past t = 1 (dt = 0.01 in this model)
    assert!((1.0..1.0101).contains(&t), "{e}");
}

/// The same for a load's time factor (`log(0.5 - t)`, NaN past t = 0.5), through the CLI.
#[test]
fn nan_load_factor_mid_run_names_the_load_and_time() {
    let base = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/cantilever.toml"),
    )
    .unwrap();
    let text = base.replace(
        "moment = [0, \"M\", 0]",
        "moment = [0, \"M\", 0]\nscale = \"log(0.5 - t)\"",
    );
    let dir = std::env::temp_dir().join(format!("latdyn_nan_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("nan_load.toml");
    std::fs::write(&path, text).unwrap();
    let out = latdyn(&["run", path.to_str().unwrap(), "--set", "P=1", "--json"]);
    let err =
        String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    eprintln!("{err}");
    assert_ne!(out.status.code(), Some(0), "{err}");
    assert!(
        err.contains("log(0.5 - t)") && err.contains("load 1"),
        "{err}"
    );
    assert!(err.contains("t = 0.50"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Found by the fuzzer: with EA = 1e20 the nominal step of 1 s never converges, and the
/// controller alternated between halving and regrowing for minutes (169 000 rejected of
/// 338 000 attempts over 3 s). The run now stops as stalled, says why, and exits 3.
#[test]
fn a_step_that_keeps_collapsing_stops_as_stalled_with_exit_3() {
    let started = std::time::Instant::now();
    let out = latdyn(&[
        "run",
        "models/spinup_beam.toml",
        "--set",
        "EA=1e20",
        "--set",
        "dt=1",
        "--set",
        "t_end=3",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("{err}");
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains("stalled") && err.contains("rejected"), "{err}");
    // a stall is found within a few thousand attempts, not after minutes
    assert!(started.elapsed().as_secs() < 60);
}

#[test]
fn a_load_no_step_can_carry_is_named_not_blamed_on_round_off() {
    // 1e30 N at the cantilever's tip: no load step down to 1e-7 of it converges. The
    // message said "worst residual 2.2e-279 ... a tolerance below the model's round-off
    // cannot be reached" (the residual at λ = 0, which is no load at all).
    let out = latdyn(&["statics", "models/cantilever.toml", "--set", "P=1e30"]);
    let err = String::from_utf8_lossy(&out.stderr);
    // as the other statics diagnoses (a model that cannot carry its loads)
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("Newton diverged from the start")
            && err.contains("far beyond what it carries")
            && !err.contains("round-off")
            && err.contains("worst residual 1.192e23"),
        "{err}"
    );
}

#[test]
fn a_tangent_too_ill_conditioned_to_factor_is_named_not_reported_as_a_stall_at_zero() {
    // EA = 1e30 on the shipped cantilever (EA h²/EI = 1.6e26): the LU's condition
    // estimate in consistent units passes its limit, Newton cannot start, and the
    // message only said "stalled at load factor 0 after 0 Newton iterations (worst
    // residual 2.2e-308)"
    let out = latdyn(&[
        "statics",
        "models/cantilever.toml",
        "--set",
        "EA=1e30",
        "--set",
        "P=1",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("the tangent stiffness could not be factored")
            && err.contains("48 coordinates")
            && err.contains("EA far above EI/L²"),
        "{err}"
    );
}

#[test]
fn a_step_matrix_too_ill_conditioned_to_factor_is_named_not_reported_as_a_zero_residual() {
    // the same mesh under `run`: every step size fails at its factorization, before a
    // Newton iteration, and the message only said "did not converge with the step cut to
    // 9.5e-10 s (worst residual 0)"
    let out = latdyn(&[
        "run",
        "models/cantilever.toml",
        "--set",
        "EA=1e30",
        "--set",
        "P=1",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(
        err.contains("the step's matrix")
            && err.contains("could not be factored at any step size")
            && err.contains("48 coordinates")
            && err.contains("EA far above EI/L²"),
        "{err}"
    );
    // a model that factors but does not converge keeps the plain message
    let ok = latdyn(&["run", "models/cantilever.toml", "--set", "P=1"]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
}

#[test]
fn a_body_coordinate_that_starts_away_from_zero_is_warned_as_a_strained_start() {
    // The spin-up beam with its hub held at 0.01 rad from t = 0: only the root node turns
    // with the hub, the beam's other nodes stay where the reference put them, and the run
    // started with 2.8 J of strain, ringing, with no word of why (only "step too large"
    // and energy warnings). The shipped drive, 0 at t = 0, starts unstrained.
    let src = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/models/spinup_beam.toml"
    ))
    .unwrap();
    let drive = src
        .lines()
        .find(|l| l.trim_start().starts_with("drive = "))
        .unwrap();
    let held = src.replace(drive, "  drive = \"0.01\"");
    let path = std::env::temp_dir().join(format!("latdyn_held_hub_{}.toml", std::process::id()));
    std::fs::write(&path, held).unwrap();
    let p = path.to_str().unwrap();
    let json = latdyn_json;
    let warned = |v: &serde_json::Value| {
        v["warnings"].as_array().unwrap().iter().any(|w| {
            w.as_str()
                .unwrap()
                .contains("the start strains the structure")
        })
    };
    let v = json(&[
        "run",
        p,
        "--set",
        "t_end=0.5",
        "--set",
        "dt=0.005",
        "--json",
    ]);
    assert!(warned(&v), "{v}");
    let shipped = json(&[
        "run",
        "models/spinup_beam.toml",
        "--set",
        "t_end=0.5",
        "--set",
        "dt=0.005",
        "--json",
    ]);
    assert!(!warned(&shipped), "{shipped}");
    let _ = std::fs::remove_file(&path);
}

#[test]
fn a_limit_point_where_an_element_is_beyond_its_range_says_it_may_be_the_elements() {
    // A cantilever bent by a tip moment of 500 N·m (5 rad) on 4 elements stops at a
    // "limit point" at λ = 0.8 (4 rad): each element then turns 0.785 rad from its
    // chord, where its sine measure softens its end moments by 41 %. The structure has
    // no such limit (32 elements carry the full moment), so the message must say the
    // limit may be the element's and how to tell.
    let statics = |elements: &str| {
        latdyn(&[
            "statics",
            "models/cantilever.toml",
            "--set",
            "M=500",
            "--set",
            &format!("elements={elements}"),
        ])
    };
    let out = statics("4");
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("limit point at load factor")
            && err.contains("element 3 of beam `beam` (4 elements)")
            && err.contains("the limit may be the element's, not the structure's"),
        "{err}"
    );
    let out = statics("32");
    assert!(out.status.success(), "{out:?}");
}

/// A stall after a converged load step is not blamed on the tolerance when the residual
/// there passed it: a cantilever twisted 2.5 rad by a tip torque on 4 elements stops at
/// 0.8 of the load, where an element is turned π/4 from its chord (its sine-law torque
/// peaks there). Until session 47 it read "a tolerance below the model's round-off
/// cannot be reached" beside a residual of 8.5e-14 (a probe).
#[test]
fn a_stall_beyond_a_converged_load_step_names_the_element_not_the_tolerance() {
    let m = straight_beam("clamped", 4, PROPS, [0.0; 3], [200.0, 0.0, 0.0], "");
    let Err(e) = solve_statics(&m) else {
        panic!("4 elements cannot twist 2.5 rad")
    };
    let text = e.to_string();
    assert!(
        matches!(e, StaticsError::NoConvergence { .. })
            && text.contains("beyond its small-deformation range")
            && !text.contains("tolerance below"),
        "{text}"
    );
}

/// The consistent start of a fine mesh whose stiffness alone is past the LU's condition
/// limit names that cause, as statics does (the four-bar on 1 500 elements; until session
/// 48 it asked "a coordinate with neither stiffness nor mass?", a probe).
#[test]
fn a_consistent_start_past_the_condition_limit_names_the_mesh_not_a_massless_coordinate() {
    let out = latdyn(&[
        "run",
        "models/fourbar.toml",
        "--set",
        "elements=1500",
        "--set",
        "t_end=0.004",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(
        err.contains("consistent_velocity")
            && err.contains("condition estimate above")
            && err.contains("fewer elements may solve it"),
        "{err}"
    );
}

/// A hinge given a rate with the members beyond it at rest: the velocity given has almost
/// no kinetic energy (the end node's rotary inertia), so the strain-free start it implies
/// carries far more; the warning says so as a ratio, not as a share of 1.8 million per
/// cent (until session 48, a probe).
#[test]
fn a_hinge_rate_given_alone_is_warned_with_a_ratio_not_a_share_above_one() {
    let out = latdyn(&["run", "tests/models/hinge_rate_members_at_rest.toml"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let line = err
        .lines()
        .find(|l| l.contains("the initial velocity strains the structure"))
        .unwrap_or_else(|| panic!("not warned: {err}"));
    assert!(
        line.contains("times the kinetic energy given") && !line.contains('%'),
        "{line}"
    );
}

/// A reference tangent past the LU's condition limit (the cantilever on 6 000 elements)
/// fails alike at any load, so the solve diagnoses it after three first steps (full,
/// half, quarter load) instead of halving 24 times at 25 shifted iterations each (75 s
/// until session 48) and says why.
#[test]
fn an_ill_conditioned_reference_is_diagnosed_after_three_first_steps_not_twenty_four() {
    let out = latdyn(&[
        "statics",
        "models/cantilever.toml",
        "--set",
        "elements=6000",
        "--set",
        "P=1",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("in 3 load steps") && err.contains("condition estimate above"),
        "{err}"
    );
}
