//! Machine-configuration sweeps (`vcnc sweep`, `vcnc sweep-merge`): numeric machine-file keys
//! set by their dotted path (`axes.X.controller.kv`), value lists and ranges, the cartesian
//! product, deterministic shards of it, and the engine that runs configurations in parallel and
//! hands back typed rows in configuration order.
//!
//! Each configuration is the machine document with its keys set and checked again, so unknown
//! keys and impossible or unstable configurations become that row's error, not the sweep's. The
//! reference run (and the identified models' contour errors, with `--model`) is shared by every
//! configuration unless a key changes it (interpolation limits, kinematics, dialect).

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::Serialize;
use vcnc_machine::{Machine, MachineDocument, MachineModels};

use crate::predict::{PredictOptions, predict};
use crate::run::{Measured, Run, prepare};
use crate::sink::Discard;
use crate::source::Source;
use crate::{Error, format_num};

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
pub fn parse_set(arg: &str) -> Result<SweepKey, Error> {
    let bad = |expected: String| Error::Argument {
        option: "--set",
        value: arg.to_string(),
        expected,
    };
    let (key, values) = arg
        .split_once('=')
        .ok_or_else(|| bad("KEY=V1,V2,... or KEY=start:stop:count".into()))?;
    let key = key.trim();
    if key.is_empty() || key.split('.').any(str::is_empty) {
        return Err(bad(
            "a dotted machine-file path as the key, such as axes.X.controller.kv".into(),
        ));
    }
    let num = |s: &str| -> Result<f64, Error> {
        match s.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(bad(format!("a finite number instead of '{}'", s.trim()))),
        }
    };
    let values = if values.contains(':') {
        let parts: Vec<&str> = values.split(':').collect();
        if parts.len() != 3 {
            return Err(bad("a range as start:stop:count".into()));
        }
        let (a, b) = (num(parts[0])?, num(parts[1])?);
        let count = match parts[2].trim().parse::<usize>() {
            Ok(c) if (1..=1_000_000).contains(&c) => c,
            _ => {
                return Err(bad(format!(
                    "a count of 1 ..= 1000000 values instead of '{}'",
                    parts[2].trim()
                )));
            }
        };
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
        return Err(bad("at least one value".into()));
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
pub fn parse_shard(s: &str) -> Result<(usize, usize), Error> {
    let bad = || Error::Argument {
        option: "--shard",
        value: s.to_string(),
        expected: "i/n with whole numbers 1 <= i <= n, e.g. 2/8".into(),
    };
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let whole = |v: &str| v.trim().parse::<usize>().map_err(|_| bad());
    let (i, n) = (whole(i)?, whole(n)?);
    if n == 0 || i == 0 || i > n {
        return Err(bad());
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

/// Keys whose change alters the reference run (interpolation limits, kinematics, dialect).
pub fn changes_reference(key: &str) -> bool {
    let k = key.split('.').collect::<Vec<_>>();
    match k.as_slice() {
        ["sample_period_s"] | ["trajectory", ..] | ["kinematics", ..] | ["gcode", ..] => true,
        ["axes", _, leaf] => matches!(*leaf, "travel" | "max_velocity" | "max_acceleration"),
        _ => false,
    }
}

/// Largest number of configurations of one sweep.
pub const MAX_CONFIGURATIONS: usize = 10_000_000;

/// One configuration's figures.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigResult {
    /// Per machine axis: tracking error max and RMS of the encoder position, µm or mdeg.
    pub tracking: Vec<(f64, f64)>,
    /// Tool-tip contour error with the true drives, max, µm.
    pub contour_max_um: f64,
    /// Tool-tip contour error with the true drives, RMS, µm.
    pub contour_rms_um: f64,
    /// Orientation contour error, max, mrad.
    pub orientation_max_mrad: f64,
    /// Orientation contour error, RMS, mrad.
    pub orientation_rms_mrad: f64,
    /// With models: predicted contour max and RMS and max |predicted − true|, µm.
    pub predicted: Option<(f64, f64, f64)>,
}

/// One row of a sweep: the configuration and its figures or its error.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRow {
    /// Configuration index in the product.
    pub index: usize,
    /// The swept keys' values.
    pub values: Vec<f64>,
    /// Figures, or the configuration's error message.
    pub result: Result<ConfigResult, String>,
}

/// The best configuration: the smallest true tool-tip contour error (max).
#[derive(Debug, Clone, PartialEq)]
pub struct Best {
    /// Configuration index.
    pub index: usize,
    /// The keys' values.
    pub values: Vec<f64>,
    /// Its contour error, µm.
    pub contour_max_um: f64,
}

/// A sweep ready to run: the base machine and run, the keys, the configurations of this shard.
pub struct Sweep<'a> {
    doc: &'a MachineDocument,
    base: Machine,
    program: &'a str,
    program_name: &'a str,
    keys: Vec<SweepKey>,
    total: usize,
    shard: Option<(usize, usize)>,
    indices: Vec<usize>,
    base_run: Run,
    reuse: bool,
    /// The identified models, with their stated actual-value latencies.
    models: Option<MachineModels>,
    /// The tools every configuration's `G43 H` reads (`--tool-table`).
    tools: Option<vcnc_gcode::ToolTable>,
    lenient: bool,
}

