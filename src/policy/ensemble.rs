//! Several trained networks of one shape deployed as one policy: each vehicle's action is the
//! median of their actions ([`Combine::Median`]) or their mean ([`Combine::Mean`]).
//!
//! Every seed of a study is trained by Algorithm 1 from another initialisation and lands on
//! another approximate equilibrium; in SUMO traffic the seeds of one set differ more than the
//! deployments they are compared across (`docs/traffic_acceptance.md`). `mpgdrive cosim`
//! deploys the median of a set's seeds by default, one policy shared by every vehicle it drives
//! as a single network is; `--ensemble mean` takes their mean and `--policy-seed` one seed.
//! The median follows the seeds that agree: with the mean, one seed that brakes where the
//! others do not slows every vehicle (on `i80_merge` at demand 1.2, one traffic seed alone
//! drove its egos at 6.1 m/s in the game, the others at 8.1-10.0). Over the acceptance grid's
//! 12 rows at demand 1.2 the shipped set's median was faster than its mean in 10
//! (docs/traffic_acceptance.md section 0o); for another training of the traffic set it held
//! fewer rows than the mean: no general gain.
//!
//! The members' layers are stacked (`[members, in, out]`), so one forward pass costs about as
//! many libtorch operations as a single network's. An ensemble of one is that network, bit for
//! bit.

use crate::policy::network::{NetSpec, PolicyNet};
use crate::policy::observation::BatchPolicy;
use tch::{Kind, Tensor};

/// The networks given for an ensemble do not fit together.
#[derive(Debug, thiserror::Error)]
pub enum EnsembleError {
    /// No network was given.
    #[error("an ensemble needs at least one policy")]
    Empty,
    /// A member's sizes or scales differ from the first member's.
    #[error(
        "the policies do not fit together: policy {index} has {} (policy 0: {})",
        describe(found),
        describe(expected)
    )]
    Shape {
        /// Position of the member in the list.
        index: usize,
        /// The first member's spec.
        expected: Box<NetSpec>,
        /// This member's spec.
        found: Box<NetSpec>,
    },
}

fn describe(spec: &NetSpec) -> String {
    format!(
        "{} inputs, {} hidden units, actions up to {} m/s^2, input scales {:?}",
        spec.obs_dim, spec.hidden, spec.action_scale, spec.obs_scale
    )
}

/// How an ensemble makes one action of its members' actions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Combine {
    /// The median (of an even count, the mean of the two middle actions).
    #[default]
    Median,
    /// The mean.
    Mean,
}

impl Combine {
    /// Its name, as the command line and the results spell it.
    pub fn name(self) -> &'static str {
        match self {
            Combine::Median => "median",
            Combine::Mean => "mean",
        }
    }
}

/// Networks of one [`NetSpec`] acting as one policy: the median or the mean of their actions.
#[derive(Debug)]
pub struct PolicyEnsemble {
    spec: NetSpec,
    members: Members,
    combine: Combine,
}

#[derive(Debug)]
enum Members {
    /// A single network acts as itself (the same operations, so the same bits, as
    /// [`PolicyNet::forward`]).
    One(PolicyNet),
    /// Per layer: weights `[members, in, out]` (transposed for `x @ w`) and biases
    /// `[members, 1, out]`; and the input scales.
    Stacked {
        layers: [(Tensor, Tensor); 3],
        scale: Tensor,
        count: usize,
    },
}

