//! Merge geometry of a SUMO network (`sumo_nets/*/merge.toml`): where the conflict point is,
//! which lanes are the ramp and the target lane, which vehicle types mpgdrive may drive.
//!
//! Positions are distances along the lanes ([`crate::sumo::positions`]): the first target
//! lane starts at `target_start` (0 unless set), so any network shape works: curved ramps,
//! rotated or bending freeways.

use crate::config::{ConfigError, check, finite, load_toml, non_negative, parse_toml};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Which players of an ego's game the MPG policy drives besides the ego.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PlayerControl {
    /// Every player: the ego's eight (Table I policies), or every vehicle in the control zone
    /// (traffic policies): the game, everyone on the shared policy.
    All,
    /// Only players whose vehicle type is controllable (with traffic policies: inside the
    /// control zone). With no controllable freeway vehicles, the egos alone.
    Controllable,
}

/// One merge of `merge.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MergeGeometry {
    /// A name for results and diagrams (default: the first ramp lane's edge).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Position of the conflict point (m): on the acceleration lane.
    pub conflict_point: f64,
    /// A controllable ramp vehicle becomes an ego once its centre passes this position (m).
    pub control_from: f64,
    /// Control of a merged ego ends this far past the conflict point (m).
    pub release_after: f64,
    /// From this position on (m; on the acceleration lane) a ramp vehicle the policy drives
    /// changes to the target lane at the first gap the merge gate's entry check finds safe,
    /// and at the conflict point at the latest. Unset: at the conflict point, as the internal
    /// simulator merges.
    #[serde(default)]
    pub merge_from: Option<f64>,
    /// The desired speed a traffic policy observes (m/s). Unset: the speed limit of the
    /// target lane beside the acceleration lane. Either way within the range the policy was
    /// trained on (`traffic.desired_speed`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub desired_speed: Option<f64>,
    /// Lanes of the ramp, in driving order, the acceleration lane last (egos drive here before
    /// merging).
    pub ramp_lanes: Vec<String>,
    /// Lanes of the target lane, in driving order (players drive here; an ego merges into
    /// one).
    pub target_lanes: Vec<String>,
    /// Position of the start of the first target lane (m; default 0). The bundled networks
    /// set it so that positions are their network x (NGSIM's Local_Y on `i80_merge`).
    #[serde(default)]
    pub target_start: f64,
    /// Vehicle types mpgdrive may drive as egos.
    pub controllable_types: Vec<String>,
    /// Which players the MPG policy drives.
    pub players: PlayerControl,
}

/// A `merge.toml` with several merges: `[[merge]]` tables, each one merge.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct MergeList {
    merge: Vec<MergeGeometry>,
}

