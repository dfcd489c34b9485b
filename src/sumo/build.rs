//! `mpgdrive net build`: a merge network built from a few parameters with netconvert, with its
//! routes and a SUMO configuration, so that tests and acceptance scripts run over families of
//! networks (speed, lanes, merge form, ramp shape, demand) built at run time instead of over
//! committed files.
//!
//! The freeway runs along +x: `in` (from 0 to `upstream`), then, for an acceleration lane, `acc`
//! (one lane more, `accel_lane` long), then `out` (400 m). The ramp (`ramp`, one lane, 250 m
//! along x) joins from the right at the end of `in`: into the acceleration lane (`acc_0`,
//! [`crate::sumo::positions::MergeForm::AccelerationLane`]) or straight into the freeway's right lane through the
//! junction (`out_0`, [`crate::sumo::positions::MergeForm::Junction`]). A lane drop has no ramp: `in` has one lane more
//! than `out`, and its right lane `in_0` leads into `out_0` beside `in_1` (its vehicles appear
//! 100 m before its end). Edge priorities make
//! the ramp (or the dropped lane) the minor link. With several ramps (a corridor), each merge
//! is followed by `spacing` metres of freeway (`mid1`, `mid2`, ...) before the next ramp
//! (`ramp2`, `ramp3`, ...); the last piece is `out`. Routes are `<flow>`s with `from`/`to`, one
//! per freeway lane (`human`) and one per ramp (`ramp_mix`: `ctrl`, the type mpgdrive may drive, or
//! `human_ramp`; all `ctrl` unless `mpgdrive routes --controllable-share` sets another share).

use std::path::{Path, PathBuf};
use std::process::Command;

/// The kind of merge a built network has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BuiltForm {
    /// A ramp into an acceleration lane beside the freeway's right lane.
    Acceleration,
    /// A ramp straight into the freeway's right lane at a priority junction.
    Junction,
    /// The freeway's right lane ends and continues into the next lane at a junction.
    LaneDrop,
}

/// Parameters of a built merge network (units: m, m/s, veh/h).
#[derive(Debug, Clone, PartialEq)]
pub struct MergeNetwork {
    /// The merge form.
    pub form: BuiltForm,
    /// Freeway lanes after the merge (at least 1).
    pub lanes: u32,
    /// Freeway speed limit (m/s).
    pub speed: f64,
    /// Ramp speed limit (m/s).
    pub ramp_speed: f64,
    /// Acceleration lane length (m; [`BuiltForm::Acceleration`] only).
    pub accel_lane: f64,
    /// Freeway length before the merge (m).
    pub upstream: f64,
    /// The ramp curves in (a Bezier) instead of running straight at an angle.
    pub curved: bool,
    /// A traffic light where the ramp joins ([`BuiltForm::Junction`] only; netconvert's own
    /// program: the two roads take turns).
    pub signal: bool,
    /// Demand per freeway lane (veh/h).
    pub lane_flow: f64,
    /// Ramp demand (veh/h; on the dropped lane for a lane drop).
    pub ramp_flow: f64,
    /// Demand duration (s).
    pub duration: f64,
    /// On-ramps along the freeway (a corridor when more than 1; a lane drop has one).
    pub ramps: u32,
    /// Freeway length between one merge's end and the next ramp's gore (m).
    pub spacing: f64,
}

/// A built network's files.
#[derive(Debug, Clone, PartialEq)]
pub struct BuiltFiles {
    /// `merge.net.xml`.
    pub net: PathBuf,
    /// `merge.sumocfg` (0.1 s steps).
    pub sumocfg: PathBuf,
}

/// Why a network could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// A parameter is out of range.
    #[error("{0}")]
    Parameter(String),
    /// A file could not be written.
    #[error("writing {path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// netconvert could not be run or failed.
    #[error("netconvert: {0}")]
    Netconvert(String),
}

