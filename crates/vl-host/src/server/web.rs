//! The web Guest: a page, its script and its style, built into `vl` and
//! served on the Host's own port, so watching or driving the lab needs
//! nothing installed but a browser. The page speaks the same protocol as
//! `vl guest` over a WebSocket to the same port: the same limits and the
//! same supervisor judge what it sends.

use axum::Router;
use axum::http::header;
use axum::routing::get;

/// Each file: where it is served, its media type, its bytes.
const FILES: [(&str, &str, &str); 4] = [
    (
        "/",
        "text/html; charset=utf-8",
        include_str!("../../web/index.html"),
    ),
    (
        "/app.js",
        "text/javascript; charset=utf-8",
        include_str!("../../web/app.js"),
    ),
    (
        "/protocol.js",
        "text/javascript; charset=utf-8",
        include_str!("../../web/protocol.js"),
    ),
    (
        "/style.css",
        "text/css; charset=utf-8",
        include_str!("../../web/style.css"),
    ),
];

/// The colour legend the desktop window draws with, as the page's script
/// (made once).
static LEGEND_JS: std::sync::LazyLock<String> = std::sync::LazyLock::new(legend_js);

fn legend_js() -> String {
    let marks: Vec<serde_json::Value> = vl_core::Mark::ALL
        .iter()
        .map(|m| serde_json::json!({"id": m.id(), "colour": m.css(), "words": m.words()}))
        .collect();
    format!(
        "// The lab's colour legend, as the desktop window draws (vl-core's Mark).\n\
         const LEGEND = {};\n",
        serde_json::Value::Array(marks)
    )
}

/// The pages' content policy: their own scripts, styles and socket, the
/// camera's frames as blobs, and no one may frame them (a page in a frame
/// could be made to click STOP, or Start, for someone else).
static POLICY: std::sync::LazyLock<String> =
    std::sync::LazyLock::new(|| policy("'none'", "'none'"));

/// The content policy of a page that `frame_ancestors` may frame (an LMS
/// launch's: the registered platforms) and whose forms go to `form_action`.
pub fn policy(frame_ancestors: &str, form_action: &str) -> String {
    format!(
        "default-src 'self'; connect-src 'self'; img-src 'self' blob: data:; \
         style-src 'self'; script-src 'self'; object-src 'none'; base-uri 'none'; \
         frame-ancestors {frame_ancestors}; form-action {form_action}"
    )
}

/// The web Guest's page.
pub fn index() -> &'static str {
    FILES[0].2
}

/// The web Guest's routes.
pub(super) fn routes<S: Clone + Send + Sync + 'static>() -> Router<S> {
    let legend: &'static str = LEGEND_JS.as_str();
    let policy: &'static str = POLICY.as_str();
    let script = [
        (header::CONTENT_TYPE, "text/javascript; charset=utf-8"),
        (header::CACHE_CONTROL, "no-cache"),
    ];
    FILES
        .iter()
        .fold(Router::new(), |router, &(path, media_type, body)| {
            router.route(
                path,
                get(move || async move {
                    // Asked again each load: a Host updated serves its new page.
                    (
                        [
                            (header::CONTENT_TYPE, media_type),
                            (header::CACHE_CONTROL, "no-cache"),
                            (header::CONTENT_SECURITY_POLICY, policy),
                            (header::X_FRAME_OPTIONS, "DENY"),
                        ],
                        body,
                    )
                }),
            )
        })
        .route("/legend.js", get(move || async move { (script, legend) }))
}
