//! The first-run self-test (`shared::controller::self_test`) with the controller in
//! the loop of the simulated reference machine (`examples/vibro-driver.toml`: DC
//! motors, unbalance rotors, platform on its feet, quadrature encoders with index),
//! against references that do not come from the controller:
//!
//! - counts per revolution: the machine file's `[sensors].encoder_counts`;
//! - index offset: from the plant's true eccentric angle `phi0` (platform frame)
//!   at the tick the drive starts, the rotor's `sense` and `index_angle`: the
//!   encoder angle is `theta0 = s (phi0 - index_angle)` (docs/machine-file.md), its
//!   count `floor(theta0 N / 2 pi)`, and the index sits at the multiples of `N`, so
//!   the counts from the start to the index in the driven sense are
//!   `(-floor(theta0 N / 2 pi)) mod N`. A second, coarser reference from the
//!   geometry alone: at rest the eccentric hangs down, `phi0 = -90` degrees, within
//!   the friction band `asin(T_c / (m e g)) = asin(1e-3 / 1.962e-3) = 30.6`
//!   degrees; with `index_angle = 0` rotor 1 (ccw) is `s (0 - (-90)) = 90` degrees
//!   (1024 counts) before its index, rotor 2 (cw) `360 - 90 = 270` degrees (3072);
//! - the mechanical sense (what the flags cannot see, "check by eye"): the plant's
//!   `phi` of the driven rotor moves in its `sense`;
//! - faults injected in the loop: encoder channels swapped (the controller sees the
//!   counts negated), motor leads swapped (the winding gets `-duty`), E-stop, a stop
//!   command, a jammed rotor.
//!
//! Measured (this commit, test profile): see the `eprintln!` of each test.

use std::f64::consts::{PI, TAU};

use host_sim::event::EventRow;
use host_sim::machine::Machine;
use host_sim::plant::bridge::BridgeCommand;
use host_sim::plant::simulator::Plant;
use host_sim::simulation::closed_loop::{ControllerDriver, LastTick};
use host_sim::simulation::{simulate, Driver, RunOptions};
use shared::controller::self_test::{SelfTestReport, SelfTestStatus};
use shared::controller::{
    self_test, Bridge, Command, Controller, Direction, Faults, Inputs, Outputs, Params, ResetCause,
    State,
};
use tests::machine::TestMachine;

/// When the tests start the self-test, s: the reference machine starts with both
/// eccentrics horizontal; they swing down and come to rest well before.
const T_START: f64 = 1.5;

/// One control tick as the probe saw it.
#[derive(Clone, Copy, Debug)]
struct Tick {
    t: f64,
    /// The plant's eccentric angles `phi` (platform frame) at the tick, rad.
    phi: [f64; 2],
    out: Outputs,
    report: SelfTestReport,
}

/// What to do to the loop.
#[derive(Clone, Debug, Default)]
struct Setup {
    /// Machine file overrides.
    sets: Vec<String>,
    /// Commands to the controller, (t, command).
    commands: Vec<(f64, Command)>,
    encoder_reversed: [bool; 2],
    motor_reversed: [bool; 2],
    jammed: [bool; 2],
    /// E-stop pressed from this time on.
    estop_at: Option<f64>,
}

/// The controller driver with a probe: records the plant's true angles and the
/// controller's outputs and self-test report every tick, injects the faults.
struct Probe {
    inner: ControllerDriver,
    setup: Setup,
    ticks: Vec<Tick>,
}

impl Driver for Probe {
    fn before_tick(&mut self, t: f64, plant: &mut Plant) {
        for k in 0..2 {
            if self.setup.jammed[k] {
                plant.set_jam(k, true);
            }
        }
        self.inner.injected.estop = self.setup.estop_at.is_some_and(|te| t >= te - 1e-12);
        self.inner.before_tick(t, plant);
    }

    fn bridges(&mut self, t: f64, plant: &Plant) -> ([BridgeCommand; 2], [f64; 2]) {
        let phi = [plant.rotor_angle(0).0, plant.rotor_angle(1).0];
        let w = self.inner.bridges(t, plant);
        self.ticks.push(Tick {
            t,
            phi,
            out: *self.inner.last().expect("stepped"),
            report: self.inner.controller().self_test_report(),
        });
        w
    }

