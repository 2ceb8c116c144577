//! The pure core: every algorithm on plain slices, with no Bevy import.
//!
//! The folders are the method's stages, in the order data flows through them
//! (`docs/ARCHITECTURE.md` draws it):
//!
//! 1. [`cloud`]: the dense surface, shared by every stage: [`PointCloud`] and its checks,
//!    the file readers and writers ([`cloud::io`]), nearest-neighbour search
//!    ([`cloud::knn`]), procedural surfaces ([`cloud::shapes`]) and the surfel discs the
//!    renderer draws ([`cloud::surfels`]).
//! 2. [`normals`]: PCA normals, consistently oriented; normals from a mesh file's faces;
//!    [`normals::denoise`] decides on local fits for noisy scans.
//! 3. [`simplify`]: §3, the tangent-plane Delaunay test
//!    ([`simplify::tangent_delaunay`]) that picks the simulation points.
//! 4. [`network`]: §4.1–4.2, one triangle network over the simulation points, its
//!    stretch and bend springs and its masses.
//! 5. [`solver`]: eq 2–6, forces, three integrators, stability guards,
//!    [`solver::contact`] for rigid bodies touching the surface, and the standard cloth
//!    benchmark's network ([`solver::cloth`]) the solver is tested on.
//! 6. [`transfer`]: §5, the motion carried back to every dense point with its normal;
//!    [`transfer::resample`] fills regions the motion stretched.
//!
//! [`pipeline`] runs stages 1–4 and owns the state of 5–6 for one surface (the CLI, the
//! benches and the plugin all call it); [`scene`] describes a whole deformation in a RON
//! file and runs it headless. The baselines the benchmarks compare against (the
//! straightforward cloth loop, the paper's literal per-frame transfer) are not here: they
//! live in the `point-springs-bench` crate (`bench/`).

pub mod cloud;
pub mod network;
pub mod normals;
pub mod pipeline;
pub mod scene;
pub mod simplify;
pub mod solver;
pub mod transfer;

pub use cloud::{Aabb, CloudError, PointCloud};
