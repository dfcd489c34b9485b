//! `mpgdrive cosim`: the command over [`mpgdrive::sumo::cosim`].

use crate::cli::common::{PolicyPair, SeedChoice};
use clap::Args;
use mpgdrive::sumo::ControllerKind;
use std::path::PathBuf;

/// Arguments of `mpgdrive cosim`.
#[derive(Args)]
pub struct CosimArgs {
    /// Configuration file (TOML): vehicle limits, dt, feasibility rules of the policy, and the
    /// world its policies come from (configs/traffic.toml: the traffic policies;
    /// configs/paper.toml: the paper's Table I policies).
    #[arg(long, default_value = "configs/traffic.toml")]
    config: PathBuf,
    /// SUMO configuration to run.
    #[arg(long)]
    sumocfg: PathBuf,
    /// Route files replacing the configuration's (for example from `mpgdrive routes`).
    #[arg(long)]
    route_files: Option<PathBuf>,
    /// Merge geometry (default: merge.toml next to the .sumocfg).
    #[arg(long)]
    merge: Option<PathBuf>,
    #[command(flatten)]
    policies: PolicyPair,
    #[command(flatten)]
    deploy: SeedChoice,
    /// Controllers to compare, comma-separated: mpg, sarl, sumo.
    #[arg(long, value_delimiter = ',', default_value = "mpg,sarl,sumo")]
    controllers: Vec<ControllerKind>,
    /// SUMO's random seed (logged with the results).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Simulated duration (s), from the begin time the configuration sets (SUMO's default 0).
    #[arg(long, default_value_t = 900.0)]
    end: f64,
    /// The merge gate as a shield for the ramp vehicles the policy drives: true or false (the
    /// learned policy alone, the default: the Table I policies were trained without it; with
    /// it, the traffic policies' egos crawled: docs/experiments.md). A policy is checked
    /// against --config as it is; the results say which.
    #[arg(long, action = clap::ArgAction::Set, default_value_t = false)]
    gate: bool,
    /// SUMO speed mode of controlled vehicles. 0: the policy's speed exactly, as in its training
    /// world, whose rules `cosim` applies (the default with a traffic policy, whose scenes hold
    /// every vehicle in the control zone); 25: SUMO's safe speed towards any leader on top, a
    /// shield (the default with a Table I policy, whose game holds nine players; with traffic
    /// policies it overrode the game thousands of times a run and cost its egos 10-45% of their
    /// speed on 30-36 m/s networks, docs/experiments.md).
    #[arg(long)]
    speed_mode: Option<i32>,
    /// SUMO lane-change mode of controlled ramp vehicles (257: the merge waits while it would
    /// collide at once, and SUMO's strategic lane changes signal it, so SUMO's drivers make
    /// room; 256: the first only; 0: it happens at the conflict point whatever is there).
    #[arg(long, default_value_t = 257)]
    lane_change_mode: i32,
    /// SUMO lane-change mode of the target-lane players the policy drives (1621, SUMO's
    /// default: they change lanes as SUMO's drivers do, leaving the game when they leave the
    /// target lane; 0: they stay in it, as in the internal simulator).
    #[arg(long, default_value_t = 1621)]
    player_lane_change_mode: i32,
    /// Watch in sumo-gui (through libtraci).
    #[arg(long, conflicts_with = "attach")]
    gui: bool,
    /// Join a SUMO already running with --remote-port PORT --num-clients N.
    #[arg(long)]
    attach: Option<u16>,
    /// Client order when attached.
    #[arg(long, default_value_t = 1, requires = "attach")]
    order: i32,
    /// Output directory: cosim.md, cosim.json, egos.csv and SUMO's tripinfo/SSM files.
    #[arg(long, default_value = "results/cosim")]
    out: PathBuf,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    json: bool,
    /// Print microseconds per step: SUMO's step and the controller's own work.
    #[arg(long)]
    bench: bool,
    /// Skip the time-space diagrams (timespace_<controller>.png in --out).
    #[arg(long)]
    no_diagrams: bool,
    /// Every vehicle carries SUMO's SSM device, whatever the route files equip (the conflicts
    /// of the whole traffic, as `study` counts them; by default only when no vehicle type
    /// carries it).
    #[arg(long)]
    ssm_all: bool,
}

