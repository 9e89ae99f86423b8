//! The MCP edge shares its session places fairly (issue 43, item 5), over real sockets
//! against a served robotd, on both transports: one client's abandoned sessions never keep
//! another client out, a session that never made a call gives its place back after
//! `mcp.unused_session_timeout_s`, a 503's `Retry-After` is the time until a place really frees,
//! and an unknown session is 404 on every method, `DELETE /mcp` included (item 8).
//!
//! Clients are told apart by their address: 127.0.0.1, .2, .3 are three clients on this
//! machine (Linux routes all of 127.0.0.0/8 to the loopback).

mod common;
mod mcp_raw;

use mcp_raw::{
    open_sse, open_streamable, open_streamable_in_use, post_mcp, request, try_open_sse, SseStream,
    INITIALIZED,
};
use std::collections::VecDeque;
use std::net::Ipv4Addr;
use std::time::{Duration, Instant};

const ABANDONER: Ipv4Addr = Ipv4Addr::new(127, 0, 0, 1);
const NEWCOMER: Ipv4Addr = Ipv4Addr::new(127, 0, 0, 2);
const THIRD: Ipv4Addr = Ipv4Addr::new(127, 0, 0, 3);

/// The default share of one client (`mcp.max_sessions_per_client`).
const SHARE: usize = 80;

/// Times `open`, which must succeed, and returns how long it took.
fn timed<T>(what: &str, open: impl FnOnce() -> T) -> Duration {
    let started = Instant::now();
    open();
    let took = started.elapsed();
    eprintln!("{what}: a session in {took:?}");
    took
}

#[test]
fn after_1000_abandoned_sessions_a_new_client_gets_one_at_once() {
    let namespace = common::fresh_namespace("abandon");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &[]);

    // Streamable HTTP: 1,000 `initialize`s from one client that never come back. Each one
    // is served: past its share the client gives up its oldest unused session.
    let started = Instant::now();
    for n in 0..1000 {
        let answer = post_mcp(ABANDONER, port, None, mcp_raw::INIT);
        assert_eq!(answer.status, 200, "initialize {n}: {answer:?}");
    }
    eprintln!(
        "1,000 abandoned streamable-HTTP sessions in {:?}",
        started.elapsed()
    );
    let at_once = Duration::from_secs(2);
    let took = timed("a new client on /mcp", || open_streamable(NEWCOMER, port));
    assert!(took < at_once, "{took:?}");
    let took = timed("a new client on /sse", || open_sse(NEWCOMER, port));
    assert!(took < at_once, "{took:?}");
    let took = timed("the abandoner itself on /mcp", || {
        open_streamable(ABANDONER, port)
    });
    assert!(took < at_once, "{took:?}");

    // Legacy SSE: 1,000 streams from one client that never post. Past its share, each new
    // one ends the client's oldest unused session: its stream closes (read to its end here).
    let started = Instant::now();
    let mut held: VecDeque<SseStream> = VecDeque::new();
    for n in 0..1000 {
        let stream = try_open_sse(ABANDONER, port)
            .unwrap_or_else(|answer| panic!("GET /sse {n}: {answer:?}"));
        held.push_back(stream);
        if held.len() > SHARE {
            let mut oldest = held.pop_front().unwrap();
            oldest.until_closed();
        }
    }
    eprintln!("1,000 abandoned SSE sessions in {:?}", started.elapsed());
    let took = timed("a new client on /sse", || open_sse(NEWCOMER, port));
    assert!(took < at_once, "{took:?}");
    let took = timed("a new client on /mcp", || open_streamable(THIRD, port));
    assert!(took < at_once, "{took:?}");
    // The newcomer's sessions work.
    let session = open_streamable_in_use(NEWCOMER, port);
    let ping = br#"{"jsonrpc":"2.0","id":9,"method":"ping"}"#;
    assert_eq!(post_mcp(NEWCOMER, port, Some(&session), ping).status, 200);
}

