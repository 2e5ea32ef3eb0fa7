//! Ensemble throughput (prints, never asserts): variant-steps per second of the
//! flapping-blade campaign for 1, 10, 100 and 1000 variants on 1 and 2 threads, the
//! per-stage time split (element + assembly, factorization, output; summed over variants,
//! as a share of the summed per-variant wall time), the cost per variant relative to a
//! single run on one thread, and the 2-thread speed-up. Run:
//! `cargo bench --bench ensemble` (`-- quick` stops at 100 variants).

use latdyn::ensemble::{self, Campaign};
use latdyn::solver::dynamics::StageTimes;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let counts: &[usize] = if quick {
        &[1, 10, 100]
    } else {
        &[1, 10, 100, 1000]
    };
    println!(
        "| variants | threads | wall [s] | steps | variant-steps/s | speed-up vs 1 thread | \
         cost per variant / single | element+assembly | factorization | output | other |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    // The reference for "cost per variant": each variant run alone (one variant, one
    // thread, no output file), averaged over 16 speeds spread like the campaigns' speeds,
    // so a campaign is compared with the same work done variant by variant.
    let single = {
        let speeds: Vec<f64> = (0..16).map(|i| 1.0 + 8.0 * i as f64 / 16.0).collect();
        let mut total = 0.0;
        for &om in &speeds {
            let c = campaign(&root, vec![vec![("omega".to_string(), om)]], 1, None);
            let p = ensemble::prepare(&c).unwrap();
            let t0 = Instant::now();
            ensemble::run(&c, &p, &AtomicBool::new(false), false, &|_, _| {}).unwrap();
            total += t0.elapsed().as_secs_f64();
        }
        total / speeds.len() as f64
    };
    eprintln!("single variant alone: {:.2} ms", 1e3 * single);
    for &n in counts {
        let mut wall1 = f64::NAN;
        for threads in [1, 2] {
            let variants = (0..n)
                .map(|i| vec![("omega".to_string(), 1.0 + 8.0 * i as f64 / n.max(2) as f64)])
                .collect();
            let out_path = std::env::temp_dir().join(format!("latdyn_bench_{n}_{threads}.h5"));
            let c = campaign(&root, variants, threads, Some(out_path.clone()));
            let p = ensemble::prepare(&c).unwrap();
            let t0 = Instant::now();
            let out = ensemble::run(&c, &p, &AtomicBool::new(false), false, &|_, _| {}).unwrap();
            let wall = t0.elapsed().as_secs_f64();
            let _ = std::fs::remove_file(&out_path);
            let steps: usize = out.iter().map(|o| o.steps).sum();
            let mut times = StageTimes::default();
            let mut busy = 0.0;
            for o in &out {
                times.add(&o.times);
                busy += o.wall_s;
            }
            let per_variant = wall * threads as f64 / n as f64;
            if threads == 1 {
                wall1 = wall;
            }
            let pct = |x: f64| format!("{:.0} %", 100.0 * x / busy);
            let stage = times.element_s + times.assembly_s;
            println!(
                "| {n} | {threads} | {wall:.3} | {steps} | {:.0} | {:.2} | {:.2} | {} | {} | {} | {} |",
                steps as f64 / wall,
                wall1 / wall,
                per_variant / single,
                pct(stage),
                pct(times.factorization_s),
                pct(times.output_s),
                pct(busy - stage - times.factorization_s - times.output_s),
            );
        }
    }
}

fn campaign(
    root: &std::path::Path,
    variants: Vec<Vec<(String, f64)>>,
    threads: usize,
    output: Option<std::path::PathBuf>,
) -> Campaign {
    Campaign {
        model_path: root.join("models/flapping_blade.toml"),
        // dt 5 ms, issue 17's measure (the blade ships at 1 ms since session 23)
        base: vec![("t_end".into(), 0.1), ("dt".into(), 0.005)],
        variants,
        threads,
        batch: latdyn::ensemble::DEFAULT_BATCH,
        output,
        shard: None,
        accuracy: None,
        frequency_sensor: None,
        command_line: "bench".into(),
    }
}
