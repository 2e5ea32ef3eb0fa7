//! What the element can and cannot represent, and what the user is told: section sensors
//! are evaluated at the requested station (not snapped to an element end or midpoint),
//! and statics warns when an element deforms beyond its small-deformation range.

mod common;
use common::*;
use latdyn::assembly::{deformation_angle_warning, largest_deformation_angle};
use latdyn::solver::{check_statics_mesh, solve_statics, MESH_ERROR_WARN};

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
    // bend45 at its shipped 8 elements and P = 600 leaves the range: the root element's
    // node frame turns 0.186 rad from its chord (2θ²/3 = 2.3 % on its forces). What that
    // costs the reported numbers is measured (next test): 0.4 % at the tip, 0.56 % on the
    // strain energy, so the bound's warning is replaced by that measurement and dropped.
    let m = shipped("bend45.toml", &[]);
    let mut sol = solve_statics(&m).unwrap();
    let d = largest_deformation_angle(&m, &sol.state).unwrap();
    eprintln!(
        "bend45.toml: largest deformation angle {:.4} rad at {d:?}",
        d.angle
    );
    assert!((d.angle - 0.186).abs() < 2e-3, "{d:?}");
    assert_eq!((d.beam.as_str(), d.index_in_beam), ("bend", 0));
    assert_eq!(sol.report.warnings.len(), 1);
    let check = check_statics_mesh(
        &m,
        &mut sol,
        || Ok(shipped("bend45.toml", &[("elements", 16.0)])),
        None,
    )
    .expect("measured");
    assert!(check.estimate < MESH_ERROR_WARN, "{check:?}");
    assert!(sol.report.warnings.is_empty(), "{:?}", sol.report.warnings);
    let m = shipped("bend45.toml", &[("elements", 16.0)]);
    let sol = solve_statics(&m).unwrap();
    assert!(sol.report.warnings.is_empty(), "{:?}", sol.report.warnings);
}

/// Largest error of bend45 with `n` elements against 256 elements, over the tip's
/// components (relative to the tip's largest displacement component) and the strain
/// energy: (tip, strain energy).
fn bend45_true_error(n: usize, fine: &latdyn::solver::StaticSolution) -> (f64, f64) {
    let sol = solve_statics(&shipped("bend45.toml", &[("elements", n as f64)])).unwrap();
    let m = shipped("bend45.toml", &[]);
    let (tip, tip_ref) = (
        sensor(&m, &sol.sensors, "tip"),
        sensor(&m, &fine.sensors, "tip"),
    );
    let x0 = [
        100.0 * (0.25 * std::f64::consts::PI).sin(),
        100.0 - 100.0 * (0.25 * std::f64::consts::PI).cos(),
        0.0,
    ];
    let change = (0..3)
        .map(|c| (tip_ref[c] - x0[c]).abs())
        .fold(0.0, f64::max);
    let tip_err = (0..3)
        .map(|c| (tip[c] - tip_ref[c]).abs())
        .fold(0.0, f64::max)
        / change;
    (tip_err, rel(sol.strain_energy, fine.strain_energy))
}

