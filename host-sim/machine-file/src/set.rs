//! `--set KEY=VALUE`: overrides of machine-file keys, applied to the parsed TOML
//! table before it is checked, so an overridden value meets exactly the checks of a
//! value written in the file.
//!
//! One `--set` is parsed once, when it is made ([`Override::new`], stages 1 to
//! 3), and applied to a file's table by [`apply`] (stages 4 and 5):
//! 1. split `KEY=VALUE` at the first `=`; a missing `=` or an empty key is a problem;
//! 2. split `KEY` into segments at `.` and at `[...]` (`contacts[0].friction` is
//!    `contacts`, `0`, `friction`);
//! 3. parse `VALUE` as a TOML value (`0.2`, `[0, 0.1]`, `"cw"`, `true`); text that is
//!    not TOML stands as a string (`cw`);
//! 4. resolve the segments against [`SCHEMA`], the machine file's keys: an element of
//!    `[[contacts]]` or `[[rotors]]` is named by its `name` (default names included:
//!    `K1`, `R1`, ...) or by its index from 0; a key that is not in the schema, an
//!    element that is not in the file, or a path that ends on a table is a problem;
//! 5. write the value, creating the tables on the way that the file omits
//!    (`simulation.t_end=2` works without a `[simulation]`; so does
//!    `rotors.left.motor.resistance=3` without a `[rotors.motor]`).
//!
//! A refused override is said where it was given ([`Origin`]): on the command
//! line its problem names the whole argument in place of a file,
//!
//! ```text
//! error: --set contacts.K9.friction=0.2: no contact named K9 (contacts: K1, K2)
//! ```
//!
//! and in a file's list of overrides (a scenario's `set`) it is that file's
//! entry, the argument quoted (`error: s.toml: set[0]: "contacts.K9.friction=0.2":
//! no contact named K9 ...`). A value an override wrote that the machine's checks
//! refuse is the machine file's problem at its key, with `(from --set
//! KEY=VALUE)` added wherever the override came from.

use serde::Deserialize;
use toml::{Table, Value};

use crate::input::{cut, suggest, Location, Problem, MAX_QUOTED};

/// What a key of the machine file holds.
#[derive(Clone, Copy, Debug)]
pub enum Node {
    /// A value: a number, a vector, a string.
    Value,
    /// A table `[key]` with these keys.
    Table(&'static [(&'static str, Node)]),
    /// An array of tables `[[key]]` whose elements have these keys.
    Array {
        /// One element, for messages: `contact`, `rotor`.
        noun: &'static str,
        /// An element without a `name` is called this followed by its number from 1
        /// (`K` gives `K1`, `K2`, ...), as the machine reader names it.
        default_prefix: &'static str,
        /// The keys of an element.
        keys: &'static [(&'static str, Node)],
    },
}

/// The keys of a further body, `[[bodies]]`: a name, then those of `[platform]`
/// (the reader takes a body as a name and the platform's keys).
pub const BODY_KEYS: &[(&str, Node)] = &[
    ("name", Node::Value),
    ("mass", Node::Value),
    ("inertia", Node::Value),
    ("position", Node::Value),
    ("angle", Node::Value),
    ("velocity", Node::Value),
    ("angular_velocity", Node::Value),
];

/// The keys of `[platform]`: a body's without its name.
pub const RIGID_BODY_KEYS: &[(&str, Node)] = match BODY_KEYS.split_first() {
    Some((_, rest)) => rest,
    None => &[],
};

/// The keys of a brushed DC motor: `[motor]` and a rotor's own `[rotors.motor]`.
pub const MOTOR_KEYS: &[(&str, Node)] = &[
    ("resistance", Node::Value),
    ("inductance", Node::Value),
    ("torque_constant", Node::Value),
    ("coulomb_friction", Node::Value),
    ("viscous_friction", Node::Value),
    ("current_limit", Node::Value),
];

