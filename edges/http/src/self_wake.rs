//! Polling a connection again at once when it wakes itself while it runs.
//!
//! hyper 1.x hands a request's body to the handler through a small channel. When the handler
//! takes the body out, the channel wakes the connection's task, even when the connection has
//! already passed on the whole body and dropped its end. That wake-up comes while the
//! connection's task is being polled (the handler runs inside it), and tokio takes a task
//! woken during its own poll for one that yielded: it puts the task back in the run queue and
//! wakes an idle worker thread to look for work. So every POST woke the runtime's other
//! worker for nothing (`perf`: 1.00 such wake-ups per MCP request, 0.01 per `GET /health`;
//! BENCHMARKS.md, "Lean and long-running (issue 20)").
//!
//! [`InlineSelfWakes`] runs a future with a waker of its own. A wake-up that arrives while the
//! future is being polled is noted, and the future is polled once more before the poll
//! returns; any other wake-up goes to the task's own waker, as before. A future that keeps
//! waking itself (a deliberate yield) is polled at most [`MAX_REPOLLS`] extra times, then
//! yields to the scheduler as it asked.

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Wake, Waker};

/// Extra polls one poll may make of a future that woke itself while it ran.
pub const MAX_REPOLLS: usize = 2;

/// Not being polled: a wake-up goes to the task.
const IDLE: u8 = 0;
/// Being polled: a wake-up is noted and the poll goes again.
const POLLING: u8 = 1;
/// Being polled and woken meanwhile.
const WOKEN: u8 = 2;

/// `future`, with the wake-ups it gives itself while it runs taken care of in place.
pub struct InlineSelfWakes<F> {
    future: Pin<Box<F>>,
    shared: Arc<Shared>,
    waker: Waker,
}

struct Shared {
    state: AtomicU8,
    /// The task's own waker, from its latest poll.
    task: Mutex<Option<Waker>>,
}

impl Wake for Shared {
    fn wake(self: Arc<Self>) {
        self.wake_by_ref();
    }

    fn wake_by_ref(self: &Arc<Self>) {
        match self
            .state
            .compare_exchange(POLLING, WOKEN, Ordering::AcqRel, Ordering::Acquire)
        {
            Ok(_) | Err(WOKEN) => {}
            Err(_) => {
                let task = self.task.lock().unwrap_or_else(|e| e.into_inner());
                if let Some(task) = task.as_ref() {
                    task.wake_by_ref();
                }
            }
        }
    }
}

impl<F: Future> InlineSelfWakes<F> {
    /// Wraps `future`; spawn the result as the task.
    pub fn new(future: F) -> Self {
        let shared = Arc::new(Shared {
            state: AtomicU8::new(IDLE),
            task: Mutex::new(None),
        });
        Self {
            future: Box::pin(future),
            waker: Waker::from(shared.clone()),
            shared,
        }
    }
}

