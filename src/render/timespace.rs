//! Time-space diagrams of a merge: every vehicle's distance to the conflict point against
//! time, one panel for the target lane and one for the ramp (acceleration lane included),
//! each vehicle a line coloured by its speed, the vehicles a controller drives drawn thick with
//! a dark outline, collisions and SSM conflicts marked, the conflict point dashed.
//!
//! A [`TimeSpace`] is recorded step by step (the co-simulation controller records one per
//! run); [`DiagramLayout::fit`] gives several diagrams one scale (time, distance and speed), so
//! that controllers compare side by side; [`timespace_png`] draws one.

use crate::atomic;
use crate::render::{FONT, RenderError, draw_error, register_font};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::collections::HashMap;
use std::path::Path;

/// The lanes a sample lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Road {
    /// The target lane (and the lanes continuing it).
    Target,
    /// The ramp and its acceleration lane.
    Ramp,
}

/// One vehicle at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Simulation time (s).
    pub t: f64,
    /// Distance past the conflict point (m; negative before it).
    pub s: f64,
    /// Speed (m/s).
    pub v: f64,
    /// Driven by the controller at this time (drawn thick, outlined).
    pub marked: bool,
}

/// One vehicle's uninterrupted stretch on one road.
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    /// Vehicle id.
    pub id: String,
    /// Road.
    pub road: Road,
    /// Samples in time order.
    pub samples: Vec<Sample>,
}

/// A marked event.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mark {
    /// Road of the vehicle it is drawn on.
    pub road: Road,
    /// Time (s).
    pub t: f64,
    /// Distance past the conflict point (m).
    pub s: f64,
}

/// The record of one run: tracks, collisions and SSM conflicts.
#[derive(Debug, Clone, Default)]
pub struct TimeSpace {
    /// Tracks in the order they began.
    pub tracks: Vec<Track>,
    /// Collisions, at the colliding vehicle.
    pub collisions: Vec<Mark>,
    /// SSM conflicts, at the equipped vehicle, at the time of its worst measure.
    pub conflicts: Vec<Mark>,
    /// A new track begins after a gap longer than this (s).
    gap: f64,
    /// Each vehicle's tracks (indices into `tracks`, in time order).
    by_id: HashMap<String, Vec<usize>>,
}

impl TimeSpace {
    /// An empty record for samples every `dt` seconds.
    pub fn new(dt: f64) -> Self {
        TimeSpace {
            gap: 1.5 * dt,
            ..TimeSpace::default()
        }
    }

    /// Records vehicle `id` at one time (times increase from call to call). A change of road
    /// or a gap of more than one step starts a new track.
    pub fn record(&mut self, id: &str, road: Road, sample: Sample) {
        let tracks = &mut self.tracks;
        let entry = self.by_id.entry(id.to_owned()).or_default();
        if let Some(&k) = entry.last() {
            let track = &mut tracks[k];
            let last = track.samples.last().map_or(f64::NEG_INFINITY, |p| p.t);
            if track.road == road && sample.t - last <= self.gap {
                track.samples.push(sample);
                return;
            }
        }
        entry.push(tracks.len());
        tracks.push(Track {
            id: id.to_owned(),
            road,
            samples: vec![sample],
        });
    }

    /// Where vehicle `id` was at the recorded time nearest to `t`, if it was recorded.
    pub fn locate(&self, id: &str, t: f64) -> Option<Mark> {
        self.by_id
            .get(id)?
            .iter()
            .flat_map(|&k| {
                let track = &self.tracks[k];
                let i = track.samples.partition_point(|p| p.t < t);
                [i.checked_sub(1), Some(i)]
                    .into_iter()
                    .flatten()
                    .filter_map(move |i| track.samples.get(i).map(|p| (track.road, *p)))
            })
            .min_by(|a, b| (a.1.t - t).abs().total_cmp(&(b.1.t - t).abs()))
            .map(|(road, p)| Mark { road, t: p.t, s: p.s })
    }

    fn samples(&self, road: Road) -> impl Iterator<Item = &Sample> {
        self.tracks
            .iter()
            .filter(move |k| k.road == road)
            .flat_map(|k| &k.samples)
    }
}

/// Pixel mapping of one panel: time to the right, distance up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PanelView {
    /// Pixel column of `t.0`.
    pub left: i32,
    /// Pixel row of `s.1`.
    pub top: i32,
    /// Width of the plotting area (px): `t.1` is at `left + width`.
    pub width: i32,
    /// Height of the plotting area (px): `s.0` is at `top + height`.
    pub height: i32,
    /// Time range (s).
    pub t: (f64, f64),
    /// Distance range (m).
    pub s: (f64, f64),
}

