//! The Guest window, rendered for real (wgpu on the machine's Vulkan or GL
//! driver, no display needed) against a live simulated Host: once connected
//! and mounted it shows the camera image with the robot on it, the
//! round-trip time and the proximity readings.

use std::time::{Duration, Instant};

use crate::common;
use egui::Vec2;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;

use vl_client::{LinkState, Login, check_path, drag_path};
use vl_core::{Arena, Point, Role};
use vl_guest::GuestApp;
use vl_host::{Host, HostConfig, SimCamera, SimLab};

/// The simulated camera paints the robot's body this colour.
const BODY: [u8; 3] = [170, 36, 32];

pub(crate) fn step_until(
    harness: &mut Harness<'_, GuestApp>,
    what: &str,
    done: impl Fn(&GuestApp) -> bool,
) {
    let deadline = Instant::now() + Duration::from_secs(10);
    while !done(harness.state()) {
        assert!(Instant::now() < deadline, "the window never got to: {what}");
        harness.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    harness.step();
}

/// A Guest window on `url`, as operator, rendered by wgpu.
fn window(url: &str) -> Harness<'static, GuestApp> {
    window_as(url, Role::Operator, Vec2::new(1100.0, 720.0))
}

/// A Guest window on `url` as `role`, `size` px.
fn window_as(url: &str, role: Role, size: Vec2) -> Harness<'static, GuestApp> {
    let app = GuestApp::new(url, role, Login::default()).expect("a Host's address");
    harness_of(app, size)
}

/// `app` in a window `size` px, rendered by wgpu.
pub(crate) fn harness_of(app: GuestApp, size: Vec2) -> Harness<'static, GuestApp> {
    Harness::builder()
        .with_size(size)
        .wgpu()
        .build_ui_state(|ui, app: &mut GuestApp| app.show(ui), app)
}

/// A simulated Host on `runtime`, the navigation arena without a camera.
pub(crate) fn host_without_camera(runtime: &tokio::runtime::Runtime, config: HostConfig) -> Host {
    let lab = SimLab {
        camera: None,
        ..SimLab::new(Arena::navigation())
    };
    let listen = "127.0.0.1:0".parse().unwrap();
    runtime
        .block_on(Host::start_sim(listen, lab, config))
        .unwrap()
}

/// A simulated Host on `runtime`, the navigation arena with its camera.
fn host_with_camera(runtime: &tokio::runtime::Runtime, config: HostConfig) -> Host {
    let lab = SimLab {
        camera: Some(SimCamera::default()),
        ..SimLab::new(Arena::navigation())
    };
    let listen = "127.0.0.1:0".parse().unwrap();
    runtime
        .block_on(Host::start_sim(listen, lab, config))
        .unwrap()
}

/// Waits for the welcome, mounts the navigation experiment and waits
/// until `seen` holds of the session.
fn mount_navigation(
    harness: &mut Harness<'_, GuestApp>,
    seen: impl Fn(&vl_client::Session) -> bool,
) {
    step_until(harness, "be welcomed", |app| app.session().role.is_some());
    harness
        .get_by_label("Navigate to a goal among obstacles")
        .click();
    step_until(harness, "see the mounted lab", |app| seen(app.session()));
}

/// Defines the goal shown (the window plans the path) and, once its
/// forecast has passed, starts the run.
pub(crate) fn define_and_start(harness: &mut Harness<'_, GuestApp>) {
    let told = harness.state().session().forecasts;
    harness
        .get_by_role_and_label(egui::accesskit::Role::Button, "Define")
        .click();
    // Start waits for the new definition's forecast to pass.
    step_until(harness, "define", |app| {
        app.session().forecasts > told && app.session().allows(vl_core::Action::Start)
    });
    harness.get_by_label("Start").click();
    step_until(harness, "start", |app| app.session().running);
}

/// Runs `test` on a Guest window connected as operator to a simulated
/// Host (with or without its camera), with the navigation experiment
/// being mounted.
fn with_mounting_window(camera: bool, test: impl FnOnce(&mut Harness<'_, GuestApp>)) {
    with_window_on(camera, "Navigate to a goal among obstacles", test);
}

/// Runs `test` on a Guest window connected as operator to a simulated Host
/// (with or without its camera), with the experiment titled `experiment`
/// being mounted.
fn with_window_on(camera: bool, experiment: &str, test: impl FnOnce(&mut Harness<'_, GuestApp>)) {
    let lab = SimLab {
        camera: camera.then(SimCamera::default),
        ..SimLab::new(Arena::navigation())
    };
    with_window_in(lab, experiment, test);
}

/// The same on the simulated `lab`.
fn with_window_in(lab: SimLab, experiment: &str, test: impl FnOnce(&mut Harness<'_, GuestApp>)) {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let host = runtime
        .block_on(Host::start_sim(
            "127.0.0.1:0".parse().unwrap(),
            lab,
            HostConfig::default(),
        ))
        .unwrap();
    let _entered = runtime.enter();
    let mut harness = window(&host.url());
    step_until(&mut harness, "be welcomed", |app| {
        app.session().role.is_some()
    });
    harness.get_by_label(experiment).click();
    test(&mut harness);
}

#[test]
fn the_connected_view_renders_camera_robot_and_rtt() {
    with_mounting_window(true, connected_view);
}

fn connected_view(harness: &mut Harness<'_, GuestApp>) {
    step_until(harness, "show a frame and the robot", |app| {
        let s = app.session();
        s.lab.is_some() && s.frame.is_some() && s.robot.is_some() && s.round_trips.count() > 0
    });

    harness.get_by_label_contains("connected");
    harness.get_by_label_contains("RTT ");
    harness.get_by_label_contains("IR0 ");
    harness.get_by_label("Start");

    // Define the suggested goal: the window plans a path to it.
    harness
        .get_by_role_and_label(egui::accesskit::Role::Button, "Define")
        .click();
    step_until(
        harness,
        "show the definition and its passed forecast",
        |app| app.session().definition.is_some() && app.session().allows(vl_core::Action::Start),
    );
    let path = harness.state().session().definition.clone().unwrap().path;
    assert!(path.len() > 100, "a planned path of {} points", path.len());
    harness.get_by_label_contains("mm from obstacles");
    // Started, the robot follows the path with no hand on the stick …
    harness.get_by_label("Start").click();
    step_until(harness, "start the run", |app| app.session().running);
    let at = |app: &GuestApp| app.session().robot.as_ref().unwrap().pose.point();
    let from = at(harness.state());
    step_until(harness, "follow the path", |app| {
        at(app).distance(from) > 60.0
    });
    let here = at(harness.state());
    let off_path = path
        .iter()
        .map(|p| p.distance(here))
        .fold(f64::MAX, f64::min);
    assert!(off_path < 20.0, "{off_path:.0} mm off the path");
    // … and the arrow key takes over while held.
    let start_x = harness.state().session().robot.as_ref().unwrap().pose.x_mm;
    harness.key_down(egui::Key::ArrowUp);
    step_until(harness, "drive forward on the arrow key", |app| {
        app.session().robot.as_ref().unwrap().pose.x_mm > start_x + 20.0
    });
    harness.key_up(egui::Key::ArrowUp);
    assert!(harness.state().session().sent_event > 0);

    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(env!("CARGO_TARGET_TMPDIR"), "/guest-window.png"));
    let robot_pixels = image
        .pixels()
        .filter(|p| p.0[..3].iter().zip(BODY).all(|(a, b)| a.abs_diff(b) <= 8))
        .count();
    // The robot's 70 mm body is ~28 px across on the 320-px camera, scaled up in the view.
    assert!(
        robot_pixels > 300,
        "only {robot_pixels} robot-coloured pixels on screen"
    );
}

/// A lab without a camera still shows its floor: the arena drawn from the
/// model the Host sends at mount, with the robot's reported pose on it.
#[test]
fn without_a_camera_the_window_draws_the_arena_from_its_model() {
    with_mounting_window(false, arena_from_model);
}

fn arena_from_model(harness: &mut Harness<'_, GuestApp>) {
    step_until(harness, "mount and see the robot", |app| {
        app.session().lab.is_some() && app.session().robot.is_some()
    });
    harness.get_by_label_contains("no camera in this lab");
    assert!(harness.query_by_label("waiting for the camera…").is_none());

    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-no-camera.png"
    ));
    let count = |rgb: [u8; 3]| {
        image
            .pixels()
            .filter(|p| p.0[..3].iter().zip(rgb).all(|(a, b)| a.abs_diff(b) <= 4))
            .count()
    };
    // The navigation arena's four obstacles cover about 8 % of its floor.
    let (floor, obstacles) = (count([226, 224, 218]), count([45, 48, 56]));
    assert!(floor > 100_000, "{floor} floor pixels");
    assert!(
        obstacles * 100 > floor * 4 && obstacles * 100 < floor * 15,
        "{obstacles} obstacle pixels on {floor} of floor"
    );
}

