//! Spin-up beam (references.md §7): bounded tip deflection, converging under step and
//! mesh refinement (self-convergence: the reference is the finest latdyn solution).

mod common;
use common::*;
use latdyn::solver::dynamics::run;

/// Peak |tip deflection| over the run and its time.
fn peak(sets: &[(&str, f64)]) -> (f64, f64) {
    let m = shipped("spinup_beam.toml", sets);
    let (h, _, err) = run(&m, |_, _| {});
    assert!(err.is_none(), "{sets:?}: {err:?}");
    let k = m.sensor_index("tip_deflection").unwrap();
    h.values[k]
        .iter()
        .zip(&h.t)
        .map(|(v, t)| (v[0].abs(), *t))
        .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a })
}

#[test]
fn spinup_tip_deflection_stays_bounded_and_converges_with_step_and_mesh() {
    // time step, 10 elements
    let dts = [0.02, 0.01, 0.005];
    let p_dt: Vec<(f64, f64)> = dts.iter().map(|dt| peak(&[("dt", *dt)])).collect();
    for (dt, (p, t)) in dts.iter().zip(&p_dt) {
        eprintln!(
            "spin-up, 10 elements, dt = {dt}: peak |tip deflection| {p:.5} m at t = {t:.2} s"
        );
        // bounded: a linear assumed-mode model diverges; published peaks are ~0.5-0.6 m
        assert!(*p > 0.3 && *p < 1.0, "peak {p}");
    }
    let e1 = (p_dt[0].0 - p_dt[2].0).abs();
    let e2 = (p_dt[1].0 - p_dt[2].0).abs();
    eprintln!(
        "step self-convergence: |Δpeak| {e1:.2e} (dt 0.02), {e2:.2e} (dt 0.01) against dt 0.005"
    );
    // second order in dt: against the finest run, halving the step should cut the
    // difference by ~5 (4 for the error itself, plus the finest run's own error)
    assert!(e1 > 2.5 * e2, "step convergence too slow: {e1:e} vs {e2:e}");

    // mesh, dt = 0.01
    let meshes = [4.0, 8.0, 16.0];
    let p_el: Vec<f64> = meshes
        .iter()
        .map(|n| peak(&[("dt", 0.01), ("elements", *n)]).0)
        .collect();
    for (n, p) in meshes.iter().zip(&p_el) {
        eprintln!("spin-up, dt = 0.01, {n} elements: peak |tip deflection| {p:.5} m");
    }
    let m1 = (p_el[0] - p_el[2]).abs();
    let m2 = (p_el[1] - p_el[2]).abs();
    eprintln!("mesh self-convergence: |Δpeak| {m1:.2e} (4 el), {m2:.2e} (8 el) against 16");
    assert!(m1 > 2.5 * m2, "mesh convergence too slow: {m1:e} vs {m2:e}");
}

#[test]
fn modified_newton_converges_to_the_full_newton_solution() {
    // Both policies solve the same residual to the same tolerance (1e-8 of the force
    // scale), so the histories may differ only by that: measured 3.5e-10 relative on the
    // tip deflection over the first 4 s (2 elements, dt = 0.02, strong spin-up). Bound
    // 1e-6, the tolerance amplified over 200 steps with margin; iteration counts reported.
    let sets = [("elements", 2.0), ("dt", 0.02), ("t_end", 4.0)];
    let mut hist = Vec::new();
    for modified in [false, true] {
        let mut m = shipped("spinup_beam.toml", &sets);
        m.solver.modified_newton = modified;
        let (h, stats, err) = run(&m, |_, _| {});
        assert!(err.is_none(), "modified={modified}: {err:?}");
        let k = m.sensor_index("tip_deflection").unwrap();
        eprintln!(
            "modified={modified}: {} steps, {} Newton iterations, {} rejected, element+assembly {:.3} s, factorization {:.3} s",
            stats.steps,
            stats.newton_iterations,
            stats.rejected_steps,
            stats.times.element_s + stats.times.assembly_s,
            stats.times.factorization_s
        );
        hist.push(h.values[k].iter().map(|v| v[0]).collect::<Vec<f64>>());
    }
    let scale = hist[0].iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let diff = hist[0]
        .iter()
        .zip(&hist[1])
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    eprintln!("max difference {:.2e} of peak {scale:.4}", diff / scale);
    assert!(scale > 0.1 && diff / scale < 1e-6, "{diff} of {scale}");
}

