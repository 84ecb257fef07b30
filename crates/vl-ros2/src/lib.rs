//! The lab on ROS 2, over Zenoh as ROS 2's rmw_zenoh speaks it, with no
//! ROS installed: the message definitions vendored in `ros2-msgs/` and
//! their type hashes (`msg`), CDR (`cdr`) and the messages the lab speaks
//! (`messages`), the graph's key expressions, tokens and attachments
//! (`graph`), the lab as ROS messages (`views`), the Host publishing them
//! and taking `/cmd_vel` (`bridge`, `operator`), and any ROS 2
//! differential-drive robot as the lab's robot (`robot`, a `RobotPlug`,
//! with its camera, `camera`). The Host runs the side as an extension
//! (`Ros2Side`), on the Zenoh network of `vl-cells`.

mod bridge;
mod camera;
mod cdr;
mod graph;
mod messages;
mod msg;
mod operator;
mod robot;
#[cfg(test)]
mod tests;
mod views;

pub use msg::MsgError;
pub use robot::{Ros2Robot, Ros2RobotOptions};

use std::sync::Arc;

use vl_cells::{ZenohError, ZenohOptions};
use vl_host::{Admitted, Extension, ExtensionTask, Identity, LabHandle, Users};

/// The lab's side on ROS 2, plugged into its Host.
#[derive(Debug)]
pub struct Ros2Side(pub Ros2Options);

impl Extension for Ros2Side {
    /// A router anyone beyond this machine can join, unauthenticated.
    fn status(&self, status: &mut vl_core::HostStatus) {
        let zenoh = &self.0.zenoh;
        if zenoh.open_beyond_loopback() {
            let listen = zenoh.listen.iter().map(ToString::to_string);
            status.open_to_anyone.extend(listen);
        }
    }

    fn run(self: Arc<Self>, lab: LabHandle) -> ExtensionTask {
        Box::pin(bridge::serve(self.0.clone(), lab))
    }
}

/// A ROS 2 topic's name as `--camera ros2:/TOPIC` gives it: `/` and then
/// names of letters, digits and `_`.
pub fn topic(text: &str) -> Result<String, Ros2Error> {
    let fits = text.strip_prefix('/').is_some_and(|rest| {
        rest.split('/').all(|name| {
            !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        })
    });
    match fits {
        true => Ok(text.to_owned()),
        false => Err(Ros2Error::Topic(format!(
            "ros2:{text}: a ROS 2 topic is /name/name…, each name of letters, digits and _"
        ))),
    }
}

/// The lab as a ROS 2 node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ros2Options {
    /// ROS's domain id (`ROS_DOMAIN_ID`): the first chunk of every key.
    pub domain: u32,
    /// The Zenoh network: a `zenohd` or a gateway's router to connect to,
    /// or endpoints to listen on as a router ROS nodes connect to.
    pub zenoh: ZenohOptions,
    /// `/cmd_vel` drives the robot, as this identity (`operator_as`).
    pub operator: Option<Admitted>,
    /// A cell's name: its node's namespace (`/NAME/odom`, …) and its
    /// frames' prefix (`NAME/base_link`, …), so several cells share one
    /// ROS 2 network.
    pub cell: Option<vl_core::CellName>,
}

/// Why the lab cannot be on ROS 2.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    #[error(transparent)]
    Zenoh(#[from] ZenohError),
    #[error("ROS 2 message definitions: {0}")]
    Msg(#[from] msg::MsgError),
    #[error("no ROS 2 robot: nothing on /odom within {} s", .0.as_secs())]
    NoRobot(std::time::Duration),
    #[error("ROS 2 /cmd_vel: {0}")]
    Operator(String),
    #[error("ROS 2 robot: {0}")]
    Robot(String),
    #[error("{0}")]
    Topic(String),
}

/// Who `/cmd_vel` drives as. Whoever can publish on the ROS 2 network
/// drives, so at a lab with accounts it drives as one of them, named by
/// the lab's staff (`account`): its turns, its line and its audit entries
/// are that account's, and it ends when the account does. At a lab
/// without accounts, where anyone may drive, it is `ros2`.
pub fn operator_as(account: Option<&str>, users: Option<&Users>) -> Result<Admitted, Ros2Error> {
    let identity = match (account, users) {
        (None, None) => Identity::Ros2,
        (Some(name), None) => {
            return Err(Ros2Error::Operator(format!(
                "it drives as account {name}, but this lab has no accounts (--users)"
            )));
        }
        (None, Some(_)) => {
            return Err(Ros2Error::Operator(
                "a lab with accounts drives from ROS 2 as one of them: name it (--ros2-as NAME)"
                    .to_owned(),
            ));
        }
        (Some(name), Some(users)) => match users.role_of(name) {
            None => {
                return Err(Ros2Error::Operator(format!(
                    "no account {name} at this lab"
                )));
            }
            Some(role) if !role.may_drive() => {
                return Err(Ros2Error::Operator(format!(
                    "account {name} is an {role}'s: it may not drive"
                )));
            }
            Some(role) => Identity::Account {
                name: name.to_owned(),
                role,
            },
        },
    };
    Ok(Admitted {
        identity,
        may_drive: true,
        session: None,
    })
}

impl From<zenoh::Error> for Ros2Error {
    fn from(e: zenoh::Error) -> Ros2Error {
        Ros2Error::Zenoh(e.into())
    }
}

/// The node name the lab takes on ROS 2.
pub(crate) const NODE: &str = "vl_host";

/// The lab's node on its own session, with the vendored definitions.
async fn node(
    zenoh: &ZenohOptions,
    domain: u32,
    namespace: Option<&str>,
    name: &str,
) -> Result<graph::Node, Ros2Error> {
    let catalogue = std::sync::Arc::new(msg::MessageDefinitions::vendored()?);
    let session = vl_cells::open(zenoh).await?;
    graph::Node::new(session, domain, namespace, name, catalogue).await
}
