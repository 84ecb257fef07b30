//! The web Guest, served by the Host on its own port and used in headless
//! Chromium as a person would: watching a run (the robot's pixels move,
//! the console stays clean), driving a whole navigation run by clicking a
//! goal, Define and Start, and driving teleoperation from the keyboard
//! into a wall the safety layer holds the robot back from. Its messages
//! are the protocol's (checked against `docs/protocol.md` and the Host's
//! types), and the Host judges them as any Guest's.

use std::path::Path;
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use strum::VariantNames;
use vl_core::{CameraModel, GuestMessage, Point, Wire};

use crate::common::chromium::{self, Browser, http_get};
use crate::common::peer::Peer;
use crate::common::{s, scratch, start_host};
use tokio_tungstenite::tungstenite::Message;

const PAGE_JS: &str = include_str!("../crates/vl-host/web/protocol.js");

/// The page's address on the Host at `url` (`ws://host:port`).
pub(crate) fn page(url: &str) -> String {
    format!(
        "{}/",
        url.replacen("ws://", "http://", 1).trim_end_matches('/')
    )
}

fn port(url: &str) -> u16 {
    url.rsplit(':')
        .next()
        .unwrap()
        .trim_end_matches('/')
        .parse()
        .unwrap()
}

/// The page's CSS pixel over arena point `p` on its camera view.
fn on_screen(browser: &mut Browser, p: Point) -> (f64, f64) {
    let at = browser.eval(&format!(
        "(() => {{ const c = document.getElementById('camera'); const [x, y] = VL.toPixel(vl.lab.camera, {{x_mm: {}, y_mm: {}}}); const b = c.getBoundingClientRect(); return [b.left + x * b.width / c.width, b.top + y * b.height / c.height]; }})()",
        p.x_mm, p.y_mm
    ));
    (at[0].as_f64().unwrap(), at[1].as_f64().unwrap())
}

fn pose(browser: &mut Browser) -> Point {
    let p = browser.eval("vl.feedback.pose");
    Point {
        x_mm: p["x_mm"].as_f64().unwrap(),
        y_mm: p["y_mm"].as_f64().unwrap(),
    }
}

/// Pixels of `a` and `b` that differ clearly within `r` px of (x, y).
fn changed_near(a: &image::RgbaImage, b: &image::RgbaImage, (x, y): (f64, f64), r: f64) -> usize {
    let mut n = 0;
    for py in (y - r).max(0.0) as u32..((y + r) as u32).min(a.height()) {
        for px in (x - r).max(0.0) as u32..((x + r) as u32).min(a.width()) {
            let (p, q) = (a.get_pixel(px, py), b.get_pixel(px, py));
            let d: i32 = (0..3)
                .map(|i| (i32::from(p[i]) - i32::from(q[i])).abs())
                .sum();
            if d > 60 {
                n += 1;
            }
        }
    }
    n
}

/// Says hello as the operator from the page, with the lab's `token`.
fn drive_from(browser: &mut Browser, token: &str) {
    browser.expect(
        "vl.link === 'open' && vl.role === 'observer'",
        Duration::from_secs(10),
    );
    browser.click("#token");
    browser.type_text(token);
    browser.click("#ask");
    browser.expect("vl.role === 'operator'", Duration::from_secs(10));
}

/// A page on the Host at `url` driving with the token `lab-secret`, which
/// has mounted `experiment` by its button and waits until the lab's net
/// enables `next`.
fn operating(url: &str, experiment: &str, next: &str) -> Browser {
    let mut browser = Browser::open(&page(url), (1280, 900));
    drive_from(&mut browser, "lab-secret");
    browser.expect(
        "vl.state && vl.state.enabled.includes('mount')",
        Duration::from_secs(10),
    );
    browser.click(&format!("#mounts button[data-experiment={experiment}]"));
    browser.expect(
        &format!(
            "vl.lab && vl.lab.experiment === '{experiment}' && vl.state.enabled.includes('{next}')"
        ),
        Duration::from_secs(20),
    );
    browser
}

