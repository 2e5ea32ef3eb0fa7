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
pub use error::{elide_long_words, ModelError};
pub use limits::Limits;
pub use repeat::RepeatSummary;
pub use types::*;

/// A value as the user would type it back: shortest round-trip digits, in exponent form
/// when plain digits would run long (`1e308`, not 309 digits; `2.5e-7`).
pub fn value_text(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e16).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod value_text_tests {
    #[test]
    fn value_text_is_short_and_round_trips() {
        for (v, t) in [
            (1e308, "1e308"),
            (2.5e-7, "2.5e-7"),
            (0.001, "0.001"),
            (-3.0, "-3"),
            (123456.5, "123456.5"),
            (0.0, "0"),
        ] {
            assert_eq!(super::value_text(v), t);
            assert_eq!(t.parse::<f64>().unwrap(), v);
        }
    }
}
