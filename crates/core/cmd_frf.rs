//! `vcnc frf`: tracking and disturbance frequency responses of each axis.

use std::path::Path;

use anyhow::Result;
use vcnc_output::figures::Role;
use vcnc_pipeline::frf::{frf_summary, measure_tracking};
use vcnc_pipeline::{DriveModel, Dynamics, MachineModels};

use crate::Ctx;
use vcnc_output::figures::{
    self, FrfModel, MEASUREMENT, MeasuredFrf, TRUE_MACHINE, VCNC_MODEL, section,
};
use vcnc_output::files::{ensure_dir, write_json};
use vcnc_output::report::RunReport;
use vcnc_output::text::table;

/// `vcnc frf MACHINE [--model MODEL] --out DIR`.
pub fn frf(machine_path: &Path, model: Option<&Path>, out: &Path, ctx: &Ctx) -> Result<()> {
    let machine = ctx.machine(machine_path)?;
    let models = model
        .map(|p| MachineModels::load(p, &machine))
        .transpose()?;
    let measured = measure_tracking(&machine)?;
    ensure_dir(out)?;
    let mut report = RunReport::new(out, format!("vcnc frf: {}", machine.name));
    report.input(
        "machine",
        format!("{} ({})", machine.name, machine_path.display()),
    );
    if let Some(p) = model {
        report.input("models", p.display().to_string());
    }
    report.input(
        "measurement",
        "each true drive simulated on a multisine (1-500 Hz, about 120 log-spaced lines, 5 axis \
         units/s peak on a 25 axis units/s bias), every drive effect included \
         (docs/machine-file.md, Frequency response of the true drive)",
    );
    for (i, a) in machine.axes.iter().enumerate() {
        let mut list = vec![match &a.dynamics {
            // A drive with effects is not its rigid model: say which curve is which.
            Dynamics::Drive(d) => FrfModel {
                tag: "true",
                label: if d.effects().is_ideal() {
                    TRUE_MACHINE
                } else {
                    "true machine, rigid model"
                },
                role: Role::TrueMachine,
                model: DriveModel::from(a.true_model()),
            },
            // No true machine: the axis' own identified model is the response.
            Dynamics::Model(m) => FrfModel {
                tag: "true",
                label: "the machine's identified model (no true machine)",
                role: Role::Model,
                model: *m,
            },
        }];
        if let Some(m) = &models {
            list.push(FrfModel {
                tag: "model",
                label: VCNC_MODEL,
                role: Role::Model,
                model: *m.get(i),
            });
        }
        figures::frf_with_measured(
            &mut report,
            &format!("frf_{}", a.name),
            a.name,
            &list,
            measured[i].as_ref().map(|frf| MeasuredFrf {
                label: MEASUREMENT,
                role: Role::Measurement,
                frf,
            }),
            section::FRF,
        )?;
        report.file(
            &format!("frf_{}.csv", a.name),
            &format!(
                "axis {}: Bode data (f_hz; per model tracking and disturbance magnitude, dB, and \
                 phase, deg; measured_f_hz and the measured tracking magnitude and phase at the \
                 multisine's lines)",
                a.name
            ),
        );
    }
    let summary = frf_summary(
        &machine,
        models.as_ref().map(MachineModels::models),
        Some(&measured),
    );
    write_json(&out.join("summary.json"), &summary)?;
    report.finish()?;
    if !ctx.quiet {
        // Machine order (the summary's map is sorted by letter).
        let rows: Vec<Vec<String>> = machine
            .axes
            .iter()
            .filter_map(|a| Some((a.name, summary.axes.get(a.name.as_str())?)))
            .map(|(name, s)| {
                let f = |v: Option<f64>, d: usize| v.map_or("-".into(), |v| format!("{v:.d$}"));
                vec![
                    name.to_string(),
                    f(s.truth.wn_hz, 3),
                    f(s.truth.zeta, 4),
                    f(s.truth.p_hz, 3),
                    f(s.bandwidth_3db_hz, 2),
                ]
            })
            .collect();
        print!(
            "{}",
            table(&["axis", "wn [Hz]", "zeta", "p [Hz]", "-3 dB [Hz]"], &rows)
        );
        println!("-> {}", out.display());
    }
    Ok(())
}
