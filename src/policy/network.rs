//! The shared policy network (Section IV): input layer, two fully connected hidden layers with
//! Leaky ReLU, output layer with tanh scaled to `[-g, g]`. One network serves every player
//! (parameter sharing); the one-hot agent index in the observation tells players apart.
//!
//! Inputs are normalised by fixed scales ([`OBS_SCALE`]), stored with the policy file.

use crate::policy::observation::{BatchPolicy, Layout, N_FEATURES};
use tch::{Device, Kind, Tensor, nn, nn::Module};

/// Scale of each Table I feature (the one-hot index is not scaled): distances by 100 m,
/// speeds by 30 m/s, relative speeds by 10 m/s, flags by 1.
pub const OBS_SCALE: [f32; N_FEATURES] = [0.01, 1.0 / 30.0, 0.01, 0.1, 1.0, 0.01, 0.1, 1.0, 1.0];
/// Scale of the traffic layout's features after Table I's: the same-lane leader's (distance,
/// relative speed, flag) and the desired speed (as speeds, by 30 m/s).
pub const TRAFFIC_SCALE: [f32; 4] = [0.01, 0.1, 1.0, 1.0 / 30.0];

/// Slope of the hidden layers' Leaky ReLU below 0 (libtorch's default, which
/// [`PolicyNet::forward`] uses); the hand-written passes of training and deployment use it too.
pub(crate) const LEAKY_SLOPE: f32 = 0.01;

/// Sizes and scales of a network, everything needed to rebuild it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NetSpec {
    /// Length of the one-hot agent index: the number of players `N` in Table I's layout, 0
    /// in the traffic layout.
    pub n_agents: usize,
    /// Observation width ([`Layout::dim`]).
    pub obs_dim: usize,
    /// Width of each hidden layer.
    pub hidden: usize,
    /// Action scale `g` (m/s^2).
    pub action_scale: f64,
    /// Input scales, one per observation entry.
    pub obs_scale: Vec<f32>,
}

impl NetSpec {
    /// The spec of a network reading `layout`.
    pub fn new(layout: Layout, hidden: usize, action_scale: f64) -> Self {
        let mut obs_scale = OBS_SCALE.to_vec();
        if layout == Layout::Traffic {
            obs_scale.extend(TRAFFIC_SCALE);
        }
        obs_scale.resize(layout.dim(), 1.0);
        NetSpec {
            n_agents: layout.one_hot(),
            obs_dim: layout.dim(),
            hidden,
            action_scale,
            obs_scale,
        }
    }
}

/// The network and its parameters.
#[derive(Debug)]
pub struct PolicyNet {
    /// Parameters (the variable names are those stored in the safetensors file).
    pub vs: nn::VarStore,
    /// Sizes and scales.
    pub spec: NetSpec,
    layers: [nn::Linear; 3],
    scale: Tensor,
}

/// Calls libtorch's `tanh` once in the process, before any network exists. On the CPU it is
/// MKL's vector math, which sets itself up on its first call, and a thread
/// calling it at that moment can get other roundings: measured, when two threads started
/// together each ran a network's first forward pass, one of them differed from every later
/// pass in 24 of 72 actions, in about 1 process start in 100 (9 of 900; 0 of 400 with this
/// call first). Every network is built under [`generator_lock`], after this.
fn settle_vector_math() {
    static SETTLED: std::sync::Once = std::sync::Once::new();
    SETTLED.call_once(|| {
        let x = Tensor::ones([64], (Kind::Float, Device::Cpu));
        let _ = x.tanh();
    });
}

/// The lock over libtorch's process-wide generator while a network is initialised.
fn generator_lock() -> std::sync::MutexGuard<'static, ()> {
    settle_vector_math();
    static GENERATOR: std::sync::Mutex<()> = std::sync::Mutex::new(());
    GENERATOR
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl PolicyNet {
    /// A freshly initialised network (libtorch's default initialisation from its global
    /// generator; [`PolicyNet::seeded`] for a reproducible one).
    pub fn new(spec: NetSpec) -> Self {
        let _guard = generator_lock();
        PolicyNet::build(spec)
    }

    /// A network initialised from `seed`. libtorch's generator is process-wide: seeding and
    /// initialising happen under one lock (which every construction takes), so threads creating
    /// networks at the same time (tests run in parallel, say) cannot interleave and change each
    /// other's weights.
    pub fn seeded(spec: NetSpec, seed: i64) -> Self {
        let _guard = generator_lock();
        tch::manual_seed(seed);
        PolicyNet::build(spec)
    }

    fn build(spec: NetSpec) -> Self {
        let vs = nn::VarStore::new(Device::Cpu);
        let root = vs.root();
        let (d, h) = (spec.obs_dim as i64, spec.hidden as i64);
        let layers = [
            nn::linear(&root / "hidden1", d, h, Default::default()),
            nn::linear(&root / "hidden2", h, h, Default::default()),
            nn::linear(&root / "output", h, 1, Default::default()),
        ];
        let scale = Tensor::from_slice(&spec.obs_scale);
        PolicyNet {
            vs,
            spec,
            layers,
            scale,
        }
    }

    /// Actions `[..]` for observations `[.., obs_dim]` (raw SI values; normalised here).
    pub fn forward(&self, obs: &Tensor) -> Tensor {
        let x = obs.to_kind(Kind::Float) * &self.scale;
        let x = self.layers[0].forward(&x).leaky_relu();
        let x = self.layers[1].forward(&x).leaky_relu();
        self.layers[2].forward(&x).tanh().squeeze_dim(-1) * self.spec.action_scale
    }

    /// Layer `k` (0 and 1 hidden, 2 the output).
    pub(crate) fn layer(&self, k: usize) -> &nn::Linear {
        &self.layers[k]
    }

    /// An independent copy (for another thread).
    pub fn try_clone(&self) -> Result<Self, tch::TchError> {
        let mut copy = PolicyNet::new(self.spec.clone());
        copy.vs.copy(&self.vs)?;
        Ok(copy)
    }
}

impl BatchPolicy for PolicyNet {
    fn act(&mut self, obs: &[f32], rows: usize, out: &mut [f32]) {
        let input = Tensor::from_slice(obs).reshape([rows as i64, self.spec.obs_dim as i64]);
        let actions = tch::no_grad(|| self.forward(&input));
        let values = Vec::<f32>::try_from(actions).expect("a CPU float tensor");
        out[..rows].copy_from_slice(&values);
    }
}
