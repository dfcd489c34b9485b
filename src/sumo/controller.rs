//! The co-simulation controller: once per SUMO step it reads the vehicles on the ramp and the
//! target lane, keeps one game per ego (the ego and the 4 leading and 4 following target-lane
//! vehicles nearest to it when it was picked up, within the reach of training's initial
//! states, in the player slots of training; a player that leaves the target lane drops out;
//! with a traffic policy, every vehicle on the ramp and target lanes, formed anew each step),
//! builds observations with the training builder (Table I or the traffic layout), runs the
//! policy once for every controlled vehicle, applies the feasibility projection and limits of
//! the internal simulator, and sets SUMO's speed (see Integration).
//! Table I games are fixed as an internal episode's players are: re-forming them every step
//! made the trained egos stop altogether (CHANGELOG.md, "Design notes"). A traffic policy has
//! no player slots and was trained on whole merge sections, so its game is simply the traffic.
//!
//! Another Rust program drives it the same way `mpgdrive cosim` does:
//!
//! ```no_run
//! # use mpgdrive::sumo::{Backend, Sumo, MergeGeometry, LanePositions, Controller, ControllerKind, ControlModes};
//! # fn run(config: mpgdrive::Config, geometry: MergeGeometry, positions: LanePositions, policy: mpgdrive::policy::PolicyNet)
//! # -> Result<(), mpgdrive::sumo::SumoError> {
//! let mut sumo = Sumo::start(Backend::Libsumo, &["sumo".into(), "-c".into(), "x.sumocfg".into()])?;
//! let mut controller = Controller::new(config, geometry, positions, ControllerKind::Mpg, Some(policy.into()), ControlModes::DEFAULT);
//! while sumo.min_expected()? > 0 {
//!     sumo.step()?;
//!     controller.step(&mut sumo)?;
//! }
//! let egos = controller.finish();
//! # Ok(()) }
//! ```
//!
//! **Integration.** The internal simulator moves a vehicle with its current speed and then
//! changes the speed (eq. 1: `x' = x + v dt`, `v' = v + a dt`); SUMO's default (Euler) update
//! moves it with its new speed (`x' = x + v' dt`). So that positions agree exactly, SUMO's
//! speed runs one step behind the model's: the controller keeps the model speed
//! `v = v_SUMO + a_prev dt` of every vehicle it drove last step, observes and projects with it,
//! and sets SUMO's next speed to it (`setSpeed(v)`), which moves the vehicle by `v dt` as eq. 1
//! does. SUMO's ballistic update (`x' = x + (v + v') dt / 2`) would leave `a dt^2 / 2` per step,
//! which the policy's feedback amplified to metres within 10 s in the agreement test. The ego's
//! acceleration in the metrics is the applied action (SUMO's own for the `sumo` controller).
//!
//! Vehicles the controller drives get the SUMO speed and lane-change modes of
//! [`ControlModes`]: for a traffic policy by default speed mode 0 (the policy's speed exactly,
//! as in its training world; 25, [`ControlModes::SAFE`], adds SUMO's safe speed towards any
//! leader as a shield, the default for a Table I policy) and lane-change mode 257 (a
//! requested change waits while it would collide at once, and SUMO's strategic lane changes:
//! a ramp vehicle that must leave its lane signals, SUMO's drivers make room for it, and SUMO
//! may move it into a gap its own model accepts; [`ControlModes::lane_change`]).
//! [`ControlModes::EXACT`] (0 and 0) applies every action and lane change as the internal
//! simulator does. A traffic policy's scene holds every vehicle in the control zone, so the
//! projection keeps a driven vehicle's TTC to whatever is ahead of it in its lane (other ramp
//! vehicles queued ahead, vehicles cutting in from the next lane); a Table I game holds only
//! its nine players, and there SUMO's safe speed (`--speed-mode 25`) is what stands between a
//! driven vehicle and the traffic outside its game. The run counts the steps where SUMO did
//! not apply a commanded speed. An ego whose centre reaches the
//! conflict point is treated as merged, as in the internal simulator, and told to change to
//! the target lane next to it: from there on every scene counts it in the target lane, where
//! the policy was trained to see it, whether SUMO has moved it yet or not, except that the
//! target-lane vehicle beside it passes it (`pass_beside_waiting`), and it keeps
//! [`WAITING_MARGIN`] more to its neighbours so that SUMO finds the gap it needs (unless the
//! projection keeps a time gap, `sim.time_headway`, which does that itself). With
//! `merge.toml`'s `merge_from` it is told so earlier, at the first step from there on where
//! the lane change is safe (as the traffic world's `scenario.merge_zone`), and with a traffic
//! policy the scenes count it in the target lane from `merge_from` on: the vehicles behind
//! it make room for it, as SUMO's drivers do for a vehicle that signals a merge. Around a
//! waiting vehicle, the car behind keeps the margin too, a car within the clearance beside it
//! passes it, the ramp vehicles behind it keep the projection's TTC to it, and it
//! prepares to stop at the acceleration lane's end ([`LANE_END_BRAKE`]). These rules for
//! waiting vehicles apply only where SUMO may hold a lane change back (lane-change mode bits
//! 8-9); in [`ControlModes::EXACT`] nothing waits and the internal world's rules hold. Target-lane players keep SUMO's own lane changes
//! ([`ControlModes::player_lane_change`]). Positions are along the lanes
//! ([`LanePositions`]). Control ends when the ego is
//! `release_after` metres past the conflict point on the target lane; SUMO then drives it
//! again (speed mode 31, lane-change mode 1621, SUMO's defaults). Vehicles that leave,
//! teleport or vanish are dropped from the games at once. On a signalised merge a vehicle held
//! by its red light before the merge is out of it until the light turns green (SUMO drives
//! it: `Car::held_at_red`), and a driven vehicle stops at a red light ahead
//! (`Controller::signal_bound`), and stands at a stop sign's line before it goes on
//! (`Controller::stop_sign_bound`).

use crate::config::{Config, Entry};
use crate::engine::outcome::EgoStats;
use crate::policy::ensemble::PolicyEnsemble;
use crate::policy::observation::{BatchPolicy, Frame, Layout, observe_as};
use crate::render::timespace::{Road, Sample, TimeSpace};
use crate::sumo::geometry::{MergeGeometry, PlayerControl};
use crate::sumo::kind::ControllerKind;
use crate::sumo::positions::{LanePositions, MergeForm};
use crate::sumo::profile::SpeedBands;
use crate::sumo::{Sumo, SumoError};
use crate::world::merge_gate::{gate_holds, lane_change_is_safe, lane_end_bound, stop_bound};
use crate::world::neighbors::{Neighbors, find_neighbors, player_slots};
use crate::world::rules::WorldRules;
use crate::world::safety::{Neighbor, clip_action, feasible_interval};
use crate::world::state::{Scene, Vehicle};
use crate::world::step::{Projected, Settled, applied_action_with};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::time::Instant;

/// SUMO's default speed mode (all checks on).
pub const SUMO_SPEED_MODE: i32 = 31;
/// The speed-mode bit of SUMO's right of way at junctions.
const RIGHT_OF_WAY: i32 = 8;
/// The time gap (s) a ramp vehicle leaves before a crossing lane's vehicle reaches the junction
/// ([`Controller::crossing_holds`]): SUMO's `jmTimegapMinor` default.
const CROSSING_TIME_GAP: f64 = 1.0;
/// SUMO's halting speed (m/s): below it a vehicle stands (its waiting time runs), and a crossing
/// lane's vehicle counts as crawling towards the junction.
const HALTING_SPEED: f64 = 0.1;
/// How far before a stop sign's line (m) a vehicle's front may stand to count as stopped at it
/// (the stopping bound halts it 0.1 m before the line; SUMO's drivers halt 0.1 m or less before it).
const STOP_SIGN_REACH: f64 = 1.0;
/// SUMO's default lane-change mode.
pub const SUMO_LANE_CHANGE_MODE: i32 = 1621;

/// SUMO speed and lane-change modes of the vehicles the controller drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ControlModes {
    /// Speed mode bits (1 safe speed, 2 max accel, 4 max decel, 8 right of way, 16 red light).
    pub speed: i32,
    /// Lane-change mode bits of the ramp vehicles it drives. 257 (the default): a TraCI lane
    /// change avoids immediate collisions (256), and SUMO's strategic lane changes where they
    /// do not conflict with a TraCI request (1): an ego on a lane that ends signals, so SUMO's
    /// drivers in the target lane make room for it, and SUMO may change it into a gap its
    /// lane-change model accepts. With 256 alone the egos did not signal, nobody made room,
    /// and on `single_lane_merge` at demand 1.2 an ego braking for the lane's end beside the
    /// 17 m/s lane was moved at x_c in front of a car closing at 8.6 m/s (12-15% of the egos
    /// in an SSM conflict against 0% with 257; docs/experiments.md).
    pub lane_change: i32,
    /// Lane-change mode bits of the target-lane players it drives (1621, SUMO's default: they
    /// keep SUMO's own lane changes, so a player may move out of the target lane as SUMO's
    /// drivers do, and the policy drives it no longer; 0: none, the internal simulator's one
    /// lane).
    pub player_lane_change: i32,
}

impl ControlModes {
    /// `cosim`'s default for a traffic policy: the policy's speed exactly (no SUMO shield),
    /// collision-free requested lane changes with SUMO's strategic ones for ramp vehicles, and
    /// SUMO's own lane changes for target-lane players.
    pub const DEFAULT: ControlModes = ControlModes {
        speed: 0,
        ..ControlModes::SAFE
    };
    /// [`ControlModes::DEFAULT`] with SUMO's safe speed (speed mode 25) as a shield: `cosim`'s
    /// default for a Table I policy, whose game holds nine players.
    pub const SAFE: ControlModes = ControlModes {
        speed: 25,
        lane_change: 257,
        player_lane_change: SUMO_LANE_CHANGE_MODE,
    };
    /// `cosim`'s default for a policy of `layout`: [`ControlModes::DEFAULT`] for a traffic
    /// policy, whose scenes hold every vehicle in the control zone; [`ControlModes::SAFE`] for
    /// a Table I policy, whose game holds nine players.
    pub fn default_for(layout: Layout) -> ControlModes {
        if layout == Layout::Traffic {
            ControlModes::DEFAULT
        } else {
            ControlModes::SAFE
        }
    }

    /// No SUMO checks: every action and lane change applies as in the internal simulator.
    pub const EXACT: ControlModes = ControlModes {
        speed: 0,
        lane_change: 0,
        player_lane_change: 0,
    };
}

/// One target-lane or ramp vehicle as the controller sees it this step.
#[derive(Debug, Clone)]
struct Car {
    id: String,
    /// Centre position along the lanes (m; [`LanePositions`]): the internal simulator's x.
    x: f64,
    v: f64,
    accel: f64,
    /// On the ramp in the scenes: on a ramp lane and before where the scenes take ramp
    /// vehicles into the target lane (`Controller::scene_entry`: the conflict point, as the
    /// internal simulator, or `merge_from` with a traffic policy).
    on_ramp: bool,
    /// Ramp lane id while on a ramp lane.
    ramp_lane: Option<String>,
    /// A ramp-lane vehicle's leader on its route as SUMO sees it (within
    /// [`PATH_LEADER_REACH`]): at a gore it can be a vehicle already on a target lane whose
    /// rear is still in the ramp vehicle's path.
    path_leader: Option<String>,
    /// The next traffic light on its route, on a signalised merge: its state (SUMO's signal
    /// character) and the distance from the car's front to its stop line (m).
    signal: Option<(char, f64)>,
    /// A ramp car held by its red light before the merge: in no game until the light turns
    /// green (SUMO drives it meanwhile, and stops it there).
    held_at_red: bool,
    /// A stop sign at the end of the lane it is on that it has not yet stood at: the distance
    /// from its front to the stop line (m; [`LanePositions::stop_sign`]).
    stop_sign: Option<f64>,
    /// The speed limit of the lane it is on (m/s), when the network gives one.
    speed_limit: Option<f64>,
    /// How much longer than the world's car it is, halved (m; [`Scene::excess`]).
    excess: f64,
}

/// Whether a SUMO signal state stops traffic: red, or red-yellow before green.
fn is_red(state: char) -> bool {
    matches!(state, 'r' | 'R' | 'u')
}

/// How far past the ramp's end (m) a target-lane stop line still belongs to the merge's
/// junction: the two roads' stop lines lie a few metres apart where they meet.
const SIGNAL_REACH: f64 = 10.0;

/// How far ahead (m) SUMO is asked for a ramp-lane vehicle's leader on its route.
const PATH_LEADER_REACH: f64 = 100.0;

impl Car {
    /// A ramp vehicle past its scene entry that SUMO has not moved to the target lane yet:
    /// the scene has it in the target lane (`on_ramp` false), SUMO on the ramp.
    fn is_waiting(&self) -> bool {
        self.ramp_lane.is_some() && !self.on_ramp
    }

    /// The car as the internal simulator's state (ramp one lane width to the right).
    fn vehicle(&self, lane_width: f64) -> Vehicle {
        Vehicle {
            x: self.x,
            y: if self.on_ramp { -lane_width } else { 0.0 },
            v: self.v,
            phi: 0.0,
            on_ramp: self.on_ramp,
        }
    }
}

/// What happened to one ego.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EgoRecord {
    /// SUMO vehicle id.
    pub id: String,
    /// Simulation time when control (or tracking, for `sumo`) began (s).
    pub start: f64,
    /// Simulation time of release, if released (s).
    pub end: Option<f64>,
    /// Reached the target lane.
    pub merged: bool,
    /// Involved in a SUMO collision while tracked.
    pub collision: bool,
    /// Teleported or vanished before merging.
    pub lost: bool,
    /// Metrics accumulated over the tracked steps (same definitions as `mpgdrive eval`).
    #[serde(skip)]
    pub stats: EgoStats,
    /// Its speed by distance to the conflict point over the tracked steps.
    #[serde(skip)]
    pub speed_bands: SpeedBands,
}

