//! `mpgdrive report`: one folder with the tables, the figures and the commands that made them.

use crate::cli::common::{PolicyPair, print, threads, usage};
use crate::cli::scenario::{described_seeds, scenario};
use anyhow::{Context, Result};
use clap::Args;
use mpgdrive::atomic;
use mpgdrive::config::Config;
use mpgdrive::eval::scenario_sets::{DESCRIBED_STATES, markdown, percentile_99};
use mpgdrive::eval::study::{Study, Surrounding, evaluate};
use mpgdrive::policy::file::Sidecar;
use mpgdrive::policy::{Mode, PolicyNet};
use mpgdrive::render::charts::{Panel, Series, mean_band, panels_png};
use mpgdrive::report::{Block, Document};
use mpgdrive::train::curves::{self, EpochRecord};
use mpgdrive::train::curves_path;
use mpgdrive::world::scenarios::Preset;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `mpgdrive report`.
#[derive(Args)]
pub struct ReportArgs {
    /// Configuration file (TOML).
    #[arg(long, default_value = "configs/paper.toml")]
    config: PathBuf,
    /// Directories of one policy per seed, with their training curves.
    #[command(flatten)]
    policies: PolicyPair,
    /// Seed of the MARL policy that drives the specific scenarios (default: the lowest).
    #[arg(long)]
    policy_seed: Option<u64>,
    /// A `mpgdrive study` output directory to include: the penetration study's table and plot
    /// (skipped when it has no study.md).
    #[arg(long, default_value = "results/study")]
    study: PathBuf,
    /// A `mpgdrive cosim` output directory to include (skipped when it has no cosim.md).
    #[arg(long, default_value = "results/cosim")]
    cosim: PathBuf,
    /// A `mpgdrive ngsim eval` output directory to include (skipped when it has no table4.md).
    #[arg(long, default_value = "results/ngsim")]
    ngsim: PathBuf,
    /// A `mpgdrive batch` (or `merge`) output directory to include: its summary and charts.
    #[arg(long)]
    batch: Option<PathBuf>,
    /// Worker threads for the evaluation (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Output folder: report.md, report.html, figures/, tables.
    #[arg(long, default_value = "results/report")]
    out: PathBuf,
}

/// A saved results file whose Markdown is included: table lines as tables, the rest as text.
fn include_markdown(doc: &mut Document, text: &str) {
    let mut table = String::new();
    for line in text.lines().chain(std::iter::once("")) {
        if line.trim_start().starts_with('|') {
            table.push_str(line);
            table.push('\n');
            continue;
        }
        if !table.is_empty() {
            doc.push(Block::Table(std::mem::take(&mut table)));
        }
        if !line.trim().is_empty() {
            doc.push(Block::Text(line.trim().to_string()));
        }
    }
}

fn curves_of(dir: &Path, seeds: &[u64]) -> Result<Vec<Vec<EpochRecord>>> {
    seeds
        .iter()
        .map(|s| {
            let path = curves_path(&dir.join(format!("seed{s}")));
            curves::read(&path).with_context(|| format!("reading {}", path.display()))
        })
        .collect()
}

fn panel(title: &str, x: &str, y: &str) -> Panel {
    Panel {
        title: title.into(),
        x_label: x.into(),
        y_label: y.into(),
    }
}

fn curve(records: &[Vec<EpochRecord>], f: fn(&EpochRecord) -> Option<f64>) -> Vec<Vec<(f64, f64)>> {
    records
        .iter()
        .map(|r| {
            r.iter()
                .filter_map(|e| f(e).map(|y| (e.epoch as f64, y)))
                .collect()
        })
        .collect()
}

/// The sorted ego returns of a study's episodes under `surrounding`, as `(quantile, return)`.
fn quantiles(study: &Study, surrounding: Surrounding) -> Vec<(f64, f64)> {
    let mut r: Vec<f64> = study
        .episodes
        .iter()
        .filter(|e| e.surrounding == surrounding)
        .map(|e| e.ego_return)
        .collect();
    r.sort_by(f64::total_cmp);
    let n = r.len().max(1) as f64;
    r.into_iter()
        .enumerate()
        .map(|(k, v)| ((k as f64 + 0.5) / n, v))
        .collect()
}

