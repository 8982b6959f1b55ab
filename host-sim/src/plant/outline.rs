//! Every body's outline: the shape the animation draws and the fundament check
//! ([`crate::simulation::breach`]) follows, defined once here.
//!
//! The machine file describes no shape, only points. A body's **outline** is the
//! convex hull, in its centre-of-mass frame, of what it carries: its centre of mass,
//! its contact points, its rotors' eccentric circles (each axis with the circle of
//! radius `eccentricity` about it), its joints and the faces of contacts against it.
//! No part of the machine lies outside it (a box around those points would: the
//! corner of a body's bounding box beside a narrow foot is no part of it, and a
//! small rock about that foot took it through the floor). A body that carries only
//! its centre of mass, or points on one line, has a point or a segment for its
//! outline.
//!
//! The hull is exact; its polygon ([`Outline::polygon`], what the page draws) takes
//! each eccentric circle as the regular polygon of [`CIRCLE_SIDES`] sides through
//! it, at most `e (1 - cos(pi / 48))` = 0.21 % of the eccentricity `e` inside the
//! circle (0.04 mm for the reference machine's 20 mm).
//!
//! **The centre-of-mass frame** (m): origin at the body's centre of mass, axes
//! turning with it; the frame the trace's pose columns place (`x, y, angle` for the
//! platform, `x_<name>, y_<name>, angle_<name>` for a further body). A point `p`
//! (world, t = 0) of a body whose centre of mass is `c_0` and angle `theta_0` at
//! t = 0 is `R(-theta_0) (p - c_0)` there, and at time t it is at
//! `c(t) + R(theta(t)) R(-theta_0) (p - c_0)`.
//!
//! **Probes**: what of a body must stay on the machine's side of the fundament,
//! so that the whole outline does: each vertex of the hull that is a point it
//! carries and not one of its contact points on the fundament (those touch the
//! floor by design, and the plant holds them there), and each rotor's eccentric
//! circle by its lowest point along the fundament's normal, which is exact for any
//! turn of the body (the axis less `e n`). A linear height over a convex outline is
//! lowest at a vertex or on a circle, so nothing of the outline goes deeper than
//! its deepest probe.

use crate::machine::bodies::{FUNDAMENT, PLATFORM};
use crate::machine::{Machine, Platform};

/// The sides of the polygon that stands for an eccentric circle in
/// [`Outline::polygon`].
pub const CIRCLE_SIDES: usize = 48;

/// A body's pose at t = 0: its centre of mass (world, m) and angle (rad).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose0 {
    /// Centre of mass, world, m.
    pub centre: [f64; 2],
    /// Angle, rad.
    pub angle: f64,
}

impl Pose0 {
    /// The pose of a body as the file gives it.
    pub fn of(rigid: &Platform) -> Self {
        Pose0 {
            centre: rigid.position,
            angle: rigid.angle,
        }
    }

    /// World point `p` at t = 0 in the body's centre-of-mass frame:
    /// `R(-theta_0) (p - c_0)`.
    pub fn point(&self, p: [f64; 2]) -> [f64; 2] {
        self.vector([p[0] - self.centre[0], p[1] - self.centre[1]])
    }

    /// World vector `v` at t = 0 in the body's frame: `R(-theta_0) v`.
    pub fn vector(&self, v: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.angle.sin_cos();
        [c * v[0] + s * v[1], -s * v[0] + c * v[1]]
    }
}

/// A point or circle of a body the fundament check follows.
#[derive(Clone, Debug, PartialEq)]
pub struct Probe {
    /// What it is, for a message: `its centre of mass`, `joint "hinge"`, `the
    /// lowest point of rotor "left"'s eccentric circle`.
    pub what: String,
    /// Where, in the body's centre-of-mass frame, m: the point, or the circle's
    /// centre.
    pub point: [f64; 2],
    /// The circle's radius, m (0 for a point): its lowest point along the
    /// fundament's normal `n` is `point - radius n`, whatever the body's turn.
    pub radius: f64,
}

/// A body's outline and the points the fundament check follows.
#[derive(Clone, Debug, PartialEq)]
pub struct Outline {
    /// The body's name (`platform` for the first).
    pub name: String,
    /// Its pose at t = 0.
    pub pose0: Pose0,
    /// The hull's vertices counter-clockwise in its centre-of-mass frame, m, each
    /// eccentric circle as [`CIRCLE_SIDES`] points on it (one vertex for a body
    /// that carries one point, two for points on one line).
    pub polygon: Vec<[f64; 2]>,
    /// The hull's vertices that are carried points (not contact points on the
    /// fundament), then its rotors' eccentric circles.
    pub probes: Vec<Probe>,
}