#[cfg(not(feature = "sumo"))]
/// Runs `mpgdrive cosim`: refused, as this build has no SUMO.
pub fn run(_args: CosimArgs) -> anyhow::Result<std::process::ExitCode> {
    Err(crate::cli::common::usage(
        "this mpgdrive was built without the `sumo` feature: rebuild with default features",
    ))
}

#[cfg(feature = "sumo")]
pub use with_sumo::run;

#[cfg(feature = "sumo")]
mod with_sumo {
    use super::CosimArgs;
    use crate::cli::common::{deployed_policy, print, usage};
    use anyhow::{Context, Result};
    use mpgdrive::atomic;
    use mpgdrive::config::Config;
    use mpgdrive::policy::PolicyEnsemble;
    use mpgdrive::policy::observation::Layout;
    use mpgdrive::render::timespace::{DiagramLayout, timespace_png};
    use mpgdrive::sumo::cosim::{self, ControllerRun, CosimSettings, Launch, Shields, run_controller};
    use mpgdrive::sumo::{ControlModes, ControllerKind, MergeGeometry};
    use std::path::Path;
    use std::process::ExitCode;

    /// Runs `mpgdrive cosim`.
    pub fn run(args: CosimArgs) -> Result<ExitCode> {
        let (mut config, settings) = settings(&args)?;
        // Every policy is loaded (and checked against the configuration) before the first run.
        let mut controllers = Vec::new();
        for &kind in &args.controllers {
            let net = kind
                .mode()
                .map(|mode| deployed_policy(&args.policies.of(mode, &config)?, &args.deploy, &config))
                .transpose()?;
            controllers.push((kind, net));
        }
        config.sim.merge_gate = args.gate;
        std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
        let runs = run_all(&config, &settings, controllers, &args.out)?;
        if args.json {
            print(&serde_json::to_string_pretty(&runs)?)?;
        } else {
            print(&format!(
                "Co-simulation: {} (SUMO seed {}, {} s, merge gate shield {})\n\n{}",
                args.sumocfg.display(),
                args.seed,
                args.end,
                if args.gate { "on" } else { "off" },
                cosim::markdown(&runs)
            ))?;
        }
        if args.bench {
            print_bench(&settings, &runs)?;
        }
        Ok(ExitCode::SUCCESS)
    }

