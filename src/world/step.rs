//! One step of the world for one vehicle: the action it applies (feasibility projection, merge
//! gate, limits), eq. (1) with zero steering, and collisions between bounding boxes. One set of
//! rules for the scalar rollout, the NGSIM replay and the SUMO co-simulation.

use crate::world::drivers::{make_room_bound, makes_room, player_makes_room_for};
use crate::world::dynamics::{Kinematics, zero_steering_step};
use crate::world::geometry::{Footprint, boxes_overlap};
use crate::world::merge_gate::{gate_holds, lane_end_bound, lane_end_holds, stop_bound};
use crate::world::neighbors::Neighbors;
use crate::world::rules::WorldRules;
use crate::world::safety::{Neighbor, clip_action, feasible_interval_after, project_feasible, share_bounds};
use crate::world::state::{Scene, Vehicle};

/// A neighbour of `scene` as the generic equations take it (absent: far ahead, same speed).
pub fn neighbor_of(scene: &Scene, who: Option<usize>, me: &Vehicle) -> Neighbor<f64> {
    match who {
        Some(j) => Neighbor {
            x: scene.vehicles[j].x,
            v: scene.vehicles[j].v,
            present: 1.0,
        },
        None => Neighbor {
            x: me.x,
            v: me.v,
            present: 0.0,
        },
    }
}

/// [`neighbor_of`] vehicle `i` as the gaps between them are: a neighbour longer than the
/// world's car, or a vehicle `i` that is ([`Scene::excess`]), is moved towards `i` by their
/// excess, so that the centre distance less the world's clearance is their bumper gap.
pub fn neighbor_by_gap(scene: &Scene, who: Option<usize>, i: usize) -> Neighbor<f64> {
    let me = &scene.vehicles[i];
    let mut n = neighbor_of(scene, who, me);
    if let Some(j) = who {
        let excess = scene.excess(i) + scene.excess(j);
        n.x += if n.x > me.x { -excess } else { excess };
    }
    n
}

/// A vehicle after one step of eq. (1) with acceleration `u` and zero steering; a ramp
/// vehicle whose `x` reaches `x_c`, or that `merges` early ([`WorldRules::merges_early`]),
/// joins the target lane (its lateral position follows the lane geometry). One step for the
/// rollout and the NGSIM replay.
pub fn advance(v: &Vehicle, u: f64, merges: bool, rules: &WorldRules) -> Vehicle {
    let state = Kinematics {
        x: v.x,
        y: v.y,
        v: v.v,
        phi: v.phi,
    };
    let k = zero_steering_step(&state, &u, v.phi == 0.0, rules.axles, rules.dt);
    let on_ramp = !merges && rules.road.still_on_ramp(v.on_ramp, k.x);
    Vehicle {
        x: k.x,
        y: rules.road.lane_y(on_ramp),
        v: k.v,
        phi: k.phi,
        on_ramp,
    }
}

/// The acceleration player `i` of `scene` applies for the raw action `raw`: when `feasibility`
/// is on, projected onto its feasible interval towards its same-lane neighbours (the target
/// lane's, as Section V-ii, and a ramp queue's: ours), and held by the merge gate
/// on the ramp (`sim.merge_gate`, [`crate::world::merge_gate`]; a human driver of merge
/// traffic always merges by the gate, its lane-change rule); then clipped to
/// `[-g, g]` and the speed bounds (Section V-ii). Under the entry rule (`scenario.entry =
/// "gap"`) the ramp's end holds every ramp vehicle that may not enter, whatever `feasibility`
/// says: that is the road, not a rule of the driver. One function for the internal simulator and
/// the SUMO co-simulation.
pub fn applied_action(
    rules: &WorldRules,
    feasibility: bool,
    scene: &Scene,
    i: usize,
    nb: &Neighbors,
    raw: f64,
) -> f64 {
    applied_action_with(rules, feasibility, scene, i, nb, raw, Settled::default())
}

/// What is settled about a step before a vehicle's action is: by default nothing, and
/// [`applied_action_with`] reads both from the scene.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Settled {
    /// The entry rule's hold (`Some(true)`: the ramp's end holds the vehicle): the MPG check
    /// replays another run's.
    pub held: Option<bool>,
    /// The lane leader's speed after this step, in the sequential projection order
    /// ([`WorldRules::sequential`]).
    pub leader_next_v: Option<f64>,
    /// Whether the lane leader and the lane follower are projected too: in the shared
    /// projection order ([`WorldRules::shared`]) the vehicle then takes half of its pair's
    /// correction ([`share_bounds`]).
    pub projected: Projected,
}

/// Whether a vehicle's lane leader and lane follower are projected too.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Projected {
    /// The lane leader is.
    pub leader: bool,
    /// The lane follower is.
    pub follower: bool,
}

