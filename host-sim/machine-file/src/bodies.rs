//! Several bodies in one machine (docs/machine-file.md, "Several bodies"): the
//! `[[bodies]]` after the platform, the `[[joints]]` that hinge them (revolute, with
//! an optional torsional spring-damper), the two ends of every contact (`body`
//! against `against`, a point of one on a flat face of the other) and the body that
//! carries each rotor.
//!
//! Read and checked here, every problem with its key:
//! - body names unique, and neither `platform` nor `fundament` (the names of the
//!   first body and of the ground);
//! - a joint joins two different bodies that exist (`fundament` allowed for one),
//!   and joints make trees: a joint between two bodies already joined closes a loop;
//! - a contact's `body` moves (the platform or a further body), its `against` is any
//!   body or the fundament, never the contact's own body; against the fundament the
//!   face is the fundament's line (`face` and `normal` are for a contact against a
//!   body); against a body it needs a `normal` (world, t = 0, from `against`
//!   towards `body`) and its point must not be behind the face at t = 0;
//! - a rotor's body moves.
//!
//! host-sim simulates all of it; the firmware drives rotors only, and its build
//! refuses a machine that asks more than a platform on the fundament
//! ([`beyond_the_platform`] names what).

use crate::input::{
    check_names, cut, number, quoted, read_name, vector, Limit, Named, Need, Section, MAX_QUOTED,
};
use crate::{read_platform, MachineContact, Platform};
use shared::Enumerated;

/// The first body's name.
pub const PLATFORM: &str = "platform";
/// The ground's name.
pub const FUNDAMENT: &str = "fundament";
/// A joint's kind: the one there is, a pin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// A pin: the bodies keep one point in common and turn about it.
    Revolute,
}

/// The joint kinds, as written in the file.
impl Enumerated for JointKind {
    const ALL: &'static [JointKind] = &[JointKind::Revolute];

    fn name(self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
        }
    }
}
/// The most bodies a machine may have, the platform included (the plant's
/// fixed-size state).
pub const MAX_BODIES: usize = 6;
/// The most rotors a machine may have (the controller's two channels).
pub const MAX_ROTORS: usize = 2;
/// The most generalized coordinates a machine may have: 3 per body, less 2 per
/// joint, plus 1 per rotor.
pub const MAX_DOF: usize = 12;
/// How far a contact point may be behind its face at t = 0, m (rounding of the
/// file's decimals).
pub const FACE_GAP_TOLERANCE: f64 = 1e-9;

/// A further rigid body: its name, and the same keys as `[platform]` (mass, kg;
/// inertia about its centre of mass, kg m^2; centre of mass, angle, velocity and
/// angular velocity at t = 0, world).
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    /// Name, unique among the bodies.
    pub name: String,
    /// Its inertia and its state at t = 0.
    pub rigid: Platform,
}

/// A revolute joint between two bodies (one may be the fundament) at a world point
/// at t = 0, with a torsional spring-damper about it: stiffness, N m/rad; damping,
/// N m s/rad; the relative angle at which the spring is relaxed, rad (`None`: the
/// one at t = 0).
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// Name, unique among the joints.
    pub name: String,
    /// The two bodies it joins (`fundament` allowed for one).
    pub bodies: [String; 2],
    /// The hinge at t = 0, world, m.
    pub point: [f64; 2],
    /// Torsional stiffness, N m/rad (0: no spring).
    pub stiffness: f64,
    /// Torsional damping, N m s/rad.
    pub damping: f64,
    /// Relative angle at which the spring is relaxed, rad; `None`: the one at t = 0.
    pub rest_angle: Option<f64>,
}

/// The two ends of a contact: the point is fixed on `body`, the face on `against`.
/// `face` and `normal` (world, t = 0; the normal of unit length, from `against`
/// towards `body`) are `None` against the fundament, whose line is the face.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactEnds {
    /// The body the point is fixed on.
    pub body: String,
    /// The body (or the fundament) the face is fixed on.
    pub against: String,
    /// A point of the face at t = 0, world, m (against a body; default: the contact point).
    pub face: Option<[f64; 2]>,
    /// The face's unit normal at t = 0, from `against` towards `body` (against a body).
    pub normal: Option<[f64; 2]>,
}

/// One `[[bodies]]` table (default name `B{i+1}`): a name and `[platform]`'s keys.
pub fn read_body(index: usize, s: &Section) -> Named<Body> {
    let (given, name) = read_name(s, index, "B");
    let rigid = read_platform(s);
    let value = name
        .clone()
        .zip(rigid)
        .map(|(name, rigid)| Body { name, rigid });
    Named { given, name, value }
}

