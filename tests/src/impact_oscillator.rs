//! The vertical bounce of a platform on a rigid floor under a vertical harmonic
//! force: a one-degree-of-freedom impact oscillator, solved event by event with
//! the exact flight between events. It is the reference for a level platform
//! whose feet strike together (offset 180 degrees, rotors held at constant speed),
//! written without the plant's code.
//!
//! The height `z >= 0` of the feet above the floor obeys, in flight,
//!
//! ```text
//!   z'' = -g - A cos(w t + p)
//! ```
//!
//! (`A = F0 / M`, the exciting force's amplitude over the moving mass), so from
//! `(t0, z0, v0)`, with `tau = t - t0` and `s(t) = w t + p`,
//!
//! ```text
//!   z'(t) = v0 - g tau - (A / w) (sin s(t) - sin s(t0))
//!   z(t)  = z0 + v0 tau - g tau^2 / 2 + (A / w^2) (cos s(t) - cos s(t0)) + (A / w) sin s(t0) tau.
//! ```
//!
//! At the floor, approaching: Newton's restitution `z'+ = -e z'-` (one contact, or
//! several striking together without friction work: the same as Poisson's). A
//! rebound slower than `zeno` ends an accumulation: the platform rests (the
//! plant's rule, `Settings::zeno_velocity`) until the free acceleration
//! `-g - A cos s(t)` reaches `a_L`, at `s = acos(-(g + a_L) / A)` (mod 2 pi), where
//! it lifts off: `a_L = 0` is the ideal floor; the plant lifts off where the floor
//! would pull with its force tolerance, `a_L = (sum of the feet's eps_F) / M`.
//!
//! In the frame moving with `-(A / w^2) cos s(t)` this is the ball bouncing on a
//! sinusoidally vibrating table (Holmes, J. Sound Vib. 84 (1982) 173-189; Luck &
//! Mehta, Phys. Rev. E 48 (1993) 3988-3997) with `Gamma = A / g`.

use std::f64::consts::PI;

/// The oscillator's constants.
#[derive(Clone, Copy, Debug)]
pub struct Oscillator {
    /// Gravity, m/s^2.
    pub g: f64,
    /// Amplitude of the exciting acceleration `F0 / M`, m/s^2.
    pub a: f64,
    /// Angular frequency, rad/s.
    pub w: f64,
    /// Phase at t = 0, rad.
    pub phase: f64,
    /// Restitution.
    pub e: f64,
    /// Rebound speed below which the platform comes to rest, m/s.
    pub zeno: f64,
    /// Free acceleration at which the platform at rest lifts off, m/s^2 (0 for an
    /// ideal floor).
    pub liftoff: f64,
}

/// What happened at an event.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// An impact: normal velocity before and after, m/s.
    Impact(f64, f64),
    /// The platform leaves the floor from rest.
    Liftoff,
    /// An accumulation ends: the platform rests on the floor.
    Rest,
}

/// An event at time `t`, s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Event {
    /// Time, s.
    pub t: f64,
    /// What happened.
    pub kind: Kind,
}

/// A flight from `(t0, z0, v0)`.
#[derive(Clone, Copy, Debug)]
pub struct Flight {
    /// Start time, s.
    pub t0: f64,
    /// Height at the start, m.
    pub z0: f64,
    /// Velocity at the start, m/s.
    pub v0: f64,
}

impl Oscillator {
    /// The free acceleration `-g - A cos(w t + p)`, m/s^2.
    pub fn acceleration(&self, t: f64) -> f64 {
        -self.g - self.a * (self.w * t + self.phase).cos()
    }

    /// Height and velocity at `t` on `flight`.
    pub fn at(&self, f: &Flight, t: f64) -> (f64, f64) {
        let tau = t - f.t0;
        let (s0, s) = (self.w * f.t0 + self.phase, self.w * t + self.phase);
        let (aw, aw2) = (self.a / self.w, self.a / (self.w * self.w));
        let z = f.z0 + f.v0 * tau - 0.5 * self.g * tau * tau
            + aw2 * (s.cos() - s0.cos())
            + aw * s0.sin() * tau;
        let v = f.v0 - self.g * tau - aw * (s.sin() - s0.sin());
        (z, v)
    }

