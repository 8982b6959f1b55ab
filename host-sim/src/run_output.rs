//! The outputs of `host-sim run` (spec `machine.md`): the summary as the spec's JSON
//! document or as a table for people, the trace (`--out`) and the events
//! (`--events`) as CSV, and [`write_whole`], which writes a file whole or not at all.
//!
//! Formats:
//! - JSON: keys and their order are the contract (`t_end`, `mean_velocity`,
//!   `distance`, `impacts`, `rotor_speed_rpm`, `phase_offset_deg`,
//!   `phase_error_deg_rms`, `state`, `faults`, `final`, `warnings`); a number that is
//!   not finite is written `null`, so the document always parses.
//! - CSV: a header line, then one line per row, fields separated by commas, lines
//!   ending with `\n`; text fields quoted as RFC 4180 says (in double quotes, inner
//!   quotes doubled) when they hold a comma, a quote or a line break. Numbers are
//!   written by [`csv_number`]: the shortest decimal that reads back to the same
//!   `f64`, plain between 1e-4 and 1e16 and scientific outside (`0.001`, `-2.5`,
//!   `3`, `1.5e-9`, `2e20`), `NaN`, `inf` and `-inf` for the non-finite.

use std::fmt::Write as _;
use std::fs::{self, File, OpenOptions};
use std::io::Write as _;
use std::path::{Path, PathBuf};

use serde_json::{Map, Value};

use shared::impact::MAX_CONTACTS;

use crate::text::{self, Align, Table};
use crate::trace::{EventRow, Summary, TraceRow};

/// The trace CSV's columns that every machine has (spec `machine.md`, `--out`);
/// the contact forces follow ([`trace_header`]).
pub const TRACE_HEADER: &str = "t,x,y,angle,vx,vy,omega,phi1,phi2,omega1,omega2,i1,i2,duty1,duty2";

/// The trace CSV's header for a machine whose contacts are named `contacts`:
/// [`TRACE_HEADER`], then per contact in file order `fn_<name>,ft_<name>` (the
/// spec's addition: normal and tangential force of persistent contact, N).
pub fn trace_header(contacts: &[String]) -> String {
    let mut header = TRACE_HEADER.to_string();
    for name in contacts {
        let _ = write!(
            header,
            ",{},{}",
            csv_text(&format!("fn_{name}")),
            csv_text(&format!("ft_{name}"))
        );
    }
    header
}

/// The events CSV's header (spec `machine.md`, `--events`).
pub const EVENTS_HEADER: &str = "t,kind,contact,normal_velocity_before,normal_velocity_after,normal_impulse,tangential_impulse,case,detail";

/// A JSON number, or `null` when `x` is not finite (JSON has no NaN or infinity).
fn number(x: f64) -> Value {
    // serde_json gives Null for a non-finite f64.
    Value::from(x)
}

/// `[x, y]` as a JSON array.
fn pair(v: [f64; 2]) -> Value {
    Value::Array(vec![number(v[0]), number(v[1])])
}

/// A list of strings as a JSON array.
fn strings(list: &[String]) -> Value {
    Value::Array(list.iter().map(|s| Value::from(s.as_str())).collect())
}

/// The spec's JSON document of a run's summary, keys in the spec's order.
pub fn summary_value(s: &Summary) -> Value {
    let mut doc = Map::new();
    doc.insert("t_end".into(), number(s.t_end));
    doc.insert("mean_velocity".into(), number(s.mean_velocity));
    doc.insert("distance".into(), number(s.distance));
    doc.insert("impacts".into(), Value::from(s.impacts));
    doc.insert("rotor_speed_rpm".into(), pair(s.rotor_speed_rpm));
    doc.insert("phase_offset_deg".into(), number(s.phase_offset_deg));
    doc.insert("phase_error_deg_rms".into(), number(s.phase_error_deg_rms));
    doc.insert("state".into(), Value::from(s.state.as_str()));
    doc.insert("faults".into(), strings(&s.faults));
    let f = &s.final_state;
    let mut fin = Map::new();
    fin.insert("position".into(), pair(f.position));
    fin.insert("angle".into(), number(f.angle));
    fin.insert("velocity".into(), pair(f.velocity));
    fin.insert("angular_velocity".into(), number(f.angular_velocity));
    doc.insert("final".into(), Value::Object(fin));
    doc.insert("warnings".into(), strings(&s.warnings));
    Value::Object(doc)
}

