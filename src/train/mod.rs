//! Training: potential-based gradient ascent (Algorithm 1) and the single-agent baseline.
//!
//! Each epoch draws a stratified minibatch of initial states (part of it near the merge with
//! `train.near_merge`, [`crate::world::sampler::sample_training_scenes`]), rolls the shared
//! policy out in the differentiable tensor engine ([`crate::engine::tensor`], on the tape of
//! [`crate::engine::tape`]; the network's own backward pass is [`StackedNet::act_on_tape`])
//! and takes one Adam step on the gradient, back-propagated through the whole rollout, of
//! - `mpg`: the mean discounted total potential, eq. (29), with the policy driving every player;
//! - `sarl`: the ego's mean discounted return `J_ego`, the other players driven by IDM.
//!
//! Episodes stop counting at their first collision. After each step the policy is measured on a
//! fixed probe set (disjoint from training) in the scalar engine: mean objective, collision and
//! failure rates, and the mean squared difference of the probe actions from the previous epoch.

pub mod adam;
pub mod checkpoint;
pub mod curves;
pub mod stacked;
pub mod workers;

use crate::atomic::with_suffix;
use crate::config::Config;
use crate::engine::outcome::EpisodeOutcome;
use crate::engine::rollout::{Recording, RolloutOptions, rollout};
use crate::engine::tape::{self, Var};
use crate::engine::tensor::{self, idm_actions};
use crate::eval::EpisodeMetrics;
use crate::num::Num;
use crate::policy::file::{self, PolicyError, Sidecar};
pub use crate::policy::mode::Mode;
use crate::policy::network::{NetSpec, PolicyNet};
use crate::policy::observation::{BatchPolicy, PolicyActor};
use crate::policy::observation::{Frame, Layout, observe, tensor_features};
use crate::world::drivers::Driver;
use crate::world::neighbors::find_neighbors;
use crate::world::sampler::{Purpose, purpose_seed, sample_probe_scenes, sample_training_scenes};
use crate::world::state::Scene;
use adam::Adam;
use curves::EpochRecord;
use stacked::{ParamGrads, StackedNet};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use tch::{Kind, Tensor};
use workers::Workers;

/// A training failure.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// Writing or reading a policy or checkpoint failed.
    #[error(transparent)]
    Policy(#[from] PolicyError),
    /// Writing the curves failed.
    #[error("cannot write {path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A checkpoint does not belong to this run.
    #[error("checkpoint {path} was made by another run ({message}); remove it or drop --resume")]
    ForeignCheckpoint {
        /// The checkpoint.
        path: PathBuf,
        /// What differs.
        message: String,
    },
    /// Stopped by a request (Ctrl-C); a checkpoint of the last finished epoch of every run
    /// was written.
    #[error(
        "interrupted after epoch {epoch}; checkpoints written ({checkpoint} and one per other seed), continue with --resume"
    )]
    Interrupted {
        /// Last finished epoch.
        epoch: usize,
        /// The checkpoint base path of the first run.
        checkpoint: PathBuf,
    },
    /// A checkpoint's optimiser state cannot be used.
    #[error("{path}: {message}; remove it to resume with Adam's moments restarted")]
    OptimiserState {
        /// The state's file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The objective stopped being a finite number.
    #[error(
        "training of seed {seed} diverged at epoch {epoch}: the objective is {value}; lower train.learning_rate or train.grad_clip"
    )]
    Diverged {
        /// The run's seed.
        seed: u64,
        /// The epoch.
        epoch: usize,
        /// The objective's value.
        value: f64,
    },
    /// libtorch failed.
    #[error("libtorch: {0}")]
    Torch(#[from] tch::TchError),
}

/// One training run.
#[derive(Debug, Clone)]
pub struct TrainRun {
    /// What to learn.
    pub mode: Mode,
    /// Seed of the network initialisation and of the training states.
    pub seed: u64,
    /// Output base path: writes `BASE.safetensors`, `BASE.json`, `BASE.curves.csv` and, while
    /// training, `BASE.ckpt.*`.
    pub out: PathBuf,
    /// Continue from `BASE.ckpt.*` when present.
    pub resume: bool,
    /// The command line, recorded in the sidecar.
    pub command: String,
}

