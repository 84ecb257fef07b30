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

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

use vl_core::{Arena, CameraModel, Leash, Pose, RobotModel, WheelSpeeds};
use vl_sim::{Optics, Renderer, Scheduled, SimError, World};

use crate::drivers::{Camera, CameraError, Captured, Robot, RobotError, RobotReading, Witness};

/// The longest stretch of simulated time one read catches up, s: three
/// control periods.
const MAX_CATCH_UP_S: f64 = 0.03;

/// The simulated robot.
pub(crate) struct SimRobot {
    world: Arc<Mutex<World>>,
    model: RobotModel,
    since: Instant,
    /// Wall-clock time the simulation has given up catching up, s.
    slipped_s: f64,
    /// Dead reckoning from the wheels' travel, as a real robot's encoders.
    odometry: Pose,
    travel_mm: [f64; 2],
}

/// The simulated overhead camera: a thread of its own exposes a frame
/// every period, as a real camera does whether anyone looks or not; each
/// arrives the optics' delay later, and some never do.
pub(crate) struct RenderedCamera {
    shared: Arc<InFlight>,
    /// The camera as the lab believes it is (its calibration).
    believed: CameraModel,
    delay: Duration,
}

/// Frames exposed and not yet taken, oldest first.
struct InFlight {
    frames: Mutex<VecDeque<Captured>>,
    exposed: Condvar,
}

/// Frames kept in flight at most: a second's worth at 15 fps.
const IN_FLIGHT: usize = 16;

impl RenderedCamera {
    fn start(world: Arc<Mutex<World>>, setup: SimCameraSetup) -> RenderedCamera {
        let shared = Arc::new(InFlight {
            frames: Mutex::new(VecDeque::new()),
            exposed: Condvar::new(),
        });
        let period = Duration::from_secs_f64(1.0 / setup.believed.fps.max(1.0));
        let optics = setup.optics;
        let mut renderer = Renderer::new(setup.nominal, optics);
        let mut rng = Pcg64Mcg::seed_from_u64(optics.seed ^ 0xD205);
        let exposing = shared.clone();
        std::thread::Builder::new()
            .name("vl-sim-camera".into())
            .spawn(move || {
                let mut next = Instant::now();
                // Ends when the camera is dropped.
                while Arc::strong_count(&exposing) > 1 {
                    // Rendered from a copy: the robot's clock must not wait on a frame.
                    let world = lock(&world).clone();
                    let taken = Instant::now();
                    let image = renderer.render(&world);
                    if rng.random::<f64>() >= optics.drop_rate {
                        let mut frames = lock(&exposing.frames);
                        frames.push_back(Captured { image, taken });
                        while frames.len() > IN_FLIGHT {
                            frames.pop_front();
                        }
                        exposing.exposed.notify_all();
                    }
                    next += period;
                    let now = Instant::now();
                    if next < now {
                        next = now;
                    }
                    std::thread::sleep(next - now);
                }
            })
            .expect("the OS starts a thread");
        RenderedCamera {
            shared,
            believed: setup.believed,
            delay: Duration::from_secs_f64(optics.delay_s),
        }
    }
}

/// The simulator's knowledge of where the robot truly is.
pub(crate) struct SimWitness {
    world: Arc<Mutex<World>>,
}

/// How the simulated camera is set up: `nominal` looks straight down over
/// the arena; `optics` spoil it; the lab believes `believed`.
pub(crate) struct SimCameraSetup {
    pub nominal: CameraModel,
    pub optics: Optics,
    pub believed: CameraModel,
}

/// A simulated robot, camera and witness on `arena`, with `seed` for the
/// sensor noise, and what people will do in the lab.
pub(crate) fn sim_lab(
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
        RenderedCamera::start(world.clone(), camera),
        SimWitness { world },
    ))
}

/// The world (or the frames), even if a thread panicked while holding
/// it: the simulator's state is plain data and stays usable.
fn lock<T>(shared: &Mutex<T>) -> MutexGuard<'_, T> {
    shared
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl Robot for SimRobot {
    fn model(&self) -> &RobotModel {
        &self.model
    }

    fn drive(&mut self, leash: &Leash) -> Result<(), RobotError> {
        lock(&self.world).drive(leash, self.travel_mm);
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
            travel_mm: travel,
            taken: Instant::now(),
        })
    }
}

impl Camera for RenderedCamera {
    fn model(&self) -> CameraModel {
        self.believed
    }

    fn grab(&mut self) -> Result<Captured, CameraError> {
        let deadline = Instant::now() + Duration::from_secs(1) + self.delay;
        let mut frames = lock(&self.shared.frames);
        loop {
            // The newest frame that has arrived; older ones are passed over.
            let arrived = frames.iter().rposition(|f| f.taken.elapsed() >= self.delay);
            if let Some(newest) = arrived {
                frames.drain(..newest);
                return Ok(frames.pop_front().expect("found above"));
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(CameraError::Silent(
                    "the simulated camera sends no frames".into(),
                ));
            }
            let wait = frames.front().map_or(deadline - now, |f| {
                self.delay.saturating_sub(f.taken.elapsed())
            });
            frames = self
                .shared
                .exposed
                .wait_timeout(frames, wait.max(Duration::from_millis(1)))
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }
}

impl Witness for SimWitness {
    fn true_pose(&mut self) -> Pose {
        lock(&self.world).pose()
    }
}
