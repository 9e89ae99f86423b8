//! Log lines that text from outside cannot forge: control characters escaped on the way out.
//!
//! Tool arguments, LLM replies and network messages end up in log fields (an unknown object
//! name in a skill's error, say). Written raw, a CR/LF in them starts a line that looks like
//! robotd's own, an ANSI escape rewrites the terminal, a NUL cuts the file for some readers.
//! [`EscapingMakeWriter`] wraps a log writer and writes every control character of an event as
//! `\n`, `\r`, `\t` or `\xHH`, except the newline that ends the event: one event, one line.
//! The formatter writes each event with one `write_all`, which is what makes "the last
//! newline" the event's end.

use std::borrow::Cow;
use std::io::Write;
use tracing_subscriber::fmt::MakeWriter;

/// `event` with every control character but a final newline written as an escape.
pub fn escape_controls(event: &[u8]) -> Cow<'_, [u8]> {
    let body = event.strip_suffix(b"\n").unwrap_or(event);
    let is_control = |b: &u8| *b < 0x20 || *b == 0x7f;
    if !body.iter().any(is_control) {
        return Cow::Borrowed(event);
    }
    let mut out = Vec::with_capacity(event.len() + 16);
    for &b in body {
        match b {
            b'\n' => out.extend_from_slice(b"\\n"),
            b'\r' => out.extend_from_slice(b"\\r"),
            b'\t' => out.extend_from_slice(b"\\t"),
            b if b < 0x20 || b == 0x7f => {
                out.extend_from_slice(format!("\\x{b:02x}").as_bytes());
            }
            b => out.push(b),
        }
    }
    if body.len() < event.len() {
        out.push(b'\n');
    }
    Cow::Owned(out)
}

/// A [`MakeWriter`] whose writers escape control characters (see the module).
#[derive(Debug, Clone)]
pub struct EscapingMakeWriter<M> {
    inner: M,
}

impl<M> EscapingMakeWriter<M> {
    /// Wraps `inner`.
    pub fn new(inner: M) -> Self {
        Self { inner }
    }
}

/// The writer of one event.
#[derive(Debug)]
pub struct EscapingWriter<W> {
    inner: W,
}

impl<W: Write> Write for EscapingWriter<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.inner.write_all(&escape_controls(buf))?;
        Ok(buf.len())
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        self.inner.write_all(&escape_controls(buf))
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl<'a, M: MakeWriter<'a>> MakeWriter<'a> for EscapingMakeWriter<M> {
    type Writer = EscapingWriter<M::Writer>;

    fn make_writer(&'a self) -> Self::Writer {
        EscapingWriter {
            inner: self.inner.make_writer(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_event_stays_one_line() {
        assert!(matches!(
            escape_controls(b"plain line\n"),
            Cow::Borrowed(b"plain line\n")
        ));
        assert_eq!(
            &*escape_controls(b"object 'x\nWARN forged line\r\x1b[2J\0' unknown\n"),
            b"object 'x\\nWARN forged line\\r\\x1b[2J\\x00' unknown\n"
        );
        assert_eq!(&*escape_controls(b"tab\there"), b"tab\\there");
    }
}
