//! `vl camera calibrate` through its command line: the simulated camera
//! tilted, offset, blurred, noisy and unevenly lit calibrated to within
//! half a pixel of the truth; a picture of a dot target and a file of
//! point pairs give the same camera; bad input refused with exit 2.

use crate::common;

use common::{refused, scratch, vl, vl_json};
use serde_json::{Value, json};

const NOISY: [&str; 8] = [
    "--lens-offset",
    "5,-3",
    "--blur",
    "0.8",
    "--noise",
    "4",
    "--lighting",
    "0.3",
];

fn calibrate(extra: &[&str]) -> Value {
    let mut args = vec!["camera", "calibrate", "--json"];
    args.extend_from_slice(extra);
    vl_json(&args)
}

#[test]
fn the_simulated_camera_calibrates_within_half_a_pixel() {
    for tilt in ["0", "15", "30"] {
        let mut args = vec!["--sim", "--tilt-deg", tilt];
        args.extend_from_slice(&NOISY);
        let fit = calibrate(&args);
        let rms = fit["reprojection"]["rms_px"].as_f64().unwrap();
        let truth = fit["truth_max_px"].as_f64().unwrap();
        println!("tilt {tilt}°: rms {rms:.3} px, {truth:.3} px off the true camera at worst");
        assert_eq!(fit["reprojection"]["points"], 130);
        assert!(rms < 0.5 && truth < 0.5, "{fit}");
    }
}

#[test]
fn a_picture_and_a_file_of_points_give_the_camera() {
    let dir = scratch("camera-calibrate");
    let target = json!({
        "cols": 5, "rows": 4,
        "first_mm": {"x_mm": 60.0, "y_mm": 60.0},
        "spacing_mm": [120.0, 160.0],
        "radius_mm": 12.0
    });
    let target_file = dir.join("target.json");
    std::fs::write(&target_file, target.to_string()).unwrap();
    // Point pairs from a known tilted camera: the overhead 640 px camera of
    // an 800 × 600 mm floor seen 20 px further right.
    let pairs: Vec<Value> = (0..5)
        .flat_map(|i| {
            (0..4).map(move |j| (80.0 + 160.0 * f64::from(i), 60.0 + 160.0 * f64::from(j)))
        })
        .map(|(x, y)| json!({"floor_mm": [x, y], "pixel": [x * 0.8 + 20.0, 480.0 - y * 0.8]}))
        .collect();
    let points = dir.join("points.json");
    std::fs::write(&points, Value::Array(pairs).to_string()).unwrap();
    let out = dir.join("calibration.json");
    let fit = calibrate(&[
        "--points",
        points.to_str().unwrap(),
        "--image-size",
        "640x480",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(
        fit["reprojection"]["max_px"].as_f64().unwrap() < 1e-6,
        "{fit}"
    );
    let written: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let h = &written["camera"]["floor_to_image"];
    assert!((h[0][0].as_f64().unwrap() - 0.8).abs() < 1e-9, "{written}");
    assert!((h[0][2].as_f64().unwrap() - 20.0).abs() < 1e-6, "{written}");
    assert!((h[1][1].as_f64().unwrap() + 0.8).abs() < 1e-9, "{written}");
    // The people's table names what it found.
    let table = vl(&[
        "camera",
        "calibrate",
        "--points",
        points.to_str().unwrap(),
        "--image-size",
        "640x480",
    ]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(
        text.contains("reprojection rms") && text.contains("1.250 mm per px"),
        "{text}"
    );
    // A picture of the target, as the lab's camera would take it, tilted
    // and noisy: the camera it finds puts the dots where the picture has them.
    let photo = dir.join("target.png");
    let mut render = vec![
        "sim",
        "render",
        "--arena",
        "open",
        "--width",
        "640",
        "--tilt-deg",
        "20",
    ];
    render.extend_from_slice(&NOISY);
    let (target_arg, photo_arg) = (
        target_file.to_str().unwrap().to_owned(),
        photo.to_str().unwrap().to_owned(),
    );
    render.extend_from_slice(&["--target", &target_arg, "-o", &photo_arg]);
    assert!(vl(&render).status.success());
    let fit = calibrate(&["--image", &photo_arg, "--target", &target_arg]);
    assert_eq!(fit["reprojection"]["points"], 20);
    assert!(
        fit["reprojection"]["rms_px"].as_f64().unwrap() < 0.5,
        "{fit}"
    );
    // A picture that is not of the target says what it found.
    let floor = dir.join("floor.png");
    image::RgbImage::from_pixel(64, 48, image::Rgb([220, 220, 220]))
        .save(&floor)
        .unwrap();
    refused(
        &[
            "camera",
            "calibrate",
            "--image",
            floor.to_str().unwrap(),
            "--target",
            target_file.to_str().unwrap(),
        ],
        "found 0 dots where the target has 20",
    );
}

#[test]
fn bad_calibrations_are_refused_with_the_reason() {
    let dir = scratch("camera-bad");
    let write = |name: &str, v: Value| {
        let path = dir.join(name);
        std::fs::write(&path, v.to_string()).unwrap();
        path.to_str().unwrap().to_owned()
    };
    let three = write(
        "three.json",
        json!([
            {"floor_mm": [0, 0], "pixel": [0, 480]},
            {"floor_mm": [800, 0], "pixel": [640, 480]},
            {"floor_mm": [800, 600], "pixel": [640, 0]}
        ]),
    );
    refused(
        &[
            "camera",
            "calibrate",
            "--points",
            &three,
            "--image-size",
            "640x480",
        ],
        "at least 4 point pairs, got 3",
    );
    let line = write(
        "line.json",
        json!(
            (0..6)
                .map(|i| json!({"floor_mm": [i * 100, i * 50], "pixel": [i * 80, i * 40]}))
                .collect::<Vec<_>>()
        ),
    );
    refused(
        &[
            "camera",
            "calibrate",
            "--points",
            &line,
            "--image-size",
            "640x480",
        ],
        "three or more of them lie on one line",
    );
    let garbage = write("garbage.json", json!({"not": "pairs"}));
    refused(
        &[
            "camera",
            "calibrate",
            "--points",
            &garbage,
            "--image-size",
            "640x480",
        ],
        "is not a points file",
    );
    refused(
        &[
            "camera",
            "calibrate",
            "--points",
            &three,
            "--image-size",
            "640",
        ],
        "is not WxH",
    );
    refused(&["camera", "calibrate"], "say what to calibrate from");
    // A target no sheet could be: too many dots, or a dot of no size.
    let photo = dir.join("photo.png");
    image::RgbImage::from_pixel(64, 48, image::Rgb([220, 220, 220]))
        .save(&photo)
        .unwrap();
    let target = |name: &str, cols: u32, radius: f64| {
        write(
            name,
            json!({"cols": cols, "rows": 4, "first_mm": {"x_mm": 50, "y_mm": 50},
                   "spacing_mm": [100, 100], "radius_mm": radius}),
        )
    };
    for (file, reason) in [
        (target("wide.json", 1000, 10.0), "not 1000 × 4"),
        (target("flat.json", 5, 0.0), "sizes positive"),
    ] {
        refused(
            &[
                "camera",
                "calibrate",
                "--image",
                photo.to_str().unwrap(),
                "--target",
                &file,
            ],
            reason,
        );
    }
    refused(
        &["camera", "calibrate", "--sim", "--tilt-deg", "60"],
        "at most 45°",
    );
}
