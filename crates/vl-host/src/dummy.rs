//! A robot with no hardware behind it, beside the real drivers (as OpenRR's
//! `arci` keeps `DummyMoveBase` beside each trait): it rolls exactly as
//! told, senses nothing, and can be made to fall silent, so the hub and the
//! control loop are tested in-process, in milliseconds.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use vl_core::{Leash, Pose, RobotModel, WheelSpeeds};

use crate::drivers::{Robot, RobotError, RobotReading};

/// What the dummy robot was told, and where its wheels took it.
struct DummyState {
    wheels: WheelSpeeds,
    odometry: Pose,
    moved_at: Instant,
    silent: bool,
}

impl DummyState {
    /// Rolls the wheels on from the last time they were looked at.
    fn roll(&mut self, wheel_base_mm: f64) {
        let dt = self.moved_at.elapsed().as_secs_f64();
        self.moved_at = Instant::now();
        self.odometry = self.odometry.advance(self.wheels, wheel_base_mm, dt);
    }
}

/// A robot the lab drives; its [`DummyHandle`] stays with the test.
pub(crate) struct DummyRobot {
    model: RobotModel,
    state: Arc<Mutex<DummyState>>,
}

/// A test's hold on a dummy robot it handed to the lab.
#[derive(Clone)]
pub(crate) struct DummyHandle(Arc<Mutex<DummyState>>);

fn lock(state: &Mutex<DummyState>) -> MutexGuard<'_, DummyState> {
    state.lock().unwrap_or_else(PoisonError::into_inner)
}

impl DummyRobot {
    /// A `model` robot at rest, and the test's handle on it.
    pub(crate) fn new(model: RobotModel) -> (DummyRobot, DummyHandle) {
        let state = Arc::new(Mutex::new(DummyState {
            wheels: WheelSpeeds::default(),
            odometry: Pose::default(),
            moved_at: Instant::now(),
            silent: false,
        }));
        let handle = DummyHandle(state.clone());
        (DummyRobot { model, state }, handle)
    }

    /// The robot as it answers now: silent, or rolled on to the present.
    fn answer(&self, sent: &str) -> Result<MutexGuard<'_, DummyState>, RobotError> {
        let mut state = lock(&self.state);
        if state.silent {
            return Err(RobotError::Timeout {
                sent: sent.into(),
                waited_ms: 0,
            });
        }
        state.roll(self.model.wheel_base_mm);
        Ok(state)
    }
}

impl DummyHandle {
    /// The wheel speeds last set.
    pub(crate) fn wheels(&self) -> WheelSpeeds {
        lock(&self.0).wheels
    }

    /// Whether the wheels were last told to stand still.
    pub(crate) fn still(&self) -> bool {
        self.wheels() == WheelSpeeds::default()
    }

    /// Makes the robot stop answering, or answer again.
    pub(crate) fn set_silent(&self, silent: bool) {
        lock(&self.0).silent = silent;
    }
}

impl Robot for DummyRobot {
    fn model(&self) -> &RobotModel {
        &self.model
    }

    fn drive(&mut self, leash: &Leash) -> Result<(), RobotError> {
        let wheels = leash.wheels(&self.model);
        self.answer("C")?.wheels = wheels;
        Ok(())
    }

    fn read(&mut self) -> Result<RobotReading, RobotError> {
        let state = self.answer("N")?;
        Ok(RobotReading {
            odometry: state.odometry,
            wheels: state.wheels,
            proximity: vec![0; self.model.sensors.len()],
            contact: false,
            travel_mm: [0.0; 2],
            taken: Instant::now(),
        })
    }
}
