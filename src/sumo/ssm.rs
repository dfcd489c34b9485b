//! SUMO's SSM output read as the conflicts the metrics count: an encounter whose minimum TTC is
//! below [`TTC_THRESHOLD`] or whose maximum DRAC is above [`DRAC_THRESHOLD`] (the thresholds
//! `cosim` gives SUMO).
//!
//! SSM's own "collision" (encounter type [`COLLISION_TYPE`], TTC 0) is not a conflict here: SSM
//! infers it when both vehicles are inside the conflict area it draws around a merge's or a
//! crossing's lanes, and near a junction that area is wider than the lanes. On a curved
//! junction merge (the zoo's `junction-v30-curved`) a ramp vehicle standing at its stop line,
//! its side 1.7 m from a car passing at 32 m/s, was such a "collision" with TTC 0 in 9 of 10 of
//! a run's severe conflicts, under SUMO's drivers and the game alike (SUMO's issues 7411 and
//! 13918 report the same false positives). Whether vehicles touch is SUMO's collision check's
//! call (on, with junctions, in every `cosim` run), and the metrics count its collisions.

/// SSM conflicts are encounters with a minimum TTC below this (s)...
pub const TTC_THRESHOLD: f64 = 3.0;

/// ...or a maximum deceleration to avoid a crash above this (m/s^2).
pub const DRAC_THRESHOLD: f64 = 3.0;

/// SSM's encounter type for a collision it infers (`ENCOUNTER_TYPE_COLLISION`).
pub const COLLISION_TYPE: &str = "111";

/// One extreme of an encounter: its value and when it occurred (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extreme {
    /// The value (s for TTC, m/s^2 for DRAC).
    pub value: f64,
    /// The simulation time it occurred at (s); none where SUMO wrote none.
    pub time: Option<f64>,
}

/// One conflict of one equipped vehicle (SSM logs an encounter once per equipped party).
#[derive(Debug, Clone, PartialEq)]
pub struct Conflict {
    /// The equipped vehicle.
    pub ego: String,
    /// Its minimum TTC, where SUMO measured one that is not an inferred collision.
    pub min_ttc: Option<Extreme>,
    /// Its maximum DRAC, where SUMO measured one.
    pub max_drac: Option<Extreme>,
}

impl Conflict {
    /// Whether its minimum TTC is below `ttc` (s).
    pub fn ttc_below(&self, ttc: f64) -> bool {
        self.min_ttc.is_some_and(|m| m.value < ttc)
    }
}

/// The conflicts of an SSM output file's text, in file order.
pub fn conflicts(text: &str) -> Result<Vec<Conflict>, roxmltree::Error> {
    let doc = roxmltree::Document::parse(text)?;
    Ok(doc
        .descendants()
        .filter(|n| n.has_tag_name("conflict"))
        .filter_map(|c| {
            let extreme = |tag: &str| {
                let n = c.children().find(|n| n.has_tag_name(tag))?;
                let num = |k: &str| n.attribute(k).and_then(|v| v.parse::<f64>().ok());
                let value = num("value").filter(|v| v.is_finite())?;
                let inferred_collision = n.attribute("type") == Some(COLLISION_TYPE);
                (!inferred_collision).then_some(Extreme {
                    value,
                    time: num("time"),
                })
            };
            let conflict = Conflict {
                ego: c.attribute("ego")?.to_owned(),
                min_ttc: extreme("minTTC"),
                max_drac: extreme("maxDRAC"),
            };
            let drac_above = conflict.max_drac.is_some_and(|d| d.value > DRAC_THRESHOLD);
            (conflict.ttc_below(TTC_THRESHOLD) || drac_above).then_some(conflict)
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encounter(ego: &str, ttc: &str, ttc_type: &str, drac: &str) -> String {
        format!(
            r#"<conflict begin="1.0" end="9.0" ego="{ego}" foe="x">
                <minTTC time="2.5" position="0,0" type="{ttc_type}" value="{ttc}"/>
                <maxDRAC time="3.5" position="0,0" type="3" value="{drac}"/>
            </conflict>"#
        )
    }

    #[test]
    fn an_inferred_collision_is_no_conflict_and_the_thresholds_decide_the_rest() {
        let text = format!(
            "<SSMLog>{}{}{}{}{}</SSMLog>",
            // A ramp vehicle standing at its stop line beside a passing car: SSM's "collision".
            encounter("standing", "0.00", "111", "0.04"),
            // The same type, but the encounter braked someone hard: a conflict by its DRAC.
            encounter("braked", "0.00", "111", "4.20"),
            // A merging follower closing in.
            encounter("merging", "1.17", "7", "7.93"),
            // Logged, but inside neither threshold.
            encounter("calm", "3.40", "2", "0.50"),
            encounter("unmeasured", "NA", "NA", "3.10"),
        );
        let c = conflicts(&text).unwrap();
        let egos: Vec<&str> = c.iter().map(|c| c.ego.as_str()).collect();
        assert_eq!(egos, ["braked", "merging", "unmeasured"]);
        assert_eq!(c[0].min_ttc, None);
        assert_eq!(c[0].max_drac.map(|d| d.value), Some(4.2));
        let ttc = c[1].min_ttc.unwrap();
        assert_eq!((ttc.value, ttc.time), (1.17, Some(2.5)));
        assert!(c[1].ttc_below(1.5) && !c[2].ttc_below(1.5));
        assert!(conflicts("<SSMLog><conflict").is_err());
    }
}