impl EgoRecord {
    /// Finished: released, collided or lost (an ego still driving when the run ends is not).
    pub fn finished(&self) -> bool {
        self.end.is_some() || self.collision || self.lost
    }
}

/// A collision event as SUMO reports it, counted once per pair and event.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CollisionEvent {
    /// Simulation time (s).
    pub time: f64,
    /// Colliding vehicle.
    pub collider: String,
    /// Hit vehicle.
    pub victim: String,
    /// Whether either vehicle was driven by the controller at the time.
    pub controlled: bool,
}

/// Time spent in the controller's own work (microseconds, summed over steps).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ControllerTiming {
    /// Steps handled.
    pub steps: u64,
    /// Total controller time (us).
    pub total_us: f64,
}

/// The co-simulation controller (see the module docs).
pub struct Controller {
    config: Config,
    /// The world's rules at the network's conflict point.
    rules: WorldRules,
    geometry: MergeGeometry,
    positions: LanePositions,
    /// Where the acceleration lane (the last ramp lane) ends, when `positions` knows it (m).
    lane_end: Option<f64>,
    kind: ControllerKind,
    policy: Option<PolicyEnsemble>,
    modes: ControlModes,
    types: HashMap<String, String>,
    /// The ramp or target lane each vehicle was last seen on (for junction internal lanes).
    lane_class: HashMap<String, String>,
    /// Each active ego's players and their slots, fixed at pick-up.
    players: HashMap<String, Vec<(String, usize)>>,
    egos: BTreeMap<String, EgoRecord>,
    controlled: HashSet<String>,
    colliding: HashSet<(String, String)>,
    /// Collision events (once per pair and event).
    pub collisions: Vec<CollisionEvent>,
    /// Steps where SUMO did not reach the commanded speed (by more than 0.01 m/s).
    pub overridden: u64,
    /// Driven vehicles that passed a stop line while their light showed red
    /// (`Controller::signal_bound` holds them; SUMO's speed mode may too).
    pub red_light_passes: u64,
    /// Each driven vehicle's distance to the red light ahead of it at the last step.
    red_ahead: HashMap<String, f64>,
    /// Driven vehicles that passed a stop sign's line without coming to a standstill at it
    /// (`Controller::stop_sign_bound` holds them).
    pub stop_sign_passes: u64,
    /// Where the centre of each driven vehicle that had a stop sign ahead of it at the last step,
    /// not yet stood at, is when its front reaches the line.
    sign_ahead: HashMap<String, f64>,
    /// The lane at whose stop sign each vehicle last stood.
    stood: HashMap<String, String>,
    /// Seconds until the first vehicle on a crossing lane ([`LanePositions::crossing`]) that
    /// could no longer stop before it reaches the junction this step
    /// ([`Controller::crossing_arrival`]).
    crossing_arrival: f64,
    /// Speed of every target-lane vehicle in the control zone by distance to the conflict point,
    /// each step (whoever drives it: the traffic the egos merge into).
    pub lane_speed: SpeedBands,
    commanded: HashMap<String, f64>,
    /// Acceleration applied last step per driven vehicle: model speed = SUMO speed + a dt.
    applied: HashMap<String, f64>,
    /// The policy reads the traffic layout: an ego's game is every vehicle around it, formed
    /// anew each step (no fixed players, no agent index).
    traffic: bool,
    /// The desired speed a traffic policy observes (m/s): the road's speed limit where egos
    /// merge, within the range it was trained on (`traffic.desired_speed`; without one, its
    /// `reward.v_desired`); none for Table I policies and `sumo`.
    v_desired: Option<f64>,
    timing: ControllerTiming,
    order: Vec<usize>,
    /// The time-space record, when asked for.
    timespace: Option<TimeSpace>,
    /// Colour the vehicles it drives, for sumo-gui.
    colour: bool,
}

/// Colours of the vehicles a controller drives, as sumo-gui draws them: the egos red, the
/// other players the MPG policy drives orange. A vehicle keeps its colour once handed back.
pub const EGO_COLOUR: [u8; 3] = [220, 20, 20];
/// See [`EGO_COLOUR`].
pub const PLAYER_COLOUR: [u8; 3] = [255, 150, 0];

/// Extra gap (m) a ramp vehicle waiting past its scene entry keeps to the target-lane
/// vehicles of its scene. The feasibility projection brings a vehicle that starts inside its
/// clearance (length plus `sim.safety_gap`) back towards it only asymptotically (the gap's
/// shortfall shrinks by `dt / tau_s` per step), while SUMO makes the lane change only once the
/// bumper gaps exceed the vehicles' `minGap` (2 m on the bundled networks, SUMO's default
/// 2.5 m): a waiting ego then drove level with its leader to the lane's end and merged there,
/// slowly (measured on `i80_merge`, demand 1.2: 32 of 216 egos in an SSM conflict, 12 with
/// this margin).
pub const WAITING_MARGIN: f64 = 2.0;

/// Deceleration (m/s^2) at which a ramp vehicle waiting for its lane change prepares to stop
/// at the acceleration lane's end ([`Controller`]'s `lane_end_bound`). Measured on
/// `i80_merge` (every grid deployment at demand 1.2): 1.0 and 3.5 left more egos in an SSM
/// conflict or slower than 2.0 did; on `single_lane_merge` without SUMO's safe speed, 4.0
/// gave the same grid rows as 2.0.
pub const LANE_END_BRAKE: f64 = 2.0;

/// How much farther (m) SUMO may move a vehicle in one step than the internal world predicts
/// it: the world moves it by its speed before the step (eq. 1), SUMO by its speed after, so a
/// follower accelerating at `g` gains `g dt^2`. The entry checks and the projection keep it on
/// top of their clearance (SUMO counts a collision below `minGap`, the world's `safety_gap`):
/// with the bare clearance, an ego entered at a standstill 0.0009 m above it in front of one
/// that started at `g` in the same step, and SUMO counted a collision at 1.996 m (`acc60-v36`
/// of the zoo, ego only, demand 1.2, SUMO seed 0, speed mode 0). Not in
/// [`ControlModes::EXACT`], whose contract is the internal simulator's rules, to the bit.
fn sumo_step_reach(config: &Config) -> f64 {
    config.vehicle.max_accel * config.sim.dt * config.sim.dt
}

impl Controller {
    /// A controller; `policy` is required for `mpg` and `sarl`. Every rule (observation,
    /// feasibility projection, merge gate, release) uses the network's conflict point, not the
    /// one of `config`'s internal world: the observation reads distances to it, so a policy
    /// deploys at any conflict point. That is `geometry`'s, or under the entry rule
    /// (`scenario.entry = "gap"`) the end of the ramp lanes, where the training's ramp ends
    /// too; the speed bands of the report count from it. Vehicles are placed along the lanes
    /// by `positions` ([`crate::sumo::inputs::check_geometry`] gives them).
    pub fn new(
        config: Config,
        geometry: MergeGeometry,
        positions: LanePositions,
        kind: ControllerKind,
        policy: Option<PolicyEnsemble>,
        modes: ControlModes,
    ) -> Self {
        let traffic = Layout::of(&config) == Layout::Traffic;
        // The road's speed limit, within the desired speeds the policy was trained on.
        let trained = config.traffic.as_ref().and_then(|t| t.desired_speed);
        let road = geometry.desired_speed.or(positions.road_speed());
        let v_desired = (traffic && kind != ControllerKind::Sumo).then(|| match (road, trained) {
            (Some(v), Some([lo, hi])) => v.clamp(lo, hi),
            _ => config.reward.v_desired,
        });
        let lane_end = geometry
            .ramp_lanes
            .last()
            .and_then(|lane| positions.span(lane))
            .map(|(_, end)| end);
        // Under the entry rule the world's ramp ends where the network's does (a centre half a
        // length before the last ramp lane's end: an acceleration lane's, or a stop line), and
        // there is its conflict point, as in training, whose ramp ends at x_c: the policy reads
        // `x_c - x` as the room left before it must have entered. With x_c where merge.toml puts
        // it (20 m before an acceleration lane's end) the egos braked for a stop 17.5 m short
        // of the real one (docs/experiments.md, "Where the policy's ramp ends").
        let ramp_end = lane_end.filter(|_| config.scenario.entry == Entry::Gap);
        let x_c = ramp_end.map_or(geometry.conflict_point, |end| end - 0.5 * config.vehicle.length);
        let mut config = config.at_conflict_point(x_c);
        // The merge zone, where players make room for a ramp vehicle, starts where the egos
        // may enter (`merge_from`), as the training's starts where its ramp vehicles may.
        if let (Some(_), Some(from)) = (ramp_end, geometry.merge_from) {
            config.scenario.merge_zone = config.scenario.merge_zone.max(x_c - from);
        }
        let mut rules = WorldRules::new(&config);
        if modes != ControlModes::EXACT {
            rules.gate.clearance += sumo_step_reach(&config);
        }
        Controller {
            config,
            rules,
            geometry,
            positions,
            lane_end,
            kind,
            policy,
            modes,
            types: HashMap::new(),
            lane_class: HashMap::new(),
            players: HashMap::new(),
            egos: BTreeMap::new(),
            controlled: HashSet::new(),
            colliding: HashSet::new(),
            collisions: Vec::new(),
            overridden: 0,
            red_light_passes: 0,
            red_ahead: HashMap::new(),
            stop_sign_passes: 0,
            sign_ahead: HashMap::new(),
            stood: HashMap::new(),
            crossing_arrival: f64::INFINITY,
            lane_speed: SpeedBands::default(),
            commanded: HashMap::new(),
            applied: HashMap::new(),
            traffic,
            v_desired,
            timing: ControllerTiming::default(),
            order: Vec::new(),
            timespace: None,
            colour: false,
        }
    }

    /// Keeps at least `min_gap` (m: the largest `minGap` of the network's vehicle types)
    /// between bumpers wherever the world keeps `sim.safety_gap`: SUMO counts a gap below a
    /// vehicle's `minGap` as a collision (unless `collision.mingap-factor` is 0), and a type
    /// that sets none has 2.5 m, more than the world's 2 m. Measured on a ramp-metered merge
    /// built with netconvert (default types, `--speed-mode 0`): 4 controlled "collisions" in
    /// the ramp's queue at 2.0-2.5 m gaps, none with this.
    pub fn keep_min_gap(&mut self, min_gap: f64) {
        self.rules.gate.clearance += (min_gap - self.config.sim.safety_gap).max(0.0);
    }

    /// Colours the vehicles it takes over from now on ([`EGO_COLOUR`], [`PLAYER_COLOUR`]), so
    /// that sumo-gui shows which vehicles the policy drives. The colour changes nothing else.
    pub fn colour_driven(&mut self) {
        self.colour = true;
    }

    /// Records every ramp and target-lane vehicle at every step from now on, for a
    /// time-space diagram: its distance to the conflict point, its speed (the model speed of
    /// a driven vehicle), and whether the controller drives it (for `sumo`, whether it is a
    /// tracked ego). Collisions are marked at the colliding vehicle.
    pub fn record_timespace(&mut self) {
        self.timespace = Some(TimeSpace::new(self.rules.dt));
    }

    /// The time-space record so far (none unless [`Controller::record_timespace`] was called).
    pub fn take_timespace(&mut self) -> Option<TimeSpace> {
        self.timespace.take()
    }

    /// The desired speed a traffic policy observes (m/s; none for Table I policies and
    /// `sumo`).
    pub fn desired_speed(&self) -> Option<f64> {
        self.v_desired
    }

    /// Controller time so far.
    pub fn timing(&self) -> ControllerTiming {
        self.timing
    }

    /// One control step; call it after each `sumo.step()`.
    pub fn step(&mut self, sumo: &mut Sumo) -> Result<(), SumoError> {
        self.step_sharing(sumo, &mut HashSet::new())
    }

