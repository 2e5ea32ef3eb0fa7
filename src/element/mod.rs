//! The co-rotational 3D beam element (paper section 2): pure, allocation-free functions of
//! (element data, nodal state). The GPU kernels mirror these and are tested against them.
//!
//! One file per route: [`kinematics`] (data, state, convected frame, strain energy),
//! [`force`] (internal force and tangent; twin of `shaders/beam_force.wgsl`), [`inertia`]
//! (M, S, C; twin of `shaders/beam_inertia.wgsl`), and [`reference`], the automatic-
//! differentiation routes that only tests and benches call to check the other two.

pub mod ad;
pub mod force;
pub mod inertia;
pub mod kinematics;
pub mod reference;
pub mod stage;

pub use force::*;
pub use inertia::*;
pub use kinematics::*;
pub use stage::{memo_key, CpuEval, ElemIn, ElemOut, ElementEval, EvalError, EvalRequest};

#[cfg(test)]
mod tests;
