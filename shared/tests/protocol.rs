//! The UART protocol (`shared::protocol`): CRC check values, frames byte for byte
//! against an independent encoding (Python's `zlib.crc32` and a bitwise CRC-16,
//! see `docs/protocol.md`), every message's round trip, the decoder's recovery
//! cases, and the answer rule on a mock device.

use shared::capture::{
    CaptureInfo, CaptureStatus, CommandEntry, CommandKind, MachineFingerprint, Record, Start,
    Trigger, RECORDS_PER_FRAME, RECORD_LEN,
};
use shared::codec::crc::{crc16_ccitt_false, crc32};
use shared::controller::identify::{IdentifyReport, IdentifyStatus, Identity};
use shared::controller::self_test::{RotorSelfTest, SelfTest, SelfTestReport, SelfTestStatus};
use shared::controller::{Command, Direction, Faults, State, Telemetry, TuningTable};
use shared::protocol::{
    answer_error, answer_event, answer_request, encode, encode_frame, Decoder, Device, EncodeError,
    Frame, FrameError, Message, MessageId, NackReason, ParseError, Request, Response, StatusReport,
    HEADER_LEN, MAX_FRAME, MAX_PAYLOAD, PROTOCOL_VERSION,
};

mod support;

use support::identities::identity;

/// A decoder event with the frame copied out as `(id, seq, payload)`.
type Event = Result<(u8, u16, Vec<u8>), FrameError>;

/// Every event of `bytes` fed at once.
fn events(decoder: &mut Decoder, bytes: &[u8]) -> Vec<Event> {
    let mut out = Vec::new();
    let mut input = bytes;
    while let Some(event) = decoder.decode(&mut input) {
        out.push(event.map(|f| (f.id, f.seq, f.payload.to_vec())));
    }
    out
}

/// The frame of `msg` with sequence number `seq`.
fn frame_of<M: Message>(msg: &M, seq: u16) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode(msg, seq, &mut buf).expect("encodes");
    buf[..n].to_vec()
}

/// A header with any fields and a correct header CRC (for frames `encode_frame`
/// refuses to make: other versions, lengths above `MAX_PAYLOAD`).
fn raw_header(version: u8, id: u8, seq: u16, len: u16) -> Vec<u8> {
    let mut h = vec![0xA5, 0x5A, version, id];
    h.extend_from_slice(&seq.to_le_bytes());
    h.extend_from_slice(&len.to_le_bytes());
    let crc = crc16_ccitt_false(&h);
    h.extend_from_slice(&crc.to_le_bytes());
    h
}

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}

fn sample_table() -> TuningTable {
    TuningTable::from_rows(&[
        (500.0, 90.0, 270.0),
        (1500.0, 100.5, 250.0),
        (3000.0, 350.0, 10.0),
    ])
    .unwrap()
}

fn full_table() -> TuningTable {
    let rows: Vec<(f32, f32, f32)> = (0..32)
        .map(|i| (100.0 * (i + 1) as f32, (i * 11) as f32, 359.5 - i as f32))
        .collect();
    TuningTable::from_rows(&rows).unwrap()
}

fn sample_telemetry() -> Telemetry {
    Telemetry {
        speed_rpm: [2999.5, -3001.25],
        speed_ref_rpm: [3000.0, 3000.0],
        phase_valid: true,
        phase_offset_deg: 91.5,
        phase_loop_closed: true,
        commanded_offset_deg: 90.0,
        target_offset_deg: 90.0,
        phase_error_deg: -1.5,
        current: [0.75, 0.8],
        supply_voltage: 12.1,
        duty: [0.5, -0.25],
        command_rejected: false,
        tick_late_us: 7,
        tick_busy_us: 12,
        overruns: 1,
    }
}

fn sample_status(state: State, speed: f32) -> StatusReport {
    let mut telemetry = sample_telemetry();
    telemetry.speed_rpm = [speed, speed];
    StatusReport {
        uptime_ms: 123_456,
        state,
        faults: if state == State::Fault {
            Faults::ESTOP | Faults::LINK_LOST
        } else {
            Faults::NONE
        },
        telemetry,
        rx_dropped: 2,
    }
}

fn sample_self_test() -> SelfTest {
    SelfTest {
        rotors: [
            RotorSelfTest {
                motor_polarity_ok: true,
                encoder_polarity_ok: true,
                index_seen: true,
                counts_per_rev: 4096,
                index_offset_counts: 1234,
            },
            RotorSelfTest {
                motor_polarity_ok: true,
                encoder_polarity_ok: false,
                index_seen: false,
                counts_per_rev: 0,
                index_offset_counts: 0,
            },
        ],
    }
}

