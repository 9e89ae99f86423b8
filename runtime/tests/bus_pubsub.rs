//! Publish-subscribe topics: delivery after attach, overflow policies, type safety.

mod common;

use robotd_protocol::envelope::Message;
use robotd_runtime::bus::{BusError, Overflow, Topic};
use serde::{Deserialize, Serialize};
use std::time::{Duration, Instant};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Count {
    n: u64,
}
impl Message for Count {
    const TYPE: &'static str = "test.count";
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Other {
    text: String,
}
impl Message for Other {
    const TYPE: &'static str = "test.other";
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn subscriber_receives_everything_published_after_it_attached() {
    const TOPIC: Topic<Count> = Topic::new("counts", Overflow::back_pressure(8));
    let bus = common::fresh_bus("pubsub");
    let mut subscriber = bus.subscriber(&TOPIC).unwrap();
    let publisher = bus.publisher(&TOPIC).unwrap();
    let producer = std::thread::spawn(move || {
        for n in 0..2_000 {
            assert_eq!(publisher.publish(&Count { n }).unwrap(), 1);
        }
    });
    for expected in 0..2_000 {
        let message = tokio::time::timeout(Duration::from_secs(5), subscriber.recv())
            .await
            .expect("message within 5 s")
            .unwrap();
        assert_eq!(message.body.n, expected);
        assert_eq!(message.msg_type, "test.count");
    }
    producer.join().unwrap();
    assert!(subscriber.try_recv().unwrap().is_none());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn back_pressure_sender_gets_an_error_when_a_subscriber_never_reads() {
    const TOPIC: Topic<Count> = Topic::new(
        "stuck",
        Overflow::BackPressure {
            depth: 2,
            max_wait: Duration::from_millis(50),
        },
    );
    let bus = common::fresh_bus("pubsub");
    let _never_reads = bus.subscriber(&TOPIC).unwrap();
    let publisher = bus.publisher(&TOPIC).unwrap();
    publisher.publish(&Count { n: 0 }).unwrap();
    publisher.publish(&Count { n: 1 }).unwrap();
    let started = Instant::now();
    let error = publisher.publish(&Count { n: 2 }).unwrap_err();
    assert!(matches!(error, BusError::Full { .. }), "{error}");
    assert!(
        started.elapsed() >= Duration::from_millis(40),
        "it waited before giving up"
    );
    assert!(error.to_string().contains("stuck"), "{error}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn back_pressure_sender_waits_for_a_slow_subscriber_and_loses_nothing() {
    const TOPIC: Topic<Count> = Topic::new(
        "slow",
        Overflow::BackPressure {
            depth: 2,
            max_wait: Duration::from_secs(5),
        },
    );
    let bus = common::fresh_bus("pubsub");
    let mut subscriber = bus.subscriber(&TOPIC).unwrap();
    let publisher = bus.publisher(&TOPIC).unwrap();
    let producer = std::thread::spawn(move || {
        for n in 0..50 {
            publisher.publish(&Count { n }).unwrap();
        }
    });
    for expected in 0..50 {
        if expected % 10 == 0 {
            // Fall behind now and then so the producer really has to wait.
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        assert_eq!(subscriber.recv().await.unwrap().body.n, expected);
    }
    producer.join().unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn latest_wins_keeps_the_newest_and_counts_what_it_replaced() {
    const TOPIC: Topic<Count> = Topic::new("latest", Overflow::latest_wins(2));
    let bus = common::fresh_bus("pubsub");
    let mut subscriber = bus.subscriber(&TOPIC).unwrap();
    let publisher = bus.publisher(&TOPIC).unwrap();
    // Losses are counted from the first message a subscriber sees from a publisher on.
    publisher.publish(&Count { n: 0 }).unwrap();
    assert_eq!(subscriber.recv().await.unwrap().body.n, 0);
    let dropped_before = dropped_count("latest");
    for n in 1..=10 {
        publisher.publish(&Count { n }).unwrap();
    }
    assert_eq!(subscriber.recv().await.unwrap().body.n, 9);
    assert_eq!(subscriber.recv().await.unwrap().body.n, 10);
    assert!(subscriber.try_recv().unwrap().is_none());
    assert_eq!(dropped_count("latest") - dropped_before, 8.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_message_of_another_type_is_refused_with_a_clear_error() {
    let bus = common::fresh_bus("pubsub");
    let mut subscriber = bus
        .subscriber(&Topic::<Count>::new("mixed", Overflow::back_pressure(4)))
        .unwrap();
    let publisher = bus
        .publisher(&Topic::<Other>::new("mixed", Overflow::back_pressure(4)))
        .unwrap();
    publisher.publish(&Other { text: "hi".into() }).unwrap();
    let error = subscriber.recv().await.unwrap_err();
    assert!(
        error
            .to_string()
            .contains("expected a 'test.count' message but got 'test.other'"),
        "{error}"
    );
    // The subscriber stays usable.
    assert!(subscriber.try_recv().unwrap().is_none());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn mismatched_overflow_policies_are_refused_at_setup() {
    let bus = common::fresh_bus("pubsub");
    let _first = bus
        .publisher(&Topic::<Count>::new("policy", Overflow::latest_wins(2)))
        .unwrap();
    let error = bus
        .subscriber(&Topic::<Count>::new("policy", Overflow::back_pressure(2)))
        .unwrap_err();
    assert!(matches!(error, BusError::Setup { .. }), "{error}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn oversized_messages_are_refused_before_sending() {
    const TOPIC: Topic<Other> = Topic::new("small", Overflow::back_pressure(2)).with_max_bytes(64);
    let bus = common::fresh_bus("pubsub");
    let publisher = bus.publisher(&TOPIC).unwrap();
    let error = publisher
        .publish(&Other {
            text: "x".repeat(100),
        })
        .unwrap_err();
    assert!(
        matches!(error, BusError::TooLarge { limit: 64, .. }),
        "{error}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn full_queues_of_largest_messages_fit_in_shared_memory() {
    // Publishers reserve one segment sized for `max_bytes`: every subscriber's queue full of
    // messages of the largest size the topic admits must fit, and arrive intact.
    const TOPIC: Topic<Other> =
        Topic::new("largest", Overflow::back_pressure(4)).with_max_bytes(8 * 1024);
    let bus = common::fresh_bus("pubsub");
    let mut first = bus.subscriber(&TOPIC).unwrap();
    let mut second = bus.subscriber(&TOPIC).unwrap();
    let publisher = bus.publisher(&TOPIC).unwrap();
    // The longest text whose encoded message the topic accepts.
    let mut length = 8 * 1024;
    let largest = loop {
        let message = Other {
            text: char::from(b'a' + (length % 26) as u8)
                .to_string()
                .repeat(length),
        };
        match publisher.publish(&message) {
            Ok(delivered) => break (message, delivered),
            Err(BusError::TooLarge { .. }) => length -= 1,
            Err(other) => panic!("{other}"),
        }
    };
    assert_eq!(largest.1, 2);
    assert!(
        length > 8 * 1024 - 200,
        "envelope took {} bytes",
        8 * 1024 - length
    );
    let mut sent = vec![largest.0];
    for n in 1..4 {
        let message = Other {
            text: char::from(b'a' + n as u8).to_string().repeat(length),
        };
        assert_eq!(publisher.publish(&message).unwrap(), 2);
        sent.push(message);
    }
    for subscriber in [&mut first, &mut second] {
        for expected in &sent {
            let message = tokio::time::timeout(Duration::from_secs(5), subscriber.recv())
                .await
                .expect("message within 5 s")
                .unwrap();
            assert_eq!(&message.body, expected);
        }
        assert!(subscriber.try_recv().unwrap().is_none());
    }
}

fn dropped_count(topic: &str) -> f64 {
    common::metric_sum("robotd_bus_dropped_total", topic)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stuck_subscriber_does_not_hide_messages_from_a_healthy_one() {
    const TOPIC: Topic<Count> = Topic::new(
        "two",
        Overflow::BackPressure {
            depth: 2,
            max_wait: Duration::from_millis(30),
        },
    );
    let bus = common::fresh_bus("pubsub");
    let _stuck = bus.subscriber(&TOPIC).unwrap();
    let mut healthy = bus.subscriber(&TOPIC).unwrap();
    let publisher = bus.publisher(&TOPIC).unwrap();
    for n in 0..2 {
        publisher.publish(&Count { n }).unwrap();
        assert_eq!(healthy.recv().await.unwrap().body.n, n);
    }
    let error = publisher.publish(&Count { n: 2 }).unwrap_err();
    assert!(matches!(error, BusError::Full { .. }), "{error}");
    let message = tokio::time::timeout(Duration::from_secs(2), healthy.recv())
        .await
        .expect("the healthy subscriber is woken")
        .unwrap();
    assert_eq!(message.body.n, 2);
}
