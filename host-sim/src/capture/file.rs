//! The capture file: `# key: value` header lines, then CSV, a row per control
//! tick (docs/protocol.md, "Capture file").
//!
//! ```text
//! # vibro-driver capture, format 1
//! # machine_file: 7e368ed6 7459
//! # tick_s: 0.001
//! # trigger: command
//! # start_state: idle
//! # start_speed_rpm: 0 0
//! # start_index: 8192 -
//! # start_uptime_ms: 5123
//! # tuning_table: 300:90:270 3000:95:265
//! # ended_early: no
//! # rows: 2000
//! # rows_crc32: 1a2b3c4d
//! tick,t_s,command,direction,speed_rpm,offset_deg,started,count1,...
//! ```
//!
//! `rows_crc32` is the CRC-32/ISO-HDLC of the column line and every row, each
//! with its line feed: a file edited or cut after it was written is refused
//! on reading, with what is wrong. Every value is written so that it reads
//! back to the bit (`f32`s in their shortest exact form; a NaN as `NaN`).

use std::fmt::Write as _;
use std::path::Path;

use shared::capture::{
    duty_raw, CaptureInfo, CommandKind, MachineFingerprint, Record, Start, Trigger, DUTY_SCALE,
};
use shared::codec::crc::crc32;
use shared::controller::{Bridge, Command, Direction, Faults, State, TuningTable};

use crate::failure::Failure;

/// The first line.
pub const MAGIC: &str = "# vibro-driver capture, format 1";

/// The column line.
pub const COLUMNS: &str = "tick,t_s,command,direction,speed_rpm,offset_deg,started,count1,count2,index1,index2,current1_a,current2_a,supply_v,estop,late_us,busy_us,state,faults,duty1,duty2";

/// What a capture says besides its rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// The machine file the board's firmware was built for.
    pub machine: MachineFingerprint,
    /// The control tick, s.
    pub tick_s: f64,
    /// What started the recording.
    pub trigger: Trigger,
    /// The controller before the first row.
    pub start: Start,
    /// The tuning table in use on the board: (speed rpm, right deg, left deg).
    pub tuning: Vec<(f32, f32, f32)>,
    /// The capture ended before its window (more run commands than the board
    /// keeps).
    pub ended_early: bool,
}

/// A capture: its header, and a record per tick with its command.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureFile {
    /// Everything besides the rows.
    pub header: Header,
    /// The ticks, in order.
    pub records: Vec<Record>,
    /// The command each tick took, whole (a record keeps the kind only).
    pub commands: Vec<Option<Command>>,
}

impl CaptureFile {
    /// The capture the device reported: `info`, its `records` (all of them,
    /// from 0) and the table the device uses. `Err` says what does not fit
    /// (a run command without its values).
    pub fn from_device(
        info: &CaptureInfo,
        records: Vec<Record>,
        tuning: &TuningTable,
    ) -> Result<CaptureFile, String> {
        let mut commands = vec![None; records.len()];
        for entry in &info.commands {
            let k = usize::from(entry.record);
            let kind = records.get(k).and_then(|r| r.command);
            if kind != Some(CommandKind::of(&entry.command)) {
                return Err(format!(
                    "the capture's command list names a {} at tick {k}, which its record does not show",
                    CommandKind::of(&entry.command).name()
                ));
            }
            commands[k] = Some(entry.command);
        }
        for (k, r) in records.iter().enumerate() {
            commands[k] = match (r.command, commands[k]) {
                (Some(kind), None) if kind.has_values() => {
                    return Err(format!(
                        "tick {k} took a {} whose values the capture's command list lacks",
                        kind.name()
                    ))
                }
                (Some(kind), None) => Some(plain_command(kind)),
                (_, c) => c,
            };
        }
        Ok(CaptureFile {
            header: Header {
                machine: info.machine,
                tick_s: f64::from(info.tick_us) * 1e-6,
                trigger: info.trigger,
                start: info.start,
                tuning: tuning
                    .rows()
                    .iter()
                    .map(|r| (r.speed_rpm, r.right_offset_deg, r.left_offset_deg))
                    .collect(),
                ended_early: info.ended_early,
            },
            records,
            commands,
        })
    }

