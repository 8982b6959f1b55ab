//! The host's end of the link: requests numbered, sent, sent again after
//! [`ANSWER_TIMEOUT_MS`] with the same sequence number ([`STORE_ANSWER_TIMEOUT_MS`]
//! for a table write), answers matched by sequence number, unsolicited telemetry
//! frames kept aside, everything else (garbage, corrupt frames, stale answers to an
//! earlier try) dropped.
//!
//! An answer at the request's sequence number must also be an answer to that
//! request ([`answers`]): an Ack or a Nack naming the request's id, or the report
//! the request asks for. Anything else there is [`LinkError::WrongAnswer`]: the
//! device did not say that it carried out what was asked, so the host never
//! reports it as accepted.

use std::collections::VecDeque;
use std::fmt;
use std::time::{Duration, Instant};

use shared::protocol::{
    encode, Decoder, Message, MessageId, NackReason, Request, Response, StatusReport,
    ANSWER_TIMEOUT_MS, MAX_FRAME, STORE_ANSWER_TIMEOUT_MS,
};

use super::pipe::Port;

/// Tries of a request after the first, by default: six tries of 100 ms fit in the
/// controller's 0.5 s link timeout plus one.
pub const DEFAULT_RETRIES: u32 = 5;

/// Why a request got no usable answer.
#[derive(Debug)]
pub enum LinkError {
    /// No answer to any try.
    NoAnswer {
        /// The request's name.
        request: &'static str,
        /// Tries sent.
        tries: u32,
        /// Wait after each, ms.
        timeout_ms: u32,
        /// What came back meanwhile: nothing at all (a silent line: the port,
        /// the power, the firmware) or bytes that made no answer (a noisy line).
        heard: Heard,
    },
    /// The answer at the request's sequence number answers something else (an
    /// Ack for another request, a report that was not asked for).
    WrongAnswer {
        /// The request's name.
        request: &'static str,
        /// What came instead, for people ("an Ack for Heartbeat").
        answer: String,
    },
    /// The port failed (closed, unplugged).
    Io(std::io::Error),
}

impl fmt::Display for LinkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkError::NoAnswer {
                request,
                tries,
                timeout_ms,
                heard,
            } if heard.bytes == 0 => write!(
                f,
                "no answer from the device to {request} after {} of {timeout_ms} ms, \
                 and no byte at all (is the port right, the device powered, its firmware running \
                 at 115200 baud?)",
                tries_text(*tries)
            ),
            LinkError::NoAnswer {
                request,
                tries,
                timeout_ms,
                heard,
            } => write!(
                f,
                "no answer from the device to {request} after {} of {timeout_ms} ms, \
                 though {} bytes came back ({} rejected as corrupt{}): a noisy line (a loose, \
                 long or unshielded cable, interference, or another baud rate than 115200; \
                 more --retries may get through)",
                tries_text(*tries),
                heard.bytes,
                count(heard.rejected, "frame"),
                match heard.stale {
                    0 => String::new(),
                    n => format!(", {} to an earlier request", count(n, "answer")),
                }
            ),
            LinkError::WrongAnswer { request, answer } => write!(
                f,
                "the device answered {request} with {answer}, not an answer to {request} \
                 (it may not have carried it out)"
            ),
            LinkError::Io(e) => write!(f, "the port failed: {e}"),
        }
    }
}

/// What came back while a request waited for its answer in vain.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Heard {
    /// Bytes read.
    pub bytes: u64,
    /// Frames and candidates the decoder rejected (corrupt).
    pub rejected: u32,
    /// Intact frames that answer another sequence number.
    pub stale: u32,
}

/// `1 frame`, `3 frames`.
fn count(n: u32, what: &str) -> String {
    crate::numbers::count(n as usize, what)
}

/// `1 try`, `3 tries`.
fn tries_text(n: u32) -> String {
    match n {
        1 => "1 try".to_string(),
        n => format!("{n} tries"),
    }
}

/// Counters of a client (for `--verbose` reports and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClientStats {
    /// Requests sent again after a timeout or a `Nack(BadCrc)`.
    pub retries: u32,
    /// Frames and candidates rejected by the decoder (corruption on the line).
    pub rejected: u32,
    /// Answers to another sequence number (late answers to an earlier try).
    pub stale: u32,
}

