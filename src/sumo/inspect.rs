//! `mpgdrive net inspect`: finds the merges of a SUMO network and proposes a `merge.toml`.
//!
//! A merge is either
//! - an **acceleration lane**: a lane that ends (no connection leaves it) beside a lane of the
//!   same edge that goes on, the target lane: the lane to its left, else the one to its right
//!   (this covers a lane drop whose outer lane ends, and a ramp that joins on the inner side);
//! - a **junction merge**: a lane whose connections all lead into one edge, the first (lowest
//!   index) into a lane that another incoming lane also leads into, and which yields to that
//!   lane there (its link is minor where the other's is major; with equal links, a zipper or a
//!   lane drop into one lane, the lane of the lower-priority edge, then of the edge with fewer
//!   lanes, then the right one). That is the paper's forced merge: the ramp lane ends at the
//!   conflict point. A lane that turns onto several roads approaches an intersection and is not
//!   a merge. Behind a traffic light (ramp metering, or a signal where two roads join) it is a
//!   merge when both roads lead only into the one they join, and an intersection's approach
//!   otherwise (`cosim` holds driven vehicles at a red light, and a vehicle held at one is
//!   out of the merge until it turns green).
//!
//! Only lanes that passenger cars may use count (SUMO's `allow` and `disallow`): a sidewalk
//! that ends at every junction, or a bicycle lane beside a ramp, is no acceleration lane.
//!
//! The ramp lanes are the last ramp lane and the lanes leading into it, followed back through
//! the connections (where two lead into one, the one with the right of way) until the ramp
//! reaches an edge of the target lanes (a ramp that left the freeway upstream); the target
//! lanes are the target lane and the lanes it continues from (the same way) and into (straight
//! on first). Positions are along the lanes ([`LanePositions`]), from 0 at the start of the first
//! target lane.

use crate::sumo::LanePositions;
use crate::sumo::geometry::{lane_beside, split_lane_id};
use crate::sumo::inputs::{InputError, with_network};
use crate::sumo::positions::{Link, MergeForm, connections_of};
use std::cmp::Reverse;
use std::collections::BTreeMap;
use std::path::Path;

/// One merge found in a network.
#[derive(Debug, Clone, PartialEq)]
pub struct Merge {
    /// How the ramp joins the target lane.
    pub form: MergeForm,
    /// The ramp lanes, upstream to downstream, the acceleration lane (or the lane that ends
    /// at the junction) last.
    pub ramp_lanes: Vec<String>,
    /// The target lanes, upstream to downstream.
    pub target_lanes: Vec<String>,
    /// The target lane the ramp joins: beside the acceleration lane, or the one a junction
    /// merge leads into.
    pub target_lane: String,
    /// Position where the acceleration lane begins (m): the first of the last ramp lanes that
    /// run beside a target lane, on one edge or several; for a junction merge, where the last
    /// ramp lane begins.
    pub lane_start: f64,
    /// Position where the last ramp lane ends (m): the stop line of a junction merge.
    pub lane_end: f64,
    /// Position where the first ramp lane begins (m).
    pub ramp_start: f64,
}

/// A lane: its edge, index, and the edge's priority and number of lanes.
struct Lane {
    edge: String,
    index: u32,
    priority: i64,
    lanes: usize,
}

/// At most this many lanes are followed in each direction.
const CHAIN: usize = 12;

/// The merges of the network in `net`: acceleration lanes in the order of their ids, then
/// junction merges in the order of their ramp lanes' ids.
pub fn find_merges(net: &Path) -> Result<Vec<Merge>, InputError> {
    with_network(net, merges_of)
}

