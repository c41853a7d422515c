//! Summary objects (docs/cli.md keys), plain-text tables, and the loaders shared by commands.

use std::path::Path;

use anyhow::{Context, Result};
use serde_json::{Value, json};
use vcnc_drive::ClosedLoopModel;
use vcnc_identify::FitMetrics;
use vcnc_machine::pipeline::{self, Run};
use vcnc_machine::{Machine, ModelSet, Unit};

/// A model object: `a1 a2 a3 b0 b1 b2 dc p_hz wn_hz zeta stable` (and the roots when the model
/// cannot be written as (p, ωn, ζ)).
pub fn model_json(m: &ClosedLoopModel) -> Value {
    let poles = m.poles();
    let mut v = json!({
        "a1": m.a1, "a2": m.a2, "a3": m.a3,
        "b0": m.b0, "b1": m.b1, "b2": m.b2, "dc": m.dc,
        "p_hz": poles.map(|p| p.p_hz()),
        "wn_hz": poles.map(|p| p.wn_hz()),
        "zeta": poles.map(|p| p.zeta),
        "stable": m.is_stable(),
    });
    if !m.is_stable() {
        let roots: Vec<Value> = m
            .roots()
            .iter()
            .map(|r| json!({"re": r.re, "im": r.im}))
            .collect();
        v["roots_rad_s"] = Value::Array(roots);
        v["marginally_stable"] = json!(m.is_marginally_stable());
    }
    v
}

/// A fit object in µm (linear axes) or millidegrees (rotary axes).
pub fn fit_json(f: &FitMetrics, unit: Unit) -> Value {
    let (s, k) = (unit.micro_label(), unit.micro_factor());
    let mut v = serde_json::Map::new();
    v.insert(format!("freerun_rms_{s}"), json!(f.freerun_rms * k));
    v.insert(format!("freerun_max_{s}"), json!(f.freerun_max * k));
    v.insert(format!("onestep_rms_{s}"), json!(f.onestep_rms * k));
    v.insert("fit_percent".into(), json!(f.fit_percent));
    v.insert(format!("tracking_rms_{s}"), json!(f.tracking_rms * k));
    v.insert(format!("tracking_peak_{s}"), json!(f.tracking_peak * k));
    v.insert("samples".into(), json!(f.samples));
    Value::Object(v)
}

/// Relative error in percent, `(est - truth) / truth`.
pub fn rel_pct(est: f64, truth: f64) -> f64 {
    100.0 * (est - truth) / truth
}

/// Loads a machine file; errors are bad input with file:line:col.
pub fn load_machine(path: &Path) -> Result<Machine> {
    Ok(Machine::load(path)?)
}

/// Reads an identified-model file (`--model`) and orders its models like the machine's axes;
/// `None` when no file is given.
pub fn load_models(path: Option<&Path>, machine: &Machine) -> Result<Option<Vec<ClosedLoopModel>>> {
    let Some(p) = path else { return Ok(None) };
    Ok(Some(
        ModelSet::load(p)?.for_machine(machine, &p.display().to_string())?,
    ))
}

/// Largest program file accepted, bytes. A toolpath this long already asks for more samples
/// than the interpolator's cap; refusing it up front keeps a huge junk file from costing
/// seconds and gigabytes in the parser.
pub const MAX_PROGRAM_BYTES: u64 = 64 << 20;

/// Reads a program file (lossy UTF-8: the parser reports the replacement characters).
pub fn read_program(path: &Path) -> Result<String> {
    let cannot =
        |e: std::io::Error| crate::bad_input(format!("{}: cannot read: {e}", path.display()));
    let size = std::fs::metadata(path).map_err(cannot)?.len();
    if size > MAX_PROGRAM_BYTES {
        return Err(crate::bad_input(format!(
            "{}: the program is {size} bytes, more than the {} MiB vcnc accepts; split it",
            path.display(),
            MAX_PROGRAM_BYTES >> 20
        )));
    }
    let bytes = std::fs::read(path).map_err(cannot)?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

/// Prints warnings to stderr.
pub fn print_warnings(warnings: &[String]) {
    for w in warnings {
        eprintln!("{w}");
    }
}

/// The opening of every command that runs a program on a machine file: load the machine, read
/// and interpolate the program, print its warnings.
pub fn prepare_run(machine_path: &Path, program: &Path, lenient: bool) -> Result<(Machine, Run)> {
    let machine = load_machine(machine_path)?;
    let src = read_program(program)?;
    let run = pipeline::prepare(&machine, &src, &program.display().to_string(), lenient)?;
    print_warnings(&run.warnings);
    Ok((machine, run))
}

/// A plain-text table with right-aligned columns after the first.
pub fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let cols = header.len();
    let mut width: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (i, c) in r.iter().enumerate().take(cols) {
            width[i] = width[i].max(c.chars().count());
        }
    }
    let line = |cells: &[String]| {
        let mut s = String::new();
        for (i, c) in cells.iter().enumerate().take(cols) {
            let pad = width[i] - c.chars().count();
            if i == 0 {
                s.push_str(c);
                s.push_str(&" ".repeat(pad));
            } else {
                s.push_str("  ");
                s.push_str(&" ".repeat(pad));
                s.push_str(c);
            }
        }
        s.trim_end().to_string()
    };
    let mut out = line(&header.iter().map(|h| h.to_string()).collect::<Vec<_>>());
    out.push('\n');
    out.push_str(&"-".repeat(width.iter().sum::<usize>() + 2 * (cols.saturating_sub(1))));
    out.push('\n');
    for r in rows {
        out.push_str(&line(r));
        out.push('\n');
    }
    out
}

/// Creates the output folder.
pub fn ensure_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create output folder {}", dir.display()))
}

/// `(a - b) * k` sample by sample: tracking errors `x_r - x` and prediction errors in µm/mdeg.
pub fn scaled_diff(a: &[f64], b: &[f64], k: f64) -> Vec<f64> {
    a.iter().zip(b).map(|(a, b)| (a - b) * k).collect()
}

/// RMS of a slice.
pub fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// Max |x| of a slice.
pub fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}
