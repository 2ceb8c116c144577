//! The live panel (feature `egui`): one bevy_egui window to tune a selected surface while it
//! runs, see what it costs, and keep the result.
//!
//! * **Figures**: dense and simulation points, springs, whether the surface sleeps or is
//!   out of view, ms per tick split into forces, step and transfer, ms per frame for the
//!   surfel upload, kinetic and elastic energy; plots of energy and ms per tick over the
//!   last [`HISTORY_SECONDS`] seconds.
//! * **Settings**: material (stiffness, damping, yield strain, creep rate), integrator,
//!   sub-steps, gravity, drag, the fixed tick, and the simplification level (changing it
//!   prepares the surface again in the background, with a progress bar, while the old one
//!   keeps running: [`PrepareAgain`](super::PrepareAgain)).
//! * **Actions**: pause, single step, reset to rest, bake, export to PLY; show or hide the
//!   simulation points and springs.
//!
//! Add [`PointSpringsPanelPlugin`] after `DefaultPlugins` and [`PointSpringsPlugin`](super::PointSpringsPlugin)
//! (it adds bevy_egui's `EguiPlugin` when the app has none). Click a surface's row in the
//! panel to select it; the first ready surface is selected to begin with. In a window
//! narrower than 960 points the panel starts folded (click its title to unfold it).

mod ui;

use std::collections::VecDeque;

use bevy::prelude::*;
use bevy_egui::{EguiPlugin, EguiPrimaryContextPass};

use super::PointSpringsSystems;
use super::components::{
    SimulationPoints, StepPartsQuery, SurfaceStatus, SurfaceStepper, SurfaceTimings,
};
use super::model::ModelOutcome;
use super::render::SpringGizmos;

/// Seconds of history the panel's plots show.
pub const HISTORY_SECONDS: f64 = 10.0;

/// Adds the panel (see the module docs).
#[derive(Debug, Default, Clone, Copy)]
pub struct PointSpringsPanelPlugin;

impl Plugin for PointSpringsPanelPlugin {
    fn build(&self, app: &mut App) {
        // Left out of a headless app, unless it brought egui itself.
        if !(super::has_renderer(app) || app.is_plugin_added::<EguiPlugin>()) {
            return;
        }
        if !app.is_plugin_added::<EguiPlugin>() {
            app.add_plugins(EguiPlugin::default());
        }
        app.init_resource::<SurfacePanel>()
            .init_resource::<SpringGizmos>()
            .init_resource::<PanelHistory>()
            .add_systems(
                PostUpdate,
                (select_default, record_history, read_outcomes)
                    .chain()
                    .after(PointSpringsSystems::Transfer),
            )
            .add_systems(EguiPrimaryContextPass, ui::panel);
    }
}

/// What the panel shows and keeps between frames.
#[derive(Resource, Debug, Clone)]
pub struct SurfacePanel {
    /// Whether the window is open.
    pub open: bool,
    /// The surface the panel is about.
    pub selected: Option<Entity>,
    /// Where Export writes.
    pub export_path: String,
    /// The simplification level (simulation points) for Prepare again.
    pub simulation_points: usize,
    /// The last message for the user: how a request went.
    pub message: Option<String>,
}

impl Default for SurfacePanel {
    fn default() -> Self {
        Self {
            open: true,
            selected: None,
            export_path: "surface.ply".to_owned(),
            simulation_points: 0,
            message: None,
        }
    }
}

/// One frame's figures of the selected surface, for the plots.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sample {
    /// Seconds of app time.
    time: f64,
    kinetic: f64,
    elastic: f64,
    tick_ms: f32,
}

/// The selected surface's samples over the last [`HISTORY_SECONDS`].
#[derive(Resource, Debug, Default)]
struct PanelHistory {
    surface: Option<Entity>,
    samples: VecDeque<Sample>,
}

/// The first ready surface is selected when none (or a despawned one) is; a newly selected
/// surface's simulation points are the level the panel offers to prepare again.
fn select_default(
    mut panel: ResMut<SurfacePanel>,
    surfaces: Query<(Entity, &SurfaceStatus, Option<&SimulationPoints>)>,
    mut levelled: Local<Option<Entity>>,
) {
    if !panel.selected.is_some_and(|e| surfaces.contains(e)) {
        let first = surfaces.iter().find(|(_, status, _)| status.is_ready());
        panel.selected = first.map(|(e, ..)| e);
    }
    if *levelled != panel.selected
        && let Some(Ok((entity, _, Some(points)))) = panel.selected.map(|e| surfaces.get(e))
    {
        panel.simulation_points = points.len();
        *levelled = Some(entity);
    }
}

/// The selected surface's energy and cost this frame joins the history; samples older than
/// [`HISTORY_SECONDS`] leave it.
fn record_history(
    time: Res<Time>,
    panel: Res<SurfacePanel>,
    mut history: ResMut<PanelHistory>,
    surfaces: Query<(
        &SimulationPoints,
        &SurfaceStepper,
        &SurfaceTimings,
        StepPartsQuery,
    )>,
) {
    if history.surface != panel.selected {
        history.surface = panel.selected;
        history.samples.clear();
    }
    let Some(Ok((points, stepper, timings, parts))) = panel.selected.map(|e| surfaces.get(e))
    else {
        return;
    };
    let now = time.elapsed_secs_f64();
    if history.samples.back().is_some_and(|s| s.time >= now) {
        return; // time is paused: nothing new to plot
    }
    let energy = stepper.energy(points, parts.step_parts());
    history.samples.push_back(Sample {
        time: now,
        kinetic: energy.kinetic,
        elastic: energy.spring,
        tick_ms: timings.tick_ms(),
    });
    while history
        .samples
        .front()
        .is_some_and(|s| s.time < now - HISTORY_SECONDS)
    {
        history.samples.pop_front();
    }
}

/// How the panel's requests went, for its message line.
fn read_outcomes(mut outcomes: MessageReader<ModelOutcome>, mut panel: ResMut<SurfacePanel>) {
    for outcome in outcomes.read() {
        let what = match &outcome.request {
            super::ModelMessage::Bake { .. } => "bake".to_owned(),
            super::ModelMessage::Export { path, .. } => format!("export to {}", path.display()),
            super::ModelMessage::Reset { .. } => "reset".to_owned(),
        };
        panel.message = Some(match &outcome.result {
            Ok(()) => format!("{what}: done"),
            Err(e) => format!("{what} failed: {e}"),
        });
    }
}