fn merges_of(doc: &roxmltree::Document) -> Vec<Merge> {
    let mut lanes: BTreeMap<String, Lane> = BTreeMap::new();
    for edge in doc.root_element().children().filter(|n| n.has_tag_name("edge")) {
        let Some(id) = edge.attribute("id").filter(|id| !id.starts_with(':')) else {
            continue;
        };
        let priority = edge
            .attribute("priority")
            .and_then(|p| p.parse().ok())
            .unwrap_or(0);
        let edge_lanes: Vec<_> = edge.children().filter(|n| n.has_tag_name("lane")).collect();
        for lane in edge_lanes.iter().filter(|lane| admits_cars(lane)) {
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
                    priority,
                    lanes: edge_lanes.len(),
                },
            );
        }
    }
    // Connections between lanes of normal edges, in file order.
    let links: Vec<Link> = connections_of(doc)
        .into_iter()
        .filter(|l| lanes.contains_key(&l.from) && lanes.contains_key(&l.to))
        .collect();
    let continues = |lane: &str| links.iter().any(|l| l.from == lane);
    // The next lane along a chain: downstream the link straight on first, upstream the lane with
    // the most right of way (the road that has priority where two join); else file order.
    let next_lane = |at: &str, forward: bool| {
        let by = |l: &&Link| (forward && !l.straight, Reverse(right_of_way(&l.state)));
        match forward {
            true => links
                .iter()
                .filter(|l| l.from == at)
                .min_by_key(by)
                .map(|l| l.to.clone()),
            false => links
                .iter()
                .filter(|l| l.to == at)
                .min_by_key(by)
                .map(|l| l.from.clone()),
        }
    };
    // Up to CHAIN lanes from `first`, each next lane taken while `keep(chain so far, lane)`
    // (downstream, a road that loops back ends before a lane it already holds).
    let chain = |first: &str, forward: bool, keep: &dyn Fn(&[String], &str) -> bool| {
        let mut out = vec![first.to_owned()];
        while out.len() < CHAIN {
            let last = out.last().expect("not empty");
            match next_lane(last, forward) {
                Some(n) if !out.contains(&n) && keep(&out, &n) => out.push(n),
                _ => break,
            }
        }
        if !forward {
            out.reverse();
        }
        out
    };
    let any = |_: &[String], _: &str| true;
    // The ramp lanes back from its last lane: on the target lanes' edges only along the
    // acceleration lane, so a ramp that left the freeway upstream (a collector road, an
    // interchange) ends where it left it, and no freeway lane is a ramp lane.
    let ramp_chain = |last: &str, target_lanes: &[String]| {
        let edges: Vec<&str> = target_lanes.iter().map(|l| lanes[l].edge.as_str()).collect();
        let on_target_edge = |l: &str| edges.contains(&lanes[l].edge.as_str());
        chain(last, false, &|out, n| {
            !target_lanes.iter().any(|t| t == n)
                && (!on_target_edge(n) || out.iter().all(|l| on_target_edge(l)))
        })
    };
    let mut merges = Vec::new();
    // Acceleration lanes: a lane that ends beside a lane of its edge that goes on (the lane to
    // its left first, else the one to its right: a ramp that joins on the inner side).
    for id in lanes.keys() {
        if continues(id) {
            continue;
        }
        let Some((beside, _)) = lane_beside(id, |l| lanes.contains_key(l) && continues(l)) else {
            continue;
        };
        let mut target_lanes = chain(&beside, false, &any);
        let onward = chain(&beside, true, &|_, n| !target_lanes.iter().any(|t| t == n));
        target_lanes.extend(onward.into_iter().skip(1));
        merges.extend(placed(doc, ramp_chain(id, &target_lanes), target_lanes, &beside));
    }
    // Junction merges: a lane whose links all lead into one edge, the first of them into a lane
    // that another incoming lane also leads into, and which yields to it there.
    for id in lanes.keys() {
        let out: Vec<&Link> = links.iter().filter(|l| l.from == *id).collect();
        let Some(first) = out.iter().min_by_key(|l| lanes[&l.to].index) else {
            continue;
        };
        let joined = &lanes[&first.to].edge;
        if out.iter().any(|l| lanes[&l.to].edge != *joined) {
            continue; // an intersection's approach: it turns onto several roads
        }
        let target = &first.to;
        let rank = |l: &Link| {
            let of = &lanes[&l.from];
            (right_of_way(&l.state), of.priority, of.lanes, of.index)
        };
        let others: Vec<&Link> = links
            .iter()
            .filter(|l| l.to == *target && l.from != *id)
            .collect();
        let Some(feeder) = others.iter().max_by_key(|l| rank(l)) else {
            continue;
        };
        if rank(first) >= rank(feeder) {
            continue; // it does not yield there: the feeder is the ramp, if either is
        }
        // Behind a signal, a road that also turns elsewhere makes the junction an intersection.
        let only_into_joined = |lane: &str| {
            let edge = &lanes[lane].edge;
            links
                .iter()
                .filter(|l| lanes[&l.from].edge == *edge)
                .all(|l| lanes[&l.to].edge == *joined)
        };
        let behind_signal = first.signalised || feeder.signalised;
        if behind_signal && !(only_into_joined(id) && only_into_joined(&feeder.from)) {
            continue;
        }
        let mut target_lanes = chain(&feeder.from, false, &|_, n| n != target);
        let onward = chain(target, true, &|_, n| !target_lanes.iter().any(|t| t == n));
        target_lanes.extend(onward);
        merges.extend(placed(doc, ramp_chain(id, &target_lanes), target_lanes, target));
    }
    merges
}