fn every_request() -> Vec<Request> {
    vec![
        Request::Command(Command::Heartbeat),
        Request::GetStatus,
        Request::Command(Command::Stop),
        Request::Command(Command::Travel {
            direction: Direction::Right,
            speed_rpm: 3000.0,
        }),
        Request::Command(Command::Travel {
            direction: Direction::Left,
            speed_rpm: 1200.5,
        }),
        Request::Command(Command::HoldOffset {
            speed_rpm: 2500.0,
            offset_deg: 180.0,
        }),
        Request::Command(Command::ResetFaults),
        Request::ReadTuningTable,
        Request::WriteTuningTable(sample_table()),
        Request::WriteTuningTable(full_table()),
        Request::RunSelfTest,
        Request::ReadSelfTest,
        Request::RunIdentify,
        Request::ReadIdentify,
        Request::StreamTelemetry { period_ms: 0 },
        Request::StreamTelemetry { period_ms: 50 },
        Request::ArmCapture {
            trigger: Trigger::Fault,
            window: 2048,
        },
        Request::ArmCapture {
            trigger: Trigger::Now,
            window: 0,
        },
        Request::GetCapture,
        Request::ReadCapture { first: 2047 },
    ]
}

fn every_response() -> Vec<Response> {
    vec![
        Response::Ack { request: 0x04 },
        Response::Nack {
            request: 0x7F,
            reason: NackReason::UnknownMessage,
        },
        Response::Status(sample_status(State::Running, 3000.0)),
        Response::Status(sample_status(State::Fault, 0.0)),
        Response::TuningTable(sample_table()),
        Response::TuningTable(full_table()),
        Response::SelfTest(SelfTestReport {
            status: SelfTestStatus::Done,
            result: sample_self_test(),
        }),
        Response::SelfTest(SelfTestReport {
            status: SelfTestStatus::NotRun,
            result: SelfTest::default(),
        }),
        Response::Telemetry(sample_status(State::Starting, 1000.0)),
        Response::Identify(IdentifyReport {
            status: IdentifyStatus::Done,
            identity: identity(3),
        }),
        Response::Identify(IdentifyReport {
            status: IdentifyStatus::NotRun,
            identity: Identity::default(),
        }),
        Response::Status(sample_status(State::Identify, 750.0)),
        Response::Capture(sample_capture_info()),
        Response::CaptureRecords {
            first: 22,
            count: 2,
            records: {
                let mut slots = [[0u8; RECORD_LEN]; RECORDS_PER_FRAME];
                slots[0] = sample_record(false).to_bytes();
                slots[1] = sample_record(true).to_bytes();
                slots
            },
        },
        Response::CaptureRecords {
            first: 2000,
            count: 0,
            records: [[0u8; RECORD_LEN]; RECORDS_PER_FRAME],
        },
    ]
}

/// A capture's info with a command of each kind that carries values.
fn sample_capture_info() -> CaptureInfo {
    let mut commands = heapless::Vec::new();
    commands
        .push(CommandEntry {
            record: 0,
            command: Command::Travel {
                direction: Direction::Left,
                speed_rpm: 2800.0,
            },
        })
        .unwrap();
    commands
        .push(CommandEntry {
            record: 900,
            command: Command::HoldOffset {
                speed_rpm: 3000.0,
                offset_deg: 95.5,
            },
        })
        .unwrap();
    CaptureInfo {
        id: 3,
        status: CaptureStatus::Done,
        trigger: Trigger::Command,
        capacity: 2048,
        window: 2000,
        recorded: 2000,
        ended_early: false,
        tick_us: 1000,
        start: Start {
            state: State::Idle,
            speed_rpm: [0.5, -0.25],
            index: [Some(4096), None],
            uptime_ms: 123_456,
        },
        machine: MachineFingerprint {
            crc32: 0x7e36_8ed6,
            len: 7459,
        },
        commands,
    }
}

/// A record with every field set; `off`: rotor 2's bridge off.
fn sample_record(off: bool) -> Record {
    Record {
        encoder: [u32::MAX - 3, 12],
        index: [Some(u32::MAX - 100), None],
        current: [0.125, -0.5],
        supply_voltage: 11.9,
        estop: off,
        command: Some(CommandKind::Travel),
        self_test_started: false,
        identify_started: off,
        tuning_changed: !off,
        timing_us: [3, 412],
        duty_raw: [Some(-32767), if off { None } else { Some(16000) }],
        state: State::Running,
        faults: Faults::from_bits(Faults::LINK_LOST.bits() | Faults::ESTOP.bits()),
    }
}

