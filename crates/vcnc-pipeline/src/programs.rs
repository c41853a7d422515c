//! Programs vcnc generates: the identification excitation, the 5-axis spiral as a
//! tool-centre-point program, a long program for measurements.

use vcnc_axis::AxisName;
use vcnc_gcode::{IdentificationOptions, SpiralOptions, TcpProgramOptions};
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{Axes, Branch, TableTiltingAc};
use vcnc_machine::Machine;

use crate::Error;

/// The paper's identification excitation of one axis (`vcnc gen identification`): `moves`
/// random moves within ±`range` (mm or deg), feeds up to `max_feed` units/s, from `seed`.
pub fn identification_program(
    axis: AxisName,
    moves: usize,
    range: f64,
    max_feed: f64,
    seed: u64,
) -> Result<String, Error> {
    let opts = IdentificationOptions {
        moves,
        range,
        max_feed,
        min_feed: (max_feed / 10.0).min(IdentificationOptions::default().min_feed),
        seed,
        ..IdentificationOptions::default()
    };
    vcnc_gcode::identification(axis, &opts)
        .map_err(|e| Error::gcode("<identification generator>", e))
}

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

/// The docs/contour.md spiral for `machine`'s own kinematics (`vcnc gen spiral --machine M`):
/// the same tip path (3 turns, radius 20 to 60 mm on a 100 mm dome centred at x 30, y 20).
/// On a 5-axis machine the tool axis is the dome normal, turned into the machine's rotary axes
/// (A or B, and C) by its inverse kinematics on its `kinematics.branch`, C unwound
/// continuously within its travel, and written as a tool-centre-point (`G43.4`) program with
/// the machine's axis letters; on a 3-axis machine the tool stays along +Z and the program is
/// a plain `G1 X Y Z` contour. `feed_mm_s` along the tip path, `segment_mm` between points.
/// Error: the machine has no kinematics, or a point the kinematics cannot reach.
pub fn machine_spiral_program(
    machine: &Machine,
    feed_mm_s: f64,
    segment_mm: f64,
) -> Result<String, Error> {
    let name = "<spiral generator>";
    let kin = machine.require_kinematics()?;
    if !(feed_mm_s.is_finite() && feed_mm_s > 0.0) {
        return Err(Error::Generator {
            program: "spiral",
            what: "the feed (mm/s)",
            value: feed_mm_s,
        });
    }
    let opts = SpiralOptions {
        segment_mm,
        ..SpiralOptions::default()
    };
    let points = vcnc_gcode::spiral_points(&opts).map_err(|e| Error::gcode(name, e))?;
    let rotary: Vec<AxisName> = kin.axis_names().into_iter().skip(3).collect();
    let mut previous = Axes::default();
    let mut text = String::with_capacity(points.len() * 64 + 512);
    let five = !rotary.is_empty();
    let letters: String = kin.axis_names().iter().map(|a| a.as_str()).collect();
    text.push_str(&format!(
        "%\n(vcnc spiral of docs/contour.md for {}: {} kinematics, axes {letters}; 3 turns, radius 20 to 60 mm on a 100 mm dome centred at x 30 y 20; {}; {feed_mm_s} mm/s; {segment_mm} mm segments)\n",
        machine.name.replace(['(', ')'], " "),
        kin.family(),
        if five {
            format!("tool axis = dome normal, IK branch {}", kin.branch)
        } else {
            "tool along +Z".to_string()
        }
    ));
    text.push_str(if five {
        "(tool-centre-point program: X Y Z = tool tip in the workpiece frame, mm; rotary axes in deg)\nG21 G90 G94 G17 G64\nG43.4\n"
    } else {
        "(3-axis program: X Y Z = tool tip, mm)\nG21 G90 G94 G17 G64\n"
    });
    for (k, p) in points.iter().enumerate() {
        let mut line = String::from(if k == 0 { "G0" } else { "G1" });
        for (axis, v) in ["X", "Y", "Z"].iter().zip(p.p) {
            line.push_str(&format!(" {axis}{}", decimals5(v)));
        }
        if five {
            let o = Vector3::from(p.o);
            let sol = kin
                .model
                .inverse_orientation(&o, kin.branch, &previous, Some(k))
                .map_err(|source| Error::Kinematics {
                    context: format!("{name}: point {k}"),
                    source,
                })?;
            previous = sol.joints;
            for axis in &rotary {
                line.push_str(&format!(
                    " {axis}{}",
                    decimals5(previous[*axis].to_degrees())
                ));
            }
        }
        if k == 1 {
            line.push_str(&format!(" F{:.1}", feed_mm_s * 60.0));
        }
        line.push('\n');
        text.push_str(&line);
    }
    text.push_str(if five { "G49\nM2\n%\n" } else { "M2\n%\n" });
    Ok(text)
}

