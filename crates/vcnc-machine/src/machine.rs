//! The checked machine: raw [`MachineFile`] → [`Machine`] (ripgrep's LowArgs → HiArgs split).
//!
//! [`MachineDocument`] is a machine file as read (its TOML table, its text when it has one, and
//! where relative paths resolve); [`MachineDocument::check`] checks it section by section into a
//! [`Machine`] that holds only checked values, with every look-up the pipeline needs resolved at
//! load time (the drives, the kinematics and which machine axis plays X Y Z A C), so no look-up
//! can fail after loading. Sweeps set keys in the document's table and check it again
//! ([`MachineDocument::with_values`]).

use std::path::{Path, PathBuf};

use vcnc_axis::{AxisName, Unit};
use vcnc_drive::{ClosedLoopModel, Drive, DriveModel, DriveParams, NominalFilter, ShapingFilter};
use vcnc_gcode::{
    AxisLimits as GcodeAxisLimits, FINE_BLOCK_MAX_SAMPLES, InterpOptions, InterpolateOptions,
    Limits, PathMode, PlannerRules, Profile, ToolTable, write::BlockRules,
};
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{
    Axes, AxisLimits as Travels, AxisMap, Branch, Family, IkOptions, KinematicChain,
    KinematicsParams, Pose, TableTilting, Tilt, Track, Travel,
};

use crate::file::{
    AxisFile, ControlFile, ControlFilterFile, FamilyFile, GcodeFile, IdentificationFile,
    KinematicsFile, MachineFile, PlannerFile, ProfileFile, ProgramFile, ProgramOutputFile,
    TiltFile, TrajectoryFile,
};
use crate::locate::{error_offset, line_col, locate_key};
use crate::options_file::OptionsFile;
use crate::{Error, MachineModels, ModelSet, embedded};

/// One checked axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// The axis.
    pub name: AxisName,
    /// mm or deg.
    pub unit: Unit,
    /// Travel `[lower, upper]`, axis units.
    pub travel: [f64; 2],
    /// Velocity limit, units/s.
    pub max_velocity: f64,
    /// Acceleration limit, units/s².
    pub max_acceleration: f64,
    /// Jerk limit, units/s³ (`None`: none).
    pub max_jerk: Option<f64>,
    /// What moves the axis in a run: its virtual drive, or only its identified model.
    pub dynamics: Dynamics,
    /// Half-range of this axis' identification moves, axis units.
    pub identification_range: f64,
    /// Centre of this axis' identification moves (a work offset), axis units.
    pub identification_centre: f64,
    /// Where the axis is when a program starts, axis units (machine coordinates).
    pub start: f64,
}

/// What moves an axis in a run (docs/machine-file.md#a-machine-made-of-identified-models).
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)] // one per axis, built once: boxing the drive buys nothing
pub enum Dynamics {
    /// A virtual drive built from the axis' plant and controller (validated: stable, gains
    /// resolved): the true machine of virtual experiments.
    Drive(Drive),
    /// Only an identified model (the machine file's `model`): there is no true machine behind
    /// the axis, and what the model predicts is the result.
    Model(DriveModel),
}

impl Axis {
    /// The virtual drive, or `None` for an axis known only by its identified model.
    pub fn drive(&self) -> Option<&Drive> {
        match &self.dynamics {
            Dynamics::Drive(d) => Some(d),
            Dynamics::Model(_) => None,
        }
    }

    /// The virtual drive, or an error saying that `what` needs one and this axis of `machine`
    /// is known only by its identified model.
    pub fn require_drive(&self, machine: &Machine, what: &str) -> Result<&Drive, Error> {
        self.drive().ok_or_else(|| Error::NoDrive {
            file: machine.source.clone(),
            axis: self.name,
            what: what.to_string(),
        })
    }

    /// What controls the axis, as summaries print it: the virtual drive's controller kind
    /// (`p-pi`, `pid`, `smc`), or `model` for an axis known by its identified model.
    pub fn controller_kind(&self) -> &'static str {
        match &self.dynamics {
            Dynamics::Drive(d) => d.controller().kind(),
            Dynamics::Model(_) => "model",
        }
    }

    /// The analytic closed-loop model of the axis (docs/drive-model.md): the virtual drive's,
    /// or the 7-parameter core of the identified model.
    pub fn true_model(&self) -> ClosedLoopModel {
        match &self.dynamics {
            Dynamics::Drive(d) => d.closed_loop_model(),
            Dynamics::Model(m) => m.core,
        }
    }

    /// The actual-value latency of this axis' control as its configuration states it, s: the
    /// position loop's dead time, `feedback.dead_time_cycles` servo cycles of
    /// $1/f_\text{servo}$ — the logged actual position is the reading the loop used, that many
    /// cycles old (docs/machine-file.md#feedback). 0 without a dead time. What a model file's
    /// `actual_latency_s` states for models identified on this machine
    /// (docs/drive-model.md#actual-value-latency). For an axis known by its model, the model's
    /// stated latency.
    pub fn actual_latency_s(&self) -> f64 {
        let drive = match &self.dynamics {
            Dynamics::Drive(d) => d,
            Dynamics::Model(m) => return m.actual_latency_s,
        };
        let cycles = drive.params().feedback.map_or(0, |f| f.dead_time_cycles);
        if cycles == 0 {
            0.0
        } else {
            f64::from(cycles) / drive.servo_rate_hz()
        }
    }
}

/// The checked kinematics of a machine, whatever its family (docs/kinematics.md): the model,
/// which machine axes it reads, and the branch for poses given without axes. The pipeline
/// talks only to these methods and never matches on the family.
#[derive(Debug, Clone, PartialEq)]
pub struct Kinematics {
    /// The model (mm, rad) with the file's offsets and the axes' travels.
    pub model: vcnc_kinematics::Kinematics,
    /// Which machine axis plays each axis of the model.
    pub map: AxisMap,
    /// Inverse-kinematics branch (the sign of the tilt) for poses given without axes.
    pub branch: Branch,
    /// The machine axes (indices into [`Machine::axes`]) in the model's order: X Y Z, then the
    /// rotary axes in the order A B C.
    axes: Vec<usize>,
}

impl Kinematics {
    /// The kinematics `model` on a machine with `axes`, or the model's error when the machine
    /// lacks an axis it needs.
    fn new(
        model: vcnc_kinematics::Kinematics,
        axes: &[Axis],
        branch: Branch,
    ) -> Result<Kinematics, vcnc_kinematics::Error> {
        let names: Vec<AxisName> = axes.iter().map(|a| a.name).collect();
        let map = AxisMap::new(&model, &names)?;
        let order = model
            .axes()
            .into_iter()
            .filter_map(|n| map.index(n))
            .collect();
        Ok(Kinematics {
            model,
            map,
            branch,
            axes: order,
        })
    }

    /// The family (3-axis, table-tilting A/C, ...).
    pub fn family(&self) -> Family {
        self.model.family()
    }

    /// The axes the kinematics reads, in its order: X Y Z, then the rotary axes (A B C order).
    pub fn axis_names(&self) -> Vec<AxisName> {
        self.model.axes()
    }

    /// The machine axes (indices into [`Machine::axes`]) in the kinematics' order
    /// ([`Kinematics::axis_names`]).
    pub fn machine_axes(&self) -> &[usize] {
        &self.axes
    }

    /// The tool pose (workpiece frame: tip in mm, unit tool axis) at sample `k` of axis
    /// positions given per machine axis (mm, deg), by the forward kinematics.
    pub fn pose_at<P: AsRef<[f64]>>(&self, positions: &[P], k: usize) -> Pose {
        self.model.forward(&self.map.at(positions, k))
    }