    /// What a capture holds, for people: `2000 ticks (2 s) from uptime 0.002 s,
    /// trigger command; states idle -> starting -> running` (and whether it ended
    /// early).
    pub fn contents(&self) -> String {
        let h = &self.header;
        let n = self.records.len();
        format!(
            "{} ({} s) from uptime {} s, trigger {}{}; states {}",
            crate::numbers::count(n, "tick"),
            crate::numbers::sig(n as f64 * h.tick_s),
            crate::numbers::fixed(f64::from(h.start.uptime_ms) * 1e-3 + h.tick_s, 3),
            h.trigger.name(),
            if h.ended_early {
                format!(
                    "; ended early: more than {} run commands",
                    shared::capture::MAX_COMMANDS
                )
            } else {
                String::new()
            },
            self.state_path()
        )
    }

    /// The states the capture went through, in order: `idle -> starting -> running`.
    fn state_path(&self) -> String {
        let mut path = vec![self.header.start.state.name()];
        for r in &self.records {
            if path.last() != Some(&r.state.name()) {
                path.push(r.state.name());
            }
        }
        path.join(" -> ")
    }

    /// The tuning table of the header.
    pub fn tuning_table(&self) -> Result<TuningTable, String> {
        TuningTable::from_rows(&self.header.tuning).map_err(|e| e.to_string())
    }

    /// The file's text.
    pub fn to_text(&self) -> String {
        let mut rows = String::new();
        rows.push_str(COLUMNS);
        rows.push('\n');
        for (k, (r, c)) in self.records.iter().zip(&self.commands).enumerate() {
            row(&mut rows, k, self.header.tick_s, r, c.as_ref());
        }
        let h = &self.header;
        let mut text = String::new();
        let _ = writeln!(text, "{MAGIC}");
        let _ = writeln!(
            text,
            "# machine_file: {:08x} {}",
            h.machine.crc32, h.machine.len
        );
        let _ = writeln!(text, "# tick_s: {}", h.tick_s);
        let _ = writeln!(text, "# trigger: {}", h.trigger.name());
        let _ = writeln!(text, "# start_state: {}", h.start.state.name());
        let _ = writeln!(
            text,
            "# start_speed_rpm: {} {}",
            num(h.start.speed_rpm[0]),
            num(h.start.speed_rpm[1])
        );
        let index = h
            .start
            .index
            .map(|i| i.map_or("-".to_string(), |c| c.to_string()));
        let _ = writeln!(text, "# start_index: {} {}", index[0], index[1]);
        let _ = writeln!(text, "# start_uptime_ms: {}", h.start.uptime_ms);
        let table: Vec<String> = h
            .tuning
            .iter()
            .map(|(s, r, l)| format!("{}:{}:{}", num(*s), num(*r), num(*l)))
            .collect();
        let _ = writeln!(text, "# tuning_table: {}", table.join(" "));
        let _ = writeln!(
            text,
            "# ended_early: {}",
            if h.ended_early { "yes" } else { "no" }
        );
        let _ = writeln!(text, "# rows: {}", self.records.len());
        let _ = writeln!(text, "# rows_crc32: {:08x}", crc32(rows.as_bytes()));
        text.push_str(&rows);
        text
    }

