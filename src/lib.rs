//! latdyn: large-angle transient dynamics of flexible multibody systems, after NASA's
//! LATDYN (Wu, Chang & Housner 1989): co-rotational 3D beam elements, rigid joint bodies
//! and hinge angles built into the element connectivity, implicit time integration.
//!
//! Data flow: model file → [`model::load`] → immutable [`model::Model`] → per-run
//! [`joint::State`] → stages (kinematics, element evaluation, assembly, sparse solve,
//! integrator update, sensors).

// Index loops are the clearest form for small fixed-size numeric kernels, and they mirror
// the WGSL kernels line by line.
#![allow(clippy::needless_range_loop)]

pub mod assembly;
pub mod campaign;
pub mod element;
pub mod ensemble;
pub mod frequency;
pub mod gpu;
pub mod joint;
pub mod linalg;
pub mod math;
pub mod model;
pub mod output;
pub mod sensors;
pub mod signal;
pub mod solver;
pub mod verify;
