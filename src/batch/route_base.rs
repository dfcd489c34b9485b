//! The parts of a base route file that `routes` generates from: its vehicle types and routes
//! (copied verbatim), its flows and its explicit vehicles and trips, which of them drive along a
//! ramp, and how each generated vehicle's type is drawn from the shares.

use crate::batch::routes::RoutesError;
use crate::sumo::geometry::{MergeGeometry, split_lane_id};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;

/// A flow of the base file.
#[derive(Debug, Clone)]
pub(super) struct Flow {
    pub(super) id: String,
    pub(super) vtype: String,
    /// The named route or route distribution; none for a flow with `from`/`to` (kept in
    /// `extra`), whose vehicles become trips that SUMO routes.
    pub(super) route: Option<String>,
    pub(super) begin: f64,
    pub(super) end: f64,
    pub(super) per_hour: f64,
    /// Other attributes (departLane, departSpeed, ...), copied to each vehicle.
    pub(super) extra: Vec<(String, String)>,
    /// Its children (an embedded route, stops, parameters), verbatim, copied into each vehicle.
    pub(super) inner: String,
    pub(super) ramp: bool,
}

/// Attributes of a flow that the generated vehicles do not copy.
const RATE_ATTRIBUTES: [&str; 9] = [
    "id",
    "type",
    "route",
    "begin",
    "end",
    "vehsPerHour",
    "period",
    "probability",
    "number",
];

/// A `<vehicle>` or `<trip>` of the base file.
#[derive(Debug, Clone)]
pub(super) struct Explicit {
    pub(super) tag: String,
    pub(super) id: String,
    pub(super) vtype: String,
    /// Its departure, as written and as a number.
    pub(super) depart: (String, f64),
    /// Other attributes (route, from, to, departLane, ...), copied.
    pub(super) extra: Vec<(String, String)>,
    /// Its children (an embedded route, stops, parameters), verbatim.
    pub(super) inner: String,
    pub(super) ramp: bool,
}

/// Attributes of a vehicle that its copies write themselves.
const OWN_ATTRIBUTES: [&str; 3] = ["id", "type", "depart"];

/// The ramps' edges, to tell the ramp's vehicles from the freeway's.
struct RampEdges<'a> {
    /// Per merge: the edges of its ramp lanes in driving order, each with whether it holds a
    /// target lane too (an acceleration lane's edge).
    merges: Vec<Vec<(&'a str, bool)>>,
}

impl<'a> RampEdges<'a> {
    fn of(merges: &'a [MergeGeometry]) -> Self {
        let edge = |lane: &'a String| split_lane_id(lane).map_or(lane.as_str(), |(e, _)| e);
        let merges = merges
            .iter()
            .map(|g| {
                let mut edges: Vec<(&str, bool)> = Vec::new();
                for e in g.ramp_lanes.iter().map(edge) {
                    if edges.last().is_none_or(|(last, _)| *last != e) {
                        edges.push((e, g.target_lanes.iter().any(|t| edge(t) == e)));
                    }
                }
                edges
            })
            .collect();
        Self { merges }
    }

    /// Whether a route (its edges) is the ramp's: it reaches a merge's last ramp edge from an
    /// edge of that ramp that holds no target lane, along the ramp's edges. A route that only
    /// passes a ramp edge (a collector road, a ramp that leaves the freeway upstream and turns
    /// elsewhere) or drives along the freeway past the acceleration lane is not.
    fn of_route(&self, edges: &str) -> bool {
        let route: Vec<&str> = edges.split_whitespace().collect();
        self.merges.iter().any(|ramp| {
            let Some((last, _)) = ramp.last() else {
                return false;
            };
            route
                .iter()
                .enumerate()
                .filter(|(_, e)| *e == last)
                .any(|(j, _)| {
                    route[..=j]
                        .iter()
                        .rev()
                        .map_while(|e| ramp.iter().find(|(r, _)| r == e))
                        .any(|(_, beside_target)| !beside_target)
                })
        })
    }

