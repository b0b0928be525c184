//! The guard in front of every route: the `Host` must name this server (DNS rebinding), a
//! request from a page of another site is refused (its `Origin` or `Sec-Fetch-Site` says
//! so), beyond the loopback every API and WebSocket request carries the token, and a request
//! is read and answered within the page timeout (a slow sender does not keep its task).

use std::net::IpAddr;

use axum::extract::{Request as HttpRequest, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use crate::App;

/// Refuses requests for another host (DNS rebinding), requests from another site (cross-site
/// requests, WebSockets included), API requests without the token, and requests not read and
/// answered within the page timeout.
pub(crate) async fn guard(State(app): State<App>, request: HttpRequest, next: Next) -> Response {
    let headers = request.headers();
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or("");
    if let Err(why) = app.hosts.check(host) {
        return refuse(&app, StatusCode::FORBIDDEN, why);
    }
    if let Err(why) = same_site(headers, host) {
        let what = format!("{} {}", request.method(), request.uri().path());
        return refuse(
            &app,
            StatusCode::FORBIDDEN,
            format!("{what} refused: {why}"),
        );
    }
    let path = request.uri().path();
    if (path == "/ws" || path.starts_with("/api/"))
        && let Some(token) = &app.token
    {
        let given = request
            .uri()
            .query()
            .unwrap_or("")
            .split('&')
            .find_map(|kv| kv.strip_prefix("token="))
            .unwrap_or("");
        if !same(given.as_bytes(), token.as_bytes()) {
            return (
                StatusCode::UNAUTHORIZED,
                "missing or wrong token: open the URL printed by `ucc gui`",
            )
                .into_response();
        }
    }
    // The handler reads the request's body: a body sent slowly ends here (a WebSocket's
    // upgrade returns at once; the page's session has its own timeout).
    match tokio::time::timeout(app.page_timeout, next.run(request)).await {
        Ok(response) => response,
        Err(_) => (
            StatusCode::REQUEST_TIMEOUT,
            format!(
                "the request was not received within {} s (--page-timeout)",
                app.page_timeout.as_secs_f64()
            ),
        )
            .into_response(),
    }
}

/// Refuses with `why`, logged on the terminal and in the page's log: the first 8 refusals,
/// then the 16th, 32nd, 64th… with the count (a page that keeps trying floods neither).
fn refuse(app: &App, status: StatusCode, why: String) -> Response {
    let noted = app
        .refusals
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .note();
    if let Some(count) = noted {
        let line = if count > 8 {
            format!("{why} (refusal {count})")
        } else {
            why.clone()
        };
        tracing::warn!("ucc gui: {line}");
        app.shared.lock().log(0, "warn", line);
    }
    (status, why).into_response()
}

/// Whether a request comes from this page (or from no page: curl, scripts, tests). A browser
/// names the page that sent a request in `Origin` (always for a WebSocket and a POST) and,
/// recent ones, in `Sec-Fetch-Site`; a page of another site is refused.
fn same_site(headers: &HeaderMap, host: &str) -> Result<(), String> {
    if let Some(origin) = headers.get(header::ORIGIN) {
        let origin = origin.to_str().unwrap_or("(not text)");
        let own = [format!("http://{host}"), format!("https://{host}")];
        if !own.iter().any(|o| o.eq_ignore_ascii_case(origin)) {
            return Err(format!(
                "it comes from a page of {} (Origin), not from this page (http://{host})",
                quoted(origin)
            ));
        }
    }
    if let Some(site) = headers.get("sec-fetch-site") {
        let site = site.to_str().unwrap_or("(not text)");
        if !["same-origin", "none"].contains(&site) {
            return Err(format!(
                "it comes from a page of another site (Sec-Fetch-Site: {})",
                quoted(site)
            ));
        }
    }
    Ok(())
}

/// A peer's text in a message: quoted, escaped and shortened.
fn quoted(text: &str) -> String {
    format!("\"{}\"", usar_proto::shown::Shown(text))
}

/// Constant-time comparison.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The `Host` values a listener answers: its own address, the loopback's names, and the
/// names the user allowed (`--allow-host`).
#[derive(Debug, Clone)]
pub struct Hosts {
    /// The listener's address.
    pub listen: std::net::SocketAddr,
    /// Names allowed besides (any port), compared without case.
    pub allowed: Vec<String>,
}

impl Hosts {
    /// Whether `host` (the `Host` header) may reach this listener. Anything else is refused:
    /// a page of another site whose name was made to resolve to this machine (DNS
    /// rebinding) sends its own name.
    pub fn check(&self, host: &str) -> Result<(), String> {
        let port = self.listen.port();
        let (name, given_port) = split_host(host);
        let name = name.to_ascii_lowercase();
        if self
            .allowed
            .iter()
            .any(|a| a.eq_ignore_ascii_case(&name) || a.eq_ignore_ascii_case(host))
        {
            return Ok(());
        }
        let port_ok = match given_port {
            Some(p) => p == Some(port),
            None => port == 80,
        };
        let ip = name
            .trim_start_matches('[')
            .trim_end_matches(']')
            .parse::<IpAddr>()
            .ok();
        let listen = self.listen.ip();
        let name_ok = name == "localhost"
            || ip.is_some_and(|ip| {
                ip.is_loopback()
                    || ip == listen
                    // Listening on every address: any address of this machine names it, and an
                    // address is never a rebound name.
                    || (listen.is_unspecified() && (listen.is_ipv6() || ip.is_ipv4()))
            });
        if port_ok && name_ok {
            return Ok(());
        }
        Err(format!(
            "refused: Host {} is not this server's address (open {}; a name of this machine \
             needs --allow-host NAME)",
            quoted(host),
            crate::url(self.listen, None)
        ))
    }
}

/// `name:port` split: `Some(Some(port))`, `Some(None)` for a port that is not one, `None`
/// without a port. An IPv6 address keeps its brackets.
fn split_host(host: &str) -> (&str, Option<Option<u16>>) {
    let (name, rest) = match host.find(']') {
        Some(i) if host.starts_with('[') => host.split_at(i + 1),
        _ => match host.rfind(':') {
            Some(i) => host.split_at(i),
            None => (host, ""),
        },
    };
    match rest.strip_prefix(':') {
        Some(p) => (name, Some(p.parse().ok())),
        None if rest.is_empty() => (name, None),
        None => (host, Some(None)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hosts() {
        let local = Hosts {
            listen: "127.0.0.1:8080".parse().unwrap(),
            allowed: vec!["gui.lab".into()],
        };
        for ok in [
            "127.0.0.1:8080",
            "localhost:8080",
            "LOCALHOST:8080",
            "[::1]:8080",
            "gui.lab",
            "GUI.lab:443",
        ] {
            assert!(local.check(ok).is_ok(), "{ok}");
        }
        for bad in [
            "evil.example:8080",
            "127.0.0.1:8081",
            "127.0.0.1",
            "localhost",
            "",
            "localhost.evil.example:8080",
            "192.168.1.5:8080",
            "[::1]:x",
            "127.0.0.1:8080:8080",
        ] {
            let e = local.check(bad).unwrap_err();
            assert!(e.contains("http://127.0.0.1:8080/"), "{bad}: {e}");
        }
        let any = Hosts {
            listen: "0.0.0.0:80".parse().unwrap(),
            allowed: Vec::new(),
        };
        for ok in ["192.168.1.5", "10.0.0.1:80", "localhost"] {
            assert!(any.check(ok).is_ok(), "{ok}");
        }
        for bad in ["evil.example", "10.0.0.1:81", "[fe80::1]"] {
            assert!(any.check(bad).is_err(), "{bad}");
        }
        let one = Hosts {
            listen: "192.168.1.5:8080".parse().unwrap(),
            allowed: Vec::new(),
        };
        assert!(one.check("192.168.1.5:8080").is_ok());
        assert!(one.check("192.168.1.6:8080").is_err());
    }
}
