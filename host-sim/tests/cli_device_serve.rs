//! `host-sim device telemetry --serve` through the real binary against the real
//! `host-sim device-sim` over TCP: the routes over plain HTTP (the page, the
//! event stream's frames, Stop and its acknowledgement, also behind half-sent
//! requests, 404/405, the loopback and origin checks, two Host headers, the end
//! of the stream), the remote warning, the refusal of a
//! network address without `--allow-remote`, and the live page in a headless
//! chromium: values that change, Pause, no console error, Stop stopping the
//! device (seen by `host-sim device status`), a screenshot in
//! `target/browser/live-telemetry.png`.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, ChildStderr, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

mod browser;
mod common;
use common::device_sim::DeviceSim;

impl DeviceSim {
    /// `host-sim device --port PORT args...` to its end.
    fn run(&self, args: &[&str]) -> common::Run {
        let mut cmd = common::host_sim();
        cmd.args(["device", "--port", &self.port])
            .args(args)
            .stdin(Stdio::null());
        common::finish_within(cmd, Duration::from_secs(20))
    }

    /// `host-sim device --port PORT telemetry --serve ...args`, started; its
    /// page's address (`http://HOST:PORT`, from the line on stderr).
    fn serve(&self, args: &[&str]) -> Served {
        let mut child = common::host_sim()
            .args(["device", "--port", &self.port, "telemetry", "--serve"])
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("host-sim runs");
        let lines = lines(child.stderr.take().expect("piped"));
        let mut said = Vec::new();
        let url = loop {
            let line = lines
                .recv_timeout(Duration::from_secs(10))
                .unwrap_or_else(|_| panic!("no address on stderr; it said {said:?}"));
            if let Some(at) = line.find("http://") {
                let url = line[at..].split(' ').next().unwrap_or_default();
                break url.trim_end_matches('/').to_string();
            }
            said.push(line);
        };
        Served {
            child,
            url,
            stderr: lines,
        }
    }
}

/// The lines of `stderr` as they come.
fn lines(stderr: ChildStderr) -> Receiver<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// A `telemetry --serve` running.
struct Served {
    child: Child,
    /// `http://HOST:PORT`.
    url: String,
    /// Its stderr lines after the address.
    stderr: Receiver<String>,
}

impl Served {
    /// `HOST:PORT`.
    fn addr(&self) -> &str {
        self.url.trim_start_matches("http://")
    }

