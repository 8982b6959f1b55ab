//! Processor in the loop: the records that the firmware's binary `pil` (on QEMU's
//! `netduinoplus2`) and `host-sim run --firmware` exchange once per control tick
//! (`docs/pil.md`). The host is the firmware's board: it sends what the board's
//! sensors and UART would deliver ([`Sample`]) and gets back what the board's
//! timer and UART would be given ([`Drive`]).
//!
//! Fixed-size binary records, little-endian, each opening with a magic word and
//! [`VERSION`]:
//!
//! | record | from | bytes | fields after magic and version |
//! | --- | --- | --- | --- |
//! | [`Hello`] | firmware, once | [`Hello::LEN`] | the machine file's CRC-32 and length, the tick period in us, the machine file's path |
//! | [`Drive`] | firmware, each tick | [`Drive::LEN`] | tick number, TIM8's four compare values, its main output enable, how long the tick's task ran, the tick's status report, the UART bytes sent |
//! | [`Sample`] | host, each tick | [`Sample::LEN`] | tick number, the encoder counters and index latches, the mean currents, the supply, the E-stop, how late the next tick starts, the UART bytes received |
//!
//! Tick `n` (from 1): the firmware sends the [`Drive`] of tick `n - 1` (the
//! [`Hello`] before tick 1) and reads the [`Sample`] of tick `n`; each side
//! checks the other's magic, version and tick number. Every parse is
//! bounds-checked and returns a [`RecordError`], never panics.
//!
//! The machine's fingerprint is CRC-32/ISO-HDLC ([`crate::codec::crc::crc32`]) of
//! the machine file's bytes, with their count: the firmware's build computes it
//! from the file it compiles in, the host from the file it simulates.

use crate::codec::wire::{Reader, Writer};
use crate::protocol::StatusReport;

/// Version of the record layouts.
pub const VERSION: u16 = 3;

/// UART bytes one record carries at most, each way. At 115200 baud, 8N1, a UART
/// moves 11.5 bytes per 1 ms tick; 128 is room for a burst of ten times that.
pub const MAX_BYTES: usize = 128;

/// Bytes of the machine file's path a [`Hello`] carries (longer paths are cut).
pub const PATH_LEN: usize = 192;

/// Magic of [`Hello`]: `"PILH"`.
pub const HELLO_MAGIC: u32 = u32::from_le_bytes(*b"PILH");
/// Magic of [`Drive`]: `"PILD"`.
pub const DRIVE_MAGIC: u32 = u32::from_le_bytes(*b"PILD");
/// Magic of [`Sample`]: `"PILS"`.
pub const SAMPLE_MAGIC: u32 = u32::from_le_bytes(*b"PILS");

/// What is wrong with a record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecordError {
    /// Not the record's magic word.
    Magic,
    /// Another layout version.
    Version,
    /// Not the tick expected.
    Tick {
        /// The tick number expected.
        expected: u32,
        /// The tick number the record carries.
        got: u32,
    },
    /// Too short, or a byte count beyond [`MAX_BYTES`].
    Length,
    /// A field out of its range (a flag byte, a status report).
    Value,
}

impl core::fmt::Display for RecordError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RecordError::Magic => write!(f, "not the record's magic word"),
            RecordError::Version => write!(f, "another record version (this side: {VERSION})"),
            RecordError::Tick { expected, got } => {
                write!(f, "tick {got} where tick {expected} was due")
            }
            RecordError::Length => write!(f, "too short, or a byte count over {MAX_BYTES}"),
            RecordError::Value => write!(f, "a field out of its range"),
        }
    }
}

/// UART bytes of one tick: at most [`MAX_BYTES`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bytes {
    len: u8,
    data: [u8; MAX_BYTES],
}

impl Default for Bytes {
    fn default() -> Self {
        Bytes {
            len: 0,
            data: [0; MAX_BYTES],
        }
    }
}

