//! `--ros2-operator`: a Twist on `/cmd_vel` drives the robot as the
//! Guests' stick does. The first Twist asks for the operator's role as
//! the identity the lab's staff named (`ros2::operator_as`), as a Guest's
//! hello does: refused while someone drives or others wait in line; then
//! it mounts a teleoperation run and starts it. Twists then become
//! commands paced by feedback (`server::pacing`), through the supervisor,
//! the safety layer, the leash and the watchdog, which stops the robot
//! 0.5 s after the last Twist. The role is let go after `RELEASE_AFTER`
//! without a Twist. After a run ends (its time, a fault, an
//! administrator's stop) no new run starts until `/cmd_vel` has been
//! quiet for `QUIET_TO_RESTART`. An emergency stop is latched: someone
//! saw something wrong, so no Twist drives again until `vl host` is
//! started again, by the lab's staff.

use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::sync::{mpsc, watch};
use tracing::{info, warn};
use vl_core::{
    Drive, EndReason, GuestMessage, HostMessage, PROTOCOL_VERSION, Role, RunComponent, Wire,
};

use super::Ros2Error;
use super::graph::{Node, Qos};
use super::messages::Twist;
use vl_host::Hush;
use vl_host::Pacer;
use vl_host::hub::{OUTBOX, ToConnection, ToHub};
use vl_host::{ACCOUNT_ENDED, Admitted, Gate};

const CMD_VEL: &str = "/cmd_vel";
/// The ROS side's clients of the hub are numbered from here, apart from
/// the connections the Host accepts and a cell's links.
const FIRST_ID: u64 = 1 << 56;
/// Without a Twist this long the role goes back to the lab's Guests.
const RELEASE_AFTER: Duration = Duration::from_secs(10);
/// How long `/cmd_vel` must be quiet before a new run starts after one ended.
const QUIET_TO_RESTART: Duration = Duration::from_secs(1);
/// How often a refused role or start is tried again while Twists come.
const RETRY_EVERY: Duration = Duration::from_secs(1);

/// The ROS side as one client of the hub.
struct AtHub {
    id: u64,
    inbox: mpsc::Receiver<ToConnection>,
    pacer: Pacer,
    /// When the run was last asked to start.
    start_asked: Option<Instant>,
}

/// Who `/cmd_vel` drives as, and the lab it drives.
pub(super) struct AtLab {
    pub(super) admitted: Admitted,
    /// Asked before each hello: an account removed drives no more.
    pub(super) gate: Arc<Gate>,
    pub(super) hub: mpsc::Sender<ToHub>,
}

/// Drives the lab from `/cmd_vel` for as long as the Host runs.
pub(super) async fn drive(
    node: &Node,
    lab: AtLab,
    mut feedback: watch::Receiver<Option<HostMessage>>,
) -> Result<(), Ros2Error> {
    let (twists_in, mut twists) = watch::channel(None::<Twist>);
    let _subscription = node
        .subscribe(CMD_VEL, Qos::STATE, move |twist: Twist, _| {
            twists_in.send_replace(Some(twist));
        })
        .await?;
    let mut driver = Driver {
        admitted: lab.admitted,
        gate: lab.gate,
        hub: lab.hub,
        next_id: FIRST_ID,
        at_hub: None,
        last_twist: None,
        quiet_needed: false,
        latched: false,
        refused_at: None,
        hush: Hush::default(),
    };
    let mut tick = tokio::time::interval(RETRY_EVERY / 4);
    loop {
        tokio::select! {
            changed = twists.changed() => {
                if changed.is_err() {
                    return Ok(());
                }
                let twist = *twists.borrow_and_update();
                if let Some(twist) = twist {
                    driver.twist(twist).await;
                }
            }
            out = driver.inbox() => driver.heard(out).await,
            changed = feedback.changed(), if driver.running() => {
                if changed.is_err() {
                    return Ok(());
                }
                let event = match &*feedback.borrow_and_update() {
                    Some(HostMessage::Feedback(f)) => Some(f.event),
                    _ => None,
                };
                if let Some(event) = event {
                    driver.feedback(event).await;
                }
            }
            _ = tick.tick() => driver.idle().await,
        }
    }
}

struct Driver {
    /// Who the lab's staff let `/cmd_vel` drive as.
    admitted: Admitted,
    gate: Arc<Gate>,
    hub: mpsc::Sender<ToHub>,
    next_id: u64,
    at_hub: Option<AtHub>,
    last_twist: Option<Instant>,
    /// A run ended: the next starts only after a quiet `/cmd_vel`.
    quiet_needed: bool,
    /// An emergency stop ended a run: nothing drives again.
    latched: bool,
    /// When the role or the run was last refused.
    refused_at: Option<Instant>,
    hush: Hush,
}

impl Driver {
    fn running(&self) -> bool {
        self.at_hub.as_ref().is_some_and(|a| a.pacer.running())
    }

    async fn inbox(&mut self) -> Option<ToConnection> {
        match &mut self.at_hub {
            Some(at_hub) => at_hub.inbox.recv().await,
            None => std::future::pending().await,
        }
    }

    async fn tell(&self, message: GuestMessage) {
        if let Some(at_hub) = &self.at_hub {
            let _ = self.hub.send(ToHub::Message(at_hub.id, message)).await;
        }
    }

