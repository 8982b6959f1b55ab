//! A telemetry frame as the live page receives it: one JSON object whose keys are
//! the CSV columns of `host-sim device telemetry --csv` ([`super::super::report`]),
//! with the same units (rpm, degrees, amperes, volts, ms, us); faults as a list of
//! names, flags as booleans.

use serde_json::{json, Value};
use shared::protocol::StatusReport;

use crate::device::report::{
    field, AMPERE_PLACES, DEG_PLACES, DUTY_PLACES, RPM_PLACES, VOLT_PLACES,
};

/// An `f32` as the JSON number of its CSV cell ([`field`]: rounded to `places`
/// decimals, 3000.091 rather than the widened 3000.09130859375); a non-finite one
/// as `null`.
fn number(x: f32, places: usize) -> Value {
    field(x, places)
        .parse::<f64>()
        .ok()
        .and_then(serde_json::Number::from_f64)
        .map_or(Value::Null, Value::Number)
}

/// The frame `s` as one line of JSON.
pub fn json(s: &StatusReport) -> String {
    let t = &s.telemetry;
    let faults: Vec<&str> = s.faults.names().collect();
    json!({
        "uptime_ms": s.uptime_ms,
        "state": s.state.name(),
        "faults": faults,
        "speed1_rpm": number(t.speed_rpm[0], RPM_PLACES),
        "speed2_rpm": number(t.speed_rpm[1], RPM_PLACES),
        "speed_ref1_rpm": number(t.speed_ref_rpm[0], RPM_PLACES),
        "speed_ref2_rpm": number(t.speed_ref_rpm[1], RPM_PLACES),
        "phase_valid": t.phase_valid,
        "phase_loop_closed": t.phase_loop_closed,
        "phase_offset_deg": number(t.phase_offset_deg, DEG_PLACES),
        "commanded_offset_deg": number(t.commanded_offset_deg, DEG_PLACES),
        "target_offset_deg": number(t.target_offset_deg, DEG_PLACES),
        "phase_error_deg": number(t.phase_error_deg, DEG_PLACES),
        "current1_a": number(t.current[0], AMPERE_PLACES),
        "current2_a": number(t.current[1], AMPERE_PLACES),
        "supply_voltage_v": number(t.supply_voltage, VOLT_PLACES),
        "duty1": number(t.duty[0], DUTY_PLACES),
        "duty2": number(t.duty[1], DUTY_PLACES),
        "command_rejected": t.command_rejected,
        "tick_late_us": t.tick_late_us,
        "tick_busy_us": t.tick_busy_us,
        "overruns": t.overruns,
        "rx_dropped": s.rx_dropped,
    })
    .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::report::{csv_row, CSV_HEADER};
    use shared::controller::{Faults, State};
    use shared::protocol::link::no_telemetry;

    #[test]
    fn the_json_has_the_csv_columns_and_values() {
        let mut telemetry = no_telemetry();
        telemetry.speed_rpm = [3000.0913, -12.5];
        telemetry.phase_valid = true;
        telemetry.supply_voltage = 12.0;
        let s = StatusReport {
            uptime_ms: 1234,
            state: State::Running,
            faults: Faults::STALL | Faults::LINK_LOST,
            telemetry,
            rx_dropped: 3,
        };
        let v: Value = serde_json::from_str(&json(&s)).unwrap();
        let keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
        assert_eq!(keys, CSV_HEADER.split(',').collect::<Vec<_>>());
        // Every field reads as its CSV cell: the same numbers, faults by name,
        // flags as 0/1 there and booleans here.
        let cell = |v: &Value| match v {
            Value::Bool(b) => if *b { "1" } else { "0" }.to_string(),
            Value::String(s) => s.clone(),
            Value::Array(a) => a
                .iter()
                .map(|f| f.as_str().unwrap())
                .collect::<Vec<_>>()
                .join("|"),
            other => other.to_string(),
        };
        let cells: Vec<String> = v.as_object().unwrap().values().map(cell).collect();
        let row = csv_row(&s);
        let row: Vec<&str> = row.split(',').collect();
        for ((k, got), want) in keys.iter().zip(&cells).zip(&row) {
            // JSON writes a whole number as 12.0 where the CSV writes 12.
            let same = got == want
                || got
                    .parse::<f64>()
                    .ok()
                    .zip(want.parse::<f64>().ok())
                    .is_some_and(|(a, b)| a == b);
            assert!(same, "{k}: {got} in JSON, {want} in CSV");
        }
        assert_eq!(v["speed1_rpm"], json!(3000.091));
        assert_eq!(v["faults"], json!(["stall", "link_lost"]));
    }
}
