//! Several trained networks of one shape deployed as one policy: each vehicle's action is the
//! median of their actions ([`Combine::Median`]) or their mean ([`Combine::Mean`]).
//!
//! Every seed of a study is trained by Algorithm 1 from another initialisation and lands on
//! another approximate equilibrium; in SUMO traffic the seeds of one set differ more than the
//! deployments they are compared across (`docs/experiments.md`). `mpgdrive cosim`
//! deploys the median of a set's seeds by default, one policy shared by every vehicle it drives
//! as a single network is; `--ensemble mean` takes their mean and `--policy-seed` one seed.
//! The median follows the seeds that agree: with the mean, one seed that brakes where the
//! others do not slows every vehicle (on `i80_merge` at demand 1.2, one traffic seed alone
//! drove its egos at 6.1 m/s in the game, the others at 8.1-10.0). Over the acceptance grid's
//! 12 rows at demand 1.2 the shipped set's median was faster than its mean in 10
//! (docs/experiments.md); for another training of the traffic set it held
//! fewer rows than the mean: no general gain.
//!
//! The forward pass is plain Rust over `f32` weights copied out of the networks at load time:
//! a deployment acts on a few dozen vehicles per step, where libtorch's cost per operation
//! (about 10 us each, some twelve operations per pass) outweighed the arithmetic. The
//! statistical study (`eval`, [`crate::policy::drive::policy_rollout`]) runs it too, on some
//! 2,250 rows per step and thread, where libtorch's fresh buffers cost a page fault per page
//! and the pass took half the time of the tables. Each output of a layer is summed over its
//! inputs in their order, the same on every x86-64 machine whatever the vector width the
//! processor offers (no fused multiply-add, no reassociation), so a co-simulation's or a
//! study's numbers do not depend on the machine's instruction set. Against libtorch's
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
#[derive(Debug, Clone)]
pub struct PolicyEnsemble {
    spec: NetSpec,
    members: Vec<Dense>,
    combine: Combine,
    /// The vector instructions of this processor (checked once, at construction).
    isa: Isa,
    /// Buffers kept from one call to the next: an evaluation acts on thousands of rows every
    /// step, and buffers that large, allocated afresh, cost a page fault per page.
    scratch: Scratch,
}

/// The working buffers of [`PolicyEnsemble::actions`].
#[derive(Debug, Clone, Default)]
struct Scratch {
    input: Vec<f32>,
    hidden: [Vec<f32>; 2],
    /// `[members][rows]`.
    each: Vec<f32>,
    column: Vec<f32>,
}

/// One member's weights: per layer, `[in][out]` row-major (each input's weights to every output
/// side by side) and `[out]` biases.
#[derive(Debug, Clone)]
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

/// The vector instructions [`dense`] uses, found once per ensemble.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Isa {
    /// Whatever the compiler targets by default.
    Portable,
    /// 256-bit registers.
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// 512-bit registers.
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

impl Isa {
    /// The widest this processor runs.
    fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                return Isa::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    }
}

/// `out = x w + b` for `rows` rows of `x` (`[rows][inputs]`) into `out` (`[rows][outputs]`):
/// each output summed over the inputs in their order, then the bias added, then the Leaky ReLU
/// applied if `leaky` ([`activation`]). Every path computes each output by the same scalar
/// operations in the same order, so all give the same bits.
fn dense(x: &[f32], rows: usize, w: &[f32], b: &[f32], out: &mut [f32], leaky: bool, isa: Isa) {
    let (inputs, outputs) = (w.len() / b.len(), b.len());
    assert!(w.len() == inputs * outputs && x.len() >= rows * inputs && out.len() >= rows * outputs);
    let (x, out) = (&x[..rows * inputs], &mut out[..rows * outputs]);
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found that this processor runs AVX-512F, the one requirement of
        // `dense_avx512` (safe code in every other respect).
        Isa::Avx512 if outputs % 64 == 0 => unsafe { dense_avx512(x, w, b, out, leaky) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found that this processor runs AVX2, the one requirement.
        Isa::Avx2 if outputs % 64 == 0 => unsafe { dense_avx2(x, w, b, out, leaky) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: this processor runs AVX2 (every AVX-512F processor does), the one requirement.
        Isa::Avx2 | Isa::Avx512 if outputs % 16 == 0 => unsafe { dense_avx2_narrow(x, w, b, out, leaky) },
        _ if outputs == 1 => dense_blocked::<8, 1>(x, w, b, out, leaky),
        _ => dense_rows(x, w, b, out, leaky),
    }
}

// The block sizes below were the fastest of those tried on a 64-wide layer (benches/ensemble.rs,
// `network_2250_rows`, on a 2-core Xeon with AVX-512).

/// [`dense`] with AVX-512F code generation: 2 rows by 64 outputs at a time.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn dense_avx512(x: &[f32], w: &[f32], b: &[f32], out: &mut [f32], leaky: bool) {
    dense_blocked::<2, 64>(x, w, b, out, leaky);
}

