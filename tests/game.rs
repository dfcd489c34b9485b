//! Reward terms at hand-picked states, the Theorem 3 potential, symmetry, and the MPG check.

mod common;

use approx::assert_abs_diff_eq;
use common::{car, scene, smoke};
use mpgdrive::eval::mpg_check::{CheckSettings, check_mpg};
use mpgdrive::game::terms::{
    comfort, conflict_time_gap, conflict_time_gap_before, conflict_time_gap_signed, same_lane_ttc,
    speed_tracking,
};
use mpgdrive::game::{PairReward, PairTerms, PaperReward, StepRewards};
use mpgdrive::world::sampler::sample_scene;
use mpgdrive::world::state::Vehicle;
use proptest::prelude::*;

#[test]
fn self_terms_at_hand_picked_states() {
    assert_eq!(speed_tracking(&12.0, 15.0), -9.0);
    assert_eq!(speed_tracking(&15.0, 15.0), 0.0);
    assert_eq!(comfort(&-2.0), -4.0);
}

#[test]
fn same_lane_ttc_term_both_branches() {
    // |dv| = 5 > v_c = 1: TTC = 20 / 5 = 4 s, term = -1 / (4 + 0.1).
    assert_abs_diff_eq!(
        same_lane_ttc(&0.0, &15.0, &20.0, &10.0, 1.0, 0.1),
        -1.0 / 4.1,
        epsilon = 1e-15
    );
    // |dv| = 0.5 <= v_c: term = -1 / (20 / 1 + 0.1).
    assert_abs_diff_eq!(
        same_lane_ttc(&0.0, &15.0, &20.0, &14.5, 1.0, 0.1),
        -1.0 / 20.1,
        epsilon = 1e-15
    );
    // Continuous at |dv| = v_c.
    assert_abs_diff_eq!(
        same_lane_ttc(&0.0, &15.0, &20.0, &14.0, 1.0, 0.1),
        -1.0 / 20.1,
        epsilon = 1e-15
    );
}

#[test]
fn conflict_time_gap_term_eq_28() {
    // T_i = 30 / 10.1 = 2.9703 s, T_j = 20 / 15.1 = 1.3245 s;
    // -1 / (sqrt(T_i T_j) (T_i - T_j)^2 + 0.1) = -0.1827315 (computed independently).
    let r = conflict_time_gap(&150.0, &10.0, &160.0, &15.0, 180.0, 0.1);
    assert_abs_diff_eq!(r, -0.182_731_493_509_931_56, epsilon = 1e-12);
    // Same arrival time (10 / 10.1 = 20 / 20.2 s): the largest penalty, -1 / eps.
    assert_abs_diff_eq!(
        conflict_time_gap(&170.0, &10.0, &160.0, &20.1, 180.0, 0.1),
        -10.0,
        epsilon = 1e-9
    );
}

#[test]
fn the_conflict_term_can_end_at_the_conflict_point() {
    // Both before x_c: eq. (28) as above.
    let r = conflict_time_gap_before([&150.0, &10.0, &160.0, &15.0], 180.0, 0.0, 0.1);
    assert_abs_diff_eq!(r, -0.182_731_493_509_931_56, epsilon = 1e-12);
    // The target-lane car 10 m past x_c at 10.1 m/s and the ramp vehicle 10 m before it at
    // 10.1 m/s: the paper's |x - x_c| gives both T = 10 / 10.2 s, the largest penalty -1 / eps;
    // ended at x_c, 0 (either order of the pair).
    assert_abs_diff_eq!(
        conflict_time_gap(&170.0, &10.1, &190.0, &10.1, 180.0, 0.1),
        -10.0,
        epsilon = 1e-9
    );
    assert_eq!(
        conflict_time_gap_before([&170.0, &10.1, &190.0, &10.1], 180.0, 0.0, 0.1),
        0.0
    );
    assert_eq!(
        conflict_time_gap_before([&190.0, &10.1, &170.0, &10.1], 180.0, 0.0, 0.1),
        0.0
    );
    // With a clearance of 12 m the car 10 m past x_c still counts (the same -1 / eps), and one
    // 13 m past (T = 13 / 10.2 s on both sides) no longer does.
    assert_abs_diff_eq!(
        conflict_time_gap_before([&170.0, &10.1, &190.0, &10.1], 180.0, 12.0, 0.1),
        -10.0,
        epsilon = 1e-9
    );
    assert_eq!(
        conflict_time_gap_before([&167.0, &10.1, &193.0, &10.1], 180.0, 12.0, 0.1),
        0.0
    );
}

