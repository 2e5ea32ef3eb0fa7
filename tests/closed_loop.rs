//! A closed kinematic loop built only from hinge coordinates (no constraint equations):
//! the parallelogram four-bar of models/fourbar.toml.

mod common;
use common::*;
use latdyn::solver::dynamics::run;

#[test]
fn four_bar_hinge_angles_obey_the_parallelogram_geometry() {
    let m = shipped("fourbar.toml", &[("t_end", 0.5)]);
    let (h, stats, err) = run(&m, |_, _| {});
    assert!(err.is_none(), "{err:?}");
    let get = |name: &str| &h.values[m.sensor_index(name).unwrap()];
    let (g1, g2, c1, cp) = (get("g1"), get("g2"), get("c1"), get("coupler"));
    let mut worst_pos: f64 = 0.0;
    for i in 0..h.t.len() {
        // the coupler keeps its orientation; the crank chord turns by about the mean of
        // its end hinge angles, and the coupler sits at the crank tips: with rigid cranks
        // x = 0.5 − sin θ, y = cos θ. Elastic bending under the coupler's weight and
        // inertia (~mgL³/3EI ≈ 1e-3 m) is the allowed difference.
        assert!(cp[i][5].abs() < 1e-6, "coupler turned by {}", cp[i][5]);
        assert!((g1[i][0] - g2[i][0]).abs() < 1e-6);
        let th = 0.5 * (g1[i][0] + c1[i][0]);
        let dx = cp[i][0] - (0.5 - th.sin());
        let dy = cp[i][1] - th.cos();
        worst_pos = worst_pos.max(dx.hypot(dy));
    }
    eprintln!(
        "four-bar: {} steps, final angle {:.4} rad, worst coupler offset from rigid geometry {worst_pos:.2e} m",
        stats.steps,
        g1.last().unwrap()[0]
    );
    assert!(
        g1.last().unwrap()[0] < -0.5,
        "the mechanism should have moved"
    );
    assert!(
        worst_pos < 5e-3,
        "coupler off the linkage geometry by {worst_pos} m"
    );
}

#[test]
fn locking_a_hinge_at_a_set_angle_freezes_it_and_stops_the_mechanism() {
    let lock = -0.3;
    let m = shipped("fourbar.toml", &[("t_end", 0.6), ("lock", lock)]);
    let (h, _, err) = run(&m, |_, _| {});
    assert!(err.is_none(), "{err:?}");
    let g1 = &h.values[m.sensor_index("g1").unwrap()];
    let g2 = &h.values[m.sensor_index("g2").unwrap()];
    let first = g1
        .iter()
        .position(|v| v[0] == lock)
        .expect("hinge g1 never locked");
    for i in first..h.t.len() {
        assert_eq!(g1[i][0], lock, "locked hinge moved at t = {}", h.t[i]);
        assert_eq!(g1[i][1], 0.0);
        // the rest is now a structure: the other ground hinge only vibrates elastically
        assert!(
            (g2[i][0] - lock).abs() < 0.03,
            "g2 = {} at t = {}",
            g2[i][0],
            h.t[i]
        );
    }
}

/// θ(t), θ̇(t) of the parallelogram with rigid cranks: the coupler (mass mc) translates on
/// a circle of radius L above the ground hinges, each crank (ρA L) turns about its ground
/// hinge, and both fall from the upright position, so
/// (mc L² + 2 ρA L³/3) θ̈ = (mc + ρA L) g L sin θ, θ(0) = 0, θ̇(0) = −v0 / L.
/// Classical RK4 at 1e-5 s: its own error is far below the tolerances below.
fn rigid_four_bar(v0: f64, t: &[f64]) -> Vec<[f64; 2]> {
    let (l, rho_a, mc, g) = (1.0, 1.0, 5.0, 9.81);
    let k = (mc + rho_a * l) * g * l / (mc * l * l + 2.0 * rho_a * l * l * l / 3.0);
    let f = |y: [f64; 2]| [y[1], k * y[0].sin()];
    let h: f64 = 1e-5;
    let mut y = [0.0, -v0 / l];
    let mut now = 0.0;
    let mut out = Vec::new();
    for &ti in t {
        while now < ti - 1e-12 {
            let hh = h.min(ti - now);
            let k1 = f(y);
            let k2 = f([y[0] + 0.5 * hh * k1[0], y[1] + 0.5 * hh * k1[1]]);
            let k3 = f([y[0] + 0.5 * hh * k2[0], y[1] + 0.5 * hh * k2[1]]);
            let k4 = f([y[0] + hh * k3[0], y[1] + hh * k3[1]]);
            for c in 0..2 {
                y[c] += hh / 6.0 * (k1[c] + 2.0 * k2[c] + 2.0 * k3[c] + k4[c]);
            }
            now += hh;
        }
        out.push(y);
    }
    out
}

