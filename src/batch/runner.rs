//! `mpgdrive batch`: every (route file, controller, seed) combination as its own worker
//! process (`mpgdrive cosim`; libsumo holds one simulation per process), `jobs` at a time.
//!
//! Each finished run is written atomically to `out/runs/KEY.json`; the worker's output goes to
//! `out/logs/KEY.log` and its SUMO files to `out/work/KEY/`. Killing the batch at any moment
//! loses at most the runs in flight; `resume` skips runs whose result file is complete. A run
//! that fails (malformed routes, a SUMO error, a crash, `timeout`) is recorded with its error
//! and the batch goes on. Workers run in their own process group, so Ctrl-C reaches the batch
//! only: it stops the workers in flight and leaves every finished result in place.

use crate::atomic;
use crate::batch::summary::{RunMetrics, RunResult, read_results, write_summary};
use std::collections::HashMap;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// One combination to run.
#[derive(Debug, Clone, PartialEq)]
pub struct Combo {
    /// Route file.
    pub route: PathBuf,
    /// Controller name.
    pub controller: String,
    /// SUMO seed.
    pub seed: u64,
}

impl Combo {
    /// The run's unique name: `<route stem>__<controller>__s<seed>`.
    pub fn key(&self) -> String {
        let stem = self
            .route
            .file_name()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        let stem = stem.trim_end_matches(".xml").trim_end_matches(".rou");
        format!("{stem}__{}__s{}", self.controller, self.seed)
    }
}

/// All combinations in a fixed order (route files sorted), then the share of shard `k` of `n`
/// (1-based): every combination whose index is `k - 1` modulo `n`.
pub fn combos(
    routes: &[PathBuf],
    controllers: &[String],
    seeds: &[u64],
    shard: (usize, usize),
) -> Vec<Combo> {
    let mut routes = routes.to_vec();
    routes.sort();
    let all = routes.iter().flat_map(|r| {
        controllers.iter().flat_map(move |c| {
            seeds.iter().map(move |&s| Combo {
                route: r.clone(),
                controller: c.clone(),
                seed: s,
            })
        })
    });
    let (k, n) = shard;
    all.enumerate()
        .filter(|(i, _)| i % n == k - 1)
        .map(|(_, c)| c)
        .collect()
}

/// What every worker shares.
#[derive(Debug, Clone)]
pub struct BatchSettings {
    /// The mpgdrive binary to run workers with.
    pub exe: PathBuf,
    /// Arguments common to every worker (`cosim --sumocfg ... --end ...`).
    pub common_args: Vec<String>,
    /// Output directory.
    pub out: PathBuf,
    /// Worker processes at a time.
    pub jobs: usize,
    /// Skip runs whose result is already there.
    pub resume: bool,
    /// Kill a worker after this long.
    pub timeout: Option<Duration>,
}

/// A route file's entry in the `manifest.json` beside it.
fn manifest_entry(
    route: &Path,
    cache: &mut HashMap<PathBuf, Vec<crate::batch::routes::ManifestEntry>>,
) -> Option<crate::batch::routes::ManifestEntry> {
    let dir = route.parent()?.to_path_buf();
    let entries = cache.entry(dir.clone()).or_insert_with(|| {
        std::fs::read_to_string(dir.join("manifest.json"))
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or_default()
    });
    let name = route.file_name()?.to_str()?;
    entries.iter().find(|e| e.file == name).cloned()
}

/// The metrics of a worker's `cosim --json` output (one controller).
/// Also SUMO's version, when the output names it.
fn metrics_of(stdout: &str) -> Result<(RunMetrics, Option<String>), String> {
    let runs: serde_json::Value =
        serde_json::from_str(stdout).map_err(|e| format!("worker output is not JSON: {e}"))?;
    let r = &runs[0];
    let s = &r["summary"];
    let num = |v: &serde_json::Value| {
        v.as_f64()
            .ok_or_else(|| format!("worker output lacks a number: {v}"))
    };
    let count = |v: &serde_json::Value| {
        v.as_u64()
            .map(|x| x as usize)
            .ok_or_else(|| format!("worker output lacks a count: {v}"))
    };
    let metrics = RunMetrics {
        egos: count(&s["episodes"])?,
        unfinished: count(&r["unfinished"])?,
        collisions: count(&s["collisions"])?,
        failures: count(&s["failures"])?,
        mean_speed: num(&s["mean_speed"])?,
        mean_abs_accel: num(&s["mean_abs_accel"])?,
        mean_abs_jerk: num(&s["mean_abs_jerk"])?,
        sumo_collisions: r["collisions"].as_array().map_or(0, Vec::len),
        mean_time_loss: r["mean_time_loss"].as_f64(),
        vehicle_seconds: num(&r["vehicle_seconds"])?,
        ssm_conflict_egos: r["egos"].as_array().map(|egos| {
            egos.iter()
                .filter(|e| {
                    e["finished"] == true && (e["ssm_min_ttc"].is_number() || e["ssm_max_drac"].is_number())
                })
                .count()
        }),
    };
    Ok((metrics, r["sumo_version"].as_str().map(str::to_owned)))
}

