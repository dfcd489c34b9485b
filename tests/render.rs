//! Pictures and reports: the world-to-pixel mapping by hand, pixels where vehicles and the
//! conflict point are, every output decoding as an image, and the report commands.

mod common;

use common::{bin, car, fresh_dir, scene};
use image::AnimationDecoder;
use mpgdrive::render::charts::{Panel, Series, mean_band, panels_png};
use mpgdrive::render::scene::{Layout, episode_gif, frame_png, key_steps};
use mpgdrive::render::timespace::{
    CONFLICT_POINT, DiagramLayout, Mark, Road, SSM_MARK, Sample, TimeSpace, speed_color, timespace_png,
};
use mpgdrive::report::{Block, Document};

fn layout() -> Layout {
    // 1560 px of drawing for 156 m: exactly 10 px per metre.
    Layout {
        conflict_point: 180.0,
        lane_width: 3.66,
        vehicle: (5.0, 2.0),
        size: (1600, 200),
        span: 156.0,
        dt: 0.1,
    }
}

#[test]
fn the_view_maps_metres_to_pixels_at_one_scale() {
    let l = layout();
    let v = l.view(100.0);
    assert_eq!(v.scale, 10.0);
    // Top of the road (y = +w/2) sits 40 px of header plus half the free height below:
    // (200 - 40 - 2 * 36.6) / 2 = 43.4 -> 43.
    assert_eq!(v.to_px(100.0, 1.83), (20, 83));
    assert_eq!(v.to_px(115.5, -1.83), (175, 120)); // 15.5 m right, one lane (36.6 px) down
    assert_eq!(v.to_px(100.0, -5.49), (20, 156)); // the ramp's outer edge: 73.2 px down
    // Vehicles at 100-140 m and x_c = 180 m fit with it (195 - 100 + 20 <= 156): centred.
    let s = scene(vec![car(100.0, 10.0, true), car(140.0, 10.0, false)]);
    assert_eq!(l.x_min(&s), 0.5 * (100.0 + 195.0) - 78.0);
    // Spread over more than the span: the camera follows the rear, 10 m behind it.
    let wide = scene(vec![car(0.0, 10.0, true), car(150.0, 10.0, false)]);
    assert_eq!(l.x_min(&wide), -10.0);
    assert_eq!(key_steps(300, Some(100), 0.1), [0, 90, 120]);
    assert_eq!(key_steps(300, None, 0.1), [0, 150, 300]);
    assert_eq!(key_steps(105, Some(100), 0.1), [0, 90, 105]);
}

#[test]
fn frames_draw_vehicles_and_the_conflict_point_where_the_view_puts_them() {
    let dir = fresh_dir("render-frame");
    let l = layout();
    let s = scene(vec![
        car(120.0, 10.0, true),
        car(150.0, 12.0, false),
        car(110.0, 9.0, false),
    ]);
    let path = dir.join("frame.png");
    frame_png(&path, &l, &s, 7, "test").unwrap();
    let img = image::open(&path).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (1600, 200));
    let v = l.view(l.x_min(&s));
    let at = |x: f64, y: f64| {
        let (px, py) = v.to_px(x, y);
        img.get_pixel(px as u32, py as u32).0
    };
    assert_eq!(at(120.0, -3.66), [214, 39, 40]); // the ego, red, on the ramp
    assert_eq!(at(121.5, -3.66), [214, 39, 40]); // 1.5 m ahead of its centre: still the ego
    assert_ne!(at(123.0, -3.66), [214, 39, 40]); // 3 m ahead: past its 2.5 m half-length
    assert_eq!(at(150.0, 0.0), [31, 119, 180]); // player 1, blue, in the target lane
    assert_eq!(at(180.0, -1.0), [230, 140, 0]); // the conflict point line
    assert_eq!(at(140.0, 0.0), [92, 92, 98]); // asphalt between vehicles
    assert!(
        !dir.read_dir()
            .unwrap()
            .any(|e| e.unwrap().file_name().to_string_lossy().contains(".tmp."))
    );
}

