//! Output files and tables of the kinds of result several commands produce (identifications
//! and predictions), so that command files never import each other.

use std::path::Path;

use anyhow::Result;
use vcnc_drive::ClosedLoopModel;
use vcnc_pipeline::identify::{IdentifySummary, model_set};
use vcnc_pipeline::{AxisIdentification, ContourFigures, Prediction, Run};

use crate::figures::write_identification_plots;
use crate::output::{write_atomic, write_json};
use crate::sink::{TableOptions, write_table};
use crate::table::table;

/// How `model.toml` describes models identified on a simulated machine.
pub const MACHINE_MODELS: &str = "identified by vcnc: stability-constrained PSO (paper section 3) + output-error refinement (docs/identification.md)";

/// Writes `summary.json`, `model.toml` and the plots of identifications.
pub fn write_identification(
    out: &Path,
    summary: &IdentifySummary,
    model_machine: &str,
    model_description: &str,
    ids: &[AxisIdentification],
) -> Result<()> {
    for r in ids {
        write_identification_plots(out, r)?;
    }
    write_json(&out.join("summary.json"), summary)?;
    let set = model_set(model_machine, model_description, ids);
    write_atomic(&out.join("model.toml"), set.to_toml_string()?.as_bytes())?;
    Ok(())
}

/// `wn [Hz] / zeta / p [Hz]` of a model, or `-`.
pub fn fmt_poles(m: &ClosedLoopModel) -> String {
    match m.poles() {
        Some(p) => format!("{:.3} / {:.4} / {:.3}", p.wn_hz(), p.zeta, p.p_hz()),
        None => "-".into(),
    }
}

/// Per axis of a simulated machine: true vs identified poles, dc, and validation fit.
pub fn identification_table(results: &[AxisIdentification]) -> String {
    let mut rows = Vec::new();
    for r in results {
        let label = r.unit.micro_label();
        let k = r.unit.micro_factor();
        let ls = &r.result.unconstrained_ls;
        let truth = r.truth();
        rows.push(vec![
            r.axis.to_string(),
            truth.map_or("-".into(), fmt_poles),
            fmt_poles(&r.result.identified),
            fmt_poles(&r.result.paper_pso),
            (if ls.stable { "stable" } else { "UNSTABLE" }).to_string(),
            format!(
                "{} / {:.1}",
                truth.map_or("-".into(), |t| format!("{:.1}", t.dc)),
                r.result.identified.dc
            ),
            format!(
                "{:.2} / {:.2} {label}",
                r.validation.freerun_max * k,
                r.validation.tracking_peak * k
            ),
        ]);
    }
    table(
        &[
            "axis",
            "true wn/zeta/p [Hz]",
            "identified",
            "paper PSO",
            "LS baseline",
            "dc true/id",
            "validation err/peak",
        ],
        &rows,
    )
}

/// The `contour` table (`contour.csv` or `.parquet`): per sample t; reference, true and
/// predicted axis positions; reference, true and predicted tool tip and orientation; contour and
/// orientation errors of both.
pub fn write_contour_table(
    out: &Path,
    run: &Run,
    p: &Prediction,
    opts: &TableOptions,
) -> Result<()> {
    let n = run.len();
    let t = run.times();
    let reference = run.poses.as_deref().unwrap_or(&[]);
    let pose_cols = |poses: &[vcnc_kinematics::Pose]| -> Vec<Vec<f64>> {
        let mut cols: Vec<Vec<f64>> = (0..6).map(|_| Vec::with_capacity(n)).collect();
        for q in poses {
            for i in 0..3 {
                cols[i].push(q.p[i]);
                cols[3 + i].push(q.o[i]);
            }
        }
        cols
    };
    let rc = pose_cols(reference);
    let tc = pose_cols(&p.true_poses);
    let pc = pose_cols(&p.predicted_poses);
    let to_um = |v: &[f64]| v.iter().map(|x| x * 1000.0).collect::<Vec<f64>>();
    let tip_t = to_um(&p.true_contour.tip_mm);
    let tip_p = to_um(&p.predicted_contour.tip_mm);
    let or_t = to_um(&p.true_contour.orientation_rad);
    let or_p = to_um(&p.predicted_contour.orientation_rad);
    let mut header = vec!["t".to_string()];
    let mut cols: Vec<&[f64]> = vec![&t];
    for (i, a) in run.axes.iter().enumerate() {
        header.push(format!("{}_ref", a.name));
        cols.push(&a.pos);
        header.push(format!("{}_true", a.name));
        cols.push(&p.true_traces[i].true_position);
        header.push(format!("{}_pred", a.name));
        cols.push(&p.predicted[i]);
    }
    let names = ["px", "py", "pz", "ox", "oy", "oz"];
    for (prefix, c) in [("ref", &rc), ("true", &tc), ("pred", &pc)] {
        for (i, nm) in names.iter().enumerate() {
            header.push(format!("{prefix}_{nm}"));
            cols.push(&c[i]);
        }
    }
    header.extend(
        [
            "true_contour_um",
            "pred_contour_um",
            "true_orientation_mrad",
            "pred_orientation_mrad",
        ]
        .map(String::from),
    );
    cols.extend([
        tip_t.as_slice(),
        tip_p.as_slice(),
        or_t.as_slice(),
        or_p.as_slice(),
    ]);
    write_table(out, "contour", header, &cols, opts)?;
    Ok(())
}

/// The contour figures as table rows: label, tool tip (µm), orientation (mrad).
pub fn contour_rows(f: &ContourFigures) -> Vec<(String, f64, f64)> {
    f.rows()
        .iter()
        .map(|(label, _, v)| (label.to_string(), v.tip_um, v.orientation_mrad))
        .collect()
}
