//! Several bodies in the machine file: `[[bodies]]`, `[[joints]]`, contacts between
//! bodies and rotors on them read as written, and every rule of the contract refused
//! with its key path and reason.

use std::path::Path;

use machine_file::bodies::{FUNDAMENT, PLATFORM};
use machine_file::input::render;
use machine_file::Machine;

const MINIMAL: &str = include_str!("../../../tests/fixtures/minimal-machine.toml");

/// A collision element on a flat spring: body "element" hinged to the platform at
/// (0.1, 0.06), its face at y = 0.08 facing up; contact K3 is a point of a second
/// body "actuator" (hinged to the platform too) 1 mm above that face.
const TWO_BODIES: &str = r#"
[[bodies]]
name = "element"
mass = 0.05
inertia = 2e-5
position = [0.1, 0.07]

[[bodies]]
name = "actuator"
mass = 0.2
inertia = 1e-4
position = [0.1, 0.1]
velocity = [0.0, 0.05]          # turning about its hinge at (0, 0.1)
angular_velocity = 0.5

[[joints]]
name = "spring"
kind = "revolute"
bodies = ["platform", "element"]
point = [0.1, 0.06]
stiffness = 40.0
damping = 0.01

[[joints]]
name = "hinge"
kind = "revolute"
bodies = ["platform", "actuator"]
point = [0.0, 0.1]
rest_angle = 0.1

[[contacts]]
name = "K3"
point = [0.1, 0.081]
restitution = 0.5
friction = 0.2
body = "actuator"
against = "element"
face = [0.1, 0.08]
normal = [0.0, 2.0]
"#;

fn read(extra: &str) -> Result<Machine, String> {
    read_with(&format!("{MINIMAL}{extra}"))
}

#[test]
fn bodies_joints_and_contacts_between_bodies_read_as_written() {
    let m = read(TWO_BODIES).expect("valid");
    assert_eq!(m.bodies.len(), 2);
    assert_eq!(m.bodies[1].name, "actuator");
    assert_eq!(m.bodies[1].rigid.angular_velocity, 0.5);
    assert_eq!(m.bodies[0].rigid.velocity, [0.0, 0.0]);
    assert_eq!(
        m.joints[0].bodies,
        [PLATFORM.to_string(), "element".to_string()]
    );
    assert_eq!((m.joints[0].stiffness, m.joints[0].damping), (40.0, 0.01));
    assert_eq!(m.joints[0].rest_angle, None);
    assert_eq!(m.joints[1].rest_angle, Some(0.1));
    let k3 = &m.contacts[2];
    assert_eq!(
        (k3.ends.body.as_str(), k3.ends.against.as_str()),
        ("actuator", "element")
    );
    assert_eq!(k3.ends.normal, Some([0.0, 1.0]), "the normal is made unit");
    assert_eq!(k3.ends.face, Some([0.1, 0.08]));
    // The feet keep their defaults: the platform on the fundament.
    assert_eq!(m.contacts[0].ends.against, FUNDAMENT);
    assert_eq!(m.contacts[0].ends.normal, None);
    assert_eq!(m.rotors[0].body, PLATFORM);
    assert!(m.beyond_the_platform().len() >= 3);
    // A one-body machine asks nothing beyond the platform.
    assert!(read("").unwrap().beyond_the_platform().is_empty());
}

#[test]
fn a_face_defaults_to_the_contact_point() {
    let text = TWO_BODIES.replace("face = [0.1, 0.08]\n", "");
    let m = read(&text).expect("valid");
    assert_eq!(m.contacts[2].ends.face, Some([0.1, 0.081]));
}

