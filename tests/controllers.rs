//! A user's own controller (issue 58), from outside: the shipped examples
//! through `vl controller` and `vl guest --headless --controller` on the
//! simulated lab and on the emulated Khepera; hostile modules through the
//! same command line and the Host's socket, each refused before the robot
//! moves or stopped, with its reason, and never a contact.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::{Value, json};

use crate::common::peer::Peer;
use crate::common::{
    self, headless_run, s, scratch, start_emulator, start_host, start_khepera_host_with, vl,
};

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples/controllers")
        .join(name)
}

/// The C example, built by Debian's clang and lld as its comment says;
/// none (said why) where they are missing.
fn built_c(dir: &Path) -> Option<PathBuf> {
    let out = dir.join("go_to_goal.wasm");
    let built = Command::new("clang")
        .args(["--target=wasm32", "-nostdlib", "-O2", "-Wl,--no-entry"])
        .args(["-Wl,--export-dynamic", "-o", s(&out)])
        .arg(example("go_to_goal.c"))
        .status();
    match built {
        Ok(status) if status.success() => Some(out),
        _ => {
            common::missing("clang and lld", "Debian's clang and lld");
            None
        }
    }
}

/// The Rust example, built as docs/controllers.md says with rustup's
/// `wasm32-unknown-unknown` target; none (said why) where it is missing.
fn built_rust(dir: &Path) -> Option<PathBuf> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let built = Command::new(cargo)
        .args([
            "build",
            "--release",
            "--quiet",
            "--target",
            "wasm32-unknown-unknown",
        ])
        .args(["--target-dir", s(dir)])
        .current_dir(example("rust"))
        .env_remove("RUSTFLAGS")
        .output()
        .expect("cargo runs");
    if !built.status.success() {
        let said = common::stderr(&built);
        assert!(
            said.contains("wasm32-unknown-unknown"),
            "the Rust example does not build: {said}"
        );
        common::missing(
            "rustup's wasm32-unknown-unknown target",
            "rustup target add wasm32-unknown-unknown",
        );
        return None;
    }
    Some(dir.join("wasm32-unknown-unknown/release/go_to_goal.wasm"))
}

/// A module in the text format whose `vl_step` runs `step` (leaving an
/// i32), its observation at 0 and its command at 256, written to `dir`.
fn module(dir: &Path, name: &str, step: &str) -> PathBuf {
    let text = format!(
        r#"(module
             (memory (export "memory") 1)
             (func (export "vl_abi") (result i32) (i32.const 1))
             (func (export "vl_observation") (result i32) (i32.const 0))
             (func (export "vl_command") (result i32) (i32.const 256))
             (func (export "vl_step") (result i32) {step}))"#
    );
    let file = dir.join(format!("{name}.wat"));
    std::fs::write(&file, text).unwrap();
    file
}

/// `vl controller forecast FILE ARGS… --json`: its exit code and report.
fn forecast(file: &Path, args: &[&str]) -> (Option<i32>, Value) {
    let out = vl(&[&["controller", "forecast", s(file), "--json"], args].concat());
    let report = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("no report ({e}): {}", common::stderr(&out)));
    (out.status.code(), report)
}

/// A headless operator's run of `file` on the lab at `url`: its exit code
/// and what it said on stderr.
fn refused_run(url: &str, file: &Path, goal: &str) -> (Option<i32>, String) {
    let extra = ["--experiment", "your-controller", "--goal", goal];
    let out = common::headless(url, 60, &[&extra[..], &["--controller", s(file)]].concat());
    (out.status.code(), common::stderr(&out))
}

