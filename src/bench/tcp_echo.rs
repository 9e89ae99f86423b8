//! The raw baseline under every HTTP figure: a loopback TCP round trip.
//!
//! An echo server on its own thread answers each message with the same bytes; the caller
//! times write-then-read round trips of a message about the size of an MCP request, with
//! `TCP_NODELAY` on both ends as robotd's HTTP port has. Two threads handing a message back
//! and forth through the kernel cost two wake-ups per round trip, which is the floor of any
//! HTTP call on the machine of the run: what remains above it is the HTTP stack's, MCP's and
//! the tool's.

use super::Latency;
use anyhow::{bail, Context, Result};
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::time::Instant;

/// Bytes per message: about an MCP `tools/call` request with its headers.
const MESSAGE_BYTES: usize = 400;

/// Round trips made before timing starts.
const WARM_UP: usize = 100;

/// `round_trips` loopback TCP round trips, timed.
pub fn latency(round_trips: usize) -> Result<Latency> {
    let listener = TcpListener::bind("127.0.0.1:0").context("binding the echo server")?;
    let address = listener.local_addr()?;
    let server = std::thread::Builder::new()
        .name("bench-echo".into())
        .spawn(move || -> std::io::Result<()> {
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
        })?;
    let mut client = TcpStream::connect(address).context("connecting to the echo server")?;
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
    drop(client);
    match server.join() {
        Ok(Ok(())) => {}
        Ok(Err(error)) => bail!("the echo server failed: {error}"),
        Err(_) => bail!("the echo server panicked"),
    }
    Ok(Latency::of(&mut samples))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_are_timed_and_the_server_ends_with_the_client() {
        let latency = latency(50).unwrap();
        assert!(latency.p50_us > 0.0, "{}", latency.p50_us);
        assert!(latency.p99_us >= latency.p50_us);
    }
}
