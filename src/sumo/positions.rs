//! Positions along the merge's lanes: the one coordinate every rule of the co-simulation reads
//! (observation, feasibility projection, merge gate, pick-up, release, time-space diagrams).
//!
//! A position is a distance driven along the lanes, so a curved ramp, a rotated network or a
//! freeway that bends measure what the internal simulator measures. The target lanes, in
//! driving order, are laid end to end (with the junction lanes between them) from
//! `target_start` at the start of the first; the acceleration lane (the last ramp lane) runs
//! beside the target lane of its edge, at the same positions; the ramp lanes before it are
//! laid back from its start, so a ramp vehicle's distance to the conflict point is the
//! distance it has to drive. A vehicle's position is its lane's start plus its lane position
//! (SUMO's `getLanePosition`, which runs along the lane's `length`).
//!
//! A **junction merge** ([`MergeForm::Junction`]) has no acceleration lane: the last ramp lane
//! ends at a junction and leads through it (a minor or zipper link) into one of the target
//! lanes, which other incoming lanes also lead into (the paper's forced merge; also a lane
//! drop whose two lanes both continue into one). The ramp's junction lanes (the *entry
//! lanes*) are laid back from the start of the target lane they lead into, and the ramp lanes
//! back from them, so the stop line at the end of the ramp lies where a vehicle driving on
//! reaches the target lane's junction lane of the same length.

use std::collections::HashMap;

/// A lane as the network gives it.
struct NetLane {
    length: f64,
    /// Speed limit (m/s).
    speed: Option<f64>,
}

/// Where each ramp, target and junction lane between them starts, and how lane positions
/// scale onto the road (1 except on an acceleration lane whose length differs from its
/// neighbour's).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LanePositions {
    lanes: HashMap<String, Placed>,
    /// How the ramp joins the target lane.
    form: MergeForm,
    /// A junction merge's entry lanes: the junction lanes that leave the last ramp lane.
    entry: Vec<String>,
    /// Speed limit of the target lane beside the acceleration lane (m/s), the road's speed
    /// where egos merge.
    road_speed: Option<f64>,
    /// A traffic light controls a link out of a ramp or target lane.
    signalised: bool,
    /// A junction merge whose entry links are minor (SUMO's `m`, or `s`, stop first), with no
    /// traffic light, from a ramp lane with no target lane beside it: SUMO's drivers there give
    /// way to every vehicle approaching on the target lane.
    minor_entry: bool,
    /// A junction merge whose entry links are all zipper links (SUMO's `Z`), with no traffic
    /// light: SUMO's drivers there merge by arrival, the first at the junction first.
    zipper_entry: bool,
    /// A junction merge whose last ramp lane runs beside a target lane of its edge (a lane drop).
    lane_drop: bool,
    /// The lanes besides the ramp and target lanes whose links the entry yields to and whose
    /// paths cross its own.
    crossing: Vec<CrossingLane>,
    /// The ramp and target lanes whose link on along the merge is a stop sign, with the
    /// position of their end, its stop line.
    stop_signs: HashMap<String, f64>,
}

/// An incoming lane of a junction merge's junction whose link the ramp's entry must yield to
/// (SUMO's `response` of the entry link names it) and whose path crosses the entry's, other
/// than the target lane's: a ramp linked across the lanes between it and its target lane (as
/// some edited maps are). Netconvert's on-ramps have none.
#[derive(Debug, Clone, PartialEq)]
pub struct CrossingLane {
    /// The incoming lane: a vehicle at lane position `p` on it is `length - p` before the
    /// junction.
    pub lane: String,
    /// Its length (m).
    pub length: f64,
    /// The junction lanes of its yielded-to links: a vehicle on one is in the junction.
    pub vias: Vec<String>,
}

/// How the ramp joins the target lane.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum MergeForm {
    /// The last ramp lane ends beside a target lane of the same edge, which goes on: a ramp
    /// vehicle changes lanes along it (an acceleration lane, or a lane drop whose lane ends).
    #[default]
    AccelerationLane,
    /// The last ramp lane ends at a junction and leads through it into a target lane: a ramp
    /// vehicle enters by driving on, from the stop line at the end of its lane.
    Junction,
}

/// One lane on the road.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Placed {
    start: f64,
    scale: f64,
    length: f64,
    /// Speed limit (m/s), when the network gives one.
    speed: Option<f64>,
}

/// How many junction lanes a connection may pass through.
const MAX_VIA: usize = 8;

