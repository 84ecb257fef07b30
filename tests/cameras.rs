//! Real cameras from outside: a network camera streaming MJPEG over HTTP,
//! served by this test from the simulator's frames of the emulated
//! Khepera, driving whole navigation runs and unplugged mid-run; and a
//! webcam's MJPEG and YUYV buffers through the decode the V4L2 path uses.

use crate::common;

use std::io::Write;
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use common::{start_emulator_watched, start_khepera_host_with, vl};
use vl_core::{Arena, Pose, RobotModel};
use vl_sim::{Optics, World, camera_for};

/// Frames a second the test's camera sends.
const FPS: f64 = 15.0;

/// The simulator's view of `arena` with the robot at `pose`, as a JPEG.
fn frame(arena: &Arena, pose: Pose) -> Vec<u8> {
    let mut placed = arena.clone();
    placed.start = pose;
    let world = World::new(placed, RobotModel::khepera_ii(), 1).expect("the robot is on the floor");
    let image = world.render(&camera_for(&world, 320, FPS), &Optics::default());
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 85)
        .encode_image(&image)
        .expect("a frame encodes");
    jpeg
}

/// What the camera sees when a frame is taken, as a JPEG.
type Scene = Arc<dyn Fn() -> Vec<u8> + Send + Sync>;

/// An MJPEG camera over HTTP, as mjpg-streamer serves one, sending what
/// its scene shows. While `plugged` is false it answers nothing and drops
/// whoever was watching.
struct HttpCamera {
    port: u16,
    plugged: Arc<AtomicBool>,
}

impl HttpCamera {
    fn serve(scene: Scene) -> HttpCamera {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let plugged = Arc::new(AtomicBool::new(true));
        let on = plugged.clone();
        thread::spawn(move || {
            for client in listener.incoming().flatten() {
                if !on.load(Ordering::SeqCst) {
                    continue; // dropped: the connection closes unanswered
                }
                let (scene, on) = (scene.clone(), on.clone());
                thread::spawn(move || stream(client, &scene, &on));
            }
        });
        HttpCamera { port, plugged }
    }

    fn url(&self) -> String {
        format!("http://127.0.0.1:{}/?action=stream", self.port)
    }
}

fn stream(mut client: TcpStream, scene: &Scene, on: &AtomicBool) {
    // The request is read and not looked at: this camera has one stream.
    let mut request = [0u8; 1024];
    let _ = std::io::Read::read(&mut client, &mut request);
    let head = "HTTP/1.0 200 OK\r\nContent-Type: multipart/x-mixed-replace;boundary=boundarydonotcross\r\n\r\n";
    if client.write_all(head.as_bytes()).is_err() {
        return;
    }
    while on.load(Ordering::SeqCst) {
        let jpeg = scene();
        let part = format!(
            "--boundarydonotcross\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n",
            jpeg.len()
        );
        if client.write_all(part.as_bytes()).is_err()
            || client.write_all(&jpeg).is_err()
            || client.write_all(b"\r\n").is_err()
        {
            return;
        }
        thread::sleep(Duration::from_secs_f64(1.0 / FPS));
    }
}

fn headless(url: &str, goal: Option<&str>) -> serde_json::Value {
    let goal: Vec<&str> = goal.map(|g| vec!["--goal", g]).unwrap_or_default();
    common::headless_run(url, 40, &goal)
}

