//! NGSIM loading (both official layouts, the real sample) and Savitzky-Golay smoothing against
//! scipy.

mod common;

use common::real_sample;
use mpgdrive::ngsim::load::{FOOT, NgsimError, load};
use mpgdrive::ngsim::smooth::{savgol, savgol_segments};
use std::path::{Path, PathBuf};

fn temp(name: &str, text: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ngsim");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn savitzky_golay_matches_scipy_interp_mode() {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/sgolay.json"))
            .unwrap();
    let fixture: serde_json::Value = serde_json::from_str(&text).unwrap();
    let input: Vec<f64> = serde_json::from_value(fixture["input"].clone()).unwrap();
    for case in fixture["cases"].as_array().unwrap() {
        let (w, p) = (
            case["window"].as_u64().unwrap() as usize,
            case["order"].as_u64().unwrap() as usize,
        );
        let expected: Vec<f64> = serde_json::from_value(case["output"].clone()).unwrap();
        let ours = savgol(&input, w, p).unwrap();
        let worst = ours
            .iter()
            .zip(&expected)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "window {w}, order {p}: worst difference {worst}");
    }
}

#[test]
fn savitzky_golay_keeps_polynomials_short_series_and_refuses_bad_windows() {
    // A cubic is its own least-squares cubic: unchanged everywhere, edges included.
    let cubic: Vec<f64> = (0..30)
        .map(|i| 0.01 * f64::from(i).powi(3) - f64::from(i))
        .collect();
    let out = savgol(&cubic, 9, 3).unwrap();
    assert!(out.iter().zip(&cubic).all(|(a, b)| (a - b).abs() < 1e-9));
    // Two cubic pieces with a hole between them (frames 0..29, then 100..129, 500 m further):
    // piece by piece each is kept; one window across the hole would blend them.
    let frames: Vec<u32> = (0..30).chain(100..130).collect();
    let y: Vec<f64> = cubic
        .iter()
        .copied()
        .chain(cubic.iter().map(|v| v + 500.0))
        .collect();
    let pieces = savgol_segments(&frames, &y, 9, 3).unwrap();
    assert!(pieces.iter().zip(&y).all(|(a, b)| (a - b).abs() < 1e-9));
    assert!(
        savgol(&y, 9, 3)
            .unwrap()
            .iter()
            .zip(&y)
            .any(|(a, b)| (a - b).abs() > 1.0)
    );
    // Shorter than the window: left as it is.
    assert_eq!(savgol(&[1.0, 5.0, 2.0], 5, 2).unwrap(), vec![1.0, 5.0, 2.0]);
    assert!(savgol(&cubic, 10, 3).is_err());
    assert!(savgol(&cubic, 5, 5).is_err());
}

const FHWA: &str = "\
 2  13  437  1113433136100  16.467  35.381  6451137.641  1873344.809  14.5  4.9  2  40.00  0.00  2  0  0  0.00  0.00
 2  14  437  1113433136200  16.447  39.381  6451137.641  1873348.809  14.5  4.9  2  40.00  0.00  2  0  0  0.00  0.00
 3  14  600  1113433136200  6.0  20.0  0  0  15.0  6.0  2  30.00  1.00  7  2  0  20.0  1.0
 2  12  437  1113433136000  16.467  31.381  6451137.641  1873340.809  14.5  4.9  2  40.00  0.00  2  0  0  0.00  0.00
 3  x  600  1113433136200  6.0  20.0  0  0  15.0  6.0  2  30.00  1.00  7  2  0  20.0  1.0
 3  15  600
";

#[test]
fn the_fhwa_text_layout_loads_in_metres_sorted_per_vehicle() {
    let t = load(&temp("fhwa.txt", FHWA), "i-80").unwrap();
    assert_eq!(t.rows, 4);
    assert_eq!(t.skipped, 2);
    assert_eq!(t.skipped_examples.iter().map(|e| e.0).collect::<Vec<_>>(), [5, 6]);
    assert!(
        t.skipped_examples[0].1.contains("Frame_ID"),
        "{:?}",
        t.skipped_examples
    );
    let two = &t.vehicles[&2];
    assert_eq!(two.iter().map(|r| r.frame).collect::<Vec<_>>(), [12, 13, 14]);
    // 31.381 ft = 9.5649 m; 40 ft/s = 12.192 m/s; 14.5 ft = 4.4196 m.
    assert!((two[0].local_y - 9.564_928_8).abs() < 1e-9);
    assert!((two[0].speed - 12.192).abs() < 1e-12 && (two[0].length - 4.4196).abs() < 1e-12);
    let three = &t.vehicles[&3][0];
    assert_eq!((three.lane, three.preceding), (7, 2));
}