/// Every key of the machine file (docs/machine-file.md, "Keys"; `bodies` and
/// `joints`: "Several bodies"), section by section in the order of "Keys". The
/// machine reader's unit tests check that it reads exactly these keys.
pub const SCHEMA: &[(&str, Node)] = &[
    (
        "fundament",
        Node::Table(&[
            ("point", Node::Value),
            ("normal", Node::Value),
            ("gravity", Node::Value),
        ]),
    ),
    ("platform", Node::Table(RIGID_BODY_KEYS)),
    (
        "bodies",
        Node::Array {
            noun: "body",
            default_prefix: "B",
            keys: BODY_KEYS,
        },
    ),
    (
        "joints",
        Node::Array {
            noun: "joint",
            default_prefix: "J",
            keys: &[
                ("name", Node::Value),
                ("kind", Node::Value),
                ("bodies", Node::Value),
                ("point", Node::Value),
                ("stiffness", Node::Value),
                ("damping", Node::Value),
                ("rest_angle", Node::Value),
            ],
        },
    ),
    (
        "contacts",
        Node::Array {
            noun: "contact",
            default_prefix: "K",
            keys: &[
                ("name", Node::Value),
                ("point", Node::Value),
                ("restitution", Node::Value),
                ("friction", Node::Value),
                ("weight", Node::Value),
                ("body", Node::Value),
                ("against", Node::Value),
                ("face", Node::Value),
                ("normal", Node::Value),
            ],
        },
    ),
    (
        "rotors",
        Node::Array {
            noun: "rotor",
            default_prefix: "R",
            keys: &[
                ("name", Node::Value),
                ("axis", Node::Value),
                ("eccentric_mass", Node::Value),
                ("eccentricity", Node::Value),
                ("inertia", Node::Value),
                ("sense", Node::Value),
                ("angle", Node::Value),
                ("index_angle", Node::Value),
                ("body", Node::Value),
                ("motor", Node::Table(MOTOR_KEYS)),
            ],
        },
    ),
    ("motor", Node::Table(MOTOR_KEYS)),
    (
        "drive",
        Node::Table(&[
            ("supply_voltage", Node::Value),
            ("decay", Node::Value),
            ("pwm_hz", Node::Value),
        ]),
    ),
    (
        "sensors",
        Node::Table(&[
            ("encoder_counts", Node::Value),
            ("current_noise", Node::Value),
            ("encoder_jitter", Node::Value),
        ]),
    ),
    (
        "controller",
        Node::Table(&[
            ("rate_hz", Node::Value),
            ("speed_rpm", Node::Value),
            ("tuning_table", Node::Value),
        ]),
    ),
    ("impact", Node::Table(&[("law", Node::Value)])),
    (
        "simulation",
        Node::Table(&[
            ("t_end", Node::Value),
            ("output_step", Node::Value),
            ("seed", Node::Value),
            ("rtol", Node::Value),
            ("max_tilt", Node::Value),
            ("progress_budget", Node::Value),
        ]),
    ),
];

/// Every key `--set` can set, as a path with `NAME` for an element of an array of
/// tables: `fundament.point`, ..., `contacts.NAME.friction`, ...,
/// `rotors.NAME.motor.resistance`, ...
pub fn key_paths() -> Vec<String> {
    fn walk(prefix: &str, keys: &[(&str, Node)], out: &mut Vec<String>) {
        for (key, node) in keys {
            let path = if prefix.is_empty() {
                key.to_string()
            } else {
                format!("{prefix}.{key}")
            };
            match node {
                Node::Value => out.push(path),
                Node::Table(keys) => walk(&path, keys, out),
                Node::Array { keys, .. } => walk(&format!("{path}.NAME"), keys, out),
            }
        }
    }
    let mut out = Vec::new();
    walk("", SCHEMA, &mut out);
    out
}

/// Where an override was given.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Origin {
    /// `--set KEY=VALUE` on the command line.
    CommandLine,
    /// An entry of a file's list of overrides (a scenario's `set`): the file as
    /// the user named it and the entry's key path (`set[0]`).
    Entry {
        /// The file.
        file: String,
        /// The entry's key path.
        key_path: String,
    },
}

/// One `KEY=VALUE` override of a machine-file key: the argument as given, where
/// it was given, and its key and value parsed once, when it is made (stages 1 to
/// 3 of the module doc). A problem with it is said where it was given.
#[derive(Clone, Debug, PartialEq)]
pub struct Override {
    /// `KEY=VALUE`, as given.
    pub arg: String,
    /// Where it was given.
    pub origin: Origin,
    /// The key's segments and the value, or why `arg` is not an override.
    parsed: Result<Parsed, Refusal>,
}

