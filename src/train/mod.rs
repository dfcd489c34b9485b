//! Training: potential-based gradient ascent (Algorithm 1) and the single-agent baseline.
//!
//! Each epoch draws a stratified minibatch of initial states, rolls the shared policy out in
//! the differentiable tensor engine ([`crate::sim::tensor`]) and takes one Adam step on the
//! gradient, back-propagated through the whole rollout, of
//! - `mpg`: the mean discounted total potential, eq. (29), with the policy driving every player;
//! - `sarl`: the ego's mean discounted return `J_ego`, the other players driven by IDM.
//!
//! Episodes stop counting at their first collision. After each step the policy is measured on a
//! fixed probe set (disjoint from training) in the scalar engine: mean objective, collision and
//! failure rates, and the mean squared difference of the probe actions from the previous epoch.

pub mod curves;

use crate::atomic::with_suffix;
use crate::config::Config;
use crate::eval::EpisodeMetrics;
use crate::policy::drive::{Others, policy_rollout};
use crate::policy::file::{self, PolicyError, Sidecar};
use crate::policy::network::{NetSpec, PolicyNet};
use crate::policy::observation::{OBS_LAYOUT_VERSION, obs_dim, observe, tensor_observations};
use crate::sim::neighbors::find_neighbors;
use crate::sim::rollout::{Driver, EpisodeOutcome, Recording};
use crate::sim::sampler::{Purpose, purpose_seed, sample_scenes};
use crate::sim::state::Scene;
use crate::sim::tensor::{self, idm_actions};
use curves::EpochRecord;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use tch::{Kind, Tensor, nn::OptimizerConfig};

/// What is learned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Shared policy for every player, maximising the potential.
    Mpg,
    /// Ego policy only, maximising the ego's return, the others on IDM.
    Sarl,
}

impl Mode {
    /// Lower-case name ("mpg" or "sarl").
    pub fn name(self) -> &'static str {
        match self {
            Mode::Mpg => "mpg",
            Mode::Sarl => "sarl",
        }
    }
}

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
    /// Stopped by a request (Ctrl-C); a checkpoint of the last finished epoch was written.
    #[error("interrupted after epoch {epoch}; checkpoint {checkpoint} written, continue with --resume")]
    Interrupted {
        /// Last finished epoch.
        epoch: usize,
        /// The checkpoint base path.
        checkpoint: PathBuf,
    },
    /// The objective stopped being a finite number.
    #[error(
        "training diverged at epoch {epoch}: the objective is {value}; lower train.learning_rate or train.grad_clip"
    )]
    Diverged {
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

/// The checkpoint base path of a run.
pub fn checkpoint_path(out: &Path) -> PathBuf {
    with_suffix(out, ".ckpt")
}

/// The curves CSV path of a run.
pub fn curves_path(out: &Path) -> PathBuf {
    with_suffix(out, ".curves.csv")
}

/// Raw actions of every player for a tensor batch: the network for the players it drives,
/// IDM for the others.
fn tensor_actions(
    config: &Config,
    net: &PolicyNet,
    mode: Mode,
    batch: &tensor::TensorBatch,
    nb: &tensor::NeighborIndex,
) -> Tensor {
    let obs = tensor_observations(config.scenario.conflict_point, batch, nb).to_kind(Kind::Float);
    let (b, n) = (obs.size()[0], obs.size()[1]);
    match mode {
        Mode::Mpg => net.forward(&obs.reshape([b * n, -1])).reshape([b, n]),
        Mode::Sarl => {
            let ego = net.forward(&obs.select(1, 0)).unsqueeze(1);
            let others = idm_actions(config, batch, nb)
                .to_kind(Kind::Float)
                .narrow(1, 1, n - 1);
            Tensor::cat(&[ego, others], 1)
        }
    }
}

/// Who drives the other players on the probe set: the shared policy (mpg) or IDM (sarl).
fn probe_others(mode: Mode) -> Others<'static> {
    match mode {
        Mode::Mpg => Others::SameNetwork,
        Mode::Sarl => Others::Driver(Driver::Idm),
    }
}