impl PolicyEnsemble {
    /// The ensemble of `nets` (at least one, all of one spec), combining their actions by
    /// `combine`.
    pub fn new(mut nets: Vec<PolicyNet>, combine: Combine) -> Result<Self, EnsembleError> {
        let first = nets.first().ok_or(EnsembleError::Empty)?;
        if let Some((index, net)) = nets.iter().enumerate().find(|(_, n)| n.spec != first.spec) {
            return Err(EnsembleError::Shape {
                index,
                expected: Box::new(first.spec.clone()),
                found: Box::new(net.spec.clone()),
            });
        }
        let spec = first.spec.clone();
        if nets.len() == 1 {
            let net = nets.pop().expect("one network");
            return Ok(PolicyEnsemble {
                spec,
                members: Members::One(net),
                combine,
            });
        }
        let layers = std::array::from_fn(|k| {
            tch::no_grad(|| {
                let ws: Vec<Tensor> = nets.iter().map(|n| n.layer(k).ws.tr()).collect();
                let bs: Vec<Tensor> = nets
                    .iter()
                    .map(|n| {
                        let layer = n.layer(k);
                        let out = layer.ws.size()[0];
                        layer.bs.as_ref().map_or_else(
                            || Tensor::zeros([1, out], (Kind::Float, tch::Device::Cpu)),
                            |b| b.reshape([1, out]),
                        )
                    })
                    .collect();
                (
                    Tensor::stack(&ws, 0).contiguous(),
                    Tensor::stack(&bs, 0).contiguous(),
                )
            })
        });
        Ok(PolicyEnsemble {
            members: Members::Stacked {
                layers,
                scale: Tensor::from_slice(&spec.obs_scale),
                count: nets.len(),
            },
            spec,
            combine,
        })
    }

    /// Number of member networks.
    pub fn members(&self) -> usize {
        match &self.members {
            Members::One(_) => 1,
            Members::Stacked { count, .. } => *count,
        }
    }

    /// Sizes and scales of every member.
    pub fn spec(&self) -> &NetSpec {
        &self.spec
    }

    /// How the members' actions make one.
    pub fn combine(&self) -> Combine {
        self.combine
    }

    /// The members' combined action `[rows]` for observations `[rows, obs_dim]` (raw SI values).
    pub fn forward(&self, obs: &Tensor) -> Tensor {
        tch::no_grad(|| match &self.members {
            Members::One(net) => net.forward(obs),
            Members::Stacked { layers, scale, count } => {
                let mut x = (obs.to_kind(Kind::Float) * scale).unsqueeze(0);
                for (k, (w, b)) in layers.iter().enumerate() {
                    x = x.matmul(w) + b;
                    if k < 2 {
                        x = x.leaky_relu();
                    }
                }
                // [members, rows]
                let actions = (x.tanh() * self.spec.action_scale).squeeze_dim(-1);
                match self.combine {
                    Combine::Mean => actions.mean_dim(0, false, Kind::Float),
                    Combine::Median => {
                        let (sorted, _) = actions.sort(0, false);
                        let n = *count as i64;
                        (sorted.select(0, (n - 1) / 2) + sorted.select(0, n / 2)) * 0.5
                    }
                }
            }
        })
    }
}

impl From<PolicyNet> for PolicyEnsemble {
    /// The ensemble of one network: its own actions.
    fn from(net: PolicyNet) -> Self {
        PolicyEnsemble::new(vec![net], Combine::default()).expect("one network has one shape")
    }
}