/// The curves CSV path of a run.
pub fn curves_path(out: &Path) -> PathBuf {
    with_suffix(out, ".curves.csv")
}

/// Raw actions of every player for a tensor batch of `members` x `batch` scenarios (member
/// `k`'s scenarios are rows `k * batch ..`): each member's network for the players it drives,
/// IDM for the others.
fn tensor_actions(
    config: &Config,
    net: &StackedNet,
    grads: &ParamGrads,
    mode: Mode,
    batch: &tensor::TensorBatch,
    nb: &tensor::NeighborIndex,
) -> Var {
    let layout = Layout::of(config);
    let features = tensor_features(layout, Frame::of(config), batch, nb);
    match mode {
        Mode::Mpg => net.act_on_tape(layout, &features, grads),
        Mode::Sarl => {
            let first: std::rc::Rc<[usize]> = [0].into();
            let ego_features: Vec<Var> = features.iter().map(|f| f.select_cols(&first)).collect();
            let ego = net.act_on_tape(layout, &ego_features, grads);
            let (b, n) = (batch.x.rows(), batch.x.cols());
            let is_ego = Var::constant(
                (0..b * n).map(|k| f64::from(u8::from(k % n == 0))).collect(),
                b,
                n,
            );
            Var::select(&is_ego, &ego, &idm_actions(config, batch, nb))
        }
    }
}

/// Actions of every player at the probe initial states of every member (for the
/// action-difference curve): `[members, scenes * players]`.
fn probe_actions(config: &Config, net: &mut StackedNet, probe: &[Scene]) -> Tensor {
    let n = config.n_agents();
    let layout = Layout::of(config);
    let dim = layout.dim();
    let mut obs = vec![0f32; probe.len() * n * dim];
    let (mut order, mut nb) = (Vec::new(), Vec::new());
    for (b, scene) in probe.iter().enumerate() {
        find_neighbors(scene, &mut order, &mut nb);
        for (i, neighbors) in nb.iter().enumerate() {
            let row = b * n + i;
            observe(
                layout,
                Frame::of(config),
                scene,
                i,
                neighbors,
                &mut obs[row * dim..(row + 1) * dim],
            );
        }
    }
    let mut actions = vec![0f32; probe.len() * n];
    net.act(&obs, actions.len(), &mut actions);
    Tensor::from_slice(&actions).reshape([net.members() as i64, -1])
}

fn objective(mode: Mode, o: &EpisodeOutcome) -> f64 {
    match mode {
        Mode::Mpg => o.potential_return,
        Mode::Sarl => o.returns[0],
    }
}

fn sidecar(
    config: &Config,
    run: &TrainRun,
    net: &PolicyNet,
    epochs: usize,
    metrics: serde_json::Value,
) -> Sidecar {
    Sidecar {
        format: file::FORMAT.to_string(),
        obs_layout_version: Layout::of(config).version(),
        net: net.spec.clone(),
        mode: run.mode,
        seed: run.seed,
        epochs,
        command: run.command.clone(),
        code_version: crate::VERSION.to_string(),
        config: config.clone(),
        metrics,
    }
}

/// The epochs of the step-size cycle holding `epoch` (from 0): from the last of
/// `train.learning_rate_restarts` at or before it (else 0) up to the next one (else
/// `train.epochs`), exclusive.
pub fn learning_rate_cycle(t: &crate::config::TrainConfig, epoch: usize) -> std::ops::Range<usize> {
    let restarts = &t.learning_rate_restarts;
    let next = restarts.partition_point(|&r| r <= epoch);
    let start = if next == 0 { 0 } else { restarts[next - 1] };
    start..restarts.get(next).copied().unwrap_or(t.epochs)
}

/// Step size of `epoch` (from 0): exponential decay from `learning_rate` to
/// `learning_rate_final` over its cycle ([`learning_rate_cycle`]; without restarts, the
/// whole run).
pub fn learning_rate(t: &crate::config::TrainConfig, epoch: usize) -> f64 {
    let cycle = learning_rate_cycle(t, epoch);
    let progress = if cycle.len() > 1 {
        (epoch - cycle.start) as f64 / (cycle.len() - 1) as f64
    } else {
        0.0
    };
    t.learning_rate * (t.learning_rate_final / t.learning_rate).powf(progress)
}

