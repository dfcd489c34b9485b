//! Initial states of merge traffic (`scenario.kind = "traffic"`, `[traffic]`).
//!
//! Scenario `k` of a seed is drawn from its own random stream, as the paper's are
//! ([`crate::world::sampler`]). It holds `ramp_vehicles` ramp vehicles and `target_vehicles`
//! target-lane vehicles:
//! 1. the demand: the target lane's flow `q_l` and the ramp's `q_r` uniform in their ranges
//!    (veh/h), each stream's speed uniform in `sampling.speed` (target lane) and
//!    `sampling.ego_speed` (ramp), and the share of human drivers uniform in `human_share`;
//! 2. the ego (vehicle 0) on the ramp, stratified in position and speed as the paper's ego is;
//! 3. the other ramp vehicles as a stream through the ego: a uniform number of them ahead of
//!    it (those that would reach `x_c - 2 m` go behind instead), the rest behind; under the
//!    entry rule every ramp vehicle, the ego too, starts slow enough to stop 2 m before the
//!    ramp's end braking at `sim.b_safe` (a faster one is capped, one ahead of the ego goes
//!    behind it instead);
//! 4. the target lane as a stream through the conflict point: `ahead_share` of its vehicles
//!    from a point up to one headway past `x_c` onwards, the rest behind it.
//!
//! Headways (centre to centre) are `h_min + Exp(s - h_min)`, with `h_min =
//! sampling.headway[0]` and `s = 3600 v / q` the stream's mean spacing (at least `h_min +
//! 1 m`): a stream of flow `q` at speed `v` with random arrivals. A vehicle's speed is its
//! stream's plus a uniform part of +-2 m/s, within `sampling.speed` widened to hold the
//! stream speed, and held so that the TTC to the vehicle ahead of it in its lane is at least
//! `sampling.min_ttc` (as the paper's sampler does). Every vehicle but the ego is a human (IDM)
//! driver with the drawn share's probability.
//!
//! With the projection's time gap `h = sim.time_headway > 0`, the scenes start as its rule
//! asks: a stream's least headway is also the projection's clearance plus `h` times the
//! stream's speed, and a follower's speed cap gives up `h v` of its headway, `v <= (v_ahead +
//! h_c / min_ttc) / (1 + h / min_ttc)` for a centre headway `h_c`. Drawn without it, the
//! target lane started far inside the time gaps it then had to open (7 m centre headways at
//! 8-20 m/s), and training's probe potential did not improve in 90 epochs (measured with an
//! earlier form of the projection; `docs/experiments.md`).
//!
//! With `desired_speed`, the scene's desired speed `v_d` is drawn first, uniform in its range,
//! and every speed range above (streams, spreads' bounds, the ego's strata) is scaled by
//! `v_d / reward.v_desired` (capped at `vehicle.v_max`): the same traffic on a faster road.

use crate::config::{Config, Entry, TrafficConfig};
use crate::world::geometry::Road;
use crate::world::sampler::{scenario_rng, stratified_ego};
use crate::world::state::{Scene, Vehicle};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Largest deviation of a vehicle's speed from its stream's (m/s).
const SPEED_SPREAD: f64 = 2.0;
/// How far before `x_c` a ramp vehicle may start (m).
const RAMP_END_MARGIN: f64 = 2.0;

fn uniform(rng: &mut ChaCha8Rng, range: [f64; 2]) -> f64 {
    range[0] + (range[1] - range[0]) * rng.random::<f64>()
}

/// The sampled streams' spacing rules: the least headway, the initial TTC and the
/// projection's time gap and clearance (module docs).
struct Spacing {
    h_min: f64,
    min_ttc: f64,
    time_headway: f64,
    clearance: f64,
}

impl Spacing {
    /// `1 + h / min_ttc`: how much more a follower's own speed weighs in its cap than its
    /// leader's (exactly 1 without a time gap, so the cap is then the paper sampler's).
    fn own_speed_weight(&self) -> f64 {
        1.0 + self.time_headway / self.min_ttc
    }

    /// The speed of a vehicle `h` (centre to centre) behind one at `v_ahead` may be at most
    /// this.
    fn speed_cap(&self, v_ahead: f64, h: f64) -> f64 {
        (v_ahead + h / self.min_ttc) / self.own_speed_weight()
    }

    /// The least speed of a vehicle `h` ahead of one at `v`: `v` is within its speed cap.
    fn least_ahead(&self, v: f64, h: f64) -> f64 {
        v * self.own_speed_weight() - h / self.min_ttc
    }
}

/// A stream: its speed, mean spacing and least headway.
struct Stream {
    speed: f64,
    spacing: f64,
    h_min: f64,
}