impl LanePositions {
    /// The positions of `ramp_lanes` and `target_lanes` (each in driving order) in the
    /// network `doc`, the first target lane starting at `target_start`. The message says what
    /// does not fit: a lane that does not lead to the next one listed, or an acceleration lane
    /// that is not beside a target lane.
    pub fn of_network(
        doc: &roxmltree::Document,
        ramp_lanes: &[String],
        target_lanes: &[String],
        target_start: f64,
    ) -> Result<Self, String> {
        let net = lanes_of(doc);
        let links = connections_of(doc);
        let length = |id: &str| {
            net.get(id)
                .map(|l| l.length)
                .ok_or_else(|| format!("lane `{id}` is not in the network"))
        };
        let Some(accel) = ramp_lanes.last() else {
            return Err("ramp_lanes is empty".into());
        };
        // A junction merge when the last ramp lane leads into a target lane (first among the
        // forms: in a lane drop the lane beside it may be a target lane too), else an
        // acceleration lane beside one.
        let joins = target_lanes
            .iter()
            .enumerate()
            .skip(1)
            .find_map(|(k, t)| Some((k, via_lanes(&links, accel, t, "ramp_lanes").ok()?)));
        let beside = crate::sumo::geometry::lane_beside(accel, |l| target_lanes.iter().any(|t| t == l))
            .map(|(lane, _)| lane);
        // SUMO's drivers on a junction's minor road give way to all that approaches, unless they
        // can change lanes into the target lane beside them first (a lane drop).
        let target_beside = beside.is_some();
        let mut minor_entry = !target_beside;
        let mut zipper_entry = true;
        let (form, meets) = match (&joins, beside) {
            (Some((k, _)), _) => (MergeForm::Junction, target_lanes[*k].clone()),
            (None, Some(beside)) => (MergeForm::AccelerationLane, beside),
            (None, None) => {
                return Err(format!(
                    "the last ramp lane `{accel}` must be an acceleration lane (a lane beside it on \
                     the same edge one of target_lanes) or lead through a junction into one of \
                     target_lanes"
                ));
            }
        };
        let mut lanes = HashMap::new();
        let mut place = |lane: &str, start: f64, scale: f64| -> Result<f64, String> {
            let length = length(lane)?;
            let speed = net.get(lane).and_then(|l| l.speed);
            lanes.insert(
                lane.to_owned(),
                Placed {
                    start,
                    scale,
                    length,
                    speed,
                },
            );
            Ok(length)
        };
        let mut pos = target_start;
        let mut start = pos;
        for (k, lane) in target_lanes.iter().enumerate() {
            if k > 0 {
                for via in via_lanes(&links, &target_lanes[k - 1], lane, "target_lanes")? {
                    pos += place(&via, pos, 1.0)?;
                }
            }
            if *lane == meets {
                start = pos;
            }
            pos += place(lane, pos, 1.0)?;
        }
        let mut entry = Vec::new();
        // The junction lanes from the ramp into the target lane: SUMO's drivers take the first
        // link out of their lane that leads on, and the target lane is that link's.
        let path = joins.as_ref().map(|(_, vias)| vias.clone()).unwrap_or_default();
        match joins {
            Some((_, vias)) => {
                for via in vias.iter().rev() {
                    start -= length(via)?;
                    place(via, start, 1.0)?;
                }
                // Every junction lane out of the ramp is an entry lane, laid from the stop
                // line on (a ramp linked to several lanes may take any of them).
                for link in links.iter().filter(|l| l.from == *accel) {
                    minor_entry &= !link.signalised && matches!(link.state.as_str(), "m" | "s");
                    zipper_entry &= !link.signalised && link.state == "Z";
                    if let Some(via) = &link.via {
                        if vias.first() != Some(via) {
                            place(via, start, 1.0)?;
                        }
                        entry.push(via.clone());
                    }
                }
                start -= length(accel)?;
                place(accel, start, 1.0)?;
            }
            None => {
                minor_entry = false;
                zipper_entry = false;
                place(accel, start, length(&meets)? / length(accel)?)?;
            }
        }
        for k in (0..ramp_lanes.len() - 1).rev() {
            let vias = via_lanes(&links, &ramp_lanes[k], &ramp_lanes[k + 1], "ramp_lanes")?;
            for via in vias.iter().rev() {
                start -= length(via)?;
                place(via, start, 1.0)?;
            }
            start -= length(&ramp_lanes[k])?;
            place(&ramp_lanes[k], start, 1.0)?;
        }
        let road_speed = net.get(&meets).and_then(|l| l.speed);
        let mut steps: Vec<(&String, &String)> = (ramp_lanes.windows(2).chain(target_lanes.windows(2)))
            .map(|w| (&w[0], &w[1]))
            .collect();
        if form == MergeForm::Junction {
            steps.push((accel, &meets));
        }
        let stop_signs = steps
            .into_iter()
            .filter(|&(from, to)| {
                let link = links.iter().find(|l| l.from == *from && l.to == *to);
                link.is_some_and(Link::is_stop_sign)
            })
            .filter_map(|(from, _)| {
                let p = lanes.get(from)?;
                Some((from.clone(), p.start + p.scale * p.length))
            })
            .collect();
        let signalised = links
            .iter()
            .any(|l| l.signalised && (ramp_lanes.contains(&l.from) || target_lanes.contains(&l.from)));
        let ours = |lane: &str| ramp_lanes.iter().chain(target_lanes).any(|l| l == lane);
        let crossing = crossing_lanes(doc, &links, &path, ours)
            .into_iter()
            .map(|(lane, vias)| {
                Ok(CrossingLane {
                    length: length(&lane)?,
                    lane,
                    vias,
                })
            })
            .collect::<Result<_, String>>()?;
        Ok(LanePositions {
            lanes,
            lane_drop: form == MergeForm::Junction && target_beside,
            form,
            entry,
            road_speed,
            signalised,
            minor_entry,
            zipper_entry,
            crossing,
            stop_signs,
        })
    }