impl Bytes {
    /// The bytes held.
    pub fn as_slice(&self) -> &[u8] {
        self.data.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// Append `b`; `false` if full.
    pub fn push(&mut self, b: u8) -> bool {
        match self.data.get_mut(usize::from(self.len)) {
            Some(slot) => {
                *slot = b;
                self.len += 1;
                true
            }
            None => false,
        }
    }

    /// Whether no more fits.
    pub fn is_full(&self) -> bool {
        usize::from(self.len) >= MAX_BYTES
    }

    fn write(&self, w: &mut Writer<'_>) {
        w.u8(self.len);
        w.bytes(&self.data);
    }

    fn read(r: &mut Reader<'_>) -> Result<Self, RecordError> {
        let len = r.u8().ok_or(RecordError::Length)?;
        let data = r.array::<MAX_BYTES>().ok_or(RecordError::Length)?;
        if usize::from(len) > MAX_BYTES {
            return Err(RecordError::Length);
        }
        Ok(Bytes { len, data })
    }
}

/// Magic and version, written.
fn write_head(w: &mut Writer<'_>, magic: u32) {
    w.u32(magic);
    w.u16(VERSION);
}

/// Magic and version, checked.
fn read_head(r: &mut Reader<'_>, magic: u32) -> Result<(), RecordError> {
    if r.u32().ok_or(RecordError::Length)? != magic {
        return Err(RecordError::Magic);
    }
    if r.u16().ok_or(RecordError::Length)? != VERSION {
        return Err(RecordError::Version);
    }
    Ok(())
}

/// The tick number, checked against `expected`.
fn read_tick(r: &mut Reader<'_>, expected: u32) -> Result<u32, RecordError> {
    let got = r.u32().ok_or(RecordError::Length)?;
    if got != expected {
        return Err(RecordError::Tick { expected, got });
    }
    Ok(got)
}

/// The firmware's first record: what it was built for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Hello {
    /// CRC-32/ISO-HDLC of the machine file's bytes.
    pub machine_crc: u32,
    /// The machine file's length, bytes.
    pub machine_len: u32,
    /// The control tick's period, us.
    pub tick_us: u32,
    /// The machine file's path as the build named it (UTF-8, cut at
    /// [`PATH_LEN`] bytes), its length first.
    pub path_len: u8,
    /// See `path_len`.
    pub path: [u8; PATH_LEN],
}

impl Hello {
    /// Record bytes: magic 4, version 2, CRC 4, length 4, tick 4, path 1 + 192.
    pub const LEN: usize = 4 + 2 + 4 + 4 + 4 + 1 + PATH_LEN;

    /// The record of a build for the file at `path` with these bytes' `crc` and
    /// `len`, ticking every `tick_us`.
    pub fn new(machine_crc: u32, machine_len: u32, tick_us: u32, path: &str) -> Self {
        let mut bytes = [0u8; PATH_LEN];
        let n = path.len().min(PATH_LEN);
        bytes[..n].copy_from_slice(&path.as_bytes()[..n]);
        Hello {
            machine_crc,
            machine_len,
            tick_us,
            path_len: n as u8,
            path: bytes,
        }
    }

    /// The machine file's path (lossy where a cut split a character).
    pub fn path_bytes(&self) -> &[u8] {
        self.path.get(..usize::from(self.path_len)).unwrap_or(&[])
    }

    /// Its bytes.
    pub fn to_bytes(&self) -> [u8; Hello::LEN] {
        let mut out = [0u8; Hello::LEN];
        let mut w = Writer::new(&mut out);
        write_head(&mut w, HELLO_MAGIC);
        w.u32(self.machine_crc);
        w.u32(self.machine_len);
        w.u32(self.tick_us);
        w.u8(self.path_len);
        w.bytes(&self.path);
        out
    }

    /// The record of `bytes`.
    pub fn parse(bytes: &[u8]) -> Result<Self, RecordError> {
        let mut r = Reader::new(bytes);
        read_head(&mut r, HELLO_MAGIC)?;
        let (Some(machine_crc), Some(machine_len), Some(tick_us), Some(path_len), Some(path)) =
            (r.u32(), r.u32(), r.u32(), r.u8(), r.array::<PATH_LEN>())
        else {
            return Err(RecordError::Length);
        };
        if usize::from(path_len) > PATH_LEN {
            return Err(RecordError::Length);
        }
        Ok(Hello {
            machine_crc,
            machine_len,
            tick_us,
            path_len,
            path,
        })
    }
}

/// What the firmware's tick gave its board: TIM8's compare values and main
/// output enable as the timer holds them after the tick, the tick's status
/// report (an observation for the host's summary and events, not an input of
/// the loop) and the UART bytes sent since the last record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drive {
    /// The tick these outputs are of (1 for the first).
    pub tick: u32,
    /// Compare values CH1..CH4: motor 1 IN1, IN2, motor 2 IN1, IN2; each input
    /// high for `compare / ARR` of the PWM period (`shared::drive`).
    pub compare: [u16; 4],
    /// The timer's main output enable (MOE): off, every input low (coast).
    pub enabled: bool,
    /// How long the tick's control task ran, from its first instruction to the
    /// end of its step (the record exchange at its start included), in ns of the
    /// firmware's clock. On QEMU with `-icount shift=0` one instruction is 1 ns,
    /// so this is the task's instructions.
    pub busy_ns: u32,
    /// The tick's status report.
    pub status: StatusReport,
    /// UART bytes sent.
    pub tx: Bytes,
}

