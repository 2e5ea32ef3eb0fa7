//! Solvers: statics (load stepping), modes (linearised eigenproblem), and the Newton
//! system they share.

pub mod batch;
pub mod dynamics;
pub mod linear;
pub mod modes;
pub mod path;
pub mod rotating;
pub mod start;
pub mod statics;

use crate::assembly::Assembler;
use crate::joint::State;
use crate::model::Model;
use crate::sensors::{self, Energies};

/// Mesh refinement of [`check_statics_mesh`]: every beam with twice its elements.
pub const MESH_REFINE: usize = 2;

/// Estimated mesh error above which statics warns: 1 % of a sensor's change under the
/// loads (or of the strain energy), the digits a user reads in a table (the same limit
/// as the time-error estimate's and `sweep --verify`'s default target).
pub const MESH_ERROR_WARN: f64 = 1e-2;

/// Result of a static solution: the equilibrium state, solver counts and every sensor.
pub struct StaticSolution {
    pub state: State,
    pub report: statics::StaticsReport,
    /// sensor values in model order
    pub sensors: Vec<Vec<f64>>,
    pub strain_energy: f64,
}

/// Static equilibrium of `model` under its loads, from the reference configuration.
pub fn solve_statics(model: &Model) -> Result<StaticSolution, statics::StaticsError> {
    let mut s = State::new(model);
    let report = statics::solve(model, &mut s)?;
    let (sensors, strain_energy) = static_sensors(model, &s, 1.0);
    Ok(StaticSolution {
        state: s,
        report,
        sensors,
        strain_energy,
    })
}

/// Sensor values (model order) and strain energy of a static state `s` at load factor
/// `lambda`: no kinetic energy, and at driven dofs the generalized forces the drivers
/// supply there.
fn static_sensors(model: &Model, s: &State, lambda: f64) -> (Vec<Vec<f64>>, f64) {
    let strain: f64 = model
        .elem_data
        .iter()
        .enumerate()
        .map(|(ie, e)| crate::element::strain_energy(e, &crate::joint::elem_state(model, s, ie)))
        .sum();
    let en = Energies {
        kinetic: 0.0,
        strain,
        ..Energies::default()
    };
    let mut gen = vec![0.0; model.dofs.len()];
    Assembler::new(model).evaluate(
        model,
        s,
        crate::assembly::Coeffs::statics(lambda),
        &mut gen,
        None,
    );
    let vals = model
        .sensors
        .iter()
        .map(|sn| sensors::sample(model, s, &sn.kind, &en, &gen))
        .collect();
    (vals, strain)
}

/// The mesh error of a static solution, measured (see [`check_statics_mesh`]).
#[derive(Clone, Debug)]
pub struct MeshError {
    /// largest of `by_sensor` and `strain_energy`
    pub estimate: f64,
    /// per sensor (model order): the largest estimate over its components, each relative
    /// to the largest change of the sensor's components with the same unit under the
    /// loads (from the reference configuration to the equilibrium)
    pub by_sensor: Vec<f64>,
    /// estimate of the strain energy, relative to its change under the loads
    pub strain_energy: f64,
    /// what carries `estimate`: `sensor.component`, or `strain energy`
    pub worst: String,
    /// elements of the most deformed beam in the base and the refined mesh
    pub elements: (usize, usize),
}

