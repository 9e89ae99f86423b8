//! Who opened an MCP session, so that only they can use it.
//!
//! A session id travels in URLs (`/messages/?session_id=…`) and headers (`Mcp-Session-Id`)
//! and ends up in proxies' logs. Knowing it must not be enough to post into someone else's
//! session: each session is bound to the client that opened it — its IP address and the
//! credential it presented (`Authorization`, compared by a keyed hash, never stored). A
//! request naming a session with another owner is answered exactly like one naming an
//! unknown session (404), so ids cannot be probed either.

use axum::extract::ConnectInfo;
use axum::http::{header, Extensions, HeaderMap};
use std::collections::hash_map::RandomState;
use std::hash::BuildHasher;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::OnceLock;

/// The client a session belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SessionOwner {
    peer: IpAddr,
    credential: u64,
}

impl SessionOwner {
    /// The owner of a request with `headers` and `extensions` (where axum puts the peer's
    /// `ConnectInfo<SocketAddr>`; without it the peer counts as unspecified).
    pub fn of(headers: &HeaderMap, extensions: &Extensions) -> Self {
        let peer = extensions
            .get::<ConnectInfo<SocketAddr>>()
            .map(|info| canonical(info.0.ip()))
            .unwrap_or(IpAddr::V4(Ipv4Addr::UNSPECIFIED));
        let authorization = headers
            .get(header::AUTHORIZATION)
            .map(|v| v.as_bytes())
            .unwrap_or_default();
        Self {
            peer,
            credential: credential_hasher().hash_one(authorization),
        }
    }
}

/// `::1` and IPv4-mapped addresses as their IPv4 form, so one client is one address.
fn canonical(ip: IpAddr) -> IpAddr {
    match ip {
        IpAddr::V6(v6) if v6.is_loopback() => IpAddr::V4(Ipv4Addr::LOCALHOST),
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(ip, IpAddr::V4),
        v4 => v4,
    }
}

/// One random key per process: the hashes mean nothing outside it.
fn credential_hasher() -> &'static RandomState {
    static KEY: OnceLock<RandomState> = OnceLock::new();
    KEY.get_or_init(RandomState::new)
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn owner(peer: &str, auth: Option<&str>) -> SessionOwner {
        let mut headers = HeaderMap::new();
        if let Some(auth) = auth {
            headers.insert(header::AUTHORIZATION, HeaderValue::from_str(auth).unwrap());
        }
        let mut extensions = Extensions::new();
        extensions.insert(ConnectInfo::<SocketAddr>(peer.parse().unwrap()));
        SessionOwner::of(&headers, &extensions)
    }

    #[test]
    fn same_client_same_owner() {
        let a = owner("127.0.0.1:5000", Some("Bearer x"));
        assert_eq!(a, owner("127.0.0.1:6000", Some("Bearer x")));
        assert_eq!(a, owner("[::1]:6000", Some("Bearer x")));
        assert_eq!(a, owner("[::ffff:127.0.0.1]:1", Some("Bearer x")));
        assert_ne!(a, owner("127.0.0.2:5000", Some("Bearer x")));
        assert_ne!(a, owner("127.0.0.1:5000", Some("Bearer y")));
        assert_ne!(a, owner("127.0.0.1:5000", None));
    }
}
