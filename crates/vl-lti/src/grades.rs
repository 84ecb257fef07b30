//! Grades from runs: when a person who came from an LMS ends a run, the
//! lab's rubric grades its summary and the score goes to their launch's
//! line item (AGS), tried again with back-off when the platform does not
//! take it. A run counts only when its driver ended it, and only as the
//! assignment the teacher linked (its experiment, its goal: the learner
//! cannot change them); one that does not count is kept, with why, and not
//! posted — a score posted replaces the learner's last, so another's
//! emergency stop or a fault would otherwise take a grade away. What was
//! sent, is waiting, failed or did not count is kept for the status, the
//! instructor's roster page and the audit log.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, SystemTime};

use serde::Serialize;
use tracing::{info, warn};
use vl_core::{Experiments, Goal, GradesStatus, Rubric, Summary};

use tokio::sync::broadcast;

use super::Lti;
use super::sessions::{Assignment, Launch};
use vl_host::Admitted;
use vl_host::AuditEntry;
use vl_host::LabEvent;

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
    /// The run does not count for a grade: why.
    NotCounted(String),
}

impl Sent {
    /// Where the score is, in words.
    pub(crate) fn words(&self) -> String {
        match self {
            Sent::Sending => "being sent".into(),
            Sent::Posted => "posted".into(),
            Sent::Failed(why) => format!("failed: {why}"),
            Sent::NoLineItem => "no grade column for it".into(),
            Sent::NotCounted(why) => format!("not sent: {why}"),
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

/// The rubrics, and the graded runs by person.
pub(super) struct GradeBook {
    /// The lab's rubric for every run, when its config gives one.
    fixed: Option<Rubric>,
    /// Each experiment's own, as its folder declares it.
    declared: HashMap<String, Rubric>,
    book: Mutex<Book>,
}

impl GradeBook {
    /// Runs graded by `fixed`, else by the rubric their experiment in
    /// `experiments` declares, else by the default.
    pub(super) fn new(fixed: Option<Rubric>, experiments: &Experiments) -> GradeBook {
        let declared = experiments
            .ids()
            .into_iter()
            .filter_map(|id| {
                let rubric = experiments.get(id.as_str()).ok()?.declared.rubric?;
                Some((id.to_string(), rubric))
            })
            .collect();
        GradeBook {
            fixed,
            declared,
            book: Mutex::new(Book::default()),
        }
    }

    /// The rubric a run of `experiment` is graded by.
    pub(super) fn rubric(&self, experiment: Option<&str>) -> Rubric {
        self.fixed
            .or_else(|| experiment.and_then(|e| self.declared.get(e).copied()))
            .unwrap_or_default()
    }

    /// The most a run of `experiment` may earn.
    pub(super) fn maximum(&self, experiment: Option<&str>) -> f64 {
        self.rubric(experiment).maximum()
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

/// The summary to grade a run by for `assignment`, or why it does not
/// count: ended by someone or something other than its driver, or of
/// another experiment than the assignment's. With an assignment's goal,
/// the goal is reached when the run ends within the usual tolerance of
/// it, whatever goal the learner defined.
pub(super) fn judged(summary: &Summary, assignment: &Assignment) -> Result<Summary, String> {
    summary.ended_by_driver().map_err(|e| e.to_string())?;
    if let Some(wanted) = &assignment.experiment
        && summary.experiment.as_ref() != Some(wanted)
    {
        return Err(format!(
            "the assignment is {wanted}, the run was {}",
            summary.experiment.as_deref().unwrap_or("of no experiment")
        ));
    }
    let mut judged = summary.clone();
    if let Some(goal) = &assignment.goal {
        let (x, y) = goal
            .split_once(',')
            .and_then(|(x, y)| Some((x.trim().parse::<f64>().ok()?, y.trim().parse::<f64>().ok()?)))
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .ok_or_else(|| format!("the assignment's goal {goal:?} is no x,y in mm"))?;
        let at = summary.final_pose;
        judged.reached_goal = (at.x_mm - x).hypot(at.y_mm - y) <= Goal::DEFAULT_TOLERANCE_MM;
    }
    Ok(judged)
}

impl Lti {
    /// Grades the runs of this lab as they end, for as long as it runs.
    pub(crate) async fn grade_runs(self: Arc<Self>, mut events: broadcast::Receiver<LabEvent>) {
        loop {
            match events.recv().await {
                Ok(LabEvent::RunEnded(ended)) => {
                    if let Some(driver) = &ended.driver {
                        self.run_ended(ended.run, &driver.admitted, &ended.summary);
                    }
                }
                Err(broadcast::error::RecvError::Lagged(missed)) => {
                    warn!(
                        "{missed} of the lab's events went by ungraded: the LMS side fell behind"
                    );
                }
                Err(broadcast::error::RecvError::Closed) => return,
            }
        }
    }

    /// Grades, and sends, a run `admitted` drove (run `run` of this lab,
    /// when it is this lab's), if an LMS launch's session let them in: for
    /// that launch, its assignment and its line item.
    pub(crate) fn run_ended(
        self: &Arc<Self>,
        run: Option<u64>,
        admitted: &Admitted,
        summary: &Summary,
    ) {
        let Some(launch) = admitted.session.and_then(|id| self.sessions.launch_of(id)) else {
            return;
        };
        let user = launch.user.as_str();
        let named = run.map_or_else(|| "A run".to_owned(), |run| format!("Run {run}"));
        let judged = judged(summary, &launch.assignment);
        let rubric = self.grades.rubric(summary.experiment.as_deref());
        let graded = judged.as_ref().map(|s| rubric.grade(s));
        let (given, maximum, comment, sent) = match &graded {
            Ok(grade) => {
                let comment = format!("{named}, {}. {}", summary.ending(), grade.comment());
                let sent = if launch.lineitem.is_some() {
                    self.grades.book().status.sending += 1;
                    Sent::Sending
                } else {
                    Sent::NoLineItem
                };
                (grade.given, grade.maximum, comment, sent)
            }
            Err(why) => {
                info!(user, "a run that does not count for a grade: {why}");
                self.audit.record(
                    AuditEntry::new("grade_withheld")
                        .user(Some(user))
                        .detail(format!("{named}: {why}")),
                );
                let maximum = rubric.maximum();
                let comment = format!("{named}, {}: not counted, {why}.", summary.ending());
                (0.0, maximum, comment, Sent::NotCounted(why.to_string()))
            }
        };
        let id = self.grades.keep(
            user,
            Graded {
                id: 0,
                run,
                given,
                maximum,
                ending: summary.ending(),
                comment: comment.clone(),
                sent: sent.clone(),
            },
        );
        if sent != Sent::Sending {
            return;
        }
        let score = serde_json::json!({
            "scoreGiven": given,
            "scoreMaximum": maximum,
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

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::{EndReason, Pose, Role, Stopper};

    fn summary(reason: EndReason, experiment: &str, at: (f64, f64)) -> Summary {
        let json = serde_json::json!({
            "experiment": experiment, "reason": reason, "reached_goal": true, "events": 3,
            "final_pose": Pose { x_mm: at.0, y_mm: at.1, theta_rad: 0.0 },
            "seconds": 2.0, "distance_mm": 60.0, "collisions": 0,
        });
        serde_json::from_value(json).unwrap()
    }

    fn assignment(experiment: &str, goal: &str) -> Assignment {
        Assignment {
            experiment: Some(experiment.into()),
            goal: Some(goal.into()),
        }
    }

    /// The learner's own goal, 60 mm ahead and reached, is not the
    /// assignment's: graded against the link's goal, it is not reached.
    #[test]
    fn a_run_is_graded_against_the_assignment_s_goal() {
        let own = summary(EndReason::GoalReached, "navigation", (160.0, 120.0));
        assert!(!judged_reached(&own, "680,470"));
        let there = summary(EndReason::GoalReached, "navigation", (675.0, 466.0));
        assert!(judged_reached(&there, "680,470"));
        let teleoperated = summary(EndReason::Stopped, "teleoperation", (675.0, 466.0));
        let why = judged(&teleoperated, &assignment("navigation", "680,470")).unwrap_err();
        assert_eq!(
            why,
            "the assignment is navigation, the run was teleoperation"
        );
        assert!(judged(&there, &assignment("navigation", "680;470")).is_err());
    }

    fn judged_reached(summary: &Summary, goal: &str) -> bool {
        judged(summary, &assignment("navigation", goal))
            .unwrap()
            .reached_goal
    }

    /// Only its driver's ending counts: another's emergency stop, a fault,
    /// a lost robot do not.
    #[test]
    fn only_runs_their_driver_ended_count() {
        let none = Assignment::default();
        let mut run = summary(EndReason::EmergencyStop, "teleoperation", (0.0, 0.0));
        run.stopped_by = Some(Stopper {
            role: Role::Operator,
            session: 3,
        });
        assert!(judged(&run, &none).is_ok(), "their own emergency stop");
        run.stopped_by = Some(Stopper {
            role: Role::Observer,
            session: 4,
        });
        assert!(judged(&run, &none).is_err(), "another's");
        for reason in [EndReason::Fault, EndReason::RobotLost, EndReason::Kicked] {
            assert!(judged(&summary(reason, "navigation", (0.0, 0.0)), &none).is_err());
        }
        for reason in [
            EndReason::GoalReached,
            EndReason::TimeLimit,
            EndReason::Stopped,
        ] {
            assert!(judged(&summary(reason, "navigation", (0.0, 0.0)), &none).is_ok());
        }
    }
}
