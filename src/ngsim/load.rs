//! Reading NGSIM trajectory files in both official layouts, streamed line by line:
//!
//! - the FHWA per-period text files (`trajectories-0400-0415.txt`): 18 whitespace-separated
//!   columns, no header;
//! - the data.transportation.gov CSV: a header row, extra columns (O_Zone, ..., Location), many
//!   locations (rows are kept when `Location` equals the requested one, case-insensitively).
//!
//! Feet become metres here (and ft/s, ft/s^2 become m/s, m/s^2); nothing past this module sees
//! feet. Rows are grouped per vehicle and sorted by Frame_ID. A malformed row is skipped and
//! counted (the first few are listed with their line numbers); a file whose columns do not
//! match either layout, or that has no usable row, is refused.

use std::collections::BTreeMap;
use std::io::BufRead;
use std::path::{Path, PathBuf};

/// Metres per foot.
pub const FOOT: f64 = 0.3048;

/// The 18 FHWA columns, in file order (also the CSV header names).
pub const COLUMNS: [&str; 18] = [
    "Vehicle_ID",
    "Frame_ID",
    "Total_Frames",
    "Global_Time",
    "Local_X",
    "Local_Y",
    "Global_X",
    "Global_Y",
    "v_Length",
    "v_Width",
    "v_Class",
    "v_Vel",
    "v_Acc",
    "Lane_ID",
    "Preceding",
    "Following",
    "Space_Headway",
    "Time_Headway",
];

/// One row, in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// Frame (0.1 s each).
    pub frame: u32,
    /// Lateral position of the front centre from the left road edge (m).
    pub local_x: f64,
    /// Longitudinal position of the front bumper from the upstream boundary (m).
    pub local_y: f64,
    /// Vehicle length (m).
    pub length: f64,
    /// Vehicle width (m).
    pub width: f64,
    /// 1 motorcycle, 2 auto, 3 truck.
    pub class: u8,
    /// Recorded speed (m/s).
    pub speed: f64,
    /// Recorded acceleration (m/s^2).
    pub accel: f64,
    /// Lane (1 = left-most; 7 = on-ramp at I-80).
    pub lane: u8,
    /// Preceding vehicle id (0: none).
    pub preceding: u32,
    /// Following vehicle id (0: none).
    pub following: u32,
}

/// A loaded file: rows per vehicle, each sorted by frame.
#[derive(Debug, Clone, Default)]
pub struct Trajectories {
    /// Vehicle id -> rows by frame.
    pub vehicles: BTreeMap<u32, Vec<Row>>,
    /// Rows kept.
    pub rows: usize,
    /// Rows skipped as malformed (or of another location in the CSV layout: not counted here).
    pub skipped: usize,
    /// The first skipped rows: (line number, reason).
    pub skipped_examples: Vec<(usize, String)>,
}

/// Errors that refuse a whole file.
#[derive(Debug, thiserror::Error)]
pub enum NgsimError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Neither layout.
    #[error(
        "{path}: line {line} has {found} columns; an NGSIM file has 18 (FHWA text) or a header naming {missing}"
    )]
    Layout {
        /// The file.
        path: PathBuf,
        /// First line.
        line: usize,
        /// Columns found.
        found: usize,
        /// What was missing.
        missing: String,
    },
    /// Nothing usable.
    #[error("{path}: no usable rows ({skipped} malformed{location})")]
    NoRows {
        /// The file.
        path: PathBuf,
        /// Malformed rows.
        skipped: usize,
        /// ", none at location X" in the CSV layout.
        location: String,
    },
}

const EXAMPLES: usize = 5;

