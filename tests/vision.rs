//! The vision pipeline against OpenCV's answers on rendered arena frames
//! (`tests/vision/`, expected values made by `opencv_expected.py`), and
//! `vl vision` through its command line.

use std::path::{Path, PathBuf};

use crate::common;

use common::{refused, s, vl_json};
use serde_json::Value;
use vl_core::{Connectivity, Threshold, binarise, components, grey, inspect, label, otsu};

fn frames() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/vision");
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let name = p.file_name().unwrap().to_str().unwrap();
            name.ends_with(".png") && !name.ends_with(".labels.png")
        })
        .collect();
    frames.sort();
    assert!(frames.len() >= 3, "frames in {}", dir.display());
    frames
}

fn expected(frame: &Path) -> Value {
    let text = std::fs::read_to_string(frame.with_extension("expected.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

#[test]
fn agrees_with_opencv() {
    for frame in frames() {
        let name = frame.file_name().unwrap().to_string_lossy().into_owned();
        let want = expected(&frame);
        let rgb = image::open(&frame).unwrap().to_rgb8();
        let g = grey(&rgb);
        let grey_sum: u64 = g.as_raw().iter().map(|&v| u64::from(v)).sum();
        assert_eq!(grey_sum, want["grey_sum"].as_u64().unwrap(), "{name}: grey");
        let t = otsu(&g);
        assert_eq!(
            f64::from(t),
            want["otsu_threshold"].as_f64().unwrap(),
            "{name}: Otsu"
        );

        let mask = binarise(&g, t, true);
        let (found, labels) = components(&mask, Connectivity::Eight);
        let theirs = want["components_8"].as_array().unwrap();
        assert_eq!(found.len(), theirs.len(), "{name}: component count");
        for (c, o) in found.iter().zip(theirs) {
            assert_eq!(c.area, o["area"].as_u64().unwrap(), "{name}: area");
            let centroid = [c.centroid.x, c.centroid.y];
            for k in 0..2 {
                assert!(
                    (centroid[k] - o["centroid"][k].as_f64().unwrap()).abs() < 1e-9,
                    "{name}: centroid {centroid:?} vs {}",
                    o["centroid"]
                );
            }
            let bbox: Vec<u64> = o["bbox"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_u64().unwrap())
                .collect();
            assert_eq!(c.bbox.map(u64::from).to_vec(), bbox, "{name}: bbox");
            for (k, (ours, cv)) in c.hu.iter().zip(o["hu"].as_array().unwrap()).enumerate() {
                let cv = cv.as_f64().unwrap();
                // Relative 1e-6; invariants that are zero by symmetry differ
                // only by rounding, so below 1e-12 of h1² counts as equal.
                let floor = 1e-12 * c.hu[0] * c.hu[0];
                assert!(
                    (ours - cv).abs() <= 1e-6 * cv.abs().max(ours.abs()) + floor,
                    "{name}: component {} h{}: {ours} vs OpenCV {cv}",
                    c.label,
                    k + 1
                );
            }
        }
        let cv_labels = image::open(frame.with_extension("labels.png"))
            .unwrap()
            .to_luma8();
        assert!(
            labels
                .iter()
                .zip(cv_labels.as_raw())
                .all(|(&ours, &cv)| ours == u32::from(cv)),
            "{name}: the 8-connected label images differ"
        );
        assert_eq!(
            u64::from(label(&mask, Connectivity::Four).1),
            want["count_4"].as_u64().unwrap(),
            "{name}: 4-connected count"
        );
        let bright = binarise(&g, 128, false);
        assert_eq!(
            u64::from(label(&bright, Connectivity::Eight).1),
            want["count_fixed_128_bright_8"].as_u64().unwrap(),
            "{name}: fixed threshold"
        );
    }
}

#[test]
fn finds_the_robot_where_the_simulator_put_it() {
    // navigation.png: 320 px across 800 mm; the robot starts at (100, 120) mm facing +x.
    let frame = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/vision/navigation.png");
    let scene = inspect(
        &image::open(&frame).unwrap().to_rgb8(),
        Threshold::Otsu,
        true,
    );
    let robot = scene.robot.expect("the robot is found");
    let (x_px, y_px) = (100.0 / 2.5 - 0.5, 240.0 - 120.0 / 2.5 - 0.5);
    assert!(
        (robot.x - x_px).abs() < 0.5 && (robot.y - y_px).abs() < 0.5,
        "{robot:?}"
    );
    assert!(robot.theta.abs() < 0.05, "{robot:?}");
    // Only the robot is taken for the robot: the round obstacles are not.
    let robots = scene
        .components
        .iter()
        .filter(|c| vl_core::is_robot(c))
        .count();
    assert_eq!(robots, 1);
}

#[test]
fn the_cli_reports_json_and_refuses_bad_input() {
    let frame = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/vision/maze-640.png");
    let v = vl_json(&["vision", "inspect", "--invert", "--json", s(&frame)]);
    assert_eq!(
        v["threshold"].as_f64(),
        expected(&frame)["otsu_threshold"].as_f64()
    );
    assert_eq!(v["components"].as_array().unwrap().len(), 5);
    assert_eq!(v["components"][0]["hu"].as_array().unwrap().len(), 7);
    assert!(v["components"][0]["orientation_rad"].is_number());
    assert!(v["robot"]["theta"].is_number());

    refused(
        &["vision", "inspect", "/no/such.png"],
        "cannot read the image /no/such.png",
    );
    let not_png = Path::new(env!("CARGO_TARGET_TMPDIR")).join("not-an-image.png");
    std::fs::write(&not_png, "hello").unwrap();
    refused(
        &["vision", "inspect", not_png.to_str().unwrap()],
        "cannot read the image",
    );
    // A small PNG that declares 20000 × 20000 pixels is refused at once.
    let mut png = Vec::new();
    image::GrayImage::new(1, 1)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png[16..24].copy_from_slice(&[0, 0, 0x4e, 0x20, 0, 0, 0x4e, 0x20]);
    let crc = crc32fast::hash(&png[12..29]);
    png[29..33].copy_from_slice(&crc.to_be_bytes());
    let huge = Path::new(env!("CARGO_TARGET_TMPDIR")).join("declares-huge.png");
    std::fs::write(&huge, &png).unwrap();
    let started = std::time::Instant::now();
    refused(&["vision", "inspect", s(&huge)], "limit");
    assert!(started.elapsed().as_secs_f64() < 2.0);
    refused(
        &[
            "vision",
            "inspect",
            "--threshold",
            "300",
            frame.to_str().unwrap(),
        ],
        "invalid value '300' for '--threshold <THRESHOLD>': a threshold is 'otsu' or a grey level 0–255, not '300'",
    );
}
