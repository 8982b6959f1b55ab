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
//! The machine file describes no shape, only points: a body's **outline** is
//! [`crate::plant::outline`]'s polygon, the convex hull of what it carries (the
//! shape the fundament check follows too); the page says so.

use serde_json::{json, Value};

use crate::machine::bodies::FUNDAMENT;
use crate::machine::{Machine, Sense};
use crate::plant::outline::{bodies, outlines};

/// What the page says of the outlines.
pub const OUTLINE_NOTE: &str =
    "outlines: convex hull of each body's centre of mass, feet, eccentric circles and joints (the machine file gives no shape)";

/// The scene of `machine` as JSON (the module doc's frames; m, rad, N):
/// `{"bodies": [{"name", "outline": [[x, y], ...]}] (the outline's vertices
/// counter-clockwise), "outline_note",
/// "rotors": [{"name", "body", "axis", "eccentricity", "sense"}], "contacts":
/// [{"name", "body", "point", "friction", "against", "face", "normal"}] (`against`
/// -1 for the fundament, whose `face` and `normal` are world), "joints": [{"name",
/// "body", "point", "spring"}] (drawn on the joint's second body, or its first when
/// the second is the fundament), "fundament": {"point", "normal"}, "weight"}` with
/// `weight` the machine's weight, N (the force arrows' scale).
pub fn scene(machine: &Machine) -> Value {
    let bodies = bodies(machine);
    let index = |name: &str| bodies.iter().position(|(n, _)| *n == name);

    let rotors: Vec<Value> = machine
        .rotors
        .iter()
        .filter_map(|r| {
            let b = index(&r.body)?;
            let axis = bodies[b].1.point(r.axis);
            let e = r.eccentricity;
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
            let (against, face, normal) = match index(&c.ends.against) {
                Some(a) if c.ends.against != FUNDAMENT => {
                    let pose = bodies[a].1;
                    let face = pose.point(c.ends.face.unwrap_or(c.point));
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
            let b = index(&j.bodies[1]).or_else(|| index(&j.bodies[0]))?;
            let point = bodies[b].1.point(j.point);
            Some(json!({
                "name": j.name, "body": b, "point": point,
                "spring": j.stiffness > 0.0 || j.damping > 0.0,
            }))
        })
        .collect();

    let outlines: Vec<Value> = outlines(machine)
        .iter()
        .map(|o| json!({"name": o.name, "outline": o.polygon}))
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
