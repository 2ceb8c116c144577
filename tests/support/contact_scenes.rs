//! Headless games for contact (issue 64), the way the README says to write them: rapier in
//! the fixed schedule, a rapier floor, crates (rapier cuboids) dropped on surfaces lying on
//! it, one `update()` a tick. Each tick is measured as a player would see it: the total
//! mechanical energy of bodies and points, the fastest crate and point, how low the
//! surfaces' points go and how close the crates come to the floor. Included by path by
//! `tests/contact_scenes.rs`.

use std::path::Path;
use std::time::{Duration, Instant};

use bevy::ecs::system::RunSystemOnce;
use bevy::prelude::*;
use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::cloud::shapes;
use bevy_point_springs::core::pipeline::SurfaceConfig;
use bevy_point_springs::core::simplify::SimplifyConfig;
use bevy_point_springs::core::solver::{Integrator, SpringMaterial, StepParts};
use bevy_point_springs::plugin::{
    SurfaceAnchors, SurfaceContacts, SurfaceMasses, SurfaceNetwork, SurfacePressure,
    SurfaceSprings, SurfaceStepper,
};
use bevy_point_springs::prelude::*;
use bevy_rapier3d::prelude::*;

use super::rapier_app;

/// Upper bound on waiting for preparation (a hang guard, not a speed check).
const SETTLE_TIMEOUT: Duration = Duration::from_secs(300);

/// Gravity, m/s², along −Y: rapier's and the surfaces'.
pub const G: f32 = 9.81;

/// The floor's top, metres up.
pub const FLOOR_TOP: f32 = 0.0;

/// A crate's side, metres (a 0.2 m cube).
pub const CRATE_SIDE: f32 = 0.2;

/// A crate dropped in a scene.
#[derive(Debug, Clone, Copy)]
pub struct Crate {
    pub entity: Entity,
    /// Its centre's height when dropped.
    pub start: f32,
}

/// What one tick looked like.
#[derive(Debug, Clone, Copy, Default)]
pub struct Tick {
    /// Kinetic and gravitational energy of crates and points (zero at the floor's top), and
    /// the surfaces' elastic and gas energy, J.
    pub energy: f64,
    /// Each crate's speed, m/s (up to 3 crates).
    pub crate_speed: [f32; 3],
    /// Each crate's centre height (up to 3 crates).
    pub crate_height: [f32; 3],
    /// The lowest corner of any crate, above the floor's top.
    pub crate_clearance: f32,
    /// The fastest simulation point of any surface, m/s.
    pub point_speed: f32,
    /// The lowest simulation point's centre of any surface, above the floor's top.
    pub lowest_point: f32,
}

/// A scene: the app, its surfaces and its crates.
pub struct Scene {
    pub app: App,
    pub surfaces: Vec<Entity>,
    pub crates: Vec<Crate>,
    /// Every tick measured so far.
    pub ticks: Vec<Tick>,
}

impl Scene {
    /// The app with rapier's gravity and a floor 10 m square whose top is at
    /// [`FLOOR_TOP`].
    pub fn new() -> Self {
        let mut app = rapier_app::create_app();
        let mut config = app
            .world_mut()
            .query::<&mut RapierConfiguration>()
            .single_mut(app.world_mut())
            .unwrap();
        config.gravity = Vec3::new(0.0, -G, 0.0);
        app.world_mut().spawn((
            RigidBody::Fixed,
            Collider::cuboid(5.0, 0.1, 5.0),
            Transform::from_xyz(0.0, FLOOR_TOP - 0.1, 0.0),
        ));
        Self {
            app,
            surfaces: Vec::new(),
            crates: Vec::new(),
            ticks: Vec::new(),
        }
    }

    /// Sets rapier's solver iterations (`IntegrationParameters::num_solver_iterations`,
    /// 4 by default).
    pub fn solver_iterations(&mut self, iterations: usize) {
        let world = self.app.world_mut();
        let mut simulation = world
            .query::<&mut RapierContextSimulation>()
            .single_mut(world)
            .unwrap();
        simulation.integration_parameters.num_solver_iterations = iterations;
    }