    /// One control step of one of several controllers of a simulation (one per merge of the
    /// network, each stepped in turn): the vehicles in `taken` were driven this step by an
    /// earlier one and are left to it; the ones this controller drives are added.
    pub fn step_sharing(&mut self, sumo: &mut Sumo, taken: &mut HashSet<String>) -> Result<(), SumoError> {
        let started = Instant::now();
        let time = sumo.time()?;
        let known_collisions = self.collisions.len();
        self.note_collisions(sumo, time)?;
        let teleporting = sumo.teleporting()?;
        let gone: HashSet<String> = sumo
            .arrived()?
            .into_iter()
            .chain(teleporting.iter().cloned())
            .collect();
        for id in &gone {
            self.controlled.remove(id);
            self.commanded.remove(id);
            self.applied.remove(id);
            if let Some(ego) = self.egos.get_mut(id).filter(|e| !e.finished()) {
                ego.lost = !ego.merged || teleporting.contains(id);
                ego.end = Some(time);
            }
        }
        let cars = self.read_cars(sumo, &gone)?;
        self.crossing_arrival = self.crossing_arrival(sumo)?;
        // An ego that left the merge's lanes (a merged ego that changed lanes before its
        // release, a ramp vehicle that took a junction link into another lane) ends there.
        let present: HashSet<&str> = cars.iter().map(|c| c.id.as_str()).collect();
        for ego in self.egos.values_mut() {
            if !ego.finished() && !present.contains(ego.id.as_str()) {
                ego.lost = !ego.merged;
                ego.end = Some(time);
            }
        }
        let x_c = self.rules.conflict_point();
        let zone = self.geometry.control_from..=x_c + self.geometry.release_after;
        for c in cars
            .iter()
            .filter(|c| c.ramp_lane.is_none() && zone.contains(&c.x))
        {
            self.lane_speed.record(c.x - x_c, c.v);
        }
        let games = self.form_games(sumo, &cars, time)?;
        let commands = self.decide(&cars, &games);
        let mut driven = HashSet::new();
        let mut applied = HashMap::new();
        for (car, accel) in commands {
            let c = &cars[car];
            if taken.contains(&c.id) {
                continue;
            }
            if self.controlled.insert(c.id.clone()) {
                sumo.set_speed_mode(&c.id, self.speed_mode(c))?;
                let mode = match c.ramp_lane {
                    Some(_) => self.modes.lane_change,
                    None => self.modes.player_lane_change,
                };
                sumo.set_lane_change_mode(&c.id, mode)?;
                if self.colour {
                    let ego = self.egos.contains_key(&c.id);
                    sumo.set_color(&c.id, if ego { EGO_COLOUR } else { PLAYER_COLOUR })?;
                }
            }
            let accel = self.within_speed_limit(c, accel);
            // SUMO's next speed is the model's current one (module docs: one-step lag). A
            // vehicle braked to a stop can land a rounding error below zero (v + (-v / dt) dt),
            // and a negative speed tells SUMO to drive the vehicle itself again.
            let v = c.v.max(0.0);
            sumo.set_speed(&c.id, v)?;
            self.commanded.insert(c.id.clone(), v);
            applied.insert(c.id.clone(), accel);
            if let Some(lane) = c.ramp_lane.as_ref().filter(|_| self.merges_now(&cars, car)) {
                if let Some((_, index)) = self.geometry.merge_lane(lane) {
                    sumo.change_lane(&c.id, index, 1.0)?;
                }
            }
            driven.insert(c.id.clone());
        }
        self.applied = applied;
        if self.timespace.is_some() {
            let marked: HashSet<&str> = if self.kind == ControllerKind::Sumo {
                games.iter().map(|g| cars[g.ego_car()].id.as_str()).collect()
            } else {
                driven.iter().map(String::as_str).collect()
            };
            self.record_step(time, &cars, &marked, known_collisions);
        }
        let released: Vec<String> = self.controlled.difference(&driven).cloned().collect();
        taken.extend(driven);
        for id in released {
            self.controlled.remove(&id);
            self.commanded.remove(&id);
            if taken.contains(&id) {
                continue; // another merge's controller drives it now
            }
            // A vehicle removed by someone else (another TraCI client) refuses the first call:
            // there is nothing left to hand back.
            if !gone.contains(&id) && sumo.set_speed(&id, -1.0).is_ok() {
                sumo.set_speed_mode(&id, SUMO_SPEED_MODE)?;
                sumo.set_lane_change_mode(&id, SUMO_LANE_CHANGE_MODE)?;
            }
        }
        self.timing.steps += 1;
        self.timing.total_us += started.elapsed().as_secs_f64() * 1e6;
        Ok(())
    }

    /// Where a ramp vehicle enters the target lane of the scenes: with a traffic policy at
    /// `merge_from` (where it asks SUMO for the lane change at the first safe gap), otherwise
    /// at the conflict point, as the internal simulator moves it. Counted in the target lane
    /// from there on, it is a leader the target-lane vehicles behind it keep their distance
    /// to, as SUMO's drivers make room for a vehicle that signals a merge; without that, a
    /// target-lane player level with it kept its speed, neither gave way, and the ego drove
    /// beside it to the end of the acceleration lane (measured on `i80_merge`, the game,
    /// demand 1.0: 21% of the egos in an SSM conflict, 4% with the rule).
    /// Under the entry rule (`scenario.entry = "gap"`) a ramp vehicle is on the ramp in the
    /// scenes until SUMO has moved it, as the internal world has it until it enters.
    fn scene_entry(&self) -> f64 {
        let x_c = self.rules.conflict_point();
        if self.entry_rule() {
            return f64::INFINITY;
        }
        match self.geometry.merge_from {
            Some(from) if self.traffic && self.sumo_holds_lane_changes() => from.min(x_c),
            _ => x_c,
        }
    }

    /// SUMO speed mode of a vehicle the controller takes over: [`ControlModes::speed`], but a
    /// ramp vehicle of a junction merge without SUMO's right of way (bit 8): where it crosses
    /// the stop line is the entry rule's decision ([`Controller::stop_line_bound`]), as where
    /// it changes lanes is on an acceleration lane. SUMO's minor link yields to every lane its
    /// junction lane conflicts with, often all lanes of the freeway at once: on a 3-lane
    /// freeway with 900 veh/h, 2 of SUMO's own ramp drivers got through in 300 s.
    fn speed_mode(&self, car: &Car) -> i32 {
        match car.ramp_lane {
            Some(_) if self.is_junction() => self.modes.speed & !RIGHT_OF_WAY,
            _ => self.modes.speed,
        }
    }

    /// Whether the merge is a junction merge (the ramp lane ends at the stop line).
    fn is_junction(&self) -> bool {
        self.positions.form() == MergeForm::Junction
    }

    /// Whether ramp vehicles enter by the entry rule (`scenario.entry = "gap"`), the world's
    /// physics: then the lane's end holds them ([`applied_action`]) and nothing forces an entry.
    fn entry_rule(&self) -> bool {
        self.config.scenario.entry == Entry::Gap && self.kind != ControllerKind::Sumo
    }

    /// Whether SUMO may hold back a lane change the controller asks for (the ramp vehicles'
    /// lane-change mode has bits 8-9, TraCI requests checked against other vehicles). Only
    /// then can a ramp vehicle wait beside the target lane, and only then do the rules for
    /// waiting vehicles apply (`scene_entry` at `merge_from`, [`WAITING_MARGIN`], the car
    /// beside passing, the physical ramp leader, the lane's end): with mode 0
    /// ([`ControlModes::EXACT`]) a lane change is made the step it is asked for, as the
    /// internal world makes it, and the co-simulation reproduces the internal world.
    fn sumo_holds_lane_changes(&self) -> bool {
        (self.modes.lane_change >> 8) & 3 != 0
    }

    /// Whether `car` waits beside the target lane for a lane change SUMO holds back: past its
    /// scene entry on a ramp lane ([`Car::is_waiting`]), where SUMO may hold one back.
    fn waits(&self, car: &Car) -> bool {
        self.sumo_holds_lane_changes() && car.is_waiting()
    }

    /// Whether ramp vehicle `car`, driven by the policy, changes to the target lane now: at
    /// the conflict point, or from `merge_from` on where the lane change is safe (the traffic
    /// world's merge-zone rule, [`lane_change_is_safe`]).
    /// Under the entry rule (`scenario.entry = "gap"`) it is never at the conflict point
    /// whatever is beside it: from `merge_from` on (else from the merge zone's start) at the
    /// first step the entry rule holds, the lane change of the internal world.
    fn merges_now(&self, cars: &[Car], car: usize) -> bool {
        if self.is_junction() {
            return false; // it enters by driving on through the junction
        }
        let x = cars[car].x;
        if self.entry_rule() {
            let x_c = self.rules.conflict_point();
            let from = self
                .geometry
                .merge_from
                .unwrap_or(x_c - self.config.scenario.merge_zone);
            let lane = ego_and_target_lane(cars, car, self.config.scenario.lane_width);
            return x >= from && lane_change_is_safe(&lane, 0, &self.rules.gate);
        }
        x >= self.rules.conflict_point()
            || self.geometry.merge_from.is_some_and(|from| {
                x >= from
                    && lane_change_is_safe(
                        &ego_and_target_lane(cars, car, self.config.scenario.lane_width),
                        0,
                        &self.rules.gate,
                    )
            })
    }

    /// Adds this step's vehicles and new collisions to the time-space record.
    fn record_step(&mut self, time: f64, cars: &[Car], marked: &HashSet<&str>, known_collisions: usize) {
        let Some(ts) = self.timespace.as_mut() else {
            return;
        };
        let x_c = self.rules.conflict_point();
        for c in cars {
            let road = if c.ramp_lane.is_some() {
                Road::Ramp
            } else {
                Road::Target
            };
            let sample = Sample {
                t: time,
                s: c.x - x_c,
                v: c.v,
                marked: marked.contains(c.id.as_str()),
            };
            ts.record(&c.id, road, sample);
        }
        for event in &self.collisions[known_collisions..] {
            if let Some(mark) = ts.locate(&event.collider, time) {
                ts.collisions.push(mark);
            }
        }
    }

    /// Records collisions new this step (a pair overlapping over several steps counts once).
    fn note_collisions(&mut self, sumo: &Sumo, time: f64) -> Result<(), SumoError> {
        let mut now = HashSet::new();
        for c in sumo.collisions()? {
            let pair = if c.collider <= c.victim {
                (c.collider.clone(), c.victim.clone())
            } else {
                (c.victim.clone(), c.collider.clone())
            };
            if now.insert(pair.clone()) && !self.colliding.contains(&pair) {
                for id in [&c.collider, &c.victim] {
                    if let Some(ego) = self.egos.get_mut(id) {
                        if !ego.finished() {
                            ego.collision = true;
                        }
                    }
                }
                self.collisions.push(CollisionEvent {
                    time,
                    controlled: self.controlled.contains(&c.collider) || self.controlled.contains(&c.victim),
                    collider: c.collider,
                    victim: c.victim,
                });
            }
        }
        self.colliding = now;
        Ok(())
    }

    /// Ramp and target-lane vehicles, centre positions along the lanes.
    fn read_cars(&mut self, sumo: &Sumo, gone: &HashSet<String>) -> Result<Vec<Car>, SumoError> {
        // (vehicle, ramp or target lane it belongs to, lane it is on)
        let mut found: Vec<(String, String, String)> = Vec::new();
        for lane in self.geometry.ramp_lanes.iter().chain(&self.geometry.target_lanes) {
            found.extend(
                sumo.lane_vehicles(lane)?
                    .into_iter()
                    .map(|id| (id, lane.clone(), lane.clone())),
            );
        }
        // A vehicle crossing a junction is on an internal lane for a step or more: it keeps the
        // class of the lane it came from.
        let listed: HashSet<&str> = found.iter().map(|(id, _, _)| id.as_str()).collect();
        let crossing: Vec<(String, String)> = self
            .lane_class
            .iter()
            .filter(|(id, _)| !listed.contains(id.as_str()) && !gone.contains(*id))
            .map(|(id, lane)| (id.clone(), lane.clone()))
            .collect();
        for (id, lane) in crossing {
            // An error here means the vehicle was removed (by another client, say): skip it.
            if let Ok(on) = sumo.lane_id(&id) {
                if on.starts_with(':') {
                    found.push((id, lane, on));
                }
            }
        }
        let in_lane_from = self.scene_entry();
        let signs_ahead = std::mem::take(&mut self.sign_ahead);
        let present: HashSet<&str> = found.iter().map(|(id, _, _)| id.as_str()).collect();
        self.stood.retain(|id, _| present.contains(id.as_str()));
        let mut cars = Vec::with_capacity(found.len());
        self.lane_class.clear();
        for (id, lane, on) in found {
            let s = sumo.vehicle(&id)?;
            // A junction lane that leads off the merge: the vehicle has left it.
            let Some(front) = self.positions.position(&on, s.lane_pos) else {
                continue;
            };
            let x = front - 0.5 * s.length;
            // On a junction merge's entry lane a vehicle has crossed the stop line: it is
            // entering the target lane.
            let ramp = self.geometry.is_ramp(&lane) && !self.positions.is_entry(&on);
            if self
                .commanded
                .get(&id)
                .is_some_and(|&cmd| (s.speed - cmd).abs() > 0.01)
            {
                self.overridden += 1;
            }
            let (v, accel) = match self.applied.get(&id) {
                Some(&a) => (s.speed + a * self.rules.dt, a),
                None => (s.speed, s.accel),
            };
            self.lane_class.insert(id.clone(), lane.clone());
            let path_leader = if ramp {
                sumo.leader(&id, PATH_LEADER_REACH)?.map(|(leader, _)| leader)
            } else {
                None
            };
            let signal = match self.positions.signalised() {
                true => sumo.next_signal(&id)?,
                false => None,
            };
            // A car held by its red light before the merge is out of it until the light turns
            // green (SUMO drives it, and stops it there): the light gives the other road its
            // turn. An ego beside a platoon held at the light waited for it as for a jam, and
            // players made room for egos held at theirs.
            let held_at_red = signal.is_some_and(|(state, d)| {
                is_red(state) && d >= 0.0 && self.lane_end.is_some_and(|end| front + d <= end + SIGNAL_REACH)
            });
            if held_at_red && !ramp {
                continue;
            }
            // A driven car that had a red light ahead last step and has passed it since (SUMO
            // gives the light a car is crossing at a negative distance, or none).
            if let Some(was) = self.red_ahead.remove(&id) {
                if signal.is_none_or(|(_, d)| d < 0.0 || d > was + 1.0) {
                    self.red_light_passes += 1;
                }
            }
            // SUMO's drivers stand at a stop sign's line before they go on (speed below SUMO's
            // halting speed, 0.1 m/s); from then on the link is a minor one.
            let stop_sign = (self.positions.stop_sign(&on)).map(|line| (line - front).max(0.0));
            if stop_sign.is_some_and(|d| s.speed < HALTING_SPEED && d <= STOP_SIGN_REACH) {
                self.stood.insert(id.clone(), on.clone());
            }
            let stop_sign = stop_sign.filter(|_| self.stood.get(&id) != Some(&on));
            // Past the line it had not stood at (a car that left the lane sideways is gone).
            if signs_ahead.get(&id).is_some_and(|&line| x > line) {
                self.stop_sign_passes += 1;
            }
            cars.push(Car {
                signal,
                held_at_red,
                stop_sign,
                speed_limit: self.positions.speed_limit(&on),
                excess: 0.5 * (s.length - self.config.vehicle.length),
                on_ramp: ramp && x < in_lane_from,
                ramp_lane: ramp.then_some(lane),
                path_leader,
                id,
                x,
                v,
                accel,
            });
        }
        Ok(cars)
    }