/// Adam's steps after `epochs` epochs: those since the last step-size restart.
fn adam_steps_after(t: &crate::config::TrainConfig, epochs: usize) -> usize {
    epochs
        .checked_sub(1)
        .map_or(0, |last| epochs - learning_rate_cycle(t, last).start)
}

/// The reward's `epsilon` in training epoch `epoch`: `reward.epsilon`, or during
/// `train.continuation`'s epochs a geometric decay from its `epsilon_start` to it.
pub fn training_epsilon(config: &Config, epoch: usize) -> f64 {
    let end = config.reward.epsilon;
    match &config.train.continuation {
        Some(c) if epoch < c.epochs => {
            end * (c.epsilon_start / end).powf(1.0 - epoch as f64 / c.epochs as f64)
        }
        _ => end,
    }
}

/// The training world's `sim.shared_correction` in epoch `epoch`: the configured one, or
/// `train.correction_continuation`'s `start` until its first epoch, then linearly to the
/// configured one by its last.
pub fn training_shared_correction(config: &Config, epoch: usize) -> f64 {
    let end = config.sim.shared_correction;
    match &config.train.correction_continuation {
        Some(c) if epoch < c.epochs[1] => {
            let [from, to] = c.epochs;
            let progress = if epoch <= from {
                0.0
            } else {
                (epoch - from) as f64 / (to - from) as f64
            };
            c.start + (end - c.start) * progress
        }
        _ => end,
    }
}

/// Networks trained together: the stacked parameters, their optimiser, and each member's
/// training seed (whose stream gives its minibatches).
struct Stack {
    mode: Mode,
    net: StackedNet,
    adam: Adam,
    seeds: Vec<u64>,
}

impl Stack {
    fn new(mode: Mode, nets: &[PolicyNet], seeds: Vec<u64>) -> Self {
        let net = StackedNet::from_nets(nets);
        let adam = Adam::new(&net.param_lengths());
        Stack {
            mode,
            net,
            adam,
            seeds,
        }
    }

    /// One epoch of Algorithm 1 for every member: gradient ascent on its objective over its
    /// minibatch of training states (the learning-rate schedule of `epoch`), all members in
    /// one rollout per shard ([`SHARDS`]). Returns each member's minibatch objective.
    fn gradient_step<'env>(
        &mut self,
        config: &'env Config,
        workers: &Workers<'env>,
        epoch: usize,
    ) -> Result<Vec<f64>, TrainError> {
        let t = &config.train;
        if t.learning_rate_restarts.contains(&epoch) {
            self.adam = Adam::new(&self.net.param_lengths());
        }
        let scenes: Vec<Scene> = self
            .seeds
            .iter()
            .flat_map(|&s| sample_training_scenes(config, purpose_seed(s, Purpose::Train), epoch))
            .collect();
        let members = self.seeds.len();
        let mut epoch_config = config.clone();
        epoch_config.reward.epsilon = training_epsilon(config, epoch);
        epoch_config.sim.shared_correction = training_shared_correction(config, epoch);
        let shards = shards_of(&self.net, &scenes, members);
        let mode = self.mode;
        let results = workers.run(shards, move |(net, scenes)| {
            shard_gradient(&epoch_config, mode, &net, &scenes, members)
        });
        let mut values = vec![0.0; members];
        let mut sums: Option<Vec<Tensor>> = None;
        for (objectives, grads) in results {
            values.iter_mut().zip(objectives).for_each(|(v, o)| *v += o);
            sums = match (sums, grads) {
                (Some(a), Some(b)) => Some(a.iter().zip(&b).map(|(a, b)| a + b).collect()),
                (a, b) => a.or(b),
            };
        }
        values.iter_mut().for_each(|v| *v /= t.batch as f64);
        let diverged = |k: usize, value: f64| TrainError::Diverged {
            seed: self.seeds[k],
            epoch: epoch + 1,
            value,
        };
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(diverged(k, values[k]));
        }
        self.net.zero_grads();
        if let Some(sums) = sums {
            self.net.set_grads(&sums);
        }
        self.net.clip_grad_norm(t.grad_clip);
        self.net.adam_step(&mut self.adam, learning_rate(t, epoch));
        // A NaN gradient would poison the parameters without changing this epoch's objective.
        if let Some(k) = self.net.finite().iter().position(|ok| !ok) {
            return Err(diverged(k, f64::NAN));
        }
        Ok(values)
    }
}

