//! Persistent contact between two moving bodies, against closed forms written here
//! (Newton's second law for each body and the whole machine's momentum and angular
//! momentum; none of the plant's matrices):
//!
//! A platform (mass `M`) stands on a frictionless floor; a block (mass `m_b`)
//! rests on the platform's top face on two points `B1`, `B2` (`body = "block"`,
//! `against = "platform"`, normal up) with friction `mu`, started sliding to the
//! right at `v0` relative to the platform, which starts at rest. Gravity on; the
//! one rotor inert (no eccentric mass, winding open, motor without friction).
//!
//! While the block slips, Coulomb's law puts `mu m_b g` against the slip on the
//! block and its opposite on the platform (the floor takes no horizontal force):
//!
//! ```text
//!   a_b = -mu g,   a_p = +mu m_b g / M,
//!   v_b - v_p = v0 - mu g (1 + m_b / M) t,   slip ends at t* = v0 / (mu g (1 + m_b / M))
//! ```
//!
//! after which both move at `V = m_b v0 / (m_b + M)` (the horizontal momentum
//! `m_b v0` is kept: no horizontal external force). Vertically nothing moves: the
//! block's two normal forces carry `m_b g`, the feet `(M + m_b) g`. Neither body
//! turns, so the moments balance:
//!
//! - on the block, about its centre (contacts at `x_b -+ a`, the face `h_b` below
//!   the centre, friction `-mu N_i` along x at each): `a (N2 - N1) = mu h_b (N1 +
//!   N2)`, so `N2 - N1 = mu m_b g h_b / a` (the leading point takes more), `N1 =
//!   N2` once the slip has ended;
//! - on the whole machine, about the origin: `dL/dt = -(M y_p a_p + m_b y_b a_b) =
//!   mu m_b g (y_b - y_p)` equals the external moments `x_1 F_1 + x_2 F_2 - g (M x_p
//!   + m_b x_b)`; with the feet at `x_p -+ d`, `F_1 + F_2 = (M + m_b) g`:
//!   `F_2 - F_1 = m_b g ((x_b - x_p) + mu (y_b - y_p)) / d` while slipping, without
//!   the `mu` term after.
//!
//! The plant's slip-end event fires where the slip has passed zero by its velocity
//! tolerance `eps_v` (`events.rs`, `s u_t + eps_v`), so at `t* + eps_v / a_rel`,
//! `a_rel = mu g (1 + m_b / M)` the relative deceleration; it is located to the
//! event time tolerance (1e-12 s). The mode decision then removes that residual
//! slip by the least mass-weighted change (an internal impulse), which keeps the
//! momentum: `V` exactly.

use tests::initial_state;
use tests::machine::{TestMachine, DRIVE_12V, FRICTIONLESS_MOTOR};

use host_sim::event::EventKind;
use host_sim::machine::Machine;
use host_sim::plant::contact::ContactMode;
use host_sim::plant::model::PlantModel;
use host_sim::plant::simulator::{Holds, Plant, Settings};
use tests::rig::{check, G};

/// The platform: 2 kg, its centre 0.03 m above the floor, feet 0.08 m either side.
const PLATFORM_MASS: f64 = 2.0;
const PLATFORM_Y: f64 = 0.03;
const FOOT: f64 = 0.08;
/// The platform's top face, m (world y).
const FACE_Y: f64 = 0.06;
/// The block: 0.5 kg, 60 mm wide and 40 mm high, its points at `-+ A` from its
/// centre on its underside, `H_B` above the face.
const BLOCK_MASS: f64 = 0.5;
const A: f64 = 0.03;
const H_B: f64 = 0.02;
/// Friction between block and platform, and the block's initial slip, m/s.
const MU: f64 = 0.3;