/// Whether passenger cars may use a lane (SUMO's `allow` and `disallow` lists of vehicle
/// classes; neither: every class).
fn admits_cars(lane: &roxmltree::Node) -> bool {
    let lists = |key: &str| {
        lane.attribute(key)
            .map(|v| v.split_whitespace().any(|c| c == "passenger" || c == "all"))
    };
    match (lists("allow"), lists("disallow")) {
        (Some(allowed), _) => allowed,
        (None, Some(disallowed)) => !disallowed,
        (None, None) => true,
    }
}

/// How much right of way a link state gives: major, then zipper or equal, then the rest (minor,
/// stop, yield).
fn right_of_way(state: &str) -> u8 {
    match state {
        "M" | "O" => 2,
        "Z" | "=" => 1,
        _ => 0,
    }
}

/// The merge of `ramp_lanes` into `target`, one of `target_lanes`, placed along the lanes
/// (none when they do not fit together).
fn placed(
    doc: &roxmltree::Document,
    ramp_lanes: Vec<String>,
    target_lanes: Vec<String>,
    target: &str,
) -> Option<Merge> {
    let positions = LanePositions::of_network(doc, &ramp_lanes, &target_lanes, 0.0).ok()?;
    let (mut lane_start, lane_end) = positions.span(ramp_lanes.last()?)?;
    let (ramp_start, _) = positions.span(&ramp_lanes[0])?;
    if positions.form() == MergeForm::AccelerationLane {
        // An acceleration lane may span several edges: it begins at the first of the last ramp
        // lanes that each run beside a target lane.
        let beside = |lane: &&String| lane_beside(lane, |l| target_lanes.iter().any(|t| t == l)).is_some();
        let first = ramp_lanes.iter().rev().take_while(beside).last()?;
        lane_start = positions.span(first)?.0;
    }
    Some(Merge {
        form: positions.form(),
        ramp_lanes,
        target_lane: target.to_owned(),
        target_lanes,
        lane_start,
        lane_end,
        ramp_start,
    })
}

fn quoted(list: &[String]) -> String {
    let items: Vec<String> = list.iter().map(|l| format!("\"{l}\"")).collect();
    format!("[{}]", items.join(", "))
}

/// Where the conflict point goes on an acceleration lane: 20 m before its end (a vehicle's
/// centre never reaches the very end: SUMO stops it there), within the lane.
pub const BEFORE_END: f64 = 20.0;

/// Egos are picked up at least this far before the acceleration lane begins, and may merge
/// from this far into it (m).
pub const LANE_MARGIN: f64 = 10.0;

/// Egos are picked up this far before the end of the ramp lanes (m): where a traffic policy's
/// conflict point is in `cosim` (its training's ramp ends at `x_c`), and as far as its
/// training starts them (`sampling.ego_position`, 40-120 m before `x_c`).
pub const PICK_UP: f64 = 120.0;