    /// Wait for its end (at most `limit`): exit status, stdout, stderr after the
    /// address line.
    fn wait(mut self, limit: Duration) -> (i32, String, String) {
        let start = Instant::now();
        let status = loop {
            if let Some(s) = self.child.try_wait().expect("wait") {
                break s;
            }
            if start.elapsed() > limit {
                let _ = self.child.kill();
                panic!("telemetry --serve did not end within {limit:?}");
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let mut out = String::new();
        self.child
            .stdout
            .take()
            .expect("piped")
            .read_to_string(&mut out)
            .expect("stdout");
        let err: Vec<String> = self.stderr.try_iter().collect();
        let err = err.join("\n");
        assert!(!err.contains("panicked"), "{err}");
        (status.code().unwrap_or(-1), out, err)
    }

    /// Ctrl-C to it (the child this test started, by its id).
    #[cfg(unix)]
    fn interrupt(&self) {
        let pid = nix::unistd::Pid::from_raw(i32::try_from(self.child.id()).unwrap());
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).unwrap();
    }
}

/// One HTTP request (`head` without its final empty line) to `addr`; the whole
/// response.
fn http(addr: &str, head: &str) -> String {
    let mut s = TcpStream::connect(addr).expect("the page's server");
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(s, "{head}\r\nConnection: close\r\n\r\n").unwrap();
    let mut out = String::new();
    s.read_to_string(&mut out).expect("a whole response");
    out
}

/// `GET path` from `addr` with a loopback Host.
fn get(addr: &str, path: &str) -> String {
    http(addr, &format!("GET {path} HTTP/1.1\r\nHost: {addr}"))
}

/// The status line's code and the body of a response.
fn status_body(response: &str) -> (u16, String) {
    let code = response
        .get(9..12)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status line in {response:?}"));
    let body = response.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    (code, body.to_string())
}

#[test]
fn a_network_address_needs_allow_remote_and_a_bad_one_is_refused() {
    // Checked before the port is opened: no device needed.
    let port = "tcp:127.0.0.1:1";
    for (addr, needle) in [
        ("0.0.0.0:8321", "not a loopback address"),
        ("0.0.0.0:8321", "--allow-remote"),
        ("nonsense", "--serve: `nonsense` is no address to listen on"),
        ("127.0.0.1:99999", "is no address to listen on"),
    ] {
        common::run(&["device", "--port", port, "telemetry", "--serve", addr]).refused(needle);
    }
    // --allow-remote means nothing alone; --serve replaces --csv and --count.
    for args in [
        &["telemetry", "--allow-remote"][..],
        &["telemetry", "--serve", "--csv", "-"],
        &["telemetry", "--serve", "127.0.0.1:0", "--count", "3"],
    ] {
        let mut all = vec!["device", "--port", port];
        all.extend_from_slice(args);
        assert_eq!(common::run(&all).status, 2, "{args:?}");
    }
}

#[cfg(unix)]
#[test]
fn the_routes_over_plain_http() {
    let dev = DeviceSim::start(&[]);
    // At a frame every 50 ms, until the operator's Ctrl-C after the requests
    // below (however long a loaded machine takes for them).
    let served = dev.serve(&["127.0.0.1:0", "--period", "50"]);
    let addr = served.addr().to_string();

    let (code, page) = status_body(&get(&addr, "/"));
    assert_eq!(code, 200);
    assert!(page.contains("window.vibroLive"), "{page}");
    assert!(page.contains(&dev.port), "the page names the device");
    assert!(
        !page.contains("id=\"remote\""),
        "no remote warning on loopback"
    );
    assert!(
        !page.contains("http://") && !page.contains("https://"),
        "nothing fetched elsewhere"
    );

    // The event stream: frames as JSON with the CSV's names, kept open to see
    // its end.
    let mut events = TcpStream::connect(&addr).unwrap();
    events
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    write!(events, "GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
    let mut events = BufReader::new(events);
    let mut head = String::new();
    while !head.ends_with("\r\n\r\n") {
        events.read_line(&mut head).unwrap();
    }
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert!(head.contains("Content-Type: text/event-stream"), "{head}");
    let mut frames = Vec::new();
    while frames.len() < 3 {
        let mut line = String::new();
        events.read_line(&mut line).unwrap();
        if let Some(data) = line.strip_prefix("data: ") {
            frames.push(serde_json::from_str::<Value>(data).expect("JSON"));
        }
    }
    let names: Vec<&str> = common::TELEMETRY_CSV_HEADER.split(',').collect();
    assert_eq!(common::keys(&frames[0]), names);
    // Frames in order, about a period apart (the device's clock, ms): later
    // each time, and three within 3 periods and a heartbeat's slack.
    let uptime = |k: usize| frames[k]["uptime_ms"].as_u64().unwrap();
    assert!(uptime(0) < uptime(1) && uptime(1) < uptime(2));
    assert!(uptime(2) - uptime(0) <= 3 * 50 + 50, "{frames:?}");

    // Anything but the three routes.
    assert_eq!(status_body(&get(&addr, "/nope")).0, 404);
    let r = get(&addr, "/stop");
    assert_eq!(status_body(&r).0, 405);
    assert!(r.contains("Allow: POST\r\n"), "{r}");
    let post = |path: &str, extra: &str| {
        http(
            &addr,
            &format!("POST {path} HTTP/1.1\r\nHost: {addr}\r\nContent-Length: 0{extra}"),
        )
    };
    assert_eq!(status_body(&post("/", "")).0, 405);
    assert_eq!(status_body(&post("/events", "")).0, 405);
    // A name that is not loopback (DNS rebinding), a Stop from another site.
    let r = http(&addr, "GET / HTTP/1.1\r\nHost: attacker.example:8321");
    assert_eq!(status_body(&r).0, 403);
    let r = post("/stop", "\r\nOrigin: http://attacker.example");
    assert_eq!(status_body(&r).0, 403);
    // Without Origin, the browser's other words for another site's page.
    let r = post("/stop", "\r\nSec-Fetch-Site: cross-site");
    assert_eq!(status_body(&r).0, 403, "{r}");
    let r = post("/stop", "\r\nReferer: http://attacker.example/page");
    assert_eq!(status_body(&r).0, 403, "{r}");
    // Two Host headers: neither is taken.
    for hosts in [
        format!("Host: {addr}\r\nHost: attacker.example"),
        format!("Host: attacker.example\r\nHost: {addr}"),
    ] {
        let r = http(&addr, &format!("GET / HTTP/1.1\r\n{hosts}"));
        assert_eq!(status_body(&r).0, 400, "{r}");
        assert!(r.contains("two Host headers"), "{r}");
    }
    // Clients that send the start of a request and nothing more, more than the
    // server lets wait: the Stop below still gets through.
    let half: Vec<TcpStream> = (0..80)
        .map(|_| {
            let mut s = TcpStream::connect(&addr).unwrap();
            s.write_all(b"POST /stop HTTP/1.1\r\nHost: 127.0.0.1")
                .unwrap();
            s
        })
        .collect();

    // Stop, acknowledged by the device.
    let r = post("/stop", &format!("\r\nOrigin: http://{addr}"));
    let (code, body) = status_body(&r);
    assert_eq!(code, 200, "{r}");
    assert_eq!(
        serde_json::from_str::<Value>(&body).unwrap(),
        json!({ "accepted": true, "answer": "stop: accepted" })
    );
    drop(half);

    // Ctrl-C ends it: the open stream gets its end, the stream is off.
    served.interrupt();
    let mut end = None;
    for line in events.lines() {
        let line = line.expect("the stream until its end");
        if line == "event: end" {
            end = Some(line);
            break;
        }
    }
    assert!(end.is_some(), "no end event");
    let (status, out, err) = served.wait(Duration::from_secs(120));
    assert_eq!(status, 0, "{out}{err}");
    assert!(out.contains("stop: accepted (from the page)\n"), "{out}");
    assert!(out.contains(" frames served\n"), "{out}");
    // The link is free again, and the device answers.
    let s = dev.run(&["status"]);
    assert_eq!(s.status, 0, "{}", s.stderr);
}

#[test]
fn a_network_address_with_allow_remote_warns_on_the_page() {
    let dev = DeviceSim::start(&[]);
    let served = dev.serve(&["0.0.0.0:0", "--allow-remote", "--duration", "1.5"]);
    // The line after the address.
    let warning = served.stderr.recv_timeout(Duration::from_secs(5));
    assert!(
        warning
            .as_deref()
            .is_ok_and(|l| l.contains("reachable from the network")),
        "{warning:?}"
    );
    // Served on every interface: reached here through loopback.
    let port = served.addr().rsplit_once(':').unwrap().1.to_string();
    let (code, page) = status_body(&get(&format!("127.0.0.1:{port}"), "/"));
    assert_eq!(code, 200);
    assert!(page.contains("id=\"remote\""), "{page}");
    assert!(page.contains("can stop the device"), "{page}");
    let (status, out, err) = served.wait(Duration::from_secs(10));
    assert_eq!(status, 0, "{out}{err}");
}

/// The canvas `id`'s pixels as a data URL (to compare two drawings).
#[cfg(unix)]
fn canvas(id: &str) -> String {
    format!("document.getElementById('{id}').toDataURL()")
}

#[cfg(unix)]
#[test]
fn the_live_page_in_a_browser_shows_the_stream_and_its_stop_stops_the_device() {
    // Chromium first, then the device.
    let Some(mut b) = browser::Browser::launch() else {
        return;
    };
    let dev = DeviceSim::start(&[]);
    // The travel returns at once; the page's server takes over the link (the
    // test's device-sim has a link timeout of 300 s: no load makes it lapse).
    let t = dev.run(&["travel", "right", "--speed", "3000"]);
    assert_eq!(t.status, 0, "{}", t.stderr);
    let served = dev.serve(&["127.0.0.1:0", "--period", "50"]);
    b.navigate(&format!("{}/", served.url));

    // Frames come and their values change: ten more frames, however long a
    // loaded machine takes to bring them (a frame every 50 ms otherwise).
    b.wait_for("window.vibroLive.frames >= 3", Duration::from_secs(10));
    let sample = "[vibroLive.frames, vibroLive.last.uptime_ms, vibroLive.last.speed1_rpm, vibroLive.last.state]";
    let first = b.eval(sample);
    assert!(
        matches!(first[3].as_str(), Some("starting" | "running")),
        "the travel did not survive the hand-over: {first}"
    );
    let ten_more = first[0].as_u64().map_or(10, |n| n + 10);
    b.wait_for(
        &format!("window.vibroLive.frames >= {ten_more}"),
        Duration::from_secs(120),
    );
    let second = b.eval(sample);
    assert!(
        second[0].as_u64() >= first[0].as_u64().map(|n| n + 10),
        "{first} then {second}"
    );
    assert!(
        second[1].as_u64() > first[1].as_u64(),
        "{first} then {second}"
    );
    assert_ne!(
        second[2], first[2],
        "the speed did not change: {first} then {second}"
    );

    // Running at the speed asked for, and the page says so: the device holds
    // 3000 rpm within a few rpm (docs/cli-device.md's status); 1 % is the margin.
    b.wait_for(
        "vibroLive.last.state === 'running'",
        Duration::from_secs(10),
    );
    let last = b.eval("vibroLive.last");
    for key in ["speed1_rpm", "speed2_rpm", "speed_ref1_rpm"] {
        let v = last[key].as_f64().unwrap();
        assert!((v - 3000.0).abs() < 30.0, "{key} {v}: {last}");
    }
    assert_eq!(
        b.eval("document.getElementById('state').textContent"),
        "running"
    );
    assert_eq!(
        b.eval("document.getElementById('faults').textContent"),
        "none"
    );
    // The speed plot has its curves: pixels of rotor 1's blue (#1f77b4) drawn.
    let blue = b.eval(
        "(() => { const c = document.getElementById('plot-speed');
          const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
          let n = 0;
          for (let i = 0; i < d.length; i += 4)
            if (Math.abs(d[i] - 0x1f) < 40 && Math.abs(d[i + 1] - 0x77) < 40 && Math.abs(d[i + 2] - 0xb4) < 40) n++;
          return n; })()",
    );
    assert!(
        blue.as_u64() > Some(50),
        "no curve drawn: {blue} blue pixels"
    );

