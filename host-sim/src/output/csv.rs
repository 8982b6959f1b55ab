//! The trace (`--out`) and the events (`--events`) of a run as CSV
//! (docs/cli-run.md, "Outputs"): a header line, then one line per row, fields separated
//! by commas, lines ending with `\n`; text fields quoted as RFC 4180 says (in double
//! quotes, inner quotes doubled) when they hold a comma, a quote or a line break.
//! Numbers are written by [`csv_number`]: the shortest decimal that reads back to the
//! same `f64`, plain between 1e-4 and 1e16 and scientific outside (`0.001`, `-2.5`,
//! `3`, `1.5e-9`, `2e20`), `NaN`, `inf` and `-inf` for the non-finite.

use std::fmt::Write as _;

use shared::impact::MAX_CONTACTS;

use crate::event::EventRow;
use crate::machine::MachineContact;
use crate::simulation::trace::TraceRow;

/// The trace CSV's columns that every machine has (docs/cli-run.md, `--out`);
/// the contact forces follow ([`trace_header`]).
pub const TRACE_HEADER: &str = "t,x,y,angle,vx,vy,omega,phi1,phi2,omega1,omega2,i1,i2,duty1,duty2";

/// The columns of every body after the platform, `<column>_<name>`: centre of
/// mass (m), angle (rad), their rates (m/s, rad/s).
pub const BODY_COLUMNS: [&str; 6] = ["x", "y", "angle", "vx", "vy", "omega"];

/// The trace CSV's header for a machine whose contacts are named `contacts` and
/// whose bodies after the platform `bodies`: [`TRACE_HEADER`], then per contact in
/// file order `fn_<name>,ft_<name>` (the normal and tangential force of persistent
/// contact, N), then per body [`BODY_COLUMNS`] with `_<name>`.
pub fn trace_header(contacts: &[String], bodies: &[String]) -> String {
    let mut header = TRACE_HEADER.to_string();
    for name in contacts {
        let _ = write!(
            header,
            ",{},{}",
            csv_text(&format!("fn_{name}")),
            csv_text(&format!("ft_{name}"))
        );
    }
    for name in bodies {
        for column in BODY_COLUMNS {
            let _ = write!(header, ",{}", csv_text(&format!("{column}_{name}")));
        }
    }
    header
}

/// The events CSV's header (docs/cli-run.md, `--events`), ending with the contact's
/// two bodies (`body`, the point's; `against`, the face's: a body or `fundament`;
/// empty for controller events).
pub const EVENTS_HEADER: &str = "t,kind,contact,normal_velocity_before,normal_velocity_after,normal_impulse,tangential_impulse,case,detail,body,against";

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

/// One trace row as a CSV line (with its line break) appended to `out`: the
/// fifteen columns every machine has, then normal and tangential force of the
/// first `contacts` contacts, then the motion of the first `bodies` bodies after
/// the platform.
pub fn trace_line(r: &TraceRow, contacts: usize, bodies: usize, out: &mut String) {
    let n = contacts.min(MAX_CONTACTS);
    let fields = [
        r.t, r.x, r.y, r.angle, r.vx, r.vy, r.omega, r.phi1, r.phi2, r.omega1, r.omega2, r.i1,
        r.i2, r.duty1, r.duty2,
    ];
    let forces = (0..n).flat_map(|j| [r.normal_force[j], r.tangential_force[j]]);
    let motion = r.bodies.iter().take(bodies).flatten().copied();
    for (i, v) in fields.into_iter().chain(forces).chain(motion).enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push_str(&csv_number(v));
    }
    out.push('\n');
}

/// Appends one line of the `--events` CSV (after [`EVENTS_HEADER`]) for `e`, its
/// newline included; `case` empty when the row has none; `body` and `against`
/// those of the machine's contact it names (empty for a row naming none).
pub fn event_line(e: &EventRow, contacts: &[MachineContact], out: &mut String) {
    let case = e.case.map(|c| c.to_string()).unwrap_or_default();
    let (body, against) = contacts
        .iter()
        .find(|c| c.name == e.contact)
        .map_or(("", ""), |c| {
            (c.ends.body.as_str(), c.ends.against.as_str())
        });
    // Writing to a String cannot fail.
    let _ = writeln!(
        out,
        "{},{},{},{},{},{},{},{},{},{},{}",
        csv_number(e.t),
        e.kind.name(),
        csv_text(&e.contact),
        csv_number(e.normal_velocity_before),
        csv_number(e.normal_velocity_after),
        csv_number(e.normal_impulse),
        csv_number(e.tangential_impulse),
        case,
        csv_text(&e.detail),
        csv_text(body),
        csv_text(against),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `--events` CSV of `rows` for a machine with `contacts`.
    fn events_csv(rows: &[EventRow], contacts: &[MachineContact]) -> String {
        let mut out = format!("{EVENTS_HEADER}\n");
        for e in rows {
            event_line(e, contacts, &mut out);
        }
        out
    }

    /// The `--out` trace of a machine whose contacts are named `contacts`:
    /// [`trace_header`], then one line per row ([`trace_line`]).
    fn trace_csv(rows: &[TraceRow], contacts: &[String]) -> String {
        let n = contacts.len().min(MAX_CONTACTS);
        let mut out = String::with_capacity(32 + rows.len() * (15 + 2 * n) * 12);
        out.push_str(&trace_header(&contacts[..n], &[]));
        out.push('\n');
        for r in rows {
            trace_line(r, n, 0, &mut out);
        }
        out
    }
    use crate::event::EventKind;

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
    fn trace_has_the_documented_columns() {
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
            EventRow::controller(
                0.75,
                EventKind::Fault,
                "overcurrent, rotor \"left\"".to_string(),
            ),
        ];
        let machine = crate::machine::Machine::from_text(
            "m.toml",
            include_str!("../../../examples/vibro-driver.toml"),
            std::path::Path::new("examples"),
            &[],
        )
        .expect("the reference machine");
        let csv = events_csv(&rows, &machine.contacts);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines[0], EVENTS_HEADER);
        assert_eq!(
            lines[1],
            "0.5,impact,K1,-0.25,0.075,0.5,-0.125,3,,platform,fundament"
        );
        assert_eq!(
            lines[2],
            "0.75,fault,,0,0,0,0,,\"overcurrent, rotor \"\"left\"\"\",,"
        );
        assert_eq!(csv_text("a\nb"), "\"a\nb\"");
    }
}
