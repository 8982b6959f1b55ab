//! The UART protocol between the host and the firmware: frames with a
//! length and two CRCs, a decoder that never trusts a length it has not checked, an
//! answer to every frame, and a heartbeat. `docs/protocol.md` is the byte-by-byte
//! reference; this crate is its implementation, used by the firmware and by host-sim.
//! Its CRCs and little-endian fields are [`crate::codec`]'s.
//!
//! - `frame`: the frame layout, [`encode_frame`], the streaming [`Decoder`];
//! - `message`: message ids, [`Request`], [`Response`] and their payloads;
//! - `handler`: the answer rule, on a [`Device`];
//! - [`link`]: the device's end of the link as the firmware runs it ([`link::Link`]).
//!
//! # Link
//!
//! UART at [`BAUD_RATE`] (115200 baud, 8 data bits, no parity, 1 stop bit), both
//! ways. The host sends requests, each with a sequence number of its choice (one
//! more for each new request, wrapping; a retry keeps its number); the device
//! answers each with one frame carrying the same sequence number, in the order the
//! requests came, within [`ANSWER_TIMEOUT_MS`] ([`STORE_ANSWER_TIMEOUT_MS`] for
//! [`Request::WriteTuningTable`], which erases a flash sector). Unsolicited
//! [`Response::Telemetry`] frames carry the device's own counter. The host sends a
//! request at least every [`HEARTBEAT_PERIOD_MS`] while the motors run: the
//! controller latches `LINK_LOST` after 0.5 s without one
//! ([`crate::controller::FaultLimits::link_timeout_s`]).
//!
//! # No panic, no heap
//!
//! Every buffer is a fixed array; every index is checked (`get`, split functions);
//! the decoder's buffer never holds more than one frame. `tests/protocol_props.rs`
//! feeds arbitrary bytes.

mod frame;
mod handler;
pub mod link;
mod message;

pub use frame::{
    encode_frame, Decoder, DecoderStats, EncodeError, Frame, FrameError, CRC_LEN, HEADER_LEN, SYNC,
};
pub use handler::{answer_error, answer_event, answer_request, is_answer, Device};
pub use message::{
    Message, MessageId, NackReason, ParseError, Request, Response, StatusReport,
    MIN_TELEMETRY_PERIOD_MS,
};

/// Protocol version, byte 2 of every frame: 4 since the capture's requests and
/// answers (3: the motor identification's requests, its report and the state
/// `identify`; 2: the 68-byte status report).
pub const PROTOCOL_VERSION: u8 = 4;

/// UART speed, baud (8N1). 115200 is the rate every USB-serial adapter and every
/// terminal program supports; it carries 11520 bytes/s, so the largest frame
/// (414 bytes, a whole tuning table) takes 36 ms and the telemetry stream at its
/// fastest ([`MIN_TELEMETRY_PERIOD_MS`]) a third of the link.
pub const BAUD_RATE: u32 = 115_200;

/// Largest payload, bytes: a whole tuning table in one frame, `1 + 12 x 32 = 385`
/// bytes ([`crate::controller::MAX_TUNING_ROWS`] rows), rounded up.
pub const MAX_PAYLOAD: usize = 400;

/// Largest frame, bytes: header, [`MAX_PAYLOAD`], CRC.
pub const MAX_FRAME: usize = HEADER_LEN + MAX_PAYLOAD + CRC_LEN;

/// Longest the host waits for an answer before it sends the request again, ms:
/// the device answers from its communication task, well within a few control
/// ticks; 100 ms leaves five retries inside the link timeout.
pub const ANSWER_TIMEOUT_MS: u32 = 100;

/// Longest the host waits for the answer to [`Request::WriteTuningTable`], ms: a
/// 128 KiB sector erase takes about 1 s, at most 2 s (STM32F405 datasheet,
/// `t_ERASE128KB` at 32-bit parallelism), and the CPU may stall meanwhile; the
/// host sends nothing else until the answer (bytes sent during the erase may be
/// lost).
pub const STORE_ANSWER_TIMEOUT_MS: u32 = 5_000;

/// Silence after which the device gives up on an incomplete frame, ms
/// ([`Decoder::abandon`]): the host sends a frame's bytes back to back, and a
/// USB-serial adapter holds bytes back for at most 16 ms (FTDI's default latency
/// timer), so 50 ms of silence inside a frame means that its sender stopped.
pub const FRAME_GAP_TIMEOUT_MS: u32 = 50;

/// How often the host sends a request (a [`Request::Command`] with [`crate::controller::Command::Heartbeat`] when it has
/// nothing else to say) while the motors run, ms: five chances within the
/// controller's 0.5 s link timeout.
pub const HEARTBEAT_PERIOD_MS: u32 = 100;

/// Encode `msg` as a frame with sequence number `seq` into `out` (at least the
/// frame's length; [`MAX_FRAME`] bytes always suffice); returns the frame's length.
pub fn encode<M: Message>(msg: &M, seq: u16, out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = msg
        .write_payload(&mut payload)
        .ok_or(EncodeError::PayloadTooLong)?;
    encode_frame(msg.id() as u8, seq, payload.get(..n).unwrap_or(&[]), out)
}