/// The machine: the platform on frictionless feet, the block on it, started at
/// `v0` (m/s).
fn machine(v0: f64) -> Machine {
    let block_y = FACE_Y + H_B;
    // A uniform block, m (w^2 + h^2) / 12.
    let block_inertia = BLOCK_MASS * ((2.0 * A).powi(2) + (2.0 * H_B).powi(2)) / 12.0;
    let text = format!(
        r#"[platform]
mass = {PLATFORM_MASS:?}
inertia = 7.3e-3
position = [0.0, {PLATFORM_Y:?}]

[[bodies]]
name = "block"
mass = {BLOCK_MASS:?}
inertia = {block_inertia:?}
position = [0.0, {block_y:?}]
velocity = [{v0:?}, 0.0]

[[contacts]]
name = "K1"
point = [{:?}, 0.0]
restitution = 0.3
friction = 0.0

[[contacts]]
name = "K2"
point = [{FOOT:?}, 0.0]
restitution = 0.3
friction = 0.0

[[contacts]]
name = "B1"
body = "block"
against = "platform"
point = [{:?}, {FACE_Y:?}]
face = [{:?}, {FACE_Y:?}]
normal = [0.0, 1.0]
restitution = 0.0
friction = {MU:?}

[[contacts]]
name = "B2"
body = "block"
against = "platform"
point = [{A:?}, {FACE_Y:?}]
face = [{A:?}, {FACE_Y:?}]
normal = [0.0, 1.0]
restitution = 0.0
friction = {MU:?}

[[rotors]]
axis = [0.0, {PLATFORM_Y:?}]
eccentric_mass = 0.0
eccentricity = 0.0
inertia = 6.0e-6
sense = "ccw"

"#,
        -FOOT, -A, -A,
    );
    TestMachine::new("block-on-platform.toml")
        .with(&text)
        .with(FRICTIONLESS_MOTOR)
        .with(DRIVE_12V)
        .machine()
}

#[test]
fn a_block_sliding_on_a_free_platform_drags_it_until_both_move_with_the_momentum() {
    // To the right and, mirrored, to the left (the other slip state, the moments'
    // signs turned).
    for v0 in [0.5, -0.5] {
        slide(v0);
    }
}

