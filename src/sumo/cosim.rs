//! `mpgdrive cosim`: runs controllers on the same SUMO configuration and seed, one after the
//! other in this process, and compares them.
//!
//! Per ego (a controllable ramp vehicle, tracked from `control_from` until released), with
//! the definitions of `mpgdrive eval`: collision (SUMO reported one involving the ego while
//! tracked), failure (no collision, and the ego never reached the target lane: it stopped,
//! teleported or vanished), minimum centre distance to its players, average speed,
//! acceleration magnitude (SUMO's reported acceleration) and jerk magnitude. Egos still driving
//! when the run ends are reported as unfinished and left out of the averages. SUMO's own:
//! collision events from getCollisions (once per pair and event), the SSM device's minimum
//! TTC and maximum DRAC per ego, and tripinfo travel time and time loss.

use crate::config::Config;
use crate::eval::metrics::{EpisodeMetrics, Summary};
use crate::policy::ensemble::{Combine, PolicyEnsemble};
use crate::render::timespace::TimeSpace;
use crate::sumo::controller::{CollisionEvent, ControlModes, Controller, EgoRecord};
use crate::sumo::geometry::MergeGeometry;
use crate::sumo::kind::ControllerKind;
use crate::sumo::positions::LanePositions;
use crate::sumo::profile::{self, BandSpeed, SpeedBands};
use crate::sumo::ssm;
use crate::sumo::{Backend, Sumo, SumoError};
use serde::Serialize;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How mpgdrive reaches SUMO.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Launch {
    /// libsumo in this process (headless, the default).
    Libsumo,
    /// sumo-gui started through libtraci.
    Gui,
    /// Join a running SUMO (`--num-clients N`) on localhost:port as client `order`.
    Attach {
        /// TCP port.
        port: u16,
        /// Client order (1 steps first).
        order: i32,
    },
}

/// Everything a co-sim run needs besides the controller.
#[derive(Debug, Clone)]
pub struct CosimSettings {
    /// The SUMO configuration.
    pub sumocfg: PathBuf,
    /// Route files replacing the configuration's (SUMO's `--route-files`), if any.
    pub route_files: Option<PathBuf>,
    /// The network's merges: each geometry with where its lanes lie along the road
    /// ([`crate::sumo::inputs::check_geometry`]). Each has its own controller, egos and games.
    pub merges: Vec<(MergeGeometry, LanePositions)>,
    /// Where the geometry came from (for messages).
    pub geometry_path: PathBuf,
    /// SUMO's random seed.
    pub seed: u64,
    /// Simulated duration (s), from the configuration's begin on.
    pub end: f64,
    /// The largest `minGap` of the route files' vehicle types (m): driven vehicles keep at
    /// least this bumper gap ([`Controller::keep_min_gap`]).
    pub min_gap: f64,
    /// SUMO speed and lane-change modes of the controlled vehicles.
    pub modes: ControlModes,
    /// How SUMO runs.
    pub launch: Launch,
    /// Directory for SUMO's tripinfo and SSM outputs (per controller).
    pub out: PathBuf,
    /// Record each run's time-space diagram ([`ControllerRun::timespace`]).
    pub timespace: bool,
    /// Equip every vehicle with SUMO's SSM device (when the inputs equip none: the conflict
    /// metrics need it).
    pub equip_ssm: bool,
    /// SUMO's step length (s), set on its command line where the configuration sets another or
    /// none (the policy's `sim.dt`).
    pub step_length: Option<f64>,
    /// SUMO checks collisions (its default, `teleport`) where the configuration turns the
    /// check off (`collision.action none`): collisions are the metrics' first figure.
    pub check_collisions: bool,
}

