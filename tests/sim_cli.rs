//! `vl sim …` through its command line: deterministic runs, camera frames,
//! link statistics, speed, and named refusals of bad input.

use crate::common;

use common::{refused, vl, vl_json as json};

#[test]
fn runs_are_deterministic_per_seed() {
    let run = |seed: &str| json(&["sim", "run", "--seed", seed, "--duration", "5", "--json"]);
    let (a, b, c) = (run("11"), run("11"), run("12"));
    assert_eq!(a["trace_hash"], b["trace_hash"]);
    assert_eq!(a["final_pose"], b["final_pose"]);
    assert_ne!(a["trace_hash"], c["trace_hash"]);
    assert_eq!(a["collisions"], 0);

    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let script = dir.join("square.txt");
    std::fs::write(&script, "0 200 200\n1 -100 100\n1.5 200 200\n").unwrap();
    let scripted = json(&[
        "sim",
        "run",
        "--script",
        script.to_str().unwrap(),
        "--duration",
        "3",
        "--json",
    ]);
    assert!(scripted["distance_mm"].as_f64().unwrap() > 100.0);
}

#[test]
fn render_writes_a_camera_frame() {
    let png = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("arena.png");
    assert!(
        vl(&[
            "sim",
            "render",
            "--arena",
            "navigation",
            "-o",
            png.to_str().unwrap()
        ])
        .status
        .success()
    );
    let frame = image::open(&png).unwrap().to_rgb8();
    assert_eq!(frame.dimensions(), (320, 240));
}