/// Every member's minibatch and probe set run as this many shards, each the same block of
/// every member's scenes on its own thread and tape. Their gradients add up in shard order,
/// so the weights do not depend on how many threads run the shards (`train.threads`).
pub const SHARDS: usize = 2;

/// The shards of `scenes` (each member's in turn, as many for each) that hold scenes, each
/// with its own copy of the networks.
fn shards_of(net: &StackedNet, scenes: &[Scene], members: usize) -> Vec<(StackedNet, Vec<Scene>)> {
    let per_member = scenes.len() / members;
    let size = per_member.div_ceil(SHARDS);
    (0..SHARDS)
        .map(|k| (k * size).min(per_member)..((k + 1) * size).min(per_member))
        .filter(|range| !range.is_empty())
        .map(|range| {
            let block = scenes
                .chunks(per_member)
                .flat_map(|own| own[range.clone()].iter().cloned())
                .collect();
            (net.snapshot(), block)
        })
        .collect()
}

/// One shard's part of a gradient step: each member's summed objective over its scenes of
/// the shard, and the gradients of minus the members' mean objectives (over the whole
/// minibatch, `train.batch` scenes each) restricted to these scenes.
fn shard_gradient(
    config: &Config,
    mode: Mode,
    net: &StackedNet,
    scenes: &[Scene],
    members: usize,
) -> (Vec<f64>, Option<Vec<Tensor>>) {
    let run = tensor::TensorRun {
        steps: config.n_steps(),
        feasibility: config.sim.feasibility,
        terminate_on_collision: config.sim.terminate_on_collision,
        learning: match mode {
            Mode::Mpg => tensor::Learning::All,
            Mode::Sarl => tensor::Learning::Ego,
        },
        sums: match mode {
            Mode::Mpg => tensor::Sums::Potential,
            Mode::Sarl => tensor::Sums::Returns,
        },
    };
    let grads = ParamGrads::default();
    tape::start();
    let out = tensor::rollout(config, scenes, &run, |b, nb, _| {
        tensor_actions(config, net, &grads, mode, b, nb)
    });
    // The objective of an episode: its potential (MPG) or the ego's return (SARL).
    let root = match mode {
        Mode::Mpg => out.potential,
        Mode::Sarl => out.returns,
    }
    .expect("the run's sums hold its objective");
    let cols = root.cols();
    let sums = root
        .values()
        .chunks(cols * scenes.len() / members)
        .map(|own| own.iter().step_by(cols).sum())
        .collect();
    let weight = -1.0 / config.train.batch as f64;
    let seed = (0..root.values().len())
        .map(|k| if k % cols == 0 { weight } else { 0.0 })
        .collect();
    tape::backward(&root, seed);
    (sums, grads.take().map(|s| net.grad_tensors(&s)))
}

/// Rolls every member out on its probe states (`probe`: each member's scenes in turn, as
/// many for each) in the scalar engine, the members' networks in one batched call per step.
/// Returns the outcomes, member after member.
fn probe_outcomes<'env>(
    config: &'env Config,
    workers: &Workers<'env>,
    mode: Mode,
    net: &StackedNet,
    probe: &[Scene],
) -> Vec<EpisodeOutcome> {
    let members = net.members();
    let shards = workers.run(
        shards_of(net, probe, members),
        move |(net, scenes): (StackedNet, Vec<Scene>)| {
            let opts = RolloutOptions {
                threads: 1,
                // A single-agent ego's probe objective is its own return: the other players'
                // rewards are not needed (the same bits, `tests/rollout.rs`).
                recording: match mode {
                    Mode::Mpg => Recording::Summary,
                    Mode::Sarl => Recording::Ego,
                },
                ..RolloutOptions::from_config(config)
            };
            let frozen = Mutex::new(Some(net));
            // One rollout worker: the batched call needs every member's rows.
            rollout(config, &opts, &scenes, || {
                let net = frozen.lock().expect("probe lock").take().expect("one worker");
                PolicyActor::new(config, net, Driver::Idm, mode == Mode::Mpg)
            })
        },
    );
    // Member after member: its outcomes of each shard in turn.
    let mut outcomes = Vec::with_capacity(probe.len());
    let mut parts: Vec<_> = shards
        .into_iter()
        .map(|o| {
            let per_member = o.len() / members;
            let mut o = o.into_iter();
            (0..members)
                .map(|_| o.by_ref().take(per_member).collect::<Vec<_>>())
                .collect::<Vec<_>>()
                .into_iter()
        })
        .collect();
    for _ in 0..members {
        for part in &mut parts {
            outcomes.extend(part.next().expect("one block per member"));
        }
    }
    outcomes
}