impl<'a> Sweep<'a> {
    /// Plans a sweep of `program` (its text and name) on the machine `doc` over `keys`
    /// (`--set` arguments), restricted to `shard` (`i/n`), with optional identified `models`
    /// (their positions advanced by their stated actual-value latencies, [`crate::latency`])
    /// and the `tools` of a tool table for every configuration. The base machine and run must
    /// be valid.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        doc: &'a MachineDocument,
        program: &'a str,
        program_name: &'a str,
        sets: &[String],
        shard: Option<&str>,
        models: Option<MachineModels>,
        tools: Option<vcnc_gcode::ToolTable>,
        lenient: bool,
    ) -> Result<Sweep<'a>, Error> {
        let mut base = doc.check()?;
        if let Some(t) = &tools {
            base.tools = t.clone();
        }
        let keys: Vec<SweepKey> = sets
            .iter()
            .map(|s| parse_set(s))
            .collect::<Result<_, _>>()?;
        let shard = shard.map(parse_shard).transpose()?;
        let total = product_len(&keys);
        if total > MAX_CONFIGURATIONS {
            return Err(Error::TooManyConfigurations {
                total,
                max: MAX_CONFIGURATIONS,
            });
        }
        let base_run = prepare(&base, program, program_name, lenient)?;
        let reuse = !keys.iter().any(|k| changes_reference(&k.key));
        Ok(Sweep {
            doc,
            base,
            program,
            program_name,
            indices: shard_indices(total, shard),
            keys,
            total,
            shard,
            base_run,
            reuse,
            models,
            tools,
            lenient,
        })
    }

    /// The base machine (checked).
    pub fn base(&self) -> &Machine {
        &self.base
    }

    /// The reference run of the base machine.
    pub fn base_run(&self) -> &Run {
        &self.base_run
    }

    /// The swept keys.
    pub fn keys(&self) -> &[SweepKey] {
        &self.keys
    }

    /// The configurations this sweep (shard) runs, in order.
    pub fn indices(&self) -> &[usize] {
        &self.indices
    }

    /// The column names of `sweep.csv`.
    pub fn header(&self) -> Vec<String> {
        let mut h = vec!["index".to_string()];
        h.extend(self.keys.iter().map(|k| k.key.clone()));
        for a in &self.base.axes {
            h.push(format!("{}_tracking_max", a.name));
            h.push(format!("{}_tracking_rms", a.name));
        }
        h.extend(
            [
                "contour_max_um",
                "contour_rms_um",
                "orientation_max_mrad",
                "orientation_rms_mrad",
            ]
            .map(String::from),
        );
        if self.models.is_some() {
            h.extend(
                [
                    "predicted_contour_max_um",
                    "predicted_contour_rms_um",
                    "discrepancy_max_um",
                ]
                .map(String::from),
            );
        }
        h.push("status".into());
        h
    }

    /// The CSV cells of a row (the header's columns).
    pub fn cells(&self, row: &SweepRow) -> Vec<String> {
        let mut cells = vec![row.index.to_string()];
        cells.extend(row.values.iter().map(|v| format_num(*v)));
        match &row.result {
            Ok(r) => {
                for (max, rms) in &r.tracking {
                    cells.push(format_num(*max));
                    cells.push(format_num(*rms));
                }
                cells.extend(
                    [
                        r.contour_max_um,
                        r.contour_rms_um,
                        r.orientation_max_mrad,
                        r.orientation_rms_mrad,
                    ]
                    .map(format_num),
                );
                if let Some((max, rms, disc)) = r.predicted {
                    cells.extend([max, rms, disc].map(format_num));
                }
                cells.push("ok".into());
            }
            Err(msg) => {
                let n = 2 * self.base.axes.len() + 4 + if self.models.is_some() { 3 } else { 0 };
                cells.extend(std::iter::repeat_n(String::new(), n));
                cells.push(csv_cell(&format!("error: {msg}")));
            }
        }
        cells
    }

    /// The configurations of the shard whose machine cannot be built (checked without running
    /// anything), as `(index, error)`, in configuration order.
    pub fn unbuildable(&self) -> Vec<(usize, String)> {
        self.indices
            .par_iter()
            .filter_map(|&index| {
                self.machine_of(&configuration(&self.keys, index))
                    .err()
                    .map(|e| (index, e.to_string().replace(['\n', '\r'], " ")))
            })
            .collect()
    }

    /// An error naming the configurations that cannot be built ([`Sweep::unbuildable`]), if any.
    pub fn check_buildable(&self) -> Result<(), Error> {
        let bad = self.unbuildable();
        let Some((first_index, first)) = bad.first().cloned() else {
            return Ok(());
        };
        let first_set = self
            .keys
            .iter()
            .zip(configuration(&self.keys, first_index))
            .map(|(k, v)| format!("{}={v}", k.key))
            .collect::<Vec<_>>()
            .join(" ");
        Err(Error::InvalidConfigurations {
            count: bad.len(),
            total: self.indices.len(),
            first_index,
            first_set,
            first,
        })
    }

    /// Runs configuration `index`.
    pub fn run_config(&self, index: usize) -> SweepRow {
        let values = configuration(&self.keys, index);
        let result = self
            .evaluate(&values)
            .map_err(|e| e.to_string().replace(['\n', '\r'], " "));
        SweepRow {
            index,
            values,
            result,
        }
    }

    /// The machine of one configuration: the document with the swept `values`, checked.
    fn machine_of(&self, values: &[f64]) -> Result<Machine, Error> {
        let set: Vec<(&str, f64)> = self
            .keys
            .iter()
            .zip(values)
            .map(|(k, v)| (k.key.as_str(), *v))
            .collect();
        Ok(self.doc.with_values(&set)?)
    }

    fn evaluate(&self, values: &[f64]) -> Result<ConfigResult, Error> {
        let mut machine = self.machine_of(values)?;
        if let Some(t) = &self.tools {
            machine.tools = t.clone();
        }
        let owned;
        let run = if self.reuse {
            &self.base_run
        } else {
            owned = prepare(&machine, self.program, self.program_name, self.lenient)?;
            &owned
        };
        // The statistics cover the feed moves (what is cut), as `vcnc predict`'s do; the
        // tracking errors every sample.
        let sets: Vec<&MachineModels> = self.models.iter().collect();
        let opts = PredictOptions {
            measured: Measured::Feed,
            tracking: true,
        };
        let out = predict(&machine, Source::Prepared(run), &sets, &opts, &mut Discard)?;
        let (max, rms) = out.truth;
        Ok(ConfigResult {
            tracking: out.tracking,
            contour_max_um: max.tip_um,
            contour_rms_um: rms.tip_um,
            orientation_max_mrad: max.orientation_mrad,
            orientation_rms_mrad: rms.orientation_mrad,
            predicted: out.figures.first().map(|f| {
                (
                    f.predicted_max.tip_um,
                    f.predicted_rms.tip_um,
                    f.discrepancy_max.tip_um,
                )
            }),
        })
    }

    /// Runs every configuration of the shard, `chunk` at a time in parallel; hands each chunk's
    /// rows, in configuration order, to `on_chunk` (which writes them) and calls `progress`
    /// once per configuration. Same rows for any thread count.
    pub fn run(
        &self,
        chunk: usize,
        progress: &(dyn Fn() + Sync),
        mut on_chunk: impl FnMut(&[SweepRow]) -> std::io::Result<()>,
    ) -> Result<SweepOutcome, SweepRunError> {
        let mut outcome = SweepOutcome::default();
        for part in self.indices.chunks(chunk.max(1)) {
            let rows: Vec<SweepRow> = part
                .par_iter()
                .map(|&i| {
                    let r = self.run_config(i);
                    progress();
                    r
                })
                .collect();
            on_chunk(&rows).map_err(SweepRunError::Write)?;
            for r in rows {
                outcome.add(r);
            }
        }
        Ok(outcome)
    }

    /// The summary of a finished run.
    pub fn summary(&self, outcome: &SweepOutcome) -> SweepSummary {
        SweepSummary {
            keys: self
                .keys
                .iter()
                .map(|k| KeySummary {
                    key: k.key.clone(),
                    values: k.values.clone(),
                })
                .collect(),
            configurations: self.total,
            shard: self.shard.map(|(i, n)| format!("{i}/{n}")),
            ok: outcome.ok,
            failed: outcome.failed,
            best: outcome
                .best
                .as_ref()
                .map(|b| BestSummary::of(b, &self.keys)),
            criterion: CRITERION,
        }
    }
}

