//! The checked machine: raw [`MachineFile`] → [`Machine`] (ripgrep's LowArgs → HiArgs split).

use std::path::{Path, PathBuf};
use std::str::FromStr;

use vcnc_axis::AxisName;

use vcnc_drive::{ClosedLoopModel, Drive, DriveParams};
use vcnc_gcode::{AxisLimits as GcodeAxisLimits, InterpOptions, InterpolateOptions, Limits};
use vcnc_identify::IdentifyOptions;
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{Axes, AxisLimits as Travels, KinematicChain, TableTiltingAc, Travel};

use crate::file::{MachineFile, ProgramFile, Unit};
use crate::locate::{error_offset, line_col, locate_key};
use crate::{Error, embedded};

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
    /// The true drive (validated: stable, gains resolved).
    pub drive: Drive,
    /// Half-range of this axis' identification moves, axis units.
    pub identification_range: f64,
    /// Centre of this axis' identification moves (a work offset), axis units.
    pub identification_centre: f64,
}

impl Axis {
    /// The analytic closed-loop model of the true drive (docs/drive-model.md).
    pub fn true_model(&self) -> ClosedLoopModel {
        self.drive.closed_loop_model()
    }
}

/// A checked machine. Build it with [`Machine::load`] or [`Machine::from_toml_str`].
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
    /// The closed-form table-tilting A/C model (mm, rad), with its URDF chain, when the file
    /// has `[kinematics]`.
    pub kinematics: Option<(KinematicChain, TableTiltingAc)>,
    /// Inverse-kinematics branch sign (−1 or +1).
    pub branch: i8,
    /// Tool-tip path velocity limit, mm/s.
    pub tcp_max_vel: f64,
    /// Tool-tip path acceleration limit, mm/s².
    pub tcp_max_acc: f64,
    /// Junction deviation override, mm.
    pub junction_deviation: Option<f64>,
    /// M-codes switching TCP on / off.
    pub tcp_mcodes: (Vec<u32>, Vec<u32>),
    /// Identification program settings.
    pub program: ProgramFile,
    /// Identifier settings.
    pub identify: IdentifyOptions,
    /// The raw file, as read (for sweeps and for writing back).
    pub file: MachineFile,
}

impl Machine {
    /// Reads and checks a machine file.
    pub fn load(path: &Path) -> Result<Machine, Error> {
        let (file, src) = crate::read_text(path)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Machine::from_toml_str(&src, &file, &base)
    }

    /// The embedded default: the NMV5000 with the the paper's Table 3 drives (URDF embedded too).
    pub fn embedded_nmv5000() -> Result<Machine, Error> {
        let name = "<embedded>/machines/nmv5000.toml";
        let file = parse_file(embedded::NMV5000_TOML, name)?;
        Machine::from_file(file, name, Source::Embedded, Some(embedded::NMV5000_TOML))
    }

    /// Checks a machine file given as text. `source` names it in messages; `base_dir` resolves
    /// the URDF path.
    pub fn from_toml_str(src: &str, source: &str, base_dir: &Path) -> Result<Machine, Error> {
        let file = parse_file(src, source)?;
        Machine::from_file(file, source, Source::Dir(base_dir.to_path_buf()), Some(src))
    }

    /// Checks a machine file given as a TOML table (sweeps set keys in the table first). Errors
    /// carry no line numbers (the table has none).
    pub fn from_toml_table(
        table: toml::Table,
        source: &str,
        base_dir: Option<&Path>,
    ) -> Result<Machine, Error> {
        let file: MachineFile =
            toml::Value::Table(table)
                .try_into()
                .map_err(|e: toml::de::Error| Error::Invalid {
                    file: source.to_string(),
                    at: None,
                    key: String::new(),
                    message: e.message().to_string(),
                })?;
        let src = match base_dir {
            Some(d) => Source::Dir(d.to_path_buf()),
            None => Source::Embedded,
        };
        Machine::from_file(file, source, src, None)
    }

