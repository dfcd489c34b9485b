//! Every picture of one simulated episode: the three key moments (PNG), the whole episode
//! (GIF), and the ego's speed, acceleration and gap over time (PNG).

use crate::config::Config;
use crate::engine::outcome::EpisodeOutcome;
use crate::render::RenderError;
use crate::render::charts::{Panel, Series, panels_png};
use crate::render::scene::{Layout, episode_gif, frame_png, key_steps, span_for};
use crate::world::neighbors::find_neighbors;
use crate::world::state::Scene;
use std::path::{Path, PathBuf};

/// The scenes of a fully recorded outcome, one per state `s_0 .. s_steps`.
pub fn scenes_of(outcome: &EpisodeOutcome) -> Vec<Scene> {
    let n = outcome.final_scene.len();
    outcome
        .trajectory
        .as_ref()
        .map(|t| t.states.chunks(n).map(|c| Scene::new(c.to_vec())).collect())
        .unwrap_or_default()
}

/// The ego's bumper-to-bumper gap to its nearest leader (any lane, the Table I leader) in
/// each scene; `None` without a leader.
pub fn ego_gaps(scenes: &[Scene], length: f64) -> Vec<Option<f64>> {
    let (mut order, mut nb) = (Vec::new(), Vec::new());
    scenes
        .iter()
        .map(|s| {
            find_neighbors(s, &mut order, &mut nb);
            nb[0].leader.map(|j| s.vehicles[j].x - s.ego().x - length)
        })
        .collect()
}

/// The frame layout of a configuration for these scenes (1600 px wide, one scale for all;
/// with `show_conflict_point`, a span wide enough to show it in every scene too).
pub fn layout_for(config: &Config, scenes: &[Scene], show_conflict_point: bool) -> Layout {
    let x_c = config.scenario.conflict_point;
    Layout {
        conflict_point: x_c,
        lane_width: config.scenario.lane_width,
        vehicle: (config.vehicle.length, config.vehicle.width),
        size: (1600, 200),
        span: span_for(scenes, show_conflict_point.then_some(x_c)),
        dt: config.sim.dt,
    }
}

/// Writes `NAME_initial.png`, `NAME_before.png`, `NAME_after.png`, `NAME.gif` (every 5th step,
/// 2x real time) and `NAME_timeseries.png` into `dir`; returns their paths.
pub fn render_episode(
    dir: &Path,
    name: &str,
    title: &str,
    config: &Config,
    outcome: &EpisodeOutcome,
) -> Result<Vec<PathBuf>, RenderError> {
    let scenes = scenes_of(outcome);
    if scenes.is_empty() {
        return Err(RenderError::Empty(format!(
            "{name}: the episode was not recorded"
        )));
    }
    let dt = config.sim.dt;
    let steps = scenes.len() - 1;
    let mut written = Vec::new();
    let moments = key_steps(steps, outcome.ego_merged_at, dt);
    let key_scenes: Vec<Scene> = moments.iter().map(|&k| scenes[k].clone()).collect();
    let layout = layout_for(config, &key_scenes, true);
    let labels = if outcome.ego_merged_at.is_some() {
        ["initial state", "ego before merging", "ego after merging"]
    } else {
        [
            "initial state",
            "halfway (the ego does not merge)",
            "last step (the ego did not merge)",
        ]
    };
    for ((step, what), label) in moments
        .into_iter()
        .zip(["initial", "before", "after"])
        .zip(labels)
    {
        let path = dir.join(format!("{name}_{what}.png"));
        frame_png(&path, &layout, &scenes[step], step, &format!("{title}: {label}"))?;
        written.push(path);
    }
    let gif = dir.join(format!("{name}.gif"));
    episode_gif(
        &gif,
        &layout_for(config, &scenes, false),
        &scenes,
        5,
        (5.0 * dt * 1000.0 / 2.0) as u32,
        title,
    )?;
    written.push(gif);
    let t = |k: usize| k as f64 * dt;
    let speed: Vec<(f64, f64)> = scenes
        .iter()
        .enumerate()
        .map(|(k, s)| (t(k), s.ego().v))
        .collect();
    let actions = outcome
        .trajectory
        .as_ref()
        .map(|tr| tr.actions.as_slice())
        .unwrap_or_default();
    let n = outcome.final_scene.len();
    let accel: Vec<(f64, f64)> = actions
        .iter()
        .step_by(n)
        .enumerate()
        .map(|(k, a)| (t(k), *a))
        .collect();
    let gap: Vec<(f64, f64)> = ego_gaps(&scenes, config.vehicle.length)
        .into_iter()
        .enumerate()
        .filter_map(|(k, g)| g.map(|g| (t(k), g)))
        .collect();
    let line = |points: Vec<(f64, f64)>| {
        vec![Series {
            label: String::new(),
            points,
            band: Vec::new(),
        }]
    };
    let panel = |title: &str, y: &str| Panel {
        title: title.to_string(),
        x_label: "time (s)".to_string(),
        y_label: y.to_string(),
    };
    let series = dir.join(format!("{name}_timeseries.png"));
    panels_png(
        &series,
        (1000, 900),
        &[
            (panel(&format!("{title}: ego speed"), "speed (m/s)"), line(speed)),
            (
                panel("ego acceleration (applied)", "acceleration (m/s^2)"),
                line(accel),
            ),
            (
                panel("gap to the ego's nearest leader (bumper to bumper)", "gap (m)"),
                line(gap),
            ),
        ],
    )?;
    written.push(series);
    Ok(written)
}