#[test]
fn the_page_shows_a_run_live_and_its_console_stays_clean() {
    if !chromium::available() {
        return;
    }
    let (_host, url) = start_host(&["--no-record"]);
    let mut browser = Browser::open(&page(&url), (1280, 900));
    browser.expect("vl.image && vl.frames > 3", Duration::from_secs(20));
    let run_url = url.clone();
    let run = std::thread::spawn(move || crate::common::headless_run(&run_url, 60, &[]));
    browser.expect(
        "vl.running && vl.lab && vl.feedback && vl.trail.length > 5",
        Duration::from_secs(20),
    );
    let dir = scratch("web-watch");
    let before = pose(&mut browser);
    let at_before = on_screen(&mut browser, before);
    let first = browser.screenshot(&dir.join("first.png"));
    // However fast this machine lets it go: until the page shows the robot
    // 20 mm on (a run that stalls fails here).
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut after = pose(&mut browser);
    while before.distance(after) <= 20.0 {
        assert!(
            Instant::now() < deadline,
            "the robot hardly moved in 20 s: {before:?} → {after:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
        after = pose(&mut browser);
    }
    let at_after = on_screen(&mut browser, after);
    let second = browser.screenshot(&dir.join("second.png"));
    let radius = 25.0;
    let (old, new) = (
        changed_near(&first, &second, at_before, radius),
        changed_near(&first, &second, at_after, radius),
    );
    assert!(
        old > 100 && new > 100,
        "the robot's pixels did not move on screen: {old} changed where it was, {new} where it went (screenshots in {})",
        s(&dir)
    );
    // The header tells the ages once it has timed a frame and a pose.
    browser.expect(
        "document.querySelector('header').innerText.includes('ms old')",
        Duration::from_secs(10),
    );
    let shown = browser.eval("document.querySelector('header').innerText");
    let shown = shown.as_str().unwrap();
    assert!(shown.contains("connected · watching"), "{shown}");
    assert!(
        shown.contains("round trip") && shown.contains("ms old"),
        "{shown}"
    );
    let run_words = browser.eval("document.getElementById('run').innerText");
    assert_eq!(run_words, "a run is under way");
    let errors = browser.errors();
    assert!(errors.is_empty(), "the console had errors: {errors:#?}");
    let report = run.join().unwrap();
    assert_eq!(report["reached_goal"], true, "{report}");
    // The run's end reaches the page in words.
    browser.expect(
        "document.getElementById('run').innerText.startsWith('last run: goal reached')",
        Duration::from_secs(10),
    );
}

#[test]
fn a_whole_navigation_run_is_driven_from_the_page() {
    if !chromium::available() {
        return;
    }
    let (_host, url) = start_host(&["--no-record", "--token", "lab-secret"]);
    let mut browser = operating(&url, "navigation", "define");
    let goal = browser.eval("vl.lab.arena.goal");
    let goal = Point {
        x_mm: goal["x_mm"].as_f64().unwrap(),
        y_mm: goal["y_mm"].as_f64().unwrap(),
    };
    let (x, y) = on_screen(&mut browser, goal);
    browser.click_at(x, y);
    browser.expect(
        "vl.planned && vl.planned.length > 10",
        Duration::from_secs(10),
    );
    // The click landed on the goal, within a pixel's worth of floor.
    let clicked = browser.eval("vl.goal");
    let clicked = Point {
        x_mm: clicked["x_mm"].as_f64().unwrap(),
        y_mm: clicked["y_mm"].as_f64().unwrap(),
    };
    assert!(clicked.distance(goal) < 5.0, "{clicked:?} for {goal:?}");
    browser.click("#define");
    browser.expect(
        "vl.definition && vl.forecast && vl.state.enabled.includes('start')",
        Duration::from_secs(30),
    );
    browser.click("#start");
    browser.expect("vl.running", Duration::from_secs(10));
    browser.expect("vl.summary", Duration::from_secs(60));
    let summary = browser.eval("vl.summary");
    assert_eq!(summary["reason"], "goal_reached", "{summary}");
    assert_eq!(summary["collisions"], 0, "{summary}");
    let words = browser.eval("document.getElementById('run').innerText");
    assert!(
        words
            .as_str()
            .unwrap()
            .starts_with("last run: goal reached"),
        "{words}"
    );
    let sent = browser.eval("vl.sent");
    for kind in ["hello", "mount", "plan", "define", "start"] {
        assert!(sent.as_array().unwrap().contains(&json!(kind)), "{sent}");
    }
    browser.screenshot(&scratch("web-navigation").join("done.png"));
    let errors = browser.errors();
    assert!(errors.is_empty(), "the console had errors: {errors:#?}");
}

/// The page builds its controls from what the experiment declares: on the
/// waypoint lab, clicks on the floor are numbered points to visit, the
/// Host plans through them, and the run visits each in order.
#[test]
fn a_waypoint_run_is_defined_by_clicks_from_the_page() {
    if !chromium::available() {
        return;
    }
    let (_host, url) = start_host(&["--no-record", "--token", "lab-secret"]);
    let mut browser = operating(&url, "tour", "define");
    browser.expect(
        "!document.getElementById('waypoints-hint').hidden && document.getElementById('goal-hint').hidden",
        Duration::from_secs(5),
    );
    let points = [(150.0, 320.0), (400.0, 330.0), (680.0, 470.0)];
    for (x_mm, y_mm) in points {
        let (x, y) = on_screen(&mut browser, Point { x_mm, y_mm });
        browser.click_at(x, y);
    }
    browser.expect(
        "vl.waypoints.length === 3 && vl.planned && vl.planned.length > 10",
        Duration::from_secs(10),
    );
    let count = browser.eval("document.getElementById('waypoints-count').innerText");
    assert!(
        count.as_str().unwrap().starts_with("3 of 2 to 8 points"),
        "{count}"
    );
    browser.screenshot(&scratch("web-waypoints").join("planned.png"));
    browser.click("#define");
    browser.expect(
        "vl.definition && vl.definition.waypoints.length === 3 && vl.forecast && vl.state.enabled.includes('start')",
        Duration::from_secs(30),
    );
    browser.click("#start");
    browser.expect("vl.running", Duration::from_secs(10));
    browser.expect("vl.summary", Duration::from_secs(60));
    let summary = browser.eval("vl.summary");
    assert_eq!(summary["reason"], "goal_reached", "{summary}");
    assert_eq!(
        summary["waypoints"],
        json!({"visited": 3, "of": 3}),
        "{summary}"
    );
    let errors = browser.errors();
    assert!(errors.is_empty(), "the console had errors: {errors:#?}");
}

/// On an experiment the user's own controller drives, the page takes the
/// module from a file picker, sends it in parts, and a click on the floor
/// is its goal; the twin tries it, and the run is the module's.
#[test]
fn a_controller_is_sent_from_the_page_and_drives_to_the_clicked_goal() {
    if !chromium::available() {
        return;
    }
    let (_host, url) = start_host(&["--no-record", "--token", "lab-secret"]);
    let mut browser = operating(&url, "your-controller", "define");
    browser.expect(
        "!document.getElementById('controller-hint').hidden && document.getElementById('goal-hint').hidden",
        Duration::from_secs(5),
    );
    // The file as a user picks it: the shipped example in the text format.
    let module = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/controllers/go_to_goal.wat"),
    )
    .unwrap();
    browser.eval(&format!(
        "const picked = new DataTransfer(); picked.items.add(new File([{}], 'go_to_goal.wat')); \
         const input = document.getElementById('controller-file'); input.files = picked.files; \
         input.dispatchEvent(new Event('change')); true",
        json!(module)
    ));
    browser.expect(
        "vl.controller && vl.controller.bytes > 1000",
        Duration::from_secs(10),
    );
    let (x, y) = on_screen(
        &mut browser,
        Point {
            x_mm: 200.0,
            y_mm: 300.0,
        },
    );
    browser.click_at(x, y);
    browser.expect(
        "vl.goal && !document.getElementById('define').disabled",
        Duration::from_secs(5),
    );
    let dir = scratch("web-controller");
    browser.screenshot(&dir.join("chosen.png"));
    browser.click("#define");
    browser.expect(
        "vl.definition && vl.definition.controller === vl.controller.sha256 && vl.forecast && vl.state.enabled.includes('start')",
        Duration::from_secs(30),
    );
    browser.click("#start");
    browser.expect("vl.running", Duration::from_secs(10));
    browser.expect(
        "document.getElementById('next').innerText === 'Your controller drives: Stop ends the run, STOP halts it at once.'",
        Duration::from_secs(2),
    );
    browser.expect("vl.summary", Duration::from_secs(60));
    let summary = browser.eval("vl.summary");
    assert_eq!(summary["reason"], "goal_reached", "{summary}");
    assert_eq!(summary["collisions"], 0, "{summary}");
    browser.screenshot(&dir.join("done.png"));
    let sent = browser.eval("vl.sent");
    assert!(
        sent.as_array().unwrap().contains(&json!("controller")),
        "{sent}"
    );
    let errors = browser.errors();
    assert!(errors.is_empty(), "the console had errors: {errors:#?}");
}

