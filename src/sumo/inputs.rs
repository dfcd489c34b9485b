//! SUMO inputs checked before a run starts, so that a bad input writes nothing: the
//! configuration is a SUMO configuration, its network holds the lanes `merge.toml` names and
//! the conflict point lies on them, and every route file is XML whose vehicles use routes,
//! types and edges that exist, on paths the network has. SUMO itself would find most of this only after starting (and writing its outputs),
//! and a conflict point beyond the network would run to the end with no ego.

use crate::sumo::positions::MergeForm;
use crate::sumo::{LanePositions, MergeGeometry};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

/// What is wrong with the inputs (each names its file).
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A file is not well-formed XML.
    #[error("{path}: not well-formed XML: {message}")]
    Xml {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// The file is XML but not what it should be, or refers to something that does not exist.
    #[error("{path}: {message}")]
    Content {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

fn read(path: &Path) -> Result<String, InputError> {
    read_sumo_file(path).map_err(|source| InputError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// The text of a SUMO input file, plain or gzip-compressed as SUMO reads them too (netconvert's
/// and osmWebWizard's `.net.xml.gz`): compressed when it begins with gzip's magic bytes,
/// whatever its name.
pub fn read_sumo_file(path: &Path) -> std::io::Result<String> {
    let bytes = std::fs::read(path)?;
    let bytes = if bytes.starts_with(&[0x1f, 0x8b]) {
        let mut plain = Vec::new();
        std::io::Read::read_to_end(&mut flate2::read::MultiGzDecoder::new(&bytes[..]), &mut plain)?;
        plain
    } else {
        bytes
    };
    String::from_utf8(bytes).map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))
}

fn parse<'a>(path: &Path, text: &'a str) -> Result<roxmltree::Document<'a>, InputError> {
    roxmltree::Document::parse(text).map_err(|e| InputError::Xml {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

fn content(path: &Path, message: String) -> InputError {
    InputError::Content {
        path: path.to_path_buf(),
        message,
    }
}

/// The files a SUMO configuration names, resolved against its folder.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigFiles {
    /// `net-file`.
    pub net: PathBuf,
    /// `route-files`.
    pub routes: Vec<PathBuf>,
    /// `additional-files` (they may define routes and types).
    pub additional: Vec<PathBuf>,
    /// `step-length` (s), if the configuration sets one (SUMO's default is 1 s).
    pub step_length: Option<f64>,
    /// `begin` (s), the time the simulation starts at (SUMO's default 0).
    pub begin: f64,
    /// `scale`, SUMO's demand scale, if the configuration sets one.
    pub scale: Option<String>,
    /// The configuration turns SUMO's collision check off (`collision.action none`).
    pub no_collision_check: bool,
    /// The ways of running SUMO the configuration asks for that are not the policy's world:
    /// `step-method.ballistic` (positions move by the mean of the old and new speed, where the
    /// world's move by one speed per step) and `mesosim` (queues on edges, without lanes).
    pub other_dynamics: Vec<&'static str>,
    /// The configuration equips vehicles with the SSM device itself (`device.ssm.probability`
    /// or `device.ssm.explicit`).
    pub ssm_option: bool,
}

/// Reads a `.sumocfg`: its root must be `<configuration>` (or `<sumoConfiguration>`) and it
/// must name a network.
pub fn config_files(sumocfg: &Path) -> Result<ConfigFiles, InputError> {
    let text = read(sumocfg)?;
    let doc = parse(sumocfg, &text)?;
    let root = doc.root_element().tag_name().name();
    if root != "configuration" && root != "sumoConfiguration" {
        return Err(content(
            sumocfg,
            format!("not a SUMO configuration (root element <{root}>, expected <configuration>)"),
        ));
    }
    let dir = sumocfg.parent().unwrap_or(Path::new(""));
    let list = |option: &str| -> Vec<PathBuf> {
        doc.descendants()
            .filter(|n| n.has_tag_name(option))
            .filter_map(|n| n.attribute("value"))
            .flat_map(|v| {
                v.split(',')
                    .map(str::trim)
                    .filter(|f| !f.is_empty())
                    .map(|f| dir.join(f))
            })
            .collect()
    };
    let net = list("net-file")
        .pop()
        .ok_or_else(|| content(sumocfg, "names no network (<net-file value=\"...\"/>)".into()))?;
    // An option's value, trimmed, where the configuration sets it.
    let option = |name: &str| {
        (doc.descendants())
            .find(|n| n.has_tag_name(name))
            .and_then(|n| n.attribute("value"))
            .map(str::trim)
    };
    let step_length = match option("step-length") {
        None => None,
        Some(v) => Some(
            v.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite() && *x > 0.0)
                .ok_or_else(|| content(sumocfg, format!("step-length {v:?} is not a positive number")))?,
        ),
    };
    let begin = match option("begin") {
        None => 0.0,
        Some(v) => sumo_time(v)
            .filter(|t| *t >= 0.0)
            .ok_or_else(|| content(sumocfg, format!("begin {v:?} is not a time of 0 s or later")))?,
    };
    let other_dynamics = ["step-method.ballistic", "mesosim"]
        .into_iter()
        .filter(|o| option(o) == Some("true"))
        .collect();
    let no_collision_check = option("collision.action") == Some("none");
    let scale = option("scale").map(str::to_owned);
    let ssm_option = doc
        .descendants()
        .any(|n| n.has_tag_name("device.ssm.probability") || n.has_tag_name("device.ssm.explicit"));
    Ok(ConfigFiles {
        net,
        routes: list("route-files"),
        additional: list("additional-files"),
        step_length,
        begin,
        scale,
        no_collision_check,
        other_dynamics,
        ssm_option,
    })
}

/// A SUMO time value: seconds, or `[[d:]h:]m:s` as SUMO also reads them ("6:00:00" is 21,600
/// s); none for anything else.
fn sumo_time(value: &str) -> Option<f64> {
    let parts: Vec<&str> = value.trim().split(':').collect();
    if parts.len() > 4 {
        return None;
    }
    let mut seconds = 0.0;
    for (k, part) in parts.iter().enumerate() {
        let x: f64 = part.trim().parse().ok().filter(|x: &f64| x.is_finite())?;
        // Every field but the last (seconds) is a whole number.
        if k + 1 < parts.len() && (x.fract() != 0.0 || x < 0.0) {
            return None;
        }
        let unit = [1.0, 60.0, 3600.0, 86_400.0][parts.len() - 1 - k];
        seconds += x * unit;
    }
    Some(seconds)
}

/// Reads the network in `net` (XML with a `<net>` root) and hands it to `f`.
pub(crate) fn with_network<T>(
    net: &Path,
    f: impl FnOnce(&roxmltree::Document) -> T,
) -> Result<T, InputError> {
    let text = read(net)?;
    let doc = parse(net, &text)?;
    if doc.root_element().tag_name().name() != "net" {
        return Err(content(
            net,
            "not a SUMO network (root element is not <net>)".into(),
        ));
    }
    Ok(f(&doc))
}

/// Checks `geometry` against the network and returns where its lanes lie along the road:
/// its lanes exist and each leads to the next one listed, the last ramp lane is an
/// acceleration lane beside a target lane or leads through a junction into one, and the
/// conflict point lies on it.
pub fn check_geometry(
    geometry: &MergeGeometry,
    geometry_path: &Path,
    net: &Path,
) -> Result<LanePositions, InputError> {
    let in_net = |message: String| content(geometry_path, format!("{message} (network {})", net.display()));
    with_network(net, |doc| {
        let ids: Vec<String> = doc
            .descendants()
            .filter(|n| n.has_tag_name("lane"))
            .filter_map(|n| n.attribute("id").map(str::to_owned))
            .collect();
        geometry.check_lanes(&ids).map_err(|e| in_net(e.to_string()))?;
        let positions = LanePositions::of_network(
            doc,
            &geometry.ramp_lanes,
            &geometry.target_lanes,
            geometry.target_start,
        )
        .map_err(in_net)?;
        let accel = geometry.ramp_lanes.last().expect("validated: not empty");
        let (lo, hi) = positions.span(accel).expect("placed");
        let x_c = geometry.conflict_point;
        let what = match positions.form() {
            MergeForm::AccelerationLane => "the acceleration lane",
            MergeForm::Junction => "the last ramp lane",
        };
        if !(lo <= x_c && x_c <= hi) {
            return Err(in_net(format!(
                "conflict_point {x_c} m is not on {what} `{accel}` (its positions run from {lo:.1} \
                 to {hi:.1} m along the lanes)"
            )));
        }
        if positions.form() == MergeForm::Junction && geometry.merge_from.is_some() {
            return Err(in_net(format!(
                "merge_from is for acceleration lanes: `{accel}` leads through a junction into the \
                 target lane, where a ramp vehicle enters from the stop line (remove merge_from)"
            )));
        }
        Ok(positions)
    })?
}

/// SUMO's built-in vehicle types, which a route file may use without defining them.
const DEFAULT_TYPES: &[&str] = &[
    "DEFAULT_VEHTYPE",
    "DEFAULT_PEDTYPE",
    "DEFAULT_BIKETYPE",
    "DEFAULT_CONTAINERTYPE",
    "DEFAULT_TAXITYPE",
    "DEFAULT_RAILTYPE",
];

/// The edges of a network and, for each, the edges its connections lead to.
#[derive(Debug, Default)]
struct EdgeGraph {
    next: HashMap<String, HashSet<String>>,
}

impl EdgeGraph {
    fn of(doc: &roxmltree::Document) -> Self {
        let mut next: HashMap<String, HashSet<String>> = doc
            .root_element()
            .children()
            .filter(|n| n.has_tag_name("edge") && n.attribute("function") != Some("internal"))
            .filter_map(|n| Some((n.attribute("id")?.to_owned(), HashSet::new())))
            .collect();
        for c in doc
            .root_element()
            .children()
            .filter(|n| n.has_tag_name("connection"))
        {
            if let (Some(from), Some(to)) = (c.attribute("from"), c.attribute("to")) {
                if next.contains_key(to) {
                    if let Some(set) = next.get_mut(from) {
                        set.insert(to.to_owned());
                    }
                }
            }
        }
        EdgeGraph { next }
    }

    fn has(&self, edge: &str) -> bool {
        self.next.contains_key(edge)
    }

    /// Whether a vehicle can drive from `from` to `to` (the same edge counts).
    fn reaches(&self, from: &str, to: &str, seen: &mut HashMap<String, HashSet<String>>) -> bool {
        let reach = seen.entry(from.to_owned()).or_insert_with(|| {
            let mut reach = HashSet::from([from.to_owned()]);
            let mut todo = vec![from.to_owned()];
            while let Some(e) = todo.pop() {
                for n in self.next.get(&e).into_iter().flatten() {
                    if reach.insert(n.clone()) {
                        todo.push(n.clone());
                    }
                }
            }
            reach
        });
        reach.contains(to)
    }
}

/// Checks route (and additional) files: well-formed XML; every `route` a vehicle or flow
/// names is defined in one of them (as a route or a route distribution); every vehicle type
/// used is defined (a vType or a vTypeDistribution) or one of SUMO's defaults; and, given the
/// network, every edge a route, trip or flow names (`edges`, `from`, `to`, `via`) is in it,
/// consecutive edges of a route are connected, and a trip's or flow's `to` can be reached from
/// its `from` through its `via` edges, as SUMO's router needs. Returns what the co-simulation
/// needs to know of them ([`RouteFacts`]).
pub fn check_routes(files: &[PathBuf], net: Option<&Path>) -> Result<RouteFacts, InputError> {
    let texts: Vec<(PathBuf, String)> = files
        .iter()
        .map(|f| Ok((f.clone(), read(f)?)))
        .collect::<Result<_, InputError>>()?;
    let docs: Vec<(&Path, roxmltree::Document)> = texts
        .iter()
        .map(|(f, t)| Ok((f.as_path(), parse(f, t)?)))
        .collect::<Result<_, InputError>>()?;
    let all = || docs.iter().flat_map(|(_, d)| d.descendants());
    let defined: HashSet<&str> = all()
        .filter(|n| n.has_tag_name("route") || n.has_tag_name("routeDistribution"))
        .filter_map(|n| n.attribute("id"))
        .collect();
    let types: HashSet<&str> = all()
        .filter(|n| n.has_tag_name("vType") || n.has_tag_name("vTypeDistribution"))
        .filter_map(|n| n.attribute("id"))
        .chain(DEFAULT_TYPES.iter().copied())
        .collect();
    let graph = net.map(|net| with_network(net, EdgeGraph::of)).transpose()?;
    let mut reach = HashMap::new();
    const DEPARTING: [&str; 3] = ["vehicle", "flow", "trip"];
    for (path, doc) in &docs {
        for n in doc
            .descendants()
            .filter(|n| DEPARTING.contains(&n.tag_name().name()))
        {
            let id = n.attribute("id").unwrap_or("?");
            if let Some(route) = n.attribute("route").filter(|r| !defined.contains(r)) {
                return Err(content(
                    path,
                    format!("`{id}` uses route `{route}`, which no route file defines"),
                ));
            }
            // A type may also be a list of distributions or types: every one must exist.
            for ty in n
                .attribute("type")
                .into_iter()
                .flat_map(|t| t.split(','))
                .map(str::trim)
            {
                if !types.contains(ty) {
                    return Err(content(
                        path,
                        format!("`{id}` uses vehicle type `{ty}`, which no route or additional file defines"),
                    ));
                }
            }
            let Some(graph) = &graph else { continue };
            let ends: Vec<&str> = n
                .attribute("from")
                .into_iter()
                .chain(n.attribute("via").into_iter().flat_map(str::split_whitespace))
                .chain(n.attribute("to"))
                .collect();
            if let Some(bad) = ends.iter().find(|e| !graph.has(e)) {
                return Err(content(
                    path,
                    format!("`{id}` names edge `{bad}`, which is not in the network"),
                ));
            }
            if let Some(w) = ends.windows(2).find(|w| !graph.reaches(w[0], w[1], &mut reach)) {
                return Err(content(
                    path,
                    format!(
                        "`{id}`: no route leads from edge `{}` to edge `{}` in the network",
                        w[0], w[1]
                    ),
                ));
            }
        }
        let Some(graph) = &graph else { continue };
        for r in doc.descendants().filter(|n| n.has_tag_name("route")) {
            let id = r.attribute("id").unwrap_or("?");
            let edges: Vec<&str> = r.attribute("edges").unwrap_or("").split_whitespace().collect();
            if let Some(bad) = edges.iter().find(|e| !graph.has(e)) {
                return Err(content(
                    path,
                    format!("route `{id}` has edge `{bad}`, which is not in the network"),
                ));
            }
            let connected = |w: &&[&str]| graph.next.get(w[0]).is_some_and(|n| n.contains(w[1]));
            if let Some(w) = edges.windows(2).find(|w| !connected(w)) {
                return Err(content(
                    path,
                    format!(
                        "route `{id}`: edge `{}` does not lead to `{}` in the network",
                        w[0], w[1]
                    ),
                ));
            }
        }
    }
    let ssm = all().any(|n| {
        n.has_tag_name("param")
            && n.attribute("key") == Some("has.ssm.device")
            && n.attribute("value").is_some_and(|v| v.trim() == "true")
    });
    let min_gap = all()
        .filter(|n| n.has_tag_name("vType"))
        .map(|n| {
            n.attribute("minGap")
                .and_then(|g| g.parse().ok())
                .unwrap_or(SUMO_MIN_GAP)
        })
        .filter(|g: &f64| g.is_finite())
        .reduce(f64::max)
        .unwrap_or(SUMO_MIN_GAP);
    let mut types: Vec<String> = all()
        .filter(|n| n.has_tag_name("vType") || n.has_tag_name("vTypeDistribution"))
        .filter_map(|n| n.attribute("id").map(str::to_owned))
        .collect();
    types.sort();
    types.dedup();
    Ok(RouteFacts { ssm, min_gap, types })
}

/// SUMO's `minGap` of a vehicle type that sets none (m).
pub const SUMO_MIN_GAP: f64 = 2.5;

/// What route (and additional) files tell the co-simulation.
#[derive(Debug, Clone, PartialEq)]
pub struct RouteFacts {
    /// A file equips vehicles with the SSM device (a `has.ssm.device` parameter set to true).
    pub ssm: bool,
    /// The largest `minGap` of the vehicle types they define ([`SUMO_MIN_GAP`] for a type that
    /// sets none, and when they define none) (m): SUMO counts a bumper gap below it as a
    /// collision unless `collision.mingap-factor` is 0.
    pub min_gap: f64,
    /// The vehicle types and type distributions they define, sorted.
    pub types: Vec<String>,
}

/// Every check before a co-simulation, given the configuration's files: each merge's geometry
/// against its network, and the route files (`route_files`, a comma-separated list as SUMO
/// takes it, replacing the configuration's when given). Returns where each merge's lanes lie
/// along the road, and what the route files tell (the SSM device also when the configuration
/// equips vehicles with it).
pub fn check_inputs(
    files: &ConfigFiles,
    route_files: Option<&Path>,
    merges: &[MergeGeometry],
    geometry_path: &Path,
) -> Result<(Vec<LanePositions>, RouteFacts), InputError> {
    let positions = merges
        .iter()
        .enumerate()
        .map(|(k, g)| {
            check_geometry(g, geometry_path, &files.net).map_err(|e| match e {
                InputError::Content { path, message } if merges.len() > 1 => InputError::Content {
                    path,
                    message: format!("merge {} (`{}`): {message}", k + 1, g.label()),
                },
                e => e,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut routes = match route_files {
        Some(r) => r
            .to_string_lossy()
            .split(',')
            .map(|f| PathBuf::from(f.trim()))
            .collect(),
        None => files.routes.clone(),
    };
    routes.extend(files.additional.iter().cloned());
    let mut facts = check_routes(&routes, Some(&files.net))?;
    facts.ssm |= files.ssm_option;
    Ok((positions, facts))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn sumo_times_read_in_seconds_and_in_days_hours_minutes_and_seconds() {
        for (text, seconds) in [
            ("21600", Some(21_600.0)),
            (" 0.5 ", Some(0.5)),
            ("6:00:00", Some(21_600.0)),
            ("16:40", Some(1_000.0)),
            ("1:00:00:01.5", Some(86_401.5)),
            ("1:2:3:4:5", None),
            ("0:-1:00", None),
            ("1.5:00", None),
            ("6 am", None),
            ("", None),
        ] {
            assert_eq!(sumo_time(text), seconds, "{text:?}");
        }
    }

    #[test]
    fn a_gzip_compressed_input_reads_as_its_plain_text_and_a_broken_one_is_an_error() {
        let dir = std::env::temp_dir().join(format!("mpgdrive-gz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let text = "<net version=\"1.9\"><edge id=\"a\"/></net>\n";
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        gz.write_all(text.as_bytes()).unwrap();
        let gz = gz.finish().unwrap();
        let (plain_path, gz_path, broken) =
            (dir.join("n.net.xml"), dir.join("n.net.xml.gz"), dir.join("b.gz"));
        std::fs::write(&plain_path, text).unwrap();
        std::fs::write(&gz_path, &gz).unwrap();
        std::fs::write(&broken, &gz[..gz.len() / 2]).unwrap();
        assert_eq!(read_sumo_file(&plain_path).unwrap(), text);
        assert_eq!(read_sumo_file(&gz_path).unwrap(), text);
        assert!(matches!(read(&broken), Err(InputError::Read { .. })));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
