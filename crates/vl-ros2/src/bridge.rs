//! The Host on ROS 2: one node, `vl_host`, publishing what the lab knows
//! as it changes — `/odom` and `/tf` with every feedback (at most 50 a
//! second), `/scan` at 10, the camera's JPEG frames while a subscriber
//! takes them (counted as one watcher, so the camera makes them only
//! then), the camera's calibration and the frames' places once a second,
//! and `/map` latched — and, with `--ros2-operator`, driven by `/cmd_vel`.

use std::sync::Arc;
use std::time::{Duration, Instant};

use tracing::{info, warn};
use vl_core::{Feedback, FrameHeader, HostMessage, ImageFormat, LabScene};

use super::graph::{Publisher, Qos};
use super::messages::{CameraInfo, CompressedImage, LaserScan, OccupancyGrid, Odometry, TfMessage};
use super::views::{self, Frames};
use super::{NODE, Ros2Error, Ros2Options};
use vl_host::{Gate, LabHandle, Watching};

/// The fastest `/odom` and `/tf` go, and `/scan`.
const ODOM_EVERY: Duration = Duration::from_millis(20);
const SCAN_EVERY: Duration = Duration::from_millis(100);
/// How often what changes slowly is said again for those who came later.
const SLOW_EVERY: Duration = Duration::from_secs(1);
/// How often the camera's topic is asked whether anyone takes it.
const LOOK_EVERY: Duration = Duration::from_millis(200);

/// What the bridge takes from the Host it is part of.
struct Lab {
    handle: LabHandle,
    /// Whether the account `/cmd_vel` drives as is still the lab's.
    gate: Arc<Gate>,
    scene: LabScene,
}

/// Serves the lab on ROS 2 for as long as the Host runs (never
/// returning: a lab that cannot reach its Zenoh network still serves its
/// Guests).
pub(crate) async fn serve(options: Ros2Options, handle: LabHandle) {
    let Some(scene) = handle.scene.clone() else {
        warn!("the lab is not on ROS 2: a gateway has no lab of its own to publish");
        return std::future::pending().await;
    };
    let lab = Lab {
        gate: handle.gate.clone(),
        handle,
        scene,
    };
    if let Err(e) = publish(&options, lab).await {
        warn!("the lab is not on ROS 2: {e}");
    }
    std::future::pending().await
}

/// The lab's publishers.
struct Topics {
    odom: Publisher<Odometry>,
    tf: Publisher<TfMessage>,
    scan: Publisher<LaserScan>,
    image: Publisher<CompressedImage>,
    camera_info: Publisher<CameraInfo>,
    _map: Publisher<OccupancyGrid>,
    frames: Frames,
}

async fn publish(options: &Ros2Options, lab: Lab) -> Result<(), Ros2Error> {
    let cell = options.cell.as_ref().map(|c| c.as_str());
    let node = super::node(&options.zenoh, options.domain, cell, NODE).await?;
    let frames = Frames::of(cell);
    let map = node.publisher("/map", Qos::LATCHED).await?;
    if let Some(grid) = views::map(&frames, &lab.scene.arena) {
        map.put(&grid).await?;
    }
    let topics = Topics {
        odom: node.publisher("/odom", Qos::STATE).await?,
        tf: node.publisher("/tf", Qos::STATE).await?,
        scan: node.publisher("/scan", Qos::SENSOR).await?,
        image: node
            .publisher("/camera/image_raw/compressed", Qos::SENSOR)
            .await?,
        camera_info: node.publisher("/camera/camera_info", Qos::STATE).await?,
        _map: map,
        frames,
    };
    let namespace = cell.map(|c| format!("/{c}")).unwrap_or_default();
    info!(
        "the lab is on ROS 2 as node {namespace}/{NODE}, domain {}",
        options.domain
    );
    let driving = async {
        if let Some(admitted) = options.operator.clone() {
            let at_hub = super::operator::AtLab {
                admitted,
                gate: lab.gate.clone(),
                hub: lab.handle.hub.clone(),
            };
            super::operator::drive(&node, at_hub, lab.handle.feedback.clone()).await
        } else {
            std::future::pending().await
        }
    };
    tokio::try_join!(state(&topics, &lab), camera(&topics, &lab), driving)?;
    Ok(())
}

/// `/odom`, `/tf`, `/scan` and the camera's calibration, from feedback.
async fn state(topics: &Topics, lab: &Lab) -> Result<(), Ros2Error> {
    let pinhole = lab.scene.camera.pinhole();
    let robot = &lab.scene.robot;
    let mut feedback = lab.handle.feedback.clone();
    let mut slow = tokio::time::interval(SLOW_EVERY);
    let (mut odom_at, mut scan_at) = (Instant::now(), Instant::now());
    let mut latest: Option<Feedback> = None;
    loop {
        tokio::select! {
            changed = feedback.changed() => {
                if changed.is_err() {
                    return Ok(());
                }
                let Some(HostMessage::Feedback(fresh)) = feedback.borrow_and_update().clone() else {
                    continue;
                };
                if odom_at.elapsed() >= ODOM_EVERY {
                    odom_at = Instant::now();
                    topics.odom.put(&views::odometry(&topics.frames, &fresh, robot)).await?;
                    topics.tf.put(&views::transforms(&topics.frames, &fresh, &pinhole)).await?;
                }
                if scan_at.elapsed() >= SCAN_EVERY {
                    scan_at = Instant::now();
                    topics.scan.put(&views::scan(&topics.frames, &fresh, robot)).await?;
                }
                latest = Some(fresh);
            }
            _ = slow.tick() => {
                topics.camera_info.put(&views::camera_info(&topics.frames, &pinhole)).await?;
                if let Some(fresh) = &latest {
                    topics.tf.put(&views::transforms(&topics.frames, fresh, &pinhole)).await?;
                    topics.scan.put(&views::scan(&topics.frames, fresh, robot)).await?;
                }
            }
        }
    }
}

/// The camera's frames, made only while a subscriber takes them.
async fn camera(topics: &Topics, lab: &Lab) -> Result<(), Ros2Error> {
    let mut frames = lab.handle.frames.clone();
    let mut look = tokio::time::interval(LOOK_EVERY);
    let mut watching: Option<Watching> = None;
    loop {
        tokio::select! {
            _ = look.tick() => {
                let wanted = topics.image.matched().await;
                if wanted != watching.is_some() {
                    watching = wanted.then(|| Watching::new(&lab.handle.watchers));
                }
            }
            changed = frames.changed(), if watching.is_some() => {
                if changed.is_err() {
                    return Ok(());
                }
                let Some(frame) = frames.borrow_and_update().clone() else {
                    continue;
                };
                match FrameHeader::decode(&frame) {
                    Ok((header, jpeg)) if header.format == ImageFormat::Jpeg => {
                        topics.image.put(&views::image(&topics.frames, jpeg)).await?;
                    }
                    Ok(_) => {}
                    Err(e) => warn!("ROS 2: a camera frame that does not decode: {e}"),
                }
            }
        }
    }
}