impl Drive {
    /// Record bytes: magic 4, version 2, tick 4, compare 8, enable 1, busy 4,
    /// status 68, bytes 1 + 128.
    pub const LEN: usize = 4 + 2 + 4 + 8 + 1 + 4 + StatusReport::LEN + 1 + MAX_BYTES;

    /// Its bytes.
    pub fn to_bytes(&self) -> [u8; Drive::LEN] {
        let mut out = [0u8; Drive::LEN];
        let mut w = Writer::new(&mut out);
        write_head(&mut w, DRIVE_MAGIC);
        w.u32(self.tick);
        for c in self.compare {
            w.u16(c);
        }
        w.u8(u8::from(self.enabled));
        w.u32(self.busy_ns);
        w.bytes(&self.status.to_bytes());
        self.tx.write(&mut w);
        out
    }

    /// The record of `bytes`, which must be of tick `tick`.
    pub fn parse(bytes: &[u8], tick: u32) -> Result<Self, RecordError> {
        let mut r = Reader::new(bytes);
        read_head(&mut r, DRIVE_MAGIC)?;
        let tick = read_tick(&mut r, tick)?;
        let mut compare = [0u16; 4];
        for c in compare.iter_mut() {
            *c = r.u16().ok_or(RecordError::Length)?;
        }
        let enabled = match r.u8().ok_or(RecordError::Length)? {
            0 => false,
            1 => true,
            _ => return Err(RecordError::Value),
        };
        let busy_ns = r.u32().ok_or(RecordError::Length)?;
        let status = r
            .array::<{ StatusReport::LEN }>()
            .ok_or(RecordError::Length)?;
        let status = StatusReport::from_bytes(&status).map_err(|_| RecordError::Value)?;
        let tx = Bytes::read(&mut r)?;
        Ok(Drive {
            tick,
            compare,
            enabled,
            busy_ns,
            status,
            tx,
        })
    }
}

/// What the board's sensors and UART deliver at a tick: the controller's
/// `Inputs` but the command and the timing (the firmware's link and clock give
/// those), and the UART bytes received since the last tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// The tick this sample is for (1 for the first).
    pub tick: u32,
    /// Encoder counters (`Inputs::encoder`).
    pub encoder: [u32; 2],
    /// Index latches (`Inputs::index`).
    pub index: [Option<u32>; 2],
    /// Mean winding currents over the tick just ended, A (`Inputs::current`).
    pub current: [f32; 2],
    /// Supply voltage, V.
    pub supply_voltage: f32,
    /// The E-stop circuit open.
    pub estop: bool,
    /// How late the next tick starts, us, below [`MAX_LATE_US`]: the firmware
    /// keeps the core busy after this tick until that long past the next
    /// tick's timer event (an injected starved loop), so that its own clock
    /// measures the next tick late.
    pub next_late_us: u16,
    /// UART bytes received.
    pub rx: Bytes,
}

/// The largest [`Sample::next_late_us`] (exclusive): less than one tick of the
/// fastest control rate, so that no tick is skipped.
pub const MAX_LATE_US: u16 = 1000;

/// Flag bits of [`Sample`]: index latched on rotor 1, on rotor 2, E-stop open.
const INDEX_1: u8 = 1 << 0;
const INDEX_2: u8 = 1 << 1;
const ESTOP: u8 = 1 << 2;

impl Sample {
    /// Record bytes: magic 4, version 2, tick 4, encoders 8, flags 1, index 8,
    /// currents 8, supply 4, next tick's lateness 2, bytes 1 + 128.
    pub const LEN: usize = 4 + 2 + 4 + 8 + 1 + 8 + 8 + 4 + 2 + 1 + MAX_BYTES;

    /// Its bytes.
    pub fn to_bytes(&self) -> [u8; Sample::LEN] {
        let mut out = [0u8; Sample::LEN];
        let mut w = Writer::new(&mut out);
        write_head(&mut w, SAMPLE_MAGIC);
        w.u32(self.tick);
        let mut flags = 0;
        for (k, bit) in [INDEX_1, INDEX_2].into_iter().enumerate() {
            if self.index[k].is_some() {
                flags |= bit;
            }
        }
        if self.estop {
            flags |= ESTOP;
        }
        for e in self.encoder {
            w.u32(e);
        }
        w.u8(flags);
        for i in self.index {
            w.u32(i.unwrap_or(0));
        }
        for i in self.current {
            w.f32(i);
        }
        w.f32(self.supply_voltage);
        w.u16(self.next_late_us);
        self.rx.write(&mut w);
        out
    }

