//! What plugs into `vl host` from the crates its features bring: a
//! gateway it joins as a cell (`gateway`), its side on ROS 2 and a ROS 2
//! base as its robot (`ros2`), Foxglove's live server (`foxglove`). A
//! flag whose feature this vl lacks says which it needs.

use anyhow::Result;
#[cfg(feature = "zenoh")]
use anyhow::bail;
use vl_host::{HostConfig, RobotSpec};

#[cfg(feature = "ros2")]
use super::RobotDriver;
use super::{CameraArg, HostArgs};
#[cfg(feature = "zenoh")]
use crate::BadInput;

/// Plugs the lab's extensions its flags ask for into `config`, and
/// Foxglove's live server where this vl has it.
pub(super) fn plug_in(args: &HostArgs, config: &mut HostConfig) -> Result<()> {
    config.extensions.extend(always());
    if args.ros2 {
        config.extensions.push(ros2_side(args, config)?);
    }
    if args.cell.is_some() {
        config.extensions.push(cell_side(args)?);
    }
    Ok(())
}

/// What every lab this vl serves has plugged in: Foxglove's live server.
pub(crate) fn always() -> Vec<std::sync::Arc<dyn vl_host::Extension>> {
    #[cfg(feature = "foxglove")]
    return vec![std::sync::Arc::new(vl_foxglove::Foxglove::default())];
    #[cfg(not(feature = "foxglove"))]
    Vec::new()
}

#[cfg(feature = "ros2")]
fn ros2_side(
    args: &HostArgs,
    config: &HostConfig,
) -> Result<std::sync::Arc<dyn vl_host::Extension>> {
    let options = vl_ros2::Ros2Options {
        domain: args.ros2_domain,
        zenoh: ros2_zenoh(args)?,
        operator: args
            .ros2_operator
            .then(|| vl_ros2::operator_as(args.ros2_as.as_deref(), config.users.as_ref()))
            .transpose()
            .map_err(|e| BadInput(e.to_string()))?,
        cell: args.cell.clone(),
    };
    say_on_ros2(&options);
    Ok(std::sync::Arc::new(vl_ros2::Ros2Side(options)))
}

#[cfg(not(feature = "ros2"))]
fn ros2_side(_: &HostArgs, _: &HostConfig) -> Result<std::sync::Arc<dyn vl_host::Extension>> {
    Err(crate::without("--ros2", "ros2"))
}

#[cfg(feature = "gateway")]
fn cell_side(args: &HostArgs) -> Result<std::sync::Arc<dyn vl_host::Extension>> {
    let name = args.cell.clone().expect("a cell's name");
    Ok(std::sync::Arc::new(vl_cells::CellSide(
        vl_cells::CellOptions {
            name,
            zenoh: gateway_zenoh(args)?,
        },
    )))
}

#[cfg(not(feature = "gateway"))]
fn cell_side(_: &HostArgs) -> Result<std::sync::Arc<dyn vl_host::Extension>> {
    Err(crate::without("--cell", "gateway"))
}

/// `--robot ros2`: the ROS 2 base on the Zenoh network, with its camera
/// if `--camera ros2:/TOPIC` names one.
#[cfg(feature = "ros2")]
pub(super) fn ros2_robot(args: &HostArgs) -> Result<RobotSpec> {
    let zenoh = args.zenoh.options(args.listen, false)?;
    warn_if_open(&zenoh);
    let camera = match &args.camera {
        CameraArg::Ros2(topic) => Some(topic.clone()),
        CameraArg::Source(_) => None,
    };
    Ok(RobotSpec::Plugged(std::sync::Arc::new(
        vl_ros2::Ros2RobotOptions {
            domain: args.ros2_domain,
            zenoh,
            camera,
        },
    )))
}

#[cfg(not(feature = "ros2"))]
pub(super) fn ros2_robot(_: &HostArgs) -> Result<RobotSpec> {
    Err(crate::without("--robot ros2", "ros2"))
}

/// A ROS 2 camera's topic, as `--camera ros2:/TOPIC` gives it.
#[cfg(feature = "ros2")]
pub(super) fn ros2_camera(topic: &str) -> Result<String> {
    Ok(vl_ros2::topic(topic)?)
}

