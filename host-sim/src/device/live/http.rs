//! Just enough HTTP/1.1 for the live page: a request (its line, its headers and
//! a body of a declared length, bounded) recognised in the bytes received so far,
//! and whole responses written, each on a connection of its own (`Connection:
//! close`).

use std::io::{self, Write};

/// The longest request head read (line and headers), bytes.
pub const MAX_HEAD: usize = 8 * 1024;

/// The longest request body taken (and dropped), bytes: the page's Stop has none.
pub const MAX_BODY: usize = 4 * 1024;

/// Headers a request may send once only: a second `Host` or `Origin` would let
/// one check read the first and another part of the way the second.
const SINGLE: [&str; 5] = [
    "host",
    "origin",
    "referer",
    "sec-fetch-site",
    "content-length",
];

/// A request's head.
#[derive(Debug, PartialEq, Eq)]
pub struct Request {
    /// `GET`, `POST`, ...
    pub method: String,
    /// The path, without its query.
    pub path: String,
    /// Headers, names lower-cased, in order.
    pub headers: Vec<(String, String)>,
}

impl Request {
    /// The value of header `name` (lower case), if sent.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// What the bytes received on a connection so far are.
#[derive(Debug, PartialEq, Eq)]
pub enum Received {
    /// The start of a request: more to come.
    Partial,
    /// A whole request: its head, and its body (of `Content-Length` bytes) all
    /// there.
    Whole(Request),
    /// No HTTP/1.x request this server takes, and why (for the 400 answer).
    Refused(&'static str),
}

/// What `bytes`, the bytes received on a connection so far, are: a request is
/// whole once its head (at most [`MAX_HEAD`] bytes) and the body it declares
/// (at most [`MAX_BODY`]) are there; the body is not kept.
pub fn received(bytes: &[u8]) -> Received {
    let Some(end) = bytes.windows(4).position(|w| w == b"\r\n\r\n") else {
        return if bytes.len() >= MAX_HEAD {
            Received::Refused("a request head longer than 8 KiB")
        } else {
            Received::Partial
        };
    };
    if end + 4 > MAX_HEAD {
        return Received::Refused("a request head longer than 8 KiB");
    }
    let Ok(head) = std::str::from_utf8(&bytes[..end + 4]) else {
        return Received::Refused("a request head that is not UTF-8");
    };
    let request = match parse_head(head) {
        Ok(r) => r,
        Err(why) => return Received::Refused(why),
    };
    let body = match request.header("content-length").map(str::parse::<usize>) {
        None => 0,
        Some(Ok(n)) if n <= MAX_BODY => n,
        Some(Ok(_)) => return Received::Refused("a body longer than 4 KiB"),
        Some(Err(_)) => return Received::Refused("a Content-Length that is no length"),
    };
    if bytes.len() < end + 4 + body {
        return Received::Partial;
    }
    Received::Whole(request)
}

/// The request line and headers of `head` (which ends with an empty line), or
/// why it is refused.
fn parse_head(head: &str) -> Result<Request, &'static str> {
    let not_http = "not an HTTP/1.1 request";
    let mut lines = head.split("\r\n");
    let mut line = lines.next().ok_or(not_http)?.split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (line.next(), line.next(), line.next(), line.next())
    else {
        return Err(not_http);
    };
    if !version.starts_with("HTTP/1.") || !target.starts_with('/') {
        return Err(not_http);
    }
    let path = target.split_once('?').map_or(target, |(p, _)| p);
    let mut headers: Vec<(String, String)> = Vec::new();
    for l in lines.filter(|l| !l.is_empty()) {
        let (name, value) = l.split_once(':').ok_or(not_http)?;
        let name = name.trim().to_ascii_lowercase();
        if SINGLE.contains(&name.as_str()) && headers.iter().any(|(n, _)| *n == name) {
            return Err(match name.as_str() {
                "host" => "two Host headers: a request names one host",
                "origin" => "two Origin headers: a request has one origin",
                "referer" => "two Referer headers",
                "sec-fetch-site" => "two Sec-Fetch-Site headers",
                _ => "two Content-Length headers",
            });
        }
        headers.push((name, value.trim().to_string()));
    }
    Ok(Request {
        method: method.to_string(),
        path: path.to_string(),
        headers,
    })
}

/// A status code's reason phrase.
fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        502 => "Bad Gateway",
        503 => "Service Unavailable",
        _ => "Error",
    }
}

