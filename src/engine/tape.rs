//! Reverse-mode differentiation of `[rows, cols]` arrays of `f64`: the number type of the
//! training rollout.
//!
//! Training's arrays are small (tens of scenarios of a few players), so the cost of a rollout
//! is the number of operations, not their size. A libtorch operation with autograd costs a few
//! microseconds before it touches a number; an operation here is a plain loop plus one boxed
//! closure on a tape. [`Var`] implements [`Num`], so the generic equations of the world and the
//! game run on it unchanged.
//!
//! Each thread records on its own tape. [`start`] clears it; every operation with a tracked
//! operand appends a node; [`backward`] runs the nodes in reverse and returns the gradients of
//! the leaves ([`Var::leaf`]). An operand recorded before the last [`start`] counts as a
//! constant. Shapes broadcast in one way only: an operand of one column stands for every
//! column of the other.

use crate::engine::dual::Dual;
use crate::num::Num;
use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;

/// A node's backward step: from the gradient of its output, the gradient of each operand
/// (`None` for an operand without one).
type Backward = Box<dyn FnOnce(&[f64]) -> Vec<Option<Vec<f64>>>>;

struct Node {
    /// The recorded operands, in the order of the backward step's results.
    operands: Vec<Option<usize>>,
    /// `None` for a leaf.
    backward: Option<Backward>,
}

#[derive(Default)]
struct Tape {
    generation: u64,
    nodes: Vec<Node>,
}

thread_local! {
    static TAPE: RefCell<Tape> = RefCell::new(Tape::default());
}

/// Clears this thread's tape: values recorded before count as constants from now on.
pub fn start() {
    TAPE.with(|t| {
        let mut t = t.borrow_mut();
        t.generation += 1;
        t.nodes.clear();
    });
}

/// The number of operations recorded on this thread's tape since [`start`]: the memory a
/// backward pass will hold.
pub fn recorded() -> usize {
    TAPE.with(|t| t.borrow().nodes.len())
}

/// An array of `rows x cols` values (row-major), on this thread's tape when it depends on a
/// leaf.
#[derive(Debug, Clone)]
pub struct Var {
    value: Rc<Vec<f64>>,
    rows: usize,
    cols: usize,
    /// The node on the tape: (generation, index).
    node: Option<(u64, usize)>,
}

fn record(operands: &[&Var], backward: Option<Backward>) -> (u64, usize) {
    TAPE.with(|t| {
        let mut t = t.borrow_mut();
        let generation = t.generation;
        let operands = operands
            .iter()
            .map(|v| v.node.filter(|&(g, _)| g == generation).map(|(_, i)| i))
            .collect();
        t.nodes.push(Node { operands, backward });
        (generation, t.nodes.len() - 1)
    })
}

impl Var {
    /// A constant (no gradient).
    pub fn constant(value: Vec<f64>, rows: usize, cols: usize) -> Var {
        assert_eq!(value.len(), rows * cols, "values of a {rows} x {cols} array");
        Var {
            value: Rc::new(value),
            rows,
            cols,
            node: None,
        }
    }

    /// A leaf on this thread's tape: [`backward`] returns its gradient.
    pub fn leaf(value: Vec<f64>, rows: usize, cols: usize) -> Var {
        let mut v = Var::constant(value, rows, cols);
        v.node = Some(record(&[], None));
        v
    }

    /// A value computed outside the tape's operations from `operands`, with its own backward
    /// step (the gradient of each operand, in order, from the gradient of the value). Without
    /// a tracked operand it is a constant and `backward` is dropped.
    pub fn custom(
        operands: &[&Var],
        value: Vec<f64>,
        rows: usize,
        cols: usize,
        backward: impl FnOnce(&[f64]) -> Vec<Option<Vec<f64>>> + 'static,
    ) -> Var {
        let v = Var::constant(value, rows, cols);
        if operands.iter().any(|o| o.tracked()) {
            v.recorded(operands, backward)
        } else {
            v
        }
    }

    /// These values recorded on the tape as computed from `operands`, with the backward step
    /// of [`Var::custom`], even without a tracked operand: for a value that also depends on
    /// something the tape does not see (a network's weights, whose gradient `backward` keeps
    /// itself).
    pub fn recorded(
        mut self,
        operands: &[&Var],
        backward: impl FnOnce(&[f64]) -> Vec<Option<Vec<f64>>> + 'static,
    ) -> Var {
        self.node = Some(record(operands, Some(Box::new(backward))));
        self
    }

