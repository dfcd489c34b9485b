//! Merge scenarios: every vehicle first seen on the on-ramp and last seen in the target lane
//! is an ego. Its scenario starts at the first frame where its centre is
//! `merge.start_distance` before the conflict point (it must still be on the ramp then); its
//! players are the target-lane vehicles of that frame, up to `n_leaders` ahead and
//! `n_followers` behind by distance to the conflict point, in the slots of training (fewer when
//! the data has fewer).

use crate::ngsim::config::{FRAME_SECONDS, NgsimConfig};
use crate::ngsim::process::Prepared;
use crate::world::neighbors::player_slots;
use serde::Serialize;

/// One merge scenario; vehicles are indices into [`Prepared::tracks`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MergeScenario {
    /// The ego's track.
    pub ego: usize,
    /// First frame.
    pub start_frame: u32,
    /// `(track, player slot)`, leaders front-most first, then followers nearest first.
    pub players: Vec<(usize, usize)>,
}

/// Extracted scenarios and why other ramp vehicles gave none.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Extraction {
    /// Scenarios by start frame (at most `merge.max_scenarios`).
    pub scenarios: Vec<MergeScenario>,
    /// Merging vehicles that give a scenario (before the cap).
    pub available: usize,
    /// Merging vehicles first seen past the start position, or no longer on the ramp there.
    pub late: usize,
    /// Merging vehicles whose record ends before the start position.
    pub short: usize,
}

/// Extracts the merge scenarios of `data`.
pub fn extract(data: &Prepared, config: &NgsimConfig, n_leaders: usize, n_followers: usize) -> Extraction {
    let lanes = &config.lanes;
    let start_x = config.merge.conflict_point - config.merge.start_distance;
    let mut out = Extraction::default();
    for (e, ego) in data.tracks.iter().enumerate() {
        let last = ego.lane.len() - 1;
        if ego.lane[0] != lanes.ramp_lane() || ego.lane[last] != lanes.target_lane() {
            continue;
        }
        let Some(k) = (0..=last).find(|&k| ego.centre(k) >= start_x) else {
            out.short += 1;
            continue;
        };
        // Seen first well past the start (more than one frame of travel), or merged already.
        if ego.lane[k] != lanes.ramp_lane()
            || (k == 0 && ego.centre(0) > start_x + ego.speed[0].abs() * FRAME_SECONDS + 0.5)
        {
            out.late += 1;
            continue;
        }
        let frame = ego.frames[k];
        let target: Vec<(usize, f64)> = data
            .tracks
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != e)
            .filter_map(|(j, t)| {
                let i = t.at(frame)?;
                (t.lane[i] == lanes.target_lane()).then(|| (j, t.centre(i)))
            })
            .collect();
        out.scenarios.push(MergeScenario {
            ego: e,
            start_frame: frame,
            players: player_slots(ego.centre(k), &target, n_leaders, n_followers),
        });
    }
    out.available = out.scenarios.len();
    out.scenarios
        .sort_by_key(|s| (s.start_frame, data.tracks[s.ego].id));
    out.scenarios.truncate(config.merge.max_scenarios);
    out
}
