//! Interval arithmetic for time functions: the range of a load's time factor over a time
//! interval, from the same parse tree as its values. The load-impulse check
//! (`Integrator::account_load_impulse`) samples a factor at a few points per step; a pulse
//! narrower than the sample spacing falls between the samples and, without this, the run
//! applied none of it with no word (the rotating cantilever with `t_pulse = 1e-3` at its
//! shipped dt = 0.01). The enclosure tells where a factor may do more between its samples
//! than the samples show, so the check refines there.
//!
//! The enclosures are computed in round-to-nearest without outward rounding: they may miss
//! the true range by a few ulps, which is far below anything the check resolves.

use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::ops::{Add, Div, Mul, Neg, Sub};
use std::str::FromStr;

/// The closed interval [lo, hi]; NaN bounds where the function is undefined somewhere on it.
#[derive(Clone, Copy, Debug, Default, PartialEq, PartialOrd)]
pub struct Interval {
    pub lo: f64,
    pub hi: f64,
}

const WHOLE: Interval = Interval {
    lo: f64::NEG_INFINITY,
    hi: f64::INFINITY,
};

impl Interval {
    pub fn new(lo: f64, hi: f64) -> Interval {
        Interval { lo, hi }
    }
    pub fn point(v: f64) -> Interval {
        Interval { lo: v, hi: v }
    }
    pub fn width(self) -> f64 {
        self.hi - self.lo
    }
    fn contains(self, v: f64) -> bool {
        self.lo <= v && v <= self.hi
    }
    /// f applied to a function that does not decrease
    fn up(self, f: impl Fn(f64) -> f64) -> Interval {
        Interval::new(f(self.lo), f(self.hi))
    }
    /// f applied to a function that does not increase
    fn down(self, f: impl Fn(f64) -> f64) -> Interval {
        Interval::new(f(self.hi), f(self.lo))
    }
    /// the hull of a few values
    fn hull(vals: &[f64]) -> Interval {
        if vals.iter().any(|v| v.is_nan()) {
            return Interval::point(f64::NAN);
        }
        let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Interval::new(lo, hi)
    }
    /// the part of the interval where a function is defined (`lo_ok`..`hi_ok`), NaN if none
    fn clamp_domain(self, lo_ok: f64, hi_ok: f64) -> Interval {
        if self.hi < lo_ok || self.lo > hi_ok || self.is_nan() {
            Interval::point(f64::NAN)
        } else {
            Interval::new(self.lo.max(lo_ok), self.hi.min(hi_ok))
        }
    }
    fn is_nan(self) -> bool {
        self.lo.is_nan() || self.hi.is_nan()
    }
    /// sin over the interval: the end values, and ±1 where a crest lies inside
    fn sin_range(self) -> Interval {
        if self.is_nan() || self.width() >= TAU || !self.width().is_finite() {
            return if self.is_nan() {
                self
            } else {
                Interval::new(-1.0, 1.0)
            };
        }
        let (a, b) = (self.lo.sin(), self.hi.sin());
        let (mut lo, mut hi) = (a.min(b), a.max(b));
        // crests at π/2 + 2πk, troughs at −π/2 + 2πk
        let k = ((self.lo - FRAC_PI_2) / TAU).ceil();
        if FRAC_PI_2 + TAU * k <= self.hi {
            hi = 1.0;
        }
        let k = ((self.lo + FRAC_PI_2) / TAU).ceil();
        if -FRAC_PI_2 + TAU * k <= self.hi {
            lo = -1.0;
        }
        Interval::new(lo, hi)
    }
    fn pow_int(self, p: i64) -> Interval {
        if p == 0 {
            return Interval::point(1.0);
        }
        if p < 0 {
            return Interval::point(1.0) / self.pow_int(-p);
        }
        let f = |x: f64| x.powi(p as i32);
        if p % 2 == 1 || self.lo >= 0.0 {
            self.up(f)
        } else if self.hi <= 0.0 {
            self.down(f)
        } else {
            Interval::new(0.0, f(self.lo).max(f(self.hi)))
        }
    }
}

impl FromStr for Interval {
    type Err = std::num::ParseFloatError;
    fn from_str(s: &str) -> Result<Interval, Self::Err> {
        s.parse::<f64>().map(Interval::point)
    }
}

impl Add for Interval {
    type Output = Interval;
    fn add(self, b: Interval) -> Interval {
        Interval::new(self.lo + b.lo, self.hi + b.hi)
    }
}
impl Sub for Interval {
    type Output = Interval;
    fn sub(self, b: Interval) -> Interval {
        Interval::new(self.lo - b.hi, self.hi - b.lo)
    }
}
impl Mul for Interval {
    type Output = Interval;
    fn mul(self, b: Interval) -> Interval {
        // 0 × ∞ is 0 here: a factor that is exactly zero on the interval zeroes the product
        let m = |x: f64, y: f64| if x == 0.0 || y == 0.0 { 0.0 } else { x * y };
        Interval::hull(&[
            m(self.lo, b.lo),
            m(self.lo, b.hi),
            m(self.hi, b.lo),
            m(self.hi, b.hi),
        ])
    }
}
impl Div for Interval {
    type Output = Interval;
    fn div(self, b: Interval) -> Interval {
        if b.is_nan() || self.is_nan() {
            return Interval::point(f64::NAN);
        }
        if b.contains(0.0) {
            return if b.lo == 0.0 && b.hi == 0.0 {
                Interval::point(f64::NAN)
            } else {
                WHOLE
            };
        }
        self * Interval::new(1.0 / b.hi, 1.0 / b.lo)
    }
}
impl Neg for Interval {
    type Output = Interval;
    fn neg(self) -> Interval {
        Interval::new(-self.hi, -self.lo)
    }
}

