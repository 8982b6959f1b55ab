//! The bytes under the serial protocol and the flash record, one layer below both:
//!
//! - [`crc`]: CRC-16/CCITT-FALSE (the frame header) and CRC-32/ISO-HDLC (whole
//!   frames, flash records);
//! - `wire`: little-endian field readers and writers over fixed buffers, every access
//!   bounds-checked (crate-internal).
//!
//! Layers of `shared`, each using only those below it: [`crate::controller`] (knows
//! nothing of bytes), `codec`, [`crate::storage`] (the flash record),
//! [`crate::protocol`] (frames, messages, the device's end of the link).

pub mod crc;
pub(crate) mod wire;
