//! Live in Foxglove: the Host's port speaks the Foxglove WebSocket
//! protocol to a client that offers its subprotocol, by either name.
//! An outside client (Python's websockets, nothing of vl's) subscribes to
//! the camera and the pose during a run and decodes what comes; a careless
//! or hostile one cannot publish but on `/cmd_vel`, subscribe without
//! bound, or send more than a subscription's worth, and a lab that admits
//! only accounts to watch refuses it. (Foxglove's own libraries check the
//! rest: `foxglove_outside`.)

use std::process::Command;
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::protocol::CloseFrame;
use tokio_tungstenite::tungstenite::protocol::frame::coding::CloseCode;
use tokio_tungstenite::tungstenite::{Bytes, Message};

use crate::common::{self, s, scratch, start_host};

/// What the outside client saw in `seconds` on `url`, offering `subprotocol`.
fn watch_from_python(url: &str, subprotocol: &str, seconds: f64) -> Option<Value> {
    // `.ci/run` installs Debian's python3-websockets.
    let python = common::python_with("websockets")?;
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/foxglove/client.py");
    let out = Command::new(python)
        .args([script, url, subprotocol, &seconds.to_string()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    Some(serde_json::from_slice(&out.stdout).expect("the client prints JSON"))
}

#[test]
fn an_outside_foxglove_client_watches_a_run_by_either_subprotocol() {
    let (_host, url) = start_host(&["--no-record"]);
    let run_url = url.clone();
    let run = std::thread::spawn(move || common::headless_run(&run_url, 60, &[]));
    // Both clients at once, while the run is mounted and under way.
    let watching: Vec<_> = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
        .into_iter()
        .map(|subprotocol| {
            let url = url.clone();
            std::thread::spawn(move || (subprotocol, watch_from_python(&url, subprotocol, 4.0)))
        })
        .collect();
    for client in watching {
        let (subprotocol, seen) = client.join().unwrap();
        let Some(seen) = seen else {
            break;
        };
        assert_eq!(seen["subprotocol"], subprotocol, "{seen}");
        for (topic, schema) in [
            ("/camera", "foxglove.CompressedImage"),
            ("/camera/annotations", "foxglove.ImageAnnotations"),
            ("/robot/pose", "foxglove.PoseInFrame"),
            ("/tf", "foxglove.FrameTransform"),
            ("/scene", "foxglove.SceneUpdate"),
            ("/log", "foxglove.Log"),
            ("/feedback", "vl.Feedback"),
        ] {
            assert_eq!(seen["channels"][topic], schema, "{topic}: {seen}");
        }
        let counts = &seen["counts"];
        let count = |topic: &str| counts[topic].as_u64().unwrap_or(0);
        // 15 frames and 50 poses a second sent; a third of that is
        // taken as enough on a machine busy with other tests.
        assert!(count("/camera") >= 20, "{seen}");
        assert_eq!(seen["jpegs"].as_u64().unwrap(), count("/camera"), "{seen}");
        assert!(count("/robot/pose") >= 60, "{seen}");
        // One of each a feedback; the window may close between the two.
        assert!(count("/tf").abs_diff(count("/robot/pose")) <= 1, "{seen}");
        assert!(count("/scene") >= 1 && count("/state") >= 1, "{seen}");
        assert_eq!(seen["bad"], json!([]), "{seen}");
        assert_eq!(seen["times_rise"], true, "{seen}");
        let pose = seen["pose"].as_array().unwrap();
        let x_m = pose[0].as_f64().unwrap();
        assert!((0.0..0.8).contains(&x_m), "a pose in metres: {seen}");
    }
    let report = run.join().unwrap();
    assert_eq!(report["reached_goal"], true, "{report}");
}

type Socket =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// A Foxglove client of the Host at `url`, offering `subprotocol`.
async fn foxglove(url: &str, subprotocol: &str) -> Socket {
    let mut request = url.into_client_request().unwrap();
    request
        .headers_mut()
        .insert("sec-websocket-protocol", subprotocol.parse().unwrap());
    let (ws, response) = tokio_tungstenite::connect_async(request)
        .await
        .expect("the Foxglove handshake");
    assert_eq!(
        response.headers()["sec-websocket-protocol"],
        subprotocol,
        "answered with the subprotocol offered"
    );
    ws
}

/// The next text message's JSON, within 5 s; none if the socket ends.
async fn next_op(ws: &mut Socket) -> Option<Value> {
    tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            match ws.next().await? {
                Ok(Message::Text(t)) => return serde_json::from_str(t.as_str()).ok(),
                Ok(Message::Close(_)) | Err(_) => return None,
                Ok(_) => {}
            }
        }
    })
    .await
    .ok()
    .flatten()
}

/// The next `status` message, skipping others.
async fn next_status(ws: &mut Socket) -> Option<Value> {
    loop {
        let op = next_op(ws).await?;
        if op["op"] == "status" {
            return Some(op);
        }
    }
}

