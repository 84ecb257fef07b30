//! The LTI pages on the Host's port: `/lti/login` (third-party login
//! initiation, GET and POST), `/lti/launch` (the platform's signed
//! answer: the lab page logged in, or the instructor's choice of what a
//! link opens), `/lti/deep-link` (that choice, signed back to the
//! platform), `/lti/roster` (the course's members and their runs) and
//! `/lti/jwks` (the tool's public key). A launched page may be framed by
//! the registered platforms only; every refusal is a 4xx page and an
//! audit line, and logs no one in.

use std::net::IpAddr;
use std::sync::Arc;

use axum::extract::{Form, Query, State};
use axum::http::{HeaderName, StatusCode, header};
use axum::response::{IntoResponse, Redirect, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use serde::Deserialize;

use super::Lti;
use super::launch::{LoginRequest, Refused};
use super::sessions::Launch;
use vl_core::Experiments;
use vl_host::AccountRole;
use vl_host::AuditEntry;
use vl_host::web;

/// Who asks, for the audit.
#[derive(Clone)]
struct Asked {
    lti: Arc<Lti>,
    address: IpAddr,
}

/// The LTI routes, for a request from `address`.
pub(crate) fn routes<S: Clone + Send + Sync + 'static>(
    lti: Arc<Lti>,
    address: IpAddr,
) -> Router<S> {
    Router::new()
        .route("/lti/login", get(login_get).post(login_post))
        .route("/lti/launch", post(launch))
        .route("/lti/deep-link", post(deep_link))
        .route("/lti/roster", post(roster))
        .route("/lti/jwks", get(jwks))
        .route("/lti/submit.js", get(submit_js))
        .with_state(Asked { lti, address })
}

/// `text` safe inside HTML text and attribute values.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A page of the tool's own (no framing limits beyond the platforms').
fn page(
    status: StatusCode,
    frame_ancestors: &str,
    form_action: &str,
    title: &str,
    body: &str,
) -> Response {
    let html = format!(
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>vl — {}</title><link rel=\"stylesheet\" href=\"/style.css\"></head>\
         <body class=\"lti\"><h1>{}</h1>{body}</body></html>",
        escape(title),
        escape(title)
    );
    html_page(status, web::policy(frame_ancestors, form_action), html)
}

/// An HTML answer of the LTI pages: never kept by a cache, nor its address
/// (which may carry a session) told to a page it links.
fn html_page(status: StatusCode, policy: String, html: String) -> Response {
    (
        status,
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8".to_owned()),
            (header::CACHE_CONTROL, "no-store".to_owned()),
            (header::CONTENT_SECURITY_POLICY, policy),
            (header::REFERRER_POLICY, "no-referrer".to_owned()),
        ],
        html,
    )
        .into_response()
}

impl Asked {
    /// Where the lab's pages may be framed: itself and the platforms.
    fn frame_ancestors(&self) -> String {
        let mut origins = vec!["'self'".to_owned()];
        if let Ok(registry) = self.lti.platforms() {
            for p in &registry.platforms {
                for origin in p.origins() {
                    if !origins.contains(&origin) {
                        origins.push(origin);
                    }
                }
            }
        }
        origins.join(" ")
    }

    /// A refusal, as a page and an audit line.
    fn refuse(&self, refused: Refused) -> Response {
        self.lti.audit.record(
            AuditEntry::new("lti_refused")
                .address(self.address)
                .detail(refused.why.clone()),
        );
        let mut why = refused.why.clone();
        if let Some(first) = why.get(..1) {
            why.replace_range(..1, &first.to_uppercase());
        }
        let body = format!(
            "<p class=\"error\">{}.</p><p>Nothing was opened. Go back to your course and open the lab from there again; if this stays, tell the lab's administrator.</p>",
            escape(&why)
        );
        page(
            refused.status,
            &self.frame_ancestors(),
            "'none'",
            "The lab could not be opened",
            &body,
        )
    }

    fn login(&self, request: Result<LoginRequest, String>) -> Response {
        let request = match request {
            Ok(request) => request,
            Err(why) => {
                return self.refuse(Refused {
                    status: StatusCode::BAD_REQUEST,
                    why: format!(
                        "a login initiation needs iss, login_hint and target_link_uri: {why}"
                    ),
                });
            }
        };
        match self.lti.login(&request) {
            Ok((to, _state)) => Redirect::to(&to).into_response(),
            Err(refused) => self.refuse(refused),
        }
    }
}