/// `v` with 5 decimals, without the sign of a negative zero (as `vcnc_gcode::tcp_program`
/// writes coordinates).
fn decimals5(v: f64) -> String {
    let s = format!("{v:.5}");
    match s.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => s,
    }
}

/// A long 5-axis tool-centre-point program for measuring speed and memory
/// (docs/performance.md): `segments` short `G1` moves of the tool tip, switched into TCP mode by
/// `tcp_on_mcode` (the machine's `gcode.tcp_on_mcodes`, e.g. `M428`), with inverse-time feeds
/// (`G93`, each `F` = 1 / the move's duration in minutes), as CAM post-processors write them.
///
/// The tip runs turn after turn round a wavy band (angle $\theta$, radius
/// $r = 30 + 5\sin 7\theta$ mm, height $z = 20 + 4\sin(\theta/5)$ mm) with the table turning
/// with it ($C = \theta$ in degrees; $\theta$ runs back and forth over 50 turns) and the tilt
/// swinging
/// ($A = -40 + 15\sin 3\theta$ deg); consecutive tips are about `segment_mm` apart and each
/// move lasts `segment_s`. Deterministic: the same arguments give the same text.
pub fn long_tcp_program(
    segments: usize,
    segment_mm: f64,
    segment_s: f64,
    tcp_on_mcode: u32,
) -> Result<String, Error> {
    let mut out = String::with_capacity(segments * 64 + 256);
    write_long_tcp_program(&mut out, segments, segment_mm, segment_s, tcp_on_mcode)?;
    Ok(out)
}

/// [`long_tcp_program`] written into any `fmt::Write` (a 1 GB program need not be held as
/// a string: pass an adapter over a buffered file).
pub fn write_long_tcp_program(
    out: &mut impl std::fmt::Write,
    segments: usize,
    segment_mm: f64,
    segment_s: f64,
    tcp_on_mcode: u32,
) -> Result<(), Error> {
    let bad = |what: &'static str, value: f64| Error::Generator {
        program: "long program",
        what,
        value,
    };
    if !(segment_mm.is_finite() && segment_mm > 0.0) {
        return Err(bad("the segment length (mm)", segment_mm));
    }
    if !(segment_s.is_finite() && segment_s > 0.0) {
        return Err(bad("the segment duration (s)", segment_s));
    }
    let io = |_| Error::GeneratorOutput {
        program: "long program",
    };
    let tip = |theta: f64| {
        let r = 30.0 + 5.0 * (7.0 * theta).sin();
        [
            r * theta.cos(),
            r * theta.sin(),
            20.0 + 4.0 * (theta / 5.0).sin(),
        ]
    };
    let axes = |theta: f64| (-40.0 + 15.0 * (3.0 * theta).sin(), theta.to_degrees());
    writeln!(
        out,
        "(vcnc long 5-axis TCP program: {segments} segments of about {segment_mm} mm, {segment_s} s each, inverse-time feeds)"
    )
    .map_err(io)?;
    writeln!(out, "G21 G90 G17 G64").map_err(io)?;
    writeln!(out, "M{tcp_on_mcode}").map_err(io)?;
    let [x, y, z] = tip(0.0);
    let (a, c) = axes(0.0);
    writeln!(out, "G0 X{x:.3} Y{y:.3} Z{z:.3} A{a:.3} C{c:.3}").map_err(io)?;
    writeln!(out, "G93").map_err(io)?;
    // Inverse time: F = 1 / (duration in minutes).
    let f = 60.0 / segment_s;
    // θ steps of about segment_mm of tip travel (r ≥ 25 mm, so at most segment_mm · 35/30).
    let dtheta = segment_mm / 30.0;
    // Back and forth every 50 turns, so that C stays within ±9000° however long the program.
    let turns = 100.0 * std::f64::consts::PI;
    for k in 1..=segments {
        let s = (k as f64 * dtheta) % (2.0 * turns);
        let theta = if s <= turns { s } else { 2.0 * turns - s };
        let [x, y, z] = tip(theta);
        let (a, c) = axes(theta);
        writeln!(out, "G1 X{x:.3} Y{y:.3} Z{z:.3} A{a:.3} C{c:.3} F{f:.3}").map_err(io)?;
    }
    writeln!(out, "G94").map_err(io)?;
    writeln!(out, "M2").map_err(io)?;
    Ok(())
}
