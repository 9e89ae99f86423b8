//! bus (in progress)
