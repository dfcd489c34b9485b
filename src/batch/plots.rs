//! Batch results as charts: per metric, one chart with a line per controller against the
//! demand scale (and against the controllable share when the runs sweep it), each point the
//! mean over that level's runs (seeds) with a band of one sample standard deviation, as in
//! `summary.md`.

use crate::batch::summary::{RunMetrics, RunResult, mean_sd};
use crate::render::RenderError;
use crate::render::charts::{Panel, Series, panels_png};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One charted metric: file stem, title, axis label and its value in one run.
struct Metric {
    stem: &'static str,
    title: &'static str,
    unit: &'static str,
    value: fn(&RunMetrics) -> Option<f64>,
}

const METRICS: [Metric; 4] = [
    Metric {
        stem: "speed",
        title: "Mean ego speed",
        unit: "m/s",
        value: |m| (m.egos > 0).then_some(m.mean_speed),
    },
    Metric {
        stem: "time_loss",
        title: "Mean ego time loss",
        unit: "s",
        value: |m| m.mean_time_loss,
    },
    Metric {
        stem: "conflict_share",
        title: "Share of egos with an SSM conflict (TTC < 3 s or DRAC > 3 m/s^2)",
        unit: "share of finished egos",
        value: RunMetrics::conflict_share,
    },
    Metric {
        stem: "collision_rate",
        title: "Collision rate",
        unit: "collisions per finished ego",
        value: |m| (m.egos > 0).then(|| m.collisions as f64 / m.egos as f64),
    },
];

/// The swept quantity on a chart's x axis.
#[derive(Clone, Copy, PartialEq)]
enum Axis {
    Demand,
    Share,
}

impl Axis {
    fn of(self, r: &RunResult) -> Option<f64> {
        match self {
            Axis::Demand => r.demand,
            Axis::Share => r.controllable_share,
        }
    }

    fn other(self) -> Axis {
        match self {
            Axis::Demand => Axis::Share,
            Axis::Share => Axis::Demand,
        }
    }

    fn label(self) -> &'static str {
        match self {
            Axis::Demand => "demand scale (x base demand)",
            Axis::Share => "controllable share",
        }
    }

    fn short(self) -> &'static str {
        match self {
            Axis::Demand => "demand",
            Axis::Share => "controllable share",
        }
    }
}

fn key(x: f64) -> i64 {
    (x * 1e6).round() as i64
}

/// Distinct values of `axis` among the ok runs.
fn levels(results: &[&RunResult], axis: Axis) -> Vec<f64> {
    let mut v: Vec<i64> = results.iter().filter_map(|r| axis.of(r)).map(key).collect();
    v.sort_unstable();
    v.dedup();
    v.into_iter().map(|k| k as f64 / 1e6).collect()
}

/// The lines of one chart: per controller (and per level of the other swept quantity, when it
/// varies), the mean and band at each level of `axis`.
fn series(results: &[&RunResult], axis: Axis, metric: &Metric) -> Vec<Series> {
    let split = levels(results, axis.other()).len() > 1;
    let mut groups: BTreeMap<(String, i64), BTreeMap<i64, Vec<f64>>> = BTreeMap::new();
    for r in results {
        let (Some(x), Some(y)) = (axis.of(r), r.metrics.as_ref().and_then(metric.value)) else {
            continue;
        };
        let other = if split {
            axis.other().of(r).map_or(i64::MIN, key)
        } else {
            0
        };
        groups
            .entry((r.controller.clone(), other))
            .or_default()
            .entry(key(x))
            .or_default()
            .push(y);
    }
    groups
        .into_iter()
        .map(|((controller, other), by_x)| {
            let label = if split && other != i64::MIN {
                format!("{controller}, {} {:.2}", axis.other().short(), other as f64 / 1e6)
            } else {
                controller
            };
            let stats: Vec<(f64, (f64, f64))> = by_x
                .into_iter()
                .map(|(x, ys)| (x as f64 / 1e6, mean_sd(&ys)))
                .collect();
            Series {
                label,
                points: stats.iter().map(|&(x, (m, _))| (x, m)).collect(),
                band: stats.iter().map(|&(x, (m, s))| (x, m - s, m + s)).collect(),
            }
        })
        .collect()
}

/// Draws `batch_<axis>_<metric>.png` into `out` for every swept quantity with at least two
/// levels among the ok runs, and returns the files with their captions (none when nothing
/// is swept).
pub fn batch_plots(results: &[RunResult], out: &Path) -> Result<Vec<(PathBuf, String)>, RenderError> {
    let ok: Vec<&RunResult> = results
        .iter()
        .filter(|r| r.status == "ok" && r.metrics.is_some())
        .collect();
    let mut files = Vec::new();
    for axis in [Axis::Demand, Axis::Share] {
        if levels(&ok, axis).len() < 2 {
            continue;
        }
        for metric in &METRICS {
            let lines = series(&ok, axis, metric);
            if lines.iter().all(|s| s.points.is_empty()) {
                continue;
            }
            let axis_stem = if axis == Axis::Demand { "demand" } else { "share" };
            let path = out.join(format!("batch_{axis_stem}_{}.png", metric.stem));
            let title = format!("{} against {}", metric.title, axis.short());
            let panel = Panel {
                title: title.clone(),
                x_label: axis.label().into(),
                y_label: metric.unit.into(),
            };
            panels_png(&path, (1000, 450), &[(panel, lines)])?;
            files.push((
                path,
                format!("{title}: mean over seeds per controller, band of one standard deviation"),
            ));
        }
    }
    Ok(files)
}
