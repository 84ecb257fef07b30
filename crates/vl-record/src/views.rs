//! What the Host sends, as channels: each protocol message on its own
//! topic, and Foxglove's views of it (pose, transforms, camera image and
//! calibration, annotations, scene, grids, paths, sensors, numbers). One
//! home for that conversion, shared by the recorder (into a run's file)
//! and the live Foxglove server (onto its watchers' sockets), so a live
//! view and a recorded one are the same.

use std::collections::VecDeque;

use schemars::JsonSchema;
use serde::Serialize;
use vl_core::{
    Definition, Feedback, FrameHeader, HostMessage, LabScene, Point, PoseSource, Wire,
    distance_to_polyline,
};

use super::Topic;
use super::foxglove::{self, Level};

/// One message on one channel.
pub struct View {
    pub topic: Topic,
    /// When it happened, ns since 1970 (a feedback's reading, a frame's
    /// capture), else when it was sent.
    pub ns: u64,
    pub data: Vec<u8>,
}

impl View {
    fn json(topic: Topic, ns: u64, value: &serde_json::Value) -> View {
        View {
            topic,
            ns,
            data: serde_json::to_vec(value).expect("JSON values serialise"),
        }
    }

    /// A line of the Host's log.
    pub fn log(ns: u64, level: Level, text: &str) -> View {
        View::json(Topic::Log, ns, &foxglove::log_message(ns, level, text))
    }

    /// A client's round trip.
    pub fn round_trip(ns: u64, round_trip: crate::RoundTrip) -> View {
        let value = serde_json::to_value(round_trip).expect("numbers serialise");
        View::json(Topic::RoundTrip, ns, &value)
    }
}

/// The robot's motion as numbers, one message a feedback: what Plot
/// draws (the tracking error only when there is a path to be off).
#[derive(Debug, Clone, Serialize, JsonSchema)]
pub struct Motion {
    pub left_mm_s: f64,
    pub right_mm_s: f64,
    pub forward_mm_s: f64,
    /// How far the robot is from the defined path; none without one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tracking_error_mm: Option<f64>,
    /// The Host held the robot back from what was asked (the safety layer,
    /// or an assisted run's push).
    pub limited: bool,
    pub contact: bool,
    /// The pose rests on a recent camera sighting (else odometry alone).
    pub sighted: bool,
}

/// Poses kept to draw over frames: 2 s of feedback at 50 Hz, longer than
/// any camera's delay.
const POSES_KEPT: usize = 100;

/// What the views need to remember between messages: the lab's scene (for
/// the camera's pixels, the scene and the grids), the definition (its
/// path), the forecast's seeds, whether a run is under way and the robot's
/// recent poses (drawn over the frames).
pub struct Views {
    scene: Option<LabScene>,
    definition: Definition,
    seeds: Vec<Vec<Point>>,
    /// The robot's recent poses, oldest first, each with when it was read:
    /// a frame is drawn over with the pose of when it was taken.
    poses: VecDeque<(u64, vl_core::Pose)>,
    /// A run is under way: only then is the robot off its path by any
    /// measure (between runs it drives back to the start on a route of
    /// its own).
    running: bool,
    /// ns since 1970 at the lab's clock's zero, which feedback's `t_ms`
    /// and frames' capture times count from.
    since_ns: u64,
}

impl Views {
    pub fn new(since_ns: u64, scene: Option<LabScene>, definition: Definition) -> Views {
        Views {
            scene,
            definition,
            seeds: Vec::new(),
            poses: VecDeque::new(),
            running: false,
            since_ns,
        }
    }

    /// The arena, its obstacles, the paths and the robot's body as a scene.
    pub fn scene(&self, ns: u64) -> Option<View> {
        let lab = self.scene.as_ref()?;
        let scene = foxglove::scene(ns, &lab.arena, &self.definition, &self.seeds, &lab.robot);
        Some(View::json(Topic::Scene, ns, &scene))
    }

    /// Everything that says what the lab is, as it stands: the scene, the
    /// grids, the camera's place and calibration, the defined path.
    pub fn lab(&self, ns: u64) -> Vec<View> {
        let Some(lab) = &self.scene else {
            return Vec::new();
        };
        let mut views: Vec<View> = self.scene(ns).into_iter().collect();
        views
            .extend(foxglove::map_grid(ns, &lab.arena).map(|map| View::json(Topic::Map, ns, &map)));
        views.extend(self.cspace(ns));
        let pinhole = lab.camera.pinhole();
        views.push(View::json(
            Topic::CameraTransform,
            ns,
            &foxglove::camera_transform(ns, &pinhole),
        ));
        views.push(View::json(
            Topic::Calibration,
            ns,
            &foxglove::calibration(ns, &pinhole),
        ));
        views.push(self.path(ns));
        views
    }

