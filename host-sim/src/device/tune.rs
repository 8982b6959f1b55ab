//! `host-sim device tune`: the tuning sweep on the machine itself. For every grid
//! point not yet in the measured file
//! ([`super::measured`]), in grid order (speed by speed, offsets ascending):
//!
//! 1. `HoldOffset(speed, offset)`; the status polled every 50 ms (each poll is a
//!    heartbeat, so the link stays alive) until the controller holds the offset
//!    ([`offset_held`]: running, phase loop closed, the ramped reference at the
//!    target) and the target is the point's offset; `--timeout` bounds the wait;
//! 2. `--settle` seconds more, so the gait settles;
//! 3. the mark line (`mark: ...`) on stdout: the operator marks the platform's
//!    position; the point is held `--for` seconds; then the end line (`end:
//!    ...`): the operator marks the position again, so the distance measured
//!    is that of the held gait alone, without the ramp down;
//! 4. `Stop`, and the status polled until `idle` with both rotors at rest
//!    (below `WRITE_MAX_SPEED_RPM`, 10 rpm);
//! 5. the prompt: the distance between the two marks, mm. At a terminal, lines
//!    typed while the point ran are ignored (and said so): a stray Enter must
//!    not start the machine again beside the operator. A number is
//!    appended to the file at once as `velocity = distance / S` (m/s); an empty
//!    line runs the point again; `s` skips it; `q` (or the end of stdin) ends the
//!    sweep with what was measured; anything else is explained and asked again.
//!
//! While a point runs, every status is watched: a latched fault (the E-stop is
//! one), a state other than the expected, a refused command, the link lost
//! (no answer), and Ctrl-C stop the machine (a best-effort `Stop`, then the
//! status asked until it is at rest, within `--timeout`: [`crate::link::rest`]) and end
//! the sweep with exit 1, saying what the status said; the rows already appended
//! stay.
//!
//! The machine is behind [`Rig`] and the operator behind [`Operator`], so the
//! unit tests drive the sweep with a fake of each.

use std::io::{BufRead, IsTerminal};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, TryRecvError};
use std::time::{Duration, Instant};

use shared::controller::{Command, State};
use shared::protocol::{Request, StatusReport};

use super::args::DeviceTuneArgs;
use super::measured::{self, MeasuredFile};
use super::report::faults_text;
use super::tune_table;
use crate::failure::{Console, Failure};
use crate::interrupt;
use crate::link::client::Client;
use crate::link::requests::{command, HEARTBEAT_EVERY};
use crate::link::rest::{at_rest, await_rest, motion, Poll};
use crate::measured::velocity_refusal;
use crate::numbers;
use crate::numbers::count;
use crate::output::file::Staged;
use crate::sweep::table_problems;
use crate::sweep::{offset_held, wrap_offsets, Grid};
use shared::controller::angle::wrap_deg_signed_f64;

/// The prompt after each point.
pub const PROMPT: &str = "distance between the two marks, mm (+ right, - left); Enter repeats the point, s skips it, q stops and ends: ";

/// How close the device's target offset must be to the point's, degrees: the
/// offset crosses the link as an `f32` (7 significant digits: 4e-5 deg at 360).
const TARGET_MATCH_DEG: f64 = 0.01;

/// How long a status may still show the state before a command, s: the
/// controller takes a command at its next tick (1 ms), but the status answered
/// may be that of the tick before, and a retried request takes 100 ms more.
const TAKE_S: f64 = 0.3;

/// The machine as the sweep uses it: commanded, and its status asked
/// ([`Poll`]; asking keeps the link alive).
pub trait Rig: Poll {
    /// Hold `offset_deg` at `speed_rpm` (accepted, or the failure).
    fn hold(&mut self, speed_rpm: f64, offset_deg: f64) -> Result<(), Failure>;
    /// Ramp down to rest (accepted, or the failure).
    fn stop(&mut self) -> Result<(), Failure>;
}

