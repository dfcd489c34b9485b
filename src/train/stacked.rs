//! Several policy networks trained side by side as one computation.
//!
//! Training's work per step is small (tens of scenarios of 9 players, a 64-wide network), so
//! libtorch's per-operation cost dominates. Stacking the networks of every seed (and every
//! screening candidate) lets one rollout carry all of them: the layers are batched matrix
//! products over a leading member dimension, `[members, rows, features]`, and each member's
//! rows are its own scenarios.
//!
//! Every operation acts on each member separately (batched products, element-wise maps, and
//! the per-member gradient clipping of [`StackedNet::clip_grad_norm`]), and Adam is
//! element-wise, so a member learns exactly what it would learn alone: `tests/train.rs` checks
//! that a seed's curves do not depend on which other seeds train with it.

use crate::policy::network::{NetSpec, PolicyNet};
use crate::policy::observation::BatchPolicy;
use tch::{Kind, Tensor, nn};

/// The PolicyNet variables of each layer, in order.
const LAYERS: [&str; 3] = ["hidden1", "hidden2", "output"];

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
        StackedNet {
            vs,
            members: nets.len() as i64,
            scale: Tensor::from_slice(&spec.obs_scale),
            spec,
            layers,
        }
    }

    /// Number of members.
    pub fn members(&self) -> usize {
        self.members as usize
    }

    /// Actions `[members, rows]` for observations `[members, rows, obs_dim]` (raw SI values):
    /// member `k`'s network on its own rows.
    pub fn forward(&self, obs: &Tensor) -> Tensor {
        let mut x = obs.to_kind(Kind::Float) * &self.scale;
        for (w, b) in &self.layers[..2] {
            x = b.baddbmm(&x, w, 1.0, 1.0);
            let _ = x.leaky_relu_(); // in place: autograd keeps one tensor instead of two
        }
        // The single-output layer as a product and a sum: a batched product with one output
        // column takes another kernel whose result depends on the number of members.
        let (w, b) = &self.layers[2];
        let z = (x * w.transpose(1, 2)).sum_dim_intlist(-1, false, None) + b.squeeze_dim(-1);
        z.tanh() * self.spec.action_scale
    }

    /// A frozen copy of the current weights (for rollouts without gradient).
    pub fn snapshot(&self) -> StackedNet {
        StackedNet {
            vs: nn::VarStore::new(tch::Device::Cpu),
            spec: self.spec.clone(),
            members: self.members,
            layers: self
                .layers
                .iter()
                .map(|(w, b)| (w.detach().copy(), b.detach().copy()))
                .collect(),
            scale: self.scale.copy(),
        }
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
    /// most `max`, as `clip_grad_norm` does for one network alone.
    pub fn clip_grad_norm(&self, max: f64) {
        tch::no_grad(|| {
            let grads: Vec<Tensor> = self.params().map(|p| p.grad()).collect();
            let squares: Vec<Tensor> = grads
                .iter()
                .map(|g| {
                    g.square()
                        .reshape([self.members, -1])
                        .sum_dim_intlist(1, false, None)
                })
                .collect();
            let norm = Tensor::stack(&squares, 0).sum_dim_intlist(0, false, None).sqrt();
            let coef = ((norm + 1e-6).reciprocal() * max).clamp_max(1.0);
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
        let dim = self.spec.obs_dim as i64;
        let input = Tensor::from_slice(&obs[..rows * dim as usize]).reshape([self.members, -1, dim]);
        let actions = tch::no_grad(|| self.forward(&input)).flatten(0, -1);
        let values = Vec::<f32>::try_from(actions).expect("a CPU float tensor");
        out[..rows].copy_from_slice(&values);
    }
}