async fn login_get(
    State(asked): State<Asked>,
    query: Result<Query<LoginRequest>, axum::extract::rejection::QueryRejection>,
) -> Response {
    asked.login(query.map(|q| q.0).map_err(|e| e.body_text()))
}

async fn login_post(
    State(asked): State<Asked>,
    form: Result<Form<LoginRequest>, axum::extract::rejection::FormRejection>,
) -> Response {
    asked.login(form.map(|f| f.0).map_err(|e| e.body_text()))
}

#[derive(Deserialize)]
struct LaunchForm {
    id_token: String,
    state: String,
}

async fn launch(
    State(asked): State<Asked>,
    form: Result<Form<LaunchForm>, axum::extract::rejection::FormRejection>,
) -> Response {
    let Ok(Form(form)) = form else {
        return asked.refuse(Refused {
            status: StatusCode::BAD_REQUEST,
            why: "a launch posts id_token and state".into(),
        });
    };
    let launched = match asked.lti.launch(&form.id_token, &form.state).await {
        Ok(launched) => launched,
        Err(refused) => return asked.refuse(refused),
    };
    let who = &launched.launch;
    asked.lti.audit.record(
        AuditEntry::new("lti_launch")
            .address(asked.address)
            .user(Some(&who.user))
            .detail(format!(
                "{}{} from {}{}",
                who.person
                    .as_deref()
                    .map(|p| format!("{p}, "))
                    .unwrap_or_default(),
                who.role,
                who.issuer,
                who.course
                    .as_deref()
                    .map(|c| format!(", course '{c}'"))
                    .unwrap_or_default()
            )),
    );
    match &who.deep_linking {
        Some(_) => choose_page(&asked, &launched.session, &asked.lti.experiments),
        None => lab_page(&asked, &launched.session, who),
    }
}

/// The lab's own page, logged in as the launch's person.
fn lab_page(asked: &Asked, session: &str, launch: &Launch) -> Response {
    let mut meta = format!("<meta name=\"vl-session\" content=\"{}\">", escape(session));
    if launch.role.may_drive() {
        meta.push_str("<meta name=\"vl-drives\" content=\"yes\">");
    }
    let mut assignment = Vec::new();
    if let Some(experiment) = &launch.assignment.experiment {
        assignment.push(format!("the {experiment} experiment"));
    }
    if let Some(goal) = &launch.assignment.goal {
        assignment.push(format!("goal at {goal} mm"));
    }
    if !assignment.is_empty() {
        meta.push_str(&format!(
            "<meta name=\"vl-assignment\" content=\"{}\">",
            escape(&assignment.join(", "))
        ));
    }
    if let Some(goal) = &launch.assignment.goal {
        meta.push_str(&format!(
            "<meta name=\"vl-goal\" content=\"{}\">",
            escape(goal)
        ));
    }
    let roster = launch.role == AccountRole::Admin && launch.memberships.is_some();
    if roster {
        meta.push_str("<meta name=\"vl-roster\" content=\"/lti/roster\">");
    }
    let html = web::index().replacen("<head>", &format!("<head>\n{meta}"), 1);
    // The roster is posted to, from this page.
    let forms = if roster { "'self'" } else { "'none'" };
    let policy = web::policy(&asked.frame_ancestors(), forms);
    html_page(StatusCode::OK, policy, html)
}

/// What an instructor chooses a link to open: an experiment, and a goal.
fn choose_page(asked: &Asked, session: &str, experiments: &Experiments) -> Response {
    let options: String = experiments
        .experiments()
        .map(|e| {
            format!(
                "<option value=\"{id}\">{id}: {title}</option>",
                id = escape(e.id.as_str()),
                title = escape(&e.title)
            )
        })
        .collect();
    let body = format!(
        "<form method=\"post\" action=\"/lti/deep-link\" class=\"lti\">\
         <input type=\"hidden\" name=\"session\" value=\"{}\">\
         <label>Title <input name=\"title\" value=\"Mobile robotics lab\" maxlength=\"100\" required></label>\
         <label>Experiment <select name=\"experiment\">{options}</select></label>\
         <label>Goal x, mm <input name=\"goal_x\" type=\"number\" min=\"0\" max=\"10000\"></label>\
         <label>Goal y, mm <input name=\"goal_y\" type=\"number\" min=\"0\" max=\"10000\"></label>\
         <button>Add to the course</button></form>",
        escape(session)
    );
    page(
        StatusCode::OK,
        &asked.frame_ancestors(),
        "'self'",
        "Choose what this link opens",
        &body,
    )
}

