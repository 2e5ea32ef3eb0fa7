//! The whole Mini-Mast, models/minimast.toml: `bays` copies of the shipped bay stacked
//! with `[[repeat]]`. One bay must be the shipped bay; two bays must both deploy and lock.

mod common;
use common::*;
use latdyn::solver::dynamics::run;
use std::f64::consts::PI;

/// Packaged longeron joint-to-joint length (Table 2, A1 to B1; references.md §9).
fn l0() -> f64 {
    (-0.23372f64 + 0.60598).hypot(0.65954 + 0.34987)
}

/// Turn of a batten relative to the one below that puts the longerons vertical (Table 2
/// angles of A1 and B1, 100.49 deg).
fn turn() -> f64 {
    (-0.34987f64).atan2(-0.60598) - 0.65954f64.atan2(-0.23372) + 2.0 * PI
}

#[test]
fn one_bay_mast_matches_the_shipped_bay_to_round_off() {
    // What differs between the two files for bays = 1: corner 3 is turned by
    // cos/sin(4*pi/3) instead of the bay's cos/sin(2*pi/3) with signs, the lower joints
    // hang on a grounded body `batten0` at the origin instead of `ground`, and the drive
    // is written `(1 - 0)*(1*Z) + 0*(...)`. All of it is round-off in the initial
    // geometry (1 ulp of the coordinates), so the member moments agree to round-off
    // amplified by the run: within 1e-9 of each sensor's peak over the whole stroke with
    // the mid-hinge snap-through and locks (measured 7e-12 to 1.4e-11 with this mesh and
    // step; the margin is for other platforms' libm). The body sensor reads the same pose.
    let sets = [("elements", 2.0), ("dt", 2e-3), ("t_end", 1.1)];
    let bay = shipped("minimast_bay.toml", &sets);
    let mast = shipped("minimast.toml", &[sets[0], sets[1], sets[2], ("bays", 1.0)]);
    assert_eq!(mast.n_eq, bay.n_eq);
    let (hb, sb, eb) = run(&bay, |_, _| {});
    let (hm, sm, em) = run(&mast, |_, _| {});
    assert!(eb.is_none() && em.is_none(), "{eb:?} {em:?}");
    assert_eq!(hb.t, hm.t, "same output times");
    assert_eq!(sb.steps, sm.steps);
    for name in [
        "longeron_mid",
        "longeron_top",
        "diagonal_a_mid",
        "diagonal_b_mid",
        "longeron_rotation",
        "diagonal_mid_hinge",
        "drive_force",
    ] {
        let a = hist(&bay, &hb, name);
        let b = hist(&mast, &hm, name);
        let peak = a
            .iter()
            .flatten()
            .fold(0.0f64, |m, x| m.max(x.abs()))
            .max(1e-300);
        let worst = a
            .iter()
            .zip(b)
            .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p - q).abs()))
            .fold(0.0f64, f64::max);
        eprintln!("{name}: largest difference {worst:.3e} of peak {peak:.3e}");
        assert!(worst <= 1e-9 * peak, "{name}: {worst} vs peak {peak}");
    }
    // the body sensors differ by where the batten is: same pose
    let a = hist(&bay, &hb, "upper_z");
    let b = hist(&mast, &hm, "upper_z");
    for (x, y) in a.iter().zip(b) {
        for c in 0..6 {
            assert!((x[c] - y[c]).abs() < 1e-9, "{x:?} {y:?}");
        }
    }
}

fn hist<'a>(
    m: &latdyn::model::Model,
    h: &'a latdyn::solver::dynamics::History,
    name: &str,
) -> &'a [Vec<f64>] {
    &h.values[m.sensor_index(name).expect("sensor")]
}

/// Index of the output sample at time `t`.
fn at(t: &[f64], time: f64) -> usize {
    t.iter()
        .position(|&x| (x - time).abs() < 1e-9)
        .expect("sample")
}

#[test]
fn two_bays_deployed_together_both_extend_turn_and_lock() {
    let m = shipped(
        "minimast.toml",
        &[
            ("bays", 2.0),
            ("elements", 2.0),
            ("dt", 2e-3),
            ("t_end", 1.05),
        ],
    );
    let (h, stats, err) = run(&m, |_, _| {});
    assert!(err.is_none(), "{err:?}");
    let i = at(&h.t, 1.0);
    for j in 1..=2 {
        let b = hist(&m, &h, &format!("batten{j}"));
        let z = b[i][2] - b[0][2];
        let turn_j = b[i][5].rem_euclid(2.0 * PI);
        let mid = hist(&m, &h, &format!("mid_hinge{j}_1"));
        eprintln!(
            "bay {j}: Z = {z:.6} m, turn {:.2} deg (rigid members: {:.2}), mid-hinge {:.3} deg; {} steps",
            turn_j.to_degrees(),
            (j as f64 * turn()).rem_euclid(2.0 * PI).to_degrees(),
            mid[i][0].to_degrees(),
            stats.steps
        );
        // driven: exactly j strokes
        assert!((z - j as f64 * l0()).abs() < 1e-9, "batten {j}: Z = {z}");
        // the free turn comes out of the members: within 3 deg of the rigid-member turn
        // per bay (the shipped bay turns 100.38 against 100.49)
        let want = (j as f64 * turn()).rem_euclid(2.0 * PI);
        let d = (turn_j - want + PI).rem_euclid(2.0 * PI) - PI;
        assert!(
            d.abs() < (3.0f64 * j as f64).to_radians(),
            "batten {j}: turn off by {d}"
        );
        // the mid-hinge lock (lock_angle = pi) has fired: exactly straight
        assert!(
            (mid[i][0] - PI).abs() < 1e-9,
            "bay {j} mid-hinge {}",
            mid[i][0]
        );
    }
}

