//! Where a run leaves what the model describes: a body through the fundament, or a
//! free body turned over. Only declared contact points meet the fundament in the
//! plant; every other point of a body passes through it unopposed. So a machine
//! that leans onto a point it has no foot at (a platform on one foot) sinks through
//! the floor, and its travel is no travel.
//!
//! Checked at every trace row (every `output_step` and around every event), body
//! by body, from the row's poses:
//!
//! - **through the fundament**: a probe of the body ([`crate::plant::outline`]:
//!   each vertex of its outline, the convex hull of what it carries, that is not a
//!   contact point on the fundament, and the lowest point of each eccentric circle
//!   on it) lies more than [`BELOW_TOLERANCE`] below the fundament: its signed
//!   distance `(p - P) . n - r < -BELOW_TOLERANCE`, with `P` and `n` the
//!   fundament's point and normal from the machine file and `r` the circle's
//!   radius (0 for a point);
//! - **tipped over**: a free body (a tree's root that no joint holds to the
//!   fundament: the platform, a loose block) has turned by more than
//!   `[simulation] max_tilt` from its angle at t = 0. A body hinged to another
//!   turns as its joint lets it and is not judged.
//!
//! Each is reported once per body ([`Breach`]): when first, what, how far at worst.

use crate::machine::Machine;
use crate::numbers::sig;
use crate::plant::model::{Mount, PlantModel};
use crate::plant::outline::{outlines, Outline};

/// How far below the fundament a probe must be to count as through it, m: 1 mm.
/// The plant holds the contact points on the fundament to far better than that
/// (contacts within 1e-7 m of it take part in one impact, a closed contact is
/// projected back onto it after every step); 1 mm is 10^4 times that, so no
/// rounding or drift of the solver reaches it, and small against the reference
/// machine (its eccentric circles stand 10 mm above the floor).
pub const BELOW_TOLERANCE: f64 = 1e-3;

/// What went wrong with a body.
#[derive(Clone, Debug, PartialEq)]
pub enum BreachKind {
    /// A probe went more than [`BELOW_TOLERANCE`] below the fundament.
    Fundament {
        /// The first probe found below (its [`crate::plant::outline::Probe::what`]).
        first: String,
        /// How far below the deepest probe went, m (positive).
        deepest: f64,
        /// Which probe that was.
        deepest_what: String,
        /// When, s.
        deepest_t: f64,
    },
    /// A free body turned past the limit.
    Tilt {
        /// The limit, rad (`[simulation] max_tilt`).
        limit: f64,
        /// The largest turn from its angle at t = 0, signed (ccw positive), rad.
        largest: f64,
        /// When, s.
        largest_t: f64,
    },
}

/// A body that left what the model describes, found at the trace rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Breach {
    /// The body's name (`platform` for the first).
    pub body: String,
    /// The first trace row's time at which it was found, s.
    pub t: f64,
    /// What happened.
    pub kind: BreachKind,
}

impl Breach {
    /// Whether it is a body through the fundament (else a free body turned over).
    pub fn through_fundament(&self) -> bool {
        matches!(self.kind, BreachKind::Fundament { .. })
    }

    /// In a few words, with its time: `platform went through the fundament at t =
    /// 0.12 s`, `platform turned past simulation.max_tilt = 60 deg at t = 0.5 s`.
    pub fn short(&self) -> String {
        match &self.kind {
            BreachKind::Fundament { .. } => format!(
                "{} went through the fundament at t = {} s",
                self.body,
                sig(self.t)
            ),
            BreachKind::Tilt { limit, .. } => format!(
                "{} turned past simulation.max_tilt = {} deg at t = {} s",
                self.body,
                sig(limit.to_degrees()),
                sig(self.t)
            ),
        }
    }

    /// The warning: what, which point, when first, how far at worst.
    pub fn warning(&self) -> String {
        match &self.kind {
            BreachKind::Fundament {
                first,
                deepest,
                deepest_what,
                deepest_t,
            } => format!(
                "{} went through the fundament (only contact points meet it): first {first}, more than {} mm below at t = {} s; deepest {} mm below ({deepest_what}, t = {} s)",
                self.body,
                sig(BELOW_TOLERANCE * 1e3),
                sig(self.t),
                sig(deepest * 1e3),
                sig(*deepest_t)
            ),
            BreachKind::Tilt {
                limit,
                largest,
                largest_t,
            } => format!(
                "{} tipped over: first turned more than simulation.max_tilt = {} deg from its angle at t = 0 at t = {} s; furthest {} deg (t = {} s)",
                self.body,
                sig(limit.to_degrees()),
                sig(self.t),
                sig(largest.to_degrees()),
                sig(*largest_t)
            ),
        }
    }
}

/// One body as the watch follows it.
#[derive(Clone, Debug)]
struct Watched {
    outline: Outline,
    /// Whether it is a free root (judged for tilt).
    free: bool,
    /// Through the fundament: the first row's time and probe, the deepest.
    below: Option<(f64, String, f64, String, f64)>,
    /// Tipped: the first row's time, the largest turn and its time.
    tilt: Option<(f64, f64, f64)>,
}

