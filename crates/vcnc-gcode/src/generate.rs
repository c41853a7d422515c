//! Program generators: the identification excitation (paper section 4, docs/gcode.md) and the
//! 5-axis spiral test path (docs/contour.md).

use crate::{AxisName, Error};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;
use std::fmt::Write;

/// Settings of the identification program. Units are the axis' own: mm for X Y Z, deg for
/// A B C (feeds then in deg/s and the program's F in deg/min).
#[derive(Debug, Clone, PartialEq)]
pub struct IdentificationOptions {
    /// Number of random moves N. Default 70 (the paper's).
    pub moves: usize,
    /// Travel half-range R: every target lies in [−R, R], mm or deg. Default 50.
    pub range: f64,
    /// Highest feed, units/s. Default 250 (F15000).
    pub max_feed: f64,
    /// Lowest feed, units/s. Default 25 (a tenth of the highest).
    pub min_feed: f64,
    /// Fraction of short strokes, in [0, 1]. Default 0.3.
    pub short_fraction: f64,
    /// Short strokes are uniform in [`short_min`, `short_max`], units. Default 0.5.
    ///
    /// [`short_min`]: IdentificationOptions::short_min
    /// [`short_max`]: IdentificationOptions::short_max
    pub short_min: f64,
    /// Upper end of the short strokes, units. Default 5.
    pub short_max: f64,
    /// Long strokes are uniform in [`long_min`, 2R] (shortened to the room left), units.
    /// Default 10.
    ///
    /// [`long_min`]: IdentificationOptions::long_min
    pub long_min: f64,
    /// Probability that a move reverses the previous one's direction, in [0, 1]. Default 0.7
    /// (back-and-forth motion excites the friction and the reversal dynamics).
    pub reversal_probability: f64,
    /// Dwell after every move, s (`G4 P`). Default 0.
    pub dwell_s: f64,
    /// Seed of the `ChaCha8Rng`. Default 1.
    pub seed: u64,
    /// Decimals written for positions. Default 4.
    pub decimals: usize,
}

impl Default for IdentificationOptions {
    fn default() -> Self {
        IdentificationOptions {
            moves: 70,
            range: 50.0,
            max_feed: 250.0,
            min_feed: 25.0,
            short_fraction: 0.3,
            short_min: 0.5,
            short_max: 5.0,
            long_min: 10.0,
            reversal_probability: 0.7,
            dwell_s: 0.0,
            seed: 1,
            decimals: 4,
        }
    }
}

/// Most moves [`identification`] writes. The paper uses 70; a million moves is already about
/// 40 MB of G-code and hours of motion, so a larger count is a typo, and refusing it keeps the
/// generator's memory bounded (issue 7).
pub const MAX_IDENTIFICATION_MOVES: usize = 1_000_000;

fn check(ok: bool, name: &'static str, value: f64, expected: &'static str) -> Result<(), Error> {
    if ok {
        Ok(())
    } else {
        Err(Error::InvalidGenerator {
            name,
            value,
            expected,
        })
    }
}