/// Each broken rule: the text changed, the key path and the words expected.
#[test]
fn every_rule_is_refused_with_its_key() {
    let cases: &[(&str, &str, &str, &str)] = &[
        (
            "name = \"element\"",
            "name = \"platform\"",
            "bodies[0].name",
            "is taken",
        ),
        (
            "kind = \"revolute\"\nbodies = [\"platform\", \"element\"]",
            "kind = \"prismatic\"\nbodies = [\"platform\", \"element\"]",
            "joints[0].kind",
            "revolute",
        ),
        (
            "bodies = [\"platform\", \"element\"]",
            "bodies = [\"platform\", \"elemnt\"]",
            "joints[0].bodies",
            "no body named \"elemnt\"",
        ),
        (
            "bodies = [\"platform\", \"element\"]",
            "bodies = [\"element\", \"element\"]",
            "joints[0].bodies",
            "to itself",
        ),
        (
            "bodies = [\"platform\", \"element\"]",
            "bodies = \"platform\"",
            "joints[0].bodies",
            "two names",
        ),
        (
            "bodies = [\"platform\", \"actuator\"]",
            "bodies = [\"platform\", \"element\"]",
            "joints[1].bodies",
            "closes a loop",
        ),
        (
            "body = \"actuator\"",
            "body = \"fundament\"",
            "contacts[2].body",
            "does not move",
        ),
        (
            "body = \"actuator\"",
            "body = \"element\"",
            "contacts[2].against",
            "against itself",
        ),
        (
            "against = \"element\"",
            "against = \"elemnt\"",
            "contacts[2].against",
            "no body named",
        ),
        (
            "normal = [0.0, 2.0]\n",
            "",
            "contacts[2].normal",
            "missing; required against a body",
        ),
        (
            "normal = [0.0, 2.0]",
            "normal = [0.0, 0.0]",
            "contacts[2].normal",
            "must not be zero",
        ),
        (
            "point = [0.1, 0.081]",
            "point = [0.1, 0.079]",
            "contacts[2].point",
            "overlaps \"element\" at t = 0",
        ),
        (
            "stiffness = 40.0",
            "stiffness = -1.0",
            "joints[0].stiffness",
            ">= 0",
        ),
        ("mass = 0.05", "mass = 0.0", "bodies[0].mass", "> 0"),
        (
            "inertia = 2e-5",
            "inertia = -2e-5",
            "bodies[0].inertia",
            "> 0",
        ),
        (
            "position = [0.1, 0.07]\n",
            "",
            "bodies[0].position",
            "missing",
        ),
        (
            "position = [0.1, 0.07]",
            "position = [0.1, 0.07]\nangle = \"up\"",
            "bodies[0].angle",
            "must be a number",
        ),
        (
            "angular_velocity = 0.5",
            "angular_velocity = [0.5]",
            "bodies[1].angular_velocity",
            "must be a number",
        ),
        (
            "velocity = [0.0, 0.05]",
            "velocity = [0.0]",
            "bodies[1].velocity",
            "[x, y]",
        ),
        (
            "name = \"hinge\"",
            "name = \"spring\"",
            "joints[1].name",
            "duplicate joint name",
        ),
        ("point = [0.1, 0.06]\n", "", "joints[0].point", "missing"),
        (
            "damping = 0.01",
            "damping = -0.01",
            "joints[0].damping",
            ">= 0",
        ),
        (
            "rest_angle = 0.1",
            "rest_angle = \"flat\"",
            "joints[1].rest_angle",
            "must be a number",
        ),
        (
            "stiffness = 40.0",
            "stiffness = 1e12",
            "joints[0].stiffness",
            "swings the joint at sqrt(k / J) =",
        ),
        (
            "damping = 0.01",
            "damping = 1e12",
            "joints[0].damping",
            "relaxes the joint at c / J =",
        ),
        (
            "rest_angle = 0.1",
            "rest_angle = 1e6",
            "joints[1].rest_angle",
            "winds the spring by -1000000 rad at t = 0",
        ),
        (
            "face = [0.1, 0.08]",
            "face = [0.1]",
            "contacts[2].face",
            "[x, y]",
        ),
        (
            "velocity = [0.0, 0.05]",
            "velocity = [0.0, 0.0]",
            "joints[1].point",
            "moves at [0, 0] m/s with \"platform\" but at [0, -0.05] m/s with \"actuator\"",
        ),
    ];
    for (from, to, key, words) in cases {
        assert!(
            TWO_BODIES.contains(from),
            "the case's text is in the file: {from}"
        );
        let text = TWO_BODIES.replacen(from, to, 1);
        let e = read(&text).expect_err(key);
        let line = e
            .lines()
            .find(|l| l.contains(&format!("m.toml: {key}:")))
            .unwrap_or_else(|| panic!("{key}: not named in\n{e}"));
        assert!(line.contains(words), "{key}: {line:?} lacks {words:?}");
    }
}

/// The minimal machine with `from` changed to `to` (once) is refused with `needle`.
fn minimal_refused(from: &str, to: &str, needle: &str) {
    let e = read_with(&MINIMAL.replacen(from, to, 1)).expect_err(needle);
    assert!(e.contains(needle), "{needle:?} not in\n{e}");
}