#[test]
fn crc_check_values_of_the_catalogue() {
    assert_eq!(crc16_ccitt_false(b"123456789"), 0x29B1);
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
}

#[test]
fn frames_match_the_documented_bytes() {
    // The examples of docs/protocol.md, computed with Python (zlib.crc32 and a
    // bitwise CRC-16/CCITT-FALSE), not with this crate.
    assert_eq!(
        frame_of(&Request::Command(Command::Heartbeat), 1),
        hex("A5 5A 04 01 01 00 00 00 F4 3C DE EC 59 FD")
    );
    assert_eq!(
        frame_of(
            &Request::Command(Command::Travel {
                direction: Direction::Right,
                speed_rpm: 1500.0
            }),
            0x1234
        ),
        hex("A5 5A 04 04 34 12 05 00 F9 5D 00 00 80 BB 44 FB 92 A9 33")
    );
    assert_eq!(
        frame_of(&Response::Ack { request: 0x01 }, 1),
        hex("A5 5A 04 80 01 00 01 00 44 87 01 B3 5C 0D A4")
    );
    assert_eq!(
        frame_of(
            &Response::Nack {
                request: 0x04,
                reason: NackReason::BadValue
            },
            0x1234
        ),
        hex("A5 5A 04 81 34 12 02 00 E9 C5 04 03 7D 8B 2C 04")
    );
    assert_eq!(
        frame_of(
            &Request::ArmCapture {
                trigger: Trigger::Command,
                window: 2000
            },
            7
        ),
        hex("A5 5A 04 0E 07 00 03 00 C7 2B 01 D0 07 04 3B 02 1E")
    );
    assert_eq!(
        frame_of(&Request::ReadCapture { first: 11 }, 8),
        hex("A5 5A 04 10 08 00 02 00 EA 07 0B 00 60 B6 EE 65")
    );
}

#[test]
fn every_request_and_response_round_trips() {
    let mut decoder = Decoder::new();
    for (i, request) in every_request().into_iter().enumerate() {
        let bytes = frame_of(&request, 1000 + i as u16);
        let mut input = &bytes[..];
        let frame = decoder.decode(&mut input).unwrap().unwrap();
        assert_eq!(frame.seq, 1000 + i as u16);
        assert_eq!(frame.id, request.id() as u8);
        assert_eq!(Request::parse(&frame), Ok(request.clone()));
        // A request is no response.
        assert_eq!(Response::parse(&frame), Err(ParseError::UnknownId));
        assert!(decoder.decode(&mut input).is_none());
    }
    for response in every_response() {
        let bytes = frame_of(&response, 7);
        let mut input = &bytes[..];
        let frame = decoder.decode(&mut input).unwrap().unwrap();
        assert_eq!(Response::parse(&frame), Ok(response.clone()));
        assert_eq!(Request::parse(&frame), Err(ParseError::UnknownId));
    }
}

#[test]
fn a_whole_tuning_table_fits_one_frame() {
    let bytes = frame_of(&Request::WriteTuningTable(full_table()), 0);
    assert_eq!(bytes.len(), HEADER_LEN + 1 + 32 * 12 + 4);
    assert!(bytes.len() <= MAX_FRAME);
}

#[test]
fn message_ids_are_unique_and_split_by_direction() {
    for (i, a) in MessageId::ALL.iter().enumerate() {
        assert_eq!(MessageId::from_u8(*a as u8), Some(*a));
        assert_eq!(a.is_request(), (*a as u8) < 0x80);
        for b in &MessageId::ALL[i + 1..] {
            assert_ne!(*a as u8, *b as u8);
        }
    }
    for r in NackReason::ALL {
        assert_eq!(NackReason::from_u8(r as u8), Some(r));
    }
    assert_eq!(NackReason::from_u8(0), None);
}

#[test]
fn encode_refuses_what_does_not_fit() {
    let mut small = [0u8; 13];
    assert_eq!(
        encode(&Request::Command(Command::Stop), 0, &mut small),
        Err(EncodeError::BufferTooSmall)
    );
    let mut buf = [0u8; MAX_FRAME + 10];
    assert_eq!(
        encode_frame(1, 0, &[0; MAX_PAYLOAD + 1], &mut buf),
        Err(EncodeError::PayloadTooLong)
    );
    assert_eq!(
        encode_frame(1, 0, &[0; MAX_PAYLOAD], &mut buf),
        Ok(MAX_FRAME)
    );
}