/// The block started at `v0` relative to the platform at rest: `s = sign(v0)` turns
/// every friction term of the module's closed forms.
fn slide(v0: f64) {
    let s = v0.signum();
    let m = machine(v0);
    let model = PlantModel::new(&m);
    assert_eq!(model.bodies.len(), 2);
    let names: Vec<&str> = model.contacts.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["K1", "K2", "B1", "B2"]);
    let mut plant = Plant::new(
        model,
        initial_state(&m),
        Settings::default(),
        Holds::default(),
    );
    // Every contact closed from the start; the block's slip is u_t = t . (v_b -
    // v_p) with t = z x n = (-1, 0), so -v0: slipping along -t for v0 > 0.
    let slip = if s > 0.0 {
        ContactMode::SlipNegative
    } else {
        ContactMode::SlipPositive
    };
    assert_eq!(plant.modes[2], slip, "{:?}", plant.modes);
    assert_eq!(plant.modes[3], slip, "{:?}", plant.modes);
    assert!(
        plant.modes[..2].iter().all(|m| *m != ContactMode::Open),
        "the feet on the floor: {:?}",
        plant.modes
    );

    let (mp, mb) = (PLATFORM_MASS, BLOCK_MASS);
    let weight = (mp + mb) * G;
    let a_b = -s * MU * G;
    let a_p = s * MU * mb * G / mp;
    let a_rel = MU * G * (1.0 + mb / mp);
    let t_star = v0.abs() / a_rel;
    let eps_v = plant.settings.velocity_tolerance;
    let t_event = t_star + eps_v / a_rel;
    let common = mb * v0 / (mb + mp);
    let block_y = FACE_Y + H_B;

    let dt = 1e-3;
    let steps = (2.0 * t_star / dt).ceil() as usize;
    let (mut worst_v, mut worst_x, mut worst_f) = (0.0f64, 0.0f64, 0.0f64);
    for k in 1..=steps {
        let t = k as f64 * dt;
        plant.advance_to(t, &mut |_| {}).unwrap();
        let [xp, yp, thp, vxp, vyp, wp] = plant.platform_motion();
        let [xb, yb, thb, vxb, vyb, wb] = plant.model.body_motion(1, &plant.y);
        let f = plant.contact_forces();
        let ctx = format!("v0 {v0}, t = {t:.3} s");
        // Closed forms: while slipping, the constant accelerations; after, V and
        // the positions the stick instant leaves (the residual slip eps_v of the
        // event is taken out by an internal impulse; its effect on positions is
        // eps_v^2 / a_rel ~ 3e-15 m).
        let slipping = t < t_event;
        let (xb_ref, vb_ref, xp_ref, vp_ref) = if slipping {
            (
                v0 * t + 0.5 * a_b * t * t,
                v0 + a_b * t,
                0.5 * a_p * t * t,
                a_p * t,
            )
        } else {
            let te = t_event;
            let xb_e = v0 * te + 0.5 * a_b * te * te;
            let xp_e = 0.5 * a_p * te * te;
            (
                xb_e + common * (t - te),
                common,
                xp_e + common * (t - te),
                common,
            )
        };
        let speed = v0.abs();
        // Velocities: 1e-9 of v0 (linear in t while slipping: the integrator is
        // exact on them to rounding; the event time's 1e-12 s moves them by
        // 4e-12 m/s).
        check(&format!("{ctx}: v_b"), vxb, vb_ref, 1e-9 * speed);
        check(&format!("{ctx}: v_p"), vxp, vp_ref, 1e-9 * speed);
        worst_v = worst_v.max((vxb - vb_ref).abs()).max((vxp - vp_ref).abs());
        // Positions: 1e-9 m (quadratics, exact in the integrator; the projections
        // onto the gaps move nothing along x).
        check(&format!("{ctx}: x_b"), xb, xb_ref, 1e-9);
        check(&format!("{ctx}: x_p"), xp, xp_ref, 1e-9);
        worst_x = worst_x.max((xb - xb_ref).abs()).max((xp - xp_ref).abs());
        // Nothing moves vertically or turns.
        for (what, got, want) in [
            ("y_p", yp, PLATFORM_Y),
            ("y_b", yb, block_y),
            ("theta_p", thp, 0.0),
            ("theta_b", thb, 0.0),
        ] {
            check(&format!("{ctx}: {what}"), got, want, 1e-12);
        }
        for (what, got) in [("v_y,p", vyp), ("v_y,b", vyb), ("w_p", wp), ("w_b", wb)] {
            check(&format!("{ctx}: {what}"), got, 0.0, 1e-9 * speed);
        }

        // Forces: 1e-9 of the weight (a linear solve of the closed contacts'
        // equations, exact to rounding, ~1e-15 of the forces).
        let tol_f = 1e-9 * weight;
        let [n1, t1] = f[2];
        let [n2, t2] = f[3];
        let [f1, _] = f[0];
        let [f2, _] = f[1];
        // The signed friction coefficient of the closed forms.
        let friction = if slipping { s * MU } else { 0.0 };
        // The block's forces along x: -(lambda_t1 + lambda_t2) (t = (-1, 0)).
        let block_fx = -(t1 + t2);
        check(
            &format!("{ctx}: friction on the block"),
            block_fx,
            -friction * mb * G,
            tol_f,
        );
        if slipping {
            // Each slipping point on the cone's edge, against the slip.
            check(&format!("{ctx}: B1 on the cone"), t1, s * MU * n1, tol_f);
            check(&format!("{ctx}: B2 on the cone"), t2, s * MU * n2, tol_f);
        }
        check(&format!("{ctx}: N1 + N2"), n1 + n2, mb * G, tol_f);
        check(
            &format!("{ctx}: N2 - N1"),
            n2 - n1,
            friction * mb * G * H_B / A,
            tol_f,
        );
        check(&format!("{ctx}: F1 + F2"), f1 + f2, weight, tol_f);
        let lever = (xb - xp) + friction * (yb - yp);
        check(
            &format!("{ctx}: F2 - F1"),
            f2 - f1,
            mb * G * lever / FOOT,
            tol_f,
        );
        worst_f = worst_f
            .max((block_fx + friction * mb * G).abs())
            .max((n1 + n2 - mb * G).abs())
            .max((n2 - n1 - friction * mb * G * H_B / A).abs())
            .max((f1 + f2 - weight).abs())
            .max((f2 - f1 - mb * G * lever / FOOT).abs());
    }

    // The slip ends once, on both points together, at t* + eps_v / a_rel.
    let sticks: Vec<_> = plant
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Stick)
        .collect();
    assert_eq!(sticks.len(), 2, "stick events {:?}", plant.events);
    let mut stuck: Vec<&str> = sticks.iter().map(|e| e.contact.as_str()).collect();
    stuck.sort_unstable();
    assert_eq!(stuck, ["B1", "B2"]);
    let t_stick = sticks[0].t;
    assert_eq!(sticks[1].t, t_stick);
    // Located to the event time tolerance, 1e-12 s; the closed form's own
    // rounding (1e-16 of t*) is far below.
    let tol_t = 10.0 * plant.settings.event_time_tolerance;
    check("stick time", t_stick, t_event, tol_t);
    assert!(
        plant
            .events
            .iter()
            .all(|e| e.kind == EventKind::Stick || e.kind == EventKind::Contact),
        "only the stick: {:?}",
        plant.events
    );
    assert!(plant.warnings.is_empty(), "{:?}", plant.warnings);
    assert_eq!(plant.modes[2], ContactMode::Stick);
    assert_eq!(plant.modes[3], ContactMode::Stick);
    eprintln!(
        "v0 {v0}: stick at {t_stick:.15} s, t* = {t_star:.15} s, t* + eps_v / a_rel = {t_event:.15} s \
         (diff {:.1e} s); worst errors: v {worst_v:.1e} m/s, x {worst_x:.1e} m, forces \
         {worst_f:.1e} N (weight {weight} N)",
        t_stick - t_event
    );
}

