//! A tuning row's bytes, the same in the flash record and in the tuning-table
//! messages: speed, right offset, left offset, `f32` each (IEEE 754 binary32,
//! little-endian), [`TUNING_ROW_LEN`] bytes. Any bit pattern reads; whether the rows
//! make a table is [`crate::controller::TuningTable::from_rows`]'s to say.

use crate::controller::TuningRow;

use super::wire::{Field, Reader, Writer};

/// Bytes of one tuning row: speed (rpm), right offset, left offset (degrees).
pub const TUNING_ROW_LEN: usize = 12;

impl Field for TuningRow {
    fn write(&self, w: &mut Writer<'_>) {
        w.f32(self.speed_rpm);
        w.f32(self.right_offset_deg);
        w.f32(self.left_offset_deg);
    }

    fn read(r: &mut Reader<'_>) -> Option<Self> {
        Some(TuningRow {
            speed_rpm: r.f32()?,
            right_offset_deg: r.f32()?,
            left_offset_deg: r.f32()?,
        })
    }
}