/// [`dense`] with AVX2 code generation: one row by 64 outputs at a time.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn dense_avx2(x: &[f32], w: &[f32], b: &[f32], out: &mut [f32], leaky: bool) {
    dense_blocked::<1, 64>(x, w, b, out, leaky);
}

/// [`dense`] with AVX2 code generation for layers of a multiple of 16 outputs: 4 rows by 16.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn dense_avx2_narrow(x: &[f32], w: &[f32], b: &[f32], out: &mut [f32], leaky: bool) {
    dense_blocked::<4, 16>(x, w, b, out, leaky);
}

/// [`dense`] in blocks of `R` rows by `W` outputs whose `R x W` sums stay in registers (so each
/// loaded weight serves `R` rows, and `R` independent sums hide the adds' latency), with
/// `outputs` a multiple of `W`; the rows after the last full block go one at a time, still `W`
/// outputs at once. Plain multiplies and adds (Rust does not fuse them), each sum over the
/// inputs in their order: the compiler vectorises across the `W` outputs, which does not
/// change any output's bits.
#[inline(always)]
fn dense_blocked<const R: usize, const W: usize>(
    x: &[f32],
    w: &[f32],
    b: &[f32],
    out: &mut [f32],
    leaky: bool,
) {
    let (inputs, outputs) = (w.len() / b.len(), b.len());
    let full = x.len() / inputs / R * R;
    let (x_blocks, x_rest) = x.split_at(full * inputs);
    let (out_blocks, out_rest) = out.split_at_mut(full * outputs);
    for (xs, os) in x_blocks
        .chunks_exact(R * inputs)
        .zip(out_blocks.chunks_exact_mut(R * outputs))
    {
        dense_block::<R, W>(xs, w, b, os, leaky);
    }
    for (xs, os) in x_rest
        .chunks_exact(inputs)
        .zip(out_rest.chunks_exact_mut(outputs))
    {
        dense_block::<1, W>(xs, w, b, os, leaky);
    }
}

/// `R` rows of [`dense_blocked`].
#[inline(always)]
fn dense_block<const R: usize, const W: usize>(
    xs: &[f32],
    w: &[f32],
    b: &[f32],
    os: &mut [f32],
    leaky: bool,
) {
    let (inputs, outputs) = (w.len() / b.len(), b.len());
    for j0 in (0..outputs).step_by(W) {
        let mut acc = [[0.0f32; W]; R];
        for k in 0..inputs {
            let wk: &[f32; W] = w[k * outputs + j0..][..W].try_into().expect("W weights");
            for (r, sums) in acc.iter_mut().enumerate() {
                let xv = xs[r * inputs + k];
                for (s, &wl) in sums.iter_mut().zip(wk) {
                    *s += xv * wl;
                }
            }
        }
        for (r, sums) in acc.iter().enumerate() {
            let o = &mut os[r * outputs + j0..][..W];
            for ((o, &s), &bl) in o.iter_mut().zip(sums).zip(&b[j0..j0 + W]) {
                *o = activation(s + bl, leaky);
            }
        }
    }
}

/// [`dense`] one row and one output at a time.
fn dense_rows(x: &[f32], w: &[f32], b: &[f32], out: &mut [f32], leaky: bool) {
    dense_blocked::<1, 1>(x, w, b, out, leaky);
}

