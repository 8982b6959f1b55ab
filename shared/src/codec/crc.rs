//! The two CRCs of the project, computed by the `crc` crate (table-driven, one byte
//! a step, the tables built at compile time, no heap): the catalogue's parameters
//! are named, not written out here. docs/development.md ("Crates") says why the
//! crate replaced the hand-written tables and what it cost.
//!
//! | name | width | polynomial | init | reflected in/out | xor out | check (`"123456789"`) |
//! | --- | --- | --- | --- | --- | --- | --- |
//! | CRC-16/CCITT-FALSE (a.k.a. CRC-16/IBM-3740) | 16 | `0x1021` | `0xFFFF` | no / no | `0x0000` | `0x29B1` |
//! | CRC-32/ISO-HDLC (zlib, Ethernet, PNG) | 32 | `0x04C11DB7` (reflected `0xEDB88320`) | `0xFFFFFFFF` | yes / yes | `0xFFFFFFFF` | `0xCBF43926` |
//!
//! The parameters are those of the Williams model as catalogued by Greg Cook's
//! "Catalogue of parametrised CRC algorithms" (reveng); the check values are that
//! catalogue's. CRC-32/ISO-HDLC is Python's `zlib.crc32` and `binascii.crc32`, so a
//! host script can check a frame or a flash record without this crate.
//!
//! - CRC-16/CCITT-FALSE guards the 8-byte frame header, so that a frame's length is
//!   never used before it is known to be right (see `crate::protocol::frame`).
//! - CRC-32/ISO-HDLC guards whole frames and flash records. Its non-zero init and
//!   xor-out make the CRC of a run of `0x00` bytes non-zero for every length but 0,
//!   and the CRC of a run of `0xFF` bytes differ from `0xFFFFFFFF` for every length
//!   but exactly 4 (those 4 bytes cancel the init). Records are far longer
//!   than 4 bytes (`crate::storage::record`), so neither erased (`0xFF`) nor zeroed
//!   flash can carry a matching CRC; `tests/storage.rs` checks every record length.

use crc::{Crc, Digest, CRC_16_IBM_3740, CRC_32_ISO_HDLC};

/// CRC-16/CCITT-FALSE, which the catalogue now names CRC-16/IBM-3740: one 256-entry
/// table of `u16` (512 bytes of flash), built at compile time.
static CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// CRC-32/ISO-HDLC: one 256-entry table of `u32` (1 KiB of flash), built at compile
/// time.
static CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// CRC-16/CCITT-FALSE of `data` (poly `0x1021`, init `0xFFFF`, not reflected, no
/// final xor). `crc16_ccitt_false(b"123456789") == 0x29B1`.
pub fn crc16_ccitt_false(data: &[u8]) -> u16 {
    CRC16.checksum(data)
}

/// A CRC-32/ISO-HDLC computed in pieces: `Crc32::new().update(a).update(b).finish()`
/// equals [`crc32`] of `a` followed by `b`.
#[derive(Clone)]
pub struct Crc32 {
    /// The register, kept by the `crc` crate.
    digest: Digest<'static, u32>,
}

impl Default for Crc32 {
    fn default() -> Self {
        Crc32::new()
    }
}

impl Crc32 {
    /// The register at its init value, `0xFFFFFFFF`.
    pub fn new() -> Self {
        Crc32 {
            digest: CRC32.digest(),
        }
    }

    /// Shift `data` through the register.
    pub fn update(mut self, data: &[u8]) -> Self {
        self.digest.update(data);
        self
    }

    /// The CRC: the register xor `0xFFFFFFFF`.
    pub fn finish(self) -> u32 {
        self.digest.finalize()
    }
}

/// CRC-32/ISO-HDLC of `data` (poly `0x04C11DB7` reflected, init `0xFFFFFFFF`, xor
/// out `0xFFFFFFFF`), as `zlib.crc32`. `crc32(b"123456789") == 0xCBF43926`.
pub fn crc32(data: &[u8]) -> u32 {
    CRC32.checksum(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit-by-bit references, straight from the definitions (independent of the
    /// crate).
    fn crc16_bitwise(data: &[u8]) -> u16 {
        let mut r: u16 = 0xFFFF;
        for &b in data {
            r ^= u16::from(b) << 8;
            for _ in 0..8 {
                r = if r & 0x8000 != 0 {
                    (r << 1) ^ 0x1021
                } else {
                    r << 1
                };
            }
        }
        r
    }

    fn crc32_bitwise(data: &[u8]) -> u32 {
        let mut r: u32 = 0xFFFF_FFFF;
        for &b in data {
            r ^= u32::from(b);
            for _ in 0..8 {
                r = if r & 1 != 0 {
                    (r >> 1) ^ 0xEDB8_8320
                } else {
                    r >> 1
                };
            }
        }
        !r
    }

    #[test]
    fn check_values_of_the_catalogue() {
        assert_eq!(crc16_ccitt_false(b"123456789"), 0x29B1);
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc16_ccitt_false(b""), 0xFFFF);
        assert_eq!(crc32(b""), 0);
    }

    #[test]
    fn tables_agree_with_the_bitwise_definition() {
        let data: [u8; 64] = core::array::from_fn(|i| (i as u8).wrapping_mul(37) ^ 0x5a);
        for n in 0..data.len() {
            assert_eq!(crc16_ccitt_false(&data[..n]), crc16_bitwise(&data[..n]));
            assert_eq!(crc32(&data[..n]), crc32_bitwise(&data[..n]));
            let (a, b) = data[..n].split_at(n / 3);
            assert_eq!(Crc32::new().update(a).update(b).finish(), crc32(&data[..n]));
        }
    }
}
