//! Frames on the UART: the byte layout, [`encode_frame`], and the streaming
//! [`Decoder`] that never trusts a length it has not checked.
//!
//! # Layout
//!
//! ```text
//!  offset  size  field
//!  0       2     sync: 0xA5 0x5A
//!  2       1     version: PROTOCOL_VERSION
//!  3       1     message id
//!  4       2     sequence number, u16 little-endian
//!  6       2     payload length n, u16 little-endian, 0..=MAX_PAYLOAD
//!  8       2     header CRC: CRC-16/CCITT-FALSE of bytes 0..8, little-endian
//!  10      n     payload
//!  10+n    4     frame CRC: CRC-32/ISO-HDLC of bytes 0..10+n, little-endian
//! ```
//!
//! The header has its own CRC so that the length, the message id and the sequence
//! number are known to be right before the payload is read: a corrupted length can
//! neither make the decoder wait for bytes that belong to the next frames nor send an
//! answer to a sequence number the host never used. The 10-byte header keeps this
//! layout in every version of the protocol; only the payloads change with the
//! version byte.
//!
//! # Decoding
//!
//! [`Decoder`] holds at most one frame ([`MAX_FRAME`] bytes) and looks for a frame
//! starting at the first byte it holds:
//!
//! 1. bytes until `0xA5 0x5A` are skipped (counted in [`DecoderStats::skipped`]);
//! 2. at the 10th byte the header CRC is checked, then the version, then the length
//!    against [`MAX_PAYLOAD`]: a failure is an error;
//! 3. at the last byte (`14 + n`) the frame CRC is checked: a frame or an error.
//!
//! After any failure the decoder drops the first byte of the candidate and searches
//! again *in the bytes it already holds* before it takes new ones: a frame that
//! started inside a rejected one (a lost byte, garbage that looked like a header) is
//! still found. Each call returns at most one event; a byte can complete an error and,
//! on the rescan, a frame, so callers loop until [`Decoder::decode`] returns `None`.

use super::{MAX_FRAME, MAX_PAYLOAD, PROTOCOL_VERSION};
use crate::codec::crc::{crc16_ccitt_false, Crc32};

/// The two bytes that open every frame.
pub const SYNC: [u8; 2] = [0xA5, 0x5A];
/// Bytes before the payload: sync, version, id, sequence, length, header CRC.
pub const HEADER_LEN: usize = 10;
/// Bytes of the frame CRC after the payload.
pub const CRC_LEN: usize = 4;
/// Bytes of the header covered by the header CRC (everything before it).
const HEADER_CRC_AT: usize = 8;

/// A frame whose header and frame CRCs and version are right: a message id, a
/// sequence number and a payload of at most [`MAX_PAYLOAD`] bytes. Whether the id is
/// known and the payload fits it is the message parser's business
/// ([`super::Message::parse`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Message id ([`super::MessageId`]).
    pub id: u8,
    /// Sequence number: chosen by the host for a request, echoed in its answer.
    pub seq: u16,
    /// The payload, `0..=MAX_PAYLOAD` bytes.
    pub payload: &'a [u8],
}

/// Why a candidate frame was rejected. Garbage before a sync pattern is no error
/// (it is only counted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The 8 header bytes do not match their CRC-16: nothing in them can be trusted,
    /// not even the sequence number, so this gets no answer.
    HeaderCrc,
    /// A correct header of another protocol version.
    BadVersion {
        /// The version byte received.
        version: u8,
        /// Message id.
        id: u8,
        /// Sequence number.
        seq: u16,
    },
    /// A correct header announcing more than [`MAX_PAYLOAD`] bytes.
    TooLong {
        /// Message id.
        id: u8,
        /// Sequence number.
        seq: u16,
        /// The announced payload length, bytes.
        len: u16,
    },
    /// A correct header, but the frame CRC-32 does not match: the payload is corrupt.
    BadCrc {
        /// Message id.
        id: u8,
        /// Sequence number.
        seq: u16,
    },
}

impl FrameError {
    /// The sequence number and message id of the rejected frame, when its header
    /// passed its CRC (every error but [`FrameError::HeaderCrc`]).
    pub fn header(&self) -> Option<(u16, u8)> {
        match *self {
            FrameError::HeaderCrc => None,
            FrameError::BadVersion { id, seq, .. }
            | FrameError::TooLong { id, seq, .. }
            | FrameError::BadCrc { id, seq } => Some((seq, id)),
        }
    }
}

/// Why a frame could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The payload is longer than [`MAX_PAYLOAD`].
    PayloadTooLong,
    /// The output buffer is too small; [`MAX_FRAME`] bytes always suffice.
    BufferTooSmall,
}

