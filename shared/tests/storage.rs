//! The parameter store (`shared::storage`): the record layout byte for byte, the
//! CRC over erased and zeroed flash, round trips, and the power-cut proof: a
//! simulated flash that loses power after every possible number of bytes of a
//! store, in every starting situation, always loads the previous record (or the new
//! one once the store has completed), never garbage, never nothing when a record
//! existed.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use shared::codec::crc::crc32;
use shared::controller::self_test::{RotorSelfTest, SelfTest};
use shared::controller::{Direction, TuningTable};
use shared::storage::{
    encode_record, parse_record, PAYLOAD_LEN, RECORD_HEADER_LEN, RECORD_LEN, RECORD_WORDS,
    V1_PAYLOAD_LEN,
};
use shared::storage::{
    is_newer, load, slot_offset, store, Record, SimError, SimFlash, StoreError, Stored, MAGIC,
    MAX_UNIT,
};
use shared::storage::{SIM_SECTOR_BYTES, SIM_SECTOR_SIZE};

mod support;

use support::identities::identity;
use support::power_cut::STORE_WORK;

fn record(k: u32) -> Record {
    let rows: Vec<(f32, f32, f32)> = (0..=(k % 32))
        .map(|i| {
            (
                100.0 * (i + 1) as f32 + k as f32,
                (i * 7 + k) as f32 % 360.0,
                (200 + i + k) as f32 % 360.0,
            )
        })
        .collect();
    Record {
        tuning: TuningTable::from_rows(&rows).unwrap(),
        self_test: (k % 2 == 1).then_some(SelfTest {
            rotors: [
                RotorSelfTest {
                    motor_polarity_ok: true,
                    encoder_polarity_ok: true,
                    index_seen: true,
                    counts_per_rev: 4096 + k,
                    index_offset_counts: 17 * k,
                },
                RotorSelfTest {
                    motor_polarity_ok: matches!(k % 3, 0),
                    encoder_polarity_ok: true,
                    index_seen: false,
                    counts_per_rev: 0,
                    index_offset_counts: 0,
                },
            ],
        }),
        identity: (k % 3 != 1).then(|| identity(k)),
    }
}

/// `v2`'s first 412 payload bytes as a version 1 record (what the firmware before
/// the identification wrote), its CRC recomputed.
fn as_version_1(v2: &[u8]) -> Vec<u8> {
    let mut b = v2[..RECORD_HEADER_LEN + V1_PAYLOAD_LEN].to_vec();
    b[4..6].copy_from_slice(&1u16.to_le_bytes());
    b[6..8].copy_from_slice(&(V1_PAYLOAD_LEN as u16).to_le_bytes());
    let crc = crc32(&b);
    b.extend_from_slice(&crc.to_le_bytes());
    b
}

#[test]
fn the_layout_is_as_documented() {
    assert_eq!(RECORD_HEADER_LEN, 12);
    assert_eq!(V1_PAYLOAD_LEN, 412);
    assert_eq!(PAYLOAD_LEN, 552);
    assert_eq!(RECORD_LEN, 568);
    assert_eq!(RECORD_WORDS * 4, RECORD_LEN);
    const { assert!(RECORD_LEN <= SIM_SECTOR_BYTES) };
    assert_eq!(MAGIC.to_le_bytes(), *b"VIBT");

    let r = Record {
        tuning: TuningTable::from_rows(&[(500.0, 90.0, 270.0), (3000.0, 80.0, 280.0)]).unwrap(),
        self_test: None,
        identity: None,
    };
    let bytes = encode_record(&r, 0x0102_0304);
    assert_eq!(&bytes[0..4], b"VIBT");
    assert_eq!(&bytes[4..6], &2u16.to_le_bytes());
    assert_eq!(&bytes[6..8], &552u16.to_le_bytes());
    assert_eq!(&bytes[8..12], &[4, 3, 2, 1]);
    assert_eq!(&bytes[12..16], &[2, 0, 0, 0]); // 2 rows, no self-test
    assert_eq!(&bytes[16..20], &500f32.to_le_bytes());
    assert_eq!(&bytes[20..24], &90f32.to_le_bytes());
    assert_eq!(&bytes[24..28], &270f32.to_le_bytes());
    assert_eq!(&bytes[28..32], &3000f32.to_le_bytes());
    assert!(bytes[40..564].iter().all(|&b| b == 0));
    assert_eq!(&bytes[564..568], &crc32(&bytes[..564]).to_le_bytes());
    assert_eq!(parse_record(&bytes), Some((r.clone(), 0x0102_0304)));

    // Both results present: bits 0 and 1, the identification at payload byte 412.
    let both = Record {
        self_test: record(1).self_test,
        identity: Some(identity(0)),
        ..r
    };
    let bytes = encode_record(&both, 7);
    assert_eq!(bytes[13], 0b11);
    assert_eq!(bytes[12 + 412], 2, "rotors identified");
    assert_eq!(&bytes[12 + 416 + 4..12 + 416 + 8], &2.0f32.to_le_bytes());
    assert_eq!(parse_record(&bytes), Some((both, 7)));
}