/// Actions of every player at the probe initial states (for the action-difference curve).
fn probe_actions(config: &Config, net: &PolicyNet, probe: &[Scene]) -> Tensor {
    let n = config.n_agents();
    let dim = obs_dim(n);
    let mut obs = vec![0f32; probe.len() * n * dim];
    let (mut order, mut nb) = (Vec::new(), Vec::new());
    for (b, scene) in probe.iter().enumerate() {
        find_neighbors(scene, &mut order, &mut nb);
        for (i, neighbors) in nb.iter().enumerate() {
            let row = b * n + i;
            observe(
                config.scenario.conflict_point,
                scene,
                i,
                neighbors,
                &mut obs[row * dim..(row + 1) * dim],
            );
        }
    }
    tch::no_grad(|| net.forward(&Tensor::from_slice(&obs).reshape([(probe.len() * n) as i64, dim as i64])))
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
        obs_layout_version: OBS_LAYOUT_VERSION,
        net: net.spec.clone(),
        mode: run.mode.name().to_string(),
        seed: run.seed,
        epochs,
        command: run.command.clone(),
        code_version: crate::VERSION.to_string(),
        config: config.clone(),
        metrics,
    }
}

/// Step size of `epoch` (from 0): exponential decay from `learning_rate` to
/// `learning_rate_final` at the last epoch.
pub fn learning_rate(t: &crate::config::TrainConfig, epoch: usize) -> f64 {
    let progress = if t.epochs > 1 {
        epoch as f64 / (t.epochs - 1) as f64
    } else {
        0.0
    };
    t.learning_rate * (t.learning_rate_final / t.learning_rate).powf(progress)
}

/// One epoch of Algorithm 1: gradient ascent on the objective over the epoch's minibatch of
/// training states (the learning-rate schedule of `epoch`). Returns the minibatch objective.
fn gradient_step(
    config: &Config,
    run: &TrainRun,
    net: &PolicyNet,
    opt: &mut tch::nn::Optimizer,
    epoch: usize,
) -> Result<f64, TrainError> {
    let t = &config.train;
    let train_seed = purpose_seed(run.seed, Purpose::Train);
    opt.set_lr(learning_rate(t, epoch));
    let scenes = sample_scenes(config, train_seed, epoch * t.batch, t.batch);
    let out = tensor::rollout(
        config,
        &scenes,
        Kind::Float,
        config.n_steps(),
        config.sim.feasibility,
        config.sim.terminate_on_collision,
        |b, nb, _| tensor_actions(config, net, run.mode, b, nb),
    );
    let objective_t = match run.mode {
        Mode::Mpg => out.potential.mean(Kind::Float),
        Mode::Sarl => out.returns.select(1, 0).mean(Kind::Float),
    };
    let train_objective = objective_t.double_value(&[]);
    if !train_objective.is_finite() {
        return Err(TrainError::Diverged {
            epoch: epoch + 1,
            value: train_objective,
        });
    }
    opt.backward_step_clip_norm(&(-&objective_t), t.grad_clip);
    // A NaN gradient would poison the parameters without changing this epoch's objective.
    let finite = net
        .vs
        .trainable_variables()
        .iter()
        .all(|p| p.isfinite().all().int64_value(&[]) == 1);
    if !finite {
        return Err(TrainError::Diverged {
            epoch: epoch + 1,
            value: f64::NAN,
        });
    }
    Ok(train_objective)
}

