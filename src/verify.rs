//! `sweep --verify K`: a measured discretisation error for a campaign.
//!
//! After the campaign, K of its variants (spread evenly over its index range, see
//! [`select`]) run again with the discretisation refined by [`REFINE`]: every beam
//! meshed with twice its elements and the time step halved (`dt`, `dt_min`, `dt_max`),
//! on the same output grid and reading the same material points
//! ([`crate::model::compile_str_refined`]). For every sensor component the change of its
//! extremes (min and max over the run) is measured relative to the component's range
//! over the base run ([`rel_diff`]); a change above the target (the campaign's
//! accuracy target, [`DEFAULT_TARGET`] if it has none) is a warning naming the sensor
//! and the variant.
//!
//! The refined runs are separate models run after the campaign: the campaign's own
//! numbers are untouched (still bit-identical to running each variant alone).

use std::time::Instant;

use rayon::prelude::*;

use crate::ensemble::{Campaign, Outcome, SensorSummary, Stage};
use crate::model::{self, Model};
use crate::output::{VariantState, VerificationData, VerificationSensor};
use crate::sensors;
use crate::solver::dynamics::{self, DynamicsError};

/// Refinement factor of the verification runs: 2× the elements, dt / 2.
pub const REFINE: usize = 2;

/// Target used when the campaign sets none (`--accuracy`, `[solver] accuracy`): 1 % of
/// a sensor's range, the digits a user reads in a table.
pub const DEFAULT_TARGET: f64 = 1e-2;

/// Below this fraction of the largest magnitude among a sensor's components of the
/// same unit, a component's range counts as "at rest": its difference is measured
/// against this floor (a planar model's out-of-plane displacement moves by round-off
/// only; its range must not turn round-off into a 100 % "error").
pub const REST_FRACTION: f64 = 1e-6;

/// The `k` variants to verify among `candidates` (global indices in campaign order):
/// evenly spread, the first and the last included when `k` ≥ 2, the middle one when
/// `k` = 1. Deterministic; an error unless 1 ≤ `k` ≤ `candidates.len()`.
pub fn select(candidates: &[usize], k: usize) -> Result<Vec<usize>, String> {
    let n = candidates.len();
    check_count(k, n, &format!("there are {n} to choose from"))?;
    if k == 1 {
        return Ok(vec![candidates[(n - 1) / 2]]);
    }
    // spacing (n − 1)/(k − 1) ≥ 1: the rounded positions are distinct
    Ok((0..k)
        .map(|j| {
            let pos = (j * (n - 1) + (k - 1) / 2) / (k - 1);
            candidates[pos]
        })
        .collect())
}

/// The bound of `--verify K`: 1 ≤ K ≤ `n`, the variants it may choose from (`note`
/// says which, e.g. "the campaign has 5 variants").
pub fn check_count(k: usize, n: usize, note: &str) -> Result<(), String> {
    if k == 0 || k > n {
        return Err(format!(
            "--verify {k}: need from 1 to {n} variants to verify ({note})"
        ));
    }
    Ok(())
}

/// The relative change of each component's extremes from `base` to `refined`:
/// max(|max_r − max_b|, |min_r − min_b|) / scale, where scale is the component's range
/// over the base run (max_b − min_b), but at least [`REST_FRACTION`] × the largest
/// magnitude of the sensor's components with the same unit (`units`), in both runs. 0
/// where both runs are the same; infinite where a value is not finite.
///
/// With `shared`, the scale is also at least the largest base range among the sensor's
/// components with that unit: an energy sensor's terms are one account, and a conserved
/// total (its range the scheme's drift, 1e-6 of the pendulum's energy) is measured
/// against the energy exchanged, not against that drift (which halves under refinement
/// and read as a 75 % "not converged").
pub fn rel_diff(
    base: &SensorSummary,
    refined: &SensorSummary,
    units: &[&str],
    shared: bool,
    model_magnitudes: &[(&str, f64)],
) -> Vec<f64> {
    let scales = rel_scales(base, refined, units, shared, model_magnitudes);
    (0..base.min.len())
        .map(|c| {
            let vals = [base.min[c], base.max[c], refined.min[c], refined.max[c]];
            if vals.iter().any(|x| !x.is_finite()) {
                return f64::INFINITY;
            }
            let diff = (refined.max[c] - base.max[c])
                .abs()
                .max((refined.min[c] - base.min[c]).abs());
            relative(diff, scales[c])
        })
        .collect()
}

/// `diff` over `scale`: 0 where `diff` is 0, infinite where it is not finite or the
/// scale is 0.
fn relative(diff: f64, scale: f64) -> f64 {
    if diff == 0.0 {
        0.0
    } else if diff.is_finite() && scale > 0.0 {
        diff / scale
    } else {
        f64::INFINITY
    }
}

