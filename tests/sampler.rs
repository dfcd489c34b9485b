//! Initial states: headway and TTC rules, strata, reproducibility.

mod common;

use common::{paper, smoke};
use mpgdrive::config::NearMergeConfig;
use mpgdrive::world::safety::ttc;
use mpgdrive::world::sampler::{
    family_scene, sample_probe_scenes, sample_scene, sample_scenes, sample_training_scenes, scenario_rng,
    stratum,
};
use mpgdrive::world::scenarios::Preset;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    #[test]
    fn every_sampled_state_meets_headway_and_ttc_rules(seed in any::<u64>(), index in 0usize..10_000) {
        let config = paper();
        let s = sample_scene(&config, seed, index);
        prop_assert_eq!(s.len(), 9);
        prop_assert!(s.vehicles[0].on_ramp);
        prop_assert!(s.vehicles[1..].iter().all(|v| !v.on_ramp));
        // Players are numbered front to back: 1..4 ahead of the ego, 5..8 behind.
        for w in s.vehicles[1..5].windows(2) { prop_assert!(w[0].x > w[1].x); }
        for w in s.vehicles[5..].windows(2) { prop_assert!(w[0].x > w[1].x); }
        prop_assert!(s.vehicles[4].x > s.vehicles[0].x && s.vehicles[5].x < s.vehicles[0].x);
        // Every successive follower/leader pair along the road, ego included.
        let mut order: Vec<_> = s.vehicles.iter().collect();
        order.sort_by(|a, b| a.x.total_cmp(&b.x));
        for w in order.windows(2) {
            let (follower, leader) = (w[0], w[1]);
            let headway = leader.x - follower.x;
            prop_assert!(headway >= 7.0 - 1e-9, "headway {}", headway);
            prop_assert!(ttc(headway, follower.v - leader.v) >= 4.0 - 1e-9);
        }
        let p = &config.sampling;
        let ego = s.ego();
        prop_assert!(ego.x >= p.ego_position[0] && ego.x <= p.ego_position[1]);
        prop_assert!(ego.v >= p.ego_speed[0] && ego.v <= p.ego_speed[1]);
        prop_assert!(s.vehicles.iter().all(|v| v.v >= 0.0 && v.v <= 30.0));
    }
}

#[test]
fn each_stratum_is_reached_and_its_cell_respected() {
    let config = paper();
    let [np, nv] = config.sampling.strata;
    let p = &config.sampling;
    let (wp, wv) = (
        (p.ego_position[1] - p.ego_position[0]) / np as f64,
        (p.ego_speed[1] - p.ego_speed[0]) / nv as f64,
    );
    let mut seen = vec![false; np * nv];
    for (k, s) in sample_scenes(&config, 5, 0, 2 * np * nv).iter().enumerate() {
        let (cp, cv) = stratum(&config, k);
        seen[cp * nv + cv] = true;
        let ego = s.ego();
        let lo_x = p.ego_position[0] + wp * cp as f64;
        let lo_v = p.ego_speed[0] + wv * cv as f64;
        assert!(
            ego.x >= lo_x && ego.x <= lo_x + wp,
            "scenario {k}: x {} outside its cell",
            ego.x
        );
        assert!(
            ego.v >= lo_v && ego.v <= lo_v + wv,
            "scenario {k}: v {} outside its cell",
            ego.v
        );
    }
    assert!(
        seen.iter().all(|&s| s),
        "every stratum is reached in the first n_p * n_v scenarios"
    );
}

#[test]
fn same_seed_same_scenes_and_batches_do_not_matter() {
    let config = smoke();
    let all = sample_scenes(&config, 42, 0, 10);
    assert_eq!(all, sample_scenes(&config, 42, 0, 10));
    assert_eq!(&all[4..], &sample_scenes(&config, 42, 4, 6)[..]);
    assert_ne!(all, sample_scenes(&config, 43, 0, 10));
}

#[test]
fn a_near_merge_share_redraws_only_the_last_states_of_a_minibatch_with_the_same_draws() {
    let mut config = paper();
    config.train.batch = 8;
    config.train.near_merge = None;
    assert_eq!(
        sample_training_scenes(&config, 9, 3),
        sample_scenes(&config, 9, 24, 8),
        "without near_merge a minibatch is the stratified draws"
    );
    config.train.near_merge = Some(NearMergeConfig {
        share: 0.3, // round(2.4) = 2 states
        ego_position: [150.0, 178.0],
        ego_speed: [0.0, 8.0],
    });
    let batch = sample_training_scenes(&config, 9, 3);
    let plain = sample_scenes(&config, 9, 24, 8);
    assert_eq!(batch[..6], plain[..6]);
    let p = &config.sampling;
    for k in 6..8 {
        // Same stream: the same uniform draw in the stratum's cell, mapped to the new range
        // (4 x 4 strata: cells 20 m x 3 m before, 7 m x 2 m now).
        let (cp, cv) = stratum(&config, 24 + k);
        let u_x = (plain[k].ego().x - p.ego_position[0]) / 20.0 - cp as f64;
        let u_v = (plain[k].ego().v - p.ego_speed[0]) / 3.0 - cv as f64;
        let ego = batch[k].ego();
        assert!(
            (ego.x - (150.0 + 7.0 * (cp as f64 + u_x))).abs() < 1e-9,
            "state {k}: x {}",
            ego.x
        );
        assert!(
            (ego.v - 2.0 * (cv as f64 + u_v)).abs() < 1e-9,
            "state {k}: v {}",
            ego.v
        );
        // The players one headway after another from the ego, as in the stratified draw
        // (the same headway draws).
        for i in 1..9 {
            let offset = |s: &mpgdrive::world::state::Scene| s.vehicles[i].x - s.ego().x;
            assert!((offset(&batch[k]) - offset(&plain[k])).abs() < 1e-9, "player {i}");
        }
    }
}