    /// The arguments checked, before anything is written: the configuration, the geometry
    /// against its network, the route files.
    fn settings(args: &CosimArgs) -> Result<(Config, CosimSettings)> {
        let config = Config::load(&crate::cli::bundled::resolve(&args.config)?)?;
        if !args.sumocfg.is_file() {
            return Err(usage(format!(
                "--sumocfg {}: no such file",
                args.sumocfg.display()
            )));
        }
        if !(args.end.is_finite() && args.end > 0.0) {
            return Err(usage(format!(
                "--end {}: must be a positive number of seconds",
                args.end
            )));
        }
        let files = mpgdrive::sumo::inputs::config_files(&args.sumocfg)?;
        // SUMO runs at the policy's step: its actions, the entry rule and the lane-end stop are
        // computed for that step, and every controller of a run (SUMO's drivers too) shares it.
        let step_differs = files.step_length.is_none_or(|s| (s - config.sim.dt).abs() > 1e-9);
        let merge = args
            .merge
            .clone()
            .unwrap_or_else(|| args.sumocfg.with_file_name("merge.toml"));
        let geometries = MergeGeometry::load_all(&merge)?;
        let (positions, facts) =
            mpgdrive::sumo::inputs::check_inputs(&files, args.route_files.as_deref(), &geometries, &merge)?;
        if step_differs && args.attach.is_none() {
            let set = match files.step_length {
                Some(s) => format!("sets step-length {s} s"),
                None => "sets no step-length (SUMO's default is 1 s)".into(),
            };
            eprintln!(
                "cosim: {} {set}: SUMO runs at the policy's {} s, every controller alike",
                args.sumocfg.display(),
                config.sim.dt
            );
        }
        if files.no_collision_check && args.attach.is_none() {
            eprintln!(
                "cosim: {} sets collision.action none: SUMO checks collisions (its default, teleport), the metrics' first figure",
                args.sumocfg.display()
            );
        }
        if !files.other_dynamics.is_empty() && args.attach.is_none() {
            eprintln!(
                "cosim: {} sets {}: SUMO runs with the policy's world's update (one speed per step, microscopic), every controller alike",
                args.sumocfg.display(),
                files.other_dynamics.join(" and ")
            );
        }
        for lanes in positions.iter().map(|p| p.crossing()).filter(|c| !c.is_empty()) {
            let names: Vec<&str> = lanes.iter().map(|c| c.lane.as_str()).collect();
            eprintln!(
                "cosim: the ramp's links at its junction also yield to {}: egos wait for their vehicles there as SUMO's drivers do",
                names.join(", ")
            );
        }
        for lanes in positions
            .iter()
            .map(|p| p.stop_sign_lanes())
            .filter(|l| !l.is_empty())
        {
            eprintln!(
                "cosim: a stop sign ends {}: every vehicle the policy drives stands at its line before it goes on, as SUMO's drivers do",
                lanes.join(", ")
            );
        }
        let driven = geometries.iter().flat_map(|g| &g.controllable_types);
        let policy_drives = args.controllers.iter().any(|&k| k != ControllerKind::Sumo);
        if policy_drives && !driven.clone().any(|t| facts.types.contains(t)) {
            let names: Vec<&str> = driven.map(String::as_str).collect();
            eprintln!(
                "cosim: no vehicle type of the route files is one of merge.toml's controllable_types ({}): \
                 the policy drives no vehicle (`mpgdrive routes --controllable-share` makes route files with some)",
                names.join(", ")
            );
        }
        if !facts.ssm {
            eprintln!(
                "cosim: {} equips no vehicle with the SSM device: every vehicle gets one (the conflict metrics need it)",
                args.sumocfg.display()
            );
        }
        let settings = CosimSettings {
            sumocfg: args.sumocfg.clone(),
            route_files: args.route_files.clone(),
            merges: geometries.into_iter().zip(positions).collect(),
            geometry_path: merge,
            seed: args.seed,
            end: args.end,
            min_gap: facts.min_gap,
            modes: ControlModes {
                speed: args
                    .speed_mode
                    .unwrap_or(ControlModes::default_for(Layout::of(&config)).speed),
                lane_change: args.lane_change_mode,
                player_lane_change: args.player_lane_change_mode,
            },
            launch: match (args.gui, args.attach) {
                (true, _) => Launch::Gui,
                (false, Some(port)) => Launch::Attach {
                    port,
                    order: args.order,
                },
                (false, None) => Launch::Libsumo,
            },
            out: args.out.clone(),
            timespace: !args.no_diagrams,
            equip_ssm: args.ssm_all || !facts.ssm,
            step_length: step_differs.then_some(config.sim.dt),
            check_collisions: files.no_collision_check,
        };
        Ok((config, settings))
    }

    /// A policy to deploy and its training seeds.
    type Deployed = (PolicyEnsemble, Vec<u64>);

    /// Every controller in turn; on a failure, the results so far are written before the error.
    fn run_all(
        config: &Config,
        settings: &CosimSettings,
        controllers: Vec<(ControllerKind, Option<Deployed>)>,
        out: &Path,
    ) -> Result<Vec<ControllerRun>> {
        let mut runs = Vec::new();
        for (kind, policy) in controllers {
            let (policy, seeds) = policy.unzip();
            let ensemble = policy.as_ref().map(PolicyEnsemble::combine);
            match run_controller(config, settings, kind, policy) {
                Ok(mut run) => {
                    run.policy_seeds = seeds.unwrap_or_default();
                    run.ensemble = ensemble.filter(|_| run.policy_seeds.len() > 1);
                    eprintln!(
                        "cosim: {} done: {} egos over {:.0} s of SUMO time",
                        kind.name(),
                        run.egos.len(),
                        run.simulated
                    );
                    runs.push(run);
                }
                Err(e) => {
                    write_outputs(out, &runs)?;
                    return Err(e).context(format!(
                        "{} run (results so far in {})",
                        kind.name(),
                        out.display()
                    ));
                }
            }
        }
        write_outputs(out, &runs)?;
        Ok(runs)
    }