/// An override's key and value, as parsed from `KEY=VALUE`.
#[derive(Clone, Debug, PartialEq)]
struct Parsed {
    /// The key's segments: `contacts[0].friction` is `contacts`, `0`, `friction`.
    segments: Vec<String>,
    /// The value, a TOML value (text that is not TOML stands as a string).
    value: Value,
}

impl Override {
    /// `arg` given at `origin`, its key and value parsed (stages 1 to 3 of the
    /// module doc); an argument that does not parse is refused when applied.
    pub fn new(arg: String, origin: Origin) -> Override {
        let parsed = parse(&arg);
        Override {
            arg,
            origin,
            parsed,
        }
    }

    /// The `--set` arguments of a command line, in order.
    pub fn command_line(args: &[String]) -> Vec<Override> {
        args.iter()
            .map(|arg| Override::new(arg.clone(), Origin::CommandLine))
            .collect()
    }

    /// This override refused for `why`, said where it was given: `--set
    /// KEY=VALUE: why`, or at the file's entry, `FILE: set[i]: "KEY=VALUE": why`.
    fn refused(&self, why: String) -> Problem {
        match &self.origin {
            Origin::CommandLine => Problem {
                file: format!("--set {}", self.arg),
                location: Location::File,
                message: why,
            },
            Origin::Entry { file, key_path } => Problem {
                file: file.clone(),
                location: Location::Key(key_path.clone()),
                message: format!("{:?}: {why}", self.arg),
            },
        }
    }
}

/// Why an override was refused: not `KEY=VALUE` at all, or a key or value
/// the machine file does not take.
#[derive(Clone, Debug, PartialEq)]
enum Refusal {
    NotKeyValue(String),
    Refused(String),
}

impl Refusal {
    fn message(&self) -> String {
        match self {
            Refusal::NotKeyValue(m) | Refusal::Refused(m) => m.clone(),
        }
    }
}

/// The problems of the overrides that are not `KEY=VALUE` at all (no `=`): what
/// can be said of them without the machine file (when it does not parse).
pub fn not_key_value(overrides: &[Override]) -> Vec<Problem> {
    overrides
        .iter()
        .filter_map(|o| match &o.parsed {
            Err(Refusal::NotKeyValue(why)) => Some(o.refused(why.clone())),
            _ => None,
        })
        .collect()
}

/// A `--set` that was applied.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Applied {
    /// The argument as given, `KEY=VALUE`.
    pub arg: String,
    /// The key path the machine reader gives the key, elements numbered from 0:
    /// `contacts.K1.friction` is `contacts[0].friction`.
    pub key_path: String,
}

/// Applies every override in order to the parsed machine file `table`.
/// Returns those applied and one problem for each refused, said where it was
/// given (a refused one changes nothing). Later overrides of the same key win.
pub fn apply(table: &mut Table, overrides: &[Override]) -> (Vec<Applied>, Vec<Problem>) {
    let mut applied = Vec::new();
    let mut problems = Vec::new();
    for o in overrides {
        let written = match &o.parsed {
            Ok(parsed) => apply_one(table, parsed),
            Err(refusal) => Err(refusal.clone()),
        };
        match written {
            Ok(key_path) => applied.push(Applied {
                arg: o.arg.clone(),
                key_path,
            }),
            Err(refusal) => problems.push(o.refused(refusal.message())),
        }
    }
    (applied, problems)
}

/// One step from a table to what it holds: a key, or an element of an array.
enum Step {
    Key(String),
    Element(usize),
}

/// Stages 1 to 3 of the module doc for one argument.
fn parse(arg: &str) -> Result<Parsed, Refusal> {
    // Stage 1: KEY=VALUE.
    let (key, value_text) = key_value(arg)?;
    // Stage 2: the key's segments.
    let segments = segments(key).map_err(Refusal::Refused)?;
    // Stage 3: the value.
    let value = parse_value(value_text);
    Ok(Parsed { segments, value })
}

