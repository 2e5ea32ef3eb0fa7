//! Scalars for the element functions: plain `f64`, and a hyper-dual number that carries
//! two first-order directional derivatives and their mixed second derivative.
//!
//! The element's kinematics are written once, generic over [`Real`]; evaluated in `f64`
//! they give values, in [`HyperDual`] they give exact (to round-off) first and second
//! directional derivatives, so the internal force, the consistent tangent, the
//! configuration-dependent mass matrix and the quadratic-velocity terms all come from the
//! same formulas as the strain energy and the position field, with no hand-derived
//! Hessians to get wrong.

use std::ops::{Add, Div, Mul, Neg, Sub};

pub trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// The plain numbers this scalar's values are made of: `f64`, or [`F4`] when four
    /// elements are evaluated at once. Element constants (lengths, stiffnesses) are
    /// computed in it and lifted, so a constant's bits do not depend on the scalar.
    type Base: Lane;
    /// `v` in every lane, no derivative
    fn cst(v: f64) -> Self;
    /// `self · a + b`, rounded once where the build has FMA (x86-64-v3), else twice: every
    /// number type of one build rounds it the same way, so lanes, duals and jets keep the
    /// bits of the plain `f64` evaluation.
    fn madd(self, a: Self, b: Self) -> Self;
    /// `b` as this scalar, no derivative
    fn lift(b: Self::Base) -> Self;
    fn sqrt(self) -> Self;
}

/// A plain number type the element code runs on: `f64`, or [`F4`], four elements in SIMD
/// lanes. Every lane of an [`F4`] operation is the IEEE operation `f64` does (add, sub,
/// mul, div, sqrt are correctly rounded, neg flips the sign bit), so a lane's result is
/// bit-identical to the `f64` evaluation of that element alone.
pub trait Lane: Real<Base = Self> + Default + Send + Sync + 'static {
    const WIDTH: usize;
    /// The bits of `self` where `mask`'s are set: `mask` all ones keeps a lane, all zeros
    /// makes it +0.0 (a lane at rest gets the exact zero its scalar evaluation has).
    fn keep(self, mask: Self) -> Self;
}

impl Real for f64 {
    type Base = f64;
    #[inline(always)]
    fn cst(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn lift(b: f64) -> Self {
        b
    }
    #[inline(always)]
    fn madd(self, a: f64, b: f64) -> f64 {
        #[cfg(target_feature = "fma")]
        {
            f64::mul_add(self, a, b)
        }
        #[cfg(not(target_feature = "fma"))]
        {
            self * a + b
        }
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
}
impl Lane for f64 {
    const WIDTH: usize = 1;
    #[inline(always)]
    fn keep(self, mask: f64) -> f64 {
        f64::from_bits(self.to_bits() & mask.to_bits())
    }
}

/// Four f64 lanes (AVX on x86-64-v3, two SSE2 halves on a baseline build).
pub type F4 = wide::f64x4;

impl Real for F4 {
    type Base = F4;
    #[inline(always)]
    fn cst(v: f64) -> Self {
        F4::splat(v)
    }
    #[inline(always)]
    fn lift(b: F4) -> Self {
        b
    }
    #[inline(always)]
    fn madd(self, a: F4, b: F4) -> F4 {
        // wide fuses exactly when AVX and FMA are both enabled; FMA implies AVX on x86
        #[cfg(target_feature = "fma")]
        {
            F4::mul_add(self, a, b)
        }
        #[cfg(not(target_feature = "fma"))]
        {
            self * a + b
        }
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        F4::sqrt(self)
    }
}
impl Lane for F4 {
    const WIDTH: usize = 4;
    #[inline(always)]
    fn keep(self, mask: F4) -> F4 {
        self & mask
    }
}

/// v + a ε₁ + b ε₂ + ab ε₁ε₂ with ε₁² = ε₂² = 0.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HyperDual {
    pub v: f64,
    pub a: f64,
    pub b: f64,
    pub ab: f64,
}

impl HyperDual {
    #[inline]
    pub fn new(v: f64, a: f64, b: f64, ab: f64) -> Self {
        HyperDual { v, a, b, ab }
    }
    /// apply a scalar function given its value and first two derivatives at `self.v`
    #[inline]
    fn lift(self, f: f64, f1: f64, f2: f64) -> Self {
        HyperDual {
            v: f,
            a: f1 * self.a,
            b: f1 * self.b,
            ab: f1 * self.ab + f2 * self.a * self.b,
        }
    }
}

impl Add for HyperDual {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        HyperDual::new(self.v + o.v, self.a + o.a, self.b + o.b, self.ab + o.ab)
    }
}
impl Sub for HyperDual {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        HyperDual::new(self.v - o.v, self.a - o.a, self.b - o.b, self.ab - o.ab)
    }
}
impl Neg for HyperDual {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        HyperDual::new(-self.v, -self.a, -self.b, -self.ab)
    }
}
impl Mul for HyperDual {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        HyperDual::new(
            self.v * o.v,
            self.v.madd(o.a, self.a * o.v),
            self.v.madd(o.b, self.b * o.v),
            self.ab
                .madd(o.v, self.v.madd(o.ab, self.a * o.b) + self.b * o.a),
        )
    }
}
impl Div for HyperDual {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        self * o.lift(inv, -inv * inv, 2.0 * inv * inv * inv)
    }
}

