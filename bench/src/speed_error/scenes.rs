//! The four fixed scenes of `point-springs-bench report`: the paper's sphere pressed and held, the hat
//! sagging from its rim, a square sheet sagging from its edges, and the kitten scan pulled
//! by its head. Each is a [`Scene`] built for a simplification level, an integrator and a
//! step, so that its pulls keep their timing in seconds whatever the step.

use std::path::{Path, PathBuf};

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::cloud::shapes::{fibonacci_sphere, hat, square_sheet};
use bevy_point_springs::core::scene::{Pull, Region, Scene, level_target};
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::core::solver::{
    BendingModel, DampingModel, Integrator, MaterialUnits, SolverConfig, SpringMaterial,
};
use glam::Vec3;
use serde::Serialize;

use crate::failure::Failure;

/// The real scan, relative to `--assets`.
const SCAN: &str = "kitten.off";

/// Gravity's magnitude, m/s².
const GRAVITY: f32 = 9.81;

/// Viscous drag of every scene, 1/s (the runs settle within their time).
const DRAG: f32 = 2.0;

/// Seconds over which a pull moves its points to their held place.
const RAMP_S: f32 = 1.0;

/// Gas pressure κ inside the sphere, N/m² (see `Pressure`).
const SPHERE_GAS: f32 = 100.0;

/// The material of every scene, in a sheet's units so that every level models the same
/// sheet (see `MaterialUnits::Sheet`): stretch and bend moduli 70 N/m, damping ratios 0.3,
/// bending as `bending` says (hinges of the default flexural rigidity).
fn material(density: f32, bending: BendingModel) -> SpringMaterial {
    SpringMaterial {
        density,
        bending,
        units: MaterialUnits::Sheet,
        stretch_stiffness: 70.0,
        bend_stiffness: 70.0,
        stretch_damping: 0.3,
        bend_damping: 0.3,
        ..SpringMaterial::default()
    }
}

/// A scene of the report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum ReportScene {
    /// The sphere of Fig. 5 (3203 points) with gas inside, held below y = −0.6, its top
    /// pressed 0.3 in over a second and held there (a sustained poke).
    Sphere,
    /// The hat of Fig. 6 (3000 points), held at its rim, sagging under gravity (ρ = 1).
    Hat,
    /// A 2 × 2 square sheet (2929 points), held along its edges, sagging under gravity.
    Sheet,
    /// The kitten scan (5210 points, uneven density, normals estimated), held at its feet,
    /// the top of its head pulled 0.08 sideways over a second and held there.
    Kitten,
}

impl ReportScene {
    /// Every scene, in the report's order.
    pub const ALL: [Self; 4] = [Self::Sphere, Self::Hat, Self::Sheet, Self::Kitten];