    fn last_tick(&self) -> Option<LastTick<'_>> {
        self.inner.last_tick()
    }

    fn events(&mut self) -> Vec<EventRow> {
        self.inner.events()
    }
}

/// A self-test run: the machine, every tick, and whether it started.
struct Run {
    machine: Machine,
    ticks: Vec<Tick>,
    started: Option<(f64, bool)>,
}

impl Run {
    fn last(&self) -> &Tick {
        self.ticks.last().expect("ticks")
    }

    /// The ticks in which rotor `k` is driven.
    fn driven(&self, k: usize) -> Vec<&Tick> {
        self.ticks
            .iter()
            .filter(|t| t.out.duties()[k] != 0.0)
            .collect()
    }

    /// When the self-test ended (status no longer running), s.
    fn ended_at(&self) -> Option<f64> {
        self.ticks
            .iter()
            .filter(|t| t.t > T_START)
            .find(|t| t.report.status != SelfTestStatus::Running)
            .map(|t| t.t)
    }
}

/// Runs the reference machine to `t_end` with a self-test started at [`T_START`].
fn run(setup: Setup, t_end: f64) -> Run {
    let machine = TestMachine::example().sets(&setup.sets).machine();
    let mut inner =
        ControllerDriver::new(&machine, setup.commands.clone()).expect("the controller starts");
    inner.start_self_test_at(T_START);
    inner.injected.encoder_reversed = setup.encoder_reversed;
    inner.injected.motor_reversed = setup.motor_reversed;
    let mut probe = Probe {
        inner,
        setup,
        ticks: Vec::new(),
    };
    let options = RunOptions::new(t_end);
    simulate(&machine, &mut probe, &options);
    Run {
        started: probe.inner.self_test_started(),
        machine,
        ticks: probe.ticks,
    }
}

/// Counts from the start angle `phi0` to the index in the driven sense, from the
/// machine file's geometry and the encoder's definition (module documentation).
fn expected_offset(m: &Machine, k: usize, phi0: f64) -> u32 {
    let r = &m.rotors[k];
    let n = i64::from(m.sensors.encoder_counts);
    let theta0 = r.sense.sign() * (phi0 - r.index_angle);
    let count0 = (theta0 * n as f64 / TAU).floor() as i64;
    (-count0).rem_euclid(n) as u32
}

/// The healthy reference run, shared by two tests.
fn reference() -> &'static Run {
    static RUN: std::sync::OnceLock<Run> = std::sync::OnceLock::new();
    RUN.get_or_init(|| run(Setup::default(), 5.0))
}