#[test]
fn a_network_camera_drives_runs_and_when_unplugged_stops_one_and_comes_back() {
    let arena = Arena::named("navigation").unwrap();
    let (_emulator, device, lines) = start_emulator_watched(&[]);
    let truth = Arc::new(Mutex::new(arena.start));
    {
        let truth = truth.clone();
        thread::spawn(move || {
            for line in lines {
                let f: Vec<f64> = line
                    .split(' ')
                    .skip(1)
                    .filter_map(|v| v.parse().ok())
                    .collect();
                if let [_, x_mm, y_mm, theta_rad, _] = f[..] {
                    *truth.lock().unwrap() = Pose {
                        x_mm,
                        y_mm,
                        theta_rad,
                    };
                }
            }
        });
    }
    let scene: Scene = {
        let (arena, truth) = (arena.clone(), truth.clone());
        Arc::new(move || frame(&arena, *truth.lock().unwrap()))
    };
    let camera = HttpCamera::serve(scene);
    let (_host, url) = start_khepera_host_with(&device, &["--camera", &camera.url(), "--no-reset"]);
    // An observer hears what the Host says of its camera all along.
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let heard = {
        let url = url.clone();
        runtime.spawn(async move {
            let mut observer = common::peer::Peer::connect(&url).await;
            observer.hello("observer").await;
            let mut camera = Vec::new();
            while let Some(status) = observer.next_of("status", Duration::from_secs(60)).await {
                camera.push(status["camera"].as_str().unwrap_or_default().to_owned());
                if camera.ends_with(&["offline".to_owned(), "online".to_owned()]) {
                    break;
                }
            }
            camera
        })
    };

    // A whole run, steered by what the camera sees.
    let run = headless(&url, None);
    assert_eq!(run["reason"], "goal_reached", "{run}");
    assert_eq!(run["collisions"], 0, "{run}");
    assert_eq!(run["pose_source"], "camera", "{run}");
    assert!(run["frames"].as_u64().unwrap() > 10, "{run}");

    // Unplugged mid-run: the run stops, saying the camera lost the robot.
    let unplug = {
        let plugged = camera.plugged.clone();
        thread::spawn(move || {
            thread::sleep(Duration::from_millis(1500));
            plugged.store(false, Ordering::SeqCst);
        })
    };
    let cut = headless(&url, Some("100,100"));
    unplug.join().unwrap();
    assert_eq!(cut["reason"], "robot_lost", "{cut}");
    assert_eq!(cut["reached_goal"], false, "{cut}");

    // Plugged in again, it comes back by itself and steers the next run.
    camera.plugged.store(true, Ordering::SeqCst);
    thread::sleep(Duration::from_secs(3));
    let again = headless(&url, Some("100,100"));
    assert_eq!(again["reason"], "goal_reached", "{again}");
    assert_eq!(again["pose_source"], "camera", "{again}");
    let heard = runtime.block_on(heard).unwrap();
    assert!(
        heard.ends_with(&["offline".to_owned(), "online".to_owned()]),
        "the camera was said to be {heard:?}"
    );
    let at = *truth.lock().unwrap();
    assert!(
        (at.x_mm - 100.0).hypot(at.y_mm - 100.0) < 20.0,
        "the robot is truly at {at:?}"
    );
}

#[test]
fn a_network_camera_looking_at_the_target_gives_its_lens() {
    let (k1, k2) = (-0.2, 0.12);
    let target = vl_core::DotTarget::spread_over(800.0, 600.0);
    let nominal = vl_core::CameraModel::overhead(800.0, 600.0, 640, FPS);
    let optics = Optics {
        distortion: vl_core::Distortion { k1, k2 },
        lens_offset_px: [0.0, 0.0],
        ..Optics::noisy(3)
    };
    let picture = vl_sim::render_target(&target, &nominal, &optics, 800.0, 600.0);
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95)
        .encode_image(&picture)
        .unwrap();
    let camera = HttpCamera::serve(Arc::new(move || jpeg.clone()));
    let dir = common::scratch("calibrate-http");
    let file = dir.join("target.json");
    std::fs::write(&file, serde_json::to_string(&target).unwrap()).unwrap();
    let fit = common::vl_json(&[
        "camera",
        "calibrate",
        "--camera",
        &camera.url(),
        "--target",
        common::s(&file),
        "--json",
    ]);
    let lens = &fit["camera"]["distortion"];
    let (f1, f2) = (lens["k1"].as_f64().unwrap(), lens["k2"].as_f64().unwrap());
    assert!(
        (f1 - k1).abs() <= 0.1 * k1.abs() && (f2 - k2).abs() <= 0.1 * k2.abs(),
        "{fit}"
    );
    assert!(
        fit["reprojection"]["rms_px"].as_f64().unwrap() < 0.2,
        "{fit}"
    );
}

