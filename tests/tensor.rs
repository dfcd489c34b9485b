//! The tensor engine (training) against the scalar engine (evaluation): the same equations,
//! so the same numbers; and gradients that match finite differences.

mod common;

use common::paper;
use mpgdrive::config::Config;
use mpgdrive::engine::rollout::{DriverActor, RolloutOptions, rollout};
use mpgdrive::engine::tape::{self, Var};
use mpgdrive::engine::tensor::{self, idm_actions};
use mpgdrive::num::Num;
use mpgdrive::world::Driver;
use mpgdrive::world::sampler::sample_scenes;

/// A tensor rollout.
fn double(
    steps: usize,
    feasibility: bool,
    terminate_on_collision: bool,
    learning: tensor::Learning,
) -> tensor::TensorRun {
    tensor::TensorRun {
        steps,
        feasibility,
        terminate_on_collision,
        learning,
        sums: tensor::Sums::Both,
    }
}

/// Runs both engines on the same scenes and checks returns and potentials agree; returns the
/// number of collisions.
fn compare(config: &Config, ego: Driver, others: Driver, feasibility: bool, terminate: bool) -> usize {
    let scenes = sample_scenes(config, 17, 0, 24);
    let steps = 150;
    let opts = RolloutOptions {
        feasibility,
        terminate_on_collision: terminate,
        steps,
        threads: 2,
        ..RolloutOptions::from_config(config)
    };
    let scalar = rollout(config, &opts, &scenes, || DriverActor::new(config, ego, others));
    let mask = |d: Driver| if d == Driver::Idm { 1.0 } else { 0.0 };
    let weights: Vec<f64> = (0..scenes.len() * 9)
        .map(|k| if k % 9 == 0 { mask(ego) } else { mask(others) })
        .collect();
    let weights = Var::constant(weights, scenes.len(), 9);
    let t = tensor::rollout(
        config,
        &scenes,
        &double(steps, feasibility, terminate, tensor::Learning::All),
        |b, nb, _| idm_actions(config, b, nb).mul(&weights),
    );
    let (returns, potential) = (t.returns.expect("both sums"), t.potential.expect("both sums"));
    let (returns, potential) = (returns.values(), potential.values());
    let mut collisions = 0;
    for (k, o) in scalar.iter().enumerate() {
        collisions += usize::from(o.collision.is_some());
        let tol = 1e-6 * o.potential_return.abs().max(1.0);
        assert!(
            (o.potential_return - potential[k]).abs() < tol,
            "scenario {k}: {} vs {}",
            o.potential_return,
            potential[k]
        );
        for i in 0..9 {
            let (a, b) = (o.returns[i], returns[k * 9 + i]);
            assert!(
                (a - b).abs() < 1e-6 * a.abs().max(1.0),
                "scenario {k} player {i}: {a} vs {b}"
            );
        }
    }
    collisions
}

/// The paper's configuration with the projection binding the drivers (as the tensor engine's
/// `Learning::All` binds every player): IDM egos then crash, so the comparison covers
/// terminated episodes.
fn ungated() -> Config {
    let mut config = paper();
    (config.sim.merge_gate, config.sim.project_non_learning) = (false, true);
    config
}

#[test]
fn engines_agree_with_feasibility_across_lanes() {
    // The other reading of the paper's immediate neighbours: the target-lane drivers keep
    // their TTC to the IDM ego on the ramp too, and the ungated crashes above disappear, in
    // both engines alike.
    let mut config = ungated();
    config.sim.feasibility_across_lanes = true;
    assert_eq!(compare(&config, Driver::Idm, Driver::Idm, true, true), 0);
    assert_eq!(compare(&config, Driver::Idm, Driver::ConstSpeed, true, true), 0);
}

#[test]
fn engines_agree_with_idm_players_and_feasibility() {
    assert!(compare(&ungated(), Driver::Idm, Driver::Idm, true, true) > 0);
}

#[test]
fn engines_agree_with_constant_speed_players() {
    assert!(compare(&ungated(), Driver::Idm, Driver::ConstSpeed, true, true) > 0);
}