/// A version 1 record (a firmware before the identification wrote it) loads, from
/// bytes and from flash, with its table and self-test and no identification;
/// the next store writes version 2 over it, and the table survives.
#[test]
fn a_version_1_record_still_loads() {
    let mut old = record(3);
    old.identity = None;
    let v1 = as_version_1(&encode_record(&old, 41));
    assert_eq!(v1.len(), 428);
    assert_eq!(parse_record(&v1), Some((old.clone(), 41)));
    // In flash, erased beyond it.
    let mut flash = SimFlash::new();
    let mut padded = v1.clone();
    padded.resize(v1.len().next_multiple_of(4), 0xFF);
    flash.write(0, &padded).unwrap();
    let stored = load(&flash).expect("the version 1 record loads");
    assert_eq!(stored.record, old);
    assert_eq!(stored.sequence, 41);
    // A store keeps its table and writes version 2 in the other slot.
    let mut new = stored.record.clone();
    new.identity = Some(identity(5));
    let written = store(&mut flash, &new).unwrap();
    assert_eq!((written.slot, written.sequence), (1, 42));
    assert_eq!(load(&flash).unwrap().record, new);
    // A version 1 record has no identification bit.
    let mut bits = as_version_1(&encode_record(&old, 41));
    bits[13] |= 0b10;
    let n = bits.len();
    let crc = crc32(&bits[..n - 4]);
    bits[n - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(parse_record(&bits), None);
}

#[test]
fn erased_or_zeroed_flash_never_validates() {
    // The CRC alone: over every length up to twice a record's, a run of 0xFF never
    // has the CRC 0xFFFFFFFF, except the 4-byte run (shorter than any record), and
    // a run of 0x00 never the CRC 0 (only the empty run has it).
    assert_eq!(crc32(&[]), 0);
    for n in 1..=2 * RECORD_LEN {
        let ff = crc32(&vec![0xFF; n]);
        assert_eq!(ff == 0xFFFF_FFFF, n == 4, "{n} bytes of 0xFF");
        assert_ne!(crc32(&vec![0x00; n]), 0, "{n} bytes of 0x00");
    }
    // Whole records.
    assert_eq!(parse_record(&[0xFF; RECORD_LEN]), None);
    assert_eq!(parse_record(&[0x00; RECORD_LEN]), None);
    // Whole flashes.
    assert_eq!(load(&SimFlash::new()), None);
    assert_eq!(load(&SimFlash::filled(0x00)), None);
    // The magic is neither, and no byte of it is 0xFF.
    assert_ne!(MAGIC, 0xFFFF_FFFF);
    assert_ne!(MAGIC, 0);
    assert!(MAGIC.to_le_bytes().iter().all(|&b| b != 0xFF));
}

#[test]
fn a_valid_crc_is_not_enough() {
    // Records that pass the CRC but break a payload rule are refused: the CRC
    // recomputed after each change.
    let good = encode_record(&record(3), 9);
    let reseal = |mut b: [u8; RECORD_LEN]| {
        let crc = crc32(&b[..RECORD_LEN - 4]);
        b[RECORD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
        b
    };
    let mut cases = Vec::new();
    let mut b = good;
    b[0] ^= 1; // magic
    cases.push(b);
    let mut b = good;
    b[4] = 3; // version
    cases.push(b);
    let mut b = good;
    b[4] = 1; // version 1 with version 2's length
    cases.push(b);
    let mut b = good;
    b[6] = 0; // length
    cases.push(b);
    let mut b = good;
    b[12] = 0; // no row
    cases.push(b);
    let mut b = good;
    b[12] = 33; // too many rows
    cases.push(b);
    let mut b = good;
    b[13] = 4; // an unknown present bit
    cases.push(b);
    let mut b = good;
    b[14] = 1; // reserved
    cases.push(b);
    let mut b = good;
    b[16..20].copy_from_slice(&f32::NAN.to_le_bytes()); // a NaN speed
    cases.push(b);
    let mut b = good;
    b[12 + 4 + 4 * 12 + 1] = 1; // an unused row slot (record(3) has 4 rows)
    cases.push(b);
    let mut b = good;
    b[12 + 388 + 1] = 1; // a reserved byte of rotor 1's self-test
    cases.push(b);
    let mut b = good;
    b[12 + 388] |= 0x08; // an unknown self-test flag
    cases.push(b);
    let mut b = encode_record(&record(2), 9); // no self-test ...
    b[12 + 388 + 4] = 1; // ... but bytes in its place
    cases.push(b);
    let mut b = encode_record(&record(4), 9); // no identification ...
    b[12 + 412 + 20] = 1; // ... but bytes in its place
    cases.push(b);
    let mut b = good; // record(3) has one
    b[12 + 412 + 1] = 1; // a reserved byte of it
    cases.push(b);
    let mut b = good;
    b[12 + 416 + 8..12 + 416 + 12].copy_from_slice(&(-1f32).to_le_bytes()); // a negative spread
    cases.push(b);
    for (i, case) in cases.into_iter().enumerate() {
        assert_eq!(parse_record(&reseal(case)), None, "case {i}");
    }
    assert!(parse_record(&good).is_some());
}

/// A record written under the rule before tuning rows had one rule (the same
/// format version): the default table's single row at speed 0, offsets of 360
/// degrees. It still loads, meaning what it meant: the single row holds its
/// offsets at every speed, 360 is 0; the self-test result stored with it is kept.
/// A table of several rows with a speed 0 was never written and stays refused.
#[test]
fn a_record_under_the_earlier_row_rule_still_loads() {
    let mut one_row = record(2);
    one_row.tuning = TuningTable::default();
    let mut b = encode_record(&one_row, 5);
    b[16..20].copy_from_slice(&0f32.to_le_bytes()); // speed 0
    b[20..24].copy_from_slice(&360f32.to_le_bytes()); // right offset 360
    let crc = crc32(&b[..RECORD_LEN - 4]);
    b[RECORD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    let (loaded, sequence) = parse_record(&b).expect("an earlier record loads");
    assert_eq!(sequence, 5);
    assert_eq!(loaded.self_test, one_row.self_test);
    let row = loaded.tuning.rows()[0];
    assert_eq!(row.right_offset_deg, 0.0);
    assert_eq!(
        row.left_offset_deg,
        one_row.tuning.rows()[0].left_offset_deg
    );
    for speed in [300.0, 3000.0, 6000.0] {
        assert_eq!(
            loaded.tuning.offset(Direction::Right, speed),
            0.0,
            "at {speed} rpm"
        );
    }

    let mut b = encode_record(&record(3), 5);
    b[16..20].copy_from_slice(&0f32.to_le_bytes()); // the first of 4 rows at 0
    let crc = crc32(&b[..RECORD_LEN - 4]);
    b[RECORD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(parse_record(&b), None);
}

#[test]
fn stores_alternate_and_load_takes_the_newest() {
    let mut flash = SimFlash::new();
    for k in 0..6u32 {
        let stored = store(&mut flash, &record(k)).unwrap();
        assert_eq!(stored.sequence, k + 1);
        assert_eq!(stored.slot, (k % 2) as usize);
        assert_eq!(load(&flash), Some(stored));
    }
    assert_eq!(flash.erases(), 6);
    assert_eq!(flash.words_programmed(), 6 * RECORD_WORDS as u32);
}

#[test]
fn a_corrupt_newest_record_falls_back_to_the_older() {
    let mut flash = SimFlash::new();
    let old = store(&mut flash, &record(1)).unwrap();
    let new = store(&mut flash, &record(2)).unwrap();
    assert_eq!(load(&flash), Some(new.clone()));
    // A bit flipped anywhere in the newest record: the older one is taken.
    for byte in (0..RECORD_LEN).step_by(7) {
        let mut f = flash.clone();
        f.corrupt(SIM_SECTOR_SIZE * new.slot as u32 + byte as u32, 0x10)
            .unwrap();
        assert_eq!(load(&f), Some(old.clone()), "byte {byte}");
        // The next store overwrites the corrupt sector, not the good one.
        let next = store(&mut f, &record(3)).unwrap();
        assert_eq!(next.slot, new.slot);
        assert_eq!(next.sequence, old.sequence + 1);
    }
}

#[test]
fn sequence_numbers_compare_across_the_wrap() {
    assert!(is_newer(1, 0));
    assert!(is_newer(0, u32::MAX));
    assert!(!is_newer(u32::MAX, 0));
    assert!(!is_newer(5, 5));
    // Two records around the wrap: the one after it is the newer.
    let mut flash = SimFlash::new();
    let a = encode_record(&record(1), u32::MAX);
    let b = encode_record(&record(2), 0);
    for (slot, bytes) in [(0, a), (1, b)] {
        flash.write(SIM_SECTOR_SIZE * slot, &bytes).unwrap();
    }
    let loaded = load(&flash).unwrap();
    assert_eq!((loaded.slot, loaded.sequence), (1, 0));
    assert_eq!(store(&mut flash, &record(3)).unwrap().sequence, 1);
}

#[test]
fn the_sim_flash_follows_the_chip_rules() {
    let mut flash = SimFlash::new();
    // Two 128 KiB sectors, programmed in words, read in bytes.
    assert_eq!(flash.capacity(), 2 * SIM_SECTOR_SIZE as usize);
    assert_eq!(SimFlash::ERASE_SIZE, SIM_SECTOR_SIZE as usize);
    assert_eq!((SimFlash::WRITE_SIZE, SimFlash::READ_SIZE), (4, 1));
    let base = SIM_SECTOR_SIZE;
    assert_eq!(flash.write(base + 2, &[0; 4]), Err(SimError::Unaligned));
    assert_eq!(flash.write(base, &[0; 3]), Err(SimError::Unaligned));
    assert_eq!(flash.write(2 * base, &[0; 4]), Err(SimError::OutOfRange));
    // Programming outside the modelled bytes of a sector is refused.
    let past = base + SIM_SECTOR_BYTES as u32;
    assert_eq!(flash.write(past, &[0; 4]), Err(SimError::OutOfRange));
    assert_eq!(flash.erase(1, base), Err(SimError::Unaligned));
    assert_eq!(flash.erase(0, 3 * base), Err(SimError::OutOfRange));
    flash.write(base, &0x1234_5678u32.to_le_bytes()).unwrap();
    assert_eq!(flash.write(base, &[0; 4]), Err(SimError::NotErased));
    let mut out = [0u8; 6];
    flash.read(base, &mut out).unwrap();
    assert_eq!(out, [0x78, 0x56, 0x34, 0x12, 0xFF, 0xFF]);
    // Unmodelled bytes read erased.
    let mut far = [0u8; 2];
    flash.read(past, &mut far).unwrap();
    assert_eq!(far, [0xFF; 2]);
    assert_eq!(
        flash.read(2 * base - 1, &mut far),
        Err(SimError::OutOfRange)
    );
    flash.erase(base, 2 * base).unwrap();
    flash.read(base, &mut out).unwrap();
    assert_eq!(out, [0xFF; 6]);
    // A cut: the power stays off until power_on.
    flash.cut_after(2);
    assert_eq!(flash.write(base, &[0; 4]), Err(SimError::PowerCut));
    assert!(flash.is_off());
    flash.read(base, &mut out).unwrap();
    assert_eq!(out[..4], [0x00, 0x00, 0xF0, 0xFF]);
    assert_eq!(flash.erase(0, base), Err(SimError::PowerCut));
    flash.power_on();
    assert!(!flash.is_off());
    flash.erase(base, 2 * base).unwrap();
    // The errors' kinds, for generic callers.
    assert_eq!(SimError::Unaligned.kind(), NorFlashErrorKind::NotAligned);
    assert_eq!(SimError::OutOfRange.kind(), NorFlashErrorKind::OutOfBounds);
}

/// The flash states a store can start from, with the record `load` gives before it.
fn starting_points() -> Vec<(&'static str, SimFlash, Option<Stored>)> {
    let mut points = Vec::new();
    points.push(("erased", SimFlash::new(), None));
    points.push(("zeroed", SimFlash::filled(0x00), None));

    let mut one = SimFlash::new();
    let r1 = store(&mut one, &record(1)).unwrap();
    points.push(("one record", one.clone(), Some(r1)));

    let mut two = one.clone();
    let r2 = store(&mut two, &record(2)).unwrap();
    points.push(("two records", two.clone(), Some(r2)));

    let mut three = two.clone();
    let r3 = store(&mut three, &record(3)).unwrap();
    points.push(("three records", three, Some(r3.clone())));

    // The newest record's sector next to a half-written one (an earlier cut).
    let mut cut = two.clone();
    cut.cut_after(SIM_SECTOR_BYTES + RECORD_LEN / 2);
    assert!(store(&mut cut, &record(9)).is_err());
    cut.power_on();
    let newest = load(&two);
    assert_eq!(load(&cut), newest);
    points.push(("after an earlier cut", cut, newest));
    points
}

#[test]
fn a_power_cut_at_every_byte_keeps_the_last_good_record() {
    let new = record(20);
    for (name, start, old) in starting_points() {
        assert_eq!(load(&start), old, "{name}");
        let mut completed_at = None;
        for n in 0..=STORE_WORK + 1 {
            let mut flash = start.clone();
            flash.cut_after(n);
            let result = store(&mut flash, &new);
            // Power back: what does the next boot load?
            flash.power_on();
            let loaded = load(&flash);
            match result {
                Ok(stored) => {
                    // Completed: the new record, and the old one still beside it.
                    completed_at.get_or_insert(n);
                    assert_eq!(loaded.as_ref(), Some(&stored), "{name}, cut after {n}");
                    assert_eq!(stored.record, new);
                    if let Some(old) = &old {
                        assert_ne!(stored.slot, old.slot);
                        assert!(is_newer(stored.sequence, old.sequence));
                    }
                }
                Err(error) => {
                    // Cut: exactly the previous record (or none if there was none).
                    assert_eq!(error, StoreError::Flash(SimError::PowerCut));
                    assert_eq!(loaded, old, "{name}, cut after {n} bytes");
                    // And the next store, power back, succeeds.
                    let again = store(&mut flash, &new).unwrap();
                    assert_eq!(load(&flash), Some(again));
                }
            }
        }
        // The store completes only once every byte is done: the magic last.
        assert_eq!(completed_at, Some(STORE_WORK), "{name}");
    }
}

#[test]
fn a_cut_during_the_commit_word_never_validates_the_new_record() {
    // The four bytes of the magic, each half programmed in turn.
    let mut start = SimFlash::new();
    let old = store(&mut start, &record(5)).unwrap();
    for n in STORE_WORK - 4..STORE_WORK {
        let mut flash = start.clone();
        flash.cut_after(n);
        assert!(store(&mut flash, &record(6)).is_err());
        flash.power_on();
        let bytes = flash.sector_bytes(1 - old.slot).unwrap();
        let magic = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        assert_ne!(magic, MAGIC);
        // Everything after the magic was already written.
        assert_eq!(
            &bytes[4..RECORD_LEN],
            &encode_record(&record(6), old.sequence + 1)[4..]
        );
        assert_eq!(load(&flash), Some(old.clone()));
    }
}

/// A NOR flash in RAM of any geometry: program units of `W` bytes, read units of
/// `R` bytes, two erase units of `E` bytes. Programming only clears bits, as on the
/// chips; every write is logged as `(offset, length)`.
struct RamFlash<const W: usize, const R: usize, const E: usize> {
    bytes: Vec<u8>,
    writes: Vec<(u32, usize)>,
}

impl<const W: usize, const R: usize, const E: usize> RamFlash<W, R, E> {
    fn new() -> Self {
        RamFlash {
            bytes: vec![0xFF; 2 * E],
            writes: Vec::new(),
        }
    }
}

#[derive(Debug)]
struct RamError(NorFlashErrorKind);

impl NorFlashError for RamError {
    fn kind(&self) -> NorFlashErrorKind {
        self.0
    }
}

impl<const W: usize, const R: usize, const E: usize> ErrorType for RamFlash<W, R, E> {
    type Error = RamError;
}

impl<const W: usize, const R: usize, const E: usize> ReadNorFlash for RamFlash<W, R, E> {
    const READ_SIZE: usize = R;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), RamError> {
        embedded_storage::nor_flash::check_read(self, offset, bytes.len()).map_err(RamError)?;
        let at = offset as usize;
        bytes.copy_from_slice(&self.bytes[at..at + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        2 * E
    }
}

impl<const W: usize, const R: usize, const E: usize> NorFlash for RamFlash<W, R, E> {
    const WRITE_SIZE: usize = W;
    const ERASE_SIZE: usize = E;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), RamError> {
        embedded_storage::nor_flash::check_erase(self, from, to).map_err(RamError)?;
        self.bytes[from as usize..to as usize].fill(0xFF);
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), RamError> {
        embedded_storage::nor_flash::check_write(self, offset, bytes.len()).map_err(RamError)?;
        let at = offset as usize;
        for (dst, src) in self.bytes[at..at + bytes.len()].iter_mut().zip(bytes) {
            *dst &= src;
        }
        self.writes.push((offset, bytes.len()));
        Ok(())
    }
}

/// Three stores and loads on a flash of the given geometry: the slots alternate,
/// each record's bytes are exactly the board's (the same `encode_record`), the
/// padding to whole program units is left erased, and the last write of each
/// store is the commit unit at the slot's start.
fn round_trip<const W: usize, const R: usize, const E: usize>() {
    let mut flash = RamFlash::<W, R, E>::new();
    for k in 0..3u32 {
        let stored = store(&mut flash, &record(k)).unwrap();
        assert_eq!((stored.slot, stored.sequence), ((k % 2) as usize, k + 1));
        assert_eq!(
            load(&mut flash),
            Some(stored.clone()),
            "W {W}, R {R}, E {E}"
        );
        let at = slot_offset(flash.capacity(), stored.slot).unwrap() as usize;
        let bytes = &flash.bytes[at..at + RECORD_LEN];
        assert_eq!(bytes, &encode_record(&record(k), stored.sequence)[..]);
        let padded = RECORD_LEN.next_multiple_of(W.max(4));
        assert!(flash.bytes[at + RECORD_LEN..at + padded]
            .iter()
            .all(|&b| b == 0xFF));
        let &(commit_at, commit_len) = flash.writes.last().unwrap();
        assert_eq!(commit_at as usize, at);
        assert!(commit_len >= 4 && commit_len % W == 0 && commit_len <= MAX_UNIT);
    }
}

#[test]
fn any_nor_flash_geometry_keeps_the_record_format() {
    // Byte, half-word, word, double-word and 256-bit program units; small and
    // large erase units.
    round_trip::<1, 1, 4096>();
    round_trip::<2, 1, 4096>();
    round_trip::<4, 4, 2048>();
    round_trip::<8, 1, 8192>();
    round_trip::<16, 16, 4096>();
    round_trip::<32, 32, 131_072>();
    // Program units above MAX_UNIT, or halves too small for a record: refused,
    // nothing written.
    let mut big = RamFlash::<64, 1, 4096>::new();
    assert!(matches!(
        store(&mut big, &record(1)),
        Err(StoreError::Geometry)
    ));
    assert!(big.writes.is_empty());
    let mut small = RamFlash::<4, 1, 256>::new();
    assert!(matches!(
        store(&mut small, &record(1)),
        Err(StoreError::Geometry)
    ));
    assert_eq!(load(&mut small), None);
}
