//! A raw protocol client: JSON over a WebSocket, as the protocol page
//! describes it and as a careless or hostile client could send it.

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream, connect_async};

/// A Guest's control period: how long after a feedback its next command goes.
const CONTROL_PERIOD: Duration = Duration::from_millis(10);

pub(crate) type Socket = WebSocketStream<MaybeTlsStream<TcpStream>>;

pub(crate) struct Peer {
    pub ws: Socket,
    /// Camera frames seen while waiting for text messages.
    pub frames: usize,
}

impl Peer {
    pub(crate) async fn connect(url: &str) -> Peer {
        Peer::try_connect(url).await.expect("connects")
    }

    pub(crate) async fn try_connect(
        url: &str,
    ) -> Result<Peer, tokio_tungstenite::tungstenite::Error> {
        let (ws, _) = connect_async(url).await?;
        Ok(Peer { ws, frames: 0 })
    }

    /// A peer connecting from `local` (127.0.0.x on the loopback standing
    /// for another machine's address).
    pub(crate) async fn connect_from(url: &str, local: std::net::IpAddr) -> Peer {
        let authority = url.trim_start_matches("ws://").trim_end_matches('/');
        let target: std::net::SocketAddr = authority.parse().expect("ws://address:port");
        let socket = tokio::net::TcpSocket::new_v4().unwrap();
        socket.bind((local, 0).into()).expect("a loopback address");
        let stream = socket.connect(target).await.expect("connects");
        let stream = MaybeTlsStream::Plain(stream);
        let (ws, _) = tokio_tungstenite::client_async(url, stream)
            .await
            .expect("a WebSocket");
        Peer { ws, frames: 0 }
    }

    pub(crate) async fn send(&mut self, message: Value) {
        self.send_text(&message.to_string()).await;
    }

    pub(crate) async fn send_text(&mut self, text: &str) {
        self.ws.send(Message::text(text)).await.expect("sends");
    }

    /// The next text message of `kind`, skipping others; `None` when none
    /// comes within `wait` or the connection ends.
    pub(crate) async fn next_of(&mut self, kind: &str, wait: Duration) -> Option<Value> {
        self.next_of_any(&[kind], wait).await
    }

    /// The next text message of one of `kinds`, skipping others; `None`
    /// when none comes within `wait` or the connection ends.
    pub(crate) async fn next_of_any(&mut self, kinds: &[&str], wait: Duration) -> Option<Value> {
        tokio::time::timeout(wait, async {
            loop {
                let v = self.next_text().await?;
                if kinds.iter().any(|k| v["type"] == *k) {
                    return Some(v);
                }
            }
        })
        .await
        .ok()
        .flatten()
    }

    /// The next text message of any kind within 5 s.
    pub(crate) async fn next_any(&mut self) -> Option<Value> {
        tokio::time::timeout(Duration::from_secs(5), self.next_text())
            .await
            .ok()
            .flatten()
    }

    /// The next text message but a ping; `None` when the connection ends.
    /// It answers the Host's pings, as a live Guest does (a frozen one
    /// does not read).
    async fn next_text(&mut self) -> Option<Value> {
        loop {
            match self.ws.next().await {
                Some(Ok(Message::Text(t))) => {
                    let v: Value = serde_json::from_str(&t).expect("the Host sends JSON");
                    if v["type"] != "ping" {
                        return Some(v);
                    }
                    let pong = json!({"type": "pong", "t": v["t"]}).to_string();
                    self.ws.send(Message::text(pong)).await.ok()?;
                }
                Some(Ok(Message::Binary(_))) => self.frames += 1,
                Some(Ok(_)) => {}
                _ => return None,
            }
        }
    }

    /// The next text message of `kind`; panics after 5 s.
    pub(crate) async fn expect(&mut self, kind: &str) -> Value {
        self.next_of(kind, Duration::from_secs(5))
            .await
            .unwrap_or_else(|| panic!("no {kind} within 5 s"))
    }

    /// The next `error`, which must carry `code`.
    pub(crate) async fn expect_error(&mut self, code: &str) -> Value {
        let e = self.expect("error").await;
        assert_eq!(e["code"], code, "{e}");
        assert!(!e["message"].as_str().unwrap_or("").is_empty());
        e
    }