/// Format `v` with `decimals` decimals, without a negative zero.
fn num(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// The identification program for one axis (G-code text).
///
/// N moves of the named axis within ±R at feeds uniform in [min_feed, max_feed], strokes short
/// (uniform in [short_min, short_max]) with probability `short_fraction` or long (uniform in
/// [long_min, 2R]), each reversing the previous direction with probability
/// `reversal_probability`; a stroke that would leave ±R turns back if there is room, otherwise
/// it is shortened to the room in the roomier direction. Every block is exact stop (`G61.1`), so
/// the axis rests between moves. The program opens with `G0 <axis>0`, so the machine starts at
/// rest at 0. Same options (seed included) → the same text, byte for byte.
pub fn identification(axis: AxisName, opts: &IdentificationOptions) -> Result<String, Error> {
    let o = opts;
    check(
        (1..=MAX_IDENTIFICATION_MOVES).contains(&o.moves),
        "moves",
        o.moves as f64,
        "1 to 1 000 000 moves",
    )?;
    // Long strokes are drawn from [long_min, 2R]: 2R must be finite too.
    check(
        o.range > 0.0 && (2.0 * o.range).is_finite(),
        "range",
        o.range,
        "a positive length ≤ f64::MAX / 2",
    )?;
    check(
        o.max_feed.is_finite() && o.max_feed > 0.0,
        "max_feed",
        o.max_feed,
        "a positive speed",
    )?;
    check(
        o.min_feed > 0.0 && o.min_feed <= o.max_feed,
        "min_feed",
        o.min_feed,
        "a speed in (0, max_feed]",
    )?;
    check(
        (0.0..=1.0).contains(&o.short_fraction),
        "short_fraction",
        o.short_fraction,
        "a fraction in [0, 1]",
    )?;
    check(
        o.short_min > 0.0 && o.short_min <= o.short_max,
        "short_min",
        o.short_min,
        "a positive length ≤ short_max",
    )?;
    check(
        o.short_max <= 2.0 * o.range,
        "short_max",
        o.short_max,
        "a length ≤ 2 range",
    )?;
    check(
        o.long_min > 0.0 && o.long_min <= 2.0 * o.range,
        "long_min",
        o.long_min,
        "a positive length ≤ 2 range",
    )?;
    check(
        (0.0..=1.0).contains(&o.reversal_probability),
        "reversal_probability",
        o.reversal_probability,
        "a probability in [0, 1]",
    )?;
    check(
        o.dwell_s.is_finite() && o.dwell_s >= 0.0,
        "dwell_s",
        o.dwell_s,
        "a non-negative time",
    )?;
    check(o.decimals <= 9, "decimals", o.decimals as f64, "0 to 9")?;

    let unit = axis.unit().as_str();
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed);
    let mut out = String::new();
    let r = o.range;
    let _ = writeln!(out, "%");
    let _ = writeln!(
        out,
        "(vcnc identification program: axis {axis}, {} random moves within +-{} {unit}, feeds {}..{} {unit}/s, seed {})",
        o.moves, r, o.min_feed, o.max_feed, o.seed
    );
    let _ = writeln!(
        out,
        "(short strokes {}..{} {unit} with probability {}, long strokes {}..{} {unit}, reversal probability {}; exact stop G61.1)",
        o.short_min,
        o.short_max,
        o.short_fraction,
        o.long_min,
        2.0 * r,
        o.reversal_probability
    );
    let _ = writeln!(out, "G21 G90 G94 G17 G61.1");
    let _ = writeln!(out, "G0 {axis}0");
    let mut x = 0.0f64;
    let mut dir = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    for i in 0..o.moves {
        if i > 0 && rng.random_bool(o.reversal_probability) {
            dir = -dir;
        }
        let short = rng.random_bool(o.short_fraction);
        let mut stroke = if short {
            rng.random_range(o.short_min..=o.short_max)
        } else {
            rng.random_range(o.long_min..=2.0 * r)
        };
        let feed = rng.random_range(o.min_feed..=o.max_feed);
        let room = |d: f64| if d > 0.0 { r - x } else { x + r };
        if stroke > room(dir) {
            if stroke <= room(-dir) {
                dir = -dir;
            } else {
                if room(-dir) > room(dir) {
                    dir = -dir;
                }
                stroke = room(dir);
            }
        }
        let target: f64 = (x + dir * stroke).clamp(-r, r);
        let text = num(target, o.decimals);
        // Use the written value so the program and the generator agree exactly.
        x = text.parse().unwrap_or(target);
        let _ = writeln!(out, "G1 {axis}{text} F{}", num(feed * 60.0, 1));
        if o.dwell_s > 0.0 {
            let _ = writeln!(out, "G4 P{}", num(o.dwell_s, 4));
        }
    }
    let _ = writeln!(out, "M2");
    let _ = writeln!(out, "%");
    Ok(out)
}

/// Tool-tip pose on a path: position and unit tool axis, both in the workpiece frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipPose {
    /// Tool-tip position, mm.
    pub p: [f64; 3],
    /// Unit tool-axis direction (dimensionless), pointing from the tip up the tool.
    pub o: [f64; 3],
}

/// Settings of the spiral (docs/contour.md). Lengths in mm.
#[derive(Debug, Clone, PartialEq)]
pub struct SpiralOptions {
    /// Spiral centre (x, y) in the workpiece frame, mm. Default (30, 20).
    pub centre: [f64; 2],
    /// Dome radius, mm. Default 100.
    pub dome_radius: f64,
    /// z of the dome's sphere centre, mm. Default −50 (so p_z = −50 + √(100² − ρ²)).
    pub dome_centre_z: f64,
    /// Spiral radius at the start, mm. Default 20.
    pub rho_start: f64,
    /// Spiral radius at the end, mm. Default 60.
    pub rho_end: f64,
    /// Number of turns. Default 3.
    pub turns: f64,
    /// Target tip arc length of one segment, mm (the segments are equal in length). Default 0.5.
    pub segment_mm: f64,
}

