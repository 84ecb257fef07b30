//! A Guest's link to its cell, as the front keeps it: opened with the
//! operator's hello, carrying the Guest's messages up and the cell's down,
//! and let go when the Guest leaves.

use std::time::Instant;

use tokio_tungstenite::tungstenite::Message;
use tracing::{info, warn};
use vl_core::{CellName, ErrorCode, HostMessage, Role, Wire};
use vl_host::hub::ToConnection;

use super::{Event, Front, Link, RETIRE, WELCOME, grades};
use crate::keys;
use crate::link::{LinkDown, LinkUp};

impl Front {
    /// Links Guest `id` to cell `name` and passes its hello as operator on.
    pub(super) async fn link(
        &mut self,
        id: u64,
        name: CellName,
        protocol: u32,
        resume: Option<String>,
        promoted: bool,
    ) {
        self.links += 1;
        let number = self.links;
        let key = format!("{}-{number}", self.since);
        let opened = async {
            // Listening first: the cell answers at once.
            let down = self
                .session
                .declare_subscriber(keys::down(&name, &key))
                .await?;
            let token = self
                .session
                .liveliness()
                .declare_token(keys::link(&name, &key))
                .await?;
            let up = self
                .session
                .declare_publisher(keys::up(&name, &key))
                .await?;
            Ok::<_, zenoh::Error>((down, token, up))
        };
        let (down, token, up) = match opened.await {
            Ok(opened) => opened,
            Err(e) => {
                warn!("the gateway cannot link a Guest to cell {name}: {e}");
                return self.refuse(
                    id,
                    ErrorCode::NoCell,
                    format!("cell {name} cannot be reached"),
                );
            }
        };
        let events = self.events.clone();
        let listening = tokio::spawn(async move {
            // Only the cell may speak here (the network's access control),
            // and even it is read within bounds, its mistakes said once a
            // second.
            let hush = vl_host::Hush::default();
            while let Ok(sample) = down.recv_async().await {
                if !crate::within(&sample, keys::MOST_TEXT, &hush) {
                    continue;
                }
                match serde_json::from_slice(&sample.payload().to_bytes()) {
                    Ok(said) => {
                        if events.send(Event::Down(id, number, said)).await.is_err() {
                            return;
                        }
                    }
                    Err(e) if hush.speak() => warn!("a cell said what is no link message: {e}"),
                    Err(_) => {}
                }
            }
        });
        if let Some(cell) = self.cells.get_mut(&name) {
            cell.claimed = Some(Instant::now());
        }
        let Some(guest) = self.guests.get_mut(&id) else {
            return;
        };
        info!(connection = id, cell = %name, "linked");
        guest.link = Some(Link {
            number,
            cell: name,
            up,
            _token: token,
            listening,
            welcomed: false,
            promoted,
            driving: false,
        });
        let hello = LinkUp::Hello {
            admitted: guest.admitted.clone(),
            protocol,
            role: Role::Operator,
            resume,
        };
        self.up(id, &hello).await;
    }

    /// Passes `said` up Guest `id`'s link.
    pub(super) async fn up(&mut self, id: u64, said: &LinkUp) {
        let Some(link) = self.guests.get(&id).and_then(|g| g.link.as_ref()) else {
            return;
        };
        if let Err(e) = link.up.put(said.encode()).await {
            warn!(connection = id, "a link to cell {} failed: {e}", link.cell);
        }
    }

    /// Tells Guest `id`'s cell it left (`meant` to, or its link dropped).
    /// The link's token is held a moment longer: Zenoh may carry a token's
    /// end ahead of data, and a cell that saw the token go first would
    /// take a leaving operator for a dropped one and hold the run.
    pub(super) async fn unlink(&mut self, id: u64, meant: bool) {
        self.up(id, &LinkUp::Leave { meant }).await;
        let link = self.guests.get_mut(&id).and_then(|g| g.link.take());
        if let Some(link) = link {
            self.retiring.push((Instant::now() + RETIRE, link));
        }
    }

    /// What a linked Guest's cell says to it.
    pub(super) fn down(&mut self, id: u64, number: u64, said: LinkDown) {
        let Some(guest) = self.guests.get_mut(&id) else {
            return;
        };
        // A link already let go may still have said something.
        let Some(link) = guest.link.as_mut().filter(|l| l.number == number) else {
            return;
        };
        match said {
            LinkDown::RunEnded { summary } => {
                grades::ended(&self.lab_events, id, &guest.admitted, *summary);
            }
            LinkDown::Send { text } => {
                link.follow_role(&text);
                // Read only what decides where the Guest stands: a refusal
                // of its hello, and the welcome of one already watching,
                // told as the role it grants.
                let deciding = !link.welcomed || (link.promoted && text.starts_with(WELCOME));
                match deciding.then(|| HostMessage::decode(&text).ok()).flatten() {
                    // The cell would not have them: they are where they were.
                    Some(HostMessage::Error { code, message }) if !link.welcomed => {
                        guest.link = None;
                        self.tell(id, &HostMessage::error(code, message));
                    }
                    Some(HostMessage::Welcome { role, resume, .. }) if link.promoted => {
                        let granted = HostMessage::Role {
                            role,
                            resume,
                            slot_s: None,
                            ended: None,
                        };
                        self.tell(id, &granted);
                    }
                    _ => self.send(id, ToConnection::Send(Message::text(text))),
                }
            }
            LinkDown::Welcomed => {
                link.welcomed = true;
                let name = link.cell.clone();
                self.unwatch(id);
                if let Some(guest) = self.guests.get_mut(&id) {
                    guest.role = Some(Role::Operator);
                    guest.watching = Some(name.clone());
                }
                if let Some(cell) = self.cells.get(&name) {
                    let streams = cell.mirror.streams();
                    self.send(id, ToConnection::Watch(streams));
                }
            }
            LinkDown::End { code, why } => {
                guest.link = None;
                self.send(id, ToConnection::End(code, why));
            }
        }
    }
}
