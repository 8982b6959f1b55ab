//! The summary of a run (docs/cli-run.md, "Outputs", `--format json`): mean
//! velocity, distance, impacts, rotor speeds and phase offset, computed from the
//! recorded trace and events.
//!
//! Every statistic "over the second half" runs from `T/2` to `T`, with `T` the time
//! of the last trace row and `T/2` the midpoint between the first and the last row
//! (the first row is at `t = 0` in a run, so this is the documented `T/2`). Values at
//! `T/2` are interpolated linearly between the rows around it.
//!
//! Phase convention (docs/machine-file.md, "Conventions"): a rotor's encoder angle is
//! `theta_k = s_k (phi_k - index_angle_k)`, `s_k = +1` for ccw and `-1` for cw; the
//! phase offset is `theta_1 - theta_2` in degrees, wrapped to [0, 360). A machine
//! with one rotor has no offset: its summary has one rotor speed and no
//! `phase_offset_deg`.

use std::f64::consts::PI;

use crate::machine::{Machine, Rotor};
use crate::simulation::breach::{Breach, BreachWatch};
use shared::controller::angle::{wrap_deg_f64, wrap_deg_signed_f64};
use shared::controller::Faults;

use crate::event::{EventKind, EventRow};
use crate::simulation::closed_loop::LastTick;
use crate::simulation::trace::{EndState, FinalState, Summary, TraceRow};

/// Converts rad/s to rpm: `60 / (2 pi)`.
const RPM_PER_RAD_S: f64 = 60.0 / (2.0 * PI);

/// A rotor's encoder angle `theta = s (phi - index_angle)`, rad, not wrapped.
pub fn encoder_angle(phi: f64, rotor: &Rotor) -> f64 {
    rotor.sense.sign() * (phi - rotor.index_angle)
}

/// The phase offset `theta_1 - theta_2` in degrees, wrapped to [0, 360), of the
/// eccentric angles `phi1`, `phi2` (rad, platform frame) of `machine`'s rotors;
/// `None` on a one-rotor machine.
pub fn phase_offset_deg(phi1: f64, phi2: f64, machine: &Machine) -> Option<f64> {
    let r2 = machine.rotors.rotor2()?;
    let theta = encoder_angle(phi1, machine.rotors.rotor1()) - encoder_angle(phi2, r2);
    Some(wrap_deg_f64(theta.to_degrees()))
}

/// The distinct times of the impact events, ascending (the rows of one
/// simultaneous impact share their `t`, so each instant counts once).
pub fn impact_times(events: &[EventRow]) -> Vec<f64> {
    let mut times: Vec<f64> = events
        .iter()
        .filter(|e| e.kind == EventKind::Impact)
        .map(|e| e.t)
        .collect();
    times.sort_by(f64::total_cmp);
    times.dedup_by(|a, b| a.to_bits() == b.to_bits());
    times
}

/// The impact instants of impacts that come in time order, counted as they come:
/// the impacts of one simultaneous impact share their `t` (to the bit), so each
/// instant counts once ([`impact_times`] of them all). The summary's `impacts`,
/// and the animation's.
#[derive(Clone, Debug, Default)]
pub struct ImpactInstants {
    count: usize,
    last: Option<u64>,
}

impl ImpactInstants {
    /// Takes an impact at `t`, s (at or after the last): the number of instants
    /// so far, this one's included.
    pub fn add(&mut self, t: f64) -> usize {
        if self.last != Some(t.to_bits()) {
            self.count += 1;
            self.last = Some(t.to_bits());
        }
        self.count
    }

    /// The number of instants so far.
    pub fn count(&self) -> usize {
        self.count
    }
}

/// The second half's phase offset samples `(t, offset_deg)`: the interpolated value
/// at `half`, then every row after it (16 bytes a row, not the whole trace row).
#[derive(Clone, Debug, Default)]
struct SecondHalf {
    samples: Vec<(f64, f64)>,
}

impl SecondHalf {
    fn push(&mut self, t: f64, offset_deg: f64) {
        self.samples.push((t, offset_deg));
    }

