//! Simulate first (issue 29), over the socket: every navigation definition
//! is tried on the lab's twin before the robot moves. A definition through
//! a virtual obstacle's corner, one whose goal lies in an obstacle's
//! margin and one too long for the lab are each refused with the reason
//! in words, and Start stays refused; a safe one is told its forecast,
//! runs, and its summary says how far the run was from the forecast.

use crate::common;

use std::time::Duration;

use common::peer::Peer;
use common::start_host;
use serde_json::{Value, json};
use vl_core::{Arena, Point, RobotModel, Shape, plan_route};

/// An operator with the navigation experiment mounted; the map the Host
/// sent with it.
async fn mounted(url: &str) -> (Peer, Arena, RobotModel) {
    let mut op = Peer::connect(url).await;
    op.hello("operator").await;
    op.send(json!({"type": "mount", "experiment": "navigation"}))
        .await;
    let lab = op.expect("mounted").await;
    let arena: Arena = serde_json::from_value(lab["arena"].clone()).unwrap();
    let robot: RobotModel = serde_json::from_value(lab["robot"].clone()).unwrap();
    (op, arena, robot)
}

/// A path planned on the Host's map from its start to `goal`.
fn planned(arena: &Arena, robot: &RobotModel, goal: Point) -> Vec<Point> {
    plan_route(arena, &[], robot, arena.start, goal)
        .expect("a path to the goal")
        .points()
}

/// Defines `definition` and returns the Host's forecast of it.
async fn forecast_of(op: &mut Peer, definition: Value) -> Value {
    let mut message = definition;
    message["type"] = json!("define");
    op.send(message).await;
    op.expect("defined").await;
    op.next_of("forecast", Duration::from_secs(30))
        .await
        .expect("a forecast of the definition")
}

/// Defines the path planned to the arena's goal; its goal and forecast,
/// which passed.
async fn to_the_arenas_goal(op: &mut Peer, arena: &Arena, robot: &RobotModel) -> (Point, Value) {
    let goal = arena.goal.unwrap();
    let path = planned(arena, robot, goal);
    let definition =
        json!({"goal": {"x_mm": goal.x_mm, "y_mm": goal.y_mm, "tolerance_mm": 15}, "path": path});
    let forecast = forecast_of(op, definition).await;
    assert_eq!(forecast["refusals"], json!([]), "{forecast}");
    (goal, forecast)
}

/// The refusals' words, one per line.
fn reasons(forecast: &Value) -> Vec<String> {
    forecast["refusals"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            assert!(r["kind"].is_string(), "{r}");
            r.to_string()
        })
        .collect()
}