    /// A square cloth of `side` metres at `simulation` points (the default material),
    /// meeting itself, lying flat (its cloud's XY plane turned onto the floor) with its
    /// points' spheres just off the floor; ready when this returns.
    pub fn cloth(&mut self, side: f32, simulation: usize) -> Entity {
        let config = SurfaceConfig {
            simplify: SimplifyConfig::target(simulation),
            ..default()
        };
        let cloud = shapes::square_sheet(side, 0.02 * side);
        let turn = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
        let cloth = self
            .app
            .world_mut()
            .spawn((
                DeformableSurface::cloud(cloud, config),
                SurfaceMeeting::default(),
                Transform::from_xyz(0.0, FLOOR_TOP + 0.5 * 0.06 * side, 0.0).with_rotation(turn),
            ))
            .id();
        self.ready(cloth);
        cloth
    }

    /// The playground's ball of gas (`assets/sphere3203.ply`, a unit sphere, 338 simulation
    /// points, its settings) resting on the floor at `x`, its bottom at `bottom` above it;
    /// ready when this returns.
    pub fn gas_ball(&mut self, x: f32, bottom: f32, radius: f32) -> Entity {
        let config = SurfaceConfig {
            simplify: SimplifyConfig::target(338),
            material: SpringMaterial {
                stretch_stiffness: 60.0,
                bend_stiffness: 60.0,
                stretch_damping: 0.6,
                bend_damping: 0.3,
                ..default()
            },
            pressure: Some(1000.0),
            solver: SolverConfig {
                integrator: Integrator::ImplicitEuler,
                drag: 2.0,
                ..default()
            },
            ..default()
        };
        self.ball(
            "sphere3203.ply",
            radius,
            config,
            Vec3::new(x, FLOOR_TOP + bottom + radius, 0.0),
        )
    }

    /// CGAL's scanned sphere (`assets/sphere926.pwn`: 926 points and their normals, radius
    /// 10) scaled to `radius`, of `material`, filled with gas of stiffness `pressure` (Pa),
    /// 300 simulation points, meeting itself, its bottom `bottom` above the floor; ready
    /// when this returns.
    pub fn scan_ball(
        &mut self,
        bottom: f32,
        radius: f32,
        material: SpringMaterial,
        pressure: f32,
    ) -> Entity {
        let config = SurfaceConfig {
            simplify: SimplifyConfig::target(300),
            material,
            pressure: Some(pressure),
            ..default()
        };
        self.ball(
            "sphere926.pwn",
            0.1 * radius,
            config,
            Vec3::new(0.0, FLOOR_TOP + bottom + radius, 0.0),
        )
    }

    /// The height of the highest simulation point of `surface` within `half` of the
    /// vertical through `(x, z)`, world coordinates.
    pub fn top_near(&self, surface: Entity, (x, z): (f32, f32), half: f32) -> f32 {
        let world = self.app.world();
        let points = world.get::<SimulationPoints>(surface).unwrap();
        let place = world.get::<GlobalTransform>(surface).unwrap();
        (0..points.len())
            .map(|i| place.transform_point(points.position(i)))
            .filter(|p| (p.x - x).abs() < half && (p.z - z).abs() < half)
            .map(|p| p.y)
            .fold(f32::NEG_INFINITY, f32::max)
    }

    /// A ball from `assets/{file}` scaled by `scale`, meeting itself, its middle at `at`;
    /// ready when this returns.
    fn ball(&mut self, file: &str, scale: f32, config: SurfaceConfig, at: Vec3) -> Entity {
        let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
        let (positions, normals) = read_cloud(&assets.join(file), None).unwrap().into_parts();
        let positions = positions.into_iter().map(|p| p * scale).collect();
        let cloud = bevy_point_springs::core::PointCloud::new(positions, normals).unwrap();
        let ball = self
            .app
            .world_mut()
            .spawn((
                DeformableSurface::cloud(cloud, config),
                SurfaceMeeting::default(),
                Transform::from_translation(at),
            ))
            .id();
        self.ready(ball);
        ball
    }

    fn ready(&mut self, surface: Entity) {
        let deadline = Instant::now() + SETTLE_TIMEOUT;
        loop {
            match self.app.world().get::<SurfaceStatus>(surface).unwrap() {
                SurfaceStatus::Ready => break,
                SurfaceStatus::Failed(why) => panic!("{why}"),
                _ => {}
            }
            assert!(Instant::now() < deadline, "the surface did not get ready");
            self.app.update();
            std::thread::sleep(Duration::from_millis(1));
        }
        self.surfaces.push(surface);
    }