    /// `(phase_offset_deg, phase_error_deg_rms)` with trapezoidal time weights
    /// `w_i = (t_{i+1} - t_{i-1}) / 2` (one-sided at the ends), which make the mean
    /// a time average however the rows are spaced; rows repeated at an event time
    /// get no weight of their own. When the half has no duration, equal weights.
    /// The RMS error is 0 without a commanded offset.
    fn finish(self, commanded_offset_deg: Option<f64>) -> (f64, f64) {
        let samples = self.samples;
        let n = samples.len();
        let mut weighted: Vec<(f64, f64)> = (0..n)
            .map(|i| {
                let before = samples[i.saturating_sub(1)].0;
                let after = samples[(i + 1).min(n - 1)].0;
                ((after - before) / 2.0, samples[i].1)
            })
            .collect();
        let total: f64 = weighted.iter().map(|(w, _)| w).sum();
        if !(total > 0.0 && total.is_finite()) {
            for (w, _) in &mut weighted {
                *w = 1.0;
            }
        }
        let rms = match commanded_offset_deg {
            Some(c) => rms_error_deg(&weighted, c),
            None => 0.0,
        };
        (circular_mean_deg(&weighted), rms)
    }
}

/// The circular mean of weighted angles in degrees, wrapped to [0, 360):
/// `atan2(sum w sin a, sum w cos a)`.
fn circular_mean_deg(samples: &[(f64, f64)]) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for (w, a) in samples {
        let a = a.to_radians();
        s += w * a.sin();
        c += w * a.cos();
    }
    wrap_deg_f64(s.atan2(c).to_degrees())
}

/// The weighted RMS of `a - commanded` wrapped to (-180, 180], degrees.
fn rms_error_deg(samples: &[(f64, f64)], commanded: f64) -> f64 {
    let (mut sum, mut total) = (0.0, 0.0);
    for (w, a) in samples {
        let e = wrap_deg_signed_f64(a - commanded);
        sum += w * e * e;
        total += w;
    }
    (sum / total).sqrt()
}

/// What the summary keeps of a trace row.
#[derive(Clone, Copy, Debug)]
struct Point {
    t: f64,
    x: f64,
    phi1: f64,
    phi2: f64,
}

impl Point {
    fn of(r: &TraceRow) -> Self {
        Point {
            t: r.t,
            x: r.x,
            phi1: r.phi1,
            phi2: r.phi2,
        }
    }
}

/// The summary built row by row, without keeping the trace: for a run whose first
/// and last times are known before it starts (`0` and `t_end`); over stored
/// rows, the first's and the last's.
#[derive(Clone, Debug)]
pub struct SummaryBuilder<'m> {
    machine: &'m Machine,
    half: f64,
    first: Option<Point>,
    /// The last row with `t <= half`.
    at_or_before_half: Option<Point>,
    /// `(x, phi1, phi2)` at `half`, once the first row after it came.
    at_half: Option<(f64, f64, f64)>,
    last: Option<TraceRow>,
    offsets: SecondHalf,
    /// Every body kept off the fundament and upright, row by row.
    breaches: BreachWatch,
}

impl<'m> SummaryBuilder<'m> {
    /// A builder for rows from `t0` to `t_end`, s.
    pub fn new(machine: &'m Machine, t0: f64, t_end: f64) -> Self {
        SummaryBuilder {
            machine,
            half: 0.5 * (t0 + t_end),
            first: None,
            at_or_before_half: None,
            at_half: None,
            last: None,
            offsets: SecondHalf::default(),
            breaches: BreachWatch::new(machine),
        }
    }

    /// Takes the next row (times ascending).
    pub fn push(&mut self, row: &TraceRow) {
        self.breaches.row(row.t, |b| match b {
            0 => [row.x, row.y, row.angle],
            _ => {
                let m = row.bodies[b - 1];
                [m[0], m[1], m[2]]
            }
        });
        let p = Point::of(row);
        self.first.get_or_insert(p);
        if p.t <= self.half {
            self.at_or_before_half = Some(p);
        } else {
            if self.at_half.is_none() {
                // The first row strictly after the half: interpolate there
                // (b.t > half >= a.t, so the denominator is positive).
                let v = match self.at_or_before_half {
                    None => (p.x, p.phi1, p.phi2),
                    Some(a) => {
                        let f = (self.half - a.t) / (p.t - a.t);
                        let lerp = |u: f64, v: f64| u + (v - u) * f;
                        (lerp(a.x, p.x), lerp(a.phi1, p.phi1), lerp(a.phi2, p.phi2))
                    }
                };
                self.at_half = Some(v);
                if let Some(o) = phase_offset_deg(v.1, v.2, self.machine) {
                    self.offsets.push(self.half, o);
                }
            }
            if let Some(o) = phase_offset_deg(p.phi1, p.phi2, self.machine) {
                self.offsets.push(p.t, o);
            }
        }
        self.last = Some(*row);
    }

