//! A class plays the lab as README's class section sets it up: accounts,
//! slots, one driver at a time. Ada drives over the protocol; Bob asks
//! from the desktop window and Carol from the page while she does; Ada's
//! slot ends and Bob drives what is mounted without mounting it again;
//! Carol is told her place and her wait; the audit log names each run's
//! driver and each refusal.

use std::time::{Duration, Instant};

use egui::Vec2;
use egui_kittest::kittest::Queryable;
use serde_json::{Value, json};
use vl_client::Login;
use vl_core::Role;
use vl_guest::GuestApp;
use vl_host::{AccountRole, Audit, HostConfig, Users};

use crate::common::chromium::{self, Browser};
use crate::common::peer::Peer;
use crate::common::scratch;
use crate::guest_window::{define_and_start, harness_of, host_without_camera, step_until};
use crate::web::{log_in, page};

/// The slot each of them gets.
const SLOT: Duration = Duration::from_secs(20);

#[test]
fn a_class_takes_turns_without_dead_ends() {
    if !chromium::available() {
        return;
    }
    let dir = scratch("class");
    let audit_file = dir.join("audit.jsonl");
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let _entered = runtime.enter();
    let mut users = Users::default();
    for (name, password) in [
        ("ada", "ada's secret"),
        ("bob", "bob's secret"),
        ("carol", "carol's secret"),
    ] {
        users.add(name, AccountRole::Operator, password).unwrap();
    }
    let host = host_without_camera(
        &runtime,
        HostConfig {
            users: Some(users),
            slot: Some(SLOT),
            audit: Audit::open(&audit_file).unwrap(),
            ..HostConfig::default()
        },
    );
    let url = host.url();

    // Ada drives: navigation mounted, a run under way.
    let mut ada = runtime.block_on(ada_drives(&url));

    // Bob asks from the window: it watches and takes the first place by itself.
    let login = Login {
        user: Some("bob".into()),
        password: Some("bob's secret".into()),
        token: None,
    };
    let app = GuestApp::new(&url, Role::Operator, login).unwrap();
    let mut bob = harness_of(app, Vec2::new(800.0, 600.0));
    step_until(&mut bob, "be first in line", |app| {
        app.session().queue.is_some_and(|q| q.position == 1)
    });
    bob.get_by_label_contains("You are 1st in line for control");
    shots(&mut bob, &dir, "in-line");

    // Carol asks from the page: second, told how long at most.
    let mut carol = Browser::open(&page(&url), (1600, 1000));
    carol.expect(
        "vl.link === 'refused' || vl.link === 'open'",
        Duration::from_secs(10),
    );
    log_in(&mut carol, "carol", "carol's secret", true);
    carol.expect(
        "vl.queue && vl.queue.position === 2",
        Duration::from_secs(10),
    );
    let line = carol.eval("document.getElementById('queue').innerText");
    assert!(
        line.as_str()
            .unwrap()
            .starts_with("you are number 2 of 2 in line, at most"),
        "{line}"
    );
    page_shots(&mut carol, &dir, "in-line");

    // Ada's slot ends: her run ends, she is told why, Bob drives.
    runtime.block_on(slot_ends(&mut ada));
    let deadline = Instant::now() + SLOT * 3;
    while bob.state().session().role != Some(Role::Operator) {
        assert!(Instant::now() < deadline, "bob never got control");
        bob.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    // What Ada mounted is Bob's at once: he defines and starts, no mount.
    step_until(&mut bob, "see navigation mounted", |app| {
        app.session()
            .lab
            .as_ref()
            .is_some_and(|l| l.experiment == *"navigation")
            && app.session().ready()
    });
    // The window names the next action.
    bob.get_by_label("Next: click the view for a goal, then Define.");
    shots(&mut bob, &dir, "after-hand-over");
    define_and_start(&mut bob);

    // Carol is first now, told her wait; the page says what is next.
    carol.expect(
        "vl.queue && vl.queue.position === 1",
        Duration::from_secs(10),
    );
    let line = carol.eval("document.getElementById('queue').innerText");
    assert!(
        line.as_str()
            .unwrap()
            .starts_with("you are number 1 of 1 in line, at most 1 min to wait"),
        "{line}"
    );
    page_shots(&mut carol, &dir, "after-hand-over");
    // She gives up her place: with no one waiting, Bob's slot runs on.
    carol.click("#line");
    carol.expect("vl.queue === null", Duration::from_secs(5));

    bob_stops(&mut bob, &dir);
    let mut ada_page = observer_joins(&url, &dir);
    for page in [&mut carol, &mut ada_page] {
        let errors = page.errors();
        assert!(
            errors.is_empty(),
            "the page's console had errors: {errors:#?}"
        );
    }

    // The audit log: each run's driver, each refusal.
    audit_names_drivers_and_refusals(&audit_file);
}

/// Ada logs in, mounts navigation and starts a run.
async fn ada_drives(url: &str) -> Peer {
    let mut ada = Peer::connect(url).await;
    ada.send(json!({"type": "hello", "protocol": 1, "role": "operator",
        "user": "ada", "password": "ada's secret"}))
        .await;
    ada.expect("welcome").await;
    ada.start("navigation").await;
    ada
}

/// Ada's slot ends: her run ends, and she is told she watches, and why.
async fn slot_ends(ada: &mut Peer) {
    let (mut done, mut watching) = (None, None);
    while done.is_none() || watching.is_none() {
        let v = ada
            .next_of_any(&["done", "role"], SLOT * 3)
            .await
            .expect("ada's slot ends");
        match v["type"].as_str() {
            Some("done") => done = Some(v),
            _ if v["role"] == "observer" => watching = Some(v),
            _ => {}
        }
    }
    let (done, watching) = (done.unwrap(), watching.unwrap());
    assert_eq!(done["summary"]["reason"], "slot_ended", "{done}");
    assert_eq!(watching["ended"], "slot_ended", "{watching}");
}

/// The audit log names each run's driver and each refusal (written by its
/// own task: read until it has them, a while at most).
fn audit_names_drivers_and_refusals(audit_file: &std::path::Path) {
    let entries = || -> Vec<Value> {
        std::fs::read_to_string(audit_file)
            .unwrap_or_default()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect()
    };
    let has = |entries: &[Value], event: &str, user: &str| {
        entries
            .iter()
            .any(|e| e["event"] == event && e["user"] == user)
    };
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let log = entries();
        let complete = has(&log, "run_started", "ada")
            && has(&log, "run_ended", "ada")
            && has(&log, "run_started", "bob")
            && has(&log, "refused", "bob")
            && has(&log, "refused", "carol")
            && has(&log, "slot_ended", "ada");
        if complete {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the audit log misses a driver or a refusal:\n{}",
            std::fs::read_to_string(audit_file).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let log = entries();
    let refusal = log
        .iter()
        .find(|e| e["event"] == "refused" && e["user"] == "carol")
        .unwrap();
    assert!(
        refusal["detail"]
            .as_str()
            .unwrap()
            .starts_with("operator_taken"),
        "{refusal}"
    );
}

/// The window at 800 and 1600 px wide, saved as `window-{size}-{what}.png`.
fn shots(window: &mut egui_kittest::Harness<'_, GuestApp>, dir: &std::path::Path, what: &str) {
    for (w, h) in [(800.0, 600.0), (1600.0, 1000.0)] {
        window.set_size(Vec2::new(w, h));
        window.step();
        window.step();
        let _ = window
            .render()
            .map(|i| i.save(dir.join(format!("window-{w}-{what}.png"))));
    }
}

/// The page at 800 and 1600 px wide, saved as `page-{size}-{what}.png`.
fn page_shots(page: &mut Browser, dir: &std::path::Path, what: &str) {
    for (w, h) in [(800, 900), (1600, 1000)] {
        page.resize(w, h);
        std::thread::sleep(Duration::from_millis(300));
        page.screenshot(&dir.join(format!("page-{w}-{what}.png")));
    }
}

/// Bob stops his run at once: the robot drives back, the twin passes what
/// is defined again, and nothing alarming is left on screen.
fn bob_stops(bob: &mut egui_kittest::Harness<'_, GuestApp>, dir: &std::path::Path) {
    bob.get_by_label("Stop").click();
    step_until(bob, "see the run end", |app| app.session().done.is_some());
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let s = bob.state().session();
        if s.ready() && s.forecast.as_ref().is_some_and(|f| f.passed()) {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the lab never got ready after Stop"
        );
        bob.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    let errors = &bob.state().session().errors;
    assert!(errors.is_empty(), "{errors:?}");
    shots(bob, dir, "after-stop");
}

/// Ada watches from a page opened now: the twin's verdict on what Bob has
/// defined, and how the lab was last used and by whom — not stale news.
fn observer_joins(url: &str, dir: &std::path::Path) -> Browser {
    let mut ada_page = Browser::open(&page(url), (1600, 1000));
    ada_page.expect(
        "vl.link === 'refused' || vl.link === 'open'",
        Duration::from_secs(10),
    );
    log_in(&mut ada_page, "ada", "ada's secret", false);
    ada_page.expect(
        "document.getElementById('forecast').innerText.startsWith(\"tried on the lab's twin\")",
        Duration::from_secs(10),
    );
    ada_page.expect(
        "document.getElementById('run').innerText.startsWith('last run: stopped by the operator (run ') && \
         document.getElementById('run').innerText.endsWith('navigation, driven by bob)')",
        Duration::from_secs(10),
    );
    page_shots(&mut ada_page, dir, "observer-joins");
    ada_page
}
