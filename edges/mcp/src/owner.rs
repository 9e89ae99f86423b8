//! Who opened an MCP session, so that only they can use it.
//!
//! A session id travels in URLs (`/messages/?session_id=…`) and headers (`Mcp-Session-Id`)
//! and ends up in proxies' logs. Knowing it must not be enough to post into someone else's
//! session: each session is bound to the client that opened it — its IP address and the
//! credential it presented (the bearer token, from `Authorization: Bearer …` or the guard's
//! `?access_token=…`, so a client may use either on any request; any other `Authorization`
//! as sent), compared by a keyed hash, never stored. A
//! request naming a session with another owner is answered exactly like one naming an
//! unknown session (404), so ids cannot be probed either.

use axum::extract::ConnectInfo;
use axum::http::{header, Extensions, HeaderMap};
use std::collections::hash_map::RandomState;
use std::hash::BuildHasher;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::OnceLock;

/// The client a session belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SessionOwner {
    peer: IpAddr,
    credential: u64,
}

impl SessionOwner {
    /// The owner of a request with `headers`, URL `query` and `extensions` (where axum puts
    /// the peer's `ConnectInfo<SocketAddr>`; without it the peer counts as unspecified).
    pub fn of(headers: &HeaderMap, query: Option<&str>, extensions: &Extensions) -> Self {
        let peer = extensions
            .get::<ConnectInfo<SocketAddr>>()
            .map(|info| canonical(info.0.ip()))
            .unwrap_or(IpAddr::V4(Ipv4Addr::UNSPECIFIED));
        // The token as the guard reads it; any other Authorization as sent.
        let credential = robotd_web::bearer::bearer_token(headers, query)
            .map(str::as_bytes)
            .or_else(|| headers.get(header::AUTHORIZATION).map(|v| v.as_bytes()))
            .unwrap_or_default();
        Self {
            peer,
            credential: credential_hasher().hash_one(credential),
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
        owner_with_query(peer, auth, None)
    }

    fn owner_with_query(peer: &str, auth: Option<&str>, query: Option<&str>) -> SessionOwner {
        let mut headers = HeaderMap::new();
        if let Some(auth) = auth {
            headers.insert(header::AUTHORIZATION, HeaderValue::from_str(auth).unwrap());
        }
        let mut extensions = Extensions::new();
        extensions.insert(ConnectInfo::<SocketAddr>(peer.parse().unwrap()));
        SessionOwner::of(&headers, query, &extensions)
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

    #[test]
    fn the_token_counts_the_same_from_the_header_or_the_url() {
        let header = owner("127.0.0.1:1", Some("Bearer s3cret"));
        let url = owner_with_query(
            "127.0.0.1:2",
            None,
            Some("session_id=a&access_token=s3cret"),
        );
        assert_eq!(header, url);
        let other = owner_with_query("127.0.0.1:2", None, Some("access_token=other"));
        assert_ne!(header, other);
        assert_ne!(header, owner("127.0.0.1:1", None));
    }
}
