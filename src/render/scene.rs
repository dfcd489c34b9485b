//! Top-down pictures of a merge, to scale, like the paper's figures: the target lane, the ramp
//! ending at the conflict point, each vehicle as its bounding box (rotated by its heading)
//! labelled with its player number and speed, the ego in red, a 10 m scale bar and the time.

use crate::atomic;
use crate::render::{FONT, RenderError, draw_error, register_font};
use crate::world::state::{Scene, player_label};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// World-to-pixel mapping with one scale on both axes (pictures are to scale).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// World x at the left edge of the drawing (m).
    pub x_min: f64,
    /// World y at the top edge of the drawing (m; y grows to the left of travel, up).
    pub y_max: f64,
    /// Pixels per metre.
    pub scale: f64,
    /// Pixel column of `x_min`.
    pub left: i32,
    /// Pixel row of `y_max`.
    pub top: i32,
}

impl View {
    /// Pixel of world point `(x, y)`: x to the right, y up.
    pub fn to_px(&self, x: f64, y: f64) -> (i32, i32) {
        (
            self.left + ((x - self.x_min) * self.scale).round() as i32,
            self.top + ((self.y_max - y) * self.scale).round() as i32,
        )
    }
}

/// What a frame shows besides the vehicles.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Conflict point (m).
    pub conflict_point: f64,
    /// Lane width (m).
    pub lane_width: f64,
    /// Vehicle box (m): length, width.
    pub vehicle: (f64, f64),
    /// Picture size (px).
    pub size: (u32, u32),
    /// Width of road shown (m).
    pub span: f64,
    /// Seconds per step (for the time label).
    pub dt: f64,
}

const MARGIN: i32 = 20;
const HEADER: i32 = 40;

impl Layout {
    /// The view for a frame whose left edge is world `x_min`: the scale fits `span` metres
    /// into the picture's width, the road (target lane and ramp) is centred vertically.
    pub fn view(&self, x_min: f64) -> View {
        let scale = f64::from(self.size.0 as i32 - 2 * MARGIN) / self.span;
        let road_px = 2.0 * self.lane_width * scale;
        let free = f64::from(self.size.1 as i32 - HEADER) - road_px;
        View {
            x_min,
            y_max: 0.5 * self.lane_width,
            scale,
            left: MARGIN,
            top: HEADER + (free / 2.0).round() as i32,
        }
    }

    /// The left edge that shows every vehicle of `scene`, and the conflict point when it fits
    /// too: centred on them if they fit in the span, else 10 m behind the rear-most vehicle
    /// (the camera follows the rear).
    pub fn x_min(&self, scene: &Scene) -> f64 {
        let (lo, hi) = extent(scene);
        let x_c = self.conflict_point;
        let (lo_c, hi_c) = (lo.min(x_c - 5.0), hi.max(x_c + 15.0));
        let (lo, hi) = if hi_c - lo_c + 20.0 <= self.span {
            (lo_c, hi_c)
        } else {
            (lo, hi)
        };
        if hi - lo + 20.0 <= self.span {
            0.5 * (lo + hi) - 0.5 * self.span
        } else {
            lo - 10.0
        }
    }
}

fn extent(scene: &Scene) -> (f64, f64) {
    scene
        .vehicles
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v.x), hi.max(v.x))
        })
}

/// The span (m) that shows every vehicle of every scene at one scale (and the conflict point
/// with them, when `conflict_point` is given): the largest spread plus 20 m, at least 120 m.
pub fn span_for(scenes: &[Scene], conflict_point: Option<f64>) -> f64 {
    scenes
        .iter()
        .map(|s| {
            let (lo, hi) = extent(s);
            let (lo, hi) = conflict_point.map_or((lo, hi), |x_c| (lo.min(x_c - 5.0), hi.max(x_c + 15.0)));
            hi - lo + 20.0
        })
        .fold(120.0, f64::max)
}

