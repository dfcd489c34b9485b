//! Who is whose leader and follower.
//!
//! Two notions, both by longitudinal position (equivalently, by signed distance to the
//! conflict point, `x_c - x`):
//! - *nearest* leader/follower: the nearest player ahead/behind across the ramp and the target
//!   lane. Observations (Table I) use it, and IDM on the ramp (a ramp vehicle follows the
//!   projection of the vehicle it will merge behind).
//! - *same-lane* leader/follower: the nearest player ahead/behind in the same lane. The
//!   feasibility projection and IDM in the target lane use it.
//!
//! Ties in position are broken by player index, so the result is deterministic.

use crate::world::state::Scene;

/// Neighbour indices of one player (`None` where there is no such player).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Neighbors {
    /// Nearest player ahead, any lane.
    pub leader: Option<usize>,
    /// Nearest player behind, any lane.
    pub follower: Option<usize>,
    /// Nearest player ahead in the same lane.
    pub lane_leader: Option<usize>,
    /// Nearest player behind in the same lane.
    pub lane_follower: Option<usize>,
}

/// Neighbours of every player of `scene`, written into `out` (resized to the scene).
/// `order` is scratch space, reused across calls to avoid allocation.
pub fn find_neighbors(scene: &Scene, order: &mut Vec<usize>, out: &mut Vec<Neighbors>) {
    let n = scene.len();
    let veh = &scene.vehicles;
    order.clear();
    // Players are numbered front to back (the ego aside), so this is nearly sorted and the
    // insertion sort has little to do; the order found does not depend on the start.
    order.extend((0..n).rev());
    order.sort_by(|&a, &b| veh[a].x.total_cmp(&veh[b].x).then(a.cmp(&b)));
    out.clear();
    out.resize(n, Neighbors::default());
    for (rank, &i) in order.iter().enumerate() {
        let ahead = &order[rank + 1..];
        let behind = &order[..rank];
        let lane = veh[i].on_ramp;
        out[i] = Neighbors {
            leader: ahead.first().copied(),
            follower: behind.last().copied(),
            lane_leader: ahead.iter().copied().find(|&j| veh[j].on_ramp == lane),
            lane_follower: behind.iter().rev().copied().find(|&j| veh[j].on_ramp == lane),
        };
    }
}

/// The players of an ego at longitudinal position `ego_x` among target-lane vehicles
/// `(key, x)`: up to `n_leaders` ahead (front-most first, in the slots that end at
/// `n_leaders`, so the nearest leader is always player `n_leaders`) and up to `n_followers` at
/// or behind it (nearest first, from slot `n_leaders + 1`). Slots are the agent indices of
/// training; the ego is slot 0. Used by the SUMO controller and the NGSIM replay.
pub fn player_slots<K: Clone>(
    ego_x: f64,
    target_lane: &[(K, f64)],
    n_leaders: usize,
    n_followers: usize,
) -> Vec<(K, usize)> {
    let mut sorted: Vec<&(K, f64)> = target_lane.iter().collect();
    sorted.sort_by(|a, b| a.1.total_cmp(&b.1));
    let ahead: Vec<&(K, f64)> = sorted
        .iter()
        .copied()
        .filter(|o| o.1 > ego_x)
        .take(n_leaders)
        .collect();
    let first_slot = n_leaders - ahead.len() + 1;
    let mut players: Vec<(K, usize)> = ahead
        .iter()
        .rev()
        .enumerate()
        .map(|(r, o)| (o.0.clone(), first_slot + r))
        .collect();
    players.extend(
        sorted
            .iter()
            .rev()
            .filter(|o| o.1 <= ego_x)
            .take(n_followers)
            .enumerate()
            .map(|(r, o)| (o.0.clone(), n_leaders + 1 + r)),
    );
    players
}

/// Writes into `order` the players in the feasibility projection's sequential order
/// (`sim.projection_order = "sequential"`): by lane rank, the number of lane leaders ahead of
/// each (0 for the front of a lane), so that every lane leader is settled before its follower;
/// ties keep index order.
pub fn front_to_back(neighbors: &[Neighbors], order: &mut Vec<usize>) {
    let rank = |mut i: usize| {
        let mut r = 0;
        while let Some(j) = neighbors[i].lane_leader {
            (i, r) = (j, r + 1);
        }
        r
    };
    order.clear();
    order.extend(0..neighbors.len());
    order.sort_by_key(|&i| rank(i));
}