    /// Whether a trip or flow that SUMO routes (`from`, `to`, `via`) is the ramp's: it departs
    /// from, or passes, an edge of a ramp that holds no target lane.
    fn of_trip(&self, from: &str, via: Option<&str>) -> bool {
        let pure = |e: &str| self.merges.iter().flatten().any(|(r, beside)| *r == e && !beside);
        pure(from) || via.unwrap_or_default().split_whitespace().any(pure)
    }
}

/// The parts of a base route file the generator uses.
pub(super) struct Base {
    /// vType, vTypeDistribution and route elements, verbatim.
    pub(super) verbatim: Vec<String>,
    /// The same elements of the files loaded with it ([`loaded_elements`]): defined, not
    /// written.
    pub(super) loaded: Vec<String>,
    pub(super) flows: Vec<Flow>,
    pub(super) explicit: Vec<Explicit>,
    /// vTypeDistribution id -> (controllable member, other member).
    pub(super) mixes: Vec<(String, String, String)>,
    /// The first vType (outside a distribution) not of a controllable type: the type a ramp
    /// flow of a plain controllable type takes where a controllable share leaves it to SUMO.
    pub(super) human: Option<String>,
    /// The controllable type the file did not define, added to `verbatim` as a copy of its
    /// first passenger car's vType (SUMO's default car without one).
    pub(super) derived_type: Option<String>,
    /// The elements the generated files do not carry over (persons, containers, ...), each as
    /// its count and tag: `3 <person>`.
    pub(super) left_out: Vec<String>,
}

/// The nodes under the root of each file of `paths` that `keep` keeps, in file order, under one
/// `<routes>` root.
pub(super) fn under_one_root(
    paths: &[std::path::PathBuf],
    keep: impl Fn(&roxmltree::Node) -> bool,
) -> Result<String, RoutesError> {
    let mut out = String::from("<routes>\n");
    for path in paths {
        let text = crate::sumo::inputs::read_sumo_file(path).map_err(|source| RoutesError::Io {
            path: path.clone(),
            source,
        })?;
        let doc = roxmltree::Document::parse(&text).map_err(|e| RoutesError::Base {
            path: path.clone(),
            message: e.to_string(),
        })?;
        for node in doc.root_element().children().filter(|n| keep(n)) {
            out += &text[node.range()];
        }
        out.push('\n');
    }
    out += "</routes>\n";
    Ok(out)
}

/// The vehicle types, type distributions, routes and route distributions SUMO loads with the
/// route files from other files (a configuration's additional files), as one `<routes>`
/// document: the base file's flows and vehicles may use them, and a generated file must not
/// define them again.
pub(super) fn loaded_elements(paths: &[std::path::PathBuf]) -> Result<String, RoutesError> {
    let kept = ["vType", "vTypeDistribution", "route", "routeDistribution"];
    under_one_root(paths, |n| kept.contains(&n.tag_name().name()))
}