impl Rig for Client {
    fn hold(&mut self, speed_rpm: f64, offset_deg: f64) -> Result<(), Failure> {
        command(
            self,
            &Request::Command(Command::HoldOffset {
                speed_rpm: speed_rpm as f32,
                offset_deg: offset_deg as f32,
            }),
        )
    }

    fn stop(&mut self) -> Result<(), Failure> {
        command(self, &Request::Command(Command::Stop))
    }
}

/// What the operator answered.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reply {
    /// A line, without its line break.
    Line(String),
    /// The end of the input: as `q`.
    End,
    /// Ctrl-C while waiting for the line.
    Interrupted,
}

/// The operator: told what to do, asked for answers.
pub trait Operator {
    /// Show `text` (lines, or a prompt without a line break) at once.
    fn tell(&mut self, text: &str);
    /// The next answer (waits for it).
    fn reply(&mut self) -> Reply;
    /// Whether the operator pressed Ctrl-C.
    fn interrupted(&mut self) -> bool;
    /// Forgets the lines typed before the prompt (while the point ran) and
    /// returns them: at a terminal an answer counts only once the prompt asks
    /// for it. A script's lines piped ahead are kept (none returned).
    fn forget_typed_ahead(&mut self) -> Vec<String>;
}

/// The operator at the terminal: lines on stdout (through the console),
/// answers from stdin, read on a thread so that Ctrl-C ends the wait.
/// Lines piped ahead are answers in order (a script may pipe them all at once);
/// at a terminal (`interactive`), lines typed while a point runs are forgotten.
pub struct Terminal<'c, 'w> {
    console: &'c mut Console<'w>,
    lines: Receiver<Option<String>>,
    interactive: bool,
    /// The input ended while lines were being forgotten.
    ended: bool,
}

impl<'c, 'w> Terminal<'c, 'w> {
    /// Reads `input` on a thread from now on; `interactive`: it is a terminal.
    pub fn new(
        console: &'c mut Console<'w>,
        input: impl BufRead + Send + 'static,
        interactive: bool,
    ) -> Self {
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in input.lines() {
                let Ok(line) = line else { break };
                if tx.send(Some(line)).is_err() {
                    return;
                }
            }
            let _ = tx.send(None);
        });
        Terminal {
            console,
            lines,
            interactive,
            ended: false,
        }
    }
}

impl Operator for Terminal<'_, '_> {
    fn tell(&mut self, text: &str) {
        self.console.print(text);
    }

    fn reply(&mut self) -> Reply {
        if self.ended {
            return Reply::End;
        }
        loop {
            if interrupt::interrupted() {
                return Reply::Interrupted;
            }
            match self.lines.recv_timeout(Duration::from_millis(100)) {
                Ok(Some(line)) => return Reply::Line(line.trim_end_matches('\r').to_string()),
                Ok(None) | Err(RecvTimeoutError::Disconnected) => return Reply::End,
                Err(RecvTimeoutError::Timeout) => {}
            }
        }
    }

    fn interrupted(&mut self) -> bool {
        interrupt::interrupted()
    }

    fn forget_typed_ahead(&mut self) -> Vec<String> {
        let mut typed = Vec::new();
        while self.interactive && !self.ended {
            match self.lines.try_recv() {
                Ok(Some(line)) => typed.push(line.trim_end_matches('\r').to_string()),
                Ok(None) | Err(TryRecvError::Disconnected) => self.ended = true,
                Err(TryRecvError::Empty) => break,
            }
        }
        typed
    }
}

/// The timing of every point, seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// Measured hold (`--for`).
    pub for_s: f64,
    /// Settling once the offset is held (`--settle`).
    pub settle_s: f64,
    /// Longest wait for the offset held, and for idle after the stop (`--timeout`).
    pub timeout_s: f64,
}