#[test]
fn the_reference_machine_passes_with_its_own_geometry() {
    let r = reference();
    let m = &r.machine;
    assert_eq!(
        r.started,
        Some((T_START, true)),
        "the self-test starts at rest"
    );
    let end = r.ended_at().expect("the self-test ends");
    let last = r.last();
    assert_eq!(last.report.status, SelfTestStatus::Done);
    assert_eq!(last.out.state, State::Idle);
    assert_eq!(last.out.faults, Faults::NONE);
    assert!(last.report.result.passed(), "{:?}", last.report.result);
    eprintln!("self-test: {:.3} s to {end:.3} s", T_START);
    assert!(end - T_START < 3.0, "took {} s", end - T_START);

    let p = Params::reference();
    let duty = self_test::SelfTestConfig::from_params(&p).duty;
    for (k, &d) in duty.iter().enumerate() {
        let res = last.report.result.rotors[k];
        // Counts per revolution: the machine file's, exactly.
        assert_eq!(res.counts_per_rev, m.sensors.encoder_counts, "rotor {k}");

        // The drive: one rotor at a time, at the test duty, the other at 0.
        let driven = r.driven(k);
        let first = driven.first().expect("driven");
        let lastd = driven.last().expect("driven");
        assert!(driven.iter().all(|t| t.out.duties()[1 - k] == 0.0));
        assert!(driven.iter().all(|t| t.out.duties()[k] == d));
        assert!(driven
            .iter()
            .all(|t| t.out.state == State::SelfTest && t.out.drives()));

        // Index offset: from the plant's true angle where the drive started.
        let phi0 = first.phi[k];
        let want = expected_offset(m, k, phi0);
        assert_eq!(res.index_offset_counts, want, "rotor {k}, phi0 {phi0} rad");
        // ... and from the geometry alone: hanging down within the friction band.
        let hanging = if k == 0 { 1024.0 } else { 3072.0 };
        let band = 4096.0 * (1.0e-3f64 / 1.962e-3).asin() / TAU;
        let off = f64::from(res.index_offset_counts);
        assert!(
            (off - hanging).abs() <= band + 1.0,
            "rotor {k}: {off} vs {hanging}"
        );

        // The mechanical sense, which no flag sees: the rotor turned its own way,
        // a little more than a turn and at most two.
        let turned = m.rotors[k].sense.sign() * (lastd.phi[k] - phi0);
        assert!(
            turned > 1.0 * TAU && turned < 2.0 * TAU + 0.5,
            "rotor {k}: {turned} rad"
        );
        let speed_rpm = turned / (lastd.t - first.t) * 30.0 / PI;
        eprintln!(
            "rotor {}: drive {:.3} to {:.3} s ({} ticks, mean {speed_rpm:.0} rpm), phi0 {:.1} deg, \
             offset {} counts (expected {want}), counts/rev {}",
            k + 1,
            first.t,
            lastd.t,
            driven.len(),
            phi0.to_degrees(),
            res.index_offset_counts,
            res.counts_per_rev
        );
    }
    // Rotor 1 first, then rotor 2.
    assert!(r.driven(0).last().unwrap().t < r.driven(1).first().unwrap().t);
}

#[test]
fn the_report_is_running_during_the_test_and_never_earlier() {
    let r = reference();
    for t in &r.ticks {
        let want = if t.t < T_START - 1e-9 {
            SelfTestStatus::NotRun
        } else if t.out.state == State::SelfTest {
            SelfTestStatus::Running
        } else {
            SelfTestStatus::Done
        };
        assert_eq!(t.report.status, want, "t = {}", t.t);
    }
}

#[test]
fn hanging_start_gives_a_quarter_and_three_quarters_of_a_turn() {
    // Both eccentrics hanging straight down from t = 0 (phi = -90 degrees, their
    // equilibrium): rotor 1 (ccw) is 90 degrees before its index at +x, rotor 2
    // (cw) 270 degrees: 1024 and 3072 counts, up to the count the floor of an
    // angle exactly on an edge may land on.
    let sets = (0..2)
        .map(|k| format!("rotors.{k}.angle={}", -PI / 2.0))
        .collect();
    let r = run(
        Setup {
            sets,
            ..Setup::default()
        },
        5.0,
    );
    let res = r.last().report.result;
    assert_eq!(r.last().report.status, SelfTestStatus::Done);
    assert!(res.passed(), "{res:?}");
    eprintln!(
        "hanging start: offsets {} and {}",
        res.rotors[0].index_offset_counts, res.rotors[1].index_offset_counts
    );
    assert!(res.rotors[0].index_offset_counts.abs_diff(1024) <= 1);
    assert!(res.rotors[1].index_offset_counts.abs_diff(3072) <= 1);
}

#[test]
fn a_swapped_encoder_fails_its_flag_and_stops_at_once() {
    let r = run(
        Setup {
            encoder_reversed: [true, false],
            ..Setup::default()
        },
        5.0,
    );
    let last = r.last();
    assert_eq!(last.report.status, SelfTestStatus::Done);
    assert_eq!(last.out.faults, Faults::NONE);
    let bad = last.report.result.rotors[0];
    assert!(!bad.encoder_polarity_ok, "{bad:?}");
    assert!(
        bad.motor_polarity_ok,
        "the current followed the duty: {bad:?}"
    );
    assert!(!bad.passed());
    assert!(last.report.result.rotors[1].passed());
    // Stopped as soon as the counts had run 64 the wrong way: a few degrees.
    let driven = r.driven(0);
    let turned = r.machine.rotors[0].sense.sign()
        * (driven.last().unwrap().phi[0] - driven.first().unwrap().phi[0]);
    eprintln!(
        "swapped encoder: driven {} ticks, turned {:.1} deg",
        driven.len(),
        turned.to_degrees()
    );
    assert!(driven.len() <= 40, "{} ticks", driven.len());
    assert!(turned > 0.0 && turned.to_degrees() < 10.0, "{turned}");
}