#[test]
fn teleoperation_from_the_keyboard_is_held_back_by_the_safety_layer() {
    if !chromium::available() {
        return;
    }
    let (_host, url) = start_host(&["--no-record", "--token", "lab-secret"]);
    let mut browser = operating(&url, "teleoperation", "start");
    browser.click("#start");
    browser.expect("vl.running", Duration::from_secs(10));
    // A gamepad's stick pushed forward drives the robot as the keys do
    // (the page reads the browser's Gamepad API each frame).
    let from = pose(&mut browser);
    browser.eval(
        "navigator.getGamepads = () => [{id: 'a test pad', axes: [0, -1], buttons: []}]; true",
    );
    browser.expect("vl.stick.v === 1", Duration::from_secs(5));
    std::thread::sleep(Duration::from_millis(500));
    browser.eval("navigator.getGamepads = () => []; true");
    browser.expect("vl.stick.v === 0", Duration::from_secs(5));
    let to = pose(&mut browser);
    assert!(
        to.x_mm - from.x_mm > 20.0,
        "the pad drove {from:?} → {to:?}"
    );
    // Watch every feedback the page gets from here on.
    browser.eval(
        "window.seen = {limited: 0, contact: 0, force: 0, n: 0}; const take0 = takeFeedback; takeFeedback = (m) => { seen.n++; if (m.limited) seen.limited++; if (m.contact) seen.contact++; if (m.force && Math.hypot(m.force[0], m.force[1]) > 0.1) seen.force++; take0(m); }; true",
    );
    // A pad at rest (the keys drive) that records the rumble it is asked for.
    browser.eval(
        "window.rumbles = []; const pad = {id: 'a rumble pad', axes: [0, 0], buttons: [], vibrationActuator: {playEffect: (kind, effect) => { rumbles.push(effect.strongMagnitude); return Promise.resolve('complete'); }}}; navigator.getGamepads = () => [pad]; true",
    );
    // Straight ahead from the start is an obstacle: hold the up arrow.
    browser.key("ArrowUp", 38, true);
    browser.expect("seen.limited > 10", Duration::from_secs(20));
    browser.expect(
        "rumbles.length > 0 && Math.max(...rumbles) > 0.1",
        Duration::from_secs(5),
    );
    // The page says so while it lasts (the field may then turn the robot
    // along the obstacle, out of the hold).
    browser.expect(
        "document.getElementById('held').innerText === 'held back by the safety layer'",
        Duration::from_secs(2),
    );
    browser.screenshot(&scratch("web-teleoperation").join("held.png"));
    std::thread::sleep(Duration::from_secs(2));
    browser.key("ArrowUp", 38, false);
    let seen = browser.eval("seen");
    assert_eq!(seen["contact"], 0, "the robot touched something: {seen}");
    assert!(
        seen["force"].as_u64().unwrap() > 0,
        "no force was fed back: {seen}"
    );
    browser.click("#stop");
    browser.expect("vl.summary", Duration::from_secs(10));
    let summary = browser.eval("vl.summary");
    assert_eq!(summary["reason"], "stopped", "{summary}");
    assert_eq!(summary["collisions"], 0, "{summary}");
    // It drove, and its body kept clear of everything the whole run.
    assert!(summary["distance_mm"].as_f64().unwrap() > 50.0, "{summary}");
    assert!(summary["closest_mm"].as_f64().unwrap() > 0.0, "{summary}");
    let errors = browser.errors();
    assert!(errors.is_empty(), "the console had errors: {errors:#?}");
}