impl Real for HyperDual {
    type Base = f64;
    #[inline]
    fn cst(v: f64) -> Self {
        HyperDual::new(v, 0.0, 0.0, 0.0)
    }
    #[inline]
    fn lift(b: f64) -> Self {
        HyperDual::new(b, 0.0, 0.0, 0.0)
    }
    #[inline]
    fn madd(self, a: Self, b: Self) -> Self {
        HyperDual::new(
            self.v.madd(a.v, b.v),
            self.v.madd(a.a, self.a.madd(a.v, b.a)),
            self.v.madd(a.b, self.b.madd(a.v, b.b)),
            self.ab
                .madd(a.v, self.v.madd(a.ab, self.a * a.b) + self.b * a.a + b.ab),
        )
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.lift(s, 0.5 / s, -0.25 / (s * self.v))
    }
}

/// A second-order jet v + d ε + dd ε²/2 along one direction: the [`HyperDual`] along
/// (u, u) without the duplicate lane. Each operation does [`HyperDual`]'s operations in
/// the same order with a = b = d, so `dd` is bit-identical to the hyper-dual `ab` along
/// (u, u) at about two thirds of its arithmetic. Generic over the lanes ([`Lane`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Jet2<T = f64> {
    pub v: T,
    pub d: T,
    pub dd: T,
}

impl<T: Lane> Jet2<T> {
    #[inline(always)]
    pub fn new(v: T, d: T, dd: T) -> Self {
        Jet2 { v, d, dd }
    }
    /// apply a scalar function given its value and first two derivatives at `self.v`
    #[inline(always)]
    fn lift_fn(self, f: T, f1: T, f2: T) -> Self {
        Jet2 {
            v: f,
            d: f1 * self.d,
            dd: f1 * self.dd + f2 * self.d * self.d,
        }
    }
}

impl<T: Lane> Add for Jet2<T> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Jet2::new(self.v + o.v, self.d + o.d, self.dd + o.dd)
    }
}
impl<T: Lane> Sub for Jet2<T> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Jet2::new(self.v - o.v, self.d - o.d, self.dd - o.dd)
    }
}
impl<T: Lane> Neg for Jet2<T> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Jet2::new(-self.v, -self.d, -self.dd)
    }
}
impl<T: Lane> Mul for Jet2<T> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        // the hyper-dual product's operations along (u, u), in its order
        let cross = self.d * o.d;
        Jet2::new(
            self.v * o.v,
            self.v.madd(o.d, self.d * o.v),
            self.dd.madd(o.v, self.v.madd(o.dd, cross) + cross),
        )
    }
}
impl<T: Lane> Div for Jet2<T> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let inv = T::cst(1.0) / o.v;
        self * o.lift_fn(inv, -inv * inv, T::cst(2.0) * inv * inv * inv)
    }
}

impl<T: Lane> Real for Jet2<T> {
    type Base = T;
    #[inline(always)]
    fn cst(v: f64) -> Self {
        Jet2::new(T::cst(v), T::cst(0.0), T::cst(0.0))
    }
    #[inline(always)]
    fn lift(b: T) -> Self {
        Jet2::new(b, T::cst(0.0), T::cst(0.0))
    }
    #[inline(always)]
    fn madd(self, a: Self, b: Self) -> Self {
        let cross = self.d * a.d;
        Jet2::new(
            self.v.madd(a.v, b.v),
            self.v.madd(a.d, self.d.madd(a.v, b.d)),
            self.dd.madd(a.v, self.v.madd(a.dd, cross) + cross + b.dd),
        )
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.lift_fn(s, T::cst(0.5) / s, T::cst(-0.25) / (s * self.v))
    }
}

pub type V3<R> = [R; 3];
/// row-major 3x3; columns are frame axes
pub type M3<R> = [[R; 3]; 3];