impl BatchPolicy for PolicyEnsemble {
    fn act(&mut self, obs: &[f32], rows: usize, out: &mut [f32]) {
        let input = Tensor::from_slice(obs).reshape([rows as i64, self.spec.obs_dim as i64]);
        let values = Vec::<f32>::try_from(self.forward(&input)).expect("a CPU float tensor");
        out[..rows].copy_from_slice(&values);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::observation::Layout;

    fn net(seed: i64, hidden: usize) -> PolicyNet {
        PolicyNet::seeded(NetSpec::new(Layout::Traffic, hidden, 9.81), seed)
    }

    fn observations(rows: usize, dim: usize) -> Tensor {
        // Distances, speeds and flags of plausible size: 0..40 in steps of 0.37.
        let values: Vec<f32> = (0..rows * dim).map(|k| (k as f32 * 0.37) % 40.0).collect();
        Tensor::from_slice(&values).reshape([rows as i64, dim as i64])
    }

    #[test]
    fn the_action_is_the_mean_of_the_members_actions() {
        let nets = vec![net(1, 16), net(2, 16), net(3, 16)];
        let obs = observations(7, nets[0].spec.obs_dim);
        let each: Vec<Vec<f32>> = nets
            .iter()
            .map(|n| Vec::try_from(tch::no_grad(|| n.forward(&obs))).unwrap())
            .collect();
        let mut ensemble = PolicyEnsemble::new(nets, Combine::Mean).unwrap();
        assert_eq!(ensemble.members(), 3);
        let mut out = vec![0.0; 7];
        let flat: Vec<f32> = Vec::try_from(obs.reshape([-1])).unwrap();
        ensemble.act(&flat, 7, &mut out);
        for (r, &a) in out.iter().enumerate() {
            let mean = (each[0][r] + each[1][r] + each[2][r]) / 3.0;
            assert!((a - mean).abs() < 1e-5, "row {r}: {a} against {mean}");
        }
        // The members do not agree, so the mean is not one of them.
        assert!(out.iter().zip(&each[0]).any(|(a, b)| (a - b).abs() > 1e-3));
    }

    #[test]
    fn the_median_is_the_middle_action_or_the_mean_of_the_two_middle_ones() {
        for members in [3, 4, 5] {
            let nets: Vec<PolicyNet> = (0..members).map(|k| net(10 + k, 16)).collect();
            let obs = observations(9, nets[0].spec.obs_dim);
            let each: Vec<Vec<f32>> = nets
                .iter()
                .map(|n| Vec::try_from(tch::no_grad(|| n.forward(&obs))).unwrap())
                .collect();
            let median: Vec<f32> =
                Vec::try_from(PolicyEnsemble::new(nets, Combine::Median).unwrap().forward(&obs)).unwrap();
            for (r, &a) in median.iter().enumerate() {
                let mut column: Vec<f32> = each.iter().map(|e| e[r]).collect();
                column.sort_by(f32::total_cmp);
                let n = column.len();
                let expected = if n % 2 == 1 {
                    column[n / 2]
                } else {
                    (column[n / 2 - 1] + column[n / 2]) / 2.0
                };
                assert!(
                    (a - expected).abs() < 1e-5,
                    "{members} members, row {r}: {a} against {expected}"
                );
                // As many members act at or below it as at or above it.
                let below = column.iter().filter(|&&c| c <= a + 1e-6).count();
                let above = column.iter().filter(|&&c| c >= a - 1e-6).count();
                assert!(below >= n / 2 && above >= n / 2, "{column:?}: {a}");
            }
        }
    }

    #[test]
    fn two_copies_of_a_network_act_as_that_network() {
        // The stacked path (two members) against the network's own forward pass.
        let one = net(5, 8);
        let obs = observations(4, one.spec.obs_dim);
        let alone: Vec<f32> = Vec::try_from(tch::no_grad(|| one.forward(&obs))).unwrap();
        for combine in [Combine::Mean, Combine::Median] {
            let twice = PolicyEnsemble::new(vec![net(5, 8), net(5, 8)], combine).unwrap();
            let stacked: Vec<f32> = Vec::try_from(twice.forward(&obs)).unwrap();
            assert_eq!(alone.len(), 4);
            for (a, b) in alone.iter().zip(&stacked) {
                assert!((a - b).abs() < 1e-5, "{combine:?}: {a} against {b}");
            }
        }
        // An ensemble of one is the network itself.
        let own: Vec<f32> = Vec::try_from(PolicyEnsemble::from(one).forward(&obs)).unwrap();
        assert_eq!(own, alone);
    }

    #[test]
    fn members_of_another_shape_or_none_are_refused() {
        assert!(matches!(
            PolicyEnsemble::new(Vec::new(), Combine::Median),
            Err(EnsembleError::Empty)
        ));
        let err = PolicyEnsemble::new(vec![net(1, 8), net(2, 16)], Combine::Median).unwrap_err();
        assert!(matches!(err, EnsembleError::Shape { index: 1, .. }), "{err}");
    }
}
