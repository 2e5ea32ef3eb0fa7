//! Sensors: named quantities sampled from a state (the last stage of a step).

use crate::element;
use crate::joint::{self, State};
use crate::math::*;
use crate::model::{Model, SensorKind, SECTION_COMPONENTS};

/// Component names of a sensor, in output order (units in `units`).
pub fn components(kind: &SensorKind) -> Vec<&'static str> {
    match kind {
        SensorKind::NodeDisplacement { .. } | SensorKind::BodyPose { .. } => {
            vec!["x", "y", "z", "rx", "ry", "rz"]
        }
        SensorKind::NodePosition { .. } => vec!["x", "y", "z"],
        SensorKind::Section { .. } => SECTION_COMPONENTS.to_vec(),
        SensorKind::SectionComponent { component, .. } => vec![SECTION_COMPONENTS[*component]],
        SensorKind::HingeAngle { .. } => vec!["angle", "rate"],
        SensorKind::NodeDirection { .. } => vec!["u"],
        SensorKind::BodyFrameDisplacement { axis, .. } => vec![["x", "y", "z"][*axis]],
        SensorKind::Energy => vec![
            "kinetic",
            "strain",
            "gravity",
            "driver_work",
            "total",
            "load_work",
            "dissipated",
            "balance",
        ],
        SensorKind::DriverForce { .. } => vec!["force"],
        SensorKind::BeamDisplacement { nodes, .. } => node_component_names(nodes.len()),
    }
}

/// `n0`, `n1`, … as static strings (each index is leaked once, then reused).
fn node_component_names(n: usize) -> Vec<&'static str> {
    use std::sync::{Mutex, OnceLock};
    static NAMES: OnceLock<Mutex<Vec<&'static str>>> = OnceLock::new();
    let mut names = NAMES
        .get_or_init(|| Mutex::new(Vec::new()))
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    while names.len() < n {
        let i = names.len();
        names.push(Box::leak(format!("n{i}").into_boxed_str()));
    }
    names[..n].to_vec()
}

/// Which components are rotation angles that wrap by 2π (the rotation-vector parts of
/// node and body sensors): differences between two states are taken modulo 2π there.
pub fn angle_components(kind: &SensorKind) -> Vec<bool> {
    match kind {
        SensorKind::NodeDisplacement { .. } | SensorKind::BodyPose { .. } => {
            vec![false, false, false, true, true, true]
        }
        _ => vec![false; components(kind).len()],
    }
}

/// |a − b| of one component; for a rotation-vector angle ([`angle_components`]) the
/// difference is taken modulo 2π first (it jumps by 2π where the vector wraps at π).
pub fn component_distance(a: f64, b: f64, angle: bool) -> f64 {
    let d = a - b;
    if angle {
        (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
    } else {
        d
    }
    .abs()
}

/// SI units of each component.
pub fn units(kind: &SensorKind) -> Vec<&'static str> {
    match kind {
        SensorKind::NodeDisplacement { .. } | SensorKind::BodyPose { .. } => {
            vec!["m", "m", "m", "rad", "rad", "rad"]
        }
        SensorKind::NodePosition { .. } => vec!["m"; 3],
        SensorKind::Section { .. } => vec!["N", "N", "N", "N*m", "N*m", "N*m"],
        SensorKind::SectionComponent { component, .. } => {
            vec![if *component < 3 { "N" } else { "N*m" }]
        }
        SensorKind::HingeAngle { .. } => vec!["rad", "rad/s"],
        SensorKind::NodeDirection { .. } | SensorKind::BodyFrameDisplacement { .. } => vec!["m"],
        SensorKind::Energy => vec!["J"; 8],
        SensorKind::DriverForce { rotational, .. } => {
            vec![if *rotational { "N*m" } else { "N" }]
        }
        SensorKind::BeamDisplacement { nodes, .. } => vec!["m"; nodes.len()],
    }
}