impl Default for SpiralOptions {
    fn default() -> Self {
        SpiralOptions {
            centre: [30.0, 20.0],
            dome_radius: 100.0,
            dome_centre_z: -50.0,
            rho_start: 20.0,
            rho_end: 60.0,
            turns: 3.0,
            segment_mm: 0.5,
        }
    }
}

/// Points of the spiral (docs/contour.md), equally spaced in tip arc length.
///
/// With $\Theta = 2\pi\,\text{turns}$, $\theta \in [0, \Theta]$ and
/// $\rho = \rho_0 + (\rho_1 - \rho_0)\,\theta/\Theta$:
/// $$ \mathbf{p} = (c_x + \rho\cos\theta,\; c_y + \rho\sin\theta,\; z_c + \sqrt{R^2 - \rho^2}),
///    \qquad \mathbf{o} = (\mathbf{p} - (c_x, c_y, z_c)) / R $$
/// (outward dome normal: tilt $\arccos o_z$ grows from 11.5° to 36.9° with the defaults). The
/// arc length $s(\theta) = \int |\mathbf{p}'|\,d\theta$ is tabulated by Simpson's rule on a grid
/// 64 times finer than the segments and inverted by linear interpolation; the points lie exactly
/// on the curve. Returns `n + 1` points for `n = ⌈L / segment_mm⌉` segments.
pub fn spiral_points(opts: &SpiralOptions) -> Result<Vec<TipPose>, Error> {
    let o = opts;
    check(
        o.dome_radius.is_finite() && o.dome_radius > 0.0,
        "dome_radius",
        o.dome_radius,
        "a positive length",
    )?;
    for (name, rho) in [("rho_start", o.rho_start), ("rho_end", o.rho_end)] {
        check(
            rho.is_finite() && rho >= 0.0 && rho < o.dome_radius,
            name,
            rho,
            "a radius in [0, dome_radius)",
        )?;
    }
    check(
        o.turns.is_finite() && o.turns > 0.0 && o.turns <= 1e4,
        "turns",
        o.turns,
        "a positive number of turns ≤ 10000",
    )?;
    check(
        o.segment_mm.is_finite() && o.segment_mm > 0.0,
        "segment_mm",
        o.segment_mm,
        "a positive length",
    )?;
    for (name, v) in [
        ("centre.x", o.centre[0]),
        ("centre.y", o.centre[1]),
        ("dome_centre_z", o.dome_centre_z),
    ] {
        check(v.is_finite(), name, v, "a finite coordinate")?;
    }
    let big_theta = TAU * o.turns;
    let drho = (o.rho_end - o.rho_start) / big_theta;
    let r2 = o.dome_radius * o.dome_radius;
    let speed = |th: f64| {
        let rho = o.rho_start + drho * th;
        let (s, c) = th.sin_cos();
        let dx = drho * c - rho * s;
        let dy = drho * s + rho * c;
        let dz = -rho * drho / (r2 - rho * rho).sqrt();
        (dx * dx + dy * dy + dz * dz).sqrt()
    };
    // Rough length for the grid size: mean radius times the angle.
    let rough = 0.5 * (o.rho_start + o.rho_end) * big_theta + (o.rho_end - o.rho_start).abs();
    let n_est = (rough / o.segment_mm).ceil().max(1.0);
    check(
        n_est <= 1e7,
        "segment_mm",
        o.segment_mm,
        "a length giving at most 10 million segments",
    )?;
    let grid = (n_est as usize) * 64;
    let h = big_theta / grid as f64;
    let mut cum = Vec::with_capacity(grid + 1);
    cum.push(0.0);
    let mut acc = 0.0;
    for j in 0..grid {
        let a = j as f64 * h;
        acc += h / 6.0 * (speed(a) + 4.0 * speed(a + 0.5 * h) + speed(a + h));
        cum.push(acc);
    }
    let total = acc;
    let n = ((total / o.segment_mm).ceil() as usize).max(1);
    let pose = |th: f64| {
        let rho = o.rho_start + drho * th;
        let (s, c) = th.sin_cos();
        let z = (r2 - rho * rho).sqrt();
        TipPose {
            p: [
                o.centre[0] + rho * c,
                o.centre[1] + rho * s,
                o.dome_centre_z + z,
            ],
            o: [
                rho * c / o.dome_radius,
                rho * s / o.dome_radius,
                z / o.dome_radius,
            ],
        }
    };
    let mut out = Vec::with_capacity(n + 1);
    let mut j = 0usize;
    for i in 0..=n {
        let target = total * i as f64 / n as f64;
        while j + 1 < grid && cum[j + 1] < target {
            j += 1;
        }
        let (c0, c1) = (cum[j], cum[j + 1]);
        let f = if c1 > c0 {
            ((target - c0) / (c1 - c0)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let th = if i == n {
            big_theta
        } else {
            (j as f64 + f) * h
        };
        out.push(pose(th));
    }
    Ok(out)
}

/// Settings of [`tcp_program`].
#[derive(Debug, Clone, PartialEq)]
pub struct TcpProgramOptions {
    /// Feed along the tool-tip path, mm/min. Default 4500 (75 mm/s, docs/contour.md).
    pub feed_mm_per_min: f64,
    /// Decimals written for positions (mm) and angles (deg). Default 5.
    pub decimals: usize,
    /// First header comment (parentheses are replaced). Default "vcnc 5-axis spiral (docs/contour.md)".
    pub title: String,
}

impl Default for TcpProgramOptions {
    fn default() -> Self {
        TcpProgramOptions {
            feed_mm_per_min: 4500.0,
            decimals: 5,
            title: "vcnc 5-axis spiral (docs/contour.md)".to_string(),
        }
    }
}

/// A tool-centre-point program through `points`: each is (tool tip in the workpiece frame, mm;
/// A angle, deg; C angle, deg). The angles come from inverse kinematics elsewhere.
///
/// Layout: header comments, `G21 G90 G94 G17 G64`, `G43.4`, the opening positioning block
/// `G0` at the first point (it defines the start, see [`crate::interp`]), then one `G1` per
/// further point at `F`, then `G49` and `M2`.
pub fn tcp_program(
    points: &[([f64; 3], f64, f64)],
    opts: &TcpProgramOptions,
) -> Result<String, Error> {
    check(!points.is_empty(), "points", 0.0, "at least one point")?;
    check(
        opts.feed_mm_per_min.is_finite() && opts.feed_mm_per_min > 0.0,
        "feed_mm_per_min",
        opts.feed_mm_per_min,
        "a positive feed",
    )?;
    check(
        opts.decimals <= 9,
        "decimals",
        opts.decimals as f64,
        "0 to 9",
    )?;
    for (p, a, c) in points {
        for v in [p[0], p[1], p[2], *a, *c] {
            check(v.is_finite(), "points", v, "finite coordinates")?;
        }
    }
    let d = opts.decimals;
    let title: String = opts
        .title
        .chars()
        .map(|c| match c {
            '(' | ')' | '\n' | '\r' => ' ',
            c => c,
        })
        .collect();
    let mut out = String::with_capacity(points.len() * 64 + 512);
    let _ = writeln!(out, "%");
    let _ = writeln!(out, "({title})");
    let _ = writeln!(
        out,
        "(tool-centre-point program: X Y Z = tool tip in the workpiece frame, mm; A C = rotary axes, deg)"
    );
    let _ = writeln!(
        out,
        "({} points, feed {} mm/min along the tool-tip path, continuous path G64)",
        points.len(),
        num(opts.feed_mm_per_min, 1)
    );
    let _ = writeln!(out, "G21 G90 G94 G17 G64");
    let _ = writeln!(out, "G43.4");
    for (i, (p, a, c)) in points.iter().enumerate() {
        let (code, feed) = if i == 0 {
            ("G0", String::new())
        } else if i == 1 {
            ("G1", format!(" F{}", num(opts.feed_mm_per_min, 1)))
        } else {
            ("G1", String::new())
        };
        let _ = writeln!(
            out,
            "{code} X{} Y{} Z{} A{} C{}{feed}",
            num(p[0], d),
            num(p[1], d),
            num(p[2], d),
            num(*a, d),
            num(*c, d)
        );
    }
    let _ = writeln!(out, "G49");
    let _ = writeln!(out, "M2");
    let _ = writeln!(out, "%");
    Ok(out)
}
