//! The bytes under the serial protocol and the flash record, one layer below both:
//!
//! - [`crc`]: CRC-16/CCITT-FALSE (the frame header) and CRC-32/ISO-HDLC (whole
//!   frames, flash records);
//! - `wire`: little-endian field readers and writers over fixed buffers, every access
//!   bounds-checked, and the fixed layouts of values read and written whole
//!   (crate-internal);
//! - `self_test`: the self-test result's and report's bytes;
//! - `identity`: the motor identification's bytes;
//! - `tuning_row`: a tuning row's bytes.
//!
//! Layers of `shared`, each using only those below it: [`crate::controller`] (knows
//! nothing of bytes, flash or frames), `codec` (the controller's values as bytes),
//! [`crate::storage`] (the flash record), [`crate::protocol`] (frames, messages, the
//! device's end of the link).

pub mod crc;
mod identity;
mod self_test;
mod tuning_row;
pub(crate) mod wire;

pub use identity::{IDENTIFY_REPORT_LEN, IDENTITY_LEN, ROTOR_IDENTITY_LEN};
pub use self_test::{ROTOR_SELF_TEST_LEN, SELF_TEST_LEN, SELF_TEST_REPORT_LEN};
pub use tuning_row::TUNING_ROW_LEN;