    /// How the ramp joins the target lane.
    pub fn form(&self) -> MergeForm {
        self.form
    }

    /// Whether `lane` is a junction lane out of a junction merge's last ramp lane: a vehicle
    /// on it has crossed the stop line and is entering the target lane.
    pub fn is_entry(&self, lane: &str) -> bool {
        self.entry.iter().any(|l| l == lane)
    }

    /// The speed limit of the target lane where egos merge (the lane beside the acceleration
    /// lane, or the one a junction merge leads into), m/s; none when the network does not give one.
    pub fn road_speed(&self) -> Option<f64> {
        self.road_speed
    }

    /// Whether the ramp enters by a minor link without a traffic light (a priority junction's
    /// minor road) and no target lane runs beside its last lane: SUMO's drivers cross its stop
    /// line only once no vehicle approaches on the target lane. Not in a lane drop, whose drivers
    /// change lanes into the room made for them (the zoo's `lanedrop-v25-l2` at a 30% share
    /// lost 0.949 of SUMO's drivers' time loss with the players making them no room, 0.902
    /// with it).
    pub fn minor_entry(&self) -> bool {
        self.minor_entry
    }

    /// Whether the merge is a lane drop: a junction merge whose last ramp lane runs beside a
    /// target lane of its edge, into which SUMO's drivers change lanes before it ends.
    pub fn is_lane_drop(&self) -> bool {
        self.lane_drop
    }

    /// Whether the ramp enters by zipper links without a traffic light (SUMO's `Z`, a zipper
    /// node): SUMO's drivers there go by arrival at the junction and take their turn, whether or
    /// not the vehicles behind them on the target lane made room.
    pub fn zipper_entry(&self) -> bool {
        self.zipper_entry
    }

    /// The length of the longest junction lane out of a junction merge's last ramp lane (m; 0
    /// on an acceleration lane): how far a vehicle drives from the stop line into the target lane.
    pub fn entry_length(&self) -> f64 {
        self.entry
            .iter()
            .filter_map(|l| self.lanes.get(l))
            .map(|p| p.length)
            .fold(0.0, f64::max)
    }

    /// The lanes other than the ramp and target lanes whose vehicles the ramp's entry yields
    /// to at its junction ([`CrossingLane`]); none on netconvert's on-ramps.
    pub fn crossing(&self) -> &[CrossingLane] {
        &self.crossing
    }

    /// Whether a traffic light controls a link out of a ramp or target lane (ramp metering, or
    /// a signal where the two roads join).
    pub fn signalised(&self) -> bool {
        self.signalised
    }

    /// The stop line at the end of `lane` (its position), where its link on along the merge is a
    /// stop sign ([`Link::is_stop_sign`]); none elsewhere.
    pub fn stop_sign(&self, lane: &str) -> Option<f64> {
        self.stop_signs.get(lane).copied()
    }

    /// The lanes that end at a stop sign ([`LanePositions::stop_sign`]), sorted.
    pub fn stop_sign_lanes(&self) -> Vec<&str> {
        let mut lanes: Vec<&str> = self.stop_signs.keys().map(String::as_str).collect();
        lanes.sort_unstable();
        lanes
    }

    /// The position of lane position `lane_pos` on `lane` (none for a lane off the merge).
    pub fn position(&self, lane: &str, lane_pos: f64) -> Option<f64> {
        self.lanes.get(lane).map(|p| p.start + p.scale * lane_pos)
    }

    /// The speed limit of `lane` (m/s; a ramp, target or junction lane of the merge), when the
    /// network gives one.
    pub fn speed_limit(&self, lane: &str) -> Option<f64> {
        self.lanes.get(lane).and_then(|p| p.speed)
    }