impl Stream {
    fn new(rng: &mut ChaCha8Rng, flow: [f64; 2], speed: [f64; 2], rules: &Spacing) -> Self {
        let q = uniform(rng, flow);
        let v = uniform(rng, speed);
        let h_min = if rules.time_headway > 0.0 {
            rules.h_min.max(rules.clearance + rules.time_headway * v)
        } else {
            rules.h_min
        };
        Stream {
            speed: v,
            spacing: (3600.0 * v / q).max(h_min + 1.0),
            h_min,
        }
    }

    fn headway(&self, rng: &mut ChaCha8Rng) -> f64 {
        let u: f64 = rng.random();
        self.h_min - (1.0 - u).ln() * (self.spacing - self.h_min)
    }

    /// A speed for a vehicle `h` behind one at `v_ahead` (none: the front of its lane), within
    /// the scene's speed range `range` widened to hold the stream's speed.
    fn speed(
        &self,
        rng: &mut ChaCha8Rng,
        range: [f64; 2],
        rules: &Spacing,
        ahead: Option<(f64, f64)>,
    ) -> f64 {
        let lo = range[0].min(self.speed);
        let hi = range[1].max(self.speed);
        let v = uniform(rng, [self.speed - SPEED_SPREAD, self.speed + SPEED_SPREAD]).clamp(lo, hi);
        match ahead {
            Some((v_ahead, h)) => v.min(rules.speed_cap(v_ahead, h)),
            None => v,
        }
    }
}

