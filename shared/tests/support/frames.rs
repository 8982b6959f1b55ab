//! Frames for the tests: encoded messages and raw frames, and a decoder fed in
//! chunks with every event copied out.

use shared::protocol::{encode, encode_frame, Decoder, FrameError, Message, MAX_FRAME};

/// A decoder event with the frame copied out.
pub type Event = Result<(u8, u16, Vec<u8>), FrameError>;

/// Feed `bytes` in chunks of the given sizes (cycled), collecting every event.
pub fn feed(decoder: &mut Decoder, bytes: &[u8], chunks: &[usize]) -> Vec<Event> {
    let mut out = Vec::new();
    let mut rest = bytes;
    let mut k = 0;
    while !rest.is_empty() {
        let n = chunks
            .get(k % chunks.len().max(1))
            .copied()
            .unwrap_or(1)
            .clamp(1, rest.len());
        k += 1;
        let (mut input, tail) = rest.split_at(n);
        rest = tail;
        while let Some(event) = decoder.decode(&mut input) {
            out.push(event.map(|f| (f.id, f.seq, f.payload.to_vec())));
        }
        assert!(input.is_empty());
    }
    out
}

/// Abandon whatever is held (the line went quiet) until nothing is.
pub fn finish(decoder: &mut Decoder) -> Vec<Event> {
    let mut out = Vec::new();
    for _ in 0..=MAX_FRAME {
        if decoder.held() == 0 {
            break;
        }
        decoder.abandon();
        let mut input: &[u8] = &[];
        while let Some(event) = decoder.decode(&mut input) {
            out.push(event.map(|f| (f.id, f.seq, f.payload.to_vec())));
        }
    }
    assert_eq!(decoder.held(), 0);
    out
}

/// `msg` encoded as a frame with sequence number `seq`.
pub fn frame_bytes<M: Message>(msg: &M, seq: u16) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode(msg, seq, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// A frame of any id and payload, with sequence number `seq`.
pub fn raw_frame(id: u8, seq: u16, payload: &[u8]) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode_frame(id, seq, payload, &mut buf).unwrap();
    buf[..n].to_vec()
}
