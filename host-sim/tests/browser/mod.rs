//! Tests in a real browser: Debian's `chromium`, headless, driven through the
//! Chrome DevTools Protocol over a WebSocket ([`websocket`]).
//!
//! ```ignore
//! mod browser;
//! let Some(mut b) = browser::Browser::launch() else { return }; // no chromium here
//! b.navigate("http://127.0.0.1:8321/");
//! let frames = b.wait_for("window.vibroLive.frames >= 5", Duration::from_secs(10));
//! b.click("#stop");
//! b.screenshot(&browser::output_dir().join("live.png"));
//! assert_eq!(b.console_errors(), Vec::<String>::new());
//! ```
//!
//! Without chromium a test skips with a notice on stderr ([`Browser::launch`] is
//! `None`), except under CI (`CI=true`), where it fails: CI installs chromium
//! (`scripts/test-all.sh`). Screenshots go to [`output_dir`], `target/browser/`.
// Each test file uses its own subset of these.
#![allow(dead_code)]

pub mod websocket;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serde_json::{json, Value};

use websocket::WebSocket;

/// The page's size, CSS pixels (the screenshots' size).
pub const VIEWPORT: (u32, u32) = (1280, 900);

/// How long chromium may take to start and a protocol command to answer.
const TIMEOUT: Duration = Duration::from_secs(30);

/// Where the browser tests write their screenshots: `$CARGO_TARGET_DIR/browser`,
/// by default `target/browser/` at the repository root.
pub fn output_dir() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../target"));
    target.join("browser")
}

/// The chromium to run: `$CHROMIUM`, else the first of the usual names on the
/// `PATH`.
fn chromium() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os("CHROMIUM") {
        return Some(PathBuf::from(path));
    }
    let path = std::env::var_os("PATH")?;
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .flat_map(|name| std::env::split_paths(&path).map(move |dir| dir.join(name)))
        .find(|p| p.is_file())
}

/// A headless chromium with one page, closed when dropped.
pub struct Browser {
    child: Child,
    profile: PathBuf,
    ws: WebSocket,
    /// The page's session (`Target.attachToTarget`, flat mode).
    session: String,
    next_id: u64,
    /// Errors the page logged or threw, in order.
    errors: Vec<String>,
}