/// A sweep could not write its rows.
#[derive(Debug, thiserror::Error)]
pub enum SweepRunError {
    /// Writing a chunk failed.
    #[error("cannot write the sweep table: {0}")]
    Write(std::io::Error),
}

/// What a finished sweep (or merge) found.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SweepOutcome {
    /// Configurations that ran.
    pub ok: usize,
    /// Configurations that failed.
    pub failed: usize,
    /// The first failure's message.
    pub first_error: Option<String>,
    /// The best configuration.
    pub best: Option<Best>,
    /// `(values, contour max µm)` of every configuration that ran, for plots.
    pub points: Vec<(Vec<f64>, f64)>,
}

impl SweepOutcome {
    fn add(&mut self, r: SweepRow) {
        match r.result {
            Ok(c) => {
                self.ok += 1;
                let c = c.contour_max_um;
                if self.best.as_ref().is_none_or(|b| c < b.contour_max_um) {
                    self.best = Some(Best {
                        index: r.index,
                        values: r.values.clone(),
                        contour_max_um: c,
                    });
                }
                self.points.push((r.values, c));
            }
            Err(e) => {
                self.failed += 1;
                self.first_error.get_or_insert(e);
            }
        }
    }

    /// An error when configurations ran and every one failed (a sweep that measured nothing).
    pub fn check_any_ok(&self) -> Result<(), Error> {
        if self.ok == 0 && self.failed > 0 {
            return Err(Error::SweepFailed {
                configurations: self.failed,
                first: self.first_error.clone().unwrap_or_default(),
            });
        }
        Ok(())
    }
}

