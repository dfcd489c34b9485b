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
//! The forward pass is plain Rust over `f32` weights copied out of the networks at load time:
//! a deployment acts on a few dozen vehicles per step, where libtorch's cost per operation
//! (about 10 us each, some twelve operations per pass) outweighed the arithmetic. Each output
//! of a layer is summed over its inputs in their order, the same on every x86-64 machine
//! whatever the vector width the processor offers (no fused multiply-add, no reassociation), so
//! a co-simulation's numbers do not depend on the machine's instruction set. Against libtorch's
//! own forward pass the actions agree within 1e-5 m/s^2 (its matrix products sum in another
//! order); issue 15's acceptance grid came out the same to the last printed digit.

use crate::policy::network::{LEAKY_SLOPE, NetSpec, PolicyNet};
use crate::policy::observation::BatchPolicy;
use tch::Tensor;

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
    members: Vec<Dense>,
    combine: Combine,
    /// Whether the processor runs AVX2 (checked once, at construction).
    avx2: bool,
}

/// One member's weights: per layer, `[in][out]` row-major (each input's weights to every output
/// side by side) and `[out]` biases.
#[derive(Debug)]
struct Dense {
    layers: [(Vec<f32>, Vec<f32>); 3],
}

impl Dense {
    fn of(net: &PolicyNet) -> Self {
        Dense {
            layers: std::array::from_fn(|k| {
                let layer = net.layer(k);
                let out = layer.ws.size()[0] as usize;
                tch::no_grad(|| {
                    let w = floats(&layer.ws.tr().contiguous().flatten(0, -1));
                    let b = layer.bs.as_ref().map_or_else(|| vec![0.0; out], floats);
                    (w, b)
                })
            }),
        }
    }
}

fn floats(t: &Tensor) -> Vec<f32> {
    Vec::<f32>::try_from(t.to_kind(tch::Kind::Float)).expect("a CPU float tensor")
}

/// `out = x w + b` for `rows` rows of `x` (`[rows][inputs]`) into `out` (`[rows][outputs]`):
/// each output summed over the inputs in their order, then the bias added.
fn dense(x: &[f32], rows: usize, w: &[f32], b: &[f32], out: &mut [f32], avx2: bool) {
    #[cfg(target_arch = "x86_64")]
    if avx2 && b.len() % LANES == 0 {
        // SAFETY: `avx2` is true only where the processor was found to support AVX2
        // ([`has_avx2`]), the one requirement of `dense_avx2`, which checks the slices' sizes
        // before any load or store.
        unsafe { dense_avx2(x, rows, w, b, out) };
        return;
    }
    let _ = avx2;
    dense_portable(&x[..rows * (w.len() / b.len())], w, b, out);
}

/// [`dense`] one row after the other (the rows are `x`'s chunks).
fn dense_portable(x: &[f32], w: &[f32], b: &[f32], out: &mut [f32]) {
    let (inputs, outputs) = (w.len() / b.len(), b.len());
    for (xr, row) in x.chunks_exact(inputs).zip(out.chunks_exact_mut(outputs)) {
        if let [o] = row {
            // One output (the output layer): the sum in a register, in the same order.
            *o = xr.iter().zip(w).fold(0.0, |s, (&xi, &wi)| s + xi * wi) + b[0];
            continue;
        }
        row.fill(0.0);
        for (&xi, wrow) in xr.iter().zip(w.chunks_exact(outputs)) {
            for (o, &wij) in row.iter_mut().zip(wrow) {
                *o += xi * wij;
            }
        }
        for (o, &bj) in row.iter_mut().zip(b) {
            *o += bj;
        }
    }
}

/// Outputs computed together by [`dense_avx2`]: two AVX2 registers of `f32`.
#[cfg(target_arch = "x86_64")]
const LANES: usize = 16;
/// Rows computed together by [`dense_avx2`], so that each loaded weight serves all of them.
#[cfg(target_arch = "x86_64")]
const ROW_BLOCK: usize = 4;

