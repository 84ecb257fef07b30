//! The gateway's hub: the one owner of who is where. It gives each
//! operator a free cell (or a place in the one line for all of them),
//! each watcher the cell it asked for (or the busiest), passes a linked
//! Guest's messages to its cell and back, and tells every watcher of a
//! cell what that cell tells its observers, from the one copy it sent.

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::sync::mpsc;
use tokio_tungstenite::tungstenite::Message;
use tracing::{debug, info, warn};
use vl_core::{CellInfo, CellName, ErrorCode, GuestMessage, HostMessage, Role, Wire};

mod grades;
mod line;
mod links;
mod status;

use super::asked_cell;
use super::event::Event;
use super::mirror::Mirror;
use crate::link::LinkUp;
use vl_host::AuditEntry;
use vl_host::HostConfig;
use vl_host::LabEvents;
use vl_host::Users;
use vl_host::hub::{Status, ToConnection, ToHub};
use vl_host::{ACCOUNT_ENDED, Admitted};

/// How long a gone Guest's link token outlives its `leave`.
const RETIRE: Duration = Duration::from_secs(1);

/// How a welcome's text begins (serde writes the tag first).
const WELCOME: &str = r#"{"type":"welcome""#;

/// How long a cell given to an operator counts as taken before its info
/// says so.
const CLAIM: Duration = Duration::from_secs(3);

/// A cell the gateway sees.
struct Cell {
    info: Option<CellInfo>,
    mirror: Mirror,
    /// What a late observer is told, newest asked.
    catch_up: Option<Vec<HostMessage>>,
    /// Guests watching through the gateway (not linked to the cell).
    watchers: BTreeSet<u64>,
    /// Watchers waiting for the first catch-up.
    waiting: Vec<u64>,
    /// When an operator was last sent here.
    claimed: Option<Instant>,
}

impl Cell {
    fn is_free(&self) -> bool {
        self.info.as_ref().is_some_and(CellInfo::is_free)
            && self.claimed.is_none_or(|at| at.elapsed() > CLAIM)
    }
}

/// A Guest of the gateway linked to a cell.
struct Link {
    number: u64,
    cell: CellName,
    up: zenoh::pubsub::Publisher<'static>,
    _token: zenoh::liveliness::LivelinessToken,
    listening: tokio::task::JoinHandle<()>,
    welcomed: bool,
    /// Given to a Guest already watching (from the line, or asking
    /// control): its cell's welcome is told as the role it grants.
    promoted: bool,
    /// Whether the cell has the Guest drive now (one place per account).
    driving: bool,
}

impl Drop for Link {
    fn drop(&mut self) {
        self.listening.abort();
    }
}

struct Guest {
    out: mpsc::Sender<ToConnection>,
    asked: Option<Result<CellName, String>>,
    admitted: Admitted,
    role: Option<Role>,
    watching: Option<CellName>,
    link: Option<Link>,
}

pub(super) struct Front {
    config: Arc<HostConfig>,
    session: zenoh::Session,
    events: mpsc::Sender<Event>,
    /// The gateway's own lab events: its cells' runs its Guests drove.
    lab_events: LabEvents,
    /// This gateway's start, naming its links apart from an earlier one's.
    since: u64,
    links: u64,
    guests: HashMap<u64, Guest>,
    cells: BTreeMap<CellName, Cell>,
    /// Operators waiting for any cell, first first.
    line: VecDeque<u64>,
    /// Links of Guests gone, held until then (see `unlink`).
    retiring: Vec<(Instant, Link)>,
}

impl Front {
    pub(super) fn new(
        config: Arc<HostConfig>,
        session: zenoh::Session,
        events: mpsc::Sender<Event>,
        lab_events: LabEvents,
        since: u64,
    ) -> Front {
        Front {
            config,
            session,
            events,
            lab_events,
            since,
            links: 0,
            guests: HashMap::new(),
            cells: BTreeMap::new(),
            line: VecDeque::new(),
            retiring: Vec::new(),
        }
    }

