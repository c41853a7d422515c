//! `vcnc sweep` and `vcnc sweep-merge`: machine-configuration experiments.
//!
//! Each configuration of the cartesian product of `--set` values is a machine file with those
//! keys set; it runs the program through the true drives (and, with `--model`, the identified
//! models) and reports tracking and contour errors. Configurations run in parallel; rows are
//! written in configuration order, a chunk at a time, each row whole and flushed, so an
//! interrupted sweep keeps every row already written and the file is the same for any thread
//! count. `--shard i/n` runs every configuration whose index is i−1 modulo n; `sweep-merge`
//! joins shard folders back into one table, row for row equal to the unsharded sweep.

use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde_json::json;
use vcnc_contour::ContourReport;
use vcnc_drive::ClosedLoopModel;
use vcnc_machine::Machine;
use vcnc_machine::pipeline::{self, Run};
use vcnc_machine::sweep::{
    SweepKey, configuration, parse_set, parse_shard, product_len, set_key, shard_indices,
};

use crate::cli::SweepArgs;
use crate::output::{format_num, write_json};
use crate::plot::{LinePlot, Scale, Series, write_scatter};
use crate::report::{ensure_dir, load_models, max_abs, read_program, rms, scaled_diff};
use crate::{Ctx, bad_input};

/// Keys whose change alters the reference run (interpolation limits, kinematics, dialect).
fn changes_reference(key: &str) -> bool {
    let k = key.split('.').collect::<Vec<_>>();
    match k.as_slice() {
        ["sample_period_s"] | ["trajectory", ..] | ["kinematics", ..] | ["gcode", ..] => true,
        ["axes", _, leaf] => matches!(*leaf, "travel" | "max_velocity" | "max_acceleration"),
        _ => false,
    }
}

/// One configuration's results, in CSV cells.
struct Row {
    index: usize,
    cells: Vec<String>,
    contour_max_um: Option<f64>,
}

fn header(keys: &[SweepKey], axes: &[vcnc_gcode::AxisName], with_model: bool) -> Vec<String> {
    let mut h = vec!["index".to_string()];
    h.extend(keys.iter().map(|k| k.key.clone()));
    for a in axes {
        h.push(format!("{a}_tracking_max"));
        h.push(format!("{a}_tracking_rms"));
    }
    h.extend(
        [
            "contour_max_um",
            "contour_rms_um",
            "orientation_max_mrad",
            "orientation_rms_mrad",
        ]
        .iter()
        .map(|s| s.to_string()),
    );
    if with_model {
        h.extend(
            [
                "predicted_contour_max_um",
                "predicted_contour_rms_um",
                "discrepancy_max_um",
            ]
            .iter()
            .map(|s| s.to_string()),
        );
    }
    h.push("status".into());
    h
}

fn csv_cell(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\"").replace(['\n', '\r'], " "))
    } else {
        s.to_string()
    }
}

struct Setup<'a> {
    base: &'a toml::Table,
    base_dir: &'a Path,
    source: &'a str,
    program: &'a str,
    program_name: &'a str,
    keys: &'a [SweepKey],
    base_run: Option<&'a Run>,
    models: Option<&'a [ClosedLoopModel]>,
    /// Contour errors of `models` on the shared run: the same for every configuration when the
    /// run is shared (no swept key changes the reference or the kinematics), so computed once.
    base_predicted: Option<&'a ContourReport>,
    n_axes: usize,
    lenient: bool,
}

fn run_config(s: &Setup, index: usize) -> Row {
    let values = configuration(s.keys, index);
    let mut cells = vec![index.to_string()];
    cells.extend(values.iter().map(|v| format_num(*v)));
    let n_result = 2 * s.n_axes + 4 + if s.models.is_some() { 3 } else { 0 };
    match evaluate(s, &values) {
        Ok((res, cmax)) => {
            cells.extend(res);
            cells.push("ok".into());
            Row {
                index,
                cells,
                contour_max_um: Some(cmax),
            }
        }
        Err(e) => {
            cells.extend(std::iter::repeat_n(String::new(), n_result));
            let msg = e.to_string().replace(['\n', '\r'], " ");
            cells.push(csv_cell(&format!("error: {msg}")));
            Row {
                index,
                cells,
                contour_max_um: None,
            }
        }
    }
}