/// The scale [`rel_diff`] divides each component's change by (see there).
fn rel_scales(
    base: &SensorSummary,
    refined: &SensorSummary,
    units: &[&str],
    shared: bool,
    model_magnitudes: &[(&str, f64)],
) -> Vec<f64> {
    let nc = base.min.len();
    let mag: Vec<f64> = (0..nc)
        .map(|c| {
            [base.min[c], base.max[c], refined.min[c], refined.max[c]]
                .iter()
                .filter(|x| x.is_finite())
                .fold(0.0f64, |a, x| a.max(x.abs()))
        })
        .collect();
    (0..nc)
        .map(|c| {
            // over the components with this one's unit: the largest magnitude, and the
            // largest base range
            let (same_unit, shared_range) = (0..nc)
                .filter(|&o| units.get(o) == units.get(c))
                .fold((0.0f64, 0.0f64), |(m, r), o| {
                    (m.max(mag[o]), r.max(base.max[o] - base.min[o]))
                });
            // and over every sensor of the model in this unit (`model_magnitudes`): a
            // parallelogram coupler's rz, round-off about 0 in its own sensor whose other
            // angles are 0 too, read 175 % beside hinge angles of 0.5 rad (a probe,
            // session 46)
            let same_unit = model_magnitudes
                .iter()
                .filter(|(u, _)| Some(u) == units.get(c))
                .fold(same_unit, |m, (_, x)| m.max(*x));
            let shared_range = if shared { shared_range } else { 0.0 };
            (base.max[c] - base.min[c])
                .max(REST_FRACTION * same_unit)
                .max(shared_range)
        })
        .collect()
}

