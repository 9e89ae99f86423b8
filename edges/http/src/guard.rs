//! The guard in front of every route of robotd's HTTP port.
//!
//! One middleware decides, before any handler runs, whether a request may reach the robot:
//!
//! 1. **Host** (DNS-rebinding protection). A web page can make a browser send requests to
//!    `127.0.0.1` under a name the attacker controls; only the `Host` header tells. On a
//!    loopback bind the `Host` must name this machine (`localhost`, `127.0.0.1`, `[::1]`, any
//!    port) or an entry of `[http] allowed_hosts`; on other binds `allowed_hosts`, when set,
//!    restricts it too (the token is the protection there). A request without `Host` is
//!    refused.
//! 2. **Origin**. A browser page from another site gets 403 unless its origin is local or
//!    listed in `[mcp] allowed_origins`.
//! 3. **Bearer token** (`[mcp] token`). When set, every route needs
//!    `Authorization: Bearer <token>`, or the `access_token` query parameter (RFC 6750 §2.3:
//!    what a browser can send for a page, an `<img>` or an event stream) — except `/health`
//!    and `/metrics` on a loopback bind, which monitoring on the same machine reads without it. A non-loopback bind needs a token
//!    ([`check_bind`]), whether MCP is on or off: the port also serves the e-stop, health and
//!    metrics.
//! 4. **Body size** (`[mcp] max_body_bytes`): a larger `Content-Length` is 413 before the body
//!    is read, and streamed bodies are cut at the same limit; except `POST /estop`, which
//!    engages whatever its body (it reads only the first bytes, [`crate::safety`]).

use axum::extract::{DefaultBodyLimit, Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::Router;
use std::net::SocketAddr;
use std::sync::Arc;

/// How the HTTP port is protected.
#[derive(Debug, Clone)]
pub struct HttpGuard {
    /// Required `Authorization: Bearer <token>`; `None` = no token (loopback only).
    pub token: Option<String>,
    /// Largest request body accepted, bytes.
    pub max_body_bytes: usize,
    /// Extra `Origin` values accepted besides local ones (e.g. `https://lab.example.org`).
    pub allowed_origins: Vec<String>,
    /// Extra `Host` names accepted besides local ones (e.g. `robot-pc.lab`), without port.
    pub allowed_hosts: Vec<String>,
    /// Whether the port is bound to a loopback address (Host is then always checked, and
    /// `/health` and `/metrics` need no token).
    pub loopback: bool,
}

impl Default for HttpGuard {
    fn default() -> Self {
        Self {
            token: None,
            max_body_bytes: 1024 * 1024,
            allowed_origins: Vec::new(),
            allowed_hosts: Vec::new(),
            loopback: true,
        }
    }
}

/// Why the HTTP port refuses to start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// A non-loopback address without a token would give the robot to anyone on the network.
    #[error(
        "refusing to serve on {bind} without a bearer token: a non-loopback address exposes \
         the robot (MCP, e-stop, health) to the network. Set [mcp] token (or \
         ROBOTD_MCP__TOKEN), or bind 127.0.0.1"
    )]
    TokenRequired {
        /// The address asked for.
        bind: SocketAddr,
    },
}

/// Checks that `bind` may be served with `guard`.
pub fn check_bind(bind: SocketAddr, guard: &HttpGuard) -> Result<(), StartError> {
    if !bind.ip().is_loopback() && guard.token.as_deref().is_none_or(str::is_empty) {
        return Err(StartError::TokenRequired { bind });
    }
    Ok(())
}

/// `routes` behind `guard` (see the module documentation).
pub fn guarded(routes: Router, guard: HttpGuard) -> Router {
    let limit = guard.max_body_bytes;
    routes
        .layer(DefaultBodyLimit::max(limit))
        .layer(middleware::from_fn_with_state(Arc::new(guard), check))
}

/// The host part of a `Host` header or of an origin's authority, lower-case, without port
/// and brackets.
fn host_name(authority: &str) -> String {
    let host = if let Some(v6) = authority.strip_prefix('[') {
        v6.split(']').next().unwrap_or("")
    } else {
        authority.split(':').next().unwrap_or("")
    };
    host.to_ascii_lowercase()
}

fn is_local_name(host: &str) -> bool {
    matches!(host, "localhost" | "127.0.0.1" | "::1")
}

