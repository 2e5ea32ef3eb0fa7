//! `sweep --frequency`: the line of the first elastic mode, checked against the
//! rotating-frame eigenvalue, with a warning beside every value that may be wrong.

mod common;
use common::*;
use latdyn::frequency::campbell_crossings;
use latdyn::solver::rotating::{find_spin, rotating_modes_with_shapes, RIGID_DEFORMATION};
use std::f64::consts::PI;

/// One variant: Ω, first_bending [rad/s], eigenvalue [rad/s], warnings.
type Row = (f64, f64, f64, Vec<String>);

/// `latdyn sweep ... --frequency mid_moment --json` → per variant a [`Row`], plus stderr.
fn sweep(args: &[&str]) -> (Vec<Row>, String) {
    let mut a = vec!["sweep", "models/flapping_blade.toml"];
    a.extend_from_slice(args);
    a.extend_from_slice(&["--frequency", "mid_moment", "--json"]);
    let out = latdyn(&a);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(0), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let rows = v["variants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| {
            let d = &x["derived"];
            let hz = |k: &str| 2.0 * PI * d[k].as_f64().unwrap_or(f64::NAN);
            // the frequency warnings only: the blade's mid-span moment also carries a
            // time-error warning at dt = 0.005 (README "Accuracy")
            let w = x["warnings"]
                .as_array()
                .unwrap()
                .iter()
                .map(|s| s.as_str().unwrap().to_string())
                .filter(|s| s.starts_with("first_bending_hz"))
                .collect();
            (
                x["parameters"]["omega"].as_f64().unwrap(),
                hz("first_bending_hz"),
                hz("first_bending_eig_hz"),
                w,
            )
        })
        .collect();
    (rows, err)
}

const ISSUE: [&str; 10] = [
    "--set", "L=1", "--set", "EI=1", "--set", "rhoA=1", "--set", "GJ=1", "--set", "EA=1e6",
];

#[test]
fn issue_blade_at_twelve_reports_the_elastic_flap_line_not_the_three_omega_line() {
    // Issue 14: at Ω̄ = 12 the largest line of the mid-span moment is at 35.60 rad/s (near
    // 3Ω = 36); the first elastic flap mode is at 33.76 rad/s (`latdyn modes`). The line
    // nearest the eigenvalue is now reported: 33.39 rad/s at dt = 0.005, the step the
    // issue ran (33.46 at dt = 0.001, the step shipped since session 23; 33.39 over 40 s:
    // converged in dt and record length), 1.1 % below the eigenvalue because the tilted
    // release is a large motion (tilt 0.157: at tilt 0.02 the two agree to 0.27 %, the
    // integrator's period error at ω·dt = 0.17). So: not the 3Ω line (> 4 % from 35.60),
    // within 2 % of the eigenvalue, and, being more than 1 % off, warned with the cause
    // named (the amplitude). At the shipped step (0.88 % off) the same line, no warning.
    let shipped = {
        let mut args = vec!["--vary", "omega=12:12:1"];
        args.extend_from_slice(&ISSUE);
        sweep(&args).0.remove(0)
    };
    eprintln!("Ω̄ = 12, shipped step: {shipped:?}");
    assert!(rel(shipped.1, 35.60) > 0.04, "{shipped:?}");
    assert!(
        rel(shipped.1, shipped.2) < 0.01 && shipped.3.is_empty(),
        "{shipped:?}"
    );
    let mut args = vec!["--vary", "omega=10:12:2", "--set", "dt=0.005"];
    args.extend_from_slice(&ISSUE);
    let (rows, err) = sweep(&args);
    let (om, f, eig, w) = &rows[1];
    assert_eq!(*om, 12.0);
    eprintln!("Ω̄ = 12: FFT {f:.4} rad/s, eigenvalue {eig:.4}, warnings {w:?}");
    // eigenvalue: `latdyn modes` gives 33.758 rad/s; 1e-4 covers printing
    assert!(rel(*eig, 33.758) < 1e-4, "{eig}");
    assert!(rel(*f, 35.60) > 0.04, "picked the 3Ω line: {f}");
    assert!(rel(*f, *eig) < 0.02, "{f} vs {eig}");
    assert!(
        rel(*f, *eig) < 0.01 || !w.is_empty(),
        "off by > 1 % without warning"
    );
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with("first_bending_hz: disagrees with the eigenvalue")
            && w[0].contains("amplitude"),
        "{}",
        w[0]
    );
    assert!(
        err.contains("1 variant(s): first_bending_hz: disagrees"),
        "{err}"
    );
    // Ω̄ = 10: the mode's line is the right one to 0.2 %, no warning
    let (_, f, eig, w) = &rows[0];
    assert!(rel(*f, *eig) < 0.005 && w.is_empty(), "{f} vs {eig}: {w:?}");
    // a small release: the same line within 0.5 % of the eigenvalue (measured 0.27 %:
    // the integrator's period error), warning-free
    let mut args = vec![
        "--vary",
        "omega=12:12:1",
        "--set",
        "tilt=0.02",
        "--set",
        "dt=0.005",
    ];
    args.extend_from_slice(&ISSUE);
    let (rows, _) = sweep(&args);
    let (_, f, eig, w) = &rows[0];
    eprintln!("Ω̄ = 12, tilt 0.02: FFT {f:.4} rad/s, eigenvalue {eig:.4}");
    assert!(rel(*f, *eig) < 0.005 && w.is_empty(), "{f} vs {eig}: {w:?}");
}

