//! The simulated lab behind the driver traits: one `vl_sim::World` shared
//! by a robot and a camera, advanced to the wall clock whenever the robot
//! is read, so the simulated robot lives in real time like a real one —
//! except that a Host starved of the processor finds its lab's clock slowed
//! rather than the robot moved on unwatched by a long stride.

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

use image::RgbImage;
use vl_core::{Arena, CameraModel, RobotModel, WheelSpeeds};
use vl_sim::{Optics, SimError, World, camera_for};

use crate::drivers::{Camera, CameraError, Robot, RobotError, RobotReading};

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
}

/// The simulated overhead camera.
pub struct SimCamera {
    world: Arc<Mutex<World>>,
    model: CameraModel,
}

/// A simulated robot and camera on `arena`, with `seed` for the sensor noise.
pub fn sim_lab(
    arena: Arena,
    robot: RobotModel,
    seed: u64,
    camera_width_px: u32,
    fps: f64,
) -> Result<(SimRobot, SimCamera), SimError> {
    let world = World::new(arena, robot.clone(), seed)?;
    let camera = camera_for(&world, camera_width_px, fps);
    let world = Arc::new(Mutex::new(world));
    Ok((
        SimRobot {
            world: world.clone(),
            model: robot,
            since: Instant::now(),
            slipped_s: 0.0,
        },
        SimCamera {
            world,
            model: camera,
        },
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
        Ok(RobotReading {
            pose: world.pose(),
            wheels: world.wheels(),
            proximity: world.proximity(),
            contact: world.contact(),
        })
    }
}

impl Camera for SimCamera {
    fn model(&self) -> CameraModel {
        self.model
    }

    fn grab(&mut self) -> Result<RgbImage, CameraError> {
        Ok(lock(&self.world).render(&self.model, &Optics::default()))
    }
}