#[test]
fn a_swapped_motor_fails_its_flag_and_stops_at_once() {
    let r = run(
        Setup {
            motor_reversed: [false, true],
            ..Setup::default()
        },
        5.0,
    );
    let last = r.last();
    assert_eq!(last.report.status, SelfTestStatus::Done);
    assert_eq!(last.out.faults, Faults::NONE);
    let bad = last.report.result.rotors[1];
    assert!(!bad.motor_polarity_ok, "{bad:?}");
    assert!(
        bad.encoder_polarity_ok,
        "the counts followed the current: {bad:?}"
    );
    assert_eq!(bad.counts_per_rev, 0);
    assert!(last.report.result.rotors[0].passed());
    // The rotor turned backwards a few degrees and no more.
    let driven = r.driven(1);
    let turned = r.machine.rotors[1].sense.sign()
        * (driven.last().unwrap().phi[1] - driven.first().unwrap().phi[1]);
    eprintln!(
        "swapped motor: driven {} ticks, turned {:.1} deg",
        driven.len(),
        turned.to_degrees()
    );
    assert!(driven.len() <= 40, "{} ticks", driven.len());
    assert!(turned < 0.0 && turned.to_degrees() > -10.0, "{turned}");
}

#[test]
fn estop_during_the_test_aborts_with_the_motors_off_in_that_tick() {
    // Rotor 1 is driven from about 1.7 s.
    let t_e = 1.8;
    let r = run(
        Setup {
            estop_at: Some(t_e),
            ..Setup::default()
        },
        2.5,
    );
    let before = r
        .ticks
        .iter()
        .rev()
        .find(|t| t.t < t_e - 1e-9)
        .expect("a tick before");
    assert_eq!(before.out.state, State::SelfTest);
    assert!(
        before.out.duties()[0] > 0.0,
        "rotor 1 driven before the E-stop"
    );
    let at = r.ticks.iter().find(|t| t.t >= t_e - 1e-9).expect("tick");
    assert_eq!(at.out.bridges, [Bridge::Off; 2], "{:?}", at.out);
    assert_eq!(at.out.state, State::Fault);
    assert!(at.out.faults.contains(Faults::ESTOP));
    assert_eq!(at.report.status, SelfTestStatus::Aborted);
    assert!(r
        .ticks
        .iter()
        .filter(|t| t.t >= t_e - 1e-9)
        .all(|t| !t.out.drives() && t.report.status == SelfTestStatus::Aborted));
}

#[test]
fn a_stop_command_aborts_with_the_motors_off_in_that_tick() {
    let t_s = 1.8;
    let r = run(
        Setup {
            commands: vec![(t_s, Command::Stop)],
            ..Setup::default()
        },
        2.5,
    );
    let at = r.ticks.iter().find(|t| t.t >= t_s - 1e-9).expect("tick");
    assert_eq!(at.out.bridges, [Bridge::Off; 2]);
    assert_eq!(at.out.state, State::Idle);
    assert_eq!(at.out.faults, Faults::NONE);
    assert_eq!(r.last().report.status, SelfTestStatus::Aborted);
    assert!(r.driven(0).iter().all(|t| t.t < t_s));
    assert!(r.driven(1).is_empty());
}

#[test]
fn a_jammed_rotor_fails_and_the_test_ends() {
    let r = run(
        Setup {
            jammed: [true, false],
            ..Setup::default()
        },
        5.0,
    );
    let last = r.last();
    assert_eq!(last.report.status, SelfTestStatus::Done);
    assert_eq!(last.out.faults, Faults::NONE, "no stall at the test's duty");
    assert_eq!(last.out.state, State::Idle);
    let jammed = last.report.result.rotors[0];
    assert!(
        !jammed.motor_polarity_ok
            && !jammed.encoder_polarity_ok
            && !jammed.index_seen
            && jammed.counts_per_rev == 0,
        "{jammed:?}"
    );
    assert!(last.report.result.rotors[1].passed());
    let driven = r.driven(0);
    let end = r.ended_at().expect("ends");
    eprintln!(
        "jammed rotor 1: driven {} ticks; test {T_START} to {end:.3} s",
        driven.len()
    );
    // The move timeout, 0.25 s, and not a tick more.
    assert!((245..=252).contains(&driven.len()), "{}", driven.len());
    assert!(end < T_START + 3.0);
}