/// The base route file at `path` (its `text`) as the generator reads it, with the elements of
/// `loaded` ([`loaded_elements`]) defined before it but left out of `verbatim`.
pub(super) fn parse_base(
    path: &Path,
    text: &str,
    loaded: &str,
    merges: &[MergeGeometry],
) -> Result<Base, RoutesError> {
    let bad = |message: String| RoutesError::Base {
        path: path.to_path_buf(),
        message,
    };
    let given =
        roxmltree::Document::parse(loaded).map_err(|e| bad(format!("the files loaded with it: {e}")))?;
    let doc = roxmltree::Document::parse(text).map_err(|e| bad(e.to_string()))?;
    // An element's children (an embedded route, stops, parameters), verbatim; none when blank.
    let children = |node: roxmltree::Node, text: &str| match (node.first_child(), node.last_child()) {
        (Some(a), Some(b)) if !text[a.range().start..b.range().end].trim().is_empty() => {
            text[a.range().start..b.range().end].to_owned()
        }
        _ => String::new(),
    };
    let ramp = RampEdges::of(merges);
    let controllable = controllable_types(merges);
    let mut verbatim = Vec::new();
    let mut routes = Vec::new();
    let mut mixes = Vec::new();
    let mut human = None;
    // The first vType of a passenger car (SUMO's class `passenger`, its default) not of a
    // controllable type, its id replaced by the first controllable type's.
    let mut car_copy = None;
    let mut flows = Vec::new();
    let mut explicit = Vec::new();
    let mut left_out: Vec<(String, usize)> = Vec::new();
    // The loaded files' types and routes count as the base file's, defined before it; only
    // the base file's own are copied into the generated files.
    let mut defined_elsewhere = Vec::new();
    let elements = (given.root_element().children().map(|n| (n, loaded, true)))
        .chain(doc.root_element().children().map(|n| (n, text, false)))
        .filter(|(n, _, _)| n.is_element());
    for (node, text, elsewhere) in elements {
        let attr = |k: &str| node.attribute(k).map(str::to_owned);
        let children = |node| children(node, text);
        let verbatim = match elsewhere {
            true => &mut defined_elsewhere,
            false => &mut verbatim,
        };
        match node.tag_name().name() {
            "vType" => {
                verbatim.push(text[node.range()].to_owned());
                let id = node.attributes().find(|a| a.name() == "id");
                let other = id.filter(|id| !controllable.contains(&id.value()));
                if human.is_none() {
                    human = other.map(|id| id.value().to_owned());
                }
                let car = node.attribute("vClass").is_none_or(|c| c == "passenger");
                if let (None, Some(id), Some(ctrl), true) = (&car_copy, other, controllable.first(), car) {
                    let (element, value) = (node.range(), id.range_value());
                    car_copy = Some(format!(
                        "{}{ctrl}{}",
                        &text[element.start..value.start],
                        &text[value.end..element.end]
                    ));
                }
            }
            "vTypeDistribution" => {
                verbatim.push(text[node.range()].to_owned());
                let members: Vec<&str> = node
                    .children()
                    .filter(|n| n.has_tag_name("vType"))
                    .filter_map(|n| n.attribute("id"))
                    .collect();
                let ctrl = members.iter().find(|m| controllable.contains(m));
                let other = members.iter().find(|m| !controllable.contains(m));
                if let (Some(id), Some(c), Some(o)) = (attr("id"), ctrl, other) {
                    mixes.push((id, c.to_string(), o.to_string()));
                }
            }
            "route" | "routeDistribution" => {
                verbatim.push(text[node.range()].to_owned());
                let id =
                    attr("id").ok_or_else(|| bad(format!("a <{}> without id", node.tag_name().name())))?;
                // A distribution is the ramp's when its first route is.
                let edges = std::iter::once(node)
                    .chain(node.children().filter(|n| n.has_tag_name("route")))
                    .find_map(|n| n.attribute("edges"))
                    .unwrap_or_default();
                routes.push((id, ramp.of_route(edges)));
            }
            "flow" => {
                let number = |k: &str, v: &str| match v.parse::<f64>() {
                    Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
                    _ => Err(bad(format!(
                        "flow attribute {k}=\"{v}\" is not a non-negative number"
                    ))),
                };
                let num = |k: &str| number(k, &attr(k).ok_or_else(|| bad(format!("flow without `{k}`")))?);
                // SUMO's defaults: from the simulation's begin (0 here) for 24 hours.
                let num_or = |k: &str, default: f64| attr(k).map_or(Ok(default), |v| number(k, &v));
                let route = attr("route");
                let embedded = node.children().find(|n| n.has_tag_name("route"));
                let on_ramp = match (&route, embedded) {
                    (Some(route), _) => routes
                        .iter()
                        .find(|(id, _)| id == route)
                        .map(|(_, r)| *r)
                        .ok_or_else(|| bad(format!("flow uses route `{route}`, not defined before it")))?,
                    (None, Some(r)) => ramp.of_route(r.attribute("edges").unwrap_or_default()),
                    (None, None) => attr("from")
                        .filter(|_| node.attribute("to").is_some())
                        .map(|from| ramp.of_trip(&from, node.attribute("via")))
                        .ok_or_else(|| {
                            bad("flow without a route (`route` or a <route> in it) or `from` and `to`".into())
                        })?,
                };
                let (begin, end) = (num_or("begin", 0.0)?, num_or("end", 86_400.0)?);
                // The rate: vehsPerHour, period (s between vehicles; `exp(r)`: Poisson arrivals
                // at r per second, as the generator draws every flow's), probability (per
                // second) or number (over begin..end).
                let poisson =
                    attr("period").and_then(|p| Some(p.strip_prefix("exp(")?.strip_suffix(')')?.to_owned()));
                let per_hour = if node.attribute("vehsPerHour").is_some() {
                    num("vehsPerHour")?
                } else if let Some(rate) = poisson {
                    3600.0
                        * number("period", &rate).map_err(|_| {
                            bad(format!(
                                "flow attribute period=\"exp({rate})\": the rate is not a non-negative number"
                            ))
                        })?
                } else if node.attribute("period").is_some() {
                    3600.0 / num("period")?.max(f64::MIN_POSITIVE)
                } else if node.attribute("probability").is_some() {
                    3600.0 * num("probability")?
                } else if node.attribute("number").is_some() {
                    num("number")? * 3600.0 / (end - begin).max(f64::MIN_POSITIVE)
                } else {
                    return Err(bad(
                        "flow without vehsPerHour, period, probability or number".into()
                    ));
                };
                flows.push(Flow {
                    id: attr("id").ok_or_else(|| bad("flow without id".into()))?,
                    vtype: attr("type").unwrap_or_else(|| "DEFAULT_VEHTYPE".into()),
                    ramp: on_ramp,
                    route,
                    begin,
                    end,
                    per_hour,
                    extra: node
                        .attributes()
                        .filter(|a| !RATE_ATTRIBUTES.contains(&a.name()))
                        .map(|a| (a.name().to_owned(), a.value().to_owned()))
                        .collect(),
                    inner: children(node),
                });
            }
            tag @ ("vehicle" | "trip") => {
                let id = attr("id").ok_or_else(|| bad(format!("a <{tag}> without id")))?;
                let depart = attr("depart").unwrap_or_default();
                let at = depart.parse::<f64>().ok().filter(|t| t.is_finite() && *t >= 0.0).ok_or_else(|| {
                    bad(format!(
                        "<{tag} id=\"{id}\">: depart=\"{depart}\" is not a time in seconds (the only departures it scales)"
                    ))
                })?;
                let embedded = node.children().find(|n| n.has_tag_name("route"));
                let on_ramp = match (attr("route"), embedded, attr("from")) {
                    (Some(route), _, _) => routes
                        .iter()
                        .find(|(r, _)| *r == route)
                        .map(|(_, r)| *r)
                        .ok_or_else(|| {
                            bad(format!(
                                "<{tag} id=\"{id}\"> uses route `{route}`, not defined before it"
                            ))
                        })?,
                    (None, Some(r), _) => ramp.of_route(r.attribute("edges").unwrap_or_default()),
                    (None, None, Some(from)) => ramp.of_trip(&from, node.attribute("via")),
                    (None, None, None) => {
                        return Err(bad(format!("<{tag} id=\"{id}\"> without a route or `from`")));
                    }
                };
                explicit.push(Explicit {
                    tag: tag.to_owned(),
                    vtype: attr("type").unwrap_or_else(|| "DEFAULT_VEHTYPE".into()),
                    depart: (depart, at),
                    extra: node
                        .attributes()
                        .filter(|a| !OWN_ATTRIBUTES.contains(&a.name()))
                        .map(|a| (a.name().to_owned(), a.value().to_owned()))
                        .collect(),
                    inner: children(node),
                    ramp: on_ramp,
                    id,
                });
            }
            other => match left_out.iter_mut().find(|(tag, _)| tag == other) {
                Some((_, n)) => *n += 1,
                None => left_out.push((other.to_owned(), 1)),
            },
        }
    }
    if flows.is_empty() && explicit.is_empty() {
        return Err(bad("no <flow>, <vehicle> or <trip> to scale".into()));
    }
    // A file that defines no controllable type (osmWebWizard's trips, randomTrips without
    // types) gets one: the same car as its first passenger car's vType, or SUMO's default car.
    // The policies' world is one of passenger cars.
    let mut base = Base {
        verbatim,
        loaded: defined_elsewhere,
        flows,
        explicit,
        mixes,
        human,
        derived_type: None,
        left_out: left_out.iter().map(|(tag, n)| format!("{n} <{tag}>")).collect(),
    };
    if let Some(ctrl) = controllable
        .first()
        .filter(|_| !controllable.iter().any(|c| base.defines(c)))
    {
        base.verbatim
            .push(car_copy.unwrap_or_else(|| format!("<vType id=\"{ctrl}\"/>")));
        base.derived_type = Some(ctrl.to_string());
    }
    Ok(base)
}

