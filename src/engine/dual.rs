//! Forward-mode derivatives: a value with its partial derivatives in `K` inputs.
//!
//! The tape ([`crate::engine::tape`]) records one node per operation on a whole array. For a
//! long element-wise expression of a few inputs (a pair's reward terms) it is cheaper to run
//! the generic equation once per element on [`Dual`] numbers and keep only the `K` partial
//! derivatives: [`crate::engine::tape::Var::pairwise`].

use crate::num::Num;

/// `v` and `d[i] = dv / d input_i`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dual<const K: usize> {
    /// The value.
    pub v: f64,
    /// Its partial derivatives.
    pub d: [f64; K],
}

impl<const K: usize> Dual<K> {
    /// Input `i` of value `v`.
    pub fn input(v: f64, i: usize) -> Self {
        let mut d = [0.0; K];
        d[i] = 1.0;
        Dual { v, d }
    }

    fn constant(v: f64) -> Self {
        Dual { v, d: [0.0; K] }
    }

    /// `f(v)` of derivative `slope` at `v` (a derivative of 0 stays 0, even where the slope is
    /// infinite).
    fn chain(self, v: f64, slope: f64) -> Self {
        Dual {
            v,
            d: self.d.map(|d| if d == 0.0 { 0.0 } else { d * slope }),
        }
    }

    /// `self` where it compares to `o` as `keep`, `o` otherwise (with `pick`'s value, for a
    /// NaN), both halves on a tie: the minimum or the maximum.
    fn extreme(&self, o: &Self, keep: std::cmp::Ordering, pick: fn(f64, f64) -> f64) -> Self {
        match self.v.partial_cmp(&o.v) {
            Some(order) if order == keep => *self,
            Some(std::cmp::Ordering::Equal) => self.combine(*o, self.v, 0.5, 0.5),
            _ => Dual {
                v: pick(self.v, o.v),
                ..*o
            },
        }
    }

    fn combine(self, o: Self, v: f64, da: f64, db: f64) -> Self {
        let mut d = [0.0; K];
        for ((d, a), b) in d.iter_mut().zip(self.d).zip(o.d) {
            *d = a * da + b * db;
        }
        Dual { v, d }
    }
}

impl<const K: usize> Num for Dual<K> {
    fn full(&self, c: f64) -> Self {
        Dual::constant(c)
    }
    fn add(&self, o: &Self) -> Self {
        self.combine(*o, self.v + o.v, 1.0, 1.0)
    }
    fn sub(&self, o: &Self) -> Self {
        self.combine(*o, self.v - o.v, 1.0, -1.0)
    }
    fn mul(&self, o: &Self) -> Self {
        self.combine(*o, self.v * o.v, o.v, self.v)
    }
    fn div(&self, o: &Self) -> Self {
        let q = self.v / o.v;
        self.combine(*o, q, 1.0 / o.v, -q / o.v)
    }
    fn add_c(&self, c: f64) -> Self {
        Dual {
            v: self.v + c,
            d: self.d,
        }
    }
    fn mul_c(&self, c: f64) -> Self {
        self.chain(self.v * c, c)
    }
    fn abs(&self) -> Self {
        let sign = if self.v > 0.0 {
            1.0
        } else if self.v < 0.0 {
            -1.0
        } else {
            0.0
        };
        self.chain(self.v.abs(), sign)
    }
    fn sqrt(&self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, 0.5 / s)
    }
    fn sin(&self) -> Self {
        self.chain(self.v.sin(), self.v.cos())
    }
    fn cos(&self) -> Self {
        self.chain(self.v.cos(), -self.v.sin())
    }
    fn tan(&self) -> Self {
        let t = self.v.tan();
        self.chain(t, 1.0 + t * t)
    }
    fn atan(&self) -> Self {
        self.chain(self.v.atan(), 1.0 / (1.0 + self.v * self.v))
    }
    // Ties share the derivative, as the tape's minimum and maximum do.
    fn min(&self, o: &Self) -> Self {
        self.extreme(o, std::cmp::Ordering::Less, f64::min)
    }
    fn max(&self, o: &Self) -> Self {
        self.extreme(o, std::cmp::Ordering::Greater, f64::max)
    }
    fn clamp_c(&self, lo: f64, hi: f64) -> Self {
        let slope = if (lo..=hi).contains(&self.v) { 1.0 } else { 0.0 };
        self.chain(self.v.clamp(lo, hi), slope)
    }
    fn gt(&self, o: &Self) -> Self {
        Dual::constant(if self.v > o.v { 1.0 } else { 0.0 })
    }
    fn select(mask: &Self, a: &Self, b: &Self) -> Self {
        if mask.v > 0.5 { *a } else { *b }
    }
    fn recip(&self) -> Self {
        let r = 1.0 / self.v;
        self.chain(r, -r * r)
    }
    fn square(&self) -> Self {
        self.chain(self.v * self.v, 2.0 * self.v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partial_derivatives_of_a_pair_term_match_finite_differences() {
        // -1 / (sqrt(a b) (a - b)^2 + 0.1) at (a, b) = (2, 3.5): d/da and d/db by central
        // differences of the plain f64 evaluation.
        let f = |a: f64, b: f64| -1.0 / ((a * b).sqrt() * (a - b).powi(2) + 0.1);
        let (a, b) = (Dual::<2>::input(2.0, 0), Dual::<2>::input(3.5, 1));
        let out = a.mul(&b).sqrt().mul(&a.sub(&b).square()).add_c(0.1).recip().neg();
        assert!((out.v - f(2.0, 3.5)).abs() < 1e-15);
        let h = 1e-6;
        let da = (f(2.0 + h, 3.5) - f(2.0 - h, 3.5)) / (2.0 * h);
        let db = (f(2.0, 3.5 + h) - f(2.0, 3.5 - h)) / (2.0 * h);
        assert!((out.d[0] - da).abs() < 1e-8, "{} vs {da}", out.d[0]);
        assert!((out.d[1] - db).abs() < 1e-8, "{} vs {db}", out.d[1]);
    }

    #[test]
    fn min_max_and_masks_route_the_derivative() {
        let (a, b) = (Dual::<2>::input(1.0, 0), Dual::<2>::input(4.0, 1));
        assert_eq!(a.min(&b).d, [1.0, 0.0]);
        assert_eq!(a.max(&b).d, [0.0, 1.0]);
        assert_eq!(a.min(&a.full(1.0)).d, [0.5, 0.0]);
        assert_eq!(Dual::select(&a.gt(&b), &a, &b).d, [0.0, 1.0]);
        assert_eq!(a.sub(&a).abs().d, [0.0, 0.0]);
        assert_eq!(a.clamp_c(2.0, 3.0).v, 2.0);
        assert_eq!(a.clamp_c(2.0, 3.0).d, [0.0, 0.0]);
    }
}