#[derive(Deserialize)]
struct Choice {
    session: String,
    title: String,
    experiment: String,
    #[serde(default)]
    goal_x: Option<String>,
    #[serde(default)]
    goal_y: Option<String>,
}

/// The instructor's choice, signed back to the platform.
async fn deep_link(
    State(asked): State<Asked>,
    form: Result<Form<Choice>, axum::extract::rejection::FormRejection>,
) -> Response {
    let Ok(Form(choice)) = form else {
        return asked.refuse(Refused {
            status: StatusCode::BAD_REQUEST,
            why: "a choice posts session, title and experiment".into(),
        });
    };
    let session = choice.session.clone();
    match asked.lti.deep_link_response(&session, &choice.into_item()) {
        Ok((return_url, jwt)) => {
            let origin = url::Url::parse(&return_url)
                .map(|u| u.origin().ascii_serialization())
                .unwrap_or_default();
            let body = format!(
                "<form id=\"return\" method=\"post\" action=\"{}\">\
                 <input type=\"hidden\" name=\"JWT\" value=\"{}\">\
                 <button>Back to the course</button></form>\
                 <script src=\"/lti/submit.js\"></script>",
                escape(&return_url),
                escape(&jwt)
            );
            page(
                StatusCode::OK,
                &asked.frame_ancestors(),
                &origin,
                "Added to the course",
                &body,
            )
        }
        Err(refused) => asked.refuse(refused),
    }
}

impl Choice {
    fn into_item(self) -> super::deep_link::Item {
        let number = |v: &Option<String>| {
            v.as_deref()
                .and_then(|s| s.trim().parse::<f64>().ok())
                .filter(|n| n.is_finite() && (0.0..=10_000.0).contains(n))
        };
        super::deep_link::Item {
            title: self.title.chars().take(100).collect(),
            experiment: self.experiment,
            goal: number(&self.goal_x).zip(number(&self.goal_y)),
        }
    }
}

async fn submit_js() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        "document.getElementById(\"return\").submit();\n",
    )
}

async fn jwks(State(asked): State<Asked>) -> impl IntoResponse {
    (
        [(HeaderName::from_static("cache-control"), "max-age=300")],
        Json(asked.lti.key.jwks()),
    )
}

/// The roster's form: the instructor's session, in the body, never in a URL.
#[derive(Deserialize)]
struct RosterForm {
    session: String,
}

/// The course's members, and each one's runs here.
async fn roster(
    State(asked): State<Asked>,
    form: Result<Form<RosterForm>, axum::extract::rejection::FormRejection>,
) -> Response {
    let launch = form
        .ok()
        .and_then(|f| asked.lti.sessions.launch(&f.session));
    let Some(launch) = launch.filter(|l| l.role == AccountRole::Admin) else {
        return asked.refuse(Refused {
            status: StatusCode::FORBIDDEN,
            why: "the roster is the course's instructors': open it from an instructor's launch"
                .into(),
        });
    };
    match asked.lti.roster_rows(&launch).await {
        Ok(rows) => page(
            StatusCode::OK,
            &asked.frame_ancestors(),
            "'none'",
            &format!(
                "Who has run what{}",
                launch
                    .course
                    .as_deref()
                    .map(|c| format!(" in {c}"))
                    .unwrap_or_default()
            ),
            &roster_table(&rows),
        ),
        Err(e) => asked.refuse(Refused {
            status: StatusCode::BAD_GATEWAY,
            why: e.to_string(),
        }),
    }
}

fn roster_table(rows: &[super::roster::RosterRow]) -> String {
    let mut html = String::from(
        "<table class=\"roster\"><thead><tr><th>member</th><th>role</th><th>runs</th>\
         <th>best score</th><th>last run</th><th>sent to the LMS</th></tr></thead><tbody>",
    );
    for row in rows {
        let last = row.runs.last();
        let best = row
            .runs
            .iter()
            .map(|g| (g.given, g.maximum))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        html.push_str(&format!(
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            escape(&row.name),
            escape(&row.roles),
            row.runs.len(),
            best.map(|(g, m)| format!("{g:.1} of {m:.0}"))
                .unwrap_or_else(|| "—".into()),
            escape(&last.map(|g| g.ending.clone()).unwrap_or_else(|| "—".into())),
            escape(&last.map(|g| g.sent.words()).unwrap_or_else(|| "—".into())),
        ));
    }
    html.push_str("</tbody></table>");
    html
}
