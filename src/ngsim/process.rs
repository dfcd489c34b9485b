//! Processing as in the paper (Section V, "Data processing"): per vehicle, the longitudinal
//! and lateral positions are smoothed with a Savitzky-Golay filter (piece by piece across
//! frame gaps; pieces shorter than the window stay as recorded), speed and acceleration are
//! recomputed by differentiating the smoothed positions, and lanes are reassigned from the
//! smoothed lateral position and the lane geometry.

use crate::ngsim::config::{FRAME_SECONDS, NgsimConfig};
use crate::ngsim::load::Trajectories;
use crate::ngsim::smooth::{SmoothError, savgol_segments};
use serde::Serialize;
use std::collections::BTreeMap;

/// One processed vehicle: per-frame series of equal length, sorted by frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    /// Vehicle_ID.
    pub id: u32,
    /// Frame_ID of each sample.
    pub frames: Vec<u32>,
    /// Smoothed `Local_Y`: the front bumper's distance from the upstream boundary (m).
    pub front: Vec<f64>,
    /// Smoothed `Local_X`: lateral position from the left edge (m).
    pub lateral: Vec<f64>,
    /// Longitudinal speed from the smoothed positions (m/s).
    pub speed: Vec<f64>,
    /// Longitudinal acceleration from the recomputed speed (m/s^2).
    pub accel: Vec<f64>,
    /// Lane reassigned from the smoothed lateral position.
    pub lane: Vec<u8>,
    /// Lane as recorded.
    pub recorded_lane: Vec<u8>,
    /// Vehicle length (m; the first row's).
    pub length: f64,
    /// Vehicle width (m).
    pub width: f64,
    /// 1 motorcycle, 2 auto, 3 truck.
    pub class: u8,
}

impl Track {
    /// Index of `frame` in the series, if recorded.
    pub fn at(&self, frame: u32) -> Option<usize> {
        self.frames.binary_search(&frame).ok()
    }

    /// Centre of the vehicle along the road (m): the front bumper minus half the length.
    pub fn centre(&self, k: usize) -> f64 {
        self.front[k] - 0.5 * self.length
    }
}

/// What `prepare` saw.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PrepareSummary {
    /// Vehicles.
    pub vehicles: usize,
    /// Rows kept.
    pub rows: usize,
    /// Malformed rows skipped.
    pub rows_skipped: usize,
    /// The first skipped rows: "line N: reason".
    pub skipped_examples: Vec<String>,
    /// First and last Frame_ID.
    pub frames: [u32; 2],
    /// Series pieces (split at frame gaps) shorter than the window, left unsmoothed.
    pub unsmoothed_pieces: usize,
    /// Rows per reassigned lane.
    pub rows_per_lane: BTreeMap<u8, usize>,
    /// Rows whose reassigned lane differs from the recorded one.
    pub lane_changed_rows: usize,
    /// Vehicles first seen on the on-ramp.
    pub ramp_vehicles: usize,
    /// Of those, vehicles last seen in the target lane (the merge scenarios' egos).
    pub merging_vehicles: usize,
    /// `Local_X` is the same in every row (some re-extractions publish lanes and longitudinal
    /// positions only): lanes are the recorded ones, not reassigned.
    pub lateral_constant: bool,
    /// Vehicles recorded with a zero (or negative) length or width, given their class's
    /// default size ([`class_size`]).
    pub default_sizes: usize,
    /// What was noticed and worked around, one sentence each.
    pub warnings: Vec<String>,
}

/// Default length and width (m) of an NGSIM vehicle class, for records without a size:
/// 1 motorcycle (2.4 x 0.9), 3 truck (12.2 x 2.6), otherwise an automobile (4.6 x 1.8;
/// NGSIM I-80's median car is 4.6 m long).
pub fn class_size(class: u8) -> (f64, f64) {
    match class {
        1 => (2.4, 0.9),
        3 => (12.2, 2.6),
        _ => (4.6, 1.8),
    }
}

/// Processed data.
#[derive(Debug, Clone, Default)]
pub struct Prepared {
    /// Vehicles by id.
    pub tracks: Vec<Track>,
    /// Counts.
    pub summary: PrepareSummary,
}

/// Derivative of `y` sampled every `dt` within runs of consecutive frames: central differences
/// inside a run, one-sided at its ends; a run of one sample takes `isolated`.
pub fn derivative(frames: &[u32], y: &[f64], dt: f64, isolated: impl Fn(usize) -> f64) -> Vec<f64> {
    let n = y.len();
    let joined = |i: usize| i + 1 < n && frames[i].checked_add(1) == Some(frames[i + 1]); // i and i + 1 adjacent
    (0..n)
        .map(|i| {
            let prev = i > 0 && joined(i - 1);
            match (prev, joined(i)) {
                (true, true) => (y[i + 1] - y[i - 1]) / (2.0 * dt),
                (false, true) => (y[i + 1] - y[i]) / dt,
                (true, false) => (y[i] - y[i - 1]) / dt,
                (false, false) => isolated(i),
            }
        })
        .collect()
}

