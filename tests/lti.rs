//! The lab as an LTI 1.3 tool, checked against an LMS platform written
//! from the specifications with PyJWT and cryptography (tests/lti/
//! lms.py), nothing of vl's: its launches open the lab page logged in
//! (the WebSocket hello with the page's session is welcomed as that
//! person), tampered launches are refused and log no one in, an instructor
//! runs the lab, deep linking answers what the platform verifies by the
//! tool's published key, a learner's run is graded and posted to the line
//! item over OAuth2 client credentials, and the roster lists who ran what.

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use crate::common::chromium::{self, Browser};
use crate::common::peer::Peer;
use crate::common::{self, s, scratch, start_host, vl, vl_command};

const PLATFORM: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/lti/lms.py");

/// The outside platform, spoken to a JSON line at a time.
struct Platform {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
    /// What it printed first: its issuer, client id and endpoints.
    about: Value,
}

impl Platform {
    fn start(python: &str) -> Platform {
        let mut child = Command::new(python)
            .arg(PLATFORM)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("python runs");
        let stdin = child.stdin.take().unwrap();
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        stdout.read_line(&mut line).expect("the platform starts");
        let about = serde_json::from_str(&line).expect("the platform says where it is");
        Platform {
            child,
            stdin,
            stdout,
            about,
        }
    }

    fn ask(&mut self, command: Value) -> Value {
        writeln!(self.stdin, "{command}").unwrap();
        let mut line = String::new();
        self.stdout
            .read_line(&mut line)
            .expect("the platform answers");
        let answer: Value = serde_json::from_str(&line).expect("JSON");
        assert!(answer.get("error").is_none(), "{command}: {answer}");
        answer
    }

    fn at(&self, key: &str) -> &str {
        self.about[key].as_str().unwrap()
    }
}