/// A whole response: `status`, `extra` header lines (each ending in CRLF), the
/// body of type `content_type`.
pub fn respond(
    w: &mut impl Write,
    status: u16,
    extra: &str,
    content_type: &str,
    body: &[u8],
) -> io::Result<()> {
    let head = format!(
        "HTTP/1.1 {status} {}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nConnection: close\r\n{extra}\r\n",
        reason(status),
        body.len()
    );
    // One write: the head and the body leave together, so that a client never
    // holds the head alone when the connection ends.
    let mut whole = head.into_bytes();
    whole.extend_from_slice(body);
    w.write_all(&whole)?;
    w.flush()
}

/// A plain-text response: `text` and a line break.
pub fn respond_text(w: &mut impl Write, status: u16, extra: &str, text: &str) -> io::Result<()> {
    respond(
        w,
        status,
        extra,
        "text/plain; charset=utf-8",
        format!("{text}\n").as_bytes(),
    )
}

/// The head of an event stream (`text/event-stream`, no length: it lasts).
pub fn start_event_stream(w: &mut impl Write) -> io::Result<()> {
    w.write_all(
        b"HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\n\
          X-Content-Type-Options: nosniff\r\nConnection: close\r\n\r\n",
    )?;
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_is_whole_with_its_declared_body() {
        let text = "POST /stop?x=1 HTTP/1.1\r\nHost: 127.0.0.1:8321\r\nContent-Length: 2\r\n\r\n{}";
        for cut in 0..text.len() {
            assert_eq!(
                received(&text.as_bytes()[..cut]),
                Received::Partial,
                "{cut}"
            );
        }
        let Received::Whole(q) = received(text.as_bytes()) else {
            panic!("not whole")
        };
        assert_eq!((q.method.as_str(), q.path.as_str()), ("POST", "/stop"));
        assert_eq!(q.header("host"), Some("127.0.0.1:8321"));
    }

    #[test]
    fn what_is_no_request_is_refused() {
        let long = format!("GET / HTTP/1.1\r\nX: {}\r\n\r\n", "a".repeat(MAX_HEAD));
        let body = format!(
            "POST / HTTP/1.1\r\nContent-Length: {}\r\n\r\n",
            MAX_BODY + 1
        );
        for (bad, why) in [
            ("GET /\r\n\r\n", "not an HTTP/1.1 request"),
            ("GET * HTTP/1.1\r\n\r\n", "not an HTTP/1.1 request"),
            ("GET / SPDY/3\r\n\r\n", "not an HTTP/1.1 request"),
            (
                "GET / HTTP/1.1\r\nno colon\r\n\r\n",
                "not an HTTP/1.1 request",
            ),
            (long.as_str(), "a request head longer than 8 KiB"),
            (body.as_str(), "a body longer than 4 KiB"),
            (
                "POST / HTTP/1.1\r\nContent-Length: two\r\n\r\n",
                "a Content-Length that is no length",
            ),
            (
                "GET / HTTP/1.1\r\nHost: 127.0.0.1:1\r\nHost: evil.example\r\n\r\n",
                "two Host headers: a request names one host",
            ),
            (
                "POST /stop HTTP/1.1\r\nOrigin: http://a\r\norigin: http://b\r\n\r\n",
                "two Origin headers: a request has one origin",
            ),
        ] {
            assert_eq!(received(bad.as_bytes()), Received::Refused(why), "{bad:?}");
        }
        // Without its end, a long head is refused as soon as it is too long.
        assert_eq!(
            received(&long.as_bytes()[..MAX_HEAD]),
            Received::Refused("a request head longer than 8 KiB")
        );
    }

    #[test]
    fn a_response_declares_its_length() {
        let mut out = Vec::new();
        respond_text(&mut out, 404, "", "no such page").unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with("HTTP/1.1 404 Not Found\r\n"), "{text}");
        assert!(text.contains("Content-Length: 13\r\n"), "{text}");
        assert!(text.ends_with("\r\n\r\nno such page\n"), "{text}");
    }
}