impl PanelView {
    /// Pixel of time `t` and distance `s`.
    pub fn to_px(&self, t: f64, s: f64) -> (i32, i32) {
        let fx = (t - self.t.0) / (self.t.1 - self.t.0);
        let fy = (self.s.1 - s) / (self.s.1 - self.s.0);
        (
            self.left + (fx * f64::from(self.width)).round() as i32,
            self.top + (fy * f64::from(self.height)).round() as i32,
        )
    }
}

/// What every diagram of a comparison shares: picture size and the scales.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiagramLayout {
    /// Picture size (px).
    pub size: (u32, u32),
    /// Time range (s).
    pub t: (f64, f64),
    /// Distance range of the target-lane panel (m).
    pub target: (f64, f64),
    /// Distance range of the ramp panel (m).
    pub ramp: (f64, f64),
    /// Speed at the top of the colour scale (m/s).
    pub v_max: f64,
}

const LEFT: i32 = 80;
const RIGHT: i32 = 120;
const TOP: i32 = 84;
const BOTTOM: i32 = 56;
const GAP: i32 = 56;

/// Rounds `x` down (`up` false) or up to a multiple of `step`.
fn snap(x: f64, step: f64, up: bool) -> f64 {
    let q = x / step;
    step * if up { q.ceil() } else { q.floor() }
}

impl DiagramLayout {
    /// One layout for all of `diagrams`: time from 0 to the last sample, each panel's distances
    /// over every sample on its road (rounded out to 10 m, the conflict point always inside),
    /// speeds up to the fastest sample (rounded up to 5 m/s).
    pub fn fit(diagrams: &[&TimeSpace], size: (u32, u32)) -> Self {
        let range = |road: Road| {
            let (lo, hi) = diagrams
                .iter()
                .flat_map(|d| d.samples(road))
                .fold((0.0f64, 0.0f64), |(lo, hi), p| (lo.min(p.s), hi.max(p.s)));
            (snap(lo, 10.0, false) - 10.0, snap(hi, 10.0, true) + 10.0)
        };
        let all = || {
            diagrams
                .iter()
                .flat_map(|d| d.samples(Road::Target).chain(d.samples(Road::Ramp)))
        };
        let t_end = all().map(|p| p.t).fold(0.0, f64::max);
        let v_max = all().map(|p| p.v).fold(0.0, f64::max);
        DiagramLayout {
            size,
            t: (0.0, if t_end > 0.0 { t_end } else { 1.0 }),
            target: range(Road::Target),
            ramp: range(Road::Ramp),
            v_max: snap(v_max, 5.0, true).max(5.0),
        }
    }

    /// The pixel mapping of a panel: the target lane above (two thirds of the height), the
    /// ramp below.
    pub fn view(&self, road: Road) -> PanelView {
        let free = self.size.1 as i32 - TOP - BOTTOM - GAP;
        let target_h = free * 2 / 3;
        let width = self.size.0 as i32 - LEFT - RIGHT;
        match road {
            Road::Target => PanelView {
                left: LEFT,
                top: TOP,
                width,
                height: target_h,
                t: self.t,
                s: self.target,
            },
            Road::Ramp => PanelView {
                left: LEFT,
                top: TOP + target_h + GAP,
                width,
                height: free - target_h,
                t: self.t,
                s: self.ramp,
            },
        }
    }
}

/// The colour of speed `v` on a scale to `v_max`: red (stopped) through yellow to green.
pub fn speed_color(v: f64, v_max: f64) -> RGBColor {
    const STOPS: [(f64, f64, f64); 3] = [(200.0, 30.0, 30.0), (240.0, 200.0, 40.0), (30.0, 150.0, 60.0)];
    let f = (v / v_max).clamp(0.0, 1.0) * 2.0;
    let k = (f.floor() as usize).min(1);
    let w = f - k as f64;
    let (a, b) = (STOPS[k], STOPS[k + 1]);
    let mix = |x: f64, y: f64| (x + (y - x) * w).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Colour of the conflict point line.
pub const CONFLICT_POINT: RGBColor = RGBColor(230, 140, 0);
/// Colour of the SSM conflict markers.
pub const SSM_MARK: RGBColor = RGBColor(170, 0, 170);
const OUTLINE: RGBColor = RGBColor(20, 20, 20);
const GRID: RGBColor = RGBColor(232, 232, 232);

/// A tick step of 1, 2 or 5 times a power of ten giving about `n` intervals over `span`.
fn tick_step(span: f64, n: f64) -> f64 {
    let raw = span / n;
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * p)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * p)
}

