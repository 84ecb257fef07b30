//! Who a hello proves its sender is: an account by name and password, a
//! script by the lab's token, a person by the session their LMS launch
//! opened, or no one. Wrong credentials are answered
//! only after [`FAILURE_DELAY`]; each address, and each account from each
//! address, may fail [`FAILURES_BURST`] times and then once per
//! [`FAILURE_REFILL`], beyond which attempts are refused without the cost
//! of checking them — the guesser is slowed, never the account's owner
//! from their own address, and a throttled name answers as any; tokens
//! are compared in constant time; every attempt is logged. Checking a
//! password is slow on purpose, so it runs off the async threads, one at
//! a time, on a thread of its own at the lowest priority: a flood of
//! logins cannot take the cores the robot's loop and the operator need.
//! The accounts file is read again when it changes, so accounts added or
//! removed on a running lab count from the next login.

use std::net::IpAddr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use subtle::ConstantTimeEq;
use tokio::sync::Semaphore;
use tracing::{info, warn};
use vl_core::{ErrorCode, Named, Role};

use super::audit::{Audit, AuditEntry};
use super::limits::Failures;
pub use super::limits::{FAILURE_REFILL, FAILURES_BURST};
use super::users::{AccountRole, Users};

/// The sessions something outside the accounts opened (an LMS's launches):
/// the gate asks them who a hello's `session` speaks for, and knows no more
/// of them.
pub trait SessionCheck: Send + Sync {
    /// Who the session `secret` speaks for, and which session it is, while
    /// it lasts.
    fn vouch(&self, secret: &str) -> Option<(Identity, SessionId)>;
}

/// One session a [`SessionCheck`] opened, named without its secret: what a
/// run remembers of how its driver came in (a grade goes to the launch
/// that opened it), safe to tell a gateway's cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct SessionId(pub u64);

/// How long a wrong password, name or token waits for its answer.
pub const FAILURE_DELAY: Duration = Duration::from_secs(1);
/// Whether people who watch must log in too.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Observers {
    /// Anyone may watch without an account.
    #[default]
    Anyone,
    /// Only people with an account may watch.
    Accounts,
}

impl Named for Observers {
    const KIND: &'static str = "observers policy";
    const ALL: &'static [Observers] = &[Observers::Anyone, Observers::Accounts];

    fn id(self) -> &'static str {
        match self {
            Observers::Anyone => "anyone",
            Observers::Accounts => "accounts",
        }
    }
}

vl_core::named_by_id!(Observers);

/// Who a connection speaks for, as its hello proved (told by a gateway to
/// its cells, which take its word for it).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Identity {
    /// No one in particular.
    Anonymous,
    /// A script holding the lab's token: it may drive.
    Token,
    /// A person with an account.
    Account { name: String, role: AccountRole },
    /// The lab's own ROS 2 side (`--ros2-operator`): `/cmd_vel`.
    Ros2,
    /// A person an LMS vouched for in a launch (LTI 1.3): `sub@platform`.
    Lms { name: String, role: AccountRole },
}

impl Identity {
    /// The account's name, if there is one.
    pub fn name(&self) -> Option<&str> {
        match self {
            Identity::Account { name, .. } | Identity::Lms { name, .. } => Some(name),
            Identity::Ros2 => Some("ros2"),
            _ => None,
        }
    }

    /// Whether they run the lab: an administrator's account, or an
    /// instructor launched from the course's LMS.
    pub fn is_admin(&self) -> bool {
        matches!(
            self,
            Identity::Account {
                role: AccountRole::Admin,
                ..
            } | Identity::Lms {
                role: AccountRole::Admin,
                ..
            }
        )
    }
}

/// What a person whose account ended (`ended_by`) is told as they are let go.
pub const ACCOUNT_ENDED: &str = "your account at this lab was removed or may no longer drive";

/// Who a hello proved its sender is, and whether they may drive.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Admitted {
    pub identity: Identity,
    /// Whether they may take the operator's role, now or in their turn.
    pub may_drive: bool,
    /// The session that vouched for them, if one did.
    #[serde(default)]
    pub session: Option<SessionId>,
}

