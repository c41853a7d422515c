//! Program → axis references: parse, interpret and interpolate a program on a machine, turn
//! tool-centre-point samples into machine-axis references, check travel, and compute the
//! reference tool poses.

use std::path::Path;

use vcnc_axis::{AxisName, Unit};
use vcnc_drive::Reference;
use vcnc_gcode::{Diagnostic, Loaded, MoveClass, Severity};
use vcnc_kinematics::Pose;
use vcnc_machine::Machine;

use crate::Error;

/// Reference signals of one machine axis, at the sample period (axis units, units/s, units/s²).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisSignals {
    /// The axis.
    pub name: AxisName,
    /// mm or deg.
    pub unit: Unit,
    /// Position.
    pub pos: Vec<f64>,
    /// Velocity (analytic, from the profile and the kinematics' derivatives).
    pub vel: Vec<f64>,
    /// Acceleration (analytic).
    pub acc: Vec<f64>,
}

impl AxisSignals {
    /// As a drive/model reference.
    pub fn reference(&self) -> Reference<'_> {
        Reference {
            pos: &self.pos,
            vel: &self.vel,
            acc: &self.acc,
        }
    }
}

/// A program prepared for a machine: interpolated, turned into axis references, checked against
/// travel.
#[derive(Debug, Clone)]
pub struct Run {
    /// The program's path (for messages).
    pub file: String,
    /// Parse tree, moves, trajectory and warnings. The trajectory's axis tracks are empty:
    /// their samples were moved into [`Run::axes`].
    pub loaded: Loaded,
    /// Sample period, s.
    pub ts: f64,
    /// Axis references in machine order (one per [`Machine::axes`]).
    pub axes: Vec<AxisSignals>,
    /// Warnings for the user (G-code warnings, limit excursions of IK'd references).
    pub warnings: Vec<String>,
    /// Per sample: the source line of the block running (0 where none is, e.g. before the
    /// first move).
    pub lines: Vec<u32>,
    /// Per sample: the kind of move running (rapid, feed, dwell; `None` before the first
    /// move).
    pub classes: Vec<Option<MoveClass>>,
}

/// Which samples the contour statistics cover.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Measured {
    /// Feed moves only (G1 G2 G3 and the feed parts of cycles): what is cut (the default).
    #[default]
    Feed,
    /// Every sample, rapids and dwells included.
    All,
}

impl Measured {
    /// How a summary names it: `feed` or `all`.
    pub fn label(self) -> &'static str {
        match self {
            Measured::Feed => "feed",
            Measured::All => "all",
        }
    }

    /// Per sample of the move classes `classes`: whether the statistics count it.
    pub fn mask(self, classes: &[Option<MoveClass>]) -> Vec<bool> {
        match self {
            Measured::All => vec![true; classes.len()],
            Measured::Feed => classes
                .iter()
                .map(|c| *c == Some(MoveClass::Feed))
                .collect(),
        }
    }
}

impl Run {
    /// Per sample: whether the contour statistics count it.
    pub fn measured(&self, which: Measured) -> Vec<bool> {
        which.mask(&self.classes)
    }
    /// Whether the program moves at all (a feed move or a rapid of some length).
    pub fn has_motion(&self) -> bool {
        moves(&self.loaded.trajectory.cycle)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.axes.first().map_or(0, |a| a.pos.len())
    }

    /// True if the run has no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Time of sample k, s.
    pub fn time(&self, k: usize) -> f64 {
        k as f64 * self.ts
    }

    /// Times of every sample, s.
    pub fn times(&self) -> Vec<f64> {
        (0..self.len()).map(|k| self.time(k)).collect()
    }

    /// Duration of the program, s.
    pub fn duration_s(&self) -> f64 {
        self.loaded.trajectory.duration_s()
    }

    /// The axis reference positions per machine axis (mm, deg).
    pub fn reference_positions(&self) -> Vec<&[f64]> {
        self.axes.iter().map(|a| a.pos.as_slice()).collect()
    }

