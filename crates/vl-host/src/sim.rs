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
use vl_sim::{Optics, OpticsPreset, Renderer, Scheduled, SimError, World};

use crate::drivers::{Camera, CameraError, Captured, Robot, RobotError, RobotReading, Witness};

/// The simulated camera's optics, as `vl host`, `vl sim` and `vl camera`
/// take them from flags.
#[derive(Debug, Clone, clap::Args)]
pub struct OpticsSettings {
    /// Optics to start from: none (an ideal camera looking straight
    /// down), noisy (a cheap webcam: offset, blur, noise, uneven light) or
    /// realistic (noisy, a wide lens, 80 ms late, motion blur, 5 % lost).
    #[arg(long, value_parser = vl_core::named_parser::<OpticsPreset>(), default_value = "none")]
    optics: OpticsPreset,
    /// Image shift in px, as DX,DY (lens off the sensor's axis).
    #[arg(long, allow_hyphen_values = true)]
    lens_offset: Option<vl_core::Point>,
    /// Gaussian blur, standard deviation in px.
    #[arg(long)]
    blur: Option<f64>,
    /// Per-pixel noise, standard deviation in grey levels.
    #[arg(long)]
    noise: Option<f64>,
    /// How much darker the bottom-right corner is (0–1).
    #[arg(long)]
    lighting: Option<f64>,
    /// How far the camera leans from looking straight down, degrees.
    #[arg(long, allow_hyphen_values = true)]
    tilt_deg: Option<f64>,
    /// The lens's radial distortion, as K1,K2 (radii in image widths;
    /// barrel distortion has K1 < 0).
    #[arg(long, allow_hyphen_values = true)]
    lens: Option<vl_core::Point>,
    /// From a frame's exposure to its arrival, ms.
    #[arg(long)]
    delay_ms: Option<f64>,
    /// How long the shutter is open, ms (a moving robot smears).
    #[arg(long)]
    exposure_ms: Option<f64>,
    /// The share of frames lost (0–0.5).
    #[arg(long)]
    drop_rate: Option<f64>,
    /// The share of frames with the robot's marker partly hidden (0–0.5).
    #[arg(long)]
    occlusion_rate: Option<f64>,
}

impl OpticsSettings {
    /// The simulator's optics these flags ask for, checked.
    pub fn optics(&self, seed: u64) -> Result<Optics, vl_sim::OpticsError> {
        let mut optics = self.optics.optics(seed);
        if let Some(k) = self.lens {
            optics.distortion = vl_core::Distortion {
                k1: k.x_mm,
                k2: k.y_mm,
            };
        }
        optics.delay_s = self.delay_ms.map_or(optics.delay_s, |ms| ms / 1e3);
        optics.exposure_s = self.exposure_ms.map_or(optics.exposure_s, |ms| ms / 1e3);
        optics.drop_rate = self.drop_rate.unwrap_or(optics.drop_rate);
        optics.occlusion_rate = self.occlusion_rate.unwrap_or(optics.occlusion_rate);
        if let Some(p) = self.lens_offset {
            optics.lens_offset_px = [p.x_mm, p.y_mm];
        }
        optics.blur_px = self.blur.unwrap_or(optics.blur_px);
        optics.noise = self.noise.unwrap_or(optics.noise);
        optics.lighting_gradient = self.lighting.unwrap_or(optics.lighting_gradient);
        if let Some(deg) = self.tilt_deg {
            optics.tilt_rad = deg.to_radians();
        }
        optics.check()?;
        Ok(optics)
    }
}

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
