//! The tables of `vcnc demo` and `vcnc demo --realistic`: contour errors side by side, the
//! realistic drives' identification, the stated latency and the effect budget.

use vcnc_pipeline::realistic::{BudgetRow, Discrepancy};
use vcnc_pipeline::{AxisIdentification, ClosedLoopModel, ContourFigures, ModelStructure};

use crate::runs::contour_rows;
use crate::text::table;

/// The contour table of two model sets side by side, for the terminal.
pub fn contour_table_pair(
    p: &ContourFigures,
    pp: &ContourFigures,
    a_name: &str,
    b_name: &str,
) -> String {
    let (a, b) = (contour_rows(p), contour_rows(pp));
    let rows: Vec<Vec<String>> = a
        .iter()
        .zip(&b)
        .map(|((n, t1, o1), (_, t2, o2))| {
            vec![
                n.clone(),
                format!("{t1:.3}"),
                format!("{o1:.4}"),
                format!("{t2:.3}"),
                format!("{o2:.4}"),
            ]
        })
        .collect();
    let h = [
        format!("tip [um] {a_name}"),
        format!("orient. [mrad] {a_name}"),
        format!("tip [um] {b_name}"),
        format!("orient. [mrad] {b_name}"),
    ];
    table(&["", &h[0], &h[1], &h[2], &h[3]], &rows)
}

/// The note on the stated-latency figures.
pub const STATED_LATENCY_NOTE: &str = "the latency is stated from the machine's control \
     configuration (feedback.dead_time_cycles / servo_rate_hz), not identified: the models \
     predict the logged actual position, which trails the physical axis by it";

/// A row of the stated-latency table: label, latencies (ms), discrepancy.
pub fn stated_row(label: &str, latency_s: &[f64], d: &Discrepancy) -> Vec<String> {
    vec![
        label.to_string(),
        if latency_s.is_empty() {
            "-".to_string()
        } else {
            latency_s
                .iter()
                .map(|t| format!("{}", t * 1e3))
                .collect::<Vec<_>>()
                .join(" ")
        },
        format!("{:.3}", d.tip_max_um),
        format!("{:.3}", d.tip_rms_um),
        format!("{:.4}", d.orientation_max_mrad),
        format!("{:.4}", d.orientation_rms_mrad),
    ]
}

pub const BUDGET_HEADER: [&str; 10] = [
    "effect",
    "true max [um]",
    "vcnc max [um]",
    "vcnc RMS [um]",
    "vcnc max [mrad]",
    "vcnc+lat. max [um]",
    "vcnc+lat. max [mrad]",
    "paper max [um]",
    "paper max [mrad]",
    "structures X Y Z A C",
];

pub fn budget_rows(rows: &[BudgetRow]) -> Vec<Vec<String>> {
    rows.iter()
        .map(|r| {
            vec![
                r.effect.to_string(),
                format!("{:.3}", r.true_max_um),
                format!("{:.3}", r.model.tip_max_um),
                format!("{:.3}", r.model.tip_rms_um),
                format!("{:.4}", r.model.orientation_max_mrad),
                format!("{:.3}", r.model_stated_latency.tip_max_um),
                format!("{:.4}", r.model_stated_latency.orientation_max_mrad),
                format!("{:.3}", r.paper_pso.tip_max_um),
                format!("{:.4}", r.paper_pso.orientation_max_mrad),
                r.structures
                    .iter()
                    .map(|(_, s)| short_tag(*s))
                    .collect::<Vec<_>>()
                    .join(" "),
            ]
        })
        .collect()
}

/// A two-letter tag of a structure for the budget table ([`BUDGET_NOTE`]).
pub fn short_tag(s: ModelStructure) -> &'static str {
    use ModelStructure as M;
    match s {
        M::Paper => "P",
        M::NoIntegral => "NI",
        M::Delay => "D",
        M::FirstOrderFilter => "F1",
        M::SecondOrderFilter => "F2",
        M::ExtraPole => "XP",
    }
}

/// The budget table's note.
pub const BUDGET_NOTE: &str = "ideal: the drives without any effect table and without encoder \
     noise; each other row adds one group of machines/nmv5000-realistic.toml \
     (docs/machine-file.md, Drive effects); |prediction − true| over the feed moves; vcnc+lat.: vcnc's \
     models with the actual-value latency stated from the configuration (dead_time_cycles / \
     servo_rate_hz; 0 without a dead time); structures chosen per axis: P paper, NI no integral \
     action, D delay, F1/F2 first/second-order reference filter, XP extra pole";

/// A short tag of a structure for tables (its name in summaries).
pub fn structure_tag(s: ModelStructure) -> String {
    serde_json::to_value(s)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_else(|| format!("{s:?}"))
}

/// Header and rows: axis, true poles, chosen structure and its core poles, the paper's
/// method's poles, then each structure's validation free-run error max (chosen starred) and
/// the paper's method's.
pub fn realistic_identification_rows(
    ids: &[AxisIdentification],
) -> (Vec<String>, Vec<Vec<String>>) {
    let poles = |m: &ClosedLoopModel| {
        m.poles().map_or("-".to_string(), |p| {
            format!(
                "{:.2} / {:.3} / {:.2}",
                p.wn / std::f64::consts::TAU,
                p.zeta,
                p.p / std::f64::consts::TAU
            )
        })
    };
    let structures: Vec<ModelStructure> = ids
        .first()
        .map(|r| r.result.structures.iter().map(|s| s.structure).collect())
        .unwrap_or_default();
    let mut header: Vec<String> = ["axis", "true", "chosen", "vcnc core", "paper's method"]
        .map(String::from)
        .to_vec();
    header.extend(structures.iter().map(|s| structure_tag(*s)));
    header.push("paper's method val.".to_string());
    let rows = ids
        .iter()
        .map(|r| {
            let k = r.unit.micro_factor();
            let mut row = vec![
                r.axis.to_string(),
                r.truth().map_or("-".to_string(), poles),
                structure_tag(r.result.structure),
                poles(&r.result.model.core),
                poles(&r.result.paper_pso),
            ];
            for s in &structures {
                let cell = r
                    .result
                    .structures
                    .iter()
                    .find(|f| f.structure == *s)
                    .and_then(|f| f.validation.as_ref())
                    .map_or("-".to_string(), |v| {
                        let star = if *s == r.result.structure { "*" } else { "" };
                        format!("{:.2} / {:.1}{star}", v.freerun_rms * k, v.freerun_max * k)
                    });
                row.push(cell);
            }
            let v = &r.validation_paper;
            row.push(format!(
                "{:.2} / {:.1}",
                v.freerun_rms * k,
                v.freerun_max * k
            ));
            row
        })
        .collect();
    (header, rows)
}
