//! `mpgdrive routes`: scenario sets as ordinary SUMO route files.
//!
//! A base route file (for example `sumo_nets/i80_merge/i80.rou.xml`) gives the vehicle types,
//! routes (or route distributions) and flows. For every demand scale and seed, each flow
//! becomes explicit vehicles (trips, for a flow with `from`/`to` instead of a route, which SUMO
//! routes) with Poisson arrivals at `scale x` its rate (`vehsPerHour`, `period` or its Poisson
//! form `exp(r)`, `probability` or `number`, from `begin` to `end`, SUMO's 0 and 24 hours when
//! missing; a route and other children in the flow are copied into each vehicle; ChaCha8,
//! stream = flow index, so a flow's vehicles do not depend on the other flows). Ramp flows
//! (whose route reaches the last ramp lane's edge along the ramp, from an edge of a ramp lane
//! of `merge.toml` beside no target lane; or whose `from` or `via` is such an edge) can be
//! rescaled to carry a given share of the demand, and a flow whose type is
//! a `vTypeDistribution` that holds a controllable type draws each vehicle's type with the
//! given controllable share, and so does a ramp flow of a plain type (one of a controllable
//! type gives the vehicles it leaves to SUMO the file's first vType of another type; one of
//! another type gives its controllable ones the controllable type); freeway flows of a plain
//! type can carry a share of the controllable type too (a penetration rate). A file may carry
//! the ramp's or the freeway's flows alone ([`Streams`]). Types and routes are copied verbatim
//! from the base file. Explicit `<vehicle>` and `<trip>` elements (route files of
//! `randomTrips.py`, say) are kept with their departures and attributes, each `scale` times in
//! expectation as SUMO's `--scale` copies them, and take the same shares.
//! A `manifest.json` lists the files with their parameters.

use crate::atomic;
use crate::batch::route_base::{
    Explicit, Flow, TypeShares, controllable_type, controllable_types, loaded_elements, parse_base,
    under_one_root,
};
use crate::sumo::geometry::MergeGeometry;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What to generate.
#[derive(Debug, Clone)]
pub struct DemandSpec {
    /// Multipliers of the base demand.
    pub scales: Vec<f64>,
    /// Share of all vehicles that come from the ramp (`None`: as in the base file).
    pub ramp_share: Option<f64>,
    /// Shares of ramp vehicles of a controllable type, one route file each (empty: as in the
    /// base file). Files of one scale and seed share their arrivals; only the types differ.
    pub controllable_shares: Vec<f64>,
    /// Share of freeway vehicles (flows not from the ramp, of a plain type) made of the
    /// controllable type, a penetration rate (`None`: none). Arrivals stay those of the file
    /// without it: the types are drawn from a stream of their own.
    pub mainline_share: Option<f64>,
    /// One route file per seed and scale.
    pub seeds: Vec<u64>,
    /// Departures from this time (s; a configuration's begin, SUMO's default 0) ...
    pub begin: f64,
    /// ... for this many seconds, within each flow's begin and end.
    pub duration: f64,
    /// Which flows the files carry; a flow's arrivals do not depend on it.
    pub streams: Streams,
    /// Files SUMO loads with the route files (a configuration's additional files): their
    /// vehicle types and routes count as the base file's, and the generated files leave them
    /// out (SUMO refuses a type defined twice).
    pub loaded: Vec<PathBuf>,
}

/// Which of the base file's flows a route file carries.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Streams {
    /// Every flow.
    #[default]
    All,
    /// The ramp flows alone.
    Ramp,
    /// The freeway flows alone.
    Freeway,
}

impl Streams {
    /// Whether a file of these streams carries a flow that is (`ramp`) or is not a ramp flow.
    fn carries(self, ramp: bool) -> bool {
        match self {
            Streams::All => true,
            Streams::Ramp => ramp,
            Streams::Freeway => !ramp,
        }
    }

    /// What it is called in file names and messages.
    pub fn name(self) -> &'static str {
        match self {
            Streams::All => "all",
            Streams::Ramp => "ramp",
            Streams::Freeway => "freeway",
        }
    }

    fn is_all(&self) -> bool {
        *self == Streams::All
    }
}

