//! The paper's two specific scenarios (Section V, "Specific scenarios") as named initial
//! states. Every player drives by the shared policy (the NE policies), as in the paper.
//!
//! - Preset 1: leaders "1"-"4" start slower than the desired speed and followers "5"-"8"
//!   faster than the ego, with the ego level with a 20 m gap between "4" and "5". Under the NE
//!   policies the leaders accelerate and the followers decelerate, so that gap widens and the
//!   ego merges into it.
//! - Preset 2: a large initial gap (40 m) between "4" and "5", but "5" is 6 m/s faster than the
//!   ego, so the gap closes quickly: the ego waits for "5" to pass, then merges behind it.

use crate::config::Config;
use crate::world::geometry::Road;
use crate::world::sampler::scenario_rng;
use crate::world::state::{Scene, Vehicle};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// A named initial state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    /// Leaders accelerate, followers decelerate: the gap between "4" and "5" widens.
    One,
    /// A large gap between "4" and "5", closing fast: the ego waits, then merges.
    Two,
}

impl Preset {
    /// The preset's number in the paper (1 or 2).
    pub fn number(self) -> u8 {
        match self {
            Preset::One => 1,
            Preset::Two => 2,
        }
    }

    /// One line saying what the preset sets up.
    pub fn description(self) -> &'static str {
        match self {
            Preset::One => {
                "leaders 1-4 below v_d, followers 5-8 above it, 5 120 m behind the ego: the gap between 4 and 5 should widen"
            }
            Preset::Two => "a 70 m gap between 4 and 5, but 5 is 6 m/s faster than the ego: wait, then merge",
        }
    }

    /// The preset's initial state.
    pub fn state(self) -> PresetState {
        match self {
            Preset::One => PresetState {
                ego_before: 30.0,
                ego_speed: 10.0,
                gap_ahead: 10.0,
                gap_behind: 120.0,
                leader_speed: 9.0,
                follower_speed: 18.0,
                headway: 14.0,
            },
            Preset::Two => PresetState {
                ego_before: 30.0,
                ego_speed: 10.0,
                gap_ahead: 10.0,
                gap_behind: 60.0,
                leader_speed: 14.0,
                follower_speed: 16.0,
                headway: 30.0,
            },
        }
    }

    /// The initial scene for a configuration (see [`PresetState::scene`]).
    pub fn scene(self, config: &Config) -> Scene {
        self.state().scene(config)
    }

    /// The players the paper's ego merges between: "4" and "5" in scenario 1 (the gap that
    /// widens), "5" and "6" in scenario 2 (it waits for "5" to pass).
    pub fn paper_outcome(self) -> [usize; 2] {
        match self {
            Preset::One => [4, 5],
            Preset::Two => [5, 6],
        }
    }

    /// `n` initial states drawn uniformly from the scenario's description in the paper, around
    /// [`Preset::state`], not chosen for any policy. State `k` comes from random stream `k` of
    /// seed 1 or 2 (the preset's number), so the set is fixed.
    ///
    /// - Scenario 1: leaders at 7-11 m/s (below v_d = 15), followers at 16-20 m/s (above it),
    ///   the nearest follower 100-140 m behind the ego.
    /// - Scenario 2: a 55-85 m gap between "4" and "5", with "5" 4-8 m/s faster than the ego
    ///   and the leaders at 12-15 m/s.
    ///
    /// Both: the ego 20-40 m before `x_c` at 8-12 m/s, "4" 7-13 m ahead of it.
    pub fn described_states(self, n: usize) -> Vec<PresetState> {
        (0..n as u64)
            .map(|k| self.draw_state(&mut scenario_rng(u64::from(self.number()), k)))
            .collect()
    }

    /// One state drawn uniformly from the scenario's description (the ranges of
    /// [`Preset::described_states`]), seven draws from `rng`.
    pub fn draw_state(self, rng: &mut ChaCha8Rng) -> PresetState {
        let mut draw = |lo: f64, hi: f64| lo + (hi - lo) * rng.random::<f64>();
        let ego_before = draw(20.0, 40.0);
        let ego_speed = draw(8.0, 12.0);
        let gap_ahead = draw(7.0, 13.0);
        match self {
            Preset::One => PresetState {
                ego_before,
                ego_speed,
                gap_ahead,
                gap_behind: draw(100.0, 140.0),
                leader_speed: draw(7.0, 11.0),
                follower_speed: draw(16.0, 20.0),
                headway: draw(10.0, 18.0),
            },
            Preset::Two => PresetState {
                ego_before,
                ego_speed,
                gap_ahead,
                gap_behind: draw(55.0, 85.0) - gap_ahead,
                leader_speed: draw(12.0, 15.0),
                follower_speed: ego_speed + draw(4.0, 8.0),
                headway: draw(20.0, 40.0),
            },
        }
    }
}

/// The initial state of a specific scenario: the ego on the ramp, the leaders "1"-"4" ahead of
/// it and the followers "5"-"8" behind it on the target lane, each group at one speed.
/// Distances are centre to centre (m), speeds in m/s.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PresetState {
    /// Distance from the ego to the conflict point.
    pub ego_before: f64,
    /// The ego's speed.
    pub ego_speed: f64,
    /// Distance from the ego forward to the nearest leader "4".
    pub gap_ahead: f64,
    /// Distance from the ego back to the nearest follower "5".
    pub gap_behind: f64,
    /// Speed of every leader.
    pub leader_speed: f64,
    /// Speed of every follower.
    pub follower_speed: f64,
    /// Distance between successive leaders, and between successive followers.
    pub headway: f64,
}