// The controller alone, with synthetic inputs: when the test may start, what it
// refuses while it runs.

/// Inputs at rest, supply nominal.
fn at_rest(command: Option<Command>) -> Inputs {
    Inputs {
        supply_voltage: 12.0,
        command,
        ..Inputs::default()
    }
}

#[test]
fn it_starts_only_idle_at_rest_and_without_a_fault() {
    let p = Params::reference();
    let mut c = Controller::new(&p, ResetCause::PowerOn);
    assert_eq!(c.self_test_report().status, SelfTestStatus::NotRun);
    c.step(&at_rest(None), 0.001);

    // A fault latched: refused.
    let mut estop = at_rest(None);
    estop.estop = true;
    c.step(&estop, 0.001);
    assert!(!c.start_self_test());
    c.step(&at_rest(Some(Command::ResetFaults)), 0.001);
    assert_eq!(c.state(), State::Idle);

    // Running: refused.
    let mut run = c.clone();
    run.step(
        &at_rest(Some(Command::Travel {
            direction: Direction::Right,
            speed_rpm: 3000.0,
        })),
        0.001,
    );
    assert_eq!(run.state(), State::Starting);
    assert!(!run.start_self_test());

    // Idle with a rotor turning (the counts move 30 a tick: 440 rpm): refused.
    let mut turning = c.clone();
    let mut i = at_rest(None);
    for _ in 0..50 {
        i.encoder[1] = i.encoder[1].wrapping_add(30);
        turning.step(&i, 0.001);
    }
    assert!(!turning.start_self_test());

    // Idle at rest: started; a run command is refused meanwhile, and the test
    // drives rotor 1 after the 0.2 s settle.
    assert!(c.start_self_test());
    assert_eq!(c.state(), State::SelfTest);
    assert_eq!(c.self_test_report().status, SelfTestStatus::Running);
    assert!(!c.start_self_test(), "not twice");
    let out = c.step(
        &at_rest(Some(Command::HoldOffset {
            speed_rpm: 3000.0,
            offset_deg: 90.0,
        })),
        0.001,
    );
    assert!(out.telemetry.command_rejected);
    assert_eq!(out.state, State::SelfTest);
    let mut first_drive = None;
    for tick in 1..400 {
        let out = c.step(&at_rest(None), 0.001);
        if out.duties()[0] > 0.0 {
            first_drive = Some(tick);
            break;
        }
        assert_eq!(
            out.bridges,
            [Bridge::Driven(0.0); 2],
            "the bridges hold the windings shorted"
        );
    }
    // The tick with the refused command was the settle's first: the drive starts
    // in its 200th, 0.2 s on.
    assert_eq!(first_drive, Some(199), "after the 0.2 s settle");
}

#[test]
fn the_state_travels_on_the_wire_as_code_5() {
    use shared::protocol::{Message, Response, StatusReport, MAX_PAYLOAD};
    let p = Params::reference();
    let mut c = Controller::new(&p, ResetCause::PowerOn);
    c.step(&at_rest(None), 0.001);
    assert!(c.start_self_test());
    let out = c.step(&at_rest(None), 0.001);
    let status = Response::Status(StatusReport {
        uptime_ms: 7,
        state: out.state,
        faults: out.faults,
        telemetry: out.telemetry,
        rx_dropped: 0,
    });
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = status.write_payload(&mut payload).expect("fits");
    // Payload byte 4: the state (docs/protocol.md).
    assert_eq!(payload[4], 5);
    let frame = shared::protocol::Frame {
        id: status.id() as u8,
        seq: 1,
        payload: &payload[..n],
    };
    assert_eq!(Response::parse(&frame), Ok(status));
    assert_eq!(State::SelfTest.name(), "self_test");
}