/// Measures the mesh error of a static solution whose most deformed element leaves the
/// small-deformation range (the bound warning of [`statics::solve`],
/// [`crate::assembly::DeformationAngle::warning`]), and replaces that bound by the
/// measurement. `refined` compiles the same model with every beam refined by
/// [`MESH_REFINE`] (`crate::model::load_refined`); it is solved, and each sensor
/// component's error is estimated as |y_n − y_2n| / (1 − 2⁻²), Richardson's estimate
/// for the second-order error of the element (its sine measure errs by 2θ²/3 with θ
/// proportional to the element length; bend45 from 8 and 16 elements: 0.215 and 0.175
/// estimated at the tip's x and z against a true 0.215 and 0.175 against 256 elements).
/// Above [`MESH_ERROR_WARN`] the warning states the measurement; below it the warning
/// is removed, since the reported numbers are then within 1 %. Where the refined model
/// cannot be compiled or solved, the bound warning stays and says why it was not
/// measured. `None` when no element left the range (nothing to check) or the check
/// could not run.
pub fn check_statics_mesh(
    model: &Model,
    sol: &mut StaticSolution,
    refined: impl FnOnce() -> Result<Model, String>,
) -> Option<MeshError> {
    let d = crate::assembly::largest_deformation_angle(model, &sol.state)?;
    let bound = d.warning(None)?;
    let slot = match sol.report.warnings.iter().position(|w| *w == bound) {
        Some(k) => k,
        None => {
            sol.report.warnings.push(bound.clone());
            sol.report.warnings.len() - 1
        }
    };
    let fine_elements = d.beam_elements * MESH_REFINE;
    let fine = refined().and_then(|rm| {
        let fs = solve_statics(&rm).map_err(|e| e.to_string())?;
        if fs.sensors.len() != sol.sensors.len()
            || fs
                .sensors
                .iter()
                .zip(&sol.sensors)
                .any(|(a, b)| a.len() != b.len())
        {
            return Err("its sensors differ from the model's".into());
        }
        Ok(fs)
    });
    let fine = match fine {
        Ok(f) => f,
        Err(e) => {
            sol.report.warnings[slot] = format!(
                "{bound} (not measured: solving again with {fine_elements} elements failed: {e})"
            );
            return None;
        }
    };
    // where the changes under the loads are measured from: the reference configuration
    let (reference, e0) = static_sensors(model, &State::new(model), 0.0);
    // Richardson for a second-order error: y_n − y = (y_n − y_2n) / (1 − 2⁻²)
    let richardson = 1.0 / (1.0 - 0.25);
    let mut worst = (0.0f64, String::new());
    let mut by_sensor = Vec::with_capacity(sol.sensors.len());
    for (k, sn) in model.sensors.iter().enumerate() {
        let (base, fine, rest) = (&sol.sensors[k], &fine.sensors[k], &reference[k]);
        let units = sensors::units(&sn.kind);
        let names = sensors::components(&sn.kind);
        let mut largest = 0.0f64;
        for c in 0..base.len() {
            let same: Vec<usize> = (0..base.len())
                .filter(|&o| units.get(o) == units.get(c))
                .collect();
            let change = same
                .iter()
                .map(|&o| (base[o] - rest[o]).abs())
                .fold(0.0, f64::max);
            let magnitude = same
                .iter()
                .flat_map(|&o| [base[o], fine[o], rest[o]])
                .fold(0.0f64, |a, x| a.max(x.abs()));
            let e = relative(
                richardson * (base[c] - fine[c]).abs(),
                change.max(crate::verify::REST_FRACTION * magnitude),
            );
            let e = if e.is_nan() { f64::INFINITY } else { e };
            largest = largest.max(e);
            if e > worst.0 || worst.1.is_empty() {
                worst = (
                    e,
                    format!("{}.{}", sn.name, names.get(c).copied().unwrap_or("?")),
                );
            }
        }
        by_sensor.push(largest);
    }
    let se = relative(
        richardson * (sol.strain_energy - fine.strain_energy).abs(),
        (sol.strain_energy - e0)
            .abs()
            .max(crate::verify::REST_FRACTION * sol.strain_energy.abs()),
    );
    if se > worst.0 {
        worst = (se, "strain energy".into());
    }
    let estimate = by_sensor.iter().copied().fold(se, f64::max);
    let check = MeshError {
        estimate,
        by_sensor,
        strain_energy: se,
        worst: worst.1,
        elements: (d.beam_elements, fine_elements),
    };
    if estimate <= MESH_ERROR_WARN {
        sol.report.warnings.remove(slot);
    } else {
        sol.report.warnings[slot] = format!(
            "{bound}; measured by solving again with twice the elements ({fine_elements} on \
             `{}`): the estimated mesh error is {:.2} % of the change under the loads ({}; \
             Richardson, second order), above the {} % limit",
            d.beam,
            100.0 * check.estimate,
            check.worst,
            100.0 * MESH_ERROR_WARN,
        );
    }
    Some(check)
}

/// `num / scale`: 0 where both are 0, infinite where `num` is not finite or the scale
/// is 0 under a nonzero difference.
fn relative(num: f64, scale: f64) -> f64 {
    if !num.is_finite() {
        f64::INFINITY
    } else if num == 0.0 {
        0.0
    } else if scale > 0.0 {
        num / scale
    } else {
        f64::INFINITY
    }
}