/// Follows every body of a run row by row ([`BreachWatch::row`]).
#[derive(Clone, Debug)]
pub struct BreachWatch {
    bodies: Vec<Watched>,
    point: [f64; 2],
    normal: [f64; 2],
    max_tilt: f64,
}

impl BreachWatch {
    /// A watch over `machine`'s bodies.
    pub fn new(machine: &Machine) -> Self {
        let model = PlantModel::new(machine);
        let bodies = outlines(machine)
            .into_iter()
            .zip(&model.bodies)
            .map(|(outline, body)| Watched {
                outline,
                free: matches!(body.mount, Mount::Free { .. }),
                below: None,
                tilt: None,
            })
            .collect();
        BreachWatch {
            bodies,
            point: machine.fundament.point,
            normal: machine.fundament.normal,
            max_tilt: machine.simulation.max_tilt,
        }
    }

    /// Checks the trace row at `t`, s, whose body `b` (0 the platform) has its
    /// centre of mass at `pose(b)[0..2]` (m) and its angle `pose(b)[2]` (rad).
    pub fn row(&mut self, t: f64, pose: impl Fn(usize) -> [f64; 3]) {
        let (p0, n) = (self.point, self.normal);
        for (b, w) in self.bodies.iter_mut().enumerate() {
            let [cx, cy, angle] = pose(b);
            // A probe p (centre-of-mass frame) is at c + R(theta) p.
            let (s, c) = angle.sin_cos();
            for probe in &w.outline.probes {
                // Its height along n, less its radius: a circle's lowest point.
                let [px, py] = probe.point;
                let world = [cx + c * px - s * py, cy + s * px + c * py];
                let h = (world[0] - p0[0]) * n[0] + (world[1] - p0[1]) * n[1] - probe.radius;
                if h < -BELOW_TOLERANCE {
                    let depth = -h;
                    match &mut w.below {
                        None => {
                            w.below = Some((t, probe.what.clone(), depth, probe.what.clone(), t))
                        }
                        Some((_, _, deepest, what, when)) => {
                            if depth > *deepest {
                                *deepest = depth;
                                what.clone_from(&probe.what);
                                *when = t;
                            }
                        }
                    }
                }
            }
            let turn = angle - w.outline.pose0.angle;
            if w.free && turn.abs() > self.max_tilt {
                match &mut w.tilt {
                    None => w.tilt = Some((t, turn, t)),
                    Some((_, largest, when)) => {
                        if turn.abs() > largest.abs() {
                            *largest = turn;
                            *when = t;
                        }
                    }
                }
            }
        }
    }

    /// What was found, by time of first finding (a body's fundament before its
    /// tilt at equal times).
    pub fn finish(self) -> Vec<Breach> {
        self.found()
    }

