//! The hooks a supervisor runs around a restart: safe state first, then cleanup.

use std::fmt;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;

/// How long a safe-state hook may take unless it says otherwise.
pub const DEFAULT_SAFE_STATE_TIMEOUT: Duration = Duration::from_secs(2);

/// How long a restart-cleanup hook may take before the supervisor reports it as failed and
/// goes on.
pub const CLEANUP_TIMEOUT: Duration = Duration::from_secs(5);

/// Drives the hardware behind a supervised actor or process to a safe state after it stopped:
/// stop the moving arm, open nothing, hold position.
///
/// It runs after every stop the supervisor did not ask for, before any restart, and it must
/// not rely on the dead incarnation: implement it on the spec side, with its own connection to
/// the hardware (or a driver handle that survives the actor), never on the actor's state. Its
/// outcome (ok or not, how long it took) is reported as [`SupervisionEvent::SafeState`]; a
/// failure is reported loudly but does not block the restart, because a fresh incarnation is
/// the next best chance to reach the hardware.
///
/// Use [`safe_state_fn`] for a closure, `()` for "nothing to do".
///
/// [`SupervisionEvent::SafeState`]: super::SupervisionEvent::SafeState
pub trait SafeState: Send + Sync + 'static {
    /// Brings the hardware to a safe state; `reason` is why the incarnation stopped.
    fn safe_state(&self, reason: &str) -> impl Future<Output = Result<(), String>> + Send;

    /// How long [`safe_state`](Self::safe_state) may take before it is abandoned and reported
    /// as failed.
    fn safe_state_timeout(&self) -> Duration {
        DEFAULT_SAFE_STATE_TIMEOUT
    }
}

/// Nothing to make safe: the hook succeeds at once.
impl SafeState for () {
    async fn safe_state(&self, _reason: &str) -> Result<(), String> {
        Ok(())
    }
}

impl<T: SafeState> SafeState for Arc<T> {
    fn safe_state(&self, reason: &str) -> impl Future<Output = Result<(), String>> + Send {
        (**self).safe_state(reason)
    }

    fn safe_state_timeout(&self) -> Duration {
        (**self).safe_state_timeout()
    }
}

/// A [`SafeState`] made from an async closure; see [`safe_state_fn`].
pub struct FnSafeState<F> {
    f: F,
    timeout: Duration,
}

impl<F> fmt::Debug for FnSafeState<F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("FnSafeState")
            .field("timeout", &self.timeout)
            .finish_non_exhaustive()
    }
}

impl<F, Fut> SafeState for FnSafeState<F>
where
    F: Fn(String) -> Fut + Send + Sync + 'static,
    Fut: Future<Output = Result<(), String>> + Send + 'static,
{
    fn safe_state(&self, reason: &str) -> impl Future<Output = Result<(), String>> + Send {
        (self.f)(reason.to_owned())
    }

    fn safe_state_timeout(&self) -> Duration {
        self.timeout
    }
}

/// Wraps an async closure as a [`SafeState`] hook with its own timeout.
///
/// ```
/// use std::time::Duration;
/// use robotd_runtime::supervision::safe_state_fn;
///
/// let hook = safe_state_fn(Duration::from_millis(500), |reason: String| async move {
///     // e.g. send "stop" to the arm controller over a connection the actor does not own
///     eprintln!("stopping the arm because {reason}");
///     Ok(())
/// });
/// # let _ = hook;
/// ```
pub fn safe_state_fn<F, Fut>(timeout: Duration, f: F) -> FnSafeState<F>
where
    F: Fn(String) -> Fut + Send + Sync + 'static,
    Fut: Future<Output = Result<(), String>> + Send + 'static,
{
    FnSafeState { f, timeout }
}

/// What the restart-cleanup hook is told about the incarnation that just died.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CleanupContext {
    /// The supervised actor's or process's name.
    pub actor: String,
    /// The dead process's id (`None` for in-process actors).
    pub pid: Option<u32>,
    /// Why it stopped.
    pub reason: String,
}

pub(crate) type HookFuture = Pin<Box<dyn Future<Output = Result<(), String>> + Send + 'static>>;

/// Object-safe form of [`SafeState`], so one supervisor type serves every hook type.
pub(crate) trait ErasedSafeState: Send + Sync + 'static {
    fn run(self: Arc<Self>, reason: String) -> HookFuture;
    fn timeout(&self) -> Duration;
}

impl<S: SafeState> ErasedSafeState for S {
    fn run(self: Arc<Self>, reason: String) -> HookFuture {
        Box::pin(async move { self.safe_state(&reason).await })
    }

    fn timeout(&self) -> Duration {
        self.safe_state_timeout()
    }
}

pub(crate) type CleanupFn = dyn Fn(&CleanupContext) -> Result<(), String> + Send + Sync + 'static;