/// A commented `merge.toml` for `merge` of the network `net`. On an acceleration lane: the
/// conflict point [`BEFORE_END`] before its end, egos picked up [`PICK_UP`] before the end, or
/// [`LANE_MARGIN`] before the acceleration lane if that is earlier, and merging from
/// [`LANE_MARGIN`] into it. At a junction: the conflict point at the stop line (the end of the
/// ramp lane, rounded down to 0.1 m so that it stays on the lane), egos picked up [`PICK_UP`]
/// before it, no `merge_from`.
pub fn proposal(merge: &Merge, net: &Path) -> String {
    header(net) + &keys_of(merge)
}

/// The keys of `merge`'s proposal (see [`proposal`]).
fn keys_of(merge: &Merge) -> String {
    let last = merge.ramp_lanes.last().map_or("", String::as_str);
    let (x_c, where_, merge_from) = match merge.form {
        MergeForm::AccelerationLane => {
            let x_c = (merge.lane_end - BEFORE_END).max(0.5 * (merge.lane_start + merge.lane_end));
            let from = (merge.lane_start + LANE_MARGIN).min(x_c);
            (
                x_c,
                format!(
                    "20 m before the end of the acceleration lane `{last}` (at {:.1}):\n\
                     #                                  ramp vehicles join the target lane here; SUMO stops them at the end",
                    merge.lane_end
                ),
                format!(
                    "merge_from = {from:.1}              # egos change to the target lane at the first safe gap from here on\n\
                     #                                  (10 m into the acceleration lane), as SUMO's drivers do (entry rule: never forced)\n"
                ),
            )
        }
        MergeForm::Junction => (
            on_lane_to_a_decimal(merge.lane_end),
            format!(
                "the stop line: `{last}` ends at the junction and leads into\n\
                 #                                  `{}`; ramp vehicles wait here for a safe gap and enter by driving on",
                merge.target_lane
            ),
            String::new(),
        ),
    };
    // Before the acceleration lane: SUMO's drivers change lanes as soon as they reach it, and
    // a ramp vehicle that changed before pick-up is never an ego.
    let mut control_from = (merge.lane_end - PICK_UP).max(merge.ramp_start);
    if merge.form == MergeForm::AccelerationLane {
        control_from = control_from
            .min(merge.lane_start - LANE_MARGIN)
            .max(merge.ramp_start);
    }
    let ramp = quoted(&merge.ramp_lanes);
    let target = quoted(&merge.target_lanes);
    format!(
        "target_start = 0.0               # the position of the start of target_lanes' first lane\n\
         conflict_point = {x_c:.1}          # {where_}\n\
         control_from = {control_from:.1}            # egos are picked up here: 120 m before the ramp's end, where a traffic\n\
         #                                  policy's x_c is (training starts them 40-120 m before x_c), or 10 m before an\n\
         #                                  acceleration lane if that is earlier, and not before the ramp begins\n\
         release_after = 200.0            # a merged ego is released 200 m past x_c (training's road reaches 220 m past it)\n\
         {merge_from}\
         ramp_lanes = {ramp}   # in driving order, the lane that ends last\n\
         target_lanes = {target}   # in driving order\n\
         controllable_types = [\"ctrl\"]   # the vehicle types of your route files that mpgdrive may drive: edit\n\
         players = \"controllable\"         # or \"all\": the MPG policy also drives every player of an ego's game\n"
    )
}

/// The largest position at one decimal, as a proposal writes it, that is not past `end`: a
/// lane end just below a tenth (2037.8999999999999, say) must not round up past itself.
fn on_lane_to_a_decimal(end: f64) -> f64 {
    let mut tenths = (end * 10.0).floor();
    if tenths / 10.0 > end {
        tenths -= 1.0;
    }
    tenths / 10.0
}

