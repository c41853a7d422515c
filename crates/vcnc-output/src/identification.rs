//! The outputs of identifications (machines and traces): `summary.json`, `model.toml`, the
//! figures, the report's tables and the terminal's.

use std::path::Path;

use vcnc_pipeline::identify::{IdentifySummary, axis_warnings, model_set};
use vcnc_pipeline::{
    AxisIdentification, ClosedLoopModel, Degeneracy, DriveModel, TraceFormat, Unit, Verdict,
};

use crate::figures;
use crate::files::{write_atomic, write_json};
use crate::report::RunReport;
use crate::text::table;
use crate::{Error, Result};

/// How `model.toml` describes models identified on a simulated machine.
pub const MACHINE_MODELS: &str = "identified by vcnc: stability-constrained PSO (paper section 3) + output-error refinement (docs/identification.md)";

/// Writes the figures of identifications, `summary.json`, `model.toml` and the folder's
/// report (its manifest and `report.html`).
pub fn write_identification(
    report: &mut RunReport,
    summary: &IdentifySummary,
    model_machine: &str,
    model_description: &str,
    ids: &[AxisIdentification],
) -> Result<()> {
    let out = report.dir().to_path_buf();
    for r in ids {
        figures::identification(report, r)?;
    }
    write_json(&out.join("summary.json"), summary)?;
    let set = model_set(model_machine, model_description, ids);
    let text = set
        .to_toml_string()
        .map_err(|e| Error::Pipeline(e.into()))?;
    write_atomic(&out.join("model.toml"), text.as_bytes())?;
    identification_report_table(report, ids);
    let (header, rows) = structure_rows(ids, Unit::micro_symbol);
    let header_s: Vec<&str> = header.iter().map(String::as_str).collect();
    report.table(
        "model structures tried",
        &header_s,
        rows,
        "* the chosen structure, what model.toml holds; free-run error of each structure's model \
         on the trace it was fitted to ((stretch): only compared, on the compared stretch) and \
         where it was judged (the validation run, or the held-out end of a single trace); the \
         verdict says why a structure was not chosen (docs/identification.md, \"Choosing a \
         structure\")",
    );
    let (header, rows) = model_rows(ids);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    report.table(
        "chosen model structure and parameter uncertainty",
        &header,
        rows,
        "structure chosen by the validation error among those tried; ± one standard deviation \
         from the refinement's Jacobian with the residual's autocorrelation (docs/identification.md)",
    );
    let warnings: Vec<String> = ids.iter().flat_map(axis_warnings).collect();
    report.warnings(&warnings);
    for r in ids {
        let a = r.axis;
        report.file(
            &format!("frf_{a}.csv"),
            &format!("axis {a}: Bode data (f_hz; per model tracking and disturbance magnitude, dB, and phase, deg)"),
        );
    }
    report.file(
        "model.toml",
        "the identified models, for --model (docs/machine-file.md)",
    );
    report.finish()
}

/// The report of `vcnc identify MACHINE`: its inputs.
pub fn identify_machine_report(
    out: &Path,
    machine: &str,
    machine_file: &Path,
    ids: &[AxisIdentification],
    seed: Option<u64>,
) -> RunReport {
    let mut report = RunReport::new(out, format!("vcnc identify: {machine}"));
    report.input("machine", format!("{machine} ({})", machine_file.display()));
    let axes: Vec<String> = ids.iter().map(|r| r.axis.to_string()).collect();
    report.input("axes", axes.join(" "));
    report.input(
        "seed",
        seed.map_or(
            "the machine file's [identification] seeds".to_string(),
            |s| s.to_string(),
        ),
    );
    report
}
/// The report of an identification from a measured trace (one or more axes).
pub fn identify_trace_report(
    out: &Path,
    file: &str,
    format: TraceFormat,
    ids: &[AxisIdentification],
    options_file: Option<&Path>,
) -> RunReport {
    let mut report = RunReport::new(
        out,
        format!(
            "vcnc identify: trace {}",
            crate::figures::program_name(file)
        ),
    );
    report.input("trace", format!("{file} ({format})"));
    for id in ids {
        let t = &id.validation_trace;
        let channels = match &id.source {
            vcnc_pipeline::IdentificationSource::Measured { provenance, .. } => format!(
                "nominal '{}', actual '{}'",
                provenance.nominal.name, provenance.actual.name
            ),
            vcnc_pipeline::IdentificationSource::Simulated { .. } => String::new(),
        };
        report.input(
            &format!("axis {}", id.axis),
            format!(
                "{} samples at Ts = {} s, {}; {channels}",
                t.len(),
                t.ts,
                id.unit.as_str()
            ),
        );
    }
    report.input(
        "identifier options",
        options_file.map_or(
            "defaults (summary.json: identify_options)".to_string(),
            |p| format!("{} (summary.json: identify_options)", p.display()),
        ),
    );
    report
}

