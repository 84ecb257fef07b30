//! The hub and the control loop in-process: a dummy robot in the open
//! arena, no camera, clients that are channels. Who may do what, the
//! lease, the grace, hand-over, the emergency stop and the watchdog, each
//! in well under a second; the line for control in `queue`.

mod queue;

use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::sync::{mpsc, watch};
use vl_core::{
    Arena, Definition, DeviceState, Drive, EndReason, ErrorCode, Feedback, Goal, GuestMessage,
    HostMessage, PROTOCOL_VERSION, Point, Readiness, RobotModel, Role, Summary, WATCHDOG, Wire,
};

use super::{Hub, OUTBOX, ToConnection, ToHub};
use crate::accounts::gate::{Admitted, Identity};
use crate::accounts::users::AccountRole;
use crate::dummy::{DummyHandle, DummyRobot};
use crate::lab::{Devices, FramePolicy, Lab};
use crate::server::HostConfig;
use crate::server::events::{LabEvent, LabEvents};

/// Longer than anything here should take.
const PATIENCE: Duration = Duration::from_secs(2);

/// A hub serving a dummy robot in the open arena.
struct HubRig {
    hub: mpsc::Sender<ToHub>,
    robot: DummyHandle,
    feedback: watch::Receiver<Option<HostMessage>>,
    /// What the hub tells its listeners (the LMS side, a cell's links).
    events: LabEvents,
    next_id: u64,
}

impl HubRig {
    /// With no drive back to the start pose between runs, unless `config` asks.
    fn new(config: HostConfig) -> HubRig {
        let (robot, handle) = DummyRobot::new(RobotModel::khepera_ii());
        let devices = Devices {
            robot: Box::new(robot),
            camera: None,
            witness: None,
        };
        let arena = Arena::named("open").expect("the open arena ships");
        let lab = Lab::spawn(devices, arena, FramePolicy::EveryFrame, true, None);
        let feedback = lab.feedback.clone();
        let supervisor = config.supervisor().expect("the shipped nets load");
        let events = LabEvents::default();
        let hub = Hub::new(lab, Arc::new(config), supervisor, events.clone());
        let (tx, rx) = mpsc::channel(super::super::HUB_QUEUE);
        tokio::spawn(hub.run(rx));
        HubRig {
            hub: tx,
            robot: handle,
            feedback,
            events,
            next_id: 0,
        }
    }

    fn plain() -> HubRig {
        HubRig::new(HostConfig {
            reset: false,
            ..HostConfig::default()
        })
    }

    /// A new connection, not yet said hello.
    async fn join(&mut self) -> Client {
        self.next_id += 1;
        let (out, inbox) = mpsc::channel(OUTBOX);
        self.hub
            .send(ToHub::Join(self.next_id, out, None))
            .await
            .expect("the hub runs");
        Client {
            id: self.next_id,
            hub: self.hub.clone(),
            inbox,
        }
    }

    /// A client welcomed as `role`.
    async fn welcomed(&mut self, role: Role) -> Client {
        let mut client = self.join().await;
        client.hello(role, None).await;
        client.welcome().await;
        client
    }

    /// An operator with `experiment` mounted and a run started.
    async fn running(&mut self, experiment: &str) -> Client {
        let mut op = self.welcomed(Role::Operator).await;
        op.mount(experiment).await;
        op.say(GuestMessage::Start).await;
        op.next("started").await;
        op
    }

