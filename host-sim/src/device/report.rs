//! What `host-sim device` prints: a status report as aligned lines, a telemetry
//! frame as one readable line or one CSV row, a self-test result per rotor.

use shared::controller::{Faults, State};

use shared::controller::self_test::{RotorSelfTest, SelfTestReport, SelfTestStatus};
use shared::protocol::link::no_telemetry;
use shared::protocol::StatusReport;

use crate::numbers::{decimals, fixed};

/// Decimals of the telemetry's `f32` fields in the CSV and the live page's frames,
/// by unit: each value is rounded to them and written in its shortest form
/// (`3000.091`, `0`; never a 45-digit subnormal nor `-0`). Finer than the board
/// measures: an encoder count is 0.088 deg at 4096 counts a turn, a 12-bit ADC
/// step 8 mA and 9 mV (`firmware/src/sense.rs`), a PWM step 1/4200 of the duty.
pub const RPM_PLACES: usize = 3;
/// Degrees: 0.001 deg.
pub const DEG_PLACES: usize = 3;
/// Amperes: 10 uA.
pub const AMPERE_PLACES: usize = 5;
/// Volts: 1 mV.
pub const VOLT_PLACES: usize = 3;
/// Duty, in [-1, 1]: 1e-5.
pub const DUTY_PLACES: usize = 5;

/// A telemetry field rounded to `places` decimals, in its shortest form.
pub fn field(x: f32, places: usize) -> String {
    decimals(f64::from(x), places)
}

/// The fault names, `none` when there is none.
pub fn faults_text(faults: Faults) -> String {
    let names: Vec<&str> = faults.names().collect();
    if names.is_empty() {
        "none".into()
    } else {
        names.join(" ")
    }
}

/// A status report, one field per line.
pub fn status_text(s: &StatusReport) -> String {
    let t = &s.telemetry;
    let mut flags = Vec::new();
    if t.phase_valid {
        flags.push("phase_valid");
    }
    if t.phase_loop_closed {
        flags.push("phase_loop_closed");
    }
    if t.command_rejected {
        flags.push("command_rejected");
    }
    let flags = if flags.is_empty() {
        "none".to_string()
    } else {
        flags.join(" ")
    };
    let f = |x: f32, places: usize| fixed(f64::from(x), places);
    format!(
        "state           {}\n\
         faults          {}\n\
         uptime          {:.3} s\n\
         speed           {} / {} rpm (rotor 1 / rotor 2)\n\
         speed ref       {} / {} rpm\n\
         phase offset    {} deg measured{}\n\
         offset target   {} deg (commanded {} deg)\n\
         phase error     {} deg\n\
         current         {} / {} A\n\
         supply          {} V\n\
         duty            {} / {}\n\
         flags           {}\n\
         control tick    started {} late, the previous worked {}; {} overruns (ticks past their deadline)\n\
         link            {} received bytes lost\n",
        s.state.name(),
        faults_text(s.faults),
        f64::from(s.uptime_ms) / 1000.0,
        f(t.speed_rpm[0], 1),
        f(t.speed_rpm[1], 1),
        f(t.speed_ref_rpm[0], 1),
        f(t.speed_ref_rpm[1], 1),
        f(t.phase_offset_deg, 1),
        if t.phase_valid { "" } else { " (not valid)" },
        f(t.target_offset_deg, 1),
        f(t.commanded_offset_deg, 1),
        f(t.phase_error_deg, 2),
        f(t.current[0], 3),
        f(t.current[1], 3),
        f(t.supply_voltage, 2),
        f(t.duty[0], 3),
        f(t.duty[1], 3),
        flags,
        saturated(t.tick_late_us, " us"),
        saturated(t.tick_busy_us, " us"),
        saturated(t.overruns, ""),
        saturated(s.rx_dropped, ""),
    )
}

/// A saturating counter of the status report: `65535` means that much or more.
fn saturated(value: u16, unit: &str) -> String {
    if value == u16::MAX {
        format!(">= {value}{unit}")
    } else {
        format!("{value}{unit}")
    }
}

/// A telemetry frame as one line.
pub fn telemetry_line(s: &StatusReport) -> String {
    let t = &s.telemetry;
    let f = |x: f32, places: usize| fixed(f64::from(x), places);
    let offset = if t.phase_valid {
        f(t.phase_offset_deg, 1)
    } else {
        "-".into()
    };
    format!(
        "{:10.3} s  {:<8} speed {:>7} {:>7} rpm  offset {:>6} deg (target {:>5})  I {:>6} {:>6} A  {:>5} V  faults {}",
        f64::from(s.uptime_ms) / 1000.0,
        s.state.name(),
        f(t.speed_rpm[0], 1),
        f(t.speed_rpm[1], 1),
        offset,
        f(t.target_offset_deg, 1),
        f(t.current[0], 3),
        f(t.current[1], 3),
        f(t.supply_voltage, 2),
        faults_text(s.faults),
    )
}