    /// Reference tool poses in the workpiece frame (mm, unit tool axis) of the samples `rows`,
    /// by the closed-form forward kinematics of the axis references. A run keeps axis
    /// references, not poses: they are computed where they are used, a chunk at a time on a
    /// long run (docs/performance.md). Error: the machine has no kinematics.
    pub fn reference_poses_at(
        &self,
        machine: &Machine,
        rows: std::ops::Range<usize>,
    ) -> Result<Vec<Pose>, Error> {
        let kin = machine.require_kinematics()?;
        let pos = self.reference_positions();
        Ok(rows.map(|k| kin.pose_at(&pos, k)).collect())
    }

    /// [`Run::reference_poses_at`] of every sample.
    pub fn reference_poses(&self, machine: &Machine) -> Result<Vec<Pose>, Error> {
        self.reference_poses_at(machine, 0..self.len())
    }

    /// The reference tool path of the contour search, built from the poses computed one at a
    /// time (never held whole).
    pub fn reference_path(&self, machine: &Machine) -> Result<vcnc_contour::ContourPath, Error> {
        let kin = machine.require_kinematics()?;
        let pos = self.reference_positions();
        let poses = (0..self.len()).map(|k| kin.pose_at(&pos, k));
        Ok(vcnc_contour::ContourPath::from_poses(poses)?)
    }

    /// True when some samples are in tool-centre-point mode.
    pub fn has_tcp(&self) -> bool {
        self.loaded.trajectory.tcp.iter().any(|t| *t)
    }
}

/// Memory a program needs to be prepared, bytes per byte of G-code: the text, its syntax tree,
/// the interpreted moves and the samples together, measured on `vcnc gen long` programs of
/// short five-axis segments (64 MB of G-code peak at 1.06 GB in `vcnc interpolate`,
/// docs/performance.md). The parser and the interpreter hold the whole program: they do not
/// stream yet.
pub const PROGRAM_MEMORY_PER_BYTE: u64 = 17;

/// Memory the system can still give this process, bytes (`MemAvailable` of `/proc/meminfo`),
/// where the system says.
fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kb.checked_mul(1024)
}

/// Lines of the file at `path` with something other than white space on them (each is a block
/// for the parser), counted a megabyte at a time.
fn non_blank_lines(path: &Path) -> std::io::Result<usize> {
    use std::io::Read;
    let mut f = std::fs::File::open(path)?;
    let mut buf = vec![0u8; 1 << 20];
    let (mut lines, mut filled) = (0usize, false);
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        for &b in &buf[..n] {
            if b == b'\n' {
                lines += usize::from(filled);
                filled = false;
            } else if !b.is_ascii_whitespace() {
                filled = true;
            }
        }
    }
    Ok(lines + usize::from(filled))
}

/// Reads a program file (lossy UTF-8: the parser reports the replacement characters).
///
/// A program of any size is read, unless preparing it would need more memory than the system
/// has available ([`PROGRAM_MEMORY_PER_BYTE`] times its size against `MemAvailable`): then it
/// is refused up front, with both figures, instead of failing gigabytes later.
pub fn read_program(path: &Path) -> Result<String, Error> {
    let cannot = |e: std::io::Error| Error::Io {
        file: path.display().to_string(),
        message: e.to_string(),
    };
    let size = std::fs::metadata(path).map_err(cannot)?.len();
    let need = size.saturating_mul(PROGRAM_MEMORY_PER_BYTE);
    if let Some(available) = available_memory()
        && need > available
    {
        return Err(Error::ProgramTooLarge {
            file: path.display().to_string(),
            bytes: size,
            need_bytes: need,
            available_bytes: available,
        });
    }
    // The parser stops at its block limit; a longer program is refused before it is read.
    // A non-blank line takes at least two bytes but the last, so only a file of more than
    // 2 × max_blocks − 1 bytes can hold too many, and only such a file is counted (the count
    // reads it once more).
    let max_blocks = vcnc_gcode::ParseOptions::default().max_blocks;
    let could_exceed = size.div_ceil(2) > max_blocks as u64;
    let lines = if could_exceed {
        non_blank_lines(path).map_err(cannot)?
    } else {
        0
    };
    if lines > max_blocks {
        return Err(Error::TooManyBlocks {
            file: path.display().to_string(),
            lines,
            max: max_blocks,
        });
    }
    let bytes = std::fs::read(path).map_err(cannot)?;
    // Valid UTF-8 is taken as it is (no copy); otherwise the lossy copy.
    Ok(String::from_utf8(bytes)
        .unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into_owned()))
}