/// Stage 1 of the module doc: `KEY=VALUE` split at the first `=`, both trimmed,
/// the key not empty.
fn key_value(arg: &str) -> Result<(&str, &str), Refusal> {
    let example = "e.g. contacts.K1.friction=0.2";
    let Some((key, value_text)) = arg.split_once('=') else {
        return Err(Refusal::NotKeyValue(format!(
            "expected KEY=VALUE ({example})"
        )));
    };
    let (key, value_text) = (key.trim(), value_text.trim());
    if key.is_empty() {
        return Err(Refusal::Refused(format!(
            "empty key; expected KEY=VALUE ({example})"
        )));
    }
    Ok((key, value_text))
}

/// Stages 4 and 5 of the module doc for one parsed override; `Ok` the reader's
/// key path.
fn apply_one(table: &mut Table, parsed: &Parsed) -> Result<String, Refusal> {
    // Stage 4: resolve against the schema and the file.
    let (steps, key_path) = resolve(table, &parsed.segments).map_err(Refusal::Refused)?;
    // Stage 5: write, creating the omitted tables.
    write(table, &steps, parsed.value.clone());
    Ok(key_path)
}

/// `contacts[0].friction` and `contacts.0.friction` both give `contacts`, `0`,
/// `friction`.
fn segments(key: &str) -> Result<Vec<String>, String> {
    let mut out = Vec::new();
    for part in key.split('.') {
        let (head, mut rest) = match part.find('[') {
            Some(at) => (&part[..at], &part[at..]),
            None => (part, ""),
        };
        if head.trim().is_empty() {
            return Err(format!(
                "malformed key `{key}`: an empty segment (keys are joined by single dots, e.g. contacts.K1.friction)"
            ));
        }
        out.push(head.trim().to_string());
        while !rest.is_empty() {
            let inner = rest
                .strip_prefix('[')
                .and_then(|r| r.split_once(']'))
                .filter(|(index, _)| !index.trim().is_empty());
            let Some((index, after)) = inner else {
                return Err(format!(
                    "malformed key `{key}`: expected `[INDEX]` after `{head}` (e.g. contacts[0].friction)"
                ));
            };
            out.push(index.trim().to_string());
            rest = after;
        }
    }
    Ok(out)
}

/// `VALUE` as a TOML value, or as a string when it is not TOML (`cw`, `K3`).
fn parse_value(text: &str) -> Value {
    Value::deserialize(toml::de::ValueDeserializer::new(text))
        .unwrap_or_else(|_| Value::String(text.to_string()))
}

/// The key path shown in messages: the segments the user wrote, joined by dots.
fn shown(segments: &[String]) -> String {
    cut(&segments.join("."), MAX_QUOTED)
}

/// Walks the schema and the file (without changing it) to the key `segments` name.
/// `Ok`: the steps to write and the reader's key path.
fn resolve(table: &Table, segments: &[String]) -> Result<(Vec<Step>, String), String> {
    let mut keys: &[(&str, Node)] = SCHEMA;
    // The file's table at this point; `None` where the file omits it.
    let mut here: Option<&Table> = Some(table);
    let mut steps = Vec::new();
    let mut key_path = String::new();
    let mut i = 0;
    loop {
        let segment = &segments[i];
        let last = i + 1 == segments.len();
        let Some((name, node)) = keys.iter().find(|(k, _)| *k == segment.as_str()) else {
            return Err(unknown_key(&segments[..i], segment, keys));
        };
        if !key_path.is_empty() {
            key_path.push('.');
        }
        key_path.push_str(name);
        steps.push(Step::Key(name.to_string()));
        let held = here.and_then(|t| t.get(*name));
        match node {
            Node::Value if last => return Ok((steps, key_path)),
            Node::Value => {
                return Err(format!(
                    "`{}` is a value, not a table: nothing can be set below it",
                    shown(&segments[..=i])
                ));
            }
            Node::Table(inner) => {
                if last {
                    return Err(format!(
                        "`{}` is a table; --set sets one key in it (keys: {})",
                        shown(&segments[..=i]),
                        names(inner)
                    ));
                }
                here = match held {
                    None => None,
                    Some(Value::Table(t)) => Some(t),
                    Some(_) => {
                        return Err(format!(
                            "cannot set below `{}`: in the file it is not a table",
                            shown(&segments[..=i])
                        ));
                    }
                };
                keys = inner;
                i += 1;
            }
            Node::Array {
                noun,
                default_prefix,
                keys: inner,
            } => {
                let Some(selector) = segments.get(i + 1) else {
                    return Err(format!(
                        "`{name}` is an array of tables; name one {noun} and a key, e.g. {name}.{default_prefix}1.{}=...",
                        inner[1].0
                    ));
                };
                let elements = match held {
                    None => &[][..],
                    Some(Value::Array(a)) => a.as_slice(),
                    Some(_) => {
                        return Err(format!(
                            "cannot set in `{name}`: in the file it is not an array of tables [[{name}]]"
                        ));
                    }
                };
                let index = find_element(elements, selector, default_prefix)
                    .ok_or_else(|| no_element(name, noun, selector, elements, default_prefix))?;
                let Some(Value::Table(element)) = elements.get(index) else {
                    return Err(format!(
                        "cannot set in `{name}[{index}]`: in the file it is not a table"
                    ));
                };
                if i + 2 == segments.len() {
                    return Err(format!(
                        "`{}` names a {noun}, not a key; add one of its keys ({})",
                        shown(&segments[..=i + 1]),
                        names(inner)
                    ));
                }
                key_path.push_str(&format!("[{index}]"));
                steps.push(Step::Element(index));
                here = Some(element);
                keys = inner;
                i += 2;
            }
        }
    }
}

