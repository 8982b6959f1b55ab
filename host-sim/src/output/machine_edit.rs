//! A machine file with some numbers changed and everything else kept: its
//! comments, spacing and order, as a person wrote them (`calibrate --write`,
//! `device identify --write`).

use std::path::Path;

use toml_edit::{DocumentMut, Item, Table};

use crate::machine::{input, Machine};

/// The machine file `text` (read from `path`) with each `(key path, value)` of
/// `values` set ([`set_value`]), checked to read back with exactly those values
/// as the file `out` (whose directory a relative tuning table is resolved
/// against). `Err`: why not, for an internal error's message.
pub fn with_values(
    path: &Path,
    text: &str,
    values: &[(String, f64)],
    out: &Path,
) -> Result<String, String> {
    let mut doc: DocumentMut = text
        .parse()
        .map_err(|e| format!("{} does not parse again: {e}", path.display()))?;
    for (key_path, x) in values {
        set_value(doc.as_table_mut(), key_path, *x).map_err(|why| format!("{key_path}: {why}"))?;
    }
    let written = doc.to_string();
    let name = out.display().to_string();
    let dir = out.parent().unwrap_or(Path::new(""));
    let numbers = Machine::numbers(&name, &written, dir, &[]).map_err(|p| {
        format!(
            "the file written does not read back: {}",
            input::render(&p).trim_end()
        )
    })?;
    for (key_path, x) in values {
        if !numbers
            .iter()
            .any(|n| n.key_path == *key_path && n.value == *x)
        {
            return Err(format!("{key_path} does not read back as {x}"));
        }
    }
    Ok(written)
}

/// Sets the key at the reader's key path `key_path` (`contacts[0].restitution`) of
/// `root` to `x`, keeping the old value's comment and spacing; creates the key
/// (and a missing table on the way) when the file gives none.
pub fn set_value(root: &mut Table, key_path: &str, x: f64) -> Result<(), String> {
    let segments: Vec<&str> = key_path.split('.').collect();
    let Some((last, path)) = segments.split_last() else {
        return Err("an empty key path".into());
    };
    let mut here: &mut dyn toml_edit::TableLike = root;
    for seg in path {
        let (name, index) = match seg.split_once('[') {
            Some((n, i)) => (n, i.trim_end_matches(']').parse::<usize>().ok()),
            None => (*seg, None),
        };
        if here.get(name).is_none() {
            here.insert(name, Item::Table(Table::new()));
        }
        let item = here.get_mut(name).ok_or("a table vanished")?;
        here = match index {
            Some(i) => item
                .as_array_of_tables_mut()
                .and_then(|a| a.get_mut(i))
                .map(|t| t as &mut dyn toml_edit::TableLike)
                .ok_or_else(|| format!("{name}[{i}] is not a table of an array"))?,
            None => item
                .as_table_like_mut()
                .ok_or_else(|| format!("{name} is not a table"))?,
        };
    }
    match here.get_mut(last).and_then(Item::as_value_mut) {
        Some(v) => {
            let decor = v.decor().clone();
            *v = number(x);
            *v.decor_mut() = decor;
        }
        None => {
            here.insert(last, Item::Value(number(x)));
        }
    }
    Ok(())
}

/// `x` as a TOML number in the shortest form that reads back as `x`: with an
/// exponent below 1e-3 and from 1e6 (`6e-6`, as a person writes an inertia),
/// plainly between (`0.41`, `2.25`).
fn number(x: f64) -> toml_edit::Value {
    let magnitude = x.abs();
    let text = if x != 0.0 && x.is_finite() && !(1e-3..1e6).contains(&magnitude) {
        format!("{x:e}")
    } else {
        return toml_edit::Value::from(x);
    };
    text.parse().unwrap_or_else(|_| toml_edit::Value::from(x))
}

#[cfg(test)]
mod tests {
    use super::*;
    use toml_edit::DocumentMut;

    #[test]
    fn values_change_and_nothing_else() {
        let text = "# top\n[[contacts]]\nname = \"K1\"\nrestitution = 0.3   # guess\n\n[[contacts]]\nrestitution = 0.3\n[motor]\nresistance = 2 # ohm\n";
        let mut doc: DocumentMut = text.parse().unwrap();
        set_value(doc.as_table_mut(), "contacts[1].restitution", 0.41).unwrap();
        set_value(doc.as_table_mut(), "motor.resistance", 2.25).unwrap();
        set_value(doc.as_table_mut(), "contacts[0].friction", 0.5).unwrap();
        set_value(doc.as_table_mut(), "simulation.rtol", 1e-3).unwrap();
        assert_eq!(
            doc.to_string(),
            "# top\n[[contacts]]\nname = \"K1\"\nrestitution = 0.3   # guess\nfriction = 0.5\n\n[[contacts]]\nrestitution = 0.41\n[motor]\nresistance = 2.25 # ohm\n\n[simulation]\nrtol = 0.001\n"
        );
    }

    /// A rotor's own motor table is made where the file has none, after its
    /// rotor's keys.
    #[test]
    fn a_rotor_gets_its_own_motor() {
        let text = "[[rotors]]\nname = \"left\"\ninertia = 6e-6 # kg m^2\n\n[[rotors]]\nname = \"right\"\n\n[motor]\nresistance = 2.0\n";
        let mut doc: DocumentMut = text.parse().unwrap();
        set_value(doc.as_table_mut(), "rotors[0].inertia", 7e-6).unwrap();
        set_value(doc.as_table_mut(), "rotors[1].motor.resistance", 2.5).unwrap();
        assert_eq!(
            doc.to_string(),
            "[[rotors]]\nname = \"left\"\ninertia = 7e-6 # kg m^2\n\n[[rotors]]\nname = \"right\"\n\n[rotors.motor]\nresistance = 2.5\n\n[motor]\nresistance = 2.0\n"
        );
    }
}
