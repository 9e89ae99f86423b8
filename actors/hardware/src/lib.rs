//! Hardware actors (placeholder: being written).