    // Pause freezes the plots while frames still come; Resume lets them move.
    b.click("#pause");
    let frozen = b.eval(&canvas("plot-speed"));
    let frames = b.eval("vibroLive.frames");
    b.eval(&format!("window.frozenPlot = {}", canvas("plot-speed")));
    b.wait_for(
        &format!("vibroLive.frames >= {}", frames.as_u64().unwrap_or(0) + 5),
        Duration::from_secs(120),
    );
    assert_eq!(
        b.eval(&canvas("plot-speed")),
        frozen,
        "the plot moved while paused"
    );
    assert!(b.eval("vibroLive.frames").as_u64() > frames.as_u64());
    b.click("#pause");
    b.wait_for(
        &format!("{} !== window.frozenPlot", canvas("plot-speed")),
        Duration::from_secs(120),
    );
    assert_ne!(
        b.eval(&canvas("plot-speed")),
        frozen,
        "the plot did not resume"
    );

    // Stop: the device's acknowledgement on the page, the rotors ramping down.
    b.click("#stop");
    let answer = b.wait_for("vibroLive.stopAnswer", Duration::from_secs(10));
    assert_eq!(
        answer,
        json!({ "accepted": true, "answer": "stop: accepted" })
    );
    assert_eq!(
        b.eval("document.getElementById('answer').textContent"),
        "stop: accepted"
    );
    b.wait_for(
        "['stopping', 'idle'].includes(vibroLive.last.state)",
        Duration::from_secs(5),
    );
    // A second of the ramp down in the picture.
    std::thread::sleep(Duration::from_secs(1));
    let png = browser::output_dir().join("live-telemetry.png");
    b.screenshot(&png);
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "not a PNG");
    assert_eq!(b.console_errors(), Vec::<String>::new());

    // Ctrl-C ends the server: the page is told, and does not try again.
    served.interrupt();
    b.wait_for("vibroLive.ended", Duration::from_secs(5));
    let (status, out, err) = served.wait(Duration::from_secs(10));
    assert_eq!(status, 0, "{out}{err}");
    assert!(out.contains("stop: accepted (from the page)\n"), "{out}");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(b.console_errors(), Vec::<String>::new());

    // The device stopped (the page's Stop, not a lapsed link: the link timeout
    // is 300 s): stopping or idle, with no fault.
    let s = dev.run(&["status"]);
    assert_eq!(s.status, 0, "{}", s.stderr);
    let state = s.stdout.lines().next().unwrap_or_default();
    assert!(
        state.ends_with(" idle") || state.ends_with(" stopping"),
        "{}",
        s.stdout
    );
    assert!(s.stdout.contains("faults          none\n"), "{}", s.stdout);
}

