//! The live page's HTTP server on `std::net`: a thread that accepts, a thread per
//! connection, four routes.
//!
//! | route | answer |
//! | --- | --- |
//! | `GET /` | the page (`page.html`: inline script and style, nothing fetched elsewhere) |
//! | `GET /events` | Server-Sent Events: one `data:` line of JSON per telemetry frame ([`super::frame`]); `event: end` when the stream ends |
//! | `POST /stop` | Stop sent to the device through the link thread; its answer as JSON: `{"accepted": true, "answer": ...}`, or `{"accepted": false, "error": ...}` with status 502 |
//! | anything else | 404, or 405 for another method on these paths |
//!
//! On a loopback address only requests naming a loopback host (`Host:
//! 127.0.0.1:PORT`, `localhost:PORT`, `[::1]:PORT`) are served, so that a web
//! site cannot reach the page by pointing its own name at 127.0.0.1 (DNS
//! rebinding); a Stop whose `Origin` is another site is refused (403) whatever
//! the address.

use std::io::{self, Write};
use std::net::{IpAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serde_json::json;

use super::http::{self, Request};
use super::hub::{Event, PageEnd};

/// The page, before [`Page::render`] fills in its `{{...}}` fields.
const PAGE: &str = include_str!("page.html");

/// How often the accepting thread looks for a connection and for the end.
const ACCEPT_POLL: Duration = Duration::from_millis(20);

/// Connections served at once; more are answered 503 (a page holds one open for
/// its event stream, and one more for a moment per Stop).
const MAX_CONNECTIONS: usize = 32;

/// How long a connection may take to send its request.
const REQUEST_TIMEOUT: Duration = Duration::from_secs(10);

/// An event stream with nothing to send gets a comment this often, so that a page
/// gone away is noticed (the write fails).
const KEEP_ALIVE: Duration = Duration::from_secs(5);

/// How long a Stop waits for the link thread's answer: more than a request's six
/// tries of 100 ms and a read in between.
const STOP_WAIT: Duration = Duration::from_secs(3);

/// What the page shows of the run.
pub struct Page {
    /// The device's `--port`.
    pub device: String,
    /// The telemetry period, ms.
    pub period_ms: u16,
    /// Whether the address is reachable from other machines (`--allow-remote`).
    pub remote: bool,
}

impl Page {
    /// The page's HTML.
    pub fn render(&self) -> String {
        let warning = if self.remote {
            "<div id=\"remote\" class=\"warning\">This page is served on a network address \
             (--allow-remote): anyone who can reach it sees the telemetry and can stop the \
             device.</div>"
        } else {
            ""
        };
        PAGE.replace("{{device}}", &escape(&self.device))
            .replace("{{period_ms}}", &self.period_ms.to_string())
            .replace("{{remote_warning}}", warning)
    }
}

/// `text` safe inside HTML.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The server running: its accepting thread, until [`Server::finish`].
pub struct Server {
    done: Arc<AtomicBool>,
    /// Event streams open now.
    streams: Arc<AtomicUsize>,
    thread: Option<JoinHandle<()>>,
}

/// What every connection's thread needs.
struct Shared {
    page: String,
    pages: PageEnd,
    remote: bool,
    connections: AtomicUsize,
    streams: Arc<AtomicUsize>,
}

impl Server {
    /// Serve `page` on `listener`, reaching the link through `pages`.
    pub fn start(listener: TcpListener, page: &Page, pages: PageEnd) -> io::Result<Server> {
        listener.set_nonblocking(true)?;
        let done = Arc::new(AtomicBool::new(false));
        let streams = Arc::new(AtomicUsize::new(0));
        let shared = Arc::new(Shared {
            page: page.render(),
            pages,
            remote: page.remote,
            connections: AtomicUsize::new(0),
            streams: streams.clone(),
        });
        let stop = done.clone();
        let thread = std::thread::spawn(move || {
            while !stop.load(Ordering::SeqCst) {
                match listener.accept() {
                    Ok((stream, _)) => admit(stream, &shared),
                    Err(_) => std::thread::sleep(ACCEPT_POLL),
                }
            }
        });
        Ok(Server {
            done,
            streams,
            thread: Some(thread),
        })
    }

    /// Stop accepting, and give the open event streams up to `wait` to send their
    /// end (the link thread has published it).
    pub fn finish(mut self, wait: Duration) {
        self.done.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let until = Instant::now() + wait;
        while self.streams.load(Ordering::SeqCst) > 0 && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

/// A connection accepted: served on a thread of its own, or, beyond
/// [`MAX_CONNECTIONS`] open (or when no thread can be had), answered 503 at once
/// without waiting for its request, so that clients that never finish theirs
/// cannot make threads without bound.
fn admit(mut stream: TcpStream, shared: &Arc<Shared>) {
    let open = shared.connections.fetch_add(1, Ordering::SeqCst);
    let refuse = |mut stream: TcpStream| {
        shared.connections.fetch_sub(1, Ordering::SeqCst);
        // Best effort, never waiting: the socket's buffer takes the answer or not.
        let _ = stream.set_nonblocking(true);
        let _ = http::respond_text(&mut stream, 503, "", "too many connections");
    };
    if open >= MAX_CONNECTIONS {
        return refuse(stream);
    }
    let Ok(again) = stream.try_clone() else {
        return refuse(stream);
    };
    let mine = shared.clone();
    let spawned = std::thread::Builder::new().spawn(move || {
        let _ = serve(&mut stream, &mine);
        mine.connections.fetch_sub(1, Ordering::SeqCst);
    });
    if spawned.is_err() {
        refuse(again);
    }
}

/// The request read (within [`REQUEST_TIMEOUT`] in all) and answered; an error
/// is the connection's end.
fn serve(stream: &mut TcpStream, shared: &Shared) -> io::Result<()> {
    stream.set_nonblocking(false)?;
    // A page that stops reading its stream is given up after this long.
    stream.set_write_timeout(Some(REQUEST_TIMEOUT))?;
    let _ = stream.set_nodelay(true);
    let Some(request) = http::read_request(&mut Deadline::new(stream, REQUEST_TIMEOUT))? else {
        return http::respond_text(stream, 400, "", "not an HTTP/1.1 request");
    };
    if !shared.remote && !loopback_host(request.header("host")) {
        return http::respond_text(
            stream,
            403,
            "",
            "this page answers requests for 127.0.0.1, localhost or [::1] only",
        );
    }
    match (request.path.as_str(), request.method.as_str()) {
        ("/", "GET") => http::respond(
            stream,
            200,
            "",
            "text/html; charset=utf-8",
            shared.page.as_bytes(),
        ),
        ("/events", "GET") => events(stream, shared),
        ("/stop", "POST") => stop(stream, shared, &request),
        ("/" | "/events", _) => http::respond_text(stream, 405, "Allow: GET\r\n", "GET only"),
        ("/stop", _) => http::respond_text(stream, 405, "Allow: POST\r\n", "POST only"),
        _ => http::respond_text(stream, 404, "", "no such page: the page is at /"),
    }
}

/// A connection read with one deadline for all its reads: a client that sends
/// a byte now and then cannot keep it open past the deadline.
struct Deadline<'s> {
    stream: &'s mut TcpStream,
    until: Instant,
}

impl<'s> Deadline<'s> {
    fn new(stream: &'s mut TcpStream, within: Duration) -> Self {
        Deadline {
            stream,
            until: Instant::now() + within,
        }
    }
}

impl io::Read for Deadline<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let left = self.until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(io::ErrorKind::TimedOut.into());
        }
        self.stream.set_read_timeout(Some(left))?;
        // A read that waits out the socket's timeout fails with `WouldBlock` on
        // Unix (EAGAIN) and `TimedOut` on Windows: either way the deadline passed.
        io::Read::read(self.stream, buf).map_err(|e| match e.kind() {
            io::ErrorKind::WouldBlock => io::ErrorKind::TimedOut.into(),
            _ => e,
        })
    }
}