    /// The capture in `path`; every mistake is a usage failure naming the
    /// file, the line and what is wrong.
    pub fn read(path: &Path) -> Result<CaptureFile, Failure> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Failure::usage(format!("{}: cannot read: {e}", path.display())))?;
        CaptureFile::parse(&text).map_err(|e| Failure::usage(format!("{}: {e}", path.display())))
    }

    /// The capture of `text`.
    pub fn parse(text: &str) -> Result<CaptureFile, String> {
        let mut lines = text.split_inclusive('\n').enumerate().peekable();
        match lines.next() {
            Some((_, l)) if l.trim_end() == MAGIC => {}
            _ => {
                return Err(format!(
                    "line 1: not a capture file (its first line must be `{MAGIC}`, as `host-sim device capture` writes it)"
                ))
            }
        }
        let mut keys: Vec<(usize, String, String)> = Vec::new();
        while let Some((n, l)) = lines.next_if(|(_, l)| l.starts_with('#')) {
            let body = l.trim_end().trim_start_matches('#').trim();
            let (k, v) = body
                .split_once(':')
                .ok_or_else(|| format!("line {}: `{body}` is no `key: value`", n + 1))?;
            keys.push((n + 1, k.trim().to_string(), v.trim().to_string()));
        }
        let header_keys = Keys(keys);
        let rows_text: String = lines.clone().map(|(_, l)| l).collect();
        let crc = header_keys.hex("rows_crc32")?;
        let count: usize = header_keys.parse("rows")?;
        let header = header_keys.header()?;
        let mut records = Vec::new();
        let mut commands = Vec::new();
        let mut columns_seen = false;
        for (n, l) in lines {
            let line = l.trim_end_matches(['\n', '\r']);
            if !columns_seen {
                if line != COLUMNS {
                    return Err(format!(
                        "line {}: the column line is not `{COLUMNS}`",
                        n + 1
                    ));
                }
                columns_seen = true;
                continue;
            }
            let (r, c) =
                parse_row(line, records.len()).map_err(|e| format!("line {}: {e}", n + 1))?;
            records.push(r);
            commands.push(c);
        }
        if !columns_seen {
            return Err("no column line and no rows: the file is cut short".into());
        }
        if records.len() != count {
            return Err(format!(
                "{} rows, but its header says {count}: the file is cut short or rows were added; capture it again",
                records.len()
            ));
        }
        let actual = crc32(rows_text.as_bytes());
        if actual != crc {
            return Err(format!(
                "its rows do not match their checksum (rows_crc32 {crc:08x}, the rows give {actual:08x}): the file was edited or damaged after it was written; capture it again"
            ));
        }
        if records.is_empty() {
            return Err("no rows: the capture recorded no tick".into());
        }
        Ok(CaptureFile {
            header,
            records,
            commands,
        })
    }
}

/// The command of a kind without values.
fn plain_command(kind: CommandKind) -> Command {
    match kind {
        CommandKind::Heartbeat => Command::Heartbeat,
        CommandKind::Stop => Command::Stop,
        CommandKind::ResetFaults => Command::ResetFaults,
        // Not called for these (they carry values).
        CommandKind::Travel | CommandKind::HoldOffset => Command::Heartbeat,
    }
}

/// One row of tick `k`.
fn row(out: &mut String, k: usize, tick_s: f64, r: &Record, c: Option<&Command>) {
    let (command, direction, speed, offset) = match c {
        None => ("", String::new(), String::new(), String::new()),
        Some(Command::Travel {
            direction,
            speed_rpm,
        }) => (
            "travel",
            match direction {
                Direction::Right => "right".to_string(),
                Direction::Left => "left".to_string(),
            },
            num(*speed_rpm),
            String::new(),
        ),
        Some(Command::HoldOffset {
            speed_rpm,
            offset_deg,
        }) => ("hold", String::new(), num(*speed_rpm), num(*offset_deg)),
        Some(other) => (
            CommandKind::of(other).name(),
            String::new(),
            String::new(),
            String::new(),
        ),
    };
    let started: Vec<&str> = [
        (r.self_test_started, "self_test"),
        (r.identify_started, "identify"),
        (r.tuning_changed, "tuning"),
    ]
    .into_iter()
    .filter_map(|(on, name)| on.then_some(name))
    .collect();
    let index = r.index.map(|i| i.map_or(String::new(), |c| c.to_string()));
    let duty = r.duty_raw.map(|d| match d {
        None => "off".to_string(),
        Some(raw) => num(f32::from(raw) / DUTY_SCALE),
    });
    let faults: Vec<&str> = r.faults.names().collect();
    let _ = writeln!(
        out,
        "{k},{},{command},{direction},{speed},{offset},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
        round9(k as f64 * tick_s),
        started.join("+"),
        r.encoder[0],
        r.encoder[1],
        index[0],
        index[1],
        num(r.current[0]),
        num(r.current[1]),
        num(r.supply_voltage),
        u8::from(r.estop),
        r.timing_us[0],
        r.timing_us[1],
        r.state.name(),
        faults.join("+"),
        duty[0],
        duty[1],
    );
}

/// `x` in its shortest form that reads back to the same bits (a NaN to a NaN,
/// of no particular sign or payload): plain digits for
/// magnitudes from 1e-4 to 1e9 (and 0), else with an exponent (`2.7e-44`).
fn num(x: f32) -> String {
    let a = x.abs();
    if a == 0.0 || !a.is_finite() || (1e-4..1e9).contains(&a) {
        x.to_string()
    } else {
        format!("{x:e}")
    }
}