/// Energies that the caller tracks over a run (kinetic, strain — hinge springs included —
/// and gravity from the last assembly; the works and the dissipation integrated by the
/// integrator, trapezoid rule per step on the powers at the step ends).
#[derive(Clone, Copy, Debug, Default)]
pub struct Energies {
    pub kinetic: f64,
    pub strain: f64,
    pub gravity: f64,
    /// work the drivers supplied (reaction × rate of the driven dofs)
    pub driver_work: f64,
    /// work of the applied loads, time scales included
    pub load_work: f64,
    /// energy taken out by Rayleigh damping and hinge dampers
    pub dissipated: f64,
}

impl Energies {
    /// Kinetic + strain + gravity − driver work − load work + dissipated: constant in
    /// exact dynamics; what time integration adds to it or takes from it is its error.
    pub fn balance(&self) -> f64 {
        self.kinetic + self.strain + self.gravity - self.driver_work - self.load_work
            + self.dissipated
    }
}

/// Values of one sensor at state `s`. `driver_forces` (by dof) holds the generalized
/// force each driven dof's driver supplies.
pub fn sample(
    model: &Model,
    s: &State,
    kind: &SensorKind,
    energies: &Energies,
    driver_forces: &[f64],
) -> Vec<f64> {
    let mut out = Vec::new();
    sample_into(model, s, kind, energies, driver_forces, &mut out);
    out
}

/// [`sample`] into a buffer the caller keeps (the time-error estimate samples every sensor
/// twice per step; a fresh vector each time was an allocation on the step's hot path).
pub fn sample_into(
    model: &Model,
    s: &State,
    kind: &SensorKind,
    energies: &Energies,
    driver_forces: &[f64],
    out: &mut Vec<f64>,
) {
    let elem_state = |e: usize| joint::elem_state(model, s, e);
    out.clear();
    match kind {
        SensorKind::NodeDisplacement { node } => {
            let u = s.node_u[*node];
            let r = rot_log(&s.node_r[*node]);
            out.extend_from_slice(&[u[0], u[1], u[2], r[0], r[1], r[2]]);
        }
        SensorKind::NodePosition { node } => {
            out.extend_from_slice(&joint::node_position(model, s, *node))
        }
        SensorKind::Section { element, xi } => out.extend_from_slice(&element::section_forces(
            &model.elem_data[*element],
            &elem_state(*element),
            *xi,
            model.elements[*element].arc,
        )),
        SensorKind::SectionComponent {
            element,
            xi,
            component,
        } => out.push(
            element::section_forces(
                &model.elem_data[*element],
                &elem_state(*element),
                *xi,
                model.elements[*element].arc,
            )[*component],
        ),
        SensorKind::HingeAngle { hinge } => {
            let d = model.hinges[*hinge].dof;
            out.extend_from_slice(&[s.q[d], s.v[d]])
        }
        SensorKind::BodyPose { body } => {
            let x = s.body_x[*body];
            let r = rot_log(&s.body_r[*body]);
            out.extend_from_slice(&[x[0], x[1], x[2], r[0], r[1], r[2]])
        }
        SensorKind::NodeDirection { node, dir } => out.push(dot(s.node_u[*node], *dir)),
        SensorKind::BodyFrameDisplacement { node, body, axis } => {
            let b = &model.bodies[*body];
            let now = mat_t_vec(
                &s.body_r[*body],
                sub(joint::node_position(model, s, *node), s.body_x[*body]),
            );
            let then = mat_t_vec(&b.r0, sub(model.x0[*node], b.x0));
            out.push(now[*axis] - then[*axis])
        }
        SensorKind::Energy => out.extend_from_slice(&[
            energies.kinetic,
            energies.strain,
            energies.gravity,
            energies.driver_work,
            // conserved without damping and loads: mechanical energy minus driver work
            energies.kinetic + energies.strain + energies.gravity - energies.driver_work,
            energies.load_work,
            energies.dissipated,
            // conserved in any model: the total minus load work plus dissipation
            energies.balance(),
        ]),
        SensorKind::DriverForce { dof, .. } => out.push(driver_forces[*dof]),
        SensorKind::BeamDisplacement { nodes, axis } => {
            out.extend(nodes.iter().map(|&n| s.node_u[n][*axis]))
        }
    }
}