#[test]
fn payload_errors_name_their_cause() {
    let parse = |id: u8, payload: &[u8]| {
        Request::parse(&Frame {
            id,
            seq: 0,
            payload,
        })
    };
    // Unknown ids, and a response id sent to the device.
    assert_eq!(parse(0x00, &[]), Err(ParseError::UnknownId));
    assert_eq!(parse(0x7F, &[]), Err(ParseError::UnknownId));
    assert_eq!(parse(0x80, &[1]), Err(ParseError::UnknownId));
    // Lengths.
    assert_eq!(parse(0x03, &[0]), Err(ParseError::BadLength));
    assert_eq!(parse(0x04, &[0, 0, 0, 0]), Err(ParseError::BadLength));
    assert_eq!(parse(0x08, &[2; 13]), Err(ParseError::BadLength));
    assert_eq!(parse(0x08, &[]), Err(ParseError::BadLength));
    // Values: direction 2, a NaN or infinite speed, a period of 5 ms, an empty
    // table, a table with decreasing speeds.
    let mut travel = vec![2];
    travel.extend_from_slice(&1000f32.to_le_bytes());
    assert_eq!(parse(0x04, &travel), Err(ParseError::BadValue));
    travel[0] = 0;
    travel[1..].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_eq!(parse(0x04, &travel), Err(ParseError::BadValue));
    let mut hold = f32::INFINITY.to_le_bytes().to_vec();
    hold.extend_from_slice(&90f32.to_le_bytes());
    assert_eq!(parse(0x05, &hold), Err(ParseError::BadValue));
    assert_eq!(parse(0x0B, &5u16.to_le_bytes()), Err(ParseError::BadValue));
    assert_eq!(
        parse(0x0B, &20u16.to_le_bytes()),
        Ok(Request::StreamTelemetry { period_ms: 20 })
    );
    assert_eq!(parse(0x08, &[0]), Err(ParseError::BadValue));
    let mut table = vec![2];
    for v in [1000f32, 90.0, 270.0, 500.0, 90.0, 270.0] {
        table.extend_from_slice(&v.to_le_bytes());
    }
    assert_eq!(parse(0x08, &table), Err(ParseError::BadValue));
}

#[test]
fn commands_convert_both_ways() {
    let commands = [
        Command::Stop,
        Command::Travel {
            direction: Direction::Left,
            speed_rpm: 2000.0,
        },
        Command::HoldOffset {
            speed_rpm: 1500.0,
            offset_deg: 45.0,
        },
        Command::ResetFaults,
        Command::Heartbeat,
    ];
    // Each command through the wire: its own message id, and back to itself.
    let mut ids = Vec::new();
    for command in commands {
        let request = Request::from(command);
        let mut out = [0u8; MAX_FRAME];
        let n = encode(&request, 3, &mut out).expect("a command fits a frame");
        let mut decoder = Decoder::new();
        let mut input = &out[..n];
        let frame = decoder.decode(&mut input).expect("a frame").expect("whole");
        assert_eq!(Request::parse(&frame).map(|r| r.command()), Ok(command));
        ids.push(frame.id);
    }
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(
        ids.len(),
        commands.len(),
        "one message id per command: {ids:?}"
    );
    // Every request gives exactly one command; those without motion a heartbeat.
    for request in every_request() {
        let motion = matches!(
            request,
            Request::Command(Command::Stop)
                | Request::Command(Command::Travel { .. })
                | Request::Command(Command::HoldOffset { .. })
                | Request::Command(Command::ResetFaults)
        );
        assert_eq!(request.is_motion_command(), motion);
        if !motion {
            assert_eq!(request.command(), Command::Heartbeat);
        }
    }
}

// ---- The decoder ----

#[test]
fn bytes_one_at_a_time_give_the_same_frames() {
    let mut stream = Vec::new();
    for (i, r) in every_request().iter().enumerate() {
        stream.extend(frame_of(r, i as u16));
    }
    let mut whole = Decoder::new();
    let at_once = events(&mut whole, &stream);
    let mut single = Decoder::new();
    let mut one_by_one = Vec::new();
    for b in &stream {
        one_by_one.extend(events(&mut single, std::slice::from_ref(b)));
    }
    assert_eq!(at_once, one_by_one);
    assert_eq!(at_once.len(), every_request().len());
    assert_eq!(whole.stats().frames, every_request().len() as u32);
    assert_eq!(whole.stats().errors, 0);
    assert_eq!(whole.held(), 0);
}

