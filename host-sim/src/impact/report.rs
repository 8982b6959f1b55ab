//! The output of `host-sim impact`: its JSON document (docs/cli-impact.md,
//! "Output"), its table for people, and the warnings in words.
//!
//! The JSON keys and their order are the contract: `law`, `velocity_before`,
//! `angular_velocity_before`, `velocity_after`, `angular_velocity_after`, `contacts`
//! (keyed by contact name, in file order), `pivot` (only when pinned),
//! `kinetic_energy_before`, `kinetic_energy_after`, `warnings`.

use serde_json::{Map, Value};
use shared::impact::{BodyImpact, ContactOutcome, ImpactLaw, SlipState, Warnings, MAX_CONTACTS};
use shared::Enumerated;

use crate::impact::case::ImpactCase;
use crate::numbers;
use crate::output::text::{Align, Table};

/// A body's impact result, as `solve_body` returns it for up to [`MAX_CONTACTS`].
pub type Solved = BodyImpact<f64, MAX_CONTACTS>;

/// The document's keys in the documented order (docs/cli-impact.md, "`--format
/// json`"; `pivot` only when pinned).
pub const DOCUMENT_KEYS: [&str; 10] = [
    "law",
    "velocity_before",
    "angular_velocity_before",
    "velocity_after",
    "angular_velocity_after",
    "contacts",
    "pivot",
    "kinetic_energy_before",
    "kinetic_energy_after",
    "warnings",
];

/// The keys of a contact's object, in the documented order.
pub const CONTACT_KEYS: [&str; 11] = [
    "normal_impulse",
    "tangential_impulse",
    "compression",
    "restitution",
    "normal_velocity_before",
    "normal_velocity_after",
    "tangential_velocity_before",
    "tangential_velocity_after",
    "case",
    "case_name",
    "segments",
];

/// The keys of one segment of a contact's history, in the documented order.
pub const SEGMENT_KEYS: [&str; 4] = ["phase", "state", "normal_impulse", "tangential_impulse"];

/// `[x, y]` as a JSON array of numbers.
fn pair(v: [f64; 2]) -> Value {
    Value::Array(vec![Value::from(v[0]), Value::from(v[1])])
}

/// `{"normal_impulse": n, "tangential_impulse": t}`.
fn impulse_pair(p: [f64; 2]) -> Value {
    let mut m = Map::new();
    m.insert("normal_impulse".into(), Value::from(p[0]));
    m.insert("tangential_impulse".into(), Value::from(p[1]));
    Value::Object(m)
}

/// One contact's object, keys in the documented order.
fn contact_json(c: &ContactOutcome<f64>) -> Value {
    let mut m = Map::new();
    m.insert("normal_impulse".into(), Value::from(c.normal_impulse));
    m.insert(
        "tangential_impulse".into(),
        Value::from(c.tangential_impulse),
    );
    m.insert("compression".into(), impulse_pair(c.compression));
    m.insert("restitution".into(), impulse_pair(c.restitution));
    m.insert(
        "normal_velocity_before".into(),
        Value::from(c.normal_velocity_before),
    );
    m.insert(
        "normal_velocity_after".into(),
        Value::from(c.normal_velocity_after),
    );
    m.insert(
        "tangential_velocity_before".into(),
        Value::from(c.tangential_velocity_before),
    );
    m.insert(
        "tangential_velocity_after".into(),
        Value::from(c.tangential_velocity_after),
    );
    m.insert("case".into(), Value::from(c.case.number()));
    m.insert("case_name".into(), Value::from(c.case.name()));
    let segments = c
        .segments
        .iter()
        .map(|s| {
            let mut seg = Map::new();
            seg.insert("phase".into(), Value::from(s.phase.name()));
            seg.insert("state".into(), Value::from(s.state.name()));
            seg.insert("normal_impulse".into(), pair(s.normal_impulse));
            seg.insert("tangential_impulse".into(), pair(s.tangential_impulse));
            Value::Object(seg)
        })
        .collect();
    m.insert("segments".into(), Value::Array(segments));
    Value::Object(m)
}

