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
