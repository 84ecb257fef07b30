//! The labs designed by their own nets: the checked-in nets are what the
//! pipeline makes from the charts, they are sound by `vl petri` and by a
//! naive check written here, an altered chart or access design changes what
//! a Host allows,
//! and a Host driven with random actions over its socket stays in step
//! with its net.

use crate::common;

use std::collections::{HashMap, HashSet, VecDeque};
use std::path::{Path, PathBuf};
use std::time::Duration;

use common::peer::Peer;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use serde_json::{Value, json};
use vl_petri::{Net, from_pnml};

const LABS: [&str; 2] = ["navigation", "teleoperation"];

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn controlled(lab: &str) -> Net {
    let path = repo()
        .join("crates/vl-core/nets")
        .join(lab)
        .join("controlled.pnml");
    from_pnml(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn uncontrolled(lab: &str) -> Net {
    let path = repo()
        .join("crates/vl-core/nets")
        .join(lab)
        .join("uncontrolled.pnml");
    from_pnml(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn the_checked_in_nets_are_what_the_pipeline_makes() {
    let out = repo().join("crates/vl-core/nets");
    let run = common::vl(&["lab", "nets", "--check", "--out", common::s(&out)]);
    let text = common::stdout(&run);
    assert!(run.status.success(), "{text}{}", common::stderr(&run));
    for lab in LABS {
        assert!(text.contains(&format!("{lab}: up to date")), "{text}");
    }
}

// ---- a naive check, independent of vl-petri's exploration and analysis ----

fn enabled(net: &Net, m: &[u32], t: usize) -> bool {
    let tr = &net.transitions[t];
    tr.pre.iter().all(|a| m[a.place.0] >= a.weight)
        && tr.inhibit.iter().all(|a| m[a.place.0] < a.weight)
}

fn fire(net: &Net, m: &[u32], t: usize) -> Vec<u32> {
    let mut next = m.to_vec();
    for a in &net.transitions[t].pre {
        next[a.place.0] -= a.weight;
    }
    for a in &net.transitions[t].post {
        next[a.place.0] += a.weight;
    }
    next
}

/// Each reachable marking's successors: (transition, marking).
type Edges = Vec<Vec<(usize, usize)>>;

/// Every reachable marking, and each one's successors.
fn reachable(net: &Net) -> (Vec<Vec<u32>>, Edges) {
    let start: Vec<u32> = net.places.iter().map(|p| p.initial).collect();
    let mut index = HashMap::from([(start.clone(), 0)]);
    let mut markings = vec![start];
    let mut edges = Vec::new();
    let mut queue = VecDeque::from([0]);
    while let Some(s) = queue.pop_front() {
        let m = markings[s].clone();
        let mut out = Vec::new();
        for t in (0..net.transitions.len()).filter(|&t| enabled(net, &m, t)) {
            let next = fire(net, &m, t);
            let n = *index.entry(next.clone()).or_insert_with(|| {
                markings.push(next);
                queue.push_back(markings.len() - 1);
                markings.len() - 1
            });
            out.push((t, n));
        }
        edges.resize(s + 1, Vec::new());
        edges[s] = out;
        assert!(markings.len() < 100_000, "a lab's net is small");
    }
    edges.resize(markings.len(), Vec::new());
    (markings, edges)
}

/// The markings from which `goal` can be reached (backwards search).
fn reaching(edges: &[Vec<(usize, usize)>], goal: &dyn Fn(usize) -> bool) -> HashSet<usize> {
    let mut back: Vec<Vec<usize>> = vec![Vec::new(); edges.len()];
    for (s, out) in edges.iter().enumerate() {
        for &(_, n) in out {
            back[n].push(s);
        }
    }
    let mut seen: HashSet<usize> = (0..edges.len()).filter(|&s| goal(s)).collect();
    let mut queue: VecDeque<usize> = seen.iter().copied().collect();
    while let Some(s) = queue.pop_front() {
        for &p in &back[s] {
            if seen.insert(p) {
                queue.push_back(p);
            }
        }
    }
    seen
}

#[test]
fn the_controlled_nets_are_bounded_safe_live_reversible_and_deadlock_free() {
    for lab in LABS {
        // By `vl petri analyze` on the checked-in file…
        let file = repo()
            .join("crates/vl-core/nets")
            .join(lab)
            .join("controlled.pnml");
        let a = common::vl_json(&["petri", "analyze", common::s(&file), "--json"]);
        for property in ["bounded", "safe", "live", "reversible"] {
            assert_eq!(a[property], true, "{lab}: {property}: {a}");
        }
        assert_eq!(a["deadlock"], false, "{lab}: {a}");
        // …and by the naive check.
        let net = controlled(lab);
        let (markings, edges) = reachable(&net);
        assert!(markings.iter().flatten().all(|&n| n <= 1), "{lab}: safe");
        assert!(edges.iter().all(|e| !e.is_empty()), "{lab}: deadlock-free");
        let home = reaching(&edges, &|s| s == 0);
        assert_eq!(home.len(), markings.len(), "{lab}: reversible");
        for t in 0..net.transitions.len() {
            let fires = reaching(&edges, &|s| edges[s].iter().any(|&(u, _)| u == t));
            assert_eq!(
                fires.len(),
                markings.len(),
                "{lab}: {} is not live",
                net.transitions[t].id
            );
        }
    }
}

/// A marking where `place` is marked and a transition carrying `event` is
/// enabled: the bad interleaving the rule `if place then not event` forbids.
fn reaches(net: &Net, place: &str, event: &str) -> bool {
    let p = net
        .place(place)
        .unwrap_or_else(|| panic!("{place} in {}", net.id))
        .0;
    let (markings, _) = reachable(net);
    markings.iter().any(|m| {
        m[p] > 0
            && (0..net.transitions.len())
                .any(|t| net.transitions[t].label.as_deref() == Some(event) && enabled(net, m, t))
    })
}

#[test]
fn without_controllers_runs_start_too_early_and_definitions_change_mid_run() {
    for lab in LABS {
        let (free, held) = (uncontrolled(lab), controlled(lab));
        for (place, event) in [
            ("mount.idle", "start"),
            ("execute.running", "define"),
            ("execute.running", "mount"),
        ] {
            assert!(reaches(&free, place, event), "{lab}: {event} at {place}");
            assert!(!reaches(&held, place, event), "{lab}: {event} at {place}");
        }
        let report = std::fs::read_to_string(
            repo()
                .join("crates/vl-core/nets")
                .join(lab)
                .join("report.md"),
        )
        .unwrap();
        assert!(report.contains("`start` → `define`"), "{lab}: {report}");
        assert!(!report.contains("still broken"), "{lab}: {report}");
    }
    assert!(reaches(
        &uncontrolled("navigation"),
        "cspace.building",
        "define"
    ));
    assert!(!reaches(
        &controlled("navigation"),
        "cspace.building",
        "define"
    ));
}

// ---- the running Host and its net ----

/// A client that keeps a copy of the Host's nets, follows every `state`
/// the Host sends, and checks it against its own.
struct Mirror {
    nets: HashMap<String, Net>,
    markings: HashMap<String, Vec<u32>>,
    /// The lab whose net answers: the mounted one, or the first.
    lab: String,
    states: usize,
    /// Whether the lab is ready for a run, as the Host last said in a
    /// `status` (none heard on this connection yet: unknown). Between runs
    /// the robot drives back to its start, and a start then is refused
    /// whatever the net allows.
    ready: Option<bool>,
}

fn initial(net: &Net) -> Vec<u32> {
    net.places.iter().map(|p| p.initial).collect()
}

impl Mirror {
    fn new(nets: &HashMap<String, Net>) -> Mirror {
        Mirror {
            markings: nets.iter().map(|(l, n)| (l.clone(), initial(n))).collect(),
            nets: nets.clone(),
            lab: LABS[0].into(),
            states: 0,
            ready: None,
        }
    }

    /// Follows what the Host says: a `state`, or a `status` (the lab's
    /// readiness); anything else is not the mirror's.
    fn hear(&mut self, v: &Value) {
        match v["type"].as_str() {
            Some("state") => self.follow(v),
            Some("status") => self.ready = Some(v["lab"] == "ready"),
            _ => {}
        }
    }

    fn net(&self) -> &Net {
        &self.nets[&self.lab]
    }

    fn marking(&self) -> &[u32] {
        &self.markings[&self.lab]
    }

    fn marked(&self) -> Vec<String> {
        let net = self.net();
        (0..net.places.len())
            .filter(|&p| self.marking()[p] > 0)
            .map(|p| net.places[p].id.clone())
            .collect()
    }

    fn allows(&self, event: &str) -> bool {
        let net = self.net();
        (0..net.transitions.len()).any(|t| {
            net.transitions[t].label.as_deref() == Some(event) && enabled(net, self.marking(), t)
        })
    }

    /// Follows a `state`: each fired transition must be enabled in its
    /// lab's net when it fires, and the marking and enabled events must
    /// then be the Host's. A state with nothing fired (a welcome's) is a
    /// snapshot: taken as it is.
    fn follow(&mut self, state: &Value) {
        self.states += 1;
        let fired = state["fired"].as_array().cloned().unwrap_or_default();
        for f in &fired {
            let lab = f["lab"].as_str().unwrap();
            let net = &self.nets[lab];
            let id = f["transition"].as_str().unwrap();
            let t = net
                .transition(id)
                .unwrap_or_else(|| panic!("{id} is in the {lab} net"))
                .0;
            let m = &self.markings[lab];
            assert!(
                enabled(net, m, t),
                "the Host fired {id}, not enabled at {m:?}"
            );
            let next = fire(net, m, t);
            self.markings.insert(lab.to_owned(), next);
        }
        self.lab = state["lab"].as_str().unwrap_or(LABS[0]).to_owned();
        let told: Vec<String> = serde_json::from_value(state["marking"].clone()).unwrap();
        if fired.is_empty() {
            for (lab, net) in &self.nets {
                self.markings.insert(lab.clone(), initial(net));
            }
            let m = self
                .net()
                .places
                .iter()
                .map(|p| u32::from(told.contains(&p.id)))
                .collect();
            self.markings.insert(self.lab.clone(), m);
        }
        assert_eq!(
            self.marked(),
            told,
            "the Host's marking is the net's: {state}"
        );
        let net = self.net();
        let mut events: Vec<String> = (0..net.transitions.len())
            .filter(|&t| enabled(net, self.marking(), t))
            .filter_map(|t| net.transitions[t].label.clone())
            .collect();
        events.sort();
        events.dedup();
        let told: Vec<String> = serde_json::from_value(state["enabled"].clone()).unwrap();
        assert_eq!(events, told, "{state}");
    }
}

#[derive(Debug, Clone)]
enum Act {
    Mount(&'static str),
    Define,
    Start,
    Stop,
    Command,
    EmergencyStop,
    /// Say bye and come back as a new operator.
    Leave,
    /// Drop the link and come back within the grace with the resume secret.
    Drop,
}

fn act() -> impl Strategy<Value = Act> {
    prop_oneof![
        2 => Just(Act::Mount("navigation")),
        2 => Just(Act::Mount("teleoperation")),
        3 => Just(Act::Define),
        3 => Just(Act::Start),
        2 => Just(Act::Stop),
        3 => Just(Act::Command),
        1 => Just(Act::EmergencyStop),
        1 => Just(Act::Leave),
        1 => Just(Act::Drop),
    ]
}

/// The event an action fires, when it is one the net decides.
fn event(act: &Act) -> Option<&'static str> {
    match act {
        Act::Mount(_) => Some("mount"),
        Act::Define => Some("define"),
        Act::Start => Some("start"),
        Act::Stop => Some("stop"),
        Act::Command => Some("command"),
        _ => None,
    }
}

struct Operator {
    peer: Peer,
    resume: String,
    event: u64,
}

/// Says hello as operator (with `resume`, the secret of one whose link
/// dropped), trying again while the Host has not yet seen the old link go.
async fn operator(url: &str, mirror: &mut Mirror, resume: Option<&str>) -> Operator {
    let mut hello = json!({"type": "hello", "protocol": 1, "role": "operator"});
    if let Some(secret) = resume {
        hello["resume"] = json!(secret);
    }
    let (mut peer, welcome) = 'hello: {
        for _ in 0..50 {
            let mut peer = Peer::connect(url).await;
            peer.send(hello.clone()).await;
            loop {
                let v = peer.next_any().await.expect("the Host answers hello");
                match v["type"].as_str().unwrap() {
                    "welcome" => break 'hello (peer, v),
                    "error" if v["code"] == "operator_taken" => break,
                    "error" => panic!("{v}"),
                    _ => {}
                }
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        panic!("the operator role never came free");
    };
    let state = peer.expect("state").await;
    mirror.follow(&state);
    // What this connection was told of the lab's readiness comes after.
    mirror.ready = None;
    Operator {
        peer,
        resume: welcome["resume"].as_str().unwrap_or_default().to_owned(),
        event: 0,
    }
}

/// Reads until the Host has answered `act`, following every `state` on the
/// way; returns whether it was refused as not allowed now.
async fn answer(op: &mut Operator, mirror: &mut Mirror, act: &Act, allowed: bool) -> bool {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
    // A command is answered only when refused; the marker after it ends it.
    let mut refused = false;
    loop {
        let v = tokio::time::timeout_at(deadline, op.peer.next_any())
            .await
            .unwrap_or_else(|_| panic!("no answer to {act:?} (allowed: {allowed})"))
            .expect("the Host stays up");
        match v["type"].as_str().unwrap() {
            "state" => {
                mirror.follow(&v);
                let fired = v["fired"].as_array().unwrap();
                let mine = event(act).is_some_and(|e| {
                    fired.iter().any(|f| {
                        let net = &mirror.nets[f["lab"].as_str().unwrap()];
                        let t = net.transition(f["transition"].as_str().unwrap()).unwrap();
                        net.transitions[t.0].label.as_deref() == Some(e)
                    })
                });
                if mine {
                    return false;
                }
            }
            // The marker sent after a command: the command went through.
            "error" if v["message"] == "already said hello" => {
                assert!(
                    refused || allowed || mirror.allows("command"),
                    "a command was executed though not enabled"
                );
                return refused;
            }
            "status" => mirror.hear(&v),
            "error"
                if v["code"] == "not_allowed_now"
                    && matches!(act, Act::Start)
                    && v["message"].as_str().unwrap().contains("getting ready") =>
            {
                assert_ne!(mirror.ready, Some(true), "refused though ready: {v}");
                return true;
            }
            "error" if v["code"] == "not_allowed_now" => {
                let e = event(act).unwrap_or_else(|| panic!("{act:?} refused: {v}"));
                assert!(!mirror.allows(e), "{e} refused though enabled: {v}");
                let text = v["message"].as_str().unwrap();
                assert!(text.contains(&format!("`{e}`")), "names the event: {text}");
                assert!(
                    mirror.marked().iter().all(|p| text.contains(p.as_str())),
                    "names the marking: {text}"
                );
                refused = true;
                if !matches!(act, Act::Command) {
                    return true;
                }
            }
            "error" if v["code"] == "stale_command" => refused = true,
            "error" => panic!("{act:?}: {v}"),
            _ => {}
        }
    }
}

async fn play(url: &str, nets: &HashMap<String, Net>, acts: &[Act]) {
    let mut mirror = Mirror::new(nets);
    let mut op = operator(url, &mut mirror, None).await;
    for act in acts {
        let allowed = event(act).is_none_or(|e| mirror.allows(e));
        match act {
            Act::Mount(lab) => {
                op.peer
                    .send(json!({"type": "mount", "experiment": lab}))
                    .await
            }
            Act::Define => op.peer.send(json!({"type": "define"})).await,
            Act::Start => op.peer.send(json!({"type": "start"})).await,
            Act::Stop => op.peer.send(json!({"type": "stop"})).await,
            Act::Command => {
                op.event += 1;
                let c = json!({"type": "command", "event": op.event, "left": 30, "right": 30});
                op.peer.send(c).await;
                // A command that goes through is not answered: a second hello,
                // answered in turn after it, marks that it was.
                op.peer
                    .send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
                    .await;
            }
            Act::EmergencyStop => {
                op.peer.send(json!({"type": "emergency_stop"})).await;
                // A run in progress ends (its `finish` comes as a state).
                if mirror.allows("stop") {
                    loop {
                        let v = op.peer.next_any().await.expect("the Host stays up");
                        mirror.hear(&v);
                        if v["type"] == "state" && !mirror.allows("command") {
                            break;
                        }
                    }
                }
                continue;
            }
            Act::Leave => {
                let left = mirror.lab.clone();
                let was_mounted = mirror.marking() != initial(mirror.net());
                leave(op).await;
                op = operator(url, &mut mirror, None).await;
                // Leaving released the lab: its net is back where it began,
                // or — what was mounted mounted again for the next operator —
                // mounted afresh: nothing defined, no run.
                if was_mounted {
                    assert_eq!(mirror.lab, left, "the same lab mounted again");
                    let marked = mirror.marked();
                    for place in ["mount.mounted", "define.default", "execute.ready"] {
                        assert!(marked.iter().any(|p| p == place), "{place}: {marked:?}");
                    }
                } else {
                    assert_eq!(mirror.marking(), initial(mirror.net()), "released");
                }
                continue;
            }
            Act::Drop => {
                let secret = op.resume.clone();
                drop(op);
                op = operator(url, &mut mirror, Some(&secret)).await;
                // Given back as it stood, or with the run ended meanwhile:
                // a marking of the net either way.
                let (markings, _) = reachable(mirror.net());
                assert!(
                    markings.iter().any(|m| m == mirror.marking()),
                    "{:?}",
                    mirror.marked()
                );
                continue;
            }
        }
        // An accepted action's transition was checked to be enabled where
        // the Host fired it, in the order the Host told (a run's end may
        // come in between sending and the answer).
        let refused = answer(&mut op, &mut mirror, act, allowed).await;
        if matches!(act, Act::Start) && !refused {
            op.event = 0;
        }
    }
    leave(op).await;
    assert!(mirror.states > 0);
}

/// Says bye and reads until the Host closes: a socket closed with unread
/// data is reset, and the bye with it.
async fn leave(mut op: Operator) {
    op.peer.send(json!({"type": "bye"})).await;
    while op.peer.next_any().await.is_some() {}
}

/// Random sequences of actions, from one operator over the socket: every
/// accepted action was enabled in the net, every refused one was not, and
/// after every firing the Host's marking is the net's.
#[test]
fn random_actions_over_the_socket_keep_the_host_and_its_net_in_step() {
    let (_host, url) = common::start_host(&["--camera", "none", "--grace", "5"]);
    let nets: HashMap<String, Net> = LABS
        .iter()
        .map(|l| (l.to_string(), controlled(l)))
        .collect();
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let mut runner = TestRunner::new(Config {
        cases: 64,
        failure_persistence: None,
        // A failed case leaves its operator's role held for the grace, so
        // shrinking would only report that; the first failure is the one.
        max_shrink_iters: 0,
        ..Config::default()
    });
    runner
        .run(&prop::collection::vec(act(), 1..60), |acts| {
            runtime.block_on(play(&url, &nets, &acts));
            Ok(())
        })
        .unwrap();
}

/// Changing a chart and running `vl lab nets` again changes what a Host
/// allows, with no Rust touched: here a definition, once given, may no
/// longer be changed.
#[test]
fn an_altered_chart_changes_the_running_supervisor() {
    let dir = common::scratch("lab-nets-altered");
    let charts = dir.join("charts");
    copy_designs(&charts);
    let chart = charts.join("common/define.scxml");
    let text = std::fs::read_to_string(&chart).unwrap();
    let altered = text.replace(
        r#"<state id="given">
    <transition event="define" target="given"/>"#,
        r#"<state id="given">"#,
    );
    assert_ne!(altered, text, "the chart changed");
    std::fs::write(&chart, altered).unwrap();
    let out = dir.join("nets");
    design_nets(&charts, &out);

    let runtime = tokio::runtime::Runtime::new().unwrap();
    let redefine = |extra: &[&str]| {
        let args = [
            &["--camera", "none", "--experiments", "teleoperation"],
            extra,
        ]
        .concat();
        let (_host, url) = common::start_host(&args);
        runtime.block_on(async {
            let mut op = Peer::connect(&url).await;
            op.hello("operator").await;
            op.send(json!({"type": "mount", "experiment": "teleoperation"}))
                .await;
            op.expect("mounted").await;
            op.send(json!({"type": "define"})).await;
            op.expect("defined").await;
            op.send(json!({"type": "define", "max_speed_mm_s": 100.0}))
                .await;
            loop {
                let v = op.next_any().await.expect("the Host stays up");
                match v["type"].as_str().unwrap() {
                    "defined" => return None,
                    "error" => return Some(v["message"].as_str().unwrap().to_owned()),
                    _ => {}
                }
            }
        })
    };
    assert_eq!(redefine(&[]), None, "the shipped nets allow redefining");
    let refused = redefine(&["--nets", common::s(&out)]).expect("the altered net refuses");
    assert!(
        refused.starts_with(
            "cannot define the experiment now: no `define` transition of the teleoperation net"
        ),
        "{refused}"
    );
    assert!(refused.contains("define.given"), "{refused}");
}

/// The access design runs in the Host beside the lab's net: a rule added
/// to it ("no one joins the line during a run") changes who the Host lets
/// into line, and the report shows the interleaving it forbids.
#[test]
fn an_altered_access_design_changes_who_the_host_lets_in_line() {
    let dir = common::scratch("lab-nets-access");
    let charts = dir.join("charts");
    copy_designs(&charts);
    let design = charts.join("access/lab.toml");
    let mut text = std::fs::read_to_string(&design).unwrap();
    text.push_str(
        "\n[[controller]]\nwhy = \"no one joins the line during a run\"\n\
         rule = \"if execute.running then not ask\"\n",
    );
    std::fs::write(&design, text).unwrap();
    let out = dir.join("nets");
    let run = design_nets(&charts, &out);
    let said = common::stdout(&run);
    assert!(
        said.contains("access: at most one operator: without controllers ask → ask → grant → grant; holds with them"),
        "{said}"
    );
    assert!(
        said.contains("access: no one joins the line during a run: without controllers"),
        "{said}"
    );

    let runtime = tokio::runtime::Runtime::new().unwrap();
    // Whether an observer may join the line while the operator's run goes.
    let queue_during_a_run = |extra: &[&str]| {
        let args = [&["--camera", "none", "--experiments", "navigation"], extra].concat();
        let (_host, url) = common::start_host(&args);
        runtime.block_on(async {
            let mut op = Peer::connect(&url).await;
            op.hello("operator").await;
            let mut watcher = Peer::connect(&url).await;
            watcher.hello("observer").await;
            op.send(json!({"type": "mount", "experiment": "navigation"}))
                .await;
            op.expect("mounted").await;
            op.send(
                json!({"type": "define", "goal": {"x_mm": 680, "y_mm": 470, "tolerance_mm": 15}}),
            )
            .await;
            op.expect("defined").await;
            op.send(json!({"type": "start"})).await;
            op.expect("started").await;
            watcher.send(json!({"type": "queue"})).await;
            let answer = loop {
                let v = watcher.next_any().await.expect("the Host stays up");
                match v["type"].as_str().unwrap() {
                    "queue" => break Ok(v["position"].clone()),
                    "error" => break Err(v["message"].as_str().unwrap().to_owned()),
                    _ => {}
                }
            };
            // Once the run has stopped, the line is open again.
            op.send(json!({"type": "stop"})).await;
            op.expect("done").await;
            if answer.is_err() {
                watcher.send(json!({"type": "queue"})).await;
                assert_eq!(watcher.expect("queue").await["position"], 1);
            }
            answer
        })
    };
    assert_eq!(queue_during_a_run(&[]), Ok(json!(1)), "the shipped design");
    let refused = queue_during_a_run(&["--nets", common::s(&out)]).unwrap_err();
    assert!(
        refused.starts_with("the access net does not let someone watching ask now"),
        "{refused}"
    );
    assert!(refused.contains("execute.running"), "{refused}");
}

/// `vl lab nets` from the charts in `charts` into `out`, which succeeds.
fn design_nets(charts: &Path, out: &Path) -> std::process::Output {
    let run = common::vl(&[
        "lab",
        "nets",
        "--charts",
        common::s(charts),
        "--out",
        common::s(out),
    ]);
    assert!(run.status.success(), "{}", common::stderr(&run));
    run
}

/// The shipped designs, as `vl lab nets --charts` takes them: the shared
/// charts and access design, and the experiment folders beside them.
fn copy_designs(charts: &Path) {
    let nets = repo().join("crates/vl-core/nets");
    for shared in ["common", "access"] {
        copy_dir(&nets.join(shared), &charts.join(shared));
    }
    for lab in LABS {
        copy_dir(
            &repo().join("assets/experiments").join(lab),
            &charts.join(lab),
        );
    }
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target: PathBuf = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

#[test]
fn a_folder_of_nets_that_cannot_run_is_refused_at_start() {
    let dir = common::scratch("lab-nets-missing");
    let run = common::vl(&["host", "--nets", common::s(&dir), "--camera", "none"]);
    assert_eq!(run.status.code(), Some(2));
    let err = common::stderr(&run);
    assert!(err.contains("--nets: navigation: cannot read"), "{err}");
}

/// No lab's rules may forbid a stop: `vl lab nets` refuses a design whose
/// controller would, naming the rule (the Host's stop and emergency stop
/// do not ask the net in any case).
#[test]
fn a_design_that_forbids_a_stop_is_refused() {
    let dir = common::scratch("lab-nets-no-stop");
    let charts = dir.join("charts");
    copy_designs(&charts);
    let lab = charts.join("teleoperation/experiment.toml");
    let mut text = std::fs::read_to_string(&lab).unwrap();
    text.push_str(
        "\n[[controller]]\nwhy = \"careless\"\nrule = \"if execute.running then not stop\"\n",
    );
    std::fs::write(&lab, text).unwrap();
    let run = common::vl(&[
        "lab",
        "nets",
        "--charts",
        common::s(&charts),
        "--out",
        common::s(&dir.join("nets")),
    ]);
    assert!(!run.status.success());
    let said = common::stderr(&run);
    assert!(
        said.contains("if execute.running then not execute.")
            && said.contains("_stop' is uncontrollable, so nothing may disable it"),
        "{said}"
    );
}