/// An arena drawn as a top-view image, with a coloured, dark-to-IR obstacle,
/// rendered with the camera's imperfections and driven by a bigger robot.
#[test]
fn arenas_from_images_with_materials() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("map-arena");
    std::fs::create_dir_all(&dir).unwrap();
    // 100 × 80 px at 4 mm per px: a dark bar at columns 60–69, all rows.
    let map = image::GrayImage::from_fn(100, 80, |c, _| {
        image::Luma([if (60..70).contains(&c) { 10 } else { 240 }])
    });
    map.save(dir.join("top.png")).unwrap();
    let arena = dir.join("arena.json");
    std::fs::write(
        &arena,
        r#"{"name": "drawn", "map": {"image": "top.png", "mm_per_px": 4},
            "obstacles": [{"shape": "circle", "x_mm": 100, "y_mm": 250, "radius_mm": 30,
                           "reflectivity": 0.05, "colour": [20, 120, 220]}],
            "start": {"x_mm": 100, "y_mm": 100, "theta_rad": 0}, "goal": null}"#,
    )
    .unwrap();
    let arena = arena.to_str().unwrap();
    let png = dir.join("frame.png");
    let out = vl(&[
        "sim",
        "render",
        "--arena",
        arena,
        "--width",
        "200",
        "--blur",
        "0.7",
        "--noise",
        "3",
        "--lighting",
        "0.2",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let frame = image::open(&png).unwrap().to_rgb8();
    assert_eq!(frame.dimensions(), (200, 160));
    // The bar (x 240–280 mm) is dark; the circle at (100, 250) is blue.
    let [r, g, b] = frame.get_pixel(130, 80).0;
    assert!(r < 60 && g < 60 && b < 60, "{:?}", (r, g, b));
    let [r, _, b] = frame.get_pixel(50, 160 - 125).0;
    assert!(b > 150 && r < 80, "{:?}", (r, b));
    // Driving straight at the bar stops against it, a robot radius short.
    let run = json(&[
        "sim",
        "run",
        "--arena",
        arena,
        "--radius-mm",
        "50",
        "--wheel-base-mm",
        "80",
        "--script",
        &write_script(&dir),
        "--duration",
        "4",
        "--json",
    ]);
    let x = run["final_pose"]["x_mm"].as_f64().unwrap();
    assert!((185.0..=190.0).contains(&x), "{run}");
    assert_eq!(run["collisions"], 1);
}

fn write_script(dir: &std::path::Path) -> String {
    let script = dir.join("ahead.txt");
    std::fs::write(
        &script,
        "0 200 200
",
    )
    .unwrap();
    script.to_str().unwrap().to_owned()
}

#[test]
fn link_and_bench_report_json() {
    let link = json(&[
        "sim",
        "link",
        "--profile",
        "intercontinental",
        "--packets",
        "20000",
        "--seed",
        "3",
        "--json",
    ]);
    let mean = link["measured"]["delay_mean_ms"].as_f64().unwrap();
    assert!((mean - 75.0).abs() < 1.0, "{mean}");
    assert!(link["measured"]["loss_rate"].as_f64().unwrap() > 0.0);
    let bench = json(&["sim", "bench", "--seconds", "20", "--json"]);
    assert!(bench["rtf_no_camera"].as_f64().unwrap() > 0.0);
    assert!(bench["rtf_camera"].as_f64().unwrap() > 0.0);
    // The forecast's run is the minute the bench says it is.
    let run_s = bench["forecast_run_s"].as_f64().unwrap();
    assert!((50.0..70.0).contains(&run_s), "{run_s}");
    assert!(bench["forecast_s"].as_f64().unwrap() > 0.0);
}

#[test]
fn bad_input_is_named() {
    refused(
        &["sim", "link", "--profile", "dialup"],
        "invalid value 'dialup' for '--profile <PROFILE>'\n  [possible values: lan, internet2, \
         internet-2005, intercontinental, congested, geo-satellite]",
    );
    refused(
        &["sim", "run", "--arena", "moon"],
        "unknown arena 'moon' (shipped: navigation, corridor, open, maze; or a .json file)",
    );
    refused(
        &["sim", "run", "--robot", "roomba"],
        "[possible values: khepera-ii, khepera-i]",
    );
    refused(
        &["sim", "run", "--radius-mm", "10", "--wheel-base-mm", "53"],
        "does not fit",
    );
    refused(
        &["sim", "render", "--lighting", "1.5", "-o", "/dev/null"],
        "lighting gradient must be between 0 and 1",
    );
    let bad = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("bad-script.txt");
    std::fs::write(&bad, "0 100\n").unwrap();
    refused(
        &["sim", "run", "--script", bad.to_str().unwrap()],
        "script line 1",
    );
}

/// Arena files with something wrong are refused, saying what and where.
#[test]
fn bad_arena_files_are_named() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let write = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_owned()
    };
    let arena = |obstacles: &str, start: &str| {
        format!(
            r#"{{"name": "test", "width_mm": 500, "height_mm": 400, "obstacles": [{obstacles}], "start": {start}, "goal": null}}"#
        )
    };
    let free = r#"{"x_mm": 100, "y_mm": 100, "theta_rad": 0}"#;
    refused(
        &[
            "sim",
            "run",
            "--arena",
            &write("syntax.json", "{\"name\": \"x\", "),
        ],
        "syntax.json: arena file: EOF",
    );
    let two_points = arena(
        r#"{"shape": "polygon", "points": [{"x_mm": 1, "y_mm": 1}, {"x_mm": 5, "y_mm": 5}]}"#,
        free,
    );
    refused(
        &[
            "sim",
            "render",
            "--arena",
            &write("line.json", &two_points),
            "-o",
            "/dev/null",
        ],
        "obstacle 0: a polygon needs at least 3 vertices",
    );
    // Each obstacle alone in an arena file, and what the refusal must say.
    let refusals = [
        (
            r#"{"shape": "rect", "x_mm": 0, "y_mm": 0, "width_mm": -5, "height_mm": 10}"#,
            "its width must be a positive number",
        ),
        (
            r#"{"shape": "circle", "x_mm": 110, "y_mm": 100, "radius_mm": 40}"#,
            "overlaps a wall or obstacle",
        ),
        (
            r#"{"shape": "circle", "x_mm": 300, "y_mm": 200, "radius_mm": 40, "reflectivity": 3}"#,
            "obstacle 0: its reflectivity must be between 0 and 1",
        ),
    ];
    for (i, (obstacle, needle)) in refusals.into_iter().enumerate() {
        let file = write(&format!("refused-{i}.json"), &arena(obstacle, free));
        refused(&["sim", "run", "--arena", &file], needle);
    }
    let unmapped = r#"{"name": "m", "map": {"image": "nowhere.png", "mm_per_px": 2}, "obstacles": [], "start": {"x_mm": 10, "y_mm": 10, "theta_rad": 0}, "goal": null}"#;
    refused(
        &["sim", "run", "--arena", &write("unmapped.json", unmapped)],
        "cannot read the map image",
    );
    // A valid file works like a shipped arena.
    let ok = arena(
        r#"{"shape": "circle", "x_mm": 300, "y_mm": 200, "radius_mm": 40}"#,
        free,
    );
    assert!(
        vl(&[
            "sim",
            "run",
            "--arena",
            &write("ok.json", &ok),
            "--duration",
            "1"
        ])
        .status
        .success()
    );
}

#[test]
fn runs_follow_a_planned_path_and_report_the_tracking_error() {
    // With no --duration the run lasts as long as its path needs: the maze
    // takes longer than the 10 s scripts get.
    for arena in ["corridor", "maze"] {
        let out = json(&["sim", "run", "--arena", arena, "--json"]);
        let following = &out["following"];
        assert_eq!(following["reached_goal"], true, "{arena}: {out}");
        assert_eq!(out["collisions"], 0, "{arena}: {out}");
        let (mean, max) = (
            following["mean_error_mm"].as_f64().unwrap(),
            following["max_error_mm"].as_f64().unwrap(),
        );
        assert!(mean > 0.0 && mean <= max && max < 25.0, "{arena}: {out}");
        assert!(
            out["sim_seconds"].as_f64().unwrap() < 60.0,
            "it stops on arrival"
        );
    }
    let open = json(&[
        "sim",
        "run",
        "--arena",
        "open",
        "--goal",
        "500,100",
        "--duration",
        "30",
        "--json",
    ]);
    assert_eq!(open["following"]["reached_goal"], true, "{open}");
    refused(
        &["sim", "run", "--arena", "navigation", "--goal", "280,100"],
        "no path to follow: the goal (280.0, 100.0)",
    );
}
