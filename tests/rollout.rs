//! The rollout loop: determinism, merging, collisions, failures, feasibility.

mod common;

use approx::assert_abs_diff_eq;
use common::{car, scene, smoke};
use mpgdrive::engine::rollout::{Actor, DriverActor, Recording, RolloutOptions, rollout};
use mpgdrive::eval::EpisodeMetrics;
use mpgdrive::eval::study::CollisionRecord;
use mpgdrive::world::Driver;
use mpgdrive::world::neighbors::Neighbors;
use mpgdrive::world::safety::ttc;
use mpgdrive::world::sampler::sample_scenes;
use mpgdrive::world::state::Scene;

fn opts(config: &mpgdrive::Config, threads: usize) -> RolloutOptions {
    RolloutOptions {
        recording: Recording::Full,
        threads,
        ..RolloutOptions::from_config(config)
    }
}

/// One scene, every player at constant speed, fully recorded.
fn constant_speed(config: &mpgdrive::Config, s: mpgdrive::world::Scene) -> mpgdrive::engine::EpisodeOutcome {
    rollout(config, &opts(config, 1), &[s], || {
        DriverActor::new(config, Driver::ConstSpeed, Driver::ConstSpeed)
    })
    .remove(0)
}

#[test]
fn same_seed_gives_identical_rollouts_whatever_the_thread_count() {
    let config = smoke();
    let scenes = sample_scenes(&config, 9, 0, 12);
    let run = |threads| {
        rollout(&config, &opts(&config, threads), &scenes, || {
            DriverActor::new(&config, Driver::Idm, Driver::Idm)
        })
    };
    let a = run(1);
    assert_eq!(a, run(1));
    assert_eq!(a, run(3));
    assert_eq!(a.len(), 12);
    let t = a[0].trajectory.as_ref().unwrap();
    assert_eq!(t.states.len(), (config.n_steps() + 1) * 9);
    assert_eq!(t.potential.len(), config.n_steps());
}

#[test]
fn returns_are_the_discounted_sums_of_the_recorded_rewards() {
    let mut config = smoke();
    config.sim.absorbing_collision = false;
    let scenes = sample_scenes(&config, 1, 0, 3);
    for o in rollout(&config, &opts(&config, 1), &scenes, || {
        DriverActor::new(&config, Driver::Idm, Driver::ConstSpeed)
    }) {
        let t = o.trajectory.as_ref().unwrap();
        let mut phi = 0.0;
        let mut j0 = 0.0;
        for (k, p) in t.potential.iter().enumerate() {
            phi += config.sim.gamma.powi(k as i32) * p;
            j0 += config.sim.gamma.powi(k as i32) * t.rewards[k * 9];
        }
        assert_abs_diff_eq!(o.potential_return, phi, epsilon = 1e-9 * phi.abs());
        assert_abs_diff_eq!(o.returns[0], j0, epsilon = 1e-9 * j0.abs().max(1.0));
    }
}

/// Runs `scenes` under constant-speed drivers with `recording` on two threads.
fn constant_speeds(
    config: &mpgdrive::Config,
    scenes: &[Scene],
    recording: Recording,
) -> Vec<mpgdrive::engine::EpisodeOutcome> {
    let opts = RolloutOptions {
        recording,
        ..opts(config, 2)
    };
    rollout(config, &opts, scenes, || {
        DriverActor::new(config, Driver::ConstSpeed, Driver::ConstSpeed)
    })
}

#[test]
fn recording_the_ego_alone_gives_its_return_and_statistics_bit_for_bit() {
    // Sampled scenes, and the scene of `a_collision_ends_the_episode_for_everyone` (the ego
    // runs into a stopped car) to charge the absorbing tail.
    let mut crash = smoke();
    (crash.scenario.n_leaders, crash.scenario.n_followers) = (1, 0);
    crash.sim.feasibility = false;
    let crash_scene = scene(vec![car(175.0, 10.0, true), car(183.0, 0.0, false)]);
    let sampled = smoke();
    let cases = [
        (&sampled, sample_scenes(&sampled, 4, 0, 24), false),
        (&crash, vec![crash_scene], true),
    ];
    for (config, scenes, crashes) in &cases {
        let every = constant_speeds(config, scenes, Recording::Summary);
        let ego = constant_speeds(config, scenes, Recording::Ego);
        let n = scenes[0].len();
        for (a, b) in every.iter().zip(&ego) {
            assert_eq!(a.returns[0].to_bits(), b.returns[0].to_bits());
            assert_eq!(a.vehicles[0], b.vehicles[0]);
            assert_eq!(
                (a.steps, a.collision, a.ego_merged_at),
                (b.steps, b.collision, b.ego_merged_at)
            );
            assert_eq!(
                (a.others_overlapped, &a.final_scene),
                (b.others_overlapped, &b.final_scene)
            );
            assert_eq!((a.returns.len(), b.returns.len(), b.vehicles.len()), (n, 1, 1));
            assert!(a.potential_return.is_finite() && b.potential_return.is_nan());
            if *crashes {
                assert_eq!(b.steps, 5, "the crash ends the episode after step 4");
            }
        }
    }
}