    /// Tool-centre-point samples to machine-axis references, in place. Per machine axis,
    /// `pos`, `vel` and `acc` hold the samples of one piece (mm, deg, per s, per s²); where
    /// `tcp[k]` is true the linear axes hold the tool tip in the workpiece frame and become the
    /// machine axes that put it there, with the analytic derivatives of the chain rule. Every
    /// sample is transformed on its own, so pieces of any length give the whole run's values.
    /// Error: a chain whose slides cannot reach the tip (the sample is in the error).
    pub fn inverse_tcp(
        &self,
        pos: &mut [Vec<f64>],
        vel: &mut [Vec<f64>],
        acc: &mut [Vec<f64>],
        tcp: &[bool],
    ) -> Result<(), vcnc_kinematics::Error> {
        let track = |i: usize| Track {
            pos: &pos[i],
            vel: &vel[i],
            acc: &acc[i],
        };
        let slides = [self.axes[0], self.axes[1], self.axes[2]];
        let rotary: Vec<Track<'_>> = self.axes[3..].iter().map(|i| track(*i)).collect();
        let out = self
            .model
            .inverse_tcp_track(slides.map(track), &rotary, tcp)?;
        for (i, t) in slides.into_iter().zip(out) {
            pos[i] = t.pos;
            vel[i] = t.vel;
            acc[i] = t.acc;
        }
        Ok(())
    }

    /// The tool pose of one set of axis values given in the kinematics' own order
    /// ([`Kinematics::axis_names`]: X Y Z mm, rotary axes deg). Missing values are 0.
    pub fn pose_of(&self, values: &[f64]) -> Pose {
        let mut j = Axes::default();
        for (name, v) in self.axis_names().into_iter().zip(values) {
            j[name] = if name.is_rotary() { v.to_radians() } else { *v };
        }
        self.model.forward(&j)
    }

    /// Inverse kinematics of a sequence of poses on `branch` (the machine file's when
    /// `None`), the rotary axes unwound continuously from pose to pose: per pose the axis
    /// values in the kinematics' order ([`Kinematics::axis_names`]: X Y Z mm, rotary deg).
    pub fn inverse_poses(
        &self,
        poses: &[Pose],
        branch: Option<Branch>,
    ) -> Result<Vec<Vec<f64>>, vcnc_kinematics::Error> {
        let opts = IkOptions {
            branch: Some(branch.unwrap_or(self.branch)),
            ..IkOptions::default()
        };
        let sol = self.model.inverse_sequence(poses, &opts)?;
        let names = self.axis_names();
        Ok(sol
            .axes
            .iter()
            .map(|j| {
                names
                    .iter()
                    .map(|n| {
                        if n.is_rotary() {
                            j[*n].to_degrees()
                        } else {
                            j[*n]
                        }
                    })
                    .collect()
            })
            .collect())
    }
}

/// The identification settings, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct IdentificationSettings {
    /// The excitation program.
    pub program: ProgramFile,
    /// The identifier options (the same type as an `--options` file).
    pub options: OptionsFile,
}

/// A checked machine. Build it with [`Machine::load`], [`Machine::from_toml_str`] or
/// [`MachineDocument::check`].
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    /// Machine name.
    pub name: String,
    /// Where it was read from (for messages).
    pub source: String,
    /// Sample period $T_s$, s.
    pub ts: f64,
    /// Axes in the canonical order X Y Z A B C.
    pub axes: Vec<Axis>,
    /// The kinematics, when the file has `[kinematics]` or the machine is a plain X Y Z one.
    pub kinematics: Option<Kinematics>,
    /// Tool-tip path velocity limit, mm/s.
    pub tcp_max_vel: f64,
    /// Tool-tip path acceleration limit, mm/s².
    pub tcp_max_acc: f64,
    /// Tool-tip path jerk limit, mm/s³ (`None`: none).
    pub tcp_max_jerk: Option<f64>,
    /// Blend tolerance of a plain `G64`, mm (`None`: LinuxCNC 2.9's rule).
    pub blend_tolerance: Option<f64>,
    /// Speed profile.
    pub profile: Profile,
    /// Planner rules.
    pub planner: PlannerRules,
    /// M-codes switching TCP on / off.
    pub tcp_mcodes: (Vec<u32>, Vec<u32>),
    /// The path mode before the program sets one.
    pub startup_path_mode: PathMode,
    /// Identification program and identifier settings.
    pub identification: IdentificationSettings,
    /// Tools for `G43 H` (a LinuxCNC `.tbl` given on the command line; empty by default).
    pub tools: ToolTable,
    /// The identified model file the axes without a plant take their dynamics from (the
    /// machine file's `model`, resolved), when the file names one.
    pub model_file: Option<String>,
    /// How programs for the control are written (`[program_output]`).
    pub program_output: BlockRules,
    /// The control's nominal-position filter chain between the interpolator and the drives
    /// (`[control]`); `None` when it has no delay and no filter.
    pub control: Option<NominalFilter>,
}

/// Where relative paths of a machine file resolve.
#[derive(Debug, Clone, PartialEq)]
enum Base {
    /// Compiled into the binary.
    Embedded,
    /// A folder on disk.
    Dir(PathBuf),
}

/// A machine file as read: its TOML table, its text (for line numbers in messages; absent once
/// keys are set programmatically), its name and where its relative paths resolve.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineDocument {
    /// The name used in messages (the path, or `<embedded>/…`).
    pub source: String,
    text: Option<String>,
    table: toml::Table,
    base: Base,
}

impl MachineDocument {
    /// Reads a machine file (not yet checked).
    pub fn load(path: &Path) -> Result<MachineDocument, Error> {
        let (file, src) = crate::read_text(path)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        MachineDocument::from_toml_str(&src, &file, &base)
    }

    /// A machine file given as text; `source` names it in messages, `base_dir` resolves its
    /// URDF path. Only TOML syntax is checked here.
    pub fn from_toml_str(
        src: &str,
        source: &str,
        base_dir: &Path,
    ) -> Result<MachineDocument, Error> {
        MachineDocument::new(src, source, Base::Dir(base_dir.to_path_buf()))
    }

    /// The embedded NMV5000 (its URDF is embedded too).
    pub fn embedded_nmv5000() -> Result<MachineDocument, Error> {
        MachineDocument::new(
            embedded::NMV5000_TOML,
            "<embedded>/machines/nmv5000.toml",
            Base::Embedded,
        )
    }

    /// The embedded realistic NMV5000 (machines/nmv5000-realistic.toml; its URDF is the
    /// embedded NMV5000's).
    pub fn embedded_nmv5000_realistic() -> Result<MachineDocument, Error> {
        MachineDocument::new(
            embedded::NMV5000_REALISTIC_TOML,
            "<embedded>/machines/nmv5000-realistic.toml",
            Base::Embedded,
        )
    }

    fn new(src: &str, source: &str, base: Base) -> Result<MachineDocument, Error> {
        let table: toml::Table = toml::from_str(src).map_err(|e| toml_error(src, source, &e))?;
        Ok(MachineDocument {
            source: source.to_string(),
            text: Some(src.to_string()),
            table,
            base,
        })
    }

    /// Checks the document into a machine. Errors name the file, line and key.
    pub fn check(&self) -> Result<Machine, Error> {
        let file: MachineFile = match &self.text {
            Some(src) => toml::from_str(src).map_err(|e| toml_error(src, &self.source, &e))?,
            None => toml::Value::Table(self.table.clone()).try_into().map_err(
                |e: toml::de::Error| Error::Invalid {
                    file: self.source.clone(),
                    at: None,
                    key: String::new(),
                    message: e.message().to_string(),
                },
            )?,
        };
        Checker { doc: self }.machine(file)
    }

    /// The machine with numeric keys set by their dotted paths (`axes.X.controller.kv`), then
    /// checked. Errors carry no line numbers (the keys were not written in the file).
    pub fn with_values(&self, values: &[(&str, f64)]) -> Result<Machine, Error> {
        let mut doc = self.clone();
        doc.text = None;
        for (key, value) in values {
            crate::sweep::set_key(&mut doc.table, key, *value).map_err(|e| match e {
                Error::Invalid {
                    at, key, message, ..
                } => Error::Invalid {
                    file: self.source.clone(),
                    at,
                    key,
                    message,
                },
                other => other,
            })?;
        }
        doc.check()
    }
}