/// How a sweep ended without failure.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Tally {
    /// Points measured (rows appended).
    pub measured: usize,
    /// Points skipped (`s`).
    pub skipped: usize,
    /// Runs repeated (Enter).
    pub repeated: usize,
    /// Points not reached because the operator ended (`q`, end of input).
    pub left: usize,
}

/// An answer at the prompt.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Answer {
    Distance(f64),
    Repeat,
    Skip,
    Quit,
}

/// `line` as an answer: a finite number of mm, empty, `s` or `q` (either case,
/// blanks around ignored); `None` for anything else.
fn answer(line: &str) -> Option<Answer> {
    match line.trim() {
        "" => Some(Answer::Repeat),
        "s" | "S" => Some(Answer::Skip),
        "q" | "Q" => Some(Answer::Quit),
        t => t
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .map(Answer::Distance),
    }
}

/// A point for messages: `3000 rpm, 90 deg`.
fn at(speed_rpm: f64, offset_deg: f64) -> String {
    format!(
        "{} rpm, {} deg",
        numbers::sig(speed_rpm),
        numbers::sig(offset_deg)
    )
}

/// Runs the sweep of `points` on `rig`, asking `op`, appending to `file`. A
/// failure has stopped the machine (best effort) and says so.
pub fn sweep(
    rig: &mut dyn Rig,
    op: &mut dyn Operator,
    file: &mut MeasuredFile,
    points: &[(f64, f64)],
    timing: Timing,
) -> Result<Tally, Failure> {
    let mut tally = Tally::default();
    let mut k = 0;
    while k < points.len() {
        let (speed, offset) = points[k];
        let here = at(speed, offset);
        op.tell(&format!(
            "point {}/{}: {here}: holding\n",
            k + 1,
            points.len()
        ));
        if let Err(f) = run_point(rig, op, speed, offset, timing) {
            // The machine stopped whatever went wrong; the link may be gone.
            return Err(stopped(f, &here, rig, timing.timeout_s));
        }
        let typed = op.forget_typed_ahead();
        if !typed.is_empty() {
            let quoted: Vec<String> = typed.iter().map(|l| format!("{l:?}")).collect();
            op.tell(&format!(
                "ignored: {} typed while the point ran ({}): answer at the prompt\n",
                count(typed.len(), "line"),
                quoted.join(", ")
            ));
        }
        loop {
            op.tell(PROMPT);
            let line = match op.reply() {
                Reply::Line(line) => line,
                Reply::End => {
                    op.tell("\n");
                    "q".to_string()
                }
                Reply::Interrupted => {
                    return Err(Failure::run(format!(
                        "{} at the prompt of {here}: the machine was at rest before the prompt; that point is not recorded",
                        interrupt::interruption()
                    )))
                }
            };
            match answer(&line) {
                Some(Answer::Distance(mm)) => {
                    // velocity = distance / S, m/s.
                    let v = mm * 1e-3 / timing.for_s;
                    // A row the file's reader would refuse is not appended.
                    if let Some(why) = velocity_refusal(v) {
                        op.tell(&format!(
                            "not a distance: {} mm in {} s is {} m/s, and a measured velocity {why}; give the distance in mm\n",
                            numbers::sig(mm),
                            numbers::sig(timing.for_s),
                            numbers::sig(v)
                        ));
                        continue;
                    }
                    file.append(speed, offset, v)?;
                    tally.measured += 1;
                    op.tell(&format!(
                        "recorded: {here}: {} mm in {} s = {} m/s\n",
                        numbers::sig(mm),
                        numbers::sig(timing.for_s),
                        numbers::signed(v)
                    ));
                    k += 1;
                }
                Some(Answer::Repeat) => {
                    tally.repeated += 1;
                    op.tell(&format!("repeating {here}\n"));
                }
                Some(Answer::Skip) => {
                    tally.skipped += 1;
                    op.tell(&format!("skipped: {here} (not recorded)\n"));
                    k += 1;
                }
                Some(Answer::Quit) => {
                    tally.left = points.len() - k;
                    op.tell(&format!(
                        "ended: {here} not recorded; {} not measured\n",
                        count(tally.left, "point")
                    ));
                    return Ok(tally);
                }
                None => {
                    op.tell(&format!(
                        "not an answer: {line:?}; give the distance in mm (a number: + right, - left), or Enter to repeat the point, s to skip it, q to stop and end\n"
                    ));
                    continue;
                }
            }
            break;
        }
    }
    Ok(tally)
}

