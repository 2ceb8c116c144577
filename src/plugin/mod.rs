//! The Bevy layer: deformable surfaces as ECS data, simulated on the fixed tick.
//!
//! Add [`PointSpringsPlugins`] (or [`PointSpringsPlugin`] alone, headless) and spawn a
//! [`DeformableSurface`]. The plugin prepares it in the background ([`prepare`]; it says
//! when it is ready or why it failed with the events of [`lifecycle`]), then every tick of
//! its schedule (by default
//! [`FixedUpdate`]) runs the chained sets of [`PointSpringsSystems`]:
//! `Forces → Integrate → Transfer` (`simulate.rs`). Each surface is one entity whose
//! components hold whole arrays ([`components`]); drawing comes with the `render` feature.
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_point_springs::prelude::*;
//! use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
//!
//! /// Wind from +X, added to every simulation point each tick.
//! fn wind(mut surfaces: Query<&mut SurfaceForces>) {
//!     for mut forces in &mut surfaces {
//!         for i in 0..forces.len() {
//!             forces.add(i, Vec3::X * 0.01).unwrap();
//!         }
//!     }
//! }
//!
//! let mut app = App::new();
//! app.add_plugins((MinimalPlugins, PointSpringsPlugins::default()))
//!     .add_systems(FixedUpdate, wind.in_set(PointSpringsSystems::Forces));
//! let config = SurfaceConfig::default();
//! app.world_mut()
//!     .spawn(DeformableSurface::cloud(fibonacci_sphere(1500, 1.0), config));
//! app.update();
//! ```

pub mod assets;
pub mod attach;
pub mod components;
#[cfg(feature = "rapier")]
pub mod contact;
#[cfg(feature = "render")]
pub mod gpu_transfer;
pub mod grab;
pub mod health;
pub mod lifecycle;
pub mod meet;
pub mod model;
#[cfg(feature = "egui")]
pub mod panel;
#[cfg(feature = "render")]
pub mod pick;
pub mod prepare;
#[cfg(feature = "render")]
pub mod render;
pub mod save;
pub(crate) mod simulate;
pub mod sleep;
#[cfg(feature = "render")]
pub mod view;
pub mod world;

use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;

pub use assets::{CloudAsset, CloudLoader, SceneAsset, SceneLoader};
pub use attach::{
    AttachPoints, AttachmentError, AttachmentId, AttachmentState, SurfaceAttachments,
};
pub use components::{
    DEFAULT_SLEEP_AFTER, DEFAULT_SLEEP_SPEED, DeformableSurface, DenseSurface, GpuTransferInput,
    PreparationProgress, PreparedFileOutcome, PreviousTick, SceneTimeline, SimulationPoints,
    SleepSettings, StepOnce, SurfaceAnchors, SurfaceForces, SurfaceInView, SurfaceMasses,
    SurfaceMaterial, SurfaceNetwork, SurfacePressure, SurfaceRunSettings, SurfaceSleep,
    SurfaceSource, SurfaceSprings, SurfaceStatus, SurfaceStepper, SurfaceTimings, SurfaceWork,
    TransferTiming,
};
#[cfg(feature = "rapier")]
pub use contact::{
    BodySupports, ContactDiagnostics, ContactSolve, SurfaceContact, SurfaceContactPlugin,
    SurfaceContacts,
};
pub use grab::{GrabMessage, GrabSettings, Grabs};
pub use health::{STABLE_STEPS_TO_RECOVER, SurfaceHealth, SurfaceUnstable};
pub use lifecycle::{SurfaceError, SurfaceFailed, SurfaceReady};
pub use meet::{SurfaceMeeting, SurfaceMeetingReport};
pub use model::{ModelError, ModelMessage, ModelOutcome};
pub use prepare::{PreparationPool, PrepareAgain, PrepareAgainFailed};
pub use save::{
    SAVED_GAME_MAGIC, SaveGameError, SaveGameMessage, SaveGameOutcome, SaveName, SurfaceBaked,
};
pub use world::{SurfaceGravity, SurfacePins, WorldSurfaceError, WorldSurfaces};

/// All of the crate's plugins that the enabled features bring, on one schedule: the
/// simulation ([`PointSpringsPlugin`]); with `render`, surfel drawing (left out where the
/// app has no renderer, as in a headless server) and pointer grabs; with `egui`, the panel
/// (left out without a renderer unless the app brings egui itself); with `rapier`,
/// contacts with bevy_rapier3d's colliders (which needs
/// rapier's plugin on the same schedule). Leave one out with
/// `PointSpringsPlugins::default().build().disable::<P>()`. Add it after `DefaultPlugins`:
/// the drawing plugins look for the renderer when they are built.
#[derive(Debug, Clone)]
pub struct PointSpringsPlugins {
    schedule: InternedScheduleLabel,
}

impl PointSpringsPlugins {
    /// Every plugin of the group on `schedule` (see [`PointSpringsPlugin::new`]).
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self {
            schedule: schedule.intern(),
        }
    }
}

impl Default for PointSpringsPlugins {
    fn default() -> Self {
        Self::new(FixedUpdate)
    }
}

impl PluginGroup for PointSpringsPlugins {
    fn build(self) -> bevy::app::PluginGroupBuilder {
        let group = bevy::app::PluginGroupBuilder::start::<Self>().add(PointSpringsPlugin {
            schedule: self.schedule,
        });
        #[cfg(feature = "render")]
        let group = group
            .add(render::SurfelRenderPlugin)
            .add(pick::SurfacePickingPlugin);
        #[cfg(feature = "rapier")]
        let group = group.add(SurfaceContactPlugin::new(self.schedule));
        #[cfg(feature = "egui")]
        let group = group.add(panel::PointSpringsPanelPlugin);
        group
    }
}