/// [`summary_value`] as text: pretty-printed, ending with a newline.
pub fn summary_json(s: &Summary) -> String {
    let mut text = serde_json::to_string_pretty(&summary_value(s))
        .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    text.push('\n');
    text
}

/// The summary for people: one quantity a line with its unit, then the faults and
/// the warnings.
pub fn summary_table(s: &Summary) -> String {
    let mut out = format!(
        "run to t = {} s, controller state: {}\n\n",
        text::sig(s.t_end),
        s.state
    );
    let mut t = Table::new(&[
        ("quantity", Align::Left),
        ("value", Align::Right),
        ("unit", Align::Left),
    ]);
    let mut row = |name: &str, value: String, unit: &str| {
        t.row(vec![name.to_string(), value, unit.to_string()]);
    };
    row(
        "mean velocity (second half)",
        text::signed(s.mean_velocity),
        "m/s",
    );
    row("distance", text::signed(s.distance), "m");
    row("impacts", s.impacts.to_string(), "");
    row(
        "rotor 1 speed (second half)",
        text::sig(s.rotor_speed_rpm[0]),
        "rpm",
    );
    row(
        "rotor 2 speed (second half)",
        text::sig(s.rotor_speed_rpm[1]),
        "rpm",
    );
    row(
        "phase offset (circular mean)",
        text::sig(s.phase_offset_deg),
        "deg",
    );
    row("phase error (RMS)", text::sig(s.phase_error_deg_rms), "deg");
    let f = &s.final_state;
    row("final position", text::vec2(f.position), "m");
    row(
        "final angle",
        format!(
            "{} ({} deg)",
            text::sig(f.angle),
            text::sig(f.angle.to_degrees())
        ),
        "rad",
    );
    row("final velocity", text::vec2(f.velocity), "m/s");
    row(
        "final angular velocity",
        text::sig(f.angular_velocity),
        "rad/s",
    );
    out.push_str(&t.render());
    out.push('\n');

    // Faults and warnings, one a line.
    for (title, list) in [("faults", &s.faults), ("warnings", &s.warnings)] {
        if list.is_empty() {
            out.push_str(&format!("{title}: none\n"));
        } else {
            out.push_str(&format!("{title}:\n"));
            for item in list {
                out.push_str(&format!("  - {item}\n"));
            }
        }
    }
    out
}

