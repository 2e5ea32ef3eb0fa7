//! Ensemble throughput (prints, never asserts): variant-steps per second of the
//! flapping-blade campaign for 1, 10, 100 and 1000 variants on 1 and 2 threads, and the
//! cost per variant relative to a single run. Run: `cargo bench --bench ensemble`
//! (`-- quick` stops at 100 variants).

use latdyn::ensemble::{self, Campaign};
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
        "| variants | threads | wall [s] | steps | variant-steps/s | cost per variant / single |"
    );
    println!("|---|---|---|---|---|---|");
    let mut single = None;
    for &n in counts {
        for threads in [1, 2] {
            let variants = (0..n)
                .map(|i| vec![("omega".to_string(), 1.0 + 8.0 * i as f64 / n.max(2) as f64)])
                .collect();
            let c = Campaign {
                model_path: root.join("models/flapping_blade.toml"),
                base: vec![("t_end".into(), 0.1)],
                variants,
                threads,
                output: None,
                shard: None,
                frequency_sensor: None,
                command_line: "bench".into(),
            };
            let p = ensemble::prepare(&c).unwrap();
            let t0 = Instant::now();
            let out = ensemble::run(&c, &p, &AtomicBool::new(false), false, &|_, _| {}).unwrap();
            let wall = t0.elapsed().as_secs_f64();
            let steps: usize = out.iter().map(|o| o.steps).sum();
            let per_variant = wall * threads as f64 / n as f64;
            let base = *single.get_or_insert(per_variant);
            println!(
                "| {n} | {threads} | {wall:.3} | {steps} | {:.0} | {:.2} |",
                steps as f64 / wall,
                per_variant / base
            );
        }
    }
}