#[test]
fn two_bays_deployed_one_after_the_other_lock_in_turn() {
    let m = shipped(
        "minimast.toml",
        &[
            ("bays", 2.0),
            ("elements", 2.0),
            ("dt", 2e-3),
            ("sequential", 1.0),
        ],
    );
    assert!((m.solver.t_end - 2.2).abs() < 1e-12, "t_end = 2T + 0.2");
    let (h, _, err) = run(&m, |_, _| {});
    assert!(err.is_none(), "{err:?}");
    let (i1, i2) = (at(&h.t, 1.0), at(&h.t, 2.0));
    let mid1 = hist(&m, &h, "mid_hinge1_1");
    let mid2 = hist(&m, &h, "mid_hinge2_1");
    let b1 = hist(&m, &h, "batten1");
    let b2 = hist(&m, &h, "batten2");
    // at T: bay 1 out and locked, bay 2 still packaged on top of it
    assert!(
        (mid1[i1][0] - PI).abs() < 1e-9,
        "bay 1 at T: {}",
        mid1[i1][0]
    );
    assert!(mid2[i1][0].abs() < 0.05, "bay 2 at T: {}", mid2[i1][0]);
    assert!(((b2[i1][2] - b2[0][2]) - l0()).abs() < 1e-9);
    // at 2T: both out; batten 1 stayed at one stroke
    assert!(
        (mid2[i2][0] - PI).abs() < 1e-9,
        "bay 2 at 2T: {}",
        mid2[i2][0]
    );
    assert!(((b1[i2][2] - b1[0][2]) - l0()).abs() < 1e-9);
    assert!(((b2[i2][2] - b2[0][2]) - 2.0 * l0()).abs() < 1e-9);
}

/// Length of a beam from its end nodes' reference positions.
fn span(m: &latdyn::model::Model, beam: &str) -> f64 {
    let b = m.beams.iter().find(|b| b.name == beam).expect("beam");
    let (a, c) = (m.x0[b.nodes[0]], m.x0[*b.nodes.last().unwrap()]);
    ((a[0] - c[0]).powi(2) + (a[1] - c[1]).powi(2) + (a[2] - c[2]).powi(2)).sqrt()
}

#[test]
fn deployed_geometry_keeps_the_member_lengths_and_is_a_stable_symmetric_mast() {
    let sets = [("bays", 2.0), ("elements", 2.0)];
    let packaged = shipped("minimast.toml", &sets);
    let deployed = shipped("minimast.toml", &[sets[0], sets[1], ("deployed", 1.0)]);
    // rigid members: every longeron and diagonal half has its packaged length in the
    // deployed geometry, which is built from the turn and the stroke, not from lengths.
    // Tolerance 0.05 mm: the table's 5 digits put B1 100.488 deg from A1 with radii equal
    // to 1e-5 m, and the straight diagonal is 0.02 mm shorter than its two halves.
    for j in 1..=2 {
        for k in 1..=3 {
            let l = format!("b{j}_longeron{k}");
            let (lp, ld) = (span(&packaged, &l), span(&deployed, &l));
            assert!((lp - ld).abs() < 5e-5, "{l}: {lp} packaged, {ld} deployed");
            let (a, b) = (format!("b{j}_diagonal{k}_a"), format!("b{j}_diagonal{k}_b"));
            let whole_p = span(&packaged, &a) + span(&packaged, &b);
            let whole_d = span(&deployed, &a) + span(&deployed, &b);
            assert!((whole_p - whole_d).abs() < 5e-5, "diagonal {j}.{k}");
            // the longerons stand vertical: upper joint above the lower one
            let b_ = deployed.beams.iter().find(|x| x.name == l).unwrap();
            let (p, q) = (
                deployed.x0[b_.nodes[0]],
                deployed.x0[*b_.nodes.last().unwrap()],
            );
            assert!((p[0] - q[0]).hypot(p[1] - q[1]) < 1e-4, "{l} not vertical");
        }
    }
    // batten 2 sits two deployed pitches L + 2 zj up, minus zj (its joints' plane)
    let top = deployed
        .bodies
        .iter()
        .find(|b| b.name == "batten2")
        .unwrap();
    assert!((top.x0[2] - (2.0 * (l0() + 2.0 * 0.02379) - 0.02379)).abs() < 1e-12);
    // modes of the unstressed deployed mast: no zero-frequency (mechanism) mode, and the
    // first bending frequency comes as a pair (three-fold symmetry about z, battens with
    // Ixx = Iyy), equal to round-off (measured 4e-13 relative; 1e-9 leaves room)
    let s = latdyn::joint::State::new(&deployed);
    let md = latdyn::solver::modes::lowest_modes(&deployed, &s, 4).expect("modes");
    let f = &md.frequencies_hz;
    eprintln!("2 deployed bays: {:?} Hz", &f[..4]);
    assert!(
        md.zero_frequency.iter().all(|z| !z),
        "{:?}",
        md.zero_frequency
    );
    assert!(f[0] > 1.0 && (f[1] - f[0]).abs() < 1e-9 * f[0], "{f:?}");
}
