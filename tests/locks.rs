//! A hinge lock is an inelastic impact: the stop's impulse acts on the hinge's own
//! coordinate only, so every momentum the stop does not resist is kept.

mod common;
use common::rel;

/// Beams of length 1 hinged about z at the axis of a hub that turns freely about z (no
/// drive, no gravity), each turning relative to the hub at `w0` from a rest hub and locking
/// after 0.5 rad. Nothing acts on the hub about z but the beams, so the angular momentum
/// about z is kept through the locks: H = n I_b w0 before, and after them the hub and the
/// beams turn together at H / (I_h + n I_b), I_b = ρA L³/3 + ρI L about the axis.
fn hub_with_locking_beams(beams: usize, elements: usize, rho_i: f64) -> latdyn::model::Model {
    let mut text = format!(
        r#"
[parameters]
rI = {rho_i}
Ib = "1/3 + rI"
Ih = 1.0

[sections.s]
EA = 1e8
EIy = 1e4
EIz = 1e4
GJ = 1e4
rhoA = 1.0
rhoIy = "rI"
rhoIz = "rI"

[[bodies]]
name = "hub"
position = [0, 0, 0]
mass = 1.0
inertia = ["Ih", "Ih", "Ih"]
  [[bodies.dofs]]
  type = "rotation"
  axis = [0, 0, 1]

[[sensors]]
name = "hub"
type = "body"
body = "hub"

[initial]
consistent_velocity = true

[solver]
t_end = 3.0
dt = 1e-3
output_dt = 0.01
rho_inf = 0.8
"#
    );
    for b in 0..beams {
        let a = 2.0 * std::f64::consts::PI * b as f64 / beams as f64;
        text += &format!(
            r#"
[[nodes]]
name = "root{b}"
position = [0, 0, 0]

[[nodes]]
name = "tip{b}"
position = [{}, {}, 0]

[[beams]]
name = "beam{b}"
from = "root{b}"
to = "tip{b}"
elements = {elements}
section = "s"

[[joints]]
name = "pin{b}"
node = "root{b}"
body = "hub"
type = "hinge"
axis = [0, 0, 1]
initial_rate = 2.0
lock_angle = 0.5
"#,
            a.cos(),
            a.sin()
        );
    }
    latdyn::model::compile_str(&text, "hub_lock.toml", &[]).unwrap_or_else(|e| panic!("{e}"))
}

/// The hub's turning rate after the locks: the slope of its angle over t > 0.4 s (the
/// locks come at 0.25 s), fitted by least squares through the beams' ringing.
fn rate_after_the_locks(m: &latdyn::model::Model) -> f64 {
    let (h, stats, err) = latdyn::solver::dynamics::run(m, |_, _| {});
    assert!(err.is_none(), "{err:?}");
    let (_, t_lock) = stats.first_lock.expect("the hinges lock");
    assert!((t_lock - 0.25).abs() < 2e-3, "locked at {t_lock}");
    let k = m.sensor_index("hub").unwrap();
    let pts: Vec<(f64, f64)> =
        h.t.iter()
            .zip(&h.values[k])
            .filter(|(t, _)| **t > 0.4)
            .map(|(t, v)| (*t, v[5]))
            .collect();
    let n = pts.len() as f64;
    let (st, sa) = pts
        .iter()
        .fold((0.0, 0.0), |(st, sa), (t, a)| (st + t, sa + a));
    let (tm, am) = (st / n, sa / n);
    let (num, den) = pts.iter().fold((0.0, 0.0), |(num, den), (t, a)| {
        (num + (t - tm) * (a - am), den + (t - tm) * (t - tm))
    });
    num / den
}

#[test]
fn a_lock_keeps_the_angular_momentum_about_a_free_hubs_axis() {
    // Closed form: H / (I_h + n I_b) with w0 = 2, I_h = 1. Measured (session 23): 1.1e-4 to
    // 1.6e-4 below it, one beam or two locking at once, 2 or 4 elements, rotary inertia
    // 1e-6 or 1e-2 (the beams ring after the impact, 2e-3 rad about the fitted line).
    // Stopping the hinge's rate alone, as the lock did until session 23, read 1.3e-2 low
    // with one beam of 2 elements: the impulse it applied to the beam's root node took
    // momentum that nothing outside removes. Tolerance 1e-3: 6× the measured bias, 13×
    // below that error.
    for (beams, elements, rho_i) in [(1, 2, 1e-6), (1, 2, 1e-2), (2, 2, 1e-6), (1, 4, 1e-2)] {
        let m = hub_with_locking_beams(beams, elements, rho_i);
        let ib = 1.0 / 3.0 + rho_i;
        let n = beams as f64;
        let want = n * ib * 2.0 / (1.0 + n * ib);
        let got = rate_after_the_locks(&m);
        eprintln!(
            "{beams} beam(s) of {elements} elements, ρI = {rho_i}: hub rate {got:.6} against \
             {want:.6}, {:.1e} off",
            rel(got, want)
        );
        assert!(rel(got, want) < 1e-3, "{got} vs {want}");
    }
}