    pub(super) async fn run(
        mut self,
        mut inbox: mpsc::Receiver<ToHub>,
        mut events: mpsc::Receiver<Event>,
    ) {
        let mut line_check = tokio::time::interval(Duration::from_millis(500));
        loop {
            tokio::select! {
                event = events.recv() => match event {
                    Some(event @ (Event::Told(..) | Event::Info(_))) => self.event(event).await,
                    Some(event) => {
                        self.event(event).await;
                        self.want_frames();
                    }
                    None => return,
                },
                message = inbox.recv() => match message {
                    Some(message) => {
                        self.guest_said(message).await;
                        self.want_frames();
                    }
                    None => return,
                },
                _ = line_check.tick() => {
                    self.retiring.retain(|(until, _)| *until > Instant::now());
                }
            }
            self.serve_line().await;
        }
    }

    async fn guest_said(&mut self, message: ToHub) {
        match message {
            ToHub::Join(id, out, path) => {
                let guest = Guest {
                    out,
                    asked: asked_cell(path.as_deref()),
                    admitted: Admitted::anyone(),
                    role: None,
                    watching: None,
                    link: None,
                };
                self.guests.insert(id, guest);
            }
            ToHub::Hello {
                id,
                admitted,
                protocol,
                role,
                resume,
            } => {
                if let Some(guest) = self.guests.get_mut(&id) {
                    guest.admitted = admitted;
                }
                self.hello(id, protocol, role, resume).await;
            }
            ToHub::Message(id, message) => self.message(id, message).await,
            ToHub::Leave(id, meant) => self.leave(id, meant).await,
            ToHub::Status(answer) => {
                let _ = answer.send(Status::Gateway(self.status()));
            }
            ToHub::CatchUp(answer) => drop(answer),
            ToHub::Accounts(users) => self.accounts_changed(&users).await,
        }
    }

    /// The accounts file changed: whoever it no longer lets in as they
    /// came in is let go at once, off their cell (which ends their run as
    /// one left) and out of the line.
    async fn accounts_changed(&mut self, users: &Users) {
        let ended: Vec<(u64, Option<String>)> = self
            .guests
            .iter()
            .filter(|(_, g)| g.admitted.ended_by(users))
            .map(|(id, g)| (*id, g.admitted.identity.name().map(str::to_owned)))
            .collect();
        for (id, user) in ended {
            let entry = AuditEntry::new("account_ended").connection(id);
            self.config.audit.record(entry.user(user.as_deref()));
            self.unlink(id, true).await;
            let end = ToConnection::End(ErrorCode::Unauthorized, ACCOUNT_ENDED.into());
            self.send(id, end);
            self.forget(id);
        }
    }

    fn send(&mut self, id: u64, message: ToConnection) {
        let Some(guest) = self.guests.get(&id) else {
            return;
        };
        if guest.out.try_send(message).is_err() {
            // Its outbox is full: it is let go, as at a Host (its
            // connection says why; its link's token goes with it).
            debug!(connection = id, "a Guest of the gateway fell behind");
            self.forget(id);
        }
    }

    /// Lets go of Guest `id`: off its cell, out of the line.
    fn forget(&mut self, id: u64) {
        self.unwatch(id);
        self.line.retain(|&waiting| waiting != id);
        self.guests.remove(&id);
    }

    /// Takes frames from the cells someone is on, and from no other.
    fn want_frames(&mut self) {
        let watched: BTreeSet<&CellName> = self
            .guests
            .values()
            .filter_map(|g| g.watching.as_ref())
            .collect();
        for (name, cell) in &mut self.cells {
            cell.mirror
                .want_frames(&self.session, watched.contains(name));
        }
    }

    fn tell(&mut self, id: u64, message: &HostMessage) {
        self.send(id, ToConnection::Send(Message::text(message.encode())));
    }

    fn refuse(&mut self, id: u64, code: ErrorCode, why: impl Into<String>) {
        let why = why.into();
        self.config.audit.record(
            AuditEntry::new("refused")
                .connection(id)
                .detail(format!("{code}: {why}")),
        );
        self.tell(id, &HostMessage::error(code, why));
    }