/// Whether a `Host` header names a loopback host (`127.0.0.1:8321`,
/// `localhost:8321`, `[::1]:8321`).
fn loopback_host(host: Option<&str>) -> bool {
    let Some(host) = host else { return false };
    // Without the port: after the last colon, unless that is inside [::1].
    let name = match host.rsplit_once(':') {
        Some((name, port)) if !port.contains(']') => name,
        _ => host,
    };
    let name = name.trim_start_matches('[').trim_end_matches(']');
    name.eq_ignore_ascii_case("localhost")
        || name.parse::<IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

/// `GET /events`: the frames as they come, until the stream ends or the page
/// goes away.
fn events(stream: &mut TcpStream, shared: &Shared) -> io::Result<()> {
    let Some(rx) = shared.pages.subscribe() else {
        return http::respond_text(stream, 503, "", "the telemetry stream has ended");
    };
    shared.streams.fetch_add(1, Ordering::SeqCst);
    let result = (|| {
        http::start_event_stream(stream)?;
        loop {
            match rx.recv_timeout(KEEP_ALIVE) {
                Ok(Event::Frame(json)) => write!(stream, "data: {json}\n\n")?,
                Ok(Event::End(why)) => {
                    let why = json!({ "reason": &*why }).to_string();
                    write!(stream, "event: end\ndata: {why}\n\n")?;
                    stream.flush()?;
                    return Ok(());
                }
                Err(RecvTimeoutError::Timeout) => stream.write_all(b": keep-alive\n\n")?,
                Err(RecvTimeoutError::Disconnected) => return Ok(()),
            }
            stream.flush()?;
        }
    })();
    shared.streams.fetch_sub(1, Ordering::SeqCst);
    result
}

/// `POST /stop`: Stop through the link thread, its answer as JSON.
fn stop(stream: &mut TcpStream, shared: &Shared, request: &Request) -> io::Result<()> {
    // A page of another site may post here (a form needs no permission): only
    // this page's own requests, or those of no page (curl), are taken.
    if let (Some(origin), Some(host)) = (request.header("origin"), request.header("host")) {
        if origin != format!("http://{host}") {
            return http::respond_text(stream, 403, "", "Stop is taken from this page only");
        }
    }
    let (status, body) = match shared.pages.stop(STOP_WAIT) {
        Ok(answer) => (200, json!({ "accepted": true, "answer": answer })),
        Err(error) => (502, json!({ "accepted": false, "error": error })),
    };
    http::respond(
        stream,
        status,
        "",
        "application/json",
        body.to_string().as_bytes(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    #[test]
    fn loopback_hosts() {
        for ok in [
            "127.0.0.1:8321",
            "localhost:1",
            "LOCALHOST",
            "[::1]:8321",
            "[::1]",
            "127.1.2.3:80",
        ] {
            assert!(loopback_host(Some(ok)), "{ok}");
        }
        for bad in [
            "evil.example:8321",
            "10.0.0.1:8321",
            "[::2]:1",
            "0.0.0.0:8321",
            "",
            "localhost.evil:1",
        ] {
            assert!(!loopback_host(Some(bad)), "{bad}");
        }
        assert!(!loopback_host(None));
    }

    /// A server on a free loopback port, and its address.
    fn started() -> (Server, std::net::SocketAddr, super::super::hub::LinkEnd) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let (link, pages) = super::super::hub::hub();
        let page = Page {
            device: "sim".into(),
            period_ms: 100,
            remote: false,
        };
        (Server::start(listener, &page, pages).unwrap(), addr, link)
    }

    #[test]
    fn beyond_the_cap_a_silent_connection_is_refused_at_once() {
        let (server, addr, _link) = started();
        // Clients that open a connection and never send their request.
        let idle: Vec<TcpStream> = (0..MAX_CONNECTIONS)
            .map(|_| TcpStream::connect(addr).unwrap())
            .collect();
        // The accepting thread counts them within a few polls.
        std::thread::sleep(ACCEPT_POLL * 10);
        let mut more = TcpStream::connect(addr).unwrap();
        // Refused without waiting for a request: well within REQUEST_TIMEOUT.
        more.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        let mut answer = String::new();
        more.read_to_string(&mut answer).unwrap();
        assert!(answer.starts_with("HTTP/1.1 503 "), "{answer:?}");
        drop(idle);
        server.finish(Duration::ZERO);
    }

    #[test]
    fn a_request_dribbled_a_byte_at_a_time_is_cut_at_the_deadline() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let dribble = std::thread::spawn(move || {
            let mut c = TcpStream::connect(addr).unwrap();
            // One byte every 20 ms, never a whole head: each read alone is quick.
            for _ in 0..100 {
                if c.write_all(b"G").is_err() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        });
        let (mut stream, _) = listener.accept().unwrap();
        let within = Duration::from_millis(200);
        let started = Instant::now();
        let read = http::read_request(&mut Deadline::new(&mut stream, within));
        let took = started.elapsed();
        assert_eq!(read.unwrap_err().kind(), io::ErrorKind::TimedOut);
        // The deadline and at most one read's wait (20 ms) and scheduling after.
        assert!(took < within + Duration::from_millis(150), "{took:?}");
        drop(stream);
        dribble.join().unwrap();
    }

    #[test]
    fn the_page_shows_the_remote_warning_only_when_remote() {
        let page = |remote| Page {
            device: "tcp:<x>:1".into(),
            period_ms: 100,
            remote,
        };
        let local = page(false).render();
        assert!(!local.contains("id=\"remote\""));
        assert!(!local.contains("{{"), "a field left unfilled");
        assert!(local.contains("tcp:&lt;x&gt;:1"));
        assert!(page(true).render().contains("id=\"remote\""));
    }
}
