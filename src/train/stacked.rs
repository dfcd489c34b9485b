//! Several policy networks trained side by side as one computation.
//!
//! Training's work per step is small (tens of scenarios of 9 players, a 64-wide network), so
//! the per-operation cost matters. Stacking the networks of every seed (and every screening
//! candidate) lets one rollout carry all of them: the layers are batched matrix products over
//! a leading member dimension, `[members, rows, features]`, and each member's rows are its
//! own scenarios.
//!
//! Every operation acts on each member separately (batched products, element-wise maps, and
//! the per-member gradient clipping of [`StackedNet::clip_grad_norm`]), and Adam is
//! element-wise, so a member learns exactly what it would learn alone: `tests/train.rs` checks
//! that a seed's curves do not depend on which other seeds train with it.

use crate::engine::tape::Var;
use crate::policy::network::{LEAKY_SLOPE, NetSpec, PolicyNet};
use crate::policy::observation::{BatchPolicy, Layout, observation_rows};
use crate::train::adam::Adam;
use std::cell::RefCell;
use std::rc::Rc;
use tch::{Device, Kind, Tensor, nn};

/// The gradient of each stacked parameter (as [`StackedNet`] holds them: per layer weight,
/// then bias; each member's values in turn, row-major), summed over the steps of a rollout by
/// [`StackedNet::act_on_tape`]; [`StackedNet::grad_tensors`] shapes them.
pub type ParamGrads = Rc<RefCell<Option<Vec<Vec<f32>>>>>;

/// Panics unless `t` is a contiguous CPU float tensor (what `floats` and `floats_mut` read).
fn assert_plain_floats(t: &Tensor) {
    assert!(
        t.kind() == Kind::Float && t.device() == Device::Cpu && t.is_contiguous(),
        "a contiguous CPU float tensor"
    );
}

/// The values of a contiguous CPU float tensor, in place.
fn floats(t: &Tensor) -> &[f32] {
    assert_plain_floats(t);
    // SAFETY: a contiguous CPU float tensor holds `numel` f32 values from `data_ptr`; the
    // storage lives as long as the borrowed handle, and nothing writes to it meanwhile (the
    // tensors read here are this module's own products, never handed out).
    unsafe { std::slice::from_raw_parts(t.data_ptr() as *const f32, t.numel()) }
}

/// The values of a contiguous CPU float tensor, to write in place.
fn floats_mut(t: &mut Tensor) -> &mut [f32] {
    assert_plain_floats(t);
    // SAFETY: as in `floats`; the exclusive borrow of the handle stands for its storage while
    // the slice lives: the tensors written here are fresh products, or the stacked parameters
    // during an optimiser step, which nothing else reads meanwhile.
    unsafe { std::slice::from_raw_parts_mut(t.data_ptr() as *mut f32, t.numel()) }
}

/// The derivative of `leaky_relu` at an output `h`: it is positive exactly where its input is.
fn leaky_slope(h: f32) -> f32 {
    if h > 0.0 { 1.0 } else { LEAKY_SLOPE }
}

/// One member's rows of a step, as the forward pass left them (row-major).
struct Activations<'a> {
    /// Scaled observations, `[rows, obs_dim]`.
    x0: &'a [f32],
    /// First hidden layer after its activation, `[rows, hidden]`.
    h1: &'a [f32],
    /// Second hidden layer after its activation, `[rows, hidden]`.
    h2: &'a [f32],
    /// Gradient of the objective by the output layer's value (before tanh), `[rows]`.
    gz: &'a [f32],
}

/// A `[rows, cols]` tensor over `values`, without a copy.
///
/// # Safety
/// The tensor borrows `values`: it must be dropped before them (products made from it are
/// new tensors and may outlive them).
unsafe fn matrix_over(values: &[f32], rows: usize, cols: usize) -> Tensor {
    assert_eq!(values.len(), rows * cols, "values of a {rows} x {cols} matrix");
    // SAFETY: `values` holds `rows * cols` contiguous f32 values, which the caller keeps
    // alive and unchanged while the tensor lives; libtorch only reads them.
    unsafe {
        Tensor::from_blob(
            values.as_ptr().cast(),
            &[rows as i64, cols as i64],
            &[],
            Kind::Float,
            Device::Cpu,
        )
    }
}

