//! The batch dimension (src/solver/batch.rs): variants advanced in lockstep with one
//! element-stage call per round give every variant exactly the numbers of its single run,
//! whatever the batch size, including variants that fail, are interrupted, or adapt
//! their steps.

use latdyn::element::{CpuEval, ElemData, ElemIn, ElemOut, ElementEval, EvalError, EvalRequest};
use latdyn::ensemble::{self, Campaign, Outcome, Stage};
use latdyn::output::VariantState;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn campaign(model: &str, variants: Vec<Vec<(String, f64)>>, batch: usize) -> Campaign {
    Campaign {
        model_path: root().join(model),
        base: vec![],
        variants,
        threads: 1,
        batch,
        output: None,
        shard: None,
        accuracy: None,
        frequency_sensor: None,
        command_line: "test".into(),
    }
}

/// The CPU stage, counting its batched calls and the largest request count of one call.
#[derive(Default)]
struct Counting {
    calls: AtomicU64,
    requests: AtomicU64,
    widest: AtomicUsize,
}

impl ElementEval for Counting {
    fn evaluate(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        CpuEval.evaluate(elems, inputs, inertia, out)
    }
    fn evaluate_residual(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        CpuEval.evaluate_residual(elems, inputs, inertia, out)
    }
    fn evaluate_batch(&self, reqs: &mut [EvalRequest<'_>]) -> Result<(), EvalError> {
        self.calls.fetch_add(1, Ordering::Relaxed);
        self.requests
            .fetch_add(reqs.len() as u64, Ordering::Relaxed);
        self.widest.fetch_max(reqs.len(), Ordering::Relaxed);
        CpuEval.evaluate_batch(reqs)
    }
    fn name(&self) -> String {
        "cpu (counting)".into()
    }
}

fn counting_stage(counter: &Arc<Counting>) -> Stage {
    let c = Arc::clone(counter);
    Stage {
        make: Some(Arc::new(move || Arc::clone(&c) as Arc<dyn ElementEval>)),
        ..Stage::cpu()
    }
}

/// Every number a variant reports, bit for bit (NaN equal to NaN), against its single run.
fn assert_same_as_single(c: &Campaign, o: &Outcome, what: &str) {
    let mut sets = c.base.clone();
    sets.extend(c.variants[o.global_index].iter().cloned());
    let mut m = latdyn::model::load(&c.model_path, &sets).unwrap();
    if c.accuracy.is_some() {
        m.solver.accuracy = c.accuracy;
    }
    let (h, stats, err) = latdyn::solver::dynamics::run(&m, |_, _| {});
    let label = format!("{what}, variant {}", o.global_index);
    let eh = o.history.as_ref().expect("histories kept");
    assert_eq!(eh.t, h.t, "{label}: time");
    assert_eq!(eh.values, h.values, "{label}: sensors");
    assert_eq!(o.steps, stats.steps, "{label}: steps");
    assert_eq!(o.rejected_steps, stats.rejected_steps, "{label}: rejected");
    assert_eq!(
        o.newton_iterations, stats.newton_iterations,
        "{label}: Newton iterations"
    );
    assert_eq!(o.warnings, stats.warnings(), "{label}: warnings");
    let bits = |x: Option<f64>| x.map(f64::to_bits);
    assert_eq!(bits(o.energy_growth), bits(stats.energy_growth), "{label}");
    assert_eq!(bits(o.energy_loss), bits(stats.energy_loss), "{label}");
    assert_eq!(
        bits(o.time_error_estimate),
        bits(stats.time_error_estimate),
        "{label}"
    );
    match &err {
        None => assert_eq!(o.state, VariantState::Completed, "{label}: {}", o.message),
        Some(e) => {
            assert_eq!(o.state, VariantState::Failed, "{label}");
            assert_eq!(o.message, e.to_string(), "{label}");
            assert_eq!(o.t_fail.to_bits(), e.time().to_bits(), "{label}");
        }
    }
}

/// Run `c` with each batch size (histories kept), the batched calls counted.
fn run_batched(c: &Campaign, sizes: &[usize]) -> Vec<(usize, Vec<Outcome>, Arc<Counting>)> {
    sizes
        .iter()
        .map(|&b| {
            let c = Campaign {
                batch: b,
                ..c.clone()
            };
            let p = ensemble::prepare(&c).unwrap();
            let counter = Arc::new(Counting::default());
            let out = ensemble::run_on(
                &c,
                &p,
                &AtomicBool::new(false),
                true,
                &|_, _| {},
                &counting_stage(&counter),
            )
            .unwrap();
            (b, out, counter)
        })
        .collect()
}

#[test]
fn every_variant_of_a_batch_is_bit_identical_to_its_single_run_for_batch_sizes_1_3_and_all() {
    let blade: Vec<Vec<(String, f64)>> = (0..10)
        .map(|i| {
            vec![
                ("omega".to_string(), 20.0 + 2.0 * i as f64),
                ("t_end".to_string(), 0.5),
            ]
        })
        .collect();
    // dt up to 0.05: the large steps are warned about (energy), and their warnings too
    // must come out the same
    let spinup: Vec<Vec<(String, f64)>> = [0.005, 0.01, 0.02, 0.03, 0.05, 0.04, 0.015, 0.025]
        .iter()
        .enumerate()
        .map(|(i, dt)| {
            vec![
                ("dt".to_string(), *dt),
                ("ws".to_string(), 4.0 + i as f64),
                ("Ts".to_string(), 1.0),
                ("t_end".to_string(), 2.0),
            ]
        })
        .collect();
    for (model, vs) in [
        ("models/flapping_blade.toml", blade),
        ("models/spinup_beam.toml", spinup),
    ] {
        let c = campaign(model, vs.clone(), 1);
        let n = vs.len();
        for (b, out, counter) in run_batched(&c, &[1, 3, n]) {
            assert_eq!(out.len(), n);
            for (k, o) in out.iter().enumerate() {
                assert_eq!(o.global_index, k, "{model}: output order");
                assert_same_as_single(&c, o, &format!("{model}, batch {b}"));
            }
            // one call per round carries every variant of the batch still running
            let widest = counter.widest.load(Ordering::Relaxed);
            assert_eq!(widest, b.min(n), "{model}, batch {b}: widest call");
            let calls = counter.calls.load(Ordering::Relaxed);
            let requests = counter.requests.load(Ordering::Relaxed);
            eprintln!(
                "{model}, batch {b}: {calls} calls, {:.2} requests per call",
                requests as f64 / calls as f64
            );
        }
    }
}

#[test]
fn a_failing_variant_leaves_its_batch_and_the_others_finish_bit_identical() {
    // growth 60 diverges (the hub's drive runs away); the others complete
    let vs: Vec<Vec<(String, f64)>> = [0.0, 60.0, 0.5, 0.2, 0.8]
        .iter()
        .map(|g| vec![("growth".to_string(), *g)])
        .collect();
    let c = campaign("tests/models/spinning_hub.toml", vs.clone(), 1);
    for (b, out, _) in run_batched(&c, &[1, 3, vs.len()]) {
        assert_eq!(out[1].state, VariantState::Failed, "batch {b}");
        assert_eq!(
            out.iter()
                .filter(|o| o.state == VariantState::Completed)
                .count(),
            4,
            "batch {b}"
        );
        for o in &out {
            assert_same_as_single(&c, o, &format!("spinning hub, batch {b}"));
        }
    }
}

#[test]
fn accuracy_runs_that_resume_from_a_checkpoint_batch_bit_identically() {
    // over 12 s the spin-up's second run resumes the first (steps of 0.04 s, about 300
    // of them) at about 5 s: its result then counts the kept part's steps, so the steps of
    // all runs fall short of the first run's plus the result's
    let vs: Vec<Vec<(String, f64)>> = [5.0, 6.0, 7.0]
        .iter()
        .map(|ws| {
            vec![
                ("ws".to_string(), *ws),
                ("t_end".to_string(), 12.0),
                ("dt".to_string(), 0.04),
            ]
        })
        .collect();
    let c = Campaign {
        accuracy: Some(1e-2),
        ..campaign("models/spinup_beam.toml", vs.clone(), 1)
    };
    for (b, out, _) in run_batched(&c, &[1, vs.len()]) {
        assert!(
            out.iter()
                .any(|o| o.accuracy_runs == 2 && o.accuracy_steps < o.steps + 480),
            "batch {b}: no variant resumed"
        );
        for o in &out {
            assert_same_as_single(&c, o, &format!("resumed, batch {b}"));
        }
    }
}

#[test]
fn accuracy_targets_and_their_runs_batch_bit_identically() {
    // with a 1 % target from 0.04 s the spin-up beam makes more than one run
    let vs: Vec<Vec<(String, f64)>> = [4.0, 5.0, 6.0, 7.0, 8.0]
        .iter()
        .map(|ws| {
            vec![
                ("ws".to_string(), *ws),
                ("Ts".to_string(), 1.0),
                ("t_end".to_string(), 1.0),
                ("dt".to_string(), 0.04),
            ]
        })
        .collect();
    let c = Campaign {
        accuracy: Some(1e-2),
        ..campaign("models/spinup_beam.toml", vs.clone(), 1)
    };
    for (b, out, _) in run_batched(&c, &[1, 3, vs.len()]) {
        assert!(out.iter().any(|o| o.accuracy_runs > 1));
        for o in &out {
            assert_same_as_single(&c, o, &format!("adaptive, batch {b}"));
        }
    }
}

#[test]
fn a_stop_mid_batch_interrupts_the_running_variants_with_their_samples_so_far() {
    let c = campaign(
        "models/flapping_blade.toml",
        (0..6)
            .map(|i| vec![("omega".to_string(), 20.0 + 4.0 * i as f64)])
            .collect(),
        6,
    );
    let p = ensemble::prepare(&c).unwrap();
    let stop = AtomicBool::new(false);
    let counter = Arc::new(Counting::default());
    // stop once the batch has evaluated some rounds: every variant is mid-run
    let finished = AtomicBool::new(false);
    let out = std::thread::scope(|sc| {
        sc.spawn(|| {
            while counter.calls.load(Ordering::Relaxed) < 400 && !finished.load(Ordering::SeqCst) {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
            stop.store(true, Ordering::SeqCst);
        });
        let out = ensemble::run_on(&c, &p, &stop, true, &|_, _| {}, &counting_stage(&counter));
        finished.store(true, Ordering::SeqCst);
        out.unwrap()
    });
    assert_eq!(out.len(), 6);
    for o in &out {
        assert_eq!(o.state, VariantState::Interrupted, "{}", o.message);
        let h = o.history.as_ref().unwrap();
        assert!(h.t.len() > 1, "{:?}", h.t);
        // what it sampled before the stop is what its single run samples
        let mut m = latdyn::model::load(&c.model_path, &c.variants[o.global_index]).unwrap();
        m.solver.t_end = h.t[h.t.len() - 1];
        let (single, _, err) = latdyn::solver::dynamics::run(&m, |_, _| {});
        assert!(err.is_none());
        assert_eq!(single.t, h.t);
        assert_eq!(single.values, h.values);
    }
}