/// A cantilever hinged at its root about y (spring k) to a held cart, bent by a tip
/// moment M about y, the hinge locking at `lock`.
fn hinged_cantilever(lock: f64) -> latdyn::model::Model {
    let text = format!(
        r#"
[sections.main]
EA = 1e6
EIy = 100
EIz = 100
GJ = 80
rhoA = 1

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
section = "main"

[[bodies]]
name = "cart"
position = [0, 0, 0]
mass = 1.0
inertia = [1, 1, 1]
  [[bodies.dofs]]
  type = "translation"
  axis = [1, 0, 0]
  drive = "0*t"

[[joints]]
name = "h"
node = "root"
body = "cart"
type = "hinge"
axis = [0, 1, 0]
stiffness = 1000
lock_angle = {lock}

[[loads]]
node = "tip"
moment = [0, 100, 0]

[[sensors]]
name = "hinge"
type = "hinge"
joint = "h"
"#
    );
    latdyn::model::compile_str(&text, "hinged_cantilever.toml", &[])
        .unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn statics_past_a_lock_angle_says_the_hinge_never_locked() {
    // One equilibrium under the full loads turns the hinge to M/k = 0.1 rad whatever its
    // lock angle (0.05 here): the lock is an event along the loading, which plain statics
    // does not follow. Until session 30 it said nothing; now it warns and names the fix.
    let m = hinged_cantilever(0.05);
    let sol = latdyn::solver::solve_statics(&m).unwrap();
    let angle = common::sensor(&m, &sol.sensors, "hinge")[0];
    assert!((angle - 0.1).abs() < 1e-9, "{angle}");
    let w: Vec<_> = sol
        .report
        .warnings
        .iter()
        .filter(|w| w.starts_with("hinge `h` turned past its lock angle"))
        .collect();
    assert_eq!(w.len(), 1, "{:?}", sol.report.warnings);
    assert!(w[0].contains("statics --path"), "{}", w[0]);
    // a lock the equilibrium does not reach is not warned
    let m = hinged_cantilever(0.5);
    let sol = latdyn::solver::solve_statics(&m).unwrap();
    assert!(
        !sol.report.warnings.iter().any(|w| w.contains("lock angle")),
        "{:?}",
        sol.report.warnings
    );
}

/// A stiff rod hinged at its root, released horizontal under gravity, locking at 1 rad.
fn falling_rod(dt: f64) -> latdyn::model::Model {
    let text = format!(
        r#"[environment]
gravity = [0, 0, -9.81]
[sections.rod]
EA = 1.0e9
EIy = 1.0e4
EIz = 1.0e4
GJ = 1.0e4
rhoA = 1.0
rhoIy = 1e-6
rhoIz = 1e-6
[[nodes]]
name = "root"
position = [0, 0, 0]
[[nodes]]
name = "tip"
position = [1, 0, 0]
[[beams]]
name = "rod"
from = "root"
to = "tip"
elements = 4
section = "rod"
[[joints]]
name = "h"
node = "root"
body = "ground"
type = "hinge"
axis = [0, 1, 0]
lock_angle = 1.0
[[sensors]]
name = "h"
type = "hinge"
joint = "h"
[solver]
t_end = 0.6
dt = {dt}
output_dt = 0.05
rho_inf = 0.9
tol = 1e-10
"#
    );
    latdyn::model::compile_str(&text, "falling_rod.toml", &[]).unwrap_or_else(|e| panic!("{e}"))
}

/// A fixed step carries the hinge past its lock angle (4.6e-3 rad at dt = 1e-3), and the
/// lock turns the hinge back alone, straining the rod by 1.7 J against 4.1 J of motion:
/// energy no lock has, in a sample interval the energy check leaves out, so it went
/// unsaid (a probe, session 46). It is warned naming the hinge and the energy; at
/// dt = 1e-4 the snap adds under 1 % and nothing is said.
#[test]
fn a_lock_snapped_back_from_far_past_its_angle_is_warned_with_the_energy_it_added() {
    let (_, coarse, err) = latdyn::solver::dynamics::run(&falling_rod(1e-3), |_, _| {});
    assert!(err.is_none(), "{err:?}");
    let w = coarse.warnings();
    let snap = w
        .iter()
        .find(|x| x.contains("hinge `h` locked") && x.contains("past its lock angle"))
        .unwrap_or_else(|| panic!("{w:?}"));
    assert!(snap.contains("--accuracy"), "{snap}");
    let (_, fine, err) = latdyn::solver::dynamics::run(&falling_rod(1e-4), |_, _| {});
    assert!(err.is_none(), "{err:?}");
    assert!(
        !fine
            .warnings()
            .iter()
            .any(|x| x.contains("past its lock angle")),
        "{:?}",
        fine.warnings()
    );
}