/// Every `type` the page's protocol.js can send.
fn page_kinds() -> Vec<String> {
    let guest = PAGE_JS
        .split("const guest = {")
        .nth(1)
        .and_then(|rest| rest.split("\n  };").next())
        .expect("protocol.js builds its messages in `guest`");
    guest
        .split("type: \"")
        .skip(1)
        .map(|rest| rest.split('"').next().unwrap().to_owned())
        .collect()
}

#[test]
fn the_page_is_served_over_https_and_speaks_wss_where_tls_is_on() {
    if !chromium::available() {
        return;
    }
    let (_host, url) = start_host(&["--no-record", "--tls-self-signed"]);
    // wss://127.0.0.1:PORT/#pin=… → https://127.0.0.1:PORT/
    let address = url.trim_start_matches("wss://").split('/').next().unwrap();
    let mut browser = Browser::open_with(
        &format!("https://{address}/"),
        (1024, 768),
        // The Host's certificate is its own, as a self-signed one is.
        &["--ignore-certificate-errors"],
    );
    browser.expect(
        "vl.link === 'open' && vl.socket.url.startsWith('wss://') && vl.frames > 2",
        Duration::from_secs(15),
    );
    let errors = browser.errors();
    assert!(errors.is_empty(), "the console had errors: {errors:#?}");
}

