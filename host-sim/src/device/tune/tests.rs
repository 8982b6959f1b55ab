//! The sweep's logic with a fake machine and a scripted operator: the answers
//! (number, Enter, `s`, `q`, end of input, nonsense), the rows appended, the
//! requests made, and the machine stopped on a fault and on Ctrl-C.

use std::collections::VecDeque;

use shared::controller::{Faults, Telemetry};
use shared::protocol::link::no_telemetry;

use super::*;

/// A machine that takes a hold in one poll (`starting`, then `running` with the
/// offset held), stops in one (`stopping`, then `idle`), and latches `fault`
/// at the `fault_at`-th poll of a point, if given. `stuck`: it never closes the
/// phase loop; `gone_after`: the link dies after that many polls of a point;
/// `runs_on`: it acknowledges a stop and runs on at 3000 rpm.
struct FakeRig {
    state: State,
    target: f32,
    polls: usize,
    fault_at: Option<usize>,
    faults: Faults,
    stuck: bool,
    gone_after: Option<usize>,
    runs_on: bool,
    log: Vec<String>,
}

impl FakeRig {
    fn new(fault_at: Option<usize>) -> Self {
        FakeRig {
            state: State::Idle,
            target: 0.0,
            polls: 0,
            fault_at,
            faults: Faults::NONE,
            stuck: false,
            gone_after: None,
            runs_on: false,
            log: Vec::new(),
        }
    }

    fn gone(&self) -> Result<(), Failure> {
        match self.gone_after {
            Some(n) if self.polls >= n => Err(Failure::device("the port failed: closed")),
            _ => Ok(()),
        }
    }
}

impl Rig for FakeRig {
    fn hold(&mut self, speed_rpm: f64, offset_deg: f64) -> Result<(), Failure> {
        self.log.push(format!("hold {speed_rpm} {offset_deg}"));
        self.state = State::Starting;
        self.target = offset_deg as f32;
        self.polls = 0;
        Ok(())
    }

    fn stop(&mut self) -> Result<(), Failure> {
        self.gone()?;
        self.log.push("stop".into());
        if self.state != State::Fault && !self.runs_on {
            self.state = State::Stopping;
        }
        Ok(())
    }
}

impl Poll for FakeRig {
    fn status(&mut self) -> Result<StatusReport, Failure> {
        self.gone()?;
        self.polls += 1;
        if self.fault_at == Some(self.polls) {
            self.state = State::Fault;
            self.faults = Faults::ESTOP;
        }
        let report = StatusReport {
            uptime_ms: 0,
            state: self.state,
            faults: self.faults,
            telemetry: Telemetry {
                phase_loop_closed: self.state == State::Running,
                speed_rpm: match self.state {
                    State::Starting | State::Running => [3000.0; 2],
                    _ => [0.0; 2],
                },
                commanded_offset_deg: self.target,
                target_offset_deg: self.target,
                ..no_telemetry()
            },
            rx_dropped: 0,
        };
        self.state = match self.state {
            State::Starting if self.stuck => State::Starting,
            State::Starting => State::Running,
            State::Stopping => State::Idle,
            s => s,
        };
        Ok(report)
    }

    fn wait(&mut self, wait: Duration) -> Result<(), Failure> {
        std::thread::sleep(wait.min(Duration::from_millis(1)));
        Ok(())
    }
}

/// An operator reading answers from a script (then the end of input), keeping
/// what it was told; Ctrl-C pressed at the `ctrl_c_at`-th look, if given;
/// `typed`: lines typed while the first point runs.
struct Script {
    answers: VecDeque<Reply>,
    told: String,
    looks: usize,
    ctrl_c_at: Option<usize>,
    typed: Vec<String>,
}

impl Script {
    fn new(answers: &[&str]) -> Self {
        Script {
            answers: answers.iter().map(|a| Reply::Line(a.to_string())).collect(),
            told: String::new(),
            looks: 0,
            ctrl_c_at: None,
            typed: Vec::new(),
        }
    }
}

impl Operator for Script {
    fn tell(&mut self, text: &str) {
        self.told.push_str(text);
    }

    fn reply(&mut self) -> Reply {
        self.answers.pop_front().unwrap_or(Reply::End)
    }

