//! Headless pictures of point clouds: each point a lit disc, orthographic, painted far to
//! near (plotters' bitmap backend, no GPU, no fonts).

use std::path::Path;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::knn::{KnnIndex, SPACING_NEIGHBOURS};
use glam::Vec3;
use plotters::prelude::*;

use crate::failure::Failure;

/// Largest picture side, pixels.
const MAX_PICTURE_SIDE: u32 = 8192;

/// Fraction of the picture left as margin on each side.
const MARGIN: f32 = 0.06;
/// Disc radius as a multiple of the point's spacing (mean distance to its nearest few).
const DISC_SPACING: f32 = 0.9;
/// Smallest disc radius, pixels.
const MIN_DISC_PX: f32 = 1.2;
/// Light: ambient and diffuse shares.
const AMBIENT: f32 = 0.25;
const DIFFUSE: f32 = 0.75;
/// Surface colours of the front and the back (inner) side, linear 0–1.
const FRONT: [f32; 3] = [0.93, 0.62, 0.30];
const BACK: [f32; 3] = [0.35, 0.45, 0.75];

/// How to look at a cloud.
#[derive(Debug, Clone, Copy)]
pub struct View {
    /// Direction from the cloud's centre towards the eye.
    pub from: Vec3,
    /// Up on the picture.
    pub up: Vec3,
    /// Picture size, pixels.
    pub size: (u32, u32),
}

impl View {
    /// A view from `from` with `up` up, on a picture of `size` pixels; a picture too small
    /// or too large, or a view direction zero or parallel to up, is bad input.
    pub fn checked(from: Vec3, up: Vec3, size: (u32, u32)) -> Result<Self, Failure> {
        if !(1..=MAX_PICTURE_SIDE).contains(&size.0) || !(1..=MAX_PICTURE_SIDE).contains(&size.1) {
            return Err(Failure::bad_input(format!(
                "the picture must be between 1 and {MAX_PICTURE_SIDE} pixels on each side"
            )));
        }
        if from.length_squared() == 0.0 || up.cross(from).length_squared() == 0.0 {
            return Err(Failure::bad_input(
                "the view direction must be non-zero and not parallel to up",
            ));
        }
        Ok(Self { from, up, size })
    }
}

/// What was drawn.
#[derive(Debug, Clone, Copy)]
pub struct Drawn {
    /// Points drawn.
    pub points: usize,
    /// Disc radius, pixels.
    pub disc_px: f32,
}

/// Draws `clouds` (with normals) side by side to a PNG at `path`, all at one scale and
/// centred on the box that holds them all (so a rest shape and its deformation compare).
/// The file is written to a temporary file and renamed into place.
pub fn render(clouds: &[&PointCloud], view: &View, path: &Path) -> Result<Drawn, String> {
    let mut drawn = None;
    bevy_point_springs::core::cloud::io::write_atomically_to_path(path, |tmp| {
        drawn = Some(draw(clouds, view, tmp)?);
        Ok(())
    })
    .map_err(|e| e.to_string())?;
    drawn.ok_or_else(|| "nothing was drawn".to_owned())
}

/// [`render`]'s drawing, to `path` directly.
fn draw(clouds: &[&PointCloud], view: &View, path: &Path) -> Result<Drawn, String> {
    if clouds.is_empty() {
        return Err("nothing to draw".into());
    }
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for cloud in clouds {
        let b = cloud.bounds().ok_or("a cloud is empty")?;
        lo = lo.min(b.min);
        hi = hi.max(b.max);
    }
    let centre = 0.5 * (lo + hi);
    let w = view
        .from
        .try_normalize()
        .ok_or("the view direction is zero")?;
    let u = view
        .up
        .cross(w)
        .try_normalize()
        .ok_or("the up direction is parallel to the view")?;
    let v = w.cross(u);
    // Scale: the common box's corners must fit in one panel.
    let (mut half_x, mut half_y) = (0.0f32, 0.0f32);
    for i in 0..8 {
        let c = Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        ) - centre;
        half_x = half_x.max(c.dot(u).abs());
        half_y = half_y.max(c.dot(v).abs());
    }
    let panel_w = view.size.0 as f32 / clouds.len() as f32;
    let height = view.size.1 as f32;
    let usable = 1.0 - 2.0 * MARGIN;
    let scale = (usable * panel_w / (2.0 * half_x.max(f32::MIN_POSITIVE)))
        .min(usable * height / (2.0 * half_y.max(f32::MIN_POSITIVE)));
    let light = (w + 0.6 * v + 0.4 * u).normalize();
    let root = BitMapBackend::new(path, view.size).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let mut drawn = Drawn {
        points: 0,
        disc_px: f32::INFINITY,
    };
    for (panel, cloud) in clouds.iter().enumerate() {
        let positions = cloud.positions();
        let normals = cloud
            .normals()
            .ok_or("a cloud has no normals to light it with")?;
        // Each disc as wide as its own neighbourhood: stretched regions get larger discs.
        let mut spacing = KnnIndex::build(positions)
            .knn_graph(positions, SPACING_NEIGHBOURS)
            .mean_distances();
        spacing.resize(positions.len(), 0.0);
        let radius: Vec<f32> = spacing
            .iter()
            .map(|s| (DISC_SPACING * s * scale).max(MIN_DISC_PX))
            .collect();
        let mut order: Vec<usize> = (0..positions.len()).collect();
        let depth = |i: usize| (positions[i] - centre).dot(w);
        order.sort_by(|&a, &b| depth(a).total_cmp(&depth(b)));
        let x0 = panel_w * (panel as f32 + 0.5);
        for i in order {
            let d = positions[i] - centre;
            let x = x0 + d.dot(u) * scale;
            let y = height * 0.5 - d.dot(v) * scale;
            let n = normals[i];
            // A normal facing away from the eye shows the surface's other side.
            let (n, base) = if n.dot(w) >= 0.0 {
                (n, FRONT)
            } else {
                (-n, BACK)
            };
            let shade = AMBIENT + DIFFUSE * n.dot(light).max(0.0);
            let [r, g, b] = base.map(|c| (255.0 * (c * shade).clamp(0.0, 1.0)) as u8);
            root.draw(&Circle::new(
                (x.round() as i32, y.round() as i32),
                radius[i].round().max(1.0) as i32,
                RGBColor(r, g, b).filled(),
            ))
            .map_err(|e| e.to_string())?;
        }
        drawn.points += positions.len();
        drawn.disc_px = radius.iter().copied().fold(drawn.disc_px, f32::min);
    }
    root.present().map_err(|e| e.to_string())?;
    Ok(drawn)
}
