//! What the animation draws that does not change: every body's outline, its feet,
//! its rotors' axes and eccentricities, its joints and springs, the contacts' faces
//! and friction, and the fundament, as JSON for the page.
//!
//! Every point is given in its body's **centre-of-mass frame** (m): the frame whose
//! origin is the body's centre of mass and whose axes turn with it, the frame the
//! trace's pose columns place (`x, y, angle` for the platform, `x_<name>, y_<name>,
//! angle_<name>` for a further body). A point `p` (world, t = 0) of a body whose
//! centre of mass is `c_0` and angle `theta_0` at t = 0 is `R(-theta_0) (p - c_0)`
//! there, and at time t it is drawn at `c(t) + R(theta(t)) R(-theta_0) (p - c_0)`.
//!
//! The machine file describes no shape, only points: a body's **outline** is the
//! bounding box (in its frame) of what it carries (its contact points, its rotors'
//! axes with their eccentric circles, its joints, the faces on it and its centre of
//! mass), at least [`MIN_HALF_SIZE`] from its centre each way; the page says so.

use serde_json::{json, Value};

use crate::machine::bodies::{FUNDAMENT, PLATFORM};
use crate::machine::{Machine, Platform, Sense};

/// The smallest half width and half height of an outline, m: a body that carries
/// one point still shows as a box.
pub const MIN_HALF_SIZE: f64 = 2.5e-3;

/// What the page says of the outlines.
pub const OUTLINE_NOTE: &str =
    "outlines: bounding box of each body's feet, rotors and joints (the machine file gives no shape)";

/// A body's pose at t = 0: its centre of mass (world, m) and angle (rad).
#[derive(Clone, Copy, Debug)]
struct Pose0 {
    centre: [f64; 2],
    angle: f64,
}

impl Pose0 {
    fn of(rigid: &Platform) -> Self {
        Pose0 {
            centre: rigid.position,
            angle: rigid.angle,
        }
    }

    /// World point `p` at t = 0 in the body's centre-of-mass frame:
    /// `R(-theta_0) (p - c_0)`.
    fn point(&self, p: [f64; 2]) -> [f64; 2] {
        self.vector([p[0] - self.centre[0], p[1] - self.centre[1]])
    }

    /// World vector `v` at t = 0 in the body's frame: `R(-theta_0) v`.
    fn vector(&self, v: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.angle.sin_cos();
        [c * v[0] + s * v[1], -s * v[0] + c * v[1]]
    }
}

/// The machine's bodies, the platform first, as (name, pose at t = 0).
fn bodies(machine: &Machine) -> Vec<(&str, Pose0)> {
    let mut list = vec![(PLATFORM, Pose0::of(&machine.platform))];
    list.extend(
        machine
            .bodies
            .iter()
            .map(|b| (b.name.as_str(), Pose0::of(&b.rigid))),
    );
    list
}

/// The scene of `machine` as JSON (the module doc's frames; m, rad, N):
/// `{"bodies": [{"name", "box": [x_min, y_min, x_max, y_max]}], "outline_note",
/// "rotors": [{"name", "body", "axis", "eccentricity", "sense"}], "contacts":
/// [{"name", "body", "point", "friction", "against", "face", "normal"}] (`against`
/// -1 for the fundament, whose `face` and `normal` are world), "joints": [{"name",
/// "body", "point", "spring"}] (drawn on the joint's second body, or its first when
/// the second is the fundament), "fundament": {"point", "normal"}, "weight"}` with
/// `weight` the machine's weight, N (the force arrows' scale).
pub fn scene(machine: &Machine) -> Value {
    let bodies = bodies(machine);
    let index = |name: &str| bodies.iter().position(|(n, _)| *n == name);
    // What each body carries, in its frame, for its outline.
    let mut carried: Vec<Vec<[f64; 2]>> = vec![vec![[0.0, 0.0]]; bodies.len()];

    let rotors: Vec<Value> = machine
        .rotors
        .iter()
        .filter_map(|r| {
            let b = index(&r.body)?;
            let axis = bodies[b].1.point(r.axis);
            let e = r.eccentricity;
            carried[b].extend([[axis[0] - e, axis[1] - e], [axis[0] + e, axis[1] + e]]);
            let sense = match r.sense {
                Sense::Ccw => 1,
                Sense::Cw => -1,
            };
            Some(
                json!({"name": r.name, "body": b, "axis": axis, "eccentricity": e, "sense": sense}),
            )
        })
        .collect();

    let contacts: Vec<Value> = machine
        .contacts
        .iter()
        .filter_map(|c| {
            let b = index(&c.ends.body)?;
            let point = bodies[b].1.point(c.point);
            carried[b].push(point);
            let (against, face, normal) = match index(&c.ends.against) {
                Some(a) if c.ends.against != FUNDAMENT => {
                    let pose = bodies[a].1;
                    let face = pose.point(c.ends.face.unwrap_or(c.point));
                    carried[a].push(face);
                    let normal = pose.vector(c.ends.normal.unwrap_or(machine.fundament.normal));
                    (a as i64, face, normal)
                }
                _ => (-1, machine.fundament.point, machine.fundament.normal),
            };
            Some(json!({
                "name": c.name, "body": b, "point": point, "friction": c.friction,
                "against": against, "face": face, "normal": normal,
            }))
        })
        .collect();

    let joints: Vec<Value> = machine
        .joints
        .iter()
        .filter_map(|j| {
            // Both bodies carry the hinge (the fundament is no body here).
            for name in &j.bodies {
                if let Some(a) = index(name) {
                    let p = bodies[a].1.point(j.point);
                    carried[a].push(p);
                }
            }
            let b = index(&j.bodies[1]).or_else(|| index(&j.bodies[0]))?;
            let point = bodies[b].1.point(j.point);
            Some(json!({
                "name": j.name, "body": b, "point": point,
                "spring": j.stiffness > 0.0 || j.damping > 0.0,
            }))
        })
        .collect();

    let outlines: Vec<Value> = bodies
        .iter()
        .zip(&carried)
        .map(|((name, _), points)| json!({"name": name, "box": bounding_box(points)}))
        .collect();
    let mass = machine.platform.mass
        + machine.bodies.iter().map(|b| b.rigid.mass).sum::<f64>()
        + machine.rotors.iter().map(|r| r.eccentric_mass).sum::<f64>();
    let g = machine.fundament.gravity;
    json!({
        "bodies": outlines,
        "outline_note": OUTLINE_NOTE,
        "rotors": rotors,
        "contacts": contacts,
        "joints": joints,
        "fundament": {"point": machine.fundament.point, "normal": machine.fundament.normal},
        "weight": mass * g[0].hypot(g[1]),
    })
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
}