/// A device at the end of a [`Port`].
pub struct Client {
    port: Box<dyn Port>,
    decoder: Decoder,
    /// The last sequence number used.
    seq: u16,
    retries: u32,
    /// Telemetry frames received, oldest first, with when they came.
    telemetry: VecDeque<(Instant, StatusReport)>,
    stats: ClientStats,
    /// Bytes read since the client was made.
    bytes: u64,
}

/// The name of a request for messages.
pub fn request_name(request: &Request) -> &'static str {
    id_name(request.id())
}

/// The name of a request id for messages.
fn id_name(id: MessageId) -> &'static str {
    match id {
        MessageId::Heartbeat => "Heartbeat",
        MessageId::GetStatus => "GetStatus",
        MessageId::Stop => "Stop",
        MessageId::Travel => "Travel",
        MessageId::HoldOffset => "HoldOffset",
        MessageId::ResetFaults => "ResetFaults",
        MessageId::ReadTuningTable => "ReadTuningTable",
        MessageId::WriteTuningTable => "WriteTuningTable",
        MessageId::RunSelfTest => "RunSelfTest",
        MessageId::ReadSelfTest => "ReadSelfTest",
        MessageId::StreamTelemetry => "StreamTelemetry",
        MessageId::RunIdentify => "RunIdentify",
        MessageId::ReadIdentify => "ReadIdentify",
        MessageId::ArmCapture => "ArmCapture",
        MessageId::GetCapture => "GetCapture",
        MessageId::ReadCapture => "ReadCapture",
        _ => "a response",
    }
}

/// The request a raw id byte of an Ack or Nack names, for messages.
fn answered_name(id: u8) -> String {
    match MessageId::from_u8(id).filter(|id| id.is_request()) {
        Some(id) => id_name(id).to_string(),
        None => format!("an unknown request (id 0x{id:02X})"),
    }
}

/// A response, for messages: "an Ack for Heartbeat", "a status report".
pub fn answer_text(response: &Response) -> String {
    match response {
        Response::Ack { request } => format!("an Ack for {}", answered_name(*request)),
        Response::Nack { request, reason } => format!(
            "a Nack for {} ({})",
            answered_name(*request),
            nack_text(*reason)
        ),
        Response::Status(_) => "a status report".into(),
        Response::TuningTable(_) => "a tuning table".into(),
        Response::SelfTest(_) => "a self-test report".into(),
        Response::Identify(_) => "an identification report".into(),
        Response::Capture(_) => "a capture's status".into(),
        Response::CaptureRecords { .. } => "a capture's records".into(),
        Response::Telemetry(_) => "a telemetry frame".into(),
    }
}

/// Whether `response` answers `request` (the device's answer rule,
/// `shared::protocol::answer_request`): a Nack naming the request's id; an Ack naming it,
/// for the requests answered by Ack; the report asked for by `GetStatus`,
/// `ReadTuningTable`, `ReadSelfTest`, `ReadIdentify` and `GetCapture`, and
/// the records from the first asked for by `ReadCapture`.
pub fn answers(request: &Request, response: &Response) -> bool {
    let asked = request.id() as u8;
    let wants_report = matches!(
        request,
        Request::GetStatus
            | Request::ReadTuningTable
            | Request::ReadSelfTest
            | Request::ReadIdentify
            | Request::GetCapture
            | Request::ReadCapture { .. }
    );
    match response {
        Response::Nack { request: id, .. } => *id == asked,
        Response::Ack { request: id } => *id == asked && !wants_report,
        Response::Status(_) => matches!(request, Request::GetStatus),
        Response::TuningTable(_) => matches!(request, Request::ReadTuningTable),
        Response::SelfTest(_) => matches!(request, Request::ReadSelfTest),
        Response::Identify(_) => matches!(request, Request::ReadIdentify),
        Response::Capture(_) => matches!(request, Request::GetCapture),
        Response::CaptureRecords { first, .. } => {
            matches!(request, Request::ReadCapture { first: f } if f == first)
        }
        Response::Telemetry(_) => false,
    }
}

/// What a Nack reason means, for people.
pub fn nack_text(reason: NackReason) -> &'static str {
    match reason {
        NackReason::UnknownMessage => "unknown message (another protocol version?)",
        NackReason::BadLength => "bad payload length (another protocol version?)",
        NackReason::BadValue => "a value out of its domain",
        NackReason::BadCrc => "the frame arrived corrupted",
        NackReason::TooLong => "frame too long",
        NackReason::BadVersion => "another protocol version",
        NackReason::NotStopped => {
            "the motors must be stopped (state idle or fault, rotors at rest)"
        }
        NackReason::Faulted => "a fault is latched: reset it first",
        NackReason::StorageFailed => {
            "the flash write failed; the previous table is still in use and in flash"
        }
        NackReason::Busy => "busy: a self-test or an identification is running",
    }
}

