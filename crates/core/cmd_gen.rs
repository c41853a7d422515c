//! `vcnc gen identification|spiral`: G-code programs on standard output.

use std::io::Write;

use anyhow::Result;
use vcnc_pipeline::Machine;
use vcnc_pipeline::programs::{
    identification_program, machine_spiral_program, spiral_program, write_long_tcp_program,
};

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
        } => identification_program(*axis, *moves, *range, *max_feed, *seed)
            .map_err(|e| bad_input(e.to_string()))?,
        GenCommand::Spiral {
            feed,
            segment,
            machine: None,
        } => spiral_program(*feed, *segment)?,
        GenCommand::Spiral {
            feed,
            segment,
            machine: Some(path),
        } => machine_spiral_program(&Machine::load(path)?, *feed, *segment)?,
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
