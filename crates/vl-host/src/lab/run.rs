//! One run of an experiment as the control loop keeps it: what it
//! follows, what it has seen so far, and its summary when it ends.

use std::sync::Arc;
use std::time::{Duration, Instant};

use vl_core::{
    Definition, EndReason, Experiment, Follower, HeldBack, MapField, PathRecorder, Pose,
    PoseSource, Summary, Surroundings, Vector, Visited, WaypointsVisited, WheelSpeeds,
};

/// What the control loop does in a run, from the experiment's components:
/// follow the defined path, assist the operator (fields and force), end
/// where the definition is reached (the goal, or every waypoint).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Conduct {
    pub(crate) follows: bool,
    pub(crate) assists: bool,
    pub(crate) ends_at_goal: bool,
}

impl Conduct {
    /// The drive back to the start pose after a run: follow a planned
    /// path and stop at its end.
    pub(crate) const BACK_TO_START: Conduct = Conduct {
        follows: true,
        assists: false,
        ends_at_goal: true,
    };
}

impl From<&Experiment> for Conduct {
    fn from(experiment: &Experiment) -> Conduct {
        Conduct {
            follows: experiment.follows(),
            assists: experiment.assists_the_operator(),
            ends_at_goal: experiment.ends_at_goal(),
        }
    }
}

/// An assisted run's two sides: the velocity the operator asks for (robot
/// frame), and the force last fed back to the stick.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Assist {
    pub(super) desired: Vector,
    pub(super) force: [f64; 2],
}

/// The share of the forward speed asked that the safety layer let
/// through, averaged over the periods in which a command asked to move.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct SpeedKept {
    sum: f64,
    periods: u64,
}

impl SpeedKept {
    /// One period that asked for `asked` mm/s forward and got `let_through`.
    pub(super) fn add(&mut self, asked: f64, let_through: f64) {
        if asked != 0.0 && asked.is_finite() && let_through.is_finite() {
            self.sum += (let_through / asked).clamp(0.0, 1.0);
            self.periods += 1;
        }
    }

    /// The mean share, 0 to 1; none when nothing asked to move.
    pub(super) fn share(&self) -> Option<f64> {
        (self.periods > 0).then(|| self.sum / self.periods as f64)
    }
}

/// How far a followed run has come along its path, and since when it has
/// come no further.
#[derive(Debug, Clone, Copy)]
pub(super) struct PathProgress {
    /// The furthest along the path, mm.
    along_mm: f64,
    /// When it last came `step_mm` further (or was excused: held, turning,
    /// steered by the operator).
    since: Instant,
}

impl PathProgress {
    pub(super) fn new(now: Instant) -> PathProgress {
        PathProgress {
            along_mm: 0.0,
            since: now,
        }
    }

    /// The run is not expected to make progress now: the clock restarts.
    pub(super) fn excuse(&mut self, now: Instant) {
        self.since = now;
    }

    /// The follower is `along_mm` along the path at `now`: whether it has
    /// come no `step_mm` further for `patience`.
    pub(super) fn stalled(
        &mut self,
        along_mm: f64,
        step_mm: f64,
        patience: Duration,
        now: Instant,
    ) -> bool {
        if along_mm >= self.along_mm + step_mm {
            self.along_mm = along_mm;
            self.since = now;
            return false;
        }
        now.saturating_duration_since(self.since) >= patience
    }
}

/// One run of an experiment, from `start` to its end.
pub(super) struct Run {
    pub(super) number: u64,
    pub(super) definition: Definition,
    pub(super) conduct: Conduct,
    /// The arena and the definition's virtual obstacles, for the safety layer.
    pub(super) surroundings: Surroundings,
    pub(super) started: Instant,
    pub(super) last_command: Instant,
    /// Whether the operator has commanded this run: a command that is
    /// still fresh overrides the path being followed.
    pub(super) commanded: bool,
    /// The Host follows the definition's path in a navigation run.
    pub(super) follower: Option<Follower>,
    /// The estimated (and, in simulation, true) path against the plan.
    pub(super) record: PathRecorder,
    pub(super) distance_mm: f64,
    /// Contacts seen: by the robot's sensors, or by the estimate reaching
    /// something (counted once per touch, not per period).
    pub(super) collisions: u64,
    pub(super) touching: bool,
    /// The wheel speeds the last command asks for.
    pub(super) wheels: WheelSpeeds,
    /// The operator's link is down: the robot stays still until they are back.
    pub(super) held: bool,
    /// For an assisted run: what the operator asks, what is fed back.
    pub(super) assist: Option<Assist>,
    /// The map's potential field the Host built for this run's definition.
    pub(super) field: Option<Arc<MapField>>,
    /// Whether the robot is held back from what was asked: the safety layer
    /// changed the last command, or (assisted) the obstacles' push did.
    pub(super) limited: bool,
    /// The body's least clearance seen, mm.
    pub(super) closest_mm: f64,
    /// How much of the forward speed asked the safety layer let through.
    pub(super) kept: SpeedKept,
    /// The heading to turn to in place once at the goal, and whether the
    /// robot is there and turning.
    pub(super) face: Option<f64>,
    pub(super) turning: bool,
    /// How far the follower has come along the path, and since when not.
    pub(super) progress: PathProgress,
    pub(super) held_back: Option<HeldBack>,
    /// What failed, when a fault ends the run.
    pub(super) fault: Option<String>,
    /// The definition's waypoints visited so far, in order.
    pub(super) visited: Visited,
    /// The user's controller driving the run, on its thread.
    pub(super) controller: Option<super::controller::Beside>,
}

