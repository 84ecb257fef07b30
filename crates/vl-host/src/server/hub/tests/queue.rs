//! The line for control: first come first served, a slot that ends the
//! run and hands control on, a place an account keeps across a dropped
//! link, and no place for those who may not drive.

use std::time::Duration;

use vl_core::{EndReason, ErrorCode, GuestMessage, HostMessage, Role};

use super::{Client, HubRig, PATIENCE};
use crate::accounts::users::AccountRole;
use crate::server::HostConfig;

/// A lab whose operator drives `slot` while others wait.
fn slotted(slot: Duration) -> HubRig {
    HubRig::new(HostConfig {
        slot: Some(slot),
        reset: false,
        ..HostConfig::default()
    })
}

impl Client {
    /// Where this client stands in line: (position, length, wait).
    async fn place(&mut self) -> (Option<u32>, u32, Option<f64>) {
        match self.next("queue").await {
            HostMessage::Queue {
                position,
                length,
                wait_s,
            } => (position, length, wait_s),
            _ => unreachable!(),
        }
    }

    /// Its next role change: the role, and the slot's length.
    async fn role(&mut self) -> (Role, Option<f64>) {
        match self.next("role").await {
            HostMessage::Role { role, slot_s, .. } => (role, slot_s),
            _ => unreachable!(),
        }
    }
}

#[tokio::test]
async fn the_second_driver_waits_in_line_and_drives_when_the_first_leaves() {
    let mut rig = slotted(Duration::from_secs(600));
    let op = rig.welcomed(Role::Operator).await;
    let mut second = rig.welcomed(Role::Observer).await;
    second.say(GuestMessage::Queue).await;
    let (position, length, wait) = second.place().await;
    assert_eq!((position, length), (Some(1), 1));
    let wait = wait.expect("slots have a length");
    assert!(
        (590.0..=600.0).contains(&wait),
        "waits what is left of the slot: {wait}"
    );
    // A third who asks to drive is told to wait too, and is second in line.
    let mut third = rig.welcomed(Role::Observer).await;
    third.hello(Role::Operator, None).await;
    assert_eq!(third.refused().await.0, ErrorCode::OperatorTaken);
    third.say(GuestMessage::Queue).await;
    let (position, length, wait) = third.place().await;
    assert_eq!((position, length), (Some(2), 2));
    assert!(wait.unwrap() > 1150.0, "a slot more: {wait:?}");
    op.leave(true).await;
    assert_eq!(second.role().await, (Role::Operator, Some(600.0)));
    assert_eq!(third.place().await.0, Some(1));
    second.mount("teleoperation").await;
}

#[tokio::test]
async fn a_slot_ends_the_run_and_hands_control_on() {
    let mut rig = slotted(Duration::from_millis(400));
    let mut op = rig.running("teleoperation").await;
    op.command(1, 100.0).await;
    rig.robot_moves().await;
    let mut next = rig.welcomed(Role::Observer).await;
    next.say(GuestMessage::Queue).await;
    assert_eq!(next.place().await.0, Some(1));
    // The slot may have run on before anyone waited: the last word is the end.
    while op.role().await.0 == Role::Operator {}
    assert_eq!(next.role().await.0, Role::Operator);
    assert_eq!(op.done().await.reason, EndReason::SlotEnded);
    rig.robot_stops().await;
    // The one who drove now only watches.
    op.say(GuestMessage::Start).await;
    assert_eq!(op.refused().await.0, ErrorCode::NotOperator);
    next.mount("teleoperation").await;
}