fn ticks((lo, hi): (f64, f64), n: f64) -> Vec<f64> {
    let step = tick_step(hi - lo, n);
    let mut v = snap(lo, step, true);
    let mut out = Vec::new();
    while v <= hi + 1e-9 {
        out.push(if v.abs() < 1e-9 { 0.0 } else { v });
        v += step;
    }
    out
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;
type DrawResult = Result<(), DrawingAreaErrorKind<<BitMapBackend<'static> as DrawingBackend>::ErrorType>>;

fn text<'a>(root: &Area<'a>, s: &str, at: (i32, i32), size: u32, pos: Pos) -> DrawResult {
    root.draw(&Text::new(
        s.to_owned(),
        at,
        (FONT, size).into_font().color(&BLACK).pos(pos),
    ))
}

fn frame<'a>(root: &Area<'a>, v: &PanelView, caption: &str, x_label: bool) -> DrawResult {
    let (right, bottom) = (v.left + v.width, v.top + v.height);
    for t in ticks(v.t, 10.0) {
        let (x, _) = v.to_px(t, v.s.0);
        root.draw(&PathElement::new(vec![(x, v.top), (x, bottom)], GRID))?;
        root.draw(&PathElement::new(vec![(x, bottom), (x, bottom + 5)], BLACK))?;
        text(
            root,
            &format!("{t:.0}"),
            (x, bottom + 8),
            13,
            Pos::new(HPos::Center, VPos::Top),
        )?;
    }
    for s in ticks(v.s, 5.0) {
        let (_, y) = v.to_px(v.t.0, s);
        root.draw(&PathElement::new(vec![(v.left, y), (right, y)], GRID))?;
        root.draw(&PathElement::new(vec![(v.left - 5, y), (v.left, y)], BLACK))?;
        text(
            root,
            &format!("{s:.0}"),
            (v.left - 8, y),
            13,
            Pos::new(HPos::Right, VPos::Center),
        )?;
    }
    root.draw(&Rectangle::new([(v.left, v.top), (right, bottom)], BLACK))?;
    text(
        root,
        caption,
        (v.left, v.top - 6),
        15,
        Pos::new(HPos::Left, VPos::Bottom),
    )?;
    let mid = v.top + v.height / 2;
    root.draw(&Text::new(
        "distance to x_c (m)".to_owned(),
        (16, mid),
        (FONT, 13)
            .into_font()
            .transform(FontTransform::Rotate270)
            .color(&BLACK)
            .pos(Pos::new(HPos::Center, VPos::Top)),
    ))?;
    if x_label {
        text(
            root,
            "time (s)",
            (v.left + v.width / 2, bottom + 28),
            14,
            Pos::new(HPos::Center, VPos::Top),
        )?;
    }
    Ok(())
}

/// The points of a track worth drawing at this scale: the first, the last, and each one that
/// moves to another pixel (one per pixel column and row is enough).
fn thin(view: &PanelView, samples: &[Sample]) -> Vec<((i32, i32), Sample)> {
    let mut out: Vec<((i32, i32), Sample)> = Vec::new();
    for (k, p) in samples.iter().enumerate() {
        let px = view.to_px(p.t, p.s);
        let moved = out
            .last()
            .is_none_or(|(q, last)| *q != px || last.marked != p.marked);
        if moved || k + 1 == samples.len() {
            out.push((px, *p));
        }
    }
    out
}

fn tracks<'a>(root: &Area<'a>, layout: &DiagramLayout, diagram: &TimeSpace, road: Road) -> DrawResult {
    let view = layout.view(road);
    let thinned: Vec<Vec<((i32, i32), Sample)>> = diagram
        .tracks
        .iter()
        .filter(|k| k.road == road)
        .map(|k| thin(&view, &k.samples))
        .collect();
    // Unmarked vehicles first, then the marked stretches on top (outline, then colour).
    for pass in 0..3 {
        for pts in &thinned {
            for w in pts.windows(2) {
                let ((a, _), (b, p)) = (w[0], w[1]);
                let marked = w[0].1.marked && p.marked;
                let style = match (pass, marked) {
                    (0, false) => speed_color(p.v, layout.v_max).stroke_width(1),
                    (1, true) => OUTLINE.stroke_width(4),
                    (2, true) => speed_color(p.v, layout.v_max).stroke_width(2),
                    _ => continue,
                };
                root.draw(&PathElement::new(vec![a, b], style))?;
            }
        }
    }
    let (x0, y0) = view.to_px(view.t.0, 0.0);
    let (x1, _) = view.to_px(view.t.1, 0.0);
    let mut x = x0;
    while x < x1 {
        root.draw(&PathElement::new(
            vec![(x, y0), ((x + 8).min(x1), y0)],
            CONFLICT_POINT.stroke_width(1),
        ))?;
        x += 14;
    }
    for m in diagram.conflicts.iter().filter(|m| m.road == road) {
        let (x, y) = view.to_px(m.t, m.s);
        let corners = vec![(x, y - 5), (x - 4, y + 3), (x + 4, y + 3), (x, y - 5)];
        root.draw(&Polygon::new(corners.clone(), SSM_MARK.mix(0.35).filled()))?;
        root.draw(&PathElement::new(corners, SSM_MARK.stroke_width(1)))?;
    }
    for m in diagram.collisions.iter().filter(|m| m.road == road) {
        let (x, y) = view.to_px(m.t, m.s);
        for (dx, dy) in [(8, 8), (8, -8)] {
            root.draw(&PathElement::new(
                vec![(x - dx, y - dy), (x + dx, y + dy)],
                BLACK.stroke_width(3),
            ))?;
        }
    }
    Ok(())
}