/// Runs `mpgdrive report`.
pub fn run(args: ReportArgs) -> Result<ExitCode> {
    let t0 = std::time::Instant::now();
    let config = Config::load(&crate::cli::bundled::resolve(&args.config)?)?;
    let threads = threads(args.threads)?;
    let policies = [
        args.policies.of(Mode::Mpg, &config)?,
        args.policies.of(Mode::Sarl, &config)?,
    ];
    check_inputs(&args, &policies)?;
    let [mpg, sarl] = args.policies.load(&config)?;
    let figures = args.out.join("figures");
    std::fs::create_dir_all(&figures).with_context(|| format!("creating {}", figures.display()))?;
    let command: Vec<String> = std::env::args().collect();
    let ctx = Sections {
        args: &args,
        config: &config,
        cfg: args.config.display().to_string(),
        figures,
        policies,
    };
    let mut doc = Document::default();
    let title = "mpgdrive report";
    doc.push(Block::Heading(1, title.into()));
    doc.push(Block::Text(format!(
        "mpgdrive {}; configuration `{}`; MARL policies `{}` (seeds {:?}), single-agent policies `{}` (seeds {:?}). Made by `{}`.",
        mpgdrive::VERSION,
        ctx.cfg,
        ctx.policies[0].display(),
        seeds(&mpg),
        ctx.policies[1].display(),
        seeds(&sarl),
        command.join(" ")
    )));
    let all = [Surrounding::Ne, Surrounding::Idm, Surrounding::Const];
    let marl = evaluate(&config, &mpg, &[], &all, threads)?;
    let single = evaluate(&config, &sarl, &mpg, &all, threads)?;
    let claims = study_section(&mut doc, &ctx, &marl, &single)?;
    let families = scenarios_section(&mut doc, &ctx, &marl)?;
    atomic::write(&args.out.join("claims.md"), format!("{claims}\n{families}"))?;
    training_section(&mut doc, &ctx, (&mpg, &sarl), (&marl, &single))?;
    // The penetration study, co-simulation, NGSIM and batch, when present.
    study_in_sumo_section(&mut doc, &args.study, &ctx.figures)?;
    cosim_section(&mut doc, &args.cosim, &ctx.figures)?;
    include_results(
        &mut doc,
        "NGSIM I-80 replay (Table IV)",
        &args.ngsim.join("table4.md"),
        "no NGSIM results: run `mpgdrive ngsim eval` on the official I-80 files (see docs/NGSIM.md) and pass its --out here with --ngsim",
    );
    if let Some(dir) = &args.batch {
        batch_section(&mut doc, dir, &ctx.figures)?;
    }
    let (md, html) = doc.write(&args.out, title)?;
    print(&marl.markdown())?;
    print(&format!(
        "report: {} ({}), {:.0} s",
        html.display(),
        md.display(),
        t0.elapsed().as_secs_f64()
    ))?;
    Ok(ExitCode::SUCCESS)
}

/// The binary the report's commands name.
const EXE: &str = "./target/release/mpgdrive";

/// What the report's sections share.
struct Sections<'a> {
    args: &'a ReportArgs,
    config: &'a Config,
    /// The configuration's path, as the commands name it.
    cfg: String,
    /// Where the figures go.
    figures: PathBuf,
    /// The MARL and single-agent policy directories.
    policies: [PathBuf; 2],
}

/// Loaded policies with their sidecars.
type Policies = [(PolicyNet, Sidecar)];

fn seeds(policies: &Policies) -> Vec<u64> {
    policies.iter().map(|(_, s)| s.seed).collect()
}

/// Everything the report reads is checked before any work: the policy directories, the
/// results folders.
fn check_inputs(args: &ReportArgs, policies: &[PathBuf; 2]) -> Result<()> {
    for dir in policies {
        if !dir.is_dir() {
            return Err(usage(format!(
                "{}: the report needs a directory of one policy per seed (with their curves)",
                dir.display()
            )));
        }
    }
    check_results(&args.study, &["study.md", "study.csv"])?;
    check_results(&args.cosim, &["cosim.md", "cosim.json"])?;
    check_results(&args.ngsim, &["table4.md"])?;
    if let Some(dir) = args.batch.as_ref().filter(|d| !d.join("summary.md").is_file()) {
        return Err(usage(format!(
            "--batch {}: no summary.md (not a `mpgdrive batch` or `merge` output directory)",
            dir.display()
        )));
    }
    Ok(())
}