#[test]
fn the_page_sends_only_documented_messages_of_the_protocol() {
    let kinds = page_kinds();
    assert!(kinds.len() >= 10, "{kinds:?}");
    let docs = include_str!("../docs/protocol.md");
    for kind in &kinds {
        assert!(
            GuestMessage::VARIANTS.contains(&kind.as_str()),
            "the page sends `{kind}`, which no Guest message is"
        );
        assert!(
            docs.contains(&format!("{{\"type\": \"{kind}\"")),
            "the page sends `{kind}`, which docs/protocol.md shows no example of"
        );
    }
}

#[test]
fn the_pages_messages_and_geometry_are_the_hosts() {
    if !chromium::available() {
        return;
    }
    let (_host, url) = start_host(&["--no-record"]);
    let mut browser = Browser::open(&page(&url), (1024, 768));
    browser.expect("vl.link === 'open'", Duration::from_secs(10));
    // Every message the page builds decodes as the Host decodes it.
    let examples = browser.eval("VL.examples()");
    let examples = examples.as_array().unwrap();
    let mut kinds: Vec<&str> = Vec::new();
    for example in examples {
        let decoded = GuestMessage::decode(&example.to_string())
            .unwrap_or_else(|e| panic!("the page's {example} is no Guest message: {e}"));
        kinds.push(decoded.kind());
    }
    let mut built = page_kinds();
    built.sort();
    kinds.sort();
    kinds.dedup();
    assert_eq!(
        kinds, built,
        "VL.examples() has each message the page builds"
    );
    // The page's camera geometry is vl-core's, lens and all.
    let mut camera: Value =
        serde_json::to_value(CameraModel::overhead(800.0, 600.0, 640, 15.0)).unwrap();
    camera["distortion"] = json!({"k1": -0.18, "k2": 0.08});
    let model: CameraModel = serde_json::from_value(camera.clone()).unwrap();
    for (x, y) in [(10.0, 10.0), (400.0, 300.0), (790.0, 20.0), (123.0, 555.0)] {
        let p = Point { x_mm: x, y_mm: y };
        let (c, r) = model.to_pixel(p);
        let js = browser.eval(&format!("VL.toPixel({camera}, {{x_mm: {x}, y_mm: {y}}})"));
        let (jc, jr) = (js[0].as_f64().unwrap(), js[1].as_f64().unwrap());
        assert!(
            (jc - c).abs() < 1e-6 && (jr - r).abs() < 1e-6,
            "({jc}, {jr}) ≠ ({c}, {r})"
        );
        let back = browser.eval(&format!("VL.toArena({camera}, {c}, {r})"));
        let expected = model.to_arena(c, r);
        assert!(
            (back["x_mm"].as_f64().unwrap() - expected.x_mm).abs() < 1e-6,
            "{back}"
        );
        assert!(
            (back["y_mm"].as_f64().unwrap() - expected.y_mm).abs() < 1e-6,
            "{back}"
        );
    }
    // What the page sends out of turn is refused, on the page, in words.
    browser.eval("vl.socket.send(JSON.stringify(VL.guest.start())); true");
    browser.expect(
        "vl.error && vl.error.code === 'not_operator'",
        Duration::from_secs(5),
    );
    let shown = browser.eval("document.getElementById('error').innerText");
    assert!(
        shown
            .as_str()
            .unwrap()
            .contains("only the operator may start"),
        "{shown}"
    );
}

/// The error `peer` is told next, or that its connection closed.
async fn answer_or_close(peer: &mut Peer) -> String {
    tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            match peer.ws.next().await {
                Some(Ok(Message::Text(t))) => {
                    let v: Value = serde_json::from_str(&t).unwrap();
                    if v["type"] == "error" {
                        return format!("error {}", v["code"]);
                    }
                }
                Some(Ok(Message::Close(_)) | Err(_)) | None => return "closed".to_owned(),
                Some(Ok(_)) => {}
            }
        }
    })
    .await
    .expect("answered or closed within 10 s")
}