impl Client {
    /// A client on `port`, trying each request `1 + retries` times.
    pub fn new(port: Box<dyn Port>, retries: u32) -> Client {
        Client {
            port,
            decoder: Decoder::new(),
            // Start anywhere: a device that still holds an answer of an earlier
            // session's sequence number 1 is then not mistaken for ours.
            seq: seed_seq(),
            retries,
            telemetry: VecDeque::new(),
            stats: ClientStats::default(),
            bytes: 0,
        }
    }

    /// The counters so far.
    pub fn stats(&self) -> ClientStats {
        self.stats
    }

    /// Take the telemetry frames received so far.
    pub fn take_telemetry(&mut self) -> Vec<(Instant, StatusReport)> {
        self.telemetry.drain(..).collect()
    }

    /// Send `request` and wait for its answer, trying again after each timeout
    /// and after a `Nack(BadCrc)` (the request was corrupted on the way). The
    /// answer returned [`answers`] the request; one that does not is
    /// [`LinkError::WrongAnswer`].
    pub fn request(&mut self, request: &Request) -> Result<Response, LinkError> {
        self.seq = self.seq.wrapping_add(1);
        let seq = self.seq;
        let mut frame = [0u8; MAX_FRAME];
        // Every request fits a frame (the table has at most 32 rows).
        let len = encode(request, seq, &mut frame).unwrap_or(0);
        let timeout_ms = if matches!(request, Request::WriteTuningTable(_)) {
            STORE_ANSWER_TIMEOUT_MS
        } else {
            ANSWER_TIMEOUT_MS
        };
        let tries = 1 + self.retries;
        let before = (self.bytes, self.stats);
        for attempt in 0..tries {
            if attempt > 0 {
                self.stats.retries += 1;
            }
            self.port.write_all(&frame[..len]).map_err(LinkError::Io)?;
            let deadline = Instant::now() + Duration::from_millis(u64::from(timeout_ms));
            match self.wait_answer(seq, deadline)? {
                Some(response) if !answers(request, &response) => {
                    return Err(LinkError::WrongAnswer {
                        request: request_name(request),
                        answer: answer_text(&response),
                    })
                }
                Some(Response::Nack {
                    reason: NackReason::BadCrc,
                    ..
                }) => continue,
                Some(response) => return Ok(response),
                None => continue,
            }
        }
        Err(LinkError::NoAnswer {
            request: request_name(request),
            tries,
            timeout_ms,
            heard: Heard {
                bytes: self.bytes - before.0,
                rejected: self.stats.rejected - before.1.rejected,
                stale: self.stats.stale - before.1.stale,
            },
        })
    }

    /// Read until the answer to `seq` or `deadline`, keeping telemetry.
    fn wait_answer(&mut self, seq: u16, deadline: Instant) -> Result<Option<Response>, LinkError> {
        loop {
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            if let Some(answer) = self.read_some(deadline - now, Some(seq))? {
                return Ok(Some(answer));
            }
        }
    }

    /// Read and decode for up to `wait` (telemetry only, no answer awaited).
    pub fn pump(&mut self, wait: Duration) -> Result<(), LinkError> {
        let deadline = Instant::now() + wait;
        loop {
            let now = Instant::now();
            if now >= deadline {
                return Ok(());
            }
            self.read_some(deadline - now, None)?;
        }
    }

    /// One read of at most `wait`; the answer to `seq` if it came.
    fn read_some(
        &mut self,
        wait: Duration,
        seq: Option<u16>,
    ) -> Result<Option<Response>, LinkError> {
        let mut buf = [0u8; 512];
        let n = self
            .port
            .read_timeout(&mut buf, wait.min(Duration::from_millis(20)))
            .map_err(LinkError::Io)?;
        self.bytes += n as u64;
        let mut input = &buf[..n];
        let mut answer = None;
        while let Some(event) = self.decoder.decode(&mut input) {
            let Ok(frame) = event else {
                self.stats.rejected += 1;
                continue;
            };
            let frame_seq = frame.seq;
            match Response::parse(&frame) {
                Ok(Response::Telemetry(report)) => {
                    self.telemetry.push_back((Instant::now(), report));
                }
                Ok(response) if Some(frame_seq) == seq && answer.is_none() => {
                    answer = Some(response);
                }
                Ok(_) => self.stats.stale += 1,
                Err(_) => self.stats.rejected += 1,
            }
        }
        Ok(answer)
    }
}

