//! The simulated world (placeholder: being written).
