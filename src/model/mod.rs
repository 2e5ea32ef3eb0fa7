//! Model files: spec (serde types, user vocabulary), expressions, compilation into the
//! immutable [`Model`].

mod error;
pub mod expr;
pub mod spec;
mod types;

pub use error::ModelError;
pub use types::*;