    fn from_file(
        file: MachineFile,
        source: &str,
        base: Source,
        src: Option<&str>,
    ) -> Result<Machine, Error> {
        let invalid = |key: &str, message: String| {
            let path: Vec<&str> = key.split('.').collect();
            Error::Invalid {
                file: source.to_string(),
                at: src.and_then(|s| locate_key(s, &path)),
                key: key.to_string(),
                message,
            }
        };
        let ts = file.sample_period_s;
        // 1 µs: the servo loop runs at most at 1 MHz (vcnc-drive), and a trace is never
        // sampled faster than its servo.
        if !(ts.is_finite() && (1e-6..=0.1).contains(&ts)) {
            return Err(invalid(
                "sample_period_s",
                format!("sample period must be in [1e-6, 0.1] s, got {ts:?}"),
            ));
        }
        if file.axes.is_empty() {
            return Err(invalid("axes", "the machine has no axes".to_string()));
        }
        let mut axes = Vec::with_capacity(file.axes.len());
        for (key, a) in &file.axes {
            let name = match AxisName::from_str(key) {
                Ok(n) if n.as_str() == key => n,
                _ => {
                    return Err(invalid(
                        &format!("axes.{key}"),
                        format!("unknown axis '{key}': expected one of X Y Z A B C"),
                    ));
                }
            };
            let k = |field: &str| format!("axes.{key}.{field}");
            let expected = name.unit();
            if a.unit != expected {
                return Err(invalid(
                    &k("unit"),
                    format!(
                        "axis {name} must be in {}, got \"{}\"",
                        expected.as_str(),
                        a.unit.as_str()
                    ),
                ));
            }
            let [lo, hi] = a.travel;
            if !(lo.is_finite()
                && hi.is_finite()
                && lo < hi
                && lo.abs() <= LIMIT
                && hi.abs() <= LIMIT)
            {
                return Err(invalid(
                    &k("travel"),
                    format!(
                        "travel must be [lower, upper] with lower < upper, both within ±{LIMIT:e}, got [{lo:e}, {hi:e}]"
                    ),
                ));
            }
            for (field, v) in [
                ("max_velocity", a.max_velocity),
                ("max_acceleration", a.max_acceleration),
            ] {
                if !positive(v) || v > LIMIT {
                    return Err(invalid(
                        &k(field),
                        format!("{field} must be positive and at most {LIMIT:e}, got {v:e}"),
                    ));
                }
            }
            let params = DriveParams {
                plant: a.plant.clone(),
                controller: a.controller.clone(),
                encoder: a.encoder.clone(),
                servo_rate_hz: a.servo_rate_hz,
            };
            let drive = params.validate().map_err(|e| {
                let field = drive_error_key(&e);
                invalid(&k(field), format!("axis {name}: {e}"))
            })?;
            drive
                .ticks_per_sample(ts)
                .map_err(|e| invalid(&k("servo_rate_hz"), format!("axis {name}: {e}")))?;
            let range = a
                .identification_range
                .unwrap_or(file.identification.program.range);
            let centre = a.identification_centre.unwrap_or(0.0);
            if !positive(range) || range > LIMIT || !centre.is_finite() {
                return Err(invalid(
                    &k("identification_range"),
                    format!("identification range must be positive, got {range:?}"),
                ));
            }
            if centre - range < lo || centre + range > hi {
                return Err(invalid(
                    &k("identification_range"),
                    format!(
                        "identification moves {} ± {range} {} leave the travel [{lo}, {hi}]; set identification_range / identification_centre",
                        centre,
                        a.unit.as_str()
                    ),
                ));
            }
            axes.push(Axis {
                name,
                unit: a.unit,
                travel: a.travel,
                max_velocity: a.max_velocity,
                max_acceleration: a.max_acceleration,
                drive,
                identification_range: range,
                identification_centre: centre,
            });
        }
        axes.sort_by_key(|a| a.name);

        let t = &file.trajectory;
        for (field, v) in [
            ("max_linear_velocity", t.max_linear_velocity),
            ("max_linear_acceleration", t.max_linear_acceleration),
        ] {
            if !positive(v) {
                return Err(invalid(
                    &format!("trajectory.{field}"),
                    format!("{field} must be positive, got {v:?}"),
                ));
            }
        }
        if let Some(j) = t.junction_deviation.filter(|j| !positive(*j)) {
            return Err(invalid(
                "trajectory.junction_deviation",
                format!("junction deviation must be positive, got {j:?}"),
            ));
        }
        let p = &file.identification.program;
        if let Some(acc) = p.max_acceleration.filter(|a| !positive(*a)) {
            return Err(invalid(
                "identification.program.max_acceleration",
                format!("max_acceleration must be positive, got {acc:?}"),
            ));
        }
        if !(10..=100_000).contains(&p.moves)
            || !positive(p.max_feed)
            || !positive(p.min_feed)
            || p.min_feed > p.max_feed
        {
            return Err(invalid(
                "identification.program",
                format!(
                    "the identification program needs 10 to 100 000 moves and 0 < min_feed <= max_feed (got {} moves, feeds {} ..= {})",
                    p.moves, p.min_feed, p.max_feed
                ),
            ));
        }
        file.identification
            .options
            .validate()
            .map_err(|e| invalid("identification.options", e.to_string()))?;

        let kinematics = match &file.kinematics {
            None => None,
            Some(k) => {
                let (chain, urdf_name) = match &base {
                    Source::Embedded => (
                        KinematicChain::from_urdf_str(
                            embedded::NMV5000_URDF,
                            "<embedded>/machines/nmv5000.urdf",
                        ),
                        "<embedded>/machines/nmv5000.urdf".to_string(),
                    ),
                    Source::Dir(dir) => {
                        let path = dir.join(&k.urdf);
                        (
                            KinematicChain::from_urdf_file(&path),
                            path.display().to_string(),
                        )
                    }
                };
                let chain = chain.map_err(|e| Error::Kinematics {
                    context: format!("{source}: kinematics.urdf = {}", urdf_name),
                    message: e.to_string(),
                })?;
                let mut model = chain.table_tilting_ac();
                let r = k.c_centre_mm.map(Vector3::from).unwrap_or(model.r);
                let d = k.a_offset_mm.map(Vector3::from).unwrap_or(model.d);
                model = model
                    .with_offsets(r, d)
                    .map_err(|e| invalid("kinematics", e.to_string()))?;
                // The machine file's travels govern (the URDF's are nominal).
                let mut travels = Travels::default();
                for axis in &axes {
                    let scale = if axis.unit == Unit::Deg {
                        std::f64::consts::PI / 180.0
                    } else {
                        1.0
                    };
                    let tr = Travel::new(axis.travel[0] * scale, axis.travel[1] * scale).map_err(
                        |e| invalid(&format!("axes.{}.travel", axis.name), e.to_string()),
                    )?;
                    if let Some(t) = travels.get_mut(axis.name) {
                        *t = tr;
                    }
                }
                model = model
                    .with_limits(travels)
                    .map_err(|e| invalid("kinematics", e.to_string()))?;
                for needed in Axes::NAMES {
                    if !axes.iter().any(|a| a.name == needed) {
                        return Err(invalid(
                            "kinematics",
                            format!("a table-tilting A/C machine needs axis {needed} in [axes]"),
                        ));
                    }
                }
                if k.branch != 1 && k.branch != -1 {
                    return Err(invalid(
                        "kinematics.branch",
                        format!("branch must be 1 or -1, got {}", k.branch),
                    ));
                }
                Some((chain, model))
            }
        };

        Ok(Machine {
            name: file.name.clone(),
            source: source.to_string(),
            ts,
            axes,
            kinematics,
            branch: file.kinematics.as_ref().map_or(-1, |k| k.branch),
            tcp_max_vel: t.max_linear_velocity,
            tcp_max_acc: t.max_linear_acceleration,
            junction_deviation: t.junction_deviation,
            tcp_mcodes: (
                file.gcode.tcp_on_mcodes.clone(),
                file.gcode.tcp_off_mcodes.clone(),
            ),
            program: file.identification.program.clone(),
            identify: file.identification.options.clone(),
            file,
        })
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
        }; 6];
        for a in &self.axes {
            axes[a.name.index()] = GcodeAxisLimits {
                max_vel: a.max_velocity,
                max_acc: a.max_acceleration,
            };
        }
        Limits {
            axes,
            tcp_max_vel: self.tcp_max_vel,
            tcp_max_acc: self.tcp_max_acc,
        }
    }

    /// Interpreter options (dialect M-codes, leniency).
    pub fn interp_options(&self, lenient: bool) -> InterpOptions {
        InterpOptions {
            lenient,
            // The machine file has no start position yet (issue 13 item 7): keep the behaviour
            // the pipeline's figures were made with, the opening motion defines the start.
            start: vcnc_gcode::StartPosition::FirstMove,
            tcp_on_mcodes: self.tcp_mcodes.0.clone(),
            tcp_off_mcodes: self.tcp_mcodes.1.clone(),
            ..InterpOptions::default()
        }
    }

    /// Interpolation options (sample period, this machine's axes).
    pub fn interpolate_options(&self) -> InterpolateOptions {
        let mut o = InterpolateOptions {
            ts: self.ts,
            axes: Some(self.axis_names()),
            ..InterpolateOptions::default()
        };
        if let Some(j) = self.junction_deviation {
            o.junction_deviation = j;
        }
        o
    }

    /// The closed-form kinematics, or an error saying the machine has none.
    pub fn kinematics_model(&self) -> Result<&TableTiltingAc, Error> {
        self.kinematics.as_ref().map(|(_, m)| m).ok_or_else(|| Error::Kinematics {
            context: self.source.clone(),
            message: "the machine file has no [kinematics] section (needed for TCP programs, poses and contour errors)".into(),
        })
    }
}

/// Largest magnitude accepted for travels and limits, axis units (C turns a million degrees).
const LIMIT: f64 = 1e9;

/// Finite and strictly positive.
fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

/// Where relative paths of a machine file resolve.
enum Source {
    /// Compiled into the binary.
    Embedded,
    /// A folder on disk.
    Dir(PathBuf),
}

/// TOML text → raw file, errors with file:line:col.
fn parse_file(src: &str, source: &str) -> Result<MachineFile, Error> {
    toml::from_str::<MachineFile>(src).map_err(|e| Error::Toml {
        file: source.to_string(),
        at: line_col(src, error_offset(src, e.span(), e.message())),
        message: e.message().trim().to_string(),
    })
}

/// The machine-file key a drive error is about.
fn drive_error_key(e: &vcnc_drive::Error) -> &'static str {
    use vcnc_drive::Error as E;
    match e {
        E::BadParameter { name, .. } => name,
        E::Unstable { .. } | E::MissingGain { .. } | E::GainsAndDesign { .. } => "controller",
        E::BadDesign { .. } => "controller.design",
        _ => "controller",
    }
}