/// Largest difference of the ground hinge's angle and rate from the rigid four-bar, each
/// over the rigid history's range.
fn off_rigid(m: &latdyn::model::Model) -> [f64; 2] {
    let (h, _, err) = run(m, |_, _| {});
    assert!(err.is_none(), "{err:?}");
    let g1 = &h.values[m.sensor_index("g1").unwrap()];
    let rigid = rigid_four_bar(1.0, &h.t);
    let mut worst = [0.0f64; 2];
    for c in 0..2 {
        let (lo, hi) = rigid
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), y| (a.min(y[c]), b.max(y[c])));
        let off = g1
            .iter()
            .zip(&rigid)
            .fold(0.0f64, |w, (x, y)| w.max((x[c] - y[c]).abs()));
        worst[c] = off / (hi - lo);
    }
    worst
}

#[test]
fn a_consistent_start_launches_the_four_bar_as_the_rigid_mechanism_moves() {
    // The shipped four-bar sets only the coupler's rate; its consistent start gives the
    // cranks and hinges the rates that strain nothing. Its cranks are stiff (first bending
    // mode near 80 Hz against a 0.5 Hz fall), so its hinge angle and rate must follow the
    // rigid mechanism to within the cranks' elastic share: the coupler's inertia (up to
    // about 25 N per crank) bends a crank by F L³ / 3 EI ≈ 4e-4 m, 4e-4 rad against a
    // range of about 1 rad, hence 1e-3. The same model with its cranks at rest is the
    // control: the coupler strikes them and the hinge rate rings, which is what the start
    // removes. Measured at dt = 5e-4 over 1 s: consistent 3.1e-5 (angle) and 5.9e-5
    // (rate) of the range, at rest 5.3e-2 and 0.47.
    let consistent = shipped("fourbar.toml", &[("dt", 5e-4)]);
    assert_eq!(consistent.initial_consistent_velocity, Some(true));
    let [angle, rate] = off_rigid(&consistent);
    eprintln!("consistent start: angle {angle:.2e}, rate {rate:.2e} of the range off rigid");
    assert!(angle < 1e-3 && rate < 1e-3, "{angle:.2e} {rate:.2e}");
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/fourbar.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("consistent_velocity = true", "consistent_velocity = false");
    let at_rest =
        latdyn::model::compile_str(&text, "fourbar-at-rest.toml", &[("dt".to_string(), 5e-4)])
            .unwrap_or_else(|e| panic!("{e}"));
    let [angle0, rate0] = off_rigid(&at_rest);
    eprintln!("cranks at rest: angle {angle0:.2e}, rate {rate0:.2e} of the range off rigid");
    assert!(rate0 > 10.0 * rate, "{rate0:.2e} against {rate:.2e}");
}

/// `run --json` of the shipped four-bar with its `[initial]` section replaced by
/// `initial` (written to a file of its own).
fn four_bar_json(initial: &str, tag: &str) -> serde_json::Value {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let shipped = std::fs::read_to_string(root.join("models/fourbar.toml")).unwrap();
    let section = "[initial]\nconsistent_velocity = true\n";
    assert!(shipped.contains(section));
    let text = shipped.replace(section, initial);
    let dir = std::env::temp_dir().join(format!("latdyn-start-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("fourbar.toml");
    std::fs::write(&path, text).unwrap();
    let out = latdyn(&["run", path.to_str().unwrap(), "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn a_start_that_strains_the_structure_is_warned_unless_the_file_says_what_it_wants() {
    const WARN: &str = "the initial velocity strains the structure";
    let has = |v: &serde_json::Value| {
        v["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains(WARN))
    };
    // not written: measured, not applied, and warned (7.5 % of the kinetic energy)
    let unsaid = four_bar_json("", "unsaid");
    let c = &unsaid["consistent_start"];
    assert_eq!(c["applied"], false);
    assert!(c["kinetic_share"].as_f64().unwrap() > 0.05, "{c}");
    assert!(has(&unsaid), "{}", unsaid["warnings"]);
    // `false`: the velocity as intended, nothing measured or said
    let given = four_bar_json("[initial]\nconsistent_velocity = false\n", "false");
    assert!(given["consistent_start"].is_null());
    assert!(!has(&given));
    // `true`: applied, and the start strains nothing
    let made = four_bar_json("[initial]\nconsistent_velocity = true\n", "true");
    assert_eq!(made["consistent_start"]["applied"], true);
    assert!(
        made["consistent_start"]["strain_rate_left"]
            .as_f64()
            .unwrap()
            < 1e-9
    );
    assert!(!has(&made));
    // a start in rigid rotation (the blade) strains nothing and is not warned
    let out = latdyn(&[
        "run",
        concat!(env!("CARGO_MANIFEST_DIR"), "/models/flapping_blade.toml"),
        "--set",
        "t_end=0.2",
        "--json",
    ]);
    let blade: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(blade["consistent_start"]["kinetic_share"].as_f64().unwrap() < 1e-12);
    assert!(!has(&blade));
}