/// Checks both engines agree in `order` with constant-speed players (whose bounds bind) and in
/// merge traffic; returns the ungated configuration in that order.
fn engines_agree_in(order: mpgdrive::config::ProjectionOrder) -> Config {
    engines_agree_with(order, 0.5)
}

/// [`engines_agree_in`] with each projected end taking `share` of its correction.
fn engines_agree_with(order: mpgdrive::config::ProjectionOrder, share: f64) -> Config {
    let mut config = ungated();
    (config.sim.projection_order, config.sim.shared_correction) = (order, share);
    assert!(compare(&config, Driver::Idm, Driver::ConstSpeed, true, true) > 0);
    let mut traffic = common::traffic();
    (traffic.sim.projection_order, traffic.sim.shared_correction) = (order, share);
    traffic_engines_agree(&traffic);
    config
}

#[test]
fn engines_agree_in_the_sequential_projection_order() {
    // Front to back, each leader bound reading the leader's settled speed: the scalar engine
    // settles by lane rank, the tensor engine in passes. Constant-speed players close in on
    // each other, so bounds bind; the returns differ from the simultaneous order's.
    let config = engines_agree_in(mpgdrive::config::ProjectionOrder::Sequential);
    let scenes = sample_scenes(&config, 17, 0, 24);
    let opts = RolloutOptions {
        steps: 150,
        threads: 2,
        ..RolloutOptions::from_config(&config)
    };
    let run = |config: &Config| {
        rollout(config, &opts, &scenes, || {
            DriverActor::new(config, Driver::Idm, Driver::ConstSpeed)
        })
        .iter()
        .map(|o| o.potential_return)
        .collect::<Vec<_>>()
    };
    assert_ne!(run(&config), run(&ungated()));
}

#[test]
fn engines_agree_in_the_shared_projection_order() {
    // At once, a projected pair halving its correction: the scalar engine reads whether each
    // neighbour is projected from the actor, the tensor engine from its mask. Constant-speed
    // players close in on each other, so pushes and holds bind; in merge traffic the human
    // drivers are not projected and take no half.
    engines_agree_in(mpgdrive::config::ProjectionOrder::Shared);
    // Each end taking 3/4 (configs/paper.toml's), where the two engines' pushes differ from
    // the halves above.
    engines_agree_with(mpgdrive::config::ProjectionOrder::Shared, 0.75);
}

#[test]
fn the_sequential_order_records_one_projection_pass_a_step() {
    // Its passes settle on values; the tape gets one recorded pass a step, as in the
    // simultaneous order, plus the leaders' settled speeds (3 operations). Recording every
    // pass (one per lane rank) took over twice the memory of the whole rollout.
    use mpgdrive::config::ProjectionOrder::{Sequential, Simultaneous};
    let recorded = |order| {
        let mut config = ungated();
        config.sim.projection_order = order;
        let scenes = sample_scenes(&config, 17, 0, 24);
        tape::start();
        let run = double(150, true, true, tensor::Learning::All);
        tensor::rollout(&config, &scenes, &run, |b, nb, _| {
            let gain = Var::leaf(vec![1.0; b.x.rows()], b.x.rows(), 1);
            idm_actions(&config, b, nb).mul(&gain)
        });
        tape::recorded()
    };
    let (simultaneous, sequential) = (recorded(Simultaneous), recorded(Sequential));
    assert!(
        sequential <= simultaneous + 150 * 3,
        "{sequential} operations recorded against {simultaneous}"
    );
}

#[test]
fn engines_agree_with_the_merge_gate() {
    // The gate holds the IDM ego (which ignores target-lane cars) until entering is safe:
    // the crashes of the ungated runs above disappear, in both engines alike.
    let mut config = paper();
    (config.sim.merge_gate, config.sim.project_non_learning) = (true, true);
    assert_eq!(compare(&config, Driver::Idm, Driver::Idm, true, true), 0);
    assert_eq!(compare(&config, Driver::Idm, Driver::ConstSpeed, true, true), 0);
}