// ---------------------------------------------------------------------------------
// Two plates on one hinge (examples/paper-fig8.toml's actuator and element)
// ---------------------------------------------------------------------------------

/// The common hinge of the two plates, world, m (paper-fig8.toml's clamp).
const HINGE: [f64; 2] = [-0.03, 0.06];
/// The actuator (body 4): mass, kg; inertia about its centre, kg m^2; centre at
/// angle 0, world, m.
const ACTUATOR: (f64, f64, [f64; 2]) = (0.4, 6.0e-4, [-0.045, 0.15]);
/// The element (body 3), likewise.
const ELEMENT: (f64, f64, [f64; 2]) = (0.15, 1.6e-4, [-0.015, 0.115]);
/// K3 and K4: heights above the hinge on the actuator's right face, m.
const HEIGHTS: [f64; 2] = [0.04, 0.10];
/// Time from the start to the impact, s.
const T_HIT: f64 = 0.01;

/// `p` turned by `angle` about the hinge.
fn about_hinge(p: [f64; 2], angle: f64) -> [f64; 2] {
    let (s, c) = angle.sin_cos();
    let d = [p[0] - HINGE[0], p[1] - HINGE[1]];
    [
        HINGE[0] + c * d[0] - s * d[1],
        HINGE[1] + s * d[0] + c * d[1],
    ]
}