#[test]
fn a_session_without_a_call_ends_and_the_503_says_when_a_place_frees() {
    let namespace = common::fresh_namespace("unused");
    let port = common::free_port();
    let _robotd = common::start_robotd(
        &namespace,
        port,
        &[
            "--set",
            "mcp.max_sessions=2",
            "--set",
            "mcp.unused_session_timeout_s=3",
        ],
    );
    // One session in use (streamable) and one that never makes a call (SSE).
    let in_use = open_streamable_in_use(ABANDONER, port);
    let mut unused = open_sse(NEWCOMER, port);
    let refused = post_mcp(THIRD, port, None, mcp_raw::INIT);
    let refused_at = Instant::now();
    assert_eq!(refused.status, 503, "{refused:?}");
    assert!(
        refused.body.contains("mcp.max_sessions"),
        "{}",
        refused.body
    );
    let retry_after: u64 = refused
        .header("retry-after")
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no Retry-After: {refused:?}"));
    // Sessions end on a whole second: 3 s after it opened, or less than a second later.
    assert!((1..=4).contains(&retry_after), "Retry-After: {retry_after}");
    // The unused session's stream ends when its time is up, and that is when a place frees.
    unused.until_closed();
    let waited = refused_at.elapsed().as_secs_f64();
    eprintln!("Retry-After {retry_after} s; the place freed after {waited:.2} s");
    assert!(
        waited <= retry_after as f64 + 0.5 && waited >= retry_after as f64 - 1.0,
        "Retry-After said {retry_after} s, the place freed after {waited:.2} s"
    );
    let fresh = open_streamable(THIRD, port);
    // The session in use lives on.
    let ping = br#"{"jsonrpc":"2.0","id":5,"method":"ping"}"#;
    assert_eq!(post_mcp(ABANDONER, port, Some(&in_use), ping).status, 200);

    // A streamable-HTTP session that made no call ends too: its standalone event stream
    // closes, and it is unknown from then on.
    let mut events = mcp_raw::connect_from(THIRD, port);
    let headers = [
        ("Accept", "text/event-stream"),
        ("Mcp-Session-Id", fresh.as_str()),
    ];
    mcp_raw::send(&mut events, "GET", "/mcp", &headers, b"");
    let stream = mcp_raw::read_answer(&mut events);
    assert_eq!(stream.status, 200, "{stream:?}");
    let answer = post_mcp(THIRD, port, Some(&fresh), INITIALIZED);
    assert_eq!(answer.status, 404, "{answer:?}");

    // With only sessions that end when their client closes them, a 503 names no time …
    let mut sse_in_use = open_sse(NEWCOMER, port);
    sse_in_use.handshake(true);
    let refused = post_mcp(THIRD, port, None, mcp_raw::INIT);
    assert_eq!(refused.status, 503, "{refused:?}");
    let retry: u64 = refused
        .header("retry-after")
        .and_then(|v| v.parse().ok())
        .expect("the streamable session's idle timeout");
    // … but the session in use over streamable HTTP ends after its idle timeout (300 s).
    assert!((290..=301).contains(&retry), "Retry-After: {retry}");
    let gone = request(
        ABANDONER,
        port,
        "DELETE",
        "/mcp",
        &[("Mcp-Session-Id", in_use.as_str())],
        b"",
    );
    assert!(gone.status < 300, "{gone:?}");
    let mut sse_second = open_sse(THIRD, port);
    sse_second.handshake(true);
    let refused = try_open_sse(ABANDONER, port).err().expect("full");
    assert_eq!(refused.status, 503, "{refused:?}");
    assert_eq!(refused.header("retry-after"), None, "{refused:?}");
    assert!(
        refused.body.contains("when its client closes it"),
        "{}",
        refused.body
    );
}

#[test]
fn a_client_holds_its_share_and_no_more() {
    let namespace = common::fresh_namespace("share");
    let port = common::free_port();
    let _robotd = common::start_robotd(
        &namespace,
        port,
        &[
            "--set",
            "mcp.max_sessions=10",
            "--set",
            "mcp.max_sessions_per_client=2",
        ],
    );
    let _first = open_streamable_in_use(ABANDONER, port);
    let mut second = open_sse(ABANDONER, port);
    second.handshake(true);
    // Both of its sessions are in use: a third is refused, on either transport.
    let refused = post_mcp(ABANDONER, port, None, mcp_raw::INIT);
    assert_eq!(refused.status, 503, "{refused:?}");
    assert!(
        refused.body.contains("mcp.max_sessions_per_client"),
        "{}",
        refused.body
    );
    let retry: u64 = refused
        .header("retry-after")
        .and_then(|v| v.parse().ok())
        .expect("the streamable session's idle timeout");
    assert!((290..=301).contains(&retry), "Retry-After: {retry}");
    let refused = try_open_sse(ABANDONER, port).err().expect("refused");
    assert_eq!(refused.status, 503, "{refused:?}");
    // Another client is not held to the first one's share.
    open_streamable(NEWCOMER, port);
    open_sse(NEWCOMER, port).handshake(true);
}

#[test]
fn an_unknown_session_is_404_on_every_method() {
    let namespace = common::fresh_namespace("unknown");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &[]);
    let closed = open_streamable(ABANDONER, port);
    let delete = |who: Ipv4Addr, id: &str| {
        request(who, port, "DELETE", "/mcp", &[("Mcp-Session-Id", id)], b"").status
    };
    // Another client's session, then its own: only the owner closes it, once.
    assert_eq!(delete(NEWCOMER, &closed), 404);
    assert!(delete(ABANDONER, &closed) < 300);
    for id in [closed.as_str(), "no-such-session"] {
        assert_eq!(delete(ABANDONER, id), 404, "DELETE {id}");
        let ping = br#"{"jsonrpc":"2.0","id":3,"method":"ping"}"#;
        assert_eq!(
            post_mcp(ABANDONER, port, Some(id), ping).status,
            404,
            "POST {id}"
        );
        let get = request(
            ABANDONER,
            port,
            "GET",
            "/mcp",
            &[("Accept", "text/event-stream"), ("Mcp-Session-Id", id)],
            b"",
        );
        assert_eq!(get.status, 404, "GET {id}");
    }
}