/// One generated file, as listed in `manifest.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ManifestEntry {
    /// File name (in the manifest's directory).
    pub file: String,
    /// Demand scale.
    pub scale: f64,
    /// Ramp share used (`None`: the base file's).
    pub ramp_share: Option<f64>,
    /// Controllable share used (`None`: the base file's).
    pub controllable_share: Option<f64>,
    /// Controllable share of the freeway vehicles (`None`: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mainline_share: Option<f64>,
    /// Seed of the arrivals and type draws.
    pub seed: u64,
    /// Which flows the file carries.
    #[serde(default, skip_serializing_if = "Streams::is_all")]
    pub streams: Streams,
    /// Vehicles written.
    pub vehicles: usize,
    /// The controllable type the base file does not define, which this file defines as a copy
    /// of the base's first passenger car's vType (SUMO's default car without one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub derived_type: Option<String>,
    /// Elements of the base file this file does not carry over, each as its count and tag
    /// (`3 <person>`): the generator writes vehicle types, routes and vehicles only.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub left_out: Vec<String>,
}

/// What a command says about how the generated files (`manifest`) differ from the base file
/// at `base` beyond the demand: a controllable type it did not define
/// ([`ManifestEntry::derived_type`]), and elements they leave out ([`ManifestEntry::left_out`]).
pub fn base_notes(base: &Path, manifest: &[ManifestEntry]) -> Vec<String> {
    let Some(first) = manifest.first() else {
        return Vec::new();
    };
    let base = base.display();
    let derived = (first.derived_type.as_ref()).map(|ctrl| {
        format!("{base} defines no controllable type: `{ctrl}` is added as a copy of its first passenger car's vType")
    });
    let left_out = (!first.left_out.is_empty()).then(|| {
        format!(
            "{base}: left out of the generated files: {}",
            first.left_out.join(", ")
        )
    });
    derived.into_iter().chain(left_out).collect()
}