/// Stops `rig` after the failure `f` of the point `here` and asks its status
/// until it is at rest (at most `timeout_s`): the failure, naming the point,
/// with what the status says. "The machine is stopped" only when the status
/// says so: a device may acknowledge the stop and run on.
fn stopped(f: Failure, here: &str, rig: &mut dyn Rig, timeout_s: f64) -> Failure {
    let cause = |e: Failure| e.text();
    let link_lost =
        "the device stops the motors itself 0.5 s after its last request (fault link_lost)";
    let stop = match rig.stop().map(|()| await_rest(rig, timeout_s)) {
        Ok(Ok(rest)) if rest.reached => format!("the machine is stopped: {}", rest.describe()),
        Ok(Ok(rest)) => format!(
            "the stop was accepted, but the machine is {}: stop it by hand (E-stop) or with `host-sim device --port PORT stop`, and check with `host-sim device --port PORT status`",
            rest.describe()
        ),
        Ok(Err(e)) => format!(
            "the stop was accepted, but the status after it could not be read ({}): {link_lost}",
            cause(e)
        ),
        Err(e) => format!("the stop failed too ({}): {link_lost}", cause(e)),
    };
    f.map_text(|m| {
        let m = m.strip_prefix(&format!("{here}: ")).unwrap_or(m);
        format!("{here}: {m}; {stop}")
    })
}

/// Steps 1 to 4 of the module doc for one point.
fn run_point(
    rig: &mut dyn Rig,
    op: &mut dyn Operator,
    speed: f64,
    offset: f64,
    timing: Timing,
) -> Result<(), Failure> {
    let here = at(speed, offset);
    rig.hold(speed, offset)?;
    // 1. Until the offset is held.
    watch(rig, op, &here, "reaching the offset", |s, elapsed| {
        let t = &s.telemetry;
        if t.command_rejected {
            return Err(
                "the controller refused the point (command_rejected: the speed is outside its range)"
                    .into(),
            );
        }
        match s.state {
            State::Starting | State::Running | State::Stopping => {}
            State::Idle if elapsed < TAKE_S => {}
            other => return Err(format!("the controller is {}", other.name())),
        }
        let on_target =
            wrap_deg_signed_f64(f64::from(t.target_offset_deg) - offset).abs() < TARGET_MATCH_DEG;
        if offset_held(s.state, t) && on_target {
            return Ok(true);
        }
        if elapsed >= timing.timeout_s {
            return Err(format!(
                "the offset is not held {} s after the hold (--timeout): state {}, phase loop {}, offset reference {:.1} deg heading for {:.1} deg",
                numbers::sig(timing.timeout_s),
                s.state.name(),
                if t.phase_loop_closed { "closed" } else { "open" },
                t.commanded_offset_deg,
                t.target_offset_deg
            ));
        }
        Ok(false)
    })?;
    // 2. and 3. Settle, then the measured hold: running all the while.
    let running = |s: &StatusReport, _: f64| {
        if s.state == State::Running {
            Ok(false)
        } else {
            Err(format!(
                "the controller left running: it is {}",
                s.state.name()
            ))
        }
    };
    hold_for(rig, op, &here, "settling", timing.settle_s, running)?;
    op.tell(&format!(
        "mark: {here}: mark the platform's position now; measuring for {} s\n",
        numbers::sig(timing.for_s)
    ));
    hold_for(rig, op, &here, "measuring", timing.for_s, running)?;
    op.tell(&format!(
        "end: {here}: mark the platform's position again now; stopping\n"
    ));
    // 4. Stop, until at rest: idle, both rotors below the controller's own
    // "at rest" (what a table write requires), so the platform has stopped too.
    rig.stop()?;
    watch(rig, op, &here, "stopping", |s, elapsed| match s.state {
        State::Idle if at_rest(s) => Ok(true),
        State::Running if elapsed < TAKE_S => Ok(false),
        State::Idle | State::Stopping if elapsed < timing.timeout_s => Ok(false),
        State::Idle | State::Stopping => Err(format!(
            "not at rest {} s after the stop (--timeout): {}",
            numbers::sig(timing.timeout_s),
            motion(s)
        )),
        other => Err(format!("the controller is {} after the stop", other.name())),
    })
}