/// A Host that cannot be reached leaves the window open, saying why and
/// trying again with back-off, the attempt shown; once the Host is up the
/// window connects by itself and the error goes.
#[test]
fn an_unreachable_host_is_shown_and_tried_until_it_is_up() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let port = common::free_port();
    let url = format!("ws://127.0.0.1:{port}");
    let _entered = runtime.enter();
    let mut harness = window(&url);
    step_until(&mut harness, "try connecting again", |app| {
        matches!(
            app.session().link,
            LinkState::Unreachable { attempt: 2.., .. }
        )
    });
    harness.get_by_label_contains(&format!("cannot connect to {url}: connection refused"));
    harness.get_by_label_contains("trying again (attempt");
    harness.get_by_label("no Host answers yet: trying again…");
    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-unreachable.png"
    ));

    let _host = runtime
        .block_on(Host::start_sim(
            ([127, 0, 0, 1], port).into(),
            SimLab {
                camera: None,
                ..SimLab::new(Arena::navigation())
            },
            HostConfig::default(),
        ))
        .unwrap();
    // The window connects by itself once the Host is up.
    step_until(&mut harness, "be welcomed once the Host is up", |app| {
        app.session().role.is_some()
    });
    assert!(harness.query_by_label_contains("trying again").is_none());
    assert!(harness.query_by_label("Reconnect").is_none());
    harness.get_by_label("Navigate to a goal among obstacles");
}

/// A window on a Host that is killed (as `kill -9`) mid-run and started
/// again reconnects by itself, shows the new Host's robot and frames live
/// within 2 s of its first frame, and keeps nothing from before: no mount,
/// definition, path, run or message of the old Host.
#[test]
fn a_host_started_again_is_seen_live_with_nothing_from_before() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let listen = format!("127.0.0.1:{}", common::free_port());
    let start = || common::start_vl(&["host", "--listen", &listen], "vl host listening on ");
    let (host, url) = start();
    let _entered = runtime.enter();
    let mut harness = window(&url);
    mount_navigation(&mut harness, |s| {
        s.lab.is_some() && s.frame.is_some() && s.robot.is_some()
    });
    define_and_start(&mut harness);
    let old_frame = harness.state().session().frame.as_ref().unwrap().header.seq;

    drop(host);
    step_until(&mut harness, "notice the Host is gone", |app| {
        matches!(app.session().link, LinkState::Reconnecting { .. })
    });
    let _host = start();
    step_until(&mut harness, "be welcomed by the new Host", |app| {
        app.session().welcomes == 2
    });
    // Nothing of the old Host's is shown.
    let s = harness.state().session();
    assert!(s.lab.is_none() && s.definition.is_none() && s.done.is_none());
    assert!(s.errors.is_empty(), "{:?}", s.errors);
    for old in [
        "mm from obstacles",
        "Last run",
        "Host said",
        "Define",
        "link lost",
    ] {
        assert!(
            harness.query_by_label_contains(old).is_none(),
            "'{old}' is still on screen"
        );
    }
    // Live again: the new Host's frames and feedback arrive and move on.
    step_until(&mut harness, "see the new Host's first frame", |app| {
        app.session().frame.is_some() && app.session().robot.is_some()
    });
    let first = Instant::now();
    let (seq, t_ms) = {
        let s = harness.state().session();
        (
            s.frame.as_ref().unwrap().header.seq,
            s.robot.as_ref().unwrap().t_ms,
        )
    };
    step_until(&mut harness, "see frames and poses move on", |app| {
        let s = app.session();
        s.frame.as_ref().unwrap().header.seq > seq && s.robot.as_ref().unwrap().t_ms > t_ms
    });
    assert!(
        first.elapsed() <= Duration::from_secs(2),
        "live again {:.1} s after the first frame",
        first.elapsed().as_secs_f64()
    );
    assert!(
        seq < old_frame + 1_000_000,
        "a frame number of the new Host"
    );
    harness.get_by_label_contains("pose 0.");
    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-after-restart.png"
    ));
}

/// The force the obstacles push back with is drawn on the stick and on the
/// robot: nothing in the open, an arrow when driving at the box ahead.
#[test]
fn the_force_arrow_appears_at_an_obstacle_and_vanishes_in_the_open() {
    with_window_on(false, "Drive the robot by joystick", force_arrow);
}

/// The force arrow's colour.
const FORCE: [u8; 3] = [255, 70, 90];

fn force_pixels(harness: &mut Harness<'_, GuestApp>, name: &str) -> usize {
    let image = harness.render().expect("the window renders");
    let _ = image.save(format!("{}/{name}.png", env!("CARGO_TARGET_TMPDIR")));
    image
        .pixels()
        .filter(|p| p.0[..3].iter().zip(FORCE).all(|(a, b)| a.abs_diff(b) <= 6))
        .count()
}

fn force_arrow(harness: &mut Harness<'_, GuestApp>) {
    step_until(harness, "mount and see the robot", |app| {
        app.session().lab.is_some() && app.session().robot.is_some()
    });
    // No definition needed: Start hands the robot to the stick.
    harness.get_by_label("Start").click();
    step_until(harness, "start the run", |app| app.session().running);
    step_until(harness, "feel the open arena", |app| {
        app.session()
            .robot
            .as_ref()
            .is_some_and(|r| r.force.is_some())
    });
    assert_eq!(
        force_pixels(harness, "force-open"),
        0,
        "no push in the open"
    );
    // The box is 150 mm ahead of the start: drive at it until the push is
    // strong. The arrows grow with it: at a push of 0.3 they cover about
    // 140 pixels, at 0.6 about 270, so the bound below is not one render's
    // luck.
    harness.key_down(egui::Key::ArrowUp);
    step_until(harness, "feel the box ahead", |app| {
        app.session()
            .robot
            .as_ref()
            .and_then(|r| r.force)
            .is_some_and(|[_, ahead]| ahead < -0.6)
    });
    harness.key_up(egui::Key::ArrowUp);
    let near = force_pixels(harness, "force-near-box");
    assert!(near > 150, "only {near} force-coloured pixels near the box");
    let robot = harness.state().session().robot.clone().unwrap();
    assert!(!robot.contact);
    // Back into the open: the arrow goes.
    harness.key_down(egui::Key::ArrowDown);
    step_until(harness, "back away", |app| {
        app.session()
            .robot
            .as_ref()
            .and_then(|r| r.force)
            .is_some_and(|[x, y]| x.hypot(y) < 0.01)
    });
    harness.key_up(egui::Key::ArrowDown);
    assert_eq!(force_pixels(harness, "force-backed-off"), 0);
    // Space is the emergency stop: the run ends.
    harness.key_press(egui::Key::Space);
    step_until(harness, "stop on Space", |app| !app.session().running);
    assert_eq!(
        harness.state().session().done.as_ref().map(|d| d.reason),
        Some(vl_core::EndReason::EmergencyStop)
    );
}

