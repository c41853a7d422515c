//! Numeric machine-file keys set by their dotted path (`axes.X.controller.kv`), for sweeps
//! ([`crate::MachineDocument::with_values`]).

use crate::Error;

/// Sets the numeric value at dotted `key` in a TOML table. The parent tables must exist; the
/// leaf may be new (the machine-file check then accepts or rejects it as an unknown key). An
/// existing non-numeric leaf is an error.
pub(crate) fn set_key(table: &mut toml::Table, key: &str, value: f64) -> Result<(), Error> {
    let parts: Vec<&str> = key.split('.').collect();
    let unknown = |at: &str| Error::Invalid {
        file: String::new(),
        at: None,
        key: key.to_string(),
        message: format!("unknown key {key}: no table '{at}' in the machine file"),
    };
    let (leaf, parents) = parts.split_last().ok_or_else(|| unknown(key))?;
    let mut t = table;
    let mut path = String::new();
    for p in parents {
        if !path.is_empty() {
            path.push('.');
        }
        path.push_str(p);
        t = match t.get_mut(*p) {
            Some(toml::Value::Table(inner)) => inner,
            _ => return Err(unknown(&path)),
        };
    }
    match t.get(*leaf) {
        None | Some(toml::Value::Float(_)) => {
            t.insert((*leaf).to_string(), toml::Value::Float(value));
        }
        Some(toml::Value::Integer(_)) => {
            if value.fract() == 0.0 && value.abs() < 9.0e15 {
                t.insert((*leaf).to_string(), toml::Value::Integer(value as i64));
            } else {
                t.insert((*leaf).to_string(), toml::Value::Float(value));
            }
        }
        Some(other) => {
            return Err(Error::Invalid {
                file: String::new(),
                at: None,
                key: key.to_string(),
                message: format!("key {key} is a {}, not a number", other.type_str()),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_set_by_dotted_path() {
        let mut t: toml::Table =
            toml::from_str("[axes.X.plant]\nj = 0.01\n[axes.X]\nunit = \"mm\"\n").unwrap();
        set_key(&mut t, "axes.X.plant.j", 0.02).unwrap();
        assert_eq!(t["axes"]["X"]["plant"]["j"].as_float(), Some(0.02));
        assert!(set_key(&mut t, "axes.Q.plant.j", 1.0).is_err());
        assert!(set_key(&mut t, "axes.X.unit", 1.0).is_err());
    }
}