#[tokio::test]
async fn with_no_one_waiting_the_slot_runs_on() {
    let mut rig = slotted(Duration::from_millis(200));
    let mut op = rig.running("teleoperation").await;
    for event in 1..=8 {
        op.command(event, 50.0).await;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    // Told the slot at its welcome, and each time it ran on.
    for _ in 0..3 {
        let (role, slot) = op.role().await;
        assert_eq!(role, Role::Operator);
        assert!((slot.unwrap() - 0.2).abs() < 0.05, "{slot:?}");
    }
    assert!(!op.hears("done", Duration::from_millis(100)).await);
}

#[tokio::test]
async fn an_account_keeps_its_place_across_a_dropped_link() {
    let mut rig = slotted(Duration::from_secs(600));
    let _op = rig.welcomed(Role::Operator).await;
    let ada = rig.join().await;
    ada.hello_as("ada", AccountRole::Operator, Role::Observer)
        .await;
    let mut ada = ada;
    ada.welcome().await;
    ada.say(GuestMessage::Queue).await;
    assert_eq!(ada.place().await.0, Some(1));
    let mut later = rig.welcomed(Role::Observer).await;
    later.say(GuestMessage::Queue).await;
    assert_eq!(later.place().await.0, Some(2));
    ada.leave(false).await;
    // Back within the grace, ada is first again.
    let mut back = rig.join().await;
    back.hello_as("ada", AccountRole::Operator, Role::Observer)
        .await;
    back.welcome().await;
    assert_eq!(back.place().await.0, Some(1));
    // An anonymous place is given up with its link.
    later.leave(false).await;
    let mut again = rig.welcomed(Role::Observer).await;
    again.say(GuestMessage::Queue).await;
    assert_eq!(again.place().await.0, Some(2));
}

#[tokio::test]
async fn those_who_may_not_drive_get_no_place() {
    let mut rig = slotted(Duration::from_secs(600));
    let mut bob = rig.join().await;
    bob.hello_as("bob", AccountRole::Observer, Role::Observer)
        .await;
    bob.welcome().await;
    bob.say(GuestMessage::Queue).await;
    let (code, why) = bob.refused().await;
    assert_eq!(code, ErrorCode::Unauthorized);
    assert!(why.contains("may drive"), "{why}");
    // With no one driving or waiting, asking is being granted at once.
    let mut ada = rig.join().await;
    ada.hello_as("ada", AccountRole::Operator, Role::Observer)
        .await;
    ada.welcome().await;
    ada.say(GuestMessage::Queue).await;
    assert_eq!(ada.role().await.0, Role::Operator);
    ada.say(GuestMessage::Queue).await;
    assert_eq!(ada.refused().await.0, ErrorCode::NotAllowedNow);
}

#[tokio::test]
async fn an_administrator_ends_a_turn_and_a_place_and_no_one_else_may() {
    let mut rig = slotted(Duration::from_secs(600));
    let mut op = rig.running("teleoperation").await;
    let mut next = rig.welcomed(Role::Observer).await;
    next.say(GuestMessage::Queue).await;
    assert_eq!(next.place().await.0, Some(1));
    let mut last = rig.welcomed(Role::Observer).await;
    last.say(GuestMessage::Queue).await;
    assert_eq!(last.place().await.0, Some(2));
    // Not an administrator: refused.
    next.say(GuestMessage::Kick { session: op.id }).await;
    assert_eq!(next.refused().await.0, ErrorCode::Unauthorized);
    let mut root = rig.join().await;
    root.hello_as("root", AccountRole::Admin, Role::Observer)
        .await;
    root.welcome().await;
    root.say(GuestMessage::Kick { session: op.id }).await;
    assert_eq!(op.role().await.0, Role::Observer);
    // Its connection is ended: it asks for nothing more from it.
    assert!(op.ended(PATIENCE).await);
    assert_eq!(root.done().await.reason, EndReason::Kicked);
    assert_eq!(next.role().await.0, Role::Operator);
    root.say(GuestMessage::Kick { session: last.id }).await;
    loop {
        if last.place().await.0.is_none() {
            break;
        }
    }
    assert!(last.ended(PATIENCE).await);
    root.say(GuestMessage::Kick { session: 999 }).await;
    assert_eq!(root.refused().await.0, ErrorCode::NotAllowedNow);
}