impl PresetState {
    /// The scene for a configuration with 4 leaders and 4 followers (other counts: the nearest
    /// ones of the same pattern). Positions are relative to the conflict point, so that they
    /// hold for any `x_c`.
    pub fn scene(&self, config: &Config) -> Scene {
        let road = Road::new(config);
        let ego_x = road.conflict_point - self.ego_before;
        let target = |x: f64, v: f64| Vehicle {
            x,
            y: road.lane_y(false),
            v,
            phi: 0.0,
            on_ramp: false,
        };
        let n_l = config.scenario.n_leaders;
        let mut vehicles = vec![Vehicle {
            x: ego_x,
            y: road.lane_y(true),
            v: self.ego_speed,
            phi: 0.0,
            on_ramp: true,
        }];
        // "1" (front-most) .. "n_l" (nearest).
        vehicles.extend((0..n_l).map(|k| {
            target(
                ego_x + self.gap_ahead + (n_l - 1 - k) as f64 * self.headway,
                self.leader_speed,
            )
        }));
        vehicles.extend((0..config.scenario.n_followers).map(|k| {
            target(
                ego_x - self.gap_behind - k as f64 * self.headway,
                self.follower_speed,
            )
        }));
        Scene::new(vehicles)
    }
}

/// The players the ego merged between, as player numbers `[front, back]` (0 for none): its
/// nearest target-lane player ahead and behind in `scene`, the first state after the ego
/// passed the conflict point.
pub fn merged_between(scene: &Scene) -> [usize; 2] {
    let ego = scene.ego();
    let lane = || {
        scene
            .vehicles
            .iter()
            .enumerate()
            .skip(1)
            .filter(|(_, v)| !v.on_ramp)
    };
    let front = lane()
        .filter(|(_, v)| v.x >= ego.x)
        .min_by(|a, b| a.1.x.total_cmp(&b.1.x))
        .map_or(0, |(i, _)| i);
    let back = lane()
        .filter(|(_, v)| v.x < ego.x)
        .max_by(|a, b| a.1.x.total_cmp(&b.1.x))
        .map_or(0, |(i, _)| i);
    [front, back]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::state::cruising_car as car;

    #[test]
    fn a_preset_state_places_the_leaders_ahead_and_the_followers_behind_the_ego() {
        let config =
            Config::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper.toml"))
                .unwrap();
        // x_c = 180: the ego 30 m before it at 150; "4" 10 m ahead (160), "1" three headways
        // of 14 m further (202); "5" 120 m behind (30), "8" three headways further back (-12).
        let scene = Preset::One.scene(&config);
        let xv: Vec<(f64, f64)> = scene.vehicles.iter().map(|v| (v.x, v.v)).collect();
        assert_eq!(
            xv,
            vec![
                (150.0, 10.0),
                (202.0, 9.0),
                (188.0, 9.0),
                (174.0, 9.0),
                (160.0, 9.0),
                (30.0, 18.0),
                (16.0, 18.0),
                (2.0, 18.0),
                (-12.0, 18.0)
            ]
        );
        assert!(scene.vehicles[0].on_ramp && scene.vehicles[1..].iter().all(|v| !v.on_ramp));
    }

    #[test]
    fn the_ego_merged_between_its_nearest_target_lane_players() {
        // Players 1-2 ahead (2 nearer), 3-4 behind (3 nearer); a ramp car right behind is no
        // target-lane player.
        let scene = Scene::new(vec![
            car(181.0, false),
            car(230.0, false),
            car(190.0, false),
            car(170.0, false),
            car(150.0, false),
            car(178.0, true),
        ]);
        assert_eq!(merged_between(&scene), [2, 3]);
        let alone = Scene::new(vec![car(181.0, false), car(150.0, false)]);
        assert_eq!(merged_between(&alone), [0, 1]);
    }

    #[test]
    fn described_states_are_fixed_and_keep_to_each_scenarios_description() {
        let within = |x: f64, lo: f64, hi: f64| (lo..=hi).contains(&x);
        for preset in [Preset::One, Preset::Two] {
            let states = preset.described_states(200);
            // A fixed set: the first states do not depend on how many are drawn.
            assert_eq!(preset.described_states(3)[..], states[..3]);
            for s in &states {
                assert!(
                    within(s.ego_before, 20.0, 40.0) && within(s.ego_speed, 8.0, 12.0),
                    "{s:?}"
                );
                assert!(within(s.gap_ahead, 7.0, 13.0), "{s:?}");
                match preset {
                    // Leaders below v_d = 15, followers above it, "5" 100-140 m behind.
                    Preset::One => assert!(
                        s.leader_speed < 15.0
                            && s.follower_speed > 15.0
                            && within(s.gap_behind, 100.0, 140.0),
                        "{s:?}"
                    ),
                    // A 55-85 m gap between "4" and "5", "5" 4-8 m/s faster than the ego.
                    Preset::Two => assert!(
                        within(s.gap_ahead + s.gap_behind, 55.0, 85.0)
                            && within(s.follower_speed - s.ego_speed, 4.0, 8.0),
                        "{s:?}"
                    ),
                }
            }
            // Spread over the ranges, not bunched: some below and some above the middle.
            let low = states.iter().filter(|s| s.ego_before < 30.0).count();
            assert!((60..=140).contains(&low), "{low} of 200 below 30 m");
        }
        assert_ne!(Preset::One.described_states(1), Preset::Two.described_states(1));
    }
}