fn parse_row(fields: &[&str], index: &[usize; 18]) -> Result<(u32, Row), String> {
    let f = |k: usize| fields.get(index[k]).copied().unwrap_or("");
    let num = |k: usize| -> Result<f64, String> {
        let v: f64 = f(k)
            .trim()
            .parse()
            .map_err(|_| format!("{} = {:?} is not a number", COLUMNS[k], f(k)))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{} = {v} is not finite", COLUMNS[k]))
        }
    };
    let int = |k: usize| -> Result<u32, String> {
        let v = num(k)?;
        if v >= 0.0 && v.fract() == 0.0 && v <= f64::from(u32::MAX) {
            Ok(v as u32)
        } else {
            Err(format!("{} = {v} is not a non-negative integer", COLUMNS[k]))
        }
    };
    let small = |k: usize| -> Result<u8, String> {
        let v = int(k)?;
        u8::try_from(v).map_err(|_| format!("{} = {v} is out of range", COLUMNS[k]))
    };
    Ok((
        int(0)?,
        Row {
            frame: int(1)?,
            local_x: num(4)? * FOOT,
            local_y: num(5)? * FOOT,
            length: num(8)? * FOOT,
            width: num(9)? * FOOT,
            class: small(10)?,
            speed: num(11)? * FOOT,
            accel: num(12)? * FOOT,
            lane: small(13)?,
            preceding: int(14)?,
            following: int(15)?,
        },
    ))
}

/// Reads an NGSIM file of either layout; in the CSV layout only rows whose `Location` equals
/// `location` (case-insensitive) are kept.
pub fn load(path: &Path, location: &str) -> Result<Trajectories, NgsimError> {
    let io = |source| NgsimError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let reader = std::io::BufReader::with_capacity(1 << 20, file);
    let mut out = Trajectories::default();
    let mut layout: Option<([usize; 18], Option<usize>, bool)> = None; // (index, location column, csv)
    let mut other_location = 0usize;
    for (n, line) in reader.lines().enumerate() {
        let line = line.map_err(io)?;
        let number = n + 1;
        if line.trim().is_empty() {
            continue;
        }
        let (index, loc_col, csv) = match layout {
            Some(l) => l,
            None => {
                let l = detect(path, number, &line)?;
                layout = Some(l);
                if l.2 {
                    continue; // the header
                }
                l
            }
        };
        let fields: Vec<&str> = if csv {
            line.split(',').collect()
        } else {
            line.split_whitespace().collect()
        };
        if let Some(c) = loc_col {
            match fields.get(c) {
                Some(l) if l.trim().eq_ignore_ascii_case(location) => {}
                Some(_) => {
                    other_location += 1;
                    continue;
                }
                None => {}
            }
        }
        let expected = if csv {
            index.iter().max().map_or(0, |m| m + 1)
        } else {
            18
        };
        let parsed = if fields.len() < expected || (!csv && fields.len() != 18) {
            Err(format!("{} columns", fields.len()))
        } else {
            parse_row(&fields, &index)
        };
        match parsed {
            Ok((id, row)) => {
                out.vehicles.entry(id).or_default().push(row);
                out.rows += 1;
            }
            Err(reason) => {
                out.skipped += 1;
                if out.skipped_examples.len() < EXAMPLES {
                    out.skipped_examples.push((number, reason));
                }
            }
        }
    }
    if out.rows == 0 {
        return Err(NgsimError::NoRows {
            path: path.to_path_buf(),
            skipped: out.skipped,
            location: if other_location > 0 {
                format!(", {other_location} rows at other locations than {location:?}")
            } else {
                String::new()
            },
        });
    }
    for rows in out.vehicles.values_mut() {
        rows.sort_by_key(|r| r.frame);
    }
    Ok(out)
}

/// The layout from the first non-empty line: a CSV header naming the 18 columns, or 18
/// whitespace-separated fields.
fn detect(
    path: &Path,
    line_number: usize,
    line: &str,
) -> Result<([usize; 18], Option<usize>, bool), NgsimError> {
    if line.contains(',') {
        let names: Vec<String> = line.split(',').map(|s| s.trim().to_ascii_lowercase()).collect();
        let mut index = [0usize; 18];
        for (k, col) in COLUMNS.iter().enumerate() {
            index[k] = names
                .iter()
                .position(|n| n == &col.to_ascii_lowercase())
                .ok_or_else(|| NgsimError::Layout {
                    path: path.to_path_buf(),
                    line: line_number,
                    found: names.len(),
                    missing: format!("the column {col}"),
                })?;
        }
        let location = names.iter().position(|n| n == "location");
        return Ok((index, location, true));
    }
    let found = line.split_whitespace().count();
    if found != 18 {
        return Err(NgsimError::Layout {
            path: path.to_path_buf(),
            line: line_number,
            found,
            missing: "Vehicle_ID, Frame_ID, ...".into(),
        });
    }
    Ok((std::array::from_fn(|k| k), None, false))
}
