//! A scenario's [`Report`] as a table for people or as JSON (docs/scenarios.md).

use serde_json::{Map, Value};

use super::judge::Detection;
use super::judge::Report;
use crate::numbers::sig;
use crate::output::text::{Align, Table};

/// `encoder at 2.068 s (+68 ms)`, or `none to the end`.
fn detection_text(d: &Detection) -> String {
    match &d.latched {
        Some((names, t)) => format!(
            "{} at {} s (+{} ms)",
            names.join(", "),
            sig(*t),
            sig(((t - d.t) * 1e3 * 1e6).round() / 1e6)
        ),
        None => "none to the end".to_string(),
    }
}

/// The report for people: a heading, one line per expectation (PASS or FAIL, its
/// key and kind, what it expects, what was measured), the first fault after each
/// injection, and the verdict.
pub fn table(r: &Report) -> String {
    let mut out = format!(
        "scenario {}: machine {}, {} s simulated, final state {}\n\n",
        r.scenario,
        r.machine,
        sig(r.t_end),
        r.final_state.name()
    );
    let mut t = Table::new(&[
        ("result", Align::Left),
        ("expectation", Align::Left),
        ("expected", Align::Left),
        ("measured", Align::Left),
    ]);
    for o in &r.outcomes {
        t.row(vec![
            if o.pass { "PASS" } else { "FAIL" }.to_string(),
            format!("{} {}", o.key, o.kind),
            o.expected.clone(),
            o.measured.clone(),
        ]);
    }
    out.push_str(&t.render());
    if !r.detections.is_empty() {
        out.push('\n');
        let mut t = Table::new(&[
            ("injected", Align::Left),
            ("at", Align::Right),
            ("first fault latched at or after it", Align::Left),
        ]);
        for d in &r.detections {
            t.row(vec![
                format!("{} {}", d.key, d.injected),
                format!("{} s", sig(d.t)),
                detection_text(d),
            ]);
        }
        out.push_str(&t.render());
    }
    if !r.warnings.is_empty() {
        out.push_str("\nwarnings of the run:\n");
        for w in &r.warnings {
            out.push_str(&format!("  - {w}\n"));
        }
    }
    let passed = r.outcomes.iter().filter(|o| o.pass).count();
    out.push_str(&format!(
        "\n{}: {passed} of {} expectations hold\n",
        if r.passed() { "PASS" } else { "FAIL" },
        r.outcomes.len()
    ));
    out
}

/// The report as one JSON document:
/// `{"scenario", "machine", "t_end", "pass", "final_state", "expectations": [{"key",
/// "kind", "pass", "expected", "measured"}], "injections": [{"key", "injected", "t",
/// "latched": [names] | null, "latched_at": s | null, "delay": s | null}],
/// "warnings": [the run's warnings]}`.
pub fn json(r: &Report) -> String {
    let mut doc = Map::new();
    doc.insert("scenario".into(), Value::from(r.scenario.as_str()));
    doc.insert("machine".into(), Value::from(r.machine.as_str()));
    doc.insert("t_end".into(), Value::from(r.t_end));
    doc.insert("pass".into(), Value::from(r.passed()));
    doc.insert("final_state".into(), Value::from(r.final_state.name()));
    let expectations = r
        .outcomes
        .iter()
        .map(|o| {
            let mut e = Map::new();
            e.insert("key".into(), Value::from(o.key.as_str()));
            e.insert("kind".into(), Value::from(o.kind));
            e.insert("pass".into(), Value::from(o.pass));
            e.insert("expected".into(), Value::from(o.expected.as_str()));
            e.insert("measured".into(), Value::from(o.measured.as_str()));
            Value::Object(e)
        })
        .collect();
    doc.insert("expectations".into(), Value::Array(expectations));
    let injections = r
        .detections
        .iter()
        .map(|d| {
            let mut e = Map::new();
            e.insert("key".into(), Value::from(d.key.as_str()));
            e.insert("injected".into(), Value::from(d.injected.as_str()));
            e.insert("t".into(), Value::from(d.t));
            let (names, at) = match &d.latched {
                Some((names, t)) => (
                    Value::Array(names.iter().map(|n| Value::from(n.as_str())).collect()),
                    Value::from(*t),
                ),
                None => (Value::Null, Value::Null),
            };
            e.insert("latched".into(), names);
            e.insert("latched_at".into(), at);
            e.insert(
                "delay".into(),
                d.latched
                    .as_ref()
                    .map_or(Value::Null, |(_, t)| Value::from(t - d.t)),
            );
            Value::Object(e)
        })
        .collect();
    doc.insert("injections".into(), Value::Array(injections));
    doc.insert(
        "warnings".into(),
        Value::Array(r.warnings.iter().map(|w| Value::from(w.as_str())).collect()),
    );
    let mut text = serde_json::to_string_pretty(&Value::Object(doc))
        .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    text.push('\n');
    text
}
