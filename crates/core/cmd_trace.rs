//! `vcnc trace info FILE`: what a scope file holds.

use anyhow::Result;

use crate::Ctx;
use crate::cli::TraceCommand;

pub fn trace(what: &TraceCommand, _ctx: &Ctx) -> Result<()> {
    match what {
        TraceCommand::Info { file, read, json } => {
            if let Some(u) = &read.units {
                // Refused rather than ignored: info lists the units the file states.
                return Err(crate::bad_input(format!(
                    "--units {u}: trace info shows the units the file states; --units applies \
                     where positions are paired (identify --trace, validate)"
                )));
            }
            let opts = read
                .trace_args(None, &[])
                .read_options()
                .map_err(vcnc_pipeline::Error::from)?;
            let info = vcnc_pipeline::traces::read_path(file, &opts)
                .map_err(vcnc_pipeline::Error::from)?
                .info();
            if *json {
                print!("{}", vcnc_output::files::json_text(&info)?);
            } else {
                print!("{info}");
            }
            Ok(())
        }
    }
}
