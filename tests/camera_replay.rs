//! A camera of recorded footage behind the same trait as the simulated one:
//! `vl host --camera dir:PATH` plays a directory's frames back, maps the
//! floor and locates the robot from them, and says the camera is offline
//! when the footage goes away — never a panic.

use crate::common;

use std::time::Duration;

use common::peer::Peer;
use common::{refused, scratch, start_emulator, start_khepera_host_with};

/// Frames the simulator renders of the navigation arena, as recorded footage.
fn footage(name: &str, frames: usize) -> std::path::PathBuf {
    let dir = scratch(name);
    for i in 0..frames {
        let file = dir.join(format!("frame-{i:03}.png"));
        let seed = i.to_string();
        common::render_arena(&file, &["--optics", "noisy", "--seed", &seed]);
    }
    dir
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn recorded_footage_is_the_camera_until_it_goes_away() {
    let dir = footage("replay-footage", 3);
    let (_emu, device) = start_emulator(&["--arena", "navigation"]);
    let camera = format!("dir:{}", dir.display());
    let (_host, url) = start_khepera_host_with(&device, &["--camera", &camera]);
    let mut watcher = Peer::connect(&url).await;
    watcher.hello("observer").await;
    let status = watcher.expect("status").await;
    assert_eq!(status["camera"], "online", "{status}");
    // Frames flow, and the pose comes from them.
    let mut op = Peer::connect(&url).await;
    op.hello("operator").await;
    op.send(serde_json::json!({"type": "mount", "experiment": "navigation"}))
        .await;
    let mounted = op.expect("mounted").await;
    assert_eq!(mounted["camera"]["width_px"], 640);
    let feedback = watcher
        .next_of("feedback", Duration::from_secs(5))
        .await
        .expect("feedback");
    assert_eq!(feedback["source"], "camera", "{feedback}");
    for _ in 0..100 {
        if watcher.frames > 0 {
            break;
        }
        watcher.next_of("feedback", Duration::from_secs(1)).await;
    }
    assert!(watcher.frames > 0, "no frame arrived");

    std::fs::remove_dir_all(&dir).unwrap();
    let offline = watcher
        .next_of("status", Duration::from_secs(10))
        .await
        .expect("a status once the footage is gone");
    assert_eq!(offline["camera"], "offline", "{offline}");
}

#[test]
fn footage_that_is_not_there_is_a_clear_error() {
    let empty = scratch("replay-empty");
    let (_emu, device) = start_emulator(&["--arena", "navigation"]);
    refused(
        &[
            "host",
            "--robot",
            "khepera",
            "--port",
            &device,
            "--camera",
            "dir:/no/such/footage",
        ],
        "cannot read the footage in /no/such/footage",
    );
    let camera = format!("dir:{}", empty.display());
    refused(
        &[
            "host", "--robot", "khepera", "--port", &device, "--camera", &camera,
        ],
        "it holds no .png or .jpg images",
    );
    refused(
        &["host", "--camera", "webcam"],
        "is no camera: use sim, none, http://… (an MJPEG stream), v4l2:/dev/videoN (a webcam), dir:PATH",
    );
    refused(
        &["host", "--camera", &camera],
        "replay it with --robot khepera",
    );
}