/// The machine's bodies, the platform first, as (name, pose at t = 0).
pub fn bodies(machine: &Machine) -> Vec<(&str, Pose0)> {
    let mut list = vec![(PLATFORM, Pose0::of(&machine.platform))];
    list.extend(
        machine
            .bodies
            .iter()
            .map(|b| (b.name.as_str(), Pose0::of(&b.rigid))),
    );
    list
}

/// A point a body carries, in its frame.
#[derive(Clone, Debug)]
struct Carried {
    point: [f64; 2],
    /// What it is; `None` for a point on an eccentric circle (its circle is a
    /// probe of its own).
    what: Option<String>,
}

/// Every body's outline, the platform first, then `[[bodies]]` in file order.
pub fn outlines(machine: &Machine) -> Vec<Outline> {
    let bodies = bodies(machine);
    let index = |name: &str| bodies.iter().position(|(n, _)| *n == name);
    let at = |b: usize, p: [f64; 2]| bodies[b].1.point(p);
    let named = |point: [f64; 2], what: String| Carried {
        point,
        what: Some(what),
    };
    // What each body carries, in its frame: its centre of mass first.
    let mut carried: Vec<Vec<Carried>> = (0..bodies.len())
        .map(|_| vec![named([0.0, 0.0], "its centre of mass".to_string())])
        .collect();
    let mut circles: Vec<Vec<Probe>> = vec![Vec::new(); bodies.len()];
    let mut feet: Vec<Vec<[f64; 2]>> = vec![Vec::new(); bodies.len()];
    for r in &machine.rotors {
        if let Some(b) = index(&r.body) {
            let axis = at(b, r.axis);
            let e = r.eccentricity;
            if e > 0.0 {
                carried[b].extend(circle(axis, e).map(|point| Carried { point, what: None }));
            } else {
                // No eccentric circle: the axis itself lies inside the outline.
                carried[b].push(Carried {
                    point: axis,
                    what: None,
                });
            }
            circles[b].push(Probe {
                what: if e > 0.0 {
                    format!("the lowest point of rotor {:?}'s eccentric circle", r.name)
                } else {
                    format!("rotor {:?}'s axis", r.name)
                },
                point: axis,
                radius: e,
            });
        }
    }
    for c in &machine.contacts {
        if let Some(b) = index(&c.ends.body) {
            let point = at(b, c.point);
            carried[b].push(named(point, format!("contact {:?}'s point", c.name)));
            if c.ends.against == FUNDAMENT {
                feet[b].push(point);
            }
        }
        if c.ends.against != FUNDAMENT {
            if let Some(a) = index(&c.ends.against) {
                let face = at(a, c.ends.face.unwrap_or(c.point));
                carried[a].push(named(face, format!("the face of contact {:?}", c.name)));
            }
        }
    }
    for j in &machine.joints {
        // Both bodies carry the hinge (the fundament is no body here).
        for name in &j.bodies {
            if let Some(a) = index(name) {
                carried[a].push(named(at(a, j.point), format!("joint {:?}", j.name)));
            }
        }
    }
    bodies
        .iter()
        .enumerate()
        .map(|(b, (name, pose0))| {
            let hull = convex_hull(&carried[b]);
            let mut probes: Vec<Probe> = hull
                .iter()
                .filter(|v| !feet[b].contains(&v.point))
                .filter_map(|v| {
                    Some(Probe {
                        what: v.what.clone()?,
                        point: v.point,
                        radius: 0.0,
                    })
                })
                .collect();
            probes.append(&mut circles[b]);
            Outline {
                name: name.to_string(),
                pose0: *pose0,
                polygon: hull.iter().map(|v| v.point).collect(),
                probes,
            }
        })
        .collect()
}

/// [`CIRCLE_SIDES`] points on the circle of radius `r` about `centre`, the first
/// at its lowest point in the body's frame.
fn circle(centre: [f64; 2], r: f64) -> impl Iterator<Item = [f64; 2]> {
    (0..CIRCLE_SIDES).map(move |k| {
        let a =
            -std::f64::consts::FRAC_PI_2 + std::f64::consts::TAU * k as f64 / CIRCLE_SIDES as f64;
        [centre[0] + r * a.cos(), centre[1] + r * a.sin()]
    })
}

