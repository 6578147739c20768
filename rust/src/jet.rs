//! Second-order jets: a value with its first and second time derivatives, carried through
//! arithmetic by the chain rule (forward-mode differentiation). The controller's belief
//! about a curved surface (SPEC §15) evaluates X_d = p + x_a n̂(p) on jets, so Ẋ_d and Ẍ_d
//! are the exact derivatives of the reference it follows, not finite differences.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// x, ẋ, ẍ.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Jet {
    pub v: f64,
    pub d: f64,
    pub dd: f64,
}

/// What a geometry written once for values and for jets needs: `f64` and [`Jet`].
pub trait Smooth:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Mul<f64, Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// A constant.
    fn constant(x: f64) -> Self;
    /// The value (a jet's x).
    fn value(self) -> f64;
    fn sqrt(self) -> Self;
    /// The largest |component| (a value's |x|; a jet's largest of |x|, |ẋ|, |ẍ|), for
    /// convergence tests that must cover the derivatives too. NaN if any is NaN.
    fn magnitude(self) -> f64;
}

impl Smooth for f64 {
    #[inline(always)]
    fn constant(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn value(self) -> f64 {
        self
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn magnitude(self) -> f64 {
        self.abs()
    }
}

impl Jet {
    pub fn new(v: f64, d: f64, dd: f64) -> Self {
        Self { v, d, dd }
    }
}

impl Smooth for Jet {
    #[inline(always)]
    fn constant(x: f64) -> Self {
        Self::new(x, 0.0, 0.0)
    }
    #[inline(always)]
    fn value(self) -> f64 {
        self.v
    }
    /// r = √a: ṙ = ȧ / 2r, r̈ = (ä − 2ṙ²) / 2r.
    #[inline(always)]
    fn sqrt(self) -> Self {
        let v = self.v.sqrt();
        let d = self.d / (2.0 * v);
        Self::new(v, d, (self.dd - 2.0 * d * d) / (2.0 * v))
    }
    #[inline(always)]
    fn magnitude(self) -> f64 {
        let m = self.v.abs().max(self.d.abs()).max(self.dd.abs());
        if self.v.is_nan() || self.d.is_nan() || self.dd.is_nan() {
            f64::NAN
        } else {
            m
        }
    }
}

impl Add for Jet {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.v + o.v, self.d + o.d, self.dd + o.dd)
    }
}

impl Sub for Jet {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::new(self.v - o.v, self.d - o.d, self.dd - o.dd)
    }
}

impl Neg for Jet {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self::new(-self.v, -self.d, -self.dd)
    }
}

impl Mul for Jet {
    type Output = Self;
    /// (ab)˙ = ȧb + aḃ, (ab)¨ = äb + 2ȧḃ + ab̈.
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self::new(
            self.v * o.v,
            self.d * o.v + self.v * o.d,
            self.dd * o.v + 2.0 * self.d * o.d + self.v * o.dd,
        )
    }
}

impl Mul<f64> for Jet {
    type Output = Self;
    /// A jet times a constant: the product with `Jet::constant(k)` without its zero terms.
    #[inline(always)]
    fn mul(self, k: f64) -> Self {
        Self::new(self.v * k, self.d * k, self.dd * k)
    }
}

impl Div for Jet {
    type Output = Self;
    /// q = a/b: q̇ = (ȧ − q ḃ)/b, q̈ = (ä − 2q̇ḃ − q b̈)/b.
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let v = self.v / o.v;
        let d = (self.d - v * o.d) / o.v;
        Self::new(v, d, (self.dd - 2.0 * d * o.d - v * o.dd) / o.v)
    }
}

/// A 3-vector of jets or values.
pub type V3<S> = [S; 3];

#[inline(always)]
pub fn dot<S: Smooth>(a: &V3<S>, b: &V3<S>) -> S {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
pub fn scaled<S: Smooth>(a: &V3<S>, k: S) -> V3<S> {
    [a[0] * k, a[1] * k, a[2] * k]
}

#[inline(always)]
pub fn plus<S: Smooth>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline(always)]
pub fn minus<S: Smooth>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// A constant vector.
#[inline(always)]
pub fn constant<S: Smooth>(a: &nalgebra::Vector3<f64>) -> V3<S> {
    [S::constant(a[0]), S::constant(a[1]), S::constant(a[2])]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Jets against the closed-form derivatives of f(t) = √(1 + t²) / (2 + t) at t = 0.7.
    #[test]
    fn chain_rule_matches_closed_forms() {
        let t = Jet::new(0.7, 1.0, 0.0);
        let one = Jet::constant(1.0);
        let f = (one + t * t).sqrt() / (Jet::constant(2.0) + t);
        let g = |t: f64| (1.0 + t * t).sqrt() / (2.0 + t);
        let h = 1e-4;
        let d = (g(0.7 + h) - g(0.7 - h)) / (2.0 * h);
        let dd = (g(0.7 + h) - 2.0 * g(0.7) + g(0.7 - h)) / (h * h);
        assert!((f.v - g(0.7)).abs() < 1e-15);
        assert!((f.d - d).abs() < 1e-8, "{} {d}", f.d);
        assert!((f.dd - dd).abs() < 1e-6, "{} {dd}", f.dd);
    }
}