    /// The summary of the rows taken, with `impacts` the number of distinct
    /// impact times and `last_tick` the controller that drove the windings
    /// (`None`: open loop):
    ///
    /// - `mean_velocity = (x(T) - x(T/2)) / (T/2)`, `distance = x(T) - x(0)`;
    /// - `rotor_speed_rpm[k] = s_k (phi_k(T) - phi_k(T/2)) / (T/2)` in rpm (phi
    ///   is unwrapped, so this is the exact mean speed in the driven sense);
    /// - `phase_offset_deg`: the time-weighted circular mean of the offset over
    ///   the second half; `phase_error_deg_rms`: the RMS of (offset - commanded),
    ///   wrapped to (-180, 180], over the second half when the controller held an
    ///   offset at its last tick, else 0;
    /// - `final_state`: the last row.
    ///
    /// Values at `T/2` are interpolated linearly between the last row with
    /// `row.t <= T/2` and the first row after it (so of two rows at one event
    /// time, the later, "after", one is used). No rows give zeros, the machine's
    /// initial state as the final state and a warning; rows of no duration give
    /// zero velocities and speeds.
    pub fn finish(
        self,
        impacts: usize,
        last_tick: Option<LastTick<'_>>,
        warnings: Vec<String>,
    ) -> Summary {
        self.conclude(impacts, Drive::of(last_tick), warnings)
    }

    /// [`Self::finish`] with what drove the windings.
    fn conclude(mut self, impacts: usize, drive: Drive, mut warnings: Vec<String>) -> Summary {
        let Drive {
            state,
            faults,
            commanded_offset_deg,
            phase_loop,
        } = drive;
        let machine = self.machine;
        let breaches = self.breaches.finish();
        warnings.extend(breaches.iter().map(Breach::warning));
        let rotors = machine.rotors.len();
        let two = machine.rotors.rotor2().is_some();
        let (Some(first), Some(last)) = (self.first, self.last) else {
            let p = &machine.platform;
            warnings.push("the run recorded no trace rows: the summary is empty".to_string());
            return Summary {
                impacts,
                rotor_speed_rpm: vec![0.0; rotors],
                phase_offset_deg: two.then_some(0.0),
                state,
                phase_loop,
                faults,
                final_state: FinalState {
                    position: p.position,
                    angle: p.angle,
                    velocity: p.velocity,
                    angular_velocity: p.angular_velocity,
                },
                warnings,
                ..Summary::default()
            };
        };
        // No row after the half: the values of the last row at or before it.
        let (x_half, phi1_half, phi2_half) = match self.at_half {
            Some(v) => v,
            None => {
                let a = self.at_or_before_half.unwrap_or(first);
                if let Some(o) = phase_offset_deg(a.phi1, a.phi2, machine) {
                    self.offsets.push(self.half, o);
                }
                (a.x, a.phi1, a.phi2)
            }
        };

        // The second half: from the midpoint to the end.
        let t_end = last.t;
        let duration = t_end - self.half;
        let rate = |end: f64, mid: f64| {
            if duration > 0.0 {
                (end - mid) / duration
            } else {
                0.0
            }
        };

        // Travel.
        let mean_velocity = rate(last.x, x_half);
        let distance = last.x - first.x;

        // Rotor speeds in the driven sense: s_k dphi_k/dt, in rpm.
        let phis = [(last.phi1, phi1_half), (last.phi2, phi2_half)];
        let rotor_speed_rpm = machine
            .rotors
            .iter()
            .zip(phis)
            .map(|(r, (end, mid))| r.sense.sign() * rate(end, mid) * RPM_PER_RAD_S)
            .collect();

        // Phase offset and its error over the second half (two rotors).
        let (phase_offset_deg, phase_error_deg_rms) = if two {
            let (mean, rms) = self.offsets.finish(commanded_offset_deg);
            (Some(mean), rms)
        } else {
            (None, 0.0)
        };

        Summary {
            t_end,
            mean_velocity,
            distance,
            impacts,
            rotor_speed_rpm,
            phase_offset_deg,
            phase_error_deg_rms,
            state,
            phase_loop,
            faults,
            final_state: FinalState {
                position: [last.x, last.y],
                angle: last.angle,
                velocity: [last.vx, last.vy],
                angular_velocity: last.omega,
            },
            warnings,
            breaches,
        }
    }
}