#[test]
fn animations_and_charts_decode_as_images() {
    let dir = fresh_dir("render-anim");
    let scenes: Vec<_> = (0..20)
        .map(|k| {
            scene(vec![
                car(100.0 + k as f64, 10.0, true),
                car(130.0 + k as f64, 10.0, false),
            ])
        })
        .collect();
    let gif = dir.join("episode.gif");
    episode_gif(&gif, &layout(), &scenes, 5, 100, "test").unwrap();
    let file = std::io::BufReader::new(std::fs::File::open(&gif).unwrap());
    let frames = image::codecs::gif::GifDecoder::new(file)
        .unwrap()
        .into_frames()
        .collect_frames()
        .unwrap();
    assert_eq!(frames.len(), 4); // steps 0, 5, 10, 15
    assert_eq!(frames[0].buffer().dimensions(), (1600, 200));

    let band = mean_band(
        "two seeds",
        &[vec![(1.0, 1.0), (2.0, 3.0)], vec![(1.0, 3.0), (2.0, 5.0)]],
    );
    assert_eq!(band.points, [(1.0, 2.0), (2.0, 4.0)]);
    assert_eq!(band.band, [(1.0, 1.0, 3.0), (2.0, 3.0, 5.0)]);
    let chart = dir.join("chart.png");
    let panel = Panel {
        title: "t".into(),
        x_label: "x".into(),
        y_label: "y".into(),
    };
    panels_png(&chart, (600, 400), &[(panel.clone(), vec![band])]).unwrap();
    assert_eq!(image::open(&chart).unwrap().to_rgb8().dimensions(), (600, 400));
    let empty = Series {
        label: String::new(),
        points: vec![(0.0, f64::NAN)],
        band: Vec::new(),
    };
    assert!(panels_png(&dir.join("nothing.png"), (600, 400), &[(panel, vec![empty])]).is_err());
    assert!(!dir.join("nothing.png").exists());

    // A report embeds every image; its Markdown points at them relatively.
    let mut doc = Document::default();
    doc.push(Block::Heading(1, "R".into()))
        .push(Block::Table("| a | b |\n|---|---|\n| 1 | <2> |\n".into()))
        .push(Block::Image(chart.clone(), "a chart".into()));
    let (md, html) = doc.write(&dir, "R").unwrap();
    let md = std::fs::read_to_string(md).unwrap();
    let html = std::fs::read_to_string(html).unwrap();
    assert!(md.contains("![a chart](chart.png)"), "{md}");
    assert!(html.contains("<td>&lt;2&gt;</td>") && html.contains("src=\"data:image/png;base64,iVBORw0KGgo"));
    assert!(!html.contains("src=\"http") && !html.contains("src=\"chart.png"));
}

#[test]
fn scenario_and_report_commands_write_their_pictures() {
    let dir = fresh_dir("render-cli");
    let o = bin()
        .args([
            "scenario",
            "--config",
            "configs/smoke.toml",
            "--preset",
            "2",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "preset2_initial.png",
        "preset2_before.png",
        "preset2_after.png",
        "preset2_timeseries.png",
    ] {
        image::open(dir.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
    }
    assert!(dir.join("preset2.gif").is_file() && dir.join("preset2.json").is_file());
    // The outcome names the players the ego merged between (none when it did not merge).
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("preset2.json")).unwrap()).unwrap();
    match record["merged_at_step"].as_u64() {
        None => assert!(record["merged_between"].is_null(), "{record}"),
        Some(_) => {
            let pair = record["merged_between"].as_array().unwrap();
            assert_eq!(pair.len(), 2);
            assert!(pair.iter().all(|p| p.as_u64().unwrap() <= 8), "{record}");
        }
    }
    // The described states: every seed's episodes, each counted where it merged.
    let o = bin()
        .args([
            "scenario",
            "--config",
            "configs/smoke.toml",
            "--preset",
            "2",
            "--states",
            "3",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("preset2_states.json")).unwrap()).unwrap();
    let (seeds, summaries) = (
        record["seeds"].as_array().unwrap(),
        record["summaries"].as_array().unwrap(),
    );
    assert_eq!(
        (
            seeds.len(),
            summaries.len(),
            record["states"].as_array().unwrap().len()
        ),
        (5, 5, 3)
    );
    for (seed, summary) in seeds.iter().zip(summaries) {
        let episodes = seed["episodes"].as_array().unwrap();
        let paper = episodes
            .iter()
            .filter(|e| e["merged_between"] == serde_json::json!([5, 6]) && e["collision"] == false)
            .count();
        assert_eq!(
            (summary["states"].as_u64(), summary["paper_outcomes"].as_u64()),
            (Some(3), Some(paper as u64))
        );
    }
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("| seed | paper's outcome |") && stdout.contains("of 5 seeds merge"),
        "{stdout}"
    );
    let bad = bin()
        .args(["scenario", "--preset", "3", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));

    let report = dir.join("report");
    let o = bin()
        .args([
            "report",
            "--config",
            "configs/smoke.toml",
            "--cosim",
            "/nonexistent",
            "--ngsim",
            "/nonexistent",
            "--out",
        ])
        .arg(&report)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(report.join("report.html")).unwrap();
    // 2 scenarios x 5 pictures, Figures 7 and 8, testing returns (+ training returns when the
    // curves record them).
    let images = html.matches("<img src=\"data:image/").count();
    assert!((13..=14).contains(&images), "{images} images");
    assert!(
        html.contains("Statistical results: MARL with MPGs")
            && html.contains("Not included: no co-simulation")
    );
}

