//! Road geometry and vehicle bounding boxes.
//!
//! The target lane's centre line is `y = 0`; the ramp's is one lane width to its right
//! (`y = -lane_width`). The ramp joins the target lane at the conflict point `x_c`, or at the
//! end of an acceleration lane past it (`scenario.accel_lane`): a ramp vehicle is moved onto
//! the target-lane centre line when its `x` reaches the ramp's end (longitudinal control, the
//! lane geometry gives the lateral position).

use crate::config::Config;
use nalgebra::{Rotation2, Vector2};

/// The merge road.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Road {
    /// Conflict point `x_c` (m).
    pub conflict_point: f64,
    /// Lane width (m).
    pub lane_width: f64,
    /// How far before `x_c` a ramp vehicle may join the target lane at a safe gap (m).
    pub merge_zone: f64,
    /// How far before `x_c` the drivers who make room for a ramp vehicle start to (m; at least
    /// `merge_zone`, `scenario.yield_zone`).
    pub yield_zone: f64,
    /// How far the ramp goes on past `x_c` as an acceleration lane (m).
    pub accel_lane: f64,
}

impl Road {
    /// The road of a configuration.
    pub fn new(config: &Config) -> Self {
        Road {
            conflict_point: config.scenario.conflict_point,
            lane_width: config.scenario.lane_width,
            merge_zone: config.scenario.merge_zone,
            yield_zone: (config.scenario.yield_zone)
                .map_or(config.scenario.merge_zone, |z| z.max(config.scenario.merge_zone)),
            accel_lane: config.scenario.accel_lane,
        }
    }

    /// Whether a ramp vehicle at `x` is where it joins the target lane at the first safe gap:
    /// from the merge zone's start before `x_c` to the acceleration lane's end.
    pub fn in_merge_zone(&self, x: f64) -> bool {
        self.merge_zone + self.accel_lane > 0.0 && x >= self.conflict_point - self.merge_zone
    }

    /// Whether a ramp vehicle at `x` is where the drivers who make room for one do
    /// (`scenario.yield_zone`): the merge zone and up to `yield_zone` before `x_c`.
    pub fn in_yield_zone(&self, x: f64) -> bool {
        self.merge_zone + self.accel_lane > 0.0 && x >= self.conflict_point - self.yield_zone
    }

    /// Where the ramp ends (m): `x_c` plus the acceleration lane.
    pub fn ramp_end(&self) -> f64 {
        self.conflict_point + self.accel_lane
    }

    /// Lateral position of a lane's centre line.
    pub fn lane_y(&self, on_ramp: bool) -> f64 {
        if on_ramp { -self.lane_width } else { 0.0 }
    }

    /// Whether a vehicle at `x` that was on the ramp is still on it.
    pub fn still_on_ramp(&self, was_on_ramp: bool, x: f64) -> bool {
        was_on_ramp && x < self.ramp_end()
    }
}

/// A vehicle's footprint: a `length` x `width` rectangle centred at `(x, y)`, rotated by `phi`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Centre x (m).
    pub x: f64,
    /// Centre y (m).
    pub y: f64,
    /// Heading (rad).
    pub phi: f64,
    /// Length along the heading (m).
    pub length: f64,
    /// Width across the heading (m).
    pub width: f64,
}

impl Footprint {
    fn axes(&self) -> [Vector2<f64>; 2] {
        let r = Rotation2::new(self.phi);
        [r * Vector2::x(), r * Vector2::y()]
    }

    /// Half-extent of the rectangle projected on unit axis `n`.
    fn radius_on(&self, n: &Vector2<f64>) -> f64 {
        let [a, b] = self.axes();
        0.5 * self.length * a.dot(n).abs() + 0.5 * self.width * b.dot(n).abs()
    }
}

/// True when two footprints overlap with positive area (touching edges do not count).
/// Separating-axis test over the four edge normals.
pub fn boxes_overlap(a: &Footprint, b: &Footprint) -> bool {
    let d = Vector2::new(b.x - a.x, b.y - a.y);
    a.axes()
        .iter()
        .chain(b.axes().iter())
        .all(|n| d.dot(n).abs() < a.radius_on(n) + b.radius_on(n))
}