/// [`dense`] in blocks of [`ROW_BLOCK`] rows by [`LANES`] outputs whose sums stay in registers
/// (`outputs` a multiple of [`LANES`]); the rows after the last full block go through
/// [`dense_portable`]. Separate multiplies and adds in [`dense_portable`]'s order, so its bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn dense_avx2(x: &[f32], rows: usize, w: &[f32], b: &[f32], out: &mut [f32]) {
    use std::arch::x86_64::{_mm256_add_ps, _mm256_loadu_ps, _mm256_mul_ps, _mm256_set1_ps};
    use std::arch::x86_64::{_mm256_setzero_ps, _mm256_storeu_ps};
    let outputs = b.len();
    let inputs = w.len() / outputs;
    assert!(outputs % LANES == 0 && w.len() == inputs * outputs);
    assert!(x.len() >= rows * inputs && out.len() >= rows * outputs);
    let blocks = rows / ROW_BLOCK;
    for block in 0..blocks {
        let r0 = block * ROW_BLOCK;
        for j0 in (0..outputs).step_by(LANES) {
            // SAFETY: the loads read `w[k * outputs + j0..][..16]` (k < inputs, j0 + 16 <=
            // outputs) and `b[j0..][..16]`, the stores write `out[(r0 + r) * outputs + j0..]
            // [..16]` (r0 + r < rows): all within the lengths asserted above.
            unsafe {
                let mut acc = [[_mm256_setzero_ps(); 2]; ROW_BLOCK];
                for k in 0..inputs {
                    let wk = w.as_ptr().add(k * outputs + j0);
                    let (w0, w1) = (_mm256_loadu_ps(wk), _mm256_loadu_ps(wk.add(8)));
                    for (r, sums) in acc.iter_mut().enumerate() {
                        let xv = _mm256_set1_ps(x[(r0 + r) * inputs + k]);
                        sums[0] = _mm256_add_ps(sums[0], _mm256_mul_ps(xv, w0));
                        sums[1] = _mm256_add_ps(sums[1], _mm256_mul_ps(xv, w1));
                    }
                }
                let bias = b.as_ptr().add(j0);
                let (b0, b1) = (_mm256_loadu_ps(bias), _mm256_loadu_ps(bias.add(8)));
                for (r, sums) in acc.iter().enumerate() {
                    let o = out.as_mut_ptr().add((r0 + r) * outputs + j0);
                    _mm256_storeu_ps(o, _mm256_add_ps(sums[0], b0));
                    _mm256_storeu_ps(o.add(8), _mm256_add_ps(sums[1], b1));
                }
            }
        }
    }
    let done = blocks * ROW_BLOCK;
    dense_portable(
        &x[done * inputs..rows * inputs],
        w,
        b,
        &mut out[done * outputs..rows * outputs],
    );
}

/// Whether this processor runs AVX2 instructions.
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    return std::arch::is_x86_feature_detected!("avx2");
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Without a branch (a select the compiler vectorises): the signs of hidden units are
/// unpredictable, and a mispredicted branch per unit cost more than the layer's products.
fn leaky_relu(x: &mut [f32]) {
    for v in x {
        *v = if *v < 0.0 { *v * LEAKY_SLOPE } else { *v };
    }
}

impl PolicyEnsemble {
    /// The ensemble of `nets` (at least one, all of one spec), combining their actions by
    /// `combine`.
    pub fn new(nets: Vec<PolicyNet>, combine: Combine) -> Result<Self, EnsembleError> {
        let first = nets.first().ok_or(EnsembleError::Empty)?;
        if let Some((index, net)) = nets.iter().enumerate().find(|(_, n)| n.spec != first.spec) {
            return Err(EnsembleError::Shape {
                index,
                expected: Box::new(first.spec.clone()),
                found: Box::new(net.spec.clone()),
            });
        }
        Ok(PolicyEnsemble {
            spec: first.spec.clone(),
            members: nets.iter().map(Dense::of).collect(),
            combine,
            avx2: has_avx2(),
        })
    }

    /// Number of member networks.
    pub fn members(&self) -> usize {
        self.members.len()
    }

    /// Sizes and scales of every member.
    pub fn spec(&self) -> &NetSpec {
        &self.spec
    }

    /// How the members' actions make one.
    pub fn combine(&self) -> Combine {
        self.combine
    }