fn read_with(text: &str) -> Result<Machine, String> {
    Machine::from_text("m.toml", text, Path::new(""), &[]).map_err(|p| render(&p))
}

#[test]
fn face_and_normal_are_refused_against_the_fundament() {
    minimal_refused(
        "friction = 0.4\n",
        "friction = 0.4\nnormal = [0.0, 1.0]\n",
        "m.toml: contacts[0].normal: only for a contact against a body",
    );
}

#[test]
fn a_rotor_sits_on_a_moving_body() {
    minimal_refused(
        "sense = \"ccw\"\n",
        "sense = \"ccw\"\nbody = \"fundament\"\n",
        "m.toml: rotors[0].body: no moving body named \"fundament\"",
    );
}

#[test]
fn further_bodies_can_be_set_from_the_command_line() {
    let m = Machine::from_text(
        "m.toml",
        &format!("{MINIMAL}{TWO_BODIES}"),
        Path::new(""),
        &[
            "bodies.element.mass=0.07".to_string(),
            "joints.spring.stiffness=55".to_string(),
        ],
    )
    .expect("valid");
    assert_eq!(m.bodies[0].rigid.mass, 0.07);
    assert_eq!(m.joints[0].stiffness, 55.0);
}

/// `n` free bodies (no joints) far above the floor.
fn free_bodies(n: usize) -> String {
    (0..n)
        .map(|i| {
            format!(
                "\n[[bodies]]\nname = \"b{i}\"\nmass = 0.1\ninertia = 1e-4\nposition = [{}, 1.0]\n",
                i as f64
            )
        })
        .collect()
}

#[test]
fn the_plant_limits_are_refused_with_the_numbers() {
    use machine_file::bodies::{MAX_BODIES, MAX_DOF};
    // Within the bodies' limit, beyond the coordinates': 3 x 6 + 2 rotors.
    let e = read(&free_bodies(MAX_BODIES - 1)).expect_err("too many coordinates");
    assert!(
        e.contains("m.toml: joints: the machine has 20 degrees of freedom")
            && e.contains(&format!("at most {MAX_DOF}")),
        "{e}"
    );
    let e = read(&free_bodies(MAX_BODIES)).expect_err("too many bodies");
    assert!(
        e.contains(&format!(
            "m.toml: bodies: {MAX_BODIES} [[bodies]] make {} bodies",
            MAX_BODIES + 1
        )),
        "{e}"
    );
    // Three free bodies with two rotors: 11 coordinates, accepted.
    read(&free_bodies(2)).expect("11 coordinates");
}

/// A joint's rate and preload limits: the bound each message names is allowed, and
/// one a thousandth beyond it is refused (the figure rounded towards the allowed
/// side; `joint_limits::MAX_JOINT_RATE` and `MAX_PRELOAD` against the two bodies'
/// least relative inertia).
#[test]
fn the_bound_a_joint_limit_names_is_allowed_and_a_little_more_is_not() {
    for (from, key, unit) in [
        ("stiffness = 40.0", "joints[0].stiffness", "N m/rad here"),
        ("damping = 0.01", "joints[0].damping", "N m s/rad here"),
        (
            "rest_angle = 0.1",
            "joints[1].rest_angle",
            "rad (half a turn)",
        ),
    ] {
        let name = from.split(' ').next().unwrap();
        let e = read(&TWO_BODIES.replacen(from, &format!("{name} = 1e9"), 1)).expect_err(key);
        let line = e
            .lines()
            .find(|l| l.contains(key))
            .unwrap_or_else(|| panic!("{e}"));
        let bound: f64 = line
            .split("at most ")
            .last()
            .and_then(|rest| rest.split(' ').next())
            .and_then(|x| x.parse().ok())
            .unwrap_or_else(|| panic!("no bound in {line:?}"));
        assert!(line.contains(unit), "{line}");
        // The rest angle winds the spring by its distance from the t = 0 angle (0).
        let allowed = TWO_BODIES.replacen(from, &format!("{name} = {bound:?}"), 1);
        if let Err(e) = read(&allowed) {
            panic!("{key} = {bound} (the bound named) refused:\n{e}");
        }
        let beyond = TWO_BODIES.replacen(from, &format!("{name} = {:?}", bound * 1.001), 1);
        let e = read(&beyond).expect_err(key);
        assert!(e.contains(&format!("m.toml: {key}:")), "{e}");
    }
}
