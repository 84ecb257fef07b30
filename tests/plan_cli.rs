//! `vl plan` through its command line: the ROS map frame, NF1 values a
//! hand count confirms, a path around a wall, "no path", virtual
//! obstacles, coarser cells, the SVG, and bad input refused with exit 2.

use crate::common;

use std::path::PathBuf;

use common::{refused, vl, vl_json};
use image::{GrayImage, Luma};
use serde_json::Value;

/// `vl plan` flags for `map` at `scale` mm per px from `start` to `goal`, then `extra`.
fn args<'a>(
    map: &'a str,
    scale: &'a str,
    start: &'a str,
    goal: &'a str,
    extra: &[&'a str],
) -> Vec<&'a str> {
    let mut all = vec![
        "--map",
        map,
        "--mm-per-px",
        scale,
        "--start",
        start,
        "--goal",
        goal,
    ];
    all.extend_from_slice(extra);
    all
}

fn plan_json(args: &[&str]) -> Value {
    let mut all = vec!["plan", "--json"];
    all.extend_from_slice(args);
    vl_json(&all)
}

/// A 20 × 10 px white map with a black wall down column 10 from the top,
/// rows 0 to `wall_rows` − 1, saved under `name`.
fn wall_map(name: &str, wall_rows: u32) -> PathBuf {
    let mut image = GrayImage::from_pixel(20, 10, Luma([255]));
    for r in 0..wall_rows {
        image.put_pixel(10, r, Luma([0]));
    }
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    image.save(&path).unwrap();
    path
}

/// At 10 mm per px, pixel (c, r)'s centre is ((c + ½)·10, (10 − r − ½)·10).
const START: &str = "25,75";
const GOAL: &str = "175,75";

#[test]
fn plans_around_a_wall_in_the_ros_map_frame() {
    let map = wall_map("wall8.png", 8);
    let map = map.to_str().unwrap();
    let out = plan_json(&args(
        map,
        "10",
        START,
        GOAL,
        &["--robot-radius", "0", "--connectivity", "4"],
    ));
    assert_eq!(out["found"], true);
    assert_eq!(out["grid"]["width"], 20);
    assert_eq!(out["grid_path"][0], serde_json::json!([2, 2]));
    let cells = out["grid_path"].as_array().unwrap();
    assert_eq!(cells.last().unwrap(), &serde_json::json!([17, 2]));
    // Down 6 rows to the gap under the wall, 15 columns across, 6 rows up.
    assert_eq!(out["nf1_start_value"], 27);
    assert_eq!(cells.len(), 28);
    let path = out["path"].as_array().unwrap();
    assert_eq!(path[0], serde_json::json!([25.0, 75.0]));
    assert_eq!(path.last().unwrap(), &serde_json::json!([175.0, 75.0]));
    for p in path {
        let (x, y) = (p[0].as_f64().unwrap(), p[1].as_f64().unwrap());
        // The wall spans x 100–110 mm and y 20–100 mm.
        assert!(
            !((100.0..110.0).contains(&x) && y >= 20.0),
            "({x}, {y}) is in the wall"
        );
    }
    let clearance = out["min_clearance_mm"].as_f64().unwrap();
    assert!(clearance > 0.0 && clearance < 10.0, "{clearance}");
    let length = out["length_mm"].as_f64().unwrap();
    // No shorter than straight lines via the wall's foot (110, 20) mm.
    assert!(
        length > 2.0 * 85f64.hypot(55.0) && length < 280.0,
        "{length}"
    );
    assert!(out["seconds"].as_f64().unwrap() >= 0.0);

    // With 8-connectivity the descent cuts corners: fewer steps.
    let eight = plan_json(&args(map, "10", START, GOAL, &["--robot-radius", "0"]));
    assert!(eight["nf1_start_value"].as_u64().unwrap() < 27);

    // A robot 11 mm in radius no longer fits under the wall's end …
    let fat = plan_json(&args(map, "10", START, GOAL, &["--robot-radius", "11"]));
    assert_eq!(fat["found"], false);
    assert!(fat["reason"].as_str().unwrap().contains("not connected"));
    // … and a virtual obstacle can close the gap for a point too.
    let closed = plan_json(&args(
        map,
        "10",
        START,
        GOAL,
        &[
            "--robot-radius",
            "0",
            "--virtual-obstacle",
            "rect:95,0,20,25",
        ],
    ));
    assert_eq!(closed["found"], false);
}