#[test]
fn shipped_blade_campaign_speeds_away_from_crossings_are_unchanged_and_warning_free() {
    // docs/studies/blade_speed_campaign.md (shipped model and settings, 10 s record, made
    // at dt = 0.005, the blade's step until session 23): the FFT column there is the old
    // "largest line" value. Away from the harmonic crossings the largest line is the
    // mode's, so the value must be the same (the table prints 4 decimals in rad/s: 1e-4)
    // and carry no frequency warning.
    // Session 47 moved three values: the element now applies the blade's unequal flap
    // and lag stiffnesses in its twisted sections' axes (`SectionTurn`): 17.9941 →
    // 17.9935, 19.8097 → 19.8085, 25.9369 → 25.8963 at Ω = 5, 6, 9. The line at Ω = 9
    // converged in dt (5e-4 s) went from 26.135 to 26.076 rad/s, against the eigenvalue
    // 25.983 (the release's amplitude shifts the line).
    let table = [
        (1.0, 13.1378),
        (2.0, 13.8434),
        (5.0, 17.9935),
        (6.0, 19.8085),
        (9.0, 25.8963),
    ];
    let csv = std::env::temp_dir().join(format!("latdyn_freq_{}.csv", std::process::id()));
    let body: String = table.iter().map(|(o, _)| format!("{o}\n")).collect();
    std::fs::write(&csv, format!("omega\n{body}")).unwrap();
    // the study's mesh: the blade's 10 elements until session 49
    let (rows, err) = sweep(&[
        "--variants",
        csv.to_str().unwrap(),
        "--set",
        "dt=0.005",
        "--set",
        "elements=10",
    ]);
    let _ = std::fs::remove_file(&csv);
    for ((om, f, eig, w), (om_t, f_t)) in rows.iter().zip(table) {
        assert_eq!(*om, om_t);
        eprintln!("Ω = {om}: FFT {f:.4} rad/s (table {f_t}), eigenvalue {eig:.4}");
        assert!((f - f_t).abs() < 1e-4, "Ω = {om}: {f} vs {f_t}");
        assert!(w.is_empty(), "Ω = {om}: {w:?}");
    }
    // (the mid-span moment's time-error warning at dt = 0.005 is not this test's)
    assert!(!err.contains("first_bending_hz"), "{err}");
}

#[test]
fn third_harmonic_within_the_resolution_of_the_mode_is_warned_as_ambiguous() {
    // Shipped blade at Ω = 7.5: 3Ω = 22.5 rad/s, the first elastic flap eigenvalue 22.83
    // (docs/studies/blade_speed_campaign.md): 0.33 rad/s apart, less than the resolution
    // 2π/10 s = 0.63 rad/s, so the 10 s record cannot separate the forced response from
    // the mode; the FFT gives 22.44 (−1.7 %), which must carry the warning naming 3Ω.
    let (rows, err) = sweep(&["--vary", "omega=7.5:7.5:1"]);
    let (_, f, eig, w) = &rows[0];
    eprintln!("Ω = 7.5: FFT {f:.4} rad/s, eigenvalue {eig:.4}, warnings {w:?}");
    assert!(rel(*eig, 22.8281) < 1e-4, "{eig}");
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with("first_bending_hz: ambiguous spectrum") && w[0].contains("3Ω"),
        "{}",
        w[0]
    );
    assert!(
        err.contains("first_bending_hz: ambiguous spectrum"),
        "{err}"
    );
}

