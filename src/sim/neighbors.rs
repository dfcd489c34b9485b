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

use crate::sim::state::Scene;

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
    order.extend(0..n);
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