impl Browser {
    /// Start chromium with an empty page. `None` when chromium is not installed
    /// and this is not CI (a notice on stderr); under CI (`CI=true`) a missing
    /// chromium fails the test.
    pub fn launch() -> Option<Browser> {
        let Some(exe) = chromium() else {
            let why = "chromium is not installed (apt-get install chromium; \
                       scripts/test-all.sh installs it)";
            if std::env::var("CI").is_ok_and(|v| v == "true") {
                panic!("{why}: the browser tests cannot run");
            }
            eprintln!("notice: browser test skipped: {why}");
            return None;
        };
        let profile = std::env::temp_dir().join(format!(
            "host-sim-chromium-{}-{}",
            std::process::id(),
            clock_nanos()
        ));
        let mut child = Command::new(&exe)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--remote-debugging-port=0",
                "--no-first-run",
                "--no-default-browser-check",
                "--disable-extensions",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--hide-scrollbars",
                "--mute-audio",
                &format!("--window-size={},{}", VIEWPORT.0, VIEWPORT.1),
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg("about:blank")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("{}: cannot start: {e}", exe.display()));
        // The DevTools address on stderr; the rest of stderr drained and kept for
        // a failure's message.
        let stderr = child.stderr.take().expect("piped");
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                let url = line
                    .strip_prefix("DevTools listening on ")
                    .map(|u| u.trim().to_string());
                let _ = tx.send((line, url));
            }
        });
        let start = Instant::now();
        let mut said = Vec::new();
        let url = loop {
            match rx.recv_timeout(TIMEOUT.saturating_sub(start.elapsed())) {
                Ok((_, Some(url))) => break url,
                Ok((line, None)) => said.push(line),
                Err(_) => {
                    let _ = child.kill();
                    panic!(
                        "{} gave no DevTools address within {TIMEOUT:?}; it said:\n{}",
                        exe.display(),
                        said.join("\n")
                    );
                }
            }
        };
        let ws = WebSocket::connect(&url).unwrap_or_else(|e| panic!("{url}: {e}"));
        let mut b = Browser {
            child,
            profile,
            ws,
            session: String::new(),
            next_id: 0,
            errors: Vec::new(),
        };
        let target = b.browser_call("Target.createTarget", json!({ "url": "about:blank" }));
        let attached = b.browser_call(
            "Target.attachToTarget",
            json!({ "targetId": target["targetId"], "flatten": true }),
        );
        b.session = attached["sessionId"]
            .as_str()
            .expect("a session id")
            .to_string();
        for domain in ["Runtime", "Log", "Page"] {
            b.call(&format!("{domain}.enable"), json!({}));
        }
        b.call(
            "Emulation.setDeviceMetricsOverride",
            json!({ "width": VIEWPORT.0, "height": VIEWPORT.1, "deviceScaleFactor": 1, "mobile": false }),
        );
        Some(b)
    }

    /// Open `url` and wait until it has loaded.
    pub fn navigate(&mut self, url: &str) {
        let r = self.call("Page.navigate", json!({ "url": url }));
        if let Some(e) = r.get("errorText") {
            panic!("{url}: {e}");
        }
        self.wait_for("document.readyState === 'complete'", TIMEOUT);
    }

    /// The value of the JavaScript expression `js` in the page (a promise
    /// awaited), as JSON; an exception thrown fails the test.
    pub fn eval(&mut self, js: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({ "expression": js, "returnByValue": true, "awaitPromise": true }),
        );
        if let Some(e) = r.get("exceptionDetails") {
            let text = e["exception"]["description"]
                .as_str()
                .or(e["text"].as_str())
                .unwrap_or("an exception");
            panic!("{js}: {text}");
        }
        r["result"].get("value").cloned().unwrap_or(Value::Null)
    }

    /// Evaluate `js` every 50 ms until it is truthy (not `false`, `null`, `0`,
    /// `""`); that value. Fails the test after `timeout`, with the last value.
    pub fn wait_for(&mut self, js: &str, timeout: Duration) -> Value {
        let start = Instant::now();
        loop {
            let v = self.eval(js);
            let truthy = match &v {
                Value::Null | Value::Bool(false) => false,
                Value::Number(n) => n.as_f64() != Some(0.0),
                Value::String(s) => !s.is_empty(),
                _ => true,
            };
            if truthy {
                return v;
            }
            if start.elapsed() > timeout {
                panic!("{js}: still {v} after {timeout:?}");
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Click the element `selector` names (a missing one fails the test).
    pub fn click(&mut self, selector: &str) {
        let s = serde_json::to_string(selector).expect("a string");
        let found = self.eval(&format!(
            "(() => {{ const e = document.querySelector({s}); if (e) e.click(); return !!e; }})()"
        ));
        assert_eq!(found, json!(true), "no element {selector}");
    }

    /// What the page logged as errors or threw so far: `console.error`, uncaught
    /// exceptions, the browser's own error entries (a resource that failed).
    pub fn console_errors(&mut self) -> Vec<String> {
        // The events that came since the last command.
        while let Ok(Some(m)) = self.ws.recv(Duration::ZERO) {
            self.event(&m);
        }
        self.errors.clone()
    }

    /// A PNG of the page's viewport to `path` (its folder made).
    pub fn screenshot(&mut self, path: &Path) {
        let r = self.call("Page.captureScreenshot", json!({ "format": "png" }));
        let png = base64_decode(r["data"].as_str().expect("PNG data"));
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).expect("the screenshot's folder");
        }
        std::fs::write(path, png).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }

    /// A command to the page; its result.
    pub fn call(&mut self, method: &str, params: Value) -> Value {
        let session = self.session.clone();
        self.send(method, params, Some(&session))
    }

    /// A command to the browser itself (`Target.*`); its result.
    fn browser_call(&mut self, method: &str, params: Value) -> Value {
        self.send(method, params, None)
    }

    /// Send a command and read until its answer, keeping the events that come
    /// first.
    fn send(&mut self, method: &str, params: Value, session: Option<&str>) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let mut message = json!({ "id": id, "method": method, "params": params });
        if let Some(s) = session {
            message["sessionId"] = json!(s);
        }
        self.ws
            .send(&message.to_string())
            .unwrap_or_else(|e| panic!("{method}: {e}"));
        let start = Instant::now();
        loop {
            let left = TIMEOUT.saturating_sub(start.elapsed());
            let Some(text) = self
                .ws
                .recv(left)
                .unwrap_or_else(|e| panic!("{method}: {e}"))
            else {
                panic!("{method}: no answer within {TIMEOUT:?}");
            };
            let v: Value = serde_json::from_str(&text).expect("DevTools sends JSON");
            if v["id"] == json!(id) {
                if let Some(e) = v.get("error") {
                    panic!("{method}: {e}");
                }
                return v["result"].clone();
            }
            self.event(&text);
        }
    }

    /// An event: errors kept.
    fn event(&mut self, text: &str) {
        let v: Value = serde_json::from_str(text).expect("DevTools sends JSON");
        let p = &v["params"];
        let error = match v["method"].as_str() {
            Some("Runtime.consoleAPICalled")
                if matches!(p["type"].as_str(), Some("error" | "assert")) =>
            {
                let args: Vec<String> = p["args"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .map(|a| match a.get("value") {
                        Some(Value::String(s)) => s.clone(),
                        Some(other) => other.to_string(),
                        None => a["description"].as_str().unwrap_or("?").to_string(),
                    })
                    .collect();
                Some(format!(
                    "console.{}: {}",
                    p["type"].as_str().unwrap_or(""),
                    args.join(" ")
                ))
            }
            Some("Runtime.exceptionThrown") => {
                let d = &p["exceptionDetails"];
                let text = d["exception"]["description"]
                    .as_str()
                    .or(d["text"].as_str())
                    .unwrap_or("?");
                Some(format!("uncaught: {text}"))
            }
            Some("Log.entryAdded") if p["entry"]["level"] == "error" => Some(format!(
                "{}: {} {}",
                p["entry"]["source"].as_str().unwrap_or("log"),
                p["entry"]["text"].as_str().unwrap_or(""),
                p["entry"]["url"].as_str().unwrap_or("")
            )),
            _ => None,
        };
        self.errors.extend(error);
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self
            .ws
            .send(&json!({ "id": 0, "method": "Browser.close" }).to_string());
        let until = Instant::now() + Duration::from_secs(3);
        while Instant::now() < until {
            if let Ok(Some(_)) = self.child.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.profile);
    }
}