/// The JSON document of docs/cli-impact.md for `case` solved into `result`.
pub fn json(case: &ImpactCase, result: &Solved) -> Value {
    let mut doc = Map::new();
    doc.insert("law".into(), Value::from(case.law.name()));
    doc.insert("velocity_before".into(), pair(result.velocity_before));
    doc.insert(
        "angular_velocity_before".into(),
        Value::from(result.angular_velocity_before),
    );
    doc.insert("velocity_after".into(), pair(result.velocity_after));
    doc.insert(
        "angular_velocity_after".into(),
        Value::from(result.angular_velocity_after),
    );
    let mut contacts = Map::new();
    for (named, outcome) in case.contacts.iter().zip(&result.outcome.contacts) {
        contacts.insert(named.name.clone(), contact_json(outcome));
    }
    doc.insert("contacts".into(), Value::Object(contacts));
    if let Some(p) = &result.pivot {
        let mut pivot = Map::new();
        pivot.insert("impulse".into(), pair(p.impulse));
        pivot.insert("compression".into(), pair(p.compression));
        pivot.insert("restitution".into(), pair(p.restitution));
        doc.insert("pivot".into(), Value::Object(pivot));
    }
    doc.insert(
        "kinetic_energy_before".into(),
        Value::from(result.kinetic_energy_before),
    );
    doc.insert(
        "kinetic_energy_after".into(),
        Value::from(result.kinetic_energy_after),
    );
    let warnings = warnings(case, result)
        .into_iter()
        .map(Value::from)
        .collect();
    doc.insert("warnings".into(), Value::Array(warnings));
    Value::Object(doc)
}

/// The JSON document as text: pretty-printed, ending with a newline.
pub fn json_text(case: &ImpactCase, result: &Solved) -> String {
    let mut s = serde_json::to_string_pretty(&json(case, result))
        .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    s.push('\n');
    s
}

/// The contacts (name, outcome) of a result, in file order.
fn named<'a>(
    case: &'a ImpactCase,
    result: &'a Solved,
) -> impl Iterator<Item = (&'a str, &'a ContactOutcome<f64>)> {
    case.contacts
        .iter()
        .map(|c| c.name.as_str())
        .zip(&result.outcome.contacts)
}

/// Names as `K1, K2`, or `fallback` when there are none.
fn names(list: Vec<&str>, fallback: &str) -> String {
    if list.is_empty() {
        fallback.to_string()
    } else {
        list.join(", ")
    }
}

