//! Grades for an LMS from runs at cells: the gateway follows the role a
//! linked Guest holds at its cell, and a run that ends while that Guest
//! drives is graded as the person the gateway let in (`Lti::run_ended`).

use vl_core::{HostMessage, Role, Summary, Wire};

use super::{Link, WELCOME};
use crate::accounts::gate::Admitted;
use crate::server::HostConfig;

const ROLE: &str = r#"{"type":"role""#;
const DONE: &str = r#"{"type":"done""#;

/// What `text`, told down `link`, says of its Guest's driving: whether it
/// drives now, and the summary of a run it drove that ended.
pub(super) fn follow(link: &mut Link, text: &str) -> Option<Summary> {
    let telling = [WELCOME, ROLE, DONE].iter().any(|p| text.starts_with(p));
    match telling.then(|| HostMessage::decode(text).ok()).flatten()? {
        HostMessage::Welcome { role, .. } | HostMessage::Role { role, .. } => {
            link.driving = role == Role::Operator;
            None
        }
        HostMessage::Done { summary } => link.driving.then_some(*summary),
        _ => None,
    }
}

/// Grades the run that `admitted` drove at its cell, if an LMS sent them.
pub(super) fn grade(config: &HostConfig, admitted: &Admitted, summary: &Summary) {
    if let (Some(lti), Some(name)) = (&config.lti, admitted.identity.name()) {
        lti.run_ended(None, name, summary);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_messages_followed_are_told_by_their_start() {
        let role = HostMessage::Role {
            role: Role::Operator,
            resume: None,
            slot_s: None,
            ended: None,
        };
        assert!(role.encode().starts_with(ROLE));
        assert!(!HostMessage::Bye.encode().starts_with(DONE));
    }
}