/// Reads the program at `path` and prepares it on `machine` ([`prepare`]).
pub fn prepare_file(machine: &Machine, path: &Path, lenient: bool) -> Result<Run, Error> {
    let src = read_program(path)?;
    prepare(machine, &src, &path.display().to_string(), lenient)
}

/// Whether a program with this cycle time moves at all (a feed move or a rapid of some length).
pub(crate) fn moves(cycle: &vcnc_gcode::CycleTime) -> bool {
    cycle.feed_s + cycle.rapid_s > 0.0
}

/// The warning of a program that moves no axis (empty, or only modal codes and dwells).
pub(crate) fn no_motion_warning(file: &str) -> String {
    format!(
        "{file}: warning: the program moves no axis (empty, or no G0/G1/G2/G3 move of any length)"
    )
}

/// Reads the LinuxCNC tool table (`.tbl`) at `path`, for [`Machine::tools`]: every line
/// checked, an error names the file and line ([`vcnc_gcode::parse_tool_table`]).
pub fn load_tool_table(path: &Path) -> Result<vcnc_gcode::ToolTable, Error> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
        file: file.clone(),
        message: e.to_string(),
    })?;
    vcnc_gcode::parse_tool_table(&text, &file).map_err(Error::ToolTable)
}

/// Interpolates `src` (the program at `file`) on `machine` and prepares the axis references.
///
/// In TCP mode (G43.4) the trajectory carries the tool tip in the workpiece frame and the rotary
/// angles; inverse kinematics turns every sample into X Y Z with analytic velocity and
/// acceleration ([`vcnc_kinematics::Kinematics::inverse_tcp_track`]). Every sample is
/// checked against the axis travels.
pub fn prepare(machine: &Machine, src: &str, file: &str, lenient: bool) -> Result<Run, Error> {
    let interp = machine.interp_options(lenient);
    let (program, toolpath, diags) =
        vcnc_gcode::parse_and_interpret(src, &interp).map_err(|e| Error::gcode(file, e))?;
    check_axes_exist(machine, &toolpath, file)?;
    let mut loaded = vcnc_gcode::load_toolpath(
        program,
        toolpath,
        diags,
        &machine.limits(),
        &machine.interpolate_options(),
    )
    .map_err(|e| Error::gcode(file, e))?;
    let mut warnings: Vec<String> = loaded
        .warnings
        .iter()
        .map(|d| format!("{file}:{}:{}: warning: {}", d.line, d.col, d.message))
        .collect();
    if !moves(&loaded.trajectory.cycle) {
        warnings.push(no_motion_warning(file));
    }
    let mut axes = take_axis_signals(machine, &mut loaded.trajectory);
    let traj = &loaded.trajectory;
    let any_tcp = traj.tcp.iter().any(|t| *t);
    if any_tcp {
        let kin = machine.require_kinematics()?;
        let mut take = |f: fn(&mut AxisSignals) -> &mut Vec<f64>| -> Vec<Vec<f64>> {
            axes.iter_mut().map(|a| std::mem::take(f(a))).collect()
        };
        let (mut pos, mut vel, mut acc) = (
            take(|a| &mut a.pos),
            take(|a| &mut a.vel),
            take(|a| &mut a.acc),
        );
        kin.inverse_tcp(&mut pos, &mut vel, &mut acc, &traj.tcp)
            .map_err(|source| Error::Kinematics {
                context: file.to_string(),
                source,
            })?;
        for (a, ((p, v), ac)) in axes.iter_mut().zip(pos.into_iter().zip(vel).zip(acc)) {
            (a.pos, a.vel, a.acc) = (p, v, ac);
        }
    }
    for (a, s) in machine.axes.iter().zip(&axes) {
        check_travel(a, s, &loaded, file)?;
        if any_tcp {
            warnings.extend(limit_warnings(a, s, file));
        }
    }
    let (lines, classes) = traj
        .sample_spans()
        .map(|i| {
            i.and_then(|i| traj.blocks.get(i))
                .map_or((0, None), |b| (b.line, Some(b.class)))
        })
        .unzip();
    Ok(Run {
        file: file.to_string(),
        ts: traj.ts,
        loaded,
        axes,
        warnings,
        lines,
        classes,
    })
}