/// Write a frame with message id `id`, sequence number `seq` and `payload` into
/// `out`; returns its length, `HEADER_LEN + payload.len() + CRC_LEN`.
pub fn encode_frame(
    id: u8,
    seq: u16,
    payload: &[u8],
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    let n = payload.len();
    let len = u16::try_from(n)
        .ok()
        .filter(|_| n <= MAX_PAYLOAD)
        .ok_or(EncodeError::PayloadTooLong)?;
    let total = HEADER_LEN + n + CRC_LEN;
    let frame = out.get_mut(..total).ok_or(EncodeError::BufferTooSmall)?;
    let (header, rest) = frame.split_at_mut(HEADER_LEN);
    let (body, crc) = rest.split_at_mut(n);

    // Header: sync, version, id, seq, length, then the CRC-16 of those 8 bytes.
    let [s0, s1] = SYNC;
    let [q0, q1] = seq.to_le_bytes();
    let [l0, l1] = len.to_le_bytes();
    let fields = [s0, s1, PROTOCOL_VERSION, id, q0, q1, l0, l1];
    let [h0, h1] = crc16_ccitt_false(&fields).to_le_bytes();
    header.copy_from_slice(&[s0, s1, PROTOCOL_VERSION, id, q0, q1, l0, l1, h0, h1]);

    // Payload, then the CRC-32 of everything before it.
    body.copy_from_slice(payload);
    let sum = Crc32::new().update(header).update(body).finish();
    crc.copy_from_slice(&sum.to_le_bytes());
    Ok(total)
}

/// Counters of a [`Decoder`], wrapping at `2^32`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecoderStats {
    /// Frames accepted.
    pub frames: u32,
    /// Candidates rejected ([`FrameError`]s returned).
    pub errors: u32,
    /// Bytes dropped while searching for a sync pattern (each rejected candidate's
    /// first byte included).
    pub skipped: u32,
}

/// What the byte at one position of a candidate frame decides.
enum Step {
    /// Still a valid prefix of a frame: take the next byte.
    More,
    /// Not a frame start (no sync): drop a byte, no event.
    Skip,
    /// A rejected candidate: drop a byte, report this.
    Reject(FrameError),
    /// A complete frame of this many bytes.
    Done(usize),
}

/// A streaming frame decoder with a fixed buffer of [`MAX_FRAME`] bytes; see the
/// module documentation for the algorithm.
///
/// ```
/// use shared::controller::Command;
/// use shared::protocol::{encode, Decoder, Message, Request, MAX_FRAME};
///
/// let mut out = [0u8; MAX_FRAME];
/// let n = encode(&Request::Command(Command::Stop), 7, &mut out).unwrap();
/// let mut decoder = Decoder::new();
/// let mut input = &out[..n];
/// let frame = decoder.decode(&mut input).unwrap().unwrap();
/// assert_eq!((frame.seq, Request::parse(&frame)), (7, Ok(Request::Command(Command::Stop))));
/// assert!(decoder.decode(&mut input).is_none());
/// ```
#[derive(Clone, Debug)]
pub struct Decoder {
    /// Bytes held: the candidate frame at the front, then bytes still to rescan.
    buf: [u8; MAX_FRAME],
    /// Bytes held in `buf`.
    held: usize,
    /// Bytes of the candidate at the front checked so far (`<= held`).
    checked: usize,
    /// Length of the frame returned by the previous call, dropped on the next one.
    returned: usize,
    /// Counters.
    stats: DecoderStats,
}

impl Default for Decoder {
    fn default() -> Self {
        Decoder::new()
    }
}