/// The warnings of a result in words, one string each: the solver's flags, then
/// contacts whose history was truncated.
pub fn warnings(case: &ImpactCase, result: &Solved) -> Vec<String> {
    let flags = result.outcome.warnings;
    let mut out = Vec::new();
    if flags.contains(Warnings::ENERGY_GAINED) {
        let why = match case.law {
            ImpactLaw::Newton => "Newton's law with friction can create energy",
            ImpactLaw::Poisson => {
                "Poisson's law with unequal restitution at several contacts can create energy"
            }
            ImpactLaw::Stronge => {
                "Stronge's law should not create energy: treat this result with suspicion"
            }
        };
        out.push(format!(
            "energy gained: {} J ({why})",
            numbers::signed(result.outcome.energy_change)
        ));
    }
    if flags.contains(Warnings::PENETRATION_LEFT) {
        let approaching = named(case, result)
            .filter(|(_, c)| c.normal_velocity_after < 0.0)
            .map(|(n, _)| n)
            .collect();
        out.push(format!(
            "penetration left: {} still approaching after the impact (normal velocity after < 0)",
            names(approaching, "a contact is")
        ));
    }
    if flags.contains(Warnings::JAMMING) {
        // The contacts that end the impact sticking are the ones that jam.
        let stuck = named(case, result)
            .filter(|(_, c)| {
                c.segments
                    .last()
                    .is_some_and(|s| s.state == SlipState::Stick)
            })
            .map(|(n, _)| n)
            .collect::<Vec<_>>();
        let who = if stuck.is_empty() {
            "a contact sticks".to_string()
        } else {
            format!("contact {} sticks", stuck.join(", "))
        };
        out.push(format!(
            "jamming (self-locking): {who} where slip would not separate it (the paper's h < f d case; its eq. (5) does not apply)"
        ));
    }
    let energies = [result.kinetic_energy_before, result.kinetic_energy_after];
    if energies.iter().any(|e| !e.is_finite()) {
        out.push(
            "kinetic energy out of range: (1/2) m v^2 overflows a double (velocities near 1e154 m/s or more); it is reported as inf in the table and null in JSON, the impulses and velocities are still the solver's"
                .to_string(),
        );
    }
    if flags.contains(Warnings::INCONSISTENT) {
        out.push(
            "inconsistent configuration: at some event no consistent set of contact states (slip, stick, released) exists; the solver took the closest one, so the result is approximate"
                .to_string(),
        );
    }
    for (name, c) in named(case, result) {
        if c.truncated {
            out.push(format!(
                "contact {name}: history truncated to its first {} segments (more slip/stick switches than recorded); impulses and case are complete",
                c.segments.len()
            ));
        }
    }
    out
}

/// The history of a contact in short: `c:slip- r:slip+` (c compression,
/// r restitution), `-` when it has none.
fn history(c: &ContactOutcome<f64>) -> String {
    let parts: Vec<String> = c
        .segments
        .iter()
        .map(|s| format!("{}:{}", &s.phase.name()[..1], s.state.name()))
        .collect();
    if parts.is_empty() {
        "-".to_string()
    } else if c.truncated {
        format!("{} ...", parts.join(" "))
    } else {
        parts.join(" ")
    }
}