/// Errors of a co-sim run.
#[derive(Debug, thiserror::Error)]
pub enum CosimError {
    /// SUMO failed.
    #[error(transparent)]
    Sumo(#[from] SumoError),
    /// The merge geometry does not fit the network.
    #[error("{path}")]
    Geometry {
        /// merge.toml.
        path: String,
        /// What is wrong.
        #[source]
        source: crate::config::ConfigError,
    },
    /// SUMO's step length differs from the policy's.
    #[error(
        "SUMO's step length is {sumo} s but the policy was trained with sim.dt = {config} s: set <step-length value=\"{config}\"/>"
    )]
    StepLength {
        /// SUMO's.
        sumo: f64,
        /// The configuration's.
        config: f64,
    },
    /// A SUMO output could not be read.
    #[error("reading SUMO output {path}: {message}")]
    Output {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

/// Metrics of one ego.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EgoResult {
    /// SUMO vehicle id.
    pub id: String,
    /// Tracking began (s).
    pub start: f64,
    /// Tracking ended (s); none when unfinished.
    pub end: Option<f64>,
    /// Released, collided or lost before the run ended.
    pub finished: bool,
    /// The six metrics of `mpgdrive eval`.
    pub metrics: EpisodeMetrics,
    /// SSM minimum TTC over the ego's conflicts (s).
    pub ssm_min_ttc: Option<f64>,
    /// SSM maximum DRAC (m/s^2).
    pub ssm_max_drac: Option<f64>,
    /// Trip duration (s).
    pub travel_time: Option<f64>,
    /// Time lost to driving below the ideal speed (s).
    pub time_loss: Option<f64>,
    /// The merge it was an ego of (index into [`CosimSettings::merges`]).
    pub merge: usize,
}

/// One merge's share of a run (a network with several merges reports each).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MergeRun {
    /// The merge's name ([`MergeGeometry::label`]).
    pub name: String,
    /// Its egos, finished or not.
    pub egos: usize,
    /// Averages over its finished egos.
    pub summary: Summary,
    /// SUMO collisions involving a vehicle its controller drove.
    pub controlled_collisions: usize,
    /// The desired speed a traffic policy observed there (m/s; none for Table I policies and
    /// `sumo`).
    pub desired_speed: Option<f64>,
}

/// One controller's run.
#[derive(Debug, Clone, Serialize)]
pub struct ControllerRun {
    /// Controller.
    pub controller: ControllerKind,
    /// Training seeds of the policy that drove (several: one ensemble; none for `sumo`).
    pub policy_seeds: Vec<u64>,
    /// How several seeds' actions made one (none for one seed and for `sumo`).
    pub ensemble: Option<Combine>,
    /// SUMO seed.
    pub seed: u64,
    /// SUMO's version ("SUMO 1.15.0").
    pub sumo_version: String,
    /// Simulated time (s).
    pub simulated: f64,
    /// Steps run.
    pub steps: u64,
    /// Egos, finished or not.
    pub egos: Vec<EgoResult>,
    /// Averages over finished egos.
    pub summary: Summary,
    /// Egos still driving when the run ended.
    pub unfinished: usize,
    /// SUMO collision events (once per pair and event).
    pub collisions: Vec<CollisionEvent>,
    /// Steps where SUMO did not apply the commanded speed.
    pub speed_overrides: u64,
    /// Driven vehicles that passed a red light (on a signalised merge; none expected).
    pub red_light_passes: u64,
    /// Driven vehicles that passed a stop sign without a standstill at its line (none expected).
    pub stop_sign_passes: u64,
    /// Mean speed of the finished egos by distance to the conflict point ([`profile`]).
    pub speed_by_position: Vec<BandSpeed>,
    /// Mean speed of the target-lane vehicles in the control zone, by the same bands: the
    /// traffic the egos merge into (the players, in the game).
    pub lane_speed_by_position: Vec<BandSpeed>,
    /// Mean SSM minimum TTC over finished egos with an SSM conflict (s).
    pub mean_min_ttc: Option<f64>,
    /// Mean SSM maximum DRAC (m/s^2).
    pub mean_max_drac: Option<f64>,
    /// Mean travel time of finished egos (s).
    pub mean_travel_time: Option<f64>,
    /// Mean time loss of finished egos (s).
    pub mean_time_loss: Option<f64>,
    /// Time spent in the network by every vehicle, from tripinfo (s; 0 when attached).
    pub vehicle_seconds: f64,
    /// The shields the controlled vehicles ran under: the merge gate, and SUMO's speed and
    /// lane-change modes (`sumo`: none applies).
    pub shields: Shields,
    /// The desired speed a traffic policy observed (m/s): the speed limit of the lane egos
    /// merge into (at the first merge; [`MergeRun`] has each); none for Table I policies and
    /// `sumo`.
    pub desired_speed: Option<f64>,
    /// Wall time in SUMO's step (us per step).
    pub sumo_us_per_step: f64,
    /// Wall time in the controller (us per step).
    pub controller_us_per_step: f64,
    /// Each merge's share of the run, in the order of [`CosimSettings::merges`].
    pub merges: Vec<MergeRun>,
    /// Each merge's time-space record, with SUMO's SSM conflicts marked (when asked for).
    #[serde(skip)]
    pub timespace: Vec<TimeSpace>,
    /// SUMO's SSM output file and its text as the run ended ([`restore_ssm_outputs`]).
    #[serde(skip)]
    pub ssm_output: Option<(PathBuf, String)>,
}