#[test]
fn the_text_format_example_is_tried_on_the_twin_before_it_may_run() {
    let wat = example("go_to_goal.wat");
    let checked = vl(&["controller", "check", s(&wat)]);
    assert!(checked.status.success(), "{}", common::stderr(&checked));
    assert!(common::stdout(&checked).contains("version 1: checked, and it starts"));
    // In the open arena it drives straight there…
    let (code, open) = forecast(&wat, &["--arena", "open"]);
    assert_eq!(code, Some(0), "{open}");
    assert_eq!(open["forecast"]["runs"].as_array().unwrap().len(), 5);
    for run in open["forecast"]["runs"].as_array().unwrap() {
        assert_eq!(run["reached_goal"], true, "{run}");
        assert_eq!(run["collisions"], 0, "{run}");
    }
    // …and in the navigation arena, which it does not know how to go round,
    // the safety layer holds it off the wall: refused, and never a contact.
    let (code, blocked) = forecast(&wat, &[]);
    assert_eq!(code, Some(1), "{blocked}");
    assert_eq!(blocked["refusals"][0]["kind"], "no_goal", "{blocked}");
    let runs = blocked["forecast"]["runs"].as_array().unwrap();
    assert!(runs.iter().all(|r| r["collisions"] == 0), "{blocked}");
}

/// The Rust example builds as its docs say and, like the text format's (it
/// does not go round obstacles either), reaches the goal in the open.
#[test]
fn the_rust_example_builds_as_documented_and_reaches_the_goal() {
    let Some(wasm) = built_rust(&scratch("controller-rust")) else {
        return;
    };
    let (code, open) = forecast(&wasm, &["--arena", "open", "--seeds", "3"]);
    assert_eq!(code, Some(0), "{open}");
    for run in open["forecast"]["runs"].as_array().unwrap() {
        assert_eq!(run["reached_goal"], true, "{run}");
        assert_eq!(run["collisions"], 0, "{run}");
    }
}

#[test]
fn the_c_example_reaches_the_goal_on_the_simulated_lab_and_the_emulated_khepera() {
    let dir = scratch("controller-c");
    let Some(wasm) = built_c(&dir) else { return };
    let (code, foreseen) = forecast(&wasm, &[]);
    assert_eq!(code, Some(0), "{foreseen}");
    let run = |url: &str, download: &Path| {
        headless_run(
            url,
            90,
            &[
                "--experiment",
                "your-controller",
                "--controller",
                s(&wasm),
                "--download-to",
                s(download),
            ],
        )
    };
    let (_host, url) = start_host(&["--recordings", s(&dir.join("sim-runs"))]);
    let simulated = run(&url, &dir.join("sim-download"));
    assert_eq!(simulated["reached_goal"], true, "{simulated}");
    assert_eq!(simulated["collisions"], 0, "{simulated}");
    assert!(
        simulated["forecast"]["forecast_s"].as_f64().is_some(),
        "the run is compared with its forecast: {simulated}"
    );
    // Its recording keeps the module, so a replay or regrade runs exactly it.
    let file = simulated["downloaded"].as_str().expect("downloaded");
    let info = common::vl_json(&["record", "info", file, "--json"]);
    assert!(
        info["attachments"]
            .as_array()
            .unwrap()
            .contains(&json!("controller.wasm")),
        "{info}"
    );
    // A regrade grades the run by the experiment's rubric and runs that
    // module again on the twin, from where the run began.
    let regraded = common::vl_json(&["record", "regrade", file, "--seeds", "3", "--json"]);
    assert_eq!(regraded["experiment"], "your-controller", "{regraded}");
    assert!(
        regraded["recorded"]["given"].as_f64().unwrap() >= 70.0,
        "the goal without contact earns most: {regraded}"
    );
    let rerun = &regraded["rerun"];
    assert_eq!(rerun["sha256"], foreseen["module"]["sha256"], "{regraded}");
    assert_eq!(rerun["seeds"].as_array().unwrap().len(), 3, "{regraded}");
    assert_eq!(rerun["reproduces"], true, "{regraded}");
    for seed in rerun["seeds"].as_array().unwrap() {
        assert_eq!(seed["collisions"], 0, "{regraded}");
        let grade = seed["grade"]["given"].as_f64().unwrap();
        assert!(grade >= 70.0, "{regraded}");
    }
    // A file that is not a run is refused, naming it.
    let wrong = vl(&["record", "regrade", s(&wasm)]);
    assert_eq!(wrong.status.code(), Some(2), "{}", common::stderr(&wrong));
    assert!(
        common::stderr(&wrong).contains("go_to_goal.wasm"),
        "{}",
        common::stderr(&wrong)
    );

    let (_emulator, device) = start_emulator(&["--arena", "navigation"]);
    let (_khepera_host, url) = start_khepera_host_with(&device, &[]);
    let emulated = run(&url, &dir.join("khepera-download"));
    assert_eq!(emulated["reached_goal"], true, "{emulated}");
    assert_eq!(emulated["collisions"], 0, "{emulated}");
}

