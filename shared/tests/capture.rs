//! The capture (`shared::capture`) as the firmware runs it: the control tick's
//! port records into the link state's buffer, the link answers the host's
//! requests. Checked: a record's bytes keep every input and output to the bit
//! (duties to 1/32767), over many generated records; each trigger fires on the
//! tick it names, that tick first, with the controller's state before it; the
//! window ends the capture, a full command list ends it early; a window longer
//! than the buffer is refused; a capture read over the link in frames is the
//! one recorded.

use shared::capture::{
    Capture, CaptureStatus, CommandKind, MachineFingerprint, Record, Slot, Trigger, MAX_COMMANDS,
    RECORDS_PER_FRAME,
};
use shared::controller::{
    Bridge, Command, Controller, Direction, Faults, Inputs, Outputs, Params, ResetCause, State,
    TickTiming,
};
use shared::protocol::link::LinkState;
use shared::protocol::{NackReason, Request, Response};
use shared::tick::{self, Board, LinkPort};

mod support;

use support::device::{responses, Device};
use support::frames::frame_bytes;
use support::rig::{Rotor, DT, N, SUBSTEPS};
use support::rng::Rng;

/// A buffer of `n` slots that lives as long as the test.
fn buffer(n: usize) -> &'static mut [Slot] {
    Box::leak(vec![[0u8; shared::capture::RECORD_LEN]; n].into_boxed_slice())
}

const MACHINE: MachineFingerprint = MachineFingerprint {
    crc32: 0xDEAD_BEEF,
    len: 1234,
};

/// Two rig rotors behind an encoder and a current sensor, driven by the last
/// outputs: the board of a control tick.
struct RigBoard {
    rotors: [Rotor; 2],
    bridges: [Bridge; 2],
    estop: bool,
    late_s: f32,
}

impl RigBoard {
    fn new() -> Self {
        RigBoard {
            rotors: [Rotor::new(0.3), Rotor::new(-0.2)],
            bridges: [Bridge::Off; 2],
            estop: false,
            late_s: 0.0,
        }
    }

    fn count(theta: f64) -> i64 {
        (theta / std::f64::consts::TAU * f64::from(N)).floor() as i64
    }
}

impl Board for RigBoard {
    fn sample(&mut self) -> Inputs {
        let mut index = [None; 2];
        let mut encoder = [0u32; 2];
        let mut current = [0.0f32; 2];
        for k in 0..2 {
            let before = RigBoard::count(self.rotors[k].theta);
            let h = f64::from(DT) / SUBSTEPS as f64;
            for _ in 0..SUBSTEPS {
                self.rotors[k].advance(
                    f64::from(self.bridges[k].duty()),
                    self.bridges[k].is_driven(),
                    h,
                );
            }
            let now = RigBoard::count(self.rotors[k].theta);
            let n = i64::from(N);
            if now.div_euclid(n) != before.div_euclid(n) {
                index[k] = Some((now.div_euclid(n).max(before.div_euclid(n)) * n) as u32);
            }
            encoder[k] = now as u32;
            current[k] = self.rotors[k].current as f32;
        }
        Inputs {
            encoder,
            index,
            current,
            supply_voltage: 12.0,
            estop: self.estop,
            command: None,
            timing: TickTiming {
                late_s: self.late_s,
                busy_s: 0.000_21,
            },
        }
    }

    fn apply(&mut self, out: &Outputs) {
        self.bridges = out.bridges;
    }
}

/// A controller, its board and the link state with a capture of `capacity`
/// ticks, as the firmware starts them.
struct Bench {
    controller: Controller,
    board: RigBoard,
    state: LinkState,
    uptime_ms: u32,
    /// Every tick's inputs (command included) and outputs.
    ticks: Vec<(Inputs, Outputs)>,
}

/// A board that remembers what it sampled.
struct Remember<'a> {
    board: &'a mut RigBoard,
    sampled: Option<Inputs>,
}

impl Board for Remember<'_> {
    fn sample(&mut self) -> Inputs {
        let inputs = self.board.sample();
        self.sampled = Some(inputs);
        inputs
    }
    fn apply(&mut self, out: &Outputs) {
        self.board.apply(out);
    }
}

impl Bench {
    fn new(capacity: usize) -> Bench {
        let controller = Controller::new(&Params::reference(), ResetCause::PowerOn);
        let state = LinkState::at_start(&controller, None).with_capture(Capture::new(
            buffer(capacity),
            MACHINE,
            1e-3,
        ));
        Bench {
            controller,
            board: RigBoard::new(),
            state,
            uptime_ms: 0,
            ticks: Vec::new(),
        }
    }