impl Machine {
    /// Reads and checks a machine file.
    pub fn load(path: &Path) -> Result<Machine, Error> {
        MachineDocument::load(path)?.check()
    }

    /// The embedded default: the NMV5000 with the paper's Table 3 drives (URDF embedded too).
    pub fn embedded_nmv5000() -> Result<Machine, Error> {
        MachineDocument::embedded_nmv5000()?.check()
    }

    /// The embedded realistic NMV5000: the same machine with every drive effect
    /// (machines/nmv5000-realistic.toml).
    pub fn embedded_nmv5000_realistic() -> Result<Machine, Error> {
        MachineDocument::embedded_nmv5000_realistic()?.check()
    }

    /// Checks a machine file given as text. `source` names it in messages; `base_dir` resolves
    /// the URDF path.
    pub fn from_toml_str(src: &str, source: &str, base_dir: &Path) -> Result<Machine, Error> {
        MachineDocument::from_toml_str(src, source, base_dir)?.check()
    }

    /// The axis with this name.
    pub fn axis(&self, name: AxisName) -> Option<&Axis> {
        self.axes.iter().find(|a| a.name == name)
    }

    /// Axis names in order.
    pub fn axis_names(&self) -> Vec<AxisName> {
        self.axes.iter().map(|a| a.name).collect()
    }

    /// Interpolator limits from the axes and the `[trajectory]` section.
    pub fn limits(&self) -> Limits {
        let mut axes = [GcodeAxisLimits {
            max_vel: 0.0,
            max_acc: 0.0,
            max_jerk: f64::INFINITY,
        }; 6];
        for a in &self.axes {
            axes[a.name.index()] = GcodeAxisLimits {
                max_vel: a.max_velocity,
                max_acc: a.max_acceleration,
                max_jerk: a.max_jerk.unwrap_or(f64::INFINITY),
            };
        }
        Limits {
            axes,
            tcp_max_vel: self.tcp_max_vel,
            tcp_max_acc: self.tcp_max_acc,
            tcp_max_jerk: self.tcp_max_jerk.unwrap_or(f64::INFINITY),
        }
    }

    /// Where a program starts: every axis at its `start` (machine coordinates, X Y Z A B C
    /// order; axes the machine lacks at 0).
    pub fn start_position(&self) -> [f64; 6] {
        let mut p = [0.0; 6];
        for a in &self.axes {
            p[a.name.index()] = a.start;
        }
        p
    }

    /// Interpreter options (dialect M-codes, leniency, start position).
    pub fn interp_options(&self, lenient: bool) -> InterpOptions {
        InterpOptions {
            lenient,
            // The first block moves from the machine's start position, as on a control. (In
            // tool-centre-point mode the interpreter reads it as tool-tip coordinates; on a
            // table-tilting machine they agree at A = C = 0, where the workpiece frame is the
            // machine frame.)
            start: vcnc_gcode::StartPosition::Machine(self.start_position()),
            tcp_on_mcodes: self.tcp_mcodes.0.clone(),
            tcp_off_mcodes: self.tcp_mcodes.1.clone(),
            path_mode: self.startup_path_mode,
            tools: self.tools.clone(),
            ..InterpOptions::default()
        }
    }

    /// Interpolation options (sample period, this machine's axes).
    pub fn interpolate_options(&self) -> InterpolateOptions {
        InterpolateOptions {
            ts: self.ts,
            axes: Some(self.axis_names()),
            blend_tolerance: self.blend_tolerance,
            profile: self.profile,
            planner: self.planner,
            ..InterpolateOptions::default()
        }
    }

    /// The axes' identified models when every axis is known only by its model (the machine
    /// file's `model`): what a prediction on this machine runs. `None` when some axis has a
    /// virtual drive.
    pub fn own_models(&self) -> Option<MachineModels> {
        let models = self
            .axes
            .iter()
            .map(|a| match &a.dynamics {
                Dynamics::Model(m) => Some(*m),
                Dynamics::Drive(_) => None,
            })
            .collect::<Option<Vec<_>>>()?;
        let source = self
            .model_file
            .clone()
            .unwrap_or_else(|| self.source.clone());
        MachineModels::new(self, models, source).ok()
    }

    /// What plays the true machine in runs, as summaries and tables say it: `virtual drives`,
    /// `no true machine: the identified models of FILE`, or for a mixed machine which axes are
    /// which.
    pub fn truth_description(&self) -> String {
        let names = |drive: bool| {
            self.axes
                .iter()
                .filter(|a| a.drive().is_some() == drive)
                .map(|a| a.name.as_str())
                .collect::<Vec<_>>()
                .join(" ")
        };
        let file = self.model_file.as_deref().unwrap_or("");
        match (names(true), names(false)) {
            (_, m) if m.is_empty() => "virtual drives".to_string(),
            (d, _) if d.is_empty() => format!("no true machine: the identified models of {file}"),
            (d, m) => format!("virtual drives on {d}, the identified models of {file} on {m}"),
        }
    }

    /// Whether every axis has a virtual drive (a true machine to compare predictions with).
    pub fn has_true_machine(&self) -> bool {
        self.axes.iter().all(|a| a.drive().is_some())
    }

    /// The kinematics, or an error saying the machine has none (needed for TCP programs, poses
    /// and contour errors).
    pub fn require_kinematics(&self) -> Result<&Kinematics, Error> {
        self.kinematics.as_ref().ok_or_else(|| Error::NoKinematics {
            file: self.source.clone(),
        })
    }
}

/// Largest magnitude accepted for travels and limits, axis units (C turns a million degrees).
const LIMIT: f64 = 1e9;

/// Finite and strictly positive.
fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

/// TOML syntax or schema error → file:line:col.
fn toml_error(src: &str, source: &str, e: &toml::de::Error) -> Error {
    Error::Toml {
        file: source.to_string(),
        at: line_col(src, error_offset(src, e.span(), e.message())),
        message: e.message().trim().to_string(),
    }
}

/// The section checkers of one document: each takes its raw section and returns its checked
/// form, or an error naming the file, line and key.
struct Checker<'a> {
    doc: &'a MachineDocument,
}