/// Writes each run's SSM output file again, as it was when its run ended. SUMO 1.15 empties the
/// SSM file of a finished simulation when the next one in the process starts, so after a
/// comparison every file but the last controller's was left empty.
pub fn restore_ssm_outputs(runs: &[ControllerRun]) -> std::io::Result<()> {
    for (path, text) in runs.iter().filter_map(|r| r.ssm_output.as_ref()) {
        crate::atomic::write(path, text)?;
    }
    Ok(())
}

fn sumo_args(settings: &CosimSettings, binary: &str, tripinfo: &Path, ssm: &Path) -> Vec<String> {
    let mut args: Vec<String> = vec![
        binary.into(),
        "-c".into(),
        settings.sumocfg.display().to_string(),
        "--seed".into(),
        settings.seed.to_string(),
        // No end of SUMO's own: the run ends `settings.end` after the configuration's begin
        // (`more_to_run`), which public scenarios set to the hour they model (6:00 is 21,600 s).
        "--end".into(),
        "-1".into(),
        // The policy's world moves each vehicle by one speed per step, on lanes: SUMO runs so
        // for every controller, whatever the configuration sets. Under the ballistic update a
        // held ego slid past its stop line and into the junction in front of a car.
        "--step-method.ballistic".into(),
        "false".into(),
        "--mesosim".into(),
        "false".into(),
        "--no-warnings".into(),
        "true".into(),
        "--no-step-log".into(),
        "true".into(),
        // Nothing of SUMO's on stdout, whatever the configuration's <report> asks (osmWebWizard's
        // sets verbose and statistics): `cosim --json` writes its results there.
        "--verbose".into(),
        "false".into(),
        "--duration-log.statistics".into(),
        "false".into(),
        "--tripinfo-output".into(),
        absolute(tripinfo),
        "--device.ssm.file".into(),
        absolute(ssm),
        "--tripinfo-output.write-unfinished".into(),
        "true".into(),
        // Collisions on junction lanes count too: a junction merge enters the target lane there.
        "--collision.check-junctions".into(),
        "true".into(),
        // The conflict definition of the metrics, whatever the configuration sets.
        "--device.ssm.measures".into(),
        "TTC,DRAC".into(),
        "--device.ssm.thresholds".into(),
        format!("{},{}", ssm::TTC_THRESHOLD, ssm::DRAC_THRESHOLD),
        "--device.ssm.range".into(),
        "50.0".into(),
    ];
    if settings.equip_ssm {
        args.extend(["--device.ssm.probability".into(), "1".into()]);
    }
    if let Some(step) = settings.step_length {
        args.extend(["--step-length".into(), step.to_string()]);
    }
    if settings.check_collisions {
        args.extend(["--collision.action".into(), "teleport".into()]);
    }
    if let Some(routes) = &settings.route_files {
        args.extend(["--route-files".into(), absolute(routes)]);
    }
    if binary == "sumo-gui" {
        args.extend([
            "--start".into(),
            "true".into(),
            "--quit-on-end".into(),
            "true".into(),
        ]);
        // Without SUMO_HOME, sumo-gui 1.15 looks the schemas up on the web, fails offline and
        // quits ("invalid document structure") before the first TraCI call; libsumo loads the
        // same files without SUMO_HOME, and so does the GUI run without validation.
        if std::env::var_os("SUMO_HOME").is_none() {
            args.extend(["--xml-validation", "never", "--xml-validation.routes", "never"].map(String::from));
        }
    }
    args
}

