//! Grades from runs: when a person who came from an LMS ends a run, the
//! lab's rubric grades its summary and the score goes to their launch's
//! line item (AGS), tried again with back-off when the platform does not
//! take it. What was sent, is waiting or failed is kept for the status,
//! the instructor's roster page and the audit log.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, SystemTime};

use serde::Serialize;
use tracing::{info, warn};
use vl_core::{GradesStatus, Rubric, Summary};

use super::Lti;
use super::sessions::Launch;
use crate::accounts::audit::AuditEntry;

/// How long to wait before each try again after the first.
const BACK_OFF: [Duration; 4] = [
    Duration::from_secs(1),
    Duration::from_secs(2),
    Duration::from_secs(4),
    Duration::from_secs(8),
];
/// People whose runs are kept, and runs kept per person.
const MAX_PEOPLE: usize = 10_000;
const MAX_RUNS: usize = 50;

/// Where a run's score is.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "state", content = "why")]
pub(crate) enum Sent {
    Sending,
    Posted,
    Failed(String),
    /// The launch gave no line item the tool may score.
    NoLineItem,
}

impl Sent {
    /// Where the score is, in words.
    pub(crate) fn words(&self) -> String {
        match self {
            Sent::Sending => "being sent".into(),
            Sent::Posted => "posted".into(),
            Sent::Failed(why) => format!("failed: {why}"),
            Sent::NoLineItem => "no grade column for it".into(),
        }
    }
}

/// One graded run of a person.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Graded {
    /// The grade's number at this lab (a gateway grades runs of cells
    /// whose run numbers are their own).
    #[serde(skip)]
    id: u64,
    /// The run's number, at a lab that runs it.
    pub run: Option<u64>,
    pub given: f64,
    pub maximum: f64,
    pub ending: String,
    pub comment: String,
    pub sent: Sent,
}

#[derive(Default)]
struct Book {
    graded: u64,
    status: GradesStatus,
    runs: HashMap<String, VecDeque<Graded>>,
}

/// The rubric, and the graded runs by person.
pub(super) struct GradeBook {
    rubric: Rubric,
    book: Mutex<Book>,
}

impl GradeBook {
    pub(super) fn new(rubric: Rubric) -> GradeBook {
        GradeBook {
            rubric,
            book: Mutex::new(Book::default()),
        }
    }

    /// The most a run may earn.
    pub(super) fn maximum(&self) -> f64 {
        self.rubric.maximum()
    }

    fn book(&self) -> MutexGuard<'_, Book> {
        super::locked(&self.book)
    }

    /// Keeps `graded` as `user`'s, numbered: its number.
    fn keep(&self, user: &str, mut graded: Graded) -> u64 {
        let mut book = self.book();
        book.graded += 1;
        graded.id = book.graded;
        let id = graded.id;
        if book.runs.len() >= MAX_PEOPLE && !book.runs.contains_key(user) {
            book.runs.clear();
        }
        let runs = book.runs.entry(user.to_owned()).or_default();
        if runs.len() >= MAX_RUNS {
            runs.pop_front();
        }
        runs.push_back(graded);
        id
    }

    fn mark(&self, user: &str, id: u64, sent: Sent) {
        let mut book = self.book();
        match &sent {
            Sent::Posted => book.status.posted += 1,
            Sent::Failed(why) => {
                book.status.failed += 1;
                book.status.last_failure = Some(why.clone());
            }
            _ => {}
        }
        book.status.sending = book.status.sending.saturating_sub(1);
        if let Some(graded) = book
            .runs
            .get_mut(user)
            .and_then(|r| r.iter_mut().find(|g| g.id == id))
        {
            graded.sent = sent;
        }
    }

    /// `user`'s graded runs, oldest first.
    pub(super) fn runs_of(&self, user: &str) -> Vec<Graded> {
        self.book()
            .runs
            .get(user)
            .map(|r| r.iter().cloned().collect())
            .unwrap_or_default()
    }
}

impl Lti {
    /// Grades, and sends, a run `user` drove (run `run` of this lab, when
    /// it is this lab's), if they came from an LMS.
    pub fn run_ended(self: &Arc<Self>, run: Option<u64>, user: &str, summary: &Summary) {
        let Some(launch) = self.sessions.latest(user) else {
            return;
        };
        let grade = self.grades.rubric.grade(summary);
        let named = run.map_or_else(|| "A run".to_owned(), |run| format!("Run {run}"));
        let comment = format!("{named}, {}. {}", summary.ending(), grade.comment());
        let sent = if launch.lineitem.is_some() {
            self.grades.book().status.sending += 1;
            Sent::Sending
        } else {
            Sent::NoLineItem
        };
        let id = self.grades.keep(
            user,
            Graded {
                id: 0,
                run,
                given: grade.given,
                maximum: grade.maximum,
                ending: summary.ending(),
                comment: comment.clone(),
                sent: sent.clone(),
            },
        );
        if sent == Sent::NoLineItem {
            return;
        }
        let score = serde_json::json!({
            "scoreGiven": grade.given,
            "scoreMaximum": grade.maximum,
            "activityProgress": "Completed",
            "gradingProgress": "FullyGraded",
            "userId": launch.sub,
            "timestamp": humantime::format_rfc3339_millis(SystemTime::now()).to_string(),
            "comment": comment,
        });
        let lti = self.clone();
        tokio::spawn(async move { lti.send_score(id, &launch, &score).await });
    }

    /// Posts `score` of grade `id` to `launch`'s line item, for its person.
    async fn send_score(&self, id: u64, launch: &Launch, score: &serde_json::Value) {
        let Some(lineitem) = &launch.lineitem else {
            return;
        };
        let user = launch.user.as_str();
        let mut why = String::new();
        for wait in std::iter::once(Duration::ZERO).chain(BACK_OFF) {
            tokio::time::sleep(wait).await;
            let platform = self
                .platforms()
                .ok()
                .and_then(|r| r.find(&launch.issuer, Some(&launch.client_id)).cloned());
            let Some(platform) = platform else {
                why = "the platform is no longer registered".into();
                break;
            };
            match self.post_score(&platform, lineitem, score).await {
                Ok(()) => {
                    info!(grade = id, user, "score posted to the LMS");
                    let comment = score["comment"].as_str().unwrap_or_default();
                    self.audit.record(
                        AuditEntry::new("grade_posted")
                            .user(Some(user))
                            .detail(comment.to_owned()),
                    );
                    return self.grades.mark(user, id, Sent::Posted);
                }
                Err(e) => {
                    warn!(grade = id, user, "the LMS did not take the score: {e}");
                    why = e.to_string();
                }
            }
        }
        self.audit.record(
            AuditEntry::new("grade_failed")
                .user(Some(user))
                .detail(format!(
                    "{}: {why}",
                    score["comment"].as_str().unwrap_or_default()
                )),
        );
        self.grades.mark(user, id, Sent::Failed(why));
    }

    /// What was sent, is waiting and failed, for the Host's status.
    pub fn grades_status(&self) -> GradesStatus {
        self.grades.book().status.clone()
    }
}