#[test]
fn rigid_flap_is_skipped_and_the_lag_mode_a_flap_moment_does_not_see_too() {
    // The rule that picks the wanted mode, part 1: deformation share (beam motion that is
    // not a rigid motion of the beam). Rigid flap: measured 4e-5 (Ω = 6) to 1.5e-4
    // (Ω = 12), the linearisation's round-off about the stretched steady state; elastic
    // modes 0.3 to 0.96. Bounds: 1e-2 and 4× RIGID_DEFORMATION = 0.05.
    for omega in [1.0, 6.0, 12.0] {
        let m = shipped("flapping_blade.toml", &[("omega", omega)]);
        let rm = rotating_modes_with_shapes(&m, find_spin(&m).unwrap(), 4).unwrap();
        eprintln!("Ω = {omega}: deformation shares {:?}", rm.deformation);
        assert!(
            rm.deformation[0] < 1e-2 * RIGID_DEFORMATION,
            "{:?}",
            rm.deformation
        );
        assert!(
            rm.deformation[1] > 4.0 * RIGID_DEFORMATION,
            "{:?}",
            rm.deformation
        );
        assert_eq!(rm.first_elastic(), Some(1));
    }
    // Part 2: the sensor must see the mode. The shipped blade at Ω = 12 has its first
    // lead-lag mode (4.754 Hz, `latdyn modes`) below the first elastic flap mode (5.191
    // Hz); the flapwise mid-span moment does not see the lag mode about the unconed steady
    // state, so the eigenvalue beside first_bending_hz must be the flap mode's (1e-4:
    // printing of `latdyn modes`) and the line found the flap line, not the lag line
    // (29.87 rad/s, 8.4 % below): measured 31.75 rad/s, −2.7 % from the eigenvalue (the
    // large release at this speed, as in the issue's case), so warned with that cause.
    let (rows, _) = sweep(&["--vary", "omega=12:12:1"]);
    let (_, f, eig, w) = &rows[0];
    eprintln!("shipped blade, Ω = 12: FFT {f:.4} rad/s, eigenvalue {eig:.4}, warnings {w:?}");
    assert!(rel(*eig, 2.0 * PI * 5.191393) < 1e-4, "{eig}");
    assert!(rel(*f, 2.0 * PI * 4.753767) > 0.05, "the lag line: {f}");
    assert!(rel(*f, *eig) < 0.04, "{f} vs {eig}");
    assert!(
        rel(*f, *eig) < 0.01 || !w.is_empty(),
        "off by > 1 % without warning"
    );
    assert!(w.iter().all(|x| x.contains("amplitude")), "{w:?}");
}

#[test]
fn without_a_spinning_hub_the_strongest_line_is_kept_and_a_short_record_is_warned() {
    // pendulum (no hub): the strongest line as before. 0.2 s holds a fraction of one
    // swing: the value is kept (a number) but warned; over 20 s no warning.
    let run = |t_end: &str| {
        let out = latdyn(&[
            "sweep",
            "models/pendulum.toml",
            "--vary",
            "theta0=0.5:0.5:1",
            "--set",
            t_end,
            "--frequency",
            "angle.ry",
            "--json",
        ]);
        assert_eq!(out.status.code(), Some(0));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["variants"][0].clone()
    };
    let short = run("t_end=0.2");
    assert!(short["derived"]["first_bending_hz"].is_number());
    assert!(short["derived"]["first_bending_eig_hz"].is_null());
    let w = short["warnings"][0].as_str().unwrap();
    assert!(w.starts_with("first_bending_hz: short record"), "{w}");
    let long = run("t_end=20");
    assert_eq!(long["warnings"].as_array().unwrap().len(), 0, "{long}");
}

#[test]
fn a_mode_the_release_does_not_excite_gives_nan_and_a_not_excited_warning() {
    // Shipped blade released in the plane of rotation (tilt 0): nothing drives it out of
    // the plane, the flapwise moment stays 0 and there is no line at the first elastic
    // flap mode. No number may be reported: NaN (JSON null) with the cause named; the
    // eigenvalue is still given.
    let (rows, err) = sweep(&[
        "--vary",
        "omega=6:6:1",
        "--set",
        "tilt=0",
        "--set",
        "t_end=3",
    ]);
    let (_, f, eig, w) = &rows[0];
    assert!(f.is_nan(), "{f}");
    assert!(rel(*eig, 19.8585) < 1e-4, "{eig}");
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with("first_bending_hz: not excited"),
        "{}",
        w[0]
    );
    assert!(
        err.contains("1 variant(s): first_bending_hz: not excited"),
        "{err}"
    );
}

// ---------------------------------------------------------------------------------------
// campbell_crossings: where the rotor harmonics n·Ω cross a Campbell curve