    /// `accel` within the speed limit of `c`'s lane, a rule of the road for every driver (SUMO's
    /// drive to it too): no speeding up past it, and above it (on entering a slower lane) no
    /// more braking towards it than `sim.b_safe`. The policies' world has one desired speed
    /// and a ramp as fast as the road; a network's ramp is often slower than the freeway.
    fn within_speed_limit(&self, c: &Car, accel: f64) -> f64 {
        match c.speed_limit {
            Some(limit) => accel.min(((limit - c.v) / self.rules.dt).max(-self.rules.gate.b_safe)),
            None => accel,
        }
    }

    /// Picks up new egos (choosing their players once, as the initial state of an internal
    /// episode does), releases merged ones, and returns each active ego's game: indices into
    /// `cars` with player slots, the ego first. A player that left the target lane or the
    /// network drops out; no player is added later.
    fn form_games(&mut self, sumo: &Sumo, cars: &[Car], time: f64) -> Result<Vec<Game>, SumoError> {
        let index: HashMap<&str, usize> = cars.iter().enumerate().map(|(k, c)| (c.id.as_str(), k)).collect();
        if self.traffic && self.geometry.players == PlayerControl::Controllable {
            // Merge traffic forms its games anew each step: the types of the vehicles around,
            // which decide the players the policy may drive, are learned as they come.
            for c in cars {
                self.is_controllable(sumo, &c.id)?;
            }
        }
        let mut games = Vec::new();
        for (k, c) in cars.iter().enumerate() {
            let tracked = self.egos.get(&c.id);
            if tracked.is_some_and(EgoRecord::finished) {
                continue;
            }
            if tracked.is_none() && !self.pick_up(sumo, cars, k, time)? {
                continue;
            }
            if c.held_at_red {
                continue; // it has no game until its light turns green (`Car::held_at_red`)
            }
            let (merged, release) = self.merge_progress(c);
            let ego = self.egos.get_mut(&c.id).expect("tracked");
            ego.merged |= merged;
            if release {
                ego.end = Some(time);
                self.players.remove(&c.id);
                continue;
            }
            if self.traffic {
                // Merge traffic: every vehicle around the ego is in its game, now (in the
                // order of `cars`, so that every game shares one scene), but ramp cars held at
                // their red light (`Car::held_at_red`).
                let members: Vec<(usize, usize)> = (0..cars.len())
                    .filter(|&j| !cars[j].held_at_red)
                    .map(|j| (j, 0))
                    .collect();
                let ego = members
                    .iter()
                    .position(|&(j, _)| j == k)
                    .expect("the ego is not held");
                games.push(Game { members, ego });
                continue;
            }
            let mut members = vec![(k, 0)];
            members.extend(self.players[&c.id].iter().filter_map(|(id, slot)| {
                let &j = index.get(id.as_str())?;
                (!cars[j].on_ramp).then_some((j, *slot))
            }));
            games.push(Game { members, ego: 0 });
        }
        games.sort_by(|a, b| cars[b.ego_car()].x.total_cmp(&cars[a.ego_car()].x));
        Ok(games)
    }

    /// Whether an ego has merged (SUMO has it on a target lane) and whether it is released
    /// (merged and `release_after` past the conflict point). A ramp vehicle past its scene entry
    /// whose lane change SUMO has not made yet is neither: the scenes count it in the target
    /// lane, but until it is there the policy keeps it.
    fn merge_progress(&self, c: &Car) -> (bool, bool) {
        let merged = c.ramp_lane.is_none();
        let release = merged && c.x >= self.rules.conflict_point() + self.geometry.release_after;
        (merged, release)
    }

    /// Starts tracking ramp vehicle `k` if it is controllable and in the control zone, with
    /// its players: up to `n_leaders` target-lane vehicles ahead (front-most first, in slots
    /// ending at `n_leaders`) and up to `n_followers` behind (nearest first).
    fn pick_up(&mut self, sumo: &Sumo, cars: &[Car], k: usize, time: f64) -> Result<bool, SumoError> {
        let c = &cars[k];
        if !c.on_ramp || c.x < self.geometry.control_from || !self.is_controllable(sumo, &c.id)? {
            return Ok(false);
        }
        let players = if self.traffic {
            Vec::new()
        } else {
            self.nearest_players(cars, k)
        };
        if self.geometry.players == PlayerControl::Controllable {
            for (id, _) in &players {
                self.is_controllable(sumo, id)?;
            }
        }
        self.players.insert(c.id.clone(), players);
        self.egos.insert(
            c.id.clone(),
            EgoRecord {
                id: c.id.clone(),
                start: time,
                end: None,
                merged: false,
                collision: false,
                lost: false,
                stats: EgoStats::default(),
                speed_bands: SpeedBands::default(),
            },
        );
        Ok(true)
    }

    /// The players of ego `k` now: up to `n_leaders` target-lane vehicles ahead (front-most
    /// first, in the slots that end at `n_leaders`) and up to `n_followers` behind (nearest
    /// first, from slot `n_leaders + 1`), among those within the reach of training's initial
    /// states: `n_leaders` (or `n_followers`) times the largest sampled headway (120 m in the
    /// paper's setting). Slots left empty read as a player that left: a far follower is
    /// outside what training placed, and the ego would slow on the ramp to let it pass.
    fn nearest_players(&self, cars: &[Car], k: usize) -> Vec<(String, usize)> {
        let s = &self.config.scenario;
        let headway = self.config.sampling.headway[1];
        let ego_x = cars[k].x;
        let (ahead, behind) = (s.n_leaders as f64 * headway, s.n_followers as f64 * headway);
        let target: Vec<(String, f64)> = cars
            .iter()
            .filter(|o| !o.on_ramp && o.x - ego_x <= ahead && ego_x - o.x <= behind)
            .map(|o| (o.id.clone(), o.x))
            .collect();
        player_slots(ego_x, &target, s.n_leaders, s.n_followers)
    }

    /// Whether a vehicle's type is controllable (types are asked once per vehicle).
    fn is_controllable(&mut self, sumo: &Sumo, id: &str) -> Result<bool, SumoError> {
        if !self.types.contains_key(id) {
            self.types.insert(id.to_owned(), sumo.type_id(id)?);
        }
        Ok(self.geometry.controllable_types.contains(&self.types[id]))
    }

    /// Updates the egos' metrics and returns `(car, applied acceleration)` for every vehicle
    /// the policy drives this step (each vehicle in one game at most: the first, downstream
    /// ego's game claims it).
    fn decide(&mut self, cars: &[Car], games: &[Game]) -> Vec<(usize, f64)> {
        let layout = Layout::of(&self.config);
        let dim = layout.dim();
        let x_c = self.rules.conflict_point();
        let frame = Frame::of(&self.config);
        let lane_width = self.config.scenario.lane_width;
        let mut rows: Vec<(usize, usize, usize)> = Vec::new(); // (scene, member, car)
        let mut obs: Vec<f32> = Vec::new();
        let mut scenes = Vec::with_capacity(games.len());
        let mut claimed = HashSet::new();
        let mut neighbors = Vec::new();
        let mut scene_cars = Vec::new();
        let gives = self
            .positions
            .minor_entry()
            .then(|| gives_way(cars, self.geometry.control_from, |id| self.egos.contains_key(id)));
        let zips = self
            .positions
            .zipper_entry()
            .then(|| zips(cars, |id| self.egos.contains_key(id)));
        for game in games {
            // Traffic games share one scene (every car, in the order of `cars`): built once.
            if scenes.is_empty() || !self.traffic {
                let mut scene = Scene::new(
                    game.members
                        .iter()
                        .map(|&(j, _)| cars[j].vehicle(lane_width))
                        .collect(),
                );
                scene.v_desired = self.v_desired;
                if let Some(gives) = &gives {
                    scene.gives_way = game.members.iter().map(|&(j, _)| gives[j]).collect();
                }
                if let Some(zips) = &zips {
                    scene.zips = game.members.iter().map(|&(j, _)| zips[j]).collect();
                }
                scene.excess = excess_of(game.members.iter().map(|&(j, _)| &cars[j]));
                let mut nb = Vec::new();
                find_neighbors(&scene, &mut self.order, &mut nb);
                if self.sumo_holds_lane_changes() {
                    pass_beside_waiting(cars, game, &scene, &mut nb, self.rules.clearance());
                }
                scenes.push(scene);
                neighbors.push(nb);
                scene_cars.push(game.members.iter().map(|&(j, _)| j).collect::<Vec<_>>());
            }
            let si = scenes.len() - 1;
            let (scene, nb) = (&scenes[si], &neighbors[si]);
            let ego_car = &cars[game.ego_car()];
            if let Some(record) = self.egos.get_mut(&ego_car.id) {
                record
                    .stats
                    .update_vehicle(scene, game.ego, ego_car.accel, self.rules.dt);
                record
                    .speed_bands
                    .record(ego_car.x - self.rules.conflict_point(), ego_car.v);
            }
            if self.kind != ControllerKind::Sumo {
                for (m, &(j, slot)) in game.members.iter().enumerate() {
                    let drive = m == game.ego
                        || (self.kind == ControllerKind::Mpg && self.may_drive_player(&cars[j]));
                    if drive && claimed.insert(j) {
                        let start = obs.len();
                        obs.resize(start + dim, 0.0);
                        observe_as(layout, frame, scene, m, slot, &nb[m], &mut obs[start..]);
                        rows.push((si, m, j));
                    }
                }
            }
        }
        let Some(policy) = self.policy.as_mut().filter(|_| !rows.is_empty()) else {
            return Vec::new();
        };
        let mut raw = vec![0.0f32; rows.len()];
        policy.act(&obs, rows.len(), &mut raw);
        // Front to back in the sequential projection order: each leader bound reads a
        // controlled leader's settled speed (a SUMO-driven one keeps its current speed).
        let mut order: Vec<usize> = (0..rows.len()).collect();
        if self.rules.sequential() {
            order.sort_by(|&p, &q| cars[rows[q].2].x.total_cmp(&cars[rows[p].2].x));
        }
        let mut next_v: HashMap<usize, f64> = HashMap::new();
        // The scenes' vehicles a policy drives: projected too, for the shared order.
        let driven: HashSet<(usize, usize)> = rows.iter().map(|&(si, m, _)| (si, m)).collect();
        let mut applied = vec![(0, 0.0); rows.len()];
        for r in order {
            let ((si, m, j), a) = (rows[r], raw[r]);
            {
                let nb: &Neighbors = &neighbors[si][m];
                // A waiting ego outlives its players (fixed at pick-up): the merge gate looks at
                // the target lane as it is now, so a car that arrived later is not invisible.
                // (A traffic game holds every car already; its neighbours index its scene.)
                let lane_now;
                let (scene, i) = if m == 0 && cars[j].on_ramp && !self.traffic {
                    lane_now = ego_and_target_lane(cars, j, lane_width);
                    (&lane_now, 0)
                } else {
                    (&scenes[si], m)
                };
                let scene_leader = nb.lane_leader.map(|l| scene_cars[si][l]);
                let mut rules = self.rules_for(&cars[j], scene_leader.map(|l| &cars[l]));
                if self.stops_at_b_safe(cars, j) {
                    rules.gate.lane_end_brake = rules.gate.lane_end_brake.min(rules.gate.b_safe);
                }
                // A junction merge's ramp vehicle enters where it crosses the stop line, so the
                // stop line's rule holds it (`stop_line_bound`), not a lane change's.
                let junction_ramp = self.is_junction() && cars[j].on_ramp;
                let settled = Settled {
                    held: junction_ramp.then_some(false),
                    leader_next_v: scene_leader.and_then(|l| next_v.get(&l).copied()),
                    projected: Projected {
                        leader: nb.lane_leader.is_some_and(|l| driven.contains(&(si, l))),
                        follower: nb.lane_follower.is_some_and(|f| driven.contains(&(si, f))),
                    },
                };
                let mut a = applied_action_with(
                    &rules,
                    self.config.sim.feasibility,
                    scene,
                    i,
                    nb,
                    f64::from(a),
                    settled,
                );
                if self.config.sim.feasibility {
                    let bounds = [
                        if self.sumo_holds_lane_changes() || self.is_junction() {
                            ramp_leader_bound(cars, j, scene_leader, &rules)
                        } else {
                            None
                        },
                        self.lane_end_bound(&cars[j], &rules),
                    ];
                    if let Some(hi) = bounds.into_iter().flatten().reduce(f64::min) {
                        let v = cars[j].v;
                        a = clip_action(
                            &a.min(hi),
                            &v,
                            rules.max_accel,
                            rules.v_min,
                            rules.v_max,
                            rules.dt,
                        );
                    }
                }
                let car = &cars[j];
                if let Some(stop) = [
                    self.stop_line_bound(cars, j, &rules),
                    Self::signal_bound(car, &rules),
                    Self::stop_sign_bound(car, &rules),
                ]
                .into_iter()
                .flatten()
                .reduce(f64::min)
                {
                    a = clip_action(
                        &a.min(stop),
                        &car.v,
                        rules.max_accel,
                        rules.v_min,
                        rules.v_max,
                        rules.dt,
                    );
                }
                // Before the conflict point a ramp vehicle the scenes count in the target lane
                // (scene_entry) is still on the ramp for the merge gate, when it is on.
                if rules.merge_gate && self.config.sim.feasibility && car.is_waiting() && car.x < x_c {
                    let lane = ego_and_target_lane(cars, j, lane_width);
                    if gate_holds(&lane, 0, &rules.gate) {
                        a = a.min(stop_bound(&car.x, &car.v, &rules.gate));
                    }
                }
                if self.rules.sequential() {
                    next_v.insert(j, car.v + a * rules.dt);
                }
                if let Some((_, d)) = car.signal.filter(|&(state, d)| is_red(state) && d >= 0.0) {
                    self.red_ahead.insert(car.id.clone(), d);
                }
                if let Some(d) = car.stop_sign {
                    self.sign_ahead.insert(car.id.clone(), car.x + d);
                }
                applied[r] = (j, a);
            }
        }
        applied
    }

