//! Synthetic NGSIM files in the official layouts, with on-ramp vehicles merging into the
//! target lane, for tests and benchmarks (the official files are not in the repository).
//!
//! Episode `k` is scenario `k` of the internal simulator (initial states of `seed`, every
//! player on IDM, the paper's horizon), placed in its own block of frames so episodes never
//! meet. Its ego starts in the ramp lane and moves laterally into the target lane over 2 s
//! centred on the step it passes the conflict point; its players drive in the target lane;
//! one background vehicle per other freeway lane drives at a constant speed. Episodes that end
//! in a collision are left out. Recorded positions get Gaussian noise (`noise` m, both axes),
//! recorded speed and acceleration are finite differences of the noisy positions and the
//! recorded lane is read from the noisy lateral position, as in the raw data.

use crate::config::Config;
use crate::engine::rollout::{DriverActor, Recording, RolloutOptions, rollout};
use crate::ngsim::config::{FRAME_SECONDS, NgsimConfig};
use crate::ngsim::load::{COLUMNS, FOOT};
use crate::world::drivers::Driver;
use crate::world::sampler::{sample_scenes, scenario_rng, standard_normal};
use rand::Rng;
use std::collections::BTreeMap;

/// Which official layout to write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Layout {
    /// FHWA text: 18 whitespace-separated columns, no header.
    Text,
    /// data.transportation.gov CSV: a header, the 18 columns and 7 more, `Location` = "i-80".
    Csv,
}

/// The true (noise-free) sample of a vehicle at a frame, in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruePoint {
    /// Frame_ID.
    pub frame: u32,
    /// Front bumper along the road (`Local_Y`).
    pub front: f64,
    /// Lateral position from the left edge (`Local_X`).
    pub lateral: f64,
    /// Speed.
    pub speed: f64,
}

/// One generated merge episode.
#[derive(Debug, Clone, PartialEq)]
pub struct TrueEpisode {
    /// Simulator scenario index.
    pub index: usize,
    /// First frame.
    pub first_frame: u32,
    /// Vehicle_ID of each player, by player number (index 0 is the ego).
    pub ids: Vec<u32>,
}

/// A generated file and what it was made from.
#[derive(Debug, Clone)]
pub struct Synthetic {
    /// The file's text.
    pub text: String,
    /// True samples per Vehicle_ID.
    pub truth: BTreeMap<u32, Vec<TruePoint>>,
    /// The merge episodes written.
    pub episodes: Vec<TrueEpisode>,
}

/// Frames between two episodes' blocks.
const GAP_FRAMES: u32 = 100;