/// A stick the test holds: it drives forward until told to press its stop
/// button, and records the forces the window renders on it.
struct TestPad {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    felt: std::sync::Arc<std::sync::Mutex<Vec<[f64; 2]>>>,
}

impl vl_guest::Pad for TestPad {
    fn name(&self) -> &str {
        "test pad"
    }

    fn poll(&mut self) -> vl_guest::PadInput {
        vl_guest::PadInput {
            stick: vl_core::Joystick { x: 0.0, y: 1.0 },
            emergency_stop: self.stop.load(std::sync::atomic::Ordering::Relaxed),
            dead_man: true,
        }
    }

    fn render(&mut self, force: [f64; 2]) {
        self.felt.lock().unwrap().push(force);
    }
}

/// A gamepad drives the robot from the window and feels the box ahead; its
/// stop button ends the run.
#[test]
fn a_gamepad_drives_feels_and_stops() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let host = host_without_camera(&runtime, HostConfig::default());
    let _entered = runtime.enter();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let felt = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let pad = TestPad {
        stop: stop.clone(),
        felt: felt.clone(),
    };
    let app = GuestApp::new(&host.url(), Role::Operator, Login::default())
        .unwrap()
        .with_pad(Box::new(pad));
    let mut harness = harness_of(app, Vec2::new(1100.0, 720.0));
    step_until(&mut harness, "be welcomed", |app| {
        app.session().role.is_some()
    });
    harness.get_by_label_contains("stick: test pad");
    harness.get_by_label("Drive the robot by joystick").click();
    step_until(&mut harness, "mount", |app| app.session().lab.is_some());
    harness.get_by_label("Start").click();
    step_until(&mut harness, "feel the box ahead", |app| {
        app.session()
            .robot
            .as_ref()
            .and_then(|r| r.force)
            .is_some_and(|[_, ahead]| ahead < -0.6)
    });
    assert!(
        felt.lock().unwrap().iter().any(|&[_, ahead]| ahead < -0.3),
        "the pad was given the push to render"
    );
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    step_until(&mut harness, "stop on the pad's button", |app| {
        !app.session().running
    });
    assert_eq!(
        harness.state().session().done.as_ref().map(|d| d.reason),
        Some(vl_core::EndReason::EmergencyStop)
    );
}

/// Appendix F.2 and B.1 in the window: the C-space shows over the view at
/// a click, and a box dragged on the view becomes a virtual obstacle that
/// goes into the C-space and the definition.
#[test]
fn drawn_obstacles_enter_the_cspace_and_the_definition() {
    with_mounting_window(false, draw_obstacle);
}

fn draw_obstacle(harness: &mut Harness<'_, GuestApp>) {
    step_until(harness, "mount and see the robot", |app| {
        app.session().lab.is_some() && app.session().robot.is_some()
    });
    let plain = harness.render().expect("the window renders");
    harness.get_by_label("C-space").click();
    harness.step();
    harness.step();
    let overlaid = harness.render().expect("the window renders");
    let _ = overlaid.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-cspace.png"
    ));
    let changed = |a: &image::RgbaImage, b: &image::RgbaImage| {
        a.pixels()
            .zip(b.pixels())
            .filter(|(p, q)| {
                p.0[..3]
                    .iter()
                    .zip(&q.0[..3])
                    .any(|(x, y)| x.abs_diff(*y) > 12)
            })
            .count()
    };
    // The obstacles grown by the robot's radius cover far more than the obstacles.
    let shown = changed(&plain, &overlaid);
    assert!(shown > 20_000, "the C-space changed only {shown} pixels");

    harness.get_by_label("draw obstacles").click();
    harness.step();
    // A box on open floor between the robot and the bar.
    let from = on_screen(
        harness,
        Point {
            x_mm: 170.0,
            y_mm: 230.0,
        },
    );
    let to = on_screen(
        harness,
        Point {
            x_mm: 230.0,
            y_mm: 290.0,
        },
    );
    drag(harness, from, to);
    harness.get_by_label_contains("1 drawn");
    let with_box = harness.render().expect("the window renders");
    let _ = with_box.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-drawn.png"
    ));
    assert!(
        changed(&overlaid, &with_box) > 5_000,
        "the drawn box grew the C-space"
    );
    harness
        .get_by_role_and_label(egui::accesskit::Role::Button, "Define")
        .click();
    step_until(harness, "define with the drawn obstacle", |app| {
        app.session()
            .definition
            .as_ref()
            .is_some_and(|d| d.virtual_obstacles.len() == 1)
    });
}

/// Where the floor point `p` is on screen, through the camera view's place
/// and the mounted camera model.
fn on_screen(harness: &Harness<'_, GuestApp>, p: Point) -> egui::Pos2 {
    let rect = harness.get_by_label(vl_guest::CAMERA_VIEW).rect();
    let camera = harness.state().session().lab.as_ref().unwrap().scene.camera;
    let (c, r) = camera.to_pixel(p);
    rect.min
        + Vec2::new(
            (c / f64::from(camera.width_px)) as f32 * rect.width(),
            (r / f64::from(camera.height_px)) as f32 * rect.height(),
        )
}

/// A mouse drag from `from` to `to`, in steps a hand would make.
fn drag(harness: &mut Harness<'_, GuestApp>, from: egui::Pos2, to: egui::Pos2) {
    harness.hover_at(from);
    harness.step();
    harness.drag_at(from);
    harness.step();
    for k in 1..=5 {
        harness.hover_at(from + (to - from) * (k as f32 / 5.0));
        harness.step();
    }
    harness.drop_at(to);
    harness.step();
    harness.step();
}

/// Appendix F.4: a point of the planned path dragged to open floor bends
/// the path, which is defined; dragged into an obstacle, the change is
/// refused, saying where the path would enter the C-space.
#[test]
fn a_dragged_path_is_checked_against_the_cspace() {
    with_mounting_window(false, edit_path);
}

fn edit_path(harness: &mut Harness<'_, GuestApp>) {
    step_until(harness, "mount and see the robot", |app| {
        app.session().lab.is_some() && app.session().robot.is_some()
    });
    harness
        .get_by_role_and_label(egui::accesskit::Role::Button, "Define")
        .click();
    step_until(harness, "define a planned path", |app| {
        app.session()
            .definition
            .as_ref()
            .is_some_and(|d| d.path.len() > 100)
    });
    let lab = harness.state().session().lab.clone().unwrap();
    let planned = harness.state().session().definition.clone().unwrap().path;
    let mid = planned.len() / 2;
    // Somewhere 15 mm to one side that the robot can still pass.
    let to = [(0.0, 15.0), (0.0, -15.0), (15.0, 0.0), (-15.0, 0.0)]
        .into_iter()
        .map(|(dx, dy)| Point {
            x_mm: planned[mid].x_mm + dx,
            y_mm: planned[mid].y_mm + dy,
        })
        .find(|&to| {
            drag_path(&planned, mid, to).is_ok_and(|bent| check_path(&lab, &[], &bent).is_ok())
        })
        .expect("room beside the path");
    let (from_px, to_px) = (on_screen(harness, planned[mid]), on_screen(harness, to));
    drag(harness, from_px, to_px);
    step_until(harness, "define the bent path", |app| {
        app.session()
            .definition
            .as_ref()
            .is_some_and(|d| d.path != planned)
    });
    harness.get_by_label("the changed path is clear: defined");
    let bent = harness.state().session().definition.clone().unwrap().path;
    let moved = bent
        .iter()
        .map(|p| p.distance(to))
        .fold(f64::INFINITY, f64::min);
    assert!(
        moved < 3.0,
        "the path passes {moved:.1} mm from where it was dragged"
    );
    assert_eq!(bent.first(), planned.first());
    assert_eq!(bent.last(), planned.last());

    // Into the round obstacle at (420, 170): refused, the path unchanged.
    let obstacle = Point {
        x_mm: 420.0,
        y_mm: 170.0,
    };
    let near = bent
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.distance(obstacle).total_cmp(&b.1.distance(obstacle)))
        .map(|(i, _)| i)
        .unwrap();
    let (from_px, to_px) = (on_screen(harness, bent[near]), on_screen(harness, obstacle));
    drag(harness, from_px, to_px);
    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-path-refused.png"
    ));
    harness.get_by_label_contains("not changed: the changed path enters the C-space at");
    assert_eq!(
        harness.state().session().definition.as_ref().unwrap().path,
        bent
    );
}

