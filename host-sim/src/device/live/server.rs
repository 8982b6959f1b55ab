//! The live page's HTTP server on `std::net`: one thread takes the connections
//! and reads every request as its bytes come, waiting on none ([`Server`]); a
//! request once whole is answered at once (a refusal), on a thread of its own
//! (the page; an event stream, [`super::stream`]) or by the Stop thread
//! ([`super::stops`]).
//!
//! | route | answer |
//! | --- | --- |
//! | `GET /` | the page (`page.html`: inline script and style, nothing fetched elsewhere) |
//! | `GET /events` | Server-Sent Events: one `data:` line of JSON per telemetry frame ([`super::frame`]); `event: end` when the stream ends |
//! | `POST /stop` | Stop sent to the device through the link thread; its answer as JSON: `{"accepted": true, "answer": ...}`, or `{"accepted": false, "error": ...}` with status 502 |
//! | anything else | 404, or 405 for another method on these paths |
//!
//! **Stop always gets through.** A request still coming holds no thread and no
//! slot, only its place among [`Limits::waiting`] others: a connection beyond
//! them makes the one that has waited longest give way (503), and every request
//! whole by then is taken first. A Stop is sent whole with its connection (the
//! page's `fetch` writes it at once), so it is taken the moment it is accepted:
//! clients that open connections and never finish their requests, however many,
//! only push out each other. Stops are answered by one thread, all those waiting
//! with one Stop on the link, so a flood of Stops holds nothing either (and
//! stops the device).
//!
//! **Who is answered** ([`super::guard`]): on a loopback address only requests
//! naming a loopback host, so that a web site cannot reach the page by pointing
//! its own name at 127.0.0.1 (DNS rebinding); a Stop that says it comes from
//! another page (its `Origin`, `Sec-Fetch-Site` or `Referer`) is refused (403)
//! whatever the address; a request with two `Host`, `Origin`, `Referer`,
//! `Sec-Fetch-Site` or `Content-Length` headers is refused (400), so no check
//! reads one and another part the other.

use std::collections::VecDeque;
use std::io::{self, Read};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::guard::{foreign_stop, loopback_host};
use super::http::{self, Received, Request};
use super::hub::PageEnd;
use super::{stops, stream};

/// The page, before [`Page::render`] fills in its `{{...}}` fields.
const PAGE: &str = include_str!("page.html");

/// How often the accepting thread looks for connections and bytes when none
/// came.
const ACCEPT_POLL: Duration = Duration::from_millis(20);

/// How many of each the server holds at once, and how long it waits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Requests still coming (a connection beyond makes the one waiting
    /// longest give way, 503).
    pub waiting: usize,
    /// How long a request may take to arrive whole (408 after).
    pub request_time: Duration,
    /// Event streams (a page holds one; 503 beyond).
    pub streams: usize,
    /// Pages being sent (503 beyond).
    pub answering: usize,
    /// Stops waiting for the device's answer (503 beyond: the device gets a
    /// Stop from those).
    pub stops: usize,
    /// How far behind its event stream a page may be: the age of the oldest
    /// byte it has not read, or of a frame not yet written ([`super::stream`]).
    pub drain: Duration,
}

impl Default for Limits {
    /// 64 requests coming, 10 s each; 16 event streams, 8 pages being sent, 64
    /// Stops waiting; 10 s behind (a page 10 s behind shows what is no longer
    /// so; a browser reads its streams within milliseconds, in a background tab
    /// too).
    fn default() -> Self {
        Limits {
            waiting: 64,
            request_time: Duration::from_secs(10),
            streams: 16,
            answering: 8,
            stops: 64,
            drain: Duration::from_secs(10),
        }
    }
}

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

/// What the threads that answer need.
struct Shared {
    page: String,
    pages: PageEnd,
    remote: bool,
    limits: Limits,
    /// Event streams open (or starting) now.
    streams: Arc<AtomicUsize>,
    /// Pages being sent now.
    answering: AtomicUsize,
    /// To the Stop thread.
    stops: SyncSender<TcpStream>,
}

