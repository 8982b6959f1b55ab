//! The link fuzzed, bounded and seeded so that it runs in CI like any test
//! (`VIBRO_FUZZ_ITERS` cases, 30 000 by default, from seed `VIBRO_FUZZ_SEED`; a long
//! campaign is described in docs/development.md, "Fuzzing"). Each case is a stream
//! of pieces: noise rich in sync bytes, intact frames (requests, and raw frames of
//! any id and payload), duplicated and back-to-back frames, and mutated frames (bits
//! flipped, cut short, a length that lies under a header CRC that matches it,
//! another protocol version). The stream goes through the frame decoder, fed in
//! random chunks, and through the device's end of the link. Checked:
//!
//! - nothing panics;
//! - every frame the decoder accepts is, byte for byte, a well-formed frame that is
//!   in the stream: none whose CRC is wrong;
//! - every intact frame of the stream is found, in order, once the line goes quiet;
//! - the device answers exactly what the decoder saw, by the answer rule (one
//!   answer to each frame's sequence number, the Nack of a rejected frame whose
//!   header was right, nothing for a broken header), and everything it sends is
//!   whole, valid response frames.

mod support;

use shared::codec::crc::crc16_ccitt_false;
use shared::controller::{Command, Direction};
use shared::protocol::{
    answer_error, Decoder, Request, Response, HEADER_LEN, MAX_PAYLOAD, PROTOCOL_VERSION, SYNC,
};
use support::device::{responses, Device};
use support::frames::{feed, finish, frame_bytes, raw_frame, Event};
use support::fuzz::{self, Rng};

/// Cases of a run by default: about a second at the test profile.
const CASES: u64 = 30_000;

/// A frame as the decoder gives it: id, sequence number, payload.
type Found = (u8, u16, Vec<u8>);

/// A random request, valid or not in its values (a NaN speed, an offset far out).
fn request(rng: &mut Rng) -> Request {
    let speed = |rng: &mut Rng| match rng.below(8) {
        0 => f32::NAN,
        1 => rng.uniform(-1e6, 1e6),
        _ => rng.uniform(0.0, 5000.0),
    };
    match rng.below(11) {
        0 => Request::Command(Command::Heartbeat),
        1 => Request::GetStatus,
        2 => Request::Command(Command::Stop),
        3 => Request::Command(Command::Travel {
            direction: if rng.one_in(2) {
                Direction::Right
            } else {
                Direction::Left
            },
            speed_rpm: speed(rng),
        }),
        4 => Request::Command(Command::HoldOffset {
            speed_rpm: speed(rng),
            offset_deg: rng.uniform(-720.0, 720.0),
        }),
        5 => Request::Command(Command::ResetFaults),
        6 => Request::ReadTuningTable,
        7 => Request::WriteTuningTable(fuzz::table(rng)),
        8 => Request::RunSelfTest,
        9 => Request::ReadSelfTest,
        _ => Request::StreamTelemetry {
            period_ms: rng.range(0, 1000) as u16,
        },
    }
}

/// A random well-formed frame: mostly a request, else any id with any payload.
fn any_frame(rng: &mut Rng) -> Vec<u8> {
    let seq = rng.next_u64() as u16;
    if rng.one_in(4) {
        let len = if rng.one_in(4) {
            rng.range(0, MAX_PAYLOAD)
        } else {
            rng.range(0, 16)
        };
        let payload: Vec<u8> = (0..len).map(|_| rng.byte()).collect();
        raw_frame(rng.byte(), seq, &payload)
    } else {
        frame_bytes(&request(rng), seq)
    }
}

/// Noise: 0 to 48 bytes, a quarter each sync bytes, version bytes and any byte.
fn noise(rng: &mut Rng) -> Vec<u8> {
    (0..rng.range(0, 48))
        .map(|_| match rng.below(4) {
            0 => SYNC[0],
            1 => SYNC[1],
            2 => PROTOCOL_VERSION,
            _ => rng.byte(),
        })
        .collect()
}

/// Recompute a frame's header CRC after its header was changed, so the change
/// passes the header check.
fn reseal_header(frame: &mut [u8]) {
    let crc = crc16_ccitt_false(&frame[..HEADER_LEN - 2]).to_le_bytes();
    frame[HEADER_LEN - 2..HEADER_LEN].copy_from_slice(&crc);
}

