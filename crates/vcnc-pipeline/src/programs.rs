//! Programs vcnc generates: the 5-axis spiral as a tool-centre-point program.

use vcnc_gcode::{SpiralOptions, TcpProgramOptions};
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{Branch, TableTiltingAc};

use crate::Error;

/// The docs/contour.md spiral as a TCP program: tip points on the dome, tool axis = dome
/// normal, turned into A and C by the inverse kinematics on branch −1 with C unwrapped
/// continuously. `feed_mm_s` along the tip path, `segment_mm` between points.
pub fn spiral_program(feed_mm_s: f64, segment_mm: f64) -> Result<String, Error> {
    let name = "<spiral generator>";
    let opts = SpiralOptions {
        segment_mm,
        ..SpiralOptions::default()
    };
    let points = vcnc_gcode::spiral_points(&opts).map_err(|e| Error::gcode(name, e))?;
    let mut c_prev = 0.0;
    let mut program_points = Vec::with_capacity(points.len());
    for (k, p) in points.iter().enumerate() {
        let o = Vector3::from(p.o);
        let ang = TableTiltingAc::rotary_angles(&o, Branch::Minus, c_prev, Some(k)).map_err(
            |source| Error::Kinematics {
                context: format!("{name}: point {k}"),
                source,
            },
        )?;
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
    vcnc_gcode::tcp_program(&program_points, &popts).map_err(|e| Error::gcode(name, e))
}
