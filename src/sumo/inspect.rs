//! `mpgdrive net inspect`: finds the merges of a SUMO network and proposes a `merge.toml`.
//!
//! A merge is a lane that ends (no connection leaves it) beside a lane of the same edge that
//! goes on: the acceleration lane, and the target lane to its left. The ramp lanes are the
//! acceleration lane and the lanes leading into it, followed back through the connections; the
//! target lanes are the target lane and the lanes it continues from and into. Positions are
//! along the lanes ([`LanePositions`]), from 0 at the start of the first target lane.

use crate::sumo::LanePositions;
use crate::sumo::inputs::{InputError, with_network};
use crate::sumo::positions::connections_of;
use std::collections::BTreeMap;
use std::path::Path;

/// One merge found in a network.
#[derive(Debug, Clone, PartialEq)]
pub struct Merge {
    /// The ramp lanes, upstream to downstream, the acceleration lane last.
    pub ramp_lanes: Vec<String>,
    /// The target lanes, upstream to downstream.
    pub target_lanes: Vec<String>,
    /// The target lane beside the acceleration lane.
    pub target_lane: String,
    /// Position where the acceleration lane begins (m).
    pub lane_start: f64,
    /// Position where the acceleration lane ends (m).
    pub lane_end: f64,
    /// Position where the first ramp lane begins (m).
    pub ramp_start: f64,
}

/// A lane: its edge and index.
struct Lane {
    edge: String,
    index: u32,
}

/// At most this many lanes are followed in each direction.
const CHAIN: usize = 12;

/// The merges of the network in `net`, in the order of their acceleration lanes' ids.
pub fn find_merges(net: &Path) -> Result<Vec<Merge>, InputError> {
    with_network(net, merges_of)
}

fn merges_of(doc: &roxmltree::Document) -> Vec<Merge> {
    let mut lanes: BTreeMap<String, Lane> = BTreeMap::new();
    for edge in doc.root_element().children().filter(|n| n.has_tag_name("edge")) {
        let Some(id) = edge.attribute("id").filter(|id| !id.starts_with(':')) else {
            continue;
        };
        for lane in edge.children().filter(|n| n.has_tag_name("lane")) {
            let (Some(lane_id), Some(index)) = (
                lane.attribute("id"),
                lane.attribute("index").and_then(|i| i.parse().ok()),
            ) else {
                continue;
            };
            lanes.insert(
                lane_id.to_owned(),
                Lane {
                    edge: id.to_owned(),
                    index,
                },
            );
        }
    }
    let lane_id = |edge: &str, index: &str| format!("{edge}_{index}");
    // Connections between lanes of normal edges: (from lane, to lane), in file order.
    let links: Vec<(String, String)> = connections_of(doc)
        .into_iter()
        .filter(|l| lanes.contains_key(&l.from) && lanes.contains_key(&l.to))
        .map(|l| (l.from, l.to))
        .collect();
    let continues = |lane: &str| links.iter().any(|(f, _)| f == lane);
    let chain = |first: &str, forward: bool| {
        let mut out = vec![first.to_owned()];
        while out.len() < CHAIN {
            let last = out.last().expect("not empty");
            let next = links.iter().find_map(|(f, t)| match forward {
                true if f == last => Some(t.clone()),
                false if t == last => Some(f.clone()),
                _ => None,
            });
            match next {
                Some(n) if !out.contains(&n) => out.push(n),
                _ => break,
            }
        }
        if !forward {
            out.reverse();
        }
        out
    };
    let mut merges = Vec::new();
    for (id, lane) in &lanes {
        let left = lane_id(&lane.edge, &(lane.index + 1).to_string());
        if continues(id) || !lanes.contains_key(&left) || !continues(&left) {
            continue;
        }
        let ramp_lanes = chain(id, false);
        let mut target_lanes = chain(&left, false);
        target_lanes.extend(chain(&left, true).into_iter().skip(1));
        let Ok(positions) = LanePositions::of_network(doc, &ramp_lanes, &target_lanes, 0.0) else {
            continue;
        };
        let (Some((lane_start, lane_end)), Some((ramp_start, _))) =
            (positions.span(id), positions.span(&ramp_lanes[0]))
        else {
            continue;
        };
        merges.push(Merge {
            ramp_lanes,
            target_lanes,
            target_lane: left,
            lane_start,
            lane_end,
            ramp_start,
        });
    }
    merges
}

fn quoted(list: &[String]) -> String {
    let items: Vec<String> = list.iter().map(|l| format!("\"{l}\"")).collect();
    format!("[{}]", items.join(", "))
}

/// Where the conflict point goes: 20 m before the end of the acceleration lane (a vehicle's
/// centre never reaches the very end: SUMO stops it there), within the lane.
pub const BEFORE_END: f64 = 20.0;

/// Egos are picked up at least this far before the acceleration lane begins, and may merge
/// from this far into it (m).
pub const LANE_MARGIN: f64 = 10.0;

/// A commented `merge.toml` for `merge` of the network `net`: the conflict point
/// [`BEFORE_END`] before the end of the acceleration lane, egos picked up 120 m before it, or
/// [`LANE_MARGIN`] before the acceleration lane if that is earlier, and merging from
/// [`LANE_MARGIN`] into it.
pub fn proposal(merge: &Merge, net: &Path) -> String {
    let x_c = (merge.lane_end - BEFORE_END).max(0.5 * (merge.lane_start + merge.lane_end));
    // Before the acceleration lane: SUMO's drivers change lanes as soon as they reach it, and
    // a ramp vehicle that changed before pick-up is never an ego.
    let control_from = (x_c - 120.0)
        .min(merge.lane_start - LANE_MARGIN)
        .max(merge.ramp_start);
    let merge_from = (merge.lane_start + LANE_MARGIN).min(x_c);
    format!(
        "# merge.toml proposed by `mpgdrive net inspect {net}`: check it, then save it next to the\n\
         # .sumocfg (cosim and batch read it from there, or from --merge). Units: m. Positions are\n\
         # distances driven along the lanes, from 0 at the start of the first target lane; a ramp\n\
         # vehicle's position is the target-lane position it reaches by driving on.\n\
         target_start = 0.0               # the position of the start of target_lanes' first lane\n\
         conflict_point = {x_c:.1}          # 20 m before the end of the acceleration lane `{accel}` (at {end:.1}):\n\
         #                                  ramp vehicles join the target lane here; SUMO stops them at the end\n\
         control_from = {control_from:.1}            # egos are picked up here: 120 m before x_c (training starts them 40-120 m\n\
         #                                  before), or on the ramp 10 m before the acceleration lane if that is\n\
         #                                  earlier (SUMO's drivers change lanes as soon as they reach it)\n\
         release_after = 50.0             # a merged ego is released 50 m past x_c\n\
         merge_from = {merge_from:.1}              # egos change to the target lane at the first safe gap from here on\n\
         #                                  (10 m into the acceleration lane), as SUMO's drivers do; at x_c at the latest\n\
         ramp_lanes = {ramp}   # in driving order, the acceleration lane last\n\
         target_lanes = {target}   # in driving order\n\
         controllable_types = [\"ctrl\"]   # the vehicle types of your route files that mpgdrive may drive: edit\n\
         players = \"controllable\"         # or \"all\": the MPG policy also drives every player of an ego's game\n",
        net = net.display(),
        accel = merge.ramp_lanes.last().map_or("", String::as_str),
        end = merge.lane_end,
        ramp = quoted(&merge.ramp_lanes),
        target = quoted(&merge.target_lanes),
    )
}
