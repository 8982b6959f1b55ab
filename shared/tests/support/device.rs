//! The device's end of the link as the firmware holds it (a [`Link`], its state and
//! a flash), fed bytes, and what it sends decoded.

use std::collections::VecDeque;

use shared::controller::{Faults, State, TuningTable};
use shared::protocol::link::{no_telemetry, Link, LinkState};
use shared::protocol::{Decoder, Message, Response, StatusReport};
use shared::storage::SimFlash;

/// A link with its state and flash, as the firmware holds them.
pub struct Device {
    pub link: Link,
    pub state: LinkState,
    pub flash: SimFlash,
    pub rx: VecDeque<u8>,
}

impl Device {
    pub fn new() -> Device {
        Device {
            link: Link::new(),
            state: LinkState::new(
                StatusReport {
                    uptime_ms: 0,
                    state: State::Idle,
                    faults: Faults::NONE,
                    telemetry: no_telemetry(),
                    rx_dropped: 0,
                },
                TuningTable::default_offsets(),
                None,
            ),
            flash: SimFlash::new(),
            rx: VecDeque::new(),
        }
    }

    /// Receive `bytes`, then run the link task at `now_ms` until it has taken
    /// every byte; the bytes it sent.
    pub fn exchange(&mut self, bytes: &[u8], now_ms: u32) -> Vec<u8> {
        self.rx.extend(bytes.iter().copied());
        let mut out = Vec::new();
        let Device {
            link,
            state,
            flash,
            rx,
        } = self;
        loop {
            let busy = link.poll(
                || rx.pop_front(),
                now_ms,
                &mut *state,
                flash,
                |frame| out.extend_from_slice(frame),
            );
            if !busy {
                break;
            }
        }
        out
    }
}

/// Every frame in `bytes` as `(seq, response)`; panics on anything else.
pub fn responses(bytes: &[u8]) -> Vec<(u16, Response)> {
    let mut decoder = Decoder::new();
    let mut input = bytes;
    let mut out = Vec::new();
    while let Some(event) = decoder.decode(&mut input) {
        let frame = event.expect("the device sends valid frames only");
        out.push((frame.seq, Response::parse(&frame).expect("a response")));
    }
    assert_eq!(decoder.held(), 0, "a frame cut short");
    out
}