#[test]
fn a_length_above_max_payload_is_refused_at_the_header() {
    // The header is right but announces 401 bytes: refused at its 10th byte, with
    // no payload byte waited for, and answered TooLong.
    let mut decoder = Decoder::new();
    let header = raw_header(PROTOCOL_VERSION, 0x08, 77, MAX_PAYLOAD as u16 + 1);
    let got = events(&mut decoder, &header);
    let error = FrameError::TooLong {
        id: 0x08,
        seq: 77,
        len: MAX_PAYLOAD as u16 + 1,
    };
    assert_eq!(got, vec![Err(error)]);
    assert_eq!(
        answer_error(&error),
        Some((
            77,
            Response::Nack {
                request: 0x08,
                reason: NackReason::TooLong
            }
        ))
    );
    // u16::MAX as well, and the next frame straight after is taken.
    let mut bytes = raw_header(PROTOCOL_VERSION, 0x01, 1, u16::MAX);
    bytes.extend(frame_of(&Request::Command(Command::Stop), 2));
    let got = events(&mut decoder, &bytes);
    assert!(matches!(
        got[0],
        Err(FrameError::TooLong { len: 0xFFFF, .. })
    ));
    assert_eq!(got[1], Ok((MessageId::Stop as u8, 2, vec![])));
}

#[test]
fn another_version_is_answered_bad_version() {
    // A host of version 1 (a 60-byte status report) asking a version-2 device.
    let mut decoder = Decoder::new();
    let mut bytes = raw_header(1, 0x01, 9, 0);
    bytes.extend_from_slice(&[0; 4]);
    let got = events(&mut decoder, &bytes);
    let error = FrameError::BadVersion {
        version: 1,
        id: 0x01,
        seq: 9,
    };
    assert_eq!(got, vec![Err(error)]);
    let (seq, nack) = answer_error(&error).unwrap();
    assert_eq!(seq, 9);
    assert_eq!(
        nack,
        Response::Nack {
            request: 0x01,
            reason: NackReason::BadVersion
        }
    );
    // The Nack's own header carries the device's version.
    assert_eq!(frame_of(&nack, seq)[2], PROTOCOL_VERSION);
}

#[test]
fn a_corrupt_header_gets_no_answer_and_the_next_frame_is_found() {
    let mut bytes = frame_of(&Request::GetStatus, 5);
    bytes[6] ^= 0x01; // length 0 -> 1: header CRC wrong
    bytes.extend(frame_of(&Request::Command(Command::Stop), 6));
    let mut decoder = Decoder::new();
    let got = events(&mut decoder, &bytes);
    assert_eq!(got[0], Err(FrameError::HeaderCrc));
    assert_eq!(answer_error(&FrameError::HeaderCrc), None);
    assert_eq!(got[1], Ok((MessageId::Stop as u8, 6, vec![])));
    assert_eq!(got.len(), 2);
}

#[test]
fn a_corrupt_payload_is_answered_bad_crc_to_its_sequence_number() {
    let mut bytes = frame_of(
        &Request::Command(Command::Travel {
            direction: Direction::Left,
            speed_rpm: 2000.0,
        }),
        300,
    );
    bytes[12] ^= 0x40;
    let mut decoder = Decoder::new();
    let got = events(&mut decoder, &bytes);
    let error = FrameError::BadCrc { id: 0x04, seq: 300 };
    assert_eq!(got, vec![Err(error)]);
    assert_eq!(
        answer_error(&error),
        Some((
            300,
            Response::Nack {
                request: 0x04,
                reason: NackReason::BadCrc
            }
        ))
    );
}

#[test]
fn a_lost_byte_costs_one_frame_only() {
    // A UART overrun drops a payload byte of the first frame: the decoder reads the
    // next frame's first byte as its CRC's last, rejects it, and finds that next
    // frame again among the bytes it holds.
    let mut first = frame_of(
        &Request::Command(Command::HoldOffset {
            speed_rpm: 2000.0,
            offset_deg: 90.0,
        }),
        1,
    );
    first.remove(13);
    let mut bytes = first;
    bytes.extend(frame_of(&Request::Command(Command::Heartbeat), 2));
    bytes.extend(frame_of(&Request::GetStatus, 3));
    let mut decoder = Decoder::new();
    let got = events(&mut decoder, &bytes);
    assert_eq!(got[0], Err(FrameError::BadCrc { id: 0x05, seq: 1 }));
    assert_eq!(got[1], Ok((0x01, 2, vec![])));
    assert_eq!(got[2], Ok((0x02, 3, vec![])));
    assert_eq!(got.len(), 3);
}