    /// One control tick with `command` waiting.
    fn tick(&mut self, command: Option<Command>) -> Outputs {
        if command.is_some() {
            self.state.command = command;
        }
        self.uptime_ms += 1;
        let mut board = Remember {
            board: &mut self.board,
            sampled: None,
        };
        let mut port = LinkPort::new(&mut self.state, self.uptime_ms);
        let out = tick::run(&mut self.controller, &mut board, &mut port, 1e-3);
        let mut inputs = board.sampled.expect("sampled");
        inputs.command = port.taken.command;
        self.ticks.push((inputs, out));
        out
    }

    /// `n` ticks of heartbeats.
    fn run(&mut self, n: usize) {
        for _ in 0..n {
            self.tick(Some(Command::Heartbeat));
        }
    }

    /// The records recorded, read from the buffer.
    fn records(&self) -> Vec<Record> {
        let info = self.state.capture.info();
        let mut out = Vec::new();
        let mut slots = [[0u8; shared::capture::RECORD_LEN]; RECORDS_PER_FRAME];
        while out.len() < usize::from(info.recorded) {
            let n = self.state.capture.read(out.len() as u16, &mut slots);
            assert!(n > 0);
            out.extend(
                slots[..n]
                    .iter()
                    .map(|s| Record::from_bytes(s).expect("valid")),
            );
        }
        out
    }
}

/// A record of every kind of value, drawn from `rng`.
fn random_record(rng: &mut Rng) -> Record {
    let f = |rng: &mut Rng| f32::from_bits(rng.next_u64() as u32);
    let count = rng.next_u64() as u32;
    let off = |rng: &mut Rng| rng.below(32_000) as i32 - 16_000;
    Record {
        encoder: [count, rng.next_u64() as u32],
        index: [
            rng.one_in(2).then(|| count.wrapping_add(off(rng) as u32)),
            None,
        ],
        current: [f(rng), f(rng)],
        supply_voltage: f(rng),
        estop: rng.one_in(2),
        command: [None]
            .into_iter()
            .chain(CommandKind::ALL.map(Some))
            .nth(rng.below(6))
            .flatten(),
        self_test_started: rng.one_in(2),
        identify_started: rng.one_in(2),
        tuning_changed: rng.one_in(2),
        timing_us: [rng.next_u64() as u16, rng.next_u64() as u16],
        duty_raw: [
            (!rng.one_in(4)).then(|| (rng.below(65_535) as i32 - 32_767) as i16),
            (!rng.one_in(4)).then(|| (rng.below(65_535) as i32 - 32_767) as i16),
        ],
        state: State::ALL[rng.below(State::ALL.len())],
        faults: Faults::from_bits(rng.next_u64() as u16 & 0x3FF),
    }
}

/// A record's bytes read back to the same record, every field, bit for bit
/// (NaN currents included), over many drawn records.
#[test]
fn a_record_reads_back_to_the_bit() {
    let mut rng = Rng::new(27);
    for _ in 0..20_000 {
        let r = random_record(&mut rng);
        let back = Record::from_bytes(&r.to_bytes()).expect("valid");
        assert_eq!(back.to_bytes(), r.to_bytes());
        assert_eq!(back.current.map(f32::to_bits), r.current.map(f32::to_bits));
        assert_eq!(back.supply_voltage.to_bits(), r.supply_voltage.to_bits());
        assert_eq!(
            (
                back.encoder,
                back.index,
                back.duty_raw,
                back.state,
                back.faults
            ),
            (r.encoder, r.index, r.duty_raw, r.state, r.faults)
        );
        assert_eq!(
            (back.command, back.estop, back.timing_us),
            (r.command, r.estop, r.timing_us)
        );
    }
    // A byte outside its domain is refused, not misread.
    let mut bytes = random_record(&mut rng).to_bytes();
    bytes[30] = 9; // no state has code 9
    assert!(Record::from_bytes(&bytes).is_none());
    bytes[30] = 0;
    bytes[31] = 0x70; // command code 7
    assert!(Record::from_bytes(&bytes).is_none());
}