/// Appendix F.6: the settings a user tuned in an earlier session are read
/// from their file, go into the next definition, and a change in the panel
/// is written back.
#[test]
fn settings_are_remembered_between_sessions() {
    let dir = common::scratch("guest-settings");
    let file = dir.join("vl").join("settings.toml");
    std::fs::create_dir_all(file.parent().unwrap()).unwrap();
    std::fs::write(
        &file,
        "lookahead_mm = 45.0\nmargin_mm = 15.0\nmax_speed_mm_s = 150.0\n",
    )
    .unwrap();
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let host = host_without_camera(&runtime, HostConfig::default());
    let _entered = runtime.enter();
    let app = GuestApp::new(&host.url(), Role::Operator, Login::default())
        .expect("a Host's address")
        .with_settings_file(file.clone());
    let mut harness = harness_of(app, Vec2::new(1100.0, 720.0));
    step_until(&mut harness, "be welcomed", |app| {
        app.session().role.is_some()
    });
    harness
        .get_by_label("Navigate to a goal among obstacles")
        .click();
    step_until(&mut harness, "mount and see the robot", |app| {
        app.session().lab.is_some() && app.session().robot.is_some()
    });
    harness
        .get_by_role_and_label(egui::accesskit::Role::Button, "Define")
        .click();
    step_until(&mut harness, "define", |app| {
        app.session().definition.is_some()
    });
    let definition = harness.state().session().definition.clone().unwrap();
    assert_eq!(definition.lookahead_mm, Some(45.0));
    assert_eq!(definition.max_speed_mm_s, Some(150.0));

    // Lifting the speed limit in the panel is kept for the next session.
    harness.get_by_label("Settings").click();
    harness.step();
    harness.get_by_label("speed limit").click();
    harness.step();
    harness.step();
    let kept = std::fs::read_to_string(&file).unwrap();
    assert!(!kept.contains("max_speed_mm_s"), "{kept}");
    assert!(kept.contains("lookahead_mm = 45.0"), "{kept}");
}

/// The ghost's colour.
const GHOST: [u8; 3] = [235, 90, 255];

fn ghost_pixels(harness: &mut Harness<'_, GuestApp>, name: &str) -> usize {
    let image = harness.render().expect("the window renders");
    let _ = image.save(format!("{}/{name}.png", env!("CARGO_TARGET_TMPDIR")));
    image
        .pixels()
        .filter(|p| p.0[..3].iter().zip(GHOST).all(|(a, b)| a.abs_diff(b) <= 6))
        .count()
}

/// Over a geostationary satellite's 560 ms round trip, driving forward:
/// the ghost runs ahead of the delayed pose (along the robot's heading,
/// where it truly is), the window says by how much and how old the
/// feedback is, and the toggle takes the ghost away.
#[test]
fn the_predictive_display_runs_ahead_of_the_delayed_pose() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let (host, media) = runtime.block_on(async {
        let host = Host::start_sim(
            "127.0.0.1:0".parse().unwrap(),
            SimLab {
                camera: None,
                ..SimLab::new(Arena::navigation())
            },
            HostConfig::default(),
        )
        .await
        .unwrap();
        let media = vl_host::Media::start(
            "127.0.0.1:0".parse().unwrap(),
            vl_host::MediaConfig {
                upstream: host.url(),
                model: vl_sim::LinkModel::profile(vl_sim::Profile::GeoSatellite),
                seed: 3,
            },
        )
        .await
        .unwrap();
        (host, media)
    });
    let _entered = runtime.enter();
    let mut harness = window(&media.url());
    step_until(&mut harness, "be welcomed", |app| {
        app.session().role.is_some()
    });
    harness.get_by_label("Drive the robot by joystick").click();
    step_until(&mut harness, "mount and see the robot", |app| {
        app.session().lab.is_some() && app.session().robot.is_some()
    });
    harness.get_by_label("Start").click();
    step_until(&mut harness, "start the run", |app| app.session().running);
    harness.key_down(egui::Key::ArrowUp);
    step_until(&mut harness, "drive ahead of the delayed feedback", |app| {
        let s = app.session();
        let (Some(robot), Some(ghost)) = (&s.robot, s.predicted(Instant::now())) else {
            return false;
        };
        let ahead = (ghost.x_mm - robot.pose.x_mm) * robot.pose.theta_rad.cos()
            + (ghost.y_mm - robot.pose.y_mm) * robot.pose.theta_rad.sin();
        ahead > 15.0
    });
    let label = harness
        .query_by_label_contains("mm from the reported pose")
        .expect("the window says how far ahead the ghost is")
        .value()
        .unwrap_or_default();
    // The pose shown is about one way old: half of 560 ms.
    let old: f64 = label
        .split("pose ")
        .nth(1)
        .and_then(|rest| rest.split(" s old").next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{label:?}"));
    assert!((0.2..0.6).contains(&old), "{label:?}");
    let shown = ghost_pixels(&mut harness, "ghost-shown");
    assert!(shown > 100, "only {shown} ghost-coloured pixels");
    harness.key_up(egui::Key::ArrowUp);
    harness.get_by_label("predictive display").click();
    harness.step();
    harness.step();
    assert_eq!(ghost_pixels(&mut harness, "ghost-hidden"), 0);
    assert!(
        harness
            .query_by_label_contains("mm from the reported pose")
            .is_none()
    );
    drop(media);
    drop(host);
}

/// The window's view of the lab's net follows the Host's marking through
/// mount → define → start → done, and its controls are enabled exactly when
/// their events are.
#[test]
fn the_net_view_follows_the_marking_through_a_run() {
    with_mounting_window(false, |harness| {
        let marked = |app: &GuestApp, place: &str| {
            app.session()
                .nets
                .state()
                .marking
                .iter()
                .any(|p| p == place)
        };
        step_until(harness, "mount", |app| marked(app, "cspace.built"));
        // Folded at first, in users' words when opened.
        assert!(harness.query_by_label_contains("may happen").is_none());
        harness.get_by_label("Lab net").click();
        harness.step();
        harness.get_by_label_contains("now: lab mounted");
        harness.get_by_label("may happen: define, forecast passed, forecast refused, leave, mount");
        assert!(harness.state().session().nets_agree);
        harness
            .get_by_role_and_label(egui::accesskit::Role::Button, "Define")
            .click();
        step_until(harness, "define", |app| marked(app, "forecast.passed"));
        harness.step();
        harness.get_by_label_contains(", forecast passed");
        harness.get_by_label("Start").click();
        step_until(harness, "start", |app| marked(app, "execute.running"));
        harness.get_by_label_contains("robot follows the path");
        harness.get_by_label("may happen: drive, leave, run ends, stop");
        let image = harness.render().expect("the window renders");
        let _ = image.save(concat!(env!("CARGO_TARGET_TMPDIR"), "/guest-net-view.png"));
        harness.get_by_label("Stop").click();
        // The run's end leaves the forecast unpassed; the Host tries the
        // definition again from where the robot is, and it passes.
        step_until(harness, "finish the run and pass the new forecast", |app| {
            app.session().done.is_some()
                && marked(app, "execute.ready")
                && marked(app, "forecast.passed")
        });
        harness.step();
        harness.get_by_label("may happen: define, leave, mount, start");
        assert!(harness.state().session().nets_agree);
    });
}