impl<F: Future> Future for InlineSelfWakes<F> {
    type Output = F::Output;

    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<F::Output> {
        let this = self.get_mut();
        {
            let mut task = this.shared.task.lock().unwrap_or_else(|e| e.into_inner());
            if !task.as_ref().is_some_and(|t| t.will_wake(cx.waker())) {
                *task = Some(cx.waker().clone());
            }
        }
        let mut inner = Context::from_waker(&this.waker);
        for _ in 0..=MAX_REPOLLS {
            this.shared.state.store(POLLING, Ordering::Release);
            if let Poll::Ready(output) = this.future.as_mut().poll(&mut inner) {
                this.shared.state.store(IDLE, Ordering::Release);
                return Poll::Ready(output);
            }
            let not_woken = this
                .shared
                .state
                .compare_exchange(POLLING, IDLE, Ordering::AcqRel, Ordering::Acquire)
                .is_ok();
            if not_woken {
                return Poll::Pending;
            }
        }
        // Still waking itself: let the scheduler run others first, as the future asked.
        this.shared.state.store(IDLE, Ordering::Release);
        cx.waker().wake_by_ref();
        Poll::Pending
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;

    /// A waker that counts its wake-ups.
    #[derive(Default)]
    struct Count(AtomicUsize);

    impl Wake for Count {
        fn wake(self: Arc<Self>) {
            self.0.fetch_add(1, Ordering::SeqCst);
        }
    }

    fn counting() -> (Arc<Count>, Waker) {
        let count = Arc::new(Count::default());
        (count.clone(), Waker::from(count))
    }

    /// Wakes itself on each of its first `self_wakes` polls and is ready after them.
    struct WakesItself {
        self_wakes: usize,
        polls: Arc<AtomicUsize>,
    }

    impl Future for WakesItself {
        type Output = usize;
        fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<usize> {
            let polls = self.polls.fetch_add(1, Ordering::SeqCst) + 1;
            if self.self_wakes == 0 {
                return Poll::Ready(polls);
            }
            self.self_wakes -= 1;
            cx.waker().wake_by_ref();
            Poll::Pending
        }
    }

    #[test]
    fn a_wake_while_polled_is_a_poll_more_not_a_trip_through_the_scheduler() {
        let (task, waker) = counting();
        let polls = Arc::new(AtomicUsize::new(0));
        let mut future = InlineSelfWakes::new(WakesItself {
            self_wakes: 1,
            polls: polls.clone(),
        });
        let mut cx = Context::from_waker(&waker);
        assert_eq!(Pin::new(&mut future).poll(&mut cx), Poll::Ready(2));
        assert_eq!(task.0.load(Ordering::SeqCst), 0, "the task was not woken");
    }

    #[test]
    fn a_future_that_keeps_waking_itself_still_yields() {
        let (task, waker) = counting();
        let polls = Arc::new(AtomicUsize::new(0));
        let mut future = InlineSelfWakes::new(WakesItself {
            self_wakes: usize::MAX,
            polls: polls.clone(),
        });
        let mut cx = Context::from_waker(&waker);
        assert!(Pin::new(&mut future).poll(&mut cx).is_pending());
        assert_eq!(polls.load(Ordering::SeqCst), 1 + MAX_REPOLLS);
        assert_eq!(
            task.0.load(Ordering::SeqCst),
            1,
            "it yields: the task is woken"
        );
    }

    #[test]
    fn a_wake_from_elsewhere_reaches_the_task() {
        let (task, waker) = counting();
        let stored: Arc<Mutex<Option<Waker>>> = Arc::default();
        let keep = stored.clone();
        let mut ready = false;
        let mut future = InlineSelfWakes::new(std::future::poll_fn(move |cx| {
            if ready {
                return Poll::Ready(());
            }
            ready = true;
            *keep.lock().unwrap() = Some(cx.waker().clone());
            Poll::Pending
        }));
        let mut cx = Context::from_waker(&waker);
        assert!(Pin::new(&mut future).poll(&mut cx).is_pending());
        let from_elsewhere = stored.lock().unwrap().take().unwrap();
        std::thread::spawn(move || from_elsewhere.wake())
            .join()
            .unwrap();
        assert_eq!(task.0.load(Ordering::SeqCst), 1);
        assert!(Pin::new(&mut future).poll(&mut cx).is_ready());
    }

    #[test]
    fn the_task_waker_of_the_latest_poll_is_the_one_woken() {
        let (first, first_waker) = counting();
        let (second, second_waker) = counting();
        let stored: Arc<Mutex<Option<Waker>>> = Arc::default();
        let keep = stored.clone();
        let mut future = InlineSelfWakes::new(std::future::poll_fn(move |cx| {
            *keep.lock().unwrap() = Some(cx.waker().clone());
            Poll::<()>::Pending
        }));
        let _ = Pin::new(&mut future).poll(&mut Context::from_waker(&first_waker));
        let _ = Pin::new(&mut future).poll(&mut Context::from_waker(&second_waker));
        stored.lock().unwrap().take().unwrap().wake();
        assert_eq!(first.0.load(Ordering::SeqCst), 0);
        assert_eq!(second.0.load(Ordering::SeqCst), 1);
    }
}