#[test]
fn a_frame_inside_a_rejected_candidate_is_found() {
    // Garbage with a right header announcing 400 bytes swallows two real frames;
    // when its CRC fails at byte 414, both are found among the bytes held.
    let mut bytes = raw_header(PROTOCOL_VERSION, 0x42, 0, MAX_PAYLOAD as u16);
    bytes.extend(frame_of(&Request::Command(Command::Stop), 10));
    bytes.extend(frame_of(&Request::GetStatus, 11));
    bytes.resize(MAX_FRAME, 0x00);
    let mut decoder = Decoder::new();
    let got = events(&mut decoder, &bytes);
    assert_eq!(got[0], Err(FrameError::BadCrc { id: 0x42, seq: 0 }));
    assert_eq!(got[1], Ok((0x03, 10, vec![])));
    assert_eq!(got[2], Ok((0x02, 11, vec![])));
    assert_eq!(got.len(), 3);
}

#[test]
fn abandoning_a_cut_frame_releases_the_frames_after_it() {
    // A host restarted in the middle of a table write: the header announced 385
    // bytes, 20 came. The frames sent after the restart wait behind it until the
    // line goes quiet and the firmware abandons the cut frame.
    let table = frame_of(&Request::WriteTuningTable(full_table()), 1);
    let mut bytes = table[..30].to_vec();
    bytes.extend(frame_of(&Request::Command(Command::Stop), 1));
    let mut decoder = Decoder::new();
    assert!(events(&mut decoder, &bytes).is_empty());
    assert!(decoder.held() > 0);
    decoder.abandon();
    let got = events(&mut decoder, &[]);
    assert_eq!(got, vec![Ok((0x03, 1, vec![]))]);
    assert_eq!(decoder.held(), 0);
}

#[test]
fn garbage_is_skipped_silently() {
    let mut bytes = vec![0x00, 0xFF, 0xA5, 0xA5, 0x13, 0x5A, 0xA5];
    bytes.extend(frame_of(&Request::Command(Command::ResetFaults), 3));
    let mut decoder = Decoder::new();
    let got = events(&mut decoder, &bytes);
    assert_eq!(got, vec![Ok((0x06, 3, vec![]))]);
    assert_eq!(decoder.stats().skipped, 7);
}

// ---- The answer rule on a mock device ----

/// A device that records what it is asked.
struct Mock {
    status: StatusReport,
    table: TuningTable,
    self_test: SelfTestReport,
    identify: IdentifyReport,
    identifications_started: u32,
    commands: Vec<Command>,
    refuse_commands: Option<NackReason>,
    stored: Vec<TuningTable>,
    store_fails: bool,
    self_tests_started: u32,
    telemetry_period_ms: Option<u16>,
}

impl Mock {
    fn new(state: State, speed: f32) -> Self {
        Mock {
            status: sample_status(state, speed),
            table: TuningTable::default(),
            self_test: SelfTestReport {
                status: SelfTestStatus::NotRun,
                result: SelfTest::default(),
            },
            identify: IdentifyReport {
                status: IdentifyStatus::NotRun,
                identity: Identity::default(),
            },
            identifications_started: 0,
            commands: Vec::new(),
            refuse_commands: None,
            stored: Vec::new(),
            store_fails: false,
            self_tests_started: 0,
            telemetry_period_ms: None,
        }
    }
}

impl Device for Mock {
    fn status(&self) -> StatusReport {
        self.status
    }
    fn command(&mut self, command: Command) -> Result<(), NackReason> {
        self.commands.push(command);
        match self.refuse_commands {
            Some(reason) if command != Command::Heartbeat => Err(reason),
            _ => Ok(()),
        }
    }
    fn tuning_table(&self) -> TuningTable {
        self.table.clone()
    }
    fn store_tuning_table(&mut self, table: &TuningTable) -> Result<(), NackReason> {
        if self.store_fails {
            return Err(NackReason::StorageFailed);
        }
        self.stored.push(table.clone());
        self.table = table.clone();
        Ok(())
    }
    fn self_test(&self) -> SelfTestReport {
        self.self_test
    }
    fn start_self_test(&mut self) -> Result<(), NackReason> {
        self.self_tests_started += 1;
        self.self_test.status = SelfTestStatus::Running;
        Ok(())
    }
    fn identify(&self) -> IdentifyReport {
        self.identify
    }
    fn start_identify(&mut self) -> Result<(), NackReason> {
        self.identifications_started += 1;
        self.identify.status = IdentifyStatus::Running;
        Ok(())
    }
    fn set_telemetry_period(&mut self, period_ms: u16) {
        self.telemetry_period_ms = Some(period_ms);
    }
}

fn ack(request: Request) -> Response {
    Response::Ack {
        request: request.id() as u8,
    }
}

fn nack(request: Request, reason: NackReason) -> Response {
    Response::Nack {
        request: request.id() as u8,
        reason,
    }
}