impl Drop for Platform {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Registers `platform` at the lab of `users`, as its administrator would.
fn register(users: &std::path::Path, platform: &Platform) {
    let out = vl(&[
        "lti",
        "add-platform",
        "--users",
        s(users),
        "--issuer",
        platform.at("issuer"),
        "--client-id",
        platform.at("client_id"),
        "--deployment-id",
        platform.at("deployment_id"),
        "--auth-url",
        platform.at("auth_url"),
        "--token-url",
        platform.at("token_url"),
        "--jwks-url",
        platform.at("jwks_url"),
    ]);
    assert!(out.status.success(), "{}", common::stderr(&out));
}

/// The outside platform, registered at a lab's accounts file in scratch
/// folder `name`; none where Python lacks PyJWT or cryptography (said why).
fn registered(name: &str) -> Option<(Platform, std::path::PathBuf)> {
    let python = common::python_with("jwt, cryptography")?;
    let platform = Platform::start(python);
    let users = scratch(name).join("users.toml");
    register(&users, &platform);
    Some((platform, users))
}

/// The session a launched page carries, if it carries one.
fn session_of(page: &str) -> Option<String> {
    let at = page.find("<meta name=\"vl-session\" content=\"")?;
    let rest = &page[at + "<meta name=\"vl-session\" content=\"".len()..];
    Some(rest[..rest.find('"')?].to_owned())
}

async fn hello_with_session(url: &str, session: &str, role: &str) -> (Peer, Value) {
    let mut peer = Peer::connect(url).await;
    peer.send(json!({"type": "hello", "protocol": 1, "role": role, "session": session}))
        .await;
    let answer = peer
        .next_of_any(&["welcome", "error"], Duration::from_secs(5))
        .await
        .expect("an answer to hello");
    (peer, answer)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_lms_launches_the_lab_and_gets_grades_from_runs() {
    let Some((mut platform, users)) = registered("lti") else {
        return;
    };
    let audit = users.with_file_name("audit.jsonl");
    common::account(&users, "root", "admin", "root-secret-1");
    let (_host, url) = start_host(&["--users", s(&users), "--audit", s(&audit), "--no-record"]);
    let tool = url.replace("ws://", "http://");
    platform.ask(json!({"cmd": "tool", "url": tool}));

    let session = learner_launch(&mut platform);
    refused_launches(&mut platform, &audit);
    let (mut learner, welcome) = hello_with_session(&url, &session, "operator").await;
    assert_eq!(welcome["type"], "welcome", "{welcome}");
    assert_eq!(welcome["user"], "learner-1@127.0.0.1");
    assert_eq!(welcome["role"], "operator");
    let (_, unknown) = hello_with_session(&url, "not-a-session", "observer").await;
    assert_eq!(unknown["type"], "error", "a made-up session: {unknown}");
    assert!(
        unknown["message"].as_str().unwrap().contains("LMS session"),
        "{unknown}"
    );

    // The course's link asks for a navigation run to 720,80: a
    // teleoperation run does not count, and nothing is posted.
    let withheld = run_of(&mut learner, None).await;
    assert_eq!(withheld["summary"]["experiment"], "teleoperation");
    not_posted(
        &mut platform,
        &audit,
        "the assignment is navigation, the run was teleoperation",
    )
    .await;
    // Launched from a second link that asks for nothing in particular (its
    // own line item), the learner's run there ends: the platform has its
    // score within 10 s, though its gradebook refused the first try.
    let other = launch_link(&mut platform, 2);
    let (mut learner, _) = switch_tab(&url, learner, &other).await;
    platform.ask(json!({"cmd": "fail_scores", "n": 1}));
    let score = graded_run(&mut platform, &mut learner).await;
    assert_eq!(score["lineitem"], 2, "graded in the link's own column");
    assert_eq!(platform.ask(json!({"cmd": "scores"}))["refused"], 1);
    assert_eq!(score["userId"], "learner-1");
    assert_eq!(score["scoreMaximum"], 100.0);
    assert_eq!(score["activityProgress"], "Completed");
    assert_eq!(score["gradingProgress"], "FullyGraded");
    let given = score["scoreGiven"].as_f64().unwrap();
    assert!((0.0..=100.0).contains(&given), "{score}");
    let comment = score["comment"].as_str().unwrap();
    assert!(
        comment.contains("goal: not reached (stopped)") && comment.contains("collisions: 0"),
        "the comment explains the grade: {comment}"
    );
    assert!(score["timestamp"].as_str().unwrap().ends_with('Z'));
    let (mut learner, welcome) = two_tabs(&mut platform, &url, learner).await;
    // Someone else's emergency stop ends the learner's run: it does not
    // count (a score posted would replace the last).
    let (mut root, _) = hello_as_root(&url).await;
    let stopped = run_of(&mut learner, Some(&mut root)).await;
    assert_eq!(stopped["summary"]["stopped_by"]["role"], "observer");
    not_posted(&mut platform, &audit, "the emergency stop of an observer").await;
    hostile_requests(&tool);

    in_a_browser(&mut platform);
    let teacher = instructor(&mut platform, &url, &tool, &welcome).await;
    deep_linking(&mut platform);
    gradebook_down(&mut platform, &url, &audit).await;
    course_roles_only(&mut platform);
    relaunches_end_only_their_own(&mut platform, &url, &session, &teacher).await;
    let status = http(&tool, "GET /status", &[AS_ROOT], "");
    let status: Value = serde_json::from_str(&status.1).expect("the status as JSON");
    let grades = &status["grades"];
    assert_eq!(
        (&grades["posted"], &grades["failed"]),
        (&json!(3), &json!(1)),
        "{status}"
    );
    assert!(
        grades["last_failure"].as_str().unwrap().contains("503"),
        "{status}"
    );
}

/// The lab's administrator, for its status.
const AS_ROOT: &str = "Authorization: Basic cm9vdDpyb290LXNlY3JldC0x";

/// Runs a short teleoperation run as `learner`; the score the platform
/// gets for it, within 10 s of its end.
async fn graded_run(platform: &mut Platform, learner: &mut Peer) -> Value {
    let before = platform.ask(json!({"cmd": "scores"}))["scores"]
        .as_array()
        .unwrap()
        .len();
    learner.start("teleoperation").await;
    for event in 1..=20 {
        learner.command(event, json!({"v": 60.0, "w": 0.0})).await;
    }
    learner.send(json!({"type": "stop"})).await;
    let done = learner.expect("done").await;
    assert_eq!(done["summary"]["reason"], "stopped");
    let ended = Instant::now();
    let score = loop {
        let scores = platform.ask(json!({"cmd": "scores"}));
        if let Some(score) = scores["scores"].as_array().and_then(|s| s.get(before)) {
            break score.clone();
        }
        assert!(
            ended.elapsed() < Duration::from_secs(10),
            "no score within 10 s: {scores}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    println!(
        "score {} of {} posted {:.2} s after the run ended: {}",
        score["scoreGiven"],
        score["scoreMaximum"],
        ended.elapsed().as_secs_f64(),
        score["comment"]
    );
    score
}

/// A learner's launch of the course's link `link`, which asks for nothing
/// in particular and has a line item of its own: the tab's session.
fn launch_link(platform: &mut Platform, link: u32) -> String {
    let launched =
        platform.ask(json!({"cmd": "launch", "role": "learner", "custom": {}, "link": link}));
    assert_eq!(launched["status"], 200, "{launched}");
    session_of(launched["body"].as_str().unwrap()).expect("the page's session")
}

/// `learner` leaves, and the tab of `session` says hello as operator:
/// its connection and welcome.
async fn switch_tab(url: &str, mut learner: Peer, session: &str) -> (Peer, Value) {
    learner.send(json!({"type": "bye"})).await;
    drop(learner);
    let (peer, welcome) = hello_with_session(url, session, "operator").await;
    assert_eq!(welcome["role"], "operator", "{welcome}");
    (peer, welcome)
}

/// One learner opens two of the course's links, each with its own line
/// item, in two tabs, and drives a run in each, the first tab first: each
/// line item gets its own run's score (not the latest launch's).
async fn two_tabs(platform: &mut Platform, url: &str, learner: Peer) -> (Peer, Value) {
    let first = launch_link(platform, 3);
    let second = launch_link(platform, 4);
    let (mut learner, _) = switch_tab(url, learner, &first).await;
    let score = graded_run(platform, &mut learner).await;
    assert_eq!(score["lineitem"], 3, "the first tab's run: {score}");
    let (mut learner, welcome) = switch_tab(url, learner, &second).await;
    let score = graded_run(platform, &mut learner).await;
    assert_eq!(score["lineitem"], 4, "the second tab's run: {score}");
    (learner, welcome)
}

/// The lab's administrator, as an observer.
async fn hello_as_root(url: &str) -> (Peer, Value) {
    let mut root = Peer::connect(url).await;
    root.send(json!({
        "type": "hello", "protocol": 1, "role": "observer", "user": "root", "password": "root-secret-1",
    }))
    .await;
    let welcome = root.expect("welcome").await;
    (root, welcome)
}

/// A short teleoperation run of `learner`, ended by their own stop or by
/// `stopper`'s emergency stop: its `done`.
async fn run_of(learner: &mut Peer, stopper: Option<&mut Peer>) -> Value {
    learner.start("teleoperation").await;
    for event in 1..=5 {
        learner.command(event, json!({"v": 60.0, "w": 0.0})).await;
    }
    match stopper {
        Some(stopper) => stopper.send(json!({"type": "emergency_stop"})).await,
        None => learner.send(json!({"type": "stop"})).await,
    }
    learner.expect("done").await
}

/// A run that does not count: the audit log says why, and the platform
/// is sent nothing for it.
async fn not_posted(platform: &mut Platform, audit: &std::path::Path, why: &str) {
    let scores = |platform: &mut Platform| {
        let scores = platform.ask(json!({"cmd": "scores"}));
        scores["scores"].as_array().unwrap().len() + scores["refused"].as_u64().unwrap() as usize
    };
    let before = scores(platform);
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let text = std::fs::read_to_string(audit).unwrap_or_default();
        let said = text
            .lines()
            .filter(|l| l.contains("\"grade_withheld\""))
            .any(|l| l.contains(why));
        if said {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "no grade_withheld for {why}: {text}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    // As long as a score takes to be posted when it is.
    tokio::time::sleep(Duration::from_secs(2)).await;
    assert_eq!(
        scores(platform),
        before,
        "a run that does not count was posted ({why})"
    );
}

/// Lab roles come from the course's roles only: a learner here who
/// teaches elsewhere is a learner here.
fn course_roles_only(platform: &mut Platform) {
    let launched = platform.ask(json!({"cmd": "launch", "role": "learner_teaching_elsewhere"}));
    assert_eq!(launched["status"], 200, "{launched}");
    let page = launched["body"].as_str().unwrap();
    assert!(
        page.contains("<meta name=\"vl-drives\" content=\"yes\">"),
        "{page}"
    );
    assert!(
        !page.contains("vl-roster"),
        "an administrator's page: {page}"
    );
}

/// One learner launching again and again ends their own oldest sessions,
/// never anyone else's.
async fn relaunches_end_only_their_own(
    platform: &mut Platform,
    url: &str,
    first: &str,
    teacher: &str,
) {
    let mut last = String::new();
    for _ in 0..12 {
        let launched = platform.ask(json!({"cmd": "launch", "role": "learner", "custom": {}}));
        last = session_of(launched["body"].as_str().unwrap()).expect("a session");
    }
    let (_, old) = hello_with_session(url, first, "observer").await;
    assert_eq!(
        old["type"], "error",
        "their first session outlived 12 launches: {old}"
    );
    let (_, new) = hello_with_session(url, &last, "observer").await;
    assert_eq!(new["type"], "welcome", "{new}");
    let (_, theirs) = hello_with_session(url, teacher, "observer").await;
    assert_eq!(
        theirs["type"], "welcome",
        "another's session ended: {theirs}"
    );
}

/// A gradebook that refuses every try: after its back-off the tool gives
/// up, and says so in the audit log (the status says it too).
async fn gradebook_down(platform: &mut Platform, url: &str, audit: &std::path::Path) {
    platform.ask(json!({"cmd": "fail_scores", "n": 100}));
    // The instructor ended the learner's turn: they come back from a link
    // asking for nothing in particular (the browser's launch asked for a
    // navigation run).
    let session = launch_link(platform, 1);
    let (mut learner, welcome) = hello_with_session(url, &session, "operator").await;
    assert_eq!(welcome["role"], "operator", "{welcome}");
    // A learner runs no one else's turn.
    learner
        .send(json!({"type": "kick", "session": welcome["session"]}))
        .await;
    learner.expect_error("unauthorized").await;
    learner.start("teleoperation").await;
    learner.command(1, json!({"v": 60.0, "w": 0.0})).await;
    learner.send(json!({"type": "stop"})).await;
    learner.expect("done").await;
    let deadline = Instant::now() + Duration::from_secs(40);
    loop {
        let text = std::fs::read_to_string(audit).unwrap_or_default();
        if let Some(line) = text.lines().find(|l| l.contains("\"grade_failed\"")) {
            assert!(line.contains("503"), "says why: {line}");
            break;
        }
        assert!(Instant::now() < deadline, "no grade_failed in 40 s: {text}");
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let tries = platform.ask(json!({"cmd": "scores"}))["refused"]
        .as_u64()
        .unwrap();
    assert_eq!(
        tries,
        1 + 5,
        "the first run's refused try, then five for this one"
    );
}

/// One HTTP/1.1 request (`line`: method and path) to the Host at `tool`:
/// its status and body.
fn http(tool: &str, line: &str, headers: &[&str], body: &str) -> (u16, String) {
    use std::io::Read;
    let port: u16 = tool
        .trim_end_matches('/')
        .rsplit(':')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    let mut request = format!("{line} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n");
    for header in headers {
        request.push_str(&format!("{header}\r\n"));
    }
    request.push_str(&format!("Content-Length: {}\r\n\r\n{body}", body.len()));
    stream.write_all(request.as_bytes()).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    let mut reply = Vec::new();
    let _ = stream.read_to_end(&mut reply);
    let reply = String::from_utf8_lossy(&reply).into_owned();
    let status = reply
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = reply
        .split_once("\r\n\r\n")
        .map(|(_, b)| b.to_owned())
        .unwrap_or_default();
    (status, body)
}

/// What a careless or hostile client sends the LTI pages: a 4xx each,
/// nobody logged in, the Host still serving.
fn hostile_requests(tool: &str) {
    let form = "Content-Type: application/x-www-form-urlencoded";
    let huge = format!("id_token={}&state=x", "A".repeat(100_000));
    let cases: [(&str, &[&str], String); 9] = [
        ("GET /lti/login", &[], String::new()),
        (
            "GET /lti/login?iss=https://stranger.example&login_hint=x&target_link_uri=http://x/lti/launch",
            &[],
            String::new(),
        ),
        ("POST /lti/launch", &[form], String::new()),
        (
            "POST /lti/launch",
            &[form],
            "id_token=a.b.c&state=made-up".into(),
        ),
        ("POST /lti/launch", &[form], huge),
        (
            "POST /lti/launch",
            &["Content-Type: text/plain"],
            "\u{0}\u{1}garbage".into(),
        ),
        (
            "POST /lti/deep-link",
            &[form],
            "session=x&title=t&experiment=navigation".into(),
        ),
        ("POST /lti/roster", &[form], "session=nobody".into()),
        ("GET /lti/roster", &[], String::new()),
    ];
    for (line, headers, body) in cases {
        let (status, page) = http(tool, line, headers, &body);
        assert!((400..500).contains(&status), "{line}: {status} {page}");
        assert!(session_of(&page).is_none(), "{line} logged someone in");
    }
    let (status, jwks) = http(tool, "GET /lti/jwks", &[], "");
    assert_eq!(status, 200);
    let jwks: Value = serde_json::from_str(&jwks).unwrap();
    assert_eq!(jwks["keys"][0]["alg"], "RS256");
}

/// A browser sent by the course's page to the lab: the page logs in with
/// the launch's session, with no password asked.
fn in_a_browser(platform: &mut Platform) {
    if !chromium::available() {
        return;
    }
    let course = platform.ask(json!({"cmd": "prepare", "role": "learner"}));
    let mut browser = Browser::open(course["course"].as_str().unwrap(), (1100, 760));
    browser.expect(
        "window.vl && vl.link === 'open' && vl.user === 'learner-1@127.0.0.1'",
        Duration::from_secs(20),
    );
    browser.expect(
        "document.getElementById('login').hidden",
        Duration::from_secs(2),
    );
    browser.expect(
        "document.getElementById('assignment').textContent.includes('goal at 720,80 mm')",
        Duration::from_secs(2),
    );
    let shot = scratch("lti-browser").join("launched.png");
    browser.screenshot(&shot);
    println!("the launched page: {}", shot.display());
    assert_eq!(browser.errors(), Vec::<String>::new());
}

/// A learner's launch: the login redirects as OIDC says, and the page
/// carries the session, framed only by the platform.
fn learner_launch(platform: &mut Platform) -> String {
    let launched = platform.ask(json!({"cmd": "launch", "role": "learner"}));
    for (check, ok) in launched["login"].as_object().unwrap() {
        assert_eq!(ok, true, "login {check}: {launched}");
    }
    assert_eq!(launched["status"], 200, "{launched}");
    let page = launched["body"].as_str().unwrap();
    assert!(page.contains("<meta name=\"vl-drives\" content=\"yes\">"));
    assert!(page.contains("the navigation experiment, goal at 720,80 mm"));
    let csp = launched["csp"].as_str().unwrap();
    let issuer = platform.at("issuer").to_owned();
    assert!(
        csp.contains(&format!("frame-ancestors 'self' {issuer}")),
        "framed by the platform only: {csp}"
    );
    session_of(page).expect("the page carries its session")
}

/// Tampered and replayed launches: 4xx, no session, an audit line each.
fn refused_launches(platform: &mut Platform, audit: &std::path::Path) {
    for (tamper, status, why) in [
        ("signature", 403, "InvalidSignature"),
        ("audience", 403, "InvalidAudience"),
        ("expired", 403, "ExpiredSignature"),
        ("deployment", 403, "deployment-unknown"),
    ] {
        let refused = platform.ask(json!({"cmd": "launch", "role": "learner", "tamper": tamper}));
        let body = refused["body"].as_str().unwrap();
        assert_eq!(refused["status"], status, "{tamper}: {refused}");
        assert!(session_of(body).is_none(), "{tamper} logged someone in");
        assert!(body.contains(why), "{tamper}: says why: {body}");
    }
    let replay = platform.ask(json!({"cmd": "launch", "role": "learner", "replay": true}));
    assert_eq!(replay["status"], 200);
    assert_eq!(replay["replayed"]["status"], 403, "{replay}");
    assert!(
        replay["replayed"]["body"]
            .as_str()
            .unwrap()
            .contains("nonce"),
        "{replay}"
    );
    assert_eq!(replay["state_again"]["status"], 400, "{replay}");
    assert!(session_of(replay["replayed"]["body"].as_str().unwrap()).is_none());
    // The audit log has a line for each refusal (written by its own task).
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let text = std::fs::read_to_string(audit).unwrap_or_default();
        let refusals = text
            .lines()
            .filter(|l| l.contains("\"lti_refused\""))
            .count();
        if refusals >= 6 {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "{refusals} refusals logged: {text}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// An instructor's launch: admin rights (ends the learner's turn) and
/// the course's roster with the learner's graded run.
async fn instructor(platform: &mut Platform, url: &str, tool: &str, learner: &Value) -> String {
    let launched = platform.ask(json!({"cmd": "launch", "role": "instructor"}));
    let page = launched["body"].as_str().unwrap();
    let session = session_of(page).expect("an instructor's page");
    let (mut teacher, welcome) = hello_with_session(url, &session, "observer").await;
    assert_eq!(welcome["user"], "teacher-1@127.0.0.1", "{welcome}");
    teacher
        .send(json!({"type": "kick", "session": learner["session"]}))
        .await;
    // A kick is an administrator's; the Host would refuse anyone else's.
    let refused = teacher.next_of("error", Duration::from_secs(2)).await;
    assert!(
        refused.is_none(),
        "the instructor may end turns: {refused:?}"
    );
    let roster = page
        .split("<meta name=\"vl-roster\" content=\"")
        .nth(1)
        .and_then(|r| r.split('"').next())
        .expect("an instructor's page links the roster");
    // No session in any address: the roster is posted to.
    assert!(!roster.contains("session"), "{roster}");
    let form = "Content-Type: application/x-www-form-urlencoded";
    let (status, out) = http(
        tool,
        &format!("POST {roster}"),
        &[form],
        &format!("session={session}"),
    );
    assert_eq!(status, 200, "{out}");
    assert!(
        out.contains("Ada Learner") && out.contains("Tom Teacher"),
        "{out}"
    );
    assert!(
        out.contains("<td>Learner</td><td>5</td>"),
        "five runs: {out}"
    );
    assert!(
        out.contains("not sent: the emergency stop of an observer"),
        "{out}"
    );
    session
}

/// Deep linking: the platform verifies the answer by the tool's JWKS.
fn deep_linking(platform: &mut Platform) {
    let linked = platform.ask(json!({"cmd": "deep_link"}));
    assert_eq!(linked["status"], 200, "{linked}");
    assert_eq!(linked["action"], linked["expected_action"]);
    let claims = &linked["claims"];
    assert_eq!(
        claims["https://purl.imsglobal.org/spec/lti/claim/message_type"],
        "LtiDeepLinkingResponse"
    );
    assert_eq!(claims["iss"], platform.at("client_id"));
    assert_eq!(
        claims["https://purl.imsglobal.org/spec/lti-dl/claim/data"],
        "opaque-data-42"
    );
    let item = &claims["https://purl.imsglobal.org/spec/lti-dl/claim/content_items"][0];
    assert_eq!(item["type"], "ltiResourceLink");
    assert_eq!(item["custom"]["experiment"], "navigation");
    assert_eq!(item["custom"]["goal"], "720,80");
    assert_eq!(item["lineItem"]["scoreMaximum"], 100.0);
    let csp = linked["csp"].as_str().unwrap();
    assert!(
        csp.contains(&format!("form-action {}", platform.at("issuer"))),
        "{csp}"
    );
    // A learner may not choose what a link opens.
    let learner = platform.ask(json!({"cmd": "deep_link", "role": "learner"}));
    assert_eq!(learner["status"], 403, "{learner}");
}

#[test]
fn vl_lti_keeps_platforms_and_prints_the_tool_s_configuration() {
    let dir = scratch("lti-cli");
    let users = dir.join("users.toml");
    let add = |issuer: &str, deployment: &str| {
        vl_command()
            .args([
                "lti",
                "add-platform",
                "--users",
                s(&users),
                "--issuer",
                issuer,
            ])
            .args(["--client-id", "c1", "--deployment-id", deployment])
            .args(["--auth-url", "https://lms.example.edu/auth"])
            .args(["--token-url", "https://lms.example.edu/token"])
            .args(["--jwks-url", "https://lms.example.edu/jwks"])
            .output()
            .unwrap()
    };
    assert!(add("https://lms.example.edu", "d1").status.success());
    assert!(add("https://lms.example.edu", "d2").status.success());
    let bad = add("not a url", "d1");
    assert!(!bad.status.success());
    assert!(
        common::stderr(&bad).contains("--issuer 'not a url'"),
        "{}",
        common::stderr(&bad)
    );
    let list = common::vl_json(&["lti", "list", "--users", s(&users), "--json"]);
    assert_eq!(list["platform"][0]["deployment_ids"], json!(["d1", "d2"]));
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let kept = dir.join("users.lti.toml");
        let mode = std::fs::metadata(&kept).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600, "the platforms are the owner's only");
    }
    tool_config(&users);
    let remove = || {
        vl(&[
            "lti",
            "remove",
            "--users",
            s(&users),
            "--issuer",
            "https://lms.example.edu",
        ])
    };
    let removed = remove();
    assert!(removed.status.success());
    let list = common::vl_json(&["lti", "list", "--users", s(&users), "--json"]);
    assert_eq!(list["platform"], json!([]));
    let gone = remove();
    assert!(common::stderr(&gone).contains("no platform 'https://lms.example.edu'"));
    // A platforms file that does not read stops the Host, naming it.
    std::fs::write(dir.join("users.lti.toml"), "[[platform]]\nissuer = 3\n").unwrap();
    let broken = vl(&["host", "--users", s(&users), "--listen", "127.0.0.1:0"]);
    assert!(!broken.status.success());
    assert!(
        common::stderr(&broken).contains("users.lti.toml"),
        "{}",
        common::stderr(&broken)
    );
}

/// `tool-config`: the URLs and key an LMS administrator enters, the key
/// made once and kept.
fn tool_config(users: &std::path::Path) {
    let json = || {
        common::vl_json(&[
            "lti",
            "tool-config",
            "--users",
            s(users),
            "--url",
            "https://lab.example.org:7400",
            "--json",
        ])
    };
    let config = json();
    assert_eq!(
        config["target_link_uri"],
        "https://lab.example.org:7400/lti/launch"
    );
    assert_eq!(
        config["oidc_initiation_url"],
        "https://lab.example.org:7400/lti/login"
    );
    assert_eq!(config["jwks_url"], "https://lab.example.org:7400/lti/jwks");
    assert_eq!(config["public_jwk"]["kty"], "RSA");
    assert!(
        config["public_key"]
            .as_str()
            .unwrap()
            .starts_with("-----BEGIN PUBLIC KEY-----")
    );
    // The key is made once and kept.
    let again = json();
    assert_eq!(again["public_jwk"], config["public_jwk"]);
    let text = vl(&[
        "lti",
        "tool-config",
        "--users",
        s(users),
        "--url",
        "https://lab.example.org",
    ]);
    let text = common::stdout(&text);
    assert!(
        text.contains("Initiate login URL") && text.contains("https://lab.example.org/lti/login"),
        "{text}"
    );
}

/// README's steps for an LMS administrator, run as written: the tool's
/// configuration, the platform registered, listed; and its `[rubric]`
/// table taken by `vl host --config` as the lab's rubric.
#[test]
fn readme_s_lms_steps_run_as_written() {
    let readme = include_str!("../README.md");
    let dir = scratch("lti-readme");
    for command in crate::readme::commands_under(readme, "In a teacher's LMS") {
        let out = vl_command()
            .args(crate::readme::vl_args(&command))
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(out.status.success(), "{command}: {}", common::stderr(&out));
        if command.starts_with("vl lti list") {
            let listed = common::stdout(&out);
            assert!(listed.contains("https://moodle.example.edu"), "{listed}");
        }
    }
    assert!(dir.join("lab-users.lti.toml").exists());
    assert!(dir.join("lab-users.lti-key.pem").exists());
    let section = readme.split("## In a teacher's LMS").nth(1).unwrap();
    let rubric = section
        .split("```toml\n")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("README shows a [rubric] table");
    std::fs::write(
        dir.join("lab.toml"),
        format!("users = \"lab-users.toml\"\nno-record = true\n{rubric}"),
    )
    .unwrap();
    let (_host, url) = common::start_vl_in(
        Some(&dir),
        &["host", "--config", "lab.toml", "--listen", "127.0.0.1:0"],
        "vl host listening on ",
    );
    assert!(url.starts_with("ws://"), "{url}");
    std::fs::write(
        dir.join("bad.toml"),
        "users = \"lab-users.toml\"\n[rubric]\ngoal = -5\n",
    )
    .unwrap();
    let bad = vl_command()
        .args(["host", "--config", "bad.toml", "--listen", "127.0.0.1:0"])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(
        common::stderr(&bad).contains("'goal' is -5"),
        "{}",
        common::stderr(&bad)
    );
}

/// Through a gateway: the launch at its address lets the learner in, a
/// cell runs their run, and the gateway posts its grade.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gateway_launches_and_grades_its_cells_runs() {
    let Some((mut platform, users)) = registered("lti-gateway") else {
        return;
    };
    let keys = common::cells::Keys::new("lti");
    let a = keys.issue("--cell", "a");
    let (_gateway, url, zenoh) = common::cells::start_gateway_with(&keys, &["--users", s(&users)]);
    let _cell = common::cells::start_cell(&zenoh, "a", &a);
    let tool = url.replace("ws://", "http://");
    platform.ask(json!({"cmd": "tool", "url": tool}));
    learner_launch(&mut platform);
    // From a link asking for nothing in particular: a teleoperation run
    // counts, in that link's column.
    let session = launch_link(&mut platform, 2);
    // The cell joins within seconds: until then the gateway has none to give.
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut learner = loop {
        let (peer, welcome) = hello_with_session(&url, &session, "operator").await;
        if welcome["type"] == "welcome" {
            assert_eq!(welcome["user"], "learner-1@127.0.0.1", "{welcome}");
            assert_eq!(welcome["role"], "operator", "{welcome}");
            break peer;
        }
        assert!(
            Instant::now() < deadline,
            "no cell took the learner: {welcome}"
        );
        tokio::time::sleep(Duration::from_millis(300)).await;
    };
    let score = graded_run(&mut platform, &mut learner).await;
    assert_eq!(score["userId"], "learner-1");
    assert_eq!(score["lineitem"], 2, "{score}");
    let comment = score["comment"].as_str().unwrap();
    assert!(comment.starts_with("A run, stopped."), "{comment}");
}