/// The largest magnitude in each unit over the model's sensors (energies aside) in the
/// base and the refined run's extremes: the floor of [`rel_diff`]'s scale.
fn unit_magnitudes(
    m: &Model,
    base: &[SensorSummary],
    refined: &[SensorSummary],
) -> Vec<(&'static str, f64)> {
    let mut magnitudes: Vec<(&'static str, f64)> = Vec::new();
    for (s, (b, x)) in m.sensors.iter().zip(base.iter().zip(refined)) {
        if matches!(s.kind, crate::model::SensorKind::Energy) {
            continue;
        }
        for (c, u) in sensors::units(&s.kind).into_iter().enumerate() {
            let mag = [b.min[c], b.max[c], x.min[c], x.max[c]]
                .iter()
                .filter(|v| v.is_finite())
                .fold(0.0f64, |a, v| a.max(v.abs()));
            match magnitudes.iter_mut().find(|(w, _)| *w == u) {
                Some((_, top)) => *top = top.max(mag),
                None => magnitudes.push((u, mag)),
            }
        }
    }
    magnitudes
}

/// One verified (or not) variant.
#[derive(Clone, Debug)]
pub struct VariantCheck {
    pub global_index: usize,
    pub parameters: Vec<(String, f64)>,
    /// the refined run completed and was compared
    pub verified: bool,
    /// "verified", or why not
    pub status: String,
    /// wall time of the refined run
    pub wall_s: f64,
    /// dt of the base and the refined run (NaN where not compiled)
    pub dt: [f64; 2],
    /// elements of the base and the refined mesh
    pub elements: [usize; 2],
    /// per sensor, per component (NaN where not verified)
    pub rel_diff: Vec<Vec<f64>>,
    /// extremes of the refined run (NaN where not verified)
    pub refined: Vec<SensorSummary>,
}

/// What `--verify` measured.
#[derive(Clone, Debug)]
pub struct Verification {
    pub target: f64,
    /// "--accuracy", "[solver] accuracy" or "default"
    pub target_source: String,
    /// sensor names with their component names and units
    pub sensors: Vec<(String, Vec<String>)>,
    pub variants: Vec<VariantCheck>,
    pub warnings: Vec<String>,
    /// wall time of the whole verification (its runs in parallel)
    pub wall_s: f64,
}

/// The target of a campaign and where it comes from.
pub fn target(c: &Campaign, base: Option<&Model>) -> (f64, &'static str) {
    match (c.accuracy, base.and_then(|m| m.solver.accuracy)) {
        (Some(a), _) => (a, "--accuracy"),
        (None, Some(a)) => (a, "[solver] accuracy"),
        (None, None) => (DEFAULT_TARGET, "default"),
    }
}

/// Run the refined variants `chosen` (global indices, each in `models`/`outcomes` at
/// the same position as in `global_index`) on the caller's pool and compare them with
/// the campaign's outcomes. `stop` ends the refined runs early (they are then reported
/// "interrupted", not verified).
#[allow(clippy::too_many_arguments)]
pub fn run(
    c: &Campaign,
    models: &[Model],
    global_index: &[usize],
    outcomes: &[Outcome],
    chosen: &[usize],
    stop: &std::sync::atomic::AtomicBool,
    stage: &Stage,
) -> Verification {
    let t0 = Instant::now();
    let first = models.first();
    let (target, source) = target(c, first);
    let sensors: Vec<(String, Vec<String>)> = first
        .map(|m| {
            m.sensors
                .iter()
                .map(|s| {
                    (
                        s.name.clone(),
                        sensors::components(&s.kind)
                            .iter()
                            .map(|x| x.to_string())
                            .collect(),
                    )
                })
                .collect()
        })
        .unwrap_or_default();
    let variants: Vec<VariantCheck> = chosen
        .par_iter()
        .map(|&gi| {
            let pos = global_index.iter().position(|&g| g == gi);
            check_one(c, pos.map(|p| (&models[p], &outcomes[p])), gi, stop, stage)
        })
        .collect();
    let mut warnings = Vec::new();
    let stopped = variants
        .iter()
        .filter(|v| v.status == "interrupted")
        .count();
    if stopped > 0 {
        warnings.push(format!(
            "{stopped} of the {} chosen variants not verified: a signal stopped their refined \
             runs; the measured error covers the other {} only",
            variants.len(),
            variants.len() - stopped
        ));
    }
    for v in &variants {
        if !v.verified {
            if v.status != "interrupted" {
                warnings.push(format!(
                    "variant {} ({}): not verified: {}",
                    v.global_index,
                    describe(&v.parameters),
                    v.status
                ));
            }
            continue;
        }
        for ((name, comps), rel) in sensors.iter().zip(&v.rel_diff) {
            let (c_worst, worst) = rel
                .iter()
                .copied()
                .enumerate()
                .fold((0, 0.0f64), |a, (i, x)| if x > a.1 { (i, x) } else { a });
            if worst > target {
                warnings.push(format!(
                    "variant {} ({}): sensor `{name}`: its extremes changed by {} of the \
                     range ({name}.{}) under refinement (dt {} → {}, {} → {} elements), above \
                     the target {}: its figures are not converged to the target; reduce dt \
                     or add elements",
                    v.global_index,
                    describe(&v.parameters),
                    percent(worst),
                    comps.get(c_worst).map_or("", String::as_str),
                    v.dt[0],
                    v.dt[1],
                    v.elements[0],
                    v.elements[1],
                    percent(target)
                ));
            }
        }
    }
    Verification {
        target,
        target_source: source.to_string(),
        sensors,
        variants,
        warnings,
        wall_s: t0.elapsed().as_secs_f64(),
    }
}

fn check_one(
    c: &Campaign,
    base: Option<(&Model, &Outcome)>,
    gi: usize,
    stop: &std::sync::atomic::AtomicBool,
    stage: &Stage,
) -> VariantCheck {
    let parameters = c.variants.get(gi).cloned().unwrap_or_default();
    let mut out = VariantCheck {
        global_index: gi,
        parameters,
        verified: false,
        status: String::new(),
        wall_s: 0.0,
        dt: [f64::NAN; 2],
        elements: [0; 2],
        rel_diff: Vec::new(),
        refined: Vec::new(),
    };
    let nan_like = |m: &Model| -> (Vec<Vec<f64>>, Vec<SensorSummary>) {
        let s: Vec<SensorSummary> = m
            .sensors
            .iter()
            .map(|s| {
                let nc = sensors::components(&s.kind).len();
                SensorSummary {
                    min: vec![f64::NAN; nc],
                    max: vec![f64::NAN; nc],
                    last: vec![f64::NAN; nc],
                }
            })
            .collect();
        (s.iter().map(|x| x.min.clone()).collect(), s)
    };
    let Some((m, o)) = base else {
        out.status = "not in this shard".into();
        return out;
    };
    out.dt[0] = m.solver.dt;
    out.elements[0] = m.elements.len();
    (out.rel_diff, out.refined) = nan_like(m);
    if o.state != VariantState::Completed {
        out.status = format!("its campaign run did not complete ({})", o.state.label());
        return out;
    }
    if stop.load(std::sync::atomic::Ordering::SeqCst) {
        out.status = "interrupted".into();
        return out;
    }
    let mut sets = c.base.clone();
    sets.extend(out.parameters.iter().cloned());
    let mut r = match model::load_refined(&c.model_path, &sets, REFINE) {
        Ok(r) => r,
        Err(e) => {
            out.status = format!("the refined model does not compile: {e}");
            return out;
        }
    };
    if c.accuracy.is_some() {
        r.solver.accuracy = c.accuracy;
    }
    out.dt[1] = r.solver.dt;
    out.elements[1] = r.elements.len();
    let layout = |m: &Model| -> Vec<(String, usize)> {
        m.sensors
            .iter()
            .map(|s| (s.name.clone(), sensors::components(&s.kind).len()))
            .collect()
    };
    if layout(&r) != layout(m) || dynamics::output_times(&r) != dynamics::output_times(m) {
        out.status = "the refined model reports other sensors or output times".into();
        return out;
    }
    let t0 = Instant::now();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let ctx = stage.run_context(stop);
        dynamics::run_in(&r, &ctx, |_, _| {})
    }));
    out.wall_s = t0.elapsed().as_secs_f64();
    let (hist, _stats, err) = match result {
        Ok(x) => x,
        Err(_) => {
            out.status = "the refined run panicked (a bug in latdyn; please report it)".into();
            return out;
        }
    };
    match err {
        Some(DynamicsError::Interrupted { .. }) => {
            out.status = "interrupted".into();
            return out;
        }
        Some(e) => {
            out.status = format!("the refined run failed: {e}");
            return out;
        }
        None => {}
    }
    let refined = crate::ensemble::summarize(&r, &hist);
    let magnitudes = unit_magnitudes(m, &o.sensors, &refined);
    out.rel_diff = m
        .sensors
        .iter()
        .zip(o.sensors.iter().zip(&refined))
        .map(|(s, (b, x))| {
            let energy = matches!(s.kind, crate::model::SensorKind::Energy);
            rel_diff(b, x, &sensors::units(&s.kind), energy, &magnitudes)
        })
        .collect();
    out.refined = refined;
    out.verified = true;
    out.status = "verified".into();
    out
}

