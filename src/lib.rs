//! # bevy_point_springs
//!
//! Deformable point-sampled surfaces — raw point clouds, no mesh — driven by a mass-spring
//! system, after Su et al., *Mass-Spring Based Point-Sampled Surface Modelling* (2007).
//!
//! The crate has two layers:
//!
//! * [`core`] — pure Rust on plain slices (glam, kiddo, faer; no Bevy): point-cloud I/O,
//!   k-NN, PCA normals with consistent orientation, procedural test surfaces, the paper's
//!   tangent-plane Delaunay simplification (§3), the spring network with masses (§4), the
//!   dynamics of eq 2–6 (forces, explicit, symplectic and implicit Euler, stable-step
//!   estimates and a guard), the displacement transfer back to the dense surface with
//!   normals and resampling (§5), and scene files that run all of it. It builds and tests
//!   without Bevy (`--no-default-features`).
//! * `plugin` (feature `plugin`, on by default) — the Bevy 0.19 layer: a surface is one
//!   entity whose components hold its arrays; it is prepared in the background and
//!   simulated on the fixed tick in the chained sets force accumulation → Euler stepping →
//!   displacement transfer; clouds and scenes load through the asset server; the `render`
//!   feature draws it as lit surfels, and the `rapier` feature lets bevy_rapier3d bodies
//!   and surfaces push each other.
//!
//! Cargo features: `plugin` (default, headless Bevy), `render` (Bevy's renderer), `egui`
//! (a bevy_egui panel), `rapier` (bevy_rapier3d contacts), `cli` (the `point-springs` tool).
//!
//! ```
//! use bevy_point_springs::core::{normals, cloud::shapes};
//!
//! let sphere = shapes::fibonacci_sphere(1000, 1.0);
//! let (estimated, report) = normals::estimate_normals(sphere.positions(), 10).unwrap();
//! assert_eq!(report.components, 1);
//! // Outward, like the exact normals.
//! let agree = estimated.iter().zip(sphere.normals().unwrap()).all(|(a, b)| a.dot(*b) > 0.9);
//! assert!(agree);
//! ```

#![warn(missing_docs, unused_qualifications, missing_debug_implementations)]
#![deny(rustdoc::broken_intra_doc_links, rustdoc::private_intra_doc_links)]
#![forbid(unsafe_code)]

pub mod core;

/// The README's code, compiled as doc tests (its game example needs the renderer, its
/// contact example rapier).
#[cfg(all(doctest, feature = "render", feature = "rapier"))]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

#[cfg(feature = "plugin")]
pub mod plugin;

/// What a game uses, for `use bevy_point_springs::prelude::*`: the plugins, the surface and
/// its settings, its lifecycle events, forces and positions in world space, grabs,
/// attachments, modelling and saved games. Everything else is in [`core`] and `plugin`,
/// under the module that owns it.
pub mod prelude {
    pub use crate::core::pipeline::{PrepareError, SurfaceConfig};
    pub use crate::core::simplify::SimplifyConfig;
    pub use crate::core::solver::SolverConfig;

    // Acting on a surface: grabs, attachments, meeting others, modelling, saved games.
    #[cfg(feature = "plugin")]
    pub use crate::plugin::{
        AttachPoints, GrabMessage, ModelError, ModelMessage, ModelOutcome, SaveGameMessage,
        SaveGameOutcome, SaveName, SurfaceAttachments, SurfaceMeeting,
    };
    // A surface, its state and its settings at run time.
    #[cfg(feature = "plugin")]
    pub use crate::plugin::{
        DeformableSurface, PrepareAgain, SurfaceMaterial, SurfaceRunSettings, SurfaceStatus,
    };
    // A surface's points, forces and drawn surface, in world space too.
    #[cfg(feature = "plugin")]
    pub use crate::plugin::{
        DenseSurface, SimulationPoints, SurfaceForces, SurfaceGravity, SurfacePins, WorldSurfaces,
    };
    // The plugins, and where a game's systems go.
    #[cfg(feature = "plugin")]
    pub use crate::plugin::{PointSpringsPlugin, PointSpringsPlugins, PointSpringsSystems};
    // A surface's lifecycle.
    #[cfg(feature = "plugin")]
    pub use crate::plugin::{SurfaceError, SurfaceFailed, SurfaceReady, SurfaceUnstable};

    #[cfg(feature = "rapier")]
    pub use crate::plugin::contact::SurfaceContact;
    #[cfg(feature = "egui")]
    pub use crate::plugin::panel::SurfacePanel;
    #[cfg(feature = "render")]
    pub use crate::plugin::render::SurfelRender;
}
