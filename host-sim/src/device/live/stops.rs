//! `POST /stop`: the Stops taken, answered by one thread. Every Stop waiting
//! when the thread looks is one Stop through the link thread
//! ([`PageEnd::stop`]), and each of them gets its answer as JSON: so a Stop
//! holds no thread of its own, and however many come at once, they cost one
//! request on the link.

use std::io;
use std::net::TcpStream;
use std::sync::mpsc::Receiver;
use std::time::Duration;

use serde_json::json;

use super::http;
use super::hub::PageEnd;

/// How long a Stop waits for the link thread's answer: more than a request's six
/// tries of 100 ms and a read in between.
const STOP_WAIT: Duration = Duration::from_secs(3);

/// How long writing a Stop's answer may take (a few dozen bytes to a connection
/// that has been sent nothing: its buffer takes them at once).
const ANSWER_WAIT: Duration = Duration::from_secs(1);

/// Answers the Stops that come on `stops` until every sender is gone.
pub fn answer(stops: Receiver<TcpStream>, pages: PageEnd) {
    while let Ok(first) = stops.recv() {
        let mut batch = vec![first];
        batch.extend(stops.try_iter());
        let (status, body) = match pages.stop(STOP_WAIT) {
            Ok(answer) => (200, json!({ "accepted": true, "answer": answer })),
            Err(error) => (502, json!({ "accepted": false, "error": error })),
        };
        let body = body.to_string();
        for mut stream in batch {
            let _ = respond(&mut stream, status, &body);
        }
    }
}

/// The answer `body` with `status` on `stream`, waiting at most
/// [`ANSWER_WAIT`].
fn respond(stream: &mut TcpStream, status: u16, body: &str) -> io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_write_timeout(Some(ANSWER_WAIT))?;
    http::respond(stream, status, "", "application/json", body.as_bytes())
}
