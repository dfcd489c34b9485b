//! Training curves: one CSV row per epoch (the paper's Figures 7 and 8 and the probe rates).

use std::path::Path;

/// Header of the curves CSV.
pub const HEADER: &str = "epoch,train_objective,probe_objective,action_msd,probe_collision_rate,probe_failure_rate,wall_seconds,probe_ego_return";

/// One epoch of training.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct EpochRecord {
    /// Epoch number, from 1.
    pub epoch: usize,
    /// Mean objective (potential for mpg, ego return for sarl) of the epoch's minibatch.
    pub train_objective: f64,
    /// Mean objective on the fixed probe set after the epoch's step.
    pub probe_objective: f64,
    /// Mean squared difference of the probe actions from the previous epoch (m^2/s^4).
    pub action_msd: f64,
    /// Probe episodes with an ego collision, as a fraction.
    pub probe_collision_rate: f64,
    /// Probe episodes where the ego failed to merge, as a fraction.
    pub probe_failure_rate: f64,
    /// Training wall time so far (s).
    pub wall_seconds: f64,
    /// Mean discounted return of the ego on the probe set (its total reward; the MARL and SARL
    /// curves compare on it). Not in curves written before it was added.
    pub probe_ego_return: Option<f64>,
}

/// Writes the curves atomically (temporary file, then rename).
pub fn write(path: &Path, records: &[EpochRecord]) -> std::io::Result<()> {
    let mut text = String::from(HEADER);
    text.push('\n');
    for r in records {
        text.push_str(&format!(
            "{},{},{},{},{},{},{:.3},{}\n",
            r.epoch,
            r.train_objective,
            r.probe_objective,
            r.action_msd,
            r.probe_collision_rate,
            r.probe_failure_rate,
            r.wall_seconds,
            r.probe_ego_return.map_or(String::new(), |v| v.to_string())
        ));
    }
    crate::atomic::write(path, text)
}

/// Reads curves written by [`write()`] (also those without the last column).
pub fn read(path: &Path) -> std::io::Result<Vec<EpochRecord>> {
    let bad = |line: usize| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("malformed curves row {line}"),
        )
    };
    let text = std::fs::read_to_string(path)?;
    let mut out = Vec::new();
    for (k, line) in text.lines().enumerate().skip(1) {
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != 7 && cells.len() != 8 {
            return Err(bad(k + 1));
        }
        let f: Vec<f64> = cells[..7]
            .iter()
            .map(|x| x.parse::<f64>().map_err(|_| bad(k + 1)))
            .collect::<Result<_, _>>()?;
        let ego = match cells.get(7) {
            None | Some(&"") => None,
            Some(x) => Some(x.parse::<f64>().map_err(|_| bad(k + 1))?),
        };
        out.push(EpochRecord {
            epoch: f[0] as usize,
            train_objective: f[1],
            probe_objective: f[2],
            action_msd: f[3],
            probe_collision_rate: f[4],
            probe_failure_rate: f[5],
            wall_seconds: f[6],
            probe_ego_return: ego,
        });
    }
    Ok(out)
}