#[test]
fn engines_agree_in_the_theorem_setting() {
    compare(&paper(), Driver::Idm, Driver::Idm, false, false);
}

#[test]
fn engines_agree_with_the_reward_options() {
    // The ego's speed term weighted by its lane (3 on the ramp, 1 in the target lane), and
    // the conflict term ending at x_c, 10 m past it, and on signed times.
    let mut config = ungated();
    config.reward.w_speed_ramp = Some(3.0);
    assert!(compare(&config, Driver::Idm, Driver::Idm, true, true) > 0);
    config.reward.conflict_ends_at_x_c = true;
    assert!(compare(&config, Driver::Idm, Driver::Idm, true, true) > 0);
    config.reward.conflict_clearance = 10.0;
    assert!(compare(&config, Driver::Idm, Driver::Idm, true, true) > 0);
    config.reward.conflict_ends_at_x_c = false;
    config.reward.conflict_signed_time = true;
    assert!(compare(&config, Driver::Idm, Driver::Idm, true, true) > 0);
    let mut traffic = common::traffic();
    traffic.reward.w_speed_ramp = Some(2.0);
    traffic.reward.conflict_ends_at_x_c = true;
    traffic_engines_agree(&traffic);
    traffic.reward.conflict_ends_at_x_c = false;
    traffic.reward.conflict_signed_time = true;
    traffic_engines_agree(&traffic);
}

#[test]
fn potential_gradient_matches_finite_differences() {
    // d Phi / d theta for a common acceleration offset theta added to every IDM action.
    let config = paper();
    let scenes = sample_scenes(&config, 4, 0, 8);
    // One theta per scene (a leaf of the tape); the derivative for a common offset is their
    // sum.
    let phi = |theta: &Var| {
        tensor::rollout(
            &config,
            &scenes,
            &double(60, false, false, tensor::Learning::All),
            |b, nb, _| idm_actions(&config, b, nb).add(theta),
        )
        .potential
        .expect("both sums")
    };
    let mean = |theta: f64| {
        let p = phi(&Var::constant(vec![theta; scenes.len()], scenes.len(), 1));
        p.values().iter().sum::<f64>() / scenes.len() as f64
    };
    tape::start();
    let theta = Var::leaf(vec![0.2; scenes.len()], scenes.len(), 1);
    let root = phi(&theta);
    let grads = tape::backward(&root, vec![1.0 / scenes.len() as f64; scenes.len()]);
    let grad: f64 = grads
        .of(&theta)
        .expect("the potential depends on theta")
        .iter()
        .sum();
    let h = 1e-5;
    let fd = (mean(0.2 + h) - mean(0.2 - h)) / (2.0 * h);
    assert!(grad.is_finite() && grad != 0.0);
    assert!(
        (grad - fd).abs() < 1e-5 * fd.abs().max(1.0),
        "tape gradient {grad} vs finite difference {fd}"
    );
}

/// Constant speed for every player, the ego alone a learning player (as a single-agent policy
/// among non-learning drivers).
struct EgoLearnsConstSpeed;

impl mpgdrive::engine::rollout::Actor for EgoLearnsConstSpeed {
    fn act(
        &mut self,
        _step: usize,
        _scenes: &[mpgdrive::world::Scene],
        _nb: &[mpgdrive::world::neighbors::Neighbors],
        out: &mut [f64],
    ) {
        out.fill(0.0);
    }
    fn learning(&self, i: usize) -> bool {
        i == 0
    }
}