    /// The name in tables and file names.
    pub fn name(self) -> &'static str {
        match self {
            Self::Sphere => "sphere",
            Self::Hat => "hat",
            Self::Sheet => "sheet",
            Self::Kitten => "kitten",
        }
    }

    /// The dense cloud: generated, or the scan read from `assets`.
    pub fn cloud(self, assets: &Path) -> Result<PointCloud, Failure> {
        Ok(match self {
            Self::Sphere => fibonacci_sphere(3203, 1.0),
            Self::Hat => hat(3000, 1.0, -0.2),
            Self::Sheet => square_sheet(2.0, 0.04),
            Self::Kitten => {
                let path = assets.join(SCAN);
                read_cloud(&path, None).map_err(|e| {
                    Failure::bad_input(format!(
                        "{e} (give --assets, or run from the repository root)"
                    ))
                })?
            }
        })
    }

    /// The scene on `cloud` at `fraction` of its points, bending as `bending` says, stepped
    /// by `integrator` at `dt` for `seconds`.
    pub fn scene(
        self,
        cloud: &PointCloud,
        fraction: f32,
        bending: BendingModel,
        integrator: Integrator,
        dt: f32,
        seconds: f32,
    ) -> Scene {
        let target = level_target(cloud.len(), fraction);
        let ramp = ((RAMP_S / dt).round() as usize).max(1);
        let (material, gravity, pressure, pins, pulls) = match self {
            Self::Sphere => (
                material(0.2, bending),
                Vec3::ZERO,
                Some(SPHERE_GAS),
                vec![Region::Box {
                    min: Vec3::splat(-2.0),
                    max: Vec3::new(2.0, -0.6, 2.0),
                }],
                held_pull(Vec3::Y, 0.3, Vec3::Y * 0.7, ramp),
            ),
            Self::Hat => (
                material(1.0, bending),
                Vec3::NEG_Y * GRAVITY,
                None,
                vec![Region::Box {
                    min: Vec3::new(-2.0, -0.25, -2.0),
                    max: Vec3::new(2.0, 0.0, 2.0),
                }],
                Vec::new(),
            ),
            Self::Sheet => (
                material(1.0, bending),
                Vec3::NEG_Z * GRAVITY,
                None,
                sheet_edges(0.95),
                Vec::new(),
            ),
            Self::Kitten => {
                let top = cloud
                    .positions()
                    .iter()
                    .copied()
                    .max_by(|a, b| a.y.total_cmp(&b.y))
                    .unwrap_or(Vec3::Y);
                let feet = cloud
                    .positions()
                    .iter()
                    .map(|p| p.y)
                    .fold(f32::INFINITY, f32::min);
                (
                    material(1.0, bending),
                    Vec3::ZERO,
                    None,
                    vec![Region::Box {
                        min: Vec3::new(-2.0, feet - 1.0, -2.0),
                        max: Vec3::new(2.0, feet + 0.08, 2.0),
                    }],
                    held_pull(top, 0.12, top + Vec3::X * 0.08, ramp),
                )
            }
        };
        Scene {
            cloud: PathBuf::from(format!("<{} of {} points>", self.name(), cloud.len())),
            normals: Default::default(),
            simplify: SimplifyConfig::target(target),
            material,
            solver: SolverConfig {
                integrator,
                // Eq 3's damping, which explicit Euler needs (with axial damping it hands
                // over to implicit Euler, and its rows would time implicit Euler).
                damping_model: DampingModel::Relative,
                gravity,
                drag: DRAG,
                ..SolverConfig::default()
            },
            transfer: Default::default(),
            resample: None,
            pressure,
            dt,
            steps: ((seconds / dt).round() as usize).max(1),
            pins,
            pulls,
            error_budget: None,
        }
    }
}

/// The points within `radius` of `at` pulled to `to` over `ramp` steps, then held there.
fn held_pull(at: Vec3, radius: f32, to: Vec3, ramp: usize) -> Vec<Pull> {
    let pull = Pull {
        at,
        radius: Some(radius),
        to: at,
        to_end: Some(to),
        stiffness: 300.0,
        damping: 1.0,
        start: 0,
        end: Some(ramp),
    };
    vec![
        pull,
        Pull {
            to,
            to_end: None,
            start: ramp,
            end: None,
            ..pull
        },
    ]
}

/// The four edges of the 2 × 2 sheet: points with |x| or |y| at least `inner`.
fn sheet_edges(inner: f32) -> Vec<Region> {
    let (lo, hi) = (-2.0, 2.0);
    vec![
        Region::Box {
            min: Vec3::new(lo, lo, -1.0),
            max: Vec3::new(-inner, hi, 1.0),
        },
        Region::Box {
            min: Vec3::new(inner, lo, -1.0),
            max: Vec3::new(hi, hi, 1.0),
        },
        Region::Box {
            min: Vec3::new(lo, lo, -1.0),
            max: Vec3::new(hi, -inner, 1.0),
        },
        Region::Box {
            min: Vec3::new(lo, inner, -1.0),
            max: Vec3::new(hi, hi, 1.0),
        },
    ]
}