#[test]
fn ego_merges_at_the_conflict_point_and_takes_the_target_lane() {
    // Alone on the road at 10 m/s from x = 170 m: it passes x_c = 180 after 10 steps (x = 180.0
    // is reached at the end of step 9, i.e. the 10th step).
    let mut config = smoke();
    config.scenario.n_leaders = 0;
    config.scenario.n_followers = 0;
    let s = scene(vec![car(170.0, 10.0, true)]);
    let out = &constant_speed(&config, s);
    assert_eq!(out.ego_merged_at, Some(9));
    let t = out.trajectory.as_ref().unwrap();
    assert!(t.states[9].on_ramp && t.states[9].y == -3.66);
    assert!(!t.states[10].on_ramp && t.states[10].y == 0.0);
    let m = EpisodeMetrics::of(out);
    assert!(!m.failure && !m.collision);
    assert_abs_diff_eq!(m.mean_speed, 10.0);
}

#[test]
fn a_collision_ends_the_episode_for_everyone() {
    // The ego merges at 10 m/s into a stopped car 3 m past the conflict point.
    let mut config = smoke();
    config.scenario.n_leaders = 1;
    config.scenario.n_followers = 0;
    config.sim.feasibility = false;
    let s = scene(vec![car(175.0, 10.0, true), car(183.0, 0.0, false)]);
    let out = &constant_speed(&config, s.clone());
    // After step 4 the ego is at x = 180 (merged), 3 m behind the centre of a 5 m car: overlap.
    let c = out.collision.expect("collision");
    assert_eq!((c.step, c.a, c.b), (4, 0, 1));
    assert_eq!(out.steps, 5);
    let phi = &out.trajectory.as_ref().unwrap().potential;
    assert_eq!(phi.len(), 5);
    assert!(EpisodeMetrics::of(out).collision);
    // The episode CSV's record: at t = 0.5 s, the ego (merged) at 180 m and 10 m/s, player 1
    // at 183 m, stopped.
    let record = CollisionRecord::of(out, config.sim.dt).expect("a record");
    assert_eq!(
        CollisionRecord::csv(Some(&record)),
        "0.5,0 1,180.00 183.00,10.00 0.00,0 0"
    );
    assert_eq!(CollisionRecord::csv(None), ",,,,");
    // Absorbing crash: steps 0..4 counted, then phi_4 charged for steps 5..29 of the 3 s horizon.
    let g = config.sim.gamma;
    let counted: f64 = (0..5).map(|k| g.powi(k) * phi[k as usize]).sum();
    let tail: f64 = (5..30).map(|k| g.powi(k)).sum();
    assert_abs_diff_eq!(
        out.potential_return,
        counted + tail * phi[4],
        epsilon = 1e-9 * counted.abs()
    );
    // Plain termination counts only the steps up to the collision.
    config.sim.absorbing_collision = false;
    let plain = constant_speed(&config, s);
    assert_abs_diff_eq!(plain.potential_return, counted, epsilon = 1e-9 * counted.abs());
}

#[test]
fn a_collision_between_other_players_is_not_the_egos_and_ends_it_only_between_learners() {
    // Two target-lane players at constant speed, 20 m apart centre to centre, the follower
    // 10 m/s faster: the bumpers (5 m cars) touch after 15 m of closing, 1.5 s, so the boxes
    // overlap after step index 15 (the 16th step). The ego, at 5 m/s from x = 100, is still on
    // the ramp (x = 108 < 180).
    let mut config = smoke();
    config.scenario.n_leaders = 1;
    config.scenario.n_followers = 1;
    config.sim.feasibility = false;
    let s = scene(vec![
        car(100.0, 5.0, true),
        car(120.0, 5.0, false),
        car(100.0, 15.0, false),
    ]);
    // Learning players (keeping their speed): the collision ends the episode with the ego
    // unmerged.
    let out = &rollout(&config, &opts(&config, 1), std::slice::from_ref(&s), || {
        Fixed(vec![0.0; 3])
    })
    .remove(0);
    let c = out.collision.expect("collision");
    assert_eq!((c.step, c.a, c.b, out.steps), (15, 1, 2, 16));
    let m = EpisodeMetrics::of(out);
    assert!(m.other_collision && !m.collision && m.failure, "{m:?}");
    // Constant-speed players (no policy) do not react to each other: they drive through, the
    // overlap is recorded and the episode runs its 30 steps.
    let out = &constant_speed(&config, s);
    assert_eq!(
        (out.collision, out.others_overlapped, out.steps),
        (None, true, 30)
    );
    let m = EpisodeMetrics::of(out);
    assert!(m.other_collision && !m.collision, "{m:?}");
}

