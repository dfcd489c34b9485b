//! One set of equations, two number types.
//!
//! The dynamics (eq. 1), the feasibility bounds, IDM and the reward terms are written once,
//! generically over [`Num`]. `f64` runs them per agent in the fast scalar engine (evaluation,
//! replay, co-simulation, the MPG check); `tch::Tensor` runs them on whole `[batch, agents]`
//! tensors with autograd for training. Masks are numbers: 1.0 where a condition holds, else 0.0.

use tch::Tensor;

/// Element-wise arithmetic shared by `f64` and `tch::Tensor`.
pub trait Num: Sized {
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

/// The operators both implementations spell the same way (`f64` and `Tensor` both implement
/// the `std::ops` traits on references).
macro_rules! arithmetic {
    () => {
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
    };
}

impl Num for f64 {
    fn full(&self, c: f64) -> Self {
        c
    }
    arithmetic!();
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

impl Num for Tensor {
    fn full(&self, c: f64) -> Self {
        self.full_like(c)
    }
    arithmetic!();
    fn abs(&self) -> Self {
        Tensor::abs(self)
    }
    fn sqrt(&self) -> Self {
        Tensor::sqrt(self)
    }
    fn sin(&self) -> Self {
        Tensor::sin(self)
    }
    fn cos(&self) -> Self {
        Tensor::cos(self)
    }
    fn tan(&self) -> Self {
        Tensor::tan(self)
    }
    fn atan(&self) -> Self {
        Tensor::atan(self)
    }
    fn min(&self, o: &Self) -> Self {
        self.minimum(o)
    }
    fn max(&self, o: &Self) -> Self {
        self.maximum(o)
    }
    fn clamp_c(&self, lo: f64, hi: f64) -> Self {
        self.clamp(lo, hi)
    }
    fn gt(&self, o: &Self) -> Self {
        self.gt_tensor(o).to_kind(self.kind()).detach()
    }
    fn select(mask: &Self, a: &Self, b: &Self) -> Self {
        a.where_self(&mask.gt(0.5), b)
    }
    fn recip(&self) -> Self {
        self.reciprocal() // one operation instead of two
    }
}