    /// The positions `lane` covers, from its start to its end (m).
    pub fn span(&self, lane: &str) -> Option<(f64, f64)> {
        self.lanes
            .get(lane)
            .map(|p| (p.start, p.start + p.scale * p.length))
    }
}

/// Every lane of the network, internal ones included.
fn lanes_of(doc: &roxmltree::Document) -> HashMap<String, NetLane> {
    doc.descendants()
        .filter(|n| n.has_tag_name("lane"))
        .filter_map(|lane| {
            let length = lane.attribute("length")?.parse().ok()?;
            let speed = lane.attribute("speed").and_then(|s| s.parse().ok());
            Some((lane.attribute("id")?.to_owned(), NetLane { length, speed }))
        })
        .collect()
}

/// A connection between two lanes, the junction lane it passes through first, and its right of
/// way (SUMO's link state: `M` major, `m` minor, `Z` zipper, `=` equal, ...).
pub(crate) struct Link {
    pub(crate) from: String,
    pub(crate) to: String,
    via: Option<String>,
    pub(crate) state: String,
    /// The link goes straight on (SUMO's `dir="s"`, or no direction given).
    pub(crate) straight: bool,
    /// The link is controlled by a traffic light.
    pub(crate) signalised: bool,
}

impl Link {
    /// A stop sign without a traffic light: SUMO's `s` (a minor road's stop, `priority_stop`
    /// junctions) or `w` (`allway_stop`). SUMO's drivers come to a standstill at its stop line
    /// before they go on (then as a minor link: `s` gives way).
    pub(crate) fn is_stop_sign(&self) -> bool {
        !self.signalised && matches!(self.state.as_str(), "s" | "w")
    }
}

/// The network's connections, lane to lane, in file order.
pub(crate) fn connections_of(doc: &roxmltree::Document) -> Vec<Link> {
    doc.root_element()
        .children()
        .filter(|n| n.has_tag_name("connection"))
        .filter_map(|n| {
            Some(Link {
                from: format!("{}_{}", n.attribute("from")?, n.attribute("fromLane")?),
                to: format!("{}_{}", n.attribute("to")?, n.attribute("toLane")?),
                via: n.attribute("via").map(str::to_owned),
                state: n.attribute("state").unwrap_or("M").to_owned(),
                straight: n.attribute("dir").is_none_or(|d| d == "s"),
                signalised: n.attribute("tl").is_some(),
            })
        })
        .collect()
}

/// The incoming lanes (with the junction lanes of their links) whose links one of the `path`
/// junction lanes yields to, by its junction's `<request response=...>` (bit `k` from the
/// right: the link of the junction's `k`-th internal lane), and whose junction lane crosses
/// its path, leaving out lanes `ours` says are the merge's own. Netconvert makes a minor link
/// yield to every link into the same edge, also to those of lanes it never meets (an on-ramp
/// joining the right lane of a three-lane road yields to all three): those are left out.
fn crossing_lanes(
    doc: &roxmltree::Document,
    links: &[Link],
    path: &[String],
    ours: impl Fn(&str) -> bool,
) -> Vec<(String, Vec<String>)> {
    let mut found: Vec<(String, Vec<String>)> = Vec::new();
    let junctions = doc
        .root_element()
        .children()
        .filter(|n| n.has_tag_name("junction"));
    for junction in junctions {
        let internal: Vec<&str> = junction
            .attribute("intLanes")
            .unwrap_or("")
            .split_whitespace()
            .collect();
        let responses: HashMap<usize, &str> = junction
            .children()
            .filter(|n| n.has_tag_name("request"))
            .filter_map(|n| Some((n.attribute("index")?.parse().ok()?, n.attribute("response")?)))
            .collect();
        for via in path {
            let Some(response) = internal
                .iter()
                .position(|l| l == via)
                .and_then(|i| responses.get(&i))
            else {
                continue;
            };
            let yielded = response.bytes().rev().enumerate().filter(|&(_, b)| b == b'1');
            for foe in yielded.filter_map(|(k, _)| internal.get(k)) {
                let Some(link) = links.iter().find(|l| l.via.as_deref() == Some(*foe)) else {
                    continue;
                };
                if ours(&link.from) || !paths_cross(&shape_of(doc, via), &shape_of(doc, foe)) {
                    continue;
                }
                match found.iter_mut().find(|(lane, _)| *lane == link.from) {
                    Some((_, vias)) if !vias.iter().any(|v| v == foe) => vias.push((*foe).to_owned()),
                    Some(_) => {}
                    None => found.push((link.from.clone(), vec![(*foe).to_owned()])),
                }
            }
        }
    }
    found
}