/// A sequence number to start from: from the clock, so that two runs rarely
/// start at the same number.
fn seed_seq() -> u16 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| (d.subsec_nanos() >> 10) as u16)
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use std::collections::VecDeque;
    use std::io;

    use super::*;
    use crate::device::sim::{Noise, SimDevice};
    use shared::controller::State;

    /// The simulated device at the end of an in-memory line, a control tick per
    /// read.
    struct SimPort {
        device: SimDevice,
        pending: VecDeque<u8>,
    }

    impl Port for SimPort {
        fn read_timeout(&mut self, buf: &mut [u8], _timeout: Duration) -> io::Result<usize> {
            self.device.tick();
            let out = self.device.receive();
            self.pending.extend(out);
            let n = buf.len().min(self.pending.len());
            for (b, p) in buf.iter_mut().zip(self.pending.drain(..n)) {
                *b = p;
            }
            if n == 0 {
                std::thread::sleep(Duration::from_millis(1));
            }
            Ok(n)
        }

        fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
            self.device.push_rx(bytes);
            Ok(())
        }
    }

    fn client(noise: Noise, retries: u32) -> Client {
        Client::new(
            Box::new(SimPort {
                device: SimDevice::new(None, noise),
                pending: VecDeque::new(),
            }),
            retries,
        )
    }

    #[test]
    fn answers_come_through_a_corrupting_line_by_retrying() {
        // One bit flipped in every 97th byte either way: most status frames (74
        // bytes) are hit, never four in a row; garbage before every other frame.
        let mut c = client(
            Noise {
                flip_every: Some(97),
                garbage_every: Some(2),
            },
            10,
        );
        for _ in 0..8 {
            match c.request(&Request::GetStatus) {
                Ok(Response::Status(s)) => assert_eq!(s.state, State::Idle),
                other => panic!("{other:?}"),
            }
        }
        let stats = c.stats();
        assert!(stats.retries >= 3, "{stats:?}");
        assert!(stats.rejected >= 3, "{stats:?}");
    }

    /// A line so noisy that no status report (74 bytes) arrives whole: a bit
    /// flipped in every 12th byte. The bytes came, so the message says the line
    /// is noisy, not that the port may be wrong (issue 23).
    #[test]
    fn a_noisy_line_is_not_a_silent_one() {
        let mut c = client(
            Noise {
                flip_every: Some(12),
                garbage_every: None,
            },
            1,
        );
        let e = c.request(&Request::GetStatus).unwrap_err();
        let LinkError::NoAnswer { heard, .. } = &e else {
            panic!("{e:?}");
        };
        assert!(heard.bytes > 0 && heard.rejected > 0, "{heard:?}");
        let text = e.to_string();
        assert!(
            text.starts_with(
                "no answer from the device to GetStatus after 2 tries of 100 ms, though "
            ),
            "{text}"
        );
        assert!(text.contains("a noisy line"), "{text}");
        assert!(!text.contains("is the port right"), "{text}");
    }

    /// A port that never sends a byte.
    struct Silent;

    impl Port for Silent {
        fn read_timeout(&mut self, _: &mut [u8], timeout: Duration) -> io::Result<usize> {
            std::thread::sleep(timeout.min(Duration::from_millis(5)));
            Ok(0)
        }

        fn write_all(&mut self, _: &[u8]) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_silent_line_asks_for_the_port_and_the_power() {
        let e = Client::new(Box::new(Silent), 0)
            .request(&Request::GetStatus)
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "no answer from the device to GetStatus after 1 try of 100 ms, and no byte at all \
             (is the port right, the device powered, its firmware running at 115200 baud?)"
        );
    }

    #[test]
    fn telemetry_is_kept_apart_from_answers() {
        let mut c = client(Noise::default(), 0);
        assert!(matches!(
            c.request(&Request::StreamTelemetry { period_ms: 20 }),
            Ok(Response::Ack { .. })
        ));
        c.pump(Duration::from_millis(150)).unwrap();
        assert!(matches!(
            c.request(&Request::GetStatus),
            Ok(Response::Status(_))
        ));
        let frames = c.take_telemetry();
        assert!(frames.len() >= 3, "{}", frames.len());
        assert_eq!(c.stats(), ClientStats::default());
    }
}