#[test]
fn crossings_of_a_southwell_curve() {
    // y = sqrt(4 + 6.4 x²) crosses n·x where n² x² = 4 + 6.4 x², i.e. for n² > 6.4:
    // x = sqrt(4 / (n² - 6.4)); 1x and 2x never.
    let x: Vec<f64> = (0..=300).map(|i| 0.01 * i as f64).collect();
    let y: Vec<f64> = x.iter().map(|&x| (4.0 + 6.4 * x * x).sqrt()).collect();
    let c = campbell_crossings(&x, &y, 6);
    let ns: Vec<usize> = c.iter().map(|c| c.0).collect();
    assert_eq!(ns, [3, 4, 5, 6]);
    for &(n, om) in &c {
        let exact = (4.0 / ((n * n) as f64 - 6.4)).sqrt();
        assert!((om - exact).abs() < 1e-4, "{n}: {om} vs {exact}");
    }
    assert!((c[0].1 - (4.0f64 / 2.6).sqrt()).abs() < 1e-4);
    assert!((c[1].1 - (4.0f64 / 9.6).sqrt()).abs() < 1e-4);

    // Coarse grid: exact for the piecewise-linear curve through the points.
    let x = [0.0, 1.0, 2.0];
    let y = [2.0, 2.5, 3.0];
    // 1x: g = 2, 1.5, 1, never; 2x: g = 2, 0.5, -1, between 1 and 2 at 1 + 0.5/1.5.
    let c = campbell_crossings(&x, &y, 2);
    assert_eq!(c.len(), 1, "{c:?}");
    assert_eq!(c[0].0, 2);
    assert!((c[0].1 - (1.0 + 0.5 / 1.5)).abs() < 1e-12, "{c:?}");
}

#[test]
fn crossings_edge_cases() {
    // Unsorted input with NaN points is sorted and filtered.
    let x = [2.0, f64::NAN, 0.0, 1.0, 3.0];
    let y = [3.0, 1.0, 2.0, 2.5, f64::NAN];
    let c = campbell_crossings(&x, &y, 2);
    assert_eq!(c.iter().map(|c| c.0).collect::<Vec<_>>(), [2]);
    assert!((c[0].1 - 4.0 / 3.0).abs() < 1e-12);

    // A data point exactly on a harmonic counts once (here also the last point).
    let c = campbell_crossings(&[1.0, 2.0, 3.0], &[3.0, 4.0, 5.0], 2);
    assert_eq!(c, [(2, 2.0)]);
    let c = campbell_crossings(&[1.0, 2.0], &[3.0, 4.0], 2);
    assert_eq!(c, [(2, 2.0)]);

    // Ω = 0 with zero frequency is no crossing; empty and single-point inputs give none.
    assert!(campbell_crossings(&[0.0, 1.0], &[0.0, 0.5], 3).is_empty());
    assert!(campbell_crossings(&[], &[], 6).is_empty());
    assert!(campbell_crossings(&[1.0], &[1.0], 0).is_empty());
    assert_eq!(campbell_crossings(&[1.0], &[1.0], 1), [(1, 1.0)]);
}