/// `x` to 9 decimals, as short as it goes.
fn round9(x: f64) -> String {
    let s = format!("{x:.9}");
    let s = s.trim_end_matches('0');
    s.trim_end_matches('.').to_string()
}

/// A field of a row, parsed, or what is wrong with it.
fn field<T: std::str::FromStr>(name: &str, v: &str, what: &str) -> Result<T, String> {
    v.parse()
        .map_err(|_| format!("column {name}: `{v}` is not {what}"))
}

/// A row's fields, the tick `k` it must carry.
fn parse_row(line: &str, k: usize) -> Result<(Record, Option<Command>), String> {
    let f: Vec<&str> = line.split(',').collect();
    let n = COLUMNS.split(',').count();
    if f.len() != n {
        return Err(format!("{} fields, the columns are {n}", f.len()));
    }
    let tick: usize = field("tick", f[0], "a tick number")?;
    if tick != k {
        return Err(format!(
            "column tick: {tick} where tick {k} was due (rows missing or out of order)"
        ));
    }
    let _: f64 = field("t_s", f[1], "a number of seconds")?;
    let speed = || field::<f32>("speed_rpm", f[4], "a speed in rpm");
    let command = match f[2] {
        "" => None,
        "travel" => Some(Command::Travel {
            direction: match f[3] {
                "right" => Direction::Right,
                "left" => Direction::Left,
                other => return Err(format!("column direction: `{other}` is not right or left")),
            },
            speed_rpm: speed()?,
        }),
        "hold" => Some(Command::HoldOffset {
            speed_rpm: speed()?,
            offset_deg: field("offset_deg", f[5], "an offset in degrees")?,
        }),
        other => Some(
            match CommandKind::ALL.into_iter().find(|c| c.name() == other) {
                Some(kind) if !kind.has_values() => plain_command(kind),
                _ => {
                    return Err(format!(
                        "column command: `{other}` is none of heartbeat, stop, reset, travel, hold (or empty)"
                    ))
                }
            },
        ),
    };
    let mut started = [false; 3];
    for s in f[6].split('+').filter(|s| !s.is_empty()) {
        let i = ["self_test", "identify", "tuning"]
            .iter()
            .position(|n| *n == s)
            .ok_or_else(|| {
                format!("column started: `{s}` is none of self_test, identify, tuning")
            })?;
        started[i] = true;
    }
    let count = |name: &str, v: &str| field::<u32>(name, v, "a counter value (0 to 4294967295)");
    let index = |name: &str, v: &str| {
        if v.is_empty() {
            Ok(None)
        } else {
            count(name, v).map(Some)
        }
    };
    let number = |name: &str, v: &str| field::<f32>(name, v, "a number");
    let micros =
        |name: &str, v: &str| field::<u16>(name, v, "a whole number of microseconds (0 to 65535)");
    let duty = |name: &str, v: &str| -> Result<Option<i16>, String> {
        if v == "off" {
            return Ok(None);
        }
        let d: f32 = field(name, v, "a duty in [-1, 1] or off")?;
        if !(-1.0..=1.0).contains(&d) {
            return Err(format!("column {name}: {d} is outside [-1, 1]"));
        }
        Ok(duty_raw(Bridge::Driven(d)))
    };
    let state = State::from_name(f[17]).ok_or_else(|| {
        format!(
            "column state: `{}` is no state (idle, starting, running, stopping, fault, self_test, identify)",
            f[17]
        )
    })?;
    let mut faults = Faults::NONE;
    for name in f[18].split('+').filter(|s| !s.is_empty()) {
        let (flag, _) = Faults::ALL
            .into_iter()
            .find(|(_, n)| *n == name)
            .ok_or_else(|| format!("column faults: `{name}` is no fault"))?;
        faults = Faults::from_bits(faults.bits() | flag.bits());
    }
    let record = Record {
        encoder: [count("count1", f[7])?, count("count2", f[8])?],
        index: [index("index1", f[9])?, index("index2", f[10])?],
        current: [number("current1_a", f[11])?, number("current2_a", f[12])?],
        supply_voltage: number("supply_v", f[13])?,
        estop: match f[14] {
            "0" => false,
            "1" => true,
            other => return Err(format!("column estop: `{other}` is not 0 or 1")),
        },
        command: command.as_ref().map(CommandKind::of),
        self_test_started: started[0],
        identify_started: started[1],
        tuning_changed: started[2],
        timing_us: [micros("late_us", f[15])?, micros("busy_us", f[16])?],
        duty_raw: [duty("duty1", f[19])?, duty("duty2", f[20])?],
        state,
        faults,
    };
    Ok((record, command))
}

