//! The transcripts the docs show are what the tool prints: every `$ host-sim ...`
//! line of a fenced block that is not a shell block (those are run by
//! `documented_commands.rs`) in `README.md` and `docs/*.md`, with the lines under
//! it up to the next `$` line or the block's end as the output the docs claim.
//!
//! **Which transcripts.** Each is exactly one of:
//!
//! - listed in [`NOT_RUN`] with the reason, found by a piece of its `$` line; an
//!   entry that finds no transcript, or two, fails the test;
//! - run, with the set-up of its entry in [`SETUPS`] (found the same way; an entry
//!   that finds none or two fails), or without one: a transcript whose port is
//!   `tcp:127.0.0.1:5555` and that is not `device-sim` itself needs an entry (the
//!   docs say in a comment what stands behind it), any other runs as it is. A new
//!   transcript in the docs is thus run or listed, never skipped.
//!
//! **How one runs**, in a scratch directory holding copies of `examples/`,
//! `tests/fixtures/` and `tests/scenarios/` (nothing in the repository is
//! written) and the files of its entry (`bad.toml`, `s.toml`: what the output
//! shown implies), the `host-sim` under test in place of `host-sim`, `cmd1 && cmd2`
//! run as a shell would, stdout and stderr into one file in the order written (as
//! on a terminal):
//!
//! - the port: `/dev/pts/0` is a fresh `host-sim device-sim` behind a
//!   pseudo-terminal (the reference rotors, as the docs' own `device-sim` transcript
//!   starts it), one per transcript; `tcp:127.0.0.1:5555` is what the entry
//!   says: a `device-sim --machine examples/vibro-driver.toml`, a `device-sim
//!   --flip-every 12` (a line too noisy for an answer), a listener that accepts
//!   and never answers, or a device of this test's making that acknowledges
//!   another request or never streams (`common::fake_device`); a `device-sim
//!   --listen tcp:127.0.0.1:5555` listens on port 0 instead (any free port), and
//!   `telemetry --serve` without an address serves on `127.0.0.1:0`;
//! - the entry's `host-sim device` commands run first against the same device
//!   (each must succeed): the state the docs' surrounding text implies (rotors
//!   turning after a `travel`, the link kept alive by `telemetry --duration`, the
//!   example table written before it is read back);
//! - the answers to `device tune`'s prompts are piped on stdin, and shown after
//!   each prompt in the output as a terminal echoes them;
//! - `^C` in the output shown: once the lines shown before it are there (and the
//!   entry's action has run: a travel against the device-sim, a Stop from the
//!   live page), SIGINT goes to the command running; the rest of the `^C` line
//!   is its next output line.
//!
//! **How it is compared.** A line that is exactly `...` stands for any lines
//! (none included): the lines between are matched in order, the first at the
//! start and the last at the end unless a `...` is there. Trailing blanks are not
//! compared. Then:
//!
//! - `run`, `scenario`, `impact`, `tune`, ... and every refusal (exit 2) of any
//!   command: the lines must be equal;
//! - `device` and `device-sim` otherwise (their numbers come from a simulation in
//!   real time: speeds, uptimes, currents, the port's number), and `replay` (of a
//!   capture the docs took of such a device just before): the lines compared
//!   with every number (sign, decimals and exponent with it) replaced by `#` and
//!   every run of blanks by one, so the same words in the same order, the same
//!   number of lines and of columns. In a telemetry frame (a readable line
//!   `UPTIME s STATE speed ...` or a CSV row) the controller's state and the
//!   offset's `-` (no offset yet) are values too: a frame is a sample at an
//!   instant of the wall clock, and where a ramp is at that instant depends on
//!   how fast the host started the command;
//! - the exit status: not 0 when the output shown has an `error:` line, 0
//!   otherwise.
//!
//! A transcript that differs is regenerated in the doc from the tool (the command
//! run as the doc shows it, the output pasted), not matched more loosely here.
//!
//! Nothing is timed: the device commands run in real time against a device that
//! keeps the wall clock, and the only bound is against a hang (two minutes a
//! transcript, or a wait within one). The set-ups hand the link from one
//! command to the next, as the docs tell the operator; the device-sims here have
//! the tests' link timeout of 300 s (`common::device_sim::LINK_TIMEOUT_S`, not
//! the firmware's 0.5 s), so no load makes the link lapse between two commands,
//! and a device-sim answers within `device`'s six tries of 100 ms.
//!
//! Cost (2026-11-28, the 2-core VM, test profile): 28 s of wall time, nearly all
//! of it the device transcripts' real time (`device tune`'s three points 9 s,
//! `hold --for 2` 3 s, the set-ups' `telemetry --duration 1.5`); 2.3 s of CPU.