/// A duty is kept to 1/32767, and a bridge off stays off (not a duty of 0).
#[test]
fn duties_are_kept_to_one_part_in_32767() {
    let mut rng = Rng::new(5);
    for _ in 0..10_000 {
        let d = (rng.next_u64() as f64 / u64::MAX as f64 * 2.0 - 1.0) as f32;
        let raw = shared::capture::duty_raw(Bridge::Driven(d)).unwrap();
        assert!(
            (f32::from(raw) / 32767.0 - d).abs() <= 0.5 / 32767.0 + 1e-7,
            "{d}"
        );
    }
    assert_eq!(shared::capture::duty_raw(Bridge::Off), None);
    assert_eq!(shared::capture::duty_raw(Bridge::Driven(0.0)), Some(0));
}

/// Armed on `command`, heartbeats do not fire it; the travel does, and its
/// tick is record 0, with the controller idle and at rest before it; every
/// tick after is recorded with exactly the inputs the controller stepped on
/// and the outputs it wrote, until the window is full.
#[test]
fn the_command_trigger_records_from_the_run_command_on() {
    let mut b = Bench::new(600);
    b.run(50);
    b.state.capture.arm(Trigger::Command, 500).unwrap();
    b.run(20);
    assert_eq!(b.state.capture.info().status, CaptureStatus::Armed);
    let first = b.ticks.len();
    let travel = Command::Travel {
        direction: Direction::Right,
        speed_rpm: 3000.0,
    };
    b.tick(Some(travel));
    b.run(600);
    let info = b.state.capture.info();
    assert_eq!(info.status, CaptureStatus::Done);
    assert_eq!((info.window, info.recorded), (500, 500));
    assert_eq!(info.start.state, State::Idle);
    assert_eq!(info.start.uptime_ms, first as u32);
    assert_eq!(info.machine, MACHINE);
    assert_eq!(info.tick_us, 1000);
    assert_eq!(info.commands.len(), 1);
    assert_eq!(
        (info.commands[0].record, info.commands[0].command),
        (0, travel)
    );
    let records = b.records();
    for (k, r) in records.iter().enumerate() {
        let (inputs, out) = &b.ticks[first + k];
        let expected = Record::of(inputs, [false; 3], out);
        assert_eq!(r.to_bytes(), expected.to_bytes(), "tick {k}");
        assert_eq!(r.inputs(inputs.command).encoder, inputs.encoder);
    }
    assert_eq!(records[0].command, Some(CommandKind::Travel));
    assert_eq!(records[1].command, Some(CommandKind::Heartbeat));
    assert_eq!(records[0].state, State::Starting);
    assert!(records.iter().all(|r| r.duty_raw[0].is_some()));
}

/// The index latches the controller knew before the capture are kept: where
/// `theta = 0` is at its start.
#[test]
fn the_start_keeps_the_index_the_controller_knew() {
    let mut b = Bench::new(100);
    b.tick(Some(Command::HoldOffset {
        speed_rpm: 3000.0,
        offset_deg: 90.0,
    }));
    b.run(3000);
    let known = b.controller.index_counts();
    assert!(known.iter().all(Option::is_some), "{known:?}");
    b.state.capture.arm(Trigger::Now, 10).unwrap();
    b.tick(Some(Command::Heartbeat));
    let info = b.state.capture.info();
    assert_eq!(info.start.state, State::Running);
    // The latch before the first record's tick: the one known then, or one a
    // whole number of turns before the one that tick took.
    let first = b.records()[0];
    for k in 0..2 {
        let before = info.start.index[k].expect("known");
        match first.index[k] {
            None => assert_eq!(Some(before), b.controller.index_counts()[k]),
            Some(new) => assert_eq!(new.wrapping_sub(before) % N, 0),
        }
    }
    assert!(info
        .start
        .speed_rpm
        .iter()
        .all(|s| (s - 3000.0).abs() < 100.0));
}

/// `state` fires on the first change of state, `fault` on the E-stop's fault
/// (not on a state change before it), each tick first.
#[test]
fn the_state_and_fault_triggers_fire_on_their_tick() {
    let mut b = Bench::new(100);
    b.state.capture.arm(Trigger::State, 5).unwrap();
    b.run(10);
    assert_eq!(b.state.capture.info().status, CaptureStatus::Armed);
    b.tick(Some(Command::Travel {
        direction: Direction::Left,
        speed_rpm: 3000.0,
    }));
    let info = b.state.capture.info();
    assert_eq!(info.status, CaptureStatus::Recording);
    assert_eq!(info.start.state, State::Idle);
    assert_eq!(b.records()[0].state, State::Starting);

    b.state.capture.arm(Trigger::Fault, 20).unwrap();
    b.run(300);
    assert_eq!(b.state.capture.info().status, CaptureStatus::Armed);
    b.board.estop = true;
    b.run(30);
    let info = b.state.capture.info();
    assert_eq!(info.status, CaptureStatus::Done);
    assert_ne!(info.start.state, State::Fault);
    let records = b.records();
    assert_eq!(records[0].state, State::Fault);
    assert!(records[0].faults.contains(Faults::ESTOP));
    assert!(records[0].estop);
    assert!(
        records[0].duty_raw.iter().all(Option::is_none),
        "cut at once"
    );
}

