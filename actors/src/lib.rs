//! robotd actors: arm motion, gripper, camera, perception, workspace model, skills,
//! text-to-speech and the LLM agent, each owning its state and talking only through the bus.
//!
//! This crate is the place for them; it holds none yet. The foundation they build on is in
//! `robotd-runtime`: the bus ([`robotd_runtime::bus`]) for their messages, the catalogue of
//! topics and services ([`robotd_runtime::catalog`]), and supervision
//! ([`robotd_runtime::supervision`]) that brings a failed hardware actor to a safe state and
//! restarts it. An actor can also live outside robotd entirely: see
//! `examples/external_actor.rs` for one in its own process.
