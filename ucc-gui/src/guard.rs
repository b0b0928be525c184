//! The guard in front of every route: the `Host` must name the loopback (DNS rebinding),
//! a WebSocket's `Origin` must be the page's own, and beyond the loopback every API and
//! WebSocket request carries the token.

use axum::extract::{Request as HttpRequest, State};
use axum::http::{StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use crate::App;

/// Refuses requests for another host (DNS rebinding), WebSockets from another origin, and
/// API requests without the token.
pub(crate) async fn guard(State(app): State<App>, request: HttpRequest, next: Next) -> Response {
    let headers = request.headers();
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or("");
    if let Err(why) = check_host(host, app.port, app.loopback_only) {
        return (StatusCode::FORBIDDEN, why).into_response();
    }
    let path = request.uri().path();
    if path == "/ws" {
        let origin = headers.get(header::ORIGIN).and_then(|h| h.to_str().ok());
        if origin != Some(format!("http://{host}").as_str()) {
            return (
                StatusCode::FORBIDDEN,
                format!("WebSocket refused: origin {origin:?} is not this page's (http://{host})"),
            )
                .into_response();
        }
    }
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
    next.run(request).await
}

/// Constant-time comparison.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Whether `host` (the `Host` header) may reach a listener on `port`.
pub fn check_host(host: &str, port: u16, loopback_only: bool) -> Result<(), String> {
    if !loopback_only {
        return Ok(());
    }
    let names = ["127.0.0.1", "localhost", "[::1]"];
    let ok = names
        .iter()
        .any(|n| host == *n || host == format!("{n}:{port}"));
    if ok {
        Ok(())
    } else {
        Err(format!(
            "refused: Host {host:?} is not this machine's loopback (open http://127.0.0.1:{port}/)"
        ))
    }
}