/// A target-lane car at 10 m/s from 100 m before the conflict point for 20 s, and a ramp ego
/// held 20 m before it for 10 s, recorded every 0.1 s.
fn merge_trace() -> TimeSpace {
    let mut ts = TimeSpace::new(0.1);
    for k in 0..=200 {
        let t = f64::from(k) / 10.0;
        let car = Sample {
            t,
            s: -100.0 + 10.0 * t,
            v: 10.0,
            marked: false,
        };
        ts.record("car", Road::Target, car);
        if k <= 100 {
            let ego = Sample {
                t,
                s: -20.0,
                v: 0.0,
                marked: true,
            };
            ts.record("ego", Road::Ramp, ego);
        }
    }
    ts
}

#[test]
fn time_space_records_split_tracks_and_locate_vehicles() {
    let mut ts = merge_trace();
    assert_eq!(ts.tracks.len(), 2);
    let mark = ts.locate("car", 5.04).unwrap();
    assert_eq!((mark.road, mark.t), (Road::Target, 5.0));
    assert!((mark.s + 50.0).abs() < 1e-9);
    assert_eq!(ts.locate("ego", 99.0).unwrap().t, 10.0); // the last sample is the nearest
    assert!(ts.locate("nobody", 1.0).is_none());
    // A gap of more than one step, or another road, begins a new track.
    let at = |t: f64, s: f64| Sample {
        t,
        s,
        v: 5.0,
        marked: false,
    };
    ts.record("ego", Road::Ramp, at(10.3, -19.0));
    ts.record("ego", Road::Target, at(10.4, 1.0));
    ts.record("ego", Road::Target, at(10.5, 1.5));
    assert_eq!(ts.tracks.len(), 4);
    assert_eq!(ts.tracks[3].samples.len(), 2);
    assert_eq!(ts.locate("ego", 10.45).unwrap().road, Road::Target);
}

#[test]
fn time_space_diagrams_put_each_vehicle_at_its_time_and_distance() {
    let dir = fresh_dir("render-timespace");
    let mut ts = merge_trace();
    ts.collisions.push(Mark {
        road: Road::Target,
        t: 15.0,
        s: 50.0,
    });
    ts.conflicts.push(Mark {
        road: Road::Ramp,
        t: 2.0,
        s: -20.0,
    });
    let layout = DiagramLayout::fit(&[&ts], (1600, 900));
    // Time to the last sample; distances rounded out to 10 m plus 10 m (the ramp's range
    // includes the conflict point); speeds up to 10 m/s rounded up to 5.
    assert_eq!(layout.t, (0.0, 20.0));
    assert_eq!(layout.target, (-110.0, 110.0));
    assert_eq!(layout.ramp, (-30.0, 10.0));
    assert_eq!(layout.v_max, 10.0);
    // 1400 px of time (70 px/s) from column 80; the target panel's 469 px hold 220 m from
    // row 84, the ramp panel's 235 px hold 40 m from row 84 + 469 + 56 = 609.
    let (target, ramp) = (layout.view(Road::Target), layout.view(Road::Ramp));
    assert_eq!(target.to_px(5.0, -50.0), (430, 425)); // 469 * 160 / 220 = 341.1 rows down
    assert_eq!(target.to_px(15.0, 50.0), (1130, 212)); // 469 * 60 / 220 = 127.9
    assert_eq!(ramp.to_px(5.0, -20.0), (430, 785)); // 235 * 30 / 40 = 176.25
    assert_eq!(ramp.to_px(0.0, 0.0), (80, 668)); // 235 * 10 / 40 = 58.75

    let path = dir.join("timespace.png");
    timespace_png(&path, &layout, &ts, "test", "driven").unwrap();
    let img = image::open(&path).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (1600, 900));
    let px = |(x, y): (i32, i32)| img.get_pixel(x as u32, y as u32).0;
    let rgb = |c: plotters::style::RGBColor| [c.0, c.1, c.2];
    assert_eq!(rgb(speed_color(10.0, 10.0)), [30, 150, 60]); // top of the scale: green
    assert_eq!(rgb(speed_color(0.0, 10.0)), [200, 30, 30]); // stopped: red
    assert_eq!(px((430, 425)), [30, 150, 60]); // the car at 5 s, 50 m before x_c
    assert_eq!(px((430, 415)), [255, 255, 255]); // 10 rows up: nothing there then
    assert_eq!(px((1130, 212)), [0, 0, 0]); // the collision's cross over the car at 15 s
    assert_eq!(px((430, 785)), [200, 30, 30]); // the waiting ego, red
    assert_eq!(px((430, 786 + 1)), [20, 20, 20]); // under it, its dark outline
    assert_eq!(px((430, 795)), [255, 255, 255]);
    assert_eq!(px((84, 668)), rgb(CONFLICT_POINT)); // the conflict point, dashed
    let (x, y) = ramp.to_px(2.0, -20.0);
    assert_eq!(px((x, y - 5)), rgb(SSM_MARK)); // the SSM conflict's triangle, at its apex
}