/// Whether an `Origin` header value names this machine.
pub fn origin_is_local(origin: &str) -> bool {
    let Some((scheme, rest)) = origin.split_once("://") else {
        return false;
    };
    (scheme == "http" || scheme == "https") && is_local_name(&host_name(rest))
}

impl HttpGuard {
    /// Why `host` (a `Host` header) is refused, if it is.
    fn host_refusal(&self, host: Option<&str>) -> Option<String> {
        if !self.loopback && self.allowed_hosts.is_empty() {
            return None;
        }
        let Some(host) = host else {
            return Some("Bad Request: a Host header is required".to_owned());
        };
        let name = host_name(host);
        let allowed = (self.loopback && is_local_name(&name))
            || self
                .allowed_hosts
                .iter()
                .any(|h| h.eq_ignore_ascii_case(&name));
        (!allowed).then(|| {
            format!(
                "Forbidden: Host '{host}' does not name this robotd (DNS-rebinding protection); \
                 add it to [http] allowed_hosts to allow it"
            )
        })
    }

    /// Whether a request from `origin` may go on: a local origin, a configured one, or the
    /// request's own origin (a page robotd served, e.g. the dashboard opened as
    /// `http://robot-pc.lab:8000/`; the `Host` check and, off loopback, the token already
    /// stand in front of it).
    fn origin_allowed(&self, origin: &str, host: Option<&str>) -> bool {
        origin_is_local(origin)
            || self.allowed_origins.iter().any(|o| o == origin)
            || host.is_some_and(|host| is_same_origin(origin, host))
    }
}

