//! robotd adapters
