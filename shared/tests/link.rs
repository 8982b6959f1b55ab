//! The device's end of the link (`shared::protocol::link::Link`), the code the
//! firmware runs, driven directly: every frame answered once, in order; a table
//! write stored in flash, and a power cut during it keeping the old table; the
//! telemetry period; a frame cut short abandoned after the frame gap; arbitrary
//! bytes never a panic, and every byte sent a valid response frame.

use std::collections::VecDeque;

use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use proptest::prelude::*;
use shared::controller::self_test::{RotorSelfTest, SelfTest, SelfTestReport, SelfTestStatus};
use shared::controller::{
    Bridge, Command, Controller, Direction, Faults, Inputs, Outputs, Params, ResetCause, State,
    TuningTable,
};
use shared::protocol::link::{no_telemetry, Link, LinkState, StateLock};
use shared::protocol::{Decoder, Message, NackReason, Request, Response, FRAME_GAP_TIMEOUT_MS};
use shared::storage::{self, SimFlash};

mod support;

use support::device::{responses, Device};
use support::frames::frame_bytes;

fn table(rows: &[(f32, f32, f32)]) -> TuningTable {
    TuningTable::from_rows(rows).expect("a valid table")
}

#[test]
fn every_frame_is_answered_once_in_order() {
    let mut dev = Device::new();
    let requests = [
        Request::Command(Command::Heartbeat),
        Request::GetStatus,
        Request::Command(Command::Travel {
            direction: Direction::Right,
            speed_rpm: 3000.0,
        }),
        Request::Command(Command::HoldOffset {
            speed_rpm: 2800.0,
            offset_deg: 120.0,
        }),
        Request::Command(Command::Stop),
        Request::Command(Command::ResetFaults),
        Request::ReadTuningTable,
        Request::WriteTuningTable(table(&[(2500.0, 90.0, 270.0), (3000.0, 81.1, 278.9)])),
        Request::ReadSelfTest,
        Request::StreamTelemetry { period_ms: 0 },
        Request::RunSelfTest,
    ];
    let mut bytes = Vec::new();
    for (k, r) in requests.iter().enumerate() {
        bytes.extend(frame_bytes(r, 100 + k as u16));
    }
    // A corrupted frame (payload flipped): Nack BadCrc to its sequence number.
    let mut bad = frame_bytes(&Request::GetStatus, 500);
    let last = bad.len() - 1;
    bad[last] ^= 0x01;
    bytes.extend(&bad);
    let answers = responses(&dev.exchange(&bytes, 10));
    assert_eq!(answers.len(), requests.len() + 1);
    for (k, (seq, response)) in answers.iter().take(requests.len()).enumerate() {
        assert_eq!(*seq, 100 + k as u16);
        let id = requests[k].id() as u8;
        match (&requests[k], response) {
            (Request::GetStatus, Response::Status(s)) => assert_eq!(s.state, State::Idle),
            (Request::ReadTuningTable, Response::TuningTable(t)) => {
                assert_eq!(*t, TuningTable::default_offsets())
            }
            (Request::ReadSelfTest, Response::SelfTest(r)) => {
                assert_eq!(r.status, SelfTestStatus::NotRun)
            }
            (_, Response::Ack { request }) => assert_eq!(*request, id),
            (r, other) => panic!("{r:?} answered {other:?}"),
        }
    }
    assert_eq!(
        answers[requests.len()],
        (
            500,
            Response::Nack {
                request: Request::GetStatus.id() as u8,
                reason: NackReason::BadCrc
            }
        )
    );
    // The last motion command waits for the control tick; the self-test request
    // too.
    assert_eq!(
        dev.state.command,
        Some(shared::controller::Command::ResetFaults)
    );
    assert!(dev.state.self_test_requested);
}