impl Admitted {
    /// Whether `users`, read again, no longer let this person in as they
    /// were let in: their account gone, or no longer allowed to drive.
    pub fn ended_by(&self, users: &Users) -> bool {
        match &self.identity {
            Identity::Account { name, .. } => match users.role_of(name) {
                None => true,
                Some(role) => self.may_drive && !role.may_drive(),
            },
            _ => false,
        }
    }

    /// No one in particular, at a lab that lets anyone drive.
    pub fn anyone() -> Admitted {
        Admitted {
            identity: Identity::Anonymous,
            may_drive: true,
            session: None,
        }
    }
}

/// A hello's credentials.
#[derive(Debug, Clone, Copy)]
pub struct Credentials<'a> {
    pub role: Role,
    pub user: Option<&'a str>,
    pub password: Option<&'a str>,
    pub token: Option<&'a str>,
    /// A session an LMS launch opened (the launched page's `vl-session`).
    pub session: Option<&'a str>,
    /// What they are shown for: the audit tells a session's login from a
    /// look at the status.
    pub purpose: Purpose,
}

/// What credentials are shown for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Purpose {
    /// A Guest's session, in its role.
    #[default]
    Session,
    /// The administrator's `GET /status`.
    Status,
}

/// Why a hello proves no one, as the client is told.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Refusal {
    pub code: ErrorCode,
    pub why: String,
}

fn refusal(code: ErrorCode, why: impl Into<String>) -> Refusal {
    Refusal {
        code,
        why: why.into(),
    }
}

/// A password check, run on the checker's thread.
type Check = Box<dyn FnOnce() + Send>;

/// How much less password checks count than the Host's other threads, in
/// nice levels: the least there is.
const CHECKER_NICE: i32 = 19;

/// Starts the password checker's thread, which ends with its sender.
fn checker() -> std::sync::mpsc::Sender<Check> {
    let (checks, inbox) = std::sync::mpsc::channel::<Check>();
    let started = std::thread::Builder::new()
        .name("password checks".into())
        .spawn(move || {
            crate::priority::yield_to_control(CHECKER_NICE, "password checker");
            for check in inbox {
                check();
            }
        });
    if let Err(e) = started {
        // Then every check fails to send, and every password is refused.
        warn!("cannot start the password checker: {e}");
    }
    checks
}

/// The lab's door: its accounts, its token, and the failures so far.
pub struct Gate {
    /// Read again from their file when it changes.
    users: Option<Mutex<Arc<Users>>>,
    token: Option<String>,
    observers: Observers,
    failures: Mutex<Failures>,
    hashing: Semaphore,
    /// The password checker's thread, fed one check at a time.
    checker: std::sync::mpsc::Sender<Check>,
    audit: Audit,
    /// The sessions LMS launches opened, at a lab launched from one.
    sessions: Vec<Arc<dyn SessionCheck>>,
}

impl Gate {
    pub fn new(
        users: Option<Users>,
        token: Option<String>,
        observers: Observers,
        audit: Audit,
    ) -> Gate {
        Gate {
            users: users.map(|u| Mutex::new(Arc::new(u))),
            token,
            observers,
            failures: Mutex::new(Failures::default()),
            hashing: Semaphore::new(1),
            checker: checker(),
            audit,
            sessions: Vec::new(),
        }
    }

    /// The gate that also lets in whom `sessions` (LMS launches) vouch for.
    pub fn with_sessions(mut self, sessions: Arc<dyn SessionCheck>) -> Gate {
        self.sessions.push(sessions);
        self
    }

    fn failures(&self) -> MutexGuard<'_, Failures> {
        self.failures
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// The accounts now: read again if their file changed (an account
    /// added on the running lab); a file that no longer reads keeps the
    /// accounts last read, and the log says why.
    fn users(&self) -> Option<Arc<Users>> {
        self.refresh().map(|(users, _)| users)
    }

    /// The accounts, if their file was read again since last asked: the
    /// Host then ends what accounts removed still hold.
    pub(crate) fn reread(&self) -> Option<Arc<Users>> {
        self.refresh()
            .and_then(|(users, read)| read.then_some(users))
    }

