//! The simulated lab behind the driver traits: one `vl_sim::World` shared
//! by a robot and a camera, advanced to the wall clock whenever the robot
//! is read, so the simulated robot lives in real time like a real one —
//! except that a Host starved of the processor finds its lab's clock slowed
//! rather than the robot moved on unwatched by a long stride.
//!
//! The robot reports what a real one can: odometry from its wheels'
//! travel (which slips), never the world's true pose; the camera renders
//! through its optics and reports the model the lab *believes*. Only the
//! `SimWitness` sees the truth, for judging a run afterwards.

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

use vl_core::{Arena, CameraModel, Pose, RobotModel, WheelSpeeds};
use vl_sim::{Optics, Scheduled, SimError, World};

use crate::drivers::{Camera, CameraError, Captured, Robot, RobotError, RobotReading, Witness};

/// The longest stretch of simulated time one read catches up, s: three
/// control periods.
const MAX_CATCH_UP_S: f64 = 0.03;

/// The simulated robot.
pub struct SimRobot {
    world: Arc<Mutex<World>>,
    model: RobotModel,
    since: Instant,
    /// Wall-clock time the simulation has given up catching up, s.
    slipped_s: f64,
    /// Dead reckoning from the wheels' travel, as a real robot's encoders.
    odometry: Pose,
    travel_mm: [f64; 2],
}

/// The simulated overhead camera.
pub struct RenderedCamera {
    world: Arc<Mutex<World>>,
    /// The camera as built: what renders the frames.
    nominal: CameraModel,
    optics: Optics,
    /// The camera as the lab believes it is (its calibration).
    believed: CameraModel,
}

/// The simulator's knowledge of where the robot truly is.
pub struct SimWitness {
    world: Arc<Mutex<World>>,
}

/// How the simulated camera is set up: `nominal` looks straight down over
/// the arena; `optics` spoil it; the lab believes `believed`.
pub struct SimCameraSetup {
    pub nominal: CameraModel,
    pub optics: Optics,
    pub believed: CameraModel,
}

/// A simulated robot, camera and witness on `arena`, with `seed` for the
/// sensor noise, and what people will do in the lab.
pub fn sim_lab(
    arena: Arena,
    robot: RobotModel,
    seed: u64,
    camera: SimCameraSetup,
    scene: Vec<Scheduled>,
) -> Result<(SimRobot, RenderedCamera, SimWitness), SimError> {
    let start = arena.start;
    let mut world = World::new(arena, robot.clone(), seed)?;
    for event in scene {
        world.schedule(event);
    }
    let world = Arc::new(Mutex::new(world));
    Ok((
        SimRobot {
            world: world.clone(),
            model: robot,
            since: Instant::now(),
            slipped_s: 0.0,
            odometry: start,
            travel_mm: [0.0; 2],
        },
        RenderedCamera {
            world: world.clone(),
            nominal: camera.nominal,
            optics: camera.optics,
            believed: camera.believed,
        },
        SimWitness { world },
    ))
}

/// The world, even if a thread panicked while holding it: the simulator's
/// state is plain data and stays usable.
fn lock(world: &Mutex<World>) -> MutexGuard<'_, World> {
    world
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl Robot for SimRobot {
    fn model(&self) -> &RobotModel {
        &self.model
    }

    fn set_wheels(&mut self, wheels: WheelSpeeds) -> Result<(), RobotError> {
        lock(&self.world).set_wheels(wheels);
        Ok(())
    }

    fn read(&mut self) -> Result<RobotReading, RobotError> {
        let mut world = lock(&self.world);
        let mut now = self.since.elapsed().as_secs_f64() - self.slipped_s;
        if now - world.time_s() > MAX_CATCH_UP_S {
            self.slipped_s += now - world.time_s() - MAX_CATCH_UP_S;
            now = world.time_s() + MAX_CATCH_UP_S;
        }
        while world.time_s() < now {
            world.step();
        }
        let travel = world.wheel_travel_mm();
        let moved = WheelSpeeds {
            left_mm_s: travel[0] - self.travel_mm[0],
            right_mm_s: travel[1] - self.travel_mm[1],
        };
        self.travel_mm = travel;
        self.odometry = self.odometry.advance(moved, self.model.wheel_base_mm, 1.0);
        Ok(RobotReading {
            odometry: self.odometry,
            wheels: world.wheels(),
            proximity: world.proximity(),
            contact: world.contact(),
            taken: Instant::now(),
        })
    }
}

impl Camera for RenderedCamera {
    fn model(&self) -> CameraModel {
        self.believed
    }

    fn grab(&mut self) -> Result<Captured, CameraError> {
        // Rendered from a copy: the control loop must not wait on a frame.
        let world = lock(&self.world).clone();
        Ok(Captured {
            image: world.render(&self.nominal, &self.optics),
            taken: Instant::now(),
        })
    }
}

impl Witness for SimWitness {
    fn true_pose(&mut self) -> Pose {
        lock(&self.world).pose()
    }
}