#[test]
fn a_table_write_is_stored_and_a_power_cut_keeps_the_old_table() {
    let old = table(&[(2500.0, 90.0, 270.0), (3000.0, 81.1, 278.9)]);
    let new = table(&[(2000.0, 100.0, 260.0)]);
    let mut dev = Device::new();
    let answers =
        responses(&dev.exchange(&frame_bytes(&Request::WriteTuningTable(old.clone()), 1), 5));
    assert_eq!(
        answers,
        [(
            1,
            Response::Ack {
                request: Request::WriteTuningTable(old.clone()).id() as u8
            }
        )]
    );
    assert_eq!(
        storage::load(&dev.flash).expect("stored").record.tuning,
        old
    );
    assert_eq!(dev.state.tuning, old);
    assert_eq!(dev.state.new_tuning.take(), Some(old.clone()));

    // A cut after every few bytes of the next store: Nack StorageFailed, the old
    // table still in use and the one that loads.
    let id = Request::WriteTuningTable(new.clone()).id() as u8;
    for cut in (0..1452).step_by(37) {
        let mut d = Device::new();
        d.exchange(&frame_bytes(&Request::WriteTuningTable(old.clone()), 1), 5);
        d.state.new_tuning = None;
        d.flash.cut_after(cut);
        let answers =
            responses(&d.exchange(&frame_bytes(&Request::WriteTuningTable(new.clone()), 2), 6));
        assert_eq!(
            answers,
            [(
                2,
                Response::Nack {
                    request: id,
                    reason: NackReason::StorageFailed
                }
            )],
            "cut after {cut} bytes"
        );
        assert_eq!(d.state.tuning, old, "cut after {cut}");
        assert_eq!(d.state.new_tuning, None, "cut after {cut}");
        d.flash.power_on();
        assert_eq!(
            storage::load(&d.flash)
                .expect("the old record")
                .record
                .tuning,
            old,
            "cut after {cut}"
        );
    }

    // Refused while the motors run: nothing written.
    let mut d = Device::new();
    d.state.status.state = State::Running;
    d.state.status.telemetry.speed_rpm = [3000.0; 2];
    let answers =
        responses(&d.exchange(&frame_bytes(&Request::WriteTuningTable(new.clone()), 3), 5));
    assert_eq!(
        answers,
        [(
            3,
            Response::Nack {
                request: id,
                reason: NackReason::NotStopped
            }
        )]
    );
    assert_eq!(d.flash.erases(), 0);
}

/// A self-test aborted after a good one was stored: the next table write keeps
/// the good result in flash (it is what a store writes, not the latest report).
#[test]
fn an_aborted_self_test_does_not_drop_the_stored_result() {
    let good = SelfTest {
        rotors: [RotorSelfTest {
            motor_polarity_ok: true,
            encoder_polarity_ok: true,
            index_seen: true,
            counts_per_rev: 4096,
            index_offset_counts: 1209,
        }; 2],
    };
    let mut dev = Device::new();
    dev.state = LinkState::new(
        dev.state.status,
        TuningTable::default_offsets(),
        Some(SelfTestReport {
            status: SelfTestStatus::Done,
            result: good,
        }),
    );
    // A later test, aborted (E-stop), as the control task publishes it.
    dev.state.self_test = SelfTestReport {
        status: SelfTestStatus::Running,
        result: SelfTest::default(),
    };
    let outputs = Outputs {
        bridges: [Bridge::Off; 2],
        state: State::Idle,
        faults: Faults::NONE,
        telemetry: no_telemetry(),
    };
    let mut controller = Controller::new(&Params::reference(), ResetCause::PowerOn);
    assert!(controller.start_self_test());
    let stop = Inputs {
        supply_voltage: 12.0,
        command: Some(Command::Stop),
        ..Inputs::default()
    };
    controller.step(&stop, 1e-3);
    assert_eq!(
        controller.self_test_report().status,
        SelfTestStatus::Aborted
    );
    dev.state.publish(10, &stop, &outputs, &controller);
    assert_eq!(dev.state.self_test.status, SelfTestStatus::Aborted);
    assert!(!dev.state.self_test_unsaved);

    let new = table(&[(2000.0, 100.0, 260.0)]);
    let answers =
        responses(&dev.exchange(&frame_bytes(&Request::WriteTuningTable(new.clone()), 1), 20));
    assert!(
        matches!(answers[..], [(1, Response::Ack { .. })]),
        "{answers:?}"
    );
    let stored = storage::load(&dev.flash).expect("stored").record;
    assert_eq!(stored.tuning, new);
    assert_eq!(stored.self_test, Some(good));
}