/// [`applied_action`] with what `settled` gives.
pub fn applied_action_with(
    rules: &WorldRules,
    feasibility: bool,
    scene: &Scene,
    i: usize,
    nb: &Neighbors,
    raw: f64,
    settled: Settled,
) -> f64 {
    let dt = rules.dt;
    let me = &scene.vehicles[i];
    let mut a = raw;
    if feasibility {
        let lead = neighbor_by_gap(scene, nb.lane_leader, i);
        let follow = neighbor_by_gap(scene, nb.lane_follower, i);
        let lead_next = settled.leader_next_v.unwrap_or(lead.v);
        let (mut lo, mut hi) =
            feasible_interval_after(&me.x, &me.v, &lead, &lead_next, &follow, &rules.projection());
        if rules.shared() {
            let flag = |b: bool| f64::from(u8::from(b));
            (lo, hi) = share_bounds(
                &lo,
                &hi,
                [&flag(settled.projected.follower), &flag(settled.projected.leader)],
                rules.shared_correction,
            );
        }
        if rules.feasibility_across_lanes && !me.on_ramp {
            (lo, hi) = across_lanes(scene, me, nb, (lo, hi), rules);
        }
        if let Some(j) = zipper_leader(scene, i) {
            let absent = neighbor_of(scene, None, me);
            let ramp = neighbor_by_gap(scene, Some(j), i);
            let (_, behind) =
                feasible_interval_after(&me.x, &me.v, &ramp, &ramp.v, &absent, &rules.projection());
            hi = hi.min(behind);
        }
        a = project_feasible(&a, &lo, &hi);
        if rules.players_make_room {
            if let Some(j) = player_makes_room_for(&rules.road, scene, i) {
                let ramp = neighbor_by_gap(scene, Some(j), i);
                let room = make_room_bound(&me.x, &me.v, &ramp, rules);
                if makes_room(room.reach, rules.gate.b_safe) {
                    a = a.min(room.bound);
                }
            }
        }
    }
    if feasibility && (rules.merge_gate || scene.is_human(i)) && gate_holds(scene, i, &rules.gate) {
        a = a.min(stop_bound(&me.x, &me.v, &rules.gate));
    }
    if settled
        .held
        .unwrap_or_else(|| lane_end_holds(scene, i, &rules.gate))
    {
        a = a.min(lane_end_bound(&me.x, &me.v, &rules.gate));
    }
    clip_action(&a, &me.v, rules.max_accel, rules.v_min, rules.v_max, dt)
}

/// The ramp vehicle a target-lane player `i` follows at a zipper junction: the first ahead of
/// it of those that take their turn there ([`Scene::zips`]).
fn zipper_leader(scene: &Scene, i: usize) -> Option<usize> {
    let me = &scene.vehicles[i];
    if me.on_ramp || scene.is_human(i) {
        return None;
    }
    (scene.vehicles.iter().enumerate())
        .filter(|&(j, r)| r.on_ramp && r.x > me.x && scene.zips(j))
        .min_by(|(_, p), (_, q)| p.x.total_cmp(&q.x))
        .map(|(j, _)| j)
}

/// `sim.feasibility_across_lanes`: the target-lane vehicle `me`'s feasible interval `(lo, hi)`
/// narrowed by the projection's bounds towards its nearest leader and follower (any lane,
/// [`Neighbors`]) where those are ramp vehicles: the paper's immediate neighbours read by
/// longitudinal position, as Table I orders the players.
fn across_lanes(
    scene: &Scene,
    me: &Vehicle,
    nb: &Neighbors,
    (lo, hi): (f64, f64),
    rules: &WorldRules,
) -> (f64, f64) {
    let on_ramp = |who: Option<usize>| who.filter(|&j| scene.vehicles[j].on_ramp);
    let lead = neighbor_of(scene, on_ramp(nb.leader), me);
    let follow = neighbor_of(scene, on_ramp(nb.follower), me);
    let (ramp_lo, ramp_hi) =
        feasible_interval_after(&me.x, &me.v, &lead, &lead.v, &follow, &rules.projection());
    (lo.max(ramp_lo), hi.min(ramp_hi))
}

/// The first overlapping pair `(a, b)`, `a < b`, in index order, among the pairs `counts`
/// accepts.
pub fn first_collision_among(
    scene: &Scene,
    length: f64,
    width: f64,
    counts: impl Fn(usize, usize) -> bool,
) -> Option<(usize, usize)> {
    let fp = |v: &Vehicle| Footprint {
        x: v.x,
        y: v.y,
        phi: v.phi,
        length,
        width,
    };
    let veh = &scene.vehicles;
    let diagonal = length.hypot(width); // centres farther apart than this cannot overlap
    (0..veh.len()).find_map(|a| {
        ((a + 1)..veh.len())
            .find(|&b| {
                (veh[a].x - veh[b].x).abs() < diagonal
                    && counts(a, b)
                    && boxes_overlap(&fp(&veh[a]), &fp(&veh[b]))
            })
            .map(|b| (a, b))
    })
}