    fn interrupted(&mut self) -> bool {
        self.looks += 1;
        self.ctrl_c_at.is_some_and(|n| self.looks >= n)
    }

    fn forget_typed_ahead(&mut self) -> Vec<String> {
        std::mem::take(&mut self.typed)
    }
}

/// Short enough for a unit test: a measured hold of 20 ms.
const TIMING: Timing = Timing {
    for_s: 0.02,
    settle_s: 0.0,
    timeout_s: 1.0,
};

/// A new measured file in a scratch directory.
fn scratch_file(name: &str) -> (MeasuredFile, PathBuf) {
    let dir = std::env::temp_dir().join(format!("host-sim-device-tune-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    let _ = std::fs::remove_file(&path);
    (MeasuredFile::create(&path).unwrap(), path)
}

const POINTS: [(f64, f64); 3] = [(3000.0, 0.0), (3000.0, 90.0), (3000.0, 180.0)];

#[test]
fn every_answer_does_what_the_prompt_says() {
    let (mut file, path) = scratch_file("answers.csv");
    let mut rig = FakeRig::new(None);
    // 0 deg: nonsense, then 12 mm; 90 deg: Enter (again), then skipped; 180 deg:
    // -6 mm.
    let mut op = Script::new(&["twelve", "12", "", "s", " -6 "]);
    let tally = sweep(&mut rig, &mut op, &mut file, &POINTS, TIMING).unwrap();
    assert_eq!(
        tally,
        Tally {
            measured: 2,
            skipped: 1,
            repeated: 1,
            left: 0
        }
    );
    // Each run: hold, then stop; 90 deg twice.
    assert_eq!(
        rig.log,
        [
            "hold 3000 0",
            "stop",
            "hold 3000 90",
            "stop",
            "hold 3000 90",
            "stop",
            "hold 3000 180",
            "stop"
        ]
    );
    // velocity = distance / S: 12 mm / 0.02 s = 0.6 m/s.
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        "speed_rpm,offset_deg,velocity_mps\n3000,0,0.6\n3000,180,-0.3\n"
    );
    let told = &op.told;
    assert_eq!(told.matches("mark: ").count(), 4, "{told}");
    assert_eq!(told.matches("end: ").count(), 4, "{told}");
    assert!(
        told.contains("end: 3000 rpm, 0 deg: mark the platform's position again now; stopping\n"),
        "{told}"
    );
    assert!(
        told.contains(
            "mark: 3000 rpm, 0 deg: mark the platform's position now; measuring for 0.02 s\n"
        ),
        "{told}"
    );
    assert_eq!(told.matches(PROMPT).count(), 5, "{told}");
    assert!(
        told.contains("not an answer: \"twelve\"; give the distance in mm"),
        "{told}"
    );
    assert!(told.contains("repeating 3000 rpm, 90 deg\n"), "{told}");
    assert!(
        told.contains("skipped: 3000 rpm, 90 deg (not recorded)\n"),
        "{told}"
    );
}

#[test]
fn q_and_the_end_of_input_end_the_sweep_with_what_was_measured() {
    for last in [Some("q"), None] {
        let (mut file, path) = scratch_file("q.csv");
        let mut rig = FakeRig::new(None);
        let answers: Vec<&str> = std::iter::once("5").chain(last).collect();
        let mut op = Script::new(&answers);
        let tally = sweep(&mut rig, &mut op, &mut file, &POINTS, TIMING).unwrap();
        assert_eq!((tally.measured, tally.left), (1, 2), "{last:?}");
        // The second point ran (and stopped) before its answer ended the sweep.
        assert_eq!(rig.log, ["hold 3000 0", "stop", "hold 3000 90", "stop"]);
        assert!(op
            .told
            .ends_with("ended: 3000 rpm, 90 deg not recorded; 2 points not measured\n"));
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "speed_rpm,offset_deg,velocity_mps\n3000,0,0.25\n"
        );
    }
}