    /// `--bench`: microseconds per step against plain SUMO.
    fn print_bench(settings: &CosimSettings, runs: &[ControllerRun]) -> Result<()> {
        let plain = cosim::plain_sumo_us_per_step(settings)?;
        eprintln!(
            "bench plain SUMO (libsumo, step only): {plain:.1} us/step, {:.0} steps/s",
            1e6 / plain
        );
        for r in runs {
            let total = r.sumo_us_per_step + r.controller_us_per_step;
            eprintln!(
                "bench {}: {} steps, SUMO step {:.1} us + controller {:.1} us = {:.0} steps/s, {:.2} of plain SUMO's speed",
                r.controller.name(),
                r.steps,
                r.sumo_us_per_step,
                r.controller_us_per_step,
                1e6 / total,
                plain / total
            );
        }
        Ok(())
    }

    fn write_outputs(out: &Path, runs: &[ControllerRun]) -> Result<()> {
        let command: Vec<String> = std::env::args().collect();
        atomic::write(
            &out.join("cosim.md"),
            format!(
                "Command: `{}`\n\nmpgdrive {}, {}. {}{}\n\n{}",
                command.join(" "),
                mpgdrive::VERSION,
                runs.first().map_or("SUMO not run", |r| r.sumo_version.as_str()),
                runs.first().map_or(String::new(), |r| shields_line(&r.shields)),
                runs.iter()
                    .find_map(|r| r.desired_speed)
                    .map_or(String::new(), |v| format!(
                        " The traffic policy observed a desired speed of {v} m/s (merge.toml's \
                         `desired_speed`, else the speed limit of the lane egos merge into)."
                    )),
                cosim::markdown(runs)
            ),
        )?;
        atomic::write(&out.join("cosim.json"), serde_json::to_string_pretty(runs)?)?;
        atomic::write(&out.join("egos.csv"), cosim::egos_csv(runs))?;
        cosim::restore_ssm_outputs(runs)?;
        write_diagrams(out, runs)?;
        Ok(())
    }

    /// The shields of the controlled vehicles, as one sentence.
    fn shields_line(s: &Shields) -> String {
        format!(
            "Shields of the vehicles the policies drive: merge gate {}, SUMO speed mode {}, lane-change mode {} \
             (target-lane players: {}).",
            if s.merge_gate { "on" } else { "off" },
            s.speed_mode,
            s.lane_change_mode,
            s.player_lane_change_mode
        )
    }

    /// `timespace_<controller>.png` for every run that recorded one, all on one scale; with
    /// several merges one per merge, `timespace_<controller>_<merge>.png`.
    fn write_diagrams(out: &Path, runs: &[ControllerRun]) -> Result<()> {
        let started = std::time::Instant::now();
        let recorded: Vec<_> = runs
            .iter()
            .flat_map(|r| r.timespace.iter().enumerate().map(move |(k, t)| (r, k, t)))
            .collect();
        if recorded.is_empty() {
            return Ok(());
        }
        let all: Vec<_> = recorded.iter().map(|(_, _, t)| *t).collect();
        let layout = DiagramLayout::fit(&all, (1600, 900));
        for (run, k, ts) in &recorded {
            let name = run.controller.name();
            let several = run.merges.len() > 1;
            let at = match run.merges.get(*k) {
                Some(m) if several => format!(", merge `{}`", m.name),
                _ => String::new(),
            };
            let title = format!(
                "Time-space diagram: {name} controller{at}, SUMO seed {}, {:.0} s",
                run.seed, run.simulated
            );
            let file = match several {
                true => format!("timespace_{name}_{}.png", k + 1),
                false => format!("timespace_{name}.png"),
            };
            let marked = match run.controller {
                ControllerKind::Sumo => "tracked ego (SUMO drives it)",
                ControllerKind::Sarl => "driven by the single-agent policy",
                ControllerKind::Mpg => "driven by the MPG policy",
            };
            timespace_png(&out.join(file), &layout, ts, &title, marked)?;
        }
        eprintln!(
            "cosim: {} time-space diagrams in {:.2} s",
            recorded.len(),
            started.elapsed().as_secs_f64()
        );
        Ok(())
    }
}
