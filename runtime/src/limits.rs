//! Process limits a long-running service needs.
//!
//! Each iceoryx2 port holds file descriptors, and so does every client connection. Linux
//! starts processes with a soft limit of 1,024 open files even when the hard limit allows far
//! more; [`raise_open_files_limit`] lifts the soft limit to the hard one at start, so clients
//! do not run out of descriptors that the system would have granted. Child processes
//! (actor processes) inherit it.

/// The soft and hard `RLIMIT_NOFILE` before and the soft one after raising it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OpenFilesLimit {
    /// Soft limit found at start.
    pub before: u64,
    /// Soft limit now (the hard limit, when raising worked).
    pub after: u64,
    /// The hard limit.
    pub hard: u64,
}

/// Raises the soft open-files limit to the hard limit.
pub fn raise_open_files_limit() -> std::io::Result<OpenFilesLimit> {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes into the struct it is given, which lives for the call.
    if unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut limit) } != 0 {
        return Err(std::io::Error::last_os_error());
    }
    let before = limit.rlim_cur;
    if limit.rlim_cur < limit.rlim_max {
        let raised = libc::rlimit {
            rlim_cur: limit.rlim_max,
            rlim_max: limit.rlim_max,
        };
        // SAFETY: setrlimit reads the struct it is given, which lives for the call.
        if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &raised) } != 0 {
            return Err(std::io::Error::last_os_error());
        }
        limit = raised;
    }
    Ok(OpenFilesLimit {
        before,
        after: limit.rlim_cur,
        hard: limit.rlim_max,
    })
}