fn draw_frame<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    layout: &Layout,
    scene: &Scene,
    step: usize,
    title: &str,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let view = layout.view(layout.x_min(scene));
    let w = layout.lane_width;
    let x_max = view.x_min + layout.span;
    let x_c = layout.conflict_point;
    area.fill(&RGBColor(236, 240, 232))?;
    let asphalt = RGBColor(92, 92, 98);
    // Target lane over the whole view; the ramp up to the conflict point, then a taper.
    area.draw(&Rectangle::new(
        [view.to_px(view.x_min, 0.5 * w), view.to_px(x_max, -0.5 * w)],
        asphalt.filled(),
    ))?;
    if view.x_min < x_c {
        area.draw(&Rectangle::new(
            [
                view.to_px(view.x_min, -0.5 * w),
                view.to_px(x_c.min(x_max), -1.5 * w),
            ],
            asphalt.filled(),
        ))?;
        area.draw(&Polygon::new(
            vec![
                view.to_px(x_c, -0.5 * w),
                view.to_px(x_c, -1.5 * w),
                view.to_px(x_c + 15.0, -0.5 * w),
            ],
            asphalt.filled(),
        ))?;
    }
    let paint = WHITE.stroke_width(2);
    area.draw(&PathElement::new(
        vec![view.to_px(view.x_min, 0.5 * w), view.to_px(x_max, 0.5 * w)],
        paint,
    ))?;
    // Dashed line between the ramp and the target lane, up to the conflict point.
    let mut x = view.x_min - view.x_min.rem_euclid(6.0);
    while x < x_c.min(x_max) {
        area.draw(&PathElement::new(
            vec![view.to_px(x, -0.5 * w), view.to_px((x + 3.0).min(x_c), -0.5 * w)],
            WHITE.stroke_width(2),
        ))?;
        x += 6.0;
    }
    if (view.x_min..x_max).contains(&x_c) {
        let top = view.to_px(x_c, 0.5 * w + 1.0);
        let bottom = view.to_px(x_c, -1.5 * w - 1.0);
        area.draw(&PathElement::new(
            vec![top, bottom],
            RGBColor(230, 140, 0).stroke_width(3),
        ))?;
        area.draw(&Text::new(
            format!("conflict point x_c = {x_c:.0} m"),
            (bottom.0 + 6, bottom.1 - 2),
            (FONT, 14).into_font().color(&RGBColor(160, 90, 0)),
        ))?;
    }
    let (len, wid) = layout.vehicle;
    for (i, v) in scene.vehicles.iter().enumerate().rev() {
        let (c, s) = (v.phi.cos(), v.phi.sin());
        let corner = |a: f64, b: f64| view.to_px(v.x + a * c - b * s, v.y + a * s + b * c);
        let body = vec![
            corner(0.5 * len, 0.5 * wid),
            corner(-0.5 * len, 0.5 * wid),
            corner(-0.5 * len, -0.5 * wid),
            corner(0.5 * len, -0.5 * wid),
        ];
        let color = if i == 0 {
            RGBColor(214, 39, 40)
        } else {
            RGBColor(31, 119, 180)
        };
        area.draw(&Polygon::new(body.clone(), color.filled()))?;
        let mut outline = body;
        outline.push(outline[0]);
        area.draw(&PathElement::new(outline, BLACK.stroke_width(1)))?;
        // Labels outside the asphalt: above the road for target-lane vehicles, below the ramp
        // for ramp vehicles; the player number next to the road, the speed beyond it.
        let (px, _) = view.to_px(v.x, v.y);
        let (number_y, speed_y, v_pos) = if v.on_ramp {
            let edge = view.to_px(v.x, -1.5 * w).1;
            (edge + 3, edge + 18, VPos::Top)
        } else {
            let edge = view.to_px(v.x, 0.5 * w).1;
            (edge - 3, edge - 18, VPos::Bottom)
        };
        let anchor = Pos::new(HPos::Center, v_pos);
        area.draw(&Text::new(
            player_label(i),
            (px, number_y),
            (FONT, 13).into_font().color(&color).pos(anchor),
        ))?;
        area.draw(&Text::new(
            format!("{:.1}", v.v),
            (px, speed_y),
            (FONT, 11).into_font().color(&RGBColor(60, 60, 60)).pos(anchor),
        ))?;
    }
    // Scale bar and labels.
    let bar = view.to_px(view.x_min + 2.0, -1.5 * w);
    let (bx, by) = (bar.0, layout.size.1 as i32 - 12);
    let ten = (10.0 * view.scale).round() as i32;
    area.draw(&PathElement::new(
        vec![(bx, by), (bx + ten, by)],
        BLACK.stroke_width(3),
    ))?;
    area.draw(&Text::new("10 m", (bx + ten + 6, by - 7), (FONT, 12).into_font()))?;
    area.draw(&Text::new(
        format!("{title}   t = {:.1} s   speeds in m/s", step as f64 * layout.dt),
        (MARGIN, 10),
        (FONT, 16).into_font(),
    ))?;
    Ok(())
}

/// Draws one frame to a PNG file (written to a temporary name, then renamed).
pub fn frame_png(
    path: &Path,
    layout: &Layout,
    scene: &Scene,
    step: usize,
    title: &str,
) -> Result<(), RenderError> {
    register_font();
    let err = draw_error(path);
    let draw = |tmp: &Path| {
        let area = BitMapBackend::new(tmp, layout.size).into_drawing_area();
        draw_frame(&area, layout, scene, step, title).map_err(|e| err(&e))?;
        area.present().map_err(|e| err(&e))
    };
    atomic::write_with(path, draw, |e| err(&e))
}

/// Draws every `every`-th scene as an animated GIF (`delay_ms` per frame).
pub fn episode_gif(
    path: &Path,
    layout: &Layout,
    scenes: &[Scene],
    every: usize,
    delay_ms: u32,
    title: &str,
) -> Result<(), RenderError> {
    if scenes.is_empty() {
        return Err(RenderError::Empty(format!("{}: no frames", path.display())));
    }
    register_font();
    let err = draw_error(path);
    let draw = |tmp: &Path| {
        let area = BitMapBackend::gif(tmp, layout.size, delay_ms)
            .map_err(|e| err(&e))?
            .into_drawing_area();
        for (k, scene) in scenes.iter().enumerate().step_by(every.max(1)) {
            draw_frame(&area, layout, scene, k, title).map_err(|e| err(&e))?;
            area.present().map_err(|e| err(&e))?;
        }
        Ok(())
    };
    atomic::write_with(path, draw, |e| err(&e))
}

/// The paper's three key moments of an episode whose ego merged at step `merged_at`: the
/// initial state, 1 s before the merge and 2 s after it (the last step when the episode is
/// shorter; the middle and last steps when the ego did not merge).
pub fn key_steps(steps: usize, merged_at: Option<usize>, dt: f64) -> [usize; 3] {
    let second = (1.0 / dt).round() as usize;
    match merged_at {
        Some(m) => [0, m.saturating_sub(second), (m + 2 * second).min(steps)],
        None => [0, steps / 2, steps],
    }
}