/// Tables II and III; returns the claims' table.
fn study_section(doc: &mut Document, ctx: &Sections, marl: &Study, single: &Study) -> Result<String> {
    let (args, exe, cfg) = (ctx.args, EXE, &ctx.cfg);
    doc.push(Block::Heading(2, "Statistical study (Tables II and III)".into()));
    let sim = &ctx.config.sim;
    let gate = if sim.merge_gate {
        "**with our merge gate on** (a shield holding ramp vehicles, not the learned policy's result)"
    } else {
        "by the learned policy alone (no merge gate)"
    };
    let rule = if sim.project_non_learning {
        "projected onto the feasible set"
    } else {
        "by their own rule"
    };
    doc.push(Block::Text(format!(
        "{} test scenarios per policy seed, drawn from each seed's test stream (disjoint from training); counts averaged over seeds. Measured {gate}; IDM and constant-speed players drive {rule}.",
        ctx.config.eval.test_scenarios
    )));
    for study in [marl, single] {
        include_markdown(doc, &study.markdown());
    }
    doc.push(Block::Code(format!(
        "{exe} eval --config {cfg} --policy {}\n{exe} eval --config {cfg} --policy {} --ne-policy {}",
        ctx.policies[0].display(),
        ctx.policies[1].display(),
        ctx.policies[0].display()
    )));
    doc.push(Block::Heading(3, "The paper's claims".into()));
    let claims = mpgdrive::eval::claims::markdown(&mpgdrive::eval::claims::check(marl, single));
    include_markdown(doc, &claims);
    atomic::write(&args.out.join("table2.md"), marl.markdown())?;
    atomic::write(&args.out.join("table3.md"), single.markdown())?;

    Ok(claims)
}

/// The paper's specific scenarios, run with the MARL policy and drawn, then as distributions
/// (every seed over the states drawn from each description); returns the distributions'
/// tables.
fn scenarios_section(doc: &mut Document, ctx: &Sections, marl: &Study) -> Result<String> {
    let (args, exe, cfg) = (ctx.args, EXE, &ctx.cfg);
    doc.push(Block::Heading(2, "Specific scenarios".into()));
    for preset in [Preset::One, Preset::Two] {
        let (files, summary) = scenario(
            ctx.config,
            preset,
            &ctx.policies[0],
            args.policy_seed,
            &ctx.figures,
        )?;
        doc.push(Block::Heading(3, format!("Scenario {}", preset.number())));
        doc.push(Block::Text(summary));
        let captions = [
            "initial state",
            "1 s before the ego passes x_c (halfway when it does not)",
            "2 s after the ego passed x_c (the last step when it did not)",
            "the whole episode (every 5th step, twice real time)",
            "ego speed, applied acceleration and bumper gap to its nearest leader (negative: side by side)",
        ];
        for (file, caption) in files.iter().zip(captions) {
            doc.push(Block::Image(
                file.clone(),
                format!("Scenario {}: {caption}", preset.number()),
            ));
        }
        doc.push(Block::Code(format!(
            "{exe} scenario --config {cfg} --preset {} --policy {}{}",
            preset.number(),
            ctx.policies[0].display(),
            args.policy_seed
                .map_or(String::new(), |s| format!(" --policy-seed {s}"))
        )));
    }

    doc.push(Block::Heading(3, "The scenarios as distributions".into()));
    let mut families = String::from("## The paper's scenarios as distributions\n");
    for preset in [Preset::One, Preset::Two] {
        let (mut summaries, _) =
            described_seeds(ctx.config, preset, &ctx.policies[0], None, DESCRIBED_STATES)?;
        for s in &mut summaries {
            let jerks: Vec<f64> = (marl.episodes.iter())
                .filter(|e| e.seed == s.seed && e.surrounding == Surrounding::Ne)
                .map(|e| e.metrics.mean_abs_jerk)
                .collect();
            s.test_jerk_p99 = (!jerks.is_empty()).then(|| percentile_99(&jerks));
        }
        let table = markdown(preset, &summaries);
        include_markdown(doc, &table);
        families += &format!("\n{table}");
    }
    doc.push(Block::Code(format!(
        "{exe} scenario --config {cfg} --preset K --policy {} --states {DESCRIBED_STATES}",
        ctx.policies[0].display()
    )));
    Ok(families)
}

