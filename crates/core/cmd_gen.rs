//! `vcnc gen identification|spiral`: G-code programs on standard output.

use std::io::Write;

use anyhow::Result;
use vcnc_gcode::{IdentificationOptions, SpiralOptions, TcpProgramOptions};
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{Branch, TableTiltingAc};

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

/// The docs/contour.md spiral as a TCP program: tip points on the dome, tool axis = dome normal,
/// turned into A and C by the inverse kinematics on branch −1 with C unwrapped continuously.
pub fn spiral_program(feed_mm_s: f64, segment_mm: f64) -> Result<String> {
    let opts = SpiralOptions {
        segment_mm,
        ..SpiralOptions::default()
    };
    let points = vcnc_gcode::spiral_points(&opts).map_err(|e| bad_input(e.to_string()))?;
    let mut c_prev = 0.0;
    let mut program_points = Vec::with_capacity(points.len());
    for (k, p) in points.iter().enumerate() {
        let o = Vector3::from(p.o);
        let ang = TableTiltingAc::rotary_angles(&o, Branch::Minus, c_prev, Some(k))
            .map_err(|e| anyhow::anyhow!("spiral point {k}: {e}"))?;
        c_prev = ang.c;
        program_points.push((p.p, ang.a.to_degrees(), ang.c.to_degrees()));
    }
    let popts = TcpProgramOptions {
        feed_mm_per_min: feed_mm_s * 60.0,
        title: format!(
            "vcnc 5-axis spiral of docs/contour.md: 3 turns, radius 20 to 60 mm on a 100 mm dome centred at x 30 y 20; tool axis = dome normal, IK branch -1; {feed_mm_s} mm/s; {segment_mm} mm segments"
        ),
        ..TcpProgramOptions::default()
    };
    vcnc_gcode::tcp_program(&program_points, &popts).map_err(|e| bad_input(e.to_string()))
}