impl Base {
    /// Whether the file or the files loaded with it define `id` (a type or route).
    pub(super) fn defines(&self, id: &str) -> bool {
        let attribute = format!("id=\"{id}\"");
        (self.verbatim.iter().chain(&self.loaded)).any(|v| v.contains(&attribute))
    }

    /// Whether each flow, then each explicit vehicle, starts on a ramp lane.
    pub(super) fn ramp_flags(&self) -> impl Iterator<Item = bool> + '_ {
        (self.flows.iter().map(|f| f.ramp)).chain(self.explicit.iter().map(|v| v.ramp))
    }

    /// The type of one vehicle of `vtype` (of a flow or an explicit vehicle, from the ramp if
    /// `ramp`): a vTypeDistribution holding a controllable type draws it with the controllable
    /// share from `mix_rng`; a ramp vehicle of a plain type is of the controllable type with
    /// that share (one of a controllable type otherwise takes [`Base::human`], one of another
    /// type keeps it); a freeway vehicle of a plain type becomes controllable with the mainline
    /// share. Those draw from `type_rng`.
    pub(super) fn draw_type(
        &self,
        (vtype, ramp): (&str, bool),
        shares: &TypeShares,
        (mix_rng, type_rng): (&mut ChaCha8Rng, &mut ChaCha8Rng),
    ) -> String {
        let mix = self.mixes.iter().find(|(id, _, _)| id == vtype);
        let controllable = shares.controllable.contains(&vtype);
        let drawn = |rng: &mut ChaCha8Rng, p: f64, yes: &String, no: &str| -> String {
            if rng.random::<f64>() < p {
                yes.clone()
            } else {
                no.to_owned()
            }
        };
        match (mix, shares.ramp, shares.ctrl) {
            (Some((_, ctrl, other)), Some(share), _) => drawn(mix_rng, share, ctrl, other),
            (None, Some(share), _) if ramp && controllable => match &self.human {
                Some(human) => drawn(type_rng, 1.0 - share, human, vtype),
                None => vtype.to_owned(),
            },
            (None, Some(share), Some(ctrl)) if ramp => drawn(type_rng, share, ctrl, vtype),
            _ => match shares
                .mainline
                .zip(shares.ctrl)
                .filter(|_| !ramp && mix.is_none())
            {
                Some((p, ctrl)) => drawn(type_rng, p, ctrl, vtype),
                None => vtype.to_owned(),
            },
        }
    }
}