/// One member's backward pass over its rows with a gradient (`gz` not 0): the gradients of
/// its weights and biases, added to `sums` (its part of each parameter's sum, as
/// [`ParamGrads`] holds them), and of its scaled observations, written into `d_obs`
/// (`[rows, dim]`; the other rows stay 0).
fn member_backward(
    a: &Activations,
    weights: &MemberWeights,
    sizes: (usize, usize),
    sums: [&mut [f32]; 6],
    d_obs: &mut [f32],
) {
    let (dim, hidden) = sizes;
    let live: Vec<usize> = (0..a.gz.len()).filter(|&r| a.gz[r] != 0.0).collect();
    if live.is_empty() {
        return;
    }
    let n = live.len();
    let gather = |src: &[f32], width: usize| -> Vec<f32> {
        let mut rows = Vec::with_capacity(n * width);
        for &r in &live {
            rows.extend_from_slice(&src[r * width..(r + 1) * width]);
        }
        rows
    };
    let (x0, h1, h2) = (gather(a.x0, dim), gather(a.h1, hidden), gather(a.h2, hidden));
    let [dw1, db1, dw2, db2, dw3, db3] = sums;
    // The output layer and the second activation, row by row.
    let w3 = floats(&weights.output);
    let mut dh2 = vec![0f32; n * hidden];
    let (mut step_w3, mut step_b3) = (vec![0f32; hidden], 0f32);
    for ((&r, h), d) in live
        .iter()
        .zip(h2.chunks_exact(hidden))
        .zip(dh2.chunks_exact_mut(hidden))
    {
        let gz = a.gz[r];
        step_b3 += gz;
        for c in 0..hidden {
            step_w3[c] += h[c] * gz;
            d[c] = leaky_slope(h[c]) * (gz * w3[c]);
        }
    }
    // Each step's gradient is summed first, then added to the rollout's sums.
    let add = |sum: &mut [f32], step: &[f32]| sum.iter_mut().zip(step).for_each(|(s, x)| *s += x);
    let column_sums = |m: &[f32]| {
        let mut s = vec![0f32; hidden];
        m.chunks_exact(hidden).for_each(|row| add(&mut s, row));
        s
    };
    add(dw3, &step_w3);
    db3[0] += step_b3;
    add(db2, &column_sums(&dh2));
    // SAFETY: the three matrices are dropped at the end of this function, before the vectors
    // they borrow.
    let (x0t, h1t, dh2t) = unsafe {
        (
            matrix_over(&x0, n, dim),
            matrix_over(&h1, n, hidden),
            matrix_over(&dh2, n, hidden),
        )
    };
    add(dw2, floats(&h1t.tr().mm(&dh2t)));
    let mut dh1 = dh2t.mm(&weights.hidden2_t);
    for (d, &h) in floats_mut(&mut dh1).iter_mut().zip(&h1) {
        *d *= leaky_slope(h);
    }
    add(db1, &column_sums(floats(&dh1)));
    add(dw1, floats(&x0t.tr().mm(&dh1)));
    let dx = dh1.mm(&weights.hidden1_t);
    for (&r, row) in live.iter().zip(floats(&dx).chunks_exact(dim)) {
        d_obs[r * dim..(r + 1) * dim].copy_from_slice(row);
    }
}

/// One member's weights as its backward pass reads them: views of the stacked parameters,
/// which the optimiser updates in place.
#[derive(Debug)]
struct MemberWeights {
    /// The first layer's weights transposed, `[hidden, obs_dim]`.
    hidden1_t: Tensor,
    /// The second layer's weights transposed, `[hidden, hidden]`.
    hidden2_t: Tensor,
    /// The output layer's weights, `[hidden, 1]` (contiguous).
    output: Tensor,
}

impl MemberWeights {
    /// Member `k`'s views of `layers`.
    fn of(layers: &[(Tensor, Tensor)], k: i64) -> Self {
        let w = |l: usize| layers[l].0.detach().get(k);
        MemberWeights {
            hidden1_t: w(0).tr(),
            hidden2_t: w(1).tr(),
            output: w(2),
        }
    }

    fn shallow_clone(&self) -> Self {
        MemberWeights {
            hidden1_t: self.hidden1_t.shallow_clone(),
            hidden2_t: self.hidden2_t.shallow_clone(),
            output: self.output.shallow_clone(),
        }
    }
}

/// The PolicyNet variables of each layer, in order.
const LAYERS: [&str; 3] = ["hidden1", "hidden2", "output"];

