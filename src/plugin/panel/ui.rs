//! The panel's window, drawn with egui each frame. Values are edited on copies and written
//! back only when the user changed them, so that an open panel does not wake a sleeping
//! surface or reset its springs every frame.

use bevy::ecs::query::QueryData;
use bevy::ecs::system::SystemParam;
use bevy::prelude::*;
use bevy_egui::{EguiContexts, egui};
use egui_plot::{Legend, Line, Plot};

use super::{HISTORY_SECONDS, PanelHistory, SurfacePanel};
use crate::core::simplify::MIN_SIMULATION_POINTS;
use crate::core::solver::{BendingModel, ImplicitSolver, Integrator, MaterialUnits, SubstepPolicy};
use crate::plugin::components::{
    DeformableSurface, DenseSurface, PreparationProgress, SimulationPoints, StepOnce,
    SurfaceInView, SurfaceMaterial, SurfaceNetwork, SurfaceRunSettings, SurfaceSleep,
    SurfaceSprings, SurfaceStatus, SurfaceStepper, SurfaceTimings,
};
use crate::plugin::model::ModelMessage;
use crate::plugin::prepare::{PrepareAgain, PrepareAgainFailed};
use crate::plugin::render::SpringGizmos;

/// Height of each plot, points.
const PLOT_HEIGHT: f32 = 110.0;

/// Width and height of the window when it opens, points.
const WINDOW_SIZE: [f32; 2] = [300.0, 640.0];

/// Narrower than this (points), the window starts folded so that the scene shows.
const MIN_UNFOLDED_WIDTH: f32 = 960.0;

/// The fixed tick the panel offers, Hz.
const TICK_RANGE_HZ: std::ops::RangeInclusive<f64> = 15.0..=480.0;

/// The selected surface as the panel reads and edits it.
#[derive(QueryData)]
#[query_data(mutable)]
pub(super) struct PanelSurface {
    surface: &'static DeformableSurface,
    points: &'static SimulationPoints,
    dense: &'static DenseSurface,
    network: &'static SurfaceNetwork,
    springs: &'static SurfaceSprings,
    timings: &'static SurfaceTimings,
    sleep: &'static SurfaceSleep,
    in_view: &'static SurfaceInView,
    material: &'static mut SurfaceMaterial,
    stepper: &'static mut SurfaceStepper,
    settings: &'static mut SurfaceRunSettings,
    progress: Option<&'static PreparationProgress>,
    failed: Option<&'static PrepareAgainFailed>,
}

/// What the panel changes outside the selected surface.
#[derive(SystemParam)]
pub(super) struct PanelWorld<'w, 's> {
    commands: Commands<'w, 's>,
    requests: MessageWriter<'w, ModelMessage>,
    gizmos: ResMut<'w, SpringGizmos>,
    fixed: ResMut<'w, Time<Fixed>>,
}

/// Draws the panel.
pub(super) fn panel(
    mut contexts: EguiContexts,
    mut panel: ResMut<SurfacePanel>,
    history: Res<PanelHistory>,
    mut world: PanelWorld,
    list: Query<(Entity, Option<&Name>, &SurfaceStatus)>,
    mut surfaces: Query<PanelSurface>,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    let mut open = panel.open;
    let roomy = ctx.content_rect().width() >= MIN_UNFOLDED_WIDTH;
    egui::Window::new("point springs")
        .open(&mut open)
        .default_open(roomy)
        .default_size(WINDOW_SIZE)
        .default_pos([8.0, 8.0])
        .show(ctx, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                surface_list(ui, &mut panel, &list);
                let Some(entity) = panel.selected else {
                    ui.label("No surface is ready yet.");
                    return;
                };
                let Ok(mut surface) = surfaces.get_mut(entity) else {
                    ui.label("The selected surface is not prepared.");
                    return;
                };
                figures(ui, &surface, &history);
                plots(ui, &history);
                actions(ui, entity, &mut panel, &mut surface, &mut world);
                tuning(ui, entity, &mut panel, &mut surface, &mut world);
                if let Some(message) = &panel.message {
                    ui.separator();
                    ui.label(message);
                }
            });
        });
    panel.open = open;
    Ok(())
}

