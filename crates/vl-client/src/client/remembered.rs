//! What a connection remembers across reconnections: the last hello (in
//! the role it has now), the operator's secret, and whether it waits in
//! line — so a dropped link costs no more than it must.

use vl_core::{ErrorCode, GuestMessage, HostMessage, Role};

/// What a connection remembers across reconnections.
#[derive(Default)]
pub(super) struct Remembered {
    /// The last hello the Guest said.
    pub(super) hello: Option<GuestMessage>,
    /// The operator's secret from the last welcome.
    resume: Option<String>,
    /// Whether the Guest asked for control and has not had it yet: said
    /// again after a reconnection, so a dropped link costs no more than
    /// the place.
    pub(super) in_line: bool,
}

impl Remembered {
    /// Keeps what a new connection needs from `message`: the operator's
    /// secret, and the role a grant of control or its end gave.
    pub(super) fn heard(&mut self, message: &HostMessage) {
        let (role, resume) = match message {
            HostMessage::Welcome { resume, .. } => (None, resume),
            HostMessage::Role { role, resume, .. } => (Some(*role), resume),
            _ => return,
        };
        if let Some(secret) = resume {
            self.resume = Some(secret.clone());
        }
        if role == Some(Role::Operator) {
            self.in_line = false;
        }
        if let Some(now) = role {
            self.say_role(now);
        }
    }

    /// Keeps `now` as the role a new connection says hello as.
    fn say_role(&mut self, now: Role) {
        if let Some(GuestMessage::Hello { role, .. }) = &mut self.hello {
            *role = now;
        }
    }

    /// Whether the Host's `refusal` of the hello says someone else drives
    /// (or holds the role, or waits for it first), while the Guest said
    /// hello as operator: then it watches and takes its place in line, as
    /// a person would, instead of saying the same hello again forever.
    pub(super) fn watch_and_queue(&mut self, refusal: &HostMessage) -> Option<GuestMessage> {
        let asked_to_drive = matches!(
            &self.hello,
            Some(GuestMessage::Hello {
                role: Role::Operator,
                ..
            })
        );
        let taken = matches!(
            refusal,
            HostMessage::Error {
                code: ErrorCode::OperatorTaken,
                ..
            }
        );
        if !(asked_to_drive && taken) {
            return None;
        }
        self.say_role(Role::Observer);
        self.in_line = true;
        self.hello_again()
    }

    /// The hello to say on a new connection: the last one, with the secret.
    pub(super) fn hello_again(&self) -> Option<GuestMessage> {
        match self.hello.clone()? {
            GuestMessage::Hello {
                protocol,
                role,
                token,
                user,
                password,
                session,
                ..
            } => Some(GuestMessage::Hello {
                protocol,
                role,
                token,
                resume: self.resume.clone(),
                user,
                password,
                session,
            }),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn said(role: Role) -> Remembered {
        Remembered {
            hello: Some(GuestMessage::Hello {
                protocol: 1,
                role,
                token: None,
                resume: None,
                user: Some("bob".into()),
                password: None,
                session: None,
            }),
            ..Remembered::default()
        }
    }

    #[test]
    fn asking_to_drive_a_busy_lab_becomes_watching_in_line() {
        let taken = HostMessage::error(ErrorCode::OperatorTaken, "another operator is driving");
        let mut bob = said(Role::Operator);
        let again = bob.watch_and_queue(&taken).expect("a hello to watch");
        assert!(matches!(
            again,
            GuestMessage::Hello { role: Role::Observer, ref user, .. } if user.as_deref() == Some("bob")
        ));
        assert!(bob.in_line);
        // Said once: a reconnection says hello as an observer, then asks again.
        assert!(bob.watch_and_queue(&taken).is_none());
        // Other refusals, and observers, are left alone.
        let wrong = HostMessage::error(ErrorCode::Unauthorized, "wrong password");
        assert!(said(Role::Operator).watch_and_queue(&wrong).is_none());
        assert!(said(Role::Observer).watch_and_queue(&taken).is_none());
        // Control granted: no longer in line.
        bob.heard(&HostMessage::Role {
            role: Role::Operator,
            resume: Some("s".into()),
            slot_s: None,
            ended: None,
        });
        assert!(!bob.in_line);
    }
}