/// Fig. 8's actuator and element, both hinged to the platform at [`HINGE`] without
/// springs, the actuator's right face and the element's left face through the
/// hinge, K3 and K4 on the actuator against the element; no gravity, the rotor's
/// eccentric mass 0. They turn at `w4` and `w3` (rad/s) and are started `T_HIT`
/// before their faces meet upright: angles `-w T_HIT`, every point turned so.
fn plates(w4: f64, w3: f64, restitution: f64, friction: f64) -> Machine {
    let (a4, a3) = (-w4 * T_HIT, -w3 * T_HIT);
    let body = |name: &str, (mass, inertia, c): (f64, f64, [f64; 2]), angle: f64, w: f64| {
        let p = about_hinge(c, angle);
        // v = w z x (p - hinge): the joint's hinge at rest with the held platform.
        let v = [-w * (p[1] - HINGE[1]), w * (p[0] - HINGE[0])];
        format!(
            "[[bodies]]\nname = \"{name}\"\nmass = {mass:?}\ninertia = {inertia:?}\n\
             position = [{:?}, {:?}]\nangle = {angle:?}\nvelocity = [{:?}, {:?}]\n\
             angular_velocity = {w:?}\n\n\
             [[joints]]\nname = \"{name}-hinge\"\nkind = \"revolute\"\n\
             bodies = [\"platform\", \"{name}\"]\npoint = [{:?}, {:?}]\n\n",
            p[0], p[1], v[0], v[1], HINGE[0], HINGE[1]
        )
    };
    let (s3, c3) = a3.sin_cos();
    let normal = [-c3, -s3];
    let contact = |name: &str, h: f64| {
        let upright = [HINGE[0], HINGE[1] + h];
        let point = about_hinge(upright, a4);
        let face = about_hinge(upright, a3);
        format!(
            "[[contacts]]\nname = \"{name}\"\nbody = \"actuator\"\nagainst = \"element\"\n\
             point = [{:?}, {:?}]\nface = [{:?}, {:?}]\nnormal = [{:?}, {:?}]\n\
             restitution = {restitution:?}\nfriction = {friction:?}\n\n",
            point[0], point[1], face[0], face[1], normal[0], normal[1]
        )
    };
    let axis = about_hinge([-0.045, 0.17], a4);
    let text = format!(
        r#"[fundament]
gravity = [0.0, 0.0]

[platform]
mass = 2.0
inertia = 0.0102
position = [0.0, 0.03]

{}{}{}{}[[rotors]]
body = "actuator"
axis = [{:?}, {:?}]
eccentric_mass = 0.0
eccentricity = 0.0
inertia = 6.0e-6
sense = "ccw"

"#,
        body("actuator", ACTUATOR, a4, w4),
        body("element", ELEMENT, a3, w3),
        contact("K3", HEIGHTS[0]),
        contact("K4", HEIGHTS[1]),
        axis[0],
        axis[1],
    );
    TestMachine::new("two-plates.toml")
        .with(&text)
        .with(FRICTIONLESS_MOTOR)
        .with(DRIVE_12V)
        .machine()
}

