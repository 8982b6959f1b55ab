//! The UART side of the host link, on the board and in the binaries `qemu-uart`
//! and `pil`.
//! The protocol logic (decode, answer, telemetry, flash writes) is
//! `shared::protocol::link`, tested on the host; this module holds only the byte
//! ring between the RX interrupt and it, and the count of bytes lost on the way.

use core::sync::atomic::{AtomicU32, Ordering};

use heapless::spsc::{Producer, Queue};

/// Bytes the RX ring holds: more than one largest frame (414 bytes), so a whole
/// tuning table can arrive while the link task waits for a long control tick.
pub const RX_RING_LEN: usize = 1024;

/// The ring of received bytes, from the RX interrupt to the link task.
pub type RxRing = Queue<u8, RX_RING_LEN>;

/// Received bytes lost since start: the ring full, or the UART's overrun, noise,
/// framing or parity error (the byte dropped). Counted by the RX interrupt,
/// copied into the link's status by idle (`LinkState::rx_dropped`).
static RX_DROPPED: AtomicU32 = AtomicU32::new(0);

/// Count one lost byte (the RX interrupt).
pub fn count_dropped() {
    RX_DROPPED.fetch_add(1, Ordering::Relaxed);
}

/// Received bytes lost since start.
pub fn dropped() -> u32 {
    RX_DROPPED.load(Ordering::Relaxed)
}

/// A received byte into the ring; counted lost when the ring is full.
pub fn receive(ring: &mut Producer<'_, u8>, byte: u8) {
    if ring.enqueue(byte).is_err() {
        count_dropped();
    }
}