#[test]
fn the_conflict_term_can_use_signed_times() {
    // Both before x_c: the signed times are the paper's, so eq. (28) as above.
    let r = conflict_time_gap_signed(&150.0, &10.0, &160.0, &15.0, 180.0, 0.1);
    assert_abs_diff_eq!(r, -0.182_731_493_509_931_56, epsilon = 1e-12);
    // The ramp vehicle 10 m before x_c and the target-lane car 10 m past it, both at 10.1 m/s:
    // T = +10 / 10.2 and -10 / 10.2 s, 1.96 s apart at x_c, where |x - x_c| gave -1 / eps.
    // -1 / (0.98039 * 1.96078^2 + 0.1) = -0.2584454 (computed independently); symmetric.
    for (a, b) in [(170.0, 190.0), (190.0, 170.0)] {
        assert_abs_diff_eq!(
            conflict_time_gap_signed(&a, &10.1, &b, &10.1, 180.0, 0.1),
            -0.258_445_392_059_449_83,
            epsilon = 1e-12
        );
    }
    // 10 m before at 12 m/s, the car 5 m past at 15: T = 10 / 12.1 and -5 / 15.1 s,
    // -1.2484849 (computed independently).
    assert_abs_diff_eq!(
        conflict_time_gap_signed(&170.0, &12.0, &185.0, &15.0, 180.0, 0.1),
        -1.248_484_902_066_080_2,
        epsilon = 1e-12
    );
}

/// The potential of Theorem 3 computed independently, straight from the terms.
fn theorem3_potential(r: &PaperReward, v: &[Vehicle], u: &[f64]) -> f64 {
    let [ws, wc, wt, wg] = r.weights;
    let mut phi = 0.0;
    for i in 0..v.len() {
        phi += ws * speed_tracking(&v[i].v, r.v_desired) + wc * comfort(&u[i]);
        for j in 0..i {
            phi += if v[i].on_ramp == v[j].on_ramp {
                wt * same_lane_ttc(&v[i].x, &v[i].v, &v[j].x, &v[j].v, r.v_c, r.epsilon)
            } else {
                wg * conflict_time_gap(&v[i].x, &v[i].v, &v[j].x, &v[j].v, r.conflict_point, r.epsilon)
            };
        }
    }
    phi
}

#[test]
fn potential_equals_theorem_3_sum() {
    let config = smoke();
    let reward = PaperReward::new(&config);
    let mut out = StepRewards::default();
    for k in 0..20 {
        let s = sample_scene(&config, 3, k);
        let u: Vec<f64> = (0..s.len()).map(|i| (i as f64 - 4.0) * 0.7).collect();
        out.compute(&reward, &reward, &s.vehicles, &u, &[]);
        let expected = theorem3_potential(&reward, &s.vehicles, &u);
        assert_abs_diff_eq!(out.potential, expected, epsilon = 1e-9 * expected.abs().max(1.0));
        // sum_i r_i counts each pair twice and each self term once.
        let self_sum: f64 = s
            .vehicles
            .iter()
            .zip(&u)
            .map(|(v, u)| reward.weights[0] * speed_tracking(&v.v, 15.0) + reward.weights[1] * comfort(u))
            .sum();
        let total: f64 = out.reward.iter().sum();
        assert_abs_diff_eq!(
            total,
            2.0 * out.potential - self_sum,
            epsilon = 1e-9 * total.abs().max(1.0)
        );
    }
}