#[test]
fn an_unstable_run_is_flagged_by_its_energy_balance_and_a_stable_one_is_not() {
    // Generalized-α with ρ∞ ≤ 1 only dissipates, so kinetic + strain − driver work must
    // not grow. With ρ∞ = 1 (no high-frequency dissipation), 3 elements and dt = 1/60 s
    // the spin-up's balance grows and its time-error estimate reads the cap; ρ∞ = 0.6 at
    // dt = 0.01 s shows no growth at all (0 measured) and loses 0.2 %. Limits 1e-3
    // (RunStats::ENERGY_GROWTH_LIMIT) and 1e-2 (ENERGY_LOSS_LIMIT: ρ∞ = 0.6 at dt = 0.05 s
    // loses 4 %, flagged, rightly). How much it grows depends on the rounding: the unstable
    // run amplifies round-off (builds that round a·b + c once or twice agree to 3e-9 until
    // t = 10 s and part by t = 14 s): it ends 1.07 % up with two roundings (0.80 % at
    // dt = 0.025) and 0.30 % up with session 24's fused multiply-adds (0.48 % with a first
    // choice of them). Its size is chaos; that it grows is not, so the bound is the flag's
    // own limit.
    let run_with = |rho: f64, dt: f64| {
        let sets = [("elements", 3.0), ("dt", dt), ("rho_inf", rho)];
        let m = shipped("spinup_beam.toml", &sets);
        let (_, stats, err) = run(&m, |_, _| {});
        assert!(err.is_none(), "{err:?}");
        stats
    };
    let bad = run_with(1.0, 1.0 / 60.0);
    let good = run_with(0.6, 0.01);
    eprintln!(
        "energy growth: ρ∞ 1 {:?}, ρ∞ 0.6 {:?}",
        bad.energy_growth, good.energy_growth
    );
    assert!(
        bad.energy_growth.unwrap() > latdyn::solver::dynamics::RunStats::ENERGY_GROWTH_LIMIT,
        "{:?}",
        bad.energy_growth
    );
    assert!(bad.warnings()[0].contains("unstable"));
    assert!(
        good.energy_growth.unwrap() < 1e-6,
        "{:?}",
        good.energy_growth
    );
    assert!(good.warnings().is_empty());
}

#[test]
fn a_step_that_does_not_divide_the_output_interval_keeps_the_spin_up_stable() {
    // ρ∞ = 0.9, 3 elements, dt = 0.04 s against the 0.05 s output interval. Until session
    // 17 each interval was a step of 0.04 and one of 0.01: that step-size alternation made
    // the run unstable (peak 2.18 m instead of 0.574 m, energy +39 %), and this suite took
    // it for a hard case of the integrator. Spread evenly (two steps of 0.025 s) it is
    // stable: peak 0.576 m, no growth (measured). Bound: the peak within 1 % of the
    // dt = 0.005 run's, which is what a coarse step's error allows here.
    let peak_and_stats = |dt: f64| {
        let sets = [("elements", 3.0), ("dt", dt), ("rho_inf", 0.9)];
        let m = shipped("spinup_beam.toml", &sets);
        let (h, stats, err) = run(&m, |_, _| {});
        assert!(err.is_none(), "{err:?}");
        let k = m.sensor_index("tip_deflection").unwrap();
        let peak = h.values[k].iter().fold(0.0f64, |a, v| a.max(v[0].abs()));
        (peak, stats)
    };
    let (coarse, stats) = peak_and_stats(0.04);
    let (fine, _) = peak_and_stats(0.005);
    eprintln!(
        "peak {coarse:.4} m against {fine:.4} m; growth {:?}",
        stats.energy_growth
    );
    assert!((coarse - fine).abs() < 1e-2 * fine, "{coarse} vs {fine}");
    // The alternation's instability grew the energy by 39 %. At this step Newton starts
    // 1.4 force scales off after the spin-up and some steps are cut (a diverging
    // iterate's refreshed tangent is singular): 4 to 7 cuts, which ones depending on
    // round-off (the LU's unit scaling moved them), and with them 0 or 0.37 % growth,
    // warned. The bound is 39 times below the alternation's growth and 2.7 times above
    // the cut steps' 0.37 %.
    assert!(
        stats.energy_growth.unwrap() < 1e-2,
        "{:?}",
        stats.energy_growth
    );
}