/// The index of the element named `selector` (its `name`, or its default name when
/// it has none), else of the element numbered `selector` from 0.
fn find_element(elements: &[Value], selector: &str, default_prefix: &str) -> Option<usize> {
    let by_name = elements
        .iter()
        .enumerate()
        .position(|(i, e)| element_name(e, i, default_prefix).as_deref() == Some(selector));
    by_name.or_else(|| {
        selector
            .parse::<usize>()
            .ok()
            .filter(|i| *i < elements.len())
    })
}

/// The name of element `i`: its `name` string, or `{prefix}{i+1}` without one.
fn element_name(element: &Value, i: usize, default_prefix: &str) -> Option<String> {
    match element.get("name") {
        Some(Value::String(s)) => Some(s.clone()),
        Some(_) => None,
        None => Some(format!("{default_prefix}{}", i + 1)),
    }
}

/// "no contact named K9 (contacts: K1, K2)".
fn no_element(
    array: &str,
    noun: &str,
    selector: &str,
    elements: &[Value],
    default_prefix: &str,
) -> String {
    let selector = cut(selector, MAX_QUOTED);
    if elements.is_empty() {
        return format!("no {noun} named {selector}: the file has no [[{array}]] tables");
    }
    let list = elements
        .iter()
        .enumerate()
        .map(|(i, e)| {
            element_name(e, i, default_prefix)
                .map_or_else(|| format!("[{i}]"), |n| cut(&n, MAX_QUOTED))
        })
        .collect::<Vec<_>>()
        .join(", ");
    if selector.parse::<usize>().is_ok() {
        format!(
            "no {array}[{selector}]: the file has {} [[{array}]] tables, numbered from 0 ({array}: {list})",
            elements.len()
        )
    } else {
        format!("no {noun} named {selector} ({array}: {list})")
    }
}

/// "unknown key `frction` in contacts.K1; did you mean `friction`? (allowed: ...)".
fn unknown_key(parent: &[String], key: &str, keys: &[(&str, Node)]) -> String {
    let known: Vec<&str> = keys.iter().map(|(k, _)| *k).collect();
    let place = if parent.is_empty() {
        "at the top level".to_string()
    } else {
        format!("in {}", shown(parent))
    };
    let hint = match suggest(key, &known) {
        Some(near) => format!("; did you mean `{near}`?"),
        None => String::new(),
    };
    format!(
        "unknown key `{}` {place}{hint} (allowed: {})",
        cut(key, MAX_QUOTED),
        known.join(", ")
    )
}

/// The keys of a table, for messages.
fn names(keys: &[(&str, Node)]) -> String {
    keys.iter().map(|(k, _)| *k).collect::<Vec<_>>().join(", ")
}

