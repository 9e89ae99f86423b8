//! The rules of session places, on tokio's paused clock.

use super::*;
use axum::extract::ConnectInfo;
use axum::http::{Extensions, HeaderMap};
use std::net::SocketAddr;

fn owner(peer: &str) -> SessionOwner {
    let mut extensions = Extensions::new();
    extensions.insert(ConnectInfo::<SocketAddr>(peer.parse().unwrap()));
    SessionOwner::of(&HeaderMap::new(), None, &extensions)
}

fn places(max_sessions: usize, per_client: usize) -> Arc<SessionPlaces> {
    SessionPlaces::new(PlaceLimits {
        max_sessions,
        per_client,
        unused_timeout: Duration::from_secs(30),
        idle_timeout: Duration::from_secs(300),
    })
}

fn open(places: &Arc<SessionPlaces>, who: SessionOwner, id: &str, transport: Transport) {
    places
        .admit(who)
        .unwrap_or_else(|r| panic!("{id} refused: {r:?}"))
        .open(id, transport);
}

/// Whether `future` has resolved after the runtime ran what it could.
async fn resolved(future: &mut (impl Future<Output = ()> + Unpin)) -> bool {
    tokio::time::timeout(Duration::ZERO, future).await.is_ok()
}

#[tokio::test(start_paused = true)]
async fn a_client_at_its_share_gives_up_its_oldest_unused_session() {
    let places = places(10, 2);
    let (a, b) = (owner("10.0.0.1:1"), owner("10.0.0.2:1"));
    open(&places, a, "a1", Transport::Streamable);
    tokio::time::advance(Duration::from_secs(1)).await;
    open(&places, a, "a2", Transport::Sse);
    let mut a1_closed = Box::pin(places.closed("a1"));
    assert!(!resolved(&mut a1_closed).await);
    // The third of a's sessions takes the place of its oldest one that made no call.
    open(&places, a, "a3", Transport::Streamable);
    assert!(resolved(&mut a1_closed).await, "a1 was not given up");
    assert!(!places.contains("a1") && places.contains("a2") && places.contains("a3"));
    assert_eq!(places.open(), 2);
    // Once all of a's sessions made calls, a is refused, and told when its first one ends.
    places.touch("a2", true);
    places.touch("a3", true);
    let refusal = places.admit(a).err().expect("refused at its share");
    assert_eq!(refusal.setting, "mcp.max_sessions_per_client");
    assert_eq!((refusal.held, refusal.limit), (2, 2));
    assert_eq!(
        refusal.retry_after,
        Some(Duration::from_secs(300)),
        "a3's idle timeout"
    );
    // Another client is not held to a's share.
    open(&places, b, "b1", Transport::Sse);
}

#[tokio::test(start_paused = true)]
async fn the_cap_refuses_and_says_when_the_first_place_frees() {
    let places = places(2, 2);
    let (a, b, c) = (
        owner("10.0.0.1:1"),
        owner("10.0.0.2:1"),
        owner("10.0.0.3:1"),
    );
    open(&places, a, "sse", Transport::Sse);
    tokio::time::advance(Duration::from_secs(10)).await;
    open(&places, b, "http", Transport::Streamable);
    let refusal = places.admit(c).err().expect("full");
    assert_eq!(refusal.setting, "mcp.max_sessions");
    assert_eq!(
        refusal.retry_after,
        Some(Duration::from_secs(20)),
        "sse's unused timeout"
    );
    assert_eq!(refusal.retry_after_s(), Some(20));
    // An SSE session that made a call ends only with its stream: the streamable one is next.
    places.touch("sse", true);
    let refusal = places.admit(c).err().expect("full");
    assert_eq!(refusal.retry_after, Some(Duration::from_secs(30)));
    // Expiry falls on a whole second: 300 s after a request at 10.1 s is 311 s.
    tokio::time::advance(Duration::from_millis(100)).await;
    places.touch("http", true);
    let refusal = places.admit(c).err().expect("full");
    assert_eq!(
        refusal.retry_after,
        Some(Duration::from_millis(300_900)),
        "its idle timeout"
    );
    assert_eq!(refusal.retry_after_s(), Some(301));
    // No session that ends by itself: no time to tell.
    places.release("http");
    open(&places, b, "sse2", Transport::Sse);
    places.touch("sse2", true);
    assert_eq!(places.admit(c).err().expect("full").retry_after, None);
}