/// Generates `episodes` episodes from the initial states of `seed`; `config` is the paper
/// configuration (its conflict point is replaced by the NGSIM one).
pub fn generate(
    config: &Config,
    ngsim: &NgsimConfig,
    episodes: usize,
    seed: u64,
    noise: f64,
    layout: Layout,
) -> Synthetic {
    let config = config.at_conflict_point(ngsim.merge.conflict_point);
    let scenes = sample_scenes(&config, seed, 0, episodes);
    let opts = RolloutOptions {
        recording: Recording::Full,
        ..RolloutOptions::from_config(&config)
    };
    let outcomes = rollout(&config, &opts, &scenes, || {
        DriverActor::new(&config, Driver::Idm, Driver::Idm)
    });
    let lanes = &ngsim.lanes;
    let w = lanes.width;
    let target_x = (f64::from(lanes.target_lane()) - 0.5) * w;
    let half = 0.5 * config.vehicle.length;
    let steps = config.n_steps();
    let mut truth: BTreeMap<u32, Vec<TruePoint>> = BTreeMap::new();
    let mut written = Vec::new();
    let mut next_id = 1u32;
    for (k, out) in outcomes.iter().enumerate() {
        if out.collision.is_some() {
            continue;
        }
        let first_frame = 1 + k as u32 * (steps as u32 + 1 + GAP_FRAMES);
        let states = &out.trajectory.as_ref().expect("full recording").states;
        let n = scenes[k].len();
        let ids: Vec<u32> = (0..n as u32).map(|i| next_id + i).collect();
        next_id += n as u32;
        // The ego's lateral move: 2 s centred between the last ramp step and the first merged one.
        let t_merge = out
            .ego_merged_at
            .map_or(f64::INFINITY, |m| (m as f64 + 0.5) * FRAME_SECONDS);
        for (i, &id) in ids.iter().enumerate() {
            let points = (0..=steps)
                .map(|t| {
                    let v = &states[t * n + i];
                    let lateral = if i == 0 {
                        let s = ((t as f64 * FRAME_SECONDS - t_merge + 1.0) / 2.0).clamp(0.0, 1.0);
                        target_x + w * (0.5 + 0.5 * (std::f64::consts::PI * s).cos())
                    } else {
                        target_x - v.y
                    };
                    TruePoint {
                        frame: first_frame + t as u32,
                        front: v.x + half,
                        lateral,
                        speed: v.v,
                    }
                })
                .collect();
            truth.insert(id, points);
        }
        // Background: one constant-speed vehicle in each other freeway lane.
        let mut rng = scenario_rng(seed ^ 0x6267, k as u64);
        for lane in 1..lanes.target_lane() {
            let (x0, v) = (rng.random_range(0.0..200.0), rng.random_range(8.0..20.0));
            let lateral = (f64::from(lane) - 0.5) * w;
            let points = (0..=steps)
                .map(|t| TruePoint {
                    frame: first_frame + t as u32,
                    front: x0 + v * t as f64 * FRAME_SECONDS,
                    lateral,
                    speed: v,
                })
                .collect();
            truth.insert(next_id, points);
            next_id += 1;
        }
        written.push(TrueEpisode {
            index: k,
            first_frame,
            ids,
        });
    }
    let text = write(&config, ngsim, &truth, seed, noise, layout);
    Synthetic {
        text,
        truth,
        episodes: written,
    }
}

fn write(
    config: &Config,
    ngsim: &NgsimConfig,
    truth: &BTreeMap<u32, Vec<TruePoint>>,
    seed: u64,
    noise: f64,
    layout: Layout,
) -> String {
    let rows: usize = truth.values().map(Vec::len).sum();
    let mut out = String::with_capacity(rows * 150);
    let sep = match layout {
        Layout::Text => "  ",
        Layout::Csv => ",",
    };
    if layout == Layout::Csv {
        out.push_str(&COLUMNS.join(","));
        out.push_str(",O_Zone,D_Zone,Int_ID,Section_ID,Direction,Movement,Location\n");
    }
    let mut rng = scenario_rng(seed ^ 0x006e_6f69_7365, 0);
    let (length, width) = (config.vehicle.length / FOOT, config.vehicle.width / FOOT);
    for (&id, points) in truth {
        let noisy: Vec<(f64, f64)> = points
            .iter()
            .map(|p| {
                (
                    p.lateral + noise * standard_normal(&mut rng),
                    p.front + noise * standard_normal(&mut rng),
                )
            })
            .collect();
        let diff = |k: usize| {
            let k = k.max(1);
            (noisy[k].1 - noisy[k - 1].1) / FRAME_SECONDS
        };
        for (k, p) in points.iter().enumerate() {
            let (x, y) = noisy[k];
            let speed = diff(k);
            let accel = if k + 1 < points.len() {
                (diff(k + 1) - speed) / FRAME_SECONDS
            } else {
                0.0
            };
            let lane = ngsim.lanes.lane_at(x, y);
            let fields = [
                id.to_string(),
                p.frame.to_string(),
                points.len().to_string(),
                (1_113_433_200_000u64 + u64::from(p.frame) * 100).to_string(),
                format!("{:.3}", x / FOOT),
                format!("{:.3}", y / FOOT),
                "0.000".into(),
                "0.000".into(),
                format!("{length:.1}"),
                format!("{width:.1}"),
                "2".into(),
                format!("{:.2}", speed / FOOT),
                format!("{:.2}", accel / FOOT),
                lane.to_string(),
                "0".into(),
                "0".into(),
                "0.00".into(),
                "0.00".into(),
            ];
            out.push_str(&fields.join(sep));
            if layout == Layout::Csv {
                out.push_str(",101,201,0,0,2,1,i-80");
            }
            out.push('\n');
        }
    }
    out
}