#[test]
fn a_scenario_share_draws_the_states_before_the_near_merge_ones_from_the_papers_scenarios() {
    let mut config = paper();
    config.train.batch = 10;
    config.train.probe_scenarios = 6;
    config.train.near_merge = Some(NearMergeConfig {
        share: 0.2, // the last 2 states
        ego_position: [150.0, 178.0],
        ego_speed: [0.0, 8.0],
    });
    config.train.scenario_share = 0.0;
    let without = sample_training_scenes(&config, 9, 3);
    assert_eq!(sample_probe_scenes(&config, 9), sample_scenes(&config, 9, 0, 6));
    // round(0.3 * 8) = 2 of the 8 states before the near-merge ones: indices 36 and 37.
    config.train.scenario_share = 0.3;
    let with = sample_training_scenes(&config, 9, 3);
    assert_eq!(with[..6], without[..6]);
    assert_eq!(with[8..], without[8..]);
    // Index 36 (even) is scenario 1's description, 37 (odd) scenario 2's, each read from the
    // index's own stream of seed 9.
    assert_eq!(with[6], family_scene(&config, 9, 36));
    assert_eq!(with[7], family_scene(&config, 9, 37));
    let one = Preset::One.draw_state(&mut scenario_rng(9, 36));
    let two = Preset::Two.draw_state(&mut scenario_rng(9, 37));
    assert_eq!(with[6], one.scene(&config));
    assert_eq!(with[7], two.scene(&config));
    // Scenario 1: followers above v_d = 15 and "5" 100-140 m behind the ego; scenario 2: "5"
    // 4-8 m/s faster than the ego.
    let (ego, five) = (with[6].ego(), &with[6].vehicles[5]);
    assert!(
        five.v > 15.0 && (100.0..=140.0).contains(&(ego.x - five.x)),
        "{:?}",
        with[6]
    );
    let (ego, five) = (with[7].ego(), &with[7].vehicles[5]);
    assert!((4.0..=8.0).contains(&(five.v - ego.v)), "{:?}", with[7]);
    // Not the fixed described sets (seeds 1 and 2).
    assert_ne!(one, Preset::One.described_states(37)[36]);
    // The probe set: the last round(0.3 * 6) = 2 of its 6 states.
    let probe = sample_probe_scenes(&config, 9);
    assert_eq!(probe[..4], sample_scenes(&config, 9, 0, 4)[..]);
    assert_eq!(probe[4], family_scene(&config, 9, 4));
    assert_eq!(probe[5], family_scene(&config, 9, 5));
}

/// State `index` of seed 4 drawn from `preset`'s description with the index's own stream.
fn drawn(config: &mpgdrive::config::Config, preset: Preset, index: u64) -> mpgdrive::world::state::Scene {
    preset.draw_state(&mut scenario_rng(4, index)).scene(config)
}

#[test]
fn the_probe_and_the_later_epochs_can_hold_the_papers_scenarios_on_their_own() {
    let mut config = paper();
    config.train.batch = 8;
    config.train.probe_scenarios = 8;
    config.train.near_merge = None;
    config.train.scenario_share = 0.0;
    // round(0.25 * 8) = 2: the probe's last two states, indices 6 and 7.
    config.train.probe_scenario_share = Some(0.25);
    let probe = sample_probe_scenes(&config, 4);
    assert_eq!(probe[..6], sample_scenes(&config, 4, 0, 6)[..]);
    assert_eq!(probe[6], drawn(&config, Preset::One, 6));
    assert_eq!(probe[7], drawn(&config, Preset::Two, 7));
    // The minibatches stay the stratified draws.
    assert_eq!(
        sample_training_scenes(&config, 4, 2),
        sample_scenes(&config, 4, 16, 8)
    );
    // From epoch `scenario_from` on, the minibatches hold the scenario share: the last
    // round(0.25 * 8) = 2 states of epoch 3 (indices 30 and 31), none of epoch 2.
    config.train.scenario_share = 0.25;
    config.train.scenario_from = 3;
    assert_eq!(
        sample_training_scenes(&config, 4, 2),
        sample_scenes(&config, 4, 16, 8)
    );
    let third = sample_training_scenes(&config, 4, 3);
    assert_eq!(third[..6], sample_scenes(&config, 4, 24, 6)[..]);
    assert_eq!(third[6], drawn(&config, Preset::One, 30));
    assert_eq!(third[7], drawn(&config, Preset::Two, 31));
    // The probe share overrides the minibatches' share in the probe set, 0 included.
    config.train.scenario_share = 0.5;
    config.train.probe_scenario_share = Some(0.0);
    assert_eq!(sample_probe_scenes(&config, 4), sample_scenes(&config, 4, 0, 8));
}
