//! Processor in the loop (cargo feature `pil`, binary `pil`; `docs/pil.md`): the
//! firmware on QEMU's `netduinoplus2` with the host as its board. At every
//! control tick the board's sampling and output are an exchange of records
//! (`shared::pil`) with `host-sim run --firmware` over semihosting files
//! ([`channel`]): the host's plant gives the sensors' readings and the UART's
//! received bytes, and gets back TIM8's compare values and main output enable, as
//! the board's driver writes them, and the UART's sent bytes ([`board`]). The
//! tick, the link, the bridge driver and the controller are the board's.

pub mod board;
pub mod channel;

use core::sync::atomic::{AtomicU32, Ordering};

use heapless::spsc::Queue;

/// Bytes the link may queue for the host between two ticks (each record carries
/// at most `shared::pil::MAX_BYTES` of them): more than two largest frames.
pub const TX_RING_LEN: usize = 1024;

/// The link's sent bytes, from `idle` to the control tick's record.
pub type TxRing = Queue<u8, TX_RING_LEN>;

/// Sent bytes lost since start (the ring full).
static TX_DROPPED: AtomicU32 = AtomicU32::new(0);

/// Count one sent byte lost.
pub fn count_tx_dropped() {
    TX_DROPPED.fetch_add(1, Ordering::Relaxed);
}

/// Sent bytes lost since start.
pub fn tx_dropped() -> u32 {
    TX_DROPPED.load(Ordering::Relaxed)
}
