//! Vehicle and scenario state.
//!
//! Agent numbering follows the paper's figures: index 0 is the ego (ramp) vehicle, indices
//! `1..=n_leaders` are the target-lane leaders from the front-most ("1") to the nearest
//! ("4" by default), and the followers follow from the nearest ("5") to the rear-most ("8").

/// State of one vehicle: the bicycle state of eq. (1) plus the lane it is in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vehicle {
    /// Longitudinal position of the centre of mass (m).
    pub x: f64,
    /// Lateral position of the centre of mass (m); 0 is the target-lane centre line.
    pub y: f64,
    /// Speed (m/s).
    pub v: f64,
    /// Heading (rad).
    pub phi: f64,
    /// True while the vehicle is on the ramp (before the conflict point).
    pub on_ramp: bool,
}

/// One scenario: the players' states, ego first.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Vehicles, indexed by player number (0 = ego).
    pub vehicles: Vec<Vehicle>,
    /// Which vehicles a human (IDM) drives in merge traffic, by index: not players of the
    /// game, whatever drives the others. Empty: none.
    pub humans: Vec<bool>,
    /// Which vehicles, when a human drives them, make room for a ramp vehicle in the merge zone
    /// ahead of them (`traffic.cooperation`), by index. Empty: none.
    pub yields: Vec<bool>,
    /// Which ramp vehicles give way to every vehicle approaching on the target lane, by index:
    /// the drivers of a priority junction's minor road (SUMO's, at a junction merge). No
    /// player makes room for them (`sim.players_make_room`): room made by slowing is never
    /// taken, as they go only once the target lane before them is clear. Empty: none (every
    /// ramp vehicle enters by the entry rule, training's world).
    pub gives_way: Vec<bool>,
    /// Which ramp vehicles take their turn at a zipper junction, by index: SUMO's drivers there
    /// (`cosim`, [`crate::sumo::LanePositions::zipper_entry`]), who go when they reach the
    /// junction first, room or not. A player counts the first of them ahead of it as its
    /// leader, as SUMO's drivers behind them do. Empty: none (training's world).
    pub zips: Vec<bool>,
    /// How much longer than the world's car (`vehicle.length`) each vehicle is, halved (m), by
    /// index: a SUMO truck's rear lies that much further back of its centre, its front that much
    /// further ahead, and every gap to it is that much shorter. Empty: none (training's world).
    pub excess: Vec<f64>,
    /// The scene's desired speed `v_d` (m/s): the speed the reward's speed term tracks, and
    /// (scaled by `v_d / reward.v_desired`) the IDM drivers' `v0`. None: the configuration's
    /// `reward.v_desired` (the paper's world). Merge traffic draws it per scene
    /// (`traffic.desired_speed`); the co-simulation sets the road's speed limit.
    pub v_desired: Option<f64>,
}

impl Scene {
    /// A scene of these vehicles, none of them human.
    pub fn new(vehicles: Vec<Vehicle>) -> Self {
        Scene {
            vehicles,
            humans: Vec::new(),
            yields: Vec::new(),
            gives_way: Vec::new(),
            zips: Vec::new(),
            excess: Vec::new(),
            v_desired: None,
        }
    }

    /// The scene's desired speed: its own, else `default` (the configuration's).
    pub fn desired_speed(&self, default: f64) -> f64 {
        self.v_desired.unwrap_or(default)
    }

    /// Whether a human (IDM) drives vehicle `i`.
    pub fn is_human(&self, i: usize) -> bool {
        self.humans.get(i).copied().unwrap_or(false)
    }

    /// Whether vehicle `i` is a human driver who makes room for a ramp vehicle ahead.
    pub fn is_yielding(&self, i: usize) -> bool {
        self.is_human(i) && self.yields.get(i).copied().unwrap_or(false)
    }

    /// Whether ramp vehicle `i` gives way to every approaching target-lane vehicle
    /// ([`Scene::gives_way`]).
    pub fn gives_way(&self, i: usize) -> bool {
        self.gives_way.get(i).copied().unwrap_or(false)
    }

    /// Whether ramp vehicle `i` takes its turn at a zipper junction ([`Scene::zips`]).
    pub fn zips(&self, i: usize) -> bool {
        self.zips.get(i).copied().unwrap_or(false)
    }

    /// How much longer than the world's car vehicle `i` is, halved ([`Scene::excess`]).
    pub fn excess(&self, i: usize) -> f64 {
        self.excess.get(i).copied().unwrap_or(0.0)
    }

    /// Number of players.
    pub fn len(&self) -> usize {
        self.vehicles.len()
    }

    /// True when the scene holds no vehicle.
    pub fn is_empty(&self) -> bool {
        self.vehicles.is_empty()
    }

    /// The ego vehicle.
    pub fn ego(&self) -> &Vehicle {
        &self.vehicles[0]
    }
}

/// Label of player `i` as drawn in the paper's figures ("ego", "1", "2", ...).
pub fn player_label(i: usize) -> String {
    if i == 0 { "ego".to_string() } else { i.to_string() }
}

/// A vehicle for unit tests: at `x` with speed `v`, on the ramp (`y = -3.66`, the I-80 lane
/// width) or in the target lane, heading along the road.
#[cfg(test)]
pub(crate) fn test_car(x: f64, v: f64, on_ramp: bool) -> Vehicle {
    Vehicle {
        x,
        y: if on_ramp { -3.66 } else { 0.0 },
        v,
        phi: 0.0,
        on_ramp,
    }
}

/// A test car at `x` cruising at 10 m/s, on the ramp or in the target lane.
#[cfg(test)]
pub(crate) fn cruising_car(x: f64, on_ramp: bool) -> Vehicle {
    test_car(x, 10.0, on_ramp)
}