/// The header's `key: value` lines, with their line numbers.
struct Keys(Vec<(usize, String, String)>);

impl Keys {
    fn get(&self, key: &str) -> Result<(usize, &str), String> {
        self.0
            .iter()
            .find(|(_, k, _)| k == key)
            .map(|(n, _, v)| (*n, v.as_str()))
            .ok_or_else(|| format!("its header has no `# {key}:` line"))
    }

    fn parse<T: std::str::FromStr>(&self, key: &str) -> Result<T, String> {
        let (n, v) = self.get(key)?;
        v.parse()
            .map_err(|_| format!("line {n}: {key}: `{v}` is not a valid value"))
    }

    fn hex(&self, key: &str) -> Result<u32, String> {
        let (n, v) = self.get(key)?;
        u32::from_str_radix(v, 16)
            .map_err(|_| format!("line {n}: {key}: `{v}` is not 8 hexadecimal digits"))
    }

    fn header(&self) -> Result<Header, String> {
        let (n, m) = self.get("machine_file")?;
        let bad_machine = || {
            format!("line {n}: machine_file: `{m}` is not `CRC32 BYTES` (8 hex digits, a length)")
        };
        let (crc, len) = m.split_once(' ').ok_or_else(bad_machine)?;
        let machine = MachineFingerprint {
            crc32: u32::from_str_radix(crc, 16).map_err(|_| bad_machine())?,
            len: len.trim().parse().map_err(|_| bad_machine())?,
        };
        let tick_s: f64 = self.parse("tick_s")?;
        if !(tick_s > 0.0 && tick_s < 1.0) {
            let (n, _) = self.get("tick_s")?;
            return Err(format!(
                "line {n}: tick_s: {tick_s} is no control tick (above 0, below 1 s)"
            ));
        }
        let (n, t) = self.get("trigger")?;
        let trigger = Trigger::ALL
            .into_iter()
            .find(|x| x.name() == t)
            .ok_or_else(|| {
                format!("line {n}: trigger: `{t}` is none of now, command, state, fault")
            })?;
        let (n, s) = self.get("start_state")?;
        let state = State::from_name(s)
            .ok_or_else(|| format!("line {n}: start_state: `{s}` is no state"))?;
        let pair = |key: &str| -> Result<(usize, [String; 2]), String> {
            let (n, v) = self.get(key)?;
            let parts: Vec<&str> = v.split_whitespace().collect();
            match parts.as_slice() {
                [a, b] => Ok((n, [a.to_string(), b.to_string()])),
                _ => Err(format!("line {n}: {key}: `{v}` is not two values")),
            }
        };
        let (n, speeds) = pair("start_speed_rpm")?;
        let mut speed_rpm = [0.0f32; 2];
        for k in 0..2 {
            speed_rpm[k] = speeds[k].parse().map_err(|_| {
                format!("line {n}: start_speed_rpm: `{}` is not a number", speeds[k])
            })?;
        }
        let (n, latches) = pair("start_index")?;
        let mut index = [None; 2];
        for k in 0..2 {
            if latches[k] != "-" {
                index[k] = Some(latches[k].parse().map_err(|_| {
                    format!(
                        "line {n}: start_index: `{}` is neither a count nor -",
                        latches[k]
                    )
                })?);
            }
        }
        let uptime_ms: u32 = self.parse("start_uptime_ms")?;
        let (n, table) = self.get("tuning_table")?;
        let mut tuning = Vec::new();
        for row in table.split_whitespace() {
            let v: Vec<f32> = row
                .split(':')
                .map(|x| x.parse::<f32>())
                .collect::<Result<_, _>>()
                .map_err(|_| format!("line {n}: tuning_table: `{row}` is not SPEED:RIGHT:LEFT"))?;
            match v.as_slice() {
                [s, r, l] => tuning.push((*s, *r, *l)),
                _ => {
                    return Err(format!(
                        "line {n}: tuning_table: `{row}` is not SPEED:RIGHT:LEFT"
                    ))
                }
            }
        }
        TuningTable::<{ shared::controller::MAX_TUNING_ROWS }>::from_rows(&tuning)
            .map_err(|e| format!("line {n}: tuning_table: {e}"))?;
        let (n, e) = self.get("ended_early")?;
        let ended_early = match e {
            "yes" => true,
            "no" => false,
            _ => return Err(format!("line {n}: ended_early: `{e}` is not yes or no")),
        };
        Ok(Header {
            machine,
            tick_s,
            trigger,
            start: Start {
                state,
                speed_rpm,
                index,
                uptime_ms,
            },
            tuning,
            ended_early,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A capture of `n` ticks with every kind of value a record holds.
    fn sample(n: usize) -> CaptureFile {
        let values = [
            0.0f32,
            -0.0,
            1e-44,
            2.5e-7,
            0.1,
            11.9,
            1e12,
            f32::NAN,
            -3.25,
        ];
        let records: Vec<Record> = (0..n)
            .map(|k| Record {
                encoder: [k as u32 * 97, u32::MAX - k as u32],
                index: [(k % 3 == 0).then_some(k as u32 * 97 + 5), None],
                current: [values[k % values.len()], -values[(k + 4) % values.len()]],
                supply_voltage: 12.0 - k as f32 * 1e-3,
                estop: k % 5 == 0,
                command: (k == 1).then_some(CommandKind::HoldOffset),
                self_test_started: k == 2,
                identify_started: k == 3,
                tuning_changed: false,
                timing_us: [k as u16, 65535],
                duty_raw: [Some(k as i16 - 16), (k % 2 == 0).then_some(-32767)],
                state: State::ALL[k % State::ALL.len()],
                faults: Faults::from_bits((k as u16) & 0x3FF),
            })
            .collect();
        let mut commands = vec![None; n];
        commands[1] = Some(Command::HoldOffset {
            speed_rpm: 2999.5,
            offset_deg: 1e-20,
        });
        CaptureFile {
            header: Header {
                machine: MachineFingerprint {
                    crc32: 0xabc,
                    len: 9,
                },
                tick_s: 0.001,
                trigger: Trigger::State,
                start: Start {
                    state: State::Idle,
                    speed_rpm: [2.7e-44, -0.0],
                    index: [Some(4096), None],
                    uptime_ms: 77,
                },
                tuning: vec![(2500.0, 80.0, 280.0), (3000.0, 86.8, 273.3)],
                ended_early: true,
            },
            records,
            commands,
        }
    }

    /// Written and read back: the same capture to the bit (NaN currents and
    /// subnormal speeds included), and the same text again.
    #[test]
    fn a_capture_reads_back_to_the_bit() {
        let c = sample(40);
        let text = c.to_text();
        let back = CaptureFile::parse(&text).expect("reads");
        assert_eq!(back.to_text(), text);
        // Every NaN reads back as the NaN the parser gives (its sign and
        // payload mean nothing to the controller).
        let canonical = |r: &Record| {
            let mut r = *r;
            r.current = r.current.map(|i| if i.is_nan() { f32::NAN } else { i });
            r.to_bytes()
        };
        for (a, b) in c.records.iter().zip(&back.records) {
            assert_eq!(canonical(a), b.to_bytes());
        }
        assert_eq!(back.commands, c.commands);
        assert_eq!(
            back.header.start.speed_rpm[0].to_bits(),
            2.7e-44f32.to_bits()
        );
        assert!(text.contains("# start_speed_rpm: 2.7e-44 -0"), "{text}");
    }

    /// A bad value names its line and column and what is allowed.
    #[test]
    fn a_bad_value_names_its_line_and_column() {
        let text = sample(3).to_text();
        let bad = text.replace(",starting,", ",sprinting,");
        let e = CaptureFile::parse(&bad).unwrap_err();
        assert!(
            e.contains("line 15: column state: `sprinting` is no state"),
            "{e}"
        );
        let e = CaptureFile::parse(&text.replace("# tick_s: 0.001", "# tick_s: 2")).unwrap_err();
        assert!(e.contains("line 3: tick_s: 2 is no control tick"), "{e}");
    }
}