/// A commented `merge.toml` for every merge of `merges` in the network `net`: the single form
/// for one, `[[merge]]` tables (each named after its ramp's first edge) for several.
///
/// A merge whose ramp lanes overlap an earlier one's (a ramp of two lanes, one ending beside the
/// other, then joining the freeway) is left out with a comment: a vehicle is the ego of one
/// merge at a time. Names are unique (the lane's id where two merges start on one edge).
pub fn proposals(merges: &[Merge], net: &Path) -> String {
    let mut kept: Vec<&Merge> = Vec::new();
    let mut skipped = String::new();
    for m in merges {
        match kept
            .iter()
            .position(|k| k.ramp_lanes.iter().any(|l| m.ramp_lanes.contains(l)))
        {
            Some(k) => {
                skipped += &format!(
                    "# Left out: the merge of `{}` shares ramp lanes with merge {} below.\n",
                    m.ramp_lanes.last().map_or("", String::as_str),
                    k + 1
                );
            }
            None => kept.push(m),
        }
    }
    if let [one] = kept.as_slice() {
        return proposal(one, net) + &skipped;
    }
    let mut text = header(net) + &skipped;
    let mut names: Vec<&str> = Vec::new();
    for m in kept {
        let first = m.ramp_lanes.first().map_or("", String::as_str);
        let edge = split_lane_id(first).map_or(first, |(edge, _)| edge);
        let name = if names.contains(&edge) { first } else { edge };
        names.push(name);
        text += &format!("\n[[merge]]\nname = \"{name}\"\n{}", keys_of(m));
    }
    text
}

