//! The UART side of the host link on the board. The protocol logic (decode,
//! answer, telemetry, flash writes) is `shared::protocol::link`, tested on the
//! host; this module holds only the byte ring between the RX interrupt and it.

use heapless::spsc::Queue;

/// Bytes the RX ring holds: more than one largest frame (414 bytes), so a whole
/// tuning table can arrive while the link task waits for a long control tick.
pub const RX_RING_LEN: usize = 1024;

/// The ring of received bytes, from the RX interrupt to the link task.
pub type RxRing = Queue<u8, RX_RING_LEN>;
