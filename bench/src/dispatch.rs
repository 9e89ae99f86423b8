//! From a parsed `robotd bench …` command line to the benchmark and its printed figures.

use crate::cli::BenchCommand;
use anyhow::{Context, Result};
use std::process::ExitCode;

/// Runs the benchmark `command` names and prints its figures (a table, or one JSON object
/// with `--json`). `redis_url` is asked only by the Redis benchmark: the URL of the
/// configured Redis, if any (without one it starts its own redis-server).
pub fn run(
    command: BenchCommand,
    redis_url: impl FnOnce() -> Result<Option<String>>,
) -> Result<ExitCode> {
    match command {
        BenchCommand::Bus(args) => {
            let exe = std::env::current_exe().context("finding the robotd binary")?;
            let namespace = format!("bench-{}", std::process::id());
            let figures = crate::bus::run(
                &exe,
                &namespace,
                crate::bus::BenchSizes {
                    round_trips: args.round_trips.max(1),
                    frames: args.frames.max(2),
                    restarts: args.restarts.max(1),
                },
            )?;
            print_figures(args.json, &figures, figures.table())
        }
        BenchCommand::Niryo(args) => {
            let figures = crate::niryo::run(args.round_trips, args.images, args.scenes)?;
            print_figures(args.json, &figures, figures.table())
        }
        BenchCommand::Widowx(args) => {
            let figures = crate::widowx::run(args.round_trips)?;
            print_figures(args.json, &figures, figures.table())
        }
        BenchCommand::Sim(args) => {
            let figures = crate::sim::run(args.frames.max(1))?;
            print_figures(args.json, &figures, figures.table())
        }
        BenchCommand::Perception(args) => {
            if let Some(frames) = args.randomized {
                let report = crate::perception_randomized::run(
                    frames.max(1),
                    args.seed,
                    &args.frame_seeds,
                    args.dump.as_deref(),
                )?;
                return print_figures(args.json, &report, report.table());
            }
            let figures = crate::perception::run(args.scenes.max(1), args.bus_frames.max(1))?;
            print_figures(args.json, &figures, figures.table())
        }
        BenchCommand::Redis(args) => {
            let figures = crate::redis::run(args.frames.max(10), redis_url()?)?;
            print_figures(args.json, &figures, figures.table())
        }
        BenchCommand::Jpeg(args) => {
            let figures = crate::jpeg::run(args.frames.max(10))?;
            print_figures(args.json, &figures, figures.table())
        }
        BenchCommand::Soak(args) => {
            let exe = std::env::current_exe().context("the robotd binary's path")?;
            let report = crate::soak::run(&exe, args.minutes)?;
            print_figures(args.json, &report, report.table())?;
            Ok(if report.passed {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(1)
            })
        }
        BenchCommand::Table(args) => {
            let exe = std::env::current_exe().context("the robotd binary's path")?;
            let figures = crate::table::run(&exe, args.calls.max(1), args.seed, args.time_scale)?;
            print_figures(args.json, &figures, figures.table())
        }
        BenchCommand::Ping(args) => {
            let figures = crate::ping::run(&args.namespace, args.round_trips.max(1))?;
            print_figures(args.json, &figures, figures.table())
        }
        BenchCommand::Safety(args) => {
            let figures = crate::safety::run(args.commands.max(1), args.stops.max(1))?;
            print_figures(args.json, &figures, figures.table())
        }
        BenchCommand::Mcp(args) => {
            let exe = std::env::current_exe().context("finding the robotd binary")?;
            let figures = crate::mcp::run(
                &exe,
                args.calls.max(10),
                args.seconds.max(0.5),
                args.one_core,
            )?;
            print_figures(args.json, &figures, figures.table())
        }
    }
}

/// The other process of a two-process benchmark (`robotd bench-peer ROLE`): the TCP echo of
/// the Niryo benchmark, or one side of the bus benchmark.
pub fn run_peer(
    role: &str,
    peer_namespace: &str,
    count: usize,
    cpu: Option<usize>,
) -> Result<ExitCode> {
    if role == crate::tcp_echo::PEER_ROLE {
        crate::tcp_echo::serve_peer()?;
    } else {
        crate::bus::run_peer(role, peer_namespace, count, cpu)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Prints benchmark figures as one JSON object (`--json`) or as their table.
fn print_figures(json: bool, figures: &impl serde::Serialize, table: String) -> Result<ExitCode> {
    if json {
        println!("{}", serde_json::to_string(figures)?);
    } else {
        print!("{table}");
    }
    Ok(ExitCode::SUCCESS)
}