#[test]
fn telemetry_comes_at_its_period_until_turned_off() {
    let mut dev = Device::new();
    let answers = responses(&dev.exchange(
        &frame_bytes(&Request::StreamTelemetry { period_ms: 50 }, 7),
        0,
    ));
    assert_eq!(answers.len(), 1);
    let mut telemetry = Vec::new();
    for now in 1..=1000 {
        dev.state.status.uptime_ms = now;
        for (seq, r) in responses(&dev.exchange(&[], now)) {
            match r {
                Response::Telemetry(s) => telemetry.push((seq, s.uptime_ms)),
                other => panic!("{other:?}"),
            }
        }
    }
    // Every 50 ms: 20 frames in 1 s, numbered by the device's own counter.
    assert_eq!(telemetry.len(), 20, "{telemetry:?}");
    for w in telemetry.windows(2) {
        assert_eq!(w[1].1 - w[0].1, 50);
        assert_eq!(w[1].0, w[0].0.wrapping_add(1));
    }
    // Off: an Ack, then nothing.
    let answers = responses(&dev.exchange(
        &frame_bytes(&Request::StreamTelemetry { period_ms: 0 }, 8),
        1001,
    ));
    assert!(
        matches!(answers[..], [(8, Response::Ack { .. })]),
        "{answers:?}"
    );
    for now in 1002..2000 {
        assert!(dev.exchange(&[], now).is_empty());
    }
    // Below the shortest period: refused.
    let answers = responses(&dev.exchange(
        &frame_bytes(&Request::StreamTelemetry { period_ms: 10 }, 9),
        2000,
    ));
    assert!(
        matches!(
            answers[..],
            [(
                9,
                Response::Nack {
                    reason: NackReason::BadValue,
                    ..
                }
            )]
        ),
        "{answers:?}"
    );
}

#[test]
fn a_frame_cut_short_is_abandoned_after_the_frame_gap() {
    // The start of a table write (its header announces 385 bytes), cut short.
    let long = frame_bytes(
        &Request::WriteTuningTable(
            TuningTable::from_rows(
                &(0..32)
                    .map(|k| (100.0 * (k + 1) as f32, 90.0, 270.0))
                    .collect::<Vec<_>>(),
            )
            .unwrap(),
        ),
        2,
    );
    let ping = frame_bytes(&Request::Command(Command::Heartbeat), 3);

    // Without the gap, the next frame is swallowed as the cut frame's payload.
    let mut dev = Device::new();
    assert!(dev.exchange(&long[..30], 100).is_empty());
    assert!(dev
        .exchange(&ping, 100 + FRAME_GAP_TIMEOUT_MS - 1)
        .is_empty());

    // After the gap, the cut frame is dropped and the next frame answered.
    let mut dev = Device::new();
    assert!(dev.exchange(&long[..30], 100).is_empty());
    assert!(dev.exchange(&[], 100 + FRAME_GAP_TIMEOUT_MS - 1).is_empty());
    assert!(dev.exchange(&[], 100 + FRAME_GAP_TIMEOUT_MS).is_empty());
    let answers = responses(&dev.exchange(&ping, 100 + FRAME_GAP_TIMEOUT_MS + 1));
    assert_eq!(
        answers,
        [(
            3,
            Response::Ack {
                request: Request::Command(Command::Heartbeat).id() as u8
            }
        )]
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Arbitrary bytes in arbitrary chunks at arbitrary times, with valid frames
    /// among them: no panic, and everything sent is whole, valid response frames.
    #[test]
    fn arbitrary_bytes_never_panic(
        chunks in proptest::collection::vec(
            (proptest::collection::vec(any::<u8>(), 0..120), 0u32..80, any::<bool>()),
            0..40,
        ),
    ) {
        let mut dev = Device::new();
        let mut now = 0u32;
        let mut sent = Vec::new();
        for (k, (bytes, step, with_frame)) in chunks.iter().enumerate() {
            now = now.wrapping_add(*step);
            let mut input = bytes.clone();
            if *with_frame {
                input.extend(frame_bytes(&Request::GetStatus, k as u16));
            }
            sent.extend(dev.exchange(&input, now));
        }
        let mut decoder = Decoder::new();
        let mut input = &sent[..];
        while let Some(event) = decoder.decode(&mut input) {
            let frame = event.expect("valid frames only");
            prop_assert!(Response::parse(&frame).is_ok());
        }
        prop_assert_eq!(decoder.held(), 0);
    }
}

/// A flash that checks, at every erase and program, that the link holds no lock
/// on its state (on the board the lock masks the control task, and an erase takes
/// up to 2 s) and that the state says a store is under way.
struct Watched<'a> {
    flash: SimFlash,
    locked: &'a std::cell::Cell<bool>,
    state: &'a std::cell::RefCell<LinkState>,
    operations: usize,
}