    /// The accounts now, and whether they were just read again.
    fn refresh(&self) -> Option<(Arc<Users>, bool)> {
        let mut current = self
            .users
            .as_ref()?
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        let read = match current.reread() {
            Some(Ok(users)) => {
                info!(
                    accounts = users.accounts().len(),
                    "the accounts file changed: read again"
                );
                self.audit.record(
                    AuditEntry::new("accounts_read")
                        .detail(format!("{} accounts", users.accounts().len())),
                );
                *current = Arc::new(users);
                true
            }
            Some(Err(e)) => {
                warn!("the accounts file changed but does not read; keeping the accounts: {e}");
                let mut kept = Users::clone(&current);
                kept.seen();
                *current = Arc::new(kept);
                false
            }
            None => false,
        };
        Some((current.clone(), read))
    }

    /// Whether `admitted`, let in before, is still let in as it was: its
    /// account not removed since, nor barred from driving.
    pub fn still_admits(&self, admitted: &Admitted) -> bool {
        self.users().is_none_or(|users| !admitted.ended_by(&users))
    }

    /// Whether the lab has accounts (so some things are an administrator's).
    pub(crate) fn has_accounts(&self) -> bool {
        self.users.is_some()
    }

    /// Whether an operator must prove who they are.
    fn guarded(&self) -> bool {
        self.users.is_some() || self.token.is_some()
    }