#[inline(always)]
pub fn vadd<R: Real>(a: V3<R>, b: V3<R>) -> V3<R> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline(always)]
pub fn vsub<R: Real>(a: V3<R>, b: V3<R>) -> V3<R> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
pub fn vscale<R: Real>(a: V3<R>, s: R) -> V3<R> {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline(always)]
pub fn vdot<R: Real>(a: V3<R>, b: V3<R>) -> R {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
pub fn vcross<R: Real>(a: V3<R>, b: V3<R>) -> V3<R> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline(always)]
pub fn mcol<R: Real>(m: &M3<R>, j: usize) -> V3<R> {
    [m[0][j], m[1][j], m[2][j]]
}
#[inline(always)]
pub fn mvec<R: Real>(m: &M3<R>, v: V3<R>) -> V3<R> {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

/// v + d ε with ε² = 0: one directional derivative. Generic over the lanes ([`Lane`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dual<T = f64> {
    pub v: T,
    pub d: T,
}

impl<T: Lane> Dual<T> {
    #[inline(always)]
    pub fn new(v: T, d: T) -> Self {
        Dual { v, d }
    }
}

impl<T: Lane> Add for Dual<T> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Dual::new(self.v + o.v, self.d + o.d)
    }
}
impl<T: Lane> Sub for Dual<T> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Dual::new(self.v - o.v, self.d - o.d)
    }
}
impl<T: Lane> Neg for Dual<T> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Dual::new(-self.v, -self.d)
    }
}
impl<T: Lane> Mul for Dual<T> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Dual::new(self.v * o.v, self.v.madd(o.d, self.d * o.v))
    }
}
impl<T: Lane> Div for Dual<T> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        // the value divides as f64 does, so a dual pass's values are bit-identical to
        // the plain f64 pass (the inertia takes g from the pass that also gives ġ)
        let inv = T::cst(1.0) / o.v;
        Dual::new(self.v / o.v, (self.d * o.v - self.v * o.d) * inv * inv)
    }
}
impl<T: Lane> Real for Dual<T> {
    type Base = T;
    #[inline(always)]
    fn cst(v: f64) -> Self {
        Dual::new(T::cst(v), T::cst(0.0))
    }
    #[inline(always)]
    fn lift(b: T) -> Self {
        Dual::new(b, T::cst(0.0))
    }
    #[inline(always)]
    fn madd(self, a: Self, b: Self) -> Self {
        Dual::new(
            self.v.madd(a.v, b.v),
            self.v.madd(a.d, self.d.madd(a.v, b.d)),
        )
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        Dual::new(s, T::cst(0.5) * self.d / s)
    }
}

/// v + Σₖ dₖ εₖ (εᵢεⱼ = 0): N directional derivatives carried together, so one pass of
/// the generic element code gives a whole Jacobian (N = 12: every element dof). Each lane
/// does exactly the arithmetic of a [`Dual`] pass along its direction, so the results are
/// bit-identical to N separate passes; the value is computed once instead of N times, and
/// the lane loops are straight-line array arithmetic that the compiler vectorises.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DualVec<const N: usize> {
    pub v: f64,
    pub d: [f64; N],
}

impl<const N: usize> DualVec<N> {
    #[inline]
    pub fn new(v: f64, d: [f64; N]) -> Self {
        DualVec { v, d }
    }
}

impl<const N: usize> Add for DualVec<N> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        DualVec::new(self.v + o.v, std::array::from_fn(|k| self.d[k] + o.d[k]))
    }
}
impl<const N: usize> Sub for DualVec<N> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        DualVec::new(self.v - o.v, std::array::from_fn(|k| self.d[k] - o.d[k]))
    }
}
impl<const N: usize> Neg for DualVec<N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        DualVec::new(-self.v, self.d.map(|x| -x))
    }
}
// the product rule adds inside a multiplication
#[allow(clippy::suspicious_arithmetic_impl)]
impl<const N: usize> Mul for DualVec<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        DualVec::new(
            self.v * o.v,
            std::array::from_fn(|k| self.v.madd(o.d[k], self.d[k] * o.v)),
        )
    }
}
// the product rule adds inside a multiplication
#[allow(clippy::suspicious_arithmetic_impl)]
impl<const N: usize> Div for DualVec<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        DualVec::new(
            self.v / o.v,
            std::array::from_fn(|k| (self.d[k] * o.v - self.v * o.d[k]) * inv * inv),
        )
    }
}
impl<const N: usize> Real for DualVec<N> {
    type Base = f64;
    #[inline]
    fn cst(v: f64) -> Self {
        DualVec::new(v, [0.0; N])
    }
    #[inline]
    fn lift(b: f64) -> Self {
        DualVec::new(b, [0.0; N])
    }
    #[inline]
    fn madd(self, a: Self, b: Self) -> Self {
        DualVec::new(
            self.v.madd(a.v, b.v),
            std::array::from_fn(|k| self.v.madd(a.d[k], self.d[k].madd(a.v, b.d[k]))),
        )
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        DualVec::new(s, self.d.map(|x| 0.5 * x / s))
    }
}