#[test]
fn coarser_cells_svg_and_a_polygon_robot() {
    let map = wall_map("wall6.png", 6);
    let map = map.to_str().unwrap();
    let svg = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("wall6.svg");
    let coarse = plan_json(&args(
        map,
        "10",
        START,
        GOAL,
        &[
            "--cell-mm",
            "20",
            "--robot-radius",
            "0",
            "--svg",
            svg.to_str().unwrap(),
        ],
    ));
    assert_eq!(coarse["grid"]["width"], 10);
    assert_eq!(coarse["grid"]["height"], 5);
    assert_eq!(coarse["grid_path"][0], serde_json::json!([1, 1]));
    let drawing = std::fs::read_to_string(&svg).unwrap();
    assert!(drawing.starts_with("<svg") && drawing.contains("<path d=\"M"));

    // A bar 30 mm long passes the 20 mm gap under a longer wall only end-on.
    let map = wall_map("wall8-bar.png", 8);
    let bar = plan_json(&args(
        map.to_str().unwrap(),
        "10",
        "25,75,1.5708",
        "175,75,1.5708",
        &[
            "--footprint",
            "-15,-2;15,-2;15,2;-15,2",
            "--theta-slices",
            "8",
        ],
    ));
    assert_eq!(bar["found"], true, "{bar}");
    assert_eq!(bar["grid"]["theta_slices"], 8);
    let slices: Vec<u64> = bar["grid_path_slices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k.as_u64().unwrap())
        .collect();
    let at_gap = bar["grid_path"]
        .as_array()
        .unwrap()
        .iter()
        .position(|c| c[0] == 10)
        .unwrap();
    assert!(
        slices[at_gap] == 0 || slices[at_gap] == 4,
        "under the wall it lies along x, not slice {}",
        slices[at_gap]
    );
    assert_eq!(slices[0], 2, "it starts facing +y");
}

#[test]
fn the_shipped_maze_has_a_path_for_a_khepera() {
    let file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/crates/vl-core/arenas/maze.png"
    );
    let plan = |map: &str| {
        plan_json(&[
            "--map",
            map,
            "--mm-per-px",
            "5",
            "--start",
            "80,520",
            "--goal",
            "720,80",
        ])
    };
    let out = plan(file);
    assert_eq!(out["found"], true);
    assert!(out["min_clearance_mm"].as_f64().unwrap() >= 0.0);
    assert!(out["length_mm"].as_f64().unwrap() > 800.0);
    // The maze ships inside vl: by name it plans the same from anywhere.
    let by_name = plan("maze");
    assert_eq!(by_name["path"], out["path"]);
}

#[test]
fn bad_input_is_named_with_exit_code_2() {
    let map = wall_map("wall-bad.png", 8);
    let map = map.to_str().unwrap();
    let missing = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("no-such-map.png");
    let cases: [(Vec<&str>, &str); 9] = [
        (
            args(map, "10", START, GOAL, &["--cell-mm", "0.001"]),
            "more than the 200000000 this planner holds",
        ),
        (
            args(missing.to_str().unwrap(), "10", START, GOAL, &[]),
            "cannot read the map image",
        ),
        (
            args(map, "10", "-5,75", GOAL, &[]),
            "start (-5.0, 75.0) mm is off the map",
        ),
        (
            args(map, "10", START, "105,75", &["--robot-radius", "0"]),
            "goal (105.0, 75.0) mm lies in an obstacle",
        ),
        (
            args(map, "0", START, GOAL, &[]),
            "scale must be a positive number",
        ),
        (
            args(map, "-2", START, GOAL, &[]),
            "scale must be a positive number",
        ),
        (
            args(map, "10", START, GOAL, &["--connectivity", "6"]),
            "invalid value '6' for '--connectivity <CONNECTIVITY>'\n  [possible values: 4, 8]",
        ),
        (
            args(
                map,
                "10",
                START,
                GOAL,
                &["--virtual-obstacle", "circle:1,2,-3"],
            ),
            "radius",
        ),
        (args(map, "10", "25", GOAL, &[]), "expected x,y or x,y,θ"),
    ];
    for (args, needle) in cases {
        let mut all = vec!["plan"];
        all.extend(args);
        refused(&all, needle);
    }
    refused(
        &["plan", "bench", "--size", "10"],
        "--size: the benchmark map must be at least 50 cells a side, not 10",
    );
}

#[test]
fn bench_reports_each_stage() {
    let out = vl(&["plan", "bench", "--size", "200", "--runs", "2", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "nf1_ms",
        "descent_ms",
        "spline_ms",
        "clearance_ms",
        "whole_ms",
    ] {
        assert!(report[key].as_f64().unwrap() > 0.0, "{key}: {report}");
    }
    assert!(report["path_cells"].as_u64().unwrap() > 200);
}