#[test]
fn the_csv_layout_filters_its_location_and_refuses_foreign_files() {
    let csv = "Vehicle_ID,Frame_ID,Total_Frames,Global_Time,Local_X,Local_Y,Global_X,Global_Y,v_length,v_Width,v_Class,v_Vel,v_Acc,Lane_ID,O_Zone,D_Zone,Int_ID,Section_ID,Direction,Movement,Preceding,Following,Space_Headway,Time_Headway,Location\n\
        5,100,10,0,6.0,100.0,0,0,15,6,2,30,0,7,,,,,,,0,0,0,0,i-80\n\
        5,100,10,0,6.0,100.0,0,0,15,6,2,30,0,7,,,,,,,0,0,0,0,us-101\n";
    let t = load(&temp("data.csv", csv), "i-80").unwrap();
    assert_eq!((t.rows, t.vehicles.len()), (1, 1));
    assert!((t.vehicles[&5][0].local_y - 30.48).abs() < 1e-12);
    match load(&temp("data2.csv", csv), "peachtree") {
        Err(e @ NgsimError::NoRows { .. }) => assert!(e.to_string().contains("other locations"), "{e}"),
        other => panic!("{other:?}"),
    }
    match load(&temp("wrong.txt", "1 2 3 4\n"), "i-80") {
        Err(e @ NgsimError::Layout { .. }) => assert!(e.to_string().contains("4 columns"), "{e}"),
        other => panic!("{other:?}"),
    }
    match load(&temp("wrong.csv", "a,b,c\n1,2,3\n"), "i-80") {
        Err(e @ NgsimError::Layout { .. }) => assert!(e.to_string().contains("Vehicle_ID"), "{e}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_real_sample_loads_and_smoothing_barely_moves_its_reconstructed_traces() {
    // ../shared/data/ngsim: 142 vehicles, 68,339 rows, lanes 1-3, already smooth (EMD).
    let Some(path) = real_sample() else {
        return;
    };
    let t = load(&path, "i-80").unwrap();
    assert_eq!((t.vehicles.len(), t.rows, t.skipped), (142, 68_339, 0));
    let first = &t.vehicles[&47][0];
    // The file's first row: Local_Y 72.703 ft, v_Vel 11.94 ft/s.
    assert!((first.local_y - 72.703 * FOOT).abs() < 1e-12 && (first.speed - 11.94 * FOOT).abs() < 1e-12);
    assert!(
        t.vehicles
            .values()
            .all(|rows| rows.windows(2).all(|w| w[0].frame < w[1].frame))
    );
    assert!(t.vehicles.values().flatten().all(|r| (1..=3).contains(&r.lane)));
    // Three vehicles have holes in their frames (398: frames 1632 -> 1719, 211 m apart).
    let gapped: Vec<u32> = t
        .vehicles
        .iter()
        .filter(|(_, rows)| rows.windows(2).any(|w| w[1].frame != w[0].frame + 1))
        .map(|(&id, _)| id)
        .collect();
    assert_eq!(gapped, [398, 1175, 1350]);
    // A 2.1 s window, cubic, piece by piece: an already smooth trace moves by centimetres.
    let (mut worst, mut sum_sq, mut n) = (0.0f64, 0.0, 0usize);
    for rows in t.vehicles.values() {
        let y: Vec<f64> = rows.iter().map(|r| r.local_y).collect();
        let frames: Vec<u32> = rows.iter().map(|r| r.frame).collect();
        for (a, b) in y.iter().zip(savgol_segments(&frames, &y, 21, 3).unwrap()) {
            worst = worst.max((a - b).abs());
            sum_sq += (a - b).powi(2);
            n += 1;
        }
    }
    let rms = (sum_sq / n as f64).sqrt();
    eprintln!("sample: largest change {worst:.4} m, rms {rms:.5} m");
    assert!(worst < 0.1 && rms < 0.01, "largest {worst} m, rms {rms} m");
}

#[test]
fn regression_fuzz_lanes_of_far_off_or_nan_lateral_positions_do_not_overflow() {
    let ngsim = mpgdrive::ngsim::config::NgsimConfig::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/ngsim.toml"),
    )
    .unwrap();
    let lanes = &ngsim.lanes;
    let before_ramp_end = lanes.ramp_end - 1.0;
    // 0 m is lane 1, one and a half lane widths lane 2; far right is the ramp before its end and the
    // right-most freeway lane after it; far left (and NaN) lane 1.
    assert_eq!(lanes.lane_at(0.0, before_ramp_end), 1);
    assert_eq!(lanes.lane_at(1.5 * lanes.width, before_ramp_end), 2);
    assert_eq!(lanes.lane_at(1e300, before_ramp_end), lanes.ramp_lane());
    assert_eq!(lanes.lane_at(1e300, lanes.ramp_end + 1.0), lanes.target_lane());
    assert_eq!(lanes.lane_at(-1e300, 0.0), 1);
    assert_eq!(lanes.lane_at(f64::NAN, 0.0), 1);
}