#[test]
fn non_learning_players_keep_their_own_rule_in_both_engines_when_asked() {
    let mut config = paper();
    config.sim.project_non_learning = false;
    let scenes = sample_scenes(&config, 5, 0, 16);
    let steps = 100;
    let opts = RolloutOptions {
        steps,
        threads: 1,
        recording: mpgdrive::engine::rollout::Recording::Full,
        ..RolloutOptions::from_config(&config)
    };
    let scalar = rollout(&config, &opts, &scenes, || EgoLearnsConstSpeed);
    // Constant-speed players really keep their speed: no projection moved them.
    for o in &scalar {
        let t = o.trajectory.as_ref().unwrap();
        let moved = t
            .actions
            .chunks(9)
            .take(o.steps)
            .any(|a| a[1..].iter().any(|&u| u != 0.0));
        assert!(!moved, "a non-learning player was projected");
    }
    // The ego is still held by the rules: some ego action differs from its raw 0.
    assert!(scalar.iter().any(|o| {
        o.trajectory
            .as_ref()
            .unwrap()
            .actions
            .chunks(9)
            .any(|a| a[0] != 0.0)
    }));
    let run = double(
        steps,
        true,
        config.sim.terminate_on_collision,
        tensor::Learning::Ego,
    );
    let t = tensor::rollout(&config, &scenes, &run, |b, _, _| b.x.full(0.0));
    let potential = t.potential.expect("both sums");
    let potential = potential.values();
    for (k, o) in scalar.iter().enumerate() {
        let tol = 1e-6 * o.potential_return.abs().max(1.0);
        assert!((o.potential_return - potential[k]).abs() < tol, "scenario {k}");
    }
}

#[test]
fn engines_agree_in_merge_traffic_with_human_drivers() {
    // Traffic episodes (3 ramp vehicles, 10 in the target lane, IDM humans merging by the
    // gate) with a speed-keeping linear policy for the players: same returns and potential.
    let config = common::traffic();
    traffic_engines_agree(&config);
    // ...among them drivers who make room for a ramp vehicle (`traffic.cooperation`).
    assert!(yielding_steps(&config) > 20, "{}", yielding_steps(&config));
}

/// Over the scalar engine's recorded steps of `traffic_engines_agree`'s scenes: how many times
/// a human driver made room for a ramp vehicle ahead of it.
fn yielding_steps(config: &Config) -> usize {
    use mpgdrive::world::drivers::yields_to;
    use mpgdrive::world::geometry::Road;
    use mpgdrive::world::neighbors::find_neighbors;
    let (scenes, scalar) = scalar_traffic(config);
    let road = Road::new(config);
    let (mut order, mut nb) = (Vec::new(), Vec::new());
    let mut count = 0;
    for (scene, o) in scenes.iter().zip(&scalar) {
        let states = &o.trajectory.as_ref().expect("recorded").states;
        for step in states.chunks(scene.len()).take(o.steps + 1) {
            let now = mpgdrive::world::Scene {
                vehicles: step.to_vec(),
                ..scene.clone()
            };
            find_neighbors(&now, &mut order, &mut nb);
            count += (0..now.len())
                .filter(|&i| yields_to(&road, &now, i, nb[i].leader).is_some())
                .count();
        }
    }
    count
}

#[test]
fn engines_agree_in_merge_traffic_with_a_time_headway() {
    // The projection keeping a 1 s time gap (`sim.time_headway`), the scenes sampled for it.
    let mut config = common::traffic();
    config.sim.time_headway = 1.0;
    traffic_engines_agree(&config);
}

#[test]
fn engines_agree_in_merge_traffic_with_an_acceleration_lane() {
    // The same with the ramp going on 40 m past x_c: ramp vehicles without a gap stay on it
    // past x_c (the speed-keeping players leave some there), in both engines alike.
    let mut config = common::traffic();
    config.scenario.accel_lane = 40.0;
    let x_c = config.scenario.conflict_point;
    let past = traffic_engines_agree(&config);
    assert!(past > 0, "no ramp vehicle stayed on the acceleration lane");
    // Without the lane none can be past x_c on the ramp.
    config.scenario.accel_lane = 0.0;
    assert_eq!(traffic_engines_agree(&config), 0, "x_c = {x_c}");
}

/// Runs traffic episodes (a speed-keeping linear policy for the players, IDM humans) in both
/// engines, checks their potentials agree and returns how many steps a ramp vehicle spent
/// past `x_c` still on the ramp (scalar engine).
/// Steps of the traffic rollouts compared.
const TRAFFIC_STEPS: usize = 150;