impl Checker<'_> {
    /// Error about `key` (dotted), located in the text when there is one.
    fn invalid(&self, key: &str, message: String) -> Error {
        let path: Vec<&str> = key.split('.').collect();
        Error::Invalid {
            file: self.doc.source.clone(),
            at: self.doc.text.as_deref().and_then(|s| locate_key(s, &path)),
            key: key.to_string(),
            message,
        }
    }

    fn machine(&self, file: MachineFile) -> Result<Machine, Error> {
        let ts = self.sample_period(file.sample_period_s)?;
        let models = self.model_file(file.model.as_deref())?;
        let axes = self.axes(&file, ts, models.as_ref())?;
        if models.is_some() && axes.iter().all(|a| a.drive().is_some()) {
            return Err(self.invalid(
                "model",
                "the machine names a model file but every axis has a plant and controller, so no axis would use it: remove `model`, or leave out `plant` and `controller` on the axes it describes".to_string(),
            ));
        }
        let t = &file.trajectory;
        self.trajectory(t, &axes, file.kinematics.is_some())?;
        let startup_path_mode = self.startup_path_mode(&file.gcode)?;
        let identification = self.identification(&file.identification)?;
        let program_output = self.program_output(&file.program_output, ts)?;
        let control = match &file.control {
            Some(c) => self.control(c, ts)?,
            None => None,
        };
        let kinematics = match &file.kinematics {
            Some(k) => Some(self.kinematics(k, &axes)?),
            // A plain X Y Z machine needs no section: its tool tip is its slides.
            None if axes
                .iter()
                .map(|a| a.name)
                .eq([AxisName::X, AxisName::Y, AxisName::Z]) =>
            {
                let xyz = KinematicsFile {
                    family: Some(FamilyFile::Xyz),
                    tilt: None,
                    urdf: None,
                    c_centre_mm: None,
                    tilt_offset_mm: None,
                    pivot_length_mm: None,
                    pivot_mm: None,
                    c_axis_mm: None,
                    branch: default_branch_value(),
                };
                Some(self.kinematics(&xyz, &axes)?)
            }
            None => None,
        };
        Ok(Machine {
            name: file.name,
            source: self.doc.source.clone(),
            ts,
            axes,
            kinematics,
            tcp_max_vel: t.max_linear_velocity,
            tcp_max_acc: t.max_linear_acceleration,
            tcp_max_jerk: t.max_linear_jerk,
            blend_tolerance: t.blend_tolerance,
            profile: match t.profile {
                ProfileFile::Trapezoidal => Profile::Trapezoidal,
                ProfileFile::JerkLimited => Profile::JerkLimited,
            },
            planner: match t.planner {
                PlannerFile::Vcnc => PlannerRules::Vcnc,
                PlannerFile::LinuxCnc29 => PlannerRules::LinuxCnc29,
            },
            tcp_mcodes: (file.gcode.tcp_on_mcodes, file.gcode.tcp_off_mcodes),
            startup_path_mode,
            identification,
            tools: ToolTable::default(),
            model_file: models.map(|(_, name)| name),
            program_output,
            control,
        })
    }

    /// `[control]`: the filters in order (a triangle as two moving averages of half its base,
    /// a Sinumerik jerk filter by its machine data after them), checked at the sample period.
    fn control(&self, c: &ControlFile, ts: f64) -> Result<Option<NominalFilter>, Error> {
        let mut filters = Vec::new();
        let mut fir: Vec<&[f64]> = Vec::new();
        for f in &c.filters {
            match *f {
                ControlFilterFile::Fir { ref taps } => fir.push(taps),
                ControlFilterFile::FirstOrder { time_constant_s } => {
                    filters.push(ShapingFilter::FirstOrder { time_constant_s })
                }
                ControlFilterFile::SecondOrder {
                    time_constant_s,
                    zeta,
                } => filters.push(ShapingFilter::SecondOrder {
                    time_constant_s,
                    zeta,
                }),
                ControlFilterFile::MovingAverage { window_s } => {
                    filters.push(ShapingFilter::MovingAverage { window_s })
                }
                ControlFilterFile::BandStop {
                    frequency_hz,
                    zeta_numerator,
                    zeta_denominator,
                    denominator_frequency_hz,
                } => filters.push(ShapingFilter::BandStop {
                    frequency_hz,
                    zeta_numerator,
                    zeta_denominator,
                    denominator_frequency_hz,
                }),
                ControlFilterFile::Triangular { window_s } => {
                    let half = ShapingFilter::MovingAverage {
                        window_s: window_s / 2.0,
                    };
                    filters.extend([half, half]);
                }
            }
        }
        if let Some(s) = &c.sinumerik {
            let ma = |window_s| ShapingFilter::MovingAverage { window_s };
            match s.ax_jerk_mode {
                2 => filters.push(ma(s.ax_jerk_time)),
                4 => filters.extend([
                    ma(s.ax_jerk_time),
                    ma(s.ax_jerk_time_add.unwrap_or(s.ax_jerk_time)),
                ]),
                m => {
                    return Err(self.invalid(
                        "control.sinumerik.ax_jerk_mode",
                        format!(
                            "AX_JERK_MODE {m} is not modelled: vcnc models 2 (moving average) and 4 (double moving average); for a second-order filter (mode 1) write it under control.filters with its time constant and damping, for a band-stop (mode 3) a `band-stop` filter there with its frequencies and dampings (docs/machine-file.md#control)"
                        ),
                    ));
                }
            }
        }
        let chain = NominalFilter::new(c.delay_s, &filters, ts)
            .and_then(|f| fir.into_iter().try_fold(f, |f, taps| f.with_fir(taps)));
        let chain = chain.map_err(|e| {
            let message = e
                .to_string()
                .replace("reference.filter.", "filter ")
                .replace("reference.interpolation_delay_s", "delay_s")
                .replace("servo periods 1/servo_rate_hz", "sample periods")
                .replace("the servo rate", "the sample rate");
            self.invalid(
                "control",
                format!(
                    "{message} (the control's filters act at the machine's sample period, {ts} s: the delay and windows in whole periods, a triangle's base in an even number of them)"
                ),
            )
        })?;
        Ok((!chain.is_identity()).then_some(chain))
    }

    /// `[program_output]`: resolutions and tolerances finite and ≥ 0 (at most 1), the block
    /// cycle positive and at most [`FINE_BLOCK_MAX_SAMPLES`] sample periods.
    fn program_output(&self, o: &ProgramOutputFile, ts: f64) -> Result<BlockRules, Error> {
        for (field, v, unit) in [
            ("resolution", o.resolution, "mm"),
            ("rotary_resolution", o.rotary_resolution, "deg"),
            ("chord_tolerance", o.chord_tolerance, "mm"),
            ("rotary_chord_tolerance", o.rotary_chord_tolerance, "deg"),
        ] {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                return Err(self.invalid(
                    &format!("program_output.{field}"),
                    format!("{field} must be between 0 and 1 {unit} (0: none), got {v:?}"),
                ));
            }
        }
        let periods = match o.block_cycle_s {
            None => 1,
            Some(c) => {
                let periods = (c / ts - 1e-9).ceil();
                if !(c > 0.0 && periods <= FINE_BLOCK_MAX_SAMPLES as f64) {
                    return Err(self.invalid(
                        "program_output.block_cycle_s",
                        format!(
                            "the block cycle must be positive and at most {FINE_BLOCK_MAX_SAMPLES} sample periods ({} s at this machine's sample period), got {c:?}",
                            FINE_BLOCK_MAX_SAMPLES as f64 * ts
                        ),
                    ));
                }
                periods.max(1.0) as u64
            }
        };
        Ok(BlockRules {
            min_samples: periods,
            resolution: o.resolution,
            rotary_resolution: o.rotary_resolution,
            tolerance: o.chord_tolerance,
            rotary_tolerance: o.rotary_chord_tolerance,
        })
    }

    /// The machine file's `model`: the model file read (relative to the machine file), with
    /// its name for messages.
    fn model_file(&self, path: Option<&Path>) -> Result<Option<(ModelSet, String)>, Error> {
        let Some(path) = path else {
            return Ok(None);
        };
        let full = match &self.doc.base {
            Base::Dir(dir) => dir.join(path),
            Base::Embedded => {
                return Err(self.invalid(
                    "model",
                    "an embedded machine names no model file".to_string(),
                ));
            }
        };
        let set = ModelSet::load(&full)?;
        Ok(Some((set, full.display().to_string())))
    }

    fn sample_period(&self, ts: f64) -> Result<f64, Error> {
        // 1 µs: the servo loop runs at most at 1 MHz (vcnc-drive), and a trace is never
        // sampled faster than its servo.
        if ts.is_finite() && (1e-6..=0.1).contains(&ts) {
            Ok(ts)
        } else {
            Err(self.invalid(
                "sample_period_s",
                format!("sample period must be in [1e-6, 0.1] s, got {ts:?}"),
            ))
        }
    }

    /// Every `[axes.<letter>]`, in canonical order.
    fn axes(
        &self,
        file: &MachineFile,
        ts: f64,
        models: Option<&(ModelSet, String)>,
    ) -> Result<Vec<Axis>, Error> {
        if file.axes.is_empty() {
            return Err(self.invalid("axes", "the machine has no axes".to_string()));
        }
        let mut axes = file
            .axes
            .iter()
            .map(|(key, a)| self.axis(key, a, ts, file.identification.program.range, models))
            .collect::<Result<Vec<Axis>, Error>>()?;
        axes.sort_by_key(|a| a.name);
        Ok(axes)
    }

    fn axis(
        &self,
        key: &str,
        a: &AxisFile,
        ts: f64,
        default_range: f64,
        models: Option<&(ModelSet, String)>,
    ) -> Result<Axis, Error> {
        let name = match key.parse::<AxisName>() {
            Ok(n) if n.as_str() == key => n,
            _ => {
                return Err(self.invalid(
                    &format!("axes.{key}"),
                    format!("unknown axis '{key}': expected one of X Y Z A B C"),
                ));
            }
        };
        let k = |field: &str| format!("axes.{key}.{field}");
        if a.unit != name.unit() {
            return Err(self.invalid(
                &k("unit"),
                format!("axis {name} must be in {}, got \"{}\"", name.unit(), a.unit),
            ));
        }
        let [lo, hi] = a.travel;
        if !(lo.is_finite() && hi.is_finite() && lo < hi && lo.abs() <= LIMIT && hi.abs() <= LIMIT)
        {
            return Err(self.invalid(
                &k("travel"),
                format!(
                    "travel must be [lower, upper] with lower < upper, both within ±{LIMIT:e}, got [{lo:e}, {hi:e}]"
                ),
            ));
        }
        for (field, v) in [
            ("max_velocity", a.max_velocity),
            ("max_acceleration", a.max_acceleration),
            ("max_jerk", a.max_jerk.unwrap_or(1.0)),
        ] {
            if !positive(v) || v > LIMIT {
                return Err(self.invalid(
                    &k(field),
                    format!("{field} must be positive and at most {LIMIT:e}, got {v:e}"),
                ));
            }
        }
        let dynamics = match (&a.plant, &a.controller) {
            (Some(plant), Some(controller)) => {
                let params = DriveParams {
                    plant: plant.clone(),
                    controller: controller.clone(),
                    encoder: a.encoder.clone(),
                    servo_rate_hz: a.servo_rate_hz,
                    compliance: a.compliance.clone(),
                    friction: a.friction.clone(),
                    current_loop: a.current_loop.clone(),
                    feedback: a.feedback.clone(),
                    reference: a.reference.clone(),
                };
                let drive = params.validate().map_err(|e| {
                    self.invalid(&k(drive_error_key(&e)), format!("axis {name}: {e}"))
                })?;
                drive
                    .ticks_per_sample(ts)
                    .map_err(|e| self.invalid(&k("servo_rate_hz"), format!("axis {name}: {e}")))?;
                Dynamics::Drive(drive)
            }
            (Some(_), None) | (None, Some(_)) => {
                let missing = if a.plant.is_none() {
                    "plant"
                } else {
                    "controller"
                };
                return Err(self.invalid(
                    &format!("axes.{key}"),
                    format!(
                        "axis {name} has {} but no {missing}: give both (a virtual drive) or neither (the axis is then known by the machine's identified model, `model = \"model.toml\"`)",
                        if a.plant.is_none() { "a controller" } else { "a plant" }
                    ),
                ));
            }
            (None, None) => Dynamics::Model(self.axis_model(key, name, a, models)?),
        };
        let range = a.identification_range.unwrap_or(default_range);
        let centre = a.identification_centre.unwrap_or(0.0);
        if !positive(range) || range > LIMIT || !centre.is_finite() {
            return Err(self.invalid(
                &k("identification_range"),
                format!("identification range must be positive, got {range:?}"),
            ));
        }
        if centre - range < lo || centre + range > hi {
            return Err(self.invalid(
                &k("identification_range"),
                format!(
                    "identification moves {centre} ± {range} {} leave the travel [{lo}, {hi}]; set identification_range / identification_centre",
                    a.unit
                ),
            ));
        }
        let start = a.start.unwrap_or(0.0);
        if !(start.is_finite() && start >= lo && start <= hi) {
            return Err(self.invalid(
                &k("start"),
                format!(
                    "the start position {start} {} is outside the travel [{lo}, {hi}]",
                    a.unit
                ),
            ));
        }
        Ok(Axis {
            name,
            unit: a.unit,
            travel: a.travel,
            max_velocity: a.max_velocity,
            max_acceleration: a.max_acceleration,
            max_jerk: a.max_jerk,
            dynamics,
            identification_range: range,
            identification_centre: centre,
            start,
        })
    }

    /// `[trajectory]`: positive limits; the jerk-limited profile needs every axis' jerk limit
    /// (and the tool tip's on a machine with kinematics).
    fn trajectory(&self, t: &TrajectoryFile, axes: &[Axis], kinematics: bool) -> Result<(), Error> {
        for (field, v) in [
            ("max_linear_velocity", t.max_linear_velocity),
            ("max_linear_acceleration", t.max_linear_acceleration),
            ("max_linear_jerk", t.max_linear_jerk.unwrap_or(1.0)),
        ] {
            if !positive(v) || v > LIMIT {
                return Err(self.invalid(
                    &format!("trajectory.{field}"),
                    format!("{field} must be positive and at most {LIMIT:e}, got {v:?}"),
                ));
            }
        }
        if let Some(j) = t.blend_tolerance.filter(|j| !positive(*j)) {
            return Err(self.invalid(
                "trajectory.blend_tolerance",
                format!("blend tolerance must be positive, got {j:?}"),
            ));
        }
        if t.profile == ProfileFile::JerkLimited {
            if let Some(a) = axes.iter().find(|a| a.max_jerk.is_none()) {
                return Err(self.invalid(
                    "trajectory.profile",
                    format!(
                        "the jerk-limited profile needs a jerk limit on every axis: set axes.{}.max_jerk (units/s³), or profile = \"trapezoidal\"",
                        a.name
                    ),
                ));
            }
            if kinematics && t.max_linear_jerk.is_none() {
                return Err(self.invalid(
                    "trajectory.profile",
                    "the jerk-limited profile needs the tool tip's jerk limit on a machine with kinematics: set trajectory.max_linear_jerk (mm/s³)".to_string(),
                ));
            }
        }
        Ok(())
    }

    /// `[gcode] startup_path_mode`.
    fn startup_path_mode(&self, g: &GcodeFile) -> Result<PathMode, Error> {
        match &g.startup_path_mode {
            None => Ok(PathMode::ExactStop),
            Some(text) => PathMode::parse(text).ok_or_else(|| {
                self.invalid(
                    "gcode.startup_path_mode",
                    format!(
                        "\"{text}\" is not a path mode: write \"G61.1\", \"G61\", \"G64\" or \"G64 P<mm> [Q<mm>]\""
                    ),
                )
            }),
        }
    }

    /// The identified model of axis `key` (given without plant and controller) from the
    /// machine's model file. Keys that describe a physical drive are refused on such an axis:
    /// nothing would read them.
    fn axis_model(
        &self,
        key: &str,
        name: AxisName,
        a: &AxisFile,
        models: Option<&(ModelSet, String)>,
    ) -> Result<DriveModel, Error> {
        let physical = [
            (
                "encoder",
                table_has(&self.doc.table, &["axes", key, "encoder"]),
            ),
            (
                "servo_rate_hz",
                table_has(&self.doc.table, &["axes", key, "servo_rate_hz"]),
            ),
            ("compliance", a.compliance.is_some()),
            ("friction", a.friction.is_some()),
            ("current_loop", a.current_loop.is_some()),
            ("feedback", a.feedback.is_some()),
            ("reference", a.reference.is_some()),
        ];
        if let Some((field, _)) = physical.iter().find(|(_, given)| *given) {
            return Err(self.invalid(
                &format!("axes.{key}.{field}"),
                format!(
                    "axis {name} has no plant and controller (it is known by its identified model), so `{field}`, which describes a physical drive, has nothing to act on: remove it, or give the axis a plant and controller"
                ),
            ));
        }
        let Some((set, file)) = models else {
            return Err(self.invalid(
                &format!("axes.{key}"),
                format!(
                    "axis {name} has neither plant and controller nor a model: give the axis `plant` and `controller` (a virtual drive), or name an identified model file at the top of the machine file, `model = \"model.toml\"` (written by `vcnc identify`)"
                ),
            ));
        };
        set.model_of(name, a.unit, file, || {
            format!(
                "no model for axis {name}, which the machine file {} gives without a plant",
                self.doc.source
            )
        })
    }

    /// `[identification]`: the program and the identifier options.
    fn identification(&self, f: &IdentificationFile) -> Result<IdentificationSettings, Error> {
        let p = &f.program;
        if let Some(acc) = p.max_acceleration.filter(|a| !positive(*a)) {
            return Err(self.invalid(
                "identification.program.max_acceleration",
                format!("max_acceleration must be positive, got {acc:?}"),
            ));
        }
        if !(10..=100_000).contains(&p.moves)
            || !positive(p.max_feed)
            || !positive(p.min_feed)
            || p.min_feed > p.max_feed
        {
            return Err(self.invalid(
                "identification.program",
                format!(
                    "the identification program needs 10 to 100 000 moves and 0 < min_feed <= max_feed (got {} moves, feeds {} ..= {})",
                    p.moves, p.min_feed, p.max_feed
                ),
            ));
        }
        f.options
            .validate()
            .map_err(|e| self.invalid("identification.options", e.to_string()))?;
        let sets_p_bounds = table_has(
            &self.doc.table,
            &["identification", "options", "bounds", "p_hz"],
        );
        Ok(IdentificationSettings {
            program: p.clone(),
            options: OptionsFile {
                options: f.options.clone(),
                sets_p_bounds,
                sets_structures: table_has(
                    &self.doc.table,
                    &["identification", "options", "structures"],
                ),
            },
        })
    }

    /// `[kinematics]`: the family with its offsets, or a URDF chain (with a table-tilting
    /// chain's offsets overridden by the file's), the axes' travels, roles and branch.
    fn kinematics(&self, k: &KinematicsFile, axes: &[Axis]) -> Result<Kinematics, Error> {
        let model = match (&k.family, &k.urdf) {
            (Some(_), Some(_)) => {
                return Err(self.invalid(
                    "kinematics.urdf",
                    "give either kinematics.family or kinematics.urdf, not both".to_string(),
                ));
            }
            (None, None) => {
                return Err(self.invalid(
                    "kinematics",
                    "[kinematics] needs family = \"xyz\" | \"table-ac\" | \"table-bc\" | \"head-head\" | \"head-table\", or urdf = \"machine.urdf\"".to_string(),
                ));
            }
            (Some(f), None) => self.family_model(*f, k, axes)?,
            (None, Some(urdf)) => self.urdf_model(urdf, k)?,
        };
        // The machine file's travels govern (a URDF's are nominal).
        let mut travels = Travels::default();
        for axis in axes {
            let scale = if axis.unit == Unit::Deg {
                std::f64::consts::PI / 180.0
            } else {
                1.0
            };
            let tr = Travel::new(axis.travel[0] * scale, axis.travel[1] * scale)
                .map_err(|e| self.invalid(&format!("axes.{}.travel", axis.name), e.to_string()))?;
            if let Some(t) = travels.get_mut(axis.name) {
                *t = tr;
            }
        }
        let model = model
            .with_limits(travels)
            .map_err(|e| self.invalid("kinematics", e.to_string()))?;
        let branch = Branch::try_from(i32::from(k.branch)).map_err(|_| {
            self.invalid(
                "kinematics.branch",
                format!("branch must be 1 or -1, got {}", k.branch),
            )
        })?;
        Kinematics::new(model, axes, branch).map_err(|e| {
            self.invalid(
                "kinematics",
                format!("{e}: add [axes.<letter>] for it, or choose the machine's family"),
            )
        })
    }

    /// A closed-form family from its keys.
    fn family_model(
        &self,
        f: FamilyFile,
        k: &KinematicsFile,
        axes: &[Axis],
    ) -> Result<vcnc_kinematics::Kinematics, Error> {
        let head = matches!(f, FamilyFile::HeadHead | FamilyFile::HeadTable);
        if k.tilt.is_some() && !head {
            return Err(self.invalid(
                "kinematics.tilt",
                "tilt applies to family = \"head-head\" and \"head-table\" only (a table's tilt is in its family name)".to_string(),
            ));
        }
        let tilt = || -> Result<Tilt, Error> {
            match k.tilt {
                Some(TiltFile::A) => Ok(Tilt::A),
                Some(TiltFile::B) => Ok(Tilt::B),
                None => {
                    let has = |n: AxisName| axes.iter().any(|a| a.name == n);
                    match (has(AxisName::A), has(AxisName::B)) {
                        (true, false) => Ok(Tilt::A),
                        (false, true) => Ok(Tilt::B),
                        (a, _) => Err(self.invalid(
                            "kinematics.family",
                            format!(
                                "the head's tilting axis is A or B, and the machine has {}: set kinematics.tilt = \"A\" or \"B\"",
                                if a { "both" } else { "neither" }
                            ),
                        )),
                    }
                }
            }
        };
        let family = match f {
            FamilyFile::Xyz => Family::Xyz,
            FamilyFile::TableAc => Family::TableTilting(Tilt::A),
            FamilyFile::TableBc => Family::TableTilting(Tilt::B),
            FamilyFile::HeadHead => Family::HeadHead(tilt()?),
            FamilyFile::HeadTable => Family::HeadTable(tilt()?),
        };
        let params = KinematicsParams {
            family: Some(family),
            c_centre_mm: k.c_centre_mm,
            tilt_offset_mm: k.tilt_offset_mm,
            pivot_length_mm: k.pivot_length_mm,
            pivot_mm: k.pivot_mm,
            c_axis_mm: k.c_axis_mm,
            limits: Travels::default(),
        };
        vcnc_kinematics::Kinematics::from_params(&params).map_err(|e| match &e {
            vcnc_kinematics::Error::BadParameter { name, .. } if is_key(name) => self.invalid(
                &format!("kinematics.{name}"),
                format!("{e} (family \"{}\")", family_name(f)),
            ),
            _ => self.invalid("kinematics", e.to_string()),
        })
    }

    /// A URDF chain, as its closed-form family where it matches one; a table-tilting chain's
    /// offsets may be overridden by `c_centre_mm` / `tilt_offset_mm`.
    fn urdf_model(
        &self,
        urdf: &Path,
        k: &KinematicsFile,
    ) -> Result<vcnc_kinematics::Kinematics, Error> {
        let source = &self.doc.source;
        if k.tilt.is_some() {
            return Err(self.invalid(
                "kinematics.tilt",
                "tilt goes with family; a URDF names its own axes".to_string(),
            ));
        }
        let (chain, urdf_name) = match &self.doc.base {
            Base::Embedded => {
                let name = "<embedded>/machines/nmv5000.urdf";
                (
                    KinematicChain::read_urdf_str(embedded::NMV5000_URDF, name),
                    name.to_string(),
                )
            }
            Base::Dir(dir) => {
                let path = dir.join(urdf);
                (
                    KinematicChain::read_urdf_file(&path),
                    path.display().to_string(),
                )
            }
        };
        let chain = chain.map_err(|e| Error::Kinematics {
            context: format!("{source}: kinematics.urdf = {urdf_name}"),
            message: e.to_string(),
        })?;
        let model = chain.kinematics();
        for (key, given) in [
            ("pivot_length_mm", k.pivot_length_mm.is_some()),
            ("pivot_mm", k.pivot_mm.is_some()),
            ("c_axis_mm", k.c_axis_mm.is_some()),
        ] {
            if given {
                return Err(self.invalid(
                    &format!("kinematics.{key}"),
                    format!("{key} goes with family = \"head-head\" / \"head-table\"; a URDF's pivot is in its joints"),
                ));
            }
        }
        match model {
            vcnc_kinematics::Kinematics::TableTilting(m) => {
                let r = k.c_centre_mm.map(Vector3::from).unwrap_or(m.r);
                let d = k.tilt_offset_mm.map(Vector3::from).unwrap_or(m.d);
                TableTilting::new(m.tilt, r, d, m.limits)
                    .map(vcnc_kinematics::Kinematics::TableTilting)
                    .map_err(|e| self.invalid("kinematics", e.to_string()))
            }
            other => {
                for (key, given) in [
                    ("c_centre_mm", k.c_centre_mm.is_some()),
                    ("tilt_offset_mm", k.tilt_offset_mm.is_some()),
                ] {
                    if given {
                        return Err(self.invalid(
                            &format!("kinematics.{key}"),
                            format!(
                                "{key} overrides a table-tilting URDF's offsets; {urdf_name} is a {} machine (edit its joints instead)",
                                other.family()
                            ),
                        ));
                    }
                }
                Ok(other)
            }
        }
    }
}

