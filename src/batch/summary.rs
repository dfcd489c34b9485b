//! Batch results: one JSON file per run, and the summary over them (per controller and demand
//! level, mean and spread over seeds). The summary depends only on the set of result files, so
//! shards merged with `mpgdrive merge` give the summary of one unsharded run.

use crate::atomic;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The metrics of one finished run (a `cosim` of one controller).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunMetrics {
    /// Finished egos.
    pub egos: usize,
    /// Egos still driving at the end.
    pub unfinished: usize,
    /// Egos in a collision.
    pub collisions: usize,
    /// Egos that failed to merge.
    pub failures: usize,
    /// Mean ego speed (m/s).
    pub mean_speed: f64,
    /// Mean ego acceleration magnitude (m/s^2).
    pub mean_abs_accel: f64,
    /// Mean ego jerk magnitude (m/s^3).
    pub mean_abs_jerk: f64,
    /// SUMO collision events.
    pub sumo_collisions: usize,
    /// Mean ego time loss (s), if any ego finished its trip.
    pub mean_time_loss: Option<f64>,
    /// Vehicle-seconds simulated (every vehicle's time in the network).
    pub vehicle_seconds: f64,
    /// Finished egos with an SSM conflict (TTC < 3 s or DRAC > 3 m/s^2; none in result files
    /// written before it was recorded).
    #[serde(default)]
    pub ssm_conflict_egos: Option<usize>,
}

impl RunMetrics {
    /// Share of finished egos with an SSM conflict, when recorded and any ego finished.
    pub fn conflict_share(&self) -> Option<f64> {
        let n = self.ssm_conflict_egos?;
        (self.egos > 0).then(|| n as f64 / self.egos as f64)
    }
}

/// One run's result file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunResult {
    /// Unique name: route file stem, controller, seed.
    pub key: String,
    /// Route file.
    pub route_file: PathBuf,
    /// Demand scale from the route directory's manifest, if listed there.
    pub demand: Option<f64>,
    /// Controllable share from the route directory's manifest, if it set one.
    #[serde(default)]
    pub controllable_share: Option<f64>,
    /// Controller (mpg, sarl, sumo).
    pub controller: String,
    /// SUMO seed.
    pub seed: u64,
    /// "ok" or "failed".
    pub status: String,
    /// What went wrong, for a failed run.
    pub error: Option<String>,
    /// mpgdrive version.
    pub version: String,
    /// SUMO's version, as the worker reported it (none in older result files).
    #[serde(default)]
    pub sumo_version: Option<String>,
    /// The worker's command line.
    pub command: Vec<String>,
    /// Wall time of the run (s; not part of the summary).
    pub wall_seconds: f64,
    /// Metrics of an ok run.
    pub metrics: Option<RunMetrics>,
}

impl RunResult {
    /// Reads a result file; `None` when it is missing or not a complete result.
    pub fn read(path: &Path) -> Option<RunResult> {
        let text = std::fs::read_to_string(path).ok()?;
        serde_json::from_str(&text).ok()
    }

    /// The demand level used to group runs: the scale, or the route file's stem.
    pub fn demand_label(&self) -> String {
        match self.demand {
            Some(d) => format!("{d:.2}"),
            None => self
                .route_file
                .file_stem()
                .map_or_else(String::new, |s| s.to_string_lossy().into_owned()),
        }
    }
}

/// Every result file under `dir/runs`, sorted by key.
pub fn read_results(dir: &Path) -> std::io::Result<Vec<RunResult>> {
    let mut out = Vec::new();
    let runs = dir.join("runs");
    if runs.is_dir() {
        for entry in std::fs::read_dir(&runs)? {
            let path = entry?.path();
            if path.extension().is_some_and(|e| e == "json") {
                if let Some(r) = RunResult::read(&path) {
                    out.push(r);
                }
            }
        }
    }
    out.sort_by(|a, b| a.key.cmp(&b.key));
    Ok(out)
}