/// The window as people see it, at a small and a large size: a run under
/// way with its path, trail and ghost, the legend and ages in full, the
/// status bar on one line; the lab getting ready after it; an observer
/// beside it. Each is saved for a person to look at (`target/tmp`), and
/// what can be checked in pixels and labels is.
#[test]
fn the_window_at_800_and_1600_px() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let host = host_with_camera(&runtime, HostConfig::default());
    let _entered = runtime.enter();
    for size in [Vec2::new(800.0, 600.0), Vec2::new(1600.0, 1000.0)] {
        let name = |what: &str| {
            format!(
                "{}/guest-{}x{}-{what}.png",
                env!("CARGO_TARGET_TMPDIR"),
                size.x,
                size.y
            )
        };
        let mut operator = window_as(&host.url(), Role::Operator, size);
        let mut observer = window_as(&host.url(), Role::Observer, size);
        mount_navigation(&mut operator, |s| {
            s.lab.is_some() && s.frame.is_some() && s.robot.is_some() && s.ready()
        });
        define_and_start(&mut operator);
        let at = |app: &GuestApp| app.session().robot.as_ref().unwrap().pose.point();
        let from = at(operator.state());
        step_until(&mut operator, "drive a way", |app| {
            at(app).distance(from) > 150.0
        });
        operator.get_by_label("C-space").click();
        operator.step();
        operator.step();
        // The ages line is whole, not cut off, at either size.
        operator.get_by_label_contains("frame 0.");
        operator.get_by_label_contains("ghost: where it is now, predicted");
        let image = operator.render().expect("the window renders");
        let _ = image.save(name("run"));
        // The camera view takes the room there is: at least half the width.
        let view = operator.get_by_label(vl_guest::CAMERA_VIEW).rect();
        assert!(
            view.width() >= 0.45 * size.x,
            "the camera view is {:.0} px wide in a {:.0} px window",
            view.width(),
            size.x
        );
        // The status bar is one line at either size.
        let stop = operator.get_by_label("STOP (Space)").rect();
        let event = operator.get_by_label_contains("(sent ").rect();
        assert!(
            (stop.center().y - event.center().y).abs() < 4.0,
            "{stop:?} {event:?}"
        );

        step_until(&mut observer, "watch the run", |app| {
            app.session().running && app.session().frame.is_some()
        });
        observer.get_by_label_contains("You are watching");
        assert!(observer.query_by_label_contains("Drag the stick").is_none());
        let _ = observer.render().map(|i| i.save(name("observer")));

        operator.get_by_label("Stop").click();
        step_until(&mut operator, "get ready after the run", |app| {
            !app.session().ready()
        });
        operator.get_by_label_contains("Getting ready");
        assert!(!operator.state().session().allows(vl_core::Action::Start));
        operator.get_by_label("Lab net").click();
        operator.step();
        let _ = operator.render().map(|i| i.save(name("getting-ready")));
        step_until(&mut operator, "be ready again", |app| app.session().ready());
        let pose = operator.state().session().robot.as_ref().unwrap().pose;
        assert!(
            pose.point().distance(Point {
                x_mm: 100.0,
                y_mm: 120.0
            }) < 6.0,
            "{pose:?}"
        );
        operator.get_by_label_contains("Last run: stopped");
    }
}

/// Runs in a row from a window on a Host with noisy optics (`vl host
/// --optics noisy`, its own process, as README gives it), an observer's
/// window beside, both rendered: none may end with the camera losing the
/// robot, each starts from the start pose once the lab is ready. A few in
/// CI; `bench/window_runs.sh` runs twenty.
#[test]
fn window_runs_on_noisy_optics_never_lose_the_robot() {
    let runs: usize = std::env::var("WINDOW_RUNS")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(3);
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let (_host, url) = common::start_host(&["--optics", "noisy"]);
    let _entered = runtime.enter();
    let size = Vec2::new(1100.0, 720.0);
    let mut operator = window_as(&url, Role::Operator, size);
    let mut observer = window_as(&url, Role::Observer, size);
    let mut both = |operator: &mut Harness<'_, GuestApp>| {
        observer.step();
        let _ = observer.render();
        let _ = operator.render();
    };
    mount_navigation(&mut operator, |s| s.lab.is_some());
    let mut ends = Vec::new();
    for run in 1..=runs {
        step_until(&mut operator, "see a ready lab", |app| {
            let s = app.session();
            s.robot.is_some() && s.ready() && s.allows(vl_core::Action::Define)
        });
        define_and_start(&mut operator);
        let deadline = Instant::now() + Duration::from_secs(60);
        while operator.state().session().running || operator.state().session().done.is_none() {
            assert!(Instant::now() < deadline, "run {run} did not end");
            operator.step();
            both(&mut operator);
            std::thread::sleep(Duration::from_millis(20));
        }
        let done = operator.state().session().done.clone().unwrap();
        eprintln!(
            "window run {run}/{runs}: {} in {:.1} s",
            done.reason, done.seconds
        );
        ends.push(done.reason);
        assert_ne!(done.reason, vl_core::EndReason::RobotLost, "run {run}");
        assert!(done.reached_goal, "run {run}: {}", done.reason);
    }
    assert_eq!(ends.len(), runs);
}

/// A run the safety layer holds back for good ends, and the window says
/// why in words: here a robot whose odometry slips so much, with no camera
/// and sensors it cannot trust, that it cannot pass the arena's gaps.
#[test]
fn a_held_back_run_says_why_in_the_window() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let slippery = vl_core::RobotModel {
        wheel_slip: 0.4,
        sensor_range_mm: 1.0,
        ..vl_core::RobotModel::khepera_ii()
    };
    let host = runtime
        .block_on(Host::start_sim(
            "127.0.0.1:0".parse().unwrap(),
            SimLab {
                camera: None,
                robot: slippery,
                ..SimLab::new(Arena::navigation())
            },
            HostConfig::default(),
        ))
        .unwrap();
    let _entered = runtime.enter();
    let mut harness = window(&host.url());
    mount_navigation(&mut harness, |s| {
        s.lab.is_some() && s.robot.is_some() && s.ready()
    });
    define_and_start(&mut harness);
    let deadline = Instant::now() + Duration::from_secs(30);
    while harness.state().session().done.is_none() {
        assert!(Instant::now() < deadline, "the run never ended");
        harness.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    harness.step();
    harness.get_by_label_contains("Last run: held back by the safety layer, goal not reached");
    harness.get_by_label_contains("Why: position uncertain by");
    harness.get_by_label_contains("add a camera or widen the margin.");
    // Too unsure where it is to drive back to the start by itself.
    assert!(
        harness.state().session().ready(),
        "the lab does not drive back"
    );
    let _ = harness.render().map(|i| {
        i.save(format!(
            "{}/guest-held-back.png",
            env!("CARGO_TARGET_TMPDIR")
        ))
    });
}

