//! What the element can and cannot represent, and what the user is told: section sensors
//! are evaluated at the requested station (not snapped to an element end or midpoint),
//! and statics warns when an element deforms beyond its small-deformation range.

mod common;
use common::*;
use latdyn::assembly::{deformation_angle_warning, largest_deformation_angle};
use latdyn::solver::solve_statics;

#[test]
fn section_sensor_reads_the_requested_station_not_the_nearest_end_or_midpoint() {
    // Tip force P along +z on a unit cantilever: My(x) = −P (L − x) in the section frame,
    // linear, which the Hermite element represents exactly at every ξ. Until session 28
    // `at = 0.24` on one element reported the root value −P (snapped to ξ = 0). P is small
    // so the geometric nonlinearity (relative (PL²/EI)² · O(1)) stays below 1e-9.
    let p = 1e-3;
    let stations = [0.0, 0.24, 0.5, 0.8, 1.0];
    let mut extra = String::new();
    for (k, at) in stations.iter().enumerate() {
        extra += &format!(
            "\n[[sensors]]\nname = \"s{k}\"\ntype = \"section\"\nbeam = \"beam\"\nat = {at}\n\
             component = \"My\"\n"
        );
    }
    for n in [1, 2, 3] {
        let m = straight_beam("clamped", n, BEAM_PROPS, [0.0, 0.0, p], [0.0; 3], &extra);
        let sol = solve_statics(&m).unwrap();
        assert!(sol.report.warnings.is_empty(), "{:?}", sol.report.warnings);
        for (k, at) in stations.iter().enumerate() {
            let got = sensor(&m, &sol.sensors, &format!("s{k}"))[0];
            let want = -p * (1.0 - at);
            assert!(
                (got - want).abs() <= 1e-9 * p,
                "{n} elements, at = {at}: My = {got}, want {want}"
            );
        }
    }
}

/// Cantilever twisted by a tip torque `mx` with `n` elements.
fn twisted(n: usize, mx: f64) -> latdyn::model::Model {
    straight_beam("clamped", n, BEAM_PROPS, [0.0; 3], [mx, 0.0, 0.0], "")
}

#[test]
fn statics_warns_when_an_element_twists_beyond_its_small_deformation_range() {
    // Mx = 100 on GJ = 80, L = 1: 1.25 rad of twist. With 4 elements each twists by
    // θ ≈ 0.34 rad (the sine law: T = GJ/(2ℓ) sin 2θ), 8 % softer than GJ/ℓ; with 64
    // elements θ ≈ 0.02 rad, 0.03 %.
    let m = twisted(4, 100.0);
    let sol = solve_statics(&m).unwrap();
    let tip = sensor(&m, &sol.sensors, "tip");
    assert!(tip[3] > 1.3, "4 elements over-twist: {}", tip[3]);
    let d = largest_deformation_angle(&m, &sol.state).unwrap();
    // node 1 of each element stays on its convected frame: the angle is the element twist
    assert!(
        (d.angle - tip[3] / 4.0).abs() < 1e-6,
        "{} against {}",
        d.angle,
        tip[3] / 4.0
    );
    assert_eq!((d.beam.as_str(), d.beam_elements), ("beam", 4));
    assert_eq!(sol.report.warnings.len(), 1, "{:?}", sol.report.warnings);
    let w = &sol.report.warnings[0];
    for part in [
        "beam `beam`",
        &format!("element {}", d.index_in_beam),
        &format!("{:.3} rad", d.angle),
        &format!("{:.1} %", 100.0 * 2.0 * d.angle * d.angle / 3.0),
        "more elements",
    ] {
        assert!(w.contains(part), "`{part}` not in: {w}");
    }

    let m = twisted(64, 100.0);
    let sol = solve_statics(&m).unwrap();
    let tip = sensor(&m, &sol.sensors, "tip");
    assert!(rel(tip[3], 1.25) < 1e-3, "64 elements: {}", tip[3]);
    assert!(sol.report.warnings.is_empty(), "{:?}", sol.report.warnings);
    assert!(deformation_angle_warning(&m, &sol.state).is_none());
}

#[test]
fn shipped_scenes_statics_and_their_deformation_angles() {
    // cantilever and Lee's frame at their shipped settings stay below the threshold.
    for name in ["cantilever.toml", "lee_frame.toml"] {
        let m = shipped(name, &[]);
        let sol = solve_statics(&m).unwrap();
        let a = largest_deformation_angle(&m, &sol.state).unwrap().angle;
        eprintln!("{name}: largest deformation angle {a:.4} rad");
        assert!(
            sol.report.warnings.is_empty(),
            "{name}: {:?}",
            sol.report.warnings
        );
    }
    // bend45 at its shipped 8 elements and P = 600 does warn: the root element's node
    // frame turns 0.186 rad from its chord (2θ²/3 = 2.3 % on its forces; the tip is 0.27
    // from the converged z, 0.5 %: the other elements deform less). Measured, not hidden
    // by a larger threshold; 16 elements halve the angle and do not warn.
    let m = shipped("bend45.toml", &[]);
    let sol = solve_statics(&m).unwrap();
    let d = largest_deformation_angle(&m, &sol.state).unwrap();
    eprintln!(
        "bend45.toml: largest deformation angle {:.4} rad at {d:?}",
        d.angle
    );
    assert!((d.angle - 0.186).abs() < 2e-3, "{d:?}");
    assert_eq!((d.beam.as_str(), d.index_in_beam), ("bend", 0));
    assert_eq!(sol.report.warnings.len(), 1);
    let m = shipped("bend45.toml", &[("elements", 16.0)]);
    let sol = solve_statics(&m).unwrap();
    assert!(sol.report.warnings.is_empty(), "{:?}", sol.report.warnings);
}

#[test]
fn statics_cli_prints_the_warning_and_lists_it_in_json() {
    // cantilever.toml bent by a tip moment M = 100 = EI/L (1 rad at the tip) on 2 elements:
    // end angles 0.25 rad, 4 % soft
    let args = [
        "statics",
        "models/cantilever.toml",
        "--set",
        "P=0",
        "--set",
        "M=100",
        "--set",
        "elements=2",
        "--json",
    ];
    let out = latdyn(&args);
    assert!(out.status.success(), "{out:?}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let w = v["warnings"].as_array().expect("warnings array");
    assert_eq!(w.len(), 1, "{v}");
    assert!(w[0]
        .as_str()
        .unwrap()
        .contains("large deformation per element"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("warning: models/cantilever.toml: large deformation"),
        "{err}"
    );

    // 16 elements: no warning, an empty array
    let mut args = args;
    args[7] = "elements=16";
    let out = latdyn(&args);
    assert!(out.status.success(), "{out:?}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["warnings"], serde_json::json!([]), "{v}");
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn run_warns_when_an_element_turns_beyond_its_small_deformation_range() {
    // The cantilever under a suddenly applied tip moment of 40 N·m (static tip rotation
    // 0.4 rad) swings to about twice that: with 2 elements the root element's node frame
    // turns 0.246 rad from its chord (forces 4 % off), with 32 elements 0.03 rad.
    let warns = |elements: &str| -> bool {
        let v = latdyn_json(&[
            "run",
            "models/cantilever.toml",
            "--set",
            &format!("elements={elements}"),
            "--set",
            "M=40",
            "--json",
        ]);
        v["warnings"].as_array().unwrap().iter().any(|w| {
            w.as_str()
                .unwrap()
                .contains("large deformation per element")
        })
    };
    assert!(warns("2"));
    assert!(!warns("32"));
}