/// The sidecar metrics: the last epoch's record, plus the initialisation screening if any.
fn sidecar_metrics(records: &[EpochRecord], screening: &Option<serde_json::Value>) -> serde_json::Value {
    let mut m = serde_json::json!(records.last());
    if let (Some(s), Some(obj)) = (screening, m.as_object_mut()) {
        obj.insert("init_screening".into(), s.clone());
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
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct InitScreening {
    /// Epochs each candidate trained.
    pub screen_epochs: usize,
    /// Probe objective of each candidate after them.
    pub probe_objectives: Vec<f64>,
    /// The candidate kept (the first of the best).
    pub chosen: usize,
}

/// Screens `train.init_candidates` initialisations (see [`InitScreening`]).
fn screen_inits(config: &Config, run: &TrainRun, probe: &[Scene]) -> Result<InitScreening, TrainError> {
    let t = &config.train;
    let mut probe_objectives = Vec::with_capacity(t.init_candidates);
    for c in 0..t.init_candidates {
        let spec = NetSpec::new(config.n_agents(), t.hidden, config.vehicle.max_accel);
        let net = PolicyNet::seeded(spec, init_seed(run.seed, c));
        let mut opt = tch::nn::Adam::default().build(&net.vs, t.learning_rate)?;
        for epoch in 0..t.screen_epochs {
            gradient_step(config, run, &net, &mut opt, epoch)?;
        }
        let outcomes = policy_rollout(
            config,
            &net,
            probe_others(run.mode),
            probe,
            t.threads,
            Recording::Summary,
        )?;
        probe_objectives
            .push(outcomes.iter().map(|o| objective(run.mode, o)).sum::<f64>() / outcomes.len() as f64);
    }
    let chosen = (0..probe_objectives.len()).fold(0, |best, c| {
        if probe_objectives[c] > probe_objectives[best] {
            c
        } else {
            best
        }
    });
    Ok(InitScreening {
        screen_epochs: t.screen_epochs,
        probe_objectives,
        chosen,
    })
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
    let t = &config.train;
    tch::set_num_threads(t.threads as i32);
    let n = config.n_agents();
    let mut net = PolicyNet::seeded(
        NetSpec::new(n, t.hidden, config.vehicle.max_accel),
        run.seed as i64,
    );
    let mut records: Vec<EpochRecord> = Vec::new();
    if let Some(dir) = run.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| TrainError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    let ckpt = checkpoint_path(&run.out);
    let curves = curves_path(&run.out);
    // Recorded in the sidecars' metrics (and carried through a resumed checkpoint).
    let mut screening: Option<serde_json::Value> = None;
    if run.resume && file::paths(&ckpt).1.exists() {
        let (loaded, side) = file::load(&ckpt, n)?;
        if side.mode != run.mode.name() || side.seed != run.seed || side.config != *config {
            return Err(TrainError::ForeignCheckpoint {
                path: ckpt,
                message: "its mode, seed or configuration differs".into(),
            });
        }
        net = loaded;
        screening = side.metrics.get("init_screening").cloned();
        records = curves::read(&curves).map_err(|source| TrainError::Io {
            path: curves.clone(),
            source,
        })?;
        records.truncate(side.epochs);
    }
    let probe = sample_scenes(
        config,
        purpose_seed(run.seed, Purpose::Probe),
        0,
        t.probe_scenarios,
    );
    if records.is_empty() && t.init_candidates > 1 {
        let result = screen_inits(config, run, &probe)?;
        net = PolicyNet::seeded(
            NetSpec::new(n, t.hidden, config.vehicle.max_accel),
            init_seed(run.seed, result.chosen),
        );
        screening = Some(serde_json::json!(result));
    }
    let mut opt = tch::nn::Adam::default().build(&net.vs, t.learning_rate)?;
    let mut previous = probe_actions(config, &net, &probe);
    let start = Instant::now();
    let elapsed_before = records.last().map_or(0.0, |r| r.wall_seconds);
    for epoch in records.len()..t.epochs {
        let train_objective = gradient_step(config, run, &net, &mut opt, epoch)?;

        let outcomes = policy_rollout(
            config,
            &net,
            probe_others(run.mode),
            &probe,
            t.threads,
            Recording::Summary,
        )?;
        let m = outcomes.len() as f64;
        let metrics: Vec<_> = outcomes.iter().map(EpisodeMetrics::of).collect();
        let actions = probe_actions(config, &net, &probe);
        let record = EpochRecord {
            epoch: epoch + 1,
            train_objective,
            probe_objective: outcomes.iter().map(|o| objective(run.mode, o)).sum::<f64>() / m,
            action_msd: (&actions - &previous)
                .square()
                .mean(Kind::Float)
                .double_value(&[]),
            probe_collision_rate: metrics.iter().filter(|x| x.collision).count() as f64 / m,
            probe_failure_rate: metrics.iter().filter(|x| x.failure).count() as f64 / m,
            wall_seconds: elapsed_before + start.elapsed().as_secs_f64(),
            probe_ego_return: Some(outcomes.iter().map(|o| o.returns[0]).sum::<f64>() / m),
        };
        previous = actions;
        on_epoch(&record);
        records.push(record);
        let interrupted = stop.load(Ordering::SeqCst);
        if ((epoch + 1) % t.checkpoint_every == 0 || interrupted) && epoch + 1 < t.epochs {
            curves::write(&curves, &records).map_err(|source| TrainError::Io {
                path: curves.clone(),
                source,
            })?;
            file::save(
                &ckpt,
                &net,
                &sidecar(
                    config,
                    run,
                    &net,
                    epoch + 1,
                    sidecar_metrics(&records, &screening),
                ),
            )?;
            if interrupted {
                return Err(TrainError::Interrupted {
                    epoch: epoch + 1,
                    checkpoint: ckpt,
                });
            }
        }
    }
    curves::write(&curves, &records).map_err(|source| TrainError::Io {
        path: curves.clone(),
        source,
    })?;
    file::save(
        &run.out,
        &net,
        &sidecar(config, run, &net, t.epochs, sidecar_metrics(&records, &screening)),
    )?;
    for path in [file::paths(&ckpt).0, file::paths(&ckpt).1] {
        let _ = std::fs::remove_file(path); // the finished policy supersedes the checkpoint
    }
    Ok(records)
}
