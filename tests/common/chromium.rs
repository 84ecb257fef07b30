//! Headless Chromium (Debian's `chromium`, which `.ci/run` installs),
//! driven over the DevTools protocol as a person would use the page: real
//! mouse clicks and key presses, screenshots, and every console error
//! kept. Without Chromium the tests that need it fail in CI
//! (`VL_REQUIRE_EXTERNAL=1`) and elsewhere say so and skip.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine;
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::stream::MaybeTlsStream;
use tokio_tungstenite::tungstenite::{self, Message, WebSocket};

const CHROMIUM: &str = "/usr/bin/chromium";

pub(crate) struct Browser {
    child: Child,
    ws: WebSocket<MaybeTlsStream<TcpStream>>,
    next_id: u64,
    /// Console errors, uncaught exceptions and failed loads, in words.
    errors: Vec<String>,
    _profile: PathBuf,
}

/// Chromium, if this machine has it.
pub(crate) fn available() -> bool {
    let here = std::path::Path::new(CHROMIUM).exists();
    if !here {
        super::missing(CHROMIUM, ".ci/run installs Debian's chromium");
    }
    here
}

impl Browser {
    /// Opens `url` in a new headless Chromium of `width` × `height` px.
    pub(crate) fn open(url: &str, size: (u32, u32)) -> Browser {
        Browser::open_with(url, size, &[])
    }