/// More run commands than the list keeps end the capture before the tick that
/// brings one too many: done, marked early, every record it kept whole.
#[test]
fn a_full_command_list_ends_the_capture_early() {
    let mut b = Bench::new(200);
    b.state.capture.arm(Trigger::Now, 200).unwrap();
    for k in 0..=MAX_COMMANDS {
        b.tick(Some(Command::HoldOffset {
            speed_rpm: 3000.0,
            offset_deg: k as f32,
        }));
        b.run(2);
    }
    let info = b.state.capture.info();
    assert_eq!(info.status, CaptureStatus::Done);
    assert!(info.ended_early);
    assert_eq!(info.commands.len(), MAX_COMMANDS);
    assert_eq!(usize::from(info.recorded), 3 * MAX_COMMANDS);
    assert_eq!(b.records().len(), 3 * MAX_COMMANDS);
}

/// A window longer than the buffer is refused with BadValue, nothing armed; a
/// window of 0 disarms; on the link, the capture read in frames of 11 is the
/// one recorded, and a read past the end gives none.
#[test]
fn the_link_arms_reads_and_refuses() {
    let mut dev = Device::new();
    dev.state = std::mem::replace(
        &mut dev.state,
        LinkState::at_start(
            &Controller::new(&Params::reference(), ResetCause::PowerOn),
            None,
        ),
    )
    .with_capture(Capture::new(buffer(40), MACHINE, 1e-3));
    let too_long = Request::ArmCapture {
        trigger: Trigger::Now,
        window: 41,
    };
    let answers = responses(&dev.exchange(&frame_bytes(&too_long, 1), 0));
    assert!(matches!(
        answers[0].1,
        Response::Nack {
            reason: NackReason::BadValue,
            ..
        }
    ));
    assert_eq!(dev.state.capture.info().status, CaptureStatus::Empty);

    let arm = Request::ArmCapture {
        trigger: Trigger::Now,
        window: 40,
    };
    let answers = responses(&dev.exchange(&frame_bytes(&arm, 2), 0));
    assert!(matches!(answers[0].1, Response::Ack { .. }));
    // The control task's ticks, here by hand with the link state.
    let mut controller = Controller::new(&Params::reference(), ResetCause::PowerOn);
    let mut board = RigBoard::new();
    for ms in 1..=50 {
        let mut port = LinkPort::new(&mut dev.state, ms);
        tick::run(&mut controller, &mut board, &mut port, 1e-3);
    }
    let mut read = Vec::new();
    for first in (0..44).step_by(RECORDS_PER_FRAME) {
        let request = Request::ReadCapture {
            first: first as u16,
        };
        match &responses(&dev.exchange(&frame_bytes(&request, 10 + first as u16), 60))[0].1 {
            Response::CaptureRecords {
                first: f,
                count,
                records,
            } => {
                assert_eq!(usize::from(*f), first);
                assert_eq!(
                    usize::from(*count),
                    (40 - first.min(40)).min(RECORDS_PER_FRAME)
                );
                read.extend(records[..usize::from(*count)].iter().copied());
            }
            other => panic!("{other:?}"),
        }
    }
    assert_eq!(read.len(), 40);
    let mut direct = [[0u8; shared::capture::RECORD_LEN]; RECORDS_PER_FRAME];
    for (k, slot) in read.iter().enumerate() {
        dev.state.capture.read(k as u16, &mut direct);
        assert_eq!(slot, &direct[0]);
    }
    match &responses(&dev.exchange(&frame_bytes(&Request::GetCapture, 99), 60))[0].1 {
        Response::Capture(info) => {
            assert_eq!((info.status, info.recorded), (CaptureStatus::Done, 40));
            assert_eq!(info.machine, MACHINE);
        }
        other => panic!("{other:?}"),
    }
    let disarm = Request::ArmCapture {
        trigger: Trigger::Now,
        window: 0,
    };
    responses(&dev.exchange(&frame_bytes(&disarm, 100), 60));
    assert_eq!(dev.state.capture.info().status, CaptureStatus::Empty);
}
