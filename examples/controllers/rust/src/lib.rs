//! A go-to-goal controller for vl, interface version 1: it turns towards
//! the goal and drives to it, slowing as it nears (no obstacle avoidance:
//! see `go_to_goal.c` for that). Built for `wasm32-unknown-unknown`, it
//! imports nothing and exports `memory` and the four functions vl calls.

/// What the lab writes before each step: 32 f64 (docs/controllers.md).
static mut OBSERVATION: [f64; 32] = [0.0; 32];
/// What the step answers: left and right wheel speed, mm/s.
static mut COMMAND: [f64; 2] = [0.0; 2];

/// The Khepera's wheel base, mm.
const WHEEL_BASE_MM: f64 = 53.0;

#[no_mangle]
pub extern "C" fn vl_abi() -> i32 {
    1
}

#[no_mangle]
pub extern "C" fn vl_observation() -> i32 {
    core::ptr::addr_of!(OBSERVATION) as i32
}

#[no_mangle]
pub extern "C" fn vl_command() -> i32 {
    core::ptr::addr_of!(COMMAND) as i32
}

/// 0: go on; 1: done (at the goal, or there is none).
#[no_mangle]
pub extern "C" fn vl_step() -> i32 {
    let seen = unsafe { OBSERVATION };
    let (x, y, theta) = (seen[1], seen[2], seen[3]);
    let (goal_x, goal_y, limit) = (seen[7], seen[8], seen[18]);
    let (wheels, done) = steer(x, y, theta, goal_x, goal_y, limit);
    unsafe { COMMAND = wheels };
    done as i32
}

/// Wheel speeds towards the goal, and whether the robot is there.
fn steer(x: f64, y: f64, theta: f64, goal_x: f64, goal_y: f64, limit: f64) -> ([f64; 2], bool) {
    if goal_x.is_nan() || goal_y.is_nan() {
        return ([0.0, 0.0], true);
    }
    let (dx, dy) = (goal_x - x, goal_y - y);
    let distance = (dx * dx + dy * dy).sqrt();
    if distance < 10.0 {
        return ([0.0, 0.0], true);
    }
    // The goal's direction in the robot's frame.
    let (sin, cos) = theta.sin_cos();
    let ahead = (cos * dx + sin * dy) / distance;
    let left = (cos * dy - sin * dx) / distance;
    let speed = 120.0_f64.min(limit).min(2.0 * distance + 20.0);
    let forward = speed * ahead.max(0.0);
    let mut turn = 3.0 * left;
    if ahead < 0.0 {
        turn += 2.0_f64.copysign(left);
    }
    let half = turn * WHEEL_BASE_MM / 2.0;
    ([forward - half, forward + half], false)
}
