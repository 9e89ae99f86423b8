//! The simulated wrist camera renderer (placeholder: being written).
