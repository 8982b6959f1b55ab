//! Every body's outline: the shape the animation draws and the fundament check
//! ([`crate::simulation::breach`]) follows, defined once here.
//!
//! The machine file describes no shape, only points. A body's **outline** is the
//! bounding box, in its centre-of-mass frame, of what it carries: its contact
//! points, its rotors' axes with their eccentric circles (axis +- eccentricity each
//! way), its joints, the faces of contacts against it and its centre of mass; at
//! least [`MIN_HALF_SIZE`] from its centre each way.
//!
//! **The centre-of-mass frame** (m): origin at the body's centre of mass, axes
//! turning with it; the frame the trace's pose columns place (`x, y, angle` for the
//! platform, `x_<name>, y_<name>, angle_<name>` for a further body). A point `p`
//! (world, t = 0) of a body whose centre of mass is `c_0` and angle `theta_0` at
//! t = 0 is `R(-theta_0) (p - c_0)` there, and at time t it is at
//! `c(t) + R(theta(t)) R(-theta_0) (p - c_0)`.
//!
//! **Probes**: the points of a body that must stay on the machine's side of the
//! fundament: its centre of mass, each rotor axis on it, and each corner of its
//! outline that is not one of its declared contact points (those touch the floor
//! by design, and the plant holds them there).

use crate::machine::bodies::{FUNDAMENT, PLATFORM};
use crate::machine::{Machine, Platform};

/// The smallest half width and half height of an outline, m: a body that carries
/// one point still shows as a box (5 mm square).
pub const MIN_HALF_SIZE: f64 = 2.5e-3;

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

/// A point of a body the fundament check follows.
#[derive(Clone, Debug, PartialEq)]
pub struct Probe {
    /// What it is, for a message: `its centre of mass`, `rotor "left"'s axis`,
    /// `its outline's lower right corner`.
    pub what: String,
    /// Where, in the body's centre-of-mass frame, m.
    pub point: [f64; 2],
}

/// A body's outline and the points the fundament check follows.
#[derive(Clone, Debug, PartialEq)]
pub struct Outline {
    /// The body's name (`platform` for the first).
    pub name: String,
    /// Its pose at t = 0.
    pub pose0: Pose0,
    /// `[x_min, y_min, x_max, y_max]` in its centre-of-mass frame, m.
    pub bounds: [f64; 4],
    /// Its centre of mass, rotor axes, and the outline's corners that are not
    /// declared contact points.
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

/// Every body's outline, the platform first, then `[[bodies]]` in file order.
pub fn outlines(machine: &Machine) -> Vec<Outline> {
    let bodies = bodies(machine);
    let index = |name: &str| bodies.iter().position(|(n, _)| *n == name);
    let at = |b: usize, p: [f64; 2]| bodies[b].1.point(p);
    // What each body carries, in its frame: its centre of mass first.
    let mut carried: Vec<Vec<[f64; 2]>> = vec![vec![[0.0, 0.0]]; bodies.len()];
    let mut axes: Vec<Vec<Probe>> = vec![Vec::new(); bodies.len()];
    let mut feet: Vec<Vec<[f64; 2]>> = vec![Vec::new(); bodies.len()];
    for r in &machine.rotors {
        if let Some(b) = index(&r.body) {
            let axis = at(b, r.axis);
            let e = r.eccentricity;
            carried[b].extend([[axis[0] - e, axis[1] - e], [axis[0] + e, axis[1] + e]]);
            axes[b].push(Probe {
                what: format!("rotor {:?}'s axis", r.name),
                point: axis,
            });
        }
    }
    for c in &machine.contacts {
        if let Some(b) = index(&c.ends.body) {
            let point = at(b, c.point);
            carried[b].push(point);
            feet[b].push(point);
        }
        if c.ends.against != FUNDAMENT {
            if let Some(a) = index(&c.ends.against) {
                carried[a].push(at(a, c.ends.face.unwrap_or(c.point)));
            }
        }
    }
    for j in &machine.joints {
        // Both bodies carry the hinge (the fundament is no body here).
        for name in &j.bodies {
            if let Some(a) = index(name) {
                carried[a].push(at(a, j.point));
            }
        }
    }
    bodies
        .iter()
        .enumerate()
        .map(|(b, (name, pose0))| {
            let bounds = bounding_box(&carried[b]);
            let mut probes = vec![Probe {
                what: "its centre of mass".to_string(),
                point: [0.0, 0.0],
            }];
            probes.append(&mut axes[b]);
            for (what, corner) in corners(bounds) {
                if !feet[b].contains(&corner) {
                    probes.push(Probe {
                        what: format!("its outline's {what} corner"),
                        point: corner,
                    });
                }
            }
            Outline {
                name: name.to_string(),
                pose0: *pose0,
                bounds,
                probes,
            }
        })
        .collect()
}

/// The corners of `[x_min, y_min, x_max, y_max]` with their names in the body's
/// own frame.
fn corners(b: [f64; 4]) -> [(&'static str, [f64; 2]); 4] {
    [
        ("lower left", [b[0], b[1]]),
        ("lower right", [b[2], b[1]]),
        ("upper right", [b[2], b[3]]),
        ("upper left", [b[0], b[3]]),
    ]
}

/// `[x_min, y_min, x_max, y_max]` of `points` (which hold the origin), widened to
/// at least [`MIN_HALF_SIZE`] from the origin each way.
fn bounding_box(points: &[[f64; 2]]) -> [f64; 4] {
    let h = MIN_HALF_SIZE;
    points.iter().fold([-h, -h, h, h], |b, p| {
        [
            b[0].min(p[0]),
            b[1].min(p[1]),
            b[2].max(p[0]),
            b[3].max(p[1]),
        ]
    })
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

    #[test]
    fn the_outline_holds_every_point_and_the_minimum() {
        assert_eq!(
            bounding_box(&[[0.0, 0.0], [-0.08, -0.03], [0.05, 0.02]]),
            [-0.08, -0.03, 0.05, 0.02]
        );
        let h = MIN_HALF_SIZE;
        assert_eq!(bounding_box(&[[0.0, 0.0]]), [-h, -h, h, h]);
    }

    #[test]
    fn the_reference_platform_is_probed_at_its_centre_axes_and_upper_corners() {
        // Feet K1, K2 at [-+0.08, -0.03] from the centre of mass [0, 0.03]; rotor
        // axes at [-+0.03, 0] with eccentricity 0.02: the box is [-0.08, -0.03,
        // 0.08, 0.02], its lower corners are the feet.
        let m = load("examples/vibro-driver.toml", &[]);
        let o = &outlines(&m)[0];
        assert_eq!(o.name, "platform");
        let b = o.bounds;
        let close = |a: f64, e: f64| (a - e).abs() < 1e-12;
        assert!(
            close(b[0], -0.08) && close(b[1], -0.03) && close(b[2], 0.08) && close(b[3], 0.02),
            "{b:?}"
        );
        let what: Vec<&str> = o.probes.iter().map(|p| p.what.as_str()).collect();
        assert_eq!(
            what,
            [
                "its centre of mass",
                "rotor \"left\"'s axis",
                "rotor \"right\"'s axis",
                "its outline's upper right corner",
                "its outline's upper left corner"
            ]
        );
    }
}