/// Whether `origin` (`scheme://authority`) names the server a request with `Host: host` reached.
fn is_same_origin(origin: &str, host: &str) -> bool {
    let Some((scheme, authority)) = origin.split_once("://") else {
        return false;
    };
    let default_port = match scheme {
        "http" => ":80",
        "https" => ":443",
        _ => return false,
    };
    let with_port = |a: &str| {
        if a.ends_with(']') || !a.contains(':') || (a.starts_with('[') && !a.contains("]:")) {
            format!("{a}{default_port}")
        } else {
            a.to_owned()
        }
    };
    !authority.is_empty()
        && !authority.contains('/')
        && with_port(authority).eq_ignore_ascii_case(&with_port(host))
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn check(State(guard): State<Arc<HttpGuard>>, request: Request, next: Next) -> Response {
    match refusal(&guard, &request) {
        // A refused client does not keep its connection: a place under the port's connection
        // cap is not held by requests without the token.
        Some(mut refused) => {
            refused.headers_mut().insert(
                header::CONNECTION,
                header::HeaderValue::from_static("close"),
            );
            refused
        }
        None => next.run(request).await,
    }
}

pub use robotd_web::bearer::bearer_token;

/// The guard's answer to a request it refuses, or `None` to serve it.
fn refusal(guard: &HttpGuard, request: &Request) -> Option<Response> {
    let headers = request.headers();
    let host = headers.get(header::HOST).and_then(|v| v.to_str().ok());
    if let Some(refusal) = guard.host_refusal(host) {
        tracing::warn!(host, "HTTP request with a foreign Host refused");
        let status = if host.is_none() {
            StatusCode::BAD_REQUEST
        } else {
            StatusCode::FORBIDDEN
        };
        return Some((status, refusal).into_response());
    }
    if let Some(origin) = headers.get(header::ORIGIN) {
        let origin = origin.to_str().unwrap_or("");
        if !guard.origin_allowed(origin, host) {
            tracing::warn!(origin, "HTTP request with a foreign Origin refused");
            return Some((
                StatusCode::FORBIDDEN,
                "Forbidden: Origin not allowed (robotd serves local clients and its own pages; \
                 add the origin to [mcp] allowed_origins to allow it)",
            )
                .into_response());
        }
    }
    let monitoring = matches!(request.uri().path(), "/health" | "/metrics");
    if let Some(token) = guard.token.as_deref() {
        let given = bearer_token(headers, request.uri().query()).unwrap_or("");
        let exempt = monitoring && guard.loopback;
        if !exempt && !constant_time_eq(given.as_bytes(), token.as_bytes()) {
            return Some(
                (
                    StatusCode::UNAUTHORIZED,
                    [(header::WWW_AUTHENTICATE, "Bearer")],
                    "Unauthorized: send Authorization: Bearer <token> (or ?access_token=<token>)",
                )
                    .into_response(),
            );
        }
    }
    // A request to stop is never refused for its body: `POST /estop` reads at most what it
    // needs and engages whatever the rest (`crate::safety`).
    let estop = request.method() == axum::http::Method::POST && request.uri().path() == "/estop";
    let too_long = !estop
        && headers
            .get(header::CONTENT_LENGTH)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.parse::<usize>().ok())
            .is_some_and(|n| n > guard.max_body_bytes);
    if too_long {
        return Some(
            (
                StatusCode::PAYLOAD_TOO_LARGE,
                format!(
                    "Payload Too Large: requests are limited to {} bytes",
                    guard.max_body_bytes
                ),
            )
                .into_response(),
        );
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_origins_only() {
        for ok in [
            "http://localhost:6274",
            "http://127.0.0.1",
            "https://[::1]:8000",
        ] {
            assert!(origin_is_local(ok), "{ok}");
        }
        for bad in [
            "http://evil.example.com",
            "http://127.0.0.1.evil.com",
            "null",
            "file://localhost",
            "http://localhost.evil.com:80",
        ] {
            assert!(!origin_is_local(bad), "{bad}");
        }
    }

    #[test]
    fn a_page_robotd_served_may_call_it_from_any_address() {
        let guard = HttpGuard {
            loopback: false,
            token: Some("s3cret".into()),
            ..Default::default()
        };
        let host = Some("robot-pc.lab:8000");
        assert!(guard.origin_allowed("http://robot-pc.lab:8000", host));
        assert!(guard.origin_allowed("http://ROBOT-PC.lab:8000", host));
        assert!(guard.origin_allowed("http://10.0.0.5", Some("10.0.0.5:80")));
        assert!(guard.origin_allowed("https://[fe80::1]", Some("[fe80::1]:443")));
        // The Host header carries no scheme: behind a TLS proxy the page's origin is https.
        assert!(guard.origin_allowed("https://robot-pc.lab:8000", host));
        for other in [
            "http://robot-pc.lab:8001",
            "http://evil.example:8000",
            "http://robot-pc.lab:8000/x",
            "null",
        ] {
            assert!(!guard.origin_allowed(other, host), "{other}");
        }
        assert!(!guard.origin_allowed("http://robot-pc.lab:8000", None));
    }

    #[test]
    fn hosts_on_loopback_must_name_this_machine() {
        let mut guard = HttpGuard::default();
        for ok in ["127.0.0.1:8000", "localhost", "LOCALHOST:1", "[::1]:8000"] {
            assert_eq!(guard.host_refusal(Some(ok)), None, "{ok}");
        }
        for bad in ["evil.example.com", "127.0.0.1.nip.io:8000", "[::2]:80"] {
            assert!(guard.host_refusal(Some(bad)).is_some(), "{bad}");
        }
        assert!(guard.host_refusal(None).is_some());
        guard.allowed_hosts = vec!["robot-pc.lab".into()];
        assert_eq!(guard.host_refusal(Some("Robot-PC.lab:8000")), None);
        // Off loopback: any host unless a list is given.
        guard.loopback = false;
        assert!(guard.host_refusal(Some("127.0.0.1")).is_some());
        guard.allowed_hosts.clear();
        assert_eq!(guard.host_refusal(Some("10.0.0.5:8000")), None);
    }

    #[test]
    fn non_loopback_binds_need_a_token() {
        let open: SocketAddr = "0.0.0.0:8000".parse().unwrap();
        let local: SocketAddr = "127.0.0.1:8000".parse().unwrap();
        let mut guard = HttpGuard::default();
        assert!(check_bind(local, &guard).is_ok());
        let e = check_bind(open, &guard).unwrap_err().to_string();
        // The server reads its token through the configuration's environment layer
        // (`ROBOTD_MCP__TOKEN`, double underscore); naming anything else sends users astray.
        assert!(e.contains("(or ROBOTD_MCP__TOKEN)"), "{e}");
        guard.token = Some("s3cret".into());
        assert!(check_bind(open, &guard).is_ok());
        assert!(constant_time_eq(b"abc", b"abc"));
        assert!(!constant_time_eq(b"abc", b"abd"));
        assert!(!constant_time_eq(b"abc", b"ab"));
    }
}