/// Each member's mean objective over its probe outcomes.
fn mean_objectives(mode: Mode, outcomes: &[EpisodeOutcome], members: usize) -> Vec<f64> {
    outcomes
        .chunks(outcomes.len() / members)
        .map(|c| c.iter().map(|o| objective(mode, o)).sum::<f64>() / c.len() as f64)
        .collect()
}

/// Each member's epoch record on the probe states (all but its training objective, epoch
/// number and wall time), and the new probe actions.
fn probe<'env>(
    config: &'env Config,
    workers: &Workers<'env>,
    mode: Mode,
    net: &mut StackedNet,
    probe: &[Scene],
    previous: &Tensor,
) -> (Vec<EpochRecord>, Tensor) {
    let outcomes = probe_outcomes(config, workers, mode, net, probe);
    let actions = probe_actions(config, net, probe);
    let msd = Vec::<f64>::try_from(
        (&actions - previous)
            .square()
            .mean_dim(1, false, Kind::Float)
            .to_kind(Kind::Double),
    )
    .expect("a CPU tensor");
    let objectives = mean_objectives(mode, &outcomes, net.members());
    let records = outcomes
        .chunks(outcomes.len() / net.members())
        .zip(objectives.into_iter().zip(msd))
        .map(|(outcomes, (probe_objective, action_msd))| {
            let m = outcomes.len() as f64;
            let metrics: Vec<_> = outcomes.iter().map(EpisodeMetrics::of).collect();
            EpochRecord {
                epoch: 0,
                train_objective: 0.0,
                probe_objective,
                action_msd,
                probe_collision_rate: metrics.iter().filter(|x| x.collision).count() as f64 / m,
                probe_failure_rate: metrics.iter().filter(|x| x.failure).count() as f64 / m,
                wall_seconds: 0.0,
                probe_ego_return: Some(outcomes.iter().map(|o| o.returns[0]).sum::<f64>() / m),
            }
        })
        .collect();
    (records, actions)
}

/// The probe initial states of each member's seed, member after member.
fn member_seeds_probe(config: &Config, seeds: &[u64]) -> Vec<Scene> {
    seeds
        .iter()
        .flat_map(|&s| sample_probe_scenes(config, purpose_seed(s, Purpose::Probe)))
        .collect()
}

/// The sidecar metrics: the last epoch's record, plus the initialisation screening if any.
fn sidecar_metrics(records: &[EpochRecord], screening: &Option<InitScreening>) -> serde_json::Value {
    let mut m = serde_json::json!(records.last());
    if let (Some(s), Some(obj)) = (screening, m.as_object_mut()) {
        obj.insert("init_screening".into(), serde_json::json!(s));
    }
    m
}

/// The libtorch seed of initialisation candidate `candidate` of a run: candidate 0 is the
/// run's own seed (so one candidate trains exactly as before screening existed).
pub fn init_seed(seed: u64, candidate: usize) -> i64 {
    seed as i64 + 1000 * candidate as i64
}

/// Initialisation screening: each candidate initialisation trains for `screen_epochs`, and
/// the one with the best probe objective is kept.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct InitScreening {
    /// Epochs each candidate trained.
    pub screen_epochs: usize,
    /// Probe objective of each candidate after them.
    pub probe_objectives: Vec<f64>,
    /// The candidate kept (the first of the best).
    pub chosen: usize,
}

