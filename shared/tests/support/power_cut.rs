//! One store of a power-cut history on a [`SimFlash`], checked: what the parameter
//! store's power-cut argument promises (`shared::storage`, module documentation).

use shared::storage::{
    load, store, Record, SimError, SimFlash, StoreError, RECORD_LEN, SIM_SECTOR_BYTES,
};

/// Bytes one store erases and programs on a `SimFlash`: its power-cut points.
pub const STORE_WORK: usize = SIM_SECTOR_BYTES + RECORD_LEN;

/// Store `record` on `flash` with the power cut after `cut` bytes (`None`: no
/// cut), then power back. `committed` is the last record whose store completed,
/// with its sequence number (none before the first), and becomes this one if this
/// store completes. Checked: the store completes exactly when the cut comes after
/// all [`STORE_WORK`] bytes, with the next sequence number; a cut store fails with
/// the power cut; and `load` then gives exactly the last committed record.
pub fn store_and_check(
    flash: &mut SimFlash,
    record: Record,
    cut: Option<usize>,
    committed: &mut Option<(Record, u32)>,
) {
    if let Some(n) = cut {
        flash.cut_after(n);
    }
    let result = store(&mut *flash, &record);
    flash.power_on();
    match result {
        Ok(stored) => {
            let sequence = committed.as_ref().map_or(1, |(_, s)| s.wrapping_add(1));
            assert_eq!(stored.sequence, sequence);
            assert!(cut.is_none_or(|n| n >= STORE_WORK), "completed though cut");
            *committed = Some((record, stored.sequence));
        }
        Err(error) => {
            assert_eq!(error, StoreError::Flash(SimError::PowerCut));
            assert!(cut.is_some_and(|n| n < STORE_WORK), "cut though powered");
        }
    }
    let loaded = load(&*flash).map(|s| (s.record, s.sequence));
    assert_eq!(&loaded, committed, "not the last committed record");
}