/// At a lab with accounts the window, refused as an anonymous operator,
/// opens its login form; an account typed in logs in and drives, and the
/// window says who it is.
#[test]
fn the_window_logs_in_with_an_account() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let mut users = vl_host::Users::default();
    users
        .add("ada", vl_host::AccountRole::Operator, "correct horse")
        .unwrap();
    let host = host_without_camera(
        &runtime,
        HostConfig {
            users: Some(users),
            ..HostConfig::default()
        },
    );
    let _entered = runtime.enter();
    let mut harness = window(&host.url());
    step_until(&mut harness, "be refused", |app| {
        !app.session().errors.is_empty()
    });
    harness.get_by_label_contains("this lab's operators log in");
    harness.get_by_label_contains("not let in: log in");
    for (role, text) in [
        (egui::accesskit::Role::TextInput, "ada"),
        (egui::accesskit::Role::PasswordInput, "correct horse"),
    ] {
        harness.get_by_role(role).click();
        harness.step();
        harness.get_by_role(role).type_text(text);
        harness.step();
    }
    harness.step();
    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-login.png"
    ));
    harness.get_by_label("Log in to drive").click();
    step_until(&mut harness, "be welcomed as ada", |app| {
        app.session().user.as_deref() == Some("ada")
    });
    assert_eq!(harness.state().session().role, Some(Role::Operator));
    harness.get_by_label("Logged in as ada");
    harness
        .get_by_label("Navigate to a goal among obstacles")
        .click();
    step_until(&mut harness, "mount", |app| app.session().lab.is_some());
    // The window's text never shows the password.
    assert!(harness.query_by_label_contains("correct horse").is_none());
}

/// A simulated Host whose slots last `slot`, someone driving it; its address.
fn busy_lab(
    runtime: &tokio::runtime::Runtime,
    slot: Duration,
) -> (Host, common::peer::Peer, String) {
    let host = host_without_camera(
        runtime,
        HostConfig {
            slot: Some(slot),
            ..HostConfig::default()
        },
    );
    let url = host.url();
    let driver = runtime.block_on(async {
        let mut driver = common::peer::Peer::connect(&url).await;
        driver.hello("operator").await;
        driver
    });
    (host, driver, url)
}

/// A window opened to drive a lab where someone drives watches and takes
/// its place in line by itself (it does not log in again and again), shows
/// the place and the wait with no error, and drives when the slot ends.
#[test]
fn a_window_asking_to_drive_a_busy_lab_waits_in_line() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let (_host, _driver, url) = busy_lab(&runtime, Duration::from_secs(3));
    let _entered = runtime.enter();
    let mut harness = window_as(&url, Role::Operator, Vec2::new(1100.0, 720.0));
    step_until(&mut harness, "be in line", |app| {
        app.session().queue.is_some()
    });
    assert_eq!(harness.state().session().role, Some(Role::Observer));
    assert!(
        harness.state().session().errors.is_empty(),
        "{:?}",
        harness.state().session().errors
    );
    harness.get_by_label_contains("You are 1st in line for control (1 waiting)");
    assert_eq!(harness.state().session().welcomes, 1, "logged in once");
    step_until(&mut harness, "get control", |app| {
        app.session().role == Some(Role::Operator)
    });
    harness.get_by_label_contains("your slot: 0:0");
}

/// An observer joins the line with one click, sees its place and how long
/// it waits, and drives when the operator's slot ends, the time left shown.
#[test]
fn an_observer_asks_for_control_and_gets_it_in_turn() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let (_host, _driver, url) = busy_lab(&runtime, Duration::from_secs(2));
    let _entered = runtime.enter();
    let mut harness = window_as(&url, Role::Observer, Vec2::new(1100.0, 720.0));
    step_until(&mut harness, "be welcomed", |app| {
        app.session().role.is_some()
    });
    harness.get_by_label("Ask for control").click();
    step_until(&mut harness, "be in line", |app| {
        app.session().queue.is_some()
    });
    harness
        .get_by_label_contains("You are 1st in line for control (1 waiting), control within 0:0");
    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-in-line.png"
    ));
    step_until(&mut harness, "get control", |app| {
        app.session().role == Some(Role::Operator)
    });
    harness.get_by_label_contains("your slot: 0:0");
    assert!(harness.query_by_label("Ask for control").is_none());
    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-granted.png"
    ));
}

/// Pixels of `image` within a little of `colour`.
fn pixels_of(image: &image::RgbaImage, colour: [u8; 3]) -> usize {
    image
        .pixels()
        .filter(|p| {
            p.0[..3]
                .iter()
                .zip(colour)
                .all(|(a, b)| a.abs_diff(b) <= 10)
        })
        .count()
}

/// Before Start the window shows the definition's forecast: its verdict
/// and figures, and its runs as ghosts over the view that play on Play.
/// A refused one says why, marks where, and Start stays disabled.
#[test]
fn the_forecast_is_previewed_before_start_and_a_refusal_is_shown() {
    const FORECAST: [u8; 3] = [150, 150, 255];
    const REFUSED: [u8; 3] = [230, 40, 40];
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let host = host_without_camera(&runtime, HostConfig::default());
    let _entered = runtime.enter();
    let mut harness = window(&host.url());
    mount_navigation(&mut harness, |s| s.lab.is_some() && s.robot.is_some());
    let view_before = harness.get_by_label(vl_guest::CAMERA_VIEW).rect();
    harness
        .get_by_role_and_label(egui::accesskit::Role::Button, "Define")
        .click();
    step_until(&mut harness, "be told the forecast", |app| {
        app.session().forecast.is_some()
    });
    harness.get_by_label("Passed: the run may start.");
    // The forecast's table opens in the controls: the view does not jump.
    let view_after = harness.get_by_label(vl_guest::CAMERA_VIEW).rect();
    assert!(
        (view_after.left() - view_before.left()).abs() < 1.0,
        "the camera view moved from {view_before:?} to {view_after:?}"
    );
    harness.get_by_label_contains("5 of 5 tries");
    let still = harness.render().expect("the window renders");
    harness.get_by_label("Play").click();
    let played = Instant::now();
    while played.elapsed() < Duration::from_millis(1500) {
        harness.step();
    }
    harness.get_by_label("Pause");
    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-forecast.png"
    ));
    assert!(
        pixels_of(&image, FORECAST) > 200,
        "the forecast's ghosts and paths are drawn"
    );
    assert_ne!(still.as_raw(), image.as_raw(), "the ghosts moved on Play");
    assert!(harness.state().session().allows(vl_core::Action::Start));

    // A lab that keeps 30 mm from everything refuses the same goal.
    let strict = HostConfig {
        forecast: vl_host::ForecastSettings {
            min_clearance_mm: 30.0,
            ..Default::default()
        },
        ..HostConfig::default()
    };
    let host = host_without_camera(&runtime, strict);
    let mut harness = window(&host.url());
    mount_navigation(&mut harness, |s| s.lab.is_some() && s.robot.is_some());
    harness
        .get_by_role_and_label(egui::accesskit::Role::Button, "Define")
        .click();
    step_until(&mut harness, "be told the forecast", |app| {
        app.session().forecast.is_some()
    });
    harness.get_by_label("Refused: define another.");
    harness.get_by_label_contains("this lab keeps 30 mm");
    for _ in 0..5 {
        harness.step();
    }
    assert!(!harness.state().session().allows(vl_core::Action::Start));
    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-forecast-refused.png"
    ));
    assert!(
        pixels_of(&image, REFUSED) > 50,
        "the refusal is shown in red"
    );
}

/// Where pixels of `colour` are on average in `image`, if any are.
fn centroid_of(image: &image::RgbaImage, colour: [u8; 3]) -> Option<(f64, f64)> {
    let (mut n, mut x, mut y) = (0.0, 0.0, 0.0);
    for (px, py, p) in image.enumerate_pixels() {
        if p.0[..3]
            .iter()
            .zip(colour)
            .all(|(a, b)| a.abs_diff(b) <= 10)
        {
            n += 1.0;
            x += f64::from(px);
            y += f64::from(py);
        }
    }
    (n > 0.0).then(|| (x / n, y / n))
}