/// One row per surface; a click selects it.
fn surface_list(
    ui: &mut egui::Ui,
    panel: &mut SurfacePanel,
    list: &Query<(Entity, Option<&Name>, &SurfaceStatus)>,
) {
    for (entity, name, status) in list {
        let label = match name {
            Some(name) => format!("{name} ({entity})"),
            None => format!("surface {entity}"),
        };
        let state = match status {
            SurfaceStatus::Ready => String::new(),
            SurfaceStatus::Failed(why) => format!(": failed: {why}"),
            other => format!(": {other:?}").to_lowercase(),
        };
        let selected = panel.selected == Some(entity);
        if ui.selectable_label(selected, label + &state).clicked() {
            panel.selected = Some(entity);
        }
    }
    ui.separator();
}

/// The live figures.
fn figures(ui: &mut egui::Ui, s: &PanelSurfaceItem, history: &PanelHistory) {
    let t = s.timings;
    let stretch = s.network.stretch.len();
    let energy = history.samples.back();
    egui::Grid::new("figures").num_columns(2).show(ui, |ui| {
        let mut row = |name: &str, value: String| {
            ui.label(name);
            ui.label(value);
            ui.end_row();
        };
        row("dense points", s.dense.len().to_string());
        row("simulation points", s.points.len().to_string());
        row(
            "springs",
            format!("{} ({stretch} stretch)", s.springs.len()),
        );
        let state = match (s.settings.paused, s.sleep.asleep, s.in_view.0) {
            (true, ..) => "paused",
            (_, true, _) => "asleep (costs nothing)",
            (_, _, false) => "out of view (no transfer)",
            _ => "running",
        };
        row("state", state.to_owned());
        row(
            "ms per tick",
            format!(
                "{:.3} = forces {:.3} + step {:.3} + transfer {:.3}",
                t.tick_ms(),
                t.forces_ms,
                t.step_ms,
                t.transfer_ms
            ),
        );
        row("ms per frame, upload", format!("{:.3}", t.upload_ms));
        if let Some(e) = energy {
            row("kinetic energy", energy_text(e.kinetic));
            row("elastic energy", energy_text(e.elastic));
        }
    });
}

/// An energy with four significant digits (0 as 0).
fn energy_text(e: f64) -> String {
    if e == 0.0 {
        "0".to_owned()
    } else {
        format!("{e:.3e}")
    }
}

/// Energy and ms per tick over the last seconds, time relative to now.
fn plots(ui: &mut egui::Ui, history: &PanelHistory) {
    let Some(now) = history.samples.back().map(|s| s.time) else {
        return;
    };
    let series = |f: fn(&super::Sample) -> f64| -> Vec<[f64; 2]> {
        history
            .samples
            .iter()
            .map(|s| [s.time - now, f(s)])
            .collect()
    };
    ui.label(format!("energy, last {HISTORY_SECONDS} s"));
    history_plot("energy")
        .legend(Legend::default())
        .show(ui, |plot| {
            plot.line(Line::new("kinetic", series(|s| s.kinetic)));
            plot.line(Line::new("elastic", series(|s| s.elastic)));
        });
    ui.label(format!("ms per tick, last {HISTORY_SECONDS} s"));
    history_plot("ms per tick").show(ui, |plot| {
        plot.line(Line::new("ms", series(|s| f64::from(s.tick_ms))));
    });
}

/// A fixed plot of the last [`HISTORY_SECONDS`] (time to the left of 0, values from 0 up).
fn history_plot(id: &str) -> Plot<'static> {
    Plot::new(id)
        .height(PLOT_HEIGHT)
        .include_x(-HISTORY_SECONDS)
        .include_y(0.0)
        .allow_drag(false)
        .allow_zoom(false)
        .allow_scroll(false)
}