impl Verification {
    /// Largest relative difference over the verified variants and sensors (NaN if none).
    pub fn max_rel_diff(&self) -> f64 {
        self.worst().map_or(f64::NAN, |(_, _, _, x)| x)
    }

    /// (variant position, sensor, component, value) of the largest difference.
    pub fn worst(&self) -> Option<(usize, usize, usize, f64)> {
        let mut best: Option<(usize, usize, usize, f64)> = None;
        for (vi, v) in self.variants.iter().enumerate().filter(|(_, v)| v.verified) {
            for (si, rel) in v.rel_diff.iter().enumerate() {
                for (ci, &x) in rel.iter().enumerate() {
                    if best.is_none_or(|b| x > b.3) {
                        best = Some((vi, si, ci, x));
                    }
                }
            }
        }
        best
    }

    /// Per sensor: the largest difference over the verified variants, per component.
    fn per_sensor(&self, s: usize) -> Vec<f64> {
        let nc = self.sensors[s].1.len();
        (0..nc)
            .map(|c| {
                self.variants
                    .iter()
                    .filter(|v| v.verified)
                    .map(|v| v.rel_diff[s][c])
                    .fold(f64::NAN, f64::max)
            })
            .collect()
    }

    /// One line for stderr.
    pub fn summary(&self) -> String {
        let n_ok = self.variants.iter().filter(|v| v.verified).count();
        let idx: Vec<String> = self
            .variants
            .iter()
            .map(|v| v.global_index.to_string())
            .collect();
        let target = format!("target {} ({})", percent(self.target), self.target_source);
        let worst = match self.worst() {
            Some((vi, si, ci, x)) => format!(
                "largest change of a sensor extreme {} of its range ({}.{}, variant {}); {target}{}",
                percent(x),
                self.sensors[si].0,
                self.sensors[si].1[ci],
                self.variants[vi].global_index,
                if x > self.target { ", EXCEEDED" } else { "" }
            ),
            None => format!("no variant verified; {target}"),
        };
        format!(
            "verify: {n_ok} of {} variant(s) ({}) rerun with dt/{REFINE} and {REFINE}× elements \
             in {:.2} s: {worst}",
            self.variants.len(),
            idx.join(", "),
            self.wall_s
        )
    }

    /// The `verification` object of `sweep --json`.
    pub fn to_json(&self) -> serde_json::Value {
        use serde_json::json;
        let num = |x: f64| if x.is_nan() { json!(null) } else { json!(x) };
        let per_sensor: serde_json::Map<String, serde_json::Value> = self
            .sensors
            .iter()
            .enumerate()
            .map(|(s, (name, comps))| {
                let pc = self.per_sensor(s);
                let worst = pc.iter().copied().fold(f64::NAN, f64::max);
                let per_component: serde_json::Map<String, serde_json::Value> = comps
                    .iter()
                    .zip(&pc)
                    .map(|(c, &x)| (c.clone(), num(x)))
                    .collect();
                (
                    name.clone(),
                    json!({"max_rel_diff": num(worst), "per_component": per_component}),
                )
            })
            .collect();
        let variants: Vec<serde_json::Value> = self
            .variants
            .iter()
            .map(|v| {
                let sensors: serde_json::Map<String, serde_json::Value> = self
                    .sensors
                    .iter()
                    .zip(v.rel_diff.iter().zip(&v.refined))
                    .map(|((name, _), (rel, r))| {
                        let rel: Vec<serde_json::Value> = rel.iter().map(|&x| num(x)).collect();
                        let mn: Vec<serde_json::Value> = r.min.iter().map(|&x| num(x)).collect();
                        let mx: Vec<serde_json::Value> = r.max.iter().map(|&x| num(x)).collect();
                        (
                            name.clone(),
                            json!({"rel_diff": rel, "refined_min": mn, "refined_max": mx}),
                        )
                    })
                    .collect();
                json!({
                    "index": v.global_index,
                    "status": v.status,
                    "wall_s": v.wall_s,
                    "dt": [num(v.dt[0]), num(v.dt[1])],
                    "elements": v.elements,
                    "sensors": sensors,
                })
            })
            .collect();
        json!({
            "target": self.target,
            "target_source": self.target_source,
            "refinement": {"dt_divided_by": REFINE, "elements_times": REFINE},
            "variants": self.variants.iter().map(|v| v.global_index).collect::<Vec<_>>(),
            "max_rel_diff": num(self.max_rel_diff()),
            "per_sensor": per_sensor,
            "per_variant": variants,
            "warnings": self.warnings,
            "wall_s": self.wall_s,
        })
    }