impl MergeGeometry {
    /// Reads and checks a `merge.toml` of one merge (its keys at the top level).
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let g: MergeGeometry = load_toml(path)?;
        g.validate()?;
        Ok(g)
    }

    /// Reads and checks a `merge.toml`: one merge (keys at the top level) or any number of
    /// `[[merge]]` tables. Two merges may not share a ramp lane, nor a name.
    pub fn load_all(path: &Path) -> Result<Vec<Self>, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.display().to_string(),
            source,
        })?;
        let origin = path.display().to_string();
        let several = text.parse::<toml::Table>().is_ok_and(|t| t.contains_key("merge"));
        let merges = if several {
            parse_toml::<MergeList>(&text, &origin)?.merge
        } else {
            vec![parse_toml::<MergeGeometry>(&text, &origin)?]
        };
        check("merge", !merges.is_empty(), "lists no merge".into())?;
        for (k, g) in merges.iter().enumerate() {
            g.validate().map_err(|e| match (several, e) {
                (true, ConfigError::Invalid { key, message }) => ConfigError::Invalid {
                    key: format!("merge[{}].{key}", k + 1),
                    message,
                },
                (_, e) => e,
            })?;
            for (j, h) in merges[..k].iter().enumerate() {
                if let Some(lane) = g.ramp_lanes.iter().find(|l| h.is_ramp(l)) {
                    return Err(ConfigError::Invalid {
                        key: format!("merge[{}].ramp_lanes", k + 1),
                        message: format!("lane `{lane}` is a ramp lane of merge {} too", j + 1),
                    });
                }
                check(
                    &format!("merge[{}].name", k + 1),
                    g.label() != h.label(),
                    format!("`{}` names merge {} too", g.label(), j + 1),
                )?;
            }
        }
        Ok(merges)
    }

    /// The merge's name in results: `name`, or the edge of its first ramp lane.
    pub fn label(&self) -> String {
        self.name.clone().unwrap_or_else(|| {
            let first = self.ramp_lanes.first().map_or("", String::as_str);
            split_lane_id(first).map_or(first, |(edge, _)| edge).to_owned()
        })
    }

    /// Range checks that need no network.
    pub fn validate(&self) -> Result<(), ConfigError> {
        finite("conflict_point", self.conflict_point)?;
        finite("control_from", self.control_from)?;
        non_negative("release_after", self.release_after)?;
        finite("target_start", self.target_start)?;
        if let Some(v) = self.desired_speed {
            finite("desired_speed", v)?;
            check("desired_speed", v > 0.0, format!("{v} must be positive"))?;
        }
        if let Some(from) = self.merge_from {
            finite("merge_from", from)?;
            check(
                "merge_from",
                from <= self.conflict_point,
                format!("{from} must not lie past conflict_point {}", self.conflict_point),
            )?;
        }
        check(
            "control_from",
            self.control_from < self.conflict_point,
            format!(
                "{} must lie before conflict_point {}",
                self.control_from, self.conflict_point
            ),
        )?;
        for (key, list) in [
            ("ramp_lanes", &self.ramp_lanes),
            ("target_lanes", &self.target_lanes),
            ("controllable_types", &self.controllable_types),
        ] {
            check(key, !list.is_empty(), "must not be empty".into())?;
        }
        // Each lane has one place on the road: listed once, as a ramp lane or a target lane.
        let lanes: Vec<&String> = self.ramp_lanes.iter().chain(&self.target_lanes).collect();
        if let Some(k) = (1..lanes.len()).find(|&k| lanes[..k].contains(&lanes[k])) {
            let key = if k < self.ramp_lanes.len() {
                "ramp_lanes"
            } else {
                "target_lanes"
            };
            return Err(ConfigError::Invalid {
                key: key.into(),
                message: format!(
                    "lane `{}` is listed twice in ramp_lanes and target_lanes (a lane has one place on the road)",
                    lanes[k]
                ),
            });
        }
        Ok(())
    }

    /// Checks every lane id against the network's lanes and names the ones that exist.
    pub fn check_lanes(&self, network_lanes: &[String]) -> Result<(), ConfigError> {
        for (key, list) in [
            ("ramp_lanes", &self.ramp_lanes),
            ("target_lanes", &self.target_lanes),
        ] {
            if let Some(bad) = list.iter().find(|l| !network_lanes.contains(l)) {
                let existing: Vec<&str> = network_lanes
                    .iter()
                    .filter(|l| !l.starts_with(':'))
                    .map(String::as_str)
                    .collect();
                return Err(ConfigError::Invalid {
                    key: key.into(),
                    message: format!(
                        "lane `{bad}` is not in the network; its lanes are: {}",
                        existing.join(", ")
                    ),
                });
            }
        }
        Ok(())
    }

    /// Whether a lane is a ramp lane.
    pub fn is_ramp(&self, lane: &str) -> bool {
        self.ramp_lanes.iter().any(|l| l == lane)
    }

    /// Whether a lane is a target lane.
    pub fn is_target(&self, lane: &str) -> bool {
        self.target_lanes.iter().any(|l| l == lane)
    }

    /// The target lane next to ramp lane `lane` on the same edge, and its index
    /// ([`lane_beside`]), if there is one.
    pub fn merge_lane(&self, lane: &str) -> Option<(String, i32)> {
        lane_beside(lane, |l| self.is_target(l))
    }
}

/// The lane of `lane`'s edge beside it for which `is_target` holds, and its index: the one to
/// its left (index + 1) first, else the one to its right (index - 1). An acceleration lane is
/// mostly the outer lane, but a ramp can join on the inner side (a left-hand on-ramp in
/// right-hand traffic, or an inner lane that ends).
pub fn lane_beside(lane: &str, is_target: impl Fn(&str) -> bool) -> Option<(String, i32)> {
    let (edge, index) = split_lane_id(lane)?;
    [index + 1, index - 1]
        .into_iter()
        .filter(|&i| i >= 0)
        .map(|i| (format!("{edge}_{i}"), i))
        .find(|(l, _)| is_target(l))
}