/// The identification table in a report (simulated machines: poles against the true drives).
pub fn identification_report_table(report: &mut RunReport, ids: &[AxisIdentification]) {
    if !ids.iter().any(|r| r.truth().is_some()) {
        return;
    }
    let (_, rows) = identification_rows(ids, Unit::micro_symbol);
    report.table(
        "identified poles against the true drives",
        &[
            "axis",
            "true machine ωn (Hz) / ζ / p (Hz)",
            "vcnc model",
            "paper's method",
            "LS baseline",
            "dc true / vcnc model",
            "validation: free-run error max / tracking peak",
        ],
        rows,
        "dc: Coulomb friction acceleration, axis units/s²; validation on a second excitation run \
         not used to identify",
    );
}

/// Per axis: the chosen structure and each of its parameters with its standard deviation.
pub fn model_rows(ids: &[AxisIdentification]) -> (Vec<String>, Vec<Vec<String>>) {
    let header = ["axis", "structure", "parameter", "value", "± std", "± %"]
        .map(String::from)
        .to_vec();
    let mut rows = Vec::new();
    for r in ids {
        let id = &r.result;
        let Some(u) = &id.uncertainty else {
            rows.push(vec![
                r.axis.to_string(),
                id.structure.to_string(),
                "-".into(),
                "-".into(),
                "-".into(),
                "-".into(),
            ]);
            continue;
        };
        for (i, p) in u.parameters.iter().enumerate() {
            let rel = 100.0 * p.relative();
            rows.push(vec![
                if i == 0 {
                    r.axis.to_string()
                } else {
                    String::new()
                },
                if i == 0 {
                    id.structure.to_string()
                } else {
                    String::new()
                },
                p.name.to_string(),
                format!("{:.6}", p.value),
                if p.std.is_finite() {
                    format!("{:.3e}", p.std)
                } else {
                    "undetermined".into()
                },
                if rel.is_finite() {
                    format!("{rel:.2}")
                } else {
                    "-".into()
                },
            ]);
        }
    }
    (header, rows)
}

/// Per axis, one row per model structure tried (issue 29): its model input and parameters,
/// its free-run error RMS / max on the trace it was fitted to and where it was judged (the
/// validation run, or the held-out end of a single trace), and the choice's verdict — `chosen`
/// (what `model.toml` holds) or why not, with why its parameters are not trusted where they
/// are not. Errors in µm or mdeg, labelled by `unit_label`.
pub fn structure_rows(
    ids: &[AxisIdentification],
    unit_label: fn(Unit) -> &'static str,
) -> (Vec<String>, Vec<Vec<String>>) {
    let mut rows = Vec::new();
    for r in ids {
        let label = unit_label(r.unit);
        let k = r.unit.micro_factor();
        let err = |m: &vcnc_pipeline::FitMetrics| {
            format!(
                "{:.3} / {:.3} {label}",
                m.freerun_rms * k,
                m.freerun_max * k
            )
        };
        for (i, f) in r.result.structures.iter().enumerate() {
            let chosen = matches!(f.verdict, Some(Verdict::Chosen));
            let mut verdict = f.verdict.as_ref().map_or("-".into(), short_verdict);
            for d in &f.degenerate {
                verdict.push_str("; ");
                verdict.push_str(&short_degeneracy(d));
            }
            rows.push(vec![
                if i == 0 {
                    r.axis.to_string()
                } else {
                    String::new()
                },
                format!("{}{}", if chosen { "* " } else { "" }, f.structure),
                f.input.to_string(),
                structure_parameters(&f.model),
                format!(
                    "{}{}",
                    err(&f.estimation),
                    if f.whole { "" } else { " (stretch)" }
                ),
                f.validation.as_ref().map_or("-".into(), err),
                verdict,
            ]);
        }
    }
    let header = [
        "axis",
        "structure",
        "input",
        "wn/zeta/p [Hz], own parameters",
        "estimation RMS / max",
        "held-out RMS / max",
        "verdict",
    ]
    .map(String::from)
    .to_vec();
    (header, rows)
}

