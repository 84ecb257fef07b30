//! A gamepad made in software through uinput, read by the Guest as a real
//! one: its stick drives, its stop button stops. It needs a writable
//! /dev/uinput (a kernel module CI containers cannot load), so it runs on
//! request; the mappings it relies on are tested without any device in
//! vl-guest.
#![cfg(target_os = "linux")]

use std::time::{Duration, Instant};

use evdev::uinput::VirtualDevice;
use evdev::{
    AbsInfo, AbsoluteAxisCode, AttributeSet, EventType, InputEvent, KeyCode, UinputAbsSetup,
};
use vl_guest::{Gamepad, Pad, PadInput};

fn poll_until(pad: &mut Gamepad, done: impl Fn(&PadInput) -> bool) -> PadInput {
    let deadline = Instant::now() + Duration::from_secs(2);
    loop {
        let input = pad.poll();
        if done(&input) || Instant::now() > deadline {
            return input;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
#[ignore = "needs a writable /dev/uinput: cargo test -- --ignored on a machine with one"]
fn a_virtual_gamepad_drives_and_stops() {
    let builder = VirtualDevice::builder().expect("a writable /dev/uinput");
    let axis = |code| UinputAbsSetup::new(code, AbsInfo::new(128, 0, 255, 0, 0, 0));
    let keys = AttributeSet::from_iter([KeyCode::BTN_EAST, KeyCode::BTN_TL]);
    let mut device = builder
        .name("vl test pad")
        .with_absolute_axis(&axis(AbsoluteAxisCode::ABS_X))
        .and_then(|b| b.with_absolute_axis(&axis(AbsoluteAxisCode::ABS_Y)))
        .and_then(|b| b.with_keys(&keys))
        .and_then(|b| b.build())
        .expect("a virtual gamepad");
    let path = device
        .enumerate_dev_nodes_blocking()
        .unwrap()
        .find_map(Result::ok)
        .expect("its device node");
    std::thread::sleep(Duration::from_millis(200));
    let mut pad = Gamepad::open(&path, false).expect("opens as a gamepad");
    let emit = |device: &mut VirtualDevice, kind: EventType, code: u16, value: i32| {
        device
            .emit(&[InputEvent::new(kind.0, code, value)])
            .unwrap();
    };
    // Pushed away from the operator: forward.
    emit(
        &mut device,
        EventType::ABSOLUTE,
        AbsoluteAxisCode::ABS_Y.0,
        0,
    );
    let forward = poll_until(&mut pad, |i| i.stick.y > 0.9);
    assert!(forward.drive().y > 0.9, "{forward:?}");
    emit(&mut device, EventType::KEY, KeyCode::BTN_EAST.code(), 1);
    let stop = poll_until(&mut pad, |i| i.emergency_stop);
    assert!(stop.emergency_stop);
    // With a dead-man switch required, the stick counts only while it is held.
    let mut guarded = Gamepad::open(&path, true).unwrap();
    emit(
        &mut device,
        EventType::ABSOLUTE,
        AbsoluteAxisCode::ABS_Y.0,
        0,
    );
    let unheld = poll_until(&mut guarded, |i| i.stick.y > 0.9);
    assert_eq!(unheld.drive(), vl_core::Joystick::default());
    emit(&mut device, EventType::KEY, KeyCode::BTN_TL.code(), 1);
    let held = poll_until(&mut guarded, |i| i.dead_man);
    assert!(held.drive().y > 0.9, "{held:?}");
}