/// One `[[joints]]` table (default name `J{i+1}`).
pub fn read_joint(index: usize, s: &Section) -> Named<Joint> {
    let (given, name) = read_name(s, index, "J");
    let kind = s.one_of::<JointKind>("kind", Need::Required);
    let bodies = s.string_pair("bodies", Need::Required);
    let point = s.vec2("point", Need::Required, Limit::Any);
    let stiffness = s.number("stiffness", Need::Default(0.0), Limit::NonNegative);
    let damping = s.number("damping", Need::Default(0.0), Limit::NonNegative);
    let rest_angle = s.number("rest_angle", Need::Optional, Limit::Any);
    let rest_given = s.has("rest_angle");
    s.finish();
    let value = (|| {
        kind?;
        Some(Joint {
            name: name.clone()?,
            bodies: bodies?,
            point: point?,
            stiffness: stiffness?,
            damping: damping?,
            rest_angle: if rest_given { Some(rest_angle?) } else { None },
        })
    })();
    Named { given, name, value }
}

/// A contact's `body`, `against`, `face` and `normal` keys (checked against the
/// bodies later, in [`check`]).
pub fn read_ends(s: &Section) -> Option<ContactEnds> {
    let body = s.string("body", Need::Default(PLATFORM.to_string()));
    let against = s.string("against", Need::Default(FUNDAMENT.to_string()));
    let face = s.vec2("face", Need::Optional, Limit::Any);
    let face_given = s.has("face");
    let normal = s.vec2("normal", Need::Optional, Limit::Any).and_then(|n| {
        s.unit_vector(
            "normal",
            n,
            "the face's normal, from `against` towards `body`",
        )
    });
    let normal_given = s.has("normal");
    Some(ContactEnds {
        body: body?,
        against: against?,
        face: if face_given { Some(face?) } else { None },
        normal: if normal_given { Some(normal?) } else { None },
    })
}

/// Checks the bodies, joints, contact ends and rotor bodies together (the module
/// doc's rules). `false` when a problem was recorded.
pub fn check(
    root: &Section,
    bodies: &[Named<Body>],
    joints: &[Named<Joint>],
    contacts: &[MachineContact],
    rotor_bodies: &[String],
) -> bool {
    let mut ok = check_names(root, "bodies", "body", bodies);
    let names = BodyNames {
        further: bodies.iter().filter_map(|b| b.name.as_deref()).collect(),
    };
    ok &= check_reserved_names(root, &names);
    ok &= check_names(root, "joints", "joint", joints);
    ok &= check_joint_trees(root, joints, &names);
    for (i, contact) in contacts.iter().enumerate() {
        ok &= check_contact(root, i, contact, &names);
    }
    ok &= check_rotor_bodies(root, rotor_bodies, &names);
    ok
}

/// The names of the further bodies (`[[bodies]]`, in file order), beside the
/// platform's and the fundament's, for the checks of what names a body.
struct BodyNames<'a> {
    /// The further bodies' names.
    further: Vec<&'a str>,
}

impl BodyNames<'_> {
    /// Whether `n` names a body that moves: the platform or a further body.
    fn moving(&self, n: &str) -> bool {
        n == PLATFORM || self.further.contains(&n)
    }

    /// Whether `n` names a body or the fundament.
    fn known(&self, n: &str) -> bool {
        n == FUNDAMENT || self.moving(n)
    }

    /// The bodies and the fundament, for a message: `platform, fundament, arm`.
    fn all(&self) -> String {
        let mut all = vec![PLATFORM.to_string(), FUNDAMENT.to_string()];
        all.extend(self.further.iter().map(|n| cut(n, MAX_QUOTED)));
        all.join(", ")
    }

    /// The moving bodies, for a message: `platform, arm`.
    fn all_moving(&self) -> String {
        let mut m = vec![PLATFORM.to_string()];
        m.extend(self.further.iter().map(|n| cut(n, MAX_QUOTED)));
        m.join(", ")
    }
}

/// No further body is named `platform` or `fundament` (the first body's and the
/// ground's names).
fn check_reserved_names(root: &Section, names: &BodyNames<'_>) -> bool {
    let mut ok = true;
    for (i, name) in names.further.iter().enumerate() {
        if *name == PLATFORM || *name == FUNDAMENT {
            root.problem(
                &format!("bodies[{i}].name"),
                format!("{} is taken: the first body is `platform` ([platform]), the ground `fundament`", quoted(name)),
            );
            ok = false;
        }
    }
    ok
}

/// Sets of bodies joined together (union-find over the bodies and the fundament,
/// each added the first time a joint names it).
#[derive(Default)]
struct JoinedSets {
    /// The names, in the order they were added.
    names: Vec<String>,
    /// Each name's parent in its set's tree (its own index at a root).
    parent: Vec<usize>,
}

