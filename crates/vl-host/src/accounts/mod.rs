//! Who may use the lab: accounts kept as Argon2id hashes (`users`), the
//! door every hello passes — passwords, tokens, failures and their limits
//! (`gate`) — and the audit log of who did what (`audit`).

pub(crate) mod audit;
pub(crate) mod gate;
pub(crate) mod users;