/// [`watch`] for `seconds`, `check` failing on a bad status.
fn hold_for(
    rig: &mut dyn Rig,
    op: &mut dyn Operator,
    here: &str,
    doing: &str,
    seconds: f64,
    check: impl Fn(&StatusReport, f64) -> Result<bool, String>,
) -> Result<(), Failure> {
    watch(rig, op, here, doing, |s, elapsed| {
        check(s, elapsed)?;
        Ok(elapsed >= seconds)
    })
}

/// Polls the status every [`HEARTBEAT_EVERY`] until `done` says so (`Ok(true)`;
/// it gets the status and the seconds since the first poll). A latched fault
/// (the E-stop is one), `done`'s error and Ctrl-C are the device's failure,
/// `doing` and `here` saying when.
fn watch(
    rig: &mut dyn Rig,
    op: &mut dyn Operator,
    here: &str,
    doing: &str,
    mut done: impl FnMut(&StatusReport, f64) -> Result<bool, String>,
) -> Result<(), Failure> {
    let start = Instant::now();
    loop {
        let s = rig.status()?;
        let fail = |why: String| Failure::device(format!("{here}: {doing}: {why}"));
        if !s.faults.is_empty() {
            return Err(fail(format!("fault {} latched", faults_text(s.faults))));
        }
        if op.interrupted() {
            return Err(Failure::run(format!(
                "{here}: {doing}: {}",
                interrupt::interruption()
            )));
        }
        if done(&s, start.elapsed().as_secs_f64()).map_err(fail)? {
            return Ok(());
        }
        rig.wait(HEARTBEAT_EVERY)?;
    }
}

/// What [`prepare`] checked before the port is opened.
pub struct Prepared {
    /// The grid points, in grid order.
    points: Vec<(f64, f64)>,
    /// The file continued (`--resume`), or the path of the one to create
    /// (`--out`) once the port is open.
    file: Result<MeasuredFile, PathBuf>,
    /// `--write`'s output, staged.
    table: Option<(Staged, usize)>,
    timing: Timing,
}