#[test]
fn reports_include_time_space_diagrams_and_batch_charts() {
    use mpgdrive::batch::plots::batch_plots;
    use mpgdrive::batch::summary::{RunMetrics, RunResult, write_summary};
    let dir = fresh_dir("render-batch");
    // A batch of 2 demand levels x 2 seeds x 2 controllers, results written by hand.
    let runs = dir.join("batch/runs");
    std::fs::create_dir_all(&runs).unwrap();
    let mut results = Vec::new();
    for (controller, speed) in [("mpg", 8.0), ("sumo", 13.0)] {
        for demand in [0.8, 1.2] {
            for seed in [0u64, 1] {
                let key = format!("d{demand}_s{seed}__{controller}");
                let r = RunResult {
                    key: key.clone(),
                    route_file: format!("d{demand}_s{seed}.rou.xml").into(),
                    demand: Some(demand),
                    controllable_share: None,
                    controller: controller.into(),
                    seed,
                    status: "ok".into(),
                    error: None,
                    version: "test".into(),
                    sumo_version: None,
                    command: Vec::new(),
                    wall_seconds: 1.0,
                    metrics: Some(RunMetrics {
                        egos: 10,
                        unfinished: 0,
                        collisions: 0,
                        failures: 0,
                        mean_speed: speed - demand + seed as f64,
                        mean_abs_accel: 1.0,
                        mean_abs_jerk: 1.0,
                        sumo_collisions: 0,
                        mean_time_loss: Some(5.0 * demand),
                        vehicle_seconds: 100.0,
                        ssm_conflict_egos: Some(seed as usize),
                    }),
                };
                std::fs::write(
                    runs.join(format!("{key}.json")),
                    serde_json::to_string(&r).unwrap(),
                )
                .unwrap();
                results.push(r);
            }
        }
    }
    write_summary(&results, &dir.join("batch")).unwrap();
    let charts = batch_plots(&results, &dir.join("batch")).unwrap();
    let names: Vec<String> = charts
        .iter()
        .map(|(p, _)| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    // Demand is swept, the controllable share is not.
    assert_eq!(
        names,
        [
            "batch_demand_speed.png",
            "batch_demand_time_loss.png",
            "batch_demand_conflict_share.png",
            "batch_demand_collision_rate.png"
        ]
    );
    let summary = std::fs::read_to_string(dir.join("batch/summary.csv")).unwrap();
    // mpg at demand 0.8: speeds 7.2 and 8.2 over the two seeds, conflict shares 0 and 0.1.
    assert!(
        summary.contains("mpg,0.80,2,20,0,0.000000,0.000000,0.000000,0.000000,7.700000,0.707107,"),
        "{summary}"
    );
    assert!(summary.contains(",0.050000,0.070711,\n"), "{summary}");

    // A co-simulation folder with its table and one diagram.
    let cosim = dir.join("cosim");
    std::fs::create_dir_all(&cosim).unwrap();
    std::fs::write(
        cosim.join("cosim.md"),
        "| Metric | mpg |\n|---|---|\n| Egos | 1 |\n",
    )
    .unwrap();
    std::fs::write(cosim.join("cosim.json"), "[]").unwrap();
    let ts = merge_trace();
    let layout = DiagramLayout::fit(&[&ts], (800, 450));
    timespace_png(&cosim.join("timespace_mpg.png"), &layout, &ts, "t", "driven").unwrap();

    let report = dir.join("report");
    let o = bin()
        .args([
            "report",
            "--config",
            "configs/smoke.toml",
            "--ngsim",
            "/nonexistent",
            "--cosim",
        ])
        .arg(&cosim)
        .arg("--batch")
        .arg(dir.join("batch"))
        .arg("--out")
        .arg(&report)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(report.join("report.md")).unwrap();
    assert!(
        md.contains("![Time-space diagram of the mpg controller](figures/timespace_mpg.png)"),
        "{md}"
    );
    assert!(md.contains("## Batch co-simulation") && md.contains("figures/batch_demand_speed.png"));
    assert!(report.join("figures/batch_demand_collision_rate.png").is_file());

    // A --batch folder without a summary is refused before any work.
    let o = bin()
        .args([
            "report",
            "--config",
            "configs/smoke.toml",
            "--batch",
            "/nonexistent",
            "--out",
        ])
        .arg(dir.join("refused"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no summary.md"));
    assert!(!dir.join("refused").exists());
}
