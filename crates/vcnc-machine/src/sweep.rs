//! Machine-configuration sweeps: numeric machine-file keys set by their dotted path
//! (`axes.X.controller.kv`), value lists and ranges, the cartesian product, and deterministic
//! shards of it.

use crate::Error;

/// One swept key and its values.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepKey {
    /// Dotted machine-file path, e.g. `axes.X.controller.kv`.
    pub key: String,
    /// Values, in the order given.
    pub values: Vec<f64>,
}

/// Parses `KEY=V1,V2,...` or `KEY=start:stop:count` (count ≥ 2 values evenly spaced, both ends
/// included; count = 1 gives `start`).
pub fn parse_set(arg: &str) -> Result<SweepKey, String> {
    let (key, values) = arg
        .split_once('=')
        .ok_or_else(|| format!("--set {arg}: expected KEY=V1,V2,... or KEY=start:stop:count"))?;
    let key = key.trim();
    if key.is_empty() || key.split('.').any(str::is_empty) {
        return Err(format!(
            "--set {arg}: the key must be a dotted path such as axes.X.controller.kv"
        ));
    }
    let num = |s: &str| -> Result<f64, String> {
        let v: f64 = s
            .trim()
            .parse()
            .map_err(|_| format!("--set {arg}: '{}' is not a number", s.trim()))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("--set {arg}: '{}' is not finite", s.trim()))
        }
    };
    let values = if values.contains(':') {
        let parts: Vec<&str> = values.split(':').collect();
        if parts.len() != 3 {
            return Err(format!("--set {arg}: a range is start:stop:count"));
        }
        let (a, b) = (num(parts[0])?, num(parts[1])?);
        let count: usize = parts[2].trim().parse().map_err(|_| {
            format!(
                "--set {arg}: count '{}' is not a whole number",
                parts[2].trim()
            )
        })?;
        if count == 0 || count > 1_000_000 {
            return Err(format!(
                "--set {arg}: count must be 1 ..= 1000000, got {count}"
            ));
        }
        if count == 1 {
            vec![a]
        } else {
            (0..count)
                .map(|i| {
                    if i + 1 == count {
                        b
                    } else {
                        a + (b - a) * i as f64 / (count - 1) as f64
                    }
                })
                .collect()
        }
    } else {
        values.split(',').map(num).collect::<Result<Vec<_>, _>>()?
    };
    if values.is_empty() {
        return Err(format!("--set {arg}: no values"));
    }
    Ok(SweepKey {
        key: key.to_string(),
        values,
    })
}

/// Number of configurations of the product (saturating).
pub fn product_len(keys: &[SweepKey]) -> usize {
    keys.iter()
        .fold(1usize, |n, k| n.saturating_mul(k.values.len()))
}

/// The values of configuration `index` of the product (the last key varies fastest).
pub fn configuration(keys: &[SweepKey], mut index: usize) -> Vec<f64> {
    let mut out = vec![0.0; keys.len()];
    for (i, k) in keys.iter().enumerate().rev() {
        let n = k.values.len();
        out[i] = k.values[index % n];
        index /= n;
    }
    out
}

/// Parses `i/n` (1-based shard i of n).
pub fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let (i, n) = s
        .split_once('/')
        .ok_or_else(|| format!("--shard {s}: expected i/n, e.g. 2/8"))?;
    let i: usize = i
        .trim()
        .parse()
        .map_err(|_| format!("--shard {s}: '{i}' is not a whole number"))?;
    let n: usize = n
        .trim()
        .parse()
        .map_err(|_| format!("--shard {s}: '{n}' is not a whole number"))?;
    if n == 0 || i == 0 || i > n {
        return Err(format!("--shard {s}: need 1 <= i <= n"));
    }
    Ok((i, n))
}

/// The configuration indices of shard `i` of `n` (1-based): every index with
/// `index % n == i - 1`. Deterministic, and the shards partition the product.
pub fn shard_indices(total: usize, shard: Option<(usize, usize)>) -> Vec<usize> {
    match shard {
        None => (0..total).collect(),
        Some((i, n)) => (0..total).filter(|k| k % n == i - 1).collect(),
    }
}

/// Sets the numeric value at dotted `key` in a TOML table. The parent tables must exist; the
/// leaf may be new (the machine-file check then accepts or rejects it as an unknown key). An
/// existing non-numeric leaf is an error.
pub fn set_key(table: &mut toml::Table, key: &str, value: f64) -> Result<(), Error> {
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
    fn lists_and_ranges_parse() {
        let k = parse_set("axes.X.controller.kv=10,20.5,3e1").unwrap();
        assert_eq!(k.key, "axes.X.controller.kv");
        assert_eq!(k.values, vec![10.0, 20.5, 30.0]);
        let r = parse_set("a.b=0:1:5").unwrap();
        assert_eq!(r.values, vec![0.0, 0.25, 0.5, 0.75, 1.0]);
        assert!(parse_set("a.b=1,x").is_err());
        assert!(parse_set("a.b=0:1").is_err());
        assert!(parse_set("=1").is_err());
        assert!(parse_set("a..b=1").is_err());
        assert!(parse_set("a.b=nan").is_err());
    }

    #[test]
    fn product_enumerates_every_combination_once() {
        let keys = vec![
            SweepKey {
                key: "a".into(),
                values: vec![1.0, 2.0],
            },
            SweepKey {
                key: "b".into(),
                values: vec![10.0, 20.0, 30.0],
            },
        ];
        assert_eq!(product_len(&keys), 6);
        let all: Vec<Vec<f64>> = (0..6).map(|i| configuration(&keys, i)).collect();
        assert_eq!(all[0], vec![1.0, 10.0]);
        assert_eq!(all[5], vec![2.0, 30.0]);
        let mut sorted = all.clone();
        sorted.sort_by(|x, y| x.partial_cmp(y).unwrap());
        sorted.dedup();
        assert_eq!(sorted.len(), 6);
    }

    #[test]
    fn shards_partition_the_product() {
        let mut seen = vec![0; 100];
        for i in 1..=3 {
            for k in shard_indices(100, Some((i, 3))) {
                seen[k] += 1;
            }
        }
        assert!(seen.iter().all(|&c| c == 1));
        assert!(parse_shard("0/3").is_err());
        assert!(parse_shard("4/3").is_err());
        assert_eq!(parse_shard("2/3").unwrap(), (2, 3));
    }

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
