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
    let strain: f64 = model
        .elem_data
        .iter()
        .enumerate()
        .map(|(ie, e)| crate::element::strain_energy(e, &crate::joint::elem_state(model, &s, ie)))
        .sum();
    let en = Energies {
        kinetic: 0.0,
        strain,
        ..Energies::default()
    };
    // generalized forces at equilibrium: at driven dofs, what the drivers supply
    let mut gen = vec![0.0; model.dofs.len()];
    Assembler::new(model).evaluate(
        model,
        &s,
        crate::assembly::Coeffs::statics(1.0),
        &mut gen,
        None,
    );
    let vals = model
        .sensors
        .iter()
        .map(|sn| sensors::sample(model, &s, &sn.kind, &en, &gen))
        .collect();
    Ok(StaticSolution {
        state: s,
        report,
        sensors: vals,
        strain_energy: strain,
    })
}
