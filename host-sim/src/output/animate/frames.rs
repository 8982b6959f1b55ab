//! The run's trace decimated into the animation's frames, and its impacts and
//! controller events, as JSON columns.
//!
//! **Decimation.** A frame every [`FRAME_STEP`] of simulated time: the first trace
//! row at or after each `k * FRAME_STEP` (the rows are every `output_step` and
//! around every event, so with the default 1 ms output step the frames are every
//! second regular row), and the run's last row. Frames are trace rows, never
//! interpolated: the page interpolates between them as it plays. Every impact is
//! kept (its time and contact, one entry per contact), whatever the frames, with
//! the number of impact instants up to it: the summary's count
//! ([`ImpactInstants`]), which counts the contacts of one simultaneous impact once.
//!
//! **Columns** (one number per frame, `null` for one that is not finite), rounded
//! to what the eye can use, decimals fixed so that the same run gives the same bytes:
//!
//! | column | what | unit | rounded to |
//! | --- | --- | --- | --- |
//! | `t` | time | s | 1e-6 |
//! | `x`, `y`, `angle` | the platform's centre of mass and angle | m, rad | 1e-9 |
//! | `phi1`, `phi2` | the eccentric angles in their bodies' frames, wrapped to [0, 2 pi) | rad | 1e-4 |
//! | `omega1`, `omega2` | their rates (`phi'`, not the driven sense) | rad/s | 1e-2 |
//! | `offset` | the phase offset `theta_1 - theta_2` in [0, 360) (two rotors only) | deg | 1e-2 |
//! | `fn_<c>`, `ft_<c>` | contact `c`'s persistent normal and tangential force | N | 1e-3 |
//! | `x_<b>`, `y_<b>`, `angle_<b>` | a further body's centre of mass and angle | m, rad | 1e-9 |

use std::f64::consts::TAU;
use std::fmt::Write as _;

use serde_json::Value;
use shared::impact::MAX_CONTACTS;

use crate::event::{EventKind, EventRow};
use crate::machine::Machine;
use crate::simulation::summary::{phase_offset_deg, ImpactInstants};
use crate::simulation::trace::TraceRow;

/// Simulated time between frames, s: ten frames per period of a 50 Hz hop.
pub const FRAME_STEP: f64 = 2e-3;

/// One column: its name, its decimals, and its numbers so far, comma-separated.
struct Column {
    name: String,
    decimals: usize,
    text: String,
}

/// The frames, impacts and controller events of a run as they stream in.
pub struct Frames {
    /// The columns, in the module doc's order.
    columns: Vec<Column>,
    /// Contacts, bodies after the platform, and whether there is an offset column.
    contacts: usize,
    bodies: usize,
    /// The machine, for the phase offset (two rotors), else `None`.
    offset: Option<Machine>,
    /// Index of the next frame time `k * FRAME_STEP`.
    next: u64,
    /// Frames so far.
    count: usize,
    /// The last row seen, and whether it became a frame.
    last: Option<(TraceRow, bool)>,
    /// Impacts: time (s), contact index (file order), the instants up to it.
    impacts: Vec<(f64, usize, usize)>,
    /// The impact instants so far.
    instants: ImpactInstants,
    /// Controller events: time (s), kind (`state`, `fault`), detail.
    controller: Vec<(f64, &'static str, String)>,
    /// Contact names, for the impacts' indices.
    names: Vec<String>,
}

/// `v` with `decimals` decimals, trailing zeros dropped, never `-0`; `null` when
/// not finite.
pub fn fixed(v: f64, decimals: usize) -> String {
    if !v.is_finite() {
        return "null".to_string();
    }
    let mut s = format!("{v:.decimals$}");
    if s.contains('.') {
        let trimmed = s.trim_end_matches('0').trim_end_matches('.').len();
        s.truncate(trimmed);
    }
    if s == "-0" {
        s = "0".to_string();
    }
    s
}

impl Frames {
    /// Frames for a run of `machine`.
    pub fn new(machine: &Machine) -> Self {
        let mut columns = Vec::new();
        let mut add = |name: String, decimals: usize| {
            columns.push(Column {
                name,
                decimals,
                text: String::new(),
            })
        };
        add("t".into(), 6);
        for name in ["x", "y", "angle"] {
            add(name.into(), 9);
        }
        for name in ["phi1", "phi2"] {
            add(name.into(), 4);
        }
        for name in ["omega1", "omega2"] {
            add(name.into(), 2);
        }
        let two_rotors = machine.rotors.rotor2().is_some();
        if two_rotors {
            add("offset".into(), 2);
        }
        let contacts = machine.contacts.len().min(MAX_CONTACTS);
        for c in &machine.contacts[..contacts] {
            add(format!("fn_{}", c.name), 3);
            add(format!("ft_{}", c.name), 3);
        }
        for b in &machine.bodies {
            for column in ["x", "y", "angle"] {
                add(format!("{column}_{}", b.name), 9);
            }
        }
        Frames {
            columns,
            contacts,
            bodies: machine.bodies.len(),
            offset: two_rotors.then(|| machine.clone()),
            next: 0,
            count: 0,
            last: None,
            impacts: Vec::new(),
            instants: ImpactInstants::default(),
            controller: Vec::new(),
            names: machine.contacts.iter().map(|c| c.name.clone()).collect(),
        }
    }