/// Writes `value` at `steps` (already resolved: every table on the way is a table
/// or absent, every element exists), creating the absent tables.
fn write(table: &mut Table, steps: &[Step], value: Value) {
    let Some((last, path)) = steps.split_last() else {
        return;
    };
    let mut here = table;
    let mut i = 0;
    while i < path.len() {
        let Step::Key(key) = &path[i] else {
            return;
        };
        let entry = here
            .entry(key.clone())
            .or_insert_with(|| Value::Table(Table::new()));
        here = match (entry, path.get(i + 1)) {
            (Value::Array(items), Some(Step::Element(index))) => {
                i += 1;
                match items.get_mut(*index) {
                    Some(Value::Table(t)) => t,
                    _ => return,
                }
            }
            (Value::Table(t), _) => t,
            _ => return,
        };
        i += 1;
    }
    if let Step::Key(key) = last {
        here.insert(key.clone(), value);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file() -> Table {
        toml::from_str(
            "[platform]\nmass = 2.0\n[[contacts]]\nname = \"K1\"\nfriction = 0.4\n[[contacts]]\nfriction = 0.4\n",
        )
        .unwrap()
    }

    /// A refused override is said where it was given: on the command line as
    /// `--set KEY=VALUE`, in a file at its entry with the argument quoted; only
    /// one without `=` is refused without the machine file.
    #[test]
    fn a_refusal_is_said_where_the_override_was_given() {
        let given = |arg: &str, i: usize| {
            Override::new(
                arg.to_string(),
                Origin::Entry {
                    file: "s.toml".to_string(),
                    key_path: format!("set[{i}]"),
                },
            )
        };
        let overrides = [
            given("platform.mass=3", 0),
            given("contacts.K9.friction=0.2", 1),
        ];
        let (applied, problems) = apply(&mut file(), &overrides);
        assert_eq!(applied.len(), 1);
        assert_eq!(problems.len(), 1);
        assert_eq!(problems[0].file, "s.toml");
        assert_eq!(problems[0].location, Location::Key("set[1]".to_string()));
        assert!(
            problems[0]
                .message
                .starts_with("\"contacts.K9.friction=0.2\": no contact named K9"),
            "{}",
            problems[0].message
        );

        let command_line = Override::command_line(&["mass".to_string(), "=1".to_string()]);
        let (_, problems) = apply(&mut file(), &command_line);
        assert_eq!(problems[0].file, "--set mass");
        assert_eq!(problems[0].location, Location::File);
        let not_key_value = not_key_value(&command_line);
        assert_eq!(not_key_value.len(), 1, "only `mass` has no `=`");
        assert_eq!(not_key_value[0].file, "--set mass");
    }

    fn set(table: &mut Table, arg: &str) -> Result<String, String> {
        let (applied, problems) = apply(table, &Override::command_line(&[arg.to_string()]));
        match (applied.first(), problems.first()) {
            (Some(a), None) => Ok(a.key_path.clone()),
            (None, Some(p)) => Err(crate::input::error_line(p).trim_end().to_string()),
            _ => unreachable!(),
        }
    }

    #[test]
    fn values_parse_as_toml_or_stand_as_strings() {
        assert_eq!(parse_value("0.2"), Value::Float(0.2));
        assert_eq!(parse_value("3"), Value::Integer(3));
        assert_eq!(
            parse_value("[0,0.1]"),
            Value::Array(vec![Value::Integer(0), Value::Float(0.1)])
        );
        assert_eq!(parse_value("\"cw\""), Value::String("cw".into()));
        assert_eq!(parse_value("cw"), Value::String("cw".into()));
        assert_eq!(parse_value("true"), Value::Boolean(true));
        // Not one value: a string, so the reader says "must be a number".
        assert_eq!(parse_value("1\nx = 2"), Value::String("1\nx = 2".into()));
    }

    #[test]
    fn keys_split_at_dots_and_brackets() {
        assert_eq!(
            segments("contacts[0].friction").unwrap(),
            ["contacts", "0", "friction"]
        );
        assert_eq!(
            segments("rotors[1].motor.resistance").unwrap(),
            ["rotors", "1", "motor", "resistance"]
        );
        assert!(segments("contacts..friction").is_err());
        assert!(segments("contacts[0.friction").is_err());
        assert!(segments("contacts[].friction").is_err());
    }

    #[test]
    fn elements_by_name_default_name_and_index() {
        let mut t = file();
        assert_eq!(
            set(&mut t, "contacts.K1.friction=0.2").unwrap(),
            "contacts[0].friction"
        );
        assert_eq!(
            set(&mut t, "contacts.K2.friction=0.3").unwrap(),
            "contacts[1].friction"
        );
        assert_eq!(
            set(&mut t, "contacts.1.weight=2").unwrap(),
            "contacts[1].weight"
        );
        assert_eq!(
            set(&mut t, "contacts[0].weight=3").unwrap(),
            "contacts[0].weight"
        );
        let c = t["contacts"].as_array().unwrap();
        assert_eq!(c[0]["friction"], Value::Float(0.2));
        assert_eq!(c[1]["friction"], Value::Float(0.3));
        assert_eq!(c[1]["weight"], Value::Integer(2));
        assert_eq!(c[0]["weight"], Value::Integer(3));
    }

    #[test]
    fn omitted_tables_are_created() {
        let mut t = file();
        set(&mut t, "simulation.t_end=2").unwrap();
        assert_eq!(t["simulation"]["t_end"], Value::Integer(2));
        set(&mut t, "contacts.K1.motor=1").unwrap_err();
        t.insert(
            "rotors".into(),
            toml::from_str::<Table>("[[r]]\nname = \"left\"\n").unwrap()["r"].clone(),
        );
        assert_eq!(
            set(&mut t, "rotors.left.motor.resistance=3").unwrap(),
            "rotors[0].motor.resistance"
        );
        assert_eq!(t["rotors"][0]["motor"]["resistance"], Value::Integer(3));
    }

    #[test]
    fn bad_paths_are_refused_with_the_reason() {
        let mut t = file();
        let e = set(&mut t, "contacts.K9.friction=0.2").unwrap_err();
        assert_eq!(
            e,
            "error: --set contacts.K9.friction=0.2: no contact named K9 (contacts: K1, K2)"
        );
        let e = set(&mut t, "contacts.5.friction=0.2").unwrap_err();
        assert!(
            e.contains("no contacts[5]: the file has 2 [[contacts]] tables"),
            "{e}"
        );
        let e = set(&mut t, "rotors.left.inertia=1").unwrap_err();
        assert!(
            e.contains("no rotor named left: the file has no [[rotors]] tables"),
            "{e}"
        );
        let e = set(&mut t, "platfrom.mass=1").unwrap_err();
        assert!(
            e.contains("unknown key `platfrom` at the top level; did you mean `platform`?"),
            "{e}"
        );
        let e = set(&mut t, "contacts.K1.frction=1").unwrap_err();
        assert!(
            e.contains("unknown key `frction` in contacts.K1; did you mean `friction`?"),
            "{e}"
        );
        let e = set(&mut t, "platform=1").unwrap_err();
        assert!(e.contains("`platform` is a table"), "{e}");
        let e = set(&mut t, "contacts.K1=1").unwrap_err();
        assert!(
            e.contains("`contacts.K1` names a contact, not a key"),
            "{e}"
        );
        let e = set(&mut t, "platform.mass.x=1").unwrap_err();
        assert!(e.contains("`platform.mass` is a value"), "{e}");
        let e = set(&mut t, "platform.mass").unwrap_err();
        assert_eq!(
            e,
            "error: --set platform.mass: expected KEY=VALUE (e.g. contacts.K1.friction=0.2)"
        );
        let e = set(&mut t, "=1").unwrap_err();
        assert!(e.contains("empty key"), "{e}");
        // Nothing refused changed the file.
        assert_eq!(t, file());
    }

    #[test]
    fn every_schema_key_is_listed() {
        let paths = key_paths();
        assert!(paths.contains(&"contacts.NAME.friction".to_string()));
        assert!(paths.contains(&"rotors.NAME.motor.current_limit".to_string()));
        assert!(paths.contains(&"simulation.seed".to_string()));
        assert!(paths.contains(&"simulation.rtol".to_string()));
        assert!(paths.contains(&"simulation.max_tilt".to_string()));
        assert!(paths.contains(&"simulation.progress_budget".to_string()));
        assert!(paths.contains(&"joints.NAME.stiffness".to_string()));
        assert!(paths.contains(&"bodies.NAME.mass".to_string()));
        // fundament, platform, bodies, joints, contacts, rotors (with their motor),
        // motor, drive, sensors, controller, impact, simulation.
        assert_eq!(
            paths.len(),
            3 + 6 + 7 + 7 + 9 + 9 + 6 + 6 + 3 + 3 + 3 + 1 + 6
        );
    }
}
