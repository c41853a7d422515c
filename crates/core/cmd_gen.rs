//! `vcnc gen identification|spiral`: G-code programs on standard output.

use std::io::Write;

use anyhow::Result;
use vcnc_gcode::IdentificationOptions;
use vcnc_pipeline::programs::spiral_program;

use crate::bad_input;
use crate::cli::GenCommand;

pub fn generate(what: &GenCommand) -> Result<()> {
    let text = match what {
        GenCommand::Identification {
            axis,
            moves,
            range,
            max_feed,
            seed,
        } => {
            let opts = IdentificationOptions {
                moves: *moves,
                range: *range,
                max_feed: *max_feed,
                min_feed: (max_feed / 10.0).min(IdentificationOptions::default().min_feed),
                seed: *seed,
                ..IdentificationOptions::default()
            };
            vcnc_gcode::identification(*axis, &opts).map_err(|e| bad_input(e.to_string()))?
        }
        GenCommand::Spiral { feed, segment } => spiral_program(*feed, *segment)?,
    };
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())?;
    out.flush()?;
    Ok(())
}