#[tokio::test]
async fn a_foxglove_client_publishes_only_twists_and_is_bounded() {
    let (_host, url) = start_host(&["--no-record"]);
    let mut ws = foxglove(&url, "foxglove.sdk.v1").await;
    assert_eq!(next_op(&mut ws).await.unwrap()["op"], "serverInfo");
    let advertise = next_op(&mut ws).await.unwrap();
    let channels = advertise["channels"].as_array().unwrap().len();
    // Publishing, the Guests' protocol and unknown ops: warned, not done.
    ws.send(Message::Binary(Bytes::from_static(&[1, 0, 0, 0, 0, 42])))
        .await
        .unwrap();
    let status = next_status(&mut ws).await.unwrap();
    assert!(
        status["message"]
            .as_str()
            .unwrap()
            .contains("only Twists on /cmd_vel"),
        "{status}"
    );
    // Any topic may be advertised (a 3D panel advertises where its clicks
    // go); what is published on one but /cmd_vel in json is refused.
    let advertise = json!({"op": "advertise", "channels": [
        {"id": 1, "topic": "/clicked_point", "encoding": "json", "schemaName": "x"},
        {"id": 2, "topic": "/cmd_vel", "encoding": "cdr", "schemaName": "x"},
    ]});
    ws.send(Message::text(advertise.to_string())).await.unwrap();
    for channel in [1u8, 2] {
        ws.send(Message::Binary(Bytes::from(vec![
            1, channel, 0, 0, 0, b'{', b'}',
        ])))
        .await
        .unwrap();
        let status = next_status(&mut ws).await.unwrap();
        assert!(
            status["message"].as_str().unwrap().contains("only Twists"),
            "{status}"
        );
    }
    for text in [
        json!({"type": "emergency_stop"}).to_string(),
        "{not json".to_owned(),
    ] {
        ws.send(Message::text(text)).await.unwrap();
        let status = next_status(&mut ws).await.unwrap();
        assert_eq!(status["level"], 1, "{status}");
    }
    // A channel that is not there, and subscriptions without end.
    let subscribe = |subscriptions: Vec<Value>| {
        Message::text(json!({"op": "subscribe", "subscriptions": subscriptions}).to_string())
    };
    ws.send(subscribe(vec![json!({"id": 1, "channelId": channels + 5})]))
        .await
        .unwrap();
    let status = next_status(&mut ws).await.unwrap();
    assert!(
        status["message"].as_str().unwrap().contains("no channel"),
        "{status}"
    );
    let many: Vec<Value> = (0..200).map(|i| json!({"id": i, "channelId": 2})).collect();
    ws.send(subscribe(many)).await.unwrap();
    let status = next_status(&mut ws).await.unwrap();
    assert!(
        status["message"].as_str().unwrap().contains("at most 64"),
        "{status}"
    );
    // More than a subscription's worth in one message: closed.
    let _ = ws.send(Message::text("x".repeat(1 << 20))).await;
    assert!(
        next_status(&mut ws).await.is_none(),
        "an oversized message did not close the connection"
    );
    // Through all of it the lab is as it was: no run was stopped, and a
    // Guest is served.
    let report = common::headless_run(&url, 60, &[]);
    assert_eq!(report["reached_goal"], true, "{report}");
}

#[tokio::test]
async fn a_lab_that_admits_only_accounts_to_watch_refuses_foxglove() {
    let dir = scratch("foxglove-accounts");
    let users = dir.join("users.toml");
    common::account(&users, "ada", "operator", "correct horse");
    let (_host, url) = start_host(&[
        "--no-record",
        "--users",
        s(&users),
        "--observers",
        "accounts",
    ]);
    let mut ws = foxglove(&url, "foxglove.websocket.v1").await;
    let status = next_status(&mut ws).await.expect("told why");
    assert_eq!(status["level"], 2, "{status}");
    assert!(
        next_op(&mut ws).await.is_none(),
        "still open after the refusal"
    );
}

/// Four Foxglove clients subscribing to every channel and unsubscribing
/// again as fast as they can for 6 s, during a run: each draws no more
/// than its budget (4 MiB a second, 8 MiB at once), where each drew over
/// a gigabyte (issue 43, item 8).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn foxglove_clients_draw_no_more_than_their_budget() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let (_host, url) = start_host(&["--camera", "sim"]);
    let mut operator = common::peer::Peer::connect(&url).await;
    operator.hello("operator").await;
    operator.start("teleoperation").await;
    let seconds = 6.0;
    let drawn: Vec<Arc<AtomicUsize>> = (0..4).map(|_| Arc::default()).collect();
    let mut tasks = Vec::new();
    for bytes in &drawn {
        let ws = foxglove(&url, "foxglove.websocket.v1").await;
        let (mut sink, mut source) = ws.split();
        let bytes = bytes.clone();
        tasks.push(tokio::spawn(async move {
            while let Some(Ok(message)) = source.next().await {
                bytes.fetch_add(message.len(), Ordering::Relaxed);
            }
        }));
        tasks.push(tokio::spawn(async move {
            for round in 0u32.. {
                let ids: Vec<u32> = (0..14).map(|c| round * 14 + c).collect();
                let subscriptions: Vec<Value> = ids
                    .iter()
                    .zip(0..)
                    .map(|(id, c)| json!({"id": id, "channelId": c}))
                    .collect();
                let ops = [
                    json!({"op": "subscribe", "subscriptions": subscriptions}),
                    json!({"op": "unsubscribe", "subscriptionIds": ids}),
                ];
                for op in ops {
                    if sink.send(Message::text(op.to_string())).await.is_err() {
                        return;
                    }
                }
            }
        }));
    }
    tokio::time::sleep(Duration::from_secs_f64(seconds)).await;
    let most = (4.0 * seconds + 8.0) * 1024.0 * 1024.0 * 1.1;
    for bytes in &drawn {
        let bytes = bytes.load(Ordering::Relaxed);
        println!("a Foxglove client drew {bytes} bytes in {seconds} s");
        assert!(
            (bytes as f64) < most,
            "a client drew {bytes} bytes in {seconds} s"
        );
        assert!(
            bytes > 100_000,
            "a client was sent almost nothing: {bytes} bytes"
        );
    }
    for task in tasks {
        task.abort();
    }
}

