//! What `host-sim device` prints: a status report as aligned lines, a telemetry
//! frame as one readable line or one CSV row, a self-test result per rotor.

use shared::controller::{Faults, RotorSelfTest, SelfTestReport, SelfTestStatus};
use shared::protocol::StatusReport;

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
    format!(
        "state           {}\n\
         faults          {}\n\
         uptime          {:.3} s\n\
         speed           {:.1} / {:.1} rpm (rotor 1 / rotor 2)\n\
         speed ref       {:.1} / {:.1} rpm\n\
         phase offset    {:.1} deg measured{}\n\
         offset target   {:.1} deg (commanded {:.1} deg)\n\
         phase error     {:.2} deg\n\
         current         {:.3} / {:.3} A\n\
         supply          {:.2} V\n\
         duty            {:.3} / {:.3}\n\
         flags           {}\n\
         control tick    started {} late, the previous worked {}; {} overruns (ticks past their deadline)\n\
         link            {} received bytes lost\n",
        s.state.name(),
        faults_text(s.faults),
        f64::from(s.uptime_ms) / 1000.0,
        t.speed_rpm[0],
        t.speed_rpm[1],
        t.speed_ref_rpm[0],
        t.speed_ref_rpm[1],
        t.phase_offset_deg,
        if t.phase_valid { "" } else { " (not valid)" },
        t.target_offset_deg,
        t.commanded_offset_deg,
        t.phase_error_deg,
        t.current[0],
        t.current[1],
        t.supply_voltage,
        t.duty[0],
        t.duty[1],
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
    let offset = if t.phase_valid {
        format!("{:6.1}", t.phase_offset_deg)
    } else {
        "     -".into()
    };
    format!(
        "{:10.3} s  {:<8} speed {:7.1} {:7.1} rpm  offset {} deg (target {:5.1})  I {:6.3} {:6.3} A  {:5.2} V  faults {}",
        f64::from(s.uptime_ms) / 1000.0,
        s.state.name(),
        t.speed_rpm[0],
        t.speed_rpm[1],
        offset,
        t.target_offset_deg,
        t.current[0],
        t.current[1],
        t.supply_voltage,
        faults_text(s.faults),
    )
}

/// The CSV header of [`csv_row`], without the newline.
pub const CSV_HEADER: &str =
    "uptime_ms,state,faults,speed1_rpm,speed2_rpm,speed_ref1_rpm,speed_ref2_rpm,\
phase_valid,phase_loop_closed,phase_offset_deg,commanded_offset_deg,target_offset_deg,\
phase_error_deg,current1_a,current2_a,supply_voltage_v,duty1,duty2,command_rejected,\
tick_late_us,tick_busy_us,overruns,rx_dropped";

/// A telemetry frame as a CSV row (faults by name, `|`-separated; `f32`s in their
/// shortest exact form), without the newline.
pub fn csv_row(s: &StatusReport) -> String {
    let t = &s.telemetry;
    let faults: Vec<&str> = s.faults.names().collect();
    let b = |v: bool| if v { "1" } else { "0" };
    format!(
        "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
        s.uptime_ms,
        s.state.name(),
        faults.join("|"),
        t.speed_rpm[0],
        t.speed_rpm[1],
        t.speed_ref_rpm[0],
        t.speed_ref_rpm[1],
        b(t.phase_valid),
        b(t.phase_loop_closed),
        t.phase_offset_deg,
        t.commanded_offset_deg,
        t.target_offset_deg,
        t.phase_error_deg,
        t.current[0],
        t.current[1],
        t.supply_voltage,
        t.duty[0],
        t.duty[1],
        b(t.command_rejected),
        t.tick_late_us,
        t.tick_busy_us,
        t.overruns,
        s.rx_dropped,
    )
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
        assert_eq!(row.split(',').count(), CSV_HEADER.split(',').count());
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
}