/// Splits a SUMO lane id `<edge>_<index>` into its edge and index.
pub fn split_lane_id(lane: &str) -> Option<(&str, i32)> {
    let (edge, index) = lane.rsplit_once('_')?;
    Some((edge, index.parse().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONE: &str = "conflict_point = 180.0\ncontrol_from = 60.0\nrelease_after = 50.0\n\
        ramp_lanes = [\"ramp_0\"]\ntarget_lanes = [\"main_0\", \"out_0\"]\n\
        controllable_types = [\"ctrl\"]\nplayers = \"controllable\"\n";

    fn load(text: &str) -> Result<Vec<MergeGeometry>, ConfigError> {
        static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let k = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir = crate::atomic::test_dir(&format!("merge-toml-{k}"));
        let path = dir.join("merge.toml");
        std::fs::write(&path, text).unwrap();
        let loaded = MergeGeometry::load_all(&path);
        std::fs::remove_dir_all(dir).unwrap();
        loaded
    }

    #[test]
    fn the_lane_beside_is_the_left_one_first_then_the_right_one() {
        let of = |lane: &str, targets: &[&str]| lane_beside(lane, |l| targets.contains(&l));
        assert_eq!(of("acc_0", &["acc_1"]), Some(("acc_1".into(), 1)));
        assert_eq!(of("acc_2", &["acc_1"]), Some(("acc_1".into(), 1)));
        assert_eq!(of("m_1", &["m_0", "m_2"]), Some(("m_2".into(), 2)));
        assert_eq!(of("acc_0", &["acc_2", "in_1"]), None);
        assert_eq!(of("no-index", &["no-index_1"]), None);
    }

    #[test]
    fn a_merge_toml_holds_one_merge_or_several_tables() {
        let one = load(ONE).unwrap();
        assert_eq!(one.len(), 1);
        assert_eq!(one[0].label(), "ramp");
        let other = ONE.replace("ramp_0", "ramp2_0").replace("180.0", "880.0");
        let two = load(&format!(
            "[[merge]]\n{ONE}\n[[merge]]\nname = \"second\"\n{other}"
        ))
        .unwrap();
        assert_eq!(two.len(), 2);
        assert_eq!(
            (two[0].label(), two[1].label()),
            ("ramp".to_owned(), "second".to_owned())
        );
        assert_eq!(two[1].conflict_point, 880.0);
        assert_eq!(two[0], one[0]);
    }

    #[test]
    fn merges_that_share_a_ramp_lane_or_a_name_or_break_a_rule_are_refused() {
        let err = load(&format!("[[merge]]\n{ONE}\n[[merge]]\n{ONE}"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("merge[2].ramp_lanes") && err.contains("`ramp_0`"),
            "{err}"
        );
        let other = ONE.replace("ramp_0", "ramp2_0");
        let err = load(&format!(
            "[[merge]]\nname = \"a\"\n{ONE}\n[[merge]]\nname = \"a\"\n{other}"
        ))
        .unwrap_err()
        .to_string();
        assert!(err.contains("merge[2].name"), "{err}");
        let bad = other.replace("control_from = 60.0", "control_from = 500.0");
        let err = load(&format!("[[merge]]\n{ONE}\n[[merge]]\n{bad}"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("merge[2].control_from"), "{err}");
        for (text, key) in [
            (
                ONE.replace("\"main_0\", \"out_0\"", "\"main_0\", \"ramp_0\""),
                "target_lanes",
            ),
            (
                ONE.replace("[\"ramp_0\"]", "[\"ramp_0\", \"ramp_0\"]"),
                "ramp_lanes",
            ),
        ] {
            let err = load(&text).unwrap_err().to_string();
            assert!(
                err.contains(key) && err.contains("`ramp_0` is listed twice"),
                "{err}"
            );
        }
        let err = load(&format!("[[merge]]\n{ONE}\nspeed = 3\n"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("speed"), "{err}");
        assert!(
            load("merge = []\n")
                .unwrap_err()
                .to_string()
                .contains("lists no merge")
        );
    }
}