    fn cspace(&self, ns: u64) -> Option<View> {
        let lab = self.scene.as_ref()?;
        let grid = foxglove::cspace_grid(ns, &lab.arena, &self.definition, &lab.robot)?;
        Some(View::json(Topic::CSpace, ns, &grid))
    }

    fn path(&self, ns: u64) -> View {
        let poses = foxglove::path_poses(ns, &self.definition.path);
        View::json(Topic::Path, ns, &poses)
    }

    /// `message`, sent at `ns`, on its topic, and Foxglove's views of it;
    /// nothing for a message no channel keeps.
    pub fn sent(&mut self, ns: u64, message: &HostMessage) -> Vec<View> {
        let Some(topic) = Topic::of(message) else {
            return Vec::new();
        };
        // Feedback is stamped with when the lab read the robot.
        let ns = match message {
            HostMessage::Feedback(Feedback { t_ms, .. }) => {
                self.since_ns + (t_ms.max(0.0) * 1e6) as u64
            }
            _ => ns,
        };
        let mut views = vec![View {
            topic,
            ns,
            data: message.encode().into_bytes(),
        }];
        match message {
            HostMessage::Feedback(feedback) => views.extend(self.feedback(ns, feedback)),
            HostMessage::Started { .. } => self.running = true,
            HostMessage::Done { .. } => self.running = false,
            HostMessage::Defined { definition } => {
                self.definition = definition.clone();
                self.seeds.clear();
                views.extend(self.scene(ns));
                views.extend(self.cspace(ns));
                views.push(self.path(ns));
            }
            HostMessage::Mounted(lab) => {
                self.scene = Some(lab.scene.clone());
                self.seeds.clear();
                views.extend(self.lab(ns));
            }
            HostMessage::Forecast(verdict) => {
                self.seeds = verdict
                    .forecast
                    .runs
                    .iter()
                    .map(|run| run.path.clone())
                    .collect();
                views.extend(self.scene(ns));
                views.extend(
                    self.seeds
                        .iter()
                        .map(|seed| View::json(Topic::Seeds, ns, &foxglove::path_poses(ns, seed))),
                );
            }
            _ => {}
        }
        views
    }

    fn feedback(&mut self, ns: u64, feedback: &Feedback) -> Vec<View> {
        let pose = feedback.pose;
        if self.poses.len() >= POSES_KEPT {
            self.poses.pop_front();
        }
        self.poses.push_back((ns, pose));
        let path = &self.definition.path;
        let motion = Motion {
            left_mm_s: feedback.wheels.left_mm_s,
            right_mm_s: feedback.wheels.right_mm_s,
            forward_mm_s: feedback.wheels.forward_mm_s(),
            tracking_error_mm: (self.running && !path.is_empty())
                .then(|| distance_to_polyline(path, pose.point())),
            limited: feedback.limited,
            contact: feedback.contact,
            sighted: feedback.source == PoseSource::Camera,
        };
        let mut views = vec![
            View::json(Topic::Pose, ns, &foxglove::pose_message(ns, pose)),
            View::json(Topic::Transform, ns, &foxglove::transform(ns, pose)),
            View::json(
                Topic::Motion,
                ns,
                &serde_json::to_value(&motion).expect("numbers serialise"),
            ),
        ];
        if let Some(lab) = &self.scene {
            views.push(View::json(
                Topic::Scan,
                ns,
                &foxglove::scan(ns, &lab.robot, &feedback.proximity),
            ));
        }
        views
    }

    /// The pose read nearest `ns`.
    fn pose_at(&self, ns: u64) -> Option<vl_core::Pose> {
        self.poses
            .iter()
            .min_by_key(|(at, _)| at.abs_diff(ns))
            .map(|(_, pose)| *pose)
    }

    /// A camera frame as sent (header and JPEG): the image, and the path
    /// and the robot drawn over it, where it was when the frame was taken.
    pub fn frame(&self, wire: &[u8]) -> Vec<View> {
        let Ok((header, jpeg)) = FrameHeader::decode(wire) else {
            return Vec::new();
        };
        let taken = self.since_ns + header.capture_us * 1000;
        let mut views = vec![View::json(
            Topic::Camera,
            taken,
            &foxglove::image(taken, jpeg),
        )];
        if let Some(lab) = &self.scene {
            let robot = self.pose_at(taken).map(|p| (p, lab.robot.radius_mm));
            let annotations =
                foxglove::annotations(taken, &lab.camera, &self.definition.path, robot);
            views.push(View::json(Topic::Annotations, taken, &annotations));
        }
        views
    }
}
