//! The integrator's Jacobian pattern comes from `Assembler::pattern` (no element stage):
//! it must be exactly what an evaluation with a sink adds, for every shipped scene.

use latdyn::assembly::{Assembler, Coeffs, PatternSink};
use latdyn::joint::State;

fn entries(mut v: Vec<(usize, usize)>) -> Vec<(usize, usize)> {
    v.sort_unstable();
    v.dedup();
    v
}

#[test]
fn pattern_without_the_element_stage_matches_the_evaluated_one() {
    let root = env!("CARGO_MANIFEST_DIR");
    let mut files: Vec<std::path::PathBuf> = ["models", "tests/models"]
        .iter()
        .flat_map(|d| std::fs::read_dir(format!("{root}/{d}")).unwrap())
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 10, "{files:?}");
    for f in &files {
        let m = latdyn::model::load(f, &[]).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        let asm = Assembler::new(&m);
        // at the initial state and at the state the integrator starts from
        let mut s = State::new(&m);
        for round in 0..2 {
            let mut evaluated = PatternSink::default();
            let mut gen = vec![0.0; m.dofs.len()];
            asm.evaluate(
                &m,
                &s,
                Coeffs::dynamic(1.0, 1.0, 1.0),
                &mut gen,
                Some(&mut evaluated),
            );
            let mut quick = PatternSink::default();
            asm.pattern(&m, &s, &mut quick);
            assert!(!evaluated.entries.is_empty(), "{}", f.display());
            assert_eq!(
                entries(quick.entries),
                entries(evaluated.entries),
                "{} (round {round})",
                f.display()
            );
            latdyn::joint::update_kinematics(&m, &mut s);
        }
    }
}