fn colour_bar<'a>(root: &Area<'a>, layout: &DiagramLayout) -> DrawResult {
    let v = layout.view(Road::Target);
    let (x, top, h) = (v.left + v.width + 30, v.top, v.height);
    for k in 0..h {
        let speed = layout.v_max * f64::from(h - 1 - k) / f64::from(h - 1);
        root.draw(&PathElement::new(
            vec![(x, top + k), (x + 16, top + k)],
            speed_color(speed, layout.v_max),
        ))?;
    }
    root.draw(&Rectangle::new([(x, top), (x + 16, top + h)], BLACK))?;
    let mut speed = 0.0;
    while speed <= layout.v_max + 1e-9 {
        let y = top + ((1.0 - speed / layout.v_max) * f64::from(h - 1)).round() as i32;
        text(
            root,
            &format!("{speed:.0}"),
            (x + 22, y),
            12,
            Pos::new(HPos::Left, VPos::Center),
        )?;
        speed += 5.0;
    }
    text(
        root,
        "speed (m/s)",
        (x - 4, top - 6),
        13,
        Pos::new(HPos::Left, VPos::Bottom),
    )
}

fn legend<'a>(root: &Area<'a>, marked: &str) -> DrawResult {
    let y = 46;
    let mut x = LEFT;
    root.draw(&PathElement::new(
        vec![(x, y), (x + 28, y)],
        OUTLINE.stroke_width(4),
    ))?;
    root.draw(&PathElement::new(
        vec![(x, y), (x + 28, y)],
        speed_color(0.5, 1.0).stroke_width(2),
    ))?;
    text(root, marked, (x + 34, y), 13, Pos::new(HPos::Left, VPos::Center))?;
    x += 34 + 7 * marked.len() as i32 + 24;
    root.draw(&Polygon::new(
        vec![(x + 6, y - 7), (x, y + 4), (x + 12, y + 4)],
        SSM_MARK.mix(0.35).filled(),
    ))?;
    text(
        root,
        "SSM conflict (TTC < 3 s or DRAC > 3 m/s^2)",
        (x + 18, y),
        13,
        Pos::new(HPos::Left, VPos::Center),
    )?;
    x += 330;
    for (dx, dy) in [(6, 6), (6, -6)] {
        root.draw(&PathElement::new(
            vec![(x + 6 - dx, y - dy), (x + 6 + dx, y + dy)],
            BLACK.stroke_width(3),
        ))?;
    }
    text(
        root,
        "collision",
        (x + 18, y),
        13,
        Pos::new(HPos::Left, VPos::Center),
    )?;
    x += 100;
    root.draw(&PathElement::new(vec![(x, y), (x + 8, y)], CONFLICT_POINT))?;
    root.draw(&PathElement::new(vec![(x + 14, y), (x + 22, y)], CONFLICT_POINT))?;
    text(
        root,
        "conflict point x_c",
        (x + 28, y),
        13,
        Pos::new(HPos::Left, VPos::Center),
    )
}

/// Draws `diagram` as a PNG (written to a temporary name, then renamed): `title` on top, the
/// legend naming the thick, outlined lines `marked`.
pub fn timespace_png(
    path: &Path,
    layout: &DiagramLayout,
    diagram: &TimeSpace,
    title: &str,
    marked: &str,
) -> Result<(), RenderError> {
    register_font();
    let err = draw_error(path);
    let draw = |tmp: &Path| {
        let root = BitMapBackend::new(tmp, layout.size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        text(&root, title, (LEFT, 8), 18, Pos::new(HPos::Left, VPos::Top)).map_err(|e| err(&e))?;
        legend(&root, marked).map_err(|e| err(&e))?;
        for (road, caption, x_label) in [
            (Road::Target, "target lane", false),
            (Road::Ramp, "ramp and acceleration lane", true),
        ] {
            frame(&root, &layout.view(road), caption, x_label).map_err(|e| err(&e))?;
            tracks(&root, layout, diagram, road).map_err(|e| err(&e))?;
        }
        colour_bar(&root, layout).map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))
    };
    atomic::write_with(path, draw, |e| err(&e))
}