#[test]
fn a_fault_while_measuring_stops_the_machine_and_keeps_the_rows() {
    let (mut file, path) = scratch_file("fault.csv");
    // The first point: poll 1 starting, 2 held, then measuring; the second
    // point latches the E-stop at its 4th poll (measuring).
    let mut rig = FakeRig::new(Some(4));
    let mut op = Script::new(&["7"]);
    // Long enough a hold that the 4th poll comes while measuring.
    let timing = Timing {
        for_s: 0.5,
        ..TIMING
    };
    let mut first = FakeRig::new(None);
    sweep(&mut first, &mut op, &mut file, &POINTS[..1], timing).unwrap();
    let e = sweep(&mut rig, &mut op, &mut file, &POINTS[1..], timing).unwrap_err();
    assert_eq!(e.status(), 1);
    assert_eq!(
        e.message(),
        "error: 3000 rpm, 90 deg: measuring: fault estop latched; the machine is stopped: at rest after 0.0 s (state fault, rotors at 0.0 and 0.0 rpm)\n"
    );
    assert_eq!(rig.log, ["hold 3000 90", "stop"]);
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        "speed_rpm,offset_deg,velocity_mps\n3000,0,0.014\n"
    );
}

#[test]
fn ctrl_c_stops_the_machine() {
    let (mut file, _) = scratch_file("ctrl-c.csv");
    let mut rig = FakeRig::new(None);
    let mut op = Script::new(&[]);
    op.ctrl_c_at = Some(3);
    let e = sweep(&mut rig, &mut op, &mut file, &POINTS, TIMING).unwrap_err();
    assert_eq!(e.status(), 1);
    assert!(
        e.message().contains("interrupted; the machine is stopped"),
        "{e:?}"
    );
    assert_eq!(rig.log, ["hold 3000 0", "stop"]);
    // At the prompt: nothing more to stop, the point not recorded.
    let mut op = Script::new(&[]);
    op.answers.push_back(Reply::Interrupted);
    let e = sweep(&mut rig, &mut op, &mut file, &POINTS, TIMING).unwrap_err();
    assert!(
        e.message()
            .contains("interrupted at the prompt of 3000 rpm, 0 deg"),
        "{e:?}"
    );
    assert!(file.rows.is_empty());
}

/// A device that acknowledges the stop after a failure and runs on: the sweep
/// asks its status until the timeout and says what it says, never "the
/// machine is stopped" (issue 23: printed while the device ran at 3000 rpm).
#[test]
fn a_stop_acknowledged_by_a_running_machine_is_not_a_stopped_machine() {
    let (mut file, _) = scratch_file("runs-on.csv");
    let mut rig = FakeRig::new(None);
    rig.stuck = true;
    rig.runs_on = true;
    let mut op = Script::new(&[]);
    let timing = Timing {
        timeout_s: 0.05,
        ..TIMING
    };
    let e = sweep(&mut rig, &mut op, &mut file, &POINTS, timing).unwrap_err();
    let m = e.message();
    assert!(!m.contains("the machine is stopped"), "{m}");
    assert!(
        m.contains("; the stop was accepted, but the machine is not at rest "),
        "{m}"
    );
    assert!(
        m.contains(" s after the stop: state starting, rotors at 3000.0 and 3000.0 rpm: stop it by hand (E-stop)"),
        "{m}"
    );
    assert_eq!(rig.log, ["hold 3000 0", "stop"]);
}

#[test]
fn an_offset_never_held_is_a_timeout_naming_the_point() {
    let (mut file, _) = scratch_file("stuck.csv");
    let mut rig = FakeRig::new(None);
    rig.stuck = true;
    let mut op = Script::new(&[]);
    let timing = Timing {
        timeout_s: 0.05,
        ..TIMING
    };
    let e = sweep(&mut rig, &mut op, &mut file, &POINTS, timing).unwrap_err();
    assert!(
        e.message().starts_with("error: 3000 rpm, 0 deg: reaching the offset: the offset is not held 0.05 s after the hold (--timeout): state starting, phase loop open"),
        "{e:?}"
    );
    assert_eq!(rig.log, ["hold 3000 0", "stop"]);
}