/// The machine axes' references, moved out of the trajectory's tracks (an axis the program
/// never names stays at 0). Every track is left empty afterwards, so that a long run holds its
/// samples once, in [`Run::axes`] (docs/performance.md).
fn take_axis_signals(machine: &Machine, traj: &mut vcnc_gcode::Trajectory) -> Vec<AxisSignals> {
    let n = traj.len();
    let axes = machine
        .axes
        .iter()
        .map(|a| {
            let t = traj.axes.iter_mut().find(|t| t.name == a.name);
            let (pos, vel, acc) = match t {
                Some(t) => (
                    std::mem::take(&mut t.pos),
                    std::mem::take(&mut t.vel),
                    std::mem::take(&mut t.acc),
                ),
                None => (vec![0.0; n], vec![0.0; n], vec![0.0; n]),
            };
            AxisSignals {
                name: a.name,
                unit: a.unit,
                pos,
                vel,
                acc,
            }
        })
        .collect();
    for t in &mut traj.axes {
        t.pos = Vec::new();
        t.vel = Vec::new();
        t.acc = Vec::new();
    }
    axes
}

/// Axes the program moves but the machine lacks: a clear error before interpolation.
fn check_axes_exist(
    machine: &Machine,
    toolpath: &vcnc_gcode::Toolpath,
    file: &str,
) -> Result<(), Error> {
    for m in &toolpath.moves {
        for name in AxisName::ALL {
            let i = name.index();
            if m.end[i] != m.start[i] && machine.axis(name).is_none() {
                return Err(missing_axis(machine, file, name, m.line, m.col));
            }
        }
    }
    Ok(())
}

/// The first sample of `s` beyond the axis' travel, as an error naming the block.
fn check_travel(
    a: &vcnc_machine::Axis,
    s: &AxisSignals,
    loaded: &Loaded,
    file: &str,
) -> Result<(), Error> {
    let [lo, hi] = a.travel;
    let Some(k) = s.pos.iter().position(|v| !(*v >= lo && *v <= hi)) else {
        return Ok(());
    };
    let traj = &loaded.trajectory;
    let block = traj.block_at(k);
    let target = block
        .filter(|b| !b.tcp)
        .and_then(|b| loaded.toolpath.moves.get(b.move_index))
        .map(|m| m.end[a.name.index()]);
    Err(Error::Travel {
        file: file.to_string(),
        line: block.map_or(0, |b| b.line),
        axis: a.name,
        value: s.pos[k],
        lower: lo,
        upper: hi,
        unit: a.unit.as_str(),
        t_s: k as f64 * traj.ts,
        target,
    })
}

/// Velocity and acceleration limit excursions of a kinematically transformed reference.
fn limit_warnings(a: &vcnc_machine::Axis, s: &AxisSignals, file: &str) -> Vec<String> {
    let vmax = s.vel.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let amax = s.acc.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    peak_warnings(a, vmax, amax, file)
}

/// The warnings for an axis reference peaking at `vmax` and `amax` (units/s, units/s²) above
/// the axis' limits.
pub(crate) fn peak_warnings(
    a: &vcnc_machine::Axis,
    vmax: f64,
    amax: f64,
    file: &str,
) -> Vec<String> {
    let u = a.unit;
    let mut w = Vec::new();
    if vmax > a.max_velocity * (1.0 + 1e-9) {
        w.push(format!(
            "{file}: warning: axis {} reference reaches {vmax:.1} {u}/s, above its velocity limit {} {u}/s",
            a.name, a.max_velocity,
        ));
    }
    if amax > a.max_acceleration * (1.0 + 1e-9) {
        w.push(format!(
            "{file}: warning: axis {} reference reaches {amax:.1} {u}/s², above its acceleration limit {} {u}/s²",
            a.name, a.max_acceleration,
        ));
    }
    w
}