/// What drove the windings, as the summary reads it at the end of a run.
struct Drive {
    state: EndState,
    faults: Faults,
    /// The offset the controller held at its last tick, degrees.
    commanded_offset_deg: Option<f64>,
    phase_loop: bool,
}

impl Drive {
    fn of(last_tick: Option<LastTick<'_>>) -> Self {
        match last_tick {
            None => Drive {
                state: EndState::OpenLoop,
                faults: Faults::NONE,
                commanded_offset_deg: None,
                phase_loop: false,
            },
            Some(c) => Drive {
                state: EndState::Controller(c.state()),
                faults: c.faults(),
                commanded_offset_deg: c.held_offset_deg(),
                phase_loop: c.phase_loop(),
            },
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use shared::controller::State;

    /// [`summarize`] of `rows` without events, the controller running with
    /// `commanded_offset_deg` held, no fault and no warning.
    fn running(rows: &[TraceRow], machine: &Machine, commanded_offset_deg: Option<f64>) -> Summary {
        summarize(
            rows,
            &[],
            machine,
            commanded_offset_deg,
            EndState::Controller(State::Running),
            Faults::NONE,
            vec![],
        )
    }

    /// The summary of `rows` and `events` ending in `state`, `commanded_offset_deg`
    /// held (no phase loop), as [`SummaryBuilder::finish`] makes it.
    pub(crate) fn summarize(
        rows: &[TraceRow],
        events: &[EventRow],
        machine: &Machine,
        commanded_offset_deg: Option<f64>,
        state: EndState,
        faults: Faults,
        warnings: Vec<String>,
    ) -> Summary {
        let (t0, t_end) = match (rows.first(), rows.last()) {
            (Some(a), Some(b)) => (a.t, b.t),
            _ => (0.0, 0.0),
        };
        let mut builder = SummaryBuilder::new(machine, t0, t_end);
        for r in rows {
            builder.push(r);
        }
        let drive = Drive {
            state,
            faults,
            commanded_offset_deg,
            phase_loop: false,
        };
        builder.conclude(impact_times(events).len(), drive, warnings)
    }

    /// A machine like the reference one (`examples/vibro-driver.toml`): rotor 1
    /// "left" ccw, rotor 2 "right" cw, index angles given (rad).
    pub(crate) fn machine(index: [f64; 2]) -> Machine {
        let sets = [
            format!("rotors.left.index_angle={:?}", index[0]),
            format!("rotors.right.index_angle={:?}", index[1]),
        ];
        Machine::from_text(
            "test.toml",
            include_str!("../../../tests/fixtures/minimal-machine.toml"),
            std::path::Path::new(""),
            &sets,
        )
        .unwrap_or_else(|p| panic!("{}", crate::machine::input::render(&p)))
    }

    /// An impact event at `t`.
    pub(crate) fn impact(t: f64, contact: &str) -> EventRow {
        EventRow {
            t,
            kind: EventKind::Impact,
            contact: contact.to_string(),
            normal_velocity_before: -0.1,
            normal_velocity_after: 0.03,
            normal_impulse: 0.2,
            tangential_impulse: 0.01,
            case: Some(1),
            detail: String::new(),
        }
    }

    /// Rows every `dt` from 0 to `t_end` of `f(t)`.
    fn rows(t_end: f64, dt: f64, f: impl Fn(f64) -> TraceRow) -> Vec<TraceRow> {
        let n = (t_end / dt).round() as usize;
        (0..=n).map(|i| f(i as f64 * dt)).collect()
    }

    const TOL: f64 = 1e-9;

    /// The phase offset of a two-rotor summary.
    fn offset(s: &Summary) -> f64 {
        s.phase_offset_deg.expect("two rotors have an offset")
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn wrapping() {
        assert_eq!(wrap_deg_f64(0.0), 0.0);
        assert_eq!(wrap_deg_f64(360.0), 0.0);
        assert_eq!(wrap_deg_f64(-90.0), 270.0);
        assert_eq!(wrap_deg_f64(725.0), 5.0);
        assert_eq!(wrap_deg_f64(-1e-20), 0.0);
        assert_eq!(wrap_deg_signed_f64(180.0), 180.0);
        assert_eq!(wrap_deg_signed_f64(-180.0), 180.0);
        assert_eq!(wrap_deg_signed_f64(190.0), -170.0);
        assert_eq!(wrap_deg_signed_f64(-10.0), -10.0);
        assert_eq!(wrap_deg_signed_f64(350.0), -10.0);
    }

    #[test]
    fn phase_offset_follows_the_convention() {
        let m = machine([0.0, 0.0]);
        // Rotor 1 ccw at +30 deg, rotor 2 cw at -60 deg: theta_1 = 30, theta_2 = 60.
        let offset = phase_offset_deg(30f64.to_radians(), (-60f64).to_radians(), &m).unwrap();
        assert!(close(offset, 330.0, TOL), "{offset}");
        // Index angles shift each theta: theta_1 = 30 - 10, theta_2 = -(-60 - 20) = 80.
        let m = machine([10f64.to_radians(), 20f64.to_radians()]);
        let offset = phase_offset_deg(30f64.to_radians(), (-60f64).to_radians(), &m).unwrap();
        assert!(close(offset, 300.0, TOL), "{offset}");
        // A mirror-symmetric counter-rotating pair (phi_2 = pi - phi_1), with
        // phi_1 = 45 deg: theta_1 = 45, theta_2 = -135, offset 180: vertical.
        let m = machine([0.0, 0.0]);
        let offset = phase_offset_deg(45f64.to_radians(), 135f64.to_radians(), &m).unwrap();
        assert!(close(offset, 180.0, TOL), "{offset}");
    }

    #[test]
    fn constant_velocity_and_speeds() {
        // x = 0.1 + 0.05 t, rotor 1 ccw at 50 rev/s, rotor 2 cw at 40 rev/s (phi
        // decreasing), over 2 s: mean velocity 0.05 m/s, distance 0.1 m, speeds 3000
        // and 2400 rpm.
        let w1 = 2.0 * PI * 50.0;
        let w2 = 2.0 * PI * 40.0;
        let trace = rows(2.0, 1e-3, |t| TraceRow {
            t,
            x: 0.1 + 0.05 * t,
            y: 0.03,
            vx: 0.05,
            phi1: w1 * t,
            phi2: -w2 * t,
            omega1: w1,
            omega2: -w2,
            ..TraceRow::default()
        });
        let s = summarize(
            &trace,
            &[],
            &machine([0.0, 0.0]),
            None,
            EndState::OpenLoop,
            Faults::NONE,
            vec![],
        );
        assert_eq!(s.t_end, 2.0);
        assert!(close(s.mean_velocity, 0.05, TOL), "{}", s.mean_velocity);
        assert!(close(s.distance, 0.1, TOL), "{}", s.distance);
        assert!(
            close(s.rotor_speed_rpm[0], 3000.0, 1e-6),
            "{:?}",
            s.rotor_speed_rpm
        );
        assert!(
            close(s.rotor_speed_rpm[1], 2400.0, 1e-6),
            "{:?}",
            s.rotor_speed_rpm
        );
        assert_eq!(s.phase_error_deg_rms, 0.0);
        assert_eq!(s.state, EndState::OpenLoop);
        assert_eq!(s.impacts, 0);
        assert_eq!(s.final_state.position, [0.2, 0.03]);
        assert_eq!(s.final_state.velocity, [0.05, 0.0]);
    }

    #[test]
    fn midpoint_is_interpolated_between_uneven_rows() {
        // Rows at 0, 0.3, 1.3, 2.0 with x = t^2 at the rows: T/2 = 1 falls between
        // 0.3 (x 0.09) and 1.3 (x 1.69): x(1) = 0.09 + 1.6 * 0.7 = 1.21, so the mean
        // velocity is (4 - 1.21) / 1 = 2.79.
        let trace: Vec<TraceRow> = [0.0, 0.3, 1.3, 2.0]
            .iter()
            .map(|&t| TraceRow {
                t,
                x: t * t,
                ..TraceRow::default()
            })
            .collect();
        let s = running(&trace, &machine([0.0; 2]), None);
        assert!(close(s.mean_velocity, 2.79, TOL), "{}", s.mean_velocity);
        assert!(close(s.distance, 4.0, TOL));
    }

    #[test]
    fn duplicate_rows_at_the_midpoint_are_handled() {
        // An event at exactly T/2 = 1 gives two rows at t = 1 (x continuous, v
        // jumps); the mean velocity takes x(1) = 1 from them: (3 - 1) / 1 = 2.
        let row = |t: f64, x: f64, vx: f64| TraceRow {
            t,
            x,
            vx,
            ..TraceRow::default()
        };
        let trace = vec![
            row(0.0, 0.0, 1.0),
            row(0.5, 0.5, 1.0),
            row(1.0, 1.0, 1.0),
            row(1.0, 1.0, 3.0),
            row(1.5, 2.0, 3.0),
            row(2.0, 3.0, 3.0),
        ];
        let s = running(&trace, &machine([0.0; 2]), None);
        assert!(close(s.mean_velocity, 2.0, TOL), "{}", s.mean_velocity);
        assert_eq!(s.final_state.velocity, [3.0, 0.0]);
    }

    #[test]
    fn impacts_count_distinct_instants() {
        // Two contacts at one instant, then one, then one more: three instants. Other
        // kinds do not count.
        let mut events = vec![
            impact(0.1, "K1"),
            impact(0.1, "K2"),
            impact(0.25, "K1"),
            impact(0.4, "K2"),
        ];
        let mut liftoff = impact(0.3, "K1");
        liftoff.kind = EventKind::Liftoff;
        events.push(liftoff);
        let trace = rows(1.0, 0.1, |t| TraceRow {
            t,
            ..TraceRow::default()
        });
        let s = summarize(
            &trace,
            &events,
            &machine([0.0; 2]),
            None,
            EndState::Controller(State::Running),
            Faults::NONE,
            vec![],
        );
        assert_eq!(s.impacts, 3);
        assert_eq!(impact_times(&events), [0.1, 0.25, 0.4]);
        // Counted as they come: the same instants.
        let mut instants = ImpactInstants::default();
        let so_far: Vec<usize> = [0.1, 0.1, 0.25, 0.4].map(|t| instants.add(t)).to_vec();
        assert_eq!((so_far, instants.count()), (vec![1, 1, 2, 3], 3));
    }

    #[test]
    fn known_offset_and_its_error() {
        // Both rotors at 50 rev/s in their driven senses (rotor 2 cw, so phi2
        // decreases), rotor 1 ahead by 90 deg: theta_1 - theta_2 = 90 always.
        // Commanded 80: error 10 at every row, RMS 10.
        let w = 2.0 * PI * 50.0;
        let trace = rows(1.0, 1e-3, |t| TraceRow {
            t,
            phi1: w * t + PI / 2.0,
            phi2: -w * t,
            ..TraceRow::default()
        });
        let m = machine([0.0; 2]);
        let s = running(&trace, &m, Some(80.0));
        assert!(close(offset(&s), 90.0, 1e-6), "{}", offset(&s));
        assert!(
            close(s.phase_error_deg_rms, 10.0, 1e-6),
            "{}",
            s.phase_error_deg_rms
        );
        // Commanded 270: error 180 (wrapped to +180), RMS 180.
        let s = running(&trace, &m, Some(270.0));
        assert!(
            close(s.phase_error_deg_rms, 180.0, 1e-6),
            "{}",
            s.phase_error_deg_rms
        );
    }

    #[test]
    fn circular_mean_wraps_around_zero() {
        // The offset alternates 350 and 10 deg row by row in the second half: its
        // circular mean is 0 (an arithmetic mean would say 180). Against a command
        // of 0 the RMS error is 10.
        let trace = rows(2.0, 0.5, |t| {
            let offset: f64 = if (t / 0.5).round() as i64 % 2 == 0 {
                -10.0
            } else {
                10.0
            };
            TraceRow {
                t,
                phi1: offset.to_radians(),
                ..TraceRow::default()
            }
        });
        // Rows at 1.0 (350), 1.5 (10), 2.0 (350) with trapezoid weights 0.25, 0.5,
        // 0.25: the sines cancel, the mean is exactly 0 (or 360 rounded to 0).
        let s = running(&trace, &machine([0.0; 2]), Some(0.0));
        let off = wrap_deg_signed_f64(offset(&s));
        assert!(close(off, 0.0, 1e-9), "{}", offset(&s));
        assert!(offset(&s) >= 0.0 && offset(&s) < 360.0);
        assert!(
            close(s.phase_error_deg_rms, 10.0, 1e-9),
            "{}",
            s.phase_error_deg_rms
        );
    }

    #[test]
    fn circular_mean_of_a_spread_near_the_wrap() {
        // Offsets 355 and 15 with equal time weight: the mean is 5 deg.
        let mean = |a: f64, b: f64| {
            let mut h = SecondHalf::default();
            h.push(0.0, a);
            h.push(1.0, b);
            h.finish(None).0
        };
        assert!(close(mean(355.0, 15.0), 5.0, 1e-9));
        assert!(close(mean(340.0, 350.0), 345.0, 1e-9));
    }

    #[test]
    fn empty_and_single_row_traces() {
        let m = machine([0.0; 2]);
        let s = summarize(
            &[],
            &[],
            &m,
            Some(90.0),
            EndState::Controller(State::Idle),
            Faults::STALL,
            vec![],
        );
        assert_eq!(s.t_end, 0.0);
        assert_eq!(s.final_state.position, [0.0, 0.03]);
        assert_eq!(s.warnings.len(), 1);
        assert_eq!(s.faults, Faults::STALL);

        // At the machine's rest height: a platform at y = 0 has its eccentric
        // circles below the fundament (a breach, with its warning).
        let one = [TraceRow {
            t: 0.0,
            x: 0.5,
            y: 0.03,
            phi1: PI / 2.0,
            ..TraceRow::default()
        }];
        let s = summarize(
            &one,
            &[],
            &m,
            Some(80.0),
            EndState::Controller(State::Idle),
            Faults::NONE,
            vec![],
        );
        assert_eq!(s.mean_velocity, 0.0);
        assert_eq!(s.rotor_speed_rpm, [0.0, 0.0]);
        assert!(close(offset(&s), 90.0, 1e-9));
        assert!(close(s.phase_error_deg_rms, 10.0, 1e-9));
        assert_eq!(s.final_state.position, [0.5, 0.03]);
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    }

    #[test]
    fn one_rotor_has_one_speed_and_no_offset() {
        // Rotor 1 (ccw) at 50 rev/s; whatever rotor 2's columns hold is not read.
        let m = Machine::from_text(
            "one.toml",
            include_str!("../../../tests/fixtures/one-rotor-machine.toml"),
            std::path::Path::new(""),
            &[],
        )
        .unwrap_or_else(|p| panic!("{}", crate::machine::input::render(&p)));
        let w = 2.0 * PI * 50.0;
        let trace = rows(1.0, 1e-3, |t| TraceRow {
            t,
            phi1: w * t,
            phi2: 7.0 * t * t,
            ..TraceRow::default()
        });
        let s = running(&trace, &m, None);
        assert_eq!(s.rotor_speed_rpm.len(), 1);
        assert!(
            close(s.rotor_speed_rpm[0], 3000.0, 1e-6),
            "{:?}",
            s.rotor_speed_rpm
        );
        assert_eq!(s.phase_offset_deg, None);
        assert_eq!(s.phase_error_deg_rms, 0.0);
        assert_eq!(s.rotors(), 1);
        assert_eq!(phase_offset_deg(1.0, 2.0, &m), None);
        // An empty trace too.
        let s = summarize(
            &[],
            &[],
            &m,
            None,
            EndState::Controller(State::Idle),
            Faults::NONE,
            vec![],
        );
        assert_eq!((s.rotor_speed_rpm, s.phase_offset_deg), (vec![0.0], None));
    }
}