fn csv_cell(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\"").replace(['\n', '\r'], " "))
    } else {
        s.to_string()
    }
}

const CRITERION: &str = "smallest tool-tip contour error (max) with the true drives";

/// A swept key in the summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KeySummary {
    /// Dotted key.
    pub key: String,
    /// Its values.
    pub values: Vec<f64>,
}

/// The best configuration in a summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BestSummary {
    /// Configuration index.
    pub index: usize,
    /// Key → value.
    pub values: BTreeMap<String, f64>,
    /// Its tool-tip contour error (max), µm.
    pub contour_max_um: f64,
}

impl BestSummary {
    fn of(b: &Best, keys: &[SweepKey]) -> BestSummary {
        BestSummary {
            index: b.index,
            values: keys
                .iter()
                .zip(&b.values)
                .map(|(k, v)| (k.key.clone(), *v))
                .collect(),
            contour_max_um: b.contour_max_um,
        }
    }
}

/// `summary.json` of `vcnc sweep`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepSummary {
    /// The swept keys and values.
    pub keys: Vec<KeySummary>,
    /// Configurations of the whole product.
    pub configurations: usize,
    /// `i/n` when sharded.
    pub shard: Option<String>,
    /// Configurations that ran.
    pub ok: usize,
    /// Configurations that failed.
    pub failed: usize,
    /// The best configuration.
    pub best: Option<BestSummary>,
    /// How "best" is judged.
    pub criterion: &'static str,
}