    /// What was found so far, as [`BreachWatch::finish`] gives it; the watch
    /// goes on (a device's plant asks while it runs).
    pub fn found(&self) -> Vec<Breach> {
        let limit = self.max_tilt;
        let mut found = Vec::new();
        for w in &self.bodies {
            let body = &w.outline.name;
            if let Some((t, first, deepest, deepest_what, deepest_t)) = &w.below {
                found.push(Breach {
                    body: body.clone(),
                    t: *t,
                    kind: BreachKind::Fundament {
                        first: first.clone(),
                        deepest: *deepest,
                        deepest_what: deepest_what.clone(),
                        deepest_t: *deepest_t,
                    },
                });
            }
            if let Some((t, largest, largest_t)) = w.tilt {
                found.push(Breach {
                    body: body.clone(),
                    t,
                    kind: BreachKind::Tilt {
                        limit,
                        largest,
                        largest_t,
                    },
                });
            }
        }
        found.sort_by(|a, b| a.t.total_cmp(&b.t));
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference machine with `extra` appended (further bodies, say).
    fn machine(extra: &str) -> Machine {
        let text = include_str!("../../../examples/vibro-driver.toml").to_string() + extra;
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
        Machine::from_text("m.toml", &text, &dir, &[])
            .unwrap_or_else(|p| panic!("{}", crate::machine::input::render(&p)))
    }

    /// The lowest point of the reference platform's rotor "left"'s eccentric
    /// circle, its first probe.
    const LEFT_CIRCLE: &str = "the lowest point of rotor \"left\"'s eccentric circle";

    #[test]
    fn a_probe_counts_below_only_past_the_tolerance() {
        // The reference platform (centre of mass 30 mm up, its rotor axes at its
        // height with eccentric circles of 20 mm: their lowest points 10 mm up)
        // moved down by `drop`, level.
        let m = machine("");
        let sunk = |drop: f64| {
            let mut w = BreachWatch::new(&m);
            w.row(0.5, |_| [0.0, 0.03 - drop, 0.0]);
            w.finish()
        };
        // 0.5 mm below: within the tolerance. The feet, 10.5 mm below, may lie on
        // the floor or be pressed below it: they are the plant's to hold, not
        // probes.
        assert_eq!(sunk(0.0105), []);
        // 1.5 mm below: the circles' lowest points (the left one first).
        let found = sunk(0.0115);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!((found[0].body.as_str(), found[0].t), ("platform", 0.5));
        let BreachKind::Fundament { first, deepest, .. } = &found[0].kind else {
            panic!("{found:?}");
        };
        assert_eq!(first, LEFT_CIRCLE);
        assert!((deepest - 1.5e-3).abs() < 1e-12, "{deepest}");
    }

    #[test]
    fn a_circle_is_probed_at_its_lowest_point_whatever_the_turn() {
        // The reference platform turned by a quarter turn about its centre of
        // mass, held at height y: rotor "left"'s axis (-0.03, 0) in its frame is
        // then at (0, -0.03) below the centre, its circle's lowest point 50 mm
        // below it, whichever way the eccentric points. 0.5 mm and 1.5 mm deep.
        let m = machine("");
        for (y, through) in [(0.0495, false), (0.0485, true)] {
            let mut w = BreachWatch::new(&m);
            w.row(0.0, |_| [0.0, y, std::f64::consts::FRAC_PI_2]);
            let found = w.finish();
            let below = found.iter().find(|b| b.through_fundament());
            assert_eq!(below.is_some(), through, "{y}: {found:?}");
            if let Some(b) = below {
                let BreachKind::Fundament { first, deepest, .. } = &b.kind else {
                    panic!("{b:?}");
                };
                assert_eq!(first, LEFT_CIRCLE);
                assert!((deepest - 1.5e-3).abs() < 1e-12, "{deepest}");
            }
        }
    }

    #[test]
    fn the_first_finding_and_the_worst_are_kept() {
        let m = machine("");
        let mut w = BreachWatch::new(&m);
        // The circles' lowest points 10 mm up, then 2 mm below the floor at
        // 0.1 s, 5 mm at 0.2 s, 3 mm at 0.3 s.
        for (t, below) in [(0.0, -0.01), (0.1, 0.002), (0.2, 0.005), (0.3, 0.003)] {
            w.row(t, |_| [0.0, 0.02 - below, 0.0]);
        }
        let found = w.finish();
        let b = &found[0];
        assert_eq!(b.t, 0.1);
        let BreachKind::Fundament {
            deepest, deepest_t, ..
        } = b.kind
        else {
            panic!("{b:?}");
        };
        assert!((deepest - 0.005).abs() < 1e-12 && deepest_t == 0.2, "{b:?}");
        assert_eq!(
            b.warning(),
            format!("platform went through the fundament (only contact points meet it): first {LEFT_CIRCLE}, more than 1 mm below at t = 0.1 s; deepest 5 mm below ({LEFT_CIRCLE}, t = 0.2 s)")
        );
    }

    #[test]
    fn only_free_bodies_tip_over() {
        // The arm hinged to the platform and the loose block of three-bodies.toml,
        // each turned by 2 rad (115 degrees), everything high above the floor.
        let m = machine(include_str!("../../../tests/fixtures/three-bodies.toml"));
        let mut w = BreachWatch::new(&m);
        w.row(1.0, |b| match b {
            0 => [0.0, 1.0, 0.0],
            1 => [0.1, 1.2, 0.4 + 2.0],
            _ => [0.3, 1.4, 2.0],
        });
        let found = w.finish();
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].body, "block");
        assert_eq!(
            found[0].short(),
            "block turned past simulation.max_tilt = 60 deg at t = 1 s"
        );
        let BreachKind::Tilt { largest, .. } = found[0].kind else {
            panic!("{found:?}");
        };
        assert_eq!(largest, 2.0);
    }

    #[test]
    fn a_tilted_fundament_is_measured_along_its_normal() {
        // The floor through [0, 1] with its normal 30 degrees from +y, towards -x;
        // the platform turned with it (its centre of mass 30 mm along the normal
        // when standing on its feet), then sunk by 10.5 mm and by 11.5 mm: its
        // eccentric circles' lowest points 0.5 mm, then 1.5 mm, behind the floor.
        let a = 30f64.to_radians();
        let n = [-a.sin(), a.cos()];
        let mut m = machine("");
        m.fundament.point = [0.0, 1.0];
        m.fundament.normal = n;
        for (sunk, through) in [(0.0105, false), (0.0115, true)] {
            let mut w = BreachWatch::new(&m);
            let h = 0.03 - sunk;
            w.row(0.0, |_| [h * n[0], 1.0 + h * n[1], a]);
            let list = w.finish();
            assert_eq!(
                list.iter().any(Breach::through_fundament),
                through,
                "{sunk}: {list:?}"
            );
            assert!(!list.iter().any(|b| !b.through_fundament()), "{list:?}");
        }
    }
}
