//! Pictures and reports: the world-to-pixel mapping by hand, pixels where vehicles and the
//! conflict point are, every output decoding as an image, and the report commands.

mod common;

use common::{bin, car, fresh_dir, scene};
use image::AnimationDecoder;
use mpgdrive::render::charts::{Panel, Series, mean_band, panels_png};
use mpgdrive::render::scene::{Layout, episode_gif, frame_png, key_steps};
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
