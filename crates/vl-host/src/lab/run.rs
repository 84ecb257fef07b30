//! One run of an experiment as the control loop keeps it: what it
//! follows, what it has seen so far, and its summary when it ends.

use std::sync::Arc;
use std::time::Instant;

use vl_core::{
    Definition, EndReason, Experiment, Follower, HeldBack, MapField, PathRecorder, Pose,
    PoseSource, Summary, Surroundings, Vector, WheelSpeeds,
};

/// One run of an experiment, from `start` to its end.
pub(super) struct Run {
    pub(super) number: u64,
    pub(super) definition: Definition,
    pub(super) experiment: Experiment,
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
    /// For an assisted run: the velocity the operator asks for, and the
    /// force last fed back.
    pub(super) assist: Option<(Vector, [f64; 2])>,
    /// The map's potential field the Host built for this run's definition.
    pub(super) field: Option<Arc<MapField>>,
    /// Whether the safety layer changed the last command it saw.
    pub(super) limited: bool,
    /// The body's least clearance seen, mm.
    pub(super) closest_mm: f64,
    /// Sum and count, over periods in which a command asked to move, of the
    /// forward speed the layer let through over the speed asked.
    pub(super) kept: (f64, u64),
    /// The heading to turn to in place once at the goal, and whether the
    /// robot is there and turning.
    pub(super) face: Option<f64>,
    pub(super) turning: bool,
    /// The furthest the follower had come along the path, mm, and when.
    pub(super) progress: (f64, Instant),
    pub(super) held_back: Option<HeldBack>,
    /// What failed, when a fault ends the run.
    pub(super) fault: Option<String>,
}

impl Run {
    /// Run `number` of `experiment` on `definition`, starting now, in
    /// `surroundings` (the arena and the definition's virtual obstacles).
    pub(super) fn new(
        number: u64,
        definition: Definition,
        experiment: Experiment,
        surroundings: Surroundings,
        field: Option<Arc<MapField>>,
        face: Option<f64>,
    ) -> Run {
        let now = Instant::now();
        let follower = definition
            .host_follows(experiment)
            .then(|| Follower::for_definition(&definition))
            .flatten();
        Run {
            number,
            surroundings,
            record: PathRecorder::new(definition.path.clone()),
            follower,
            commanded: false,
            definition,
            experiment,
            started: now,
            last_command: now,
            distance_mm: 0.0,
            collisions: 0,
            touching: false,
            wheels: WheelSpeeds::default(),
            held: false,
            assist: experiment
                .assists_the_operator()
                .then_some((Vector::default(), [0.0; 2])),
            field,
            limited: false,
            closest_mm: f64::INFINITY,
            kept: (0.0, 0),
            face,
            turning: false,
            progress: (0.0, now),
            held_back: None,
            fault: None,
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
            reached_goal: self.definition.at_goal(pose.point()),
            events,
            final_pose: pose,
            seconds: self.started.elapsed().as_secs_f64(),
            distance_mm: self.distance_mm,
            collisions: self.collisions,
            closest_mm: self.closest_mm.is_finite().then_some(self.closest_mm),
            speed_kept: (self.kept.1 > 0).then(|| self.kept.0 / self.kept.1 as f64),
            pose_source: source,
            path: Some(self.record.finish()),
            // The hub, which sees the commands' events, fills these in.
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