/// A path for SUMO's command line: absolute, since SUMO resolves relative paths against the
/// configuration file's folder, not the working directory.
fn absolute(path: &Path) -> String {
    std::path::absolute(path)
        .unwrap_or_else(|_| path.to_path_buf())
        .display()
        .to_string()
}

/// Whether a run goes on: before `end` (to half a step) and with vehicles still expected.
/// Whether a run that began at SUMO time `begin` and lasts `duration` (s) has steps left:
/// before its end and with vehicles still running or to come.
fn more_to_run(sumo: &Sumo, begin: f64, duration: f64, dt: f64) -> Result<bool, SumoError> {
    Ok(sumo.time()? < begin + duration - 0.5 * dt && sumo.min_expected()? > 0)
}

/// Runs one controller over the whole simulation.
pub fn run_controller(
    config: &Config,
    settings: &CosimSettings,
    kind: ControllerKind,
    policy: Option<PolicyEnsemble>,
) -> Result<ControllerRun, CosimError> {
    let tripinfo = settings.out.join(format!("tripinfo-{}.xml", kind.name()));
    let ssm = settings.out.join(format!("ssm-{}.xml", kind.name()));
    let mut sumo = match settings.launch {
        Launch::Libsumo => Sumo::start(Backend::Libsumo, &sumo_args(settings, "sumo", &tripinfo, &ssm))?,
        Launch::Gui => Sumo::start(Backend::Traci, &sumo_args(settings, "sumo-gui", &tripinfo, &ssm))?,
        Launch::Attach { port, order } => Sumo::attach(port, order)?,
    };
    let dt = sumo.delta_t()?;
    let sumo_version = sumo.version()?;
    if (dt - config.sim.dt).abs() > 1e-9 {
        return Err(CosimError::StepLength {
            sumo: dt,
            config: config.sim.dt,
        });
    }
    let lanes = sumo.lane_ids()?;
    let mut controllers = Vec::with_capacity(settings.merges.len());
    for (geometry, positions) in &settings.merges {
        geometry
            .check_lanes(&lanes)
            .map_err(|source| CosimError::Geometry {
                path: settings.geometry_path.display().to_string(),
                source,
            })?;
        let mut controller = Controller::new(
            config.clone(),
            geometry.clone(),
            positions.clone(),
            kind,
            policy.clone(),
            settings.modes,
        );
        controller.keep_min_gap(settings.min_gap);
        if settings.timespace {
            controller.record_timespace();
        }
        if !matches!(settings.launch, Launch::Libsumo) {
            controller.colour_driven(); // someone may be watching in sumo-gui
        }
        controllers.push(controller);
    }
    let mut sumo_us = 0.0;
    let mut steps = 0u64;
    let mut taken = HashSet::new();
    let begin = sumo.time()?;
    while more_to_run(&sumo, begin, settings.end, dt)? {
        let t0 = Instant::now();
        sumo.step()?;
        sumo_us += t0.elapsed().as_secs_f64() * 1e6;
        taken.clear();
        for controller in &mut controllers {
            controller.step_sharing(&mut sumo, &mut taken)?;
        }
        steps += 1;
    }
    let simulated = sumo.time()? - begin;
    sumo.close()?;
    let controller_us: f64 = controllers.iter().map(|c| c.timing().total_us).sum();
    let desired_speed = controllers.first().and_then(Controller::desired_speed);
    let mut lane_speed = SpeedBands::default();
    let mut collisions: Vec<CollisionEvent> = Vec::new();
    let mut timespace = Vec::new();
    let mut records = Vec::new();
    let mut merges = Vec::new();
    let mut speed_overrides = 0;
    let mut red_light_passes = 0;
    let mut stop_sign_passes = 0;
    for (k, mut controller) in controllers.into_iter().enumerate() {
        lane_speed.add(&controller.lane_speed);
        speed_overrides += controller.overridden;
        red_light_passes += controller.red_light_passes;
        stop_sign_passes += controller.stop_sign_passes;
        // Every controller sees SUMO's collisions: one event, controlled if any drove a party.
        for event in &controller.collisions {
            let same = |c: &&mut CollisionEvent| {
                (c.time, &c.collider, &c.victim) == (event.time, &event.collider, &event.victim)
            };
            match collisions.iter_mut().find(same) {
                Some(known) => known.controlled |= event.controlled,
                None => collisions.push(event.clone()),
            }
        }
        merges.push((
            controller.collisions.iter().filter(|c| c.controlled).count(),
            controller.desired_speed(),
        ));
        timespace.extend(controller.take_timespace());
        records.extend(controller.finish().into_iter().map(|r| (k, r)));
    }
    collisions.sort_by(|a, b| a.time.total_cmp(&b.time)); // stable: one merge keeps its order
    let ssm_output = match settings.launch {
        Launch::Attach { .. } => None,
        _ => Some((ssm.clone(), read_xml(&ssm)?)),
    };
    let (ssm, trips) = match settings.launch {
        // The server owns the outputs of a shared simulation.
        Launch::Attach { .. } => (SsmRecord::default(), HashMap::new()),
        _ => (read_ssm(&ssm)?, read_tripinfo(&tripinfo)?),
    };
    for ts in &mut timespace {
        let marks: Vec<_> = ssm.worst.iter().filter_map(|(id, t)| ts.locate(id, *t)).collect();
        ts.conflicts = marks;
    }
    let per_step = |us: f64| us / steps.max(1) as f64;
    let mut run = summarise(
        kind,
        settings.seed,
        simulated,
        steps,
        &records,
        &ssm.extremes,
        &trips,
        collisions,
        speed_overrides,
        per_step(sumo_us),
        per_step(controller_us),
    );
    run.red_light_passes = red_light_passes;
    run.stop_sign_passes = stop_sign_passes;
    run.merges = settings
        .merges
        .iter()
        .zip(merges)
        .enumerate()
        .map(|(k, ((geometry, _), (controlled_collisions, desired_speed)))| {
            let mine: Vec<&EgoResult> = run.egos.iter().filter(|e| e.merge == k).collect();
            let finished: Vec<EpisodeMetrics> =
                mine.iter().filter(|e| e.finished).map(|e| e.metrics).collect();
            MergeRun {
                name: geometry.label(),
                egos: mine.len(),
                summary: Summary::of(&finished),
                controlled_collisions,
                desired_speed,
            }
        })
        .collect();
    run.timespace = timespace;
    run.lane_speed_by_position = lane_speed.bands();
    run.ssm_output = ssm_output;
    run.sumo_version = sumo_version;
    run.desired_speed = desired_speed;
    run.shields = Shields {
        merge_gate: config.sim.merge_gate,
        speed_mode: settings.modes.speed,
        lane_change_mode: settings.modes.lane_change,
        player_lane_change_mode: settings.modes.player_lane_change,
    };
    Ok(run)
}