    /// The first feedback the Host produced at least `ms` after `since`.
    pub(crate) async fn feedback_after(&mut self, since: &Value, ms: f64) -> Value {
        let t0 = since["t_ms"].as_f64().expect("feedback has t_ms");
        loop {
            let f = self.expect("feedback").await;
            if f["t_ms"].as_f64().unwrap() >= t0 + ms {
                return f;
            }
        }
    }

    /// Says hello as `role`; the welcome, or a panic saying what came
    /// instead.
    pub(crate) async fn hello(&mut self, role: &str) -> Value {
        self.send(json!({"type": "hello", "protocol": 1, "role": role}))
            .await;
        let answer = self
            .next_of_any(&["welcome", "error"], Duration::from_secs(5))
            .await
            .unwrap_or_else(|| {
                panic!("no answer to hello as {role} within 5 s, or the socket ended")
            });
        assert_eq!(answer["type"], "welcome", "hello as {role}: {answer}");
        answer
    }

    /// Drives a teleoperation run turning on the spot for `seconds` (the
    /// camera's frames change), while `watch` looks at the folder every
    /// command; its `done`.
    pub(crate) async fn turn_for(&mut self, seconds: f64, mut watch: impl FnMut()) -> Value {
        self.start("teleoperation").await;
        let began = std::time::Instant::now();
        let mut event = 0;
        while began.elapsed().as_secs_f64() < seconds {
            event += 1;
            self.command(event, json!({"v": 0.0, "w": 1.0})).await;
            watch();
        }
        self.send(json!({"type": "stop"})).await;
        self.expect("done").await
    }

    /// Mounts `experiment`, defines nothing but the defaults and starts a
    /// run once the lab is ready (after a run the robot first drives back
    /// to its start).
    pub(crate) async fn start(&mut self, experiment: &str) {
        self.send(json!({"type": "mount", "experiment": experiment}))
            .await;
        self.expect("mounted").await;
        // No path: the operator's commands drive, with nothing for the
        // lab's twin to try first.
        self.send(json!({"type": "define"})).await;
        self.expect("defined").await;
        self.start_run().await;
    }

    /// Starts a run of what is mounted, once the lab is ready.
    pub(crate) async fn start_run(&mut self) {
        for _ in 0..30 {
            self.send(json!({"type": "start"})).await;
            let answer = self
                .next_of_any(&["started", "error"], Duration::from_secs(5))
                .await
                .expect("an answer to start");
            if answer["type"] == "started" {
                return;
            }
            let getting_ready = answer["message"]
                .as_str()
                .is_some_and(|m| m.contains("getting ready"));
            assert!(getting_ready, "start refused: {answer}");
            self.ready().await;
        }
        panic!("the lab never got ready");
    }

    /// Waits until the Host says the lab is ready.
    pub(crate) async fn ready(&mut self) {
        loop {
            let status = self
                .next_of("status", Duration::from_secs(60))
                .await
                .expect("the lab ready within a minute");
            if status["lab"] == "ready" {
                return;
            }
        }
    }

    /// Sends command `event` (`drive` holds its speeds), waits for its
    /// feedback and then a control period, as a Guest's loop does.
    pub(crate) async fn command(&mut self, event: u64, drive: Value) -> Value {
        let mut message = drive;
        message["type"] = json!("command");
        message["event"] = json!(event);
        self.send(message).await;
        loop {
            let f = self.expect("feedback").await;
            if f["event"].as_u64() >= Some(event) {
                // A Guest's next command comes a control period later.
                tokio::time::sleep(CONTROL_PERIOD).await;
                return f;
            }
        }
    }
}

/// Whether every number in `v` is finite (and none is null where a number was).
pub(crate) fn finite(v: &Value) -> bool {
    match v {
        Value::Number(n) => n.as_f64().is_some_and(f64::is_finite),
        Value::Object(o) => o.values().all(finite),
        Value::Array(a) => a.iter().all(finite),
        _ => true,
    }
}

/// Feedback whose pose and wheels are finite numbers.
pub(crate) fn assert_finite_feedback(f: &Value) {
    for key in ["pose", "wheels"] {
        assert!(f[key].is_object() && finite(&f[key]), "{key} in {f}");
    }
}

/// Resident and peak memory of process `pid`, MB.
pub(crate) fn memory_mb(pid: u32) -> (f64, f64) {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|kb| kb.parse::<f64>().ok())
            .map_or(0.0, |kb| kb / 1024.0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}
