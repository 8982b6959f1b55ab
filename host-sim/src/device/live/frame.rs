//! A telemetry frame as the live page receives it: one JSON object whose keys are
//! the CSV columns of `host-sim device telemetry --csv` ([`super::super::report`]),
//! with the same units (rpm, degrees, amperes, volts, ms, us); faults as a list of
//! names, flags as booleans.

use serde_json::Value;
use shared::protocol::StatusReport;

use crate::device::report::{columns, field, Cell};

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

/// The frame `s` as one line of JSON: its [`columns`] as keys and values.
pub fn json(s: &StatusReport) -> String {
    let object: serde_json::Map<String, Value> = columns(s)
        .into_iter()
        .map(|(name, cell)| {
            let value = match cell {
                Cell::Number(x, places) => number(x, places),
                Cell::Flag(b) => Value::Bool(b),
                Cell::Count(n) => Value::from(n),
                Cell::Name(name) => Value::from(name),
                Cell::Names(names) => Value::from(names),
            };
            (name.to_string(), value)
        })
        .collect();
    Value::Object(object).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::report::{csv_header, csv_row};
    use serde_json::json;
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
        assert_eq!(keys, csv_header().split(',').collect::<Vec<_>>());
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
