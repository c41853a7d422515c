//! `vcnc gen identification|spiral`: G-code programs on standard output.

use std::io::Write;

use anyhow::Result;
use vcnc_gcode::IdentificationOptions;
use vcnc_pipeline::programs::{spiral_program, write_long_tcp_program};

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
        GenCommand::Long {
            segments,
            segment,
            segment_s,
        } => {
            // Streamed to standard output: a program of any size without holding its text.
            let mut out = FmtOut(std::io::BufWriter::new(std::io::stdout().lock()));
            write_long_tcp_program(&mut out, *segments, *segment, *segment_s, 428)
                .map_err(|e| bad_input(e.to_string()))?;
            out.0.flush()?;
            return Ok(());
        }
    };
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())?;
    out.flush()?;
    Ok(())
}

/// `fmt::Write` over an `io::Write` (the generator writes text; stdout takes bytes).
struct FmtOut<W: Write>(W);

impl<W: Write> std::fmt::Write for FmtOut<W> {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.0.write_all(s.as_bytes()).map_err(|_| std::fmt::Error)
    }
}