impl Watched<'_> {
    fn check(&mut self) {
        assert!(
            !self.locked.get(),
            "a flash operation under the state's lock"
        );
        assert!(
            self.state.borrow().storing,
            "storing not set during the store"
        );
        self.operations += 1;
    }
}

impl ErrorType for Watched<'_> {
    type Error = <SimFlash as ErrorType>::Error;
}

impl ReadNorFlash for Watched<'_> {
    const READ_SIZE: usize = SimFlash::READ_SIZE;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.flash.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl NorFlash for Watched<'_> {
    const WRITE_SIZE: usize = SimFlash::WRITE_SIZE;
    const ERASE_SIZE: usize = SimFlash::ERASE_SIZE;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.check();
        self.flash.erase(from, to)
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.check();
        self.flash.write(offset, bytes)
    }
}

/// A lock on a shared state that tells the test how the link uses it: whether a
/// closure is running under it (`locked`), how many accesses it has seen, the
/// access that first set `storing`, and, at access `tick_at`, a control tick
/// "running" just before the closure and publishing `starting`.
struct TestLock<'a> {
    state: &'a std::cell::RefCell<LinkState>,
    locked: &'a std::cell::Cell<bool>,
    accesses: usize,
    marked_at: Option<usize>,
    tick_at: Option<usize>,
}

impl<'a> TestLock<'a> {
    fn new(state: &'a std::cell::RefCell<LinkState>, locked: &'a std::cell::Cell<bool>) -> Self {
        TestLock {
            state,
            locked,
            accesses: 0,
            marked_at: None,
            tick_at: None,
        }
    }
}

impl StateLock for TestLock<'_> {
    fn lock<R>(&mut self, f: impl FnOnce(&mut LinkState) -> R) -> R {
        self.accesses += 1;
        let mut s = self.state.borrow_mut();
        if self.tick_at == Some(self.accesses) {
            s.status.state = shared::controller::State::Starting;
        }
        let storing = s.storing;
        self.locked.set(true);
        let r = f(&mut s);
        self.locked.set(false);
        if !storing && s.storing && self.marked_at.is_none() {
            self.marked_at = Some(self.accesses);
        }
        r
    }
}

/// A table write stores the flash outside the lock on the link's state (which on
/// the board masks the control task for as long as it is held), with `storing`
/// set while it runs; a motion command that came meanwhile waits for the control
/// task until the store is done, a stop does not.
#[test]
fn a_flash_store_runs_outside_the_lock_and_holds_motion_commands_back() {
    let dev = Device::new();
    let state = std::cell::RefCell::new(dev.state);
    let locked = std::cell::Cell::new(false);
    let mut flash = Watched {
        flash: dev.flash,
        locked: &locked,
        state: &state,
        operations: 0,
    };
    let mut link = Link::new();
    let write = Request::WriteTuningTable(table(&[(2500.0, 80.0, 280.0), (3000.0, 90.0, 270.0)]));
    let bytes = frame_bytes(&write, 7);
    let mut rx: VecDeque<u8> = bytes.into_iter().collect();
    let mut out = Vec::new();
    let mut lock = TestLock::new(&state, &locked);
    while link.poll(
        || rx.pop_front(),
        1,
        &mut lock,
        &mut flash,
        |frame| out.extend_from_slice(frame),
    ) {}
    // An erase, the record after its commit unit, the commit unit: each checked.
    assert_eq!(flash.operations, 3, "flash operations");
    let request = write.id() as u8;
    assert_eq!(responses(&out), vec![(7, Response::Ack { request })]);
    let mut state = state.into_inner();
    assert!(!state.storing);
    assert_eq!(state.tuning.rows().len(), 2);

    // While storing, a travel command waits; a stop passes.
    let mut c = shared::controller::Controller::new(
        &shared::controller::Params::reference(),
        shared::controller::ResetCause::PowerOn,
    );
    state.storing = true;
    state.command = Some(shared::controller::Command::Travel {
        direction: Direction::Right,
        speed_rpm: 3000.0,
    });
    assert_eq!(state.take_for_tick(&mut c).command, None);
    assert!(state.command.is_some(), "kept for later");
    state.command = Some(shared::controller::Command::Stop);
    assert_eq!(
        state.take_for_tick(&mut c).command,
        Some(shared::controller::Command::Stop)
    );
    // A requested self-test (it drives the motors) waits too.
    state.command = None;
    state.self_test_requested = true;
    let taken = state.take_for_tick(&mut c);
    assert!(!taken.self_test_refused);
    assert_eq!(c.state(), shared::controller::State::Idle, "not started");
    assert!(state.self_test_requested, "kept for later");
    state.storing = false;
    state.take_for_tick(&mut c);
    assert_eq!(c.state(), shared::controller::State::SelfTest);
    assert!(!state.self_test_requested);
    state.command = Some(shared::controller::Command::Travel {
        direction: Direction::Right,
        speed_rpm: 3000.0,
    });
    assert!(state.take_for_tick(&mut c).command.is_some());
}