#[cfg(not(feature = "ros2"))]
pub(super) fn ros2_camera(_: &str) -> Result<String> {
    Err(crate::without("a ROS 2 camera (ros2:/TOPIC)", "ros2"))
}

/// Whether `--camera` names a camera only `--robot ros2` brings, on a
/// robot that brings none.
pub(super) fn camera_fits(args: &HostArgs, robot: &RobotSpec) -> Result<()> {
    match (&args.camera, robot) {
        (CameraArg::Ros2(_), RobotSpec::Plugged(_)) | (CameraArg::Source(_), _) => Ok(()),
        (CameraArg::Ros2(topic), RobotSpec::Sim) => Err(crate::BadInput(format!(
            "ros2:{topic}: a real camera watches a real robot, not the simulated one: use --robot ros2"
        ))
        .into()),
        (CameraArg::Ros2(topic), _) => Err(crate::BadInput(format!(
            "ros2:{topic}: a ROS 2 camera is read with --robot ros2, on the robot's network"
        ))
        .into()),
    }
}

#[cfg(feature = "ros2")]
/// The Zenoh network the lab's ROS 2 side joins: the one given; else the
/// gateway's a cell joins; else the router `--robot ros2` opens; else a
/// router of its own.
fn ros2_zenoh(args: &HostArgs) -> Result<vl_cells::ZenohOptions> {
    let given = args.zenoh.options(args.listen, false)?;
    Ok(if !given.connect.is_empty() {
        given
    } else if !args.gateway.is_empty() {
        gateway_zenoh(args)?
    } else if args.robot == RobotDriver::Ros2 {
        given.local_client()
    } else {
        given
    })
}

#[cfg(feature = "zenoh")]
/// The gateway's network a cell joins, with the credentials its gateway
/// issued to it (and to no other cell).
fn gateway_zenoh(args: &HostArgs) -> Result<vl_cells::ZenohOptions> {
    let zenoh = args.zenoh.joining(args.gateway.clone())?;
    if let (vl_cells::ZenohTrust::Member(credentials), Some(cell)) = (&zenoh.trust, &args.cell)
        && credentials.member != vl_cells::ZenohMember::Cell(cell.clone())
    {
        bail!(BadInput(format!(
            "--zenoh-credentials are {}'s, not cell {cell}'s",
            credentials.member
        )));
    }
    Ok(zenoh)
}

#[cfg(feature = "ros2")]
/// Where the lab is on ROS 2, for the person who started it.
fn say_on_ros2(ros2: &vl_ros2::Ros2Options) {
    let zenoh = match (ros2.zenoh.connect.first(), ros2.zenoh.listen.first()) {
        (Some(router), _) => format!("joining the Zenoh router at {router}"),
        (None, Some(listen)) => format!("its Zenoh router listening on {listen}"),
        (None, None) => "on Zenoh".to_owned(),
    };
    let node = match &ros2.cell {
        Some(cell) => format!("/{cell}/vl_host"),
        None => "/vl_host".to_owned(),
    };
    let drives = match ros2.operator.as_ref().map(|a| a.identity.name()) {
        Some(Some(name)) => format!("; /cmd_vel drives as {name}"),
        Some(None) => "; /cmd_vel drives".to_owned(),
        None => String::new(),
    };
    eprintln!(
        "vl host: on ROS 2 as node {node} in domain {}, {zenoh}{drives}",
        ros2.domain
    );
    warn_if_open(&ros2.zenoh);
}

#[cfg(feature = "ros2")]
/// Says loudly that a router anyone on the network can join is open.
fn warn_if_open(zenoh: &vl_cells::ZenohOptions) {
    if zenoh.open_beyond_loopback() {
        let at: Vec<String> = zenoh.listen.iter().map(ToString::to_string).collect();
        eprintln!(
            "vl host: WARNING: the Zenoh router on {} takes anyone on the network, unauthenticated: \
             listen on 127.0.0.1, or put the lab behind a gateway (`vl gateway`) whose network needs certificates",
            at.join(", ")
        );
    }
}
