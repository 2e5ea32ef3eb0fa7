//! Model files: spec (serde types, user vocabulary), expressions, compilation into the
//! immutable [`Model`].

pub mod expr;
mod types;

pub use types::*;