/// The close handshake both ways: a client's close is answered with its
/// code, and a Host that stops (SIGTERM) says so with 1001 (going away).
#[tokio::test]
async fn a_stopping_host_says_it_is_going_away() {
    let (host, url) = start_host(&["--no-record"]);
    let mut leaving = foxglove(&url, "foxglove.sdk.v1").await;
    assert_eq!(next_op(&mut leaving).await.unwrap()["op"], "serverInfo");
    leaving
        .send(Message::Close(Some(CloseFrame {
            code: CloseCode::Normal,
            reason: "done".into(),
        })))
        .await
        .unwrap();
    assert_eq!(close_code(&mut leaving).await, Some(CloseCode::Normal));
    let mut staying = foxglove(&url, "foxglove.websocket.v1").await;
    assert_eq!(next_op(&mut staying).await.unwrap()["op"], "serverInfo");
    let pid = host.0.id().to_string();
    let killed = Command::new("kill").args(["-TERM", &pid]).status().unwrap();
    assert!(killed.success());
    assert_eq!(close_code(&mut staying).await, Some(CloseCode::Away));
}

/// The code of the close frame that ends `ws`, within 5 s.
async fn close_code(ws: &mut Socket) -> Option<CloseCode> {
    tokio::time::timeout(Duration::from_secs(5), async {
        while let Some(Ok(message)) = ws.next().await {
            if let Message::Close(frame) = message {
                return frame.map(|f| f.code);
            }
        }
        None
    })
    .await
    .ok()
    .flatten()
}

/// The layout in docs/foxglove opens what the Host serves: every topic,
/// plotted field and service it names is advertised, and every panel it
/// configures is placed.
#[tokio::test]
async fn the_documented_layout_names_only_what_the_host_serves() {
    let layout: Value = serde_json::from_str(include_str!("../docs/foxglove/vl-layout.json"))
        .expect("the layout is JSON");
    let (_host, url) = start_host(&["--no-record"]);
    let mut ws = foxglove(&url, "foxglove.websocket.v1").await;
    let mut channels = None;
    let mut services = None;
    while channels.is_none() || services.is_none() {
        let op = next_op(&mut ws).await.expect("the opening ops");
        match op["op"].as_str() {
            Some("advertise") => channels = Some(op["channels"].clone()),
            Some("advertiseServices") => services = Some(op["services"].clone()),
            _ => {}
        }
    }
    let channels = channels.unwrap();
    let schema_of = |topic: &str| -> Option<Value> {
        let channel = channels.as_array()?.iter().find(|c| c["topic"] == topic)?;
        serde_json::from_str(channel["schema"].as_str()?).ok()
    };
    let served = |name: &str| {
        services
            .as_ref()
            .unwrap()
            .as_array()
            .unwrap()
            .iter()
            .any(|s| s["name"] == name)
    };
    let panels = layout["configById"].as_object().unwrap();
    let placed = layout["layout"].to_string();
    for (id, config) in panels {
        assert!(placed.contains(&format!("\"{id}\"")), "{id} is not placed");
        for topic in config["topics"]
            .as_object()
            .into_iter()
            .flatten()
            .map(|(t, _)| t)
        {
            assert!(schema_of(topic).is_some(), "{id}: no channel {topic}");
        }
        if let Some(image) = config["imageMode"]["imageTopic"].as_str() {
            assert!(schema_of(image).is_some(), "{id}: no channel {image}");
        }
        for path in config["paths"].as_array().into_iter().flatten() {
            let path = path["value"].as_str().unwrap();
            let (topic, field) = path.split_once('.').unwrap();
            let schema = schema_of(topic).unwrap_or_else(|| panic!("{id}: no channel {topic}"));
            assert!(
                schema["properties"].get(field).is_some(),
                "{id}: {topic} has no {field}"
            );
        }
        if let Some(service) = config["serviceName"].as_str() {
            assert!(served(service), "{id}: no service {service}");
        }
        if let Some(topic) = config["topic"].as_str() {
            assert_eq!(
                topic, "/cmd_vel",
                "{id} publishes where the Host takes Twists"
            );
        }
    }
}