/// The table for people: the body before and after, the pivot, one line per
/// contact, the warnings.
pub fn table(case: &ImpactCase, result: &Solved) -> String {
    let mut out = String::new();
    let n = case.contacts.len();
    let plural = if n == 1 { "" } else { "s" };
    let body = match case.pivot {
        Some(o) => format!("pinned at {}", numbers::pair(o)),
        None => "free".to_string(),
    };
    out.push_str(&format!(
        "law: {}   body: {body}, mass {} kg, inertia {} kg m^2   {n} contact{plural}\n\n",
        case.law.name(),
        numbers::sig(case.body.mass),
        numbers::sig(case.body.inertia),
    ));

    // The body before and after.
    let mut motion = Table::new(&[
        ("", Align::Left),
        ("before", Align::Right),
        ("after", Align::Right),
    ]);
    motion.row(vec![
        "velocity of C [m/s]".into(),
        numbers::pair(result.velocity_before),
        numbers::pair(result.velocity_after),
    ]);
    motion.row(vec![
        "angular velocity [rad/s]".into(),
        numbers::sig(result.angular_velocity_before),
        numbers::sig(result.angular_velocity_after),
    ]);
    motion.row(vec![
        "kinetic energy [J]".into(),
        numbers::sig(result.kinetic_energy_before),
        numbers::sig(result.kinetic_energy_after),
    ]);
    out.push_str(&motion.render());
    if let Some(p) = &result.pivot {
        out.push_str(&format!(
            "pivot impulse [N s]: {} (compression {}, restitution {})\n",
            numbers::pair(p.impulse),
            numbers::pair(p.compression),
            numbers::pair(p.restitution)
        ));
    }
    out.push('\n');

    // One line per contact.
    let mut contacts = Table::new(&[
        ("contact", Align::Left),
        ("case", Align::Left),
        ("Pn", Align::Right),
        ("Pt", Align::Right),
        ("Pn comp", Align::Right),
        ("Pt comp", Align::Right),
        ("Pn rest", Align::Right),
        ("Pt rest", Align::Right),
        ("un before", Align::Right),
        ("un after", Align::Right),
        ("ut before", Align::Right),
        ("ut after", Align::Right),
        ("history", Align::Left),
    ]);
    for (name, c) in named(case, result) {
        contacts.row(vec![
            name.to_string(),
            format!("{} {}", c.case.number(), c.case.name()),
            numbers::sig(c.normal_impulse),
            numbers::sig(c.tangential_impulse),
            numbers::sig(c.compression[0]),
            numbers::sig(c.compression[1]),
            numbers::sig(c.restitution[0]),
            numbers::sig(c.restitution[1]),
            numbers::sig(c.normal_velocity_before),
            numbers::sig(c.normal_velocity_after),
            numbers::sig(c.tangential_velocity_before),
            numbers::sig(c.tangential_velocity_after),
            history(c),
        ]);
    }
    out.push_str(&contacts.render());
    out.push_str(
        "(impulses P in N s, velocities u in m/s; n normal, t tangential; history: c compression, r restitution)\n\n",
    );

    // Warnings.
    let warnings = warnings(case, result);
    if warnings.is_empty() {
        out.push_str("warnings: none\n");
    } else {
        out.push_str("warnings:\n");
        for w in warnings {
            out.push_str(&format!("  - {w}\n"));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::impact::case::parse_case;
    use shared::impact::{ImpactOutcome, InteractionCase, Phase, PivotImpulse, Segment, Warnings};

    /// The example case of docs/cli-impact.md with a second contact "B".
    fn case_text() -> String {
        include_str!("../../tests/fixtures/pinned-body.toml").to_string()
            + "[[contacts]]\nname = \"B\"\npoint = [-0.4, 0.3]\nnormal = [1.0, 0.0]\nrestitution = 0.6\nfriction = 0.3\n"
    }

    /// A hand-made result (numbers arbitrary, not a solution).
    fn fake(warnings: Warnings) -> Solved {
        let mut k = ContactOutcome {
            normal_impulse: 1.5,
            tangential_impulse: 0.25,
            compression: [1.0, 0.3],
            restitution: [0.5, -0.05],
            normal_velocity_before: -1.25,
            normal_velocity_after: 0.75,
            tangential_velocity_before: -2.0,
            tangential_velocity_after: 1.2,
            case: InteractionCase::ReversalInRestitution,
            ..ContactOutcome::default()
        };
        k.segments
            .push(Segment {
                phase: Phase::Compression,
                state: SlipState::SlipNegative,
                normal_impulse: [0.0, 1.0],
                tangential_impulse: [0.0, 0.3],
            })
            .unwrap();
        k.segments
            .push(Segment {
                phase: Phase::Restitution,
                state: SlipState::Stick,
                normal_impulse: [1.0, 1.5],
                tangential_impulse: [0.3, 0.25],
            })
            .unwrap();
        let mut contacts: [ContactOutcome<f64>; MAX_CONTACTS] = Default::default();
        contacts[0] = k;
        contacts[1].normal_velocity_after = -0.5;
        contacts[1].truncated = true;
        BodyImpact {
            outcome: ImpactOutcome {
                len: 2,
                contacts,
                energy_change: 0.0123,
                warnings,
            },
            velocity_before: [-0.5, 1.5],
            velocity_after: [0.1, -0.3],
            angular_velocity_before: 5.0,
            angular_velocity_after: -1.0,
            pivot: Some(PivotImpulse {
                impulse: [0.5, 0.25],
                compression: [0.25, 0.125],
                restitution: [0.25, 0.125],
            }),
            kinetic_energy_before: 1.0,
            kinetic_energy_after: 0.25,
        }
    }

    fn keys(v: &Value) -> Vec<&str> {
        v.as_object().unwrap().keys().map(String::as_str).collect()
    }

    #[test]
    fn json_has_exactly_the_documented_keys_in_order() {
        let case = parse_case("c.toml", &case_text()).unwrap();
        let doc = json(&case, &fake(Warnings::default()));
        assert_eq!(keys(&doc), DOCUMENT_KEYS);
        assert_eq!(keys(&doc["contacts"]), ["K", "B"]);
        let k = &doc["contacts"]["K"];
        assert_eq!(keys(k), CONTACT_KEYS);
        assert_eq!(
            keys(&k["compression"]),
            ["normal_impulse", "tangential_impulse"]
        );
        assert_eq!(k["case"], 6);
        assert_eq!(k["case_name"], "reversal-in-restitution");
        assert_eq!(keys(&k["segments"][0]), SEGMENT_KEYS);
        assert_eq!(k["segments"][0]["state"], "slip-");
        assert_eq!(k["segments"][1]["phase"], "restitution");
        assert_eq!(k["segments"][1]["normal_impulse"][1], 1.5);
        assert_eq!(doc["contacts"]["B"]["case"], 0);
        assert_eq!(doc["contacts"]["B"]["case_name"], "inactive");
        assert_eq!(
            keys(&doc["pivot"]),
            ["impulse", "compression", "restitution"]
        );
        assert_eq!(doc["law"], "poisson");
        // Only the truncation warning.
        assert_eq!(doc["warnings"].as_array().unwrap().len(), 1);
    }

    #[test]
    fn json_text_is_one_parseable_document() {
        let case = parse_case("c.toml", &case_text()).unwrap();
        let text = json_text(&case, &fake(Warnings::default()));
        let back: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back["velocity_after"][1], -0.3);
    }

    #[test]
    fn no_pivot_key_for_a_free_body() {
        let case = parse_case("c.toml", &case_text()).unwrap();
        let mut r = fake(Warnings::default());
        r.pivot = None;
        assert!(json(&case, &r).get("pivot").is_none());
    }

    #[test]
    fn warnings_in_words() {
        let case = parse_case("c.toml", &case_text()).unwrap();
        let mut flags = Warnings::default();
        for w in [
            Warnings::ENERGY_GAINED,
            Warnings::PENETRATION_LEFT,
            Warnings::JAMMING,
            Warnings::INCONSISTENT,
        ] {
            flags.insert(w);
        }
        let w = warnings(&case, &fake(flags));
        assert_eq!(w.len(), 5, "{w:?}");
        assert!(
            w[0].starts_with("energy gained: +0.0123 J (Poisson's law"),
            "{}",
            w[0]
        );
        assert!(
            w[1].starts_with("penetration left: B still approaching"),
            "{}",
            w[1]
        );
        assert!(
            w[2].starts_with("jamming (self-locking): contact K sticks"),
            "{}",
            w[2]
        );
        assert!(w[3].starts_with("inconsistent configuration"), "{}", w[3]);
        assert!(w[4].starts_with("contact B: history truncated"), "{}", w[4]);
    }

    #[test]
    fn table_has_one_line_per_contact() {
        let case = parse_case("c.toml", &case_text()).unwrap();
        let t = table(&case, &fake(Warnings::ENERGY_GAINED));
        assert!(t.contains("law: poisson"), "{t}");
        assert!(t.contains("pinned at [0, 0]"), "{t}");
        assert!(t.contains("pivot impulse [N s]: [0.5, 0.25]"), "{t}");
        let k = t.lines().find(|l| l.starts_with("K ")).expect("a K line");
        assert!(k.contains("6 reversal-in-restitution"), "{k}");
        assert!(k.contains("c:slip- r:stick"), "{k}");
        let b = t.lines().find(|l| l.starts_with("B ")).expect("a B line");
        assert!(b.contains("0 inactive"), "{b}");
        assert!(t.contains("  - energy gained: +0.0123 J"), "{t}");
    }
}