/// The `family` value as written.
fn family_name(f: FamilyFile) -> &'static str {
    match f {
        FamilyFile::Xyz => "xyz",
        FamilyFile::TableAc => "table-ac",
        FamilyFile::TableBc => "table-bc",
        FamilyFile::HeadHead => "head-head",
        FamilyFile::HeadTable => "head-table",
    }
}

/// True for the `[kinematics]` keys [`KinematicsParams`] names in its errors.
fn is_key(name: &str) -> bool {
    matches!(
        name,
        "c_centre_mm" | "tilt_offset_mm" | "pivot_length_mm" | "pivot_mm" | "c_axis_mm"
    )
}

/// `kinematics.branch`'s default.
fn default_branch_value() -> i8 {
    -1
}

/// True when the dotted `path` is written in `table`.
fn table_has(table: &toml::Table, path: &[&str]) -> bool {
    let Some((last, parents)) = path.split_last() else {
        return false;
    };
    let mut t = table;
    for p in parents {
        match t.get(*p) {
            Some(toml::Value::Table(inner)) => t = inner,
            _ => return false,
        }
    }
    t.contains_key(*last)
}

/// The machine-file key a drive error is about.
fn drive_error_key(e: &vcnc_drive::Error) -> &'static str {
    use vcnc_drive::Error as E;
    match e {
        E::BadParameter { name, .. } | E::Alternatives { name, .. } => name,
        E::Unstable { .. } | E::MissingGain { .. } | E::GainsAndDesign { .. } => "controller",
        E::BadDesign { .. } => "controller.design",
        _ => "controller",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nmv5000() -> MachineDocument {
        MachineDocument::embedded_nmv5000().unwrap()
    }

    #[test]
    fn kinematic_roles_are_resolved_at_load_time() {
        let m = nmv5000().check().unwrap();
        let k = m.kinematics.as_ref().unwrap();
        assert_eq!(k.family(), Family::TableTilting(Tilt::A));
        let names: Vec<AxisName> = k.machine_axes().iter().map(|i| m.axes[*i].name).collect();
        assert_eq!(names, k.axis_names());
        assert_eq!(
            names,
            [
                AxisName::X,
                AxisName::Y,
                AxisName::Z,
                AxisName::A,
                AxisName::C
            ]
        );
        assert_eq!(k.branch, Branch::Minus);
    }

    #[test]
    fn set_values_are_checked_like_the_file() {
        let doc = nmv5000();
        let m = doc.with_values(&[("axes.X.controller.vff", 0.7)]).unwrap();
        let base = doc.check().unwrap();
        assert_ne!(m.axes[0].dynamics, base.axes[0].dynamics);
        assert_eq!(m.axes[1], base.axes[1]);
        let e = doc
            .with_values(&[("axes.X.controller.kv", 30.0)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("<embedded>/machines/nmv5000.toml"), "{e}");
        let e = doc.with_values(&[("axes.Q.plant.j", 1.0)]).unwrap_err();
        assert!(e.to_string().contains("axes.Q"), "{e}");
    }

    #[test]
    fn program_output_keys_give_the_writer_its_rules_and_bad_ones_name_their_key() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machines");
        let base = embedded::NMV5000_TOML;
        let m = Machine::from_toml_str(base, "m.toml", &dir).unwrap();
        assert_eq!(
            m.program_output,
            BlockRules {
                min_samples: 1,
                resolution: 1e-4,
                rotary_resolution: 1e-4,
                tolerance: 1e-4,
                rotary_tolerance: 1e-4,
            }
        );
        // A 2.5 ms block cycle at 1 ms is three periods (rounded up); 4 ms exactly is four.
        for (cycle, periods) in [(0.0025, 3), (0.004, 4), (0.0001, 1)] {
            let src = format!(
                "{base}\n[program_output]\nblock_cycle_s = {cycle}\nresolution = 0.001\nchord_tolerance = 0\n"
            );
            let m = Machine::from_toml_str(&src, "m.toml", &dir).unwrap();
            assert_eq!(m.program_output.min_samples, periods, "{cycle}");
            assert_eq!(m.program_output.resolution, 0.001);
            assert_eq!(m.program_output.tolerance, 0.0);
            assert_eq!(m.program_output.rotary_resolution, 1e-4);
        }
        for (line, key) in [
            ("block_cycle_s = 0.05", "program_output.block_cycle_s"),
            ("block_cycle_s = 0", "program_output.block_cycle_s"),
            ("resolution = -0.001", "program_output.resolution"),
            (
                "rotary_chord_tolerance = nan",
                "program_output.rotary_chord_tolerance",
            ),
            ("chord_tolerance = 2", "program_output.chord_tolerance"),
            ("decimals = 4", "decimals"),
        ] {
            let src = format!("{base}\n[program_output]\n{line}\n");
            let e = Machine::from_toml_str(&src, "m.toml", &dir)
                .unwrap_err()
                .to_string();
            assert!(e.contains(key) && e.contains("m.toml"), "{line}: {e}");
        }
    }

    #[test]
    fn band_stop_keys_reach_the_chain_and_bad_or_missing_ones_name_their_key() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machines");
        let base = embedded::NMV5000_TOML;
        let load = |filter: &str| {
            let src =
                format!("{base}\n[control]\nfilters = [{{ kind = \"band-stop\", {filter} }}]\n");
            Machine::from_toml_str(&src, "m.toml", &dir).map_err(|e| e.to_string())
        };
        let m = load("frequency_hz = 40.0, zeta_numerator = 0.05, zeta_denominator = 0.7").unwrap();
        assert_eq!(
            m.control.expect("a chain").filters(),
            [ShapingFilter::BandStop {
                frequency_hz: 40.0,
                zeta_numerator: 0.05,
                zeta_denominator: 0.7,
                denominator_frequency_hz: None,
            }]
        );
        let m = load(
            "frequency_hz = 40.0, zeta_numerator = 0, zeta_denominator = 1, denominator_frequency_hz = 50.0",
        )
        .unwrap();
        assert!(matches!(
            m.control.expect("a chain").filters(),
            [ShapingFilter::BandStop {
                denominator_frequency_hz: Some(50.0),
                ..
            }]
        ));
        // The machine's sample period is 1 ms: frequencies up to 250 Hz.
        for (filter, says) in [
            (
                "frequency_hz = 40.0, zeta_denominator = 0.7",
                "zeta_numerator",
            ),
            (
                "frequency_hz = 40.0, zeta_numerator = 0.05",
                "zeta_denominator",
            ),
            (
                "zeta_numerator = 0.05, zeta_denominator = 0.7",
                "frequency_hz",
            ),
            (
                "frequency_hz = 40.0, zeta_numerator = 0.05, zeta_denominator = 0.7, depth = 3",
                "depth",
            ),
            (
                "frequency_hz = 300.0, zeta_numerator = 0.05, zeta_denominator = 0.7",
                "filter frequency_hz",
            ),
            (
                "frequency_hz = 40.0, zeta_numerator = 0.9, zeta_denominator = 0.7",
                "filter zeta_numerator",
            ),
            (
                "frequency_hz = 40.0, zeta_numerator = 0.1, zeta_denominator = 0",
                "filter zeta_denominator",
            ),
            (
                "frequency_hz = 40.0, zeta_numerator = 0.1, zeta_denominator = 0.7, denominator_frequency_hz = -5",
                "filter denominator_frequency_hz",
            ),
        ] {
            let e = load(filter).unwrap_err();
            assert!(e.contains(says) && e.contains("m.toml"), "{filter}: {e}");
        }
        let e = load("frequency_hz = 300.0, zeta_numerator = 0.05, zeta_denominator = 0.7")
            .unwrap_err();
        assert!(e.contains("sample rate"), "{e}");
        // Sinumerik's band-stop mode is refused with the advice to write the filter.
        let src = format!(
            "{base}\n[control]\n[control.sinumerik]\nax_jerk_mode = 3\nax_jerk_time = 0.0\n"
        );
        let e = Machine::from_toml_str(&src, "m.toml", &dir)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("AX_JERK_MODE 3") && e.contains("band-stop"),
            "{e}"
        );
    }

    #[test]
    fn planner_keys_reach_the_interpolator_and_bad_ones_name_their_key() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machines");
        let base = embedded::NMV5000_TOML;
        // Defaults: trapezoidal, vcnc's rules, exact stop at start-up, no jerk limits.
        let m = Machine::from_toml_str(base, "m.toml", &dir).unwrap();
        let o = m.interpolate_options();
        assert_eq!(
            (o.profile, o.planner),
            (Profile::Trapezoidal, PlannerRules::Vcnc)
        );
        assert_eq!(m.interp_options(false).path_mode, PathMode::ExactStop);
        assert!(m.limits().axes[0].max_jerk.is_infinite());
        // Jerk limits, the jerk-limited profile, LinuxCNC's rules, a start-up mode, and the
        // earlier name of the plain-G64 tolerance.
        let mut src = base.replace(
            "[trajectory]",
            "[trajectory]\nprofile = \"jerk-limited\"\nplanner = \"linuxcnc-2.9\"\nmax_linear_jerk = 1e5\njunction_deviation = 0.02",
        );
        src = src.replace("[gcode]", "[gcode]\nstartup_path_mode = \"G64 P0.01\"");
        for axis in ["X", "Y", "Z", "A", "C"] {
            src = src.replace(
                &format!("[axes.{axis}]"),
                &format!("[axes.{axis}]\nmax_jerk = 50000.0"),
            );
        }
        let m = Machine::from_toml_str(&src, "m.toml", &dir).unwrap();
        let o = m.interpolate_options();
        assert_eq!(
            (o.profile, o.planner, o.blend_tolerance),
            (Profile::JerkLimited, PlannerRules::LinuxCnc29, Some(0.02))
        );
        assert_eq!(m.limits().axes[0].max_jerk, 50000.0);
        assert_eq!(m.limits().tcp_max_jerk, 1e5);
        assert_eq!(
            m.interp_options(false).path_mode,
            PathMode::Blend {
                tolerance_mm: Some(0.01),
                merge_mm: Some(0.01)
            }
        );
        // The jerk-limited profile without an axis' jerk limit names the key to set.
        let missing = src.replacen("max_jerk = 50000.0", "", 1);
        let e = Machine::from_toml_str(&missing, "m.toml", &dir)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("trajectory.profile") && e.contains("max_jerk"),
            "{e}"
        );
        let bad = src.replace("G64 P0.01", "G65");
        let e = Machine::from_toml_str(&bad, "m.toml", &dir)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("gcode.startup_path_mode") && e.contains("G65"),
            "{e}"
        );
        let bad = src.replace("max_linear_jerk = 1e5", "max_linear_jerk = -1.0");
        let e = Machine::from_toml_str(&bad, "m.toml", &dir)
            .unwrap_err()
            .to_string();
        assert!(e.contains("trajectory.max_linear_jerk"), "{e}");
    }

    #[test]
    fn the_options_record_whether_they_set_the_pole_bound() {
        let m = nmv5000().check().unwrap();
        assert!(m.identification.options.sets_p_bounds);
        let src = embedded::NMV5000_TOML.replace("p_hz = [0.2, 500.0]", "");
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machines");
        let m = Machine::from_toml_str(&src, "m.toml", &dir).unwrap();
        assert!(!m.identification.options.sets_p_bounds);
    }

    /// The NMV5000 with its URDF's `[kinematics]` replaced by `with` (the text of the section).
    fn nmv_with_kinematics(with: &str) -> Result<Machine, Error> {
        let src = embedded::NMV5000_TOML.replace("urdf = \"nmv5000.urdf\"", with);
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machines");
        Machine::from_toml_str(&src, "m.toml", &dir)
    }

    #[test]
    fn a_family_with_the_urdf_offsets_is_the_urdf_model() {
        let urdf = nmv5000().check().unwrap();
        let params = nmv_with_kinematics(
            "family = \"table-ac\"\nc_centre_mm = [0.0, 0.0, 0.0]\ntilt_offset_mm = [0.0, 0.0, -100.0]",
        )
        .unwrap();
        assert_eq!(urdf.kinematics, params.kinematics);
        // The earlier key name still reads.
        let old =
            nmv_with_kinematics("family = \"table-ac\"\na_offset_mm = [0.0, 0.0, -100.0]").unwrap();
        assert_eq!(urdf.kinematics, old.kinematics);
    }

    #[test]
    fn bad_kinematics_keys_name_the_file_line_and_value() {
        let e = nmv_with_kinematics("family = \"table-xy\"")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("m.toml:") && e.contains("table-xy"), "{e}");
        let e = nmv_with_kinematics("family = \"head-head\"")
            .unwrap_err()
            .to_string();
        // The NMV has A and C: a head-head A machine without its pivot.
        assert!(e.contains("kinematics.pivot_length_mm"), "{e}");
        let e = nmv_with_kinematics("family = \"table-bc\"")
            .unwrap_err()
            .to_string();
        assert!(e.contains("m.toml:") && e.contains("axis B"), "{e}");
        let e = nmv_with_kinematics("family = \"table-ac\"\npivot_length_mm = 200.0")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("kinematics.pivot_length_mm") && e.contains("table-ac"),
            "{e}"
        );
        let e = nmv_with_kinematics("family = \"xyz\"\nurdf = \"nmv5000.urdf\"")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not both"), "{e}");
        let e = nmv_with_kinematics("").unwrap_err().to_string();
        assert!(e.contains("family") && e.contains("urdf"), "{e}");
        let e = nmv_with_kinematics("family = \"xyz\"\ntilt = \"B\"")
            .unwrap_err()
            .to_string();
        assert!(e.contains("kinematics.tilt"), "{e}");
    }

    #[test]
    fn every_family_loads_and_reads_its_axes() {
        // A 5-axis machine with A and C reads as each family with A.
        for (family, extra, expect) in [
            ("xyz", "", Family::Xyz),
            ("table-ac", "", Family::TableTilting(Tilt::A)),
            (
                "head-head",
                "\npivot_length_mm = 250.0",
                Family::HeadHead(Tilt::A),
            ),
            (
                "head-table",
                "\npivot_length_mm = 180.0",
                Family::HeadTable(Tilt::A),
            ),
        ] {
            let m = nmv_with_kinematics(&format!("family = \"{family}\"{extra}"))
                .unwrap_or_else(|e| panic!("{family}: {e}"));
            let k = m.require_kinematics().unwrap();
            assert_eq!(k.family(), expect);
            let names: Vec<AxisName> = k.machine_axes().iter().map(|i| m.axes[*i].name).collect();
            assert_eq!(names, k.axis_names());
            // The pose of the axes at zero: the tool tip at the slides' zero (every family's
            // workpiece frame is the machine frame at zero), along +Z.
            let zero = vec![0.0; names.len()];
            let p = k.pose_of(&zero);
            assert!(
                p.p.norm() < 1e-12 && (p.o.z - 1.0).abs() < 1e-15,
                "{family}: {p:?}"
            );
        }
    }
}