/// Pause, step, reset, bake, export, and what to draw.
fn actions(
    ui: &mut egui::Ui,
    entity: Entity,
    panel: &mut SurfacePanel,
    s: &mut PanelSurfaceItem,
    world: &mut PanelWorld,
) {
    ui.separator();
    ui.horizontal(|ui| {
        let mut paused = s.settings.paused;
        if ui.checkbox(&mut paused, "pause").changed() {
            s.settings.paused = paused;
        }
        if ui
            .add_enabled(paused, egui::Button::new("step"))
            .on_hover_text("one tick of a paused surface")
            .clicked()
        {
            world.commands.entity(entity).insert(StepOnce);
        }
        if ui
            .button("reset")
            .on_hover_text("back to the rest shape")
            .clicked()
        {
            world
                .requests
                .write(ModelMessage::Reset { surface: entity });
        }
        if ui
            .button("bake")
            .on_hover_text("the current shape becomes the rest shape")
            .clicked()
        {
            world.requests.write(ModelMessage::Bake { surface: entity });
        }
    });
    ui.horizontal(|ui| {
        ui.text_edit_singleline(&mut panel.export_path);
        if ui.button("export PLY").clicked() {
            world.requests.write(ModelMessage::Export {
                surface: entity,
                path: panel.export_path.clone().into(),
            });
        }
    });
    ui.horizontal(|ui| {
        let mut shown = *world.gizmos;
        ui.label("show");
        ui.checkbox(&mut shown.points, "points");
        ui.checkbox(&mut shown.stretch, "stretch");
        ui.checkbox(&mut shown.bend, "bend");
        ui.checkbox(&mut shown.hinges, "hinges");
        if shown.points != world.gizmos.points
            || shown.stretch != world.gizmos.stretch
            || shown.bend != world.gizmos.bend
            || shown.hinges != world.gizmos.hinges
        {
            *world.gizmos = shown;
        }
    });
}

/// Material, integrator, tick, gravity and the simplification level.
fn tuning(
    ui: &mut egui::Ui,
    entity: Entity,
    panel: &mut SurfacePanel,
    s: &mut PanelSurfaceItem,
    world: &mut PanelWorld,
) {
    egui::CollapsingHeader::new("material")
        .default_open(true)
        .show(ui, |ui| material(ui, entity, s, world));
    egui::CollapsingHeader::new("solver")
        .default_open(true)
        .show(ui, |ui| solver(ui, panel, s, world));
    egui::CollapsingHeader::new("simplification")
        .default_open(true)
        .show(ui, |ui| simplification(ui, entity, panel, s, world));
}

/// Stiffness, damping, the bending model and plasticity (density is fixed once the masses are
/// built), labelled in the material's units. Another bending model builds other springs, so
/// choosing one prepares the surface again.
fn material(ui: &mut egui::Ui, entity: Entity, s: &mut PanelSurfaceItem, world: &mut PanelWorld) {
    let mut m = s.material.0;
    ui.label(format!("density {} (set when prepared)", m.density));
    let (stiffness, damping, damping_range) = match m.units {
        MaterialUnits::PerSpring => ("stiffness", "damping", 0.0..=20.0),
        MaterialUnits::Sheet => ("modulus", "damping ratio", 0.0..=2.0),
    };
    ui.add(log_slider(
        &mut m.stretch_stiffness,
        0.1..=10_000.0,
        format!("stretch {stiffness}"),
    ));
    ui.add(slider(
        &mut m.stretch_damping,
        damping_range.clone(),
        format!("stretch {damping}"),
    ));
    ui.horizontal(|ui| {
        ui.label("bending");
        for (model, name) in [
            (BendingModel::Springs, "bend springs"),
            (BendingModel::Hinges, "hinges"),
            (BendingModel::Curvature, "curvature"),
        ] {
            ui.radio_value(&mut m.bending, model, name)
                .on_hover_text("prepares the surface again");
        }
    });
    match m.bending {
        BendingModel::Springs => {
            ui.add(log_slider(
                &mut m.bend_stiffness,
                0.01..=10_000.0,
                format!("bend {stiffness}"),
            ));
            ui.add(slider(
                &mut m.bend_damping,
                damping_range,
                format!("bend {damping}"),
            ));
        }
        BendingModel::Hinges | BendingModel::Curvature => {
            ui.add(log_slider(
                &mut m.bending_modulus,
                1.0e-5..=100.0,
                "bending modulus, N·m",
            ));
            ui.add(log_slider(
                &mut m.bending_damping,
                1.0e-4..=1.0,
                "bending damping, s",
            ));
            ui.add(log_slider(
                &mut m.yield_angle,
                0.001..=3.0,
                "yield angle, rad",
            ));
        }
    }
    ui.add(log_slider(&mut m.yield_strain, 0.001..=1.0, "yield strain"));
    ui.add(slider(
        &mut m.creep_rate,
        0.0..=20.0,
        "creep rate (0: elastic)",
    ));
    if m.bending != s.material.0.bending {
        // Preparing again takes the material (the new bending) from the component.
        world
            .commands
            .entity(entity)
            .insert(PrepareAgain(s.surface.config));
    }
    if m != s.material.0 {
        s.material.0 = m;
    }
}

