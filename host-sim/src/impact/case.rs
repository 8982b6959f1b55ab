//! The impact case file (docs/cli-impact.md, "The case file"): one rigid body at the
//! instant its contact points touch their obstacles, optionally pinned to the ground.
//!
//! Reading a case (see [`parse_case`]):
//! 1. keys and values, each checked on its own ([`crate::machine::input`]): types, NaN and
//!    infinities, ranges (mass and inertia > 0, restitution in [0, 1], friction >= 0,
//!    weight > 0), unknown keys with a "did you mean";
//! 2. the contacts as a whole: 1 to [`MAX_CONTACTS`](shared::impact::MAX_CONTACTS), unique names, non-zero normals;
//! 3. the body's velocity against the pivot: pinned at O, the centre of mass C moves
//!    at `omega x (C - O)`;
//! 4. at least one contact approaching: `u_n = n . v_K < 0` with
//!    `v_K = v_C + omega x (K - C)`, else there is nothing to solve.

use std::path::Path;

use shared::impact::{BodyContact, ContactLaw, ImpactLaw, PlanarBody};

use crate::machine::input::{
    self, number, read_name, vector, Limit, Named, Need, Problem, Problems, Section,
};
use crate::machine::kind::{self, FileKind};

/// Relative tolerance of the check that `[body].velocity` agrees with the pivot:
/// `|v - omega x (C - O)| <= 1e-9 max(|v|, |omega| |C - O|)`. Far above rounding
/// (1e-16) of a value a generator computed, far below any real mistake.
pub const PIVOT_VELOCITY_TOLERANCE: f64 = 1e-9;

/// A contact of the case, with its name.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedContact {
    /// The contact's name (`K1`, `K2`, ... when the file gives none).
    pub name: String,
    /// Point, unit normal and law, as the solver takes them.
    pub contact: BodyContact<f64>,
}

/// An impact case, checked and ready for [`shared::impact::solve_body`].
#[derive(Clone, Debug, PartialEq)]
pub struct ImpactCase {
    /// The impact law (the file's `law`, default Poisson; `--law` overrides it).
    pub law: ImpactLaw,
    /// The body at the instant of impact. Pinned, its velocity is `omega x (C - O)`
    /// whether the file gave it or not.
    pub body: PlanarBody<f64>,
    /// The pivot O, where the body is pinned to the ground, m.
    pub pivot: Option<[f64; 2]>,
    /// The contacts in file order (1 to [`MAX_CONTACTS`](shared::impact::MAX_CONTACTS)), normals of unit length.
    pub contacts: Vec<NamedContact>,
}

impl ImpactCase {
    /// The contacts in the form the solver takes.
    pub fn body_contacts(&self) -> Vec<BodyContact<f64>> {
        self.contacts.iter().map(|c| c.contact).collect()
    }

    /// Normal and tangential velocity `(u_n, u_t)` of every contact point before the
    /// impact, m/s: `v_K = v_C + omega x (K - C)`, `u_n = n . v_K`, `u_t = t . v_K`
    /// with `t = (-n_y, n_x)`.
    pub fn contact_velocities(&self) -> Vec<(f64, f64)> {
        self.contacts
            .iter()
            .map(|c| contact_velocity(&self.body, &c.contact))
            .collect()
    }
}

/// `(u_n, u_t)` of one contact of `body` (normal of unit length).
fn contact_velocity(body: &PlanarBody<f64>, c: &BodyContact<f64>) -> (f64, f64) {
    let r = [c.point[0] - body.position[0], c.point[1] - body.position[1]];
    let w = body.angular_velocity;
    // v_K = v_C + omega x r, omega x r = omega (-r_y, r_x)
    let v = [body.velocity[0] - w * r[1], body.velocity[1] + w * r[0]];
    let n = c.normal;
    let t = [-n[1], n[0]];
    (n[0] * v[0] + n[1] * v[1], t[0] * v[0] + t[1] * v[1])
}

/// Reads and checks a case file. Every problem is returned at once.
pub fn read_case(path: &Path) -> Result<ImpactCase, Vec<Problem>> {
    let text = input::read_text(path).map_err(|p| vec![p])?;
    parse_case(&path.display().to_string(), &text)
}

/// Checks the text of a case file named `file` (the stages of the module doc).
pub fn parse_case(file: &str, text: &str) -> Result<ImpactCase, Vec<Problem>> {
    let table = input::parse(file, text).map_err(|p| vec![p])?;
    if let Some(p) = kind::wrong_kind(file, &table, FileKind::ImpactCase) {
        return Err(vec![p]);
    }
    let problems = Problems::new(file);
    let case = check(&table, &problems);
    problems.into_result(case)
}