impl Server {
    /// Serve `page` on `listener` within `limits`, reaching the link through
    /// `pages`.
    pub fn start(
        listener: TcpListener,
        page: &Page,
        pages: PageEnd,
        limits: Limits,
    ) -> io::Result<Server> {
        listener.set_nonblocking(true)?;
        let done = Arc::new(AtomicBool::new(false));
        let streams = Arc::new(AtomicUsize::new(0));
        let (stops_tx, stops_rx) = mpsc::sync_channel(limits.stops);
        let link = pages.clone();
        std::thread::Builder::new().spawn(move || stops::answer(stops_rx, link))?;
        let shared = Arc::new(Shared {
            page: page.render(),
            pages,
            remote: page.remote,
            limits,
            streams: streams.clone(),
            answering: AtomicUsize::new(0),
            stops: stops_tx,
        });
        let stop = done.clone();
        let thread = std::thread::Builder::new().spawn(move || door(&listener, &shared, &stop))?;
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

/// A connection whose request is still coming.
struct Coming {
    stream: TcpStream,
    /// What it sent so far.
    bytes: Vec<u8>,
    /// When it was accepted.
    since: Instant,
}

/// The accepting thread: new connections taken (each read at once), every
/// request still coming read as its bytes come, the one waiting longest giving
/// way to a new one beyond [`Limits::waiting`], those past
/// [`Limits::request_time`] given up, until `done`.
fn door(listener: &TcpListener, shared: &Arc<Shared>, done: &AtomicBool) {
    let limits = shared.limits;
    let mut coming: VecDeque<Coming> = VecDeque::new();
    while !done.load(Ordering::SeqCst) {
        let mut busy = false;
        // At most as many new connections as may wait, then a look at all.
        for _ in 0..limits.waiting.max(1) {
            let Ok((stream, _)) = listener.accept() else {
                break;
            };
            busy = true;
            if stream.set_nonblocking(true).is_err() {
                continue;
            }
            if coming.len() >= limits.waiting {
                // Every request whole by now is taken before one gives way.
                read_all(&mut coming, shared);
            }
            if coming.len() >= limits.waiting {
                if let Some(oldest) = coming.pop_front() {
                    refuse(
                        oldest.stream,
                        503,
                        "too many requests coming at once: the one waiting longest gives way",
                    );
                }
            }
            let new = Coming {
                stream,
                bytes: Vec::new(),
                since: Instant::now(),
            };
            coming.extend(take(new, shared));
        }
        busy |= read_all(&mut coming, shared);
        // Accepted in order: the first is the one waiting longest.
        while coming
            .front()
            .is_some_and(|c| c.since.elapsed() >= limits.request_time)
        {
            if let Some(late) = coming.pop_front() {
                refuse(
                    late.stream,
                    408,
                    &format!(
                        "the request did not arrive whole within {} s",
                        limits.request_time.as_secs_f64()
                    ),
                );
            }
        }
        if !busy {
            std::thread::sleep(ACCEPT_POLL);
        }
    }
}

/// [`take`] on every request still coming, in order; whether any sent
/// something.
fn read_all(coming: &mut VecDeque<Coming>, shared: &Arc<Shared>) -> bool {
    let mut busy = false;
    let before = std::mem::take(coming);
    for c in before {
        let sent = c.bytes.len();
        match take(c, shared) {
            Some(c) => {
                busy |= c.bytes.len() != sent;
                coming.push_back(c);
            }
            None => busy = true,
        }
    }
    busy
}

/// Reads what has come on `c` without waiting: `Some(c)` while its request is
/// still coming; `None` once it is answered, handed on, or gone.
fn take(mut c: Coming, shared: &Arc<Shared>) -> Option<Coming> {
    let mut buf = [0u8; 4096];
    while c.bytes.len() <= http::MAX_HEAD + http::MAX_BODY {
        match c.stream.read(&mut buf) {
            // Closed before its request was whole.
            Ok(0) => return None,
            Ok(n) => c.bytes.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
            Err(_) => return None,
        }
    }
    match http::received(&c.bytes) {
        Received::Partial => Some(c),
        Received::Refused(why) => {
            refuse(c.stream, 400, why);
            None
        }
        Received::Whole(request) => {
            route(c.stream, &request, shared);
            None
        }
    }
}

/// A short answer on `stream` without waiting (its send buffer, empty, takes
/// it), and the connection's end.
fn refuse(stream: TcpStream, status: u16, why: &str) {
    refuse_with(stream, status, "", why);
}

/// [`refuse`] with `extra` header lines (each ending in CRLF).
fn refuse_with(mut stream: TcpStream, status: u16, extra: &str, why: &str) {
    let _ = stream.set_nonblocking(true);
    if http::respond_text(&mut stream, status, extra, why).is_ok() {
        linger(stream);
    }
}

/// Most refused connections closed lingering at once ([`linger`]); past it, a
/// refused connection closes at once.
const LINGERING: usize = 16;

/// How long a refused connection is drained before it closes.
const LINGER: Duration = Duration::from_secs(2);

/// Refused connections lingering now.
static LINGERING_NOW: AtomicUsize = AtomicUsize::new(0);

/// Closes a connection whose answer was written while its client may still be
/// sending (a request refused before it arrived whole): the end of the answer
/// first (`shutdown(Write)`, after the answer's bytes), then what the client
/// still sends read and dropped until it closes too, for at most [`LINGER`], on a
/// thread of its own. A socket closed with bytes unread sends a reset, and a
/// client that receives the reset before it has read the answer loses it (seen
/// under load: a 408 whose body never arrived). At most [`LINGERING`] at once.
fn linger(stream: TcpStream) {
    if LINGERING_NOW.fetch_add(1, Ordering::SeqCst) >= LINGERING {
        LINGERING_NOW.fetch_sub(1, Ordering::SeqCst);
        return;
    }
    let spawned = std::thread::Builder::new()
        .name("linger".into())
        .spawn(move || {
            let mut stream = stream;
            let _ = stream.shutdown(std::net::Shutdown::Write);
            let _ = stream.set_nonblocking(false);
            let until = Instant::now() + LINGER;
            let mut sink = [0u8; 512];
            loop {
                let left = until.saturating_duration_since(Instant::now());
                if left.is_zero() || stream.set_read_timeout(Some(left)).is_err() {
                    break;
                }
                match stream.read(&mut sink) {
                    Ok(0) | Err(_) => break,
                    Ok(_) => {}
                }
            }
            LINGERING_NOW.fetch_sub(1, Ordering::SeqCst);
        });
    if spawned.is_err() {
        LINGERING_NOW.fetch_sub(1, Ordering::SeqCst);
    }
}

/// A whole request answered: refused here, or handed to a thread.
fn route(stream: TcpStream, request: &Request, shared: &Arc<Shared>) {
    let Some(host) = request.header("host") else {
        return refuse(
            stream,
            400,
            "no Host header: an HTTP/1.1 request names its host",
        );
    };
    if !shared.remote && !loopback_host(Some(host)) {
        return refuse(
            stream,
            403,
            "this page answers requests for 127.0.0.1, localhost or [::1] only",
        );
    }
    let limits = shared.limits;
    match (request.path.as_str(), request.method.as_str()) {
        ("/", "GET") => {
            if shared.answering.fetch_add(1, Ordering::SeqCst) >= limits.answering {
                shared.answering.fetch_sub(1, Ordering::SeqCst);
                return refuse(stream, 503, "too many pages being sent at once");
            }
            spawn(
                stream,
                shared,
                |s| &s.answering,
                move |mut s, shared| {
                    s.set_write_timeout(Some(limits.request_time))?;
                    http::respond(
                        &mut s,
                        200,
                        "",
                        "text/html; charset=utf-8",
                        shared.page.as_bytes(),
                    )
                },
            );
        }
        ("/events", "GET") => {
            if shared.streams.fetch_add(1, Ordering::SeqCst) >= limits.streams {
                shared.streams.fetch_sub(1, Ordering::SeqCst);
                return refuse(
                    stream,
                    503,
                    &format!("{} event streams are open: no more", limits.streams),
                );
            }
            spawn(
                stream,
                shared,
                |s| &s.streams,
                |s, shared| stream::events(s, &shared.pages, shared.limits.drain),
            );
        }
        ("/stop", "POST") => {
            if let Some(from) = foreign_stop(request) {
                return refuse(
                    stream,
                    403,
                    &format!("Stop is taken from this page only (this one says {from})"),
                );
            }
            match shared.stops.try_send(stream) {
                Ok(()) => {}
                Err(TrySendError::Full(s)) => refuse(
                    s,
                    503,
                    &format!(
                        "{} Stops are waiting for the device's answer already: the device gets a Stop",
                        limits.stops
                    ),
                ),
                Err(TrySendError::Disconnected(s)) => refuse(s, 503, "the server is ending"),
            }
        }
        ("/" | "/events", _) => refuse_with(stream, 405, "Allow: GET\r\n", "GET only"),
        ("/stop", _) => refuse_with(stream, 405, "Allow: POST\r\n", "POST only"),
        _ => refuse(stream, 404, "no such page: the page is at /"),
    }
}

/// `work` on `stream` on a thread of its own, blocking; the count `of` (taken
/// already by the caller) given back when it ends, or at once, with a 503, when
/// no thread can be had.
fn spawn(
    stream: TcpStream,
    shared: &Arc<Shared>,
    of: fn(&Shared) -> &AtomicUsize,
    work: impl FnOnce(TcpStream, &Shared) -> io::Result<()> + Send + 'static,
) {
    let again = stream.try_clone();
    let mine = shared.clone();
    let spawned = std::thread::Builder::new().spawn(move || {
        let _ = stream.set_nodelay(true);
        if stream.set_nonblocking(false).is_ok() {
            let _ = work(stream, &mine);
        }
        of(&mine).fetch_sub(1, Ordering::SeqCst);
    });
    if spawned.is_err() {
        of(shared).fetch_sub(1, Ordering::SeqCst);
        if let Ok(s) = again {
            refuse(s, 503, "no thread to answer with");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::hub::{self, Event, LinkEnd};
    use super::*;
    use std::io::Write;

    /// A server within `limits` on a free loopback port, its address, and the
    /// link's end of its hub.
    fn started(limits: Limits) -> (Server, std::net::SocketAddr, LinkEnd) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let (link, pages) = hub::hub();
        let page = Page {
            device: "sim".into(),
            period_ms: 100,
            remote: false,
        };
        let server = Server::start(listener, &page, pages, limits).unwrap();
        (server, addr, link)
    }

    /// The link thread's part for Stops: each batch answered `stop: accepted`,
    /// until `link` is handed back through the returned stopper.
    fn answering(link: LinkEnd) -> (Arc<AtomicBool>, JoinHandle<LinkEnd>) {
        let done = Arc::new(AtomicBool::new(false));
        let until = done.clone();
        let thread = std::thread::spawn(move || {
            while !until.load(Ordering::SeqCst) {
                for reply in link.stop_requests() {
                    let _ = reply.send(Ok("stop: accepted".into()));
                }
                std::thread::sleep(Duration::from_millis(5));
            }
            link
        });
        (done, thread)
    }

    /// The whole answer to `request` sent at once on a new connection (read for
    /// at most 30 s: a server that never answers fails the test).
    fn ask(addr: std::net::SocketAddr, request: &str) -> String {
        let mut c = TcpStream::connect(addr).unwrap();
        c.write_all(request.as_bytes()).unwrap();
        answer(&mut c)
    }

    /// What `c` receives until its end (at most 30 s).
    fn answer(c: &mut TcpStream) -> String {
        c.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        let mut bytes = Vec::new();
        // A reset after the answer (the server closed with bytes unread) ends it too.
        let _ = c.read_to_end(&mut bytes);
        String::from_utf8_lossy(&bytes).into_owned()
    }

    #[test]
    fn half_sent_requests_cannot_keep_a_stop_out() {
        // No request cut at its deadline while the test runs, however slowly.
        let limits = Limits {
            request_time: Duration::from_secs(3600),
            ..Limits::default()
        };
        let (server, addr, link) = started(limits);
        let (done, link_thread) = answering(link);
        // Many more clients than may wait, each sending the start of a request
        // and nothing more (issue: 32 of them took every slot, and every Stop
        // got 503 for as long as they kept coming).
        let half: Vec<TcpStream> = (0..limits.waiting * 2)
            .map(|_| {
                let mut c = TcpStream::connect(addr).unwrap();
                c.write_all(b"POST /stop HTTP/1.1\r\nHost: 127.0.0.1")
                    .unwrap();
                c
            })
            .collect();
        let stop = format!("POST /stop HTTP/1.1\r\nHost: {addr}\r\nContent-Length: 0\r\n\r\n");
        for _ in 0..3 {
            let a = ask(addr, &stop);
            assert!(a.starts_with("HTTP/1.1 200 "), "{a:?}");
            assert!(
                a.ends_with("{\"accepted\":true,\"answer\":\"stop: accepted\"}"),
                "{a:?}"
            );
        }
        // The first half gave way to the others (503); the others still wait.
        let mut first = half.into_iter().next().unwrap();
        assert!(answer(&mut first).starts_with("HTTP/1.1 503 "));
        done.store(true, Ordering::SeqCst);
        drop(link_thread.join().unwrap());
        server.finish(Duration::ZERO);
    }

    #[test]
    fn the_request_waiting_longest_gives_way_and_a_late_one_is_cut() {
        let limits = Limits {
            waiting: 4,
            request_time: Duration::from_secs(3600),
            ..Limits::default()
        };
        let (server, addr, _link) = started(limits);
        // Silent clients, one more than may wait: the first gives way at once.
        let mut silent: Vec<TcpStream> = (0..=limits.waiting)
            .map(|_| TcpStream::connect(addr).unwrap())
            .collect();
        let first = answer(&mut silent[0]);
        assert!(first.starts_with("HTTP/1.1 503 "), "{first:?}");
        assert!(
            first.contains("the one waiting longest gives way"),
            "{first:?}"
        );
        server.finish(Duration::ZERO);

        let limits = Limits {
            request_time: Duration::from_millis(300),
            ..Limits::default()
        };
        let (server, addr, _link) = started(limits);
        // One that sends a byte now and then: each read alone is quick, the
        // whole request never arrives; cut at the deadline.
        let mut dribble = TcpStream::connect(addr).unwrap();
        let mut reader = dribble.try_clone().unwrap();
        let writer = std::thread::spawn(move || {
            for _ in 0..1500 {
                if dribble.write_all(b"G").is_err() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        });
        let late = answer(&mut reader);
        assert!(late.starts_with("HTTP/1.1 408 "), "{late:?}");
        assert!(
            late.contains("did not arrive whole within 0.3 s"),
            "{late:?}"
        );
        writer.join().unwrap();
        server.finish(Duration::ZERO);
    }

    #[test]
    fn a_page_that_stops_reading_is_dropped_and_one_that_reads_is_kept() {
        let limits = Limits {
            drain: Duration::from_secs(3),
            ..Limits::default()
        };
        let (server, addr, mut link) = started(limits);
        let events = format!("GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n");
        let mut idle = TcpStream::connect(addr).unwrap();
        idle.write_all(events.as_bytes()).unwrap();
        let mut reading = TcpStream::connect(addr).unwrap();
        reading.write_all(events.as_bytes()).unwrap();
        // Reads a little at a time with pauses, keeping up on the whole (1 kB
        // every 50 ms, the frames 5 kB/s).
        let received = Arc::new(AtomicUsize::new(0));
        let count = received.clone();
        let reader = std::thread::spawn(move || {
            reading
                .set_read_timeout(Some(Duration::from_secs(30)))
                .unwrap();
            let mut buf = [0u8; 1024];
            loop {
                match reading.read(&mut buf) {
                    Ok(0) | Err(_) => return,
                    Ok(n) => count.fetch_add(n, Ordering::SeqCst),
                };
                std::thread::sleep(Duration::from_millis(50));
            }
        });
        // Frames of 500 bytes every 100 ms, as the telemetry's at its default
        // period: a trickle the kernel takes for minutes from a page that never
        // reads (its receive buffer grows). Until the idle page is dropped: at
        // most 30 s, or the test fails.
        let frame: Arc<str> = format!("\"{}\"", "x".repeat(490)).into();
        let started = Instant::now();
        let publish = |link: &mut LinkEnd| {
            link.publish(Event::Frame(frame.clone()));
            std::thread::sleep(Duration::from_millis(100));
        };
        while server.streams.load(Ordering::SeqCst) < 2 {
            publish(&mut link);
            assert!(started.elapsed() < Duration::from_secs(60), "no streams");
        }
        while server.streams.load(Ordering::SeqCst) == 2 {
            publish(&mut link);
            assert!(
                started.elapsed() < Duration::from_secs(30),
                "the page that reads nothing was not dropped"
            );
        }
        // The reading page is the one left, and goes on getting frames for
        // twice the limit.
        let before = received.load(Ordering::SeqCst);
        let again = Instant::now();
        while again.elapsed() < limits.drain * 2 {
            publish(&mut link);
        }
        assert_eq!(server.streams.load(Ordering::SeqCst), 1);
        assert!(received.load(Ordering::SeqCst) > before + 5 * 500);
        assert!(!reader.is_finished(), "the reading page was dropped");
        // The idle page's connection was ended by the server: what it holds is
        // what was sent before and within the limit, not minutes of frames.
        let rest = answer(&mut idle);
        assert!(rest.starts_with("HTTP/1.1 200 OK\r\n"), "{}", &rest[..64]);
        assert!(rest.len() < 1 << 20, "{} bytes", rest.len());
        link.publish(Event::End("test over".into()));
        drop(link);
        reader.join().unwrap();
        server.finish(Duration::from_secs(5));
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