#[test]
fn logged_terms_recombine_into_the_reward() {
    let config = smoke();
    let reward = PaperReward::new(&config);
    let s = scene(vec![
        car(170.0, 10.0, true),
        car(185.0, 12.0, false),
        car(160.0, 15.0, false),
    ]);
    let u = [1.0, -0.5, 0.0];
    let mut out = StepRewards::default();
    out.compute(&reward, &reward, &s.vehicles, &u, &[]);
    let [ws, wc, wt, wg] = reward.weights;
    for (t, r) in out.terms.iter().zip(&out.reward) {
        assert_abs_diff_eq!(
            ws * t.speed + wc * t.comfort + wt * t.ttc + wg * t.conflict,
            *r,
            epsilon = 1e-12
        );
    }
    // The ego (ramp) has no same-lane partner; the two target-lane cars none in another lane
    // but the ego.
    assert_eq!(out.terms[0].ttc, 0.0);
    assert_abs_diff_eq!(out.terms[1].ttc, out.terms[2].ttc, epsilon = 1e-15);
}

proptest! {
    #[test]
    fn pair_reward_is_symmetric(
        xi in 0.0..400.0f64, vi in 0.0..30.0f64, ri in any::<bool>(),
        xj in 0.0..400.0f64, vj in 0.0..30.0f64, rj in any::<bool>(),
    ) {
        let reward = PaperReward::new(&smoke());
        let a = car(xi, vi, ri);
        let b = car(xj, vj, rj);
        let r_ab = reward.pair(0, 1, &a, &b).reward;
        let r_ba = reward.pair(1, 0, &b, &a).reward;
        prop_assert_eq!(r_ab, r_ba);
        prop_assert!(r_ab.is_finite() && r_ab <= 0.0);
    }
}

/// The paper's pair reward, scaled up for the higher-numbered player of each pair: r_ij != r_ji.
struct Asymmetric(PaperReward);

impl PairReward for Asymmetric {
    fn pair(&self, i: usize, j: usize, a: &Vehicle, b: &Vehicle) -> PairTerms {
        let terms = self.0.pair(i, j, a, b);
        let scale = if i > j { 1.5 } else { 1.0 };
        PairTerms {
            reward: scale * terms.reward,
            ..terms
        }
    }
    fn is_symmetric(&self) -> bool {
        false
    }
}

fn settings(exact: bool) -> CheckSettings {
    CheckSettings {
        policies: 2,
        states: 6,
        seed: 11,
        exact,
        tolerance: 1e-9,
        threads: 2,
    }
}

#[test]
fn check_mpg_passes_the_paper_reward_in_the_theorem_setting() {
    let config = smoke();
    let mut calls = 0;
    let report = check_mpg(&config, &settings(true), &PaperReward::new(&config), &mut || {
        calls += 1
    });
    assert_eq!(
        calls,
        2 * (9 + 1),
        "one base and nine deviated evaluations per joint policy"
    );
    assert!(report.is_potential_game, "gap {}", report.max_relative_gap);
    assert!(report.max_relative_gap < 1e-9);
    assert_eq!(report.players.len(), 9);
    assert!(
        report.players.iter().all(|p| p.min_abs_delta_j > 1e-6),
        "deviations must change J_i"
    );
}

#[test]
fn check_mpg_flags_an_asymmetric_pair_reward() {
    let config = smoke();
    let report = check_mpg(
        &config,
        &settings(true),
        &Asymmetric(PaperReward::new(&config)),
        &mut || {},
    );
    assert!(!report.is_potential_game);
    assert!(report.max_relative_gap > 1e-3, "gap {}", report.max_relative_gap);
}

#[test]
fn check_mpg_measures_a_gap_with_projection_and_termination_on() {
    let mut config = smoke();
    config.sim.horizon = 10.0;
    let report = check_mpg(&config, &settings(false), &PaperReward::new(&config), &mut || {});
    assert!(report.feasibility && report.terminate_on_collision);
    assert!(
        report.max_relative_gap > 1e-9,
        "feasibility couples players' transitions"
    );
}