/// Hostile modules, each through the command line and the Host's socket:
/// refused before they run, refused by the twin, or stopped on the robot
/// with the reason in words; no contact, ever.
#[test]
fn hostile_controllers_are_refused_or_stopped_with_their_reason() {
    let dir = scratch("controller-hostile");
    let (_host, url) = start_host(&[]);
    let twin_refuses = [
        ("spin", "(loop $l (br $l)) (i32.const 0)", "ran out of fuel"),
        (
            "grow",
            "(loop $l (drop (memory.grow (i32.const 16))) (br $l)) (i32.const 0)",
            "grew its memory past its cap of 16 MiB",
        ),
        ("unreachable", "unreachable", "the controller trapped"),
        (
            "nan",
            "(f64.store (i32.const 256) (f64.const nan)) (i32.const 0)",
            "no finite numbers",
        ),
    ];
    for (name, step, why) in twin_refuses {
        let file = module(&dir, name, step);
        let (code, said) = refused_run(&url, &file, "680,470");
        assert_eq!(code, Some(1), "{name}: {said}");
        assert!(said.contains("tried on the lab's twin"), "{name}: {said}");
        assert!(said.contains(why), "{name}: {said}");
    }
    // Full speed ahead, at the wall: the twin's safety layer holds it, so
    // it never gets there, and it never touches.
    let wall = module(
        &dir,
        "wall",
        "(f64.store (i32.const 256) (f64.const 1000)) (f64.store (i32.const 264) (f64.const 1000)) (i32.const 0)",
    );
    let (code, rammed) = forecast(&wall, &["--time-limit", "10"]);
    assert_eq!(code, Some(1), "{rammed}");
    let runs = rammed["forecast"]["runs"].as_array().unwrap();
    assert!(runs.iter().all(|r| r["collisions"] == 0), "{rammed}");
    assert!(
        runs.iter().all(|r| r["held_back_s"].as_f64() > Some(1.0)),
        "{rammed}"
    );
    let (code, said) = refused_run(&url, &wall, "680,470");
    assert_eq!(code, Some(1), "{said}");
    assert!(said.contains("would not reach the goal"), "{said}");

    // Refused as they arrive: an import of anything but vl_log, a file
    // that is no WebAssembly.
    let system = dir.join("system.wat");
    let text = std::fs::read_to_string(module(&dir, "ok", "(i32.const 1)")).unwrap();
    std::fs::write(
        &system,
        text.replace(
            "(module",
            "(module (import \"env\" \"system\" (func (param i32) (result i32)))",
        ),
    )
    .unwrap();
    let (code, said) = refused_run(&url, &system, "680,470");
    assert_eq!(code, Some(1), "{said}");
    assert!(said.contains("imports env.system"), "{said}");
    let elf = dir.join("not.wasm");
    std::fs::write(&elf, b"\x7fELF\x02\x01\x01 not a module at all").unwrap();
    let (_, said) = refused_run(&url, &elf, "680,470");
    assert!(said.contains("not a WebAssembly module"), "{said}");
    // 20 MB: the Guest refuses it unread…
    let huge = dir.join("huge.wasm");
    std::fs::File::create(&huge)
        .unwrap()
        .set_len(20_000_000)
        .unwrap();
    common::refused(
        &[
            "guest",
            "--connect",
            &url,
            "--headless",
            "--experiment",
            "your-controller",
            "--controller",
            s(&huge),
        ],
        "20000000 bytes; a controller may have at most 2097152 (2 MiB)",
    );
}