    /// A crate of `mass` kg, its centre at `at`, at rest, turned by `turn`.
    pub fn drop_crate(&mut self, at: Vec3, turn: Quat, mass: f32) -> Crate {
        let half = 0.5 * CRATE_SIDE;
        let entity = self
            .app
            .world_mut()
            .spawn((
                RigidBody::Dynamic,
                Collider::cuboid(half, half, half),
                ColliderMassProperties::Mass(mass),
                Velocity::zero(),
                ReadMassProperties::default(),
                Transform::from_translation(at).with_rotation(turn),
            ))
            .id();
        let dropped = Crate {
            entity,
            start: at.y,
        };
        self.crates.push(dropped);
        dropped
    }

    /// Runs `ticks` ticks, measuring each (and printing each when the environment has
    /// `CONTACT_SCENES_TRACE`).
    pub fn run(&mut self, ticks: usize) {
        let trace = std::env::var_os("CONTACT_SCENES_TRACE").is_some();
        for _ in 0..ticks {
            self.app.update();
            let tick = self.measure();
            if trace {
                let diagnostics = |s: Entity| {
                    *self
                        .app
                        .world()
                        .get::<SurfaceStepper>(s)
                        .unwrap()
                        .diagnostics()
                };
                let trips: u64 = self
                    .surfaces
                    .iter()
                    .map(|&s| diagnostics(s).guard_trips)
                    .sum();
                let cg: u32 = self
                    .surfaces
                    .iter()
                    .map(|&s| diagnostics(s).last.cg_iterations)
                    .sum();
                for &s in &self.surfaces {
                    if diagnostics(s).last.recovered {
                        println!("  guard: {:?}", diagnostics(s).last);
                    }
                }
                println!(
                    "tick {:4} energy {:9.4} crate {:7.4} m/s at {:7.4} clearance {:7.4} \
                     points {:7.4} m/s lowest {:7.4} trips {trips} cg {cg}",
                    self.ticks.len(),
                    tick.energy,
                    tick.crate_speed[0],
                    tick.crate_height[0],
                    tick.crate_clearance,
                    tick.point_speed,
                    tick.lowest_point,
                );
            }
            self.ticks.push(tick);
        }
    }

    /// This tick, measured.
    pub fn measure(&mut self) -> Tick {
        let mut tick = Tick {
            crate_clearance: f32::INFINITY,
            lowest_point: f32::INFINITY,
            ..default()
        };
        for &surface in &self.surfaces {
            let s = surface_state(&mut self.app, surface);
            tick.energy += s.energy;
            tick.point_speed = tick.point_speed.max(s.fastest);
            tick.lowest_point = tick.lowest_point.min(s.lowest - FLOOR_TOP);
        }
        let crates = self.crates.clone();
        for (k, c) in crates.iter().enumerate() {
            let (energy, speed, height, lowest) = crate_state(&mut self.app, c);
            tick.energy += energy;
            if k < 3 {
                tick.crate_speed[k] = speed;
                tick.crate_height[k] = height;
            }
            tick.crate_clearance = tick.crate_clearance.min(lowest - FLOOR_TOP);
        }
        tick
    }

    /// The largest rise of the energy above its value at tick `from`, J.
    pub fn energy_rise(&self, from: usize) -> f64 {
        let start = self.ticks[from].energy;
        self.ticks[from..]
            .iter()
            .map(|t| t.energy - start)
            .fold(0.0, f64::max)
    }

    /// Crate `k`'s fastest speed from tick `from` on, and the speed of its fall: what
    /// falling from its start to the lowest its centre went gives.
    pub fn crate_speeds(&self, k: usize, from: usize) -> (f32, f32) {
        let fastest = self.ticks[from..]
            .iter()
            .map(|t| t.crate_speed[k])
            .fold(0.0, f32::max);
        let lowest = self.ticks[from..]
            .iter()
            .map(|t| t.crate_height[k])
            .fold(f32::INFINITY, f32::min);
        let fall = (2.0 * G * (self.crates[k].start - lowest).max(0.0)).sqrt();
        (fastest, fall)
    }

    /// The fastest point and crate over ticks `from..`.
    pub fn fastest_after(&self, from: usize) -> (f32, f32) {
        self.ticks[from..].iter().fold((0.0, 0.0), |(p, c), t| {
            let crates = t.crate_speed.iter().copied().fold(0.0, f32::max);
            (f32::max(p, t.point_speed), f32::max(c, crates))
        })
    }