/// The centre line of lane `id` (its `shape`), empty when the network gives none.
fn shape_of(doc: &roxmltree::Document, id: &str) -> Vec<(f64, f64)> {
    let lane = doc
        .descendants()
        .find(|n| n.has_tag_name("lane") && n.attribute("id") == Some(id));
    let points = lane.and_then(|n| n.attribute("shape")).unwrap_or("");
    points
        .split_whitespace()
        .filter_map(|p| {
            // `x,y`, or `x,y,z` in networks with elevation (OSM, OpenDRIVE imports).
            let mut xyz = p.split(',').map(str::parse::<f64>);
            Some((xyz.next()?.ok()?, xyz.next()?.ok()?))
        })
        .collect()
}

/// Whether two centre lines cross: a segment of one passes through a segment of the other
/// (touching at an end, as links out of one lane do, is not crossing).
fn paths_cross(a: &[(f64, f64)], b: &[(f64, f64)]) -> bool {
    let side =
        |p: (f64, f64), q: (f64, f64), r: (f64, f64)| (q.0 - p.0) * (r.1 - p.1) - (q.1 - p.1) * (r.0 - p.0);
    a.windows(2).any(|s| {
        b.windows(2).any(|t| {
            let (p, q, r, u) = (s[0], s[1], t[0], t[1]);
            side(p, q, r) * side(p, q, u) < 0.0 && side(r, u, p) * side(r, u, q) < 0.0
        })
    })
}