    /// [`Browser::open`], with Chromium's `flags` besides.
    pub(crate) fn open_with(url: &str, (width, height): (u32, u32), flags: &[&str]) -> Browser {
        // Each Chromium its own profile: two may not share one.
        static OPENED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = OPENED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let profile = super::scratch(&format!("chromium-profile-{n}"));
        let mut child = Command::new(CHROMIUM)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-extensions",
                "--mute-audio",
                // A page in the background would be throttled.
                "--disable-background-timer-throttling",
                "--disable-renderer-backgrounding",
                "--remote-debugging-port=0",
                &format!("--window-size={width},{height}"),
                &format!("--user-data-dir={}", profile.display()),
            ])
            .args(flags)
            .arg("about:blank")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("chromium starts");
        let stderr = child.stderr.take().expect("piped stderr");
        let mut lines = BufReader::new(stderr).lines();
        let port = loop {
            let line = lines
                .next()
                .expect("chromium says where DevTools listen")
                .expect("chromium's stderr reads");
            if let Some(rest) = line.split("DevTools listening on ws://127.0.0.1:").nth(1) {
                break rest.split('/').next().unwrap().parse::<u16>().unwrap();
            }
        };
        // Chromium's later complaints (no D-Bus here) are not read.
        std::thread::spawn(move || for _ in lines {});
        let targets = http_get(port, "/json/list");
        let targets: Value = serde_json::from_str(&targets).expect("DevTools lists targets");
        let page = targets
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["type"] == "page")
            .expect("a page target");
        let (ws, _) = tungstenite::connect(page["webSocketDebuggerUrl"].as_str().unwrap())
            .expect("DevTools WebSocket connects");
        if let MaybeTlsStream::Plain(stream) = ws.get_ref() {
            stream
                .set_read_timeout(Some(Duration::from_millis(100)))
                .unwrap();
        }
        let mut browser = Browser {
            child,
            ws,
            next_id: 1,
            errors: Vec::new(),
            _profile: profile,
        };
        for domain in ["Runtime.enable", "Log.enable", "Page.enable"] {
            browser.call(domain, json!({}));
        }
        browser.call("Page.navigate", json!({"url": url}));
        browser
    }

    /// Calls `method` and waits for its result, keeping the events that
    /// come meanwhile.
    pub(crate) fn call(&mut self, method: &str, params: Value) -> Value {
        let id = self.next_id;
        self.next_id += 1;
        let request = json!({"id": id, "method": method, "params": params});
        self.ws
            .send(Message::text(request.to_string()))
            .expect("DevTools takes a call");
        let by = Instant::now() + Duration::from_secs(30);
        loop {
            assert!(Instant::now() < by, "no answer to {method} within 30 s");
            let Some(message) = self.read() else {
                continue;
            };
            if message["id"] == id {
                if let Some(error) = message.get("error") {
                    panic!("{method} failed: {error}");
                }
                return message["result"].clone();
            }
        }
    }

    /// The next message from DevTools, events noted; none on a timeout.
    fn read(&mut self) -> Option<Value> {
        match self.ws.read() {
            Ok(Message::Text(text)) => {
                let message: Value = serde_json::from_str(text.as_str()).unwrap();
                self.note(&message);
                Some(message)
            }
            Ok(_) => None,
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                None
            }
            Err(e) => panic!("DevTools connection failed: {e}"),
        }
    }

    fn note(&mut self, event: &Value) {
        let params = &event["params"];
        match event["method"].as_str() {
            Some("Runtime.consoleAPICalled") if params["type"] == "error" => {
                self.errors
                    .push(format!("console.error: {}", params["args"]));
            }
            Some("Runtime.exceptionThrown") => {
                self.errors
                    .push(format!("exception: {}", params["exceptionDetails"]));
            }
            Some("Log.entryAdded") if params["entry"]["level"] == "error" => {
                self.errors
                    .push(format!("log: {}", params["entry"]["text"]));
            }
            _ => {}
        }
    }

    /// Console errors, exceptions and failed loads so far.
    pub(crate) fn errors(&mut self) -> Vec<String> {
        while self.read().is_some() {}
        self.errors.clone()
    }

    /// The value of the page's `expression` (awaited when a promise).
    pub(crate) fn eval(&mut self, expression: &str) -> Value {
        let result = self.call(
            "Runtime.evaluate",
            json!({"expression": expression, "returnByValue": true, "awaitPromise": true}),
        );
        if let Some(exception) = result.get("exceptionDetails") {
            panic!("{expression} threw: {exception}");
        }
        result["result"]["value"].clone()
    }

    /// Waits up to `wait` for `expression` to be true; whether it became so.
    pub(crate) fn wait_for(&mut self, expression: &str, wait: Duration) -> bool {
        let by = Instant::now() + wait;
        while Instant::now() < by {
            // Before the page has loaded, its names are not there yet.
            let guarded = format!(
                "(() => {{ try {{ return !!({expression}); }} catch {{ return false; }} }})()"
            );
            if self.eval(&guarded) == json!(true) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        false
    }

    /// Waits for `expression`, or fails saying what the page showed.
    pub(crate) fn expect(&mut self, expression: &str, wait: Duration) {
        if !self.wait_for(expression, wait) {
            let shown = self.eval("document.querySelector('aside').innerText");
            let state = self.eval(
                "JSON.stringify({role: vl.role, link: vl.link, state: vl.state, error: vl.error, sent: vl.sent})",
            );
            panic!(
                "{expression} did not become true within {wait:?}\npage: {shown}\nstate: {state}"
            );
        }
    }

    /// A left click at (x, y) CSS px of the viewport.
    pub(crate) fn click_at(&mut self, x: f64, y: f64) {
        for kind in ["mouseMoved", "mousePressed", "mouseReleased"] {
            self.call(
                "Input.dispatchMouseEvent",
                json!({"type": kind, "x": x, "y": y, "button": "left", "buttons": 1, "clickCount": 1}),
            );
        }
    }

    /// A click in the middle of the element `selector` matches.
    pub(crate) fn click(&mut self, selector: &str) {
        let at = self.eval(&format!(
            "(() => {{ const e = document.querySelector({selector:?}); if (!e || e.disabled || e.offsetParent === null) return null; const r = e.getBoundingClientRect(); return [r.x + r.width / 2, r.y + r.height / 2]; }})()"
        ));
        let at = at
            .as_array()
            .unwrap_or_else(|| panic!("{selector} is not on the page, or is disabled"));
        self.click_at(at[0].as_f64().unwrap(), at[1].as_f64().unwrap());
    }

    /// Presses (`down`) or lets go of the key with DOM `code`, e.g. `ArrowUp`.
    pub(crate) fn key(&mut self, code: &str, key_code: u32, down: bool) {
        self.call(
            "Input.dispatchKeyEvent",
            json!({"type": if down { "rawKeyDown" } else { "keyUp" }, "code": code, "key": code,
                   "windowsVirtualKeyCode": key_code, "nativeVirtualKeyCode": key_code}),
        );
    }

    /// Types `text` into the focused element.
    pub(crate) fn type_text(&mut self, text: &str) {
        self.call("Input.insertText", json!({"text": text}));
    }

    /// The page laid out for a window `width` × `height` px from now on.
    pub(crate) fn resize(&mut self, width: u32, height: u32) {
        self.call(
            "Emulation.setDeviceMetricsOverride",
            json!({"width": width, "height": height, "deviceScaleFactor": 1, "mobile": false}),
        );
    }

    /// The page as shown, saved to `path`.
    pub(crate) fn screenshot(&mut self, path: &std::path::Path) -> image::RgbaImage {
        let shot = self.call("Page.captureScreenshot", json!({"format": "png"}));
        let png = base64::engine::general_purpose::STANDARD
            .decode(shot["data"].as_str().unwrap())
            .unwrap();
        std::fs::write(path, &png).unwrap();
        image::load_from_memory(&png).unwrap().to_rgba8()
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The body of a plain HTTP GET of `path` on 127.0.0.1:`port`.
pub(crate) fn http_get(port: u16, path: &str) -> String {
    let mut stream = TcpStream::connect(("127.0.0.1", port)).expect("connects");
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    // DevTools may keep the connection open: what came within 2 s is all.
    stream
        .set_read_timeout(Some(Duration::from_secs(2)))
        .unwrap();
    let mut reply = String::new();
    let _ = stream.read_to_string(&mut reply);
    reply
        .split_once("\r\n\r\n")
        .map(|(_, body)| body.to_owned())
        .unwrap_or_default()
}