    async fn twist(&mut self, twist: Twist) {
        let now = Instant::now();
        let quiet = self
            .last_twist
            .is_none_or(|last| now.duration_since(last) >= QUIET_TO_RESTART);
        self.last_twist = Some(now);
        if self.quiet_needed && quiet {
            self.quiet_needed = false;
        }
        let Some(drive) = Drive::from_twist(twist.linear.x, twist.angular.z) else {
            if self.hush.speak() {
                warn!("ROS 2 {CMD_VEL}: a Twist whose speeds are no finite numbers, ignored");
            }
            return;
        };
        if self.latched {
            if self.hush.speak() {
                warn!(
                    "ROS 2 {CMD_VEL}: ignored since the emergency stop; start vl host again to drive from ROS 2"
                );
            }
            return;
        }
        let recently_refused = self.refused_at.is_some_and(|at| at.elapsed() < RETRY_EVERY);
        if self.quiet_needed || recently_refused {
            return;
        }
        if self.at_hub.is_none() {
            self.join().await;
        }
        let command = self.at_hub.as_mut().and_then(|a| a.pacer.drive(drive));
        if let Some(command) = command {
            self.tell(command).await;
        }
    }

    /// Asks the hub for the operator's role, as whom the staff named.
    async fn join(&mut self) {
        if !self.gate.still_admits(&self.admitted) {
            self.refused_at = Some(Instant::now());
            if self.hush.speak() {
                warn!("ROS 2 {CMD_VEL}: ignored: {ACCOUNT_ENDED}");
            }
            return;
        }
        let id = self.next_id;
        self.next_id += 1;
        let (out, inbox) = mpsc::channel(OUTBOX);
        let hello = ToHub::Hello {
            id,
            admitted: self.admitted.clone(),
            protocol: PROTOCOL_VERSION,
            role: Role::Operator,
            resume: None,
        };
        if self.hub.send(ToHub::Join(id, out, None)).await.is_ok()
            && self.hub.send(hello).await.is_ok()
        {
            self.at_hub = Some(AtHub {
                id,
                inbox,
                pacer: Pacer::default(),
                start_asked: None,
            });
        }
    }

    /// Lets the role go.
    async fn leave(&mut self) {
        if let Some(at_hub) = self.at_hub.take() {
            let _ = self.hub.send(ToHub::Leave(at_hub.id, true)).await;
        }
    }

    async fn heard(&mut self, out: Option<ToConnection>) {
        let message = match out {
            Some(ToConnection::Send(message)) => message,
            Some(ToConnection::Subscribe | ToConnection::Watch(_)) => return,
            Some(ToConnection::End(..)) | None => return self.leave().await,
        };
        let Ok(message) = message.to_text().map(HostMessage::decode) else {
            return;
        };
        let Ok(message) = message else { return };
        let Some(at_hub) = &mut self.at_hub else {
            return;
        };
        at_hub.pacer.heard(&message);
        match message {
            HostMessage::Welcome {
                role: Role::Operator,
                experiments,
                ..
            } => {
                // The first experiment driven by stick: a Twist is a stick.
                let Some(driven) = experiments
                    .iter()
                    .find(|e| e.run.has(RunComponent::Teleoperate))
                else {
                    warn!("ROS 2 {CMD_VEL}: the lab offers no experiment driven by stick");
                    return self.leave().await;
                };
                info!("ROS 2 {CMD_VEL} drives the robot ({})", driven.id);
                let mount = GuestMessage::Mount {
                    experiment: driven.id.to_string(),
                };
                self.tell(mount).await;
            }
            HostMessage::Mounted(_) => self.start().await,
            HostMessage::Done { summary } => {
                if summary.reason == EndReason::EmergencyStop {
                    warn!(
                        "ROS 2 {CMD_VEL}: an emergency stop ended the run; no Twist drives until vl host starts again"
                    );
                    self.latched = true;
                }
                self.quiet_needed = true;
                self.leave().await;
            }
            HostMessage::Role {
                role: Role::Observer,
                ..
            } => self.leave().await,
            HostMessage::Error { code, message } => {
                if self.hush.speak() {
                    warn!("ROS 2 {CMD_VEL}: the lab refused ({code}): {message}");
                }
                self.refused_at = Some(Instant::now());
                if !at_hub.pacer.operator() {
                    self.leave().await;
                }
            }
            _ => {}
        }
    }

    async fn start(&mut self) {
        if let Some(at_hub) = &mut self.at_hub {
            at_hub.start_asked = Some(Instant::now());
        }
        self.tell(GuestMessage::Start).await;
    }

    async fn feedback(&mut self, event: u64) {
        let command = self.at_hub.as_mut().and_then(|a| a.pacer.feedback(event));
        if let Some(command) = command {
            self.tell(command).await;
        }
    }

    /// Lets the role go after long quiet; asks again for a start that was
    /// refused (the lab was getting ready) while Twists still come.
    async fn idle(&mut self) {
        let quiet_for = self.last_twist.map(|t| t.elapsed());
        if quiet_for.is_some_and(|q| q >= RELEASE_AFTER) {
            return self.leave().await;
        }
        let Some(at_hub) = &self.at_hub else { return };
        let wants_start = at_hub.pacer.operator()
            && !at_hub.pacer.running()
            && at_hub
                .start_asked
                .is_some_and(|at| at.elapsed() >= RETRY_EVERY)
            && quiet_for.is_some_and(|q| q < vl_core::WATCHDOG);
        if wants_start {
            self.start().await;
        }
    }
}