    /// Frames so far.
    pub fn count(&self) -> usize {
        self.count
    }

    /// A trace row (times ascending): a frame if it is the first at or after the
    /// next frame time (a nanosecond's slack for the rounding of `k * step`).
    pub fn row(&mut self, row: &TraceRow) {
        let due = self.next as f64 * FRAME_STEP - 1e-9;
        let kept = row.t >= due;
        if kept {
            self.push(row);
            self.next = ((row.t + 1e-9) / FRAME_STEP).floor() as u64 + 1;
        }
        self.last = Some((*row, kept));
    }

    /// A batch of events: the impacts and the controller's states and faults.
    pub fn events(&mut self, batch: &[EventRow]) {
        for e in batch {
            match e.kind {
                EventKind::Impact => {
                    let instants = self.instants.add(e.t);
                    if let Some(c) = self.names.iter().position(|n| *n == e.contact) {
                        self.impacts.push((e.t, c, instants));
                    }
                }
                EventKind::State | EventKind::Fault => {
                    self.controller.push((e.t, e.kind.name(), e.detail.clone()));
                }
                _ => {}
            }
        }
    }

    /// Appends `row` to every column.
    fn push(&mut self, r: &TraceRow) {
        let offset = self
            .offset
            .as_ref()
            .and_then(|m| phase_offset_deg(r.phi1, r.phi2, m));
        let mut values = vec![
            r.t,
            r.x,
            r.y,
            r.angle,
            r.phi1.rem_euclid(TAU),
            r.phi2.rem_euclid(TAU),
            r.omega1,
            r.omega2,
        ];
        values.extend(offset);
        for c in 0..self.contacts {
            values.extend([r.normal_force[c], r.tangential_force[c]]);
        }
        for b in &r.bodies[..self.bodies] {
            values.extend([b[0], b[1], b[2]]);
        }
        for (column, v) in self.columns.iter_mut().zip(values) {
            if self.count > 0 {
                column.text.push(',');
            }
            column.text.push_str(&fixed(v, column.decimals));
        }
        self.count += 1;
    }

    /// The columns as one JSON object `{"t": [...], "x": [...], ...}`, the run's
    /// last row made a frame first if it is not one.
    pub fn columns_json(&mut self) -> String {
        if let Some((row, false)) = self.last {
            self.push(&row);
            self.last = Some((row, true));
        }
        let mut out = String::with_capacity(self.columns.iter().map(|c| c.text.len() + 16).sum());
        out.push('{');
        for (i, c) in self.columns.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            let _ = write!(out, "{}:[{}]", Value::from(c.name.as_str()), c.text);
        }
        out.push('}');
        out
    }