/// A distance whose velocity the measured file's reader would refuse is asked
/// again, not appended (the file would not read back).
#[test]
fn a_distance_beyond_the_files_bound_is_asked_again() {
    let (mut file, path) = scratch_file("huge.csv");
    let mut rig = FakeRig::new(None);
    // 1e308 mm, then 250 mm (in 0.02 s: 12.5 m/s, beyond 10 m/s), then 3 mm.
    let mut op = Script::new(&["1e308", "250", "3", "q"]);
    let tally = sweep(&mut rig, &mut op, &mut file, &POINTS, TIMING).unwrap();
    assert_eq!(tally.measured, 1);
    assert!(
        op.told.contains("not a distance: 1e308 mm in 0.02 s is 5e306 m/s, and a measured velocity must be within [-10, 10] m/s; give the distance in mm\n"),
        "{}",
        op.told
    );
    assert!(
        op.told
            .contains("not a distance: 250 mm in 0.02 s is 12.5 m/s"),
        "{}",
        op.told
    );
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text, "speed_rpm,offset_deg,velocity_mps\n3000,0,0.15\n");
    assert!(crate::measured::parse("huge.csv", &text, None).is_ok());
}

#[test]
fn answers_are_numbers_enter_s_or_q() {
    assert_eq!(answer(" 12.5 "), Some(Answer::Distance(12.5)));
    assert_eq!(answer("-3"), Some(Answer::Distance(-3.0)));
    assert_eq!(answer(""), Some(Answer::Repeat));
    assert_eq!(answer("S"), Some(Answer::Skip));
    assert_eq!(answer("q"), Some(Answer::Quit));
    for bad in ["NaN", "inf", "12mm", "quit", "x"] {
        assert_eq!(answer(bad), None, "{bad}");
    }
}

#[test]
fn a_lost_link_names_the_point_and_the_failed_stop() {
    let (mut file, _) = scratch_file("gone.csv");
    // Three polls of the first point answered, then nothing more.
    let mut rig = FakeRig::new(None);
    rig.gone_after = Some(3);
    let mut op = Script::new(&[]);
    let timing = Timing {
        for_s: 1.0,
        ..TIMING
    };
    let e = sweep(&mut rig, &mut op, &mut file, &POINTS, timing).unwrap_err();
    assert_eq!(e.status(), 1);
    assert_eq!(
        e.message(),
        "error: 3000 rpm, 0 deg: the port failed: closed; the stop failed too (the port failed: closed): \
         the device stops the motors itself 0.5 s after its last request (fault link_lost)\n"
    );
}

/// Lines typed while a point runs are not answers: the sweep says it ignored
/// them and asks; a stray Enter does not start the machine again.
#[test]
fn lines_typed_while_a_point_runs_are_ignored() {
    let (mut file, path) = scratch_file("typed.csv");
    let mut rig = FakeRig::new(None);
    let mut op = Script::new(&["4", "q"]);
    op.typed = vec!["".into(), "12".into()];
    let tally = sweep(&mut rig, &mut op, &mut file, &POINTS, TIMING).unwrap();
    assert_eq!((tally.measured, tally.repeated), (1, 0));
    assert!(
        op.told.contains(
            "ignored: 2 lines typed while the point ran (\"\", \"12\"): answer at the prompt\n"
        ),
        "{}",
        op.told
    );
    // 4 mm / 0.02 s = 0.2 m/s, not the 12 typed ahead.
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        "speed_rpm,offset_deg,velocity_mps\n3000,0,0.2\n"
    );
}

/// The terminal forgets the lines waiting when it is a terminal, keeping the
/// end of the input; piped lines are answers in order.
#[test]
fn a_terminal_forgets_lines_typed_ahead_and_a_pipe_keeps_them() {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let mut console = Console::new(&mut out, &mut err);
    let input = || std::io::Cursor::new(b"\n5\r\n".to_vec());
    let mut t = Terminal::new(&mut console, input(), true);
    let mut typed = Vec::new();
    let start = Instant::now();
    while !t.ended && start.elapsed() < Duration::from_secs(5) {
        typed.extend(t.forget_typed_ahead());
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(typed, ["", "5"]);
    assert_eq!(t.reply(), Reply::End);
    let mut t = Terminal::new(&mut console, input(), false);
    std::thread::sleep(Duration::from_millis(50));
    assert!(t.forget_typed_ahead().is_empty());
    assert_eq!(t.reply(), Reply::Line("".into()));
    assert_eq!(t.reply(), Reply::Line("5".into()));
    assert_eq!(t.reply(), Reply::End);
}