impl MergeNetwork {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), BuildError> {
        let positive = [
            ("speed", self.speed),
            ("ramp speed", self.ramp_speed),
            ("upstream", self.upstream),
            ("duration", self.duration),
        ];
        for (name, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(BuildError::Parameter(format!(
                    "{name} {value} must be a positive number"
                )));
            }
        }
        for (name, value) in [("lane flow", self.lane_flow), ("ramp flow", self.ramp_flow)] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(BuildError::Parameter(format!(
                    "{name} {value} must not be negative"
                )));
            }
        }
        if !(1..=8).contains(&self.ramps) || (self.form == BuiltForm::LaneDrop && self.ramps > 1) {
            return Err(BuildError::Parameter(format!(
                "ramps {} must be 1 to 8 (1 for a lane drop)",
                self.ramps
            )));
        }
        if self.signal && self.form != BuiltForm::Junction {
            return Err(BuildError::Parameter(
                "a signal needs the junction form (--form junction)".to_owned(),
            ));
        }
        if !(self.spacing.is_finite() && self.spacing >= 2.0 * RAMP_RUN) {
            return Err(BuildError::Parameter(format!(
                "spacing {} must be at least {} m (a ramp's run)",
                self.spacing,
                2.0 * RAMP_RUN
            )));
        }
        if !(1..=8).contains(&self.lanes) {
            return Err(BuildError::Parameter(format!(
                "lanes {} must be 1 to 8",
                self.lanes
            )));
        }
        if self.form == BuiltForm::Acceleration && !(self.accel_lane.is_finite() && self.accel_lane >= 20.0) {
            return Err(BuildError::Parameter(format!(
                "accel lane {} must be at least 20 m",
                self.accel_lane
            )));
        }
        Ok(())
    }

    /// Writes the plain XML, routes and configuration into `dir` (created) and runs netconvert.
    pub fn build(&self, dir: &Path) -> Result<BuiltFiles, BuildError> {
        self.validate()?;
        let write = |name: &str, text: String| {
            let path = dir.join(name);
            crate::atomic::write(&path, text).map_err(|source| BuildError::Write { path, source })
        };
        std::fs::create_dir_all(dir).map_err(|source| BuildError::Write {
            path: dir.to_path_buf(),
            source,
        })?;
        write("merge.nod.xml", self.nodes())?;
        write("merge.edg.xml", self.edges())?;
        write("merge.con.xml", self.connections())?;
        write("merge.rou.xml", self.routes())?;
        write("merge.sumocfg", SUMOCFG.to_owned())?;
        let out = Command::new("netconvert")
            .current_dir(dir)
            .args([
                "--node-files=merge.nod.xml",
                "--edge-files=merge.edg.xml",
                "--connection-files=merge.con.xml",
                "--output-file=merge.net.xml",
                "--no-turnarounds=true",
                "--no-warnings=true",
            ])
            .output()
            .map_err(|e| BuildError::Netconvert(format!("cannot run it ({e}); install SUMO")))?;
        if !out.status.success() {
            return Err(BuildError::Netconvert(
                String::from_utf8_lossy(&out.stderr).trim().to_owned(),
            ));
        }
        Ok(BuiltFiles {
            net: dir.join("merge.net.xml"),
            sumocfg: dir.join("merge.sumocfg"),
        })
    }

    /// The freeway's edges in driving order, and the ramps.
    fn layout(&self) -> (Vec<Piece>, Vec<Ramp>) {
        let n = self.lanes;
        let suffix = |k: u32| {
            if k == 0 {
                String::new()
            } else {
                (k + 1).to_string()
            }
        };
        let mut pieces = Vec::new();
        let mut ramps = Vec::new();
        let mut from = "start".to_owned();
        let mut piece = "in".to_owned();
        for k in 0..self.ramps {
            let s = suffix(k);
            let gore = format!("gore{s}");
            let lanes = n + u32::from(self.form == BuiltForm::LaneDrop);
            pieces.push(Piece {
                id: piece,
                from,
                to: gore.clone(),
                lanes,
            });
            from = gore.clone();
            if self.form == BuiltForm::Acceleration {
                let end = format!("accel_end{s}");
                pieces.push(Piece {
                    id: format!("acc{s}"),
                    from,
                    to: end.clone(),
                    lanes: n + 1,
                });
                from = end;
            }
            ramps.push(Ramp {
                id: format!("ramp{s}"),
                gore,
                x: self.gore(k),
            });
            piece = if k + 1 == self.ramps {
                "out".to_owned()
            } else {
                format!("mid{}", k + 1)
            };
        }
        pieces.push(Piece {
            id: piece,
            from,
            to: "end".to_owned(),
            lanes: n,
        });
        (pieces, ramps)
    }

    /// The acceleration lane's length (m; 0 for the other forms).
    fn accel(&self) -> f64 {
        match self.form {
            BuiltForm::Acceleration => self.accel_lane,
            _ => 0.0,
        }
    }

    /// Where ramp `k`'s gore is (m along x).
    fn gore(&self, k: u32) -> f64 {
        self.upstream + f64::from(k) * (self.accel() + self.spacing)
    }

    fn nodes(&self) -> String {
        let accel = self.accel();
        let last = self.gore(self.ramps - 1) + accel;
        let mut nodes = vec![
            ("start".to_owned(), 0.0, 0.0),
            ("end".to_owned(), last + 400.0, 0.0),
        ];
        let (_, ramps) = self.layout();
        for Ramp { gore, x, .. } in &ramps {
            nodes.push((gore.clone(), *x, 0.0));
            let s = gore.trim_start_matches("gore");
            if self.form == BuiltForm::Acceleration {
                nodes.push((format!("accel_end{s}"), x + accel, 0.0));
            }
            if self.form != BuiltForm::LaneDrop {
                nodes.push((format!("ramp_start{s}"), x - RAMP_RUN, -RAMP_DROP));
            }
        }
        let kind = |id: &str| match self.signal && id.starts_with("gore") {
            true => "traffic_light",
            false => "priority",
        };
        let items: String = nodes
            .iter()
            .map(|(id, x, y)| {
                format!(
                    "  <node id=\"{id}\" x=\"{x:.2}\" y=\"{y:.2}\" type=\"{}\"/>\n",
                    kind(id)
                )
            })
            .collect();
        format!("<nodes>\n{items}</nodes>\n")
    }

    fn edges(&self) -> String {
        let edge = |id: &str, from: &str, to: &str, lanes: u32, speed: f64, priority: u32, extra: String| {
            format!(
                "  <edge id=\"{id}\" from=\"{from}\" to=\"{to}\" numLanes=\"{lanes}\" speed=\"{speed:.2}\" \
                 priority=\"{priority}\" width=\"{LANE_WIDTH}\"{extra}/>\n"
            )
        };
        let (pieces, ramps) = self.layout();
        let mut edges: String = pieces
            .iter()
            .map(|p| edge(&p.id, &p.from, &p.to, p.lanes, self.speed, 3, String::new()))
            .collect();
        if self.form != BuiltForm::LaneDrop {
            for Ramp { id, gore, x } in &ramps {
                let shape = self.ramp_shape(*x);
                let start = format!("ramp_start{}", gore.trim_start_matches("gore"));
                edges += &edge(
                    id,
                    &start,
                    gore,
                    1,
                    self.ramp_speed,
                    1,
                    format!(" shape=\"{shape}\""),
                );
            }
        }
        format!("<edges>\n{edges}</edges>\n")
    }

    /// The centre line of a ramp whose gore is at `gore`: straight at an angle, or a curve that
    /// meets the freeway's direction at the gore (points of a cubic Bezier).
    fn ramp_shape(&self, gore: f64) -> String {
        let (x0, y0) = (gore - RAMP_RUN, -RAMP_DROP);
        // Lanes lie right of an edge's line: the ramp's lane ends just right of the freeway's
        // right lane (in line with the acceleration lane, or beside the junction).
        let y1 = -f64::from(self.lanes) * LANE_WIDTH;
        if !self.curved {
            return format!("{x0:.2},{y0:.2} {gore:.2},{y1:.2}");
        }
        let p = [
            (x0, y0),
            (x0 + 0.2 * RAMP_RUN, y0 + 0.9 * (y1 - y0)),
            (gore - 0.5 * RAMP_RUN, y1),
            (gore, y1),
        ];
        (0..=16)
            .map(|k| {
                let t = f64::from(k) / 16.0;
                let m = 1.0 - t;
                let w = [m * m * m, 3.0 * m * m * t, 3.0 * m * t * t, t * t * t];
                let (x, y) = (0..4).fold((0.0, 0.0), |(x, y), i| (x + w[i] * p[i].0, y + w[i] * p[i].1));
                format!("{x:.2},{y:.2}")
            })
            .collect::<Vec<_>>()
            .join(" ")
    }

    fn connections(&self) -> String {
        let (pieces, ramps) = self.layout();
        let mut links = Vec::new();
        let into = |gore: &str| {
            pieces
                .iter()
                .position(|p| p.from == gore)
                .expect("a piece leaves each gore")
        };
        for Ramp { id: ramp, gore, .. } in &ramps {
            let next = into(gore);
            let (before, after) = (&pieces[next - 1].id, &pieces[next].id);
            match self.form {
                BuiltForm::Acceleration => {
                    let out = &pieces[next + 1].id;
                    for k in 0..self.lanes {
                        links.push((before.clone(), after.clone(), k, k + 1));
                        links.push((after.clone(), out.clone(), k + 1, k));
                    }
                    links.push((ramp.clone(), after.clone(), 0, 0));
                }
                BuiltForm::Junction => {
                    for k in 0..self.lanes {
                        links.push((before.clone(), after.clone(), k, k));
                    }
                    links.push((ramp.clone(), after.clone(), 0, 0));
                }
                BuiltForm::LaneDrop => {
                    for k in 0..self.lanes {
                        links.push((before.clone(), after.clone(), k + 1, k));
                    }
                    links.push((before.clone(), after.clone(), 0, 0));
                }
            }
        }
        let items: String = links
            .iter()
            .map(|(from, to, a, b)| {
                format!("  <connection from=\"{from}\" to=\"{to}\" fromLane=\"{a}\" toLane=\"{b}\"/>\n")
            })
            .collect();
        format!("<connections>\n{items}</connections>\n")
    }

    fn routes(&self) -> String {
        let dropped = u32::from(self.form == BuiltForm::LaneDrop);
        let flow = |id: String, ty: &str, from: &str, lane: u32, per_hour: f64, pos: &str| {
            format!(
                "  <flow id=\"{id}\" type=\"{ty}\" begin=\"0\" end=\"{end}\" vehsPerHour=\"{per_hour:.0}\" \
                 from=\"{from}\" to=\"out\" departLane=\"{lane}\" departSpeed=\"max\"{pos}/>\n",
                end = self.duration
            )
        };
        let mut flows = String::new();
        for k in 0..self.lanes {
            flows += &flow(format!("main{k}"), "human", "in", k + dropped, self.lane_flow, "");
        }
        // The dropped lane's vehicles appear DROP_INSERT before its end: SUMO's drivers leave
        // a lane that ends as soon as they can, so only late ones are still on it there.
        if self.form == BuiltForm::LaneDrop {
            let pos = format!(" departPos=\"{:.1}\"", (self.upstream - DROP_INSERT).max(0.0));
            flows += &flow("ramp".into(), "ramp_mix", "in", 0, self.ramp_flow, &pos);
        } else {
            for Ramp { id, .. } in self.layout().1 {
                flows += &flow(id.clone(), "ramp_mix", &id, 0, self.ramp_flow, "");
            }
        }
        // Ramp vehicles draw their type from `ramp_mix`: all controllable, as SUMO reads the file;
        // `mpgdrive routes --controllable-share` sets another share, as for i80_merge.
        let car = "length=\"5\" minGap=\"2\" accel=\"2.6\" decel=\"4.5\" sigma=\"0.5\"";
        format!(
            "<routes>\n  <vType id=\"human\" {car}/>\n  <vTypeDistribution id=\"ramp_mix\">\n    \
             <vType id=\"ctrl\" {car} probability=\"1.0\"/>\n    <vType id=\"human_ramp\" {car} probability=\"0.0\"/>\n  \
             </vTypeDistribution>\n{flows}</routes>\n"
        )
    }
}

/// One freeway edge of a built network.
struct Piece {
    id: String,
    from: String,
    to: String,
    lanes: u32,
}

/// One on-ramp of a built network: its edge, the node it ends at, and that node's x (m).
struct Ramp {
    id: String,
    gore: String,
    x: f64,
}

/// A lane drop's vehicles on the dropped lane appear this far before its end (m).
const DROP_INSERT: f64 = 100.0;
/// Lane width (m).
const LANE_WIDTH: f64 = 3.5;
/// The ramp starts this far before the gore along x, and this far to the right (m).
const RAMP_RUN: f64 = 250.0;
/// See [`RAMP_RUN`].
const RAMP_DROP: f64 = 60.0;

/// The SUMO configuration of a built network: 0.1 s steps (the policies' `sim.dt`).
const SUMOCFG: &str = "<configuration>\n  <input>\n    <net-file value=\"merge.net.xml\"/>\n    \
    <route-files value=\"merge.rou.xml\"/>\n  </input>\n  <time>\n    <step-length value=\"0.1\"/>\n  \
    </time>\n</configuration>\n";
