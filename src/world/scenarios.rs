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
use crate::world::state::{Scene, Vehicle};

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
                "leaders 1-4 slower than v_d, followers 5-8 faster than the ego; the gap between 4 and 5 should widen"
            }
            Preset::Two => "a 40 m gap between 4 and 5, but 5 is 6 m/s faster than the ego: wait, then merge",
        }
    }

    /// The initial scene for a configuration with 4 leaders and 4 followers (other counts:
    /// the nearest ones of the same pattern). Positions are centres, relative to the
    /// conflict point so that they hold for any `x_c`.
    pub fn scene(self, config: &Config) -> Scene {
        let road = Road::new(config);
        let x_c = road.conflict_point;
        // (ego distance before x_c, ego speed, gap ahead to "4", gap behind to "5",
        //  leader speed, follower speed, headway between other players)
        let (ego_d, ego_v, ahead, behind, v_lead, v_follow, headway) = match self {
            Preset::One => (80.0, 12.0, 10.0, 10.0, 11.0, 13.0, 14.0),
            Preset::Two => (80.0, 10.0, 20.0, 20.0, 10.0, 16.0, 14.0),
        };
        let ego_x = x_c - ego_d;
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
            v: ego_v,
            phi: 0.0,
            on_ramp: true,
        }];
        // "1" (front-most) .. "n_l" (nearest).
        vehicles.extend((0..n_l).map(|k| target(ego_x + ahead + (n_l - 1 - k) as f64 * headway, v_lead)));
        vehicles.extend(
            (0..config.scenario.n_followers).map(|k| target(ego_x - behind - k as f64 * headway, v_follow)),
        );
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
}