/// Screens `train.init_candidates` initialisations of every run (see [`InitScreening`]), all
/// candidates of all runs trained side by side.
fn screen_inits<'env>(
    config: &'env Config,
    workers: &Workers<'env>,
    mode: Mode,
    seeds: &[u64],
) -> Result<Vec<InitScreening>, TrainError> {
    let t = &config.train;
    let spec = NetSpec::new(Layout::of(config), t.hidden, config.vehicle.max_accel);
    let members: Vec<(PolicyNet, u64)> = seeds
        .iter()
        .flat_map(|&seed| (0..t.init_candidates).map(move |c| (seed, c)))
        .map(|(seed, c)| (PolicyNet::seeded(spec.clone(), init_seed(seed, c)), seed))
        .collect();
    let (nets, seeds): (Vec<PolicyNet>, Vec<u64>) = members.into_iter().unzip();
    let mut stack = Stack::new(mode, &nets, seeds);
    for epoch in 0..t.screen_epochs {
        stack.gradient_step(config, workers, epoch)?;
    }
    let probe_set = member_seeds_probe(config, &stack.seeds);
    let outcomes = probe_outcomes(config, workers, mode, &stack.net, &probe_set);
    let objectives = mean_objectives(mode, &outcomes, nets.len());
    let screenings = objectives
        .chunks(t.init_candidates)
        .map(|probe_objectives| InitScreening {
            screen_epochs: t.screen_epochs,
            probe_objectives: probe_objectives.to_vec(),
            // The first of the best.
            chosen: (0..probe_objectives.len()).fold(0, |best, c| {
                if probe_objectives[c] > probe_objectives[best] {
                    c
                } else {
                    best
                }
            }),
        })
        .collect();
    Ok(screenings)
}

/// What a finished run learned.
#[derive(Debug, Clone)]
pub struct TrainOutcome {
    /// The curves, one record per epoch.
    pub records: Vec<EpochRecord>,
    /// The initialisation screening, when there was one.
    pub screening: Option<InitScreening>,
}

/// A run's state before its training loop: its network, its curves so far and its screening.
struct Start {
    net: PolicyNet,
    records: Vec<EpochRecord>,
    screening: Option<InitScreening>,
    /// Adam's state at the checkpoint, when it was saved with it.
    moments: Option<Adam>,
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> TrainError + '_ {
    move |source| TrainError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Where `run` starts: its checkpoint with `--resume`, else a fresh network (not yet screened).
fn start_of(config: &Config, run: &TrainRun) -> Result<Start, TrainError> {
    let t = &config.train;
    if let Some(dir) = run.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io_error(dir))?;
    }
    if let Some(ckpt) = checkpoint::latest(&run.out).filter(|_| run.resume) {
        let (net, side) = file::load(&ckpt, Layout::of(config))?;
        if side.mode != run.mode || side.seed != run.seed || side.config != *config {
            return Err(TrainError::ForeignCheckpoint {
                path: ckpt,
                message: "its mode, seed or configuration differs".into(),
            });
        }
        let screening = side
            .metrics
            .get("init_screening")
            .and_then(|s| serde_json::from_value(s.clone()).ok());
        let curves = curves_path(&run.out);
        let mut records = curves::read(&curves).map_err(io_error(&curves))?;
        records.truncate(side.epochs);
        // A checkpoint written before the optimiser state was kept has none (Adam restarts).
        let path = checkpoint::moments_path(&ckpt);
        let moments = if path.exists() {
            let lengths = StackedNet::from_nets(std::slice::from_ref(&net)).param_lengths();
            let steps = adam_steps_after(t, side.epochs) as u64;
            let state = Adam::load(&path, &lengths).and_then(|m| match m.steps == steps {
                true => Ok(m),
                false => Err(format!(
                    "it holds {} steps; the checkpoint after epoch {} asks for {steps}",
                    m.steps, side.epochs
                )),
            });
            Some(state.map_err(|message| TrainError::OptimiserState { path, message })?)
        } else {
            None
        };
        return Ok(Start {
            net,
            records,
            screening,
            moments,
        });
    }
    Ok(Start {
        net: PolicyNet::seeded(
            NetSpec::new(Layout::of(config), t.hidden, config.vehicle.max_accel),
            run.seed as i64,
        ),
        records: Vec::new(),
        screening: None,
        moments: None,
    })
}

/// Writes a run's curves and policy file (`base`: the checkpoint or the final policy).
fn save_run(
    config: &Config,
    run: &TrainRun,
    base: &Path,
    net: &PolicyNet,
    records: &[EpochRecord],
    screening: &Option<InitScreening>,
) -> Result<(), TrainError> {
    let curves = curves_path(&run.out);
    curves::write(&curves, records).map_err(io_error(&curves))?;
    let side = sidecar(
        config,
        run,
        net,
        records.len(),
        sidecar_metrics(records, screening),
    );
    file::save(base, net, &side)?;
    Ok(())
}