/// SUMO alone on the same configuration, seed and duration, through libsumo with nothing but
/// `step` (the `--bench` baseline): microseconds per step.
pub fn plain_sumo_us_per_step(settings: &CosimSettings) -> Result<f64, CosimError> {
    let null = Path::new("/dev/null");
    let mut sumo = Sumo::start(Backend::Libsumo, &sumo_args(settings, "sumo", null, null))?;
    let dt = sumo.delta_t()?;
    let started = Instant::now();
    let mut steps = 0u64;
    let begin = sumo.time()?;
    while more_to_run(&sumo, begin, settings.end, dt)? {
        sumo.step()?;
        steps += 1;
    }
    let us = started.elapsed().as_secs_f64() * 1e6 / steps.max(1) as f64;
    sumo.close()?;
    Ok(us)
}

/// The shields of a run (see [`ControllerRun::shields`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Shields {
    /// The merge gate held ramp vehicles the policy drives.
    pub merge_gate: bool,
    /// SUMO speed mode of controlled vehicles (0: none, the default; 25: SUMO's safe speed).
    pub speed_mode: i32,
    /// SUMO lane-change mode of controlled ramp vehicles (257: a merge waits while it would
    /// collide at once, with SUMO's strategic lane changes; 0: none).
    pub lane_change_mode: i32,
    /// SUMO lane-change mode of controlled target-lane players (1621: SUMO's own lane
    /// changes; 0: none).
    pub player_lane_change_mode: i32,
}