/// Errors of route generation.
#[derive(Debug, thiserror::Error)]
pub enum RoutesError {
    /// The base file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The base file is not usable.
    #[error("{path}: {message}")]
    Base {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A parameter is out of range.
    #[error("{0}")]
    Invalid(String),
}

/// One route file of the route files `paths` (a SUMO configuration's, in their order): the
/// elements under each file's root, in turn, under one `<routes>`. A configuration that keeps
/// its vehicle types in one file and its flows in another is one demand.
pub fn combined_route_files(paths: &[PathBuf]) -> Result<String, RoutesError> {
    under_one_root(paths, |_| true)
}

/// How many of the flows and explicit vehicles of the base file at `base_path` drive along a
/// ramp of `merges`, and how many do not: which [`Streams`] it can give.
/// `loaded`: files SUMO loads with it ([`DemandSpec::loaded`]).
pub fn flows_by_stream(
    base_path: &Path,
    loaded: &[PathBuf],
    merges: &[MergeGeometry],
) -> Result<(usize, usize), RoutesError> {
    let text = crate::sumo::inputs::read_sumo_file(base_path).map_err(|source| RoutesError::Io {
        path: base_path.to_path_buf(),
        source,
    })?;
    let base = parse_base(base_path, &text, &loaded_elements(loaded)?, merges)?;
    let ramp = base.ramp_flags().filter(|&r| r).count();
    Ok((ramp, base.ramp_flags().count() - ramp))
}

fn check_share(name: &str, x: Option<f64>) -> Result<(), RoutesError> {
    match x {
        Some(v) if !(0.0..=1.0).contains(&v) => {
            Err(RoutesError::Invalid(format!("{name} {v} must lie in [0, 1]")))
        }
        _ => Ok(()),
    }
}

/// A vehicle element: its opening tag `head` (without the closing `>`) and its children.
fn element(head: String, tag: &str, inner: &str) -> String {
    match inner.is_empty() {
        true => head + "/>",
        false => format!("{head}>{inner}</{tag}>"),
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
}

/// The most vehicles one generated route file may hold.
const MAX_VEHICLES: f64 = 1e7;

/// Writes one route file per (scale, controllable share, seed) and `manifest.json` into
/// `out`: `<stem>_d<scale>_s<seed>.rou.xml`, with `_c<share>` before `_s` when several shares
/// are given.
pub fn generate(
    base_path: &Path,
    merges: &[MergeGeometry],
    spec: &DemandSpec,
    out: &Path,
) -> Result<Vec<ManifestEntry>, RoutesError> {
    check_share("--ramp-share", spec.ramp_share)?;
    for &share in &spec.controllable_shares {
        check_share("--controllable-share", Some(share))?;
    }
    check_share("--mainline-controllable-share", spec.mainline_share)?;
    let shares: Vec<Option<f64>> = if spec.controllable_shares.is_empty() {
        vec![None]
    } else {
        spec.controllable_shares.iter().copied().map(Some).collect()
    };
    if spec.scales.is_empty() || spec.scales.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(RoutesError::Invalid(
            "demand scales must be positive numbers".into(),
        ));
    }
    if !(spec.begin.is_finite() && spec.begin >= 0.0) {
        return Err(RoutesError::Invalid(format!(
            "--begin {} must be a time of 0 s or later",
            spec.begin
        )));
    }
    if !(spec.duration.is_finite() && spec.duration > 0.0) {
        return Err(RoutesError::Invalid(format!(
            "--duration {} must be positive",
            spec.duration
        )));
    }
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| RoutesError::Io { path, source }
    };
    let text = crate::sumo::inputs::read_sumo_file(base_path).map_err(io(base_path))?;
    let base = parse_base(base_path, &text, &loaded_elements(&spec.loaded)?, merges)?;
    let controllable = controllable_types(merges);
    let ctrl_type = controllable_type(&base, merges);
    let plain_ramp_share = spec.controllable_shares.iter().any(|&c| c > 0.0)
        && (base.flows.iter().map(|f| (f.ramp, &f.vtype)))
            .chain(base.explicit.iter().map(|v| (v.ramp, &v.vtype)))
            .any(|(ramp, t)| ramp && !base.mixes.iter().any(|(id, _, _)| id == t));
    for (needed, flag) in [
        (spec.mainline_share.is_some(), "--mainline-controllable-share"),
        (
            plain_ramp_share,
            "a controllable share of ramp vehicles of a plain type",
        ),
    ] {
        if needed && ctrl_type.is_none() {
            return Err(RoutesError::Base {
                path: base_path.to_path_buf(),
                message: format!(
                    "{flag} needs a vType of a controllable type ({}) in the file",
                    controllable.join(", ")
                ),
            });
        }
    }
    let type_shares = |ramp| TypeShares {
        ramp,
        mainline: spec.mainline_share,
        ctrl: ctrl_type.as_ref(),
        controllable: &controllable,
    };
    let plain_ctrl_ramp = (base.flows.iter().filter(|f| f.ramp).map(|f| (&f.id, &f.vtype)))
        .chain(base.explicit.iter().filter(|v| v.ramp).map(|v| (&v.id, &v.vtype)))
        .find(|(_, t)| controllable.contains(&t.as_str()));
    if let Some((id, vtype)) = plain_ctrl_ramp
        && spec.controllable_shares.iter().any(|&c| c < 1.0)
        && base.human.is_none()
    {
        return Err(RoutesError::Base {
            path: base_path.to_path_buf(),
            message: format!(
                "the ramp's flow or vehicle `{id}` is of the controllable type `{vtype}`: a controllable share below 1 \
                 needs a vType of another type in the file for the vehicles it leaves to SUMO"
            ),
        });
    }
    if spec.ramp_share.is_some() && !base.explicit.is_empty() {
        return Err(RoutesError::Invalid(
            "--ramp-share rescales flows; the base file has explicit vehicles or trips".into(),
        ));
    }
    let total: f64 = base.flows.iter().map(|f| f.per_hour).sum();
    let ramp: f64 = base.flows.iter().filter(|f| f.ramp).map(|f| f.per_hour).sum();
    let factor = |f: &Flow| match spec.ramp_share {
        Some(share) if ramp > 0.0 && ramp < total => {
            if f.ramp {
                share * total / ramp
            } else {
                (1.0 - share) * total / (total - ramp)
            }
        }
        _ => 1.0,
    };
    if !base.ramp_flags().any(|r| spec.streams.carries(r)) {
        return Err(RoutesError::Invalid(format!(
            "the base file has no {} flow",
            spec.streams.name()
        )));
    }
    if spec.ramp_share.is_some() && !(ramp > 0.0 && ramp < total) {
        return Err(RoutesError::Invalid(
            "--ramp-share needs both ramp and freeway flows in the base file".into(),
        ));
    }
    let until = spec.begin + spec.duration;
    // A window that holds no departure would give empty files, and runs without traffic.
    let in_window = |v: &&Explicit| spec.streams.carries(v.ramp) && (spec.begin..until).contains(&v.depart.1);
    if !(base.flows.iter())
        .any(|f| spec.streams.carries(f.ramp) && f.per_hour > 0.0 && f.begin < until && f.end > spec.begin)
        && !base.explicit.iter().any(|v| in_window(&v))
    {
        return Err(RoutesError::Invalid(format!(
            "no flow or vehicle of the base file departs between {} and {until} s: set the begin \
             time of the configuration that runs them (`routes --begin`)",
            spec.begin
        )));
    }
    // A bound on the work: Poisson arrivals at an absurd rate would never reach the end.
    for &scale in &spec.scales {
        let expected: f64 = base
            .flows
            .iter()
            .map(|f| {
                f.per_hour * scale * factor(f) / 3600.0
                    * (f.end.min(until) - f.begin.max(spec.begin)).max(0.0)
            })
            .sum::<f64>()
            + base.explicit.len() as f64 * scale;
        if expected > MAX_VEHICLES {
            return Err(RoutesError::Invalid(format!(
                "demand scale {scale} would give about {expected:.3e} vehicles in one file (at most {MAX_VEHICLES:e})"
            )));
        }
    }
    std::fs::create_dir_all(out).map_err(io(out))?;
    let stem = base_path
        .file_name()
        .and_then(|n| n.to_str())
        .map_or("routes", |n| {
            n.trim_end_matches(".gz")
                .trim_end_matches(".xml")
                .trim_end_matches(".rou")
        });
    let mut manifest = Vec::new();
    for (&scale, &share) in spec
        .scales
        .iter()
        .flat_map(|scale| shares.iter().map(move |share| (scale, share)))
    {
        for &seed in &spec.seeds {
            let mut vehicles: Vec<(f64, String)> = Vec::new();
            for (k, flow) in base.flows.iter().enumerate() {
                let rate = flow.per_hour * scale * factor(flow) / 3600.0;
                if rate <= 0.0 || !spec.streams.carries(flow.ramp) {
                    continue;
                }
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream(k as u64);
                let mut type_rng = ChaCha8Rng::seed_from_u64(seed);
                type_rng.set_stream((1 << 32) + k as u64);
                // The arrivals run from the flow's begin whatever the window's: a flow's
                // vehicles are the same in every window that holds them.
                let mut t = flow.begin;
                let end = flow.end.min(until);
                let mut n = 0usize;
                loop {
                    t += -(1.0 - rng.random::<f64>()).ln() / rate;
                    if t >= end {
                        break;
                    }
                    // A distribution draws on the arrivals' stream (as it always has); the
                    // other draws have their own, so the arrivals stay those without a share.
                    let vtype = base.draw_type(
                        (&flow.vtype, flow.ramp),
                        &type_shares(share),
                        (&mut rng, &mut type_rng),
                    );
                    if t < spec.begin {
                        continue;
                    }
                    let extra: String = flow
                        .extra
                        .iter()
                        .map(|(a, v)| format!(" {a}=\"{}\"", xml_escape(v)))
                        .collect();
                    // A flow with from/to gives trips (its from/to/via are in `extra`), one
                    // with a route (named, or in it) vehicles; each keeps the flow's children.
                    let (tag, route) = match &flow.route {
                        Some(r) => ("vehicle", format!(" route=\"{}\"", xml_escape(r))),
                        None if flow.inner.contains("<route") => ("vehicle", String::new()),
                        None => ("trip", String::new()),
                    };
                    let head = format!(
                        "    <{tag} id=\"{}.{n}\" type=\"{}\"{route} depart=\"{t:.2}\"{extra}",
                        xml_escape(&flow.id),
                        xml_escape(&vtype),
                    );
                    vehicles.push((t, element(head, tag, &flow.inner)));
                    n += 1;
                }
            }
            // Explicit vehicles: each kept (copied) `scale` times in expectation, every copy at
            // its departure, as SUMO's --scale does; copies after the first are `<id>#<k>`.
            for (j, v) in base.explicit.iter().enumerate() {
                if !in_window(&v) {
                    continue;
                }
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream((2 << 32) + j as u64);
                let mut type_rng = ChaCha8Rng::seed_from_u64(seed);
                type_rng.set_stream((3 << 32) + j as u64);
                let copies = scale.floor() as usize + usize::from(rng.random::<f64>() < scale.fract());
                let extra: String = (v.extra.iter())
                    .map(|(a, x)| format!(" {a}=\"{}\"", xml_escape(x)))
                    .collect();
                for c in 0..copies {
                    let vtype =
                        base.draw_type((&v.vtype, v.ramp), &type_shares(share), (&mut rng, &mut type_rng));
                    let id = if c == 0 {
                        v.id.clone()
                    } else {
                        format!("{}#{c}", v.id)
                    };
                    let head = format!(
                        "    <{} id=\"{}\" type=\"{}\" depart=\"{}\"{extra}",
                        v.tag,
                        xml_escape(&id),
                        xml_escape(&vtype),
                        xml_escape(&v.depart.0)
                    );
                    vehicles.push((v.depart.1, element(head, &v.tag, &v.inner)));
                }
            }
            vehicles.sort_by(|a, b| a.0.total_cmp(&b.0).then_with(|| a.1.cmp(&b.1)));
            let swept = match share {
                Some(c) if shares.len() > 1 => format!("_c{c:.2}"),
                _ => String::new(),
            };
            let mainline = spec.mainline_share.map_or(String::new(), |m| format!("_m{m:.2}"));
            let only = (spec.streams != Streams::All).then(|| spec.streams.name());
            let streams = only.map_or(String::new(), |n| format!("_{n}"));
            let file = format!("{stem}_d{scale:.2}{swept}{mainline}{streams}_s{seed}.rou.xml");
            let mut xml = format!(
                "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- mpgdrive routes from {}: demand scale {scale}, ramp share {:?}, controllable share {:?}, mainline controllable share {:?}{}, seed {seed}, {} s{} -->\n<routes>\n",
                base_path.display(),
                spec.ramp_share,
                share,
                spec.mainline_share,
                only.map_or(String::new(), |n| format!(", only the {n} flows")),
                spec.duration,
                if spec.begin > 0.0 {
                    format!(" from {} s", spec.begin)
                } else {
                    String::new()
                }
            );
            for v in &base.verbatim {
                xml += &format!("    {v}\n");
            }
            for (_, v) in &vehicles {
                xml += v;
                xml.push('\n');
            }
            xml += "</routes>\n";
            let path = out.join(&file);
            atomic::write(&path, xml).map_err(io(&path))?;
            manifest.push(ManifestEntry {
                file,
                scale,
                ramp_share: spec.ramp_share,
                controllable_share: share,
                mainline_share: spec.mainline_share,
                seed,
                streams: spec.streams,
                vehicles: vehicles.len(),
                derived_type: base.derived_type.clone(),
                left_out: base.left_out.clone(),
            });
        }
    }
    let path = out.join("manifest.json");
    let json = serde_json::to_string_pretty(&manifest).expect("manifest serialises");
    atomic::write(&path, json).map_err(io(&path))?;
    Ok(manifest)
}