/// The operator is told the refusal in words, naming `what`; Start is
/// refused by the lab's net, which names the forecast not passed.
async fn refused_in_words(op: &mut Peer, what: &str) {
    let e = op.expect_error("forecast_refused").await;
    let words = e["message"].as_str().unwrap();
    println!("{words}");
    assert!(words.contains(what), "{words}");
    op.send(json!({"type": "start"})).await;
    let e = op.expect_error("not_allowed_now").await;
    let message = e["message"].as_str().unwrap();
    assert!(message.contains("forecast.unpassed"), "{message}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_safe_definition_is_forecast_runs_and_is_compared_with_its_forecast() {
    let (_host, url) = start_host(&[]);
    let (mut op, arena, robot) = mounted(&url).await;
    let (_, forecast) = to_the_arenas_goal(&mut op, &arena, &robot).await;
    let runs = forecast["forecast"]["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 5, "five seeds by default");
    assert!(runs.iter().all(|r| r["reached_goal"] == true), "{forecast}");
    assert!(
        runs.iter()
            .all(|r| r["path"].as_array().unwrap().len() > 10)
    );
    let foreseen: f64 = runs
        .iter()
        .map(|r| r["seconds"].as_f64().unwrap())
        .sum::<f64>()
        / 5.0;

    op.start_run().await;
    let done = op
        .next_of("done", Duration::from_secs(60))
        .await
        .expect("the run ends");
    let summary = &done["summary"];
    assert_eq!(summary["reached_goal"], true, "{summary}");
    let gap = &summary["forecast"];
    println!("run against its forecast: {gap}");
    let run_s = gap["run_s"].as_f64().unwrap();
    assert!((gap["forecast_s"].as_f64().unwrap() - foreseen).abs() < 1e-9);
    assert!(
        (run_s - foreseen).abs() / foreseen < 0.15,
        "the run took {run_s:.2} s, the forecast {foreseen:.2} s"
    );
    let mean = gap["path_mean_mm"].as_f64().unwrap();
    assert!(
        mean < 5.0,
        "the run's path is {mean} mm from the forecast's"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_path_through_a_virtual_obstacles_corner_is_refused_there() {
    let (_host, url) = start_host(&[]);
    let (mut op, arena, robot) = mounted(&url).await;
    let goal = arena.goal.unwrap();
    let path = planned(&arena, &robot, goal);
    // A box whose corner sits on the middle of the path.
    let corner = path[path.len() / 2];
    let sheet = Shape::Rect {
        x_mm: corner.x_mm,
        y_mm: corner.y_mm,
        width_mm: 60.0,
        height_mm: 60.0,
    };
    let definition = json!({
        "goal": {"x_mm": goal.x_mm, "y_mm": goal.y_mm, "tolerance_mm": 15},
        "path": path,
        "virtual_obstacles": [sheet],
    });
    let forecast = forecast_of(&mut op, definition).await;
    let reasons = reasons(&forecast);
    println!("{reasons:#?}");
    let refusal = &forecast["refusals"][0];
    assert_eq!(refusal["kind"], "no_goal", "{forecast}");
    assert_eq!(refusal["stops"]["to"], json!({"virtual_obstacle": 0}));
    refused_in_words(&mut op, "would not reach the goal").await;
    let stops: Point = serde_json::from_value(refusal["stops"]["at"].clone()).unwrap();
    assert!(
        stops.distance(corner) < robot.radius_mm + 30.0,
        "held back at {stops:?}, the corner at {corner:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_goal_in_an_obstacles_margin_is_refused_for_the_lab_s_clearance() {
    let (_host, url) = start_host(&["--min-clearance", "10"]);
    let (mut op, arena, robot) = mounted(&url).await;
    // A free goal 4 mm from an obstacle (no nearer to a wall), that the
    // C-space check lets through.
    let r = robot.radius_mm;
    let goal = (0..arena.width_mm as i32 / 2)
        .flat_map(|i| (0..arena.height_mm as i32 / 2).map(move |j| (i, j)))
        .map(|(i, j)| Point {
            x_mm: f64::from(i) * 2.0,
            y_mm: f64::from(j) * 2.0,
        })
        .find(|&p| {
            let to_obstacle = arena
                .obstacles
                .iter()
                .map(|o| o.shape.signed_distance(p))
                .fold(f64::INFINITY, f64::min);
            (to_obstacle - r - 4.0).abs() < 0.5
                && arena.wall_clearance(p) > r + 50.0
                && plan_route(&arena, &[], &robot, arena.start, p).is_ok()
        })
        .expect("a goal by an obstacle");
    let path = planned(&arena, &robot, goal);
    let definition =
        json!({"goal": {"x_mm": goal.x_mm, "y_mm": goal.y_mm, "tolerance_mm": 2}, "path": path});
    let forecast = forecast_of(&mut op, definition).await;
    let reasons = reasons(&forecast);
    println!("{reasons:#?}");
    assert!(!reasons.is_empty(), "{forecast}");
    let words = forecast["refusals"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.to_string())
        .collect::<String>();
    assert!(words.contains("\"obstacle\""), "{words}");
    refused_in_words(&mut op, "from an obstacle").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_definition_too_long_for_the_lab_is_refused_and_a_new_one_may_start() {
    let (_host, url) = start_host(&["--max-run", "2s"]);
    let (mut op, arena, robot) = mounted(&url).await;
    let goal = arena.goal.unwrap();
    let path = planned(&arena, &robot, goal);
    let far =
        json!({"goal": {"x_mm": goal.x_mm, "y_mm": goal.y_mm, "tolerance_mm": 15}, "path": path});
    let forecast = forecast_of(&mut op, far).await;
    let refusal = &forecast["refusals"][0];
    assert_eq!(refusal["kind"], "too_long", "{forecast}");
    assert_eq!(refusal["limit_s"], 2.0);
    assert!(refusal["seconds"].as_f64().unwrap() > 2.0);
    refused_in_words(&mut op, "this lab allows 2 s").await;

    // A short hop passes, and the run starts.
    let start = arena.start.point();
    let near = Point {
        x_mm: start.x_mm + 40.0 * arena.start.theta_rad.cos(),
        y_mm: start.y_mm + 40.0 * arena.start.theta_rad.sin(),
    };
    let hop = json!({"goal": {"x_mm": near.x_mm, "y_mm": near.y_mm, "tolerance_mm": 15}, "path": [start, near]});
    let forecast = forecast_of(&mut op, hop).await;
    assert_eq!(forecast["refusals"], json!([]), "{forecast}");
    op.start_run().await;
}

/// The twin is honest on the simulated lab: on every shipped arena, three
/// seeds each, the run's time is within 15 % of its forecast's and its
/// path within 5 mm (mean) of the forecast's.
#[test]
fn on_every_shipped_arena_runs_keep_to_their_forecasts() {
    let report = common::vl_json(&[
        "experiment",
        "run",
        "navigation",
        "--arena",
        "all",
        "--runs",
        "3",
        "--json",
    ]);
    let runs = report["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 12);
    for run in runs {
        let gap = &run["forecast"];
        let (arena, seed) = (&run["arena"], &run["seed"]);
        let (run_s, forecast_s) = (
            gap["run_s"].as_f64().unwrap(),
            gap["forecast_s"].as_f64().unwrap(),
        );
        println!("{arena} seed {seed}: {gap}");
        assert!(
            (run_s - forecast_s).abs() / forecast_s <= 0.15,
            "{arena} seed {seed}: {run_s:.2} s run, {forecast_s:.2} s foreseen"
        );
        let apart = gap["path_mean_mm"].as_f64().unwrap();
        assert!(
            apart <= 5.0,
            "{arena} seed {seed}: paths {apart:.1} mm apart"
        );
    }
}

/// The lab's forecast limits come from flags or its lab file; numbers out
/// of range are refused with the flag named, before anything starts.
#[test]
fn forecast_limits_out_of_range_are_refused_by_name() {
    for (args, said) in [
        (
            &["host", "--min-clearance", "-3"][..],
            "invalid value '-3' for '--min-clearance <MM>': \"-3\" is not a clearance from 0 to 1000 mm",
        ),
        (
            &["host", "--min-clearance", "inf"],
            "is not a clearance from 0 to 1000 mm",
        ),
        (
            &["host", "--forecast-seeds", "0"],
            "invalid value '0' for '--forecast-seeds <FORECAST_SEEDS>': 0 is not in 1..=8",
        ),
        (&["host", "--max-run", "2 days"], "--max-run"),
    ] {
        let out = common::vl(args);
        assert!(!out.status.success(), "{args:?}");
        let err = common::stderr(&out);
        assert!(err.contains(said), "{args:?}: {err}");
    }
    let dir = common::scratch("forecast-lab-file");
    let file = dir.join("lab.toml");
    std::fs::write(&file, "min-clearance = 1e9\n").unwrap();
    let out = common::vl(&["host", "--config", common::s(&file)]);
    assert!(!out.status.success());
    assert!(
        common::stderr(&out).contains("--min-clearance"),
        "{}",
        common::stderr(&out)
    );
}

/// A path planned from where an emergency stop left the robot, then a run
/// of it stopped half way: the robot drives back to its start, the path is
/// planned again from there to the same goal (the old one would begin
/// where the robot no longer is), and the twin passes it: no alarming
/// refusal of what the operator has not changed.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_run_stopped_half_way_keeps_a_definition_that_passes() {
    let (_host, url) = start_host(&[]);
    let (mut op, arena, robot) = mounted(&url).await;
    let (goal, _) = to_the_arenas_goal(&mut op, &arena, &robot).await;
    op.start_run().await;
    tokio::time::sleep(Duration::from_millis(1500)).await;
    // Left where it stands: no drive back after an emergency stop.
    op.send(json!({"type": "emergency_stop"})).await;
    op.expect("done").await;
    op.send(json!({"type": "plan", "goal": {"x_mm": goal.x_mm, "y_mm": goal.y_mm}}))
        .await;
    let planned = op.expect("planned").await;
    let from = &planned["path"][0];
    let from: Point = serde_json::from_value(from.clone()).unwrap();
    assert!(from.distance(arena.start.point()) > 50.0, "{planned}");
    let definition = json!({"goal": {"x_mm": goal.x_mm, "y_mm": goal.y_mm, "tolerance_mm": 15},
        "path": planned["path"]});
    let forecast = forecast_of(&mut op, definition).await;
    assert_eq!(forecast["refusals"], json!([]), "{forecast}");
    op.start_run().await;
    tokio::time::sleep(Duration::from_millis(1000)).await;
    op.send(json!({"type": "stop"})).await;
    let done = op.expect("done").await;
    assert_eq!(done["summary"]["reason"], "stopped", "{done}");
    let defined = op.expect("defined").await;
    let first = &defined["path"][0];
    let first: Point = serde_json::from_value(first.clone()).unwrap();
    assert!(
        first.distance(arena.start.point()) < 20.0,
        "planned again from the start: {defined}"
    );
    loop {
        let v = op
            .next_of_any(&["forecast", "error"], Duration::from_secs(30))
            .await
            .expect("the definition tried again");
        if v["type"] == "forecast" {
            assert_eq!(v["refusals"], json!([]), "{v}");
            break;
        }
        assert_ne!(v["code"], "forecast_refused", "{v}");
    }
    op.start_run().await;
}
