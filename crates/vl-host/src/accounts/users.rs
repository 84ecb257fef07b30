//! The lab's accounts: a TOML file of names, roles and Argon2id password
//! hashes (`vl users` keeps it; `vl host --users` reads it). Passwords are
//! never stored, only their salted hashes, and checking one takes the same
//! time whether or not the name exists.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::SystemTime;

use argon2::Argon2;
use argon2::password_hash::rand_core::OsRng;
use argon2::password_hash::{PasswordHash, PasswordHasher, PasswordVerifier, SaltString};
use serde::{Deserialize, Serialize};
use vl_core::Named;
use vl_report::table::{Report, Table};

/// What an account may do at the lab.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AccountRole {
    /// Watches; may not drive.
    Observer,
    /// Watches, and drives in their turn.
    Operator,
    /// Drives in their turn, and runs the lab: ends any run, removes
    /// anyone from the queue, reads the status.
    Admin,
}

impl Named for AccountRole {
    const KIND: &'static str = "role";
    const ALL: &'static [AccountRole] = &[
        AccountRole::Operator,
        AccountRole::Observer,
        AccountRole::Admin,
    ];

    fn id(self) -> &'static str {
        match self {
            AccountRole::Observer => "observer",
            AccountRole::Operator => "operator",
            AccountRole::Admin => "admin",
        }
    }
}

vl_core::named_by_id!(AccountRole);

impl AccountRole {
    /// Whether this account may take the operator's role.
    pub fn may_drive(self) -> bool {
        self != AccountRole::Observer
    }
}

/// Longest account name, bytes.
pub(crate) const MAX_NAME: usize = 64;
/// Shortest and longest password, bytes.
pub(crate) const MIN_PASSWORD: usize = 8;
pub(crate) const MAX_PASSWORD: usize = 256;
/// Accounts a file may hold.
pub(crate) const MAX_ACCOUNTS: usize = 10_000;

/// One account as the file keeps it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Account {
    pub name: String,
    pub role: AccountRole,
    /// The password's Argon2id hash, in the PHC string format.
    hash: String,
}

/// Why the accounts file cannot be read, written or changed so.
#[derive(Debug, thiserror::Error)]
pub enum UsersError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path} is not an accounts file: {why}")]
    Format { path: PathBuf, why: String },
    #[error("there is already an account '{0}'")]
    Exists(String),
    #[error("there is no account '{0}'")]
    NoSuch(String),
    #[error("an account name is 1 to {MAX_NAME} letters, digits, '.', '-' or '_', not '{0}'")]
    BadName(String),
    #[error("a password is {MIN_PASSWORD} to {MAX_PASSWORD} bytes long")]
    BadPassword,
    #[error("the password cannot be hashed: {0}")]
    Hash(String),
    #[error("a lab keeps at most {MAX_ACCOUNTS} accounts")]
    TooMany,
}

/// Who has an account and with what role: what `vl users list` shows,
/// without the hashes.
#[derive(Debug, Serialize)]
pub struct Roster {
    pub accounts: Vec<Member>,
}

#[derive(Debug, Serialize)]
pub struct Member {
    pub name: String,
    pub role: AccountRole,
}

impl Report for Roster {
    fn table(&self) -> Table {
        let mut table = Table::columns(&["account", "role"]);
        for member in &self.accounts {
            table.row(vec![member.name.clone(), member.role.to_string()]);
        }
        table
    }
}

/// The accounts, in the order they were added.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Users {
    #[serde(default, rename = "user")]
    accounts: Vec<Account>,
    /// The file they were read from, and when it was last changed then:
    /// a Host reads it again when it changes.
    #[serde(skip)]
    source: Option<(PathBuf, Option<SystemTime>)>,
}

/// When the file at `path` last changed, if it is there.
fn changed(path: &Path) -> Option<SystemTime> {
    std::fs::metadata(path).and_then(|m| m.modified()).ok()
}

fn check_name(name: &str) -> Result<(), UsersError> {
    let fits = |c: char| c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_');
    if name.is_empty() || name.len() > MAX_NAME || !name.chars().all(fits) {
        return Err(UsersError::BadName(name.to_owned()));
    }
    Ok(())
}