    /// The first time after `t0` where the platform resting on the floor lifts off:
    /// the free acceleration crosses `a_L` upwards,
    /// `w t + p = acos(-(g + a_L) / A) + 2 pi k`; `None` if it never does.
    pub fn next_liftoff(&self, t0: f64) -> Option<f64> {
        let g = self.g + self.liftoff;
        if self.a <= g {
            return None;
        }
        if self.acceleration(t0) > self.liftoff {
            return Some(t0);
        }
        let s_up = (-g / self.a).acos();
        let s0 = self.w * t0 + self.phase;
        let k = ((s0 - s_up) / (2.0 * PI)).ceil();
        Some((s_up + 2.0 * PI * k - self.phase) / self.w)
    }

    /// The landing of `flight` (the first return to `z = 0` after its start, while
    /// approaching), searched up to `t_max`: a scan with a step short against the
    /// flight, then bisection to the last bit.
    pub fn landing(&self, f: &Flight, t_max: f64) -> Option<f64> {
        let period = 2.0 * PI / self.w;
        // A short flight from the floor lasts about 2 v0 / |a0|: scan it finely.
        let a0 = self.acceleration(f.t0);
        let mut dt = period / 4000.0;
        if a0 < 0.0 && f.v0 > 0.0 {
            dt = dt.min(2.0 * f.v0 / -a0 / 50.0);
        }
        let mut t = f.t0;
        loop {
            let t1 = (t + dt).min(t_max);
            let (z1, _) = self.at(f, t1);
            if z1 <= 0.0 {
                let (mut lo, mut hi) = (t, t1);
                while hi - lo > 1e-15 * hi.abs().max(1.0) {
                    let mid = 0.5 * (lo + hi);
                    if mid <= lo || mid >= hi {
                        break;
                    }
                    if self.at(f, mid).0 > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                return Some(hi);
            }
            if t1 >= t_max {
                return None;
            }
            t = t1;
            // Grow the step again once past the start of a short flight.
            dt = (dt * 1.5).min(period / 4000.0);
        }
    }

    /// The events from rest on the floor at t = 0 up to `t_end`.
    pub fn run(&self, t_end: f64) -> Vec<Event> {
        let mut events = Vec::new();
        let mut t = 0.0;
        // At rest on the floor.
        'rest: while let Some(tl) = self.next_liftoff(t) {
            if tl >= t_end {
                break;
            }
            events.push(Event {
                t: tl,
                kind: Kind::Liftoff,
            });
            let mut flight = Flight {
                t0: tl,
                z0: 0.0,
                v0: 0.0,
            };
            loop {
                let Some(ti) = self.landing(&flight, t_end) else {
                    break 'rest;
                };
                let (_, v_before) = self.at(&flight, ti);
                let v_after = -self.e * v_before;
                events.push(Event {
                    t: ti,
                    kind: Kind::Impact(v_before, v_after),
                });
                if v_after < self.zeno {
                    events.push(Event {
                        t: ti,
                        kind: Kind::Rest,
                    });
                    t = ti;
                    continue 'rest;
                }
                flight = Flight {
                    t0: ti,
                    z0: 0.0,
                    v0: v_after,
                };
            }
        }
        events
    }

    /// The greatest height of `flight` before `t1`, m: where `z'` changes sign from
    /// + to - (bisection), or the larger end.
    pub fn apex(&self, f: &Flight, t1: f64) -> f64 {
        let n = 400;
        let mut best = self.at(f, f.t0).0.max(self.at(f, t1).0);
        let mut prev = f.t0;
        for i in 1..=n {
            let t = f.t0 + (t1 - f.t0) * i as f64 / n as f64;
            if self.at(f, prev).1 > 0.0 && self.at(f, t).1 <= 0.0 {
                let (mut lo, mut hi) = (prev, t);
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if self.at(f, mid).1 > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                best = best.max(self.at(f, lo).0);
            }
            prev = t;
        }
        best
    }
}
