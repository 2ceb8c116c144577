//! The pure core: every algorithm on plain slices, with no Bevy import.
//!
//! Data flows one way (see `DESIGN.md`):
//! file ([`io`]) → [`cloud::PointCloud`] → [`normals`] (PCA over [`knn`] neighbourhoods,
//! consistently oriented) → [`denoise`] (noisy scans: decide on local fits) → [`simplify`] (§3, tangent-plane Delaunay [`ring`]s) →
//! [`network`] (§4.1–4.2 springs and masses) → [`solver`] (eq 2–6: forces, integrators,
//! stability) → [`transfer`] (§5: precomputed least-squares coefficients, normals from
//! the fitted gradient; [`resample`] fills stretched regions).
//! [`scene`] describes a whole deformation in a RON file and runs it headless.
//! [`contact`] turns rigid bodies touching simulation points into impulses both ways.
//! [`shapes`] builds procedural test surfaces (sphere, hat, sheets); [`surfels`] the disc
//! geometry the renderer draws.

pub mod cloud;
pub mod contact;
pub mod denoise;
pub mod io;
pub mod knn;
pub mod network;
pub mod normals;
pub mod pipeline;
pub mod resample;
pub mod ring;
pub mod scene;
pub mod shapes;
pub mod simplify;
pub mod solver;
pub mod surfels;
pub mod transfer;

pub use cloud::{Aabb, CloudError, PointCloud};