/// The shares a generated file's vehicle types are drawn with ([`Base::draw_type`]).
pub(super) struct TypeShares<'a> {
    /// Controllable share of the ramp's vehicles.
    pub(super) ramp: Option<f64>,
    /// Controllable share of the freeway's vehicles of a plain type.
    pub(super) mainline: Option<f64>,
    /// The file's controllable type.
    pub(super) ctrl: Option<&'a String>,
    /// The controllable types of the merges.
    pub(super) controllable: &'a [&'a str],
}

/// A controllable type the base file defines (as a vType or a member of a distribution).
pub(super) fn controllable_type(base: &Base, merges: &[MergeGeometry]) -> Option<String> {
    (controllable_types(merges).into_iter()).find_map(|c| base.defines(c).then(|| c.to_owned()))
}

/// The controllable types of every merge, each once, in order.
pub(super) fn controllable_types(merges: &[MergeGeometry]) -> Vec<&str> {
    let mut types: Vec<&str> = Vec::new();
    for t in merges.iter().flat_map(|g| &g.controllable_types) {
        if !types.contains(&t.as_str()) {
            types.push(t);
        }
    }
    types
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_route_is_the_ramps_when_it_reaches_the_acceleration_lane_along_the_ramp() {
        // The ramp `a` -> `r` -> the acceleration lane `acc_0`, beside the freeway's `f` ->
        // `acc_1` -> `g`; `a` also leads elsewhere (`x`).
        let merge: MergeGeometry = toml::from_str(
            "conflict_point = 500.0\ncontrol_from = 380.0\nrelease_after = 200.0\n\
             ramp_lanes = [\"a_0\", \"r_0\", \"acc_0\"]\ntarget_lanes = [\"f_0\", \"acc_1\", \"g_0\"]\n\
             controllable_types = [\"ctrl\"]\nplayers = \"controllable\"\n",
        )
        .unwrap();
        let merges = [merge];
        let ramp = RampEdges::of(&merges);
        for (route, on_ramp, why) in [
            ("a r acc g", true, "along the ramp"),
            ("y r acc g", true, "from elsewhere onto the ramp"),
            ("a x", false, "passes the ramp's first edge, turns elsewhere"),
            ("f acc g", false, "the freeway past the acceleration lane"),
            ("acc g", false, "departs beside the ramp, on the freeway's edge"),
            ("a x acc g", false, "reaches the merge's edge not along the ramp"),
        ] {
            assert_eq!(ramp.of_route(route), on_ramp, "{route}: {why}");
        }
        // SUMO routes a trip: it is the ramp's where it departs from, or passes, a ramp edge
        // beside no target lane.
        assert!(ramp.of_trip("a", None) && ramp.of_trip("y", Some("x r")));
        assert!(!ramp.of_trip("f", None) && !ramp.of_trip("acc", Some("g")));
    }

    #[test]
    fn a_file_without_a_controllable_type_gets_a_copy_of_its_first_vtype() {
        let merge: MergeGeometry = toml::from_str(
            "conflict_point = 500.0\ncontrol_from = 380.0\nrelease_after = 200.0\n\
             ramp_lanes = [\"r_0\", \"acc_0\"]\ntarget_lanes = [\"f_0\", \"acc_1\"]\n\
             controllable_types = [\"ctrl\", \"av\"]\nplayers = \"controllable\"\n",
        )
        .unwrap();
        let base = |types: &str| {
            let text = format!(
                "<routes>{types}<trip id=\"t\" type=\"veh_passenger\" depart=\"0\" from=\"r\" to=\"acc\"/></routes>"
            );
            let base = parse_base(
                Path::new("t.rou.xml"),
                &text,
                "<routes/>",
                std::slice::from_ref(&merge),
            )
            .unwrap();
            (base.derived_type, base.verbatim)
        };
        // osmWebWizard's trips: the first controllable type is the same car, its children too.
        let (derived, verbatim) = base(
            "<vType id='veh_passenger' vClass=\"passenger\"><param key=\"k\" value=\"veh_passenger\"/></vType>",
        );
        assert_eq!(derived.as_deref(), Some("ctrl"));
        assert_eq!(
            verbatim.last().unwrap(),
            "<vType id='ctrl' vClass=\"passenger\"><param key=\"k\" value=\"veh_passenger\"/></vType>"
        );
        // No vType at all: SUMO's default car; trucks first: the first car after them.
        assert_eq!(base("").1, ["<vType id=\"ctrl\"/>"]);
        let (_, verbatim) =
            base("<vType id=\"lorry\" vClass=\"truck\"/><vType id=\"veh_passenger\" accel=\"2\"/>");
        assert_eq!(verbatim.last().unwrap(), "<vType id=\"ctrl\" accel=\"2\"/>");
        // A file that defines one of the controllable types keeps its own types.
        let (derived, verbatim) = base("<vType id=\"veh_passenger\"/><vType id=\"av\" accel=\"3\"/>");
        assert_eq!((derived, verbatim.len()), (None, 2));
        // What the generator does not write is counted by tag.
        let text = "<routes><person id=\"p\" depart=\"0\"><walk edges=\"r\"/></person><vType id=\"car\"/>\
                    <person id=\"q\" depart=\"1\"/><container id=\"c\" depart=\"2\"/>\
                    <trip id=\"t\" type=\"car\" depart=\"0\" from=\"r\" to=\"acc\"/></routes>";
        let base = parse_base(
            Path::new("t.rou.xml"),
            text,
            "<routes/>",
            std::slice::from_ref(&merge),
        )
        .unwrap();
        assert_eq!(base.left_out, ["2 <person>", "1 <container>"]);
    }
}