    async fn hello(&mut self, id: u64, protocol: u32, role: Role, resume: Option<String>) {
        let Some(guest) = self.guests.get(&id) else {
            return;
        };
        if guest.link.is_some() {
            // Linked: its cell answers every hello.
            let admitted = guest.admitted.clone();
            let up = LinkUp::Hello {
                admitted,
                protocol,
                role,
                resume,
            };
            return self.up(id, &up).await;
        }
        let asked = match guest.asked.clone() {
            Some(Ok(name)) if !self.cells.contains_key(&name) => {
                return self.refuse(
                    id,
                    ErrorCode::NoCell,
                    format!("no cell named {name} is up here"),
                );
            }
            Some(Err(name)) => {
                return self.refuse(id, ErrorCode::NoCell, format!("{name:?} is no cell's name"));
            }
            Some(Ok(name)) => Some(name),
            None => None,
        };
        let watching = guest.role.is_some();
        match role {
            Role::Operator => {
                // The line comes first: naming a cell passes no one waiting,
                // nor the one a cell was just given to.
                let cell = match asked {
                    Some(name) => {
                        let free = self.cells.get(&name).is_some_and(Cell::is_free);
                        if !(free && self.line.is_empty()) {
                            return self.refuse(
                                id,
                                ErrorCode::OperatorTaken,
                                format!("cell {name} is in use or promised: say hello as an observer and ask for control; the first cell free is yours"),
                            );
                        }
                        Some(name)
                    }
                    None => self.free_cell(),
                };
                match cell {
                    Some(cell) => self.link(id, cell, protocol, resume, watching).await,
                    None if self.cells.is_empty() => {
                        self.refuse(id, ErrorCode::NoCell, "no cell is up at this gateway yet")
                    }
                    None => self.refuse(
                        id,
                        ErrorCode::OperatorTaken,
                        "every cell is in use: say hello as an observer and ask for control; the first cell free is yours",
                    ),
                }
            }
            Role::Observer if watching => {
                self.refuse(id, ErrorCode::NotAllowedNow, "already said hello")
            }
            Role::Observer => match asked.or_else(|| self.busiest_cell()) {
                Some(cell) => self.watch(id, cell),
                None => self.refuse(id, ErrorCode::NoCell, "no cell is up at this gateway yet"),
            },
        }
    }

    /// A cell an operator may have at once, first by name.
    fn free_cell(&self) -> Option<CellName> {
        self.cells
            .iter()
            .find(|(_, cell)| cell.is_free())
            .map(|(name, _)| name.clone())
    }

    /// The cell most worth watching: one with a run, then with an
    /// operator, then with the most watchers.
    fn busiest_cell(&self) -> Option<CellName> {
        self.cells
            .iter()
            .max_by_key(|(name, cell)| {
                let info = cell.info.as_ref();
                (
                    info.is_some_and(|i| i.run.is_some()),
                    info.is_some_and(|i| i.operator.is_some()),
                    cell.watchers.len(),
                    std::cmp::Reverse((*name).clone()),
                )
            })
            .map(|(name, _)| name.clone())
    }

    /// Makes `id` a watcher of `name`, welcomed from its catch-up.
    fn watch(&mut self, id: u64, name: CellName) {
        let Some(cell) = self.cells.get_mut(&name) else {
            return;
        };
        cell.watchers.insert(id);
        if let Some(guest) = self.guests.get_mut(&id) {
            guest.watching = Some(name.clone());
            guest.role = Some(Role::Observer);
        }
        match cell.catch_up.clone() {
            Some(told) => self.welcome(id, &name, told),
            None => cell.waiting.push(id),
        }
    }

    /// Welcomes watcher `id` of `name` with what a late observer is told.
    fn welcome(&mut self, id: u64, name: &CellName, told: Vec<HostMessage>) {
        let user = self
            .guests
            .get(&id)
            .and_then(|g| g.admitted.identity.name().map(str::to_owned));
        info!(connection = id, cell = %name, "welcomed to watch");
        self.config.audit.record(
            AuditEntry::new("welcome")
                .connection(id)
                .user(user.as_deref())
                .detail(format!("observer of cell {name}")),
        );
        // Welcomed before the welcome is sent, as at a Host: a Guest that
        // answers its welcome at once is not told to say hello first.
        if let Some(cell) = self.cells.get(name) {
            let streams = cell.mirror.streams();
            self.send(id, ToConnection::Watch(streams));
        }
        for message in told {
            let message = match message {
                HostMessage::Welcome {
                    experiments, scene, ..
                } => HostMessage::Welcome {
                    session: id,
                    role: Role::Observer,
                    experiments,
                    resume: None,
                    user: user.clone(),
                    scene,
                },
                other => other,
            };
            self.tell(id, &message);
        }
    }