#[test]
fn an_ego_that_never_reaches_the_conflict_point_fails() {
    let mut config = smoke();
    config.scenario.n_leaders = 0;
    config.scenario.n_followers = 0;
    let s = scene(vec![car(100.0, 0.0, true)]);
    let out = &constant_speed(&config, s);
    let m = EpisodeMetrics::of(out);
    assert!(m.failure && !m.collision);
    assert_eq!(out.ego_merged_at, None);
}

#[test]
fn feasibility_holds_ttc_at_tau_behind_a_steady_leader() {
    // Target lane: a leader at 5 m/s, a follower 40 m behind at 15 m/s (TTC 4 s), both
    // "constant speed". The projection is two-sided: the follower brakes to keep its TTC, and
    // the leader, seeing a follower that would break it, speeds up a little. Each assumes the
    // other keeps its speed, and each correction only widens the gap, so the bumper-gap TTC
    // never drops below tau_s = 3 s and the gap stays above the safety gap. Without the
    // projection the follower closes 40 - 5 = 35 m at 10 m/s: after 35 steps (3.5 s) the boxes
    // touch, after step index 35 (the 36th) they overlap.
    let mut config = smoke();
    config.scenario.n_leaders = 1;
    config.scenario.n_followers = 1;
    config.sim.horizon = 20.0;
    // The projection binds the constant-speed drivers too.
    config.sim.project_non_learning = true;
    let s = scene(vec![
        car(0.0, 0.0, true),
        car(100.0, 5.0, false),
        car(60.0, 15.0, false),
    ]);
    let run = |config: &mpgdrive::Config| {
        rollout(config, &opts(config, 1), std::slice::from_ref(&s), || {
            DriverActor::new(config, Driver::ConstSpeed, Driver::ConstSpeed)
        })
        .remove(0)
    };
    let on = run(&config);
    assert!(on.collision.is_none());
    let t = on.trajectory.as_ref().unwrap();
    let clearance = config.vehicle.length + config.sim.safety_gap;
    let min_ttc = t
        .states
        .chunks(3)
        .map(|v| ttc(v[1].x - v[2].x - clearance, v[2].v - v[1].v))
        .fold(f64::INFINITY, f64::min);
    assert!(min_ttc >= 3.0 - 1e-9, "min TTC {min_ttc}");
    assert!(
        t.actions.chunks(3).all(|a| a[1] >= 0.0),
        "the leader is only ever pushed forward"
    );
    assert!(
        t.actions.chunks(3).all(|a| a[2] <= 0.0),
        "the follower only brakes"
    );
    let last = &t.states[t.states.len() - 3..];
    assert!(last[2].v < 15.0 && last[1].v > 5.0 && last[1].x - last[2].x > 5.0);
    // Learning players keeping their speed, without the projection (constant-speed players
    // would drive through each other, see the test above).
    config.sim.feasibility = false;
    let off = rollout(&config, &opts(&config, 1), std::slice::from_ref(&s), || {
        Fixed(vec![0.0; 3])
    })
    .remove(0);
    assert_eq!(off.collision.map(|c| (c.step, c.a, c.b)), Some((35, 1, 2)));
}

/// Every player repeats one raw action per step.
struct Fixed(Vec<f64>);

impl Actor for Fixed {
    fn act(&mut self, _step: usize, _scenes: &[Scene], _neighbors: &[Neighbors], out: &mut [f64]) {
        out.copy_from_slice(&self.0);
    }
}