/// Keeps memory that training frees inside the process. Back-propagation through a whole
/// rollout saves many large arrays and frees them every epoch; glibc's defaults return them
/// to the kernel (`munmap`, heap trimming), and faulting them in again cost a fifth of the
/// training time (measured with `perf`). A shard thread's arena also deletes a heap that
/// becomes empty whatever the trim threshold, unless the top pad is large.
fn keep_freed_memory() {
    #[cfg(target_env = "gnu")]
    // SAFETY: mallopt only changes glibc's allocation thresholds; it is called before
    // training allocates, and any value is valid for these three parameters.
    unsafe {
        // 32 MiB, glibc's largest threshold (a larger value is refused), above training's
        // largest tensor; setting it also stops glibc from moving it.
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
        // A thread arena's heap is 64 MiB at most: a pad as large keeps emptied heaps. (One
        // arena for all threads keeps them too, but its lock made some runs 50% slower.)
        libc::mallopt(libc::M_TOP_PAD, 64 << 20);
    }
}

/// Trains one policy; `on_epoch` sees every epoch's record. Returns the curves.
///
/// When `stop` becomes true, training ends after the current epoch with a checkpoint and
/// [`TrainError::Interrupted`].
pub fn train(
    config: &Config,
    run: &TrainRun,
    stop: &AtomicBool,
    on_epoch: &mut dyn FnMut(&EpochRecord),
) -> Result<Vec<EpochRecord>, TrainError> {
    let mut outcomes = train_all(config, std::slice::from_ref(run), stop, &mut |_, r| on_epoch(r))?;
    Ok(outcomes.remove(0).records)
}

/// Trains every run (one mode, one seed each) side by side: their networks stacked
/// ([`StackedNet`]) and their rollouts in one batch (in [`SHARDS`] shards), so that the
/// per-operation cost is paid once for all of them. Each run learns what it would learn
/// alone (a member's computation does not depend on the others). `on_epoch` sees each run's
/// records with the run's index.
///
/// When `stop` becomes true, training ends after the current epoch with a checkpoint of every
/// run and [`TrainError::Interrupted`].
pub fn train_all(
    config: &Config,
    runs: &[TrainRun],
    stop: &AtomicBool,
    on_epoch: &mut dyn FnMut(usize, &EpochRecord),
) -> Result<Vec<TrainOutcome>, TrainError> {
    keep_freed_memory();
    std::thread::scope(|scope| {
        let workers = Workers::start(scope, config.train.threads);
        train_on(config, &workers, runs, stop, on_epoch)
    })
}

/// [`train_all`] with its shards on `workers`.
fn train_on<'env>(
    config: &'env Config,
    workers: &Workers<'env>,
    runs: &[TrainRun],
    stop: &AtomicBool,
    on_epoch: &mut dyn FnMut(usize, &EpochRecord),
) -> Result<Vec<TrainOutcome>, TrainError> {
    let t = &config.train;
    let mut starts = runs
        .iter()
        .map(|run| start_of(config, run))
        .collect::<Result<Vec<_>, _>>()?;
    // Screening, for every run that starts from scratch, all modes' candidates per mode.
    for mode in [Mode::Mpg, Mode::Sarl] {
        let fresh: Vec<usize> = (0..runs.len())
            .filter(|&r| runs[r].mode == mode && starts[r].records.is_empty())
            .collect();
        if t.init_candidates > 1 && !fresh.is_empty() {
            let seeds: Vec<u64> = fresh.iter().map(|&r| runs[r].seed).collect();
            for (&r, screening) in fresh.iter().zip(screen_inits(config, workers, mode, &seeds)?) {
                starts[r].net = PolicyNet::seeded(
                    NetSpec::new(Layout::of(config), t.hidden, config.vehicle.max_accel),
                    init_seed(runs[r].seed, screening.chosen),
                );
                starts[r].screening = Some(screening);
            }
        }
    }
    // Runs that start at the same epoch in the same mode train together.
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for r in 0..runs.len() {
        let same = |g: &Vec<usize>| {
            runs[g[0]].mode == runs[r].mode && starts[g[0]].records.len() == starts[r].records.len()
        };
        match groups.iter_mut().find(|g| same(g)) {
            Some(g) => g.push(r),
            None => groups.push(vec![r]),
        }
    }
    let mut starts: Vec<Option<Start>> = starts.into_iter().map(Some).collect();
    let mut finished: Vec<Option<TrainOutcome>> = (0..runs.len()).map(|_| None).collect();
    for group in groups {
        let members: Vec<(&TrainRun, Start)> = group
            .iter()
            .map(|&r| (&runs[r], starts[r].take().expect("one group per run")))
            .collect();
        let outcomes = train_members(config, workers, &members, stop, &mut |k, record| {
            on_epoch(group[k], record)
        })?;
        for (&r, outcome) in group.iter().zip(outcomes) {
            finished[r] = Some(outcome);
        }
    }
    Ok(finished
        .into_iter()
        .map(|o| o.expect("every run in a group"))
        .collect())
}