/// `--frequency angle` on the pendulum takes the sensor's first component, `x`, which
/// is always 0: `first_bending_hz` was NaN with no warning. Now the variant warns `not
/// excited`, stderr notes which component was taken, and `angle.` (no component) is
/// refused.
#[test]
fn a_frequency_of_a_constant_component_is_warned_and_the_component_taken_is_noted() {
    let out = latdyn(&[
        "sweep",
        "models/pendulum.toml",
        "--vary",
        "theta0=0.1:0.2:2",
        "--set",
        "t_end=6",
        "--frequency",
        "angle",
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.contains("note: --frequency angle: the spectrum of its first component"),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for x in v["variants"].as_array().unwrap() {
        assert!(x["derived"]["first_bending_hz"].is_null(), "{x}");
        let w = x["warnings"].to_string();
        assert!(w.contains("first_bending_hz: not excited"), "{w}");
    }
    let out = latdyn(&[
        "sweep",
        "models/pendulum.toml",
        "--vary",
        "theta0=0.1:0.2:2",
        "--frequency",
        "angle.",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("names no component"));
}

/// Without a spinning hub the strongest line has no modal prior, but a record sampled
/// below twice the lowest mode's frequency is recognised: the pendulum (0.698 Hz about
/// its start) sampled every 1 s read 0.302 Hz, its alias, with no warning (session 44's
/// probe). It is warned now, naming the mode and the Nyquist frequency; sampled every
/// 0.25 s the line is the pendulum's own (within 1 % of 1/T by the elliptic integral) and
/// nothing is said.
#[test]
fn a_line_sampled_below_twice_the_lowest_modes_frequency_is_warned_as_aliased() {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/pendulum.toml"),
    )
    .unwrap()
    .replacen("[solver]\n", "[solver]\noutput_dt = \"odt\"\n", 1)
    .replacen("[parameters]\n", "[parameters]\nodt = 0.01\n", 1);
    assert!(text.contains("output_dt = \"odt\"") && text.contains("odt = 0.01"));
    let path = std::env::temp_dir().join(format!("latdyn_alias_{}.toml", std::process::id()));
    std::fs::write(&path, text).unwrap();
    let run = |odt: &str| {
        let v = latdyn_json(&[
            "sweep",
            path.to_str().unwrap(),
            "--vary",
            "theta0=0.1:0.1:1",
            "--set",
            "t_end=60",
            "--set",
            odt,
            "--frequency",
            "angle.ry",
            "--json",
        ]);
        v["variants"][0].clone()
    };
    let coarse = run("odt=1");
    let w: Vec<&str> = coarse["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|w| w.as_str())
        .collect();
    assert!(
        w.iter().any(|w| w.starts_with("first_bending_hz: aliased")
            && w.contains("Nyquist frequency of the output interval (0.50000 Hz)")),
        "{coarse}"
    );
    let fine = run("odt=0.25");
    assert_eq!(fine["warnings"].as_array().unwrap().len(), 0, "{fine}");
    // 1/T for θ0 = 0.1 by the AGM: T = 2π/(ω0 · AGM(1, cos(θ0/2)))
    let (g, m, d, ic) = (9.81f64, 2.0f64, 0.5f64, 0.01f64);
    let w0 = (m * g * d / (ic + m * d * d)).sqrt();
    let (mut a, mut b) = (1.0f64, (0.05f64).cos());
    for _ in 0..20 {
        (a, b) = (0.5 * (a + b), (a * b).sqrt());
    }
    let f = w0 * a / (2.0 * PI);
    let hz = fine["derived"]["first_bending_hz"].as_f64().unwrap();
    assert!((hz - f).abs() < 0.01 * f, "{hz} Hz against {f} Hz");
    let _ = std::fs::remove_file(&path);
}

/// A sensor component in the fixed frame across the spin axis sees a rotating-frame mode
/// at f as lines at f ± Ω/2π: the blade's `tip.x` at Ω = 10 rad/s read 4.7399 Hz for
/// the 4.7321 Hz lag mode, another line, within 1 % by chance and unwarned (a probe,
/// session 46). It is warned whatever the value; the component along the axis (`tip.z`)
/// and the convected section moment are not.
#[test]
fn a_fixed_frame_sensor_across_the_spin_axis_is_warned_as_such() {
    let warned = |sensor: &str| {
        let v = latdyn_json(&[
            "sweep",
            "models/flapping_blade.toml",
            "--vary",
            "omega=10:10:1",
            "--set",
            "t_end=2",
            "--set",
            "dt=0.005",
            "--frequency",
            sensor,
            "--json",
        ]);
        v["variants"][0]["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| {
                w.as_str()
                    .unwrap()
                    .starts_with("first_bending_hz: fixed-frame sensor")
            })
    };
    assert!(warned("tip.x"));
    assert!(!warned("tip.z"));
    assert!(!warned("mid_moment"));
}

/// The mode the sensor sees is judged per unit modal energy: per unit modal mass a
/// moment's response grows with the mode's curvature, and the rotating cantilever's
/// root moment passed over its first flap mode (2.75 % of the second's at Ω = 1) to
/// report the second, 3.53 Hz for 0.586 Hz, silently (a probe, session 46). Now the
/// first flap mode, against the published ω̄₁ = 3.6816 at Ω̄ = 1 (references.md §2):
/// within 1e-3 (the 10 elements' mesh error is 1e-5; the FFT refinement's a few 1e-5).
#[test]
fn a_root_moment_reports_the_first_flap_mode_not_the_second() {
    let v = latdyn_json(&[
        "sweep",
        "models/rotating_cantilever.toml",
        "--vary",
        "omega=1:1:1",
        "--set",
        "t_end=10",
        "--set",
        "dt=1e-3",
        "--frequency",
        "root_moment",
        "--json",
    ]);
    let d = &v["variants"][0]["derived"];
    let want = 3.6816 / (2.0 * PI);
    for k in ["first_bending_eig_hz", "first_bending_hz"] {
        let f = d[k].as_f64().unwrap();
        assert!(rel(f, want) < 1e-3, "{k}: {f} Hz against {want} Hz");
    }
}