/// The junction lanes a vehicle passes from `from` to `to`, in order (none without internal
/// links); an error when `from` does not lead to `to`.
fn via_lanes(links: &[Link], from: &str, to: &str, key: &str) -> Result<Vec<String>, String> {
    let mut vias = Vec::new();
    let mut at = from.to_owned();
    while vias.len() <= MAX_VIA {
        let Some(link) = links.iter().find(|l| l.from == at && l.to == to) else {
            break;
        };
        match &link.via {
            Some(via) => {
                vias.push(via.clone());
                at = via.clone();
            }
            None => return Ok(vias),
        }
    }
    Err(format!(
        "{key}: `{from}` does not lead to `{to}` in the network (list the lanes in driving order, \
         each connected to the next)"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ramp `r_0` (50 m, 16 m/s) into acceleration lane `m_0` (40 m, 25 m/s, beside `m_1`) through a 5 m
    /// junction lane, and target lanes `a_0` (100 m) -> `m_1` (40 m) -> `b_0` (60 m), the
    /// first through a 3 m junction lane.
    const NET: &str = r#"<net>
        <edge id=":j1" function="internal"><lane id=":j1_0" index="0" length="3.00"/></edge>
        <edge id=":j2" function="internal"><lane id=":j2_0" index="0" length="5.00"/></edge>
        <edge id="a"><lane id="a_0" index="0" length="100.00"/></edge>
        <edge id="r"><lane id="r_0" index="0" speed="16.00" length="50.00"/></edge>
        <edge id="m"><lane id="m_0" index="0" speed="25.00" length="40.00"/><lane id="m_1" index="1" length="40.00"/></edge>
        <edge id="b"><lane id="b_0" index="0" length="60.00"/></edge>
        <connection from="a" to="m" fromLane="0" toLane="1" via=":j1_0"/>
        <connection from=":j1" to="m" fromLane="0" toLane="1"/>
        <connection from="r" to="m" fromLane="0" toLane="0" via=":j2_0"/>
        <connection from=":j2" to="m" fromLane="0" toLane="0"/>
        <connection from="m" to="b" fromLane="1" toLane="0"/>
    </net>"#;

    fn lanes(ids: &[&str]) -> Vec<String> {
        ids.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn lanes_are_laid_end_to_end_along_the_road() {
        let doc = roxmltree::Document::parse(NET).unwrap();
        let p = LanePositions::of_network(
            &doc,
            &lanes(&["r_0", "m_0"]),
            &lanes(&["a_0", "m_1", "b_0"]),
            -10.0,
        )
        .unwrap();
        // Target: a_0 from -10, the junction 90..93, m_1 93..133, b_0 from 133.
        assert_eq!(p.position("a_0", 0.0), Some(-10.0));
        assert_eq!(p.position(":j1_0", 1.0), Some(91.0));
        assert_eq!(p.position("m_1", 7.0), Some(100.0));
        assert_eq!(p.position("b_0", 2.5), Some(135.5));
        // The acceleration lane runs beside m_1; the ramp ends 5 m (the junction) before it.
        assert_eq!(p.position("m_0", 7.0), Some(100.0));
        assert_eq!(p.position(":j2_0", 0.0), Some(88.0));
        assert_eq!(p.position("r_0", 50.0), Some(88.0));
        assert_eq!(p.span("r_0"), Some((38.0, 88.0)));
        assert_eq!(p.span("m_0"), Some((93.0, 133.0)));
        assert_eq!(p.position("elsewhere_0", 1.0), None);
        // Speed limits as the network gives them (the ramp slower than the acceleration lane).
        assert_eq!(
            (p.speed_limit("r_0"), p.speed_limit("m_0"), p.speed_limit("m_1")),
            (Some(16.0), Some(25.0), None)
        );
    }

    /// A junction merge: target `a_0` (100 m) -> `:j_1_0` (6 m) -> `o_0` (50 m); the ramp
    /// `r_0` (40 m) ends at the junction and leads into `o_0` through `:j_0_0` (8 m, a minor
    /// link) and into `o_1` through `:j_0_1` (9 m).
    const JUNCTION: &str = r#"<net>
        <edge id=":j_0" function="internal"><lane id=":j_0_0" index="0" length="8.00"/><lane id=":j_0_1" index="1" length="9.00"/></edge>
        <edge id=":j_1" function="internal"><lane id=":j_1_0" index="0" length="6.00"/></edge>
        <edge id="a"><lane id="a_0" index="0" length="100.00"/></edge>
        <edge id="r"><lane id="r_0" index="0" length="40.00"/></edge>
        <edge id="o"><lane id="o_0" index="0" length="50.00"/><lane id="o_1" index="1" length="50.00"/></edge>
        <connection from="a" to="o" fromLane="0" toLane="0" via=":j_1_0" state="M"/>
        <connection from=":j_1" to="o" fromLane="0" toLane="0"/>
        <connection from="r" to="o" fromLane="0" toLane="0" via=":j_0_0" state="m"/>
        <connection from="r" to="o" fromLane="0" toLane="1" via=":j_0_1" state="m"/>
        <connection from=":j_0" to="o" fromLane="0" toLane="0"/>
        <connection from=":j_0" to="o" fromLane="1" toLane="1"/>
    </net>"#;

    #[test]
    fn a_stop_sign_ends_the_lanes_whose_link_into_the_merge_says_stop() {
        let stops = |replace: &[(&str, &str)]| {
            let net = (replace.iter()).fold(JUNCTION.to_owned(), |net, (from, to)| net.replacen(from, to, 1));
            let doc = roxmltree::Document::parse(&net).unwrap();
            let p = LanePositions::of_network(&doc, &lanes(&["r_0"]), &lanes(&["a_0", "o_0"]), 0.0).unwrap();
            (p.stop_sign("r_0"), p.stop_sign("a_0"), p.stop_sign_lanes().len())
        };
        // Minor and major links: no stop sign.
        assert_eq!(stops(&[]), (None, None, 0));
        // A priority_stop junction (`s` on the ramp's link into o_0): its line is the ramp's
        // end, 98 m (laid out in the test above); the ramp's other link (into o_1) is not its
        // path and does not count.
        let ramp = r#"via=":j_0_0" state="m""#;
        assert_eq!(
            stops(&[(ramp, r#"via=":j_0_0" state="s""#)]),
            (Some(98.0), None, 1)
        );
        assert_eq!(
            stops(&[(r#"via=":j_0_1" state="m""#, r#"via=":j_0_1" state="s""#)]),
            (None, None, 0)
        );
        // An allway_stop junction (`w` everywhere): the target lane a_0 stops at its end, 100 m.
        let all = [
            (ramp, r#"via=":j_0_0" state="w""#),
            (r#"state="M""#, r#"state="w""#),
        ];
        assert_eq!(stops(&all), (Some(98.0), Some(100.0), 2));
        // Behind a traffic light a stop-like state is the light's, not a sign.
        assert_eq!(
            stops(&[(ramp, r#"via=":j_0_0" tl="j" state="s""#)]),
            (None, None, 0)
        );
    }

    #[test]
    fn a_junction_merge_ends_the_ramp_where_its_junction_lane_meets_the_target_lanes() {
        let doc = roxmltree::Document::parse(JUNCTION).unwrap();
        let p = LanePositions::of_network(&doc, &lanes(&["r_0"]), &lanes(&["a_0", "o_0"]), 0.0).unwrap();
        assert_eq!(p.form(), MergeForm::Junction);
        // o_0 starts at 100 + 6; the ramp's 8 m junction lane ends there, so the stop line
        // (the end of r_0) is at 98 and r_0 starts at 58.
        assert_eq!(p.span("o_0"), Some((106.0, 156.0)));
        assert_eq!(p.span(":j_0_0"), Some((98.0, 106.0)));
        assert_eq!(p.span("r_0"), Some((58.0, 98.0)));
        // The other junction lane out of the ramp starts at the stop line too.
        assert_eq!(p.position(":j_0_1", 2.0), Some(100.0));
        assert!(p.is_entry(":j_0_0") && p.is_entry(":j_0_1"));
        assert!(!p.is_entry(":j_1_0") && !p.is_entry("r_0"));
        // Its ramp enters by minor links: SUMO's drivers give way there; not on a zipper, where
        // they take their turn, nor behind a traffic light (neither there).
        assert!(p.minor_entry() && !p.zipper_entry() && !p.is_lane_drop());
        for (from, to, zipper) in [
            (r#"state="m""#, r#"state="Z""#, true),
            (r#"state="m""#, r#"tl="j" state="o""#, false),
            (r#"state="m""#, r#"tl="j" state="Z""#, false),
        ] {
            let net = JUNCTION.replace(from, to);
            let doc = roxmltree::Document::parse(&net).unwrap();
            let p = LanePositions::of_network(&doc, &lanes(&["r_0"]), &lanes(&["a_0", "o_0"]), 0.0).unwrap();
            assert_eq!(
                (p.form(), p.minor_entry(), p.zipper_entry()),
                (MergeForm::Junction, false, zipper),
                "{to}"
            );
        }
        // A lane drop: the ending lane i_0 has the target lane i_1 beside it, so SUMO's drivers
        // change lanes into it before the stop line.
        let drop = r#"<net>
            <edge id=":j_0" function="internal"><lane id=":j_0_0" index="0" length="5.00"/><lane id=":j_0_1" index="1" length="5.00"/></edge>
            <edge id="i"><lane id="i_0" index="0" length="100.00"/><lane id="i_1" index="1" length="100.00"/></edge>
            <edge id="o"><lane id="o_0" index="0" length="50.00"/></edge>
            <connection from="i" to="o" fromLane="0" toLane="0" via=":j_0_0" state="m"/>
            <connection from="i" to="o" fromLane="1" toLane="0" via=":j_0_1" state="M"/>
            <connection from=":j_0" to="o" fromLane="0" toLane="0"/>
            <connection from=":j_0" to="o" fromLane="1" toLane="0"/>
        </net>"#;
        let doc = roxmltree::Document::parse(drop).unwrap();
        let p = LanePositions::of_network(&doc, &lanes(&["i_0"]), &lanes(&["i_1", "o_0"]), 0.0).unwrap();
        assert_eq!(
            (p.form(), p.minor_entry(), p.is_lane_drop()),
            (MergeForm::Junction, false, true)
        );
        // The acceleration-lane network is not a junction merge.
        let doc = roxmltree::Document::parse(NET).unwrap();
        let p = LanePositions::of_network(&doc, &lanes(&["r_0", "m_0"]), &lanes(&["a_0", "m_1", "b_0"]), 0.0)
            .unwrap();
        assert_eq!(p.form(), MergeForm::AccelerationLane);
        assert!(!p.is_entry(":j2_0") && !p.minor_entry() && !p.is_lane_drop());
    }

    /// A three-lane road `a` -> `o` (centre lines at y = -8, -4.8 and -1.6 across the junction)
    /// joined by a ramp whose junction lane runs along `ramp_shape` into `o_0`, yielding to all
    /// three lanes as netconvert makes it.
    fn three_lanes(ramp_shape: &str) -> String {
        let lanes: String = (0..3)
            .map(|k| {
                let y = -8.0 + 3.2 * f64::from(k);
                format!(
                    r#"<lane id=":j_0_{k}" index="{k}" length="20.00" shape="0.00,{y:.2} 20.00,{y:.2}"/>"#
                )
            })
            .collect();
        let links: String = (0..3)
            .map(|k| {
                format!(
                    r#"<connection from="a" to="o" fromLane="{k}" toLane="{k}" via=":j_0_{k}" state="M"/>
                    <connection from=":j_0" to="o" fromLane="{k}" toLane="{k}"/>"#
                )
            })
            .collect();
        format!(
            r#"<net>
            <edge id=":j_0" function="internal">{lanes}</edge>
            <edge id=":j_3" function="internal"><lane id=":j_3_0" index="0" length="22.00" shape="{ramp_shape}"/></edge>
            <edge id="a"><lane id="a_0" index="0" length="100.00"/><lane id="a_1" index="1" length="90.00"/><lane id="a_2" index="2" length="80.00"/></edge>
            <edge id="r"><lane id="r_0" index="0" length="40.00"/></edge>
            <edge id="o"><lane id="o_0" index="0" length="50.00"/><lane id="o_1" index="1" length="50.00"/><lane id="o_2" index="2" length="50.00"/></edge>
            <junction id="j" type="priority" intLanes=":j_0_0 :j_0_1 :j_0_2 :j_3_0">
                <request index="0" response="0000" foes="1000" cont="0"/><request index="1" response="0000" foes="1000" cont="0"/>
                <request index="2" response="0000" foes="1000" cont="0"/><request index="3" response="0111" foes="0111" cont="0"/>
            </junction>
            {links}
            <connection from="r" to="o" fromLane="0" toLane="0" via=":j_3_0" state="m"/>
            <connection from=":j_3" to="o" fromLane="0" toLane="0"/>
            </net>"#
        )
    }

    #[test]
    fn a_ramp_yields_at_its_junction_to_the_lanes_its_path_crosses() {
        let positions = |ramp_shape: &str| {
            let net = three_lanes(ramp_shape);
            let doc = roxmltree::Document::parse(&net).unwrap();
            LanePositions::of_network(&doc, &lanes(&["r_0"]), &lanes(&["a_0", "o_0"]), 0.0).unwrap()
        };
        // From the road's left, across lanes 2 and 1 into lane 0: their vehicles cross its path.
        let across = positions("0.00,2.00 10.00,-3.00 20.00,-8.00");
        assert_eq!(across.entry_length(), 22.0);
        let crossing: Vec<(&str, f64, &[String])> = (across.crossing().iter())
            .map(|c| (c.lane.as_str(), c.length, &c.vias[..]))
            .collect();
        assert_eq!(
            crossing,
            [
                ("a_1", 90.0, &[":j_0_1".to_owned()][..]),
                ("a_2", 80.0, &[":j_0_2".to_owned()][..])
            ]
        );
        // The same with elevation (`x,y,z` points, as OSM and OpenDRIVE imports have them).
        let raised = three_lanes("0.00,2.00,5.00 10.00,-3.00,5.50 20.00,-8.00,6.00")
            .replace(r#",-8.00""#, r#",-8.00,6.00""#)
            .replace(r#",-4.80""#, r#",-4.80,6.00""#)
            .replace(r#",-1.60""#, r#",-1.60,6.00""#);
        let doc = roxmltree::Document::parse(&raised).unwrap();
        let p = LanePositions::of_network(&doc, &lanes(&["r_0"]), &lanes(&["a_0", "o_0"]), 0.0).unwrap();
        assert_eq!(p.crossing(), across.crossing());
        assert!(raised.contains("20.00,-4.80,6.00"));
        // From the right into lane 0, netconvert's on-ramp: it yields to lanes 1 and 2 too by
        // SUMO's request, but never meets them; lane 0 is the target lane, the entry rule's.
        assert!(positions("0.00,-12.00 20.00,-8.00").crossing().is_empty());
        // Touching a path at its end is not crossing it.
        assert!(positions("0.00,-12.00 20.00,-4.80").crossing().is_empty());
        // A second link out of the ramp, across lanes 0 and 1 into lane 2 (as SMARTS's
        // `merging` maps have it), is not the path into the target lane, which SUMO's drivers
        // take (the first link out of their lane).
        let net = three_lanes("0.00,-12.00 20.00,-8.00")
            .replace(":j_0_2 :j_3_0\"", ":j_0_2 :j_3_0 :j_3_1\"")
            .replace(
                "</junction>",
                r#"<request index="4" response="00111" foes="00111" cont="0"/></junction>"#,
            )
            .replace(
                r#"shape="0.00,-12.00 20.00,-8.00"/>"#,
                r#"shape="0.00,-12.00 20.00,-8.00"/><lane id=":j_3_1" index="1" length="25.00" shape="0.00,-12.00 20.00,-1.60"/>"#,
            )
            .replace(
                "</net>",
                r#"<connection from="r" to="o" fromLane="0" toLane="2" via=":j_3_1" state="m"/>
                <connection from=":j_3" to="o" fromLane="1" toLane="2"/></net>"#,
            );
        let doc = roxmltree::Document::parse(&net).unwrap();
        let p = LanePositions::of_network(&doc, &lanes(&["r_0"]), &lanes(&["a_0", "o_0"]), 0.0).unwrap();
        assert_eq!((p.entry_length(), p.crossing()), (25.0, &[][..]));
    }

    #[test]
    fn lanes_out_of_driving_order_or_a_ramp_beside_no_target_lane_are_refused() {
        let doc = roxmltree::Document::parse(NET).unwrap();
        let err = LanePositions::of_network(&doc, &lanes(&["r_0", "m_0"]), &lanes(&["m_1", "a_0"]), 0.0)
            .unwrap_err();
        assert!(err.contains("`m_1` does not lead to `a_0`"), "{err}");
        let err = LanePositions::of_network(&doc, &lanes(&["m_0", "r_0"]), &lanes(&["a_0", "m_1"]), 0.0)
            .unwrap_err();
        assert!(
            err.contains("last ramp lane `r_0` must be an acceleration lane"),
            "{err}"
        );
    }
}
