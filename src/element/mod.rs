//! The co-rotational 3D beam element (paper section 2): pure, allocation-free functions of
//! (element data, nodal state). The GPU kernels mirror these and are tested against them.

pub mod ad;
pub mod beam;
pub mod stage;

pub use beam::*;
pub use stage::{CpuEval, ElemIn, ElemOut, ElementEval, EvalError};

#[cfg(test)]
mod tests;