    /// The `/verification` group of the campaign file.
    pub fn data(&self) -> VerificationData {
        let sensors = self
            .sensors
            .iter()
            .enumerate()
            .map(|(s, (name, comps))| {
                let nc = comps.len();
                // [K, C]; NaN rows where a variant has no figures
                let flat = |get: &dyn Fn(&VariantCheck) -> Option<&Vec<f64>>| -> Vec<f64> {
                    self.variants
                        .iter()
                        .flat_map(|v| match get(v) {
                            Some(x) if x.len() == nc => x.clone(),
                            _ => vec![f64::NAN; nc],
                        })
                        .collect()
                };
                VerificationSensor {
                    name: name.clone(),
                    components: comps.clone(),
                    rel_diff: flat(&|v| v.rel_diff.get(s)),
                    refined_min: flat(&|v| v.refined.get(s).map(|x| &x.min)),
                    refined_max: flat(&|v| v.refined.get(s).map(|x| &x.max)),
                }
            })
            .collect();
        VerificationData {
            target: self.target,
            target_source: self.target_source.clone(),
            variants: self.variants.iter().map(|v| v.global_index).collect(),
            status: self.variants.iter().map(|v| v.status.clone()).collect(),
            wall_s: self.variants.iter().map(|v| v.wall_s).collect(),
            dt: self.variants.iter().map(|v| v.dt).collect(),
            elements: self.variants.iter().map(|v| v.elements).collect(),
            max_rel_diff: self.max_rel_diff(),
            warnings: self.warnings.clone(),
            sensors,
        }
    }
}

fn describe(p: &[(String, f64)]) -> String {
    if p.is_empty() {
        return "no parameters varied".into();
    }
    p.iter()
        .map(|(n, v)| format!("{n}={v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A fraction as a percentage (0.0123 → "1.23 %", 2.1e-5 → "2.10e-3 %").
fn percent(x: f64) -> String {
    let p = 100.0 * x;
    if !p.is_finite() || p == 0.0 || p >= 0.1 {
        format!("{p:.2} %")
    } else {
        format!("{p:.2e} %")
    }
}

/// What the mesh twin of a run ([`run_twin`], [`compare_twin`]) measured: the run's histories against
/// the same run on every beam meshed with [`crate::solver::MESH_REFINE`] times its
/// elements at the same step.
#[derive(Clone, Debug)]
pub struct RunMeshError {
    /// largest of `by_sensor`
    pub estimate: f64,
    /// per sensor (model order): the largest estimate over its components
    pub by_sensor: Vec<f64>,
    /// `sensor.component` carrying `estimate`
    pub worst: String,
    /// elements of the model's beams in the base and the refined mesh
    pub elements: (usize, usize),
    /// the twin's step, steps and wall time
    pub dt: f64,
    pub steps: usize,
    pub wall_s: f64,
    /// `sweep --frequency`: the first bending frequency's mesh error (see
    /// [`frequency_mesh_error`]); None where not asked for or not measurable
    pub first_bending: Option<f64>,
}

/// Why a run's mesh error was not measured.
#[derive(Clone, Debug)]
pub enum MeshTwinSkip {
    /// a signal stopped the twin
    Interrupted,
    /// the twin could not be built or run (the reason, for a warning)
    Failed(String),
}

/// The model of a run's mesh twin: `path` with `sets`, every beam meshed with
/// [`crate::solver::MESH_REFINE`] times its elements, stepped as `base` was (fixed step
/// `dt`: the model's, or the step an accuracy target chose) on `base`'s output grid, so
/// that the two differ by the mesh only.
pub fn mesh_twin_model(
    path: &std::path::Path,
    sets: &[(String, f64)],
    base: &Model,
    dt: f64,
) -> Result<Model, String> {
    let mut r = model::load_refined(path, sets, crate::solver::MESH_REFINE)
        .map_err(|e| format!("the model on twice the elements does not compile: {e}"))?;
    let s = &base.solver;
    r.solver.accuracy = None;
    r.solver.dt = dt;
    r.solver.dt_min = s.dt_min.min(dt);
    r.solver.dt_max = s.dt_max.max(dt);
    // the base grid: every step of a fixed-step base run is its own dt
    r.solver.output_dt = if s.output_dt > 0.0 { s.output_dt } else { s.dt };
    if dynamics::output_times(&r) != dynamics::output_times(base) {
        return Err("the model on twice the elements reports at other times".into());
    }
    let layout = |m: &Model| -> Vec<(String, usize)> {
        m.sensors
            .iter()
            .map(|s| (s.name.clone(), sensors::components(&s.kind).len()))
            .collect()
    };
    if layout(&r) != layout(base) {
        return Err("the model on twice the elements reports other sensors".into());
    }
    Ok(r)
}

/// A mesh twin's run ([`run_twin`]): its samples, steps and wall time.
pub struct TwinRun {
    pub hist: dynamics::History,
    pub steps: usize,
    pub wall_s: f64,
}

/// Runs the mesh twin `twin` ([`mesh_twin_model`]); a panic, a failure or a stop is the
/// reason it gave nothing.
pub fn run_twin(twin: &Model, ctx: &dynamics::RunContext<'_>) -> Result<TwinRun, MeshTwinSkip> {
    let t0 = Instant::now();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        dynamics::run_in(twin, ctx, |_, _| {})
    }));
    let wall_s = t0.elapsed().as_secs_f64();
    let (hist, stats, err) = result.map_err(|_| {
        MeshTwinSkip::Failed("the run on twice the elements panicked (a bug in latdyn)".into())
    })?;
    match err {
        Some(DynamicsError::Interrupted { .. }) => Err(MeshTwinSkip::Interrupted),
        Some(e) => Err(MeshTwinSkip::Failed(format!(
            "the run on twice the elements failed: {e}"
        ))),
        None => Ok(TwinRun {
            hist,
            steps: stats.steps,
            wall_s,
        }),
    }
}