/// A forward pass's hidden layers (after their activation), `tanh` of the output layer, and
/// the actions, each with a leading member dimension.
struct Pass {
    h1: Tensor,
    h2: Tensor,
    t: Tensor,
    actions: Tensor,
}

/// The stacked layers (`w`: each layer's weights, then bias, as [`StackedNet`] holds them) on
/// scaled observations `x0`.
fn layers(w: &[Tensor], x0: &Tensor, action_scale: f64) -> Pass {
    let mut h1 = w[1].baddbmm(x0, &w[0], 1.0, 1.0);
    let _ = h1.leaky_relu_(); // in place: autograd keeps one tensor instead of two
    let mut h2 = w[3].baddbmm(&h1, &w[2], 1.0, 1.0);
    let _ = h2.leaky_relu_();
    // The single-output layer as a product and a sum: a batched product with one output
    // column takes another kernel whose result depends on the number of members.
    let z = (&h2 * w[4].transpose(1, 2)).sum_dim_intlist(-1, false, None) + w[5].squeeze_dim(-1);
    let t = z.tanh();
    let actions = &t * action_scale;
    Pass { h1, h2, t, actions }
}

/// `members` networks of one [`NetSpec`], weights stacked along a leading dimension.
#[derive(Debug)]
pub struct StackedNet {
    /// The stacked parameters (what the optimiser updates).
    pub vs: nn::VarStore,
    /// Sizes and scales shared by every member.
    pub spec: NetSpec,
    members: i64,
    /// Per layer: weights `[members, in, out]` and biases `[members, 1, out]`.
    layers: Vec<(Tensor, Tensor)>,
    /// Each member's views of `layers` for the backward pass.
    views: Vec<MemberWeights>,
    scale: Tensor,
}

impl StackedNet {
    /// Stacks copies of `nets` (at least one, all of one spec).
    pub fn from_nets(nets: &[PolicyNet]) -> Self {
        let spec = nets[0].spec.clone();
        let vs = nn::VarStore::new(tch::Device::Cpu);
        let root = vs.root();
        let layers = tch::no_grad(|| {
            LAYERS
                .iter()
                .map(|name| {
                    let of = |part: &str| {
                        let all: Vec<Tensor> = nets
                            .iter()
                            .map(|n| n.vs.variables()[&format!("{name}.{part}")].detach())
                            .collect();
                        Tensor::stack(&all, 0)
                    };
                    // nn::Linear keeps weights as [out, in]; batched products want [in, out].
                    let w = root.var_copy(&format!("{name}_w"), &of("weight").transpose(1, 2));
                    let b = root.var_copy(&format!("{name}_b"), &of("bias").unsqueeze(1));
                    (w, b)
                })
                .collect()
        });
        StackedNet::assemble(vs, spec, layers)
    }

    /// Number of members.
    pub fn members(&self) -> usize {
        self.members as usize
    }

    /// Actions `[members, rows]` for observations `[members, rows, obs_dim]` (raw SI values):
    /// member `k`'s network on its own rows.
    pub fn forward(&self, obs: &Tensor) -> Tensor {
        let x0 = obs.to_kind(Kind::Float) * &self.scale;
        let w: Vec<Tensor> = self.params().map(Tensor::shallow_clone).collect();
        layers(&w, &x0, self.spec.action_scale).actions
    }