    /// Who `hello` proves its sender is, for the role it asks for.
    pub async fn check(
        &self,
        connection: u64,
        address: IpAddr,
        hello: Credentials<'_>,
    ) -> Result<Admitted, Refusal> {
        let users = self.users();
        // A name is logged only when it is an account's: what someone typed
        // in the name field may be their password.
        let account = hello
            .user
            .filter(|name| users.as_ref().is_some_and(|u| u.role_of(name).is_some()));
        let log = |event: &'static str| {
            let entry = AuditEntry::new(event)
                .connection(connection)
                .address(address)
                .user(account);
            match (hello.user, account) {
                (Some(_), None) => entry.detail("a name that is no account's"),
                _ => entry,
            }
        };
        let shown = hello.user.is_some() || hello.token.is_some() || hello.session.is_some();
        let (identity, session) = if shown {
            if !self.failures().take(address, account) {
                self.audit.record(log("rate_limited"));
                tokio::time::sleep(FAILURE_DELAY).await;
                let wait = FAILURE_REFILL.as_secs();
                return Err(refusal(
                    ErrorCode::TooManyAttempts,
                    format!("too many failed logins: wait {wait} s before the next try"),
                ));
            }
            match self.prove(hello, users).await {
                Ok((identity, session)) => {
                    self.failures().refund(address, account);
                    let login = log("login").user(identity.name());
                    self.audit.record(login.detail(match hello.purpose {
                        Purpose::Session => hello.role.to_string(),
                        Purpose::Status => "status".to_owned(),
                    }));
                    (identity, session)
                }
                Err(why) => {
                    let failed = log("login_failed");
                    let failed = match failed.detail {
                        Some(_) => failed,
                        None => failed.detail(why.clone()),
                    };
                    self.audit.record(failed);
                    tokio::time::sleep(FAILURE_DELAY).await;
                    return Err(refusal(ErrorCode::Unauthorized, why));
                }
            }
        } else {
            (Identity::Anonymous, None)
        };
        self.admits(&identity, hello.role).map_err(|why| {
            self.audit.record(log("refused").detail(why.clone()));
            refusal(ErrorCode::Unauthorized, why)
        })?;
        let may_drive = self.admits(&identity, Role::Operator).is_ok();
        Ok(Admitted {
            identity,
            may_drive,
            session,
        })
    }

    /// The identity the credentials prove, or why they prove none.
    /// `users`: the accounts now, as [`Gate::users`] read them for this check.
    async fn prove(
        &self,
        hello: Credentials<'_>,
        users: Option<Arc<Users>>,
    ) -> Result<(Identity, Option<SessionId>), String> {
        if let Some(secret) = hello.session {
            return self
                .sessions
                .iter()
                .find_map(|sessions| sessions.vouch(secret))
                .map(|(identity, id)| (identity, Some(id)))
                .ok_or_else(|| {
                    "this LMS session is unknown or has expired: open the lab from your course again"
                        .into()
                });
        }
        if let Some(name) = hello.user {
            let Some(users) = users else {
                return Err("this lab has no accounts: leave out the user name".into());
            };
            let Some(password) = hello.password else {
                return Err("a user name needs its password".into());
            };
            let (name, password) = (name.to_owned(), password.to_owned());
            let _one_at_a_time = self.hashing.acquire().await;
            let (answer, checked) = tokio::sync::oneshot::channel();
            let check = Box::new(move || {
                let proved = users.verify(&name, &password);
                let _ = answer.send(proved.map(|role| Identity::Account { name, role }));
            });
            let checked = match self.checker.send(check) {
                Ok(()) => checked.await.ok().flatten(),
                Err(_) => None,
            };
            return checked
                .map(|identity| (identity, None))
                .ok_or_else(|| "wrong user name or password".into());
        }
        let given = hello.token.unwrap_or_default();
        match &self.token {
            Some(token) if bool::from(token.as_bytes().ct_eq(given.as_bytes())) => {
                Ok((Identity::Token, None))
            }
            Some(_) => Err("the operator token is wrong".into()),
            None => Err("this lab has no token: leave it out".into()),
        }
    }

    /// Whether `identity` may take `role` at this lab.
    fn admits(&self, identity: &Identity, role: Role) -> Result<(), String> {
        match (identity, role) {
            (Identity::Anonymous, Role::Operator) if self.guarded() => {
                Err(if self.users.is_some() {
                    "this lab's operators log in with an account (its name and password), or watch as an observer".into()
                } else {
                    "this lab's operators need its token: say hello with it (vl guest --token), or watch as an observer".into()
                })
            }
            (Identity::Anonymous, Role::Observer)
                if self.users.is_some() && self.observers == Observers::Accounts =>
            {
                Err(
                    "this lab's observers log in too: say hello with your user name and password"
                        .into(),
                )
            }
            (Identity::Account { role: account, .. }, Role::Operator) if !account.may_drive() => {
                Err("your account may watch, not drive: say hello as an observer".into())
            }
            (Identity::Lms { role, .. }, Role::Operator) if !role.may_drive() => {
                Err("your role in the course may watch, not drive: say hello as an observer".into())
            }
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn address(last: u8) -> IpAddr {
        IpAddr::from([10, 0, 0, last])
    }

    fn hello<'a>(role: Role, user: Option<&'a str>, password: Option<&'a str>) -> Credentials<'a> {
        Credentials {
            role,
            user,
            password,
            token: None,
            session: None,
            purpose: Purpose::Session,
        }
    }

    fn with_token(role: Role, token: Option<&str>) -> Credentials<'_> {
        Credentials {
            token,
            ..hello(role, None, None)
        }
    }

    fn accounts(observers: Observers) -> Gate {
        Gate::new(
            Some(super::super::users::sample()),
            None,
            observers,
            Audit::default(),
        )
    }

    #[tokio::test(start_paused = true)]
    async fn a_lab_with_a_token_asks_operators_for_it() {
        let gate = Gate::new(
            None,
            Some("secret".into()),
            Observers::Anyone,
            Audit::default(),
        );
        let at = address(1);
        let none = gate.check(1, at, with_token(Role::Operator, None)).await;
        let why = none.unwrap_err();
        assert_eq!(why.code, ErrorCode::Unauthorized);
        assert!(why.why.contains("--token"), "says how to give one: {why:?}");
        let started = tokio::time::Instant::now();
        let wrong = gate
            .check(2, at, with_token(Role::Operator, Some("guess")))
            .await;
        assert!(wrong.unwrap_err().why.contains("wrong"));
        assert!(started.elapsed() >= FAILURE_DELAY, "a wrong token waits");
        // Watching needs no token; driving needs the right one.
        let watcher = gate.check(3, at, with_token(Role::Observer, None)).await;
        assert_eq!(watcher.map(|a| a.identity), Ok(Identity::Anonymous));
        let right = gate
            .check(4, at, with_token(Role::Operator, Some("secret")))
            .await;
        assert_eq!(right.map(|a| a.identity), Ok(Identity::Token));
    }

    #[tokio::test(start_paused = true)]
    async fn accounts_drive_by_their_role_and_observers_by_the_lab_s_policy() {
        let gate = accounts(Observers::Anyone);
        let at = address(1);
        let ada = gate
            .check(
                1,
                at,
                hello(Role::Operator, Some("ada"), Some("correct horse")),
            )
            .await;
        assert_eq!(
            ada.map(|a| a.identity),
            Ok(Identity::Account {
                name: "ada".into(),
                role: AccountRole::Operator
            })
        );
        let wrong = gate
            .check(
                2,
                at,
                hello(Role::Operator, Some("ada"), Some("wrong horse")),
            )
            .await
            .unwrap_err();
        assert_eq!(wrong.code, ErrorCode::Unauthorized);
        let bob = gate
            .check(
                3,
                at,
                hello(Role::Operator, Some("bob"), Some("battery staple")),
            )
            .await
            .unwrap_err();
        assert!(bob.why.contains("may watch, not drive"), "{bob:?}");
        let anonymous = gate.check(4, at, hello(Role::Operator, None, None)).await;
        assert!(
            anonymous
                .unwrap_err()
                .why
                .contains("log in with an account")
        );
        let watcher = gate.check(5, at, hello(Role::Observer, None, None)).await;
        assert_eq!(
            watcher.map(|a| (a.identity, a.may_drive)),
            Ok((Identity::Anonymous, false))
        );
        let closed = accounts(Observers::Accounts);
        let refused = closed.check(6, at, hello(Role::Observer, None, None)).await;
        assert!(refused.unwrap_err().why.contains("observers log in"));
        let bob = closed
            .check(
                7,
                at,
                hello(Role::Observer, Some("bob"), Some("battery staple")),
            )
            .await;
        assert!(bob.is_ok());
    }

    #[tokio::test(start_paused = true)]
    async fn wrong_logins_from_one_address_are_limited_and_others_are_not() {
        let gate = accounts(Observers::Anyone);
        let (guesser, elsewhere) = (address(1), address(2));
        let started = tokio::time::Instant::now();
        let (mut checked, mut limited) = (0, 0);
        for n in 0..30 {
            let guess = hello(Role::Operator, Some("ada"), Some("guess1234"));
            match gate.check(n, guesser, guess).await.unwrap_err().code {
                ErrorCode::Unauthorized => checked += 1,
                ErrorCode::TooManyAttempts => limited += 1,
                other => panic!("{other}"),
            }
        }
        let refilled = started.elapsed().as_secs_f64() / FAILURE_REFILL.as_secs_f64();
        assert!(
            f64::from(checked) <= FAILURES_BURST + refilled + 1.0,
            "{checked} guesses checked in {:?}",
            started.elapsed()
        );
        assert!(limited >= 10, "only {limited} held back");
        // Another address is not held back by this one's failures.
        let ok = hello(Role::Observer, Some("bob"), Some("battery staple"));
        assert!(gate.check(100, elsewhere, ok).await.is_ok());
    }

    #[test]
    fn the_guesser_is_held_never_the_owner_elsewhere() {
        let mut failures = Failures::default();
        let (guesser, teacher, stranger) = (address(1), address(2), address(3));
        for _ in 0..FAILURES_BURST as u8 {
            assert!(failures.take(guesser, Some("ada")));
        }
        // The guesser's address is held, for any account…
        assert!(!failures.take(guesser, Some("ada")));
        assert!(!failures.take(guesser, Some("bob")));
        assert!(!failures.take(guesser, None));
        // …not the account from its owner's address, and from a new address
        // a real account and a name that is none's are answered alike.
        assert!(failures.take(teacher, Some("ada")));
        assert!(failures.take(stranger, Some("ada")));
        assert!(failures.take(address(4), None));
        // An attempt that succeeded costs nothing.
        failures.refund(teacher, Some("ada"));
        for _ in 0..(FAILURES_BURST as u8 - 1) {
            assert!(failures.take(teacher, Some("ada")));
        }
    }
}