#[test]
fn every_request_gets_its_answer_and_one_command() {
    let mut device = Mock::new(State::Idle, 0.0);
    for request in every_request() {
        let before = device.commands.len();
        let response = answer_request(&mut device, &request);
        assert_eq!(device.commands.len(), before + 1, "{request:?}");
        assert_eq!(device.commands[before], request.command());
        let expected = match &request {
            Request::GetStatus => Response::Status(device.status),
            Request::ReadTuningTable => Response::TuningTable(device.table.clone()),
            Request::ReadSelfTest => Response::SelfTest(device.self_test),
            Request::ReadIdentify => Response::Identify(device.identify),
            Request::RunSelfTest => {
                // Started once; the next one is refused while it runs.
                device.self_test.status = SelfTestStatus::NotRun;
                ack(request.clone())
            }
            Request::RunIdentify => {
                device.identify.status = IdentifyStatus::NotRun;
                ack(request.clone())
            }
            // The mock has no capture buffer (the trait's defaults): only a
            // window of 0 (disarm) is taken, and nothing is recorded.
            Request::ArmCapture { window, .. } if *window > 0 => {
                nack(request.clone(), NackReason::BadValue)
            }
            Request::GetCapture => Response::Capture(device.capture_info()),
            Request::ReadCapture { first } => Response::CaptureRecords {
                first: *first,
                count: 0,
                records: [[0; RECORD_LEN]; RECORDS_PER_FRAME],
            },
            _ => ack(request.clone()),
        };
        assert_eq!(response, expected, "{request:?}");
    }
    assert_eq!(device.stored, vec![sample_table(), full_table()]);
    assert_eq!(device.self_tests_started, 1);
    assert_eq!(device.identifications_started, 1);
    assert_eq!(device.telemetry_period_ms, Some(50));
}

#[test]
fn a_refused_command_is_nacked_with_the_device_reason() {
    let mut device = Mock::new(State::Idle, 0.0);
    device.refuse_commands = Some(NackReason::Busy);
    let travel = Request::Command(Command::Travel {
        direction: Direction::Right,
        speed_rpm: 3000.0,
    });
    assert_eq!(
        answer_request(&mut device, &travel),
        nack(travel.clone(), NackReason::Busy)
    );
    // A heartbeat is still acknowledged.
    assert_eq!(
        answer_request(&mut device, &Request::Command(Command::Heartbeat)),
        ack(Request::Command(Command::Heartbeat))
    );
}

#[test]
fn the_table_is_written_only_with_the_motors_stopped() {
    let write = Request::WriteTuningTable(sample_table());
    // Driving states, whatever the speed.
    for state in [State::Starting, State::Running, State::Stopping] {
        let mut device = Mock::new(state, 0.0);
        assert_eq!(
            answer_request(&mut device, &write),
            nack(write.clone(), NackReason::NotStopped)
        );
        assert!(device.stored.is_empty());
    }
    // Idle or fault but still turning (coasting after a fault, or after a stop's
    // timeout), or an unknown (NaN) speed.
    for (state, speed) in [
        (State::Idle, 50.0),
        (State::Fault, -200.0),
        (State::Idle, f32::NAN),
    ] {
        let mut device = Mock::new(state, speed);
        assert_eq!(
            answer_request(&mut device, &write),
            nack(write.clone(), NackReason::NotStopped)
        );
        assert!(device.stored.is_empty());
    }
    // At rest, idle or in fault: stored.
    for state in [State::Idle, State::Fault] {
        let mut device = Mock::new(state, 3.0);
        assert_eq!(answer_request(&mut device, &write), ack(write.clone()));
        assert_eq!(device.stored, vec![sample_table()]);
    }
    // A failed write is reported and the table in use stays.
    let mut device = Mock::new(State::Idle, 0.0);
    device.store_fails = true;
    assert_eq!(
        answer_request(&mut device, &write),
        nack(write.clone(), NackReason::StorageFailed)
    );
    assert_eq!(device.table, TuningTable::default());
    // Not while a self-test or an identification runs.
    let mut device = Mock::new(State::Idle, 0.0);
    device.self_test.status = SelfTestStatus::Running;
    assert_eq!(
        answer_request(&mut device, &write),
        nack(write.clone(), NackReason::Busy)
    );
    let mut device = Mock::new(State::Idle, 0.0);
    device.identify.status = IdentifyStatus::Running;
    assert_eq!(
        answer_request(&mut device, &write),
        nack(write.clone(), NackReason::Busy)
    );
}

