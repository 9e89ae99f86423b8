//! Log lines that text from outside cannot forge: control characters escaped on the way out.
//!
//! Tool arguments, LLM replies and network messages end up in log fields (an unknown object
//! name in a skill's error, say). Written raw, a CR/LF in them starts a line that looks like
//! robotd's own, an ANSI escape rewrites the terminal, a NUL cuts the file for some readers.
//! [`EscapingMakeWriter`] wraps a log writer and writes every control character of an event as
//! `\n`, `\r`, `\t` or `\xHH`, except the newline that ends the event: one event, one line.
//! The formatter writes each event with one `write_all`, which is what makes "the last
//! newline" the event's end.
//!
//! An event is also cut at `max_event_bytes` (`[telemetry] max_event_bytes`): a 1 MB tool
//! argument in an error message becomes a line ending `… [N bytes cut]`, not a 1 MB line.

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

/// `event` (escaped) cut to at most `max` bytes at a character boundary, ending
/// `… [N bytes cut]` and its newline when cut.
pub fn limit_event(event: &[u8], max: usize) -> Cow<'_, [u8]> {
    if event.len() <= max {
        return Cow::Borrowed(event);
    }
    let mut end = max;
    // Back to the start of a UTF-8 character (continuation bytes are 0b10xxxxxx).
    while end > 0 && (event[end] & 0xc0) == 0x80 {
        end -= 1;
    }
    let mut out = event[..end].to_vec();
    out.extend_from_slice(format!("… [{} bytes cut]\n", event.len() - end).as_bytes());
    Cow::Owned(out)
}

/// A [`MakeWriter`] whose writers escape control characters and cut long events (see the
/// module).
#[derive(Debug, Clone)]
pub struct EscapingMakeWriter<M> {
    inner: M,
    max_event_bytes: usize,
}

impl<M> EscapingMakeWriter<M> {
    /// Wraps `inner`, cutting events at `max_event_bytes`.
    pub fn new(inner: M, max_event_bytes: usize) -> Self {
        Self {
            inner,
            max_event_bytes,
        }
    }
}

/// The writer of one event.
#[derive(Debug)]
pub struct EscapingWriter<W> {
    inner: W,
    max_event_bytes: usize,
}

impl<W: Write> EscapingWriter<W> {
    fn write_event(&mut self, buf: &[u8]) -> std::io::Result<()> {
        let escaped = escape_controls(buf);
        self.inner
            .write_all(&limit_event(&escaped, self.max_event_bytes))
    }
}

impl<W: Write> Write for EscapingWriter<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.write_event(buf)?;
        Ok(buf.len())
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        self.write_event(buf)
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
            max_event_bytes: self.max_event_bytes,
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

    #[test]
    fn long_events_are_cut_at_a_character() {
        assert!(matches!(limit_event(b"short\n", 100), Cow::Borrowed(_)));
        let event = "é".repeat(10) + "\n"; // 21 bytes
        let cut = limit_event(event.as_bytes(), 5);
        assert_eq!(&*cut, "éé… [17 bytes cut]\n".as_bytes());
    }
}
