//! The panic-to-answering restart latency, measured the way a caller sees it.

use std::time::{Duration, Instant};

use kameo::actor::ActorRef;
use kameo::error::Infallible;
use kameo::message::{Context, Message};
use kameo::Actor;

use super::{RestartPolicy, SupervisedError, SupervisionPolicy, Supervisor};

/// A minimal actor: answers `Ping`, dies on `Crash`.
struct LatencyProbe;

impl Actor for LatencyProbe {
    type Args = ();
    type Error = Infallible;

    fn name() -> &'static str {
        "robotd::supervision::LatencyProbe"
    }

    async fn on_start(_args: (), _actor_ref: ActorRef<Self>) -> Result<Self, Self::Error> {
        Ok(LatencyProbe)
    }
}

struct Ping;

impl Message<Ping> for LatencyProbe {
    type Reply = ();

    async fn handle(&mut self, _msg: Ping, _ctx: &mut Context<Self, Self::Reply>) {}
}

struct Crash;

impl Message<Crash> for LatencyProbe {
    type Reply = ();

    async fn handle(&mut self, _msg: Crash, _ctx: &mut Context<Self, Self::Reply>) {
        // `resume_unwind` unwinds like a panic but skips the panic hook, so the measurement is
        // the supervision path and not the hook printing to stderr.
        std::panic::resume_unwind(Box::new("latency probe crash"));
    }
}

/// Measures, `iterations` times, how long it takes from sending a request that panics the
/// actor until a request on the same handle is answered by the restarted instance.
///
/// The probe runs under a real supervisor (safe-state hook, events, metrics, budget) with
/// `backoff_initial = 0`, so what is measured is the supervision path itself: the failed
/// request's `ActorFailed` answer, noticing the death, the safe-state hook, the restart and
/// the first answer. A real panic additionally pays for the panic hook (printing, and a
/// backtrace when `RUST_BACKTRACE` is set). Run it on a multi-threaded runtime to match
/// robotd.
///
/// ```
/// # #[tokio::main(flavor = "multi_thread", worker_threads = 2)]
/// # async fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let mut samples = robotd_runtime::supervision::measure_restart_latency(50).await?;
/// samples.sort();
/// println!("restart latency p50 = {:?}", samples[samples.len() / 2]);
/// # Ok(()) }
/// ```
pub async fn measure_restart_latency(iterations: usize) -> Result<Vec<Duration>, SupervisedError> {
    let policy = SupervisionPolicy {
        max_restarts: u32::MAX,
        window: Duration::from_secs(60),
        backoff_initial: Duration::ZERO,
        backoff_max: Duration::ZERO,
        backoff_multiplier: 1.0,
        restart: RestartPolicy::Permanent,
    };
    let probe = Supervisor::new("latency-probe")
        .policy(policy)
        .safe_state(())
        .spawn_actor::<LatencyProbe>(|| ())
        .await
        .map_err(|err| SupervisedError::Stopped {
            actor: "latency-probe".to_owned(),
            reason: err.to_string(),
        })?;
    let mut samples = Vec::with_capacity(iterations);
    for _ in 0..iterations {
        let started = Instant::now();
        match probe.ask(Crash).await {
            Err(SupervisedError::ActorFailed { .. }) => {}
            Ok(()) => {
                return Err(SupervisedError::Stopped {
                    actor: probe.name().to_owned(),
                    reason: "the probe survived a crash request".to_owned(),
                })
            }
            Err(err) => return Err(err),
        }
        loop {
            match probe.ask(Ping).await {
                Ok(()) => break,
                Err(SupervisedError::Restarting { .. }) => {
                    probe.wait_ready(Duration::from_secs(5)).await?;
                }
                Err(err) => return Err(err),
            }
        }
        samples.push(started.elapsed());
    }
    let _ = probe.shutdown().await;
    Ok(samples)
}