    /// Whether the stop the road's end holds ramp vehicle `cars[j]` to is planned at
    /// `sim.b_safe` (harder only when it must) rather than at `sim.lane_end_brake`: at a
    /// junction merge's stop line always, as at a stop sign or a red light. Braking at `g` from
    /// the last metres, an ego that ran at 20 m/s to 22 m before the line crossed SSM's
    /// severe TTC (1.17 s) to the players passing ahead of it, as SUMO extrapolates it into
    /// the junction (the zoo's `junction-v30-curved`, 30% controllable, demand 1.2, SUMO seed
    /// 1; with this, no ego of seeds 0-7 does). At an acceleration lane's end, and a lane
    /// drop's, only where [`Self::stop_brakes_sumos_follower_hard`]: there a gentler stop
    /// everywhere had the egos enter slower, closer to the target-lane car behind (on the zoo's
    /// `lanedrop-v25-l2`, ego only, 2-12% of the egos in an SSM conflict instead of 0-1%). Nor
    /// where the ramp's link crosses other lanes ([`LanePositions::crossing`]): slowed early by
    /// every car that came near the junction, egos needed ever longer to clear the lanes they
    /// cross and queued (SMARTS's `merge/3lane` form, every vehicle playing: 31 of 47 egos
    /// through in 600 s, 57 of 58 with the stop at `g`).
    fn stops_at_b_safe(&self, cars: &[Car], j: usize) -> bool {
        let p = &self.positions;
        let stop_line = self.is_junction() && !p.is_lane_drop() && p.crossing().is_empty();
        (stop_line && cars[j].on_ramp) || self.stop_brakes_sumos_follower_hard(cars, j)
    }

    /// Whether a stop at `sim.lane_end_brake` would ask one of SUMO's drivers behind ramp
    /// vehicle `cars[j]` on the ramp to brake harder than `sim.b_safe` (after
    /// `sim.reaction_time`) to stop behind it: the entry rule asks no more of a human follower
    /// when a vehicle enters. The zoo's `acc60-v30` (30% controllable, demand 1.2, SUMO seed
    /// 2): an ego held at the 60 m lane's end braked from 22.9 m/s to a stop at up to
    /// 9.6 m/s^2, and SUMO's driver 42 m behind it at 21 m/s came within a TTC of 1.35 s (the
    /// study's one severe conflict there; none with this). The training's world has no such
    /// drivers; behind a vehicle the policy drives, the projection keeps the gap.
    fn stop_brakes_sumos_follower_hard(&self, cars: &[Car], j: usize) -> bool {
        let car = &cars[j];
        let gate = &self.rules.gate;
        let tau = gate.reaction_time.unwrap_or(0.0);
        let ego_stop = car.v * car.v / (2.0 * gate.lane_end_brake);
        car.on_ramp
            && cars.iter().any(|c| {
                let room = car.x - c.x - self.rules.length + ego_stop - c.v * tau;
                c.on_ramp
                    && c.x < car.x
                    && !self.controlled.contains(&c.id)
                    && (room <= 0.0 || c.v * c.v / (2.0 * room) > gate.b_safe)
            })
    }

    /// The rules `car`'s action is applied under, `lane_leader` being its leader in the
    /// scene's lane: the world's, but where SUMO may hold lane changes back
    /// (`sumo_holds_lane_changes`) a ramp vehicle waiting past its scene entry
    /// ([`Car::is_waiting`]) keeps [`WAITING_MARGIN`] more to the target-lane vehicles around
    /// it, and a target-lane vehicle behind a waiting one keeps it too. Without the second
    /// half, a player that came within the clearance behind a waiting ego converged back to a
    /// bumper gap of `sim.safety_gap` only, below what SUMO needs for the lane change, and
    /// the two drove side by side to the acceleration lane's end (`i80_merge`, the game,
    /// demand 1.0, SUMO seed 2: 13% of the egos in an SSM conflict, 7% with it; section 0y
    /// of docs/experiments.md). With a time gap in the projection
    /// (`sim.time_headway`) there is no margin: the gap settles at `safety_gap + h v`, above
    /// SUMO's `minGap` at any speed but a crawl, and the margin only held the egos back
    /// (`i80_merge`, demand 1.2, no SUMO safe speed: ego only at 0.83-0.87 of SUMO's
    /// drivers' speed with it, 0.86-0.87 without; section 0g).
    fn rules_for(&self, car: &Car, lane_leader: Option<&Car>) -> WorldRules {
        let mut rules = self.rules;
        let near_waiting = self.waits(car) || lane_leader.is_some_and(|l| self.waits(l));
        if near_waiting && rules.time_headway == 0.0 {
            rules.gate.clearance += WAITING_MARGIN;
        }
        rules
    }

    /// The largest action that lets a ramp vehicle waiting for its lane change (past its
    /// scene entry, [`Car::is_waiting`]) stop at the acceleration lane's end braking at
    /// [`LANE_END_BRAKE`], but never more than `sim.b_safe` (none for other vehicles, when
    /// SUMO makes lane changes at once, or when the network's lane end is unknown).
    /// The internal world has no lane end (a ramp vehicle is in the target lane from x_c on);
    /// in SUMO a waiting ego that reached the end at speed was braked there by SUMO's safe
    /// speed at 4.5 m/s^2, and the ramp vehicle behind it closed in at a TTC below 3 s
    /// (`i80_merge`, the game, demand 1.2: most of the 16-22% of egos in an SSM conflict).
    /// Without SUMO's safe speed (speed mode 0) nothing brakes it there: an ego level with
    /// a target-lane car from `merge_from` on reached the end at 13 m/s, stood still at
    /// once, and changed lanes in front of a car closing at 19 m/s (`single_lane_merge`,
    /// demand 1.2). So the bound holds from the scene entry on, not from x_c on: a waiting
    /// vehicle slows as it nears the end and falls behind the car beside it, as SUMO's
    /// drivers do.
    fn lane_end_bound(&self, car: &Car, rules: &WorldRules) -> Option<f64> {
        let end = self.lane_end?;
        if !self.waits(car) {
            return None;
        }
        let mut stop = rules.gate;
        stop.conflict_point = end - 0.5 * rules.length;
        stop.brake = LANE_END_BRAKE;
        Some(stop_bound(&car.x, &car.v, &stop).max(-rules.gate.b_safe))
    }

    /// The largest action that stops `car`'s front at the stop line of a red light ahead
    /// ([`Car::signal`]: ramp metering, or the signal where two roads join), braking at
    /// `sim.b_safe` from where it must (harder only when it must: the action's own bound is
    /// `g`), or at the stop line of a yellow one it can still stop at that way; none at green,
    /// without a light, or past the stop line (it clears the junction). SUMO's speed mode holds
    /// its own vehicles and, with its red-light bit (on in cosim's default), the controlled
    /// ones too; this holds them whatever the speed mode. Braking at `g` from the last moment
    /// instead, an ego that met the yellow light 88 m before the line at 18 m/s was still
    /// 10 m before it when the light turned red, too close to stop (the zoo's
    /// `junction-v20-signal`, demand 1.2, speed mode 0).
    fn signal_bound(car: &Car, rules: &WorldRules) -> Option<f64> {
        let (state, dist) = car.signal.filter(|&(_, d)| d >= 0.0)?;
        let bound = Self::stop_ahead(car, dist, rules);
        match state {
            'y' | 'Y' => (bound >= -rules.gate.b_safe).then_some(bound),
            _ => is_red(state).then_some(bound),
        }
    }

    /// The largest action that stops `car`'s front `dist` metres ahead braking at `sim.b_safe`
    /// from where it must (harder only when it must).
    fn stop_ahead(car: &Car, dist: f64, rules: &WorldRules) -> f64 {
        let mut line = rules.gate;
        line.conflict_point = car.x + dist;
        line.brake = rules.gate.b_safe;
        stop_bound(&car.x, &car.v, &line)
    }

    /// The largest action that brings `car` to a standstill at the line of a stop sign it has
    /// not yet stood at ([`Car::stop_sign`]), braking at `sim.b_safe` as at a red light; none
    /// without one. From the standstill on the link is a minor one: at the ramp's end the entry
    /// rule decides ([`Controller::stop_line_bound`]). With speed mode 0 SUMO does not stop
    /// the vehicles it is told to drive: without this the egos ran `priority_stop` ramps at
    /// up to 20 m/s, and the players an `allway_stop`'s road.
    fn stop_sign_bound(car: &Car, rules: &WorldRules) -> Option<f64> {
        car.stop_sign.map(|dist| Self::stop_ahead(car, dist, rules))
    }

    /// A junction merge's entry rule at the stop line, for a ramp vehicle the policy drives
    /// (none elsewhere): it crosses the stop line only into a gap the merge gate's entry check
    /// finds safe ([`gate_holds`]: the new follower absorbs it braking at `sim.b_safe` at most,
    /// and it its new leader); until then the largest action is the one that still stops its
    /// front at the line ([`lane_end_bound`], as at an acceleration lane's end). SUMO's
    /// drivers wait at the line the same way: a minor link yields. Like the acceleration lane's change, this is the world's rule, not a
    /// shield: it applies with or without `--gate` and whatever SUMO's speed mode.
    /// Under the entry rule (`scenario.entry = "gap"`) the check is the entry rule's, a human
    /// follower's secure gap at the crossing, and it replaces the acceleration lane's check of
    /// a lane change now ([`crate::world::merge_gate::lane_end_holds`]): a vehicle 25 m before
    /// the line at 24 m/s whose lane change "now" turned unsafe was braked at `g` and crossed
    /// at 4.5 m/s in front of a car at 28 m/s (`junction-v30-curved` of the zoo, the game,
    /// demand 0.8, SUMO seed 2, speed mode 0: a collision). The crossing check lets a vehicle
    /// that can no longer stop at `g` go on: it crosses at its speed.
    fn stop_line_bound(&self, cars: &[Car], j: usize, rules: &WorldRules) -> Option<f64> {
        let car = &cars[j];
        if !self.is_junction() || !car.on_ramp {
            return None;
        }
        let mut line = rules.gate;
        line.conflict_point = self.lane_end? - 0.5 * rules.length;
        let lane = ego_and_target_lane(cars, j, self.config.scenario.lane_width);
        let holds = gate_holds(&lane, 0, &line) || self.crossing_holds(car, line.conflict_point);
        holds.then(|| lane_end_bound(&car.x, &car.v, &line))
    }

    /// Seconds until the first vehicle on a crossing lane that could no longer stop before the
    /// junction, braking at `sim.b_safe` after `sim.reaction_time` (the entry rule's human
    /// follower), reaches it at its speed: 0 for one already in it, infinite without one. SUMO's
    /// drivers with the right of way brake for a vehicle in the junction across their path.
    fn crossing_arrival(&self, sumo: &Sumo) -> Result<f64, SumoError> {
        let mut first = f64::INFINITY;
        let tau = self.rules.gate.reaction_time.unwrap_or(0.0);
        for lane in self.positions.crossing() {
            if lane
                .vias
                .iter()
                .any(|via| sumo.lane_vehicles(via).is_ok_and(|ids| !ids.is_empty()))
            {
                return Ok(0.0);
            }
            for id in sumo.lane_vehicles(&lane.lane)? {
                let s = sumo.vehicle(&id)?;
                let to_junction = (lane.length - s.lane_pos).max(0.0);
                if to_junction > s.speed * tau + s.speed * s.speed / (2.0 * self.rules.gate.b_safe) {
                    continue; // it can still stop before the junction, as the entry rule asks
                }
                first = first.min(to_junction / s.speed.max(HALTING_SPEED));
            }
        }
        Ok(first)
    }

    /// Whether a ramp vehicle whose centre's stop line is `line` must wait there for the
    /// vehicles of a crossing lane ([`LanePositions::crossing`]), as SUMO's drivers on its
    /// minor link do: one that could no longer stop for it reaches the junction before the
    /// vehicle, setting off at `sim.b_safe` from where it is, has crossed it, with SUMO's
    /// minor-link time gap ([`CROSSING_TIME_GAP`]) to spare. A vehicle that can no longer stop
    /// before the line at `g` goes on. The training's world has no crossing lanes: this is the
    /// road's rule, as a red light is. On a map whose ramp is linked across two lanes of its road (SMARTS's
    /// `merge/3lane`), egos that did not wait collided in the junction with vehicles on them.
    fn crossing_holds(&self, car: &Car, line: f64) -> bool {
        if self.crossing_arrival.is_infinite() {
            return false;
        }
        let to_line = line - car.x;
        let can_stop = car.v * car.v <= 2.0 * self.rules.max_accel * to_line.max(0.0);
        let across = to_line + self.positions.entry_length() + self.rules.length;
        let a = self.rules.gate.b_safe;
        let clear = ((car.v * car.v + 2.0 * a * across).sqrt() - car.v) / a;
        can_stop && self.crossing_arrival < clear + CROSSING_TIME_GAP
    }

    /// Whether the MPG policy drives this player. `"all"`: every player, wherever it is (the
    /// paper's game, as the internal simulator plays it). `"controllable"`: a player of a
    /// controllable type inside the control zone; past `release_after` beyond the conflict
    /// point it is SUMO's again, as a released ego is, and stays in the ego's observation. On
    /// `i80_merge`, merged egos became players of later egos, and the trained policy, driving
    /// them as leaders far downstream of a waiting ego (never seen in training), stopped one
    /// on an open road.
    /// With a traffic policy a player is driven inside the control zone only, either way: its
    /// game is the traffic around it, which training placed there.
    fn may_drive_player(&self, car: &Car) -> bool {
        let g = &self.geometry;
        let in_zone = car.x >= g.control_from && car.x < self.rules.conflict_point() + g.release_after;
        match g.players {
            PlayerControl::All if self.traffic => in_zone,
            PlayerControl::All => true,
            PlayerControl::Controllable => {
                (if self.traffic {
                    in_zone
                } else {
                    car.x < self.rules.conflict_point() + g.release_after
                }) && self
                    .types
                    .get(&car.id)
                    .is_some_and(|t| g.controllable_types.contains(t))
            }
        }
    }