    async fn message(&mut self, id: u64, message: GuestMessage) {
        let Some(guest) = self.guests.get(&id) else {
            return;
        };
        if guest.link.is_some() {
            return self.up(id, &LinkUp::Message { message }).await;
        }
        match message {
            GuestMessage::Queue => self.join_line(id),
            GuestMessage::LeaveQueue => self.leave_line(id),
            other => self.refuse(
                id,
                ErrorCode::NotAllowedNow,
                format!(
                    "watching through the gateway, {} is not yours to send: ask for control",
                    other.kind()
                ),
            ),
        }
    }

    async fn leave(&mut self, id: u64, meant: bool) {
        self.unlink(id, meant).await;
        self.forget(id);
    }

    /// Takes `id` from the watchers of the cell it watched.
    fn unwatch(&mut self, id: u64) {
        let watching = self.guests.get_mut(&id).and_then(|g| g.watching.take());
        if let Some(cell) = watching.and_then(|name| self.cells.get_mut(&name)) {
            cell.watchers.remove(&id);
            cell.waiting.retain(|&w| w != id);
        }
    }

    async fn event(&mut self, event: Event) {
        match event {
            Event::Up(name) => {
                if !self.cells.contains_key(&name) {
                    info!(cell = %name, "a cell is up");
                    let mirror = Mirror::start(&self.session, &name, self.events.clone());
                    let cell = Cell {
                        info: None,
                        mirror,
                        catch_up: None,
                        watchers: BTreeSet::new(),
                        waiting: Vec::new(),
                        claimed: None,
                    };
                    self.cells.insert(name, cell);
                }
            }
            Event::Gone(name) => self.cell_lost(&name),
            Event::Info(info) => {
                if let Some(cell) = self.cells.get_mut(&info.name) {
                    if info.operator.is_some() {
                        cell.claimed = None;
                    }
                    cell.info = Some(info);
                }
            }
            Event::Told(name, text) => {
                let Some(cell) = self.cells.get(&name) else {
                    return;
                };
                let watchers: Vec<u64> = cell.watchers.iter().copied().collect();
                let message = Message::Text(text);
                for id in watchers {
                    self.send(id, ToConnection::Send(message.clone()));
                }
            }
            Event::CaughtUp(name, told) => {
                let Some(cell) = self.cells.get_mut(&name) else {
                    return;
                };
                cell.catch_up = Some(told.clone());
                let waiting = std::mem::take(&mut cell.waiting);
                for id in waiting {
                    self.welcome(id, &name, told.clone());
                }
            }
            Event::Down(id, number, said) => self.down(id, number, said),
        }
    }

    /// A cell that went: its Guests are told and let go, to come back to
    /// another.
    fn cell_lost(&mut self, name: &CellName) {
        let Some(cell) = self.cells.remove(name) else {
            return;
        };
        warn!(cell = %name, "a cell is lost");
        self.config
            .audit
            .record(AuditEntry::new("cell_lost").detail(format!("cell {name}")));
        let linked = self
            .guests
            .iter()
            .filter_map(|(id, g)| g.link.as_ref().filter(|l| &l.cell == name).map(|_| *id));
        let on_it: BTreeSet<u64> = linked
            .chain(cell.watchers.iter().copied())
            .chain(cell.waiting)
            .collect();
        for id in on_it {
            let why = format!(
                "cell {name} stopped answering: its run, if any, is over; connect again for another cell"
            );
            self.send(id, ToConnection::End(ErrorCode::CellLost, why));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The front tells a welcome by how its text begins.
    #[test]
    fn a_welcome_begins_as_the_front_looks_for() {
        let welcome = HostMessage::Welcome {
            session: 1,
            role: Role::Operator,
            experiments: Vec::new(),
            resume: Some("s".into()),
            user: None,
            scene: None,
        };
        assert!(welcome.encode().starts_with(WELCOME));
        assert!(!HostMessage::Bye.encode().starts_with(WELCOME));
    }
}