#[test]
fn statics_measures_the_mesh_error_of_a_large_deformation_and_warns_only_above_one_percent() {
    // bend45 (Bathe-Bolourchi, P = 600) with 2, 4 and 8 elements leaves the element's
    // small-deformation range at every mesh (root element 0.59, 0.33, 0.19 rad). The mesh
    // check solves again with twice the elements and takes Richardson's second-order
    // estimate; against 256 elements (whose own error is 1/64 of that of 32, below 1e-4
    // here) it must be within 15 % of the true error of the tip and the strain energy:
    // the leading term is second order (the sine measure's 2θ²/3, θ ∝ element length),
    // its next term shows at the coarsest mesh (2 elements: 8.98 % estimated, 9.6 % true).
    // The warning stays exactly where the true error is above 1 %.
    let fine = solve_statics(&shipped("bend45.toml", &[("elements", 256.0)])).unwrap();
    for n in [2usize, 4, 8] {
        let m = shipped("bend45.toml", &[("elements", n as f64)]);
        let mut sol = solve_statics(&m).unwrap();
        assert_eq!(
            sol.report.warnings.len(),
            1,
            "{n}: {:?}",
            sol.report.warnings
        );
        let check = check_statics_mesh(
            &m,
            &mut sol,
            || Ok(shipped("bend45.toml", &[("elements", (2 * n) as f64)])),
            None,
        )
        .expect("measured");
        let (tip, energy) = bend45_true_error(n, &fine);
        let est_tip = check.by_sensor[m.sensor_index("tip").unwrap()];
        eprintln!(
            "{n} elements: tip {est_tip:.3e} (true {tip:.3e}), strain energy {:.3e} (true {energy:.3e})",
            check.strain_energy
        );
        for (what, est, truth) in [
            ("tip", est_tip, tip),
            ("strain energy", check.strain_energy, energy),
        ] {
            assert!(
                (est / truth - 1.0).abs() < 0.15,
                "{n} elements, {what}: estimate {est:.3e}, true {truth:.3e}"
            );
        }
        assert_eq!(check.elements, (n, 2 * n));
        let truth = tip.max(energy);
        assert_eq!(
            sol.report.warnings.len(),
            usize::from(truth > 1e-2),
            "{n}: {:?}",
            sol.report.warnings
        );
        if truth > 1e-2 {
            let w = &sol.report.warnings[0];
            for part in [
                "large deformation per element",
                "measured by solving again with twice the elements",
                &format!("({} in all)", 2 * n),
                &format!("{:.2} %", 100.0 * check.estimate),
            ] {
                assert!(w.contains(part), "`{part}` not in: {w}");
            }
        }
    }
}

#[test]
fn a_mesh_check_that_cannot_run_keeps_the_bound_warning_and_says_why() {
    // The refined model may not compile (a limit on elements) or not solve: the reported
    // numbers are then unmeasured, and the per-element bound must stay.
    let m = twisted(4, 100.0);
    let mut sol = solve_statics(&m).unwrap();
    let bound = sol.report.warnings.clone();
    assert_eq!(bound.len(), 1);
    let check = check_statics_mesh(&m, &mut sol, || Err("limit on elements".into()), None);
    assert!(check.is_none());
    assert_eq!(sol.report.warnings.len(), 1);
    let w = &sol.report.warnings[0];
    assert!(w.starts_with(&bound[0]), "{w}");
    assert!(
        w.contains(
            "not measured: solving again with twice the elements (8 in all) failed: limit on \
             elements"
        ),
        "{w}"
    );
    // within the range the mesh is measured too: 64 elements twist 0.02 rad each, and
    // the tip rotation is 3e-4 off (estimated 1.6e-4 ... 4e-4), so nothing is said; a
    // refinement that fails there is said, as the only warning
    let m = twisted(64, 100.0);
    let mut sol = solve_statics(&m).unwrap();
    let check = check_statics_mesh(&m, &mut sol, || Ok(twisted(128, 100.0)), None).unwrap();
    assert!(check.estimate < 1e-3, "{check:?}");
    assert!(sol.report.warnings.is_empty(), "{:?}", sol.report.warnings);
    let mut sol = solve_statics(&m).unwrap();
    assert!(check_statics_mesh(&m, &mut sol, || Err("no memory".into()), None).is_none());
    assert_eq!(
        sol.report.warnings,
        [
            "mesh error not measured: solving again with twice the elements (128 in all) \
          failed: no memory"
        ]
    );
}