    /// The actions of every element of `features` (one `[rows, cols]` array per feature; the
    /// rows split evenly among the members, in member order) as one node of the tape: the
    /// forward pass now, without libtorch's autograd; when the tape runs back, the backward
    /// pass by hand, into the features and into `grads`.
    ///
    /// The backward pass runs on the rows whose action has a gradient only, member by member
    /// ([`member_backward`]): most have none (the feasibility projection holds the action at
    /// a bound; measured on the paper's training, 87% of the rows), and a row without one adds
    /// nothing to any gradient. Each member's products see its own rows alone, so its gradient
    /// does not depend on the other members.
    pub fn act_on_tape(&self, layout: Layout, features: &[Var], grads: &ParamGrads) -> Var {
        let (rows, cols) = (features[0].rows(), features[0].cols());
        let dim = self.spec.obs_dim;
        let mut x = observation_rows(layout, features);
        let x0 = self.scaled(&mut x);
        let scale = self.spec.action_scale;
        let Pass { h1, h2, t, actions } = self.pass(&x0);
        let actions = Var::constant(
            floats(&actions).iter().map(|&a| f64::from(a)).collect(),
            rows,
            cols,
        );
        let (input_scale, n_features) = (self.spec.obs_scale.clone(), features.len());
        let (members, hidden) = (self.members as usize, self.spec.hidden);
        let views: Vec<MemberWeights> = self.views.iter().map(MemberWeights::shallow_clone).collect();
        let sizes: Vec<usize> = self.params().map(|p| p.numel() / members).collect();
        let grads = grads.clone();
        actions.recorded(&features.iter().collect::<Vec<_>>(), move |g| {
            // d action / d z = scale (1 - tanh^2), per row.
            let gz: Vec<f32> = g
                .iter()
                .zip(floats(&t))
                .map(|(&g, &t)| g as f32 * scale as f32 * (1.0 - t * t))
                .collect();
            let per = gz.len() / members;
            let mut d_obs = vec![0f32; gz.len() * dim];
            let mut sums = grads.borrow_mut();
            let sums = sums.get_or_insert_with(|| sizes.iter().map(|s| vec![0f32; s * members]).collect());
            tch::no_grad(|| {
                for (k, weights) in views.iter().enumerate() {
                    let span = k * per..(k + 1) * per;
                    let acts = Activations {
                        x0: &floats(&x0)[span.start * dim..span.end * dim],
                        h1: &floats(&h1)[span.start * hidden..span.end * hidden],
                        h2: &floats(&h2)[span.start * hidden..span.end * hidden],
                        gz: &gz[span.clone()],
                    };
                    let mut own = sums
                        .iter_mut()
                        .zip(&sizes)
                        .map(|(s, &n)| &mut s[k * n..(k + 1) * n]);
                    let own = std::array::from_fn(|_| own.next().expect("six parameters"));
                    let d_rows = &mut d_obs[span.start * dim..span.end * dim];
                    member_backward(&acts, weights, (dim, hidden), own, d_rows);
                }
            });
            (0..n_features)
                .map(|j| {
                    let s = input_scale[j];
                    Some(
                        d_obs
                            .iter()
                            .skip(j)
                            .step_by(dim)
                            .map(|&x| f64::from(x * s))
                            .collect(),
                    )
                })
                .collect()
        })
    }

    /// Observation rows (raw SI values, row-major) scaled in place, as `[members, rows,
    /// obs_dim]`.
    fn scaled(&self, x: &mut [f32]) -> Tensor {
        let dim = self.spec.obs_dim;
        for row in x.chunks_mut(dim) {
            row.iter_mut()
                .zip(&self.spec.obs_scale)
                .for_each(|(v, s)| *v *= s);
        }
        Tensor::from_slice(x).reshape([self.members, -1, dim as i64])
    }

    /// The forward pass of [`StackedNet::forward`] without gradient on scaled observations
    /// `x0`, keeping what the backward pass reads.
    fn pass(&self, x0: &Tensor) -> Pass {
        let w: Vec<Tensor> = self.params().map(Tensor::detach).collect();
        tch::no_grad(|| layers(&w, x0, self.spec.action_scale))
    }

    /// The number of values of each stacked parameter, in the order of [`StackedNet::adam_step`].
    pub fn param_lengths(&self) -> Vec<usize> {
        self.params().map(Tensor::numel).collect()
    }

    /// Forgets the parameters' gradients (before [`StackedNet::set_grads`]).
    pub fn zero_grads(&mut self) {
        for (w, b) in &mut self.layers {
            w.zero_grad();
            b.zero_grad();
        }
    }

    /// One step of `adam` (of step size `lr`) on every stacked parameter along its gradient.
    /// Adam is element-wise, so each member moves as it would alone.
    pub fn adam_step(&mut self, adam: &mut Adam, lr: f64) {
        let grads: Vec<Tensor> = self.params().map(Tensor::grad).collect();
        let grads: Vec<&[f32]> = grads.iter().map(floats).collect();
        let mut params: Vec<&mut [f32]> = self
            .layers
            .iter_mut()
            .flat_map(|(w, b)| [w, b])
            .map(floats_mut)
            .collect();
        adam.step(lr, &mut params, &grads);
    }

    /// Sets each parameter's gradient to `grads` (as [`ParamGrads`] sums them).
    pub fn set_grads(&self, grads: &[Tensor]) {
        let surrogate = self
            .params()
            .zip(grads)
            .map(|(p, g)| (p * g.detach()).sum(Kind::Float))
            .reduce(|a, b| a + b)
            .expect("three layers");
        surrogate.backward();
    }

