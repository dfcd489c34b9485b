//! The merge section's capacity (`mpgdrive study --capacity`): SUMO's drivers alone on the
//! study's network over a sweep of demands, to find the flow at which the merge breaks down,
//! so that the game is judged near the physical limit, where a merge has delay to save.
//!
//! For each demand (a multiple of the base route file) and seed, one run of SUMO's drivers:
//! the **inflow** is the vehicles of the route file per hour of the run, the **outflow** the
//! vehicles that finished their trip per hour (every route of a merge network passes the
//! merge), the time loss as the study's ([`crate::batch::penetration`]). The merge **breaks
//! down** at the first demand of the sweep whose mean outflow rose by less than half of its
//! mean inflow's rise from the demand before ([`MARGINAL_SHARE`]): the extra vehicles no longer
//! get through, they queue. The **capacity** is the largest mean outflow of the sweep.

use crate::batch::penetration::{Quantity, Spread, StudyRun};

/// The merge has broken down where less than this share of a demand step's extra inflow comes
/// out as extra outflow.
pub const MARGINAL_SHARE: f64 = 0.5;

/// One run of the sweep: the demand, the route file's vehicles, and what SUMO gave.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRun {
    /// Demand, a multiple of the base route file.
    pub demand: f64,
    /// Vehicles in the route file.
    pub scheduled: usize,
    /// The run (SUMO's drivers alone).
    pub run: StudyRun,
}

/// One demand of the sweep, over seeds.
#[derive(Debug, Clone, PartialEq)]
pub struct DemandPoint {
    /// Demand, a multiple of the base route file.
    pub demand: f64,
    /// Vehicles scheduled per hour (veh/h).
    pub inflow: Spread,
    /// Vehicles that finished their trip per hour (veh/h).
    pub outflow: Spread,
    /// Mean time loss of every vehicle, insertion delay included (s).
    pub time_loss: Spread,
}

/// What the sweep found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capacity {
    /// The largest mean outflow of the sweep (veh/h).
    pub outflow: f64,
    /// The demand at which the merge breaks down, if it does within the sweep.
    pub breakdown: Option<f64>,
}

/// The sweep's demands in increasing order, each over its seeds.
pub fn points(runs: &[SweepRun]) -> Vec<DemandPoint> {
    let mut demands: Vec<f64> = runs.iter().map(|r| r.demand).collect();
    demands.sort_by(f64::total_cmp);
    demands.dedup();
    demands
        .into_iter()
        .map(|demand| {
            let at: Vec<&SweepRun> = runs.iter().filter(|r| r.demand == demand).collect();
            let of = |f: &dyn Fn(&SweepRun) -> Option<f64>| {
                Spread::of(&at.iter().filter_map(|r| f(r)).collect::<Vec<_>>())
            };
            DemandPoint {
                demand,
                inflow: of(&|r| Some(r.scheduled as f64 * 3600.0 / r.run.duration)),
                outflow: of(&|r| Quantity::Throughput.of(&r.run)),
                time_loss: of(&|r| Quantity::TimeLoss.of(&r.run)),
            }
        })
        .collect()
}

/// The capacity and the breakdown demand of a sweep (module docs).
pub fn capacity(points: &[DemandPoint]) -> Capacity {
    let breakdown = points.windows(2).find_map(|w| {
        let rise_in = w[1].inflow.mean - w[0].inflow.mean;
        let rise_out = w[1].outflow.mean - w[0].outflow.mean;
        (rise_out < MARGINAL_SHARE * rise_in).then_some(w[1].demand)
    });
    Capacity {
        outflow: points.iter().map(|p| p.outflow.mean).fold(0.0, f64::max),
        breakdown,
    }
}

/// The sweep as Markdown: a table by demand and what it found.
pub fn markdown(points: &[DemandPoint], found: &Capacity) -> String {
    let cell = |s: &Spread, d: usize| format!("{:.*} ± {:.*}", d, s.mean, d, s.sd);
    let mut md = String::from(
        "| demand | seeds | inflow (veh/h) | outflow (veh/h) | time loss of every vehicle (s) |\n|---|---|---|---|---|\n",
    );
    for p in points {
        md += &format!(
            "| {} | {} | {} | {} | {} |\n",
            p.demand,
            p.outflow.runs,
            cell(&p.inflow, 0),
            cell(&p.outflow, 0),
            cell(&p.time_loss, 2)
        );
    }
    md += &match (found.breakdown, points.last()) {
        (Some(d), _) => format!(
            "\nThe merge breaks down at demand {d} (less than {:.0}% of the step's extra inflow \
             came out); the largest outflow, its capacity, is {:.0} veh/h.\n",
            MARGINAL_SHARE * 100.0,
            found.outflow
        ),
        (None, Some(last)) => format!(
            "\nThe merge does not break down up to demand {} (largest outflow {:.0} veh/h).\n",
            last.demand, found.outflow
        ),
        (None, None) => String::new(),
    };
    md
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::batch::penetration::{Conflicts, Trips};

    fn run(demand: f64, scheduled: usize, arrived: usize, seed: u64) -> SweepRun {
        SweepRun {
            demand,
            scheduled,
            run: StudyRun {
                share: 0.0,
                seed,
                game: false,
                duration: 600.0,
                trips: Trips {
                    vehicles: scheduled,
                    arrived,
                    time_loss: 5.0 * scheduled as f64,
                    uncontrolled: scheduled,
                    uncontrolled_time_loss: 5.0 * scheduled as f64,
                    vehicle_km: 1.0,
                },
                conflicts: Conflicts::default(),
                ego_speed: None,
                controlled_collisions: 0,
            },
        }
    }

    #[test]
    fn the_merge_breaks_down_where_the_outflow_stops_following_the_inflow() {
        // 600 s runs: 100 vehicles are 600 veh/h. Demand 1: 600 in, 540 out. Demand 2: 1200
        // in, 1080 and 1020 out (mean 1050, sample sd sqrt(1800)): a rise of 510 for 600 in,
        // kept. Demand 3: 1800 in, 1200 out, a rise of 150 for 600: under half, broken down.
        let sweep = [
            run(1.0, 100, 90, 0),
            run(2.0, 200, 180, 0),
            run(2.0, 200, 170, 1),
            run(3.0, 300, 200, 0),
        ];
        let p = points(&sweep);
        assert_eq!(p.iter().map(|p| p.demand).collect::<Vec<_>>(), [1.0, 2.0, 3.0]);
        assert_eq!(
            (p[1].inflow.mean, p[1].outflow.mean, p[1].outflow.runs),
            (1200.0, 1050.0, 2)
        );
        assert!((p[1].outflow.sd - 1800.0_f64.sqrt()).abs() < 1e-9);
        let found = capacity(&p);
        assert_eq!(
            found,
            Capacity {
                outflow: 1200.0,
                breakdown: Some(3.0)
            }
        );
        assert!(markdown(&p, &found).contains("breaks down at demand 3"));
        // Without the last step nothing breaks down.
        let found = capacity(&p[..2]);
        assert_eq!(found.breakdown, None);
        assert!(markdown(&p[..2], &found).contains("does not break down up to demand 2"));
    }
}