/// The page's numbers: the measured phase offset is drawn while the rotors are
/// driven and not after they stop (the device still reports it valid at rest: the
/// last angle they stopped at), its reference only while the phase loop holds it;
/// the axis labels are whole multiples of the tick step with its decimals, never the
/// residue of adding steps (`-1.38778e-17` for 0, clipped at the plot's edge).
#[cfg(unix)]
#[test]
fn the_live_page_draws_the_offset_only_while_driven_and_clean_axis_labels() {
    let Some(mut b) = browser::Browser::launch() else {
        return;
    };
    let dev = DeviceSim::start(&[]);
    let t = dev.run(&["travel", "right", "--speed", "3000"]);
    assert_eq!(t.status, 0, "{}", t.stderr);
    let served = dev.serve(&["127.0.0.1:0", "--period", "50"]);
    b.navigate(&format!("{}/", served.url));
    let legend = "document.getElementById('legend-offset').textContent";
    b.wait_for(
        &format!(
            "vibroLive.last && vibroLive.last.phase_loop_closed && /measured \\d/.test({legend}) && /reference \\d/.test({legend})"
        ),
        Duration::from_secs(15),
    );

    b.click("#stop");
    b.wait_for("vibroLive.last.state === 'idle'", Duration::from_secs(30));
    b.wait_for(
        &format!("/measured -/.test({legend}) && /reference -/.test({legend})"),
        Duration::from_secs(5),
    );
    assert_eq!(
        b.eval("vibroLive.last.phase_valid"),
        json!(true),
        "the device no longer reports the offset valid: this test shows nothing"
    );

    // The ranges of the page's axes where adding steps left a residue at 0 (found
    // by trying random ranges against a loop that adds the steps), and usual ones.
    let ranges = [
        (-0.2444567336, 0.0000518796),
        (-0.4521962937, 0.0000063742),
        (-0.0365244471, 0.0008416908),
        (-0.001, 0.001),
        (2990.0, 3010.0),
        (11.9, 12.1),
    ];
    for (lo, hi) in ranges {
        let labels = b.eval(&format!("vibroLive.ticks({lo}, {hi}).map((t) => t.label)"));
        let labels: Vec<&str> = labels
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l.as_str().unwrap())
            .collect();
        let places = |l: &str| l.split_once('.').map_or(0, |(_, d)| d.len());
        let values: Vec<f64> = labels.iter().map(|l| l.parse().unwrap()).collect();
        assert!(labels.len() >= 3, "{lo}..{hi}: {labels:?}");
        for (l, v) in labels.iter().zip(&values) {
            assert!(!l.contains('e') && l.len() <= 8, "{lo}..{hi}: {labels:?}");
            assert!(*v >= lo && *v <= hi, "{lo}..{hi}: {labels:?}");
            assert_eq!(places(l), places(labels[0]), "{lo}..{hi}: {labels:?}");
            assert!(!(l.starts_with('-') && *v == 0.0), "{lo}..{hi}: {labels:?}");
        }
        // Evenly spaced to the labels' last decimal.
        let step = values[1] - values[0];
        for w in values.windows(2) {
            assert!(
                ((w[1] - w[0]) - step).abs() < 1e-9 * step.abs().max(1.0),
                "{lo}..{hi}: {labels:?}"
            );
        }
    }
    // The currents at rest: the axis drawn around 0.
    let current = b.eval("vibroLive.axes.current");
    assert!(
        current
            .as_array()
            .unwrap()
            .iter()
            .all(|l| !l.as_str().unwrap().contains('e')),
        "{current}"
    );
    assert_eq!(b.console_errors(), Vec::<String>::new());
    served.interrupt();
    let (status, out, err) = served.wait(Duration::from_secs(10));
    assert_eq!(status, 0, "{out}{err}");
}