// The device end to end, as the firmware's control task glues it
// (firmware/src/bin/board.rs): the link's RunSelfTest sets
// `self_test_requested`; the control tick takes it and calls `start_self_test`
// before its step, then publishes the status and copies the controller's report
// into the link state (unless it is `NotRun`, which would hide the stored result),
// flagging a finished test `self_test_unsaved`; the link then stores it in flash.
// The rotors are synthetic: 16 counts a tick while driven (234 rpm), the index at
// the multiples of 4096, 0.3 A.

/// The link's state, flash and task.
struct Device {
    link: shared::protocol::link::Link,
    state: shared::protocol::link::LinkState,
    flash: shared::storage::SimFlash,
}

impl Device {
    /// Sends `request` (if any) and runs the link task; the responses.
    fn poll(&mut self, request: Option<&shared::protocol::Request>, now_ms: u32) -> Vec<Vec<u8>> {
        let mut rx: std::collections::VecDeque<u8> = std::collections::VecDeque::new();
        if let Some(r) = request {
            let mut buf = [0u8; shared::protocol::MAX_FRAME];
            let n = shared::protocol::encode(r, 1, &mut buf).expect("encodes");
            rx.extend(buf[..n].iter().copied());
        }
        let mut out = Vec::new();
        let Device { link, state, flash } = self;
        while link.poll(
            || rx.pop_front(),
            now_ms,
            &mut *state,
            flash,
            |frame| out.push(frame.to_vec()),
        ) {}
        out
    }
}

/// The response in an encoded frame.
fn response(bytes: &[u8]) -> shared::protocol::Response {
    use shared::protocol::{Decoder, Message, Response};
    let mut d = Decoder::new();
    let mut input = bytes;
    let frame = d.decode(&mut input).expect("a frame").expect("valid");
    Response::parse(&frame).expect("a response")
}

#[test]
fn a_requested_self_test_runs_and_is_stored_with_the_table() {
    use shared::protocol::link::{no_telemetry, Link, LinkState};
    use shared::protocol::{Request, Response, StatusReport};
    use shared::storage::{self, SimFlash};

    let p = Params::reference();
    let mut c = Controller::new(&p, ResetCause::PowerOn);
    let mut dev = Device {
        link: Link::new(),
        state: LinkState::new(
            StatusReport {
                uptime_ms: 0,
                state: c.state(),
                faults: c.faults(),
                telemetry: no_telemetry(),
                rx_dropped: 0,
            },
            c.params().tuning.clone(),
            None,
        ),
        flash: SimFlash::new(),
    };
    let mut count = [0i64; 2];
    let mut duty = [0.0f32; 2];
    let mut done_at = None;
    for ms in 0..5000u32 {
        // The host asks at 10 ms; the link answers.
        let request = (ms == 10).then_some(&Request::RunSelfTest);
        let sent = dev.poll(request, ms);
        if ms == 10 {
            assert!(matches!(response(&sent[0]), Response::Ack { .. }), "acked");
        }

        // The synthetic rotors move under the last tick's duties.
        let mut index = [None; 2];
        let mut current = [0.0f32; 2];
        for k in 0..2 {
            if duty[k] > 0.0 {
                let before = count[k];
                count[k] += 16;
                current[k] = 0.3;
                if count[k].div_euclid(4096) > before.div_euclid(4096) {
                    index[k] = Some((count[k].div_euclid(4096) * 4096) as u32);
                }
            }
        }

        // The control tick, with the firmware's glue (shared::protocol::link).
        let taken = dev.state.take_for_tick(&mut c);
        assert!(!taken.self_test_refused);
        let command = taken.command;
        let inputs = Inputs {
            encoder: count.map(|n| n as u32),
            index,
            current,
            supply_voltage: 12.0,
            estop: false,
            command,
            timing: Default::default(),
        };
        let out = c.step(&inputs, 0.001);
        duty = out.duties();
        let was_running = dev.state.self_test.status == SelfTestStatus::Running;
        dev.state.publish(ms, &inputs, &out, &c);
        if was_running && dev.state.self_test.status == SelfTestStatus::Done {
            assert!(dev.state.self_test_unsaved);
            done_at = Some(ms);
        }
        if done_at.is_some() && !dev.state.self_test_unsaved {
            break;
        }
    }
    let done_at = done_at.expect("the self-test finished");
    let stored = storage::load(&dev.flash).expect("a record");
    let result = stored.record.self_test.expect("the self-test stored");
    assert!(result.passed(), "{result:?}");
    assert_eq!(result.rotors[0].counts_per_rev, 4096);
    // Both rotors start at count 0, exactly on an index: offset 0.
    assert_eq!(result.rotors[0].index_offset_counts, 0);
    assert_eq!(stored.record.tuning, p.tuning);
    let sent = dev.poll(Some(&Request::ReadSelfTest), done_at + 1);
    match response(&sent[0]) {
        Response::SelfTest(r) => {
            assert_eq!(r.status, SelfTestStatus::Done);
            assert_eq!(r.result, result);
        }
        other => panic!("{other:?}"),
    }

    // A later request the controller refuses (a fault latched, the E-stop
    // open): reported aborted, and it stays so, though the controller's own
    // last report is still the finished test's.
    let estop = Inputs {
        encoder: count.map(|n| n as u32),
        supply_voltage: 12.0,
        estop: true,
        ..Inputs::default()
    };
    let out = c.step(&estop, 0.001);
    assert_eq!(out.state, State::Fault);
    dev.state.publish(done_at + 2, &estop, &out, &c);
    dev.state.self_test_requested = true;
    assert!(dev.state.take_for_tick(&mut c).self_test_refused);
    assert_eq!(dev.state.self_test.status, SelfTestStatus::Aborted);
    for ms in done_at + 3..done_at + 10 {
        let out = c.step(&estop, 0.001);
        dev.state.publish(ms, &estop, &out, &c);
        assert_eq!(
            dev.state.self_test.status,
            SelfTestStatus::Aborted,
            "at {ms} ms"
        );
    }
}