impl exmex::num::Num for Interval {
    fn zero() -> Interval {
        Interval::point(0.0)
    }
    fn one() -> Interval {
        Interval::point(1.0)
    }
}

impl exmex::num::Float for Interval {
    fn from_f64(f: f64) -> Interval {
        Interval::point(f)
    }
    fn to_f64(self) -> f64 {
        0.5 * (self.lo + self.hi)
    }
    fn from_f32(f: f32) -> Interval {
        Interval::point(f as f64)
    }
    fn from_int<I: exmex::num::PrimInt>(n: I) -> Interval {
        Interval::point(n.to_i64() as f64)
    }
    fn log2(self) -> Interval {
        self.ln() / Interval::point(std::f64::consts::LN_2)
    }
    fn log10(self) -> Interval {
        self.ln() / Interval::point(std::f64::consts::LN_10)
    }
    fn abs(self) -> Interval {
        if self.lo >= 0.0 {
            self
        } else if self.hi <= 0.0 {
            -self
        } else {
            Interval::new(0.0, (-self.lo).max(self.hi))
        }
    }
    fn sin(self) -> Interval {
        self.sin_range()
    }
    fn cos(self) -> Interval {
        (self + Interval::point(FRAC_PI_2)).sin_range()
    }
    fn tan(self) -> Interval {
        // a pole at π/2 + kπ inside: unbounded
        let k = ((self.lo - FRAC_PI_2) / PI).ceil();
        if self.width() >= PI || FRAC_PI_2 + PI * k <= self.hi {
            WHOLE
        } else {
            self.up(f64::tan)
        }
    }
    fn asin(self) -> Interval {
        self.clamp_domain(-1.0, 1.0).up(f64::asin)
    }
    fn acos(self) -> Interval {
        self.clamp_domain(-1.0, 1.0).down(f64::acos)
    }
    fn atan(self) -> Interval {
        self.up(f64::atan)
    }
    fn sqrt(self) -> Interval {
        self.clamp_domain(0.0, f64::INFINITY).up(f64::sqrt)
    }
    fn signum(self) -> Interval {
        self.up(f64::signum)
    }
    fn sinh(self) -> Interval {
        self.up(f64::sinh)
    }
    fn cosh(self) -> Interval {
        self.abs().up(f64::cosh)
    }
    fn tanh(self) -> Interval {
        self.up(f64::tanh)
    }
    fn asinh(self) -> Interval {
        self.up(f64::asinh)
    }
    fn acosh(self) -> Interval {
        self.clamp_domain(1.0, f64::INFINITY).up(f64::acosh)
    }
    fn atanh(self) -> Interval {
        self.clamp_domain(-1.0, 1.0).up(f64::atanh)
    }
    fn floor(self) -> Interval {
        self.up(f64::floor)
    }
    fn ceil(self) -> Interval {
        self.up(f64::ceil)
    }
    fn round(self) -> Interval {
        self.up(f64::round)
    }
    fn trunc(self) -> Interval {
        self.up(f64::trunc)
    }
    fn fract(self) -> Interval {
        // Rust's fract keeps the sign: it rises from trunc to trunc
        if self.lo.trunc() == self.hi.trunc() && (self.lo >= 0.0) == (self.hi >= 0.0) {
            self.up(f64::fract)
        } else {
            Interval::new(-1.0, 1.0)
        }
    }
    fn exp(self) -> Interval {
        self.up(f64::exp)
    }
    fn cbrt(self) -> Interval {
        self.up(f64::cbrt)
    }
    fn ln(self) -> Interval {
        self.clamp_domain(0.0, f64::INFINITY).up(f64::ln)
    }
    fn is_nan(self) -> bool {
        Interval::is_nan(self)
    }
    fn powf(self, n: Interval) -> Interval {
        if n.lo == n.hi {
            let p = n.lo;
            if p.fract() == 0.0 && p.abs() <= i32::MAX as f64 {
                return self.pow_int(p as i64);
            }
            // a fractional power needs a base ≥ 0
            let b = self.clamp_domain(0.0, f64::INFINITY);
            return if p > 0.0 {
                b.up(|x| x.powf(p))
            } else {
                b.down(|x| x.powf(p))
            };
        }
        (n * self.ln()).exp()
    }
    fn log(self, base: Interval) -> Interval {
        self.ln() / base.ln()
    }
    fn min(self, n: Interval) -> Interval {
        Interval::new(self.lo.min(n.lo), self.hi.min(n.hi))
    }
    fn max(self, n: Interval) -> Interval {
        Interval::new(self.lo.max(n.lo), self.hi.max(n.hi))
    }
    fn atan2(self, x: Interval) -> Interval {
        let y = self;
        if x.lo > 0.0 {
            return (y / x).atan();
        }
        // a box off the origin and off the branch cut (the negative x axis): the polar
        // angle's extremes are at corners
        let on_cut = x.lo <= 0.0 && y.contains(0.0);
        if on_cut || y.is_nan() || x.is_nan() {
            return Interval::new(-PI, PI);
        }
        Interval::hull(&[
            y.lo.atan2(x.lo),
            y.lo.atan2(x.hi),
            y.hi.atan2(x.lo),
            y.hi.atan2(x.hi),
        ])
    }
    fn powi(self, n: i32) -> Interval {
        self.pow_int(n as i64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use exmex::num::Float;

    /// Every function's enclosure holds its values at 2001 points of the interval, over
    /// intervals chosen to cross the functions' crests, poles, kinks and domain edges.
    #[test]
    fn enclosures_hold_the_sampled_values() {
        type F = (&'static str, fn(Interval) -> Interval, fn(f64) -> f64);
        let funcs: [F; 18] = [
            ("sin", Float::sin, f64::sin),
            ("cos", Float::cos, f64::cos),
            ("tan", Float::tan, f64::tan),
            ("abs", Float::abs, f64::abs),
            ("exp", Float::exp, f64::exp),
            ("sqrt", Float::sqrt, f64::sqrt),
            ("ln", Float::ln, f64::ln),
            ("atan", Float::atan, f64::atan),
            ("asin", Float::asin, f64::asin),
            ("acos", Float::acos, f64::acos),
            ("signum", Float::signum, f64::signum),
            ("floor", Float::floor, f64::floor),
            ("fract", Float::fract, f64::fract),
            ("cosh", Float::cosh, f64::cosh),
            ("tanh", Float::tanh, f64::tanh),
            ("sq", |x| x.powi(2), |x| x * x),
            ("cube", |x| x.powf(Interval::point(3.0)), |x| x * x * x),
            ("inv", |x| Interval::point(1.0) / x, |x| 1.0 / x),
        ];
        let spans = [
            (-0.3, 0.2),
            (1.2, 1.9),
            (1.5, 4.8),
            (-7.0, -4.0),
            (0.0, 0.5),
            (2.3, 2.31),
            (-1e-9, 1e-9),
            (10.0, 30.0),
        ];
        for (name, fi, ff) in funcs {
            for (a, b) in spans {
                let r = fi(Interval::new(a, b));
                for k in 0..=2000 {
                    let x = a + (b - a) * k as f64 / 2000.0;
                    let v = ff(x);
                    if v.is_nan() || r.is_nan() {
                        continue;
                    }
                    let slack = 1e-12 * v.abs().max(1.0);
                    assert!(
                        r.lo - slack <= v && v <= r.hi + slack,
                        "{name} on [{a}, {b}] at {x}: {v} outside [{}, {}]",
                        r.lo,
                        r.hi
                    );
                }
            }
        }
    }

    /// Tight where it matters to the load check: a smooth pulse over part of its crest,
    /// and a factor that is exactly zero past a switch stays exactly zero.
    #[test]
    fn enclosures_are_tight_on_monotone_pieces_and_exact_on_switched_off_factors() {
        let t = Interval::new(0.01, 0.02);
        let s = (t * Interval::point(PI / 0.05)).sin().powi(2);
        let (a, b) = (
            (0.01 * PI / 0.05).sin().powi(2),
            (0.02 * PI / 0.05).sin().powi(2),
        );
        assert!(
            (s.lo - a).abs() < 1e-15 && (s.hi - b).abs() < 1e-15,
            "{s:?}"
        );
        let past = Interval::new(0.06, 0.07);
        let off = Interval::point(1.0) - (past - Interval::point(0.05)).signum();
        let z = off * (past * Interval::point(1e9)).sin().powi(2);
        assert_eq!((z.lo, z.hi), (0.0, 0.0));
    }

    #[test]
    fn atan2_encloses_the_angle_off_the_cut_and_is_whole_across_it() {
        let y = Interval::new(0.5, 1.0);
        let x = Interval::new(-1.0, 0.5);
        let r = y.atan2(x);
        for (yy, xx) in [(0.5, -1.0), (1.0, 0.5), (0.75, 0.0), (0.5, 0.5)] {
            let v = f64::atan2(yy, xx);
            assert!(r.lo - 1e-15 <= v && v <= r.hi + 1e-15, "{v} {r:?}");
        }
        let across = Interval::new(-0.1, 0.1).atan2(Interval::new(-2.0, -1.0));
        assert_eq!((across.lo, across.hi), (-PI, PI));
    }
}