    /// Does the value depend on a leaf of the current tape?
    pub fn tracked(&self) -> bool {
        match self.node {
            Some((g, _)) => TAPE.with(|t| t.borrow().generation == g),
            None => false,
        }
    }

    /// The values, row-major.
    pub fn values(&self) -> &[f64] {
        &self.value
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// The same values without gradient.
    pub fn detach(&self) -> Var {
        Var {
            node: None,
            ..self.clone()
        }
    }

    /// `out[r, c] = self[r, index[r * cols + c]]`: a column of the same row for each element
    /// (the neighbours' values).
    pub fn gather_cols(&self, index: &Rc<[usize]>) -> Var {
        let (rows, src) = (self.rows, self.cols);
        let cols = index.len() / rows;
        let value = index
            .chunks(cols)
            .zip(self.value.chunks(src))
            .flat_map(|(index, row)| index.iter().map(|&c| row[c]))
            .collect();
        let index = index.clone();
        Var::custom(&[self], value, rows, cols, move |g| {
            let mut ga = vec![0.0; rows * src];
            for ((index, g), ga) in index.chunks(cols).zip(g.chunks(cols)).zip(ga.chunks_mut(src)) {
                for (&c, &g) in index.iter().zip(g) {
                    ga[c] += g;
                }
            }
            vec![Some(ga)]
        })
    }

    /// `out[r, p] = self[r, columns[p]]`.
    pub fn select_cols(&self, columns: &Rc<[usize]>) -> Var {
        let index: Vec<usize> = (0..self.rows).flat_map(|_| columns.iter().copied()).collect();
        self.gather_cols(&index.into())
    }

    /// `out[r, p] = f(r, p, [x_i, v_i, x_j, v_j])` for the pairs `p = (i, j)` of columns of
    /// two arrays of one shape, on [`Dual`] numbers: one node that keeps the four partial
    /// derivatives of each pair's value.
    pub fn pairwise(
        x: &Var,
        v: &Var,
        pairs: &Rc<[(usize, usize)]>,
        f: impl Fn(usize, usize, [Dual<4>; 4]) -> Dual<4>,
    ) -> Var {
        assert!(x.rows == v.rows && x.cols == v.cols, "two arrays of one shape");
        let (rows, n, np) = (x.rows, x.cols, pairs.len());
        let mut value = Vec::with_capacity(rows * np);
        let mut partials = Vec::with_capacity(rows * np * 4);
        for (r, (xr, vr)) in x.value.chunks(n).zip(v.value.chunks(n)).enumerate() {
            for (p, &(i, j)) in pairs.iter().enumerate() {
                let inputs = [xr[i], vr[i], xr[j], vr[j]];
                let out = f(r, p, std::array::from_fn(|k| Dual::input(inputs[k], k)));
                value.push(out.v);
                partials.extend_from_slice(&out.d);
            }
        }
        let pairs = pairs.clone();
        Var::custom(&[x, v], value, rows, np, move |g| {
            let (mut gx, mut gv) = (vec![0.0; rows * n], vec![0.0; rows * n]);
            let blocks = g.chunks(np).zip(partials.chunks(np * 4));
            for (r, (g, d)) in blocks.enumerate() {
                for ((&(i, j), &g), d) in pairs.iter().zip(g).zip(d.chunks(4)) {
                    gx[r * n + i] += g * d[0];
                    gv[r * n + i] += g * d[1];
                    gx[r * n + j] += g * d[2];
                    gv[r * n + j] += g * d[3];
                }
            }
            vec![Some(gx), Some(gv)]
        })
    }

    /// `out[r, i]`: the sum of `self[r, p]` over the pairs `p` that hold `i` (`n` columns).
    pub fn pair_sums(&self, pairs: &Rc<[(usize, usize)]>, n: usize) -> Var {
        let (rows, np) = (self.rows, self.cols);
        let mut value = vec![0.0; rows * n];
        for r in 0..rows {
            for (p, &(i, j)) in pairs.iter().enumerate() {
                let x = self.value[r * np + p];
                value[r * n + i] += x;
                value[r * n + j] += x;
            }
        }
        let pairs = pairs.clone();
        Var::custom(&[self], value, rows, n, move |g| {
            let mut ga = vec![0.0; rows * np];
            for r in 0..rows {
                for (p, &(i, j)) in pairs.iter().enumerate() {
                    ga[r * np + p] = g[r * n + i] + g[r * n + j];
                }
            }
            vec![Some(ga)]
        })
    }

    /// `[rows, 1]`: each row's sum.
    pub fn sum_cols(&self) -> Var {
        let (rows, cols) = (self.rows, self.cols);
        let value = self.value.chunks(cols).map(|r| r.iter().sum()).collect();
        Var::custom(&[self], value, rows, 1, move |g| {
            vec![Some((0..rows * cols).map(|k| g[k / cols]).collect())]
        })
    }

    /// `f(self)`, whose backward step `d(input, gradient)` reads the input.
    fn unary(&self, f: impl Fn(f64) -> f64, d: impl Fn(f64, f64) -> f64 + 'static) -> Var {
        let value = self.value.iter().map(|&a| f(a)).collect();
        let a = self.value.clone();
        Var::custom(&[self], value, self.rows, self.cols, move |g| {
            vec![Some(derivative(g, &a, d))]
        })
    }

    /// `f(self)`, whose backward step `d(output, gradient)` reads the output.
    fn unary_out(&self, f: impl Fn(f64) -> f64, d: impl Fn(f64, f64) -> f64 + 'static) -> Var {
        let out = Var::constant(self.value.iter().map(|&a| f(a)).collect(), self.rows, self.cols);
        if !self.tracked() {
            return out;
        }
        let o = out.value.clone();
        out.recorded(&[self], move |g| vec![Some(derivative(g, &o, d))])
    }

    fn binary(
        &self,
        o: &Var,
        f: impl Fn(f64, f64) -> f64,
        da: impl Fn(f64, f64, f64) -> f64 + 'static,
        db: impl Fn(f64, f64, f64) -> f64 + 'static,
    ) -> Var {
        if self.cols != o.cols {
            let cols = broadcast(self, o).1;
            return self.expand(cols).binary(&o.expand(cols), f, da, db);
        }
        let value: Vec<f64> = self
            .value
            .iter()
            .zip(o.value.iter())
            .map(|(&a, &b)| f(a, b))
            .collect();
        let (ta, tb) = (self.tracked(), o.tracked());
        if !ta && !tb {
            return Var::constant(value, self.rows, self.cols);
        }
        let (a, b) = (self.value.clone(), o.value.clone());
        Var::custom(&[self, o], value, self.rows, self.cols, move |g| {
            let side = |tracked: bool, d: &dyn Fn(f64, f64, f64) -> f64| {
                tracked.then(|| {
                    (g.iter().zip(a.iter().zip(b.iter())))
                        .map(|(&g, (&a, &b))| if g == 0.0 { 0.0 } else { d(a, b, g) })
                        .collect()
                })
            };
            vec![side(ta, &da), side(tb, &db)]
        })
    }

    /// `self` with `cols` columns: itself, or its single column repeated.
    fn expand(&self, cols: usize) -> Var {
        if self.cols == cols {
            return self.clone();
        }
        let value = self
            .value
            .iter()
            .flat_map(|&x| std::iter::repeat_n(x, cols))
            .collect();
        Var::custom(&[self], value, self.rows, cols, move |g| {
            vec![Some(g.chunks(cols).map(|row| row.iter().sum()).collect())]
        })
    }

    /// `f(self)` of constant slope `slope`: the backward step needs no values.
    fn affine(&self, f: impl Fn(f64) -> f64, slope: f64) -> Var {
        let value = self.value.iter().map(|&a| f(a)).collect();
        Var::custom(&[self], value, self.rows, self.cols, move |g| {
            vec![Some(g.iter().map(|g| g * slope).collect())]
        })
    }

    /// `self + sign * o`: the backward step needs no values.
    fn sum_with(&self, o: &Var, sign: f64) -> Var {
        if self.cols != o.cols {
            let cols = broadcast(self, o).1;
            return self.expand(cols).sum_with(&o.expand(cols), sign);
        }
        let value = self
            .value
            .iter()
            .zip(o.value.iter())
            .map(|(&a, &b)| a + sign * b)
            .collect();
        let (ta, tb) = (self.tracked(), o.tracked());
        Var::custom(&[self, o], value, self.rows, self.cols, move |g| {
            vec![
                ta.then(|| g.to_vec()),
                tb.then(|| g.iter().map(|g| g * sign).collect()),
            ]
        })
    }

    fn filled(&self, c: f64) -> Var {
        Var::constant(vec![c; self.value.len()], self.rows, self.cols)
    }
}

/// `d(value, g)` for each element's value and gradient (0 where the gradient is 0, so that an
/// infinite derivative behind a masked element does not make NaN).
fn derivative(g: &[f64], values: &[f64], d: impl Fn(f64, f64) -> f64) -> Vec<f64> {
    g.iter()
        .zip(values)
        .map(|(&g, &x)| if g == 0.0 { 0.0 } else { d(x, g) })
        .collect()
}

/// The output shape of two operands (equal shapes, or one of them a single column).
fn broadcast(a: &Var, b: &Var) -> (usize, usize) {
    assert!(
        a.rows == b.rows && (a.cols == b.cols || a.cols == 1 || b.cols == 1),
        "shapes {}x{} and {}x{} do not broadcast",
        a.rows,
        a.cols,
        b.rows,
        b.cols
    );
    (a.rows, a.cols.max(b.cols))
}

/// Gradients of the leaves of this thread's tape.
#[derive(Debug, Default)]
pub struct Gradients {
    generation: u64,
    leaves: HashMap<usize, Vec<f64>>,
}

impl Gradients {
    /// The gradient of `leaf` (`None` when the root does not depend on it).
    pub fn of(&self, leaf: &Var) -> Option<&[f64]> {
        leaf.node
            .filter(|&(g, _)| g == self.generation)
            .and_then(|(_, i)| self.leaves.get(&i))
            .map(Vec::as_slice)
    }
}

/// Runs this thread's tape backwards from `root`, whose gradient is `seed` (one value per
/// element), and clears it. A root without a tracked value has no gradients.
pub fn backward(root: &Var, seed: Vec<f64>) -> Gradients {
    assert_eq!(seed.len(), root.value.len(), "one seed per element");
    let mut out = Gradients::default();
    if !root.tracked() {
        return out;
    }
    let (generation, last) = root.node.expect("tracked");
    out.generation = generation;
    let nodes = TAPE.with(|t| std::mem::take(&mut t.borrow_mut().nodes));
    let mut grads: Vec<Option<Vec<f64>>> = Vec::new();
    grads.resize_with(last + 1, || None);
    grads[last] = Some(seed);
    for (i, node) in nodes.into_iter().enumerate().take(last + 1).rev() {
        let Some(g) = grads[i].take() else { continue };
        let Some(step) = node.backward else {
            out.leaves.insert(i, g);
            continue;
        };
        for (operand, grad) in node.operands.into_iter().zip(step(&g)) {
            let (Some(j), Some(grad)) = (operand, grad) else {
                continue;
            };
            match &mut grads[j] {
                Some(acc) => acc.iter_mut().zip(&grad).for_each(|(a, g)| *a += g),
                slot => *slot = Some(grad),
            }
        }
    }
    start();
    out
}

impl Num for Var {
    fn full(&self, c: f64) -> Self {
        self.filled(c)
    }
    fn add(&self, o: &Self) -> Self {
        self.sum_with(o, 1.0)
    }
    fn sub(&self, o: &Self) -> Self {
        self.sum_with(o, -1.0)
    }
    fn mul(&self, o: &Self) -> Self {
        self.binary(o, |a, b| a * b, |_, b, g| g * b, |a, _, g| g * a)
    }
    fn div(&self, o: &Self) -> Self {
        self.binary(o, |a, b| a / b, |_, b, g| g / b, |a, b, g| -g * a / (b * b))
    }
    fn add_c(&self, c: f64) -> Self {
        self.affine(|a| a + c, 1.0)
    }
    fn mul_c(&self, c: f64) -> Self {
        self.affine(|a| a * c, c)
    }
    fn abs(&self) -> Self {
        self.unary(f64::abs, |a, g| {
            if a > 0.0 {
                g
            } else if a < 0.0 {
                -g
            } else {
                0.0
            }
        })
    }
    fn sqrt(&self) -> Self {
        self.unary_out(f64::sqrt, |o, g| g / (2.0 * o))
    }
    fn sin(&self) -> Self {
        self.unary(f64::sin, |a, g| g * a.cos())
    }
    fn cos(&self) -> Self {
        self.unary(f64::cos, |a, g| -g * a.sin())
    }
    fn tan(&self) -> Self {
        self.unary_out(f64::tan, |o, g| g * (1.0 + o * o))
    }
    fn atan(&self) -> Self {
        self.unary(f64::atan, |a, g| g / (1.0 + a * a))
    }
    // Ties share the gradient, as libtorch's minimum and maximum do.
    fn min(&self, o: &Self) -> Self {
        self.binary(o, f64::min, tie, |a, b, g| tie(b, a, g))
    }
    fn max(&self, o: &Self) -> Self {
        self.binary(o, f64::max, |a, b, g| tie(b, a, g), tie)
    }
    fn clamp_c(&self, lo: f64, hi: f64) -> Self {
        self.unary(
            |a| a.clamp(lo, hi),
            move |a, g| if (lo..=hi).contains(&a) { g } else { 0.0 },
        )
    }
    fn gt(&self, o: &Self) -> Self {
        let cols = broadcast(self, o).1;
        let (a, b) = (self.expand(cols).detach(), o.expand(cols).detach());
        let value = a
            .value
            .iter()
            .zip(b.value.iter())
            .map(|(&a, &b)| f64::from(u8::from(a > b)))
            .collect();
        Var::constant(value, self.rows, cols)
    }
    fn select(mask: &Self, a: &Self, b: &Self) -> Self {
        let cols = broadcast(mask, a).1.max(broadcast(mask, b).1);
        let (m, a, b) = (mask.expand(cols).detach(), a.expand(cols), b.expand(cols));
        let on = |m: f64| m > 0.5;
        let value = m
            .value
            .iter()
            .zip(a.value.iter().zip(b.value.iter()))
            .map(|(&m, (&a, &b))| if on(m) { a } else { b })
            .collect();
        let (ta, tb) = (a.tracked(), b.tracked());
        let m = m.value.clone();
        Var::custom(&[&a, &b], value, mask.rows, cols, move |g| {
            let side = |tracked: bool, when: bool| {
                tracked.then(|| {
                    g.iter()
                        .zip(m.iter())
                        .map(|(&g, &m)| if on(m) == when { g } else { 0.0 })
                        .collect()
                })
            };
            vec![side(ta, true), side(tb, false)]
        })
    }
    fn recip(&self) -> Self {
        self.unary_out(|a| 1.0 / a, |o, g| -g * o * o)
    }
    fn square(&self) -> Self {
        self.unary(|a| a * a, |a, g| 2.0 * a * g)
    }
}

/// The gradient reaching `a` of `min(a, b)`: all of it when `a` is the smaller, half on a tie.
fn tie(a: f64, b: f64, g: f64) -> f64 {
    if a < b {
        g
    } else if a == b {
        g / 2.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradients_of_broadcasts_gathers_pairs_and_masks_are_hand_computed() {
        // Two rows of three: x = [[1, 2, 3], [4, 5, 6]], a column c = [10, 20].
        start();
        let x = Var::leaf(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0], 2, 3);
        let c = Var::leaf(vec![10.0, 20.0], 2, 1);
        // y = x * c (broadcast), then each element's right neighbour (the last its own).
        let right: Rc<[usize]> = vec![1, 2, 2, 1, 2, 2].into();
        let y = x.mul(&c).gather_cols(&right);
        assert_eq!(y.values(), &[20.0, 30.0, 30.0, 100.0, 120.0, 120.0]);
        // Pair sums of the pairs (0, 1) and (0, 2), then a mask that keeps column 0 of y.
        let pairs: Rc<[(usize, usize)]> = vec![(0, 1), (0, 2)].into();
        let p = y.select_cols(&vec![0, 1].into()).pair_sums(&pairs, 3);
        assert_eq!(p.values(), &[50.0, 20.0, 30.0, 220.0, 100.0, 120.0]);
        let mask = Var::constant(vec![1.0, 0.0, 0.0, 1.0, 0.0, 0.0], 2, 3);
        let out = Var::select(&mask, &p, &x.square()).sum_cols();
        // Row 0: 50 + 2^2 + 3^2; row 1: 220 + 25 + 36.
        assert_eq!(out.values(), &[63.0, 281.0]);
        let g = backward(&out, vec![1.0, 1.0]);
        // d/dx: through p[., 0] = y0 + y1 = c x1 + c x2, and the squares of columns 1 and 2.
        assert_eq!(
            g.of(&x).unwrap(),
            &[0.0, 10.0 + 4.0, 10.0 + 6.0, 0.0, 20.0 + 10.0, 20.0 + 12.0]
        );
        // d/dc: x1 + x2 per row.
        assert_eq!(g.of(&c).unwrap(), &[5.0, 11.0]);
    }

    #[test]
    fn a_value_of_an_earlier_tape_is_a_constant() {
        start();
        let old = Var::leaf(vec![3.0], 1, 1);
        start();
        let new = Var::leaf(vec![2.0], 1, 1);
        let out = old.mul(&new);
        let g = backward(&out, vec![1.0]);
        assert_eq!(g.of(&new).unwrap(), &[3.0]);
        assert!(g.of(&old).is_none());
    }
}