/// `frame` damaged one way: bits flipped, cut at least 4 bytes short (cut 1 to 3
/// short, the next frame's first bytes can complete it, rightly, into a valid frame
/// that takes the next one's sync), a length that lies under a matching header
/// CRC, or another version under a matching header CRC.
fn mutated(rng: &mut Rng, mut frame: Vec<u8>) -> Vec<u8> {
    match rng.below(4) {
        0 => {
            for _ in 0..rng.range(1, 4) {
                let bit = rng.below(frame.len() * 8);
                frame[bit / 8] ^= 1 << (bit % 8);
            }
        }
        1 => frame.truncate(rng.range(0, frame.len() - 4)),
        2 => {
            let real = u16::from_le_bytes([frame[6], frame[7]]);
            let lie = match rng.below(3) {
                0 => rng.range(0, MAX_PAYLOAD) as u16,
                1 => rng.range(MAX_PAYLOAD + 1, 2 * MAX_PAYLOAD) as u16,
                _ => rng.next_u64() as u16,
            };
            let lie = if lie == real { real ^ 1 } else { lie };
            frame[6..8].copy_from_slice(&lie.to_le_bytes());
            reseal_header(&mut frame);
        }
        _ => {
            frame[2] = PROTOCOL_VERSION.wrapping_add(rng.range(1, 255) as u8);
            reseal_header(&mut frame);
        }
    }
    frame
}

/// A frame's id, sequence number and payload, read from its bytes.
fn fields(frame: &[u8]) -> Found {
    let seq = u16::from_le_bytes([frame[4], frame[5]]);
    (frame[3], seq, frame[HEADER_LEN..frame.len() - 4].to_vec())
}

/// One case's stream, and the intact frames in it in order.
fn stream(rng: &mut Rng) -> (Vec<u8>, Vec<Found>) {
    let mut bytes = Vec::new();
    let mut intact = Vec::new();
    for _ in 0..rng.range(1, 12) {
        match rng.below(6) {
            0 => bytes.extend(noise(rng)),
            1 => {
                let frame = any_frame(rng);
                bytes.extend(mutated(rng, frame));
            }
            // The same frame twice, or two frames back to back.
            2 => {
                let first = any_frame(rng);
                let second = if rng.one_in(2) {
                    first.clone()
                } else {
                    any_frame(rng)
                };
                for frame in [first, second] {
                    intact.push(fields(&frame));
                    bytes.extend(frame);
                }
            }
            _ => {
                let frame = any_frame(rng);
                intact.push(fields(&frame));
                bytes.extend(frame);
            }
        }
    }
    bytes.extend(noise(rng));
    (bytes, intact)
}

/// The frames among `events`.
fn frames(events: &[Event]) -> Vec<Found> {
    events.iter().filter_map(|e| e.clone().ok()).collect()
}

#[test]
fn the_decoder_and_the_device_survive_noise_and_mutated_frames() {
    fuzz::run(CASES, |rng| {
        let (bytes, intact) = stream(rng);

        // The decoder, in random chunks.
        let chunks: Vec<usize> = (0..rng.range(1, 6)).map(|_| rng.range(1, 80)).collect();
        let mut decoder = Decoder::new();
        let live = feed(&mut decoder, &bytes, &chunks);
        let mut events = live.clone();
        events.extend(finish(&mut decoder));

        // Every frame accepted is well formed and in the stream.
        let found = frames(&events);
        for (id, seq, payload) in &found {
            assert!(payload.len() <= MAX_PAYLOAD);
            let again = raw_frame(*id, *seq, payload);
            assert!(
                bytes.windows(again.len()).any(|w| w == again.as_slice()),
                "accepted a frame that is not in the stream: id {id:#04x}, seq {seq}"
            );
        }
        // Every intact frame is found, in order.
        let mut rest = found.iter();
        for frame in &intact {
            assert!(
                rest.any(|f| f == frame),
                "lost the frame with id {:#04x}, seq {}",
                frame.0,
                frame.1
            );
        }

        // The device: answers by the answer rule to what the decoder saw while the
        // bytes came (the link gives up on a frame only after a silence, and the
        // clock stands still here).
        let mut device = Device::new();
        let answers = responses(&device.exchange(&bytes, 0));
        let expected: Vec<(u16, Option<Response>)> = live
            .iter()
            .filter_map(|event| match event {
                Ok((_, seq, _)) => Some((*seq, None)),
                Err(error) => answer_error(error).map(|(seq, nack)| (seq, Some(nack))),
            })
            .collect();
        assert_eq!(answers.len(), expected.len(), "one answer per event");
        for ((seq, response), (want_seq, want)) in answers.iter().zip(&expected) {
            assert_eq!(seq, want_seq);
            if let Some(want) = want {
                assert_eq!(response, want);
            }
        }
    });
}