/// The Leaky ReLU of `v` if `leaky`, else `v`. Applied as each output is stored, while it is
/// in a register (a pass of its own over a study's 2,250 x 64 hidden values took 6% of its
/// time); a select the compiler vectorises, as the signs of hidden units are unpredictable.
#[inline(always)]
fn activation(v: f32, leaky: bool) -> f32 {
    if leaky && v < 0.0 { v * LEAKY_SLOPE } else { v }
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
            isa: Isa::detect(),
            scratch: Scratch::default(),
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
    pub fn actions(&mut self, obs: &[f32], rows: usize, out: &mut [f32]) {
        assert_eq!(
            obs.len(),
            rows * self.spec.obs_dim,
            "observations of another width"
        );
        let (h, n) = (self.spec.hidden, self.members.len());
        let Scratch {
            input: x,
            hidden: [h1, h2],
            each,
            column,
        } = &mut self.scratch;
        x.clear();
        x.extend_from_slice(obs);
        for row in x.chunks_exact_mut(self.spec.obs_dim) {
            for (xi, &s) in row.iter_mut().zip(&self.spec.obs_scale) {
                *xi *= s;
            }
        }
        h1.resize(rows * h, 0.0);
        h2.resize(rows * h, 0.0);
        each.resize(n * rows, 0.0);
        let g = self.spec.action_scale as f32;
        for (member, y) in self.members.iter().zip(each.chunks_exact_mut(rows.max(1))) {
            let [(w1, b1), (w2, b2), (w3, b3)] = &member.layers;
            dense(x, rows, w1, b1, h1, true, self.isa);
            dense(h1, rows, w2, b2, h2, true, self.isa);
            dense(h2, rows, w3, b3, y, false, self.isa);
            for a in y.iter_mut() {
                *a = a.tanh() * g;
            }
        }
        column.resize(n, 0.0);
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
    fn act(ensemble: &mut PolicyEnsemble, obs: &Tensor) -> Vec<f32> {
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
        let mut ensemble = PolicyEnsemble::new(nets, Combine::Mean).unwrap();
        assert_eq!(ensemble.members(), 3);
        let out = act(&mut ensemble, &obs);
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
            let median = act(&mut PolicyEnsemble::new(nets, Combine::Median).unwrap(), &obs);
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
            let mut twice = PolicyEnsemble::new(vec![net(5, 8), net(5, 8)], combine).unwrap();
            let stacked = act(&mut twice, &obs);
            assert_eq!(alone.len(), 4);
            for (a, b) in alone.iter().zip(&stacked) {
                assert!((a - b).abs() < 1e-5, "{combine:?}: {a} against {b}");
            }
        }
        let own = act(&mut PolicyEnsemble::from(one), &obs);
        for (a, b) in alone.iter().zip(&own) {
            assert!((a - b).abs() < 1e-5, "one member: {a} against {b}");
        }
    }

    #[test]
    fn every_instruction_set_gives_the_same_bits() {
        // 64 hidden units take the wide blocks, 16 the narrow ones.
        for hidden in [64, 16] {
            let nets: Vec<PolicyNet> = (0..5).map(|k| net(20 + k, hidden)).collect();
            let obs = observations(25, nets[0].spec.obs_dim);
            let mut ensemble = PolicyEnsemble::new(nets, Combine::Median).unwrap();
            let detected = ensemble.isa;
            ensemble.isa = Isa::Portable;
            let portable = act(&mut ensemble, &obs);
            assert!(portable.iter().all(|a| a.is_finite() && a.abs() <= 9.81));
            #[cfg(target_arch = "x86_64")]
            for isa in [Isa::Avx2, Isa::Avx512] {
                // Only what this processor runs (AVX-512 processors run AVX2 too).
                if isa == Isa::Avx2 && detected != Isa::Portable || isa == detected {
                    ensemble.isa = isa;
                    let vector = act(&mut ensemble, &obs);
                    assert_eq!(bits(&portable), bits(&vector), "{isa:?}, {hidden} hidden");
                }
            }
        }
    }

    fn bits(v: &[f32]) -> Vec<u32> {
        v.iter().map(|a| a.to_bits()).collect()
    }

    #[test]
    fn a_row_gets_the_same_bits_in_any_batch() {
        // 25 rows at once (six blocks of four and one row alone), then rows 3..10 (one block
        // and three alone) after the larger call: each row's action does not depend on the
        // rows beside it or on what the buffers held before.
        let mut ensemble = PolicyEnsemble::from(net(30, 64));
        let obs = observations(25, ensemble.spec.obs_dim);
        let all = act(&mut ensemble, &obs);
        let part = act(&mut ensemble, &obs.narrow(0, 3, 7));
        assert_eq!(bits(&all[3..10]), bits(&part));
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