/// `image` as a webcam's YUYV buffer: BT.601 limited range, each pair of
/// pixels sharing the mean of their chroma.
fn yuyv(image: &image::RgbImage) -> Vec<u8> {
    let mut out = Vec::with_capacity((image.width() * image.height() * 2) as usize);
    let yuv = |p: &image::Rgb<u8>| {
        let [r, g, b] = p.0.map(f64::from);
        (
            16.0 + (65.738 * r + 129.057 * g + 25.064 * b) / 256.0,
            128.0 + (-37.945 * r - 74.494 * g + 112.439 * b) / 256.0,
            128.0 + (112.439 * r - 94.154 * g - 18.285 * b) / 256.0,
        )
    };
    for row in image.rows() {
        let row: Vec<_> = row.collect();
        for pair in row.chunks_exact(2) {
            let (y0, u0, v0) = yuv(pair[0]);
            let (y1, u1, v1) = yuv(pair[1]);
            let byte = |v: f64| v.round().clamp(0.0, 255.0) as u8;
            out.extend([
                byte(y0),
                byte((u0 + u1) / 2.0),
                byte(y1),
                byte((v0 + v1) / 2.0),
            ]);
        }
    }
    out
}

/// A JPEG without its Huffman tables, as USB webcams send MJPEG.
fn bare_mjpeg(image: &image::RgbImage) -> Vec<u8> {
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 80)
        .encode_image(image)
        .unwrap();
    let mut out = jpeg[..2].to_vec();
    let mut i = 2;
    while jpeg[i + 1] != 0xDA {
        let len = 2 + usize::from(u16::from_be_bytes([jpeg[i + 2], jpeg[i + 3]]));
        if jpeg[i + 1] != 0xC4 {
            out.extend_from_slice(&jpeg[i..i + len]);
        }
        i += len;
    }
    out.extend_from_slice(&jpeg[i..]);
    out
}

#[test]
fn webcam_buffers_decode_to_frames_the_robot_is_found_in() {
    let mut arena = Arena::named("navigation").unwrap();
    arena.start = Pose {
        x_mm: 412.0,
        y_mm: 288.0,
        theta_rad: 0.7,
    };
    let world = World::new(arena.clone(), RobotModel::khepera_ii(), 1).unwrap();
    let camera = camera_for(&world, 640, FPS);
    let image = world.render(&camera, &Optics::default());
    let (w, h) = image.dimensions();
    // A driver may pad each row: 64 bytes more than the pixels need here.
    let stride = w as usize * 2 + 64;
    let mut padded = Vec::new();
    for row in yuyv(&image).chunks_exact(w as usize * 2) {
        padded.extend_from_slice(row);
        padded.extend([0u8; 64]);
    }
    for (format, bytes, stride) in [
        (vl_host::PixelFormat::Yuyv, padded, stride),
        (vl_host::PixelFormat::Mjpeg, bare_mjpeg(&image), 0),
    ] {
        let decoded = vl_host::decode_pixels(format, &bytes, w, h, stride)
            .unwrap_or_else(|e| panic!("{format}: {e}"));
        let seen = vl_core::look(&decoded, &camera)
            .robot
            .unwrap_or_else(|| panic!("{format}: no robot in the frame"));
        let off = (seen.x_mm - 412.0).hypot(seen.y_mm - 288.0);
        assert!(off < 2.0, "{format}: the robot {off:.2} mm off");
        assert!((seen.theta_rad - 0.7).abs() < 0.05, "{format}: {seen:?}");
        // A buffer cut short is refused, saying why.
        let short = vl_host::decode_pixels(format, &bytes[..bytes.len() / 2], w, h, stride);
        if format == vl_host::PixelFormat::Yuyv {
            assert!(short.is_err());
        }
    }
}

