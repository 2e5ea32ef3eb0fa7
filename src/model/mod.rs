//! Model files: spec (serde types, user vocabulary), expressions, compilation into the
//! immutable [`Model`].

pub mod compile;
mod error;
pub mod expr;
#[cfg(test)]
mod feature_tests;
mod interval;
pub mod limits;
pub mod repeat;
pub mod spec;
mod types;

pub use compile::{
    compile_str, compile_str_refined, load, load_refined, parse_file, parse_set, Parsed,
};
pub use error::ModelError;
pub use limits::Limits;
pub use repeat::RepeatSummary;
pub use types::*;