/// Drags the replay's time slider to `fraction` of the run, as a hand does.
fn scrub(harness: &mut Harness<'_, GuestApp>, fraction: f32) {
    let rail = harness
        .get_by_role_and_label(egui::accesskit::Role::Slider, "time")
        .rect();
    let x = (rail.left() + fraction * rail.width()).min(rail.right() - 2.0);
    let at = egui::pos2(x, rail.center().y);
    // To the end, a hand drags past the rail: a pixel inside it is still a
    // little short of the run's last moment, where its `done` is.
    let to = if fraction >= 1.0 {
        egui::pos2(rail.right() + 40.0, rail.center().y)
    } else {
        at
    };
    drag(harness, at, to);
    for _ in 0..5 {
        harness.step();
    }
}

/// A Host's configuration that records every run into `dir`.
fn recording_into(dir: &std::path::Path) -> HostConfig {
    HostConfig {
        recordings: Some(vl_record::Catalogue::open(dir).unwrap()),
        ..HostConfig::default()
    }
}

/// A run the Host recorded, downloaded by its Guest, plays back in the
/// window: paused and scrubbed, the camera shows the robot where it was.
#[test]
fn a_downloaded_run_replays_in_the_window_and_scrubbing_moves_the_robot() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let dir = common::scratch("replay-window");
    let config = recording_into(&dir.join("host"));
    let listen = "127.0.0.1:0".parse().unwrap();
    let host = runtime
        .block_on(Host::start_sim(
            listen,
            SimLab::new(Arena::navigation()),
            config,
        ))
        .unwrap();
    let script = vl_client::Script {
        download_to: Some(dir.join("guest")),
        ..vl_client::Script::default()
    };
    let report = runtime
        .block_on(vl_client::run_script(&host.url(), &script))
        .unwrap();
    let file = report.downloaded.expect("the run's file was downloaded");
    let replay = vl_client::Replay::open(&file).unwrap();
    let mut harness = harness_of(GuestApp::replaying(replay), Vec2::new(1100.0, 720.0));
    harness.step();
    harness.get_by_label("Pause").click();
    harness.step();
    scrub(&mut harness, 0.02);
    let early = harness.render().unwrap();
    let at_start = harness.state_mut().replay().unwrap().at_s;
    scrub(&mut harness, 0.98);
    let late = harness.render().unwrap();
    let at_end = harness.state_mut().replay().unwrap().at_s;
    late.save(common::scratch("replay-window-shot").join("replay.png"))
        .unwrap();
    std::fs::create_dir_all(concat!(env!("CARGO_MANIFEST_DIR"), "/target/tmp")).unwrap();
    late.save(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/target/tmp/guest-window-replay.png"
    ))
    .unwrap();
    assert!(
        at_end > at_start + 2.0,
        "the slider went from {at_start} s to {at_end} s"
    );
    let from = centroid_of(&early, BODY).expect("the robot in the early frame");
    let to = centroid_of(&late, BODY).expect("the robot in the late frame");
    let moved = ((to.0 - from.0).powi(2) + (to.1 - from.1).powi(2)).sqrt();
    assert!(
        moved > 50.0,
        "the robot moved {moved:.0} px between {at_start:.1} s and {at_end:.1} s"
    );
    scrub(&mut harness, 1.0);
    assert_eq!(
        harness
            .state()
            .session()
            .done
            .as_ref()
            .map(|d| d.reached_goal),
        Some(true),
        "scrubbed to the end, the replay shows the run's end"
    );
    // The results beside it: paths, tracking error, wheels, round trip.
    harness
        .get_by_role_and_label(egui::accesskit::Role::Button, "Results")
        .click();
    for _ in 0..5 {
        harness.step();
    }
    let plot = harness
        .get_by_label("off the planned path, mm, against s")
        .rect();
    // Beside the camera view, not over it; ages by the replay's clock.
    let view = harness.get_by_label(vl_guest::CAMERA_VIEW).rect();
    assert!(plot.left() >= view.right() - 1.0, "{plot:?} over {view:?}");
    harness.get_by_label_contains("replay at ");
    assert!(harness.query_by_label_contains("ghost").is_none());
    let results = &harness.state_mut().replay().unwrap().results;
    assert!(results.followed.len() > 100 && results.planned.len() > 10);
    assert!(
        results.tracking_error_mm.iter().all(|[_, e]| *e < 20.0),
        "a run far off its path"
    );
    assert!(!results.forecast.is_empty() && !results.round_trip_ms.is_empty());
    harness
        .render()
        .unwrap()
        .save(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/target/tmp/guest-window-results.png"
        ))
        .unwrap();
    results_beside_the_view_at_800_and_1600(&mut harness);
}

/// The replay's results beside the camera view, not over it, at either
/// end of the sizes people use (screenshots saved).
fn results_beside_the_view_at_800_and_1600(harness: &mut Harness<'_, GuestApp>) {
    for (w, h) in [(800.0, 600.0), (1600.0, 1000.0)] {
        harness.set_size(Vec2::new(w, h));
        harness.step();
        harness.step();
        let plot = harness
            .get_by_label("off the planned path, mm, against s")
            .rect();
        let view = harness.get_by_label(vl_guest::CAMERA_VIEW).rect();
        assert!(
            plot.left() >= view.right() - 1.0,
            "at {w} px: {plot:?} over {view:?}"
        );
        let _ = harness.render().map(|i| {
            i.save(format!(
                "{}/guest-window-results-{w}.png",
                env!("CARGO_TARGET_TMPDIR")
            ))
        });
    }
}

/// A definition saved as a task in the window is loaded back and defined
/// again as it was; a name that could reach outside the folder is refused.
#[test]
fn a_task_is_saved_and_loaded_back_in_the_window() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let host = host_without_camera(&runtime, HostConfig::default());
    let _entered = runtime.enter();
    let tasks_dir = common::scratch("window-tasks");
    let app = GuestApp::new(&host.url(), Role::Operator, Login::default())
        .unwrap()
        .with_tasks(vl_client::Tasks::at(&tasks_dir));
    let mut harness = harness_of(app, Vec2::new(1100.0, 720.0));
    mount_navigation(&mut harness, |s| s.lab.is_some() && s.robot.is_some());
    harness
        .get_by_role_and_label(egui::accesskit::Role::Button, "Define")
        .click();
    // The forecast's verdict, when it comes, grows the panel above the
    // tasks: a click aimed before it lands where the button was.
    step_until(&mut harness, "define and forecast", |app| {
        app.session().definition.is_some() && app.session().forecast.is_some()
    });
    let defined = harness.state().session().definition.clone().unwrap();
    harness.get_by_label("Tasks").click();
    harness.step();
    harness
        .get_by_role_and_label(egui::accesskit::Role::TextInput, "Name")
        .type_text("../escape");
    harness.get_by_label("Save").click();
    harness.step();
    harness.get_by_label_contains("cannot name a task");
    assert!(std::fs::read_dir(&tasks_dir).map_or(true, |mut d| d.next().is_none()));

    harness
        .get_by_role_and_label(egui::accesskit::Role::TextInput, "Name")
        .focus();
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    harness
        .get_by_role_and_label(egui::accesskit::Role::TextInput, "Name")
        .type_text("first lap");
    harness.get_by_label("Save").click();
    harness.step();
    harness.get_by_label_contains("Saved the definition as \"first lap\"");
    let saved: vl_client::Task =
        serde_json::from_slice(&std::fs::read(tasks_dir.join("first lap.json")).unwrap()).unwrap();
    assert_eq!(saved.definition, defined);

    harness.get_by_label("Load \"first lap\"").click();
    let defines = harness.state().session().forecasts;
    step_until(&mut harness, "define the task again", |app| {
        app.session().forecasts > defines
    });
    harness.get_by_label_contains("Loaded \"first lap\"");
    harness
        .render()
        .unwrap()
        .save(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/target/tmp/guest-window-tasks.png"
        ))
        .unwrap();
    assert_eq!(
        harness.state().session().definition.as_ref(),
        Some(&defined)
    );
}

