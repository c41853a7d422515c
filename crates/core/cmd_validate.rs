//! `vcnc validate`: an identified model scored on a measured trace (docs/identification.md).

use anyhow::Result;
use vcnc_pipeline::ModelSet;
use vcnc_pipeline::traces;
use vcnc_pipeline::validate::{ValidateSummary, validate_measured};

use crate::Ctx;
use crate::cli::ValidateArgs;
use vcnc_output::files::{ensure_dir, write_json};
use vcnc_output::report::RunReport;
use vcnc_output::table::{TableOptions, write_table};
use vcnc_output::text::table;

/// `vcnc validate --model MODEL --trace TRACE [--axis A] --out DIR`.
pub fn validate(args: &ValidateArgs, ctx: &Ctx) -> Result<()> {
    let model_file = args.model.display().to_string();
    // The model file first: a mistake in it is reported before the trace is read.
    let models = ModelSet::load(&args.model)?;
    let (read, pair) = args.columns.pairing(&args.read, &args.axes)?;
    let measured = traces::read_trace(&args.trace, &read, &pair)?;
    let file = measured.paired.file.clone();
    let scored = validate_measured(&measured, &models, &model_file, &args.axes)?;
    let summary = ValidateSummary::of(&measured, &model_file, &scored);
    ensure_dir(&args.out)?;
    let mut report = RunReport::new(
        &args.out,
        format!(
            "vcnc validate: {}",
            vcnc_output::figures::program_name(&file)
        ),
    );
    report.input("trace", format!("{file} ({})", measured.paired.format));
    report.input("models", model_file.as_str());
    let header = [
        "axis",
        "samples",
        "free-run RMS",
        "free-run max",
        "one-step RMS",
        "fit %",
        "tracking RMS",
    ];
    let mut rows = Vec::new();
    for v in &scored {
        let (k, l) = (v.unit.micro_factor(), v.unit.micro_label());
        let row = |name: String, f: &vcnc_pipeline::FitMetrics| {
            vec![
                name,
                f.samples.to_string(),
                format!("{:.3} {l}", f.freerun_rms * k),
                format!("{:.3} {l}", f.freerun_max * k),
                format!("{:.3} {l}", f.onestep_rms * k),
                format!("{:.2}", f.fit_percent),
                format!("{:.3} {l}", f.tracking_rms * k),
            ]
        };
        rows.push(row(v.axis.to_string(), &v.fit));
        if let Some((from, f)) = &v.settled {
            rows.push(row(
                format!(
                    "{} from {:.3} s (moving start)",
                    v.axis,
                    *from as f64 * v.trace.ts
                ),
                f,
            ));
        }
        vcnc_output::figures::validation_measured(&mut report, v)?;
        // The residual at every sample, for the user's own plots.
        let t: Vec<f64> = (0..v.trace.len()).map(|i| i as f64 * v.trace.ts).collect();
        let residual: Vec<f64> = v
            .fit
            .predicted_x
            .iter()
            .zip(&v.trace.x)
            .map(|(m, x)| m - x)
            .collect();
        let stem = format!("residual_{}", v.axis);
        write_table(
            &args.out,
            &stem,
            ["t", "xr", "x", "x_model", "residual"]
                .map(String::from)
                .to_vec(),
            &[&t, &v.trace.xr, &v.trace.x, &v.fit.predicted_x, &residual],
            &TableOptions::default(),
        )?;
        report.file(
            &format!("{stem}.csv"),
            &format!(
                "axis {}: t (s), nominal xr, actual x, the model's free run x_model and x_model − x, in {}",
                v.axis,
                v.unit.as_str()
            ),
        );
    }
    report.table(
        "the model on the trace",
        &header,
        rows.clone(),
        "free run: the model driven by the nominal position alone; one-step: paper eq. 7 with \
         the measured position; fit: 100 (1 − |y − ŷ| / |y − ȳ|) of the tracking error y; a \
         trace that starts in motion is also scored after the model's start transient (the model \
         starts at rest)",
    );
    write_json(&args.out.join("summary.json"), &summary)?;
    report.finish()?;
    if !ctx.quiet {
        println!("{file}: {}, models {model_file}", measured.paired.format);
        print!("{}", table(&header, &rows));
        println!("-> {}", args.out.display());
    }
    Ok(())
}