/// The body's keys as read (`None`: missing or invalid, reported).
struct BodyKeys {
    mass: Option<f64>,
    inertia: Option<f64>,
    position: Option<[f64; 2]>,
    velocity: Option<[f64; 2]>,
    /// Whether `velocity` is in the file at all (valid or not).
    has_velocity: bool,
    angular_velocity: Option<f64>,
}

/// Stages 1 to 4; `None` when some problem was recorded.
fn check(table: &toml::Table, problems: &Problems) -> Option<ImpactCase> {
    let root = Section::root(table, problems);

    // Stage 1: every key on its own.
    let law = root.one_of("law", Need::Default(ImpactLaw::Poisson));
    let body = root.section("body", Need::Required).map(|s| read_body(&s));
    // Ok(None): no pivot; Err(()): a [pivot] with a problem (reported).
    let pivot: Result<Option<[f64; 2]>, ()> = match root.section("pivot", Need::Optional) {
        None if root.has("pivot") => Err(()),
        None => Ok(None),
        Some(s) => {
            let point = s.vec2("point", Need::Required, Limit::Any);
            s.finish();
            point.map(Some).ok_or(())
        }
    };
    let contacts = root.sections("contacts").map(|list| {
        list.iter()
            .enumerate()
            .map(|(i, s)| match s {
                Some(s) => read_contact(i, s),
                // Not a table: reported, no name to check.
                None => Named {
                    given: false,
                    name: None,
                    value: None,
                },
            })
            .collect::<Vec<_>>()
    });
    root.finish();

    // Stage 2: the contacts as a whole.
    let contacts = contacts.and_then(|list| check_contacts(&root, list));

    // Stage 3: the body's velocity against the pivot.
    let body = match (body, pivot) {
        (Some(keys), Ok(pivot)) => check_body(&root, keys, pivot),
        _ => None,
    };

    // Stage 4: something to solve; only meaningful when the rest is sound.
    let case = ImpactCase {
        law: law?,
        body: body?,
        pivot: pivot.ok()?,
        contacts: contacts?,
    };
    if !problems.is_empty() {
        return None;
    }
    check_approach(&root, &case);
    problems.is_empty().then_some(case)
}

/// `[body]`: mass and inertia > 0, position, velocity (optional here), angular
/// velocity (default 0).
fn read_body(s: &Section) -> BodyKeys {
    let keys = BodyKeys {
        mass: s.number("mass", Need::Required, Limit::Positive),
        inertia: s.number("inertia", Need::Required, Limit::Positive),
        position: s.vec2("position", Need::Required, Limit::Any),
        velocity: s.vec2("velocity", Need::Optional, Limit::Any),
        has_velocity: s.has("velocity"),
        angular_velocity: s.number("angular_velocity", Need::Default(0.0), Limit::Any),
    };
    s.finish();
    keys
}

/// One `[[contacts]]` table: name (default `K{i+1}`), point, normal (non-zero,
/// normalised here), restitution in [0, 1], friction >= 0, weight > 0 (default 1).
fn read_contact(index: usize, s: &Section) -> Named<BodyContact<f64>> {
    let (given, name) = read_name(s, index, "K");
    let point = s.vec2("point", Need::Required, Limit::Any);
    let normal = s
        .vec2("normal", Need::Required, Limit::Any)
        .and_then(|n| s.unit_vector("normal", n, "the direction from the obstacle to the body"));
    let restitution = s.number("restitution", Need::Required, Limit::Between(0.0, 1.0));
    let friction = s.number("friction", Need::Required, Limit::NonNegative);
    let weight = s.number("weight", Need::Default(1.0), Limit::Positive);
    s.finish();
    let contact = (|| {
        Some(BodyContact {
            point: point?,
            normal: normal?,
            law: ContactLaw {
                restitution: restitution?,
                friction: friction?,
                weight: weight?,
            },
        })
    })();
    Named {
        given,
        name,
        value: contact,
    }
}

/// At least one contact, at most [`MAX_CONTACTS`](shared::impact::MAX_CONTACTS), names unique.
fn check_contacts(root: &Section, list: Vec<Named<BodyContact<f64>>>) -> Option<Vec<NamedContact>> {
    let named = input::check_contact_list(root, list, "in one impact")?;
    Some(
        named
            .into_iter()
            .map(|(name, contact)| NamedContact { name, contact })
            .collect(),
    )
}