    /// Waits until the dummy robot's wheels are told to stand still.
    async fn robot_stops(&self) {
        let by = Instant::now() + PATIENCE;
        while !self.robot.still() {
            assert!(Instant::now() < by, "the robot still drives");
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }

    /// Waits until the dummy robot's wheels are told to move.
    async fn robot_moves(&self) {
        let by = Instant::now() + PATIENCE;
        while self.robot.still() {
            assert!(Instant::now() < by, "the robot never moved");
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }

    /// The event of the newest feedback the lab published.
    fn feedback_event(&self) -> Option<u64> {
        match &*self.feedback.borrow() {
            Some(HostMessage::Feedback(Feedback { event, .. })) => Some(*event),
            _ => None,
        }
    }
}

/// A connection as the hub sees it: an id and an outbox.
struct Client {
    id: u64,
    hub: mpsc::Sender<ToHub>,
    inbox: mpsc::Receiver<ToConnection>,
}

impl Client {
    async fn say(&self, message: GuestMessage) {
        self.hub
            .send(ToHub::Message(self.id, message))
            .await
            .expect("the hub runs");
    }

    async fn hello(&self, role: Role, resume: Option<String>) {
        self.greet(PROTOCOL_VERSION, role, resume).await;
    }

    /// A hello the gate let through, anonymous.
    async fn greet(&self, protocol: u32, role: Role, resume: Option<String>) {
        self.greet_as(Admitted::anyone(), protocol, role, resume)
            .await;
    }

    /// A hello from the account `name` with `role`, as the gate admitted it.
    async fn hello_as(&self, name: &str, account: AccountRole, role: Role) {
        let admitted = Admitted {
            identity: Identity::Account {
                name: name.into(),
                role: account,
            },
            may_drive: account.may_drive(),
            session: None,
        };
        self.greet_as(admitted, PROTOCOL_VERSION, role, None).await;
    }

    async fn greet_as(
        &self,
        admitted: Admitted,
        protocol: u32,
        role: Role,
        resume: Option<String>,
    ) {
        let hello = ToHub::Hello {
            id: self.id,
            admitted,
            protocol,
            role,
            resume,
        };
        self.hub.send(hello).await.expect("the hub runs");
    }

    /// The connection closes: `meant` when the client said bye.
    async fn leave(self, meant: bool) {
        self.hub
            .send(ToHub::Leave(self.id, meant))
            .await
            .expect("the hub runs");
    }

    async fn mount(&mut self, experiment: &str) {
        self.say(GuestMessage::Mount {
            experiment: experiment.into(),
        })
        .await;
        self.next("mounted").await;
    }

    /// Defines a run to the goal at (`x_mm`, `y_mm`).
    async fn define_goal(&self, x_mm: f64, y_mm: f64) {
        self.say(GuestMessage::Define {
            definition: Definition {
                goal: Some(Goal::at(Point { x_mm, y_mm })),
                ..Definition::default()
            },
        })
        .await;
    }

    async fn command(&self, event: u64, v: f64) {
        self.say(GuestMessage::Command {
            event,
            seen: None,
            drive: Drive::Velocity { v, w: 0.0 },
        })
        .await;
    }

    /// The next message, or none within `wait`.
    async fn within(&mut self, wait: Duration) -> Option<HostMessage> {
        loop {
            match tokio::time::timeout(wait, self.inbox.recv()).await {
                Ok(Some(ToConnection::Send(message))) => {
                    let text = message.to_text().expect("the hub sends text");
                    return Some(HostMessage::decode(text).expect("the hub speaks the protocol"));
                }
                Ok(Some(ToConnection::Subscribe | ToConnection::Watch(_))) => {}
                Ok(Some(ToConnection::End(..)) | None) | Err(_) => return None,
            }
        }
    }

    /// The next message of `kind`, passing over others.
    async fn next(&mut self, kind: &str) -> HostMessage {
        let by = Instant::now() + PATIENCE;
        loop {
            let left = by.saturating_duration_since(Instant::now());
            let message = self
                .within(left)
                .await
                .unwrap_or_else(|| panic!("no {kind} within {PATIENCE:?}"));
            let this: &'static str = (&message).into();
            if this == kind {
                return message;
            }
            assert!(
                this != "error" || kind == "error",
                "refused while waiting for {kind}: {message:?}"
            );
        }
    }

    /// The welcome, and the resume secret an operator's carries.
    async fn welcome(&mut self) -> Option<String> {
        match self.next("welcome").await {
            HostMessage::Welcome { resume, .. } => resume,
            _ => unreachable!(),
        }
    }

    /// The next refusal's code and words.
    async fn refused(&mut self) -> (ErrorCode, String) {
        match self.next("error").await {
            HostMessage::Error { code, message } => (code, message),
            _ => unreachable!(),
        }
    }

    /// The summary of the run that ends next.
    async fn done(&mut self) -> Summary {
        match self.next("done").await {
            HostMessage::Done { summary } => *summary,
            _ => unreachable!(),
        }
    }

    /// Whether the hub ends this connection within `wait` (an
    /// administrator's kick), passing over the messages before.
    async fn ended(&mut self, wait: Duration) -> bool {
        let by = Instant::now() + wait;
        loop {
            let left = by.saturating_duration_since(Instant::now());
            match tokio::time::timeout(left, self.inbox.recv()).await {
                Ok(Some(ToConnection::End(..))) => return true,
                Ok(Some(_)) => {}
                Ok(None) | Err(_) => return false,
            }
        }
    }

    /// Whether a message of `kind` comes within `wait`.
    async fn hears(&mut self, kind: &str, wait: Duration) -> bool {
        let by = Instant::now() + wait;
        while let Some(message) = self
            .within(by.saturating_duration_since(Instant::now()))
            .await
        {
            let this: &'static str = (&message).into();
            if this == kind {
                return true;
            }
        }
        false
    }
}

// Who may do what.

#[tokio::test]
async fn nothing_but_hello_comes_first() {
    let mut rig = HubRig::plain();
    let mut client = rig.join().await;
    client.say(GuestMessage::Start).await;
    assert_eq!(client.refused().await.0, ErrorCode::HelloFirst);
}

#[tokio::test]
async fn another_protocol_is_refused_with_the_hosts() {
    let mut rig = HubRig::plain();
    let mut client = rig.join().await;
    client
        .greet(PROTOCOL_VERSION + 1, Role::Observer, None)
        .await;
    let (code, why) = client.refused().await;
    assert_eq!(code, ErrorCode::ProtocolMismatch);
    assert!(why.contains(&PROTOCOL_VERSION.to_string()), "{why}");
}

/// A run's end is told to the lab's listeners with its driver's connection
/// and admission (whom an LMS grades), not only to its Guests.
#[tokio::test]
async fn a_run_s_end_is_told_with_who_drove_it() {
    let mut rig = HubRig::plain();
    let mut events = rig.events.listen();
    let mut op = rig.running("teleoperation").await;
    op.say(GuestMessage::Stop).await;
    let summary = op.done().await;
    let told = tokio::time::timeout(PATIENCE, events.recv()).await;
    let Ok(Ok(LabEvent::RunEnded(ended))) = told else {
        panic!("no run's end told: {told:?}");
    };
    assert_eq!(ended.run, Some(1));
    assert_eq!(ended.summary.reason, summary.reason);
    let driver = ended.driver.as_ref().expect("the run had a driver");
    assert_eq!(driver.connection, op.id);
    assert_eq!(driver.admitted.identity, Identity::Anonymous);
}

#[tokio::test]
async fn a_second_hello_is_refused() {
    let mut rig = HubRig::plain();
    let mut client = rig.welcomed(Role::Observer).await;
    client.hello(Role::Observer, None).await;
    assert_eq!(client.refused().await.0, ErrorCode::NotAllowedNow);
}

#[tokio::test]
async fn observers_watch_and_may_not_drive() {
    let mut rig = HubRig::plain();
    let mut observer = rig.welcomed(Role::Observer).await;
    for message in [
        GuestMessage::Mount {
            experiment: "navigation".into(),
        },
        GuestMessage::Start,
        GuestMessage::Stop,
    ] {
        observer.say(message).await;
        let (code, why) = observer.refused().await;
        assert_eq!(code, ErrorCode::NotOperator);
        assert!(why.contains("only the operator"), "{why}");
    }
}

#[tokio::test]
async fn one_operator_at_a_time() {
    let mut rig = HubRig::plain();
    let _op = rig.welcomed(Role::Operator).await;
    let mut second = rig.join().await;
    second.hello(Role::Operator, None).await;
    let (code, why) = second.refused().await;
    assert_eq!(code, ErrorCode::OperatorTaken);
    assert!(why.contains("observer"), "says what to do instead: {why}");
}

#[tokio::test]
async fn only_offered_experiments_mount() {
    let navigation = vl_core::ExperimentId::new("navigation").unwrap();
    let mut rig = HubRig::new(HostConfig {
        experiments: vl_core::Experiments::shipped().only(&[navigation]).unwrap(),
        reset: false,
        ..HostConfig::default()
    });
    let mut op = rig.welcomed(Role::Operator).await;
    op.say(GuestMessage::Mount {
        experiment: "teleoperation".into(),
    })
    .await;
    let (code, why) = op.refused().await;
    assert_eq!(code, ErrorCode::UnknownExperiment);
    assert!(why.contains("it offers navigation"), "{why}");
}

#[tokio::test]
async fn nothing_starts_before_a_mount() {
    let mut rig = HubRig::plain();
    let mut op = rig.welcomed(Role::Operator).await;
    op.say(GuestMessage::Start).await;
    assert_eq!(op.refused().await.0, ErrorCode::NotAllowedNow);
}

#[tokio::test]
async fn a_goal_off_the_arena_is_refused_with_where_it_is() {
    let mut rig = HubRig::plain();
    let mut op = rig.welcomed(Role::Operator).await;
    op.mount("navigation").await;
    op.define_goal(900.0, 100.0).await;
    let (code, why) = op.refused().await;
    assert_eq!(code, ErrorCode::InvalidDefinition);
    assert!(why.contains("outside the 600 × 600 mm arena"), "{why}");
}

#[tokio::test]
async fn a_late_observer_catches_up_on_the_mount_and_definition() {
    let mut rig = HubRig::plain();
    let mut op = rig.welcomed(Role::Operator).await;
    op.mount("navigation").await;
    op.define_goal(500.0, 120.0).await;
    op.next("defined").await;
    let mut late = rig.welcomed(Role::Observer).await;
    late.next("mounted").await;
    late.next("defined").await;
}

#[tokio::test]
async fn stale_and_non_finite_commands_are_refused() {
    let mut rig = HubRig::plain();
    let mut op = rig.running("teleoperation").await;
    op.command(2, 50.0).await;
    op.command(2, 50.0).await;
    let (code, why) = op.refused().await;
    assert_eq!(code, ErrorCode::StaleCommand);
    assert!(why.contains("2 was already executed"), "{why}");
    op.command(3, f64::NAN).await;
    assert_eq!(op.refused().await.0, ErrorCode::BadMessage);
}

#[tokio::test]
async fn a_robot_that_does_not_answer_starts_no_run() {
    let mut rig = HubRig::plain();
    rig.robot.set_silent(true);
    let mut op = rig.welcomed(Role::Operator).await;
    op.mount("teleoperation").await;
    // The lab finds the robot silent within a few control periods, and
    // says so to everyone.
    loop {
        if let HostMessage::Status { robot, .. } = op.next("status").await
            && robot == DeviceState::Offline
        {
            break;
        }
    }
    op.say(GuestMessage::Start).await;
    let (code, why) = op.refused().await;
    assert_eq!(code, ErrorCode::RobotOffline);
    assert!(why.contains("when it is back"), "{why}");
    // Back, it drives again.
    rig.robot.set_silent(false);
    loop {
        if let HostMessage::Status { robot, .. } = op.next("status").await
            && robot == DeviceState::Online
        {
            break;
        }
    }
    op.say(GuestMessage::Start).await;
    op.next("started").await;
}

#[tokio::test]
async fn a_robot_that_falls_silent_mid_run_ends_it_as_a_fault() {
    let mut rig = HubRig::plain();
    let mut op = rig.running("teleoperation").await;
    op.command(1, 80.0).await;
    rig.robot_moves().await;
    rig.robot.set_silent(true);
    let done = op.done().await;
    assert_eq!(done.reason, EndReason::Fault);
    // The summary says what failed.
    assert!(
        done.ending().starts_with("fault: the robot did not answer"),
        "{}",
        done.ending()
    );
}

// The emergency stop.

#[tokio::test]
async fn an_observer_s_emergency_stop_ends_the_run_and_says_who() {
    let mut rig = HubRig::plain();
    let mut op = rig.running("teleoperation").await;
    let observer = rig.welcomed(Role::Observer).await;
    op.command(1, 80.0).await;
    rig.robot_moves().await;
    observer.say(GuestMessage::EmergencyStop).await;
    let summary = op.done().await;
    assert_eq!(summary.reason, EndReason::EmergencyStop);
    let stopper = summary.stopped_by.expect("who pressed it");
    assert_eq!(
        (stopper.role, stopper.session),
        (Role::Observer, observer.id)
    );
    rig.robot_stops().await;
}

#[tokio::test]
async fn after_an_emergency_stop_the_robot_is_not_driven_back() {
    let mut rig = HubRig::new(HostConfig::default());
    let mut op = rig.running("teleoperation").await;
    op.command(1, 100.0).await;
    rig.robot_moves().await;
    tokio::time::sleep(Duration::from_millis(150)).await;
    op.say(GuestMessage::EmergencyStop).await;
    op.done().await;
    rig.robot_stops().await;
    // Nothing moves until the operator starts again: no drive back (a
    // status names the last run, the lab ready as it stands).
    let by = Instant::now() + Duration::from_millis(300);
    while let Some(message) = op
        .within(by.saturating_duration_since(Instant::now()))
        .await
    {
        if let HostMessage::Status { lab, .. } = message {
            assert_eq!(lab, vl_core::Readiness::Ready);
        }
    }
    assert!(rig.robot.still());
}

#[tokio::test]
async fn a_stopped_run_that_moved_the_robot_drives_it_back_first() {
    let mut rig = HubRig::new(HostConfig::default());
    let mut op = rig.running("teleoperation").await;
    op.command(1, 100.0).await;
    rig.robot_moves().await;
    tokio::time::sleep(Duration::from_millis(200)).await;
    op.say(GuestMessage::Stop).await;
    assert_eq!(op.done().await.reason, EndReason::Stopped);
    // The lab gets ready: a start meanwhile is refused with the reason.
    loop {
        if let HostMessage::Status { lab, .. } = op.next("status").await
            && lab == Readiness::GettingReady
        {
            break;
        }
    }
    op.say(GuestMessage::Start).await;
    let (code, why) = op.refused().await;
    assert_eq!(code, ErrorCode::NotAllowedNow);
    assert!(why.contains("getting ready"), "{why}");
}

// The watchdog and the lease.

#[tokio::test]
async fn the_watchdog_stops_a_robot_whose_commands_stop() {
    let mut rig = HubRig::plain();
    let op = rig.running("teleoperation").await;
    op.command(1, 80.0).await;
    rig.robot_moves().await;
    let since = Instant::now();
    rig.robot_stops().await;
    let after = since.elapsed();
    assert!(
        after >= WATCHDOG.mul_f64(0.8) && after < WATCHDOG * 2,
        "stopped {after:?} after the last command, the watchdog is {WATCHDOG:?}"
    );
}

#[tokio::test]
async fn the_control_loop_answers_each_command_with_its_event() {
    let mut rig = HubRig::plain();
    let op = rig.running("teleoperation").await;
    for event in 1..=5 {
        op.command(event, 40.0).await;
        let by = Instant::now() + PATIENCE;
        while rig.feedback_event() < Some(event) {
            assert!(Instant::now() < by, "no feedback for event {event}");
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
    }
}

#[tokio::test]
async fn a_silent_operator_loses_the_run_and_the_role() {
    let mut rig = HubRig::new(HostConfig {
        lease: Duration::from_millis(100),
        reset: false,
        ..HostConfig::default()
    });
    let mut op = rig.running("teleoperation").await;
    let (code, why) = op.refused().await;
    assert_eq!(code, ErrorCode::Timeout);
    assert!(why.contains("you watch now"), "{why}");
    assert_eq!(op.done().await.reason, EndReason::OperatorSilent);
    // The role is free for the next person.
    let mut next = rig.join().await;
    next.hello(Role::Operator, None).await;
    next.welcome().await;
}

// Leaving, the grace, and hand-over.

#[tokio::test]
async fn an_operator_who_says_bye_frees_the_role_at_once() {
    let mut rig = HubRig::plain();
    let op = rig.running("teleoperation").await;
    let mut observer = rig.welcomed(Role::Observer).await;
    op.leave(true).await;
    assert_eq!(observer.done().await.reason, EndReason::OperatorLeft);
    // The observer takes over, on the same connection.
    observer.hello(Role::Operator, None).await;
    observer.welcome().await;
    observer.mount("navigation").await;
}

#[tokio::test]
async fn a_dropped_operator_is_held_for_and_comes_back_to_the_run() {
    let mut rig = HubRig::new(HostConfig {
        grace: Duration::from_secs(5),
        reset: false,
        ..HostConfig::default()
    });
    let mut op = rig.join().await;
    op.hello(Role::Operator, None).await;
    let resume = op.welcome().await.expect("a resume secret");
    op.mount("teleoperation").await;
    op.say(GuestMessage::Start).await;
    op.next("started").await;
    op.command(1, 80.0).await;
    rig.robot_moves().await;
    op.leave(false).await;
    // The robot is held still; the role is not anyone else's…
    rig.robot_stops().await;
    let mut other = rig.join().await;
    other.hello(Role::Operator, None).await;
    let (code, why) = other.refused().await;
    assert_eq!(code, ErrorCode::OperatorTaken);
    assert!(why.contains("held for them"), "{why}");
    // …nor theirs with a wrong secret; with the right one, the run goes on.
    other
        .hello(Role::Operator, Some("not-the-secret".into()))
        .await;
    assert_eq!(other.refused().await.0, ErrorCode::OperatorTaken);
    let mut back = rig.join().await;
    back.hello(Role::Operator, Some(resume)).await;
    back.welcome().await;
    back.next("started").await;
    back.command(2, 80.0).await;
    rig.robot_moves().await;
}

#[tokio::test]
async fn a_dropped_operator_who_does_not_come_back_loses_the_run() {
    let mut rig = HubRig::new(HostConfig {
        grace: Duration::from_millis(100),
        reset: false,
        ..HostConfig::default()
    });
    let op = rig.running("teleoperation").await;
    let mut observer = rig.welcomed(Role::Observer).await;
    op.leave(false).await;
    assert_eq!(observer.done().await.reason, EndReason::OperatorLeft);
    observer.hello(Role::Operator, None).await;
    observer.welcome().await;
}

#[tokio::test]
async fn a_client_that_does_not_read_is_let_go() {
    let mut rig = HubRig::plain();
    let mut deaf = rig.welcomed(Role::Observer).await;
    let op = rig.welcomed(Role::Operator).await;
    // Every refusal goes to the deaf observer's outbox, which is never read.
    for _ in 0..OUTBOX + 8 {
        deaf.say(GuestMessage::Start).await;
    }
    // The operator is still served…
    op.say(GuestMessage::Start).await;
    let mut op = op;
    op.refused().await;
    // …and the deaf one's outbox was let go: what is in it drains, then it closes.
    let drained = tokio::time::timeout(PATIENCE, async {
        while deaf.inbox.recv().await.is_some() {}
    })
    .await;
    assert!(drained.is_ok(), "the hub still holds the outbox");
}