/// The mesh error of a completed run of `base` (samples `hist`) from its twin's run
/// ([`history_mesh_error`]).
pub fn compare_twin(
    base: &Model,
    hist: &dynamics::History,
    twin: &Model,
    run: &TwinRun,
) -> Result<RunMeshError, MeshTwinSkip> {
    if run.hist.t.len() != hist.t.len() {
        return Err(MeshTwinSkip::Failed(
            "the run on twice the elements gave another number of samples".into(),
        ));
    }
    let (by_sensor, worst) = history_mesh_error(base, hist, &run.hist);
    let estimate = by_sensor.iter().copied().fold(0.0, f64::max);
    Ok(RunMeshError {
        estimate,
        by_sensor,
        worst,
        elements: (base.elements.len(), twin.elements.len()),
        dt: twin.solver.dt,
        steps: run.steps,
        wall_s: run.wall_s,
        first_bending: None,
    })
}

impl RunMeshError {
    /// The warning of a first bending frequency (`sweep --frequency`) whose mesh error
    /// passes [`crate::solver::MESH_ERROR_WARN`].
    pub fn frequency_warning(&self) -> Option<String> {
        let e = self.first_bending?;
        (e > crate::solver::MESH_ERROR_WARN).then(|| {
            format!(
                "first_bending_hz: mesh too coarse: the frequency is estimated {:.2} % off \
                 the converged mesh (its change from {} to {} elements, Richardson); add \
                 elements",
                100.0 * e,
                self.elements.0,
                self.elements.1
            )
        })
    }

    /// The warning a run or a variant carries when its mesh error passes
    /// [`crate::solver::MESH_ERROR_WARN`]: the worst sensor component, and how many
    /// other sensors pass it too.
    pub fn warning(&self) -> Option<String> {
        let limit = crate::solver::MESH_ERROR_WARN;
        if self.estimate <= limit {
            return None;
        }
        let others = match self.by_sensor.iter().filter(|x| **x > limit).count() {
            0 | 1 => String::new(),
            n => format!(", and {} other sensor(s) above {}", n - 1, percent(limit)),
        };
        Some(format!(
            "mesh too coarse: {} is estimated {:.2} % of its range off the converged mesh \
             (Richardson from its history on {} elements against {}){others}; add elements",
            self.worst,
            100.0 * self.estimate,
            self.elements.1,
            self.elements.0
        ))
    }
}

/// The warning of a run or a variant whose mesh error was not measured, and why.
pub fn mesh_not_measured(why: &str) -> String {
    format!("mesh error not measured: {why}")
}

/// Free coordinates of a mesh twin up to which `--mesh-check auto` runs it (`run`, and
/// each sampled variant of `sweep`). The twin has as many steps as the run, each with
/// twice the elements: alongside a fixed-step run (second core) it adds about 1-2 times
/// the run's wall time, after an accuracy-controlled one 2-3 times. 20 000 coordinates
/// is 1 600 beam elements, where one run already takes minutes and the check would add
/// as much again or more; above it the error is reported not measured.
pub const MESH_CHECK_AUTO_DOFS: usize = 20_000;

/// Bytes a sensor history kept in memory takes per value (one component of one
/// sample): the f64, and its share of the per-sample vector (24 bytes and an allocation
/// of at least 32) for a one-component sensor, the worst case. A mesh twin's history,
/// and a sampled variant's kept for its twin, are sized by it before they run.
pub const HISTORY_BYTES_PER_VALUE: f64 = 64.0;

/// Variants of a sweep whose mesh error `--mesh-check auto` measures: spread over the
/// campaign as `--verify` spreads its own ([`select`]: the first, the middle, the last).
/// A campaign varies its parameters smoothly in most studies, so its ends and middle
/// bound the mesh error of the rows between; three twins cost three variants' runs
/// about two to three times over, a few percent of a campaign of a hundred.
pub const MESH_SAMPLE: usize = 3;

/// Which variants of a sweep get a mesh twin (`sweep --mesh-check`).
#[derive(Clone, Debug, Default)]
pub struct MeshSample {
    /// global indices of the variants measured, ascending (any shard's; each shard
    /// measures those it runs, so merged shards carry the figures of the single sweep)
    pub variants: Vec<usize>,
    /// twins above this many free coordinates are not run (`auto`); None: every one
    pub max_dofs: Option<usize>,
    /// `auto` or `always`, for the report
    pub mode: String,
}

impl MeshSample {
    /// Whether variant `g` (global index) is sampled; a search, as `always` samples a
    /// million.
    pub fn samples(&self, g: usize) -> bool {
        self.variants.binary_search(&g).is_ok()
    }

    /// The plan of `--mesh-check MODE` for a campaign of `n` variants: `auto`
    /// [`MESH_SAMPLE`] of them spread by [`select`] (all when fewer) up to
    /// [`MESH_CHECK_AUTO_DOFS`], `always` every one at any size, `never` none.
    pub fn plan(mode: &str, n: usize) -> Option<MeshSample> {
        let all: Vec<usize> = (0..n).collect();
        match mode {
            "auto" if n > 0 => Some(MeshSample {
                variants: select(&all, MESH_SAMPLE.min(n)).ok()?,
                max_dofs: Some(MESH_CHECK_AUTO_DOFS),
                mode: mode.into(),
            }),
            "always" if n > 0 => Some(MeshSample {
                variants: all,
                max_dofs: None,
                mode: mode.into(),
            }),
            _ => None,
        }
    }
}