    /// The egos seen, in id order.
    pub fn finish(self) -> Vec<EgoRecord> {
        self.egos.into_values().collect()
    }
}

/// Lets a target-lane vehicle pass a ramp vehicle waiting beside it: a ramp vehicle past its
/// scene entry that SUMO has not moved to the target lane yet is in the target lane of the
/// scene (`on_ramp` false), but a target-lane vehicle less than `clearance` (the feasibility
/// projection's: length plus `sim.safety_gap`) behind it is beside it, not behind it, so its
/// lane leader is the next one ahead. Taking the waiting vehicle as its leader it could only
/// fall back (its gap is below the clearance), and once stopped there it stays too close for
/// the lane change, beside a vehicle that cannot change lanes until it has passed: measured
/// on `i80_merge`, the game stood still with the threshold at 0 m; at a car length, pairs
/// stopped 5-7 m apart at the lane's end and queues formed behind them (the game, demand
/// 1.2, SUMO seed 1: 192 of 215 egos finished at 0.60 of SUMO's drivers' speed).
fn pass_beside_waiting(cars: &[Car], game: &Game, scene: &Scene, nb: &mut [Neighbors], clearance: f64) {
    for m in 0..scene.len() {
        let Some(l) = nb[m].lane_leader else {
            continue;
        };
        let (me, leader) = (&cars[game.members[m].0], &cars[game.members[l].0]);
        if leader.is_waiting()
            && me.ramp_lane.is_none()
            && scene.vehicles[l].x - scene.vehicles[m].x < clearance + scene.excess(l) + scene.excess(m)
        {
            nb[m].lane_leader = nb[l].lane_leader;
        }
    }
}

/// Which of `cars` give way to every vehicle approaching on the target lane
/// ([`Scene::gives_way`]) on a priority junction's ramp (its minor road,
/// [`LanePositions::minor_entry`]): SUMO's own drivers (past
/// `control_from` and not `is_ego`: a controllable ramp vehicle is an ego from there on), who
/// cross the stop line by SUMO's right of way, which yields to every approaching foe, and every
/// ramp vehicle queued behind one of them on its lane. Players made room for them as
/// training's drivers would take it, and stood: the zoo's `junction-v20`, demand 1.2, 30% of
/// the vehicles playing, lost 4.1 times the time SUMO's drivers lose (docs/experiments.md).
fn gives_way(cars: &[Car], control_from: f64, is_ego: impl Fn(&str) -> bool) -> Vec<bool> {
    let sumo_driven = |c: &Car| c.on_ramp && c.x >= control_from && !is_ego(&c.id);
    cars.iter()
        .map(|c| {
            c.on_ramp
                && cars
                    .iter()
                    .any(|h| sumo_driven(h) && h.ramp_lane == c.ramp_lane && h.x >= c.x)
        })
        .collect()
}

/// Which of `cars` take their turn at a zipper junction ([`Scene::zips`],
/// [`LanePositions::zipper_entry`]): SUMO's own ramp drivers (not `is_ego`) with no ego ahead
/// of them on the ramp, who go when they reach the junction first. A player the policy drives
/// does not merge by SUMO's zipper rule: with two ramps joining a 30 m/s road at zipper nodes
/// (netconvert's `type="zipper"`) and 30% of the vehicles playing, one drove on beside SUMO's
/// driver ahead of it and they collided in the junction. Ramp vehicles queued behind an ego
/// wait for it, which enters by the entry rule.
fn zips(cars: &[Car], is_ego: impl Fn(&str) -> bool) -> Vec<bool> {
    cars.iter()
        .map(|c| c.on_ramp && !is_ego(&c.id) && !cars.iter().any(|h| h.on_ramp && h.x > c.x && is_ego(&h.id)))
        .collect()
}

/// The feasibility projection's upper bound (TTC >= tau_s, `rules`' clearance) of ramp-lane
/// vehicle `j` towards the vehicle physically ahead of it on the ramp lanes or on its route
/// (its SUMO leader), when that is not already its leader in the scene (`scene_leader`). A
/// ramp vehicle past its scene entry is in the scene's target lane, so the ramp vehicle behind
/// it no longer had it as a leader, nor did a waiting one that had a target-lane car between
/// them in the scene; both closed in on it until SUMO's safe speed braked them. Without that
/// shield, a ramp vehicle that SUMO moved to the target lane at the gore, its rear still on
/// the junction, was run into by the one behind (zoo `acc60-v36`, speed mode 0). The
/// observation stays the scene's.
fn ramp_leader_bound(cars: &[Car], j: usize, scene_leader: Option<usize>, rules: &WorldRules) -> Option<f64> {
    let me = &cars[j];
    me.ramp_lane.as_ref()?;
    let ahead_on_path =
        |k: usize| cars[k].ramp_lane.is_some() || me.path_leader.as_ref() == Some(&cars[k].id);
    let k = (0..cars.len())
        .filter(|&k| k != j && ahead_on_path(k) && cars[k].x > me.x)
        .min_by(|&a, &b| cars[a].x.total_cmp(&cars[b].x))
        .filter(|&k| Some(k) != scene_leader)?;
    let leader = Neighbor {
        x: cars[k].x - me.excess - cars[k].excess,
        v: cars[k].v,
        present: 1.0,
    };
    let none = Neighbor {
        x: me.x,
        v: me.v,
        present: 0.0,
    };
    let (_, hi) = feasible_interval(&me.x, &me.v, &leader, &none, &rules.projection());
    Some(hi)
}

/// Ramp vehicle `j` (first, on the ramp) and every other vehicle in the scene's target lane,
/// as the merge gate sees them.
fn ego_and_target_lane(cars: &[Car], j: usize, lane_width: f64) -> Scene {
    let mut me = cars[j].vehicle(lane_width);
    me.on_ramp = true;
    me.y = -lane_width;
    let lane = || (cars.iter().enumerate()).filter(|&(k, c)| k != j && !c.on_ramp);
    Scene {
        excess: excess_of(std::iter::once(&cars[j]).chain(lane().map(|(_, c)| c))),
        ..Scene::new(
            std::iter::once(me)
                .chain(lane().map(|(_, c)| c.vehicle(lane_width)))
                .collect(),
        )
    }
}

/// [`Scene::excess`] of `cars` in scene order: empty where all are the world's car length.
fn excess_of<'a>(cars: impl Iterator<Item = &'a Car>) -> Vec<f64> {
    let excess: Vec<f64> = cars.map(|c| c.excess).collect();
    if excess.iter().all(|&e| e == 0.0) {
        Vec::new()
    } else {
        excess
    }
}

/// One ego's game: `(index into cars, player slot)` of its members, and which member is the
/// ego (the first, slot 0, in a Table I game; a traffic game holds every car in order).
#[derive(Debug, Clone)]
struct Game {
    members: Vec<(usize, usize)>,
    ego: usize,
}

