//! Solvers: statics (load stepping), modes (linearised eigenproblem), and the Newton
//! system they share.

/// Why Newton failed where the forces themselves are NaN or infinite.
pub(crate) const FORCES_NOT_FINITE: &str = "; the forces are not finite (NaN or infinity): a \
    stiffness, mass, load or gravity so large (or an expression so singular) that the \
    element or body forces overflow f64; check the model's magnitudes";

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
    /// the largest single force contribution at the equilibrium (the convergence test's
    /// scale, [`crate::assembly::AssemblyInfo::force_scale`])
    pub force_scale: f64,
}

/// Static equilibrium of `model` under its loads, from the reference configuration.
pub fn solve_statics(model: &Model) -> Result<StaticSolution, statics::StaticsError> {
    solve_statics_until(model, None)
}

/// [`solve_statics`], interrupted once `stop` is set ([`statics::solve_until`]).
pub fn solve_statics_until(
    model: &Model,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> Result<StaticSolution, statics::StaticsError> {
    let mut s = State::new(model);
    let report = statics::solve_until(model, &mut s, stop)?;
    let (sensors, strain_energy, force_scale) = static_sensors(model, &s, 1.0);
    Ok(StaticSolution {
        state: s,
        report,
        sensors,
        strain_energy,
        force_scale,
    })
}

/// Sensor values (model order), strain energy and force scale of a static state `s` at
/// load factor `lambda`: no kinetic energy, and at driven dofs the generalized forces the
/// drivers supply there.
fn static_sensors(model: &Model, s: &State, lambda: f64) -> (Vec<Vec<f64>>, f64, f64) {
    let mut gen = vec![0.0; model.dofs.len()];
    let info = Assembler::new(model).evaluate(
        model,
        s,
        crate::assembly::Coeffs::statics(lambda),
        &mut gen,
        None,
    );
    let en = static_energies(model, s, lambda, &info);
    let vals = model
        .sensors
        .iter()
        .map(|sn| sensors::sample(model, s, &sn.kind, &en, &gen))
        .collect();
    (vals, en.strain, info.force_scale)
}

/// The energies of a static state at load factor `lambda`, from its assembly `info`:
/// strain with the hinge springs (until session 48 the elements' alone: a beam on a
/// spring hinge under a tip moment read 1.0 J of its 6.0), gravity's potential as a run
/// reports it (−Σ m g·x, absolute; it read 0) at the applied share of gravity, and the
/// work of the loads at their applied value on the way from the reference to the state
/// (it read 0): a dead force's F·u is that work along any path, a dead moment's M·ψ (ψ
/// the node's rotation vector) along a turn about a fixed axis of less than π (ψ wraps
/// past it: a beam rolled into a full circle reads no work of its moment). So the energy sensor's
/// `balance` is the total potential energy, least at a stable equilibrium.
pub(crate) fn static_energies(
    model: &Model,
    s: &State,
    lambda: f64,
    info: &crate::assembly::AssemblyInfo,
) -> Energies {
    let load_work: f64 = model
        .loads
        .iter()
        .map(|l| {
            let psi = crate::math::rot_log(&s.node_r[l.node]);
            lambda * (crate::math::dot(l.force, s.node_u[l.node]) + crate::math::dot(l.moment, psi))
        })
        .sum();
    Energies {
        kinetic: 0.0,
        strain: info.strain_energy,
        gravity: lambda * info.gravity_energy,
        load_work,
        ..Energies::default()
    }
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
    /// elements of the model's beams in the base and the refined mesh
    pub elements: (usize, usize),
}

/// Measures the mesh error of a static solution: `refined` compiles the same model with
/// every beam refined by [`MESH_REFINE`] (`crate::model::load_refined`), which is solved,
/// and each sensor component's error is estimated by Richardson's rule,
/// |y_n − y_2n| / (1 − 2⁻ᵖ): p = 2 for positions, rotations, reactions and energies
/// (the element's interpolation, and its sine measure of the deformation angles, err by
/// 2θ²/3 with θ proportional to the element length; bend45 from 8 and 16 elements:
/// 0.215 and 0.175 estimated at the tip's x and z against a true 0.215 and 0.175 against
/// 256 elements), p = 1 for section forces and moments (measured: bend45's root axial
/// force 94.8, 48.5, 24.5, 12.3 N on 8 … 64 elements, halving). Each is relative to the
/// sensor's change under the loads (the largest over its components of the same unit;
/// for a sensor with forces and moments, the larger of the forces' and the moments'
/// over the model's extent, and that times the extent for the moments; for one with
/// displacements and rotations, the rotations' at least the displacements' over the
/// extent),
/// but at least [`crate::verify::REST_FRACTION`] of the model's own scale in that unit
/// (lengths: its extent; forces: strain energy over extent or the largest force term at
/// the equilibrium; moments: strain energy or that force term times the extent;
/// energies: strain energy; angles: 1 rad), so that a sensor the loads do not move (a
/// reaction that is zero by symmetry) does not turn round-off into an error. Rotation-vector components
/// are compared modulo 2π.
///
/// Above [`MESH_ERROR_WARN`] it warns, naming the sensor; where an element left its
/// small-deformation range (the bound warning of [`statics::solve`],
/// [`crate::assembly::DeformationAngle::warning`]) the warning is that one with the
/// measurement added, and below the limit that bound warning is removed, since the
/// reported numbers are then within 1 %. Where the refined model cannot be compiled or
/// solved, or `stop` ends its solve (a signal), a warning says the error was not
/// measured and why (the bound warning stays).
/// `None` for a model without elements (nothing to refine), for the reference
/// configuration itself (no Newton correction: nothing deformed), or when the check
/// could not run.
pub fn check_statics_mesh(
    model: &Model,
    sol: &mut StaticSolution,
    refined: impl FnOnce() -> Result<Model, String>,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> Option<MeshError> {
    check_statics_mesh_keeping(model, sol, refined, stop).0
}

/// [`check_statics_mesh`], also giving the refined model and its equilibrium where they
/// were solved (the modes about a static equilibrium measure their own mesh error about
/// the refined one, without solving it twice).
pub fn check_statics_mesh_keeping(
    model: &Model,
    sol: &mut StaticSolution,
    refined: impl FnOnce() -> Result<Model, String>,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> (Option<MeshError>, Option<(Model, StaticSolution)>) {
    // without elements there is nothing to refine; a state that needed no Newton
    // correction is the reference configuration (no loads), which no mesh gets wrong
    if model.elem_data.is_empty() || sol.report.newton_iterations == 0 {
        return (None, None);
    }
    let bound = crate::assembly::largest_deformation_angle(model, &sol.state)
        .and_then(|d| d.warning(None).map(|w| (d, w)));
    let slot = bound.as_ref().map(
        |(_, w)| match sol.report.warnings.iter().position(|x| x == w) {
            Some(k) => k,
            None => {
                sol.report.warnings.push(w.clone());
                sol.report.warnings.len() - 1
            }
        },
    );
    let elements = (model.elem_data.len(), model.elem_data.len() * MESH_REFINE);
    // the base model stays in memory while the refined one is solved: together they
    // may hold no more elements than one model at the element limit (whose memory that
    // limit bounds)
    let lim = crate::model::Limits::from_env()
        .map(|l| l.elements)
        .unwrap_or(u64::MAX);
    let held = (elements.0 + elements.1) as u64;
    let fine = if held > lim {
        Err(format!(
            "the model and its refinement together would hold {held} elements, above the \
             element limit {lim} (LATDYN_LIMITS key `elements`)"
        ))
    } else {
        refined()
    };
    let fine = fine.and_then(|rm| {
        let fs = solve_statics_until(&rm, stop).map_err(|e| e.to_string())?;
        if fs.sensors.len() != sol.sensors.len()
            || fs
                .sensors
                .iter()
                .zip(&sol.sensors)
                .any(|(a, b)| a.len() != b.len())
        {
            return Err("its sensors differ from the model's".into());
        }
        Ok((rm, fs))
    });
    let (refined_model, fine) = match fine {
        Ok(f) => f,
        Err(e) => {
            let why = format!(
                "not measured: solving again with twice the elements ({} in all) failed: {e}",
                elements.1
            );
            match (slot, &bound) {
                (Some(k), Some((_, w))) => sol.report.warnings[k] = format!("{w} ({why})"),
                _ => sol.report.warnings.push(format!("mesh error {why}")),
            }
            return (None, None);
        }
    };
    // where the changes under the loads are measured from: the reference configuration
    let (reference, e0, _) = static_sensors(model, &State::new(model), 0.0);
    let energy = sol.strain_energy.abs().max(fine.strain_energy.abs());
    let extent = model_extent(model);
    // forces and moments: at least the largest force term at the equilibrium (a moment
    // that is zero at a free end, sensed alone without the section's forces, read its
    // round-off, 3e-9 N·m, as a 175 % error against a strain-energy floor of 1.7e-9)
    let forces = if sol.force_scale.is_finite() {
        sol.force_scale
    } else {
        0.0
    };
    let unit_scale = |unit: &str| match unit {
        "m" => extent,
        "rad" => 1.0,
        "N" if extent > 0.0 => (energy / extent).max(forces),
        "N" => forces,
        "N*m" => energy.max(forces * extent),
        "J" => energy,
        _ => 0.0,
    };
    let rest = crate::verify::REST_FRACTION;
    let mut worst = (0.0f64, String::new());
    let mut by_sensor = Vec::with_capacity(sol.sensors.len());
    for (k, sn) in model.sensors.iter().enumerate() {
        let (base, fine, refc) = (&sol.sensors[k], &fine.sensors[k], &reference[k]);
        let units = sensors::units(&sn.kind);
        let names = sensors::components(&sn.kind);
        let angles = sensors::angle_components(&sn.kind);
        // Richardson: y_n − y = (y_n − y_2n) / (1 − 2⁻ᵖ)
        let p = match sn.kind {
            crate::model::SensorKind::Section { .. }
            | crate::model::SensorKind::SectionComponent { .. } => 1,
            _ => 2,
        };
        let richardson = 1.0 / (1.0 - 0.5f64.powi(p));
        let diff = sensors::component_distance;
        let change_of = |unit: &str| {
            (0..base.len())
                .filter(|&o| units.get(o).copied() == Some(unit))
                .map(|o| diff(base[o], refc[o], angles.get(o).copied().unwrap_or(false)))
                .fold(0.0, f64::max)
        };
        // a section's forces and moments are one resultant: a moment near zero where the
        // forces are not (a free end) is measured against force × extent, and the other
        // way round
        let force_scale = if extent > 0.0 {
            change_of("N").max(change_of("N*m") / extent)
        } else {
            change_of("N")
        };
        let mut largest = 0.0f64;
        for c in 0..base.len() {
            let angle = angles.get(c).copied().unwrap_or(false);
            let unit = units.get(c).copied().unwrap_or("");
            let same: Vec<usize> = (0..base.len())
                .filter(|&o| units.get(o).copied() == Some(unit))
                .collect();
            let change = match unit {
                "N" => force_scale,
                "N*m" => change_of("N*m").max(force_scale * extent),
                // a node that moved but turned back (a beam rolled through a full turn)
                "rad" if extent > 0.0 => change_of("rad").max(change_of("m") / extent),
                _ => change_of(unit),
            };
            let magnitude = same
                .iter()
                .flat_map(|&o| [base[o], fine[o], refc[o]])
                .fold(0.0f64, |a, x| a.max(x.abs()));
            let floor = rest * unit_scale(unit).max(magnitude);
            let e = relative(
                richardson * diff(base[c], fine[c], angle),
                change.max(floor),
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
        (sol.strain_energy - fine.strain_energy).abs() / (1.0 - 0.25),
        (sol.strain_energy - e0).abs().max(rest * energy),
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
        elements,
    };
    let measured = format!(
        "measured by solving again with twice the elements ({} in all): the estimated mesh \
         error is {:.2} % of the change under the loads ({}; Richardson), above the {} % \
         limit",
        elements.1,
        100.0 * check.estimate,
        check.worst,
        100.0 * MESH_ERROR_WARN,
    );
    match (slot, &bound) {
        (Some(k), Some(_)) if estimate <= MESH_ERROR_WARN => {
            sol.report.warnings.remove(k);
        }
        (Some(k), Some((_, w))) => sol.report.warnings[k] = format!("{w}; {measured}"),
        _ if estimate > MESH_ERROR_WARN => sol.report.warnings.push(format!(
            "mesh too coarse for the reported numbers: {measured}. Use more elements \
             (halving the element length quarters a second-order error, halves a \
             section force's)"
        )),
        _ => {}
    }
    (Some(check), Some((refined_model, fine)))
}

/// The diagonal of the box around the model's reference nodes [m].
fn model_extent(model: &Model) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for x in &model.x0 {
        for c in 0..3 {
            lo[c] = lo[c].min(x[c]);
            hi[c] = hi[c].max(x[c]);
        }
    }
    let d2: f64 = (0..3).map(|c| (hi[c] - lo[c]).powi(2)).sum();
    if d2.is_finite() {
        d2.sqrt()
    } else {
        0.0
    }
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