/// The clock in nanoseconds, so that two browsers of one test process get their
/// own profile folders.
fn clock_nanos() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Base64 (RFC 4648, section 4, with padding) decoded; other bytes skipped.
pub fn base64_decode(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => Some(c - b'A'),
        b'a'..=b'z' => Some(c - b'a' + 26),
        b'0'..=b'9' => Some(c - b'0' + 52),
        b'+' => Some(62),
        b'/' => Some(63),
        _ => None,
    };
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    // Four characters carry three bytes: 6 bits each, taken 8 at a time.
    let (mut bits, mut held) = (0u32, 0u32);
    for v in text.bytes().filter_map(value) {
        bits = (bits << 6) | u32::from(v);
        held += 6;
        if held >= 8 {
            held -= 8;
            out.push((bits >> held) as u8);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_as_rfc_4648_gives_it() {
        // RFC 4648, section 10.
        for (text, bytes) in [
            ("", ""),
            ("Zg==", "f"),
            ("Zm8=", "fo"),
            ("Zm9v", "foo"),
            ("Zm9vYg==", "foob"),
            ("Zm9vYmE=", "fooba"),
            ("Zm9vYmFy", "foobar"),
        ] {
            assert_eq!(base64_decode(text), bytes.as_bytes(), "{text}");
        }
    }
}
