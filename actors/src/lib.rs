//! robotd actors