#[tokio::test]
async fn the_pages_messages_out_of_order_or_oversized_are_refused() {
    let (_host, url) = start_host(&["--no-record", "--token", "lab-secret"]);
    let guest = |kind: &str| -> Value {
        // The page's own shapes (protocol.js), filled in as it fills them.
        match kind {
            "plan" => json!({"type": "plan", "goal": {"x_mm": 680.0, "y_mm": 470.0}}),
            "define" => {
                json!({"type": "define", "goal": {"x_mm": 680.0, "y_mm": 470.0, "tolerance_mm": 15.0},
                               "path": [{"x_mm": 100.0, "y_mm": 120.0}, {"x_mm": 680.0, "y_mm": 470.0}]})
            }
            "command" => json!({"type": "command", "event": 1, "seen": 0, "v": 200.0, "w": 0.0}),
            other => json!({"type": other}),
        }
    };
    let mut peer = Peer::connect(&url).await;
    // Before hello: nothing but hello.
    peer.send(guest("start")).await;
    let e = peer.next_of("error", Duration::from_secs(5)).await.unwrap();
    assert_eq!(e["code"], "hello_first", "{e}");
    peer.send(json!({"type": "hello", "protocol": 1, "role": "operator", "token": "lab-secret"}))
        .await;
    peer.next_of("welcome", Duration::from_secs(5))
        .await
        .unwrap();
    // Out of order: nothing mounted, nothing defined.
    for (kind, code) in [
        ("plan", "not_allowed_now"),
        ("define", "not_allowed_now"),
        ("start", "not_allowed_now"),
        ("command", "not_allowed_now"),
    ] {
        peer.send(guest(kind)).await;
        let e = peer.next_of("error", Duration::from_secs(5)).await.unwrap();
        assert_eq!(e["code"], code, "{kind}: {e}");
    }
    peer.send(json!({"type": "mount", "experiment": "navigation"}))
        .await;
    peer.next_of("mounted", Duration::from_secs(10))
        .await
        .unwrap();
    // A plan to nowhere, and plans faster than the Host plans.
    peer.send(json!({"type": "plan", "goal": {"x_mm": 1e9, "y_mm": 470.0}}))
        .await;
    let e = peer.next_of("error", Duration::from_secs(5)).await.unwrap();
    assert_eq!(e["code"], "invalid_definition", "{e}");
    assert!(
        e["message"].as_str().unwrap().contains("outside the arena"),
        "{e}"
    );
    tokio::time::sleep(Duration::from_millis(300)).await;
    peer.send(guest("plan")).await;
    peer.send(guest("plan")).await;
    let planned = peer
        .next_of_any(&["planned", "error"], Duration::from_secs(5))
        .await
        .unwrap();
    assert_eq!(planned["type"], "planned", "{planned}");
    let e = peer
        .next_of_any(&["planned", "error"], Duration::from_secs(5))
        .await
        .unwrap();
    assert_eq!(e["code"], "not_allowed_now", "{e}");
    // An observer may not plan.
    let mut watcher = Peer::connect(&url).await;
    watcher
        .send(json!({"type": "hello", "protocol": 1, "role": "observer"}))
        .await;
    watcher
        .next_of("welcome", Duration::from_secs(5))
        .await
        .unwrap();
    watcher.send(guest("plan")).await;
    let e = watcher
        .next_of("error", Duration::from_secs(5))
        .await
        .unwrap();
    assert_eq!(e["code"], "not_operator", "{e}");
    // A define the size of a flood: refused, and the connection closed.
    let points: Vec<Value> = (0..60_000)
        .map(|i| json!({"x_mm": 100.0 + f64::from(i % 500), "y_mm": 120.0}))
        .collect();
    let mut huge = guest("define");
    huge["path"] = Value::Array(points);
    assert!(huge.to_string().len() > 1 << 20);
    // The Host may close before the whole of it is sent: the error can
    // then be lost with the connection.
    let _ = peer.ws.send(Message::text(huge.to_string())).await;
    let outcome = answer_or_close(&mut peer).await;
    assert!(
        outcome == "error \"too_large\"" || outcome == "closed",
        "{outcome}"
    );
    // It defined nothing: the watcher heard of no definition.
    assert!(
        watcher
            .next_of("defined", Duration::from_millis(500))
            .await
            .is_none(),
        "an oversized define was taken"
    );
    // The page is still served to the next person.
    let body = tokio::task::spawn_blocking(move || http_get(port(&url), "/"))
        .await
        .unwrap();
    assert!(body.contains("<canvas id=\"camera\""), "{body}");
}