/// 16 merge-traffic scenes and their scalar rollouts (every step recorded), the players on a
/// speed-keeping linear policy and the humans on IDM.
fn scalar_traffic(
    config: &Config,
) -> (
    Vec<mpgdrive::world::Scene>,
    Vec<mpgdrive::engine::outcome::EpisodeOutcome>,
) {
    use mpgdrive::engine::rollout::Recording;
    use mpgdrive::policy::{LinearPolicy, PolicyActor};
    let scenes = sample_scenes(config, 3, 0, 16);
    assert!(scenes.iter().any(|s| s.humans.contains(&true)));
    let opts = RolloutOptions {
        steps: TRAFFIC_STEPS,
        threads: 2,
        recording: Recording::Full,
        ..RolloutOptions::from_config(config)
    };
    let linear = LinearPolicy::speed_keeping(config);
    let scalar = rollout(config, &opts, &scenes, || {
        PolicyActor::new(config, linear.clone(), Driver::Idm, true)
    });
    (scenes, scalar)
}

fn traffic_engines_agree(config: &Config) -> usize {
    use mpgdrive::policy::LinearPolicy;
    use mpgdrive::policy::observation::{Frame, Layout, observation_rows, tensor_features};
    let (scenes, scalar) = scalar_traffic(config);
    let steps = TRAFFIC_STEPS;
    let linear = LinearPolicy::speed_keeping(config);
    let t = tensor::rollout(
        config,
        &scenes,
        &double(steps, true, true, tensor::Learning::All),
        |b, nb, _| {
            let features = tensor_features(Layout::Traffic, Frame::of(config), b, nb);
            let obs = observation_rows(Layout::Traffic, &features);
            let actions = obs
                .chunks(linear.weights.len())
                .map(|row| {
                    let z: f32 =
                        row.iter().zip(&linear.weights).map(|(o, w)| o * w).sum::<f32>() + linear.bias;
                    f64::from(z.tanh() * linear.scale)
                })
                .collect();
            Var::constant(actions, b.x.rows(), b.x.cols())
        },
    );
    let potential = t.potential.expect("both sums");
    let potential = potential.values();
    for (k, o) in scalar.iter().enumerate() {
        let tol = 1e-4 * o.potential_return.abs().max(1.0);
        assert!(
            (o.potential_return - potential[k]).abs() < tol,
            "scenario {k}: {} vs {}",
            o.potential_return,
            potential[k]
        );
    }
    let x_c = config.scenario.conflict_point;
    scalar
        .iter()
        .flat_map(|o| &o.trajectory.as_ref().expect("recorded").states)
        .filter(|v| v.on_ramp && v.x >= x_c)
        .count()
}

#[test]
fn a_rollout_asked_for_one_sum_gives_its_values_bit_for_bit() {
    // Training asks for the sum it back-propagates alone; it must be the sum a rollout asked
    // for both computes, bit for bit, also after collisions (constant speed without the
    // projection crashes, and the absorbing tail charges the collision step's values).
    let config = paper();
    let scenes = sample_scenes(&config, 17, 0, 24);
    let run = |sums: tensor::Sums| {
        let run = tensor::TensorRun {
            sums,
            ..double(150, false, true, tensor::Learning::All)
        };
        tensor::rollout(&config, &scenes, &run, |b, _, _| b.x.full(0.0))
    };
    let both = run(tensor::Sums::Both);
    let (potential, returns) = (run(tensor::Sums::Potential), run(tensor::Sums::Returns));
    assert!(potential.returns.is_none() && returns.potential.is_none());
    let values = |v: Option<Var>| v.expect("asked for").values().to_vec();
    assert_eq!(values(potential.potential), values(both.potential));
    assert_eq!(values(returns.returns), values(both.returns));
    let opts = RolloutOptions {
        feasibility: false,
        steps: 150,
        ..RolloutOptions::from_config(&config)
    };
    let scalar = rollout(&config, &opts, &scenes, || {
        DriverActor::new(&config, Driver::ConstSpeed, Driver::ConstSpeed)
    });
    assert!(
        scalar.iter().any(|o| o.collision.is_some()),
        "some episodes crash"
    );
}
