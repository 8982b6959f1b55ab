//! Instruction count of encoding and decoding frames and flash records, for
//! callgrind (repeatable whatever the machine's load, unlike wall time):
//!
//! ```text
//! cargo build --release -p shared --example frame_instructions
//! valgrind --tool=callgrind target/release/examples/frame_instructions 20000
//! ```
//!
//! One iteration encodes and decodes the largest request (`WriteTuningTable` with
//! 32 rows, a 399-byte frame) and a status report (82 bytes), then encodes and
//! parses a flash record (428 bytes): every CRC the link and the storage compute,
//! 1 794 bytes through CRC-32 and 32 through CRC-16 an iteration. Runs N iterations
//! (argument, default 20000); divide callgrind's total by N.
use std::hint::black_box;

use shared::controller::{State, TuningTable};
use shared::protocol::link::no_telemetry;
use shared::protocol::{encode, Decoder, Request, Response, StatusReport, MAX_FRAME};
use shared::storage::{encode_record, parse_record, Record};

fn main() {
    let runs: u32 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(20_000);
    let rows: Vec<(f32, f32, f32)> = (0..32)
        .map(|i| (100.0 * i as f32, 80.0 + i as f32, 280.0 - i as f32))
        .collect();
    let table = TuningTable::from_rows(&rows).expect("a valid table");
    let request = Request::WriteTuningTable(table.clone());
    let status = Response::Status(StatusReport {
        uptime_ms: 123_456,
        state: State::Running,
        faults: Default::default(),
        telemetry: no_telemetry(),
        rx_dropped: 0,
    });
    let record = Record {
        tuning: table,
        self_test: None,
        identity: None,
    };

    let mut out = [0u8; MAX_FRAME];
    let mut decoder = Decoder::new();
    let mut bytes = 0usize;
    let mut frames = 0u32;
    for k in 0..runs {
        // The two frames: encode, then decode every byte.
        let seq = k as u16;
        for n in [
            encode(black_box(&request), seq, &mut out).unwrap_or(0),
            encode(black_box(&status), seq, &mut out).unwrap_or(0),
        ] {
            bytes += n;
            let mut input = out.get(..n).unwrap_or(&[]);
            while let Some(event) = decoder.decode(black_box(&mut input)) {
                frames += u32::from(event.is_ok());
            }
        }
        // The flash record: encode, then parse (CRC first).
        let stored = encode_record(black_box(&record), k);
        frames += u32::from(parse_record(black_box(&stored)).is_some());
    }
    println!(
        "{runs} iterations, {} frame bytes each, {frames} frames and records decoded",
        bytes / runs.max(1) as usize
    );
}