/// The comment that opens a proposal.
fn header(net: &Path) -> String {
    format!(
        "# merge.toml proposed by `mpgdrive net inspect {}`: check it, then save it next to the\n\
         # .sumocfg (cosim and batch read it from there, or from --merge). Units: m. Positions are\n\
         # distances driven along the lanes, from 0 at the start of the first target lane; a ramp\n\
         # vehicle's position is the target-lane position it reaches by driving on.\n",
        net.display()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A freeway lane `a_0` (100 m, priority 3) and a ramp `r_0` (40 m, priority 1) meeting at a
    /// junction: `a_0` into `o_0` through a 6 m junction lane with link state `main`, `r_0` into
    /// `o_0` (8 m) and `o_1` (9 m) with `ramp`; `extra` goes on the ramp's links.
    fn net(main: &str, ramp: &str, extra: &str) -> String {
        format!(
            r#"<net>
            <edge id=":j_0" function="internal"><lane id=":j_0_0" index="0" length="8.00"/><lane id=":j_0_1" index="1" length="9.00"/></edge>
            <edge id=":j_1" function="internal"><lane id=":j_1_0" index="0" length="6.00"/></edge>
            <edge id="a" priority="3"><lane id="a_0" index="0" length="100.00"/></edge>
            <edge id="r" priority="1"><lane id="r_0" index="0" length="40.00"/></edge>
            <edge id="o" priority="3"><lane id="o_0" index="0" length="50.00"/><lane id="o_1" index="1" length="50.00"/></edge>
            <connection from="a" to="o" fromLane="0" toLane="0" via=":j_1_0" state="{main}"/>
            <connection from=":j_1" to="o" fromLane="0" toLane="0" state="M"/>
            <connection from="r" to="o" fromLane="0" toLane="0" via=":j_0_0" state="{ramp}"{extra}/>
            <connection from="r" to="o" fromLane="0" toLane="1" via=":j_0_1" state="{ramp}"{extra}/>
            <connection from=":j_0" to="o" fromLane="0" toLane="0" state="M"/>
            <connection from=":j_0" to="o" fromLane="1" toLane="1" state="M"/>
            </net>"#
        )
    }

    #[test]
    fn an_acceleration_lane_over_two_edges_begins_on_the_first_on_either_side() {
        // Ramp r_0 (40 m) -> b_R (100 m) -> c_R (60 m, ends); freeway a_0 (200 m) -> b_F -> c_F
        // -> d_0 (no junction lanes). The ramp joins on the outer side (R = 0, F = 1) or on the
        // inner side (R = 1, F = 0), where the lane beside it is the one to its right.
        for (r, f) in [(0, 1), (1, 0)] {
            let text = format!(
                r#"<net>
                <edge id="a"><lane id="a_0" index="0" length="200.00"/></edge>
                <edge id="r"><lane id="r_0" index="0" length="40.00"/></edge>
                <edge id="b"><lane id="b_0" index="0" length="100.00"/><lane id="b_1" index="1" length="100.00"/></edge>
                <edge id="c"><lane id="c_0" index="0" length="60.00"/><lane id="c_1" index="1" length="60.00"/></edge>
                <edge id="d"><lane id="d_0" index="0" length="300.00"/></edge>
                <connection from="a" to="b" fromLane="0" toLane="{f}"/>
                <connection from="r" to="b" fromLane="0" toLane="{r}"/>
                <connection from="b" to="c" fromLane="0" toLane="0"/>
                <connection from="b" to="c" fromLane="1" toLane="1"/>
                <connection from="c" to="d" fromLane="{f}" toLane="0"/>
                </net>"#
            );
            let found = merges(&text);
            assert_eq!(found.len(), 1);
            let m = &found[0];
            assert_eq!(m.form, MergeForm::AccelerationLane);
            assert_eq!(
                m.ramp_lanes,
                ["r_0".to_owned(), format!("b_{r}"), format!("c_{r}")]
            );
            assert_eq!(
                m.target_lanes,
                ["a_0".to_owned(), format!("b_{f}"), format!("c_{f}"), "d_0".into()]
            );
            assert_eq!(m.target_lane, format!("c_{f}"));
            // b_R runs beside b_F from 200 m, c_R beside c_F to 360 m; the ramp starts at 160 m.
            assert_eq!((m.ramp_start, m.lane_start, m.lane_end), (160.0, 200.0, 360.0));
        }
    }

    #[test]
    fn proposals_leave_out_merges_that_share_ramp_lanes_and_keep_names_unique() {
        let merge = |ramp: &[&str], target: &[&str]| Merge {
            form: MergeForm::AccelerationLane,
            ramp_lanes: ramp.iter().map(|l| l.to_string()).collect(),
            target_lanes: target.iter().map(|l| l.to_string()).collect(),
            target_lane: target[1].to_owned(),
            lane_start: 300.0,
            lane_end: 400.0,
            ramp_start: 100.0,
        };
        let merges = [
            merge(&["r_1", "m_0"], &["a_0", "m_1", "b_0"]),
            merge(&["r_0"], &["r_1", "m_0"]),
            merge(&["q_0", "m_0"], &["a_0", "m_1", "b_0"]),
        ];
        let text = proposals(&merges, Path::new("n.net.xml"));
        assert!(
            text.contains("# Left out: the merge of `m_0` shares ramp lanes with merge 1"),
            "{text}"
        );
        let names: Vec<&str> = text.lines().filter_map(|l| l.strip_prefix("name = ")).collect();
        assert_eq!(names, ["\"r\"", "\"r_0\""]);
        let parsed: toml::Table = text.parse().unwrap();
        assert_eq!(parsed["merge"].as_array().unwrap().len(), 2);
    }

    #[test]
    fn a_junction_merges_proposed_stop_line_lies_on_its_last_ramp_lane() {
        // 2037.8999999999999 times 10 rounds to 20379.0 in f64: floored naively, 2037.9 lies
        // past the lane's end and `cosim` refuses the proposal.
        let lane_end = 2037.8999999999999;
        let m = Merge {
            form: MergeForm::Junction,
            ramp_lanes: vec!["r_0".into()],
            target_lanes: vec!["a_0".into(), "o_0".into()],
            target_lane: "o_0".into(),
            lane_start: 1966.46,
            lane_end,
            ramp_start: 1966.46,
        };
        let parsed: toml::Table = keys_of(&m).parse().unwrap();
        let x_c = parsed["conflict_point"].as_float().unwrap();
        assert_eq!(x_c, 2037.8);
        // A lane end on a tenth is the stop line itself.
        let x_c = |end: f64| {
            format!("{:.1}", on_lane_to_a_decimal(end))
                .parse::<f64>()
                .unwrap()
        };
        assert_eq!((x_c(496.0), x_c(496.04), x_c(0.3)), (496.0, 496.0, 0.3));
    }

    fn merges(text: &str) -> Vec<Merge> {
        merges_of(&roxmltree::Document::parse(text).unwrap())
    }

    #[test]
    fn a_lane_that_yields_at_a_junction_into_a_lane_another_feeds_is_a_junction_merge() {
        for (main, ramp) in [("M", "m"), ("Z", "Z")] {
            let found = merges(&net(main, ramp, ""));
            assert_eq!(found.len(), 1, "{main} {ramp}");
            let m = &found[0];
            assert_eq!(m.form, MergeForm::Junction);
            assert_eq!(m.ramp_lanes, ["r_0"]);
            assert_eq!(m.target_lanes, ["a_0", "o_0"]);
            assert_eq!(m.target_lane, "o_0");
            // o_0 starts at 106; the ramp's 8 m junction lane ends there: the stop line is 98.
            assert_eq!((m.lane_start, m.lane_end), (58.0, 98.0));
        }
        // Where the freeway lane yields, it is the lane that merges.
        let swapped = merges(&net("m", "M", ""));
        assert_eq!(swapped.len(), 1);
        assert_eq!(
            (
                swapped[0].ramp_lanes.as_slice(),
                swapped[0].target_lanes.as_slice()
            ),
            (&["a_0".to_owned()][..], &["r_0".to_owned(), "o_0".to_owned()][..])
        );
        // Two major links: neither yields, no merge.
        assert!(merges(&net("M", "M", "").replace("priority=\"1\"", "priority=\"3\"")).is_empty());
    }

    #[test]
    fn behind_a_signal_two_roads_into_one_merge_and_an_intersection_does_not() {
        // Ramp metering: a signal on the ramp's links, both roads lead only into `o`.
        let metered = merges(&net("O", "o", " tl=\"j\""));
        assert_eq!(metered.len(), 1);
        assert_eq!(metered[0].ramp_lanes, ["r_0"]);
        assert_eq!((metered[0].lane_start, metered[0].lane_end), (58.0, 98.0));
        // The freeway also turns onto another road `t` there: an intersection's approach.
        let turn = r#"<edge id="t" priority="1"><lane id="t_0" index="0" length="50.00"/></edge>
            <connection from="a" to="t" fromLane="0" toLane="0" state="O" tl="j"/>
            </net>"#;
        assert!(merges(&net("O", "o", " tl=\"j\"").replace("</net>", turn)).is_empty());
        // Without the signal the same ramp still yields into `o`: a merge.
        assert_eq!(merges(&net("M", "m", "").replace("</net>", turn)).len(), 1);
    }

    #[test]
    fn lanes_closed_to_cars_are_neither_ramps_nor_targets() {
        // A sidewalk `w_0` beside the freeway lane `w_1` ends where the lane goes on: with
        // cars allowed it would be an acceleration lane; a bicycle lane neither.
        let walk = |allow: &str| {
            format!(
                r#"<net>
            <edge id="w" priority="3"><lane id="w_0" index="0" {allow} length="80.00"/><lane id="w_1" index="1" length="80.00"/></edge>
            <edge id="n" priority="3"><lane id="n_0" index="0" length="80.00"/></edge>
            <connection from="w" to="n" fromLane="1" toLane="0" state="M"/>
            </net>"#
            )
        };
        assert_eq!(merges(&walk("")).len(), 1);
        assert_eq!(merges(&walk(r#"allow="passenger truck""#)).len(), 1);
        assert!(merges(&walk(r#"allow="pedestrian""#)).is_empty());
        assert!(merges(&walk(r#"allow="bicycle""#)).is_empty());
        assert!(merges(&walk(r#"disallow="all""#)).is_empty());
        assert_eq!(merges(&walk(r#"disallow="pedestrian bicycle""#)).len(), 1);
    }
}
