//! Line charts: training curves over seeds (mean line and a band of one standard deviation,
//! the paper's Figures 7 and 8), MARL against SARL, and an episode's ego time series.

use crate::atomic;
use crate::render::{FONT, RenderError, draw_error, register_font};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// One line, optionally with a band `(x, low, high)` around it.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points `(x, y)`.
    pub points: Vec<(f64, f64)>,
    /// Band `(x, low, high)` (empty: none).
    pub band: Vec<(f64, f64, f64)>,
}

/// One panel's titles.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// Caption.
    pub title: String,
    /// X axis label.
    pub x_label: String,
    /// Y axis label.
    pub y_label: String,
}

const PALETTE: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

/// The mean over seeds at each x of curves that share their x values, with a band of one
/// standard deviation (population) around it. Curves are cut to the shortest.
pub fn mean_band(label: &str, curves: &[Vec<(f64, f64)>]) -> Series {
    let n = curves.iter().map(Vec::len).min().unwrap_or(0);
    let k = curves.len().max(1) as f64;
    let mut points = Vec::with_capacity(n);
    let mut band = Vec::with_capacity(n);
    for i in 0..n {
        let x = curves[0][i].0;
        let mean = curves.iter().map(|c| c[i].1).sum::<f64>() / k;
        let var = curves.iter().map(|c| (c[i].1 - mean).powi(2)).sum::<f64>() / k;
        points.push((x, mean));
        band.push((x, mean - var.sqrt(), mean + var.sqrt()));
    }
    Series {
        label: label.to_string(),
        points,
        band,
    }
}

fn bounds(series: &[Series]) -> Option<((f64, f64), (f64, f64))> {
    let xs = series.iter().flat_map(|s| s.points.iter().map(|p| p.0));
    let ys = series.iter().flat_map(|s| {
        s.points
            .iter()
            .map(|p| p.1)
            .chain(s.band.iter().flat_map(|b| [b.1, b.2]))
    });
    let fold = |it: &mut dyn Iterator<Item = f64>| {
        it.filter(|v| v.is_finite())
            .fold(None, |acc: Option<(f64, f64)>, v| {
                Some(acc.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))))
            })
    };
    let (x, y) = (fold(&mut xs.into_iter())?, fold(&mut ys.into_iter())?);
    let pad = |(lo, hi): (f64, f64)| {
        let d = if hi > lo { 0.05 * (hi - lo) } else { 1.0 };
        (lo - d, hi + d)
    };
    Some(((x.0, if x.1 > x.0 { x.1 } else { x.0 + 1.0 }), pad(y)))
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    series: &[Series],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let Some(((x0, x1), (y0, y1))) = bounds(series) else {
        return Ok(());
    };
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, (FONT, 18))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .label_style((FONT, 12))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;
    for (k, s) in series.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        if !s.band.is_empty() {
            let outline: Vec<(f64, f64)> = s
                .band
                .iter()
                .map(|b| (b.0, b.2))
                .chain(s.band.iter().rev().map(|b| (b.0, b.1)))
                .collect();
            chart.draw_series(std::iter::once(Polygon::new(outline, color.mix(0.2).filled())))?;
        }
        chart
            .draw_series(LineSeries::new(s.points.iter().copied(), color.stroke_width(2)))?
            .label(s.label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    if series.iter().any(|s| !s.label.is_empty()) {
        chart
            .configure_series_labels()
            .label_font((FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::LowerRight)
            .draw()?;
    }
    Ok(())
}

/// Draws panels stacked vertically into one PNG (written to a temporary name, then renamed).
pub fn panels_png(path: &Path, size: (u32, u32), panels: &[(Panel, Vec<Series>)]) -> Result<(), RenderError> {
    if panels.iter().all(|(_, s)| bounds(s).is_none()) {
        return Err(RenderError::Empty(format!(
            "{}: no finite data to plot",
            path.display()
        )));
    }
    register_font();
    let err = draw_error(path);
    let draw = |tmp: &Path| {
        let root = BitMapBackend::new(tmp, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let areas = root.split_evenly((panels.len(), 1));
        for (area, (panel, series)) in areas.iter().zip(panels) {
            draw_panel(area, panel, series).map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))
    };
    atomic::write_with(path, draw, |e| err(&e))
}
