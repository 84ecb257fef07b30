//! Making the lab ready between runs: the robot driven back to its start
//! pose on a route planned off the hub, as remote labs reset their
//! equipment between users.

use tracing::{info, warn};
use vl_core::{
    Definition, EndReason, Feedback, Goal, HostMessage, Pose, Readiness, plan_route, wrap_angle,
};

use super::{Hub, ResetRoute};
use crate::accounts::audit::AuditEntry;
use crate::lab::{Conduct, LabRequest};

/// A robot this near the start pose, mm and rad, is back: no drive needed
/// (and the drive back ends this near it).
const AT_START_MM: f64 = 5.0;
const AT_START_RAD: f64 = 0.15;
/// The drive back to the start pose gives up after this long, s.
const RESET_LIMIT_S: f64 = 90.0;

impl Hub {
    pub(super) fn set_readiness(&mut self, readiness: Readiness) {
        if self.readiness != readiness {
            self.readiness = readiness;
            self.broadcast(&self.status());
        }
    }

    /// Makes the lab ready for the next run, as remote labs reset their
    /// equipment between users: unless the robot is at the start pose
    /// already, a route back is planned off the hub on the lab's map, then
    /// driven like any run (followed, braked by the safety layer), turning
    /// at the end to the start heading. Start waits until it is there.
    pub(super) fn reset(&mut self) {
        if !self.config.reset || self.run.is_some() || self.readiness == Readiness::GettingReady {
            return;
        }
        let Some(pose) = self.robot_pose() else {
            return;
        };
        let start = self.lab.info.arena.start;
        let turn = wrap_angle(pose.theta_rad - start.theta_rad).abs();
        if pose.point().distance(start.point()) <= AT_START_MM && turn <= AT_START_RAD {
            return;
        }
        info!("the lab is getting ready: the robot drives back to its start pose");
        self.set_readiness(Readiness::GettingReady);
        let (arena, robot) = (self.lab.info.arena.clone(), self.lab.info.robot.clone());
        let routes = self.reset_routes.0.clone();
        tokio::task::spawn_blocking(move || {
            let goal = Goal {
                tolerance_mm: AT_START_MM,
                ..Goal::at(start.point())
            };
            let path = if pose.point().distance(start.point()) <= goal.tolerance_mm {
                Ok(Vec::new())
            } else {
                plan_route(&arena, &[], &robot, pose, start.point()).map(|plan| plan.points())
            };
            let route = path
                .map(|path| Definition {
                    goal: Some(goal),
                    path,
                    time_limit_s: Some(RESET_LIMIT_S),
                    ..Definition::default()
                })
                .map_err(|e| e.to_string());
            let _ = routes.send(route);
        });
    }

    /// Where the lab's newest feedback puts the robot.
    pub(super) fn robot_pose(&self) -> Option<Pose> {
        match &*self.lab.feedback.borrow() {
            Some(HostMessage::Feedback(Feedback { pose, .. })) => Some(*pose),
            _ => None,
        }
    }

    /// The route back to the start pose is planned: drive it.
    pub(super) fn reset_planned(&mut self, route: ResetRoute) {
        // An emergency stop while planning, or a run since, called it off.
        if self.readiness != Readiness::GettingReady || self.run.is_some() {
            return;
        }
        match route {
            Ok(definition) => {
                self.runs += 1;
                self.reset_run = Some(self.runs);
                // Numbered as runs are, so the audit's numbers have no gaps.
                self.config
                    .audit
                    .record(AuditEntry::new("reset").detail(format!(
                        "run {}: the robot drives back to its start pose",
                        self.runs
                    )));
                self.lab.request(LabRequest::Start {
                    run: self.runs,
                    definition: Box::new(definition),
                    conduct: Conduct::BACK_TO_START,
                    field: None,
                    face: Some(self.lab.info.arena.start.theta_rad),
                    controller: None,
                });
            }
            Err(why) => {
                warn!("no way back to the start pose ({why}): runs start where the robot stands");
                self.set_readiness(Readiness::Ready);
            }
        }
    }

    /// The drive back to the start pose ended: the lab is ready.
    pub(super) fn reset_done(&mut self, summary: &vl_core::Summary) {
        self.reset_run = None;
        if summary.reason == EndReason::GoalReached {
            info!(
                seconds = summary.seconds,
                "the robot is back at its start pose: the lab is ready"
            );
        } else {
            warn!(reason = %summary.reason, "the drive back to the start pose ended short: runs start where the robot stands");
        }
        self.set_readiness(Readiness::Ready);
    }
}
