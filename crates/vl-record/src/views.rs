//! What the Host sends, as channels: each protocol message on its own
//! topic, and Foxglove's views of it (pose, transform, camera image,
//! annotations, scene). One home for that conversion, shared by the
//! recorder (into a run's file) and the live Foxglove server (onto its
//! watchers' sockets), so a live view and a recorded one are the same.

use vl_core::{Definition, Feedback, FrameHeader, HostMessage, MountedLab, Pose, Wire};

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
}

/// What the views need to remember between messages: the lab (for the
/// camera's pixels and the scene), the definition (its path) and the
/// robot's last pose (drawn over the next frame).
pub struct Views {
    lab: Option<MountedLab>,
    definition: Definition,
    pose: Option<Pose>,
    /// ns since 1970 at the lab's clock's zero, which feedback's `t_ms`
    /// and frames' capture times count from.
    since_ns: u64,
}

impl Views {
    pub fn new(since_ns: u64, lab: Option<MountedLab>, definition: Definition) -> Views {
        Views {
            lab,
            definition,
            pose: None,
            since_ns,
        }
    }

    /// The arena, its obstacles, the path and the robot's body as a scene.
    pub fn scene(&self, ns: u64) -> Option<View> {
        let lab = self.lab.as_ref()?;
        let scene = foxglove::scene(ns, &lab.scene.arena, &self.definition, &lab.scene.robot);
        Some(View::json(Topic::Scene, ns, &scene))
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
            HostMessage::Feedback(Feedback { pose, .. }) => {
                self.pose = Some(*pose);
                views.push(View::json(
                    Topic::Pose,
                    ns,
                    &foxglove::pose_message(ns, *pose),
                ));
                views.push(View::json(
                    Topic::Transform,
                    ns,
                    &foxglove::transform(ns, *pose),
                ));
            }
            HostMessage::Defined { definition } => {
                self.definition = definition.clone();
                views.extend(self.scene(ns));
            }
            HostMessage::Mounted(lab) => {
                self.lab = Some((**lab).clone());
                views.extend(self.scene(ns));
            }
            _ => {}
        }
        views
    }

    /// A camera frame as sent (header and JPEG): the image, and the path
    /// and the robot drawn over it.
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
        if let Some(lab) = &self.lab {
            let robot = self.pose.map(|p| (p, lab.scene.robot.radius_mm));
            let annotations =
                foxglove::annotations(taken, &lab.scene.camera, &self.definition.path, robot);
            views.push(View::json(Topic::Annotations, taken, &annotations));
        }
        views
    }
}
