//! The scripted host's end of the link: requests encoded into frames, pushed in
//! bytes through the firmware's real [`Link::poll`] (the bytes the USART would
//! deliver), and the frames it sends back decoded and parsed as a host would.

use heapless::Vec;
use shared::protocol::link::{Link, LinkState};
use shared::protocol::{encode, Decoder, Message, Request, Response, MAX_FRAME};
use shared::storage::SimFlash;

/// Most answers one exchange collects.
const MAX_ANSWERS: usize = 4;

/// The device side an exchange runs on: the link task's state and flash, and the
/// state shared with the control task (behind its lock).
pub struct Device<'a, L: rtic::Mutex<T = LinkState>> {
    /// The link task's own state.
    pub link: &'a mut Link,
    /// The parameter flash.
    pub flash: &'a mut SimFlash,
    /// The state shared with the control task.
    pub state: &'a mut L,
    /// Uptime now, ms.
    pub now_ms: u32,
}

/// The unsolicited telemetry frames received.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TelemetryLog {
    /// Frames received.
    pub frames: u32,
    /// Sequence number of the last one.
    pub last_seq: u16,
    /// Its uptime, ms.
    pub last_uptime_ms: u32,
    /// Frames whose sequence number did not follow the previous one's.
    pub seq_gaps: u32,
    /// Smallest uptime step between consecutive frames, ms.
    pub min_step_ms: u32,
}

/// The host: its sequence counter, its decoder, what came back.
pub struct Host {
    /// Sequence number of the next request.
    seq: u16,
    /// Decodes what the device sends.
    decoder: Decoder,
    /// Answers (not telemetry) of the current exchange: sequence number, message.
    answers: Vec<(u16, Response), MAX_ANSWERS>,
    /// Frames that did not parse as responses.
    pub bad_frames: u32,
    /// The telemetry stream.
    pub telemetry: TelemetryLog,
}

impl Default for Host {
    fn default() -> Self {
        Host::new()
    }
}

impl Host {
    /// A host that has sent nothing.
    pub const fn new() -> Self {
        Host {
            seq: 1,
            decoder: Decoder::new(),
            answers: Vec::new(),
            bad_frames: 0,
            telemetry: TelemetryLog {
                frames: 0,
                last_seq: 0,
                last_uptime_ms: 0,
                seq_gaps: 0,
                min_step_ms: u32::MAX,
            },
        }
    }

    /// Encode `request` with the next sequence number into `out`; `(seq, length)`.
    pub fn frame(&mut self, request: &Request, out: &mut [u8; MAX_FRAME]) -> (u16, usize) {
        let seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        let len = encode(request, seq, out).unwrap_or(0);
        (seq, len)
    }

    /// The answers of the last exchange.
    pub fn answers(&self) -> &[(u16, Response)] {
        &self.answers
    }

    /// Send `request`; its one answer, if exactly one came with its sequence number.
    pub fn request<L: rtic::Mutex<T = LinkState>>(
        &mut self,
        request: &Request,
        device: &mut Device<'_, L>,
    ) -> Option<Response> {
        let mut out = [0u8; MAX_FRAME];
        let (seq, len) = self.frame(request, &mut out);
        self.exchange(out.get(..len).unwrap_or(&[]), device);
        match self.answers.as_slice() {
            [(s, response)] if *s == seq => Some(response.clone()),
            _ => None,
        }
    }

    /// Push `bytes` through the link and collect what comes back: the answers
    /// (returned), and telemetry frames (counted).
    pub fn exchange<L: rtic::Mutex<T = LinkState>>(
        &mut self,
        bytes: &[u8],
        device: &mut Device<'_, L>,
    ) -> &[(u16, Response)] {
        self.answers.clear();
        let mut input = bytes.iter();
        // One pass takes at most POLL_CHUNK bytes; one more pass with nothing new.
        loop {
            let decoder = &mut self.decoder;
            let answers = &mut self.answers;
            let telemetry = &mut self.telemetry;
            let bad = &mut self.bad_frames;
            let state = &mut *device.state;
            let busy = device.link.poll(
                || input.next().copied(),
                device.now_ms,
                crate::port::Locked(state),
                &mut *device.flash,
                |frame_bytes| receive(decoder, answers, telemetry, bad, frame_bytes),
            );
            if !busy {
                break;
            }
        }
        &self.answers
    }
}

/// Decode the bytes the device sent: answers into `answers`, telemetry into
/// `telemetry`, anything else counted in `bad`.
fn receive(
    decoder: &mut Decoder,
    answers: &mut Vec<(u16, Response), MAX_ANSWERS>,
    telemetry: &mut TelemetryLog,
    bad: &mut u32,
    mut bytes: &[u8],
) {
    while let Some(event) = decoder.decode(&mut bytes) {
        let Ok(frame) = event else {
            *bad += 1;
            continue;
        };
        match Response::parse(&frame) {
            Ok(Response::Telemetry(report)) => {
                let t = &mut *telemetry;
                if t.frames > 0 {
                    if frame.seq != t.last_seq.wrapping_add(1) {
                        t.seq_gaps += 1;
                    }
                    t.min_step_ms = t
                        .min_step_ms
                        .min(report.uptime_ms.wrapping_sub(t.last_uptime_ms));
                }
                t.frames += 1;
                t.last_seq = frame.seq;
                t.last_uptime_ms = report.uptime_ms;
            }
            Ok(response) => {
                if answers.push((frame.seq, response)).is_err() {
                    *bad += 1;
                }
            }
            Err(_) => *bad += 1,
        }
    }
}