/// Training curves (Figures 7 and 8) and the ego's return in training and testing.
fn training_section(
    doc: &mut Document,
    ctx: &Sections,
    (mpg, sarl): (&Policies, &Policies),
    (marl, single): (&Study, &Study),
) -> Result<()> {
    let (exe, cfg, figures) = (EXE, &ctx.cfg, &ctx.figures);
    doc.push(Block::Heading(2, "Training".into()));
    let mpg_curves = curves_of(&ctx.policies[0], &seeds(mpg))?;
    let sarl_curves = curves_of(&ctx.policies[1], &seeds(sarl))?;
    let over_seeds = "MARL, mean and 1 std over seeds";
    figure(
        doc,
        &figures.join("training_potential.png"),
        panel(
            "Mean total potential on the probe set (Figure 7)",
            "epoch",
            "discounted potential",
        ),
        vec![mean_band(
            over_seeds,
            &curve(&mpg_curves, |e| Some(e.probe_objective)),
        )],
        "Figure 7 analogue: mean total potential per epoch",
    )?;
    let msd = curve(&mpg_curves, |e| {
        (e.action_msd > 0.0).then(|| e.action_msd.log10())
    });
    figure(
        doc,
        &figures.join("training_action_msd.png"),
        panel(
            "Mean squared action difference between successive epochs (Figure 8)",
            "epoch",
            "log10 (m^2/s^4)",
        ),
        vec![mean_band(over_seeds, &msd)],
        "Figure 8 analogue: policy change per epoch",
    )?;
    let ego_train = curve(&mpg_curves, |e| e.probe_ego_return);
    if ego_train.iter().all(|c| !c.is_empty()) {
        figure(
            doc,
            &figures.join("training_ego_return.png"),
            panel(
                "Ego total reward on the probe set during training",
                "epoch",
                "ego discounted return",
            ),
            vec![
                mean_band("MARL (players on the shared policy)", &ego_train),
                mean_band(
                    "single-agent RL (players on IDM)",
                    &curve(&sarl_curves, |e| e.probe_ego_return),
                ),
            ],
            "Ego total reward during training, MARL against single-agent RL",
        )?;
    } else {
        doc.push(Block::Text(
            "The training curves of these policies do not record the ego's return (older curves): retrain to get the training comparison.".into(),
        ));
    }
    figure(
        doc,
        &figures.join("testing_ego_return.png"),
        panel(
            "Ego total reward in testing (all seeds' test scenarios, sorted)",
            "fraction of test scenarios",
            "ego discounted return",
        ),
        vec![
            line("MARL, NE players", quantiles(marl, Surrounding::Ne)),
            line("MARL, IDM players", quantiles(marl, Surrounding::Idm)),
            line("single-agent RL, NE players", quantiles(single, Surrounding::Ne)),
            line(
                "single-agent RL, IDM players",
                quantiles(single, Surrounding::Idm),
            ),
        ],
        "Ego total reward during testing, MARL against single-agent RL",
    )?;
    doc.push(Block::Code(format!(
        "{exe} train --config {cfg} --mode mpg --seeds 0,1,2,3,4 --out policies/mpg\n{exe} train --config {cfg} --mode sarl --seeds 0,1,2,3,4 --out policies/sarl"
    )));
    Ok(())
}

/// Draws one chart (1000 x 450) to `path` and adds it to the document.
fn figure(doc: &mut Document, path: &Path, panel: Panel, series: Vec<Series>, caption: &str) -> Result<()> {
    panels_png(path, (1000, 450), &[(panel, series)])?;
    doc.push(Block::Image(path.to_path_buf(), caption.into()));
    Ok(())
}

/// A results folder is left out when it does not exist; when it does, its files must be
/// there and readable (JSON files must parse), or the report is refused before any work.
fn check_results(dir: &Path, files: &[&str]) -> Result<()> {
    if !dir.is_dir() {
        return Ok(());
    }
    for name in files {
        let path = dir.join(name);
        let text = std::fs::read_to_string(&path).map_err(|e| {
            usage(format!(
                "{}: {e} (a results folder needs {})",
                path.display(),
                files.join(" and ")
            ))
        })?;
        if name.ends_with(".json") {
            serde_json::from_str::<serde_json::Value>(&text)
                .map_err(|e| usage(format!("{}: not valid JSON: {e}", path.display())))?;
        }
    }
    Ok(())
}

