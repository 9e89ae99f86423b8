//! The raw baseline under every HTTP figure: a loopback TCP round trip between two processes.
//!
//! An echo server in a peer process (`robotd bench-peer tcp-echo`, this binary again) answers
//! each message with the same bytes; the caller times write-then-read round trips of a
//! message about the size of an MCP request, with `TCP_NODELAY` on both ends as robotd's HTTP
//! port has. That is what any call from a client process to the service costs at least on the
//! machine of the run (two wake-ups across processes); what remains above it is the HTTP
//! stack's, MCP's and the tool's.

use super::Latency;
use anyhow::{bail, Context, Result};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

/// The `bench-peer` role of the echo server.
pub const PEER_ROLE: &str = "tcp-echo";

/// Bytes per message: about an MCP `tools/call` request with its headers.
const MESSAGE_BYTES: usize = 400;

/// Round trips made before timing starts.
const WARM_UP: usize = 100;

/// `round_trips` loopback TCP round trips to an echo server in a peer process of `exe`, timed.
pub fn latency(exe: &Path, round_trips: usize) -> Result<Latency> {
    let mut peer = Command::new(exe)
        .args([
            "bench-peer",
            PEER_ROLE,
            "--peer-namespace",
            "-",
            "--count",
            "0",
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .context("starting the TCP echo peer")?;
    let timed = (|| {
        let stdout = peer.stdout.take().context("the echo peer's stdout")?;
        let mut line = String::new();
        BufReader::new(stdout).read_line(&mut line)?;
        let port: u16 = line
            .trim()
            .strip_prefix("listening ")
            .and_then(|p| p.parse().ok())
            .with_context(|| format!("the echo peer said {line:?}, not its port"))?;
        time_round_trips(port, round_trips)
    })();
    // The peer ends when the connection closes; kill it in case it never got one.
    let _ = peer.kill();
    let _ = peer.wait();
    timed
}

fn time_round_trips(port: u16, round_trips: usize) -> Result<Latency> {
    let mut client =
        TcpStream::connect(("127.0.0.1", port)).context("connecting to the echo peer")?;
    client.set_nodelay(true)?;
    let message = [b'x'; MESSAGE_BYTES];
    let mut reply = [0u8; MESSAGE_BYTES];
    let mut samples = Vec::with_capacity(round_trips);
    for i in 0..WARM_UP + round_trips {
        let started = Instant::now();
        client.write_all(&message)?;
        client.read_exact(&mut reply)?;
        if i >= WARM_UP {
            samples.push(started.elapsed());
        }
    }
    if reply != message {
        bail!("the echo peer answered other bytes than it was sent");
    }
    Ok(Latency::of(&mut samples))
}

/// Entry of `robotd bench-peer tcp-echo`: prints `listening <port>`, echoes one connection.
pub fn serve_peer() -> Result<()> {
    let listener = TcpListener::bind("127.0.0.1:0").context("binding the echo server")?;
    println!("listening {}", listener.local_addr()?.port());
    std::io::stdout().flush()?;
    let (mut peer, _) = listener.accept()?;
    peer.set_nodelay(true)?;
    let mut buffer = [0u8; MESSAGE_BYTES];
    loop {
        let read = peer.read(&mut buffer)?;
        if read == 0 {
            return Ok(());
        }
        peer.write_all(&buffer[..read])?;
    }
}