#[test]
fn the_self_test_and_the_identification_start_only_idle_at_rest() {
    for run in [Request::RunSelfTest, Request::RunIdentify] {
        let cases = [
            (State::Fault, 0.0, Some(NackReason::Faulted)),
            (State::Running, 3000.0, Some(NackReason::NotStopped)),
            (State::Stopping, 5.0, Some(NackReason::NotStopped)),
            (State::Idle, 80.0, Some(NackReason::NotStopped)),
            (State::Idle, 0.0, None),
        ];
        for (state, speed, refused) in cases {
            let mut device = Mock::new(state, speed);
            let expected = match refused {
                Some(reason) => nack(run.clone(), reason),
                None => ack(run.clone()),
            };
            assert_eq!(answer_request(&mut device, &run), expected, "{state:?}");
            let started = device.self_tests_started + device.identifications_started;
            assert_eq!(started, u32::from(refused.is_none()));
        }
        // Neither while the other runs.
        let mut device = Mock::new(State::Idle, 0.0);
        device.self_test.status = SelfTestStatus::Running;
        assert_eq!(
            answer_request(&mut device, &run),
            nack(run.clone(), NackReason::Busy)
        );
        let mut device = Mock::new(State::Idle, 0.0);
        device.identify.status = IdentifyStatus::Running;
        assert_eq!(
            answer_request(&mut device, &run),
            nack(run.clone(), NackReason::Busy)
        );
    }
}

#[test]
fn every_frame_from_the_host_is_answered_end_to_end() {
    // Host bytes -> device decoder -> answer -> device encoder -> host decoder:
    // one answer per frame, with the frame's sequence number, except the frame
    // whose header is corrupt.
    let mut host_bytes = Vec::new();
    host_bytes.extend(frame_of(&Request::Command(Command::Heartbeat), 1));
    host_bytes.extend(frame_of(&Request::GetStatus, 2));
    host_bytes.extend(encode_raw(0x7E, 3, &[])); // unknown id
    host_bytes.extend(encode_raw(0x03, 4, &[1, 2])); // Stop with a payload
    let mut corrupt = frame_of(&Request::Command(Command::Stop), 5);
    corrupt[3] ^= 0x10; // header CRC fails: no answer
    host_bytes.extend(corrupt);
    let mut bad_crc = frame_of(&Request::Command(Command::ResetFaults), 6);
    let last = bad_crc.len() - 1;
    bad_crc[last] ^= 0x80;
    host_bytes.extend(bad_crc);
    host_bytes.extend(frame_of(&Request::StreamTelemetry { period_ms: 1 }, 7));
    host_bytes.extend(frame_of(
        &Request::Command(Command::Travel {
            direction: Direction::Left,
            speed_rpm: 2500.0,
        }),
        8,
    ));

    let mut device = Mock::new(State::Idle, 0.0);
    let mut decoder = Decoder::new();
    let mut answer_bytes = Vec::new();
    let mut input = &host_bytes[..];
    while let Some(event) = decoder.decode(&mut input) {
        if let Some((seq, response)) = answer_event(&mut device, event) {
            answer_bytes.extend(frame_of(&response, seq));
        }
    }

    let mut host = Decoder::new();
    let answers: Vec<(u16, Response)> = events(&mut host, &answer_bytes)
        .into_iter()
        .map(|e| {
            let (id, seq, payload) = e.unwrap();
            let frame = Frame {
                id,
                seq,
                payload: &payload,
            };
            (seq, Response::parse(&frame).unwrap())
        })
        .collect();
    let expected = vec![
        (1, ack(Request::Command(Command::Heartbeat))),
        (2, Response::Status(device.status)),
        (
            3,
            Response::Nack {
                request: 0x7E,
                reason: NackReason::UnknownMessage,
            },
        ),
        (
            4,
            nack(Request::Command(Command::Stop), NackReason::BadLength),
        ),
        (
            6,
            nack(Request::Command(Command::ResetFaults), NackReason::BadCrc),
        ),
        (
            7,
            nack(
                Request::StreamTelemetry { period_ms: 1 },
                NackReason::BadValue,
            ),
        ),
        (
            8,
            ack(Request::Command(Command::Travel {
                direction: Direction::Left,
                speed_rpm: 2500.0,
            })),
        ),
    ];
    assert_eq!(answers, expected);
    // Every valid, well-formed request handed one command to the controller.
    assert_eq!(
        device.commands,
        vec![
            Command::Heartbeat,
            Command::Heartbeat,
            Command::Travel {
                direction: Direction::Left,
                speed_rpm: 2500.0
            }
        ]
    );
}

fn encode_raw(id: u8, seq: u16, payload: &[u8]) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode_frame(id, seq, payload, &mut buf).unwrap();
    buf[..n].to_vec()
}