#![cfg(unix)]

use std::fs::File;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

mod common;
use common::device_sim::DeviceSim;
use common::docs;
use common::fake_device::{self, ack};
use shared::protocol::{MessageId, Request, Response};

/// Transcripts not run here: (file, a piece of the `$` line, why).
const NOT_RUN: &[(&str, &str, &str)] = &[];

/// What stands behind the port a transcript names.
#[derive(Clone, Copy)]
enum Device {
    /// No device: the transcript names none, or its own command is the device.
    None,
    /// `host-sim device-sim` behind a pseudo-terminal, as `/dev/pts/0`.
    Pty,
    /// `host-sim device-sim --machine examples/vibro-driver.toml` on a TCP port.
    Machine,
    /// `host-sim device-sim --flip-every 12` on a TCP port: a bit of every 12th
    /// byte flipped either way, so that no status report crosses it whole.
    Noisy,
    /// A TCP listener that accepts and never answers.
    Silent,
    /// A device of this test's making that answers every request by the function.
    Answering(fn(&Request) -> Vec<Response>),
}

/// How a transcript runs (the module's doc): found by a piece of its `$` line.
struct Setup {
    file: &'static str,
    needle: &'static str,
    device: Device,
    /// `host-sim device` commands run against the device first, each to succeed.
    before: &'static [&'static [&'static str]],
    /// Files written into the scratch directory first: (name, text).
    files: &'static [(&'static str, &'static str)],
    /// `device tune`'s prompt (its end) and the answers typed at it.
    typed: Option<(&'static str, &'static [&'static str])>,
    /// Run while the command runs, before its `^C`.
    during: Option<fn(&Live)>,
}

impl Setup {
    const fn on(file: &'static str, needle: &'static str, device: Device) -> Setup {
        Setup {
            file,
            needle,
            device,
            before: &[],
            files: &[],
            typed: None,
            during: None,
        }
    }
}

/// The rotors at 3000 rpm, the link kept alive to the end (on a board the next
/// command must follow within the controller's 0.5 s link timeout, as the docs
/// tell the operator; the tests' device-sims allow 300 s).
const RUNNING: &[&[&str]] = &[
    &["travel", "right", "--speed", "3000"],
    &["telemetry", "--duration", "1.5"],
];

/// The example table in the device's flash, as the transcript above the read
/// wrote it.
const EXAMPLE_TABLE: &[&[&str]] = &[&["table", "write", "examples/vibro-driver.tuning.toml"]];

/// A tuning table whose first row's rightward offset is out of range.
const BAD_TABLE: &str =
    "[[rows]]\nspeed_rpm = 3000.0\nright_offset_deg = 400.0\nleft_offset_deg = 270.0\n";

/// A scenario with every problem docs/scenarios.md's "Bad input" lists.
const BAD_SCENARIO: &str = r#"machine = "examples/vibro-driver.toml"
t_end = 2.0
set = ["contacts.K9.friction=0.2"]

[[commands]]
t = 0.0
command = "rigth"
speed_rpm = 3000

[[commands]]
t = 1.0
command = "stop"
speed_rpm = 3000

[[faults]]
t = 1.0
kind = "encodr"

[[faults]]
t = 1.0
kind = "jammed_rotor"
rotor = 3

[[faults]]
t = 1.0
knd = "estop"

[[expect]]
kind = "fault"
fault = "encoder"
within = [1.0, 5.0]

[[expect]]
kind = "state"
state = "idle"

[[expect]]
kind = "phase"
range_deg = [10, 400]
between = [1.0, 2.0]
"#;

const SETUPS: &[Setup] = &[
    Setup {
        files: &[("bad.toml", BAD_TABLE)],
        ..Setup::on("docs/cli-device.md", "table write bad.toml", Device::Pty)
    },
    Setup::on(
        "docs/cli-device.md",
        "status        # a device that never answers",
        Device::Silent,
    ),
    Setup::on(
        "docs/cli-device.md",
        "status        # a line too noisy for an answer",
        Device::Noisy,
    ),
    Setup {
        before: RUNNING,
        ..Setup::on("docs/cli-device.md", "# rotors turning", Device::Pty)
    },
    Setup::on(
        "docs/cli-device.md",
        "# a device that acknowledges another request",
        Device::Answering(|_| {
            vec![Response::Ack {
                request: MessageId::Heartbeat as u8,
            }]
        }),
    ),
    Setup {
        during: Some(travel_against_the_device_sim),
        ..Setup::on("docs/cli-device.md", "device-sim --machine", Device::None)
    },
    Setup {
        before: RUNNING,
        ..Setup::on("docs/cli-device.md", "/dev/pts/0 status\n", Device::Pty)
    },
    Setup::on(
        "docs/cli-device.md",
        "capture --for 2 --travel right",
        Device::Machine,
    ),
    Setup::on(
        "docs/cli-device.md",
        "capture --for 3 --out",
        Device::Machine,
    ),
    Setup {
        before: &[&["travel", "right", "--speed", "3000"]],
        ..Setup::on("docs/cli-device.md", "--period 250 --count 7", Device::Pty)
    },
    Setup::on(
        "docs/cli-device.md",
        "# a device that does not stream",
        Device::Answering(|request| vec![ack(request)]),
    ),
    Setup {
        before: RUNNING,
        ..Setup::on("docs/cli-device.md", "--count 3 --csv -", Device::Pty)
    },
    Setup {
        before: &[
            &["travel", "right", "--speed", "3000"],
            &["telemetry", "--duration", "1.5"],
            &["stop"],
        ],
        ..Setup::on("docs/cli-device.md", "--count 2 --csv t.csv", Device::Pty)
    },
    Setup {
        during: Some(stop_from_the_page),
        ..Setup::on("docs/cli-device.md", "telemetry --serve\n", Device::Pty)
    },
    Setup {
        before: EXAMPLE_TABLE,
        ..Setup::on("docs/cli-device.md", "table read --out", Device::Pty)
    },
    Setup {
        before: EXAMPLE_TABLE,
        ..Setup::on("docs/cli-device.md", "table read\n", Device::Pty)
    },
    Setup {
        typed: Some(("q stops and ends: ", &["12", "12", "12"])),
        ..Setup::on("docs/cli-device.md", "tune --speeds", Device::Machine)
    },
    Setup {
        files: &[("s.toml", BAD_SCENARIO)],
        ..Setup::on("docs/scenarios.md", "scenario s.toml", Device::None)
    },
];

/// A `$ host-sim ...` line and the output shown under it.
struct Transcript {
    file: String,
    /// The `$` line's, from 1.
    line: usize,
    /// The `$` line without the `$ `, its comment included.
    dollar: String,
    output: Vec<String>,
}

impl Transcript {
    fn place(&self) -> String {
        format!("{}:{}", self.file, self.line)
    }

    /// A piece of its `$` line (ended by a line break) is in it.
    fn has(&self, needle: &str) -> bool {
        format!("$ {}\n", self.dollar).contains(needle)
    }

    /// The command, its comment removed.
    fn command(&self) -> &str {
        self.dollar
            .split_once(" #")
            .map_or(self.dollar.as_str(), |(c, _)| c)
            .trim_end()
    }
}

/// The transcripts of every block that is not a shell block, in file order.
fn transcripts() -> Vec<Transcript> {
    let mut out: Vec<Transcript> = Vec::new();
    for block in docs::blocks().iter().filter(|b| !b.is_shell()) {
        let mut open = false;
        for (i, line) in block.text.lines().enumerate() {
            if let Some(dollar) = line.trim_start().strip_prefix("$ ") {
                out.push(Transcript {
                    file: block.file.clone(),
                    line: block.line + 1 + i,
                    dollar: dollar.to_string(),
                    output: Vec::new(),
                });
                open = true;
            } else if open {
                out.last_mut().unwrap().output.push(line.to_string());
            }
        }
    }
    out
}

/// What a running transcript's action sees.
struct Live {
    /// The scratch directory it runs in.
    work: PathBuf,
    /// The file its stdout and stderr go to.
    out: PathBuf,
}

impl Live {
    fn output(&self) -> String {
        std::fs::read_to_string(&self.out).unwrap_or_default()
    }

    /// Waits for a line holding `needle`; that line.
    fn line_with(&self, needle: &str) -> String {
        let start = Instant::now();
        loop {
            if let Some(line) = self.output().lines().find(|l| l.contains(needle)) {
                return line.to_string();
            }
            assert!(
                start.elapsed() < HANG,
                "no line with {needle:?} after {HANG:?}:\n{}",
                self.output()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// The bound against a hang: a transcript, or a wait within one.
const HANG: Duration = Duration::from_secs(120);

/// The travel the docs' `device-sim --machine` transcript stands for: a short
/// one at 3000 rpm against it.
fn travel_against_the_device_sim(live: &Live) {
    let port = live
        .line_with("port: ")
        .trim_start_matches("port: ")
        .to_string();
    device(
        &live.work,
        &port,
        &["travel", "right", "--speed", "3000", "--for", "1"],
    );
}

/// Stop pressed on the live page: `POST /stop` to the address it prints, and its
/// answer printed.
fn stop_from_the_page(live: &Live) {
    let line = live.line_with("live page on http://");
    let addr = line
        .split("http://")
        .nth(1)
        .and_then(|a| a.split('/').next())
        .unwrap_or_else(|| panic!("no address in {line:?}"));
    let mut s = TcpStream::connect(addr).expect("the live page listens");
    write!(
        s,
        "POST /stop HTTP/1.1\r\nHost: {addr}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut answer = String::new();
    s.read_to_string(&mut answer).unwrap();
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    live.line_with("(from the page)");
}

/// `host-sim device --port PORT args...` in `work`, which must succeed.
fn device(work: &Path, port: &str, args: &[&str]) {
    let mut cmd = common::host_sim();
    cmd.args(["device", "--port", port])
        .args(args)
        .current_dir(work)
        .stdin(Stdio::null());
    let r = common::finish_within(cmd, HANG);
    assert_eq!(r.status, 0, "{args:?}: {}{}", r.stdout, r.stderr);
}

/// A device started for a transcript, ended when dropped.
enum Started {
    None,
    Sim(DeviceSim),
    Port(String),
}

impl Started {
    fn start(device: Device) -> Started {
        match device {
            Device::None => Started::None,
            Device::Pty => Started::Sim(DeviceSim::start_pty(&[])),
            Device::Machine => Started::Sim(DeviceSim::start(&[
                "--machine",
                common::root()
                    .join("examples/vibro-driver.toml")
                    .to_str()
                    .unwrap(),
            ])),
            Device::Noisy => Started::Sim(DeviceSim::start(&["--flip-every", "12"])),
            Device::Silent => Started::Port(fake_device::silent()),
            Device::Answering(answer) => Started::Port(fake_device::answering(answer)),
        }
    }

    fn port(&self) -> Option<&str> {
        match self {
            Started::None => None,
            Started::Sim(sim) => Some(&sim.port),
            Started::Port(port) => Some(port),
        }
    }
}

/// The transcript's commands (split at `&&`) as this test runs them: the port
/// mapped (the module's doc), `host-sim` the binary under test.
fn commands(t: &Transcript, port: Option<&str>) -> Vec<Vec<String>> {
    t.command()
        .split("&&")
        .map(|c| {
            let mut words: Vec<String> = c.split_whitespace().map(String::from).collect();
            assert_eq!(
                words.first().map(String::as_str),
                Some("host-sim"),
                "{}: `{}`: a command this test does not know how to run",
                t.place(),
                c.trim()
            );
            let sim = words.get(1).is_some_and(|w| w == "device-sim");
            for w in &mut words {
                if w == "/dev/pts/0" || w == "tcp:127.0.0.1:5555" {
                    *w = match port {
                        _ if sim => "tcp:127.0.0.1:0".to_string(),
                        Some(port) => port.to_string(),
                        None => panic!("{}: `{w}`: say in SETUPS what stands behind it", t.place()),
                    };
                }
            }
            if words.last().is_some_and(|w| w == "--serve") {
                words.push("127.0.0.1:0".into());
            }
            words.remove(0);
            words
        })
        .collect()
}

/// What a transcript's run gave: its exit status and its output (stdout and
/// stderr as written).
struct Ran {
    status: i32,
    output: String,
}

/// The `^C` of a transcript: SIGINT once `lines` lines are out and `during` has
/// run.
struct CtrlC {
    lines: usize,
    during: Option<fn(&Live)>,
}

/// The process id of the command running, if any; killed when dropped (a
/// failed wait never leaves it running).
#[derive(Clone, Default)]
struct Running(Arc<Mutex<Option<u32>>>);

impl Running {
    fn set(&self, pid: Option<u32>) {
        *self.0.lock().unwrap() = pid;
    }

    /// Sends `signal` to the command running; whether one was.
    fn signal(&self, signal: nix::sys::signal::Signal) -> bool {
        let pid = *self.0.lock().unwrap();
        if let Some(pid) = pid {
            let pid = nix::unistd::Pid::from_raw(i32::try_from(pid).unwrap());
            let _ = nix::sys::signal::kill(pid, signal);
        }
        pid.is_some()
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.signal(nix::sys::signal::Signal::SIGKILL);
    }
}

/// Waits until `ready`, at most [`HANG`] from `start`.
fn wait_until(start: Instant, what: &str, live: &Live, mut ready: impl FnMut() -> bool) {
    while !ready() {
        assert!(
            start.elapsed() < HANG,
            "{what}: not after {HANG:?} (a command that runs until Ctrl-C needs `^C` in the output shown):\n{}",
            live.output()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs `commands` one after the other while each succeeds, in `work`, stdin
/// `answers` (else nothing), stdout and stderr into one file; with `ctrl_c`,
/// SIGINT to the command running once its lines are out. A run still going
/// after [`HANG`] is killed and fails.
fn run(
    work: &Path,
    commands: Vec<Vec<String>>,
    answers: Option<String>,
    ctrl_c: Option<CtrlC>,
) -> Ran {
    let out = work.join("transcript.out");
    let file = File::create(&out).expect("the output file");
    let running = Running::default();
    let chain = {
        let running = running.clone();
        let work = work.to_path_buf();
        std::thread::spawn(move || {
            let mut status = 0;
            for args in commands {
                let mut cmd = common::host_sim();
                cmd.args(&args)
                    .current_dir(&work)
                    .stdout(Stdio::from(file.try_clone().unwrap()))
                    .stderr(Stdio::from(file.try_clone().unwrap()))
                    .stdin(if answers.is_some() {
                        Stdio::piped()
                    } else {
                        Stdio::null()
                    });
                let mut child: Child = cmd.spawn().expect("host-sim runs");
                running.set(Some(child.id()));
                if let (Some(text), Some(mut stdin)) = (&answers, child.stdin.take()) {
                    let _ = stdin.write_all(text.as_bytes());
                }
                let exit = child.wait().expect("it ends");
                running.set(None);
                status = exit.code().unwrap_or(-1);
                if status != 0 {
                    break;
                }
            }
            status
        })
    };
    let live = Live {
        work: work.to_path_buf(),
        out,
    };
    let start = Instant::now();
    if let Some(CtrlC { lines, during }) = ctrl_c {
        if let Some(during) = during {
            during(&live);
        }
        let what = format!("{lines} lines before ^C");
        wait_until(start, &what, &live, || {
            live.output().lines().count() >= lines
                && running.signal(nix::sys::signal::Signal::SIGINT)
        });
    }
    wait_until(start, "the end", &live, || chain.is_finished());
    let status = chain.join().expect("the commands ran");
    let output = live.output();
    assert!(!output.contains("panicked"), "{output}");
    Ran { status, output }
}

/// The controller's states, as `status` and `telemetry` name them.
const STATES: [&str; 6] = [
    "idle",
    "starting",
    "running",
    "stopping",
    "fault",
    "self_test",
];

/// `token` with every number (its sign, decimals and exponent with it) as `#`.
fn numbers_out(token: &str) -> String {
    let c: Vec<char> = token.chars().collect();
    let digit = |i: usize| c.get(i).is_some_and(char::is_ascii_digit);
    let mut out = String::new();
    let mut i = 0;
    while i < c.len() {
        let signed = (c[i] == '-' || c[i] == '+')
            && digit(i + 1)
            && (i == 0 || !c[i - 1].is_ascii_alphanumeric());
        if !(digit(i) || signed) {
            out.push(c[i]);
            i += 1;
            continue;
        }
        i += 1;
        while digit(i) {
            i += 1;
        }
        if c.get(i) == Some(&'.') && digit(i + 1) {
            i += 1;
            while digit(i) {
                i += 1;
            }
        }
        if c.get(i).is_some_and(|&e| e == 'e' || e == 'E') {
            let j = i + 1 + usize::from(c.get(i + 1).is_some_and(|&s| s == '-' || s == '+'));
            if digit(j) {
                i = j;
                while digit(i) {
                    i += 1;
                }
            }
        }
        out.push('#');
    }
    out
}

/// A device line as compared (the module's doc): numbers as `#`, blanks as one,
/// a telemetry frame's state and `-` as values.
fn shape(line: &str) -> String {
    let tokens: Vec<String> = line.split_whitespace().map(numbers_out).collect();
    let readable_frame =
        tokens.len() > 3 && tokens[0] == "#" && tokens[1] == "s" && tokens[3] == "speed";
    if readable_frame {
        let value = |t: &String| STATES.contains(&t.as_str()) || t == "-";
        return tokens
            .iter()
            .map(|t| if value(t) { "#" } else { t })
            .collect::<Vec<_>>()
            .join(" ");
    }
    let fields: Vec<&str> = line.split(',').collect();
    let csv_row = fields.len() > 2 && fields[0].parse::<u64>().is_ok();
    if csv_row {
        return fields
            .iter()
            .map(|f| {
                if STATES.contains(f) {
                    "#".to_string()
                } else {
                    numbers_out(f)
                }
            })
            .collect::<Vec<_>>()
            .join(",");
    }
    tokens.join(" ")
}

/// Matches `shown` (with its `...` lines) against `got`, lines compared by
/// `same`; the first line that does not match, if any.
fn matches(
    shown: &[String],
    got: &[String],
    same: &dyn Fn(&str, &str) -> bool,
) -> Result<(), String> {
    let pieces: Vec<&[String]> = shown.split(|l| l.trim() == "...").collect();
    let at = |piece: &[String], from: usize| {
        from + piece.len() <= got.len() && piece.iter().zip(&got[from..]).all(|(s, g)| same(s, g))
    };
    let last = pieces.len() - 1;
    let mut from = 0;
    for (k, piece) in pieces.iter().enumerate() {
        if k == last && k > 0 {
            // Anchored at the end, after what matched so far.
            let start = got.len().checked_sub(piece.len()).filter(|&s| s >= from);
            return match start {
                Some(s) if at(piece, s) => Ok(()),
                _ => Err(format!(
                    "the lines after the last `...` ({:?}) are not the output's last",
                    piece
                )),
            };
        }
        if k == 0 {
            if !at(piece, 0) {
                let i = piece
                    .iter()
                    .zip(got)
                    .position(|(s, g)| !same(s, g))
                    .unwrap_or(piece.len().min(got.len()));
                return Err(format!(
                    "line {} shown {:?}, printed {:?}",
                    i + 1,
                    piece.get(i),
                    got.get(i)
                ));
            }
            from = piece.len();
        } else {
            match (from..=got.len()).find(|&s| at(piece, s)) {
                Some(s) => from = s + piece.len(),
                None => return Err(format!("{:?} is not in the output in order", piece)),
            }
        }
    }
    // No `...` at all: the lines are all the output.
    if pieces.len() == 1 && from != got.len() {
        return Err(format!("the output has {} more lines", got.len() - from));
    }
    Ok(())
}

/// A fresh scratch directory with copies of `examples/`, `tests/fixtures/` and
/// `tests/scenarios/`.
fn workspace() -> PathBuf {
    let dir = common::scratch("documented-transcripts", "work");
    let _ = std::fs::remove_dir_all(&dir);
    let root = common::root();
    for sub in ["examples", "tests/fixtures", "tests/scenarios"] {
        common::copy_dir(&root.join(sub), &dir.join(sub));
    }
    dir
}

/// Finds the one transcript `needle` names in `file`.
fn found_once(all: &[Transcript], file: &str, needle: &str, table: &str) {
    let n = all
        .iter()
        .filter(|t| t.file == file && t.has(needle))
        .count();
    assert_eq!(n, 1, "{table} ({file}, {needle:?}) finds {n} transcripts");
}

#[test]
fn every_transcript_the_docs_show_is_what_the_tool_prints() {
    let all = transcripts();
    for (file, needle, _) in NOT_RUN {
        found_once(&all, file, needle, "NOT_RUN");
    }
    for s in SETUPS {
        found_once(&all, s.file, s.needle, "SETUPS");
    }
    let work = workspace();
    let mut report = Vec::new();
    let mut failures = Vec::new();
    for t in &all {
        if let Some((_, _, why)) = NOT_RUN.iter().find(|(f, n, _)| t.file == *f && t.has(n)) {
            report.push(format!("{}: not run: {why}", t.place()));
            continue;
        }
        let setup = SETUPS.iter().find(|s| t.file == s.file && t.has(s.needle));
        let kind = setup.map_or(
            if t.command().contains("/dev/pts/0") && !t.command().contains("device-sim") {
                Device::Pty
            } else {
                Device::None
            },
            |s| s.device,
        );
        for (name, text) in setup.map_or(&[][..], |s| s.files) {
            std::fs::write(work.join(name), text).expect("a file");
        }
        let started = Started::start(kind);
        let port = started.port();
        for args in setup.map_or(&[][..], |s| s.before) {
            device(&work, port.expect("a device"), args);
        }
        // The output shown: `^C` taken out, where it is noted.
        let mut shown = Vec::new();
        let mut ctrl_c = None;
        for line in &t.output {
            match line.strip_prefix("^C") {
                Some(rest) => {
                    let before = shown.iter().filter(|l: &&String| l.trim() != "...").count();
                    ctrl_c = Some(CtrlC {
                        lines: before,
                        during: setup.and_then(|s| s.during),
                    });
                    if !rest.is_empty() {
                        shown.push(rest.to_string());
                    }
                }
                None => shown.push(line.clone()),
            }
        }
        assert!(
            ctrl_c.is_some() || setup.and_then(|s| s.during).is_none(),
            "{}: SETUPS gives an action to run before a ^C the output does not show",
            t.place()
        );
        let commands = commands(t, port);
        let typed = setup.and_then(|s| s.typed);
        let answers = typed.map(|(_, a)| a.iter().map(|a| format!("{a}\n")).collect());
        let start = Instant::now();
        let ran = run(&work, commands.clone(), answers, ctrl_c);
        drop(started);
        let mut output = ran.output.clone();
        if let Some((prompt, answers)) = typed {
            // The answers where a terminal shows them, after their prompts.
            let mut pieces = output.split(prompt);
            let mut echoed = pieces.next().unwrap_or_default().to_string();
            for (i, piece) in pieces.enumerate() {
                echoed += &format!("{prompt}{}\n{piece}", answers.get(i).unwrap_or(&""));
            }
            output = echoed;
        }
        let got: Vec<String> = output.lines().map(|l| l.trim_end().to_string()).collect();
        let shown: Vec<String> = shown.iter().map(|l| l.trim_end().to_string()).collect();
        // A replay's numbers come from a capture the docs take of a device
        // in real time.
        let device_like = commands.iter().any(|c| {
            c.first()
                .is_some_and(|w| w == "device" || w == "device-sim" || w == "replay")
        });
        let exact = !device_like || ran.status == 2;
        let verdict = if exact {
            matches(&shown, &got, &|s, g| s == g)
        } else {
            matches(&shown, &got, &|s, g| shape(s) == shape(g))
        };
        let error_shown = shown.iter().any(|l| l.starts_with("error:"));
        let status_ok = if error_shown {
            ran.status != 0
        } else {
            ran.status == 0
        };
        let how = if exact { "equal" } else { "numbers as #" };
        if verdict.is_err() || !status_ok {
            failures.push(format!(
                "{}: `$ {}` (compared: {how}): {}{}\n--- shown\n{}\n--- printed now (run as {:?})\n{}",
                t.place(),
                t.command(),
                verdict.err().unwrap_or_default(),
                if status_ok {
                    String::new()
                } else {
                    format!(" exit {} where the output shown {}", ran.status, if error_shown { "has an error" } else { "has no error" })
                },
                shown.join("\n"),
                commands,
                got.join("\n"),
            ));
        }
        report.push(format!(
            "{}: ran in {:.1} s, compared {how}, exit {}",
            t.place(),
            start.elapsed().as_secs_f64(),
            ran.status
        ));
    }
    eprintln!("{}", report.join("\n"));
    assert!(
        failures.is_empty(),
        "{} transcripts are not what the tool prints; regenerate them from the tool:\n\n{}",
        failures.len(),
        failures.join("\n\n")
    );
}