/// Contour errors of the identified `models` on `run`.
fn predicted_contour(
    machine: &Machine,
    run: &Run,
    models: &[ClosedLoopModel],
) -> Result<ContourReport> {
    let pred = pipeline::simulate_models(models, run)?;
    let ppos: Vec<&[f64]> = pred.iter().map(Vec::as_slice).collect();
    Ok(pipeline::contour(machine, run, &ppos)?.1)
}

fn evaluate(s: &Setup, values: &[f64]) -> Result<(Vec<String>, f64)> {
    let mut table = s.base.clone();
    for (k, v) in s.keys.iter().zip(values) {
        set_key(&mut table, &k.key, *v)?;
    }
    let machine = Machine::from_toml_table(table, s.source, Some(s.base_dir))?;
    let owned;
    let run = match s.base_run {
        Some(r) => r,
        None => {
            owned = pipeline::prepare(&machine, s.program, s.program_name, s.lenient)?;
            &owned
        }
    };
    let traces = pipeline::simulate_true(&machine, run)?;
    let mut cells = Vec::new();
    for (a, tr) in run.axes.iter().zip(&traces) {
        let k = a.unit.micro_factor();
        let e = scaled_diff(&a.pos, &tr.position, k);
        cells.push(format_num(max_abs(&e)));
        cells.push(format_num(rms(&e)));
    }
    let pos: Vec<&[f64]> = traces.iter().map(|t| t.true_position.as_slice()).collect();
    let (_, c) = pipeline::contour(&machine, run, &pos)?;
    let cmax = c.tip_max_mm * 1e3;
    cells.push(format_num(cmax));
    cells.push(format_num(c.tip_rms_mm * 1e3));
    cells.push(format_num(c.orientation_max_rad * 1e3));
    cells.push(format_num(c.orientation_rms_rad * 1e3));
    if let Some(models) = s.models {
        let owned_pc;
        let pc = match s.base_predicted {
            Some(pc) => pc,
            None => {
                owned_pc = predicted_contour(&machine, run, models)?;
                &owned_pc
            }
        };
        let disc = c
            .tip_mm
            .iter()
            .zip(&pc.tip_mm)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        cells.push(format_num(pc.tip_max_mm * 1e3));
        cells.push(format_num(pc.tip_rms_mm * 1e3));
        cells.push(format_num(disc * 1e3));
    }
    Ok((cells, cmax))
}