fn short_pieces(frames: &[u32], window: usize) -> usize {
    let mut count = 0;
    let mut start = 0;
    for i in 1..=frames.len() {
        if i == frames.len() || frames[i - 1].checked_add(1) != Some(frames[i]) {
            count += usize::from(i - start < window);
            start = i;
        }
    }
    count
}

/// Processes loaded trajectories.
pub fn prepare(data: &Trajectories, config: &NgsimConfig) -> Result<Prepared, SmoothError> {
    let (w, p) = (config.smoothing.window, config.smoothing.order);
    let lanes = &config.lanes;
    let mut summary = PrepareSummary {
        vehicles: data.vehicles.len(),
        rows: data.rows,
        rows_skipped: data.skipped,
        skipped_examples: data
            .skipped_examples
            .iter()
            .map(|(line, why)| format!("line {line}: {why}"))
            .collect(),
        frames: [u32::MAX, 0],
        ..Default::default()
    };
    let (lo, hi) = data
        .vehicles
        .values()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
            (lo.min(r.local_x), hi.max(r.local_x))
        });
    summary.lateral_constant = data.rows > 0 && hi - lo < 1e-6;
    if summary.lateral_constant {
        summary.warnings.push(format!(
            "Local_X is {lo} in every row: lanes cannot be reassigned, the recorded Lane_ID is kept"
        ));
    }
    let mut tracks = Vec::with_capacity(data.vehicles.len());
    for (&id, rows) in &data.vehicles {
        let frames: Vec<u32> = rows.iter().map(|r| r.frame).collect();
        let raw_y: Vec<f64> = rows.iter().map(|r| r.local_y).collect();
        let raw_x: Vec<f64> = rows.iter().map(|r| r.local_x).collect();
        let front = savgol_segments(&frames, &raw_y, w, p)?;
        let lateral = savgol_segments(&frames, &raw_x, w, p)?;
        let speed = derivative(&frames, &front, FRAME_SECONDS, |i| rows[i].speed);
        let accel = derivative(&frames, &speed, FRAME_SECONDS, |_| 0.0);
        let recorded_lane: Vec<u8> = rows.iter().map(|r| r.lane).collect();
        let lane: Vec<u8> = if summary.lateral_constant {
            recorded_lane.clone()
        } else {
            lateral
                .iter()
                .zip(&front)
                .map(|(&x, &y)| lanes.lane_at(x, y))
                .collect()
        };
        summary.unsmoothed_pieces += short_pieces(&frames, w);
        summary.frames[0] = summary.frames[0].min(frames[0]);
        summary.frames[1] = summary.frames[1].max(frames[frames.len() - 1]);
        for (&l, &r) in lane.iter().zip(&recorded_lane) {
            *summary.rows_per_lane.entry(l).or_default() += 1;
            summary.lane_changed_rows += usize::from(l != r);
        }
        if lane[0] == lanes.ramp_lane() {
            summary.ramp_vehicles += 1;
            summary.merging_vehicles += usize::from(lane[lane.len() - 1] == lanes.target_lane());
        }
        let (mut length, mut width) = (rows[0].length, rows[0].width);
        if !(length > 0.0 && width > 0.0) {
            (length, width) = class_size(rows[0].class);
            summary.default_sizes += 1;
        }
        tracks.push(Track {
            id,
            frames,
            front,
            lateral,
            speed,
            accel,
            lane,
            recorded_lane,
            length,
            width,
            class: rows[0].class,
        });
    }
    if summary.default_sizes > 0 {
        summary.warnings.push(format!(
            "{} vehicles have no length or width: their class's default size is used",
            summary.default_sizes
        ));
    }
    Ok(Prepared { tracks, summary })
}

/// Header of [`Prepared::csv`].
pub const PREPARED_HEADER: &str = "Vehicle_ID,Frame_ID,Local_X_m,Local_Y_m,Speed_mps,Accel_mps2,Lane_ID,Recorded_Lane_ID,Length_m,Width_m,Class";

impl Prepared {
    /// Every processed row as CSV (SI units; `Local_Y_m` is still the front bumper).
    pub fn csv(&self) -> String {
        let mut out = String::with_capacity(self.summary.rows * 72);
        out.push_str(PREPARED_HEADER);
        out.push('\n');
        for t in &self.tracks {
            for k in 0..t.frames.len() {
                out.push_str(&format!(
                    "{},{},{:.4},{:.4},{:.4},{:.4},{},{},{:.3},{:.3},{}\n",
                    t.id,
                    t.frames[k],
                    t.lateral[k],
                    t.front[k],
                    t.speed[k],
                    t.accel[k],
                    t.lane[k],
                    t.recorded_lane[k],
                    t.length,
                    t.width,
                    t.class
                ));
            }
        }
        out
    }
}