/// A machine with a webcam opens it through the same decode. CI machines
/// have none (and no kernel module to make one), so this runs on request.
#[test]
#[ignore = "needs a /dev/video* webcam: cargo test -- --ignored on a machine with one"]
fn a_webcam_on_this_machine_gives_a_frame() {
    let devices = vl_host::list_devices().unwrap();
    let device = devices.0.first().expect("a /dev/video* capture device");
    let spec: vl_host::V4l2Spec = device.path.display().to_string().parse().unwrap();
    let mut webcam = vl_host::V4l2Camera::open(spec, None, (800.0, 600.0))
        .unwrap_or_else(|e| panic!("{}: {e}", device.path.display()));
    let frame = vl_host::Camera::grab(&mut webcam).expect("a frame from the webcam");
    assert!(frame.image.width() > 0);
}

#[test]
fn camera_addresses_are_checked_before_anything_starts() {
    common::refused(
        &["host", "--camera", "rtsp://cam/"],
        "'rtsp://cam/' is no camera",
    );
    common::refused(
        &["host", "--camera", "v4l2:/dev/video0,h264"],
        "'h264' is no camera setting",
    );
    common::refused(
        &["host", "--camera", "http://127.0.0.1:9/"],
        "a real camera watches a real robot",
    );
    common::refused(
        &[
            "host",
            "--robot",
            "ros2",
            "--camera",
            "ros2:/camera/image raw",
        ],
        "a ROS 2 topic is /name/name…",
    );
    common::refused(
        &["host", "--camera", "ros2:/camera/image_raw/compressed"],
        "a real camera watches a real robot",
    );
    let listed = vl(&["camera", "list"]);
    assert!(listed.status.success(), "{}", common::stderr(&listed));
    let out = common::stdout(&listed);
    assert!(
        out.contains("/dev/video") || out.contains("no video capture devices"),
        "{out}"
    );
}

/// `jpeg` declaring `width`×`height` in its frame header, nothing else
/// changed: a few kilobytes that would decode to a huge picture.
fn declaring(mut jpeg: Vec<u8>, width: u16, height: u16) -> Vec<u8> {
    let sof = jpeg
        .windows(2)
        .position(|w| w == [0xFF, 0xC0])
        .expect("a baseline JPEG");
    jpeg[sof + 5..sof + 7].copy_from_slice(&height.to_be_bytes());
    jpeg[sof + 7..sof + 9].copy_from_slice(&width.to_be_bytes());
    jpeg
}

/// A network camera that sends, between its frames, frames declaring
/// 8192×8192 px: each is dropped by its header before any decoding, the
/// Host stays small, and the camera's own frames still reach a watcher
/// (issue 43, item 15).
#[test]
fn frames_larger_than_the_camera_are_dropped_before_decoding() {
    let arena = Arena::named("navigation").unwrap();
    let (_emulator, device, _lines) = start_emulator_watched(&[]);
    let good = frame(&arena, arena.start);
    let huge = declaring(good.clone(), 8192, 8192);
    let sent = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let scene: Scene = {
        let sent = sent.clone();
        Arc::new(move || {
            let n = sent.fetch_add(1, Ordering::SeqCst);
            if n.is_multiple_of(2) {
                good.clone()
            } else {
                huge.clone()
            }
        })
    };
    let camera = HttpCamera::serve(scene);
    let (host, url) = start_khepera_host_with(&device, &["--camera", &camera.url()]);
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let frames = runtime.block_on(async {
        let mut watcher = common::peer::Peer::connect(&url).await;
        watcher.hello("observer").await;
        let began = std::time::Instant::now();
        let mut frames = 0;
        while began.elapsed() < Duration::from_secs(8) {
            if let Ok(Some(Ok(m))) = tokio::time::timeout(
                Duration::from_millis(500),
                futures_util::StreamExt::next(&mut watcher.ws),
            )
            .await
            {
                frames += usize::from(m.is_binary());
            }
        }
        frames
    });
    let (_, peak_mb) = common::peer::memory_mb(host.0.id());
    let sent = sent.load(Ordering::SeqCst);
    assert!(sent > 60, "the camera sent {sent} frames");
    assert!(frames > 20, "{frames} frames reached the watcher");
    // Decoded, one such frame takes 200 MB (the Host peaked at 402 MB).
    assert!(peak_mb < 150.0, "the Host peaked at {peak_mb:.0} MB");
}