/// `sweep-merge`'s result: the joined table and what it holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Merged {
    /// The joined `sweep.csv` text (header and rows in index order).
    pub text: String,
    /// The swept keys' names (from the header).
    pub keys: Vec<String>,
    /// Rows, ok/failed counts, best and plot points.
    pub outcome: SweepOutcome,
    /// Rows in the joined table.
    pub rows: usize,
}

/// `summary.json` of `vcnc sweep-merge`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MergeSummary {
    /// The shard folders.
    pub merged_from: Vec<String>,
    /// Rows in the joined table.
    pub configurations: usize,
    /// Rows that ran.
    pub ok: usize,
    /// Rows that failed.
    pub failed: usize,
    /// The best configuration.
    pub best: Option<BestSummary>,
}

/// Joins shard tables `(path, text)` with the same header into one table in index order; a
/// configuration in two shards is an error.
pub fn merge(tables: &[(String, String)]) -> Result<Merged, Error> {
    let mut header: Option<&str> = None;
    let mut rows: Vec<(usize, &str)> = Vec::new();
    for (path, text) in tables {
        let mut lines = text.lines();
        let h = lines.next().ok_or_else(|| Error::Shard {
            file: path.clone(),
            problem: "the file is empty",
        })?;
        match header {
            None => header = Some(h),
            Some(prev) if prev != h => {
                return Err(Error::Shard {
                    file: path.clone(),
                    problem: "its columns differ from the first shard's",
                });
            }
            _ => {}
        }
        for (n, line) in lines.enumerate() {
            if line.is_empty() {
                continue;
            }
            let idx: usize = line
                .split(',')
                .next()
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| Error::Table {
                    file: path.clone(),
                    line: n as u64 + 2,
                    message: "no configuration index".into(),
                })?;
            rows.push((idx, line));
        }
    }
    rows.sort_by_key(|r| r.0);
    if let Some(w) = rows.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(Error::DuplicateConfiguration { index: w[0].0 });
    }
    let header = header.ok_or(Error::NoShards)?;
    let cols: Vec<&str> = header.split(',').collect();
    // The swept keys are the columns between `index` and the first per-axis column.
    let nkeys = cols
        .iter()
        .skip(1)
        .position(|c| c.ends_with("_tracking_max"))
        .unwrap_or(0);
    let ci = cols.iter().position(|c| *c == "contour_max_um");
    let si = cols.iter().position(|c| *c == "status");
    let mut outcome = SweepOutcome::default();
    let mut text = format!("{header}\n");
    for (i, r) in &rows {
        text.push_str(r);
        text.push('\n');
        let cells: Vec<&str> = r.split(',').collect();
        let values: Vec<f64> = cells
            .iter()
            .skip(1)
            .take(nkeys)
            .map(|v| v.parse().unwrap_or(f64::NAN))
            .collect();
        let ok = si.and_then(|s| cells.get(s)).is_some_and(|s| *s == "ok");
        let c = ci
            .and_then(|c| cells.get(c))
            .and_then(|c| c.parse::<f64>().ok());
        let result = match (ok, c) {
            (true, Some(c)) => Ok(ConfigResult {
                tracking: Vec::new(),
                contour_max_um: c,
                contour_rms_um: f64::NAN,
                orientation_max_mrad: f64::NAN,
                orientation_rms_mrad: f64::NAN,
                predicted: None,
            }),
            _ => Err(r.to_string()),
        };
        outcome.add(SweepRow {
            index: *i,
            values,
            result,
        });
    }
    Ok(Merged {
        text,
        keys: cols[1..=nkeys].iter().map(|s| s.to_string()).collect(),
        rows: rows.len(),
        outcome,
    })
}

impl Merged {
    /// The summary of a merge of the shard folders `dirs`.
    pub fn summary(&self, dirs: Vec<String>) -> MergeSummary {
        let keys: Vec<SweepKey> = self
            .keys
            .iter()
            .map(|k| SweepKey {
                key: k.clone(),
                values: Vec::new(),
            })
            .collect();
        MergeSummary {
            merged_from: dirs,
            configurations: self.rows,
            ok: self.outcome.ok,
            failed: self.outcome.failed,
            best: self
                .outcome
                .best
                .as_ref()
                .map(|b| BestSummary::of(b, &keys)),
        }
    }
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
}
