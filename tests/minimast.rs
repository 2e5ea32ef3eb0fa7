//! Mini-Mast bay (paper section 5.1, references.md §9): models/minimast_bay.toml deployed
//! from the packaged state by driving the upper batten triangle up by the longeron length L
//! while it turns freely about z. Run in release (`cargo test --release --test minimast`).

mod common;
use common::*;
use latdyn::solver::dynamics::run;

/// Packaged longeron joint-to-joint length from Table 2, A1 to B1 (references.md §9:
/// 1.075865 m).
fn l0() -> f64 {
    (-0.23372f64 + 0.60598).hypot(0.65954 + 0.34987)
}
/// Turn of the upper triangle that puts B1 above A1 (Table 2 angles, references.md §9).
const TURN_DEG: f64 = 100.49;

fn drive(t: f64) -> f64 {
    let tt = t.min(1.0);
    l0() * (tt - (2.0 * std::f64::consts::PI * tt).sin() / (2.0 * std::f64::consts::PI))
}

fn hist<'a>(
    m: &latdyn::model::Model,
    h: &'a latdyn::solver::dynamics::History,
    name: &str,
) -> &'a [Vec<f64>] {
    &h.values[m.sensor_index(name).expect("sensor")]
}

const SECTIONS: [&str; 4] = [
    "longeron_mid",
    "longeron_top",
    "diagonal_a_mid",
    "diagonal_b_mid",
];

#[test]
fn bay_compiles_with_the_derived_geometry() {
    let m = shipped("minimast_bay.toml", &[]);
    for s in SECTIONS.iter().chain(&[
        "longeron_axial",
        "diagonal_axial",
        "upper_z",
        "drive_force",
        "longeron_rotation",
        "diagonal_mid_hinge",
    ]) {
        assert!(m.sensor_index(s).is_some(), "sensor {s} missing");
    }
}

#[test]
fn packaged_state_is_undeformed_and_a_short_coarse_run_completes() {
    let m = shipped(
        "minimast_bay.toml",
        &[("elements", 2.0), ("t_end", 0.3), ("dt", 2e-3)],
    );
    let (h, stats, err) = run(&m, |_, _| {});
    assert!(err.is_none(), "{err:?}");
    assert!((h.t.last().unwrap() - 0.3).abs() < 1e-9);
    // t = 0: the packaged bay carries no internal force at all
    for s in SECTIONS {
        let v = &hist(&m, &h, s)[0];
        let worst = v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        assert!(worst < 1e-9, "{s} at t = 0: {v:?}");
    }
    let up = hist(&m, &h, "upper_z");
    let z = up.last().unwrap()[2] - up[0][2];
    assert!((z - drive(0.3)).abs() < 1e-9, "Z(0.3) = {z}");
    // by t = 0.3 the members bend (tens of N*m, references: members must bend and twist)
    let mid = hist(&m, &h, "longeron_mid").last().unwrap();
    let bend = mid[4].hypot(mid[5]);
    eprintln!(
        "short run: {} steps, {} rejected, Z(0.3) = {z:.5} m, longeron mid bending {bend:.2} N*m",
        stats.steps, stats.rejected_steps
    );
    assert!(bend > 1.0 && bend < 1e3, "longeron mid bending {bend}");
}

#[test]
fn full_deployment_reaches_l_and_turns_about_100_degrees() {
    let m = shipped("minimast_bay.toml", &[("t_end", 1.05)]);
    let (h, stats, err) = run(&m, |_, _| {});
    assert!(err.is_none(), "{err:?}");
    let i =
        h.t.iter()
            .position(|&t| (t - 1.0).abs() < 1e-9)
            .expect("output at t = T");
    let up = hist(&m, &h, "upper_z");
    let z = up[i][2] - up[0][2];
    let turn = up[i][5].to_degrees();
    let mid = hist(&m, &h, "diagonal_mid_hinge");
    let lm = hist(&m, &h, "longeron_mid");
    let peak = lm.iter().map(|v| v[4].hypot(v[5])).fold(0.0f64, f64::max);
    eprintln!(
        "deployment: {} steps, {} rejected; Z(T) = {z:.6} m, turn {turn:.2} deg, mid-hinge {:.2} deg, peak longeron mid bending {peak:.1} N*m",
        stats.steps,
        stats.rejected_steps,
        mid[i][0].to_degrees()
    );
    assert!((z - l0()).abs() < 1e-5, "Z(T) = {z}");
    assert!((turn - TURN_DEG).abs() < 3.0, "turn {turn} deg");
    // the mid-hinges lock straight (lock_angle = pi) by the end of the stroke
    assert!(
        (mid[i][0] - std::f64::consts::PI).abs() < 1e-9,
        "mid-hinge {}",
        mid[i][0]
    );
    // the longeron is bent on the way (the deployed state is nearly unbent)
    assert!(peak > 10.0 && peak < 1e3, "peak bending {peak}");
    let last = &lm[i];
    assert!(last[4].hypot(last[5]) < 0.3 * peak);
}
