//! The pure core: every algorithm on plain slices, with no Bevy import.
//!
//! Data flows one way (see `DESIGN.md`):
//! file ([`io`]) → [`cloud::PointCloud`] → [`normals`] (PCA over [`knn`] neighbourhoods,
//! consistently oriented) → simplification → spring network → solver → transfer.
//! [`shapes`] builds procedural test surfaces (sphere, hat, sheets); [`surfels`] the disc
//! geometry the renderer draws.

pub mod cloud;
pub mod io;
pub mod knn;
pub mod normals;
pub mod shapes;
pub mod surfels;

pub use cloud::{Aabb, CloudError, PointCloud};
