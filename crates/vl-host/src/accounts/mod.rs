//! Who may use the lab: accounts kept as Argon2id hashes (`users`), the
//! door every hello passes — passwords, tokens, failures and their limits
//! (`gate`) — and the audit log of who did what (`audit`).

pub(crate) mod audit;
pub(crate) mod gate;
mod limits;
pub(crate) mod users;

use std::path::{Path, PathBuf};

/// Writes `bytes` to `path`, readable by its owner only, through a
/// temporary file so a crash leaves the old file or the new one: how the
/// accounts, the LMS platforms and the tool's key are kept.
pub fn write_private(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut temporary = path.as_os_str().to_owned();
    temporary.push(".new");
    let temporary = PathBuf::from(temporary);
    {
        let mut options = std::fs::OpenOptions::new();
        options.write(true).create(true).truncate(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
        let mut file = options.open(&temporary)?;
        file.write_all(bytes)?;
        file.sync_all()?;
    }
    std::fs::rename(&temporary, path)
}