/// The convex hull of `points`, its vertices counter-clockwise from the lowest
/// of the leftmost (Andrew's monotone chain: A. M. Andrew, "Another efficient
/// algorithm for convex hulls in two dimensions", Information Processing Letters
/// 9, 1979). Points on an edge are no vertex; of equal points the first is kept.
/// One point: itself; points on one line: the two ends.
fn convex_hull(points: &[Carried]) -> Vec<Carried> {
    let mut sorted: Vec<&Carried> = Vec::with_capacity(points.len());
    for p in points {
        if !sorted.iter().any(|q| q.point == p.point) {
            sorted.push(p);
        }
    }
    sorted.sort_by(|a, b| {
        a.point[0]
            .total_cmp(&b.point[0])
            .then(a.point[1].total_cmp(&b.point[1]))
    });
    if sorted.len() < 3 {
        return sorted.into_iter().cloned().collect();
    }
    // The lower chain left to right, then the upper one right to left.
    let mut hull = left_turns(sorted.iter().copied());
    hull.extend(left_turns(sorted.iter().rev().copied()));
    hull.into_iter().cloned().collect()
}

/// The chain through `order` that turns left at every vertex (a point where it
/// would not is dropped), without its last point (the other chain's first).
fn left_turns<'a>(order: impl Iterator<Item = &'a Carried>) -> Vec<&'a Carried> {
    // (b - a) x (c - a) > 0: c is left of the line from a to b.
    let cross = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    let mut c: Vec<&Carried> = Vec::new();
    for p in order {
        while c.len() >= 2 && cross(c[c.len() - 2].point, c[c.len() - 1].point, p.point) <= 0.0 {
            c.pop();
        }
        c.push(p);
    }
    c.pop();
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(path: &str, sets: &[String]) -> Machine {
        let path = format!("{}/../{path}", env!("CARGO_MANIFEST_DIR"));
        Machine::load(std::path::Path::new(&path), sets).expect("a shipped machine")
    }

    #[test]
    fn a_point_at_t0_is_taken_into_the_turned_frame() {
        // A body at (1, 2) turned by 90 degrees: the world point (1, 3), one up
        // from its centre, is +x of its own frame.
        let pose = Pose0 {
            centre: [1.0, 2.0],
            angle: std::f64::consts::FRAC_PI_2,
        };
        let p = pose.point([1.0, 3.0]);
        assert!((p[0] - 1.0).abs() < 1e-15 && p[1].abs() < 1e-15, "{p:?}");
    }

    /// Named points at `at` (`p0`, `p1`, ...).
    fn points(at: &[[f64; 2]]) -> Vec<Carried> {
        at.iter()
            .enumerate()
            .map(|(k, &point)| Carried {
                point,
                what: Some(format!("p{k}")),
            })
            .collect()
    }

    fn names(hull: &[Carried]) -> Vec<&str> {
        hull.iter().map(|v| v.what.as_deref().unwrap()).collect()
    }

    #[test]
    fn the_hull_keeps_the_corners_counter_clockwise_and_drops_the_rest() {
        // A square's corners given out of order, its centre, a point on its lower
        // edge and a corner again.
        let hull = convex_hull(&points(&[
            [1.0, 1.0],
            [0.0, 0.0],
            [0.5, 0.5],
            [1.0, 0.0],
            [0.5, 0.0],
            [0.0, 1.0],
            [1.0, 1.0],
        ]));
        assert_eq!(names(&hull), ["p1", "p3", "p0", "p5"]);
        // Points on one line: its two ends; one point: itself.
        let line = convex_hull(&points(&[[0.0, 0.0], [2.0, 1.0], [1.0, 0.5], [-2.0, -1.0]]));
        assert_eq!(names(&line), ["p3", "p1"]);
        assert_eq!(names(&convex_hull(&points(&[[3.0, 4.0]]))), ["p0"]);
    }

    #[test]
    fn a_circle_is_a_polygon_through_it_from_its_lowest_point() {
        let c: Vec<[f64; 2]> = circle([1.0, 2.0], 0.5).collect();
        assert_eq!(c.len(), CIRCLE_SIDES);
        assert!((c[0][0] - 1.0).abs() < 1e-15 && (c[0][1] - 1.5).abs() < 1e-15);
        for p in &c {
            assert!(
                ((p[0] - 1.0).hypot(p[1] - 2.0) - 0.5).abs() < 1e-15,
                "{p:?}"
            );
        }
    }

    #[test]
    fn the_reference_platform_is_its_feet_under_its_eccentric_circles() {
        // Feet K1, K2 at [-+0.08, -0.03] from the centre of mass [0, 0.03]; rotor
        // axes at [-+0.03, 0] with eccentricity 0.02: the hull runs from foot to
        // foot along the floor, up to each circle and over both, and its probes are
        // the circles (the centre of mass and the axes are inside it, the feet on
        // the floor).
        let m = load("examples/vibro-driver.toml", &[]);
        let o = &outlines(&m)[0];
        assert_eq!(o.name, "platform");
        let close = |a: [f64; 2], e: [f64; 2]| (a[0] - e[0]).hypot(a[1] - e[1]) < 1e-12;
        assert!(close(o.polygon[0], [-0.08, -0.03]), "{:?}", o.polygon);
        assert!(close(o.polygon[1], [0.08, -0.03]), "{:?}", o.polygon);
        // The rest on the circles, none below y = -0.02 nor beyond x = +-0.05.
        for p in &o.polygon[2..] {
            let on = |c: f64| ((p[0] - c).hypot(p[1]) - 0.02).abs() < 1e-12;
            assert!(on(-0.03) || on(0.03), "{p:?}");
        }
        let what: Vec<&str> = o.probes.iter().map(|p| p.what.as_str()).collect();
        assert_eq!(
            what,
            [
                "the lowest point of rotor \"left\"'s eccentric circle",
                "the lowest point of rotor \"right\"'s eccentric circle",
            ]
        );
        assert_eq!(o.probes[0].point, [-0.03, 0.0]);
        assert_eq!(o.probes[0].radius, 0.02);
    }

    #[test]
    fn no_corner_beside_narrow_feet_is_probed() {
        // Issue 23: the feet moved in to x = +-0.01, the bounding box's lower
        // corners stood at x = -+0.05 at the feet's height, no part of the
        // machine, and a rock of 1.9 degrees took one 1.3 mm through the floor.
        // The hull runs from the feet straight to the circles: nothing of it is
        // lower than the feet, and no probe is beside them.
        let m = load(
            "examples/vibro-driver.toml",
            &[
                "contacts.K1.point=[-0.01, 0.0]".into(),
                "contacts.K2.point=[0.01, 0.0]".into(),
            ],
        );
        let o = &outlines(&m)[0];
        for p in &o.polygon {
            assert!(p[1] >= -0.03, "{p:?}");
            if p[1] < -0.02 + 1e-12 {
                assert!(p[0].abs() <= 0.03 + 1e-12, "{p:?}");
            }
        }
        assert!(o.probes.iter().all(|p| p.radius == 0.02), "{:?}", o.probes);
    }

    #[test]
    fn contact_points_against_a_body_joints_and_faces_are_probes() {
        // three-bodies.toml: the arm carries its hinge, its contact point `stop`
        // (against the platform, not the floor) and the face `touch` strikes; the
        // block its point `touch`: they are points of the body, not feet.
        let text = std::fs::read_to_string(format!(
            "{}/../tests/fixtures/three-bodies.toml",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap();
        let base = format!(
            "{}/../examples/vibro-driver.toml",
            env!("CARGO_MANIFEST_DIR")
        );
        let text = std::fs::read_to_string(base).unwrap() + &text;
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
        let m = Machine::from_text("m.toml", &text, &dir, &[]).expect("three bodies");
        let all = outlines(&m);
        let what =
            |o: &Outline| -> Vec<String> { o.probes.iter().map(|p| p.what.clone()).collect() };
        let arm = what(&all[1]);
        for w in [
            "joint \"hinge\"",
            "contact \"stop\"'s point",
            "the face of contact \"touch\"",
        ] {
            assert!(arm.contains(&w.to_string()), "{arm:?}");
        }
        // The block: its centre of mass and its point, a segment.
        assert_eq!(all[2].polygon.len(), 2, "{:?}", all[2].polygon);
        assert_eq!(
            what(&all[2]),
            ["contact \"touch\"'s point", "its centre of mass"]
        );
    }
}