#[allow(clippy::too_many_arguments)]
fn summarise(
    controller: ControllerKind,
    seed: u64,
    simulated: f64,
    steps: u64,
    records: &[(usize, EgoRecord)],
    ssm: &HashMap<String, SsmExtremes>,
    trips: &HashMap<String, (f64, f64)>,
    collisions: Vec<CollisionEvent>,
    speed_overrides: u64,
    sumo_us_per_step: f64,
    controller_us_per_step: f64,
) -> ControllerRun {
    let egos: Vec<EgoResult> = records
        .iter()
        .map(|(merge, r)| {
            let (ttc, drac) = ssm.get(&r.id).copied().unwrap_or((None, None));
            let trip = trips.get(&r.id);
            EgoResult {
                id: r.id.clone(),
                start: r.start,
                end: r.end,
                finished: r.finished(),
                metrics: EpisodeMetrics::from_stats(&r.stats, r.collision, r.merged),
                ssm_min_ttc: ttc,
                ssm_max_drac: drac,
                travel_time: trip.map(|t| t.0),
                time_loss: trip.map(|t| t.1),
                merge: *merge,
            }
        })
        .collect();
    let finished: Vec<&EgoResult> = egos.iter().filter(|e| e.finished).collect();
    let mut bands = SpeedBands::default();
    for (_, r) in records.iter().filter(|(_, r)| r.finished()) {
        bands.add(&r.speed_bands);
    }
    let metrics: Vec<EpisodeMetrics> = finished.iter().map(|e| e.metrics).collect();
    let mean_of = |f: &dyn Fn(&EgoResult) -> Option<f64>| {
        let v: Vec<f64> = finished.iter().filter_map(|e| f(e)).collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    };
    ControllerRun {
        controller,
        policy_seeds: Vec::new(),
        ensemble: None,
        seed,
        sumo_version: String::new(),
        desired_speed: None,
        simulated,
        steps,
        summary: Summary::of(&metrics),
        unfinished: egos.len() - finished.len(),
        mean_min_ttc: mean_of(&|e| e.ssm_min_ttc),
        mean_max_drac: mean_of(&|e| e.ssm_max_drac),
        mean_travel_time: mean_of(&|e| e.travel_time),
        mean_time_loss: mean_of(&|e| e.time_loss),
        // Summed in id order: the same run gives the same bits.
        vehicle_seconds: trips
            .iter()
            .collect::<std::collections::BTreeMap<_, _>>()
            .values()
            .map(|t| t.0)
            .sum(),
        egos,
        collisions,
        speed_overrides,
        red_light_passes: 0,
        stop_sign_passes: 0,
        speed_by_position: bands.bands(),
        lane_speed_by_position: Vec::new(),
        sumo_us_per_step,
        controller_us_per_step,
        merges: Vec::new(),
        timespace: Vec::new(),
        ssm_output: None,
        shields: Shields::default(),
    }
}