/// A number for the CSV files: the shortest decimal that reads back to the same
/// `f64` (Rust's `Display` and `LowerExp` without a precision), plain for
/// `1e-4 <= |x| < 1e16` and zero, scientific otherwise; `NaN`, `inf`, `-inf`.
pub fn csv_number(x: f64) -> String {
    if x.is_nan() {
        "NaN".to_string()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.to_string()
    } else if x == 0.0 || (1e-4..1e16).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// A text field for CSV: as it is, or in double quotes with inner quotes doubled
/// when it holds a comma, a quote or a line break (RFC 4180).
pub fn csv_text(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The `--out` trace of a machine whose contacts are named `contacts`:
/// [`trace_header`], then one line per row.
pub fn trace_csv(rows: &[TraceRow], contacts: &[String]) -> String {
    let n = contacts.len().min(MAX_CONTACTS);
    let mut out = String::with_capacity(32 + rows.len() * (15 + 2 * n) * 12);
    out.push_str(&trace_header(&contacts[..n]));
    out.push('\n');
    for r in rows {
        let fields = [
            r.t, r.x, r.y, r.angle, r.vx, r.vy, r.omega, r.phi1, r.phi2, r.omega1, r.omega2, r.i1,
            r.i2, r.duty1, r.duty2,
        ];
        let forces = (0..n).flat_map(|j| [r.normal_force[j], r.tangential_force[j]]);
        for (i, v) in fields.into_iter().chain(forces).enumerate() {
            if i > 0 {
                out.push(',');
            }
            out.push_str(&csv_number(v));
        }
        out.push('\n');
    }
    out
}

/// The `--events` CSV: [`EVENTS_HEADER`], then one line per row; `case` empty when
/// the row has none.
pub fn events_csv(rows: &[EventRow]) -> String {
    let mut out = String::new();
    out.push_str(EVENTS_HEADER);
    out.push('\n');
    for e in rows {
        let case = e.case.map(|c| c.to_string()).unwrap_or_default();
        // Writing to a String cannot fail.
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{},{}",
            csv_number(e.t),
            e.kind.name(),
            csv_text(&e.contact),
            csv_number(e.normal_velocity_before),
            csv_number(e.normal_velocity_after),
            csv_number(e.normal_impulse),
            csv_number(e.tangential_impulse),
            case,
            csv_text(&e.detail),
        );
    }
    out
}

/// The temporary file beside `path` that [`write_whole`] writes first: the same
/// directory (so the rename cannot cross file systems), a hidden name with the
/// process id.
fn temporary_beside(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?.to_string_lossy();
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    Some(dir.join(format!(".{name}.{}.tmp", std::process::id())))
}

/// Writes `contents` to `path` whole or not at all: into a temporary file in the
/// same directory, flushed to disk (fsync), then renamed over `path`. On failure the
/// temporary file is removed, `path` is left as it was, and the message names
/// `path` and the reason. The exit status is the caller's decision.
pub fn write_whole(path: &Path, contents: &str) -> Result<(), String> {
    let fail = |why: String| format!("cannot write {}: {why}", path.display());
    let tmp = temporary_beside(path).ok_or_else(|| fail("not a file name".to_string()))?;

    // Write and flush the temporary file.
    let written = (|| -> std::io::Result<()> {
        let mut file: File = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&tmp)?;
        file.write_all(contents.as_bytes())?;
        file.sync_all()
    })();
    if let Err(e) = written {
        let _ = fs::remove_file(&tmp);
        return Err(fail(e.to_string()));
    }

    // Replace the target in one step.
    if let Err(e) = fs::rename(&tmp, path) {
        let _ = fs::remove_file(&tmp);
        return Err(fail(e.to_string()));
    }

    // Make the rename itself durable where directories can be synced (best effort:
    // the file is complete either way).
    if let Some(dir) = tmp.parent() {
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::{EventKind, FinalState};

    fn summary() -> Summary {
        Summary {
            t_end: 10.0,
            mean_velocity: 0.0125,
            distance: 0.1,
            impacts: 42,
            rotor_speed_rpm: [3000.5, 2999.5],
            phase_offset_deg: 90.25,
            phase_error_deg_rms: 1.5,
            state: "running".to_string(),
            faults: vec![],
            final_state: FinalState {
                position: [0.25, 0.03],
                angle: 0.01,
                velocity: [0.05, -0.5],
                angular_velocity: 2.0,
            },
            warnings: vec!["w1".to_string()],
        }
    }

    fn keys(v: &Value) -> Vec<&str> {
        v.as_object().unwrap().keys().map(String::as_str).collect()
    }

    #[test]
    fn json_has_exactly_the_spec_keys_in_order() {
        let text = summary_json(&summary());
        let doc: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(
            keys(&doc),
            [
                "t_end",
                "mean_velocity",
                "distance",
                "impacts",
                "rotor_speed_rpm",
                "phase_offset_deg",
                "phase_error_deg_rms",
                "state",
                "faults",
                "final",
                "warnings"
            ]
        );
        assert_eq!(
            keys(&doc["final"]),
            ["position", "angle", "velocity", "angular_velocity"]
        );
        assert_eq!(doc["impacts"], 42);
        assert_eq!(doc["rotor_speed_rpm"][1], 2999.5);
        assert_eq!(doc["final"]["velocity"][1], -0.5);
        assert_eq!(doc["state"], "running");
        assert_eq!(doc["faults"], Value::Array(vec![]));
        assert_eq!(doc["warnings"][0], "w1");
        assert!(text.ends_with("}\n"));
    }

    #[test]
    fn non_finite_numbers_are_null() {
        let mut s = summary();
        s.mean_velocity = f64::NAN;
        s.rotor_speed_rpm[0] = f64::INFINITY;
        s.final_state.angle = f64::NEG_INFINITY;
        let text = summary_json(&s);
        let doc: Value = serde_json::from_str(&text).expect("valid JSON");
        assert!(doc["mean_velocity"].is_null());
        assert!(doc["rotor_speed_rpm"][0].is_null());
        assert_eq!(doc["rotor_speed_rpm"][1], 2999.5);
        assert!(doc["final"]["angle"].is_null());
        // Nothing else is added.
        assert_eq!(doc.as_object().unwrap().len(), 11);
        assert_eq!(doc["warnings"].as_array().unwrap().len(), 1);
    }

    #[test]
    fn table_states_units() {
        let mut s = summary();
        s.faults = vec!["overcurrent".to_string()];
        let t = summary_table(&s);
        assert!(
            t.starts_with("run to t = 10 s, controller state: running"),
            "{t}"
        );
        let line = |start: &str| {
            t.lines()
                .find(|l| l.starts_with(start))
                .unwrap_or_else(|| panic!("no {start} line in\n{t}"))
                .to_string()
        };
        assert!(line("mean velocity").ends_with("+0.0125  m/s"), "{t}");
        assert!(line("rotor 1 speed").ends_with("3000.5  rpm"), "{t}");
        assert!(line("phase offset").ends_with("90.25  deg"), "{t}");
        assert!(line("final velocity").ends_with("[0.05, -0.5]  m/s"), "{t}");
        assert!(line("impacts").contains("42"), "{t}");
        assert!(t.contains("faults:\n  - overcurrent\n"), "{t}");
        assert!(t.contains("warnings:\n  - w1\n"), "{t}");
    }

    #[test]
    fn numbers_round_trip() {
        for x in [
            0.0,
            -0.0,
            1.0,
            -2.5,
            0.1,
            1.0 / 3.0,
            std::f64::consts::PI * 1e5,
            1.5e-9,
            -1e-300,
            2e20,
            f64::MAX,
            f64::MIN_POSITIVE,
            5e-324,
            0.0001,
            1e16 - 2.0,
        ] {
            let s = csv_number(x);
            let back: f64 = s.parse().unwrap();
            assert_eq!(back.to_bits(), x.to_bits(), "{x} -> {s}");
        }
        assert_eq!(csv_number(0.001), "0.001");
        assert_eq!(csv_number(3.0), "3");
        assert_eq!(csv_number(1.5e-9), "1.5e-9");
        assert_eq!(csv_number(2e20), "2e20");
        assert_eq!(csv_number(f64::NAN), "NaN");
        assert_eq!(csv_number(f64::NEG_INFINITY), "-inf");
    }

    #[test]
    fn trace_has_the_spec_columns() {
        let rows = [
            TraceRow::default(),
            TraceRow {
                t: 0.001,
                x: 0.1,
                phi1: 1.0 / 3.0,
                duty2: -1.0,
                ..TraceRow::default()
            },
        ];
        let csv = trace_csv(&rows, &[]);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(
            lines[0],
            "t,x,y,angle,vx,vy,omega,phi1,phi2,omega1,omega2,i1,i2,duty1,duty2"
        );
        assert_eq!(lines.len(), 3);
        assert_eq!(lines[1], "0,0,0,0,0,0,0,0,0,0,0,0,0,0,0");
        let cells: Vec<&str> = lines[2].split(',').collect();
        assert_eq!(cells.len(), 15);
        assert_eq!(cells[0], "0.001");
        assert_eq!(cells[7].parse::<f64>().unwrap(), 1.0 / 3.0);
        assert_eq!(cells[14], "-1");
        assert_eq!(trace_csv(&[], &[]), format!("{TRACE_HEADER}\n"));
    }

    #[test]
    fn trace_has_the_contact_forces_per_contact_in_file_order() {
        let mut row = TraceRow::default();
        row.normal_force[0] = 9.5;
        row.tangential_force[0] = -1.25;
        row.normal_force[1] = 0.5;
        // A third force beyond the machine's two contacts is not written.
        row.normal_force[2] = 7.0;
        let names = ["K1".to_string(), "rear, left".to_string()];
        let csv = trace_csv(&[row], &names);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(
            lines[0],
            format!("{TRACE_HEADER},fn_K1,ft_K1,\"fn_rear, left\",\"ft_rear, left\"")
        );
        assert!(lines[1].ends_with(",9.5,-1.25,0.5,0"), "{}", lines[1]);
        assert_eq!(lines[1].split(',').count(), 19);
    }

    #[test]
    fn events_quote_text_and_leave_case_empty() {
        let rows = [
            EventRow {
                t: 0.5,
                kind: EventKind::Impact,
                contact: "K1".to_string(),
                normal_velocity_before: -0.25,
                normal_velocity_after: 0.075,
                normal_impulse: 0.5,
                tangential_impulse: -0.125,
                case: Some(3),
                detail: String::new(),
            },
            EventRow {
                t: 0.75,
                kind: EventKind::Fault,
                contact: String::new(),
                normal_velocity_before: 0.0,
                normal_velocity_after: 0.0,
                normal_impulse: 0.0,
                tangential_impulse: 0.0,
                case: None,
                detail: "overcurrent, rotor \"left\"".to_string(),
            },
        ];
        let csv = events_csv(&rows);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines[0], EVENTS_HEADER);
        assert_eq!(lines[1], "0.5,impact,K1,-0.25,0.075,0.5,-0.125,3,");
        assert_eq!(
            lines[2],
            "0.75,fault,,0,0,0,0,,\"overcurrent, rotor \"\"left\"\"\""
        );
        assert_eq!(csv_text("a\nb"), "\"a\nb\"");
    }

    /// A fresh directory for one test.
    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("host-sim-run-output-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn write_whole_replaces_the_file_and_leaves_no_temporary() {
        let dir = scratch("replace");
        let path = dir.join("out.csv");
        fs::write(&path, "old contents, longer than the new").unwrap();
        write_whole(&path, "new\n").unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "new\n");
        let names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["out.csv"]);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn write_whole_failure_names_the_path_and_keeps_the_old_file() {
        let dir = scratch("fail");
        // A missing directory: the temporary file cannot be created.
        let missing = dir.join("no-such-dir").join("out.csv");
        let e = write_whole(&missing, "x").unwrap_err();
        assert!(e.starts_with("cannot write "), "{e}");
        assert!(e.contains("out.csv"), "{e}");
        // The target is a directory: the rename fails, the temporary is removed
        // and the directory is untouched.
        let target = dir.join("taken");
        fs::create_dir(&target).unwrap();
        fs::write(target.join("keep"), "k").unwrap();
        let e = write_whole(&target, "x").unwrap_err();
        assert!(e.contains("taken"), "{e}");
        let mut names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        assert_eq!(names, ["taken"]);
        assert_eq!(fs::read_to_string(target.join("keep")).unwrap(), "k");
        fs::remove_dir_all(&dir).unwrap();
    }
}