impl JoinedSets {
    /// The index of `n`, added as a set of its own if new.
    fn node(&mut self, n: &str) -> usize {
        match self.names.iter().position(|s| s == n) {
            Some(i) => i,
            None => {
                self.names.push(n.to_string());
                self.parent.push(self.parent.len());
                self.parent.len() - 1
            }
        }
    }

    /// The root of `i`'s set (halving the path on the way).
    fn root_of(&mut self, mut i: usize) -> usize {
        let parent = &mut self.parent;
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
}

/// Joints: two different bodies that exist, in trees (a joint between two bodies
/// already joined through other joints closes a loop).
fn check_joint_trees(root: &Section, joints: &[Named<Joint>], names: &BodyNames<'_>) -> bool {
    let mut ok = true;
    let mut sets = JoinedSets::default();
    for (i, joint) in joints.iter().enumerate() {
        let Some(j) = &joint.value else { continue };
        let key = format!("joints[{i}].bodies");
        let [a, b] = &j.bodies;
        for n in [a, b] {
            if !names.known(n) {
                root.problem(
                    &key,
                    format!("no body named {} (bodies: {})", quoted(n), names.all()),
                );
                ok = false;
            }
        }
        if a == b {
            root.problem(
                &key,
                format!("joins {} to itself: a joint joins two bodies", quoted(a)),
            );
            ok = false;
            continue;
        }
        if !(names.known(a) && names.known(b)) {
            continue;
        }
        let (x, y) = (sets.node(a), sets.node(b));
        let (rx, ry) = (sets.root_of(x), sets.root_of(y));
        if rx == ry {
            root.problem(
                &key,
                format!("{} and {} are already joined through other joints: this joint closes a loop (joints must make trees)", quoted(a), quoted(b)),
            );
            ok = false;
        } else {
            sets.parent[rx] = ry;
        }
    }
    ok
}

/// The `i`-th contact: the point on a moving body, the face on another body or
/// the fundament ([`check_contact_face`]).
fn check_contact(root: &Section, i: usize, c: &MachineContact, names: &BodyNames<'_>) -> bool {
    let mut ok = true;
    let (ends, name) = (&c.ends, &c.name);
    let key = |k: &str| format!("contacts[{i}].{k}");
    if !names.moving(&ends.body) {
        let why = if ends.body == FUNDAMENT {
            "the fundament does not move: the point is on a moving body (put the fundament in `against`)".to_string()
        } else {
            format!(
                "no moving body named {} (moving: {})",
                quoted(&ends.body),
                names.all_moving()
            )
        };
        root.problem(&key("body"), why);
        ok = false;
    }
    if !names.known(&ends.against) {
        root.problem(
            &key("against"),
            format!(
                "no body named {} (bodies: {})",
                quoted(&ends.against),
                names.all()
            ),
        );
        ok = false;
    }
    if ends.body == ends.against {
        root.problem(
            &key("against"),
            format!(
                "contact {} is on {} against itself: a contact is between two bodies",
                cut(name, MAX_QUOTED),
                quoted(&ends.body)
            ),
        );
        ok = false;
    }
    check_contact_face(root, i, c) && ok
}

/// The `i`-th contact's face: against the fundament its line (no `face`, no
/// `normal`); against a body a `normal`, and the point not behind the face at
/// t = 0.
fn check_contact_face(root: &Section, i: usize, c: &MachineContact) -> bool {
    let (ends, name, point) = (&c.ends, &c.name, &c.point);
    let key = |k: &str| format!("contacts[{i}].{k}");
    if ends.against == FUNDAMENT {
        let mut ok = true;
        for (k, given) in [
            ("face", ends.face.is_some()),
            ("normal", ends.normal.is_some()),
        ] {
            if given {
                root.problem(
                    &key(k),
                    "only for a contact against a body: against the fundament the face is [fundament]'s line",
                );
                ok = false;
            }
        }
        return ok;
    }
    let Some(unit) = ends.normal else {
        root.problem(
            &key("normal"),
            format!(
                "missing; required against a body ({}): the face's normal, from it towards {}",
                quoted(&ends.against),
                quoted(&ends.body)
            ),
        );
        return false;
    };
    // The face through the point unless given ([`read_ends`]'s caller).
    let face = ends.face.unwrap_or(*point);
    let gap = unit[0] * (point[0] - face[0]) + unit[1] * (point[1] - face[1]);
    if gap < -FACE_GAP_TOLERANCE {
        root.problem(
            &key("point"),
            format!(
                "contact {} overlaps {} at t = 0: the point {} is {} m behind the face through {} (normal {}); it must be on or in front of it",
                cut(name, MAX_QUOTED),
                quoted(&ends.against),
                vector(*point),
                number(-gap),
                vector(face),
                vector(unit)
            ),
        );
        return false;
    }
    true
}

/// Rotors: each on a moving body.
fn check_rotor_bodies(root: &Section, rotor_bodies: &[String], names: &BodyNames<'_>) -> bool {
    let mut ok = true;
    for (i, body) in rotor_bodies.iter().enumerate() {
        if !names.moving(body) {
            root.problem(
                &format!("rotors[{i}].body"),
                format!(
                    "no moving body named {}: a rotor sits on the platform or a further body",
                    quoted(body)
                ),
            );
            ok = false;
        }
    }
    ok
}

/// The machine's size against the plant's limits ([`MAX_BODIES`], [`MAX_DOF`]:
/// 3 coordinates per body, less 2 per joint, plus 1 per rotor), and every joint's
/// two bodies moving together at its hinge at t = 0: the hinge's velocity from
/// either body, `v_c + omega x (p - c)` (the fundament's: zero), must agree, since
/// the joint holds it. Run after [`check`] found the names and trees sound.
pub fn check_size_and_motion(
    root: &Section,
    platform: Option<&Platform>,
    bodies: &[Named<Body>],
    joints: &[Named<Joint>],
    rotors: usize,
) -> bool {
    let mut ok = true;
    let n_bodies = 1 + bodies.len();
    if n_bodies > MAX_BODIES {
        root.problem(
            "bodies",
            format!(
                "{} [[bodies]] make {n_bodies} bodies with the platform; at most {MAX_BODIES} are allowed ({} [[bodies]])",
                bodies.len(),
                MAX_BODIES - 1
            ),
        );
        ok = false;
    }
    let dof = 3 * n_bodies + rotors;
    let dof = dof.saturating_sub(2 * joints.len());
    if dof > MAX_DOF {
        root.problem(
            "joints",
            format!(
                "the machine has {dof} degrees of freedom (3 per body, less 2 per joint, plus 1 per rotor: 3 x {n_bodies} - 2 x {} + {rotors}); at most {MAX_DOF} are allowed",
                joints.len()
            ),
        );
        ok = false;
    }
    let Some(platform) = platform else {
        return ok;
    };
    let rigid = |name: &str| -> Option<&Platform> {
        if name == PLATFORM {
            return Some(platform);
        }
        bodies
            .iter()
            .filter_map(|b| b.value.as_ref())
            .find(|b| b.name == name)
            .map(|b| &b.rigid)
    };
    for (i, joint) in joints.iter().enumerate() {
        let Some(j) = &joint.value else { continue };
        // The hinge's velocity as each body carries it, m/s.
        let carried = |name: &str| -> Option<[f64; 2]> {
            if name == FUNDAMENT {
                return Some([0.0, 0.0]);
            }
            let r = rigid(name)?;
            let d = [j.point[0] - r.position[0], j.point[1] - r.position[1]];
            let w = r.angular_velocity;
            Some([r.velocity[0] - w * d[1], r.velocity[1] + w * d[0]])
        };
        let (Some(a), Some(b)) = (carried(&j.bodies[0]), carried(&j.bodies[1])) else {
            continue;
        };
        let gap = (a[0] - b[0]).hypot(a[1] - b[1]);
        let scale = 1.0 + a[0].hypot(a[1]).max(b[0].hypot(b[1]));
        if gap > 1e-9 * scale {
            root.problem(
                &format!("joints[{i}].point"),
                format!(
                    "the hinge {} moves at {} m/s with {} but at {} m/s with {} at t = 0; a joint holds its two bodies together there: give the bodies' `velocity` and `angular_velocity` so that they agree (v_c + omega x (point - c))",
                    vector(j.point),
                    vector(a),
                    quoted(&j.bodies[0]),
                    vector(b),
                    quoted(&j.bodies[1])
                ),
            );
            ok = false;
        }
    }
    ok
}

/// What a machine asks beyond a single platform on the fundament, one key path a
/// line (empty for a one-body machine): the further bodies, the joints, contacts
/// that are not the platform's against the fundament, rotors not on the platform.
pub fn beyond_the_platform(
    bodies: &[Body],
    joints: &[Joint],
    contacts: &[ContactEnds],
    rotor_bodies: &[String],
) -> Vec<String> {
    let mut keys = Vec::new();
    if !bodies.is_empty() {
        keys.push(format!("bodies ({} further)", bodies.len()));
    }
    if !joints.is_empty() {
        keys.push(format!("joints ({})", joints.len()));
    }
    for (i, c) in contacts.iter().enumerate() {
        if c.body != PLATFORM || c.against != FUNDAMENT {
            keys.push(format!(
                "contacts[{i}] ({} against {})",
                cut(&c.body, MAX_QUOTED),
                cut(&c.against, MAX_QUOTED)
            ));
        }
    }
    for (i, b) in rotor_bodies.iter().enumerate() {
        if b != PLATFORM {
            keys.push(format!("rotors[{i}].body ({})", cut(b, MAX_QUOTED)));
        }
    }
    keys
}