#[tokio::test(start_paused = true)]
async fn a_session_without_a_call_expires_and_one_in_use_does_not() {
    let places = places(10, 10);
    let a = owner("127.0.0.1:1");
    open(&places, a, "unused", Transport::Sse);
    open(&places, a, "used", Transport::Sse);
    open(&places, a, "idle", Transport::Streamable);
    places.touch("used", true);
    places.touch("idle", true);
    let mut unused = Box::pin(places.closed("unused"));
    let mut used = Box::pin(places.closed("used"));
    let mut idle = Box::pin(places.closed("idle"));
    tokio::time::advance(Duration::from_millis(29_900)).await;
    assert!(!resolved(&mut unused).await, "expired early");
    // A notification (not a call) does not make a session used.
    places.touch("unused", false);
    tokio::time::advance(Duration::from_millis(200)).await;
    assert!(
        resolved(&mut unused).await,
        "not expired after 30 s without a call"
    );
    assert!(!places.contains("unused"));
    // A request restarts a streamable session's idle time; it ends on the next whole second
    // after 300 s (the request came at 230.1 s: at 531 s).
    tokio::time::advance(Duration::from_secs(200)).await;
    places.touch("idle", true);
    tokio::time::advance(Duration::from_millis(300_800)).await;
    assert!(!resolved(&mut idle).await, "the request did not count");
    tokio::time::advance(Duration::from_millis(200)).await;
    assert!(resolved(&mut idle).await, "idle for 301 s and still open");
    assert!(
        !resolved(&mut used).await,
        "an SSE session in use lives with its stream"
    );
    places.release("used");
    assert!(resolved(&mut used).await);
    assert_eq!(places.open(), 0);
}

#[tokio::test(start_paused = true)]
async fn a_reserved_place_counts_until_its_session_opens_or_it_is_dropped() {
    let places = places(1, 1);
    let (a, b) = (owner("10.0.0.1:1"), owner("10.0.0.2:1"));
    let ticket = places.admit(a).expect("a place");
    assert_eq!(
        places.admit(b).err().map(|r| r.setting),
        Some("mcp.max_sessions")
    );
    drop(ticket);
    places
        .admit(b)
        .expect("the place came back")
        .open("b", Transport::Sse);
    assert_eq!(places.open(), 1);
}

#[tokio::test(start_paused = true)]
async fn sessions_quiet_within_the_same_second_end_together() {
    let places = places(10, 10);
    let a = owner("127.0.0.1:1");
    tokio::time::advance(Duration::from_millis(100)).await;
    open(&places, a, "early", Transport::Streamable);
    tokio::time::advance(Duration::from_millis(800)).await;
    open(&places, a, "late", Transport::Streamable);
    let mut early = Box::pin(places.closed("early"));
    let mut late = Box::pin(places.closed("late"));
    tokio::time::advance(Duration::from_millis(30_050)).await;
    assert!(!resolved(&mut early).await && !resolved(&mut late).await);
    tokio::time::advance(Duration::from_millis(100)).await;
    assert!(
        resolved(&mut early).await && resolved(&mut late).await,
        "both at 31 s"
    );
}

#[test]
fn retry_after_is_rounded_up_to_a_whole_second() {
    let refusal = |d: Option<Duration>| Refusal {
        setting: "mcp.max_sessions",
        held: 1,
        limit: 1,
        retry_after: d,
    };
    assert_eq!(
        refusal(Some(Duration::from_millis(1))).retry_after_s(),
        Some(1)
    );
    assert_eq!(refusal(Some(Duration::ZERO)).retry_after_s(), Some(1));
    assert_eq!(
        refusal(Some(Duration::from_millis(2001))).retry_after_s(),
        Some(3)
    );
    assert_eq!(
        refusal(Some(Duration::from_secs(5))).retry_after_s(),
        Some(5)
    );
    assert_eq!(refusal(None).retry_after_s(), None);
}
