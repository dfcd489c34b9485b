//! Where along the merge vehicles drive slower or faster: their mean speed in bands of
//! [`BAND`] metres of distance to the conflict point, over every step they are recorded.
//!
//! A run's mean ego speed says how much a controller loses against SUMO's drivers; the egos'
//! profile says where (braking before the merge, merging slowly, or after it), and the target
//! lane's, in the same bands, what traffic they merge into. Each ego's band sums are kept
//! apart, so a run's ego profile, like its other metrics, is over its finished egos.

use serde::Serialize;
use std::collections::BTreeMap;

/// Width of a band (m).
pub const BAND: f64 = 20.0;

/// Speed sums per band: the key `k` is the band `[k BAND, (k + 1) BAND)` of the distance past
/// the conflict point (negative before it).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SpeedBands {
    sums: BTreeMap<i64, (f64, u64)>,
}

/// One band of a profile.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BandSpeed {
    /// Start of the band, distance past the conflict point (m; negative before it).
    pub from: f64,
    /// End of the band (m).
    pub to: f64,
    /// Mean speed over the steps in the band (m/s).
    pub mean_speed: f64,
    /// Steps counted.
    pub steps: u64,
}

impl SpeedBands {
    /// Counts one step at `s` metres past the conflict point at speed `v` (m/s).
    pub fn record(&mut self, s: f64, v: f64) {
        let entry = self.sums.entry((s / BAND).floor() as i64).or_default();
        entry.0 += v;
        entry.1 += 1;
    }

    /// Adds another record's steps to this one.
    pub fn add(&mut self, other: &SpeedBands) {
        for (&k, &(sum, n)) in &other.sums {
            let entry = self.sums.entry(k).or_default();
            entry.0 += sum;
            entry.1 += n;
        }
    }

    /// The bands with at least one step, from the first along the road.
    pub fn bands(&self) -> Vec<BandSpeed> {
        self.sums
            .iter()
            .map(|(&k, &(sum, n))| BandSpeed {
                from: k as f64 * BAND,
                to: (k + 1) as f64 * BAND,
                mean_speed: sum / n as f64,
                steps: n,
            })
            .collect()
    }
}

/// A Markdown table of the profiles of several runs, one column per run, over the bands any
/// of them has (`-` where a run has no step in a band).
pub fn markdown(names: &[&str], profiles: &[&[BandSpeed]]) -> String {
    let mut keys: Vec<(f64, f64)> = profiles
        .iter()
        .flat_map(|p| p.iter().map(|b| (b.from, b.to)))
        .collect();
    keys.sort_by(|a, b| a.0.total_cmp(&b.0));
    keys.dedup();
    let mut s = String::from("| Distance past the conflict point (m) |");
    for name in names {
        s += &format!(" {name} |");
    }
    s += "\n|---|";
    s += &"---|".repeat(names.len());
    s += "\n";
    for (from, to) in keys {
        s += &format!("| {from:.0} to {to:.0} |");
        for p in profiles {
            match p.iter().find(|b| b.from == from) {
                Some(b) => s += &format!(" {:.2} |", b.mean_speed),
                None => s += " - |",
            }
        }
        s += "\n";
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_fall_into_twenty_metre_bands_around_the_conflict_point() {
        let mut a = SpeedBands::default();
        // -25 and -20.5 lie in [-40, -20); -20 and -0.1 in [-20, 0); 0 in [0, 20).
        a.record(-25.0, 10.0);
        a.record(-20.5, 12.0);
        a.record(-20.0, 8.0);
        a.record(-0.1, 6.0);
        a.record(0.0, 9.0);
        let mut b = SpeedBands::default();
        b.record(-30.0, 14.0);
        a.add(&b);
        let bands = a.bands();
        assert_eq!(bands.len(), 3);
        assert_eq!((bands[0].from, bands[0].to, bands[0].steps), (-40.0, -20.0, 3));
        assert!((bands[0].mean_speed - 12.0).abs() < 1e-12); // (10 + 12 + 14) / 3
        assert_eq!((bands[1].from, bands[1].steps), (-20.0, 2));
        assert!((bands[1].mean_speed - 7.0).abs() < 1e-12); // (8 + 6) / 2
        assert_eq!((bands[2].from, bands[2].steps), (0.0, 1));
        assert!((bands[2].mean_speed - 9.0).abs() < 1e-12);
    }

    #[test]
    fn the_table_has_a_row_per_band_of_any_run_and_a_dash_where_a_run_has_none() {
        let mut a = SpeedBands::default();
        a.record(-10.0, 7.5);
        let mut b = SpeedBands::default();
        b.record(-10.0, 10.0);
        b.record(5.0, 11.0);
        let (pa, pb) = (a.bands(), b.bands());
        let table = markdown(&["mpg", "sumo"], &[&pa, &pb]);
        assert_eq!(
            table,
            "| Distance past the conflict point (m) | mpg | sumo |\n|---|---|---|\n\
             | -20 to 0 | 7.50 | 10.00 |\n| 0 to 20 | - | 11.00 |\n"
        );
    }
}