/// Smallest bumper gap between successive target-lane players over a recorded episode.
fn min_platoon_gap(out: &mpgdrive::engine::EpisodeOutcome, n: usize, length: f64) -> f64 {
    let t = out.trajectory.as_ref().unwrap();
    t.states
        .chunks(n)
        .flat_map(|v| {
            v[1..]
                .windows(2)
                .map(|w| w[0].x - w[1].x - length)
                .collect::<Vec<_>>()
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn projected_platoon_keeps_the_safety_gap_instead_of_touching() {
    // Regression: trained players pushed a platoon into its bounds (the middle car braking
    // hard, the one behind accelerating) and the bumper-gap projection let it settle about
    // 0.05 m apart, until simultaneous corrections made the boxes overlap (90% of NE test
    // episodes ended so). Four target-lane cars at 15 m/s, 12 m apart centre to centre
    // (TTC infinite), raw actions 0, -g, +g, +g: the projection must keep every gap at least
    // `safety_gap` minus what one step of the constant-speed assumption can lose.
    let mut config = smoke();
    config.scenario.n_leaders = 2;
    config.scenario.n_followers = 2;
    config.sim.horizon = 30.0;
    let g = config.vehicle.max_accel;
    let s = scene(vec![
        car(0.0, 10.0, true),
        car(236.0, 15.0, false),
        car(224.0, 15.0, false),
        car(212.0, 15.0, false),
        car(200.0, 15.0, false),
    ]);
    let run = |config: &mpgdrive::Config| {
        rollout(config, &opts(config, 1), std::slice::from_ref(&s), || {
            Fixed(vec![0.0, 0.0, -g, g, g])
        })
        .remove(0)
    };
    let with_gap = run(&config);
    assert!(with_gap.collision.is_none());
    let gap = min_platoon_gap(&with_gap, 5, config.vehicle.length);
    // dt * dv over one step with at most g of change on each side: 0.1 * 2 * 0.981 m.
    let slack = config.sim.dt * 2.0 * g * config.sim.dt;
    assert!(gap >= config.sim.safety_gap - slack, "min gap {gap}");
    config.sim.safety_gap = 0.0;
    let bare = run(&config);
    let bare_gap = min_platoon_gap(&bare, 5, config.vehicle.length);
    assert!(
        bare_gap < 0.5,
        "without the safety gap the platoon closes up: {bare_gap}"
    );
}

#[test]
fn a_ramp_queue_keeps_its_ttc_as_the_target_lane_does() {
    // A ramp car at 100 m and 15 m/s behind a ramp car at 115 m and 5 m/s, a target-lane car
    // beside. One step on (eq. 1 moves x with the current speed) the bumper gap less the 2 m
    // safety gap is (115.5 - 101.5) - 7 = 7 m, so TTC >= 3 s needs v' <= 5 + 7 / 3: the bound is
    // (7.333 - 15) / 0.1 = -76.7 m/s^2, clipped to -g. Alone on the ramp it would apply +g.
    let mut config = smoke();
    config.sim.merge_gate = false;
    let rules = mpgdrive::world::WorldRules::new(&config);
    let queue = scene(vec![
        car(100.0, 15.0, true),
        car(115.0, 5.0, true),
        car(100.0, 12.0, false),
    ]);
    let (mut order, mut nb) = (Vec::new(), Vec::new());
    mpgdrive::world::neighbors::find_neighbors(&queue, &mut order, &mut nb);
    let a = mpgdrive::world::step::applied_action(&rules, true, &queue, 0, &nb[0], 9.81);
    assert_abs_diff_eq!(a, -9.81, epsilon = 1e-12);
    let alone = scene(vec![car(100.0, 15.0, true), car(100.0, 12.0, false)]);
    mpgdrive::world::neighbors::find_neighbors(&alone, &mut order, &mut nb);
    let a = mpgdrive::world::step::applied_action(&rules, true, &alone, 0, &nb[0], 9.81);
    assert_abs_diff_eq!(a, 9.81, epsilon = 1e-12);
}

#[test]
fn across_lanes_a_target_lane_car_keeps_its_ttc_to_the_ramp_vehicles_beside_it() {
    // configs/paper.toml with `sim.feasibility_across_lanes`: 5 m cars, 2 m safety gap, tau_s
    // = 3 s, dt = 0.1 s. Ramp car R at 120 m and 5 m/s; target-lane car T at 100 m and 15 m/s,
    // raw +3. R is T's nearest leader: one step on the gap less the clearance is (120.5 -
    // 101.5) - 7 = 12 m, so v' <= 5 + 12 / 3 = 9 and a <= (9 - 15) / 0.1 = -60, clipped to -g.
    // Same-lane neighbours only (the setting off), T keeps its +3.
    let mut config = common::paper();
    config.sim.feasibility_across_lanes = true;
    let act = |config: &mpgdrive::Config, s: &mpgdrive::world::state::Scene, i: usize, raw: f64| {
        let (mut order, mut nb) = (Vec::new(), Vec::new());
        mpgdrive::world::neighbors::find_neighbors(s, &mut order, &mut nb);
        let rules = mpgdrive::world::WorldRules::new(config);
        mpgdrive::world::step::applied_action(&rules, true, s, i, &nb[i], raw)
    };
    let behind = scene(vec![car(120.0, 5.0, true), car(100.0, 15.0, false)]);
    assert_abs_diff_eq!(act(&config, &behind, 1, 3.0), -9.81, epsilon = 1e-12);
    let mut lane_only = config.clone();
    lane_only.sim.feasibility_across_lanes = false;
    assert_abs_diff_eq!(act(&lane_only, &behind, 1, 3.0), 3.0, epsilon = 1e-12);
    // T at 130 m and 10 m/s ahead of R at 115 m and 12 m/s, raw -8: R is T's nearest
    // follower, gap (131 - 116.2) - 7 = 7.8 m, so v' >= 12 - 7.8 / 3 = 9.4, a >= -6.
    let ahead = scene(vec![car(115.0, 12.0, true), car(130.0, 10.0, false)]);
    assert_abs_diff_eq!(act(&config, &ahead, 1, -8.0), -6.0, epsilon = 1e-9);
    assert_abs_diff_eq!(act(&lane_only, &ahead, 1, -8.0), -8.0, epsilon = 1e-12);
    // A ramp vehicle is bound by its own lane only: R keeps its raw action.
    assert_abs_diff_eq!(act(&config, &ahead, 0, 1.0), 1.0, epsilon = 1e-12);
}

/// Applied actions of a leader at 120 m (10 m/s) and a follower at 100 m (14 m/s) in the
/// target lane, raw -3 and +3 m/s^2, with the ego far behind on the ramp, over `steps`.
fn pair_actions(order: mpgdrive::config::ProjectionOrder, steps: usize) -> Vec<[f64; 2]> {
    let mut config = common::paper();
    // The shared order at its default, halving (`configs/paper.toml` has each end take 3/4).
    (config.sim.projection_order, config.sim.shared_correction) = (order, 0.5);
    pair_actions_in(&config, steps)
}

/// [`pair_actions`] in `config`'s world.
fn pair_actions_in(config: &mpgdrive::config::Config, steps: usize) -> Vec<[f64; 2]> {
    let mut o = opts(config, 1);
    o.recording = Recording::Full;
    o.steps = steps;
    let s = scene(vec![
        car(0.0, 10.0, true),
        car(120.0, 10.0, false),
        car(100.0, 14.0, false),
    ]);
    let out = rollout(config, &o, &[s], || Fixed(vec![0.0, -3.0, 3.0]))
        .pop()
        .unwrap();
    let t = out.trajectory.unwrap();
    t.actions.chunks(3).map(|a| [a[1], a[2]]).collect()
}

#[test]
fn the_sequential_projection_corrects_a_closing_speed_once() {
    use mpgdrive::config::ProjectionOrder::{Sequential, Simultaneous};
    // One step by hand (clearance 5 + 2 m, tau_s = 3 s, dt = 0.1 s): after it the gap is
    // (120 + 1) - (100 + 1.4) - 7 = 12.6 m, so 12.6 / 3 = 4.2 m/s of closing speed is allowed.
    // The leader's follower bound: v' >= 14 - 4.2 = 9.8, a >= -2 (raw -3: pushed up to -2).
    // Simultaneous, the follower's leader bound reads the leader's current 10 m/s:
    // v' <= 14.2, a <= +2. Sequential, its settled 9.8 m/s: v' <= 14.0, a <= 0.
    let [lead, follow] = pair_actions(Simultaneous, 1)[0];
    assert_abs_diff_eq!(lead, -2.0, epsilon = 1e-9);
    assert_abs_diff_eq!(follow, 2.0, epsilon = 1e-9);
    let [lead, follow] = pair_actions(Sequential, 1)[0];
    assert_abs_diff_eq!(lead, -2.0, epsilon = 1e-9);
    assert_abs_diff_eq!(follow, 0.0, epsilon = 1e-9);
}

#[test]
fn the_simultaneous_projection_chatters_where_the_sequential_one_settles() {
    use mpgdrive::config::ProjectionOrder::{Sequential, Simultaneous};
    use mpgdrive::eval::scenario_sets::longest_alternation;
    // The same pair for 20 s: simultaneous, both players correct the same closing speed, then
    // both bounds come free and the raw actions close the gap again, so every step flips the
    // sign of both actions (from -2 / +2 to +3.47 / -3.47 and on). Sequential: the leader is
    // pushed on once, the follower keeps its speed, no flip after the first step.
    let flips = |order| {
        let a = pair_actions(order, 200);
        let lead: Vec<f64> = a.iter().map(|x| x[0]).collect();
        let follow: Vec<f64> = a.iter().map(|x| x[1]).collect();
        (longest_alternation(&lead), longest_alternation(&follow))
    };
    assert_eq!(flips(Simultaneous), (199, 199));
    let (lead, follow) = flips(Sequential);
    assert!(lead <= 1 && follow <= 1, "{lead} {follow}");
    let second = pair_actions(Simultaneous, 2)[1];
    assert_abs_diff_eq!(second[0], 3.466_666_666_666_6, epsilon = 1e-9);
}

#[test]
fn the_shared_projection_halves_a_pairs_correction_and_settles() {
    use mpgdrive::config::ProjectionOrder::Shared;
    use mpgdrive::eval::scenario_sets::longest_alternation;
    // The pair above. Step 1: the pair is within its TTC at its current speeds (closing 4 of
    // 4.2 m/s allowed), only the raw actions violate it: no halving, -2 / +2 as simultaneous.
    // Step 2 (leader 121 m at 9.8 m/s, follower 101.4 m at 14.2): after it the gap is
    // (121 + 0.98) - (101.4 + 1.42) - 7 = 12.16 m, 4.0533 m/s allowed, 4.4 closing now: the
    // leader's push (14.2 - 4.0533 - 9.8) / 0.1 = +3.4667 and the follower's hold -3.4667
    // are halved to +-1.7333, which together close the gap by the allowed 4.0533 m/s, once.
    let a = pair_actions(Shared, 200);
    assert_abs_diff_eq!(a[0][0], -2.0, epsilon = 1e-9);
    assert_abs_diff_eq!(a[0][1], 2.0, epsilon = 1e-9);
    assert_abs_diff_eq!(a[1][0], 1.733_333_333_333_3, epsilon = 1e-9);
    assert_abs_diff_eq!(a[1][1], -1.733_333_333_333_3, epsilon = 1e-9);
    let lead: Vec<f64> = a.iter().map(|x| x[0]).collect();
    let follow: Vec<f64> = a.iter().map(|x| x[1]).collect();
    let flips = (longest_alternation(&lead), longest_alternation(&follow));
    assert!(flips.0 <= 1 && flips.1 <= 1, "{flips:?}");
}

#[test]
fn a_larger_shared_correction_overshoots_and_its_alternation_decays() {
    use mpgdrive::config::ProjectionOrder::Shared;
    use mpgdrive::eval::scenario_sets::longest_alternation;
    // The pair above with each end taking 3/4 of its correction. Step 2 (see the halving
    // test): the push +3.4667 and the hold -3.4667 scale to +-2.6, 1.5 times the closing
    // speed to correct, so the pair overshoots by half of it. Each later step flips the sign
    // of the pair's excess and halves it: the leader's actions go -0.44, +1.32, +0.26, +0.78
    // and settle near the halving order's, within a second, where the simultaneous order's
    // flips never stop.
    let mut config = common::paper();
    config.sim.projection_order = Shared;
    config.sim.shared_correction = 0.75;
    let a = pair_actions_in(&config, 200);
    assert_abs_diff_eq!(a[0][0], -2.0, epsilon = 1e-9);
    assert_abs_diff_eq!(a[1][0], 2.6, epsilon = 1e-9);
    assert_abs_diff_eq!(a[1][1], -2.6, epsilon = 1e-9);
    let lead: Vec<f64> = a.iter().map(|x| x[0]).collect();
    let follow: Vec<f64> = a.iter().map(|x| x[1]).collect();
    let flips = (longest_alternation(&lead), longest_alternation(&follow));
    assert!(flips.0 > 1 && flips.0 < 10 && flips.1 < 10, "{flips:?}");
    // At 1 the shared order is the simultaneous one, bit for bit.
    config.sim.shared_correction = 1.0;
    let simultaneous = pair_actions(mpgdrive::config::ProjectionOrder::Simultaneous, 200);
    assert_eq!(pair_actions_in(&config, 200), simultaneous);
}