/// Whether the app draws: the drawing plugins of [`PointSpringsPlugins`] leave themselves
/// out of an app without Bevy's renderer.
#[cfg(feature = "render")]
pub(crate) fn has_renderer(app: &App) -> bool {
    app.is_plugin_added::<bevy::render::RenderPlugin>()
}

/// The plugin. Add it next to `DefaultPlugins` (or `MinimalPlugins`, plus `AssetPlugin`
/// for files).
#[derive(Debug, Clone)]
pub struct PointSpringsPlugin {
    schedule: InternedScheduleLabel,
}

impl PointSpringsPlugin {
    /// The simulation runs in `schedule` (one step per run, of that run's `Time` delta);
    /// use [`FixedUpdate`] (the default) unless the game steps its physics elsewhere.
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self {
            schedule: schedule.intern(),
        }
    }
}

impl Default for PointSpringsPlugin {
    fn default() -> Self {
        Self::new(FixedUpdate)
    }
}

/// The system sets of the plugin. `Forces`, `Integrate` and `Transfer` run chained in the
/// plugin's schedule (one step each run); `Prepare` runs in [`PreUpdate`], and `Transfer`
/// also in [`PostUpdate`] for surfaces that follow once per frame.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PointSpringsSystems {
    /// New surfaces are started and finished preparations collected (in [`PreUpdate`]).
    Prepare,
    /// Force accumulation: grabs ([`GrabMessage`]) and scene timelines move their anchors,
    /// attachments ([`SurfaceAttachments`]) their points' velocities, then each surface's springs (eq 2–3), gravity (eq 4), anchors and pins (eq 5), drag
    /// and gas pressure. Put systems that add to [`SurfaceForces`] here.
    Forces,
    /// Euler stepping (explicit, symplectic or implicit, sub-stepped where needed), with
    /// the game's forces added; each surface's [`SurfaceHealth`] after its step; then
    /// plastic flow for materials that yield. Sleeping
    /// surfaces are woken first when something acts on them, and still ones put to sleep
    /// last ([`sleep`]).
    Integrate,
    /// Displacement transfer (§5): resampling when due, dense positions and normals.
    Transfer,
}

impl Plugin for PointSpringsPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<SurfaceStatus>()
            .register_type::<SurfaceRunSettings>()
            .register_type::<SurfaceMaterial>()
            .register_type::<PreparationProgress>()
            .register_type::<SurfaceTimings>()
            .register_type::<SurfaceInView>()
            .register_type::<StepOnce>()
            .register_type::<SurfaceHealth>()
            .register_type::<GrabSettings>()
            .register_type::<SaveName>()
            .register_type::<SurfaceMeeting>()
            .register_type::<SurfaceMeetingReport>()
            .register_type::<SurfaceGravity>()
            .add_message::<GrabMessage>()
            .add_message::<SaveGameMessage>()
            .add_message::<SaveGameOutcome>()
            .add_message::<ModelMessage>()
            .add_message::<ModelOutcome>()
            .add_observer(model::report_dropped_work)
            .init_resource::<GrabSettings>()
            .init_resource::<Grabs>()
            .configure_sets(
                self.schedule,
                (
                    PointSpringsSystems::Forces,
                    PointSpringsSystems::Integrate,
                    PointSpringsSystems::Transfer,
                )
                    .chain(),
            )
            .add_systems(
                PreUpdate,
                (
                    prepare::start_preparation,
                    prepare::finish_preparation,
                    lifecycle::announce_failures,
                )
                    .chain()
                    .in_set(PointSpringsSystems::Prepare),
            )
            .add_systems(
                self.schedule,
                (
                    (
                        simulate::remember_previous_tick,
                        model::apply_model_requests,
                        model::finish_model_work,
                        grab::apply_grabs,
                        attach::hold_attachments,
                        simulate::drive_timelines,
                        simulate::apply_materials,
                        world::apply_world_gravity,
                        simulate::accumulate_forces,
                        #[cfg(feature = "rapier")]
                        meet::read_collision_groups,
                        meet::meet_surfaces,
                    )
                        .chain()
                        .in_set(PointSpringsSystems::Forces),
                    (
                        sleep::wake_surfaces,
                        simulate::integrate,
                        meet::untangle_surfaces,
                        attach::record_pulls,
                        meet::record_meeting_contacts,
                        health::watch_health,
                        simulate::plastic_flow,
                        sleep::settle_surfaces,
                    )
                        .chain()
                        .in_set(PointSpringsSystems::Integrate),
                    (simulate::transfer_tick, lifecycle::announce_failures)
                        .chain()
                        .in_set(PointSpringsSystems::Transfer),
                ),
            )
            .add_systems(
                PostUpdate,
                (
                    (save::catch_up_before_save, save::apply_saved_games)
                        .chain()
                        .before(PointSpringsSystems::Transfer),
                    (simulate::transfer_frame, lifecycle::announce_failures)
                        .chain()
                        .in_set(PointSpringsSystems::Transfer),
                ),
            );
    }

    fn finish(&self, app: &mut App) {
        // Files need the asset server; without it (headless tests with MinimalPlugins)
        // surfaces can still be spawned from clouds in memory.
        if app.is_plugin_added::<AssetPlugin>() {
            app.init_asset::<CloudAsset>()
                .init_asset::<SceneAsset>()
                .init_asset_loader::<CloudLoader>()
                .init_asset_loader::<SceneLoader>();
        }
    }
}