impl Decoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        Decoder {
            buf: [0; MAX_FRAME],
            held: 0,
            checked: 0,
            returned: 0,
            stats: DecoderStats {
                frames: 0,
                errors: 0,
                skipped: 0,
            },
        }
    }

    /// The counters so far.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Bytes held: an incomplete frame's start, after [`Decoder::decode`] returned
    /// `None`.
    pub fn held(&self) -> usize {
        self.held
    }

    /// Give up on the incomplete frame held, once [`Decoder::decode`] has returned
    /// `None` and no byte has come for [`super::FRAME_GAP_TIMEOUT_MS`]: drop its first
    /// byte (silently, counted in [`DecoderStats::skipped`]) and let the next
    /// [`Decoder::decode`] call search the bytes after it. Without this, a frame cut
    /// short (a host restarted mid-frame) or garbage that passed the header CRC
    /// would hold the frames after it until its announced length had arrived.
    /// Does nothing while held bytes remain unchecked.
    pub fn abandon(&mut self) {
        if self.returned == 0 && self.checked == self.held && self.held > 0 {
            self.resync();
        }
    }

    /// Forget every byte held (after a UART error, say).
    pub fn clear(&mut self) {
        self.held = 0;
        self.checked = 0;
        self.returned = 0;
    }

    /// Take bytes from the front of `input` (advancing it) until an event: a frame
    /// (borrowed from the decoder until the next call) or a rejected candidate.
    /// `None` once `input` is empty and every byte held has been checked.
    ///
    /// ```
    /// # use shared::protocol::Decoder;
    /// # let bytes = [0u8; 4];
    /// # let mut decoder = Decoder::new();
    /// let mut input = &bytes[..];
    /// while let Some(event) = decoder.decode(&mut input) {
    ///     match event {
    ///         Ok(frame) => { /* parse and answer */ }
    ///         Err(error) => { /* answer when error.header() is Some */ }
    ///     }
    /// }
    /// ```
    pub fn decode(&mut self, input: &mut &[u8]) -> Option<Result<Frame<'_>, FrameError>> {
        // The frame returned last time leaves the buffer now.
        if self.returned > 0 {
            self.drop_front(self.returned);
            self.returned = 0;
        }
        loop {
            // The next byte: one held but not yet checked, else one from the input.
            if self.checked == self.held {
                let (&byte, rest) = input.split_first()?;
                *input = rest;
                match self.buf.get_mut(self.held) {
                    Some(slot) => {
                        *slot = byte;
                        self.held += 1;
                    }
                    // Unreachable: an incomplete candidate is shorter than MAX_FRAME.
                    None => {
                        self.clear();
                        continue;
                    }
                }
            }
            // Check it as the next byte of the candidate frame.
            match self.step(self.checked) {
                Step::More => self.checked += 1,
                Step::Skip => self.resync(),
                Step::Reject(error) => {
                    self.resync();
                    self.stats.errors = self.stats.errors.wrapping_add(1);
                    return Some(Err(error));
                }
                Step::Done(len) => {
                    self.stats.frames = self.stats.frames.wrapping_add(1);
                    self.returned = len;
                    self.checked = 0;
                    return Some(Ok(self.frame(len)));
                }
            }
        }
    }

    /// The frame of `len` bytes at the front of the buffer (checked by [`Self::step`]).
    fn frame(&self, len: usize) -> Frame<'_> {
        let payload_end = len.saturating_sub(CRC_LEN);
        Frame {
            id: self.byte(3),
            seq: u16::from_le_bytes([self.byte(4), self.byte(5)]),
            payload: self.buf.get(HEADER_LEN..payload_end).unwrap_or(&[]),
        }
    }

    /// The byte held at `i` (0 past the end; callers only read checked bytes).
    fn byte(&self, i: usize) -> u8 {
        self.buf.get(i).copied().unwrap_or(0)
    }

    /// Decide on the byte at position `p` of the candidate (bytes `0..p` passed).
    fn step(&self, p: usize) -> Step {
        let b = self.byte(p);
        match p {
            // Sync pattern.
            0 | 1 => {
                if SYNC.get(p) == Some(&b) {
                    Step::More
                } else {
                    Step::Skip
                }
            }
            // Header fields before the header CRC.
            2..=8 => Step::More,
            // Last header byte: header CRC, then version, then the length bound.
            9 => {
                let header = self.buf.get(..HEADER_CRC_AT).unwrap_or(&[]);
                let stored = u16::from_le_bytes([self.byte(8), self.byte(9)]);
                if crc16_ccitt_false(header) != stored {
                    return Step::Reject(FrameError::HeaderCrc);
                }
                let (version, id) = (self.byte(2), self.byte(3));
                let seq = u16::from_le_bytes([self.byte(4), self.byte(5)]);
                let len = u16::from_le_bytes([self.byte(6), self.byte(7)]);
                if version != PROTOCOL_VERSION {
                    Step::Reject(FrameError::BadVersion { version, id, seq })
                } else if usize::from(len) > MAX_PAYLOAD {
                    Step::Reject(FrameError::TooLong { id, seq, len })
                } else {
                    Step::More
                }
            }
            // Payload and frame CRC: the length is checked (<= MAX_PAYLOAD) by now.
            _ => {
                let len = usize::from(u16::from_le_bytes([self.byte(6), self.byte(7)]));
                let total = HEADER_LEN + len + CRC_LEN;
                if p + 1 < total {
                    return Step::More;
                }
                let body = self.buf.get(..total - CRC_LEN).unwrap_or(&[]);
                let stored = self
                    .buf
                    .get(total - CRC_LEN..total)
                    .and_then(|s| <[u8; 4]>::try_from(s).ok())
                    .map(u32::from_le_bytes);
                if stored == Some(Crc32::new().update(body).finish()) {
                    Step::Done(total)
                } else {
                    let (id, seq) = (
                        self.byte(3),
                        u16::from_le_bytes([self.byte(4), self.byte(5)]),
                    );
                    Step::Reject(FrameError::BadCrc { id, seq })
                }
            }
        }
    }

    /// Drop the candidate's first byte and every byte after it up to the next
    /// possible frame start (`SYNC[0]`), then check again from there.
    fn resync(&mut self) {
        let next = self
            .buf
            .get(1..self.held)
            .and_then(|rest| rest.iter().position(|&b| b == SYNC[0]))
            .map_or(self.held, |i| i + 1);
        self.stats.skipped = self.stats.skipped.wrapping_add(next as u32);
        self.drop_front(next);
    }

    /// Remove the first `n` bytes held; the candidate starts again at the new front.
    fn drop_front(&mut self, n: usize) {
        let n = n.min(self.held);
        self.buf.copy_within(n..self.held, 0);
        self.held -= n;
        self.checked = 0;
    }
}