/// The error of a program moving an axis `machine` lacks, at `line`:`col` of `file`.
pub(crate) fn missing_axis(
    machine: &Machine,
    file: &str,
    name: AxisName,
    line: u32,
    col: u32,
) -> Error {
    Error::Program {
        file: file.to_string(),
        diagnostics: vec![Diagnostic {
            line,
            col,
            severity: Severity::Error,
            kind: vcnc_gcode::DiagnosticKind::Motion,
            message: format!(
                "the program moves axis {name}, which machine \"{}\" does not have (axes: {})",
                machine.name,
                machine
                    .axis_names()
                    .iter()
                    .map(|a| a.as_str())
                    .collect::<String>()
            ),
        }],
    }
}

/// Tool poses in the workpiece frame (mm, unit tool axis) of axis positions given per machine
/// axis (mm, deg), by the closed-form forward kinematics.
pub fn forward_poses(machine: &Machine, axis_pos: &[&[f64]]) -> Result<Vec<Pose>, Error> {
    let kin = machine.require_kinematics()?;
    let n = axis_pos.first().map_or(0, |p| p.len());
    Ok((0..n).map(|k| kin.pose_at(axis_pos, k)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Truth: the parser's block limit (`ParseOptions::max_blocks`). Blank lines are not
    /// blocks; a program one block over the limit is refused before it is read, naming the
    /// count; one at the limit is read.
    #[test]
    fn programs_over_the_block_limit_are_refused_up_front() {
        let dir = std::env::temp_dir().join(format!("vcnc-run-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("p.ngc");
        std::fs::write(&path, "G1 X1\n\n  \r\n; c\n(x)").unwrap();
        assert_eq!(non_blank_lines(&path).unwrap(), 3);
        let max = vcnc_gcode::ParseOptions::default().max_blocks;
        let mut text = "G0\n\n".repeat(max);
        std::fs::write(&path, &text).unwrap();
        assert_eq!(read_program(&path).unwrap().len(), text.len());
        text.push_str("M2");
        std::fs::write(&path, &text).unwrap();
        let e = read_program(&path).unwrap_err().to_string();
        assert!(
            e.contains(&format!("{} non-blank lines", max + 1)) && e.contains(&max.to_string()),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The one-pass walk agrees with `Trajectory::block_at` at every sample a move covers (a
    /// dwell is a move of its own, on its `G4` line), and gives every sample a line.
    #[test]
    fn sample_lines_agree_with_block_at() {
        let machine = Machine::embedded_nmv5000().unwrap();
        let src = "G0 X0 Y0 Z0 A0 C0\nG1 X10 F600\nG4 P0.5\nG1 Y10\nG1 X0 Y0\nM2\n";
        let run = prepare(&machine, src, "t.ngc", false).unwrap();
        let lines = &run.lines;
        assert_eq!(lines.len(), run.len());
        let traj = &run.loaded.trajectory;
        for (k, l) in lines.iter().enumerate() {
            if let Some(b) = traj.block_at(k) {
                assert_eq!(*l, b.line, "sample {k}");
            }
        }
        // The dwell holds for 0.5 s: that many samples of line 3, give or take its ends.
        let dwell = lines.iter().filter(|l| **l == 3).count() as i64;
        assert!(
            ((dwell as f64) * run.ts - 0.5).abs() <= 2.0 * run.ts,
            "{dwell} dwell samples"
        );
        for want in [2, 3, 4, 5] {
            assert!(lines.contains(&want), "line {want} missing");
        }
        assert!(lines.iter().all(|l| *l != 0));
        let spiral = prepare(&machine, vcnc_machine::embedded::SPIRAL_NGC, "s.ngc", false).unwrap();
        let sl = &spiral.lines;
        for (k, l) in sl.iter().enumerate() {
            if let Some(b) = spiral.loaded.trajectory.block_at(k) {
                assert_eq!(*l, b.line, "spiral sample {k}");
            }
        }
    }
}