/// A slider that leaves a value set elsewhere outside its range as it is (the default
/// would clamp it, which writes the component back and wakes the surface).
fn slider<'a, N: egui::emath::Numeric>(
    value: &'a mut N,
    range: std::ops::RangeInclusive<N>,
    text: impl Into<egui::WidgetText>,
) -> egui::Slider<'a> {
    egui::Slider::new(value, range)
        .clamping(egui::SliderClamping::Edits)
        .text(text)
}

/// [`slider`] over a logarithmic range.
fn log_slider<'a, N: egui::emath::Numeric>(
    value: &'a mut N,
    range: std::ops::RangeInclusive<N>,
    text: impl Into<egui::WidgetText>,
) -> egui::Slider<'a> {
    slider(value, range, text).logarithmic(true)
}

/// Integrator, sub-steps, gravity, drag and the fixed tick.
fn solver(
    ui: &mut egui::Ui,
    panel: &mut SurfacePanel,
    s: &mut PanelSurfaceItem,
    world: &mut PanelWorld,
) {
    let mut config = *s.stepper.config();
    egui::ComboBox::from_label("integrator")
        .selected_text(format!("{:?}", config.integrator))
        .show_ui(ui, |ui| {
            for integrator in [
                Integrator::ExplicitEuler,
                Integrator::SymplecticEuler,
                Integrator::ImplicitEuler,
            ] {
                ui.selectable_value(
                    &mut config.integrator,
                    integrator,
                    format!("{integrator:?}"),
                );
            }
        });
    if config.integrator == Integrator::ImplicitEuler {
        egui::ComboBox::from_label("implicit solver")
            .selected_text(config.implicit_solver.name())
            .show_ui(ui, |ui| {
                for solver in [
                    ImplicitSolver::ConjugateGradient,
                    ImplicitSolver::LOCAL_GLOBAL,
                ] {
                    let chosen = std::mem::discriminant(&config.implicit_solver)
                        == std::mem::discriminant(&solver);
                    if ui.selectable_label(chosen, solver.name()).clicked() && !chosen {
                        config.implicit_solver = solver;
                    }
                }
            });
        if let ImplicitSolver::LocalGlobal { iterations } = &mut config.implicit_solver {
            ui.add(slider(iterations, 1..=16, "iterations a step"));
        }
    }
    if let SubstepPolicy::Auto { max_substeps } = &mut config.substeps {
        ui.add(slider(max_substeps, 1..=256, "max sub-steps"));
    }
    ui.horizontal(|ui| {
        ui.label("gravity (world)");
        for axis in 0..3 {
            ui.add(egui::DragValue::new(&mut config.gravity[axis]).speed(0.1));
        }
    });
    ui.add(slider(&mut config.drag, 0.0..=20.0, "drag"));
    if config != *s.stepper.config() {
        match s.stepper.set_config(config) {
            // A changed solver wakes a sleeping surface (it may now fall).
            Ok(()) => s.settings.set_changed(),
            Err(e) => panel.message = Some(format!("solver settings refused: {e}")),
        }
    }
    let mut hz = 1.0 / world.fixed.timestep().as_secs_f64();
    if ui
        .add(log_slider(
            &mut hz,
            TICK_RANGE_HZ,
            "fixed tick, Hz (all surfaces)",
        ))
        .changed()
    {
        world.fixed.set_timestep_hz(hz);
    }
}

/// The simplification level; changing it prepares the surface again in the background.
fn simplification(
    ui: &mut egui::Ui,
    entity: Entity,
    panel: &mut SurfacePanel,
    s: &mut PanelSurfaceItem,
    world: &mut PanelWorld,
) {
    let most = s.dense.len().max(MIN_SIMULATION_POINTS);
    ui.add(log_slider(
        &mut panel.simulation_points,
        MIN_SIMULATION_POINTS..=most,
        "simulation points",
    ));
    if let Some(progress) = s.progress {
        ui.add(egui::ProgressBar::new(progress.fraction).text(format!(
            "preparing: {} {:.0}%",
            progress.stage,
            100.0 * progress.fraction
        )));
    } else if ui
        .button("prepare again")
        .on_hover_text(
            "from the source cloud (a baked or sculpted shape is not kept), in the \
             background: the surface runs on until the new one is ready",
        )
        .clicked()
    {
        let mut config = s.surface.config;
        config.simplify.target = Some(panel.simulation_points);
        config.simplify.max_diameter = None;
        world.commands.entity(entity).insert(PrepareAgain(config));
    }
    if let Some(failed) = s.failed {
        ui.label(format!("preparing again failed: {}", failed.0));
    }
}