impl Run {
    /// Run `number` conducted as `conduct` on `definition`, starting now,
    /// in `surroundings` (the arena and the definition's virtual obstacles).
    pub(super) fn new(
        number: u64,
        definition: Definition,
        conduct: Conduct,
        surroundings: Surroundings,
        field: Option<Arc<MapField>>,
        face: Option<f64>,
    ) -> Run {
        let now = Instant::now();
        let follower = definition
            .host_follows(conduct.follows)
            .then(|| Follower::for_definition(&definition))
            .flatten();
        Run {
            number,
            surroundings,
            record: PathRecorder::new(definition.path.clone()),
            follower,
            commanded: false,
            definition,
            conduct,
            started: now,
            last_command: now,
            distance_mm: 0.0,
            collisions: 0,
            touching: false,
            wheels: WheelSpeeds::default(),
            held: false,
            assist: conduct.assists.then_some(Assist::default()),
            field,
            limited: false,
            closest_mm: f64::INFINITY,
            kept: SpeedKept::default(),
            face,
            turning: false,
            progress: PathProgress::new(now),
            held_back: None,
            fault: None,
            visited: Visited::default(),
            controller: None,
        }
    }

    pub(super) fn summary(
        self,
        reason: EndReason,
        events: u64,
        pose: Pose,
        source: PoseSource,
    ) -> Summary {
        Summary {
            reason,
            reached_goal: self.definition.reached(self.visited, pose.point()),
            waypoints: (!self.definition.waypoints.is_empty()).then_some(WaypointsVisited {
                visited: self.visited.0,
                of: self.definition.waypoints.len(),
            }),
            events,
            final_pose: pose,
            seconds: self.started.elapsed().as_secs_f64(),
            distance_mm: self.distance_mm,
            collisions: self.collisions,
            closest_mm: self.closest_mm.is_finite().then_some(self.closest_mm),
            speed_kept: self.kept.share(),
            pose_source: source,
            path: Some(self.record.finish()),
            // The hub, which mounts and sees the commands' events, fills
            // these in.
            experiment: None,
            max_event_gap: 0,
            sync_violations: 0,
            stopped_by: None,
            forecast: None,
            recording: None,
            held_back: self.held_back,
            fault: self.fault,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_kept_averages_the_moving_periods_only() {
        let mut kept = SpeedKept::default();
        assert_eq!(kept.share(), None);
        kept.add(100.0, 100.0);
        kept.add(100.0, 50.0);
        // Backwards counts alike; more than asked is all of it, not more.
        kept.add(-80.0, -20.0);
        kept.add(50.0, 80.0);
        // Nothing asked, or a number that is not one, is no period.
        kept.add(0.0, 10.0);
        kept.add(f64::NAN, 10.0);
        let share = kept.share().unwrap();
        assert!(
            (share - (1.0 + 0.5 + 0.25 + 1.0) / 4.0).abs() < 1e-12,
            "{share}"
        );
    }

    #[test]
    fn progress_stalls_only_after_the_patience_without_a_step() {
        let t0 = Instant::now();
        let s = |secs: f64| t0 + Duration::from_secs_f64(secs);
        let patience = Duration::from_secs(5);
        let mut progress = PathProgress::new(t0);
        // Creeping less than a step at a time is no progress…
        assert!(!progress.stalled(3.0, 5.0, patience, s(2.0)));
        assert!(!progress.stalled(4.9, 5.0, patience, s(4.9)));
        assert!(progress.stalled(4.9, 5.0, patience, s(5.0)));
        // …a whole step restarts the clock…
        assert!(!progress.stalled(5.0, 5.0, patience, s(6.0)));
        assert!(!progress.stalled(9.0, 5.0, patience, s(10.9)));
        assert!(progress.stalled(9.0, 5.0, patience, s(11.0)));
        // …and so does an excuse (held, turning, steered).
        progress.excuse(s(12.0));
        assert!(!progress.stalled(9.0, 5.0, patience, s(16.9)));
        assert!(progress.stalled(9.0, 5.0, patience, s(17.0)));
    }

    #[test]
    fn a_run_follows_its_path_only_in_navigation_and_assists_only_teleoperation() {
        let definition = Definition {
            path: vec![
                vl_core::Point {
                    x_mm: 100.0,
                    y_mm: 100.0,
                },
                vl_core::Point {
                    x_mm: 300.0,
                    y_mm: 100.0,
                },
            ],
            ..Definition::default()
        };
        let arena = vl_core::Arena::load("open").unwrap();
        let surroundings = Surroundings::new(&arena);
        let shipped = |id| {
            vl_core::Experiments::shipped()
                .get(id)
                .unwrap()
                .experiment()
                .clone()
        };
        let (navigation, teleoperation) = (shipped("navigation"), shipped("teleoperation"));
        let nav = Run::new(
            1,
            definition.clone(),
            Conduct::from(&navigation),
            surroundings.clone(),
            None,
            None,
        );
        assert!(nav.follower.is_some());
        assert!(nav.assist.is_none());
        let tele = Run::new(
            2,
            definition,
            Conduct::from(&teleoperation),
            surroundings,
            None,
            None,
        );
        assert!(tele.follower.is_none());
        assert!(tele.assist.is_some());
        let summary = tele.summary(EndReason::Stopped, 7, Pose::default(), PoseSource::Odometry);
        assert_eq!((summary.events, summary.collisions), (7, 0));
        assert_eq!(summary.speed_kept, None);
        assert_eq!(summary.closest_mm, None);
    }
}