fn read_xml(path: &Path) -> Result<String, CosimError> {
    std::fs::read_to_string(path).map_err(|e| CosimError::Output {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

fn parse_xml<'a>(path: &Path, text: &'a str) -> Result<roxmltree::Document<'a>, CosimError> {
    roxmltree::Document::parse(text).map_err(|e| CosimError::Output {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// SSM extremes of one vehicle: (minimum TTC in s, maximum DRAC in m/s^2).
pub type SsmExtremes = (Option<f64>, Option<f64>);

/// What the SSM output says of the equipped vehicles.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SsmRecord {
    /// Per vehicle: the smallest minTTC and the largest maxDRAC over its conflicts.
    pub extremes: HashMap<String, SsmExtremes>,
    /// Per conflict with a measured value: the equipped vehicle and the time of its minTTC
    /// (of its maxDRAC when it has no TTC), in file order.
    pub worst: Vec<(String, f64)>,
}

/// Reads SUMO's SSM output: the conflicts [`ssm::conflicts`] counts.
pub fn read_ssm(path: &Path) -> Result<SsmRecord, CosimError> {
    let text = read_xml(path)?;
    let conflicts = ssm::conflicts(&text).map_err(|e| CosimError::Output {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let mut out = SsmRecord::default();
    for c in conflicts {
        let entry = out.extremes.entry(c.ego.clone()).or_default();
        if let Some(t) = c.min_ttc {
            entry.0 = Some(entry.0.map_or(t.value, |m| m.min(t.value)));
        }
        if let Some(d) = c.max_drac {
            entry.1 = Some(entry.1.map_or(d.value, |m| m.max(d.value)));
        }
        let worst = c.min_ttc.and_then(|t| t.time);
        if let Some(t) = worst.or(c.max_drac.and_then(|d| d.time)) {
            out.worst.push((c.ego, t));
        }
    }
    Ok(out)
}

/// Per vehicle: (duration, timeLoss) from a tripinfo file.
pub fn read_tripinfo(path: &Path) -> Result<HashMap<String, (f64, f64)>, CosimError> {
    let text = read_xml(path)?;
    let doc = parse_xml(path, &text)?;
    Ok(doc
        .descendants()
        .filter(|n| n.has_tag_name("tripinfo"))
        .filter_map(|n| {
            let num = |k| n.attribute(k).and_then(|v: &str| v.parse::<f64>().ok());
            Some((
                n.attribute("id")?.to_owned(),
                (num("duration")?, num("timeLoss")?),
            ))
        })
        .collect())
}

fn opt(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.4}"))
}

/// A Markdown table, one column per controller.
pub fn markdown(runs: &[ControllerRun]) -> String {
    let mut s = String::from("| Metric |");
    for r in runs {
        s += &format!(" {} |", r.controller.name());
    }
    s += "\n|---|";
    s += &"---|".repeat(runs.len());
    s += "\n";
    let mut row = |name: &str, f: &dyn Fn(&ControllerRun) -> String| {
        s += &format!("| {name} |");
        for r in runs {
            s += &format!(" {} |", f(r));
        }
        s += "\n";
    };
    let m = |r: &ControllerRun| r.summary;
    row("Policy (training seeds)", &|r| {
        policy_cell(&r.policy_seeds, r.ensemble)
    });
    row("Egos (finished / unfinished)", &|r| {
        format!("{} / {}", r.summary.episodes, r.unfinished)
    });
    row("Collision rate", &|r| {
        format!("{}/{}", m(r).collisions, m(r).episodes)
    });
    row("Failure rate", &|r| {
        format!("{}/{}", m(r).failures, m(r).episodes)
    });
    row("Average minimum inter-vehicle distance (m)", &|r| {
        format!("{:.4}", m(r).min_distance)
    });
    row("Average minimum in-lane distance (m)", &|r| {
        crate::eval::metrics::distance_cell(m(r).min_lane_distance)
    });
    row("Average ego vehicle speed (m/s)", &|r| {
        format!("{:.4}", m(r).mean_speed)
    });
    row("Average acceleration magnitude (m/s^2)", &|r| {
        format!("{:.4}", m(r).mean_abs_accel)
    });
    row("Average jerk magnitude (m/s^3)", &|r| {
        format!("{:.4}", m(r).mean_abs_jerk)
    });
    row("SUMO collisions (all / with a controlled vehicle)", &|r| {
        format!(
            "{} / {}",
            r.collisions.len(),
            r.collisions.iter().filter(|c| c.controlled).count()
        )
    });
    row("Egos with an SSM conflict (TTC < 3 s or DRAC > 3 m/s^2)", &|r| {
        let with = |e: &&EgoResult| e.finished && (e.ssm_min_ttc.is_some() || e.ssm_max_drac.is_some());
        format!("{}/{}", r.egos.iter().filter(with).count(), r.summary.episodes)
    });
    row("SSM minimum TTC, mean over those egos (s)", &|r| {
        opt(r.mean_min_ttc)
    });
    row("SSM maximum DRAC, mean over those egos (m/s^2)", &|r| {
        opt(r.mean_max_drac)
    });
    row("Ego travel time (s)", &|r| opt(r.mean_travel_time));
    row("Ego time loss (s)", &|r| opt(r.mean_time_loss));
    row("Commanded speeds SUMO did not apply (steps)", &|r| {
        r.speed_overrides.to_string()
    });
    if let Some(first) = runs.iter().find(|r| r.merges.len() > 1) {
        s += "\nEach merge: egos finished / all, collisions with a controlled vehicle, mean speed of the finished egos (m/s):\n\n| Merge |";
        for r in runs {
            s += &format!(" {} |", r.controller.name());
        }
        s += &format!("\n|---|{}\n", "---|".repeat(runs.len()));
        for (k, merge) in first.merges.iter().enumerate() {
            s += &format!("| {} |", merge.name);
            for m in runs.iter().filter_map(|r| r.merges.get(k)) {
                s += &format!(
                    " {} / {}, {}, {:.2} |",
                    m.summary.episodes, m.egos, m.controlled_collisions, m.summary.mean_speed
                );
            }
            s += "\n";
        }
    }
    let names: Vec<&str> = runs.iter().map(|r| r.controller.name()).collect();
    let profiles: Vec<&[BandSpeed]> = runs.iter().map(|r| r.speed_by_position.as_slice()).collect();
    s +=
        "\nMean ego speed (m/s) by distance past the conflict point (finished egos, every tracked step):\n\n";
    s += &profile::markdown(&names, &profiles);
    let lanes: Vec<&[BandSpeed]> = runs.iter().map(|r| r.lane_speed_by_position.as_slice()).collect();
    s += "\nMean speed (m/s) of the target-lane vehicles in the control zone, same bands (every step):\n\n";
    s += &profile::markdown(&names, &lanes);
    s
}

/// Which trained policy drove: one seed, the median or mean of several, or none (`sumo`).
fn policy_cell(seeds: &[u64], ensemble: Option<Combine>) -> String {
    let list = || seeds.iter().map(u64::to_string).collect::<Vec<_>>().join(", ");
    match seeds.len() {
        0 => "-".into(),
        1 => format!("seed {}", seeds[0]),
        _ => format!("{} of seeds {}", ensemble.unwrap_or_default().name(), list()),
    }
}

/// Per-ego CSV over all runs.
pub fn egos_csv(runs: &[ControllerRun]) -> String {
    let mut s = format!(
        "controller,seed,id,start,end,finished,collision,failure,{},ssm_min_ttc,ssm_max_drac,travel_time,time_loss,merge\n",
        EpisodeMetrics::CSV_MOTION
    );
    let o = |x: Option<f64>| x.map_or(String::new(), |v| v.to_string());
    for r in runs {
        for e in &r.egos {
            let m = &e.metrics;
            s += &format!(
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
                r.controller.name(),
                r.seed,
                e.id,
                e.start,
                o(e.end),
                u8::from(e.finished),
                u8::from(m.collision),
                u8::from(m.failure),
                m.motion_csv(),
                o(e.ssm_min_ttc),
                o(e.ssm_max_drac),
                o(e.travel_time),
                o(e.time_loss),
                r.merges.get(e.merge).map_or("", |m| m.name.as_str())
            );
        }
    }
    s
}
