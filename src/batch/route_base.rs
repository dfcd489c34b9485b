//! The parts of a base route file that `routes` generates from: its vehicle types and routes
//! (copied verbatim), its flows and its explicit vehicles and trips, which of them start on a
//! ramp lane, and how each generated vehicle's type is drawn from the shares.

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

/// The parts of a base route file the generator uses.
pub(super) struct Base {
    /// vType, vTypeDistribution and route elements, verbatim.
    pub(super) verbatim: Vec<String>,
    pub(super) flows: Vec<Flow>,
    pub(super) explicit: Vec<Explicit>,
    /// vTypeDistribution id -> (controllable member, other member).
    pub(super) mixes: Vec<(String, String, String)>,
    /// The first vType (outside a distribution) not of a controllable type: the type a ramp
    /// flow of a plain controllable type takes where a controllable share leaves it to SUMO.
    pub(super) human: Option<String>,
}

pub(super) fn parse_base(path: &Path, text: &str, merges: &[MergeGeometry]) -> Result<Base, RoutesError> {
    let bad = |message: String| RoutesError::Base {
        path: path.to_path_buf(),
        message,
    };
    let doc = roxmltree::Document::parse(text).map_err(|e| bad(e.to_string()))?;
    let ramp_edges: Vec<&str> = merges
        .iter()
        .flat_map(|g| &g.ramp_lanes)
        .filter_map(|l| split_lane_id(l).map(|(e, _)| e))
        .collect();
    let controllable = controllable_types(merges);
    let mut verbatim = Vec::new();
    let mut routes = Vec::new();
    let mut mixes = Vec::new();
    let mut human = None;
    let mut flows = Vec::new();
    let mut explicit = Vec::new();
    for node in doc.root_element().children().filter(|n| n.is_element()) {
        let attr = |k: &str| node.attribute(k).map(str::to_owned);
        match node.tag_name().name() {
            "vType" => {
                verbatim.push(text[node.range()].to_owned());
                if human.is_none() {
                    human = attr("id").filter(|id| !controllable.contains(&id.as_str()));
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
                // A distribution's first edge is its first route's.
                let first = std::iter::once(node)
                    .chain(node.children().filter(|n| n.has_tag_name("route")))
                    .find_map(|n| n.attribute("edges"))
                    .unwrap_or_default();
                routes.push((id, first.split_whitespace().next().unwrap_or("").to_owned()));
            }
            "flow" => {
                let num = |k: &str| -> Result<f64, RoutesError> {
                    let v = attr(k).ok_or_else(|| bad(format!("flow without `{k}`")))?;
                    match v.parse::<f64>() {
                        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
                        _ => Err(bad(format!(
                            "flow attribute {k}=\"{v}\" is not a non-negative number"
                        ))),
                    }
                };
                let route = attr("route");
                let first_edge = match &route {
                    Some(route) => routes
                        .iter()
                        .find(|(id, _)| id == route)
                        .map(|(_, e)| e.clone())
                        .ok_or_else(|| bad(format!("flow uses route `{route}`, not defined before it")))?,
                    None => attr("from")
                        .filter(|_| node.attribute("to").is_some())
                        .ok_or_else(|| bad("flow without `route` or `from` and `to`".into()))?,
                };
                let (begin, end) = (num("begin")?, num("end")?);
                // The rate: vehsPerHour, period (s between vehicles), probability (per second)
                // or number (over begin..end).
                let per_hour = if node.attribute("vehsPerHour").is_some() {
                    num("vehsPerHour")?
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
                    ramp: ramp_edges.contains(&first_edge.as_str()),
                    route,
                    begin,
                    end,
                    per_hour,
                    extra: node
                        .attributes()
                        .filter(|a| !RATE_ATTRIBUTES.contains(&a.name()))
                        .map(|a| (a.name().to_owned(), a.value().to_owned()))
                        .collect(),
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
                let first_edge = match (attr("route"), embedded, attr("from")) {
                    (Some(route), _, _) => routes
                        .iter()
                        .find(|(r, _)| *r == route)
                        .map(|(_, e)| e.clone())
                        .ok_or_else(|| {
                        bad(format!(
                            "<{tag} id=\"{id}\"> uses route `{route}`, not defined before it"
                        ))
                    })?,
                    (None, Some(r), _) => r
                        .attribute("edges")
                        .unwrap_or_default()
                        .split_whitespace()
                        .next()
                        .unwrap_or("")
                        .to_owned(),
                    (None, None, Some(from)) => from,
                    (None, None, None) => {
                        return Err(bad(format!("<{tag} id=\"{id}\"> without a route or `from`")));
                    }
                };
                let inner = match (node.first_child(), node.last_child()) {
                    (Some(a), Some(b)) => text[a.range().start..b.range().end].to_owned(),
                    _ => String::new(),
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
                    inner: if inner.trim().is_empty() {
                        String::new()
                    } else {
                        inner
                    },
                    ramp: ramp_edges.contains(&first_edge.as_str()),
                    id,
                });
            }
            _ => {}
        }
    }
    if flows.is_empty() && explicit.is_empty() {
        return Err(bad("no <flow>, <vehicle> or <trip> to scale".into()));
    }
    Ok(Base {
        verbatim,
        flows,
        explicit,
        mixes,
        human,
    })
}

impl Base {
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
    controllable_types(merges).into_iter().find_map(|c| {
        base.verbatim
            .iter()
            .any(|v| v.contains(&format!("id=\"{c}\"")))
            .then(|| c.to_owned())
    })
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