    /// A frozen copy of the current weights (for rollouts without gradient).
    pub fn snapshot(&self) -> StackedNet {
        let layers = self
            .layers
            .iter()
            .map(|(w, b)| (w.detach().copy(), b.detach().copy()))
            .collect();
        StackedNet::assemble(nn::VarStore::new(tch::Device::Cpu), self.spec.clone(), layers)
    }

    fn assemble(vs: nn::VarStore, spec: NetSpec, layers: Vec<(Tensor, Tensor)>) -> StackedNet {
        let members = layers[0].0.size()[0];
        StackedNet {
            vs,
            members,
            scale: Tensor::from_slice(&spec.obs_scale),
            views: (0..members).map(|k| MemberWeights::of(&layers, k)).collect(),
            spec,
            layers,
        }
    }

    /// The sums of [`ParamGrads`] shaped as the stacked parameters.
    pub fn grad_tensors(&self, sums: &[Vec<f32>]) -> Vec<Tensor> {
        self.params()
            .zip(sums)
            .map(|(p, s)| Tensor::from_slice(s).reshape(p.size()))
            .collect()
    }

    /// Member `k` as a plain network (a copy of its current weights).
    pub fn member(&self, k: usize) -> Result<PolicyNet, tch::TchError> {
        let net = PolicyNet::new(self.spec.clone());
        let mut vars = net.vs.variables();
        tch::no_grad(|| -> Result<(), tch::TchError> {
            for (name, (w, b)) in LAYERS.iter().zip(&self.layers) {
                let mut set = |part: &str, value: &Tensor| match vars.get_mut(&format!("{name}.{part}")) {
                    Some(var) => var.f_copy_(value),
                    None => unreachable!("PolicyNet has {name}.{part}"),
                };
                set("weight", &w.get(k as i64).transpose(0, 1))?;
                set("bias", &b.get(k as i64).squeeze_dim(0))?;
            }
            Ok(())
        })?;
        Ok(net)
    }

    /// Scales each member's gradient so that its L2 norm (over all of its parameters) is at
    /// most `max`, as `clip_grad_norm` does for one network alone. Each member's norm is
    /// summed on its own (in f64): a reduction over all members could take another order as
    /// their number changes.
    pub fn clip_grad_norm(&self, max: f64) {
        tch::no_grad(|| {
            let grads: Vec<Tensor> = self.params().map(|p| p.grad()).collect();
            let coef: Vec<f64> = (0..self.members)
                .map(|k| {
                    let squares: f64 = grads
                        .iter()
                        .map(|g| {
                            g.get(k)
                                .to_kind(Kind::Double)
                                .square()
                                .sum(Kind::Double)
                                .double_value(&[])
                        })
                        .sum();
                    (max / (squares.sqrt() + 1e-6)).min(1.0)
                })
                .collect();
            let coef = Tensor::from_slice(&coef).to_kind(Kind::Float);
            for mut g in grads {
                let shape: Vec<i64> = std::iter::once(self.members)
                    .chain(std::iter::repeat_n(1, g.dim() - 1))
                    .collect();
                let _ = g.g_mul_(&coef.reshape(shape.as_slice()));
            }
        })
    }

    /// Per member: are all its parameters finite?
    pub fn finite(&self) -> Vec<bool> {
        let ok = self
            .params()
            .map(|p| {
                p.isfinite()
                    .reshape([self.members, -1])
                    .all_dim(1, false)
                    .to_kind(Kind::Int64)
            })
            .reduce(|a, b| a * b)
            .expect("three layers");
        Vec::<i64>::try_from(ok)
            .expect("a CPU tensor")
            .into_iter()
            .map(|v| v == 1)
            .collect()
    }

    fn params(&self) -> impl Iterator<Item = &Tensor> {
        self.layers.iter().flat_map(|(w, b)| [w, b])
    }
}

