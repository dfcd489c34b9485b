//! One set of equations, three number types.
//!
//! The dynamics (eq. 1), the feasibility bounds, IDM and the reward terms are written once,
//! generically over [`Num`]. `f64` runs them per agent in the fast scalar engine (evaluation,
//! replay, co-simulation, the MPG check); [`crate::engine::tape::Var`] runs them on whole
//! `[batch, agents]` arrays with reverse-mode derivatives for training, and
//! [`crate::engine::dual::Dual`] element by element with forward-mode ones (a pair's terms in
//! one pass). Masks are numbers: 1.0 where a condition holds, else 0.0.

/// Element-wise arithmetic shared by `f64` and the training rollout's numbers.
pub trait Num: Sized + Clone {
    /// A value of the same shape (and device/kind) as `self`, filled with `c`.
    fn full(&self, c: f64) -> Self;
    /// `self + o`.
    fn add(&self, o: &Self) -> Self;
    /// `self - o`.
    fn sub(&self, o: &Self) -> Self;
    /// `self * o`.
    fn mul(&self, o: &Self) -> Self;
    /// `self / o`.
    fn div(&self, o: &Self) -> Self;
    /// `self + c`.
    fn add_c(&self, c: f64) -> Self;
    /// `self * c`.
    fn mul_c(&self, c: f64) -> Self;
    /// `|self|`.
    fn abs(&self) -> Self;
    /// Square root.
    fn sqrt(&self) -> Self;
    /// Sine.
    fn sin(&self) -> Self;
    /// Cosine.
    fn cos(&self) -> Self;
    /// Tangent.
    fn tan(&self) -> Self;
    /// Arc tangent.
    fn atan(&self) -> Self;
    /// Element-wise minimum.
    fn min(&self, o: &Self) -> Self;
    /// Element-wise maximum.
    fn max(&self, o: &Self) -> Self;
    /// Clamp into `[lo, hi]`.
    fn clamp_c(&self, lo: f64, hi: f64) -> Self;
    /// Mask: 1.0 where `self > o`, else 0.0 (no gradient).
    fn gt(&self, o: &Self) -> Self;
    /// `mask ? a : b`, element-wise (mask as produced by [`Num::gt`]).
    fn select(mask: &Self, a: &Self, b: &Self) -> Self;

    /// `self * self`.
    fn square(&self) -> Self {
        self.mul(self)
    }
    /// `-self`.
    fn neg(&self) -> Self {
        self.mul_c(-1.0)
    }
    /// `1 / self`.
    fn recip(&self) -> Self {
        self.full(1.0).div(self)
    }
    /// Mask: 1.0 where `self > c`.
    fn gt_c(&self, c: f64) -> Self {
        self.gt(&self.full(c))
    }
}

impl Num for f64 {
    fn full(&self, c: f64) -> Self {
        c
    }
    fn add(&self, o: &Self) -> Self {
        self + o
    }
    fn sub(&self, o: &Self) -> Self {
        self - o
    }
    fn mul(&self, o: &Self) -> Self {
        self * o
    }
    fn div(&self, o: &Self) -> Self {
        self / o
    }
    fn add_c(&self, c: f64) -> Self {
        self + c
    }
    fn mul_c(&self, c: f64) -> Self {
        self * c
    }
    fn abs(&self) -> Self {
        f64::abs(*self)
    }
    fn sqrt(&self) -> Self {
        f64::sqrt(*self)
    }
    fn sin(&self) -> Self {
        f64::sin(*self)
    }
    fn cos(&self) -> Self {
        f64::cos(*self)
    }
    fn tan(&self) -> Self {
        f64::tan(*self)
    }
    fn atan(&self) -> Self {
        f64::atan(*self)
    }
    fn min(&self, o: &Self) -> Self {
        f64::min(*self, *o)
    }
    fn max(&self, o: &Self) -> Self {
        f64::max(*self, *o)
    }
    fn clamp_c(&self, lo: f64, hi: f64) -> Self {
        f64::clamp(*self, lo, hi)
    }
    fn gt(&self, o: &Self) -> Self {
        if self > o { 1.0 } else { 0.0 }
    }
    fn select(mask: &Self, a: &Self, b: &Self) -> Self {
        if *mask > 0.5 { *a } else { *b }
    }
}