/// A heading and a saved Markdown results file, or a line saying why it is not there.
/// Returns whether the file was included.
fn include_results(doc: &mut Document, heading: &str, file: &Path, missing: &str) -> bool {
    doc.push(Block::Heading(2, heading.into()));
    match std::fs::read_to_string(file) {
        Ok(text) => {
            doc.push(Block::Text(format!("From `{}`.", file.display())));
            include_markdown(doc, &text);
            true
        }
        Err(_) => {
            doc.push(Block::Text(format!("Not included: {missing}.")));
            false
        }
    }
}

/// The penetration study's tables and plot (copied into `figures`).
fn study_in_sumo_section(doc: &mut Document, dir: &Path, figures: &Path) -> Result<()> {
    let included = include_results(
        doc,
        "The game against SUMO's drivers, by share of controllable vehicles",
        &dir.join("study.md"),
        "no penetration study: run `mpgdrive study` (see docs/GUIDE.md) and pass its --out here with --study",
    );
    let plot = dir.join("study.png");
    if included && plot.is_file() {
        let copy = figures.join("study.png");
        let bytes = std::fs::read(&plot).with_context(|| format!("reading {}", plot.display()))?;
        atomic::write(&copy, bytes).with_context(|| format!("writing {}", copy.display()))?;
        doc.push(Block::Image(
            copy,
            "Each quantity against the share of controllable vehicles: mean over seeds, band of one sample standard deviation".into(),
        ));
    }
    Ok(())
}

/// The co-simulation table and the time-space diagram of each controller that has one
/// (copied into `figures`, so that the Markdown report's links stay inside its folder).
fn cosim_section(doc: &mut Document, dir: &Path, figures: &Path) -> Result<()> {
    let included = include_results(
        doc,
        "SUMO co-simulation",
        &dir.join("cosim.md"),
        "no co-simulation results: run `mpgdrive cosim` (see docs/GUIDE.md) and pass its --out here with --cosim",
    );
    if !included {
        return Ok(());
    }
    let controllers: Vec<&str> = ["mpg", "sarl", "sumo"]
        .into_iter()
        .filter(|c| dir.join(format!("timespace_{c}.png")).is_file())
        .collect();
    if !controllers.is_empty() {
        doc.push(Block::Text(
            "Time-space diagrams, one per controller on one scale: each vehicle's distance to the conflict point against time, coloured by speed; thick outlined lines are the vehicles the controller drives (for sumo, the same ramp vehicles driven by SUMO); triangles are SSM conflicts, crosses collisions.".into(),
        ));
    }
    for c in controllers {
        let (path, copy) = (
            dir.join(format!("timespace_{c}.png")),
            figures.join(format!("timespace_{c}.png")),
        );
        let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
        atomic::write(&copy, bytes).with_context(|| format!("writing {}", copy.display()))?;
        doc.push(Block::Image(
            copy,
            format!("Time-space diagram of the {c} controller"),
        ));
    }
    Ok(())
}

/// The batch summary and its charts (drawn from the run files into `figures`).
fn batch_section(doc: &mut Document, dir: &Path, figures: &Path) -> Result<()> {
    include_results(doc, "Batch co-simulation", &dir.join("summary.md"), "");
    let results = mpgdrive::batch::summary::read_results(dir)
        .with_context(|| format!("reading {}", dir.join("runs").display()))?;
    let charts = mpgdrive::batch::plots::batch_plots(&results, figures)?;
    if charts.is_empty() {
        doc.push(Block::Text(
            "No charts: the runs do not sweep the demand or the controllable share (fewer than two levels)."
                .into(),
        ));
    }
    for (path, caption) in charts {
        doc.push(Block::Image(path, caption));
    }
    Ok(())
}

fn line(label: &str, points: Vec<(f64, f64)>) -> Series {
    Series {
        label: label.into(),
        points,
        band: Vec::new(),
    }
}