    /// The events as JSON: `{"impacts": {"t": [...], "contact": [...], "instant":
    /// [...]}, "controller": [[t, kind, detail], ...]}` (s, to 1e-6; contact index
    /// in file order; the number of impact instants up to and with this impact;
    /// kind `state` or `fault`, detail its name). An impact of several contacts at
    /// once is one entry per contact, all with the same `instant`.
    pub fn events_json(&self) -> String {
        let join = |f: &dyn Fn(&(f64, usize, usize)) -> String| {
            self.impacts.iter().map(f).collect::<Vec<_>>().join(",")
        };
        let controller: Vec<String> = self
            .controller
            .iter()
            .map(|(t, kind, detail)| {
                format!(
                    "[{},{},{}]",
                    fixed(*t, 6),
                    Value::from(*kind),
                    Value::from(detail.as_str())
                )
            })
            .collect();
        format!(
            r#"{{"impacts":{{"t":[{}],"contact":[{}],"instant":[{}]}},"controller":[{}]}}"#,
            join(&|i| fixed(i.0, 6)),
            join(&|i| i.1.to_string()),
            join(&|i| i.2.to_string()),
            controller.join(",")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference machine (two rotors, two feet, no further body).
    fn reference() -> Machine {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/vibro-driver.toml");
        Machine::load(std::path::Path::new(path), &[]).expect("the reference machine")
    }

    fn row(t: f64, x: f64) -> TraceRow {
        TraceRow {
            t,
            x,
            ..TraceRow::default()
        }
    }

    /// The `t` and `x` columns of `frames`.
    fn times_and_x(frames: &mut Frames) -> (Vec<f64>, Vec<f64>) {
        let v: serde_json::Value = serde_json::from_str(&frames.columns_json()).unwrap();
        let numbers = |c: &str| -> Vec<f64> {
            v[c].as_array()
                .unwrap()
                .iter()
                .map(|n| n.as_f64().unwrap())
                .collect()
        };
        (numbers("t"), numbers("x"))
    }

    #[test]
    fn a_frame_is_the_first_row_at_or_after_each_step_and_the_last_row() {
        let mut frames = Frames::new(&reference());
        // Rows every 1 ms to 10 ms, a pair at an event at 3.5 ms, and the run's end
        // at 10.5 ms.
        let mut times: Vec<f64> = (0..=10).map(|k| k as f64 * 1e-3).collect();
        times.extend([3.5e-3, 3.5e-3, 10.5e-3]);
        times.sort_by(f64::total_cmp);
        for (k, t) in times.iter().enumerate() {
            frames.row(&row(*t, k as f64));
        }
        let (t, x) = times_and_x(&mut frames);
        assert_eq!(t, [0.0, 0.002, 0.004, 0.006, 0.008, 0.01, 0.0105]);
        // The rows themselves: 0.004 is the 7th row (after the event pair).
        assert_eq!(x, [0.0, 2.0, 6.0, 8.0, 10.0, 12.0, 13.0]);
    }

    #[test]
    fn every_impact_is_kept_and_controller_events_too() {
        let mut frames = Frames::new(&reference());
        let impact = |t: f64, contact: &str| EventRow {
            contact: contact.to_string(),
            ..EventRow::controller(t, EventKind::Impact, String::new())
        };
        // Two feet at one instant, one a nanosecond later (one microsecond in
        // the page's rounding of times): three foot impacts, two instants, as
        // the summary counts them.
        frames.events(&[
            impact(1e-4, "K1"),
            impact(1e-4, "K2"),
            impact(1.001e-4, "K2"),
        ]);
        frames.events(&[
            EventRow::controller(0.2, EventKind::State, "running".into()),
            EventRow::controller(0.25, EventKind::Liftoff, String::new()),
        ]);
        assert_eq!(
            frames.events_json(),
            r#"{"impacts":{"t":[0.0001,0.0001,0.0001],"contact":[0,1,1],"instant":[1,1,2]},"controller":[[0.2,"state","running"]]}"#
        );
    }

    #[test]
    fn fixed_drops_trailing_zeros_and_negative_zero() {
        assert_eq!(fixed(0.002, 6), "0.002");
        assert_eq!(fixed(3.0, 6), "3");
        assert_eq!(fixed(-1e-12, 9), "0");
        assert_eq!(fixed(-0.0300000004, 9), "-0.03");
        assert_eq!(fixed(f64::NAN, 3), "null");
        assert_eq!(fixed(f64::INFINITY, 3), "null");
        assert_eq!(fixed(123.456, 2), "123.46");
    }
}