/// One sampled variant's mesh check: its measurement, or why there is none.
#[derive(Clone, Debug)]
pub struct VariantMesh {
    pub global_index: usize,
    pub result: Result<RunMeshError, MeshTwinSkip>,
}

/// The mesh twin of `base` run with `sets` at step `dt`, after a completed run (samples
/// `hist`), unless it has more than `max_dofs` free coordinates: what [`compare_twin`]
/// measures, or why nothing was.
///
/// With `frequency` (`sweep --frequency`: the sensor component and the base run's
/// first bending frequency), also that frequency's mesh error from the twin's history.
#[allow(clippy::too_many_arguments)]
pub fn measure_mesh(
    path: &std::path::Path,
    sets: &[(String, f64)],
    base: &Model,
    hist: &dynamics::History,
    dt: f64,
    max_dofs: Option<usize>,
    ctx: &dynamics::RunContext<'_>,
    frequency: Option<((usize, usize), &crate::frequency::FirstBending)>,
) -> Result<RunMeshError, MeshTwinSkip> {
    let twin = mesh_twin_model(path, sets, base, dt).map_err(MeshTwinSkip::Failed)?;
    if let Some(limit) = max_dofs.filter(|&l| twin.n_eq > l) {
        return Err(MeshTwinSkip::Failed(too_large_for_auto(&twin, limit)));
    }
    let r = run_twin(&twin, ctx)?;
    let mut e = compare_twin(base, hist, &twin, &r)?;
    if let Some(((k, comp), fb)) = frequency {
        let x: Vec<f64> = r.hist.values[k].iter().map(|s| s[comp]).collect();
        let step = r.hist.t.get(1).map_or(0.0, |t1| t1 - r.hist.t[0]);
        let refined = crate::frequency::first_bending(&twin, (k, comp), &x, step);
        e.first_bending = frequency_mesh_error(fb, &refined);
    }
    Ok(e)
}

/// The mesh error of a first bending frequency from its value on the base mesh `base`
/// and on twice the elements `refined`: the larger relative change of the measured line
/// and of the rotating-frame eigenvalue (where both runs have it), times Richardson's
/// 4/3 ([`HISTORY_ORDER`]; a beam's frequencies converge at order 2 or faster, so this
/// reads high rather than low). None where neither is finite in both. The measured
/// line moves in steps of the spectrum's interpolation where the mesh changes it less
/// than its resolution, so the eigenvalue, exact for the model, is the finer reading.
pub fn frequency_mesh_error(
    base: &crate::frequency::FirstBending,
    refined: &crate::frequency::FirstBending,
) -> Option<f64> {
    let rel =
        |a: f64, b: f64| (a.is_finite() && b.is_finite() && a != 0.0).then(|| ((b - a) / a).abs());
    let line = rel(base.hz, refined.hz);
    let eig = match (base.eig_hz, refined.eig_hz) {
        (Some(a), Some(b)) => rel(a, b),
        _ => None,
    };
    let richardson = 1.0 / (1.0 - 0.5f64.powi(HISTORY_ORDER));
    match (line, eig) {
        (Some(a), Some(b)) => Some(a.max(b) * richardson),
        (Some(a), None) | (None, Some(a)) => Some(a * richardson),
        (None, None) => None,
    }
}

/// Why `--mesh-check auto` does not run `twin`.
pub fn too_large_for_auto(twin: &Model, limit: usize) -> String {
    format!(
        "twice the elements ({}) give {} free coordinates, above the {limit} the check runs \
         by itself (it costs about twice the run again); `--mesh-check always` runs it",
        twin.elements.len(),
        twin.n_eq
    )
}

/// Richardson order of a run's sensor histories under mesh refinement, for every sensor.
/// Measured on the rotating cantilever (first 3 s, 10/20/40 elements against 80): the
/// root moment's history converges at order 3.3 then 3.9, the tip's at 3.9 (the
/// inertial load is resolved better than a static weight, whose section forces converge
/// at order 1, README "Section forces under distributed loads"). Order 2 reads 1.3 times
/// the true error at orders of 3 and more, and 2/3 of it where a sensor converges at
/// order 1; order 1, as `statics` takes for section forces, read the root moment at 1.9
/// times its error and warned a 20-element mesh within 0.65 %.
const HISTORY_ORDER: i32 = 2;