/// A control tick can run between the handler's check that the motors are
/// stopped and the store: if it took a waiting run command and published a
/// driving state, the store is refused (`NotStopped`) under the same lock that
/// would have marked it, and nothing is erased.
#[test]
fn a_tick_that_starts_the_motors_before_the_store_gets_it_refused() {
    let write = Request::WriteTuningTable(table(&[(2500.0, 80.0, 280.0), (3000.0, 90.0, 270.0)]));
    // A run without the tick: the access of the lock that marks the store.
    let run = |tick_at: Option<usize>| {
        let dev = Device::new();
        let state = std::cell::RefCell::new(dev.state);
        let locked = std::cell::Cell::new(false);
        let mut flash = dev.flash;
        let mut lock = TestLock::new(&state, &locked);
        lock.tick_at = tick_at;
        let mut link = Link::new();
        let mut rx: VecDeque<u8> = frame_bytes(&write, 9).into_iter().collect();
        let mut out = Vec::new();
        while link.poll(
            || rx.pop_front(),
            1,
            &mut lock,
            &mut flash,
            |frame| out.extend_from_slice(frame),
        ) {}
        let marked_at = lock.marked_at;
        (out, state.into_inner(), flash, marked_at)
    };
    let (_, _, _, marked_at) = run(None);
    let store_access = marked_at.expect("the store was marked");
    assert!(store_access > 1, "the handler's own check came first");
    // The tick runs just before the store's own lock.
    let before = Device::new().flash;
    let (out, state, flash, _) = run(Some(store_access));
    let request = write.id() as u8;
    assert_eq!(
        responses(&out),
        vec![(
            9,
            Response::Nack {
                request,
                reason: NackReason::NotStopped
            }
        )]
    );
    assert!(!state.storing);
    assert!(flash == before, "nothing erased or written");
}

/// A self-test asked for and a table write in the same breath: the test would
/// start at the next tick, in the middle of the erase, so the write is refused
/// (`Busy`) and nothing is erased.
#[test]
fn a_store_waits_for_a_requested_self_test() {
    let mut dev = Device::new();
    let before = dev.flash.clone();
    let mut bytes = frame_bytes(&Request::RunSelfTest, 1);
    let write = Request::WriteTuningTable(table(&[(3000.0, 90.0, 270.0)]));
    bytes.extend(frame_bytes(&write, 2));
    let out = dev.exchange(&bytes, 1);
    let answers = responses(&out);
    assert!(
        matches!(answers[0], (1, Response::Ack { .. })),
        "{answers:?}"
    );
    assert_eq!(
        answers[1],
        (
            2,
            Response::Nack {
                request: write.id() as u8,
                reason: NackReason::Busy
            }
        )
    );
    assert!(dev.flash == before, "nothing erased or written");
}

/// Two procedures asked for before a control tick has taken the first: the
/// second is refused `Busy` (it would otherwise be Acked, then reported aborted
/// with nothing measured when the tick started the first), whichever comes
/// first; one asked for twice, likewise.
#[test]
fn a_second_procedure_asked_before_the_first_starts_is_busy() {
    for (first, second) in [
        (Request::RunSelfTest, Request::RunIdentify),
        (Request::RunIdentify, Request::RunSelfTest),
        (Request::RunIdentify, Request::RunIdentify),
    ] {
        let mut dev = Device::new();
        let mut bytes = frame_bytes(&first, 1);
        bytes.extend(frame_bytes(&second, 2));
        let answers = responses(&dev.exchange(&bytes, 10));
        assert_eq!(
            answers,
            vec![
                (
                    1,
                    Response::Ack {
                        request: first.id() as u8
                    }
                ),
                (
                    2,
                    Response::Nack {
                        request: second.id() as u8,
                        reason: NackReason::Busy
                    }
                ),
            ],
            "{first:?} then {second:?}"
        );
    }
}