    /// The combined action of each row of `obs` (`rows x obs_dim`, row-major, raw SI values)
    /// into `out[..rows]`.
    pub fn actions(&self, obs: &[f32], rows: usize, out: &mut [f32]) {
        assert_eq!(
            obs.len(),
            rows * self.spec.obs_dim,
            "observations of another width"
        );
        let (h, n) = (self.spec.hidden, self.members.len());
        let mut x = obs.to_vec();
        for row in x.chunks_exact_mut(self.spec.obs_dim) {
            for (xi, &s) in row.iter_mut().zip(&self.spec.obs_scale) {
                *xi *= s;
            }
        }
        let (mut h1, mut h2) = (vec![0.0f32; rows * h], vec![0.0f32; rows * h]);
        // [members][rows]
        let mut each = vec![0.0f32; n * rows];
        let g = self.spec.action_scale as f32;
        for (member, y) in self.members.iter().zip(each.chunks_exact_mut(rows.max(1))) {
            let [(w1, b1), (w2, b2), (w3, b3)] = &member.layers;
            dense(&x, rows, w1, b1, &mut h1, self.avx2);
            leaky_relu(&mut h1);
            dense(&h1, rows, w2, b2, &mut h2, self.avx2);
            leaky_relu(&mut h2);
            dense(&h2, rows, w3, b3, y, self.avx2);
            for a in y.iter_mut() {
                *a = a.tanh() * g;
            }
        }
        let mut column = vec![0.0f32; n];
        for (r, action) in out[..rows].iter_mut().enumerate() {
            for (m, c) in column.iter_mut().enumerate() {
                *c = each[m * rows + r];
            }
            *action = match self.combine {
                Combine::Mean => column.iter().sum::<f32>() / n as f32,
                Combine::Median => {
                    column.sort_by(f32::total_cmp);
                    (column[(n - 1) / 2] + column[n / 2]) * 0.5
                }
            };
        }
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
        self.actions(obs, rows, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::observation::Layout;

    fn net(seed: i64, hidden: usize) -> PolicyNet {
        PolicyNet::seeded(NetSpec::new(Layout::Traffic, hidden, 9.81), seed)
    }

    /// The ensemble's actions for `obs` `[rows, obs_dim]`.
    fn act(ensemble: &PolicyEnsemble, obs: &Tensor) -> Vec<f32> {
        let rows = obs.size()[0] as usize;
        let flat: Vec<f32> = Vec::try_from(obs.reshape([-1])).unwrap();
        let mut out = vec![f32::NAN; rows];
        ensemble.actions(&flat, rows, &mut out);
        out
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
        let ensemble = PolicyEnsemble::new(nets, Combine::Mean).unwrap();
        assert_eq!(ensemble.members(), 3);
        let out = act(&ensemble, &obs);
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
            let median = act(&PolicyEnsemble::new(nets, Combine::Median).unwrap(), &obs);
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
        // Two members, and one, against the network's own (libtorch) forward pass.
        let one = net(5, 8);
        let obs = observations(4, one.spec.obs_dim);
        let alone: Vec<f32> = Vec::try_from(tch::no_grad(|| one.forward(&obs))).unwrap();
        for combine in [Combine::Mean, Combine::Median] {
            let twice = PolicyEnsemble::new(vec![net(5, 8), net(5, 8)], combine).unwrap();
            let stacked = act(&twice, &obs);
            assert_eq!(alone.len(), 4);
            for (a, b) in alone.iter().zip(&stacked) {
                assert!((a - b).abs() < 1e-5, "{combine:?}: {a} against {b}");
            }
        }
        let own = act(&PolicyEnsemble::from(one), &obs);
        for (a, b) in alone.iter().zip(&own) {
            assert!((a - b).abs() < 1e-5, "one member: {a} against {b}");
        }
    }

    #[test]
    fn the_avx2_and_the_portable_code_give_the_same_bits() {
        let nets: Vec<PolicyNet> = (0..5).map(|k| net(20 + k, 64)).collect();
        let obs = observations(25, nets[0].spec.obs_dim);
        let mut ensemble = PolicyEnsemble::new(nets, Combine::Median).unwrap();
        ensemble.avx2 = false;
        let portable = act(&ensemble, &obs);
        ensemble.avx2 = has_avx2();
        let fast = act(&ensemble, &obs);
        let bits = |v: &[f32]| v.iter().map(|a| a.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&portable), bits(&fast));
        assert!(portable.iter().all(|a| a.is_finite() && a.abs() <= 9.81));
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
