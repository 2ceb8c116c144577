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

/// The most used types, for `use bevy_point_springs::prelude::*`.
pub mod prelude {
    pub use crate::core::cloud::io::{CloudFormat, LoadError, PlyEncoding, read_cloud, write_ply};
    pub use crate::core::network::{NetworkConfig, SpringNetwork, build_network};
    pub use crate::core::normals::{NormalSource, ensure_normals, estimate_normals};
    pub use crate::core::pipeline::{
        DenseCloud, ExportError, NormalsSpec, PrepareError, PreparedSurface, SurfaceConfig,
        prepare_surface,
    };
    pub use crate::core::scene::{Scene, SceneError, SceneRun};
    pub use crate::core::simplify::{SimplifyConfig, simplify, simplify_cloud};
    pub use crate::core::solver::{
        Anchor, AnchorId, BendingModel, DampingModel, Instability, InstabilityResponse, Integrator,
        Solver, SolverConfig, SolverError, SpringMaterial, SpringSpec, SubstepPolicy,
    };
    pub use crate::core::transfer::resample::ResampleConfig;
    pub use crate::core::transfer::{NormalUpdate, Transfer, TransferConfig, TransferError};
    pub use crate::core::{Aabb, PointCloud};

    #[cfg(feature = "rapier")]
    pub use crate::plugin::contact::{
        ContactDiagnostics, ContactSolve, SurfaceContact, SurfaceContactPlugin, SurfaceContacts,
    };
    #[cfg(feature = "egui")]
    pub use crate::plugin::panel::{PointSpringsPanelPlugin, SurfacePanel};
    #[cfg(feature = "render")]
    pub use crate::plugin::pick::{PointerGrabSettings, PointerGrabs, SurfacePickingPlugin};
    #[cfg(feature = "render")]
    pub use crate::plugin::render::{
        SpringGizmos, SurfelRender, SurfelRenderPlugin, TransferDevice,
    };
    #[cfg(feature = "plugin")]
    pub use crate::plugin::{
        AttachPoints, AttachmentState, CloudAsset, DeformableSurface, DenseSurface, GrabMessage,
        GrabSettings, Grabs, ModelMessage, ModelOutcome, PointSpringsPlugin, PointSpringsSystems,
        PreparationProgress, PrepareAgain, PrepareAgainFailed, PreviousTick, SaveGameError,
        SaveGameMessage, SaveGameOutcome, SaveName, SceneAsset, SceneTimeline, SimulationPoints,
        StepOnce, SurfaceAnchors, SurfaceAttachments, SurfaceForces, SurfaceHealth, SurfaceInView,
        SurfaceMasses, SurfaceMaterial, SurfaceMeeting, SurfaceMeetingReport, SurfaceNetwork,
        SurfaceSettings, SurfaceSleep, SurfaceSprings, SurfaceStatus, SurfaceStepper,
        SurfaceTimings, SurfaceUnstable, SurfaceWork, TransferTiming,
    };
}
