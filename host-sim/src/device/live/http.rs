//! Just enough HTTP/1.1 for the live page: a request's head read (its line and
//! headers, bounded), a body of a declared length read and dropped, and whole
//! responses written, each on a connection of its own (`Connection: close`).

use std::io::{self, Read, Write};

/// The longest request head read (line and headers), bytes.
const MAX_HEAD: usize = 8 * 1024;

/// The longest request body read (and dropped), bytes: the page's Stop has none.
const MAX_BODY: u64 = 4 * 1024;

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

/// Reads a request's head from `r`, and its body if it declares one (at most
/// 4 KiB, dropped); `None` for anything that is not an HTTP/1.x
/// request (or too long, or cut short).
pub fn read_request(r: &mut impl Read) -> io::Result<Option<Request>> {
    let mut head = Vec::new();
    let mut byte = [0u8; 1];
    // Byte by byte, so that nothing after the head is taken.
    while !head.ends_with(b"\r\n\r\n") {
        if head.len() >= MAX_HEAD || r.read(&mut byte)? == 0 {
            return Ok(None);
        }
        head.push(byte[0]);
    }
    let Ok(head) = String::from_utf8(head) else {
        return Ok(None);
    };
    let request = parse_head(&head);
    if let Some(len) = request
        .as_ref()
        .and_then(|q| q.header("content-length"))
        .and_then(|v| v.parse::<u64>().ok())
    {
        io::copy(&mut r.take(len.min(MAX_BODY)), &mut io::sink())?;
    }
    Ok(request)
}

/// The request line and headers of `head` (which ends with an empty line).
fn parse_head(head: &str) -> Option<Request> {
    let mut lines = head.split("\r\n");
    let mut line = lines.next()?.split(' ');
    let (method, target, version) = (line.next()?, line.next()?, line.next()?);
    if line.next().is_some() || !version.starts_with("HTTP/1.") || !target.starts_with('/') {
        return None;
    }
    let path = target.split_once('?').map_or(target, |(p, _)| p);
    let mut headers = Vec::new();
    for l in lines.filter(|l| !l.is_empty()) {
        let (name, value) = l.split_once(':')?;
        headers.push((name.trim().to_ascii_lowercase(), value.trim().to_string()));
    }
    Some(Request {
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
    w.write_all(head.as_bytes())?;
    w.write_all(body)?;
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
    fn a_request_head_is_read_and_its_body_dropped() {
        let text =
            "POST /stop?x=1 HTTP/1.1\r\nHost: 127.0.0.1:8321\r\nContent-Length: 2\r\n\r\n{}NEXT";
        let mut input = text.as_bytes();
        let q = read_request(&mut input).unwrap().unwrap();
        assert_eq!((q.method.as_str(), q.path.as_str()), ("POST", "/stop"));
        assert_eq!(q.header("host"), Some("127.0.0.1:8321"));
        assert_eq!(input, b"NEXT");
    }

    #[test]
    fn what_is_no_request_is_none() {
        let long = format!("GET / HTTP/1.1\r\nX: {}\r\n\r\n", "a".repeat(MAX_HEAD));
        for bad in [
            "GET / HTTP/1.1\r\nHost: h\r\n",
            "GET /\r\n\r\n",
            "GET * HTTP/1.1\r\n\r\n",
            "GET / SPDY/3\r\n\r\n",
            "GET / HTTP/1.1\r\nno colon\r\n\r\n",
            long.as_str(),
        ] {
            assert_eq!(read_request(&mut bad.as_bytes()).unwrap(), None, "{bad:?}");
        }
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