/// Mean and sample standard deviation (0 for a single value).
pub(crate) fn mean_sd(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    let mean = xs.iter().sum::<f64>() / n;
    let var = if xs.len() > 1 {
        xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    (mean, var.sqrt())
}

/// The summary files: `summary.csv` and `summary.md`, from `results` (ok runs aggregated per
/// controller, demand level and controllable share (when the route files set one), mean and sample standard deviation over the runs that have a
/// value: a run without a finished ego has no rates; failed runs listed).
pub fn write_summary(results: &[RunResult], out: &Path) -> std::io::Result<()> {
    let mut groups: BTreeMap<(String, String, String), Vec<&RunMetrics>> = BTreeMap::new();
    for r in results {
        if let Some(m) = r.metrics.as_ref().filter(|_| r.status == "ok") {
            let share = r.controllable_share.map_or(String::new(), |c| format!("{c:.2}"));
            groups
                .entry((r.controller.clone(), r.demand_label(), share))
                .or_default()
                .push(m);
        }
    }
    let shares = groups.keys().any(|k| !k.2.is_empty());
    // Per-run values; `None` where a run has no finished ego (or no finished trip).
    type Field = (&'static str, fn(&RunMetrics) -> Option<f64>);
    let fields: [Field; 7] = [
        ("collision_rate", |m| {
            (m.egos > 0).then(|| m.collisions as f64 / m.egos as f64)
        }),
        ("failure_rate", |m| {
            (m.egos > 0).then(|| m.failures as f64 / m.egos as f64)
        }),
        ("mean_speed", |m| (m.egos > 0).then_some(m.mean_speed)),
        ("mean_abs_accel", |m| (m.egos > 0).then_some(m.mean_abs_accel)),
        ("mean_abs_jerk", |m| (m.egos > 0).then_some(m.mean_abs_jerk)),
        ("mean_time_loss", |m| m.mean_time_loss),
        ("ssm_conflict_share", RunMetrics::conflict_share),
    ];
    let mut csv = String::from("controller,demand,runs,egos,sumo_collisions");
    for (name, _) in &fields {
        csv += &format!(",{name}_mean,{name}_sd");
    }
    csv += ",controllable_share\n";
    let mut md = String::from("| Controller | Demand |");
    if shares {
        md += " Controllable share |";
    }
    md += " Runs | Egos | SUMO collisions |";
    for (name, _) in &fields {
        md += &format!(" {name} (mean ± sd) |");
    }
    md += &format!(
        "\n|---|---|---|---|---|{}{}\n",
        if shares { "---|" } else { "" },
        "---|".repeat(fields.len())
    );
    for ((controller, demand, share), ms) in &groups {
        let egos: usize = ms.iter().map(|m| m.egos).sum();
        let sumo_collisions: usize = ms.iter().map(|m| m.sumo_collisions).sum();
        csv += &format!("{controller},{demand},{},{egos},{sumo_collisions}", ms.len());
        md += &format!("| {controller} | {demand} |");
        if shares {
            md += &format!(" {share} |");
        }
        md += &format!(" {} | {egos} | {sumo_collisions} |", ms.len());
        for (_, f) in &fields {
            let xs: Vec<f64> = ms.iter().filter_map(|m| f(m)).collect();
            if xs.is_empty() {
                csv += ",,";
                md += " - |";
            } else {
                let (mean, sd) = mean_sd(&xs);
                csv += &format!(",{mean:.6},{sd:.6}");
                md += &format!(" {mean:.4} ± {sd:.4} |");
            }
        }
        csv += &format!(",{share}\n");
        md.push('\n');
    }
    let failed: Vec<&RunResult> = results.iter().filter(|r| r.status != "ok").collect();
    md += &format!(
        "\n{} runs: {} ok, {} failed.\n",
        results.len(),
        results.len() - failed.len(),
        failed.len()
    );
    for r in failed {
        md += &format!("- {}: {}\n", r.key, r.error.as_deref().unwrap_or("failed"));
    }
    atomic::write(&out.join("summary.csv"), csv)?;
    atomic::write(&out.join("summary.md"), md)
}

/// Merges the results of several batch directories into `out` (result files copied to
/// `out/runs`, summary written). A key found twice must hold the same result.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<Vec<RunResult>, String> {
    let mut all: BTreeMap<String, RunResult> = BTreeMap::new();
    for dir in dirs {
        let results = read_results(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        if results.is_empty() {
            return Err(format!("{}: no result files under runs/", dir.display()));
        }
        for r in results {
            if let Some(prev) = all.get(&r.key) {
                if prev.metrics != r.metrics || prev.status != r.status {
                    return Err(format!("run {} has different results in two directories", r.key));
                }
            }
            all.insert(r.key.clone(), r);
        }
    }
    let results: Vec<RunResult> = all.into_values().collect();
    let runs = out.join("runs");
    std::fs::create_dir_all(&runs).map_err(|e| format!("{}: {e}", runs.display()))?;
    for r in &results {
        let json = serde_json::to_string_pretty(r).expect("result serialises");
        atomic::write(&runs.join(format!("{}.json", r.key)), json).map_err(|e| e.to_string())?;
    }
    write_summary(&results, out).map_err(|e| format!("{}: {e}", out.display()))?;
    crate::batch::plots::batch_plots(&results, out).map_err(|e| e.to_string())?;
    Ok(results)
}
