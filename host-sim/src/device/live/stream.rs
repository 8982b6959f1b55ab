//! `GET /events`: one page's event stream, on a thread of its own, until the
//! telemetry ends, the page goes away, or the page falls behind.
//!
//! A page is dropped once it is the server's `drain` limit behind the stream:
//! the oldest byte written to it that it has not read was written that long ago
//! ([`super::lag`], on Linux for a page on this machine), or a frame has waited
//! that long to be written at all (elsewhere, where only full buffers tell: the
//! kernels grow them to megabytes, minutes of frames). Meanwhile the page's
//! queue of frames in the hub stays bounded (64 frames, the rest skipped).

use std::io::{self, Write};
use std::net::TcpStream;
use std::sync::mpsc::RecvTimeoutError;
use std::time::{Duration, Instant};

use serde_json::json;

use super::http;
use super::hub::{Event, PageEnd};
use super::lag::{self, Lag};

/// An event stream with nothing to send gets a comment this often, so that a page
/// gone away is noticed (the write fails).
const KEEP_ALIVE: Duration = Duration::from_secs(5);

/// The frames from `pages` as they come on `stream` (blocking), until the
/// stream ends, the page goes away, or it is `drain` behind.
pub fn events(mut stream: TcpStream, pages: &PageEnd, drain: Duration) -> io::Result<()> {
    let Some(rx) = pages.subscribe() else {
        return http::respond_text(&mut stream, 503, "", "the telemetry stream has ended");
    };
    let ends = (stream.local_addr()?, stream.peer_addr()?);
    // Whether this system says how much of the stream the page has not read.
    let tracked = lag::queued(ends.0, ends.1).is_some();
    // How often to look: a tenth of the limit, within [10 ms, 1 s].
    let look = (drain / 10).clamp(Duration::from_millis(10), Duration::from_secs(1));
    let mut lag = Lag::default();
    let mut head = Vec::new();
    http::start_event_stream(&mut head)?;
    let mut text = String::from_utf8_lossy(&head).into_owned();
    let mut last_write = Instant::now();
    let mut last_look = Instant::now();
    loop {
        if !text.is_empty() {
            write_within(&mut stream, text.as_bytes(), drain)?;
            last_write = Instant::now();
            if tracked {
                lag.wrote(text.len(), last_write);
            }
        }
        if tracked && last_look.elapsed() >= look {
            last_look = Instant::now();
            if let Some(queued) = lag::queued(ends.0, ends.1) {
                let behind = lag.behind(queued, last_look);
                if behind >= drain {
                    return Err(io::Error::new(
                        io::ErrorKind::TimedOut,
                        format!("the page is {} s behind", behind.as_secs_f64()),
                    ));
                }
            }
        }
        text = match rx.recv_timeout(look) {
            Ok(Event::Frame(json)) => format!("data: {json}\n\n"),
            Ok(Event::End(why)) => {
                let why = json!({ "reason": &*why }).to_string();
                let end = format!("event: end\ndata: {why}\n\n");
                return write_within(&mut stream, end.as_bytes(), drain);
            }
            Err(RecvTimeoutError::Timeout) if last_write.elapsed() >= KEEP_ALIVE => {
                ": keep-alive\n\n".to_string()
            }
            Err(RecvTimeoutError::Timeout) => String::new(),
            Err(RecvTimeoutError::Disconnected) => return Ok(()),
        };
    }
}

/// Writes all of `bytes` to `stream` within `within` from now, or fails with
/// `TimedOut`: a page that reads a little now and then cannot hold the stream
/// past the limit, as each write alone could.
pub fn write_within(stream: &mut TcpStream, bytes: &[u8], within: Duration) -> io::Result<()> {
    let until = Instant::now() + within;
    let mut rest = bytes;
    while !rest.is_empty() {
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(io::ErrorKind::TimedOut.into());
        }
        stream.set_write_timeout(Some(left))?;
        match stream.write(rest) {
            Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
            Ok(n) => rest = &rest[n..],
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            // Unix reports a write that waited out the timeout as `WouldBlock`.
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                return Err(io::ErrorKind::TimedOut.into())
            }
            Err(e) => return Err(e),
        }
    }
    stream.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    #[test]
    fn a_write_that_waits_past_its_deadline_times_out() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        // A client that never reads.
        let _client = TcpStream::connect(listener.local_addr().unwrap()).unwrap();
        let (mut server, _) = listener.accept().unwrap();
        let chunk = vec![b'x'; 64 * 1024];
        let error = loop {
            if let Err(e) = write_within(&mut server, &chunk, Duration::from_millis(200)) {
                break e;
            }
        };
        assert_eq!(error.kind(), io::ErrorKind::TimedOut);
    }
}