/// What a Guest cannot make the Host do over its socket: take a module
/// larger than 2 MiB or in parts out of order, run a definition naming
/// another module, or drive a controller's run by stick. And a module that
/// behaves on the twin but traps on the robot is stopped there, saying so.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_socket_holds_a_controller_to_its_bounds() {
    let (_host, url) = start_host(&[]);
    let mut operator = Peer::connect(&url).await;
    operator
        .send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
        .await;
    operator.expect("welcome").await;
    operator
        .send(json!({"type": "mount", "experiment": "your-controller"}))
        .await;
    operator.expect("mounted").await;
    let part = |offset: u64, total: u64, bytes: &[u8]| {
        use base64::Engine as _;
        let data = base64::engine::general_purpose::STANDARD.encode(bytes);
        json!({"type": "controller", "offset": offset, "total": total, "data": data})
    };
    let refused = async |peer: &mut Peer, message: Value, why: &str| {
        peer.send(message).await;
        let error = peer.expect("error").await;
        assert!(error["message"].as_str().unwrap().contains(why), "{error}");
    };
    refused(&mut operator, part(0, 20_000_000, b"\0asm"), "not 20000000").await;
    refused(
        &mut operator,
        part(4, 8, b"\0asm"),
        "first part starts at byte 0",
    )
    .await;
    operator.send(part(0, 8, b"\0asm")).await;
    refused(&mut operator, part(6, 8, b"\x01\0"), "byte 4 of 8 was next").await;
    let no_such = json!({
        "type": "define", "goal": {"x_mm": 200.0, "y_mm": 300.0, "tolerance_mm": 15.0},
        "controller": "00".repeat(32),
    });
    refused(&mut operator, no_such, "not the one sent").await;

    // Go to the goal on the twin (its estimate is certain there), trap on
    // the robot (where it never is) a second into the run: long enough for
    // a stick's command to be refused while it runs.
    let text = std::fs::read_to_string(example("go_to_goal.wat"))
        .unwrap()
        .replace(
            "    (f64.store (i32.const 256) (f64.const 0))\n    (f64.store (i32.const 264) (f64.const 0))\n",
            "    (if (i32.and (f64.gt (f64.load (i32.const 32)) (f64.const 0)) (f64.gt (f64.load (i32.const 0)) (f64.const 1))) (then unreachable))\n    (f64.store (i32.const 256) (f64.const 0))\n    (f64.store (i32.const 264) (f64.const 0))\n",
        );
    assert!(text.contains("then unreachable"));
    operator
        .send(part(0, text.len() as u64, text.as_bytes()))
        .await;
    let taken = operator.expect("controller_taken").await;
    let sha256 = taken["sha256"].as_str().unwrap().to_owned();
    operator
        .send(json!({
            "type": "define", "goal": {"x_mm": 200.0, "y_mm": 300.0, "tolerance_mm": 15.0}, "controller": sha256,
        }))
        .await;
    let verdict = operator.expect("forecast").await;
    assert_eq!(verdict["refusals"], json!([]), "{verdict}");
    operator.send(json!({"type": "start"})).await;
    operator.expect("started").await;
    refused(
        &mut operator,
        json!({"type": "command", "event": 1, "v": 100.0, "w": 0.0}),
        "your controller drives",
    )
    .await;
    let done = operator.expect("done").await;
    let summary = &done["summary"];
    assert_eq!(summary["reason"], "fault", "{done}");
    assert!(
        summary["fault"]
            .as_str()
            .unwrap()
            .contains("the controller trapped"),
        "{done}"
    );
    assert_eq!(summary["collisions"], 0, "{done}");
}
