//! Parameter expressions and time functions.

/// A prescribed coordinate q(t) with exact first and second derivatives.
#[derive(Clone, Debug)]
pub struct TimeFunction {
    pub source: String,
}

impl TimeFunction {
    /// value, rate and acceleration at time `t`
    pub fn eval(&self, _t: f64) -> [f64; 3] {
        [0.0; 3]
    }
}