/// The choice's verdict in a few words (the numbers are in the error columns; summary.json has
/// them all).
fn short_verdict(v: &Verdict) -> String {
    match v {
        Verdict::Chosen => "chosen".into(),
        Verdict::HigherError { .. } => "higher held-out error".into(),
        Verdict::Simpler { margin, .. } => format!(
            "within {:.0} % of the chosen, which is simpler or lower",
            100.0 * margin
        ),
        Verdict::Degenerate { margin, .. } => format!(
            "not trusted and not {:.0} % below the best trusted",
            100.0 * margin
        ),
        Verdict::DegenerateOnWholeTrace => "not trusted on the whole trace".into(),
        Verdict::OtherInput { .. } => "the other input fits the whole trace better".into(),
        Verdict::WorseThanContained { .. } => {
            "fits the whole trace worse than the paper's structure".into()
        }
    }
}

/// Why a structure's parameters are not trusted, in a few words.
fn short_degeneracy(d: &Degeneracy) -> String {
    match d {
        Degeneracy::OnBound(h) => format!("{} on its {} bound", h.parameter, h.bound),
        Degeneracy::Undetermined {
            parameter,
            relative_std,
            ..
        } if relative_std.is_finite() => {
            format!("{parameter} ± {:.0} %", 100.0 * relative_std)
        }
        Degeneracy::Undetermined { parameter, .. } => format!("{parameter} undetermined"),
    }
}

/// The poles of `m`'s core and the structure's own parameters (dead time, reference filter,
/// extra pole).
fn structure_parameters(m: &DriveModel) -> String {
    let mut s = fmt_poles(&m.core);
    if m.delay_s > 0.0 {
        s.push_str(&format!("; delay {:.2} ms", m.delay_s * 1e3));
    }
    match m.reference_filter {
        Some(vcnc_pipeline::ReferenceFilter::FirstOrder { tau_s }) => {
            s.push_str(&format!("; filter tau {:.2} ms", tau_s * 1e3));
        }
        Some(vcnc_pipeline::ReferenceFilter::SecondOrder { wn_hz, zeta }) => {
            s.push_str(&format!("; filter {wn_hz:.2} Hz / {zeta:.3}"));
        }
        None => {}
    }
    if let Some(hz) = m.extra_pole_hz {
        s.push_str(&format!("; extra pole {hz:.2} Hz"));
    }
    s
}

/// [`structure_rows`] as the terminal table.
pub fn structure_table(ids: &[AxisIdentification]) -> String {
    let (header, rows) = structure_rows(ids, Unit::micro_label);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    table(&header, &rows)
}

/// The chosen structures and their parameters with standard deviations, for the terminal.
pub fn model_table(ids: &[AxisIdentification]) -> String {
    let (header, rows) = model_rows(ids);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    table(&header, &rows)
}

/// `wn [Hz] / zeta / p [Hz]` of a model, or `-`.
pub fn fmt_poles(m: &ClosedLoopModel) -> String {
    match m.poles() {
        Some(p) => format!("{:.3} / {:.4} / {:.3}", p.wn_hz(), p.zeta, p.p_hz()),
        None => "-".into(),
    }
}

/// Per axis of a simulated machine: true vs identified poles (the model written to
/// `model.toml`, whatever its structure), dc, and validation fit; the
/// header and the rows, errors labelled by `unit_label` (`um` for the terminal, `µm` in
/// reports).
pub fn identification_rows(
    results: &[AxisIdentification],
    unit_label: fn(Unit) -> &'static str,
) -> (Vec<String>, Vec<Vec<String>>) {
    let mut rows = Vec::new();
    for r in results {
        let label = unit_label(r.unit);
        let k = r.unit.micro_factor();
        let ls = &r.result.unconstrained_ls;
        let truth = r.truth();
        rows.push(vec![
            r.axis.to_string(),
            truth.map_or("-".into(), fmt_poles),
            fmt_poles(&r.result.model.core),
            fmt_poles(&r.result.paper_pso),
            (if ls.stable { "stable" } else { "UNSTABLE" }).to_string(),
            format!(
                "{} / {:.1}",
                truth.map_or("-".into(), |t| format!("{:.1}", t.dc)),
                r.result.model.core.dc
            ),
            format!(
                "{:.2} / {:.2} {label}",
                r.validation.freerun_max * k,
                r.validation.tracking_peak * k
            ),
        ]);
    }
    let header = [
        "axis",
        "true wn/zeta/p [Hz]",
        "identified",
        "paper PSO",
        "LS baseline",
        "dc true/id",
        "validation err/peak",
    ]
    .map(String::from)
    .to_vec();
    (header, rows)
}

/// [`identification_rows`] as the terminal table.
pub fn identification_table(results: &[AxisIdentification]) -> String {
    let (header, rows) = identification_rows(results, Unit::micro_label);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    table(&header, &rows)
}