/// The body: pinned at O, `v_C` must be `omega x (C - O)` (computed when absent);
/// free, `velocity` is required.
fn check_body(root: &Section, keys: BodyKeys, pivot: Option<[f64; 2]>) -> Option<PlanarBody<f64>> {
    let position = keys.position?;
    let omega = keys.angular_velocity?;
    let velocity = match (pivot, keys.velocity) {
        (Some(o), given) => {
            // omega x (C - O) = omega (-(C_y - O_y), C_x - O_x)
            let oc = [position[0] - o[0], position[1] - o[1]];
            let expected = [-omega * oc[1], omega * oc[0]];
            if let Some(v) = given {
                let scale = f64::max(v[0].hypot(v[1]), expected[0].hypot(expected[1]));
                let error = (v[0] - expected[0]).hypot(v[1] - expected[1]);
                if error > PIVOT_VELOCITY_TOLERANCE * scale {
                    root.problem(
                        "body.velocity",
                        format!(
                            "inconsistent with the pivot: pinned at {} with angular_velocity {}, the centre of mass moves at omega x (C - O) = {} (got {}); give that or omit body.velocity",
                            vector(o),
                            number(omega),
                            vector(expected),
                            vector(v)
                        ),
                    );
                    return None;
                }
            }
            expected
        }
        (None, Some(v)) => v,
        (None, None) => {
            if !keys.has_velocity {
                root.problem(
                    "body.velocity",
                    "missing; required for a free body (no [pivot]): the velocity [vx, vy] of the centre of mass, m/s",
                );
            }
            return None;
        }
    };
    Some(PlanarBody {
        mass: keys.mass?,
        inertia: keys.inertia?,
        position,
        velocity,
        angular_velocity: omega,
    })
}

/// At least one contact with `u_n < 0`.
fn check_approach(root: &Section, case: &ImpactCase) {
    let velocities = case.contact_velocities();
    if velocities.iter().any(|(u_n, _)| !u_n.is_finite()) {
        root.problems()
            .whole_file("the contact velocities overflow (not finite): the numbers are too large");
        return;
    }
    if velocities.iter().all(|(u_n, _)| *u_n >= 0.0) {
        let list = case
            .contacts
            .iter()
            .zip(&velocities)
            .map(|(c, (u_n, _))| format!("{} {}", c.name, number(*u_n)))
            .collect::<Vec<_>>()
            .join(", ");
        root.problem(
            "contacts",
            format!(
                "no contact approaches (all normal velocities >= 0): nothing to solve (u_n in m/s: {list}; approaching is u_n < 0)"
            ),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The example case of docs/cli-impact.md with Newton's law and an unnormalised
    /// normal.
    fn good() -> String {
        include_str!("../../tests/fixtures/pinned-body.toml")
            .replace("law = \"poisson\"", "law = \"newton\"")
            .replace("normal = [1.0, 0.0]", "normal = [2.0, 0.0]")
    }

    #[test]
    fn the_documented_example_reads() {
        let case = parse_case("c.toml", &good()).expect("valid");
        assert_eq!(case.law, ImpactLaw::Newton);
        assert_eq!(case.pivot, Some([0.0, 0.0]));
        assert_eq!(case.contacts[0].name, "K");
        assert_eq!(case.contacts[0].contact.normal, [1.0, 0.0]);
        assert_eq!(case.contacts[0].contact.law.weight, 1.0);
        let (u_n, u_t) = case.contact_velocities()[0];
        // v_K = omega x K = 5 (-0.25, -0.4)
        assert!((u_n + 1.25).abs() < 1e-12 && (u_t + 2.0).abs() < 1e-12);
    }

    #[test]
    fn pinned_velocity_is_computed_when_absent() {
        let text = good().replace("velocity = [-0.5, 1.5]\n", "");
        let case = parse_case("c.toml", &text).expect("valid");
        assert!((case.body.velocity[0] + 0.5).abs() < 1e-15);
        assert!((case.body.velocity[1] - 1.5).abs() < 1e-15);
    }

    #[test]
    fn default_names_and_their_clashes() {
        let text = good().replace("name = \"K\"", "name = \"K2\"")
            + "[[contacts]]\npoint = [-0.4, 0.3]\nnormal = [1.0, 0.0]\nrestitution = 0.5\nfriction = 0.1\n";
        let e = parse_case("c.toml", &text).unwrap_err();
        let s = input::render(&e);
        assert!(
            s.contains("contacts[1].name: this contact's default name \"K2\""),
            "{s}"
        );
    }
}
