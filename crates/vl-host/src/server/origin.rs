//! Which web pages may open a WebSocket to the lab. A browser sends the
//! page's origin with every WebSocket it opens, and lets any page open one
//! to any address: without this check a page from anywhere, opened by a
//! student, would drive the robot with the student's powers. Clients that
//! are no browser (`vl guest`, scripts, Foxglove's desktop app) send no
//! `Origin` and are judged by their hello as before.

/// The origins allowed besides the Host's own (`--allow-origin`).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct AllowedOrigins(Vec<String>);

/// An origin that is no web page's (`scheme://host[:port]`).
#[derive(Debug, thiserror::Error)]
#[error(
    "{0:?} is not a web page's origin (http:// or https://, a host, a port if any, nothing after)"
)]
pub struct NotAnOrigin(String);

impl AllowedOrigins {
    /// The origins `listed`, each `http(s)://host[:port]`.
    pub fn new<S: AsRef<str>>(listed: &[S]) -> Result<AllowedOrigins, NotAnOrigin> {
        listed
            .iter()
            .map(|o| normal(o.as_ref()).ok_or_else(|| NotAnOrigin(o.as_ref().to_owned())))
            .collect::<Result<_, _>>()
            .map(AllowedOrigins)
    }

    /// Whether a WebSocket opened with `origin` (none from a client that is
    /// no browser) to the Host named `host` (the request's `Host`) may go
    /// on; if not, why, in words for the page's developer.
    pub(crate) fn admit(&self, origin: Option<&str>, host: Option<&str>) -> Result<(), String> {
        let Some(origin) = origin else { return Ok(()) };
        if let Some(page) = normal(origin) {
            let same = host.is_some_and(|host| {
                page.split_once("://")
                    .is_some_and(|(_, authority)| authority.eq_ignore_ascii_case(host.trim()))
            });
            if same || self.0.contains(&page) {
                return Ok(());
            }
        }
        Err(format!(
            "a page from {origin} may not use this lab: its Host lets in its own pages, and those of --allow-origin"
        ))
    }
}

/// `origin` as `scheme://host[:port]`, lower case, the default port left
/// out; none if it is no http(s) origin.
fn normal(origin: &str) -> Option<String> {
    let url = url::Url::parse(origin).ok()?;
    let bare = url.path() == "/" && url.query().is_none() && url.fragment().is_none();
    let web = matches!(url.scheme(), "http" | "https");
    let anonymous = url.username().is_empty() && url.password().is_none();
    if !(bare && web && anonymous) {
        return None;
    }
    let host = url.host_str()?;
    Some(match url.port() {
        Some(port) => format!("{}://{host}:{port}", url.scheme()),
        None => format!("{}://{host}", url.scheme()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn its_own_pages_and_the_listed_origins_only() {
        let none = AllowedOrigins::default();
        let host = Some("127.0.0.1:7400");
        assert!(none.admit(None, host).is_ok(), "no browser");
        assert!(none.admit(Some("http://127.0.0.1:7400"), host).is_ok());
        assert!(
            none.admit(Some("HTTPS://LAB.example:7400"), Some("lab.example:7400"))
                .is_ok()
        );
        let evil = none.admit(Some("http://evil.example"), host).unwrap_err();
        assert!(evil.contains("http://evil.example"), "{evil}");
        assert!(none.admit(Some("null"), host).is_err(), "a sandboxed page");
        assert!(
            none.admit(Some("http://127.0.0.1:7401"), host).is_err(),
            "another port"
        );
        let foxglove = AllowedOrigins::new(&["https://app.foxglove.dev"]).unwrap();
        assert!(
            foxglove
                .admit(Some("https://app.foxglove.dev"), host)
                .is_ok()
        );
        assert!(
            foxglove
                .admit(Some("https://app.foxglove.dev.evil.example"), host)
                .is_err()
        );
        for bad in [
            "app.foxglove.dev",
            "ftp://x",
            "https://x/path",
            "https://u:p@x",
        ] {
            assert!(AllowedOrigins::new(&[bad]).is_err(), "{bad}");
        }
    }
}