/// One cell of a telemetry frame, as the CSV and the live page's JSON write it.
#[derive(Clone, Debug, PartialEq)]
pub enum Cell {
    /// An `f32` rounded to its unit's decimals ([`field`]).
    Number(f32, usize),
    /// A flag: `1`/`0` in the CSV, a boolean in JSON.
    Flag(bool),
    /// A whole number.
    Count(u64),
    /// A name (the state).
    Name(&'static str),
    /// Names (the faults): `|`-separated in the CSV, a list in JSON.
    Names(Vec<&'static str>),
}

impl Cell {
    /// The CSV cell.
    pub fn csv(&self) -> String {
        match self {
            Cell::Number(x, places) => field(*x, *places),
            Cell::Flag(b) => if *b { "1" } else { "0" }.to_string(),
            Cell::Count(n) => n.to_string(),
            Cell::Name(name) => name.to_string(),
            Cell::Names(names) => names.join("|"),
        }
    }
}

/// The telemetry frame `s` column by column, in the CSV's order: each
/// column's name (the CSV header's, the JSON key) and its cell. The one list of
/// the columns: [`csv_header`], [`csv_row`] and the live page's frames are
/// made from it.
pub fn columns(s: &StatusReport) -> [(&'static str, Cell); 23] {
    let t = &s.telemetry;
    [
        ("uptime_ms", Cell::Count(u64::from(s.uptime_ms))),
        ("state", Cell::Name(s.state.name())),
        ("faults", Cell::Names(s.faults.names().collect())),
        ("speed1_rpm", Cell::Number(t.speed_rpm[0], RPM_PLACES)),
        ("speed2_rpm", Cell::Number(t.speed_rpm[1], RPM_PLACES)),
        (
            "speed_ref1_rpm",
            Cell::Number(t.speed_ref_rpm[0], RPM_PLACES),
        ),
        (
            "speed_ref2_rpm",
            Cell::Number(t.speed_ref_rpm[1], RPM_PLACES),
        ),
        ("phase_valid", Cell::Flag(t.phase_valid)),
        ("phase_loop_closed", Cell::Flag(t.phase_loop_closed)),
        (
            "phase_offset_deg",
            Cell::Number(t.phase_offset_deg, DEG_PLACES),
        ),
        (
            "commanded_offset_deg",
            Cell::Number(t.commanded_offset_deg, DEG_PLACES),
        ),
        (
            "target_offset_deg",
            Cell::Number(t.target_offset_deg, DEG_PLACES),
        ),
        (
            "phase_error_deg",
            Cell::Number(t.phase_error_deg, DEG_PLACES),
        ),
        ("current1_a", Cell::Number(t.current[0], AMPERE_PLACES)),
        ("current2_a", Cell::Number(t.current[1], AMPERE_PLACES)),
        (
            "supply_voltage_v",
            Cell::Number(t.supply_voltage, VOLT_PLACES),
        ),
        ("duty1", Cell::Number(t.duty[0], DUTY_PLACES)),
        ("duty2", Cell::Number(t.duty[1], DUTY_PLACES)),
        ("command_rejected", Cell::Flag(t.command_rejected)),
        ("tick_late_us", Cell::Count(u64::from(t.tick_late_us))),
        ("tick_busy_us", Cell::Count(u64::from(t.tick_busy_us))),
        ("overruns", Cell::Count(u64::from(t.overruns))),
        ("rx_dropped", Cell::Count(u64::from(s.rx_dropped))),
    ]
}

/// The CSV header of [`csv_row`], without the newline: the names of
/// [`columns`].
pub fn csv_header() -> String {
    let none = StatusReport {
        uptime_ms: 0,
        state: State::Idle,
        faults: Faults::NONE,
        telemetry: no_telemetry(),
        rx_dropped: 0,
    };
    columns(&none).map(|(name, _)| name).join(",")
}

/// A telemetry frame as a CSV row (faults by name, `|`-separated; `f32`s rounded
/// to their unit's decimals, [`RPM_PLACES`] and the others), without the newline.
pub fn csv_row(s: &StatusReport) -> String {
    columns(s).map(|(_, cell)| cell.csv()).join(",")
}

/// The self-test status's name.
pub fn self_test_status(status: SelfTestStatus) -> &'static str {
    match status {
        SelfTestStatus::NotRun => "not run",
        SelfTestStatus::Running => "running",
        SelfTestStatus::Done => "done",
        SelfTestStatus::Aborted => "aborted",
    }
}

/// A self-test report: its status, then one block per rotor.
pub fn self_test_text(report: &SelfTestReport) -> String {
    let ok = |v: bool| if v { "ok" } else { "FAILED" };
    let mut out = format!("self-test       {}\n", self_test_status(report.status));
    for (k, r) in report.result.rotors.iter().enumerate() {
        let r: &RotorSelfTest = r;
        out.push_str(&format!(
            "rotor {}         {}\n  motor polarity     {}\n  encoder polarity   {}\n  index pulse        {}\n  counts per rev     {}\n  index offset       {} counts\n",
            k + 1,
            if r.passed() { "PASS" } else { "FAIL" },
            ok(r.motor_polarity_ok),
            ok(r.encoder_polarity_ok),
            if r.index_seen { "seen" } else { "NOT SEEN" },
            r.counts_per_rev,
            r.index_offset_counts,
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared::controller::State;
    use shared::protocol::link::no_telemetry;

    #[test]
    fn a_csv_row_has_a_field_per_column() {
        let s = StatusReport {
            uptime_ms: 1234,
            state: State::Fault,
            faults: Faults::STALL | Faults::LINK_LOST,
            telemetry: no_telemetry(),
            rx_dropped: 3,
        };
        let row = csv_row(&s);
        assert_eq!(row.split(',').count(), csv_header().split(',').count());
        assert!(row.starts_with("1234,fault,stall|link_lost,0,"), "{row}");
        assert!(telemetry_line(&s).contains("faults stall link_lost"));
        assert!(status_text(&s).contains("state           fault\n"));
        assert!(status_text(&s).contains("link            3 received bytes lost\n"));
        assert!(row.ends_with(",0,0,0,3"), "{row}");
    }

    #[test]
    fn a_saturated_counter_reads_as_at_least() {
        let mut telemetry = no_telemetry();
        telemetry.tick_late_us = u16::MAX;
        telemetry.tick_busy_us = 17;
        telemetry.overruns = 2;
        let s = StatusReport {
            uptime_ms: 1,
            state: State::Idle,
            faults: Faults::NONE,
            telemetry,
            rx_dropped: u16::MAX,
        };
        let text = status_text(&s);
        assert!(
            text.contains(
                "control tick    started >= 65535 us late, the previous worked 17 us; 2 overruns"
            ),
            "{text}"
        );
        assert!(
            text.contains("link            >= 65535 received bytes lost\n"),
            "{text}"
        );
        // The CSV keeps the numbers as sent.
        assert!(csv_row(&s).ends_with(",65535,17,2,65535"));
    }

    /// A rotor coasting to rest: its filtered speed decays into subnormal and
    /// negative-zero `f32`s, which read as 0 (they printed as 45 digits in the CSV
    /// and `-0.0 rpm` in the status); a value keeps its unit's decimals.
    #[test]
    fn speeds_decayed_to_nothing_read_as_zero() {
        let mut telemetry = no_telemetry();
        telemetry.speed_rpm = [2.7e-44, -1e-30];
        telemetry.speed_ref_rpm = [-0.0, 3000.0913];
        telemetry.current = [-0.0000001, f32::NAN];
        telemetry.phase_error_deg = -0.023040771;
        let s = StatusReport {
            uptime_ms: 10070,
            state: State::Idle,
            faults: Faults::NONE,
            telemetry,
            rx_dropped: 0,
        };
        let row = csv_row(&s);
        assert!(
            row.starts_with("10070,idle,,0,0,0,3000.091,0,0,0,0,0,-0.023,0,NaN,"),
            "{row}"
        );
        let text = status_text(&s);
        assert!(
            text.contains("speed           0.0 / 0.0 rpm (rotor 1 / rotor 2)\n"),
            "{text}"
        );
        assert!(
            text.contains("speed ref       0.0 / 3000.1 rpm\n"),
            "{text}"
        );
        assert!(text.contains("current         0.000 / NaN A\n"), "{text}");
        let line = telemetry_line(&s);
        assert!(line.contains("speed     0.0     0.0 rpm"), "{line}");
        assert!(!line.contains("-0.0"), "{line}");
    }
}