/// A run's mesh error per sensor from its history `base` and the history `refined` of its
/// mesh twin (same samples): each component's largest difference over the samples (a
/// rotation-vector angle's modulo 2π) relative to the scale [`rel_diff`] uses (its range
/// over the base run, at least [`REST_FRACTION`] of the largest magnitude in its unit
/// over the model's sensors, an energy sensor's terms against the largest range among
/// them), times Richardson's 1/(1 − 2⁻ᵖ) ([`HISTORY_ORDER`]): the base run's own distance
/// from the converged mesh. Also names the worst component. Non-finite values read
/// infinite.
pub fn history_mesh_error(
    m: &Model,
    base: &dynamics::History,
    refined: &dynamics::History,
) -> (Vec<f64>, String) {
    use crate::model::SensorKind;
    let base_sum = crate::ensemble::summarize(m, base);
    let ref_sum = crate::ensemble::summarize(m, refined);
    let magnitudes = unit_magnitudes(m, &base_sum, &ref_sum);
    let mut worst = (0.0f64, String::new());
    let by_sensor = m
        .sensors
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let angle = sensors::angle_components(&s.kind);
            let names = sensors::components(&s.kind);
            let nc = names.len();
            // the largest pointwise difference per component
            let mut diff = vec![0.0f64; nc];
            for (yb, yr) in base.values[k].iter().zip(&refined.values[k]) {
                for c in 0..nc {
                    let d = sensors::component_distance(yr[c], yb[c], angle[c]);
                    diff[c] = if d.is_finite() {
                        diff[c].max(d)
                    } else {
                        f64::INFINITY
                    };
                }
            }
            let energy = matches!(s.kind, SensorKind::Energy);
            let scales = rel_scales(
                &base_sum[k],
                &ref_sum[k],
                &sensors::units(&s.kind),
                energy,
                &magnitudes,
            );
            let mut rel: Vec<f64> = (0..nc).map(|c| relative(diff[c], scales[c])).collect();
            let richardson = 1.0 / (1.0 - 0.5f64.powi(HISTORY_ORDER));
            for (c, r) in rel.iter_mut().enumerate() {
                *r *= richardson;
                if *r > worst.0 || (worst.1.is_empty() && *r > 0.0) {
                    worst = (*r, format!("{}.{}", s.name, names[c]));
                }
            }
            rel.iter().copied().fold(0.0f64, f64::max)
        })
        .collect();
    (by_sensor, worst.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frequencys_mesh_error_is_its_larger_relative_change_times_four_thirds() {
        use crate::frequency::FirstBending;
        let fb = |hz: f64, eig: Option<f64>| FirstBending {
            hz,
            eig_hz: eig,
            warnings: Vec::new(),
        };
        let e = frequency_mesh_error(&fb(10.0, Some(2.0)), &fb(9.9, Some(2.04))).unwrap();
        assert!((e - 0.02 * 4.0 / 3.0).abs() < 1e-12, "{e}");
        let e = frequency_mesh_error(&fb(10.0, None), &fb(10.3, Some(2.0))).unwrap();
        assert!((e - 0.03 * 4.0 / 3.0).abs() < 1e-12, "{e}");
        assert!(frequency_mesh_error(&fb(f64::NAN, None), &fb(1.0, None)).is_none());
    }

    #[test]
    fn select_spreads_evenly_with_first_and_last() {
        let all: Vec<usize> = (0..10).collect();
        assert_eq!(select(&all, 2).unwrap(), vec![0, 9]);
        assert_eq!(select(&all, 3).unwrap(), vec![0, 5, 9]);
        assert_eq!(select(&all, 1).unwrap(), vec![4]);
        assert_eq!(select(&all, 10).unwrap(), all);
        assert!(select(&all, 0).is_err());
        assert!(select(&all, 11).is_err());
        let shard: Vec<usize> = (0..10).step_by(3).collect(); // 0 3 6 9
        assert_eq!(select(&shard, 2).unwrap(), vec![0, 9]);
    }

    #[test]
    fn rel_diff_is_relative_to_the_range_and_ignores_round_off_at_rest() {
        let s = |min: Vec<f64>, max: Vec<f64>| SensorSummary {
            last: min.clone(),
            min,
            max,
        };
        // x moves over [−1, 1] (range 2); z stays at 1e-17 round-off against a 1 m scale
        let b = s(vec![-1.0, 0.0], vec![1.0, 1e-17]);
        let r = s(vec![-1.02, 0.0], vec![1.0, -1e-17]);
        let d = rel_diff(&b, &r, &["m", "m"], false, &[]);
        assert!((d[0] - 0.01).abs() < 1e-12, "{d:?}");
        assert!(d[1] < 1e-9, "{d:?}");
        // identical runs: 0, also for a sensor that is 0 throughout
        let z = s(vec![0.0], vec![0.0]);
        assert_eq!(rel_diff(&z, &z, &["m"], false, &[]), vec![0.0]);
        // a refined run that blew up
        let inf = s(vec![f64::NAN], vec![f64::NAN]);
        assert_eq!(rel_diff(&z, &inf, &["m"], false, &[]), vec![f64::INFINITY]);
    }

    #[test]
    fn an_energy_accounts_conserved_total_is_measured_against_the_energy_exchanged() {
        let s = |min: Vec<f64>, max: Vec<f64>| SensorSummary {
            last: min.clone(),
            min,
            max,
        };
        // kinetic over [0, 5] J; the total at −5.3 J drifts by 1e-5 J, by half that refined
        let b = s(vec![0.0, -5.30001], vec![5.0, -5.3]);
        let r = s(vec![0.0, -5.300005], vec![5.0, -5.3]);
        let alone = rel_diff(&b, &r, &["J", "J"], false, &[]);
        assert!(alone[1] > 0.4, "{alone:?}");
        let shared = rel_diff(&b, &r, &["J", "J"], true, &[]);
        assert!((shared[1] - 1e-6).abs() < 1e-9, "{shared:?}");
        assert_eq!(shared[0], alone[0]);
    }
}