/// The last non-empty line of a log: the worker's error message.
fn last_line(path: &Path) -> String {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|t| t.lines().rev().find(|l| !l.trim().is_empty()).map(str::to_owned))
        .unwrap_or_else(|| "no output".into())
}

struct Running {
    combo: Combo,
    child: Child,
    started: Instant,
    command: Vec<String>,
}

/// How a batch ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BatchEnd {
    /// Every run finished (some may have failed).
    Done {
        /// Result files in `out` that record a failed run.
        failed: usize,
    },
    /// Stopped by the stop flag; finished results are kept.
    Stopped,
}

/// Runs `todo` (with `resume`, skipping runs whose result is ok; failed ones run again), then
/// writes the summary over every result in `out`. `on_done` is called after each run (progress).
pub fn run_batch(
    settings: &BatchSettings,
    todo: &[Combo],
    stop: &AtomicBool,
    on_done: &mut dyn FnMut(&RunResult),
) -> std::io::Result<BatchEnd> {
    for sub in ["runs", "logs", "work"] {
        std::fs::create_dir_all(settings.out.join(sub))?;
    }
    let result_path = |c: &Combo| settings.out.join("runs").join(format!("{}.json", c.key()));
    let mut pending: std::collections::VecDeque<Combo> = todo
        .iter()
        .filter(|c| !(settings.resume && RunResult::read(&result_path(c)).is_some_and(|r| r.status == "ok")))
        .cloned()
        .collect();
    let mut manifests = HashMap::new();
    let mut running: Vec<Running> = Vec::new();
    loop {
        if stop.load(Ordering::SeqCst) {
            for mut r in running {
                let _ = r.child.kill();
                let _ = r.child.wait();
            }
            return Ok(BatchEnd::Stopped);
        }
        while running.len() < settings.jobs.max(1) {
            let Some(combo) = pending.pop_front() else { break };
            let key = combo.key();
            let work = settings.out.join("work").join(&key);
            std::fs::create_dir_all(&work)?;
            let mut args = settings.common_args.clone();
            args.extend([
                "--route-files".into(),
                combo.route.display().to_string(),
                "--controllers".into(),
                combo.controller.clone(),
                "--seed".into(),
                combo.seed.to_string(),
                "--json".into(),
                "--out".into(),
                work.display().to_string(),
            ]);
            let log = std::fs::File::create(settings.out.join("logs").join(format!("{key}.log")))?;
            let child = Command::new(&settings.exe)
                .args(&args)
                .stdin(Stdio::null())
                .stdout(std::fs::File::create(work.join("stdout.json"))?)
                .stderr(log)
                .process_group(0)
                .spawn()?;
            let mut command = vec![settings.exe.display().to_string()];
            command.extend(args);
            running.push(Running {
                combo,
                child,
                started: Instant::now(),
                command,
            });
        }
        if running.is_empty() {
            break;
        }
        let mut i = 0;
        while i < running.len() {
            let r = &mut running[i];
            let timed_out = settings.timeout.is_some_and(|t| r.started.elapsed() > t);
            let status = if timed_out {
                let _ = r.child.kill();
                Some(r.child.wait()?)
            } else {
                r.child.try_wait()?
            };
            let Some(status) = status else {
                i += 1;
                continue;
            };
            let r = running.swap_remove(i);
            let key = r.combo.key();
            let outcome = if timed_out {
                Err(format!(
                    "timed out after {:.0} s",
                    settings.timeout.unwrap_or_default().as_secs_f64()
                ))
            } else if status.success() {
                std::fs::read_to_string(settings.out.join("work").join(&key).join("stdout.json"))
                    .map_err(|e| e.to_string())
                    .and_then(|t| metrics_of(&t))
            } else {
                let log = last_line(&settings.out.join("logs").join(format!("{key}.log")));
                Err(match status.code() {
                    Some(code) => format!("exit code {code}: {log}"),
                    None => format!("worker killed by a signal: {log}"),
                })
            };
            if stop.load(Ordering::SeqCst) {
                continue; // a worker that died of the stop is not a failed run
            }
            let entry = manifest_entry(&r.combo.route, &mut manifests);
            let result = RunResult {
                key: key.clone(),
                demand: entry.as_ref().map(|e| e.scale),
                controllable_share: entry.and_then(|e| e.controllable_share),
                route_file: r.combo.route.clone(),
                controller: r.combo.controller.clone(),
                seed: r.combo.seed,
                status: if outcome.is_ok() { "ok" } else { "failed" }.into(),
                error: outcome.as_ref().err().cloned(),
                sumo_version: outcome.as_ref().ok().and_then(|(_, v)| v.clone()),
                version: crate::VERSION.into(),
                command: r.command,
                wall_seconds: r.started.elapsed().as_secs_f64(),
                metrics: outcome.ok().map(|(m, _)| m),
            };
            let json = serde_json::to_string_pretty(&result).expect("result serialises");
            atomic::write(&result_path(&r.combo), json)?;
            on_done(&result);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let results = read_results(&settings.out)?;
    write_summary(&results, &settings.out)?;
    crate::batch::plots::batch_plots(&results, &settings.out).map_err(std::io::Error::other)?;
    Ok(BatchEnd::Done {
        failed: results.iter().filter(|r| r.status != "ok").count(),
    })
}