/// Two plates turning about one fixed hinge, their faces through it, closing at
/// `w4 < w3`: K3 and K4 (heights `h3`, `h4` above the hinge) meet at once, and the
/// impact is one of two bodies on a common axis. With `J4`, `J3` their inertias
/// about the hinge (Steiner: `J = I_c + m |c - hinge|^2`), each contact's impulse
/// `P_i` normal to the plates, so with the lever `h_i`; the angular impulse `L =
/// h3 P3 + h4 P4` turns the actuator by `+L / J4` and the element by `-L / J3`.
/// Poisson's law at both contacts with one `e` (each contact's restitution impulse
/// `e` times its compression impulse, so their sum too): the compression ends where
/// the plates turn together, `L_c = J3 J4 / (J3 + J4) (w3 - w4)`, and `L = (1 + e)
/// L_c` (Stronge, *Impact Mechanics*, 2000, ch. 4, for the effective inertia of two
/// bodies on one axis), so
///
/// ```text
///   w4' = w4 - (1 + e) J3 / (J3 + J4) (w4 - w3),   w3' = w3 + (1 + e) J4 / (J3 + J4) (w4 - w3)
///   h3 P3 + h4 P4 = (1 + e) J3 J4 / (J3 + J4) |w4 - w3|
///   lost energy (1 - e^2) J3 J4 / (J3 + J4) (w4 - w3)^2 / 2
/// ```
///
/// The contacts' normal rows are proportional (`h3` and `h4` times the relative
/// angle's), so the Delassus matrix has rank 1 and the split between `P3` and `P4`
/// is the solver's choice (its weights): only the sum above is checked, and each
/// `P_i >= 0`. The slip at both is zero (the plates' points move normal to them),
/// so friction takes nothing: the same with friction 0.2.
///
/// Platform held, no gravity, no springs: nothing else acts, and the angular
/// velocities are constant before and after. Tolerance 1e-9 of `|w4 - w3|`: the
/// event lies within 1e-12 s of the meeting (the angles then differ from 0 by
/// `|w| 1e-12 s`, which changes nothing to first order: the levers are `h_i` at any
/// common angle), the rest is rounding.
#[test]
fn two_plates_on_one_hinge_strike_as_two_bodies_on_one_axis() {
    let steiner = |(m, i, c): (f64, f64, [f64; 2])| {
        i + m * ((c[0] - HINGE[0]).powi(2) + (c[1] - HINGE[1]).powi(2))
    };
    let (j4, j3) = (steiner(ACTUATOR), steiner(ELEMENT));
    for (w4, w3, e, mu) in [
        (-3.0, 1.0, 0.5, 0.2),
        (-3.0, 1.0, 0.5, 0.0),
        (2.0, 6.0, 1.0, 0.2),
        (-1.0, 0.0, 0.0, 0.2),
    ] {
        let case = format!("w4 {w4}, w3 {w3}, e {e}, mu {mu}");
        let m = plates(w4, w3, e, mu);
        let model = PlantModel::new(&m);
        assert_eq!(model.bodies.len(), 3);
        let (b4, b3) = (1, 2);
        assert_eq!(model.bodies[b4].name, "actuator");
        assert_eq!(model.bodies[b3].name, "element");
        let n = model.dof;
        let (i4, i3) = (n + model.bodies[b4].angle, n + model.bodies[b3].angle);
        let holds = Holds {
            platform: true,
            ..Holds::default()
        };
        let mut plant = Plant::new(model, initial_state(&m), Settings::default(), holds);
        assert!(plant.modes.iter().all(|m| *m == ContactMode::Open));
        plant.advance_to(2.0 * T_HIT, &mut |_| {}).unwrap();
        assert!(plant.warnings.is_empty(), "{case}: {:?}", plant.warnings);
        let impacts: Vec<_> = plant
            .events
            .iter()
            .filter(|e| e.kind == EventKind::Impact)
            .collect();
        assert_eq!(plant.impacts, 1, "{case}: {:?}", plant.events);
        let names: Vec<&str> = impacts.iter().map(|e| e.contact.as_str()).collect();
        assert_eq!(names, ["K3", "K4"], "{case}: {:?}", plant.events);
        check(&format!("{case}: impact time"), impacts[0].t, T_HIT, 1e-10);
        assert_eq!(impacts[1].t, impacts[0].t);

        let closing = w4 - w3;
        let tol = 1e-9 * closing.abs();
        let w4_after = w4 - (1.0 + e) * j3 / (j3 + j4) * closing;
        let w3_after = w3 + (1.0 + e) * j4 / (j3 + j4) * closing;
        let (got4, got3) = (plant.y[i4], plant.y[i3]);
        check(&format!("{case}: w4'"), got4, w4_after, tol);
        check(&format!("{case}: w3'"), got3, w3_after, tol);
        let angular_impulse: f64 = impacts
            .iter()
            .zip(HEIGHTS)
            .map(|(e, h)| h * e.normal_impulse)
            .sum();
        let j_eff = j3 * j4 / (j3 + j4);
        let expected = (1.0 + e) * j_eff * closing.abs();
        check(
            &format!("{case}: h3 P3 + h4 P4"),
            angular_impulse,
            expected,
            tol * j_eff,
        );
        for row in &impacts {
            assert!(
                row.normal_impulse >= -tol * j_eff,
                "{case}: {} P_n {}",
                row.contact,
                row.normal_impulse
            );
            // Each contact's normal velocity: h_i (w4 - w3) before, -e times it
            // after.
            let h = if row.contact == "K3" {
                HEIGHTS[0]
            } else {
                HEIGHTS[1]
            };
            check(
                &format!("{case}: {} u_n before", row.contact),
                row.normal_velocity_before,
                h * closing,
                tol * h,
            );
            check(
                &format!("{case}: {} u_n after", row.contact),
                row.normal_velocity_after,
                -e * h * closing,
                tol * h,
            );
        }
        // Energy: the two plates' kinetic energy about the hinge, J.
        let lost = 0.5 * j4 * (w4 * w4 - got4 * got4) + 0.5 * j3 * (w3 * w3 - got3 * got3);
        let scale = j_eff * closing * closing;
        check(
            &format!("{case}: energy lost"),
            lost,
            0.5 * (1.0 - e * e) * scale,
            1e-9 * scale,
        );
        eprintln!(
            "{case}: w4' err {:.1e}, w3' err {:.1e}, angular impulse err {:.1e} (tol {:.1e}), \
             split P3 {:.6e} P4 {:.6e} N s",
            got4 - w4_after,
            got3 - w3_after,
            angular_impulse - expected,
            tol * j_eff,
            impacts[0].normal_impulse,
            impacts[1].normal_impulse
        );
    }
}