impl Game {
    /// The ego's index into `cars`.
    fn ego_car(&self) -> usize {
        self.members[self.ego].0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::network::PolicyNet;
    use crate::world::merge_gate::{GateRules, entry_is_safe};
    use crate::world::step::applied_action;

    /// A ramp vehicle past its scene entry that SUMO has not moved yet: in the scene's target
    /// lane, on the acceleration lane in SUMO.
    fn waiting_car(id: &str, x: f64, v: f64) -> Car {
        Car {
            ramp_lane: Some("merge_0".to_owned()),
            ..car(id, x, v, false)
        }
    }

    fn car(id: &str, x: f64, v: f64, on_ramp: bool) -> Car {
        Car {
            id: id.to_owned(),
            x,
            v,
            accel: 0.0,
            on_ramp,
            ramp_lane: on_ramp.then(|| "merge_0".to_owned()),
            path_leader: None,
            signal: None,
            held_at_red: false,
            stop_sign: None,
            speed_limit: None,
            excess: 0.0,
        }
    }

    #[test]
    fn on_a_junction_ramp_sumos_drivers_and_the_vehicles_queued_behind_them_give_way() {
        // Ramp lane merge_0: SUMO's driver h at the stop line, ego e1 behind it; ego e2 heads
        // lane merge_1 with SUMO's driver h2 behind it; a target-lane car t.
        let on = |id: &str, x: f64, lane: &str| Car {
            ramp_lane: Some(lane.to_owned()),
            ..car(id, x, 0.0, true)
        };
        let cars = [
            on("h", 178.0, "merge_0"),
            on("e1", 170.0, "merge_0"),
            on("e2", 175.0, "merge_1"),
            on("h2", 160.0, "merge_1"),
            car("t", 150.0, 20.0, false),
        ];
        let ego = |id: &str| id.starts_with('e');
        assert_eq!(gives_way(&cars, 60.0, ego), [true, true, false, true, false]);
        // Once SUMO's driver has crossed, the ego at the head of the queue takes room.
        assert_eq!(gives_way(&cars[1..], 60.0, ego), [false, false, true, false]);
        // Before control_from a ramp vehicle is no ego yet, whoever drives it.
        assert_eq!(gives_way(&cars, 165.0, ego), [true, true, false, false, false]);
    }

    #[test]
    fn at_a_zipper_sumos_drivers_with_no_ego_ahead_of_them_take_their_turn() {
        // SUMO's driver h1 heads the ramp, ego e1 behind it, SUMO's driver h2 behind the ego; a
        // target-lane car t.
        let cars = [
            car("h1", 178.0, 10.0, true),
            car("e1", 170.0, 10.0, true),
            car("h2", 160.0, 10.0, true),
            car("t", 175.0, 20.0, false),
        ];
        let ego = |id: &str| id.starts_with('e');
        assert_eq!(zips(&cars, ego), [true, false, false, false]);
        // Once the ego has entered (no longer on the ramp), the driver behind it takes its turn.
        let entered = [cars[0].clone(), car("e1", 172.0, 10.0, false), cars[2].clone()];
        assert_eq!(zips(&entered, ego), [true, false, true]);
    }

    #[test]
    fn a_red_light_ahead_holds_a_car_at_its_stop_line_and_a_late_yellow_does_not() {
        let rules = WorldRules::new(
            &Config::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/traffic.toml"))
                .unwrap(),
        );
        let at_light = |state: char, dist: f64| Car {
            signal: Some((state, dist)),
            ..car("c", 100.0, 10.0, true)
        };
        // 30 m before the line at 10 m/s: the largest action that still stops its front there
        // braking at b_safe.
        let mut line = rules.gate;
        (line.conflict_point, line.brake) = (130.0, rules.gate.b_safe);
        let stop = stop_bound(&100.0, &10.0, &line);
        // 10 m/s stops in 12.5 m at 4 m/s^2: 30 m ahead it may still accelerate, 13 m ahead it
        // must brake (this step's 1 m and the stop margin leave 11.9 m), within g.
        assert!(stop > 0.0, "{stop}");
        let near = Controller::signal_bound(&at_light('r', 13.0), &rules).unwrap();
        assert!(near < 0.0 && near > -rules.max_accel, "{near}");
        assert_eq!(Controller::signal_bound(&at_light('r', 30.0), &rules), Some(stop));
        assert_eq!(Controller::signal_bound(&at_light('y', 30.0), &rules), Some(stop));
        // Green, or no light: nothing.
        assert_eq!(Controller::signal_bound(&at_light('G', 30.0), &rules), None);
        assert_eq!(
            Controller::signal_bound(&car("c", 100.0, 10.0, true), &rules),
            None
        );
        // 1 m before the line at 10 m/s: stopping needs far more than b_safe; at yellow it goes
        // on, at red it brakes as hard as it may.
        let late = Controller::signal_bound(&at_light('r', 1.0), &rules).unwrap();
        assert!(late < -rules.gate.b_safe, "{late}");
        assert_eq!(Controller::signal_bound(&at_light('y', 1.0), &rules), None);
        // Past the stop line (SUMO's negative distance) it clears the junction at red too.
        assert_eq!(Controller::signal_bound(&at_light('r', -2.0), &rules), None);
    }

    #[test]
    fn a_stop_sign_ahead_brings_a_car_to_a_standstill_at_its_line_braking_at_b_safe() {
        let rules = WorldRules::new(
            &Config::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/traffic.toml"))
                .unwrap(),
        );
        let before_sign = |dist: f64| Car {
            stop_sign: Some(dist),
            ..car("c", 100.0, 10.0, true)
        };
        // 15 m before the line at 10 m/s, b_safe 4, dt 0.1: after this step's 1 m and the stop
        // margin 13.9 m are left, where it may reach v' = -0.4 + sqrt(0.16 + 8 * 13.9) =
        // 10.1527 m/s, so a <= 1.527 m/s^2.
        let bound = Controller::stop_sign_bound(&before_sign(15.0), &rules).unwrap();
        assert!((bound - 1.5272).abs() < 1e-3, "{bound}");
        // 8 m before it, it must brake harder than b_safe: it does (the action's own bound is g).
        assert!(Controller::stop_sign_bound(&before_sign(8.0), &rules).unwrap() < -rules.gate.b_safe);
        // Without a sign ahead, or once it has stood at the line (`Car::stop_sign` is then none),
        // nothing.
        assert_eq!(
            Controller::stop_sign_bound(&car("c", 100.0, 10.0, true), &rules),
            None
        );
    }

    #[test]
    fn the_gate_sees_target_lane_cars_that_are_not_players() {
        // A stopped ego past its players: the car closing in at 10 m/s 9 m behind it arrived
        // after pick-up, so it is in no game, but the gate must see it (and not the ramp car).
        let cars = [
            car("ramp.1", 179.9, 0.0, true),
            car("ramp.2", 170.0, 0.0, true),
            car("lane.9", 171.0, 10.0, false),
        ];
        let scene = ego_and_target_lane(&cars, 0, 3.66);
        let xs: Vec<(f64, bool)> = scene.vehicles.iter().map(|v| (v.x, v.on_ramp)).collect();
        assert_eq!(xs, vec![(179.9, true), (171.0, false)]);
        let rules = GateRules {
            conflict_point: 180.0,
            clearance: 7.0,
            b_safe: 4.0,
            horizon: 3.0,
            brake: 9.81,
            lane_end_brake: 9.81,
            dt: 0.1,
            reaction_time: None,
        };
        assert!(!entry_is_safe(&scene, 0, &rules));
    }

    #[test]
    fn a_stop_at_g_brakes_sumos_driver_behind_too_hard_when_it_asks_more_than_b_safe() {
        // The paper's world: 5 m cars, no reaction time, the lane's end stop at g = 9.81 and
        // b_safe = 4. An ego at 15 m/s stops at g within 225 / 19.62 = 11.47 m.
        let mut c = paper_controller();
        let hard = |c: &Controller, behind: Car| {
            c.stop_brakes_sumos_follower_hard(&[car("e", 100.0, 15.0, true), behind], 0)
        };
        // At 15 m/s with a 10 m bumper gap the follower has 21.47 m: 225 / 42.94 = 5.24 > 4;
        // with 15 m, 4.25; with 20 m, 3.57; at 10 m/s 25 m back, 1.37.
        assert!(hard(&c, car("h", 85.0, 15.0, true)));
        assert!(hard(&c, car("h", 80.0, 15.0, true)));
        assert!(!hard(&c, car("h", 75.0, 15.0, true)));
        assert!(!hard(&c, car("h", 70.0, 10.0, true)));
        assert!(!hard(&c, car("h", 90.0, 0.0, true)));
        // Not a target-lane car, nor one ahead, nor a vehicle it drives.
        assert!(!hard(&c, car("h", 85.0, 15.0, false)));
        assert!(!hard(&c, car("h", 110.0, 15.0, true)));
        c.controlled.insert("h".into());
        assert!(!hard(&c, car("h", 85.0, 15.0, true)));
    }

    #[test]
    fn a_ramp_vehicle_waits_for_a_crossing_lane_unless_it_can_no_longer_stop() {
        // No junction lane (entry length 0), a 5 m car setting off at b_safe = 4 m/s^2.
        let mut c = paper_controller();
        let line = 100.0;
        let mut holds = |arrival: f64, x: f64, v: f64| {
            c.crossing_arrival = arrival;
            c.crossing_holds(&car("e", x, v, true), line)
        };
        // Standing 3 m before the line: across the junction (3 + 5 m) in sqrt(2 * 8 / 4) = 2 s,
        // plus SUMO's 1 s time gap.
        assert!(holds(2.9, line - 3.0, 0.0));
        assert!(!holds(3.1, line - 3.0, 0.0));
        // At 10 m/s 10 m before it: (sqrt(100 + 2 * 4 * 15) - 10) / 4 = 1.21 s, plus 1 s.
        assert!(holds(2.1, line - 10.0, 10.0));
        assert!(!holds(2.3, line - 10.0, 10.0));
        // 4 m before it at 10 m/s no car stops at g (10^2 > 2 * 9.81 * 4): it goes on.
        assert!(!holds(0.0, line - 4.0, 10.0));
        assert!(!holds(f64::INFINITY, line - 3.0, 0.0));
    }

    /// An `mpg` controller with the paper's configuration on a one-lane merge at 180 m.
    fn paper_controller() -> Controller {
        let config =
            Config::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper.toml"))
                .unwrap();
        let geometry = MergeGeometry {
            name: None,
            conflict_point: 180.0,
            control_from: 60.0,
            release_after: 50.0,
            ramp_lanes: vec!["merge_0".into()],
            target_lanes: vec!["merge_1".into()],
            target_start: 0.0,
            merge_from: None,
            desired_speed: None,
            controllable_types: vec!["ctrl".into()],
            players: PlayerControl::All,
        };
        Controller::new(
            config,
            geometry,
            LanePositions::default(),
            ControllerKind::Mpg,
            None,
            ControlModes::SAFE,
        )
    }

    #[test]
    fn a_driven_car_keeps_to_its_lanes_speed_limit_and_slows_to_a_lower_one_at_b_safe() {
        let c = paper_controller();
        let (dt, b_safe) = (c.rules.dt, c.rules.gate.b_safe);
        let on = |v: f64, limit: Option<f64>| Car {
            speed_limit: limit,
            ..car("e", 100.0, v, true)
        };
        // 0.5 m/s below a 20 m/s limit: at most what reaches it in one step.
        assert!((c.within_speed_limit(&on(19.5, Some(20.0)), 9.0) - 0.5 / dt).abs() < 1e-9);
        // At the limit: no speeding up; braking stays the policy's.
        assert_eq!(c.within_speed_limit(&on(20.0, Some(20.0)), 2.0), 0.0);
        assert_eq!(c.within_speed_limit(&on(20.0, Some(20.0)), -3.0), -3.0);
        // Above a lower limit (a slower lane entered): towards it at b_safe, not at once.
        assert_eq!(c.within_speed_limit(&on(28.0, Some(20.0)), 1.0), -b_safe);
        assert_eq!(
            c.within_speed_limit(&on(20.1, Some(20.0)), 1.0),
            (20.0 - 20.1) / dt
        );
        // A lane without a limit in the network: the policy's action.
        assert_eq!(c.within_speed_limit(&on(50.0, None), 1.0), 1.0);
    }

    #[test]
    fn an_ego_is_released_only_once_it_is_on_the_target_lane() {
        let mut c = paper_controller();
        c.geometry.release_after = 0.0;
        // Past x_c still on the acceleration lane: the scene counts it in the target lane
        // (on_ramp false), SUMO does not.
        let waiting = waiting_car("ramp.1", 185.0, 10.0);
        assert_eq!(c.merge_progress(&waiting), (false, false));
        assert_eq!(c.merge_progress(&car("ramp.1", 185.0, 10.0, false)), (true, true));
        assert_eq!(
            c.merge_progress(&car("ramp.1", 175.0, 10.0, false)),
            (true, false)
        );
        assert_eq!(
            c.merge_progress(&car("ramp.1", 175.0, 10.0, true)),
            (false, false)
        );
    }

    #[test]
    fn a_car_beside_a_waiting_ramp_vehicle_passes_it() {
        // Ramp vehicle W past x_c, still on the acceleration lane (in the scene's target lane);
        // target-lane cars B 6 m behind it (beside it: inside the 7 m clearance of 5 m cars
        // with a 2 m safety gap), F 9 m behind it, and A ahead.
        let w = waiting_car("W", 190.0, 0.0);
        let cars = [
            w,
            car("B", 184.0, 10.0, false),
            car("F", 181.0, 10.0, false),
            car("A", 230.0, 10.0, false),
        ];
        let game = Game {
            members: (0..cars.len()).map(|j| (j, 0)).collect(),
            ego: 0,
        };
        let scene = Scene::new(cars.iter().map(|c| c.vehicle(3.66)).collect());
        let mut nb = Vec::new();
        find_neighbors(&scene, &mut Vec::new(), &mut nb);
        assert_eq!(nb[1].lane_leader, Some(0));
        pass_beside_waiting(&cars, &game, &scene, &mut nb, 7.0);
        // B passes W (its leader is A); F, behind W by more than the clearance, follows B; W's own
        // neighbours stay.
        assert_eq!(nb[1].lane_leader, Some(3));
        assert_eq!(nb[2].lane_leader, Some(1));
        assert_eq!((nb[0].lane_leader, nb[0].lane_follower), (Some(3), Some(1)));
        // Once W is on the target lane (SUMO moved it), B follows it again.
        let mut merged = cars.clone();
        merged[0].ramp_lane = None;
        find_neighbors(&scene, &mut Vec::new(), &mut nb);
        pass_beside_waiting(&merged, &game, &scene, &mut nb, 7.0);
        assert_eq!(nb[1].lane_leader, Some(0));
    }

    #[test]
    fn a_waiting_ego_keeps_a_margin_to_the_target_lane() {
        // Paper setting: 5 m cars, 2 m safety gap, tau_s = 3 s, dt = 0.1 s. A waiting ego 7 m
        // (centre to centre) behind a target-lane car at its own 10 m/s is at its clearance:
        // merged, it may keep its speed (a = 0 is feasible); waiting, its clearance is 9 m,
        // so it must fall back: v' <= 10 + (7 - 9) / 3, a <= -6.67 m/s^2. Both clearances
        // also hold SUMO's step, r = g dt^2: a falls by r / (tau_s dt) more.
        let c = paper_controller();
        let r = sumo_step_reach(&c.config) / 0.3;
        let waiting = waiting_car("ego", 180.0, 10.0);
        let merged = car("ego", 180.0, 10.0, false);
        let scene = Scene::new(vec![
            merged.vehicle(3.66),
            car("lead", 187.0, 10.0, false).vehicle(3.66),
        ]);
        let mut nb = Vec::new();
        find_neighbors(&scene, &mut Vec::new(), &mut nb);
        let act = |car: &Car| applied_action(&c.rules_for(car, None), true, &scene, 0, &nb[0], 0.0);
        assert!((act(&merged) + r).abs() < 1e-9, "{}", act(&merged));
        assert!((act(&waiting) + 20.0 / 3.0 + r).abs() < 1e-9, "{}", act(&waiting));
        // With a 1 s time gap the projection asks the gap itself and there is no margin: the
        // leader 15 m ahead, v' <= (10 + (15 - 7) / 3) / (1 + 1 / 3) = 9.5, a <= -5 m/s^2,
        // waiting or merged (with the margin, (10 + 6 / 3) / (4 / 3) = 9: -10).
        let mut c = c;
        c.rules.time_headway = 1.0;
        let scene = Scene::new(vec![
            merged.vehicle(3.66),
            car("lead", 195.0, 10.0, false).vehicle(3.66),
        ]);
        let act = |car: &Car| applied_action(&c.rules_for(car, None), true, &scene, 0, &nb[0], 0.0);
        // (SUMO's step: (4/3)^-1 r more.)
        assert!((act(&merged) + 5.0 + 0.75 * r).abs() < 1e-9, "{}", act(&merged));
        assert!((act(&waiting) + 5.0 + 0.75 * r).abs() < 1e-9, "{}", act(&waiting));
    }

    #[test]
    fn a_car_behind_a_waiting_ego_keeps_the_margin_too() {
        // Paper setting (7 m clearance, tau_s = 3 s, dt = 0.1 s). Target-lane car F 8 m
        // (centre to centre) behind W, both at 10 m/s. Behind a merged W it may keep its
        // speed (v' <= 10 + (8 - 7) / 3); behind a waiting W its clearance is 9 m, so
        // v' <= 10 + (8 - 9) / 3: a <= -10/3 m/s^2, and SUMO's step r = g dt^2 on top of
        // either clearance, r / (tau_s dt) more.
        let c = paper_controller();
        let r = sumo_step_reach(&c.config) / 0.3;
        let merged = car("W", 190.0, 10.0, false);
        let waiting = waiting_car("W", 190.0, 10.0);
        let follower = car("F", 182.0, 10.0, false);
        let scene = Scene::new(vec![follower.vehicle(3.66), merged.vehicle(3.66)]);
        let mut nb = Vec::new();
        find_neighbors(&scene, &mut Vec::new(), &mut nb);
        assert_eq!(nb[0].lane_leader, Some(1));
        let act = |leader: &Car| {
            applied_action(
                &c.rules_for(&follower, Some(leader)),
                true,
                &scene,
                0,
                &nb[0],
                0.0,
            )
        };
        assert!(act(&merged).abs() < 1e-9, "{}", act(&merged));
        assert!((act(&waiting) + 10.0 / 3.0 + r).abs() < 1e-9, "{}", act(&waiting));
    }

    #[test]
    fn a_ramp_vehicle_keeps_its_ttc_to_the_waiting_vehicle_ahead_on_its_lane() {
        // W waits at 190 m, stopped, on the acceleration lane (in the scene's target lane);
        // ramp vehicle R at 170 m and 10 m/s; a second waiting vehicle farther ahead and a
        // target-lane car in between do not count. One step on, the bumper gap less the
        // 2 m safety gap is 190 - 171 - 7 = 12 m, so v' <= 0 + 12 / 3 = 4: a <= -60 m/s^2
        // (before the clip to -g), and r / (tau_s dt) more for SUMO's step r = g dt^2.
        let c = paper_controller();
        let r = sumo_step_reach(&c.config) / 0.3;
        let w = waiting_car("W", 190.0, 0.0);
        let mut far = w.clone();
        far.x = 200.0;
        let cars = [car("R", 170.0, 10.0, true), far, car("T", 180.0, 10.0, false), w];
        let rules = c.rules_for(&cars[0], None);
        let hi = ramp_leader_bound(&cars, 0, None, &rules).expect("a ramp leader");
        assert!((hi + 60.0 + r).abs() < 1e-9, "{hi}");
        // Already its leader in the scene: the projection has it; a target-lane car: none.
        assert_eq!(ramp_leader_bound(&cars, 0, Some(3), &rules), None);
        assert_eq!(ramp_leader_bound(&cars, 2, None, &rules), None);
    }

    #[test]
    fn a_ramp_vehicle_keeps_its_ttc_to_its_sumo_leader_that_left_the_ramp_lanes() {
        // SUMO moved L to the target lane at the gore (centre 500.6 m, 0.6 m/s), its rear
        // still on the junction in R's path: SUMO reports it as R's leader. R at 493.3 m and
        // 11 m/s: one step on, 500.66 - 494.4 - 7 = -0.74 m, v' <= 0.6 - 0.74 / 3, a <= -106.5
        // m/s^2 less SUMO's step reach. Not its SUMO leader, a target-lane car does not count.
        let c = paper_controller();
        let r = sumo_step_reach(&c.config) / 0.3;
        let mut ramp = car("R", 493.3, 11.0, true);
        let cars = [ramp.clone(), car("L", 500.6, 0.6, false)];
        let rules = c.rules_for(&cars[0], None);
        assert_eq!(ramp_leader_bound(&cars, 0, None, &rules), None);
        ramp.path_leader = Some("L".to_owned());
        let cars = [ramp, cars[1].clone()];
        let hi = ramp_leader_bound(&cars, 0, None, &rules).expect("its SUMO leader");
        let expected = (0.6 - 0.74 / 3.0 - 11.0) / 0.1 - r;
        assert!((hi - expected).abs() < 1e-9, "{hi} against {expected}");
    }

    #[test]
    fn a_waiting_ego_prepares_to_stop_at_the_lane_end() {
        // Lane end at 222 m: a 5 m car's centre stops at 219.5 m less the gate's 0.1 m margin.
        // At 193 m and 10 m/s, one step on 25.4 m remain: v' = sqrt(2 * 2 * 25.4 + 0.2^2) - 0.2
        // = 9.8817, a = -1.1833 m/s^2. At 195 m the bound asks -5.23, floored at b_safe's -4.
        let mut c = paper_controller();
        c.lane_end = Some(222.0);
        let waiting = |x: f64| waiting_car("W", x, 10.0);
        let bound = |c: &Controller, w: &Car| c.lane_end_bound(w, &c.rules_for(w, None));
        let a = bound(&c, &waiting(193.0)).unwrap();
        assert!((a + 1.183_334_7).abs() < 1e-6, "{a}");
        assert_eq!(bound(&c, &waiting(195.0)), Some(-4.0));
        // Before x_c but waiting (a traffic policy's scene entry at merge_from): at 150 m and
        // 10 m/s, 69.4 m remain, more than the 25 m a stop at 2 m/s^2 needs: the bound is
        // above the largest action. At 170 m and 13.8 m/s it binds: one step on 48.02 m
        // remain, v' = sqrt(4 * 48.02 + 0.04) - 0.2 = 13.6607, a = -1.3926 m/s^2.
        assert!(bound(&c, &waiting(150.0)).unwrap() > c.rules.max_accel);
        let a = bound(&c, &waiting_car("W", 170.0, 13.8)).unwrap();
        assert!((a + 1.392_640_9).abs() < 1e-6, "{a}");
        // Merged, or with no known lane end: none.
        assert_eq!(bound(&c, &car("W", 193.0, 10.0, false)), None);
        c.lane_end = None;
        assert_eq!(bound(&c, &waiting(193.0)), None);
        // In exact modes nothing waits (SUMO makes the lane change at once): no bound.
        c.lane_end = Some(222.0);
        c.modes = ControlModes::EXACT;
        assert_eq!(bound(&c, &waiting(193.0)), None);
    }

    #[test]
    fn players_are_picked_within_the_reach_of_training_initial_states() {
        // Paper setting: 4 leaders and 4 followers, headways up to 30 m, so players are picked
        // at most 120 m ahead of or behind the ego (at 100 m here).
        let c = paper_controller();
        let mut cars = vec![car("ego", 100.0, 10.0, true), car("ramp.2", 80.0, 10.0, true)];
        for (id, x) in [
            ("a230", 230.0),
            ("a220", 220.0),
            ("a150", 150.0),
            ("a110", 110.0),
            ("b90", 90.0),
            ("b40", 40.0),
            ("b-20", -20.0),
            ("b-21", -21.0),
        ] {
            cars.push(car(id, x, 12.0, false));
        }
        let players = c.nearest_players(&cars, 0);
        let expected: Vec<(String, usize)> = [
            ("a220", 2),
            ("a150", 3),
            ("a110", 4),
            ("b90", 5),
            ("b40", 6),
            ("b-20", 7),
        ]
        .iter()
        .map(|&(id, slot)| (id.to_owned(), slot))
        .collect();
        assert_eq!(players, expected);
    }

    #[test]
    fn the_merge_gate_holds_egos_at_the_networks_conflict_point() {
        // Regression: the gate read configs/paper.toml's 180 m while merge.toml put the
        // conflict point elsewhere. Here x_c = 300 m: an ego at 293 m and 10 m/s, beside a
        // target-lane car, at the last step from which it can still stop before 300 m, must be
        // held, though it is past 180 m (where it would count as committed and go on at +g).
        let c = paper_controller();
        let mut config = c.config.clone();
        config.sim.merge_gate = true;
        let mut c = Controller::new(
            config,
            MergeGeometry {
                name: None,
                conflict_point: 300.0,
                ..c.geometry.clone()
            },
            LanePositions::default(),
            ControllerKind::Mpg,
            Some(full_throttle(&c.config).into()),
            ControlModes::SAFE,
        );
        let cars = [car("ego", 293.0, 10.0, true), car("lane.1", 288.0, 12.0, false)];
        let game = Game {
            members: vec![(0, 0), (1, 5)],
            ego: 0,
        };
        let commands = c.decide(&cars, &[game]);
        let ego = commands.iter().find(|(j, _)| *j == 0).unwrap().1;
        // The stop bound: after this step (1 m) 5.9 m remain to 299.9 m, enough to stop from
        // sqrt(2 g 5.9 + (g dt)^2) - g dt = 9.823 m/s, so a = (9.823 - 10) / 0.1 = -1.77.
        assert!((ego + 1.77).abs() < 0.01, "ego held at 300 m: {ego}");
        // The car beside it (a player, driven by the policy) only gets its projection.
        let lane = commands.iter().find(|(j, _)| *j == 1).unwrap().1;
        assert!(lane > 0.0, "{lane}");
        // A traffic policy counts the ego in the target lane from merge_from (here 250 m) on;
        // the gate still holds it before x_c.
        c.traffic = true;
        c.geometry.merge_from = Some(250.0);
        let ego = waiting_car("ego", 293.0, 10.0);
        let cars = [ego, car("lane.1", 288.0, 12.0, false)];
        let game = Game {
            members: vec![(0, 0), (1, 0)],
            ego: 0,
        };
        let commands = c.decide(&cars, &[game]);
        let ego = commands.iter().find(|(j, _)| *j == 0).unwrap().1;
        assert!((ego + 1.77).abs() < 0.01, "waiting ego held at 300 m: {ego}");
    }

    /// A policy whose every action is +g (all weights 0, output bias large).
    fn full_throttle(config: &Config) -> PolicyNet {
        let net = PolicyNet::new(crate::policy::network::NetSpec::new(
            Layout::of(config),
            config.train.hidden,
            config.vehicle.max_accel,
        ));
        tch::no_grad(|| {
            for (name, mut var) in net.vs.variables() {
                let value = if name == "output.bias" { 20.0 } else { 0.0 };
                let _ = var.fill_(value);
            }
        });
        net
    }

    #[test]
    fn under_the_entry_rule_nothing_forces_an_entry_and_the_lane_end_holds_the_ego() {
        let mut config =
            Config::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper.toml"))
                .unwrap();
        config.scenario.entry = Entry::Gap;
        let mut c = paper_controller();
        c.config = config.clone();
        c.rules = WorldRules::new(&config);
        c.geometry.merge_from = Some(138.0);
        // At x_c beside a car: no entry (the paper's controller would send it now).
        let beside = [car("ego", 180.0, 12.0, true), car("lane", 181.0, 12.0, false)];
        assert!(!c.merges_now(&beside, 0));
        // Alone, from merge_from on: now.
        assert!(c.merges_now(&[car("ego", 140.0, 12.0, true)], 0));
        // A follower 40 m behind at 20 m/s: MOBIL's check passes (one step on the gap is
        // 141.2 - 102 - 7 = 32.2 m, closing 8 m/s: TTC 4 s, 8^2 <= 8 * 32.2), but a human's
        // secure gap is 20 + (400 - 144) / 8 = 52 m: not now; 60 m behind (52.2 m): now.
        let follower = |behind: f64| {
            [
                car("ego", 140.0, 12.0, true),
                car("lane", 140.0 - behind, 20.0, false),
            ]
        };
        assert!(!c.merges_now(&follower(40.0), 0));
        assert!(c.merges_now(&follower(60.0), 0));
    }

    #[test]
    fn players_make_room_from_where_the_egos_may_enter() {
        // single_lane_merge: merge.toml's x_c 180 m, merge_from 110 m, the acceleration lane
        // ends at 200 m. Under the entry rule the world's x_c is the ramp's end, a centre half a
        // length (2.5 m) before it: 197.5 m, as the training's ramp ends at x_c. The merge zone
        // (where players make room for a ramp vehicle) starts at merge_from, 87.5 m before it,
        // not at the training's 40 m; a merge_from later than that keeps the 40 m (157.5 m on).
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let config = Config::load(&root.join("configs/traffic.toml")).unwrap();
        let net = root.join("sumo_nets/single_lane_merge");
        let geometry = MergeGeometry::load(&net.join("merge.toml")).unwrap();
        let positions = crate::sumo::inputs::check_geometry(
            &geometry,
            &net.join("merge.toml"),
            &net.join("merge.net.xml"),
        )
        .unwrap();
        let zone = |merge_from: f64| {
            let geometry = MergeGeometry {
                merge_from: Some(merge_from),
                ..geometry.clone()
            };
            let kind = ControllerKind::Mpg;
            let c = Controller::new(
                config.clone(),
                geometry,
                positions.clone(),
                kind,
                None,
                ControlModes::SAFE,
            );
            assert_eq!(c.rules.conflict_point(), 197.5);
            (
                c.rules.road.in_merge_zone(109.0),
                c.rules.road.in_merge_zone(110.0),
                c.rules.road.in_merge_zone(157.0),
                c.rules.road.in_merge_zone(158.0),
            )
        };
        assert_eq!(zone(110.0), (false, true, true, true));
        assert_eq!(zone(160.0), (false, false, false, true));
    }

    #[test]
    fn egos_merge_at_the_first_safe_gap_from_merge_from_and_at_x_c_at_the_latest() {
        let mut c = paper_controller();
        // Without merge_from: at x_c only, as the internal simulator.
        let alone = [car("ego", 150.0, 12.0, true)];
        assert!(!c.merges_now(&alone, 0));
        assert!(c.merges_now(&[car("ego", 180.0, 12.0, true)], 0));
        c.geometry.merge_from = Some(138.0);
        // An empty target lane from 138 m on: now, not before.
        assert!(c.merges_now(&alone, 0));
        assert!(!c.merges_now(&[car("ego", 137.9, 12.0, true)], 0));
        // A car 5 m behind at the same speed: the gap is below the 7 m clearance (length 5 m
        // + safety gap 2 m), so not now; 30 m behind at the same speed it is safe. A ramp car
        // beside does not count.
        let close = [car("ego", 150.0, 12.0, true), car("lane", 145.0, 12.0, false)];
        assert!(!c.merges_now(&close, 0));
        let far = [
            car("ego", 150.0, 12.0, true),
            car("lane", 120.0, 12.0, false),
            car("ramp", 150.0, 12.0, true),
        ];
        assert!(c.merges_now(&far, 0));
        // A car 20 m behind at 16 m/s: after the step the gap is 151.2 - 131.6 - 7 = 12.6 m,
        // closing at 4 m/s: TTC 3.15 s >= tau_s = 3 s, and 4^2 <= 2 * 4 * 12.6. 18 m behind,
        // TTC 10.6 / 4 = 2.65 s: not now.
        let gaining = |behind: f64| {
            [
                car("ego", 150.0, 12.0, true),
                car("lane", 150.0 - behind, 16.0, false),
            ]
        };
        assert!(c.merges_now(&gaining(20.0), 0));
        assert!(!c.merges_now(&gaining(18.0), 0));
        // At x_c the merge happens whatever is there.
        let at_x_c = [car("ego", 180.0, 12.0, true), car("lane", 178.0, 12.0, false)];
        assert!(c.merges_now(&at_x_c, 0));
        // An ego the scenes already count in the target lane is not its own follower.
        let entered = waiting_car("ego", 150.0, 12.0);
        assert!(c.merges_now(std::slice::from_ref(&entered), 0));
        assert!(!c.merges_now(&[entered, car("lane", 145.0, 12.0, false)], 0));
    }

    #[test]
    fn with_a_traffic_policy_a_ramp_vehicle_enters_the_scene_at_merge_from() {
        let mut c = paper_controller();
        // A Table I policy: at x_c, as the internal simulator, merge_from or not.
        assert_eq!(c.scene_entry(), 180.0);
        c.geometry.merge_from = Some(138.0);
        assert_eq!(c.scene_entry(), 180.0);
        // A traffic policy: where the ego starts asking for the lane change; never past x_c.
        c.traffic = true;
        assert_eq!(c.scene_entry(), 138.0);
        // In exact modes SUMO makes a lane change the step it is asked for: nothing waits,
        // and the scenes are the internal world's (at x_c at the latest).
        c.modes = ControlModes::EXACT;
        assert_eq!(c.scene_entry(), 180.0);
        c.modes.lane_change = 512;
        assert_eq!(c.scene_entry(), 138.0);
        c.geometry.merge_from = Some(200.0);
        assert_eq!(c.scene_entry(), 180.0);
        c.geometry.merge_from = None;
        assert_eq!(c.scene_entry(), 180.0);
    }

    #[test]
    fn controllable_players_are_driven_inside_the_control_zone_only() {
        let mut c = paper_controller();
        // "all": every player, also far downstream (the paper's game).
        assert!(c.may_drive_player(&car("lane.1", 400.0, 12.0, false)));
        // "controllable": only players whose type is listed, and only inside the control zone,
        // which ends 50 m past x_c = 180 m, where a merged ego is released too.
        c.geometry.players = PlayerControl::Controllable;
        c.types.insert("lane.1".into(), "human".into());
        c.types.insert("ramp.1".into(), "ctrl".into());
        assert!(!c.may_drive_player(&car("lane.1", 200.0, 12.0, false)));
        assert!(c.may_drive_player(&car("ramp.1", 229.9, 12.0, false)));
        assert!(!c.may_drive_player(&car("ramp.1", 230.0, 12.0, false)));
    }
}