/// bend45 with `n` elements and section sensors at the root, mid-span and tip, plus a
/// reaction that is zero by equilibrium (a driven base along x under a tip force along z).
fn bend45_sections(n: usize) -> latdyn::model::Model {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/models/bend45.toml"))
        .unwrap()
        .replace(
            "[[supports]]\nnode = \"root\"\ntype = \"clamped\"",
            "[[bodies]]\nname = \"base\"\nposition = [0, 0, 0]\nmass = 1.0\ninertia = [1, 1, 1]\n  \
             [[bodies.dofs]]\n  type = \"translation\"\n  axis = [1, 0, 0]\n  drive = \"0*t\"\n\n\
             [[joints]]\nname = \"fix\"\nnode = \"root\"\nbody = \"base\"\ntype = \"rigid\"",
        );
    assert!(text.contains("[[bodies]]"), "the support was replaced");
    let mut extra = String::new();
    for (name, at) in [("root", 0.0), ("mid", 0.5), ("end", 1.0)] {
        extra += &format!(
            "\n[[sensors]]\nname = \"{name}\"\ntype = \"section\"\nbeam = \"bend\"\nat = {at}\n"
        );
    }
    extra += "\n[[sensors]]\nname = \"reaction\"\ntype = \"driver\"\nbody = \"base\"\ndof = 0\n";
    latdyn::model::compile_str(
        &(text + &extra),
        "bend45_sections.toml",
        &[("elements".to_string(), n as f64)],
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn section_forces_are_estimated_at_first_order_and_a_zero_reaction_is_not_round_off_error() {
    // Section forces converge at first order where a distributed load acts within the
    // elements (an element's load beyond the station is not in them), so their estimate
    // is the first-order 2 |y_n − y_2n|. Under nodal loads they converge at second order
    // since session 47 (bend45's root axial force read 94.8, 48.5, 24.5, 12.3 N on 8 …
    // 64 elements before, read in the chord frame; now its root reads the tip load
    // exactly), where that estimate reads 1.5 times the truth (measured 1.50 at root,
    // mid-span and end). Against 256 elements each section sensor's estimate must be
    // within 0.6 … 1.6 of its true error.
    // The reaction along x is zero by equilibrium and computes as ~1e-11 N: measured
    // against the model's force scale it must read as nothing (it read 97 % against its
    // own round-off before), and the whole check must not warn on its account.
    let fine = solve_statics(&bend45_sections(256)).unwrap();
    let m = bend45_sections(8);
    let mut sol = solve_statics(&m).unwrap();
    let check = check_statics_mesh(&m, &mut sol, || Ok(bend45_sections(16)), None).unwrap();
    for name in ["root", "mid", "end"] {
        let k = m.sensor_index(name).unwrap();
        let (y, yr) = (&sol.sensors[k], &fine.sensors[k]);
        // the check's own measure: forces against the largest force component's change,
        // or the moments' over the model's extent (the box around bend45's nodes: its
        // chord, 76.5)
        let chord = (2.0 * 100.0f64.powi(2) * (1.0 - std::f64::consts::FRAC_PI_4.cos())).sqrt();
        let scale = (0..3)
            .map(|c| yr[c].abs())
            .fold(0.0f64, f64::max)
            .max((3..6).map(|c| yr[c].abs()).fold(0.0, f64::max) / chord);
        let truth = (0..6)
            .map(|c| (y[c] - yr[c]).abs() / if c < 3 { scale } else { scale * chord })
            .fold(0.0f64, f64::max);
        let est = check.by_sensor[k];
        eprintln!("{name}: estimate {est:.3e}, true {truth:.3e}");
        assert!(
            est / truth > 0.6 && est / truth < 1.6,
            "{name}: {est:.3e} against {truth:.3e}"
        );
    }
    let r = check.by_sensor[m.sensor_index("reaction").unwrap()];
    assert!(r < 1e-5, "reaction {r:.3e}");
    // (until session 47 the root's, whose axial force also leaked its chord frame's turn)
    assert!(!check.worst.starts_with("reaction"), "{check:?}");
}

#[test]
fn statics_warns_on_a_coarse_mesh_within_the_element_range_too() {
    // The mesh is measured whether or not an element leaves its range: the shipped
    // cantilever under its own weight (no element near its range) with a section sensor
    // at the root. An element carries its distributed load to its nodes, so within it the
    // section forces miss the load on the part of the element beyond the station: they
    // converge at first order (root shear −9.197 for −9.81 on 8 elements, −9.733 on 64):
    // estimated 6.7 %, warned as a coarse mesh naming the sensor; 64 elements 0.79 %,
    // not warned. (Until session 47 this test used bend45's root section, whose first
    // order came from reading the sections in the chord frame and leaving the moment's
    // turn out of the shear; they now read the tip load exactly.)
    let extra =
        "\n[environment]\ngravity = [0, 0, -9.81]\n\n[[sensors]]\nname = \"root_section\"\n\
                 type = \"section\"\nbeam = \"beam\"\nat = 0\n";
    let with = |n: &str| {
        let path =
            std::env::temp_dir().join(format!("latdyn_coarse_{}_{n}.toml", std::process::id()));
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/models/cantilever.toml"
        ))
        .unwrap();
        std::fs::write(&path, text + extra).unwrap();
        let v = latdyn_json(&[
            "statics",
            path.to_str().unwrap(),
            "--set",
            &format!("elements={n}"),
            "--json",
        ]);
        let _ = std::fs::remove_file(&path);
        v
    };
    let v = with("8");
    let w = v["warnings"].as_array().unwrap();
    assert_eq!(w.len(), 1, "{v}");
    let w = w[0].as_str().unwrap();
    assert!(
        w.starts_with("mesh too coarse for the reported numbers") && w.contains("root_section"),
        "{w}"
    );
    let est = v["mesh_error_by_sensor"]["root_section"].as_f64().unwrap();
    assert!(est > 0.04 && est < 0.1, "{v}");
    let v = with("64");
    assert_eq!(v["warnings"], serde_json::json!([]), "{v}");
    assert!(v["mesh_error_estimate"].as_f64().unwrap() < 1e-2, "{v}");
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
    assert!(
        w[0].as_str()
            .unwrap()
            .contains("measured by solving again with twice the elements"),
        "{v}"
    );
    assert!(v["mesh_error_estimate"].as_f64().unwrap() > 1e-2, "{v}");
    assert!(v["mesh_error_by_sensor"]["tip"].as_f64().is_some(), "{v}");
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
    assert!(v["mesh_error_estimate"].as_f64().unwrap() < 1e-2, "{v}");
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn shipped_bend45_statics_reports_its_measured_mesh_error_and_no_warning() {
    // The shipped scene at its shipped settings (issue 14: no warning there): its root
    // element leaves the range, the measured error (0.56 %, strain energy) is reported.
    let v = latdyn_json(&["statics", "models/bend45.toml", "--json"]);
    assert_eq!(v["warnings"], serde_json::json!([]), "{v}");
    let est = v["mesh_error_estimate"].as_f64().unwrap();
    assert!(est > 1e-3 && est < 1e-2, "{v}");
    assert_eq!(v["mesh_error_strain_energy"].as_f64(), Some(est), "{v}");
}

#[test]
fn statics_of_every_shipped_scene_warns_nothing_at_its_shipped_settings() {
    // Issue 14's "no warning on the shipped scenes", for `statics`: every shipped model
    // reports its static equilibrium without a warning, but the four-bar, which stands
    // in gravity on its cranks: its equilibrium is unstable (an inverted mechanism,
    // `mechanisms.rs`), and that is the one warning it must carry.
    for p in shipped_model_paths() {
        let name = p.file_name().unwrap().to_str().unwrap().to_string();
        let out = latdyn(&["statics", p.to_str().unwrap(), "--json"]);
        assert!(out.status.success(), "{name}: {out:?}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let w = v["warnings"].as_array().unwrap();
        if name == "fourbar.toml" {
            assert!(
                w.len() == 1 && w[0].as_str().unwrap().contains("unstable"),
                "{v}"
            );
            continue;
        }
        assert!(w.is_empty(), "{name}: {v}");
    }
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

#[test]
fn the_mesh_check_holds_no_more_elements_than_the_element_limit() {
    // The base model stays in memory while its refinement is solved: with the limit at
    // 20 elements, bend45's 8 and their 16 (24) are not solved, and the bound warning
    // says why the error was not measured.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args(["statics", "models/bend45.toml", "--json"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("LATDYN_LIMITS", "elements=20")
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["mesh_error_estimate"], serde_json::Value::Null, "{v}");
    let w = v["warnings"][0].as_str().unwrap();
    assert!(
        w.starts_with("large deformation per element")
            && w.contains("together would hold 24 elements, above the element limit 20"),
        "{w}"
    );
}

/// A moment sensed alone (`component = "My"`) at the free end, where it is zero: the
/// floor of its mesh-error measure was the strain energy's 1e-6 (1.7e-9 N·m here), and
/// its round-off, 3e-9 N·m, read as a 175 % mesh error and a warning. The floor now
/// includes the largest force term at the equilibrium times the model's extent.
#[test]
fn a_zero_moment_sensed_alone_is_not_read_as_a_mesh_error() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("models/cantilever.toml")).unwrap();
    assert!(text.contains("at = 0.0\ncomponent = \"My\""));
    let dir = std::env::temp_dir().join(format!("latdyn-tip-moment-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("tip_moment.toml");
    std::fs::write(
        &path,
        text.replace(
            "at = 0.0\ncomponent = \"My\"",
            "at = 1.0\ncomponent = \"My\"",
        ),
    )
    .unwrap();
    let v = latdyn_json(&["statics", path.to_str().unwrap(), "--set", "P=1", "--json"]);
    assert_eq!(v["warnings"], serde_json::json!([]), "{v}");
    let e = v["mesh_error_by_sensor"]["root_moment"].as_f64().unwrap();
    assert!(e < MESH_ERROR_WARN, "{v}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A clamped cantilever along x (L = 1, strong axis EIy = `eis`, weak EIz = `eiw`, GJ)
/// loaded at its tip, its beam written from root to tip or from tip to root.
fn anisotropic_cantilever(
    name: &str,
    reversed: bool,
    eis: f64,
    eiw: f64,
    loads: &str,
) -> std::path::PathBuf {
    let (from, to) = if reversed {
        ("tip", "root")
    } else {
        ("root", "tip")
    };
    let text = format!(
        r#"[parameters]
L = 1.0
elements = 8
P = 0.0
[sections.main]
EA = 1.0e9
EIy = {eis}
EIz = {eiw}
GJ = 80.0
rhoA = 1.0
rhoIy = 1.0e-4
rhoIz = 1.0e-4
[[nodes]]
name = "root"
position = [0, 0, 0]
[[nodes]]
name = "tip"
position = ["L", 0, 0]
[[beams]]
name = "beam"
from = "{from}"
to = "{to}"
elements = "elements"
section = "main"
orientation = [0, 1, 0]
[[supports]]
node = "root"
type = "clamped"
[[loads]]
node = "tip"
{loads}
[[sensors]]
name = "tip"
type = "node"
node = "tip"
[solver]
t_end = 1.0
dt = 1e-3
"#
    );
    let dir = std::env::temp_dir().join(format!("latdyn-anisotropic-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!(
        "{name}-{}.toml",
        if reversed { "rev" } else { "fwd" }
    ));
    std::fs::write(&p, text).unwrap();
    p
}

/// The lateral-torsional buckling load of a cantilever under a tip force through the
/// centroid: Timoshenko & Gere (Theory of Elastic Stability, §6.3) give
/// P_cr = 4.013 √(EIw GJ)/L² for a section that does not deflect before buckling; the
/// strong axis's own deflection raises it by 1/√((1 − EIw/EIs)(1 − GJ/EIs)) (Trahair,
/// Flexural-Torsional Buckling of Structures, §6.2.1), to 359.26 here from 358.94. The
/// load is found where the first frequency, signed (`modes` reports an unstable mode as
/// −|f|), crosses zero. Until session 47 the element applied EIy and EIz in node 1's
/// section axes, not in the twisted element's: P_cr read 385.6 from root to tip and 339.9
/// from tip to root on 8 elements, converging at O(h) from both sides (a probe). Now both
/// directions agree (measured 1e-5) and the mesh error falls at O(h²): 362.68, 360.12,
/// 359.48 on 8, 16, 32 elements, extrapolated 359.27.
#[test]
fn lateral_torsional_buckling_load_is_the_same_either_way_the_beam_runs_and_converges_at_second_order(
) {
    let want =
        4.013 * (100.0f64 * 80.0).sqrt() / ((1.0f64 - 100.0 / 1e5) * (1.0 - 80.0 / 1e5)).sqrt();
    let signed_f2 = |p: &std::path::Path, n: usize, load: f64| {
        let v = latdyn_json(&[
            "modes",
            p.to_str().unwrap(),
            "--set",
            &format!("elements={n}"),
            "--set",
            &format!("P={load}"),
            "--count",
            "1",
            "--mesh-check",
            "never",
            "--json",
        ]);
        let f = v["frequencies_hz"][0].as_f64().unwrap();
        f * f.abs()
    };
    let critical = |reversed: bool, n: usize| {
        let p = anisotropic_cantilever("ltb", reversed, 1e5, 100.0, "force = [0, 0, \"P\"]");
        // secant on f|f|, nearly linear in P near the crossing
        let (mut a, mut b) = (340.0, 370.0);
        let (mut fa, mut fb) = (signed_f2(&p, n, a), signed_f2(&p, n, b));
        for _ in 0..6 {
            let c = b - fb * (b - a) / (fb - fa);
            if (c - b).abs() < 1e-7 * c {
                return c;
            }
            (a, fa) = (b, fb);
            (b, fb) = (c, signed_f2(&p, n, c));
        }
        b
    };
    let mut forward = Vec::new();
    for n in [8, 16, 32] {
        let (f, r) = (critical(false, n), critical(true, n));
        assert!(
            rel(f, r) < 1e-4,
            "{n} elements: {f} root to tip, {r} tip to root"
        );
        forward.push(f);
    }
    let (d1, d2) = (forward[0] - forward[1], forward[1] - forward[2]);
    let order = (d1 / d2).log2();
    assert!(
        (1.8..2.2).contains(&order),
        "observed order {order} from {forward:?}"
    );
    let extrapolated = forward[2] - d2 / 3.0;
    // 5e-4: the closed form's 4.013 is given to four digits (the extrapolation reads 3e-5)
    assert!(
        rel(extrapolated, want) < 5e-4,
        "{extrapolated} against {want}"
    );
}

/// The tip of the same kind of cantilever (EIy = 100, EIz = 300) twisted 0.37 rad and bent
/// in both planes by a tip force and torque. Until session 47 the tip rotation's x
/// component read 0.3601 from root to tip and 0.3893 from tip to root on 8 elements
/// (converged 0.3736), with a mesh-error estimate of 0.6 % and no warning. Now the two
/// agree to 2e-5 on 16 elements and the error falls at O(h²) toward 64 elements.
#[test]
fn a_beam_twisted_and_bent_in_both_planes_gives_the_same_tip_either_way_it_runs() {
    let loads = "force = [0, 150, 250]\nmoment = [60, 0, 0]";
    let tip = |reversed: bool, n: usize| -> Vec<f64> {
        let p = anisotropic_cantilever("twisted", reversed, 100.0, 300.0, loads);
        let v = latdyn_json(&[
            "statics",
            p.to_str().unwrap(),
            "--set",
            &format!("elements={n}"),
            "--json",
        ]);
        v["sensors"]["tip"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let dist = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
    };
    let fine = tip(false, 64);
    let (f16, r16) = (tip(false, 16), tip(true, 16));
    assert!(
        dist(&f16, &r16) < 1e-4,
        "16 elements: {f16:?} against {r16:?}"
    );
    let (e16, e32) = (dist(&f16, &fine), dist(&tip(false, 32), &fine));
    // against 64 elements, whose own error is a sixteenth of 16's: a ratio of 4 for
    // O(h²) reads 5 here; O(h) read about 2.5
    assert!(e16 / e32 > 3.5, "error 16 → 32 elements: {e16} → {e32}");
}

/// A clamped root's section is the global frame whatever the beam does, so its
/// resultants are the tip load (statics: the reactions balance the loads). Tip force
/// (300, 0, 40) on EI = 100: 0.06 m of sag. Until session 47 the section sensor reported
/// the chord frame of the root element, turned by its chord's slope from the section,
/// so the axial force leaked into the shear at O(h): Vz read 32.9, 36.2, 38.0, 39.5 on 4,
/// 8, 16, 64 elements (a probe, session 47). Now 39.91, 39.976, 39.995, 40.001: what
/// remains is the element's shear from its Hermite curvature, O(h²).
#[test]
fn a_clamped_roots_section_forces_are_the_tip_load_in_the_roots_frame() {
    let text = std::fs::read_to_string(anisotropic_cantilever(
        "tension",
        false,
        100.0,
        100.0,
        "force = [300, 0, 40]",
    ))
    .unwrap()
        + "[[sensors]]\nname = \"root_sec\"\ntype = \"section\"\nbeam = \"beam\"\nat = 0.0\n";
    let dir = std::env::temp_dir().join(format!("latdyn-root-section-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("root.toml");
    std::fs::write(&p, text).unwrap();
    for (n, tol) in [(8, 1e-3), (16, 2.5e-4)] {
        let v = latdyn_json(&[
            "statics",
            p.to_str().unwrap(),
            "--set",
            &format!("elements={n}"),
            "--json",
        ]);
        let r: Vec<f64> = v["sensors"]["root_sec"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        // N to the stretch's round-off; Vz to the element's O(h²) shear (measured 5.9e-4, 1.3e-4)
        assert!(rel(r[0], 300.0) < 1e-5, "{n} elements: N = {}", r[0]);
        assert!(rel(r[2], 40.0) < tol, "{n} elements: Vz = {}", r[2]);
        assert!(r[1].abs() < 1e-9 && r[3].abs() < 1e-9, "{r:?}");
    }
}