#[test]
fn check_mpg_passes_merge_traffic_in_the_theorem_setting() {
    // Traffic episodes: 3 ramp vehicles and 10 target-lane vehicles, all players.
    let mut config = common::traffic();
    config.sim.horizon = 10.0;
    let report = check_mpg(&config, &settings(true), &PaperReward::new(&config), &mut || {});
    assert_eq!(report.players.len(), 13);
    assert!(report.max_relative_gap < 1e-9, "gap {}", report.max_relative_gap);
    assert!(report.players.iter().all(|p| p.min_abs_delta_j > 1e-6));
}

#[test]
fn the_entry_rule_couples_players_unless_the_check_replays_its_decisions() {
    // The traffic world keeps its entry rule (a gap or a hold at the ramp's end) and its
    // 40 m merge zone in the exact setting. Decided live for every player (the configured
    // setting with the projection and termination off: the same physics), a deviation moves
    // the others' entries and the identity fails; replayed for all but the deviating player,
    // it holds.
    let mut config = common::traffic();
    config.sim.horizon = 10.0;
    assert_eq!(config.scenario.entry, mpgdrive::config::Entry::Gap);
    assert!(config.scenario.merge_zone > 0.0);
    config.sim.feasibility = false;
    config.sim.terminate_on_collision = false;
    let live = check_mpg(&config, &settings(false), &PaperReward::new(&config), &mut || {});
    assert!(!live.feasibility && !live.terminate_on_collision);
    assert!(live.max_relative_gap > 1e-6, "gap {}", live.max_relative_gap);
    let replayed = check_mpg(&config, &settings(true), &PaperReward::new(&config), &mut || {});
    assert!(
        replayed.max_relative_gap < 1e-9,
        "gap {}",
        replayed.max_relative_gap
    );
}

#[test]
fn a_ramp_speed_weight_weighs_a_ramp_vehicles_speed_term_alone() {
    // A ramp vehicle at 10 m/s and a target-lane vehicle at 12 m/s, v_d = 15: raising the
    // ramp weight from w_speed = 1 to 3 adds 2 * -(10 - 15)^2 = -50 to the ramp vehicle's
    // reward and to the potential; the target-lane vehicle's reward does not move.
    let mut config = common::traffic();
    config.reward.w_speed = 1.0;
    config.reward.w_speed_ramp = None; // w_speed (configs/traffic.toml sets 2)
    let vehicles = [car(150.0, 10.0, true), car(170.0, 12.0, false)];
    let u = [0.5, -1.0];
    let step = |config: &mpgdrive::config::Config| {
        let reward = PaperReward::new(config);
        let mut out = StepRewards::default();
        out.compute(&reward, &reward, &vehicles, &u, &[]);
        out
    };
    let one = step(&config);
    config.reward.w_speed_ramp = Some(3.0);
    let three = step(&config);
    assert_abs_diff_eq!(three.reward[0] - one.reward[0], -50.0, epsilon = 1e-12);
    assert_eq!(three.reward[1], one.reward[1]);
    assert_abs_diff_eq!(three.potential - one.potential, -50.0, epsilon = 1e-12);
}

#[test]
fn check_mpg_passes_merge_traffic_with_the_reward_options() {
    // The ramp weight follows each vehicle's own lane: still a self term (Theorem 1); the
    // conflict term that ends past x_c, or reads signed times, is still symmetric (Theorem 2).
    let mut config = common::traffic();
    config.sim.horizon = 10.0;
    config.reward.w_speed_ramp = Some(3.0);
    config.reward.conflict_ends_at_x_c = true;
    config.reward.conflict_clearance = 10.0;
    let report = check_mpg(&config, &settings(true), &PaperReward::new(&config), &mut || {});
    assert!(report.max_relative_gap < 1e-9, "gap {}", report.max_relative_gap);
    config.reward.conflict_ends_at_x_c = false;
    config.reward.conflict_signed_time = true;
    let report = check_mpg(&config, &settings(true), &PaperReward::new(&config), &mut || {});
    assert!(report.max_relative_gap < 1e-9, "gap {}", report.max_relative_gap);
}