    /// The record of `bytes`, which must be of tick `tick`.
    pub fn parse(bytes: &[u8], tick: u32) -> Result<Self, RecordError> {
        let mut r = Reader::new(bytes);
        read_head(&mut r, SAMPLE_MAGIC)?;
        let tick = read_tick(&mut r, tick)?;
        let (Some(e1), Some(e2), Some(flags), Some(i1), Some(i2)) =
            (r.u32(), r.u32(), r.u8(), r.u32(), r.u32())
        else {
            return Err(RecordError::Length);
        };
        if flags & !(INDEX_1 | INDEX_2 | ESTOP) != 0 {
            return Err(RecordError::Value);
        }
        let (Some(c1), Some(c2), Some(supply_voltage), Some(next_late_us)) =
            (r.f32(), r.f32(), r.f32(), r.u16())
        else {
            return Err(RecordError::Length);
        };
        if next_late_us >= MAX_LATE_US {
            return Err(RecordError::Value);
        }
        let rx = Bytes::read(&mut r)?;
        Ok(Sample {
            tick,
            encoder: [e1, e2],
            index: [
                (flags & INDEX_1 != 0).then_some(i1),
                (flags & INDEX_2 != 0).then_some(i2),
            ],
            current: [c1, c2],
            supply_voltage,
            estop: flags & ESTOP != 0,
            next_late_us,
            rx,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::{Faults, State};
    use crate::protocol::link::no_telemetry;

    fn status() -> StatusReport {
        StatusReport {
            uptime_ms: 7,
            state: State::Running,
            faults: Faults::default(),
            telemetry: no_telemetry(),
            rx_dropped: 0,
        }
    }

    #[test]
    fn records_read_back_and_refuse_what_is_wrong() {
        let mut rx = Bytes::default();
        for b in b"frame" {
            assert!(rx.push(*b));
        }
        let s = Sample {
            tick: 3,
            encoder: [1, u32::MAX],
            index: [None, Some(4095)],
            current: [0.5, -0.25],
            supply_voltage: 12.0,
            estop: true,
            next_late_us: 300,
            rx,
        };
        let bytes = s.to_bytes();
        assert_eq!(Sample::parse(&bytes, 3), Ok(s));
        assert_eq!(
            Sample::parse(&bytes, 4),
            Err(RecordError::Tick {
                expected: 4,
                got: 3
            })
        );
        assert_eq!(Sample::parse(&bytes[..20], 3), Err(RecordError::Length));
        let mut bad = bytes;
        bad[0] ^= 1;
        assert_eq!(Sample::parse(&bad, 3), Err(RecordError::Magic));
        let mut bad = bytes;
        bad[4] = 9;
        assert_eq!(Sample::parse(&bad, 3), Err(RecordError::Version));
        let mut bad = bytes;
        bad[4 + 2 + 4 + 8] = 0x80;
        assert_eq!(Sample::parse(&bad, 3), Err(RecordError::Value));
        let late = 4 + 2 + 4 + 8 + 1 + 8 + 8 + 4;
        let mut bad = bytes;
        bad[late..late + 2].copy_from_slice(&MAX_LATE_US.to_le_bytes());
        assert_eq!(Sample::parse(&bad, 3), Err(RecordError::Value));

        let d = Drive {
            tick: 9,
            compare: [4200, 3000, 0, 0],
            enabled: true,
            busy_ns: 1_476,
            status: status(),
            tx: Bytes::default(),
        };
        let bytes = d.to_bytes();
        assert_eq!(Drive::parse(&bytes, 9), Ok(d));
        let mut bad = bytes;
        bad[Drive::LEN - MAX_BYTES - 1] = MAX_BYTES as u8 + 1;
        assert_eq!(Drive::parse(&bad, 9), Err(RecordError::Length));

        let h = Hello::new(0xDEAD_BEEF, 1234, 1000, "../examples/vibro-driver.toml");
        assert_eq!(Hello::parse(&h.to_bytes()), Ok(h));
        assert_eq!(h.path_bytes(), b"../examples/vibro-driver.toml");
        assert_eq!(Hello::parse(&d.to_bytes()), Err(RecordError::Magic));
    }
}