/// Draws traffic scenario `index` of `seed` (module docs).
pub fn sample_traffic_scene(config: &Config, traffic: &TrafficConfig, seed: u64, index: usize) -> Scene {
    let p = &config.sampling;
    let road = Road::new(config);
    let x_c = config.scenario.conflict_point;
    let rules = Spacing {
        h_min: p.headway[0],
        min_ttc: p.min_ttc,
        time_headway: config.sim.time_headway,
        clearance: config.vehicle.length + config.sim.safety_gap,
    };
    let mut rng = scenario_rng(seed, index as u64);
    let v_desired = traffic.desired_speed.map(|range| uniform(&mut rng, range));
    // The sampled speeds scale with the scene's desired speed, within the vehicle's limits.
    let k = v_desired.map_or(1.0, |v_d| v_d / config.reward.v_desired);
    let v_max = config.vehicle.v_max;
    let scaled = |r: [f64; 2]| [(r[0] * k).min(v_max), (r[1] * k).min(v_max)];
    let (lane_speed, ramp_speed) = (scaled(p.speed), scaled(p.ego_speed));
    let lane = Stream::new(&mut rng, traffic.lane_flow, lane_speed, &rules);
    let ramp = Stream::new(&mut rng, traffic.ramp_flow, ramp_speed, &rules);
    let human_share = uniform(&mut rng, traffic.human_share);
    let car = |x: f64, v: f64, on_ramp: bool| Vehicle {
        x,
        y: road.lane_y(on_ramp),
        v,
        phi: 0.0,
        on_ramp,
    };

    // Under the entry rule a ramp vehicle starts where it can still stop before the ramp's end
    // braking at b_safe (a faster one could only be forced in); the paper's entry needs no cap.
    let stoppable = |x: f64| match config.scenario.entry {
        Entry::Gap => (2.0 * config.sim.b_safe * (road.ramp_end() - RAMP_END_MARGIN - x).max(0.0)).sqrt(),
        Entry::ConflictPoint => f64::INFINITY,
    };

    // The ego, stratified as the paper's.
    let (ego_x, ego_v) = stratified_ego(config, index, &mut rng);
    let ego_v = (ego_v * k).min(v_max).min(stoppable(ego_x));
    let mut vehicles = vec![car(ego_x, ego_v, true)];

    // The ramp stream: some ahead of the ego (front-most last), the rest behind.
    let others = traffic.ramp_vehicles - 1;
    let mut ahead_wanted = rng.random_range(0..=others);
    let (mut x, mut v) = (ego_x, ego_v);
    let mut ramp_ahead = Vec::new();
    while ahead_wanted > 0 {
        let h = ramp.headway(&mut rng);
        if x + h >= x_c - RAMP_END_MARGIN {
            break;
        }
        let v_ahead = ramp
            .speed(&mut rng, ramp_speed, &rules, None)
            .max(rules.least_ahead(v, h));
        if v_ahead > stoppable(x + h) {
            break;
        }
        x += h;
        v = v_ahead;
        ramp_ahead.push(car(x, v, true));
        ahead_wanted -= 1;
    }
    let (mut x, mut v) = (ego_x, ego_v);
    for _ in ramp_ahead.len()..others {
        let h = ramp.headway(&mut rng);
        v = ramp
            .speed(&mut rng, ramp_speed, &rules, Some((v, h)))
            .min(stoppable(x - h));
        x -= h;
        vehicles.push(car(x, v, true));
    }
    vehicles.extend(ramp_ahead);

    // The target-lane stream through the conflict point, front-most first.
    let n_ahead = (traffic.ahead_share * traffic.target_vehicles as f64).round() as usize;
    let anchor = x_c + rng.random::<f64>() * lane.headway(&mut rng);
    let mut front = anchor;
    for _ in 1..n_ahead {
        front += lane.headway(&mut rng);
    }
    let (mut x, mut ahead) = (front, None);
    for k in 0..traffic.target_vehicles {
        if k > 0 {
            let h = lane.headway(&mut rng);
            x -= h;
            ahead = ahead.map(|(v, _)| (v, h));
        }
        let v = lane.speed(&mut rng, lane_speed, &rules, ahead);
        vehicles.push(car(x, v, false));
        ahead = Some((v, 0.0));
    }
    let humans = (0..vehicles.len())
        .map(|i| i > 0 && rng.random::<f64>() < human_share)
        .collect();
    // Drawn last, so that the draws above do not depend on it.
    let cooperation = uniform(&mut rng, traffic.cooperation);
    let yields = (0..vehicles.len())
        .map(|_| rng.random::<f64>() < cooperation)
        .collect();
    Scene {
        vehicles,
        humans,
        yields,
        gives_way: Vec::new(),
        zips: Vec::new(),
        excess: Vec::new(),
        v_desired,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::ScenarioKind;

    fn traffic_config() -> Config {
        let text =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/configs/traffic.toml")).unwrap();
        let config = Config::parse(&text, "traffic.toml").unwrap();
        assert_eq!(config.scenario.kind, ScenarioKind::Traffic);
        config
    }

    /// A vehicle's position and speed.
    type State = (f64, f64);

    /// Each lane's successive vehicles, `(on_ramp, (x, v) ahead, (x, v) behind)`.
    fn successive_pairs(s: &Scene) -> Vec<(bool, State, State)> {
        let mut pairs = Vec::new();
        for lane in [true, false] {
            let mut xs: Vec<State> = s
                .vehicles
                .iter()
                .filter(|v| v.on_ramp == lane)
                .map(|v| (v.x, v.v))
                .collect();
            xs.sort_by(|a, b| b.0.total_cmp(&a.0));
            pairs.extend(xs.windows(2).map(|w| (lane, w[0], w[1])));
        }
        pairs
    }

    #[test]
    fn traffic_scenes_hold_both_streams_in_order_with_safe_headways() {
        let config = traffic_config();
        let t = config.traffic.clone().unwrap();
        let x_c = config.scenario.conflict_point;
        let mut ramp_leaders = 0;
        let mut human_count = 0;
        for k in 0..200 {
            let s = sample_traffic_scene(&config, &t, 7, k);
            assert_eq!(s.len(), t.ramp_vehicles + t.target_vehicles);
            assert!(!s.is_human(0), "the ego is never human");
            human_count += s.humans.iter().filter(|&&h| h).count();
            let ramp: Vec<&Vehicle> = s.vehicles.iter().filter(|v| v.on_ramp).collect();
            assert_eq!(ramp.len(), t.ramp_vehicles);
            assert!(ramp.iter().all(|v| v.x < x_c - RAMP_END_MARGIN + 1e-9));
            // Under the entry rule each can stop 2 m before the ramp's end (x_c here) at b_safe.
            let b = config.sim.b_safe;
            assert!(
                ramp.iter()
                    .all(|v| v.v * v.v / (2.0 * b) <= x_c - RAMP_END_MARGIN - v.x + 1e-9)
            );
            ramp_leaders += usize::from(ramp.iter().any(|v| v.x > s.ego().x));
            for (_, (x_ahead, v_ahead), (x, v)) in successive_pairs(&s) {
                let (h, closing) = (x_ahead - x, v - v_ahead);
                assert!(h >= config.sampling.headway[0] - 1e-9, "headway {h}");
                assert!(closing <= h / config.sampling.min_ttc + 1e-9, "TTC below min");
            }
        }
        // Some egos start behind another ramp vehicle (26 of 200 with desired speeds up to 36
        // m/s: on a fast road a ramp vehicle ahead must still stop before the ramp's end, so
        // fewer fit), and humans are mixed in.
        assert!(ramp_leaders > 20, "{ramp_leaders}");
        assert!(human_count > 100, "{human_count}");
    }

    #[test]
    fn with_a_time_headway_every_follower_starts_within_its_speed_cap() {
        // h = 1 s, min_ttc = 4 s: a follower h_c behind a vehicle at v_ahead drives at most
        // (v_ahead + h_c / 4) / 1.25, that is h_c - h v >= 4 (v - v_ahead). The target lane's
        // headways are at least the clearance (7 m) plus 1 s at the stream's speed, which is
        // at least 8 m/s scaled by the slowest desired speed, 8 x 10 / 15 = 16 / 3 m/s.
        let mut config = traffic_config();
        config.sim.time_headway = 1.0;
        let t = config.traffic.clone().unwrap();
        let mut shortest = f64::INFINITY;
        for k in 0..200 {
            let s = sample_traffic_scene(&config, &t, 7, k);
            for (on_ramp, (x_ahead, v_ahead), (x, v)) in successive_pairs(&s) {
                let h_c = x_ahead - x;
                assert!(
                    h_c - v >= 4.0 * (v - v_ahead) - 1e-9,
                    "{h_c} m at {v} behind {v_ahead}"
                );
                if !on_ramp {
                    shortest = shortest.min(h_c);
                }
            }
        }
        assert!(
            shortest >= 7.0 + 16.0 / 3.0 - 1e-9,
            "target-lane headway {shortest}"
        );
        // Without the time gap the same scenes are packed closer.
        config.sim.time_headway = 0.0;
        let packed = (0..200)
            .flat_map(|k| successive_pairs(&sample_traffic_scene(&config, &t, 7, k)))
            .filter(|(on_ramp, _, _)| !on_ramp)
            .map(|(_, ahead, behind)| ahead.0 - behind.0)
            .fold(f64::INFINITY, f64::min);
        assert!(packed < 10.0, "{packed}");
    }

    #[test]
    fn denser_demand_packs_the_target_lane_closer() {
        let mut config = traffic_config();
        let mut mean_spacing = |flow: f64| {
            let t = TrafficConfig {
                lane_flow: [flow, flow],
                desired_speed: None,
                ..config.traffic.clone().unwrap()
            };
            config.sampling.speed = [12.0, 12.0];
            let n = t.target_vehicles as f64;
            (0..200)
                .map(|k| {
                    let s = sample_traffic_scene(&config, &t, 1, k);
                    let xs: Vec<f64> = s.vehicles.iter().filter(|v| !v.on_ramp).map(|v| v.x).collect();
                    (xs[0] - xs[xs.len() - 1]) / (n - 1.0)
                })
                .sum::<f64>()
                / 200.0
        };
        // 12 m/s at 1,240 veh/h: 34.8 m apart on average; at 620 veh/h, 69.7 m.
        let (dense, sparse) = (mean_spacing(1240.0), mean_spacing(620.0));
        assert!((dense - 34.8).abs() < 3.0, "{dense}");
        assert!((sparse - 69.7).abs() < 6.0, "{sparse}");
    }

    #[test]
    fn a_faster_road_scales_the_sampled_speeds() {
        // v_d = 22.5 m/s is 1.5 times reward.v_desired = 15: the target lane's speed range
        // [8, 20] becomes [12, 30], the ego's strata likewise, and the streams' +-2 m/s spread
        // stays. The same draws without desired_speed keep v_d = 15 (none of the scene's own).
        let config = traffic_config();
        let base = config.traffic.clone().unwrap();
        let fast = TrafficConfig {
            desired_speed: Some([22.5, 22.5]),
            ..base.clone()
        };
        let plain = TrafficConfig {
            desired_speed: None,
            ..base
        };
        let (mut fast_sum, mut plain_sum) = (0.0, 0.0);
        for k in 0..100 {
            let s = sample_traffic_scene(&config, &fast, 3, k);
            assert_eq!(s.v_desired, Some(22.5));
            assert_eq!(sample_traffic_scene(&config, &plain, 3, k).v_desired, None);
            assert!(s.vehicles.iter().all(|v| v.v <= config.vehicle.v_max));
            assert!((12.0..=30.0).contains(&s.ego().v), "ego {}", s.ego().v);
            fast_sum += s.vehicles.iter().map(|v| v.v).sum::<f64>();
            let p = sample_traffic_scene(&config, &plain, 3, k);
            plain_sum += p.vehicles.iter().map(|v| v.v).sum::<f64>();
        }
        // Not exactly 1.5: the spread and the TTC bound on a vehicle's speed do not scale.
        let ratio = fast_sum / plain_sum;
        assert!(
            (ratio - 1.5).abs() < 0.1,
            "mean speeds {fast_sum} / {plain_sum} = {ratio}"
        );
    }
}