/// Checks the options, reads a `--resume` file (every row), refuses an existing
/// `--out`, stages `--write`: every user mistake before the port is opened.
pub fn prepare(a: &DeviceTuneArgs) -> Result<Prepared, Failure> {
    let usage = Failure::usage;
    let positive = |flag: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(usage(format!(
                "{flag}: must be a number of seconds above 0 (got {v})"
            )))
        }
    };
    positive("--for", a.for_s)?;
    positive("--timeout", a.timeout)?;
    if !(a.settle.is_finite() && a.settle >= 0.0) {
        return Err(usage(format!(
            "--settle: must be a number of seconds, 0 or more (got {})",
            a.settle
        )));
    }
    if let Some(bad) = a.speeds.points.iter().find(|s| **s <= 0.0) {
        return Err(usage(format!(
            "--speeds {}: {} rpm: speeds must be above 0 (the direction comes from the offset)",
            a.speeds.text,
            numbers::sig(*bad)
        )));
    }
    let grid = Grid {
        speeds_rpm: a.speeds.points.clone(),
        offsets_deg: wrap_offsets(&a.offsets.points),
        t_end: a.for_s,
    };
    let mut table = None;
    if let Some(path) = &a.write {
        if grid.offsets_deg.len() < tune_table::MIN_OFFSETS {
            return Err(usage(format!(
                "--write: --offsets {} gives {}; the peak fit needs at least {} per speed",
                a.offsets.text,
                count(grid.offsets_deg.len(), "offset"),
                tune_table::MIN_OFFSETS
            )));
        }
        if let Some(p) = table_problems(&grid.speeds_rpm, &a.speeds.text).first() {
            return Err(Failure::usage(p.clone()));
        }
        let mut set = Staged::new();
        let i = set.add("--write", path)?;
        table = Some((set, i));
    }
    let file =
        match (&a.resume, &a.out) {
            (Some(path), _) => Ok(MeasuredFile::resume(path)?),
            (None, Some(path)) => {
                if path.exists() {
                    return Err(measured::exists(path));
                }
                Err(path.clone())
            }
            (None, None) => return Err(usage(
                "device tune: name the measured file: --out FILE.csv (new) or --resume FILE.csv"
                    .into(),
            )),
        };
    Ok(Prepared {
        points: grid.points(),
        file,
        table,
        timing: Timing {
            for_s: a.for_s,
            settle_s: a.settle,
            timeout_s: a.timeout,
        },
    })
}

/// Runs `host-sim device tune` on `rig` with the terminal operator.
pub fn run(
    rig: &mut dyn Rig,
    a: &DeviceTuneArgs,
    prepared: Prepared,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    let Prepared {
        points,
        file,
        table,
        timing,
    } = prepared;
    let mut file = match file {
        Ok(f) => f,
        Err(path) => MeasuredFile::create(&path)?,
    };
    let todo: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|&(s, o)| !file.has(s, o))
        .collect();
    out.print(&format!(
        "device tune: {} to measure ({} of the grid already in {}); each held {} s after {} s of settling; answers on stdin\n",
        count(todo.len(), "point"),
        points.len() - todo.len(),
        file.path().display(),
        numbers::sig(timing.for_s),
        numbers::sig(timing.settle_s)
    ));
    interrupt::catch();
    let result = {
        let interactive = std::io::stdin().is_terminal();
        let mut op = Terminal::new(out, std::io::BufReader::new(std::io::stdin()), interactive);
        sweep(rig, &mut op, &mut file, &todo, timing)
    };
    let kept = format!(
        "{} in {} (continue with --resume {})",
        count(file.rows.len(), "row"),
        file.path().display(),
        file.path().display()
    );
    let tally = match result {
        Ok(t) => t,
        Err(f) => return Err(f.with_detail(kept)),
    };
    out.print(&format!(
        "device tune: {} measured, {} skipped, {} repeated, {} left; {kept}\n",
        tally.measured, tally.skipped, tally.repeated, tally.left
    ));
    if let Some((set, i)) = table {
        write_table(
            &file,
            set,
            i,
            a.write.as_deref().unwrap_or(Path::new("")),
            out,
        )?;
    }
    Ok(())
}

/// `--write`: the table of every row of `file`, written whole to `path`.
fn write_table(
    file: &MeasuredFile,
    mut set: Staged,
    i: usize,
    path: &Path,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    let refuse = |why: String| {
        Failure::usage(format!(
            "--write {}: {}: {why}; nothing written",
            path.display(),
            file.path().display()
        ))
    };
    let fits = tune_table::fits(&file.rows).map_err(|p| refuse(p.join("; ")))?;
    let text = tune_table::table_file(&fits, file.path(), file.rows.len()).map_err(refuse)?;
    set.write(i, &text)?;
    set.commit()?;
    out.print(&format!(
        "table: {} written to {} (from {} of {})\n",
        count(fits.len(), "row"),
        path.display(),
        count(file.rows.len(), "row"),
        file.path().display()
    ));
    for w in tune_table::warnings(&fits) {
        out.note(&format!("warning: {w}\n"));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