fn hash(password: &str) -> Result<String, UsersError> {
    if !(MIN_PASSWORD..=MAX_PASSWORD).contains(&password.len()) {
        return Err(UsersError::BadPassword);
    }
    let salt = SaltString::generate(&mut OsRng);
    Argon2::default()
        .hash_password(password.as_bytes(), &salt)
        .map(|h| h.to_string())
        .map_err(|e| UsersError::Hash(e.to_string()))
}

/// A hash no password matches, checked against when a name has no account,
/// so that a wrong name costs as long as a wrong password.
fn decoy() -> &'static str {
    static DECOY: OnceLock<String> = OnceLock::new();
    DECOY.get_or_init(|| hash("no account has this password").unwrap_or_default())
}

fn matches(hash: &str, password: &str) -> bool {
    PasswordHash::new(hash).is_ok_and(|parsed| {
        Argon2::default()
            .verify_password(password.as_bytes(), &parsed)
            .is_ok()
    })
}

impl Users {
    /// The accounts in `path`; an empty list when the file does not exist yet.
    pub fn load(path: &Path) -> Result<Users, UsersError> {
        let changed = changed(path);
        let text = match std::fs::read_to_string(path) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Ok(Users {
                    source: Some((path.to_owned(), changed)),
                    ..Users::default()
                });
            }
            Err(source) => {
                return Err(UsersError::Read {
                    path: path.to_owned(),
                    source,
                });
            }
        };
        let format = |why: String| UsersError::Format {
            path: path.to_owned(),
            why,
        };
        let mut users: Users = toml::from_str(&text).map_err(|e| format(e.to_string()))?;
        users.source = Some((path.to_owned(), changed));
        if users.accounts.len() > MAX_ACCOUNTS {
            return Err(format(format!("more than {MAX_ACCOUNTS} accounts")));
        }
        for (i, account) in users.accounts.iter().enumerate() {
            check_name(&account.name).map_err(|e| format(e.to_string()))?;
            if PasswordHash::new(&account.hash).is_err() {
                return Err(format(format!(
                    "{}'s hash is not a PHC string",
                    account.name
                )));
            }
            if users.accounts[..i].iter().any(|a| a.name == account.name) {
                return Err(format(format!("'{}' is there twice", account.name)));
            }
        }
        Ok(users)
    }

    /// Writes the accounts to `path`, readable by its owner only, through
    /// a temporary file so a crash leaves the old file or the new one.
    pub fn save(&self, path: &Path) -> Result<(), UsersError> {
        let write = |source| UsersError::Write {
            path: path.to_owned(),
            source,
        };
        let text = toml::to_string(self).map_err(|e| UsersError::Hash(e.to_string()))?;
        super::write_private(path, text.as_bytes()).map_err(write)
    }

    /// The accounts as their file has them now, when it changed since
    /// these were read (`vl users add` on a running lab); none if it did not.
    pub fn reread(&self) -> Option<Result<Users, UsersError>> {
        let (path, read) = self.source.as_ref()?;
        (changed(path) != *read).then(|| Users::load(path))
    }

    /// Takes the file as it is now for read, though it did not read (so
    /// it is not read again until it changes again).
    pub(crate) fn seen(&mut self) {
        if let Some((path, read)) = &mut self.source {
            *read = changed(path);
        }
    }

    pub fn accounts(&self) -> &[Account] {
        &self.accounts
    }

    pub fn roster(&self) -> Roster {
        Roster {
            accounts: self
                .accounts
                .iter()
                .map(|a| Member {
                    name: a.name.clone(),
                    role: a.role,
                })
                .collect(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.accounts.is_empty()
    }

    pub fn role_of(&self, name: &str) -> Option<AccountRole> {
        self.accounts
            .iter()
            .find(|a| a.name == name)
            .map(|a| a.role)
    }

    pub fn add(&mut self, name: &str, role: AccountRole, password: &str) -> Result<(), UsersError> {
        check_name(name)?;
        if self.role_of(name).is_some() {
            return Err(UsersError::Exists(name.to_owned()));
        }
        if self.accounts.len() >= MAX_ACCOUNTS {
            return Err(UsersError::TooMany);
        }
        self.accounts.push(Account {
            name: name.to_owned(),
            role,
            hash: hash(password)?,
        });
        Ok(())
    }

    pub fn remove(&mut self, name: &str) -> Result<(), UsersError> {
        let before = self.accounts.len();
        self.accounts.retain(|a| a.name != name);
        if self.accounts.len() == before {
            return Err(UsersError::NoSuch(name.to_owned()));
        }
        Ok(())
    }

    /// Sets `name`'s password, and its role when one is given.
    pub fn passwd(
        &mut self,
        name: &str,
        password: &str,
        role: Option<AccountRole>,
    ) -> Result<(), UsersError> {
        let hashed = hash(password)?;
        let account = self
            .accounts
            .iter_mut()
            .find(|a| a.name == name)
            .ok_or_else(|| UsersError::NoSuch(name.to_owned()))?;
        account.hash = hashed;
        if let Some(role) = role {
            account.role = role;
        }
        Ok(())
    }

    /// `name`'s role when `password` is theirs. Slow on purpose (Argon2id),
    /// and as slow for a name with no account: run it off the async threads.
    pub fn verify(&self, name: &str, password: &str) -> Option<AccountRole> {
        let account = self.accounts.iter().find(|a| a.name == name);
        let hash = match account {
            Some(a) => a.hash.as_str(),
            None => decoy(),
        };
        let ok = matches(hash, password);
        account.filter(|_| ok).map(|a| a.role)
    }
}

/// Two accounts for tests: ada drives ("correct horse"), bob watches
/// ("battery staple").
#[cfg(test)]
pub(crate) fn sample() -> Users {
    let mut users = Users::default();
    users
        .add("ada", AccountRole::Operator, "correct horse")
        .expect("a good account");
    users
        .add("bob", AccountRole::Observer, "battery staple")
        .expect("a good account");
    users
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accounts_are_kept_by_hash_and_checked_by_password() {
        let dir = std::env::temp_dir().join(format!("vl-users-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("users.toml");
        assert!(Users::load(&path).unwrap().is_empty());
        let mut users = sample();
        assert!(matches!(
            users.add("ada", AccountRole::Admin, "whatever1"),
            Err(UsersError::Exists(_))
        ));
        assert!(matches!(
            users.add("no spaces", AccountRole::Admin, "whatever1"),
            Err(UsersError::BadName(_))
        ));
        assert!(matches!(
            users.add("carol", AccountRole::Admin, "short"),
            Err(UsersError::BadPassword)
        ));
        users.save(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            !text.contains("correct horse") && text.contains("$argon2id$"),
            "{text}"
        );
        let users = Users::load(&path).unwrap();
        assert_eq!(
            users.verify("ada", "correct horse"),
            Some(AccountRole::Operator)
        );
        assert_eq!(users.verify("ada", "correct horsE"), None);
        assert_eq!(users.verify("nobody", "correct horse"), None);
        let mut users = users;
        users
            .passwd("bob", "new password", Some(AccountRole::Admin))
            .unwrap();
        assert_eq!(users.verify("bob", "battery staple"), None);
        assert_eq!(
            users.verify("bob", "new password"),
            Some(AccountRole::Admin)
        );
        users.remove("ada").unwrap();
        assert!(matches!(users.remove("ada"), Err(UsersError::NoSuch(_))));
        std::fs::write(
            &path,
            "[[user]]\nname = \"x\"\nrole = \"operator\"\nhash = \"plain\"\n",
        )
        .unwrap();
        let e = Users::load(&path).unwrap_err().to_string();
        assert!(e.contains("not a PHC string"), "{e}");
        std::fs::write(
            &path,
            "[[user]]\nname = \"x\"\nrole = \"king\"\nhash = \"plain\"\n",
        )
        .unwrap();
        let e = Users::load(&path).unwrap_err().to_string();
        assert!(e.contains("unknown role 'king'"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
