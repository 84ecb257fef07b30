//! The bench's floods of wrong passwords: one address guessing an
//! account's password while the operator's commands are timed, the Host's
//! answers to the guesses counted.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use serde::Serialize;
use tokio::task::JoinSet;
use vl_core::{ErrorCode, HostMessage, Role};

use super::{AgainstQuiet, BenchError, FLOODS, Socket, connect, hello, say, time_commands, until};

/// The operator's round trips while wrong passwords pour in from one
/// address, [`GUESSES_PER_S`] a second, until [`GUESSES`] have been tried
/// (fewer for fewer commands), [`FLOODS`] times, each flood followed by a
/// quiet round of as many commands. The first round's trips run faster
/// than a run's later ones, so the floods are compared with the quiet
/// rounds between them, and the rounds are pooled: a p99 of two rounds'
/// few thousand trips moved from 1.03× to 1.17× between runs on the same
/// machine.
#[derive(Debug, Clone, Serialize)]
pub struct Guessing {
    /// The floods' round trips against the quiet rounds'.
    #[serde(flatten)]
    pub timed: AgainstQuiet,
    /// Guesses sent, and how the Host answered them: checked and refused
    /// (`unauthorized`), refused unchecked (`too_many_attempts`), or not at
    /// all (pushed out by the next before it was answered).
    pub sent: u64,
    pub checked: u64,
    pub limited: u64,
    pub unanswered: u64,
}

/// Wrong passwords tried in each flood, and how fast.
const GUESSES: u64 = 1000;
const GUESSES_PER_S: f64 = 100.0;
/// How much less the guessers count than the Host, in nice levels.
const GUESSES_NICE: i32 = 19;

/// Counts of how the Host answered guesses.
#[derive(Default)]
struct Answers {
    sent: AtomicU64,
    checked: AtomicU64,
    limited: AtomicU64,
}

/// One wrong password from this address, and how it was answered.
async fn guess(url: String, answers: Arc<Answers>) {
    let Ok(mut ws) = connect(&url).await else {
        return;
    };
    if say(&mut ws, &hello(Role::Operator, Some("a wrong guess")))
        .await
        .is_err()
    {
        return;
    }
    answers.sent.fetch_add(1, Ordering::Relaxed);
    let answer = until(&mut ws, "hear a guess answered", |m| match m {
        HostMessage::Error { code, .. } => Some(*code),
        _ => None,
    });
    match tokio::time::timeout(Duration::from_secs(3), answer).await {
        Ok(Ok(ErrorCode::Unauthorized)) => answers.checked.fetch_add(1, Ordering::Relaxed),
        Ok(Ok(ErrorCode::TooManyAttempts)) => answers.limited.fetch_add(1, Ordering::Relaxed),
        _ => 0,
    };
}

/// The operator's commands from `event` on, timed again while guesses
/// pour in, and in a quiet round after each flood.
pub(super) async fn guessing(
    operator: &mut Socket,
    url: &str,
    event: &mut u64,
    commands: usize,
) -> Result<Guessing, BenchError> {
    let answers = Arc::new(Answers::default());
    let (mut flooded, mut quiet) = (Vec::new(), Vec::new());
    // Two guesses per command timed, at most GUESSES: a short bench
    // (README's test times 50 commands) floods for a second, not ten.
    let guesses = GUESSES.min(2 * commands as u64);
    for _ in 0..FLOODS {
        let pour = flood(url, answers.clone(), guesses)?;
        let took = time_commands(operator, *event, commands, || !pour.is_finished()).await?;
        *event += took.len() as u64;
        flooded.extend(took);
        let took = time_commands(operator, *event, commands, || false).await?;
        *event += took.len() as u64;
        quiet.extend(took);
    }
    let load = |n: &AtomicU64| n.load(Ordering::Relaxed);
    let (sent, checked, limited) = (
        load(&answers.sent),
        load(&answers.checked),
        load(&answers.limited),
    );
    Ok(Guessing {
        timed: AgainstQuiet::of(flooded, quiet),
        sent,
        checked,
        limited,
        unanswered: sent - checked - limited,
    })
}

/// `guesses` wrong passwords from one address, [`GUESSES_PER_S`] a
/// second, on a thread of their own at the lowest priority: on a real lab
/// their side of each connection is another machine's work, so here it
/// takes only what the Host leaves, and what is measured is the Host's
/// own cost of the flood.
fn flood(
    url: &str,
    answers: Arc<Answers>,
    guesses: u64,
) -> Result<std::thread::JoinHandle<()>, BenchError> {
    let url = url.to_owned();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(BenchError::Runtime)?;
    Ok(std::thread::spawn(move || {
        crate::priority::yield_to_control(GUESSES_NICE, "guessers");
        runtime.block_on(async move {
            let mut tries = JoinSet::new();
            let mut every = tokio::time::interval(Duration::from_secs_f64(1.0 / GUESSES_PER_S));
            for _ in 0..guesses {
                every.tick().await;
                tries.spawn(guess(url.clone(), answers.clone()));
            }
            while tries.join_next().await.is_some() {}
        });
    }))
}