#[test]
fn humans_are_no_players_of_the_potential() {
    // Three cars: a ramp player, a target-lane player 20 m ahead and a human 30 m behind it.
    // phi = the players' own terms + every pair with a player; the human's own terms are out.
    let config = common::traffic();
    let reward = PaperReward::new(&config);
    let mut s = scene(vec![
        car(150.0, 12.0, true),
        car(170.0, 14.0, false),
        car(140.0, 15.0, false),
    ]);
    let u = [0.5, -1.0, 2.0];
    let mut all = StepRewards::default();
    all.compute(&reward, &reward, &s.vehicles, &u, &[]);
    s.humans = vec![false, false, true];
    let mut mixed = StepRewards::default();
    mixed.compute(&reward, &reward, &s.vehicles, &u, &s.humans);
    // By hand: the human's own terms are -(15 - 15)^2 - 0.5 * 2^2 = -2 (w_speed 1, w_comfort 0.5).
    assert!((all.potential - mixed.potential - (-2.0)).abs() < 1e-12);
    assert_eq!(all.reward, mixed.reward, "rewards do not depend on who is human");
    // Two humans: their pair leaves the potential too.
    s.humans = vec![false, true, true];
    let mut two = StepRewards::default();
    two.compute(&reward, &reward, &s.vehicles, &u, &s.humans);
    let r12 = reward.pair(1, 2, &s.vehicles[1], &s.vehicles[2]).reward;
    let own1 = -(14.0f64 - 15.0).powi(2) - 0.5;
    assert!((mixed.potential - two.potential - own1 - r12).abs() < 1e-12);
}

#[test]
fn a_scene_of_its_own_desired_speed_tracks_it_with_a_relative_weight() {
    // smoke.toml: v_d = 15, w_speed = 1, w_comfort = 0.5. One vehicle alone (no pair terms)
    // at 27 m/s applying 1 m/s^2 in a scene of v_d = 30: speed term -(27 - 30)^2 = -9,
    // weighted by (15 / 30)^2 = 1/4, comfort -0.5: r = -2.25 - 0.5 = -2.75. Without the
    // scene's own v_d: -(27 - 15)^2 - 0.5 = -144.5.
    let config = smoke();
    let reward = PaperReward::new(&config);
    let mut s = scene(vec![car(100.0, 27.0, false)]);
    let mut out = StepRewards::default();
    out.compute(&reward.in_scene(&s), &reward, &s.vehicles, &[1.0], &[]);
    assert_abs_diff_eq!(out.reward[0], -144.5, epsilon = 1e-12);
    s.v_desired = Some(30.0);
    let own = reward.in_scene(&s);
    out.compute(&own, &own, &s.vehicles, &[1.0], &[]);
    assert_abs_diff_eq!(out.reward[0], -2.75, epsilon = 1e-12);
    assert_abs_diff_eq!(out.potential, -2.75, epsilon = 1e-12);
    // The logged terms stay unweighted.
    assert_abs_diff_eq!(out.terms[0].speed, -9.0, epsilon = 1e-12);
}

#[test]
fn the_egos_reward_alone_is_the_full_computations_bit_for_bit() {
    // Sampled scenes (the ego on the ramp among eight target-lane players), the paper's
    // symmetric pair reward and an asymmetric one, arbitrary actions.
    let config = smoke();
    let paper = PaperReward::new(&config);
    let asymmetric = Asymmetric(PaperReward::new(&config));
    for index in 0..20 {
        let s = sample_scene(&config, 5, index);
        let u: Vec<f64> = (0..s.len()).map(|i| 0.7 * i as f64 - 2.5).collect();
        for pair in [&paper as &dyn PairReward, &asymmetric] {
            let (mut all, mut ego) = (StepRewards::default(), StepRewards::default());
            all.compute(&paper, pair, &s.vehicles, &u, &[]);
            ego.compute_ego(&paper, pair, &s.vehicles, &u);
            assert_eq!(ego.reward.len(), 1);
            assert_eq!(ego.reward[0].to_bits(), all.reward[0].to_bits(), "scene {index}");
            assert_eq!(ego.terms[0], all.terms[0]);
            assert!(all.potential.is_finite() && ego.potential.is_nan());
        }
    }
}