/// Rows are split evenly among the members, in member order: the first `rows / members` rows
/// are member 0's, and so on.
impl BatchPolicy for StackedNet {
    fn act(&mut self, obs: &[f32], rows: usize, out: &mut [f32]) {
        let mut x = obs[..rows * self.spec.obs_dim].to_vec();
        let actions = self.pass(&self.scaled(&mut x)).actions;
        out[..rows].copy_from_slice(floats(&actions));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::tape;
    use crate::num::Num;

    #[test]
    fn the_backward_pass_by_hand_matches_autograd() {
        // Two members of the Table I layout, 2 scenes x 3 players each; features are leaves
        // of the tape, the upstream gradient is arbitrary. libtorch's autograd on the same
        // forward pass gives the reference gradients of the inputs and the weights.
        let layout = Layout::Table1 { players: 3 };
        let spec = NetSpec::new(layout, 8, 9.81);
        let net = StackedNet::from_nets(&[PolicyNet::seeded(spec.clone(), 1), PolicyNet::seeded(spec, 2)]);
        let (rows, cols) = (4, 3);
        let features: Vec<Var> = (0..layout.features())
            .map(|j| {
                let values = (0..rows * cols)
                    .map(|k| ((j * 7 + k * 3) % 11) as f64 * 4.5 - 20.0)
                    .collect();
                Var::leaf(values, rows, cols)
            })
            .collect();
        // Every third row without a gradient (the backward pass skips those): member 0 has
        // rows 0, 3; member 1 rows 6, 9 without one.
        let upstream: Vec<f64> = (0..rows * cols)
            .map(|k| if k % 3 == 0 { 0.0 } else { (k as f64 - 5.5) * 0.3 })
            .collect();
        let grads = ParamGrads::default();
        let actions = net.act_on_tape(layout, &features, &grads);
        // A second call adds its step to the sums, as the steps of a rollout do.
        let twice = actions.add(&net.act_on_tape(layout, &features, &grads));
        let by_hand = tape::backward(&twice, upstream.clone());

        let obs = Tensor::from_slice(&observation_rows(layout, &features))
            .reshape([2, -1, layout.dim() as i64])
            .set_requires_grad(true);
        let g = Tensor::from_slice(&upstream)
            .to_kind(Kind::Float)
            .reshape([2, -1]);
        let forward = net.forward(&obs);
        let reference: Vec<f32> = Vec::try_from(forward.flatten(0, -1)).expect("floats");
        for (a, b) in actions.values().iter().zip(&reference) {
            assert!((a - f64::from(*b)).abs() < 1e-6, "forward {a} vs {b}");
        }
        (forward * g * 2.0).sum(Kind::Float).backward();
        let close = |ours: &[f32], theirs: &[f32], what: &str| {
            for (a, b) in ours.iter().zip(theirs) {
                assert!((a - b).abs() <= 1e-5 * b.abs().max(1.0), "{what}: {a} vs {b}");
            }
        };
        let d_obs: Vec<f32> = Vec::try_from(obs.grad().flatten(0, -1)).expect("floats");
        for (j, f) in features.iter().enumerate() {
            let ours: Vec<f32> = by_hand
                .of(f)
                .expect("a gradient")
                .iter()
                .map(|&x| x as f32)
                .collect();
            let theirs: Vec<f32> = d_obs.iter().skip(j).step_by(layout.dim()).copied().collect();
            close(&ours, &theirs, "input");
        }
        let sums = grads.borrow();
        for (p, ours) in net.params().zip(sums.as_ref().expect("gradients")) {
            let theirs: Vec<f32> = Vec::try_from(p.grad().flatten(0, -1)).expect("floats");
            assert_eq!(ours.len(), theirs.len());
            close(ours, &theirs, "weight");
        }
    }

    #[test]
    fn a_members_clipped_gradient_does_not_depend_on_the_stack() {
        // Four networks clipped as a stack of their own and behind four others (the paper's
        // width: the stack of 8 reaches libtorch's grain size for a reduction over all
        // members, which then takes another order): the same bits.
        let spec = NetSpec::new(Layout::Table1 { players: 9 }, 64, 9.81);
        let nets: Vec<PolicyNet> = (0..8).map(|k| PolicyNet::seeded(spec.clone(), k)).collect();
        let clipped = |first: usize| -> Vec<Vec<f32>> {
            let net = StackedNet::from_nets(&nets[first..]);
            let grads: Vec<Tensor> = net.params().map(|p| p.detach().sin() * 50.0).collect();
            net.set_grads(&grads);
            net.clip_grad_norm(10.0);
            net.params()
                .flat_map(|p| (first..8).map(move |k| p.grad().get((k - first) as i64)))
                .map(|g| Vec::try_from(g.flatten(0, -1)).expect("floats"))
                .collect()
        };
        let own: Vec<Vec<f32>> = clipped(4);
        let behind: Vec<Vec<f32>> = clipped(0);
        let behind: Vec<Vec<f32>> = behind.chunks(8).flat_map(|layer| layer[4..].to_vec()).collect();
        assert_eq!(own, behind);
    }
}