#[test]
fn the_watchers_bench_runs_a_class_against_no_one() {
    // A short class: the bench itself (`vl host bench-watchers`) is the
    // measurement; here it must run and every watcher be fed.
    let cost = crate::common::vl_json(&[
        "host",
        "bench-watchers",
        "--watchers",
        "5",
        "--commands",
        "50",
        "--rounds",
        "1",
        "--json",
    ]);
    assert_eq!(cost["watchers"], 5, "{cost}");
    for field in [
        "idle_p99_ms",
        "watched_p99_ms",
        "host_cores_idle",
        "host_cores_watched",
    ] {
        let value = cost[field].as_f64().unwrap_or(f64::NAN);
        assert!(value.is_finite() && value > 0.0, "{field}: {cost}");
    }
    assert!(
        cost["frames_hz_min"].as_f64().unwrap() > 0.0,
        "a watcher got no frame: {cost}"
    );
    assert!(cost["feedback_hz_min"].as_f64().unwrap() > 0.0, "{cost}");
}

/// Logs in on the page with an account, to drive or (`drive` false) watch.
pub(crate) fn log_in(browser: &mut Browser, user: &str, password: &str, drive: bool) {
    browser.click("#user");
    browser.type_text(user);
    browser.click("#password");
    browser.type_text(password);
    browser.click(if drive { "#ask" } else { "#look" });
}

#[test]
fn at_a_lab_with_accounts_the_page_logs_in_and_waits_in_line() {
    if !chromium::available() {
        return;
    }
    let dir = scratch("web-accounts");
    let users = dir.join("users.toml");
    crate::common::account(&users, "ada", "operator", "correct horse");
    crate::common::account(&users, "bob", "operator", "battery staple");
    let (_host, url) = start_host(&[
        "--no-record",
        "--users",
        s(&users),
        "--observers",
        "accounts",
        "--slot",
        "10m",
    ]);
    let mut ada = Browser::open(&page(&url), (1280, 900));
    // Anyone may not even watch here: the page says so and waits.
    ada.expect("vl.link === 'refused'", Duration::from_secs(10));
    let header = ada.eval("document.getElementById('link').innerText");
    assert_eq!(header, "not let in: log in below");
    log_in(&mut ada, "ada", "correct horse", true);
    ada.expect(
        "vl.role === 'operator' && vl.user === 'ada'",
        Duration::from_secs(10),
    );
    let header = ada.eval("document.getElementById('link').innerText");
    assert_eq!(header, "connected as ada · driving");
    ada.expect(
        "document.getElementById('slot').innerText.startsWith('your turn ends in 9:')",
        Duration::from_secs(5),
    );
    // Bob asks too: ada drives, so bob watches and takes his place in line.
    let mut bob = Browser::open(&page(&url), (1280, 900));
    bob.expect("vl.link === 'refused'", Duration::from_secs(10));
    log_in(&mut bob, "bob", "battery staple", true);
    bob.expect(
        "vl.role === 'observer' && vl.queue && vl.queue.position === 1",
        Duration::from_secs(10),
    );
    let line = bob.eval("document.getElementById('queue').innerText");
    assert!(
        line.as_str()
            .unwrap()
            .starts_with("you are number 1 of 1 in line, at most 10 min to wait"),
        "{line}"
    );
    // Ada is told someone waits after her.
    ada.expect(
        "document.getElementById('queue').innerText === '1 waiting for control after you'",
        Duration::from_secs(5),
    );
    // Ada lets go: bob drives.
    ada.click("#watch");
    bob.expect("vl.role === 'operator'", Duration::from_secs(10));
    ada.expect(
        "vl.role === 'observer' && vl.user === 'ada'",
        Duration::from_secs(10),
    );
    bob.screenshot(&dir.join("bob-drives.png"));
    for browser in [&mut ada, &mut bob] {
        let errors = browser.errors();
        assert!(errors.is_empty(), "the console had errors: {errors:#?}");
    }
}