    /// The lowest any point and any crate corner came, over ticks `from..`.
    pub fn lowest_after(&self, from: usize) -> (f32, f32) {
        self.ticks[from..]
            .iter()
            .fold((f32::INFINITY, f32::INFINITY), |(p, c), t| {
                (p.min(t.lowest_point), c.min(t.crate_clearance))
            })
    }

    /// The mean sphere radius of a surface's simulation points (its thickness is twice it).
    pub fn mean_radius(&self, surface: Entity) -> f32 {
        let radii = self
            .app
            .world()
            .get::<SurfaceContacts>(surface)
            .unwrap()
            .radii();
        radii.iter().sum::<f32>() / radii.len() as f32
    }
}

/// A surface's mechanical energy (kinetic and gravitational in the world, zero at the
/// floor's top; springs, bending and gas as the stepper counts them), its fastest point
/// and its lowest point, in world coordinates.
struct SurfaceState {
    energy: f64,
    fastest: f32,
    lowest: f32,
}

/// What [`surface_state`] reads of a surface.
type SurfaceParts = (
    &'static GlobalTransform,
    &'static SimulationPoints,
    &'static SurfaceMasses,
    &'static SurfaceSprings,
    &'static SurfaceAnchors,
    Option<&'static SurfacePressure>,
    &'static SurfaceNetwork,
    &'static SurfaceStepper,
);

fn surface_state(app: &mut App, surface: Entity) -> SurfaceState {
    app.world_mut()
        .run_system_once(move |q: Query<SurfaceParts>| {
            let (place, points, masses, springs, anchors, pressure, network, stepper) =
                q.get(surface).unwrap();
            let parts = StepParts {
                masses,
                springs,
                anchors,
                pressure: pressure.map(|p| &**p),
                rest: Some(&network.positions),
            };
            let own = stepper.energy(points, parts);
            let mut energy = own.spring + own.bending + own.anchor + own.pressure;
            let (mut fastest, mut lowest) = (0.0_f32, f32::INFINITY);
            for i in 0..points.len() {
                let at = place.transform_point(points.position(i));
                let v = place.affine().transform_vector3(points.velocity(i));
                lowest = lowest.min(at.y);
                fastest = fastest.max(v.length());
                if masses.is_pinned(i) {
                    continue;
                }
                let m = f64::from(masses.mass(i));
                energy += 0.5 * m * f64::from(v.length_squared())
                    + m * f64::from(G) * f64::from(at.y - FLOOR_TOP);
            }
            if std::env::var_os("CONTACT_SCENES_TRACE").is_some() {
                println!(
                    "  surface spring {:.4} bending {:.4} gas {:.4} anchor {:.4} all {:.4}",
                    own.spring, own.bending, own.pressure, own.anchor, energy
                );
            }
            SurfaceState {
                energy,
                fastest,
                lowest,
            }
        })
        .unwrap()
}

/// A crate's kinetic and gravitational energy (zero at the floor's top), speed, centre
/// height and lowest corner.
fn crate_state(app: &mut App, c: &Crate) -> (f64, f32, f32, f32) {
    let entity = c.entity;
    app.world_mut()
        .run_system_once(move |rapier: ReadRapierContext, q: Query<&Transform>| {
            let context = rapier.single().unwrap();
            let handle = context.rigidbody_set.entity2body()[&entity];
            let body = &context.rigidbody_set.bodies[handle];
            let place = q.get(entity).unwrap();
            let half = 0.5 * CRATE_SIDE;
            let lowest = [-half, half]
                .into_iter()
                .flat_map(|x| [-half, half].map(|y| Vec3::new(x, y, 0.0)))
                .flat_map(|p| [-half, half].map(|z| Vec3::new(p.x, p.y, z)))
                .map(|corner| place.transform_point(corner).y)
                .fold(f32::INFINITY, f32::min);
            let height = body.center_of_mass().y;
            let energy = f64::from(body.kinetic_energy())
                + f64::from(body.mass()) * f64::from(G) * f64::from(height - FLOOR_TOP);
            if std::env::var_os("CONTACT_SCENES_TRACE").is_some() {
                println!(
                    "  crate at {:.4} moving {:.4} turning {:.4}",
                    body.center_of_mass(),
                    body.linvel(),
                    body.angvel()
                );
            }
            (energy, body.linvel().length(), height, lowest)
        })
        .unwrap()
}