pub fn sweep(args: &SweepArgs, ctx: &Ctx) -> Result<()> {
    let source = args.machine.display().to_string();
    let text = std::fs::read_to_string(&args.machine)
        .map_err(|e| bad_input(format!("{source}: cannot read: {e}")))?;
    // The base machine must be valid: its errors carry line numbers.
    let base_dir = args
        .machine
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let base_machine = Machine::from_toml_str(&text, &source, &base_dir)?;
    let base: toml::Table =
        toml::from_str(&text).map_err(|e| bad_input(format!("{source}: {e}")))?;
    let keys: Vec<SweepKey> = args
        .sets
        .iter()
        .map(|s| parse_set(s).map_err(bad_input))
        .collect::<Result<_>>()?;
    let shard = args
        .shard
        .as_deref()
        .map(parse_shard)
        .transpose()
        .map_err(bad_input)?;
    let total = product_len(&keys);
    if total > 10_000_000 {
        return Err(bad_input(format!(
            "the sweep has {total} configurations; split it (at most 10 000 000)"
        )));
    }
    let indices = shard_indices(total, shard);
    let program = read_program(&args.program)?;
    let program_name = args.program.display().to_string();
    let base_run = pipeline::prepare(&base_machine, &program, &program_name, ctx.lenient)?;
    let models = load_models(args.model.as_deref(), &base_machine)?;
    let reuse = !keys.iter().any(|k| changes_reference(&k.key));
    let base_predicted = match (&models, reuse) {
        (Some(m), true) => Some(predicted_contour(&base_machine, &base_run, m)?),
        _ => None,
    };
    let setup = Setup {
        base: &base,
        base_dir: &base_dir,
        source: &source,
        program: &program,
        program_name: &program_name,
        keys: &keys,
        base_run: reuse.then_some(&base_run),
        models: models.as_deref(),
        base_predicted: base_predicted.as_ref(),
        n_axes: base_machine.axes.len(),
        lenient: ctx.lenient,
    };
    ensure_dir(&args.out)?;
    let csv_path = args.out.join("sweep.csv");
    let mut file =
        File::create(&csv_path).with_context(|| format!("cannot create {}", csv_path.display()))?;
    let head = header(&keys, &base_machine.axis_names(), models.is_some());
    writeln!(file, "{}", head.join(","))?;
    file.flush()?;
    let bar = if ctx.quiet {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::new(indices.len() as u64);
        b.set_style(
            ProgressStyle::with_template(
                "{bar:40} {pos}/{len} configurations, {per_sec}, ETA {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    };
    let chunk = (4 * rayon::current_num_threads()).max(8);
    let mut best: Option<(f64, usize, Vec<f64>)> = None;
    let (mut ok, mut failed) = (0usize, 0usize);
    let mut plot_points: Vec<(Vec<f64>, f64)> = Vec::new();
    let started = std::time::Instant::now();
    for part in indices.chunks(chunk) {
        let rows: Vec<Row> = part
            .par_iter()
            .map(|&i| {
                let r = run_config(&setup, i);
                bar.inc(1);
                r
            })
            .collect();
        let mut text = String::new();
        for r in &rows {
            text.push_str(&r.cells.join(","));
            text.push('\n');
            match r.contour_max_um {
                Some(c) => {
                    ok += 1;
                    let values = configuration(&keys, r.index);
                    if best.as_ref().is_none_or(|(b, _, _)| c < *b) {
                        best = Some((c, r.index, values.clone()));
                    }
                    plot_points.push((values, c));
                }
                None => failed += 1,
            }
        }
        // One write per chunk of whole rows, then flush: an interruption keeps whole rows.
        file.write_all(text.as_bytes())?;
        file.flush()?;
    }
    bar.finish_and_clear();
    let elapsed = started.elapsed().as_secs_f64();
    write_sweep_summary(&args.out, &keys, total, shard, ok, failed, best.as_ref())?;
    write_sweep_plots(&args.out, &keys, &plot_points)?;
    if !ctx.quiet {
        println!(
            "{} configurations ({} ok, {} failed) in {:.2} s ({:.1}/s on {} threads) -> {}",
            ok + failed,
            ok,
            failed,
            elapsed,
            (ok + failed) as f64 / elapsed.max(1e-9),
            rayon::current_num_threads(),
            args.out.display()
        );
        if let Some((c, i, v)) = &best {
            let set: Vec<String> = keys
                .iter()
                .zip(v)
                .map(|(k, v)| format!("{}={}", k.key, v))
                .collect();
            println!("best: #{i} {} with contour error {c:.3} um", set.join(" "));
        }
    }
    Ok(())
}

fn write_sweep_summary(
    out: &Path,
    keys: &[SweepKey],
    total: usize,
    shard: Option<(usize, usize)>,
    ok: usize,
    failed: usize,
    best: Option<&(f64, usize, Vec<f64>)>,
) -> Result<()> {
    let best = best.map(|(c, i, v)| {
        let values: serde_json::Map<String, serde_json::Value> = keys
            .iter()
            .zip(v)
            .map(|(k, v)| (k.key.clone(), json!(v)))
            .collect();
        json!({"index": i, "values": values, "contour_max_um": c})
    });
    write_json(
        &out.join("summary.json"),
        &json!({
            "keys": keys.iter().map(|k| json!({"key": k.key, "values": k.values})).collect::<Vec<_>>(),
            "configurations": total,
            "shard": shard.map(|(i, n)| format!("{i}/{n}")),
            "ok": ok,
            "failed": failed,
            "best": best,
            "criterion": "smallest tool-tip contour error (max) with the true drives",
        }),
    )
}

fn write_sweep_plots(out: &Path, keys: &[SweepKey], points: &[(Vec<f64>, f64)]) -> Result<()> {
    let ys: Vec<f64> = points.iter().map(|p| p.1).collect();
    for (i, k) in keys.iter().enumerate() {
        let xs: Vec<f64> = points.iter().map(|p| p.0[i]).collect();
        let title = format!("contour error against {}", k.key);
        let name = format!("sweep_{}.svg", k.key.replace(['.', '/'], "_"));
        write_scatter(
            &out.join(name),
            &LinePlot {
                title: &title,
                x_label: &k.key,
                y_label: "max contour error [um]",
                x_scale: Scale::Linear,
                series: vec![Series {
                    name: "configurations".into(),
                    x: &xs,
                    y: &ys,
                }],
            },
        )?;
    }
    Ok(())
}

/// `vcnc sweep-merge DIR... --out DIR`: joins shard tables (same header) in index order.
pub fn merge(dirs: &[PathBuf], out: &Path, ctx: &Ctx) -> Result<()> {
    let mut header: Option<String> = None;
    let mut rows: Vec<(usize, String)> = Vec::new();
    for d in dirs {
        let path = d.join("sweep.csv");
        let f = File::open(&path)
            .map_err(|e| bad_input(format!("{}: cannot read: {e}", path.display())))?;
        let mut lines = BufReader::new(f).lines();
        let h = lines
            .next()
            .transpose()?
            .ok_or_else(|| bad_input(format!("{}: empty file", path.display())))?;
        match &header {
            None => header = Some(h),
            Some(prev) if *prev != h => {
                return Err(bad_input(format!(
                    "{}: its columns differ from the first shard's",
                    path.display()
                )));
            }
            _ => {}
        }
        for (n, line) in lines.enumerate() {
            let line = line?;
            if line.is_empty() {
                continue;
            }
            let idx: usize = line
                .split(',')
                .next()
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| {
                    bad_input(format!(
                        "{}:{}: no configuration index",
                        path.display(),
                        n + 2
                    ))
                })?;
            rows.push((idx, line));
        }
    }
    rows.sort_by_key(|r| r.0);
    if let Some(w) = rows.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(bad_input(format!(
            "configuration {} appears in more than one shard",
            w[0].0
        )));
    }
    let header = header.ok_or_else(|| bad_input("no shard folders given"))?;
    ensure_dir(out)?;
    let mut text = header.clone();
    text.push('\n');
    for (_, r) in &rows {
        text.push_str(r);
        text.push('\n');
    }
    crate::output::write_atomic(&out.join("sweep.csv"), text.as_bytes())?;
    // Best row by contour_max_um.
    let cols: Vec<&str> = header.split(',').collect();
    let ci = cols.iter().position(|c| *c == "contour_max_um");
    let si = cols.iter().position(|c| *c == "status");
    // The swept keys are the columns between `index` and the first per-axis column.
    let nkeys = cols
        .iter()
        .skip(1)
        .position(|c| c.ends_with("_tracking_max"))
        .unwrap_or(0);
    let mut best: Option<(f64, usize, serde_json::Map<String, serde_json::Value>)> = None;
    let mut ok = 0;
    for (i, r) in &rows {
        let cells: Vec<&str> = r.split(',').collect();
        let is_ok = si.and_then(|s| cells.get(s)).is_some_and(|s| *s == "ok");
        if !is_ok {
            continue;
        }
        ok += 1;
        if let Some(c) = ci
            .and_then(|c| cells.get(c))
            .and_then(|c| c.parse::<f64>().ok())
            && best.as_ref().is_none_or(|(b, _, _)| c < *b)
        {
            let values = cols[1..=nkeys]
                .iter()
                .zip(&cells[1..])
                .map(|(k, v)| {
                    let v = v.parse::<f64>().map_or_else(|_| json!(v), |x| json!(x));
                    (k.to_string(), v)
                })
                .collect();
            best = Some((c, *i, values));
        }
    }
    write_json(
        &out.join("summary.json"),
        &json!({
            "merged_from": dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>(),
            "configurations": rows.len(),
            "ok": ok,
            "failed": rows.len() - ok,
            "best": best.map(|(c, i, v)| json!({"index": i, "values": v, "contour_max_um": c})),
        }),
    )?;
    if !ctx.quiet {
        println!(
            "merged {} rows from {} shards -> {}",
            rows.len(),
            dirs.len(),
            out.display()
        );
    }
    Ok(())
}
