//! Out-of-process actors: child processes restarted by the same rules as in-process actors.

use std::fmt;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::process::ExitStatus;
use std::sync::Arc;
use std::time::Duration;

use tokio::process::{Child, Command};

use super::engine::{panic_message, Core, Exit, SupervisedState, Worker};
use super::error::{SupervisedError, SupervisionError};

/// Spawns the child from its command factory and reaps it.
pub(crate) struct ProcessWorker {
    pub(crate) command: Arc<dyn Fn() -> Command + Send + Sync>,
    child: Option<Child>,
    pid: Option<u32>,
    last_pid: Option<u32>,
}

impl ProcessWorker {
    pub(crate) fn new(command: Arc<dyn Fn() -> Command + Send + Sync>) -> Self {
        ProcessWorker {
            command,
            child: None,
            pid: None,
            last_pid: None,
        }
    }

    fn reaped(&mut self) {
        self.child = None;
        self.last_pid = self.pid.take();
    }
}

fn describe(status: ExitStatus) -> Exit {
    if status.success() {
        return Exit::normal("exited with status 0");
    }
    if let Some(code) = status.code() {
        return Exit::failed(format!("exited with status {code}"));
    }
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        if let Some(signal) = status.signal() {
            return Exit::failed(format!("killed by signal {signal}"));
        }
    }
    Exit::failed(format!("ended with {status}"))
}

impl Worker for ProcessWorker {
    type Handle = u32;

    async fn start(&mut self) -> Result<u32, String> {
        let mut command = catch_unwind(AssertUnwindSafe(|| (self.command)())).map_err(|panic| {
            format!(
                "the command factory panicked: {}",
                panic_message(panic.as_ref())
            )
        })?;
        // If the supervisor (or robotd) goes away without a clean stop, the child goes too.
        command.kill_on_drop(true);
        let program = command
            .as_std()
            .get_program()
            .to_string_lossy()
            .into_owned();
        let child = command
            .spawn()
            .map_err(|err| format!("could not spawn `{program}`: {err}"))?;
        let pid = child
            .id()
            .ok_or_else(|| format!("`{program}` exited before its pid could be read"))?;
        self.child = Some(child);
        self.pid = Some(pid);
        Ok(pid)
    }

    async fn wait_exit(&mut self) -> Exit {
        let Some(child) = self.child.as_mut() else {
            return Exit::failed("no process was running");
        };
        let exit = match child.wait().await {
            Ok(status) => describe(status),
            Err(err) => Exit::failed(format!("could not wait for the process: {err}")),
        };
        self.reaped();
        exit
    }

    async fn stop(&mut self, grace: Duration) {
        let Some(mut child) = self.child.take() else {
            return;
        };
        #[cfg(unix)]
        if let Some(pid) = self.pid.and_then(|pid| libc::pid_t::try_from(pid).ok()) {
            // SAFETY: plain syscall. The child has not been reaped yet (we own its `Child` and
            // have not waited on it), so `pid` still names our child and no other process.
            unsafe {
                libc::kill(pid, libc::SIGTERM);
            }
            if let Ok(Ok(_)) = tokio::time::timeout(grace, child.wait()).await {
                self.reaped();
                return;
            }
            tracing::warn!(
                pid,
                "child did not exit within {grace:?} of SIGTERM, killing it"
            );
        }
        #[cfg(not(unix))]
        let _ = grace;
        if let Err(err) = child.kill().await {
            tracing::error!("could not kill the child process: {err}");
        }
        self.reaped();
    }

    fn last_pid(&self) -> Option<u32> {
        self.last_pid
    }
}

/// The handle to a supervised child process.
///
/// Cheap to clone. Dropping the last clone shuts the supervisor down and kills the child
/// (the child is also spawned with `kill_on_drop`, so it cannot outlive the supervisor task).
pub struct SupervisedProcess {
    pub(crate) core: Core<u32>,
}

impl Clone for SupervisedProcess {
    fn clone(&self) -> Self {
        SupervisedProcess {
            core: self.core.clone(),
        }
    }
}

impl fmt::Debug for SupervisedProcess {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SupervisedProcess")
            .field("actor", &self.name())
            .field("state", &self.state())
            .field("pid", &self.pid())
            .finish()
    }
}

impl SupervisedProcess {
    /// The name given to the supervisor.
    pub fn name(&self) -> &str {
        self.core.name()
    }

    /// What the child is doing right now.
    pub fn state(&self) -> SupervisedState {
        self.core.state()
    }

    /// The running child's process id, `None` while it is down.
    pub fn pid(&self) -> Option<u32> {
        self.core.current::<()>().ok().map(|(_, pid)| pid)
    }

    /// Waits up to `timeout` until a child is running and returns its pid; fails at once if
    /// the supervisor gave up or stopped.
    pub async fn wait_running(&self, timeout: Duration) -> Result<u32, SupervisedError> {
        self.core.wait_ready(timeout).await
    }

    /// Waits until supervision ends: `Ok` after a shutdown or a status-0 exit under a
    /// transient policy, `Err` when the supervisor gave up (the escalation).
    pub async fn wait_stopped(&self) -> Result<(), SupervisionError> {
        self.core.wait_stopped().await
    }

    /// Stops the child (SIGTERM, then SIGKILL after the stop timeout) and ends supervision;
    /// the safe-state hook does not run for a requested stop. Returns how supervision ended.
    pub async fn stop(&self) -> Result<(), SupervisionError> {
        self.core.shutdown().await
    }
}