/// The training loop of some runs of one mode that start at the same epoch, in one stack.
fn train_members<'env>(
    config: &'env Config,
    workers: &Workers<'env>,
    members: &[(&TrainRun, Start)],
    stop: &AtomicBool,
    on_epoch: &mut dyn FnMut(usize, &EpochRecord),
) -> Result<Vec<TrainOutcome>, TrainError> {
    let t = &config.train;
    let mode = members[0].0.mode;
    let nets: Vec<PolicyNet> = members
        .iter()
        .map(|(_, s)| s.net.try_clone())
        .collect::<Result<_, _>>()?;
    let mut stack = Stack::new(mode, &nets, members.iter().map(|(r, _)| r.seed).collect());
    // Resumed runs continue Adam where it stopped when every member kept its state;
    // otherwise the moments restart (as for checkpoints written before they were kept).
    let moments: Option<Vec<Adam>> = members.iter().map(|(_, s)| s.moments.clone()).collect();
    if let Some(moments) = moments {
        stack.adam = Adam::of_members(&moments);
    }
    let probe_set = member_seeds_probe(config, &stack.seeds);
    let mut previous = probe_actions(config, &mut stack.net, &probe_set);
    let mut records: Vec<Vec<EpochRecord>> = members.iter().map(|(_, s)| s.records.clone()).collect();
    let first = records[0].len();
    let start = Instant::now();
    for epoch in first..t.epochs {
        let train_objectives = stack.gradient_step(config, workers, epoch)?;
        let (probed, actions) = probe(config, workers, mode, &mut stack.net, &probe_set, &previous);
        previous = actions;
        for (k, ((_, s), mut record)) in members.iter().zip(probed).enumerate() {
            record.epoch = epoch + 1;
            record.train_objective = train_objectives[k];
            let before = s.records.last().map_or(0.0, |r| r.wall_seconds);
            record.wall_seconds = before + start.elapsed().as_secs_f64();
            on_epoch(k, &record);
            records[k].push(record);
        }
        let interrupted = stop.load(Ordering::SeqCst);
        let checkpoint = ((epoch + 1) % t.checkpoint_every == 0 || interrupted) && epoch + 1 < t.epochs;
        if checkpoint {
            for (k, (run, s)) in members.iter().enumerate() {
                let net = stack.net.member(k)?;
                checkpoint::write(&run.out, |ckpt| {
                    // The state first: the sidecar written last marks the checkpoint complete.
                    stack
                        .adam
                        .member(k, members.len())
                        .save(&checkpoint::moments_path(ckpt))?;
                    save_run(config, run, ckpt, &net, &records[k], &s.screening)
                })?;
            }
        }
        if checkpoint && interrupted {
            return Err(TrainError::Interrupted {
                epoch: epoch + 1,
                checkpoint: checkpoint::checkpoint_path(&members[0].0.out),
            });
        }
    }
    let mut outcomes = Vec::with_capacity(members.len());
    for (k, ((run, s), records)) in members.iter().zip(records).enumerate() {
        save_run(
            config,
            run,
            &run.out,
            &stack.net.member(k)?,
            &records,
            &s.screening,
        )?;
        checkpoint::remove_all(&run.out);
        outcomes.push(TrainOutcome {
            records,
            screening: s.screening.clone(),
        });
    }
    Ok(outcomes)
}