/// After a run, the window lists the runs the Host kept for it, downloads
/// one with its progress shown, plays it back in place of the live view,
/// and goes back to the lab.
#[test]
fn the_window_lists_downloads_and_replays_its_runs() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let dir = common::scratch("window-recordings");
    let config = recording_into(&dir.join("host"));
    let host = host_without_camera(&runtime, config);
    let _entered = runtime.enter();
    let downloads = dir.join("downloads");
    let app = GuestApp::new(&host.url(), Role::Operator, Login::default())
        .unwrap()
        .with_downloads(downloads.clone());
    let mut harness = harness_of(app, Vec2::new(1100.0, 720.0));
    mount_navigation(&mut harness, |s| s.lab.is_some() && s.robot.is_some());
    define_and_start(&mut harness);
    step_until(&mut harness, "end the run", |app| {
        app.session().done.is_some()
    });
    harness.get_by_label("Recordings").click();
    harness.step();
    harness.get_by_label("List my runs").click();
    step_until(&mut harness, "list the runs", |app| {
        app.session()
            .recordings
            .as_ref()
            .is_some_and(|r| !r.is_empty())
    });
    harness.get_by_label("Download run 1").click();
    // A file still being closed when asked for is asked for again.
    let deadline = Instant::now() + Duration::from_secs(20);
    while harness.query_by_label_contains("Downloaded ").is_none() {
        assert!(Instant::now() < deadline, "the run never downloaded");
        harness.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    let name = harness.state().session().recordings.as_ref().unwrap()[0]
        .name
        .clone();
    let file = downloads.join(name.as_str());
    assert_eq!(
        std::fs::read(&file).unwrap(),
        std::fs::read(dir.join("host").join(name.as_str())).unwrap()
    );
    harness.get_by_label(&format!("Replay {name}")).click();
    for _ in 0..5 {
        harness.step();
    }
    assert!(harness.state_mut().replay().is_some(), "no replay");
    harness
        .render()
        .unwrap()
        .save(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/target/tmp/guest-window-recordings.png"
        ))
        .unwrap();
    harness.get_by_label("Back to the lab").click();
    step_until(&mut harness, "be back at the lab", |app| {
        app.session().role == Some(Role::Operator)
    });
}

/// With frames sent only on change (README's host command), the camera's
/// image has no robot in it: the window draws the robot from the feedback
/// over it, before anything is mounted, from the lab's scene its welcome
/// told (the floor looked empty before).
#[test]
fn the_robot_is_drawn_before_anything_is_mounted() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let on_change = HostConfig {
        frames: vl_host::FramePolicy::OnChange {
            max_interval: Duration::from_secs(5),
        },
        ..HostConfig::default()
    };
    let host = host_with_camera(&runtime, on_change);
    let _entered = runtime.enter();
    let mut harness = window_as(&host.url(), Role::Observer, Vec2::new(1100.0, 720.0));
    step_until(
        &mut harness,
        "see the robot's feedback and a frame",
        |app| {
            let s = app.session();
            s.robot.is_some() && s.frame.is_some() && s.scene().is_some()
        },
    );
    assert!(harness.state().session().lab.is_none(), "nothing mounted");
    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-before-mount.png"
    ));
    let robot = vl_core::Mark::Robot.rgb();
    assert!(
        pixels_of(&image, robot) > 100,
        "the robot's outline is drawn: {} pixels",
        pixels_of(&image, robot)
    );
}

/// On the experiment a user's own controller drives, a module dropped on
/// the window is sent; the Host takes it, Define names it with the goal,
/// the twin tries it, and the run is the module's, to the goal.
#[test]
fn a_controller_dropped_on_the_window_drives_the_run() {
    let lab = SimLab::new(Arena::named("open").unwrap());
    with_window_in(lab, "Run your own controller", dropped_controller);
}

fn dropped_controller(harness: &mut Harness<'_, GuestApp>) {
    step_until(harness, "mount", |app| app.session().lab.is_some());
    let module = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples/controllers/go_to_goal.wat");
    harness
        .input_mut()
        .dropped_files
        .push(std::sync::Arc::new(Dropped(module)));
    step_until(harness, "the Host takes the controller", |app| {
        app.session().controller.is_some()
    });
    harness.step();
    // The module drives, not the stick; "sent" gives way to "taken".
    assert!(harness.query_by_label_contains("Drag the stick").is_none());
    harness.get_by_label_contains("Your controller drives this experiment's run");
    harness.get_by_label_contains("your controller: taken");
    assert!(
        harness
            .query_by_label_contains("the Host checks it")
            .is_none()
    );
    // At a small and a large window's size, for a look (the test's own
    // size last).
    let size = harness.ctx.content_rect().size();
    for (w, h) in [(800.0, 600.0), (1600.0, 1000.0), (size.x, size.y)] {
        harness.set_size(egui::Vec2::new(w, h));
        harness.step();
        let image = harness.render().expect("the window renders");
        let _ = image.save(format!(
            "{}/guest-window-controller-{w}.png",
            env!("CARGO_TARGET_TMPDIR")
        ));
        harness.get_by_label("Send");
    }
    define_and_start(harness);
    step_until(harness, "the run ends", |app| app.session().done.is_some());
    let done = harness.state().session().done.clone().unwrap();
    assert_eq!(done.reason, vl_core::EndReason::GoalReached, "{done:?}");
    assert_eq!(done.collisions, 0, "{done:?}");
}

/// The window's file picker: opened by Choose… in the folder typed, it
/// lists the modules (not the C source beside them), and the one chosen is
/// sent and taken.
#[test]
fn a_controller_chosen_in_the_file_picker_is_taken() {
    let lab = SimLab::new(Arena::named("open").unwrap());
    with_window_in(lab, "Run your own controller", chosen_controller);
}

fn chosen_controller(harness: &mut Harness<'_, GuestApp>) {
    step_until(harness, "mount", |app| app.session().lab.is_some());
    let folder = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/controllers");
    harness
        .get_by_role(egui::accesskit::Role::TextInput)
        .focus();
    harness.step();
    harness
        .get_by_role(egui::accesskit::Role::TextInput)
        .type_text(&folder.display().to_string());
    harness.step();
    harness.get_by_label("Choose…").click();
    for _ in 0..4 {
        harness.step();
    }
    harness.get_by_label_contains("go_to_goal.wat").click();
    harness.step();
    assert!(harness.query_by_label_contains("go_to_goal.c").is_none());
    let image = harness.render().expect("the window renders");
    let _ = image.save(concat!(
        env!("CARGO_TARGET_TMPDIR"),
        "/guest-window-controller-picker.png"
    ));
    harness.get_by_label("Open").click();
    step_until(harness, "the Host takes the chosen controller", |app| {
        app.session().controller.is_some()
    });
    harness.step();
    assert!(
        harness.query_by_label("Open").is_none(),
        "the picker closed"
    );
    harness.get_by_label_contains("your controller: taken");
}

/// A file dropped on the window, as the windowing system hands it over.
#[derive(Debug)]
struct Dropped(std::path::PathBuf);

impl egui::DroppedFile for Dropped {
    fn path(&self) -> &std::path::Path {
        &self.0
    }

    fn bytes(&self) -> Result<Vec<u8>, String> {
        std::fs::read(&self.0).map_err(|e| e.to_string())
    }
}