#[test]
fn noisy_sensors_still_pass() {
    // A shunt amplifier's 20 mA of noise and 2 us of encoder edge jitter.
    let r = run(
        Setup {
            sets: vec![
                "sensors.current_noise=0.02".into(),
                "sensors.encoder_jitter=2e-6".into(),
            ],
            ..Setup::default()
        },
        5.0,
    );
    let last = r.last();
    assert_eq!(last.report.status, SelfTestStatus::Done);
    assert!(last.report.result.passed(), "{:?}", last.report.result);
    for k in 0..2 {
        let res = last.report.result.rotors[k];
        assert_eq!(res.counts_per_rev, r.machine.sensors.encoder_counts);
        let phi0 = r.driven(k).first().expect("driven").phi[k];
        let want = expected_offset(&r.machine, k, phi0);
        // Jitter moves an edge by at most a count at these speeds.
        assert!(
            res.index_offset_counts.abs_diff(want) <= 1,
            "rotor {k}: {res:?} vs {want}"
        );
    }
}

/// The bridge as wired decides whether the self-test can work. Its duty (0.049 on
/// the reference machine: twice the load torque at rest with the mean voltage
/// `d V_s`) means that voltage only in slow decay; a bridge driven in fast decay
/// (drive, then coast) draws 2.9 mA
/// instead of 0.29 A at standstill (`plant_bridge.rs`), so neither rotor turns and
/// both fail: the current does not follow the duty, no counts, no index. With
/// slow decay (the reference run) both pass.
#[test]
fn the_self_test_fails_on_a_fast_decay_bridge() {
    let r = run(
        Setup {
            sets: vec!["drive.decay=fast".into()],
            ..Setup::default()
        },
        5.0,
    );
    let last = r.last();
    assert_eq!(last.report.status, SelfTestStatus::Done);
    for (k, rotor) in last.report.result.rotors.iter().enumerate() {
        assert!(
            !rotor.motor_polarity_ok && !rotor.index_seen && rotor.counts_per_rev == 0,
            "rotor {k}: {rotor:?}"
        );
        // Driven for the move timeout and not a turn further.
        assert!((245..=252).contains(&r.driven(k).len()), "rotor {k}");
    }
    assert!(reference().last().report.result.passed());
}
