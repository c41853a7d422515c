//! The machine file as written (raw, unchecked): serde structs that mirror the TOML document
//! (docs/machine-file.md). Unknown keys are errors (`deny_unknown_fields` everywhere). The checked form
//! is [`crate::Machine`].
//!
//! ```toml
//! name = "NMV5000 (virtual)"
//! sample_period_s = 0.001
//!
//! [kinematics]
//! urdf = "nmv5000.urdf"          # relative to this file (or family = "table-ac", ...)
//!
//! [trajectory]                  # tool-tip path limits in TCP mode (LinuxCNC [TRAJ])
//! max_linear_velocity = 250.0
//! max_linear_acceleration = 1500.0
//!
//! [axes.X]
//! unit = "mm"
//! travel = [-365.0, 365.0]
//! max_velocity = 250.0
//! max_acceleration = 2500.0
//! plant = { j = 0.01, b = 0.0419, ka = 1.0, kt = 1.0, rg = 1.5915, coulomb_torque = 0.3 }
//! controller = { kind = "p-pi", design = { p_hz = 19.3, wn_hz = 55.54, zeta = 0.39 }, vff = 0.5, bff = 0.1 }
//! ```

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use vcnc_drive::{ControllerSpec, Encoder, Plant};
use vcnc_identify::IdentifyOptions;

pub use vcnc_axis::Unit;

/// The whole machine file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineFile {
    /// Machine name, shown in tables and summaries.
    pub name: String,
    /// Free text: where the numbers come from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Interpolation and logging period $T_s$, s. Default 0.001.
    #[serde(default = "default_ts")]
    pub sample_period_s: f64,
    /// Kinematic chain (required for TCP programs and contour errors).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kinematics: Option<KinematicsFile>,
    /// Tool-tip path limits.
    #[serde(default)]
    pub trajectory: TrajectoryFile,
    /// G-code dialect settings.
    #[serde(default)]
    pub gcode: GcodeFile,
    /// Identification program and identifier settings.
    #[serde(default)]
    pub identification: IdentificationFile,
    /// How vcnc writes programs for the control (`compensate`'s fine-block program).
    #[serde(default)]
    pub program_output: ProgramOutputFile,
    /// The control's nominal-position filters between the interpolator and the drives.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub control: Option<ControlFile>,
    /// An identified model file (`model.toml`, written by `vcnc identify`), relative to this
    /// file: the dynamics of every axis given without `plant` and `controller`
    /// (docs/machine-file.md#a-machine-made-of-identified-models).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<PathBuf>,
    /// Axes by letter (X Y Z A B C).
    pub axes: BTreeMap<String, AxisFile>,
}

fn default_ts() -> f64 {
    0.001
}

/// `[kinematics]`: the machine's kinematic family with its offsets, or a URDF chain
/// (docs/machine-file.md#kinematics, docs/kinematics.md). Give `family` or `urdf`, not both.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicsFile {
    /// The closed-form family: `"xyz"`, `"table-ac"`, `"table-bc"`, `"head-head"` or
    /// `"head-table"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub family: Option<FamilyFile>,
    /// Head-head and head-table: the tilting axis in the head, `"A"` or `"B"`. Default: the one
    /// of A and B the machine has.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tilt: Option<TiltFile>,
    /// URDF file, relative to the machine file: any serial machine (mapped onto its
    /// closed-form family where it matches one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub urdf: Option<PathBuf>,
    /// Table-tilting and head-table: the C-axis centre $r$ (machine frame), mm (with a URDF:
    /// an override of a table-tilting chain's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c_centre_mm: Option<[f64; 3]>,
    /// Table-tilting: the tilt-axis (A or B) centre relative to the C-axis centre,
    /// $d = (d_x, d_y, d_z)$, mm (with a URDF: an override). `a_offset_mm` is its earlier name.
    #[serde(
        default,
        alias = "a_offset_mm",
        skip_serializing_if = "Option::is_none"
    )]
    pub tilt_offset_mm: Option<[f64; 3]>,
    /// Head-head and head-table: the pivot length $L$, mm (the tilt axis $L$ above the tool
    /// tip at zero rotation, tool length included). Give this or `pivot_mm`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pivot_length_mm: Option<f64>,
    /// Head-head and head-table: a point of the tilt axis relative to the tool tip at zero
    /// rotation, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pivot_mm: Option<[f64; 3]>,
    /// Head-head: a point of the C axis relative to the tool tip at zero rotation, mm.
    /// Default: the pivot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c_axis_mm: Option<[f64; 3]>,
    /// Inverse-kinematics branch (sign of the tilt, A or B) used when a pose must be turned
    /// into axes (`vcnc kinematics inverse`, the spiral generator). Default −1.
    #[serde(default = "default_branch")]
    pub branch: i8,
}

/// `kinematics.family`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FamilyFile {
    /// Three slides, the tool along +Z.
    Xyz,
    /// Table-tilting: A (a cradle about X) carrying C.
    TableAc,
    /// Table-tilting: B (a trunnion about Y) carrying C.
    TableBc,
    /// Head-head: C then A or B in the spindle head.
    HeadHead,
    /// Head-table: A or B in the head, C in the table.
    HeadTable,
}

/// `kinematics.tilt`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum TiltFile {
    /// About X.
    A,
    /// About Y.
    B,
}

fn default_branch() -> i8 {
    -1
}

/// `[trajectory]`: limits of the tool-tip path in TCP mode (LinuxCNC `[TRAJ]`) and how the
/// interpolator plans (docs/gcode.md, "Interpolation").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrajectoryFile {
    /// Tool-tip path velocity limit, mm/s. Default 250.
    pub max_linear_velocity: f64,
    /// Tool-tip path acceleration limit, mm/s². Default 1500 (docs/contour.md).
    pub max_linear_acceleration: f64,
    /// Tool-tip path jerk limit, mm/s³ (needed with `profile = "jerk-limited"` on a machine
    /// with `[kinematics]`). Default: none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_linear_jerk: Option<f64>,
    /// Blend tolerance of a plain `G64` (no `P`), mm. Default: LinuxCNC 2.9's rule, a quarter
    /// of the shorter block's length. (`junction_deviation`, its earlier name, is read too.)
    #[serde(alias = "junction_deviation", skip_serializing_if = "Option::is_none")]
    pub blend_tolerance: Option<f64>,
    /// Speed profile: `"trapezoidal"` (default) or `"jerk-limited"`.
    pub profile: ProfileFile,
    /// Planner rules: `"vcnc"` (default) or `"linuxcnc-2.9"` (LinuxCNC 2.9's planner).
    pub planner: PlannerFile,
}

impl Default for TrajectoryFile {
    fn default() -> Self {
        TrajectoryFile {
            max_linear_velocity: 250.0,
            max_linear_acceleration: 1500.0,
            max_linear_jerk: None,
            blend_tolerance: None,
            profile: ProfileFile::default(),
            planner: PlannerFile::default(),
        }
    }
}

/// `trajectory.profile`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProfileFile {
    /// Acceleration-limited trapezoids.
    #[default]
    Trapezoidal,
    /// Jerk-limited (needs every axis' `max_jerk`).
    JerkLimited,
}

/// `trajectory.planner`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum PlannerFile {
    /// vcnc's rules.
    #[default]
    #[serde(rename = "vcnc")]
    Vcnc,
    /// LinuxCNC 2.9's trajectory planner.
    #[serde(rename = "linuxcnc-2.9")]
    LinuxCnc29,
}

/// `[program_output]`: how vcnc writes programs the control runs (docs/machine-file.md,
/// "[program_output]").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProgramOutputFile {
    /// Resolution of linear-axis words, mm (0: full precision). Default 0.0001.
    pub resolution: f64,
    /// Resolution of rotary-axis words, deg (0: full precision). Default 0.0001.
    pub rotary_resolution: f64,
    /// The control's block cycle, s: the shortest time a block may last. Default: the sample
    /// period (one block per interpolation cycle at most).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub block_cycle_s: Option<f64>,
    /// How far a merged block's straight line may stray from the set-points it replaces,
    /// linear axes, mm. Default 0.0001.
    pub chord_tolerance: f64,
    /// The same for rotary axes, deg. Default 0.0001.
    pub rotary_chord_tolerance: f64,
}

impl Default for ProgramOutputFile {
    fn default() -> Self {
        ProgramOutputFile {
            resolution: 1e-4,
            rotary_resolution: 1e-4,
            block_cycle_s: None,
            chord_tolerance: 1e-4,
            rotary_chord_tolerance: 1e-4,
        }
    }
}

/// `[control]`: the control's nominal-position filters (docs/machine-file.md, "[control]").
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControlFile {
    /// Delay of the nominal position before the drives, s (whole sample periods). Default 0.
    pub delay_s: f64,
    /// Filters, in order. Default none.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub filters: Vec<ControlFilterFile>,
    /// Siemens Sinumerik's axial jerk filter, by its machine data (added after `filters`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sinumerik: Option<SinumerikJerkFilterFile>,
}

/// One filter of `control.filters`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ControlFilterFile {
    /// $1/(1 + Ts)$.
    FirstOrder {
        /// $T$, s.
        time_constant_s: f64,
    },
    /// $1/(T^2s^2 + 2\zeta Ts + 1)$.
    SecondOrder {
        /// $T$, s.
        time_constant_s: f64,
        /// $\zeta$ (default 1).
        #[serde(default = "default_zeta")]
        zeta: f64,
    },
    /// Moving average over `window_s` (whole sample periods).
    MovingAverage {
        /// The window, s.
        window_s: f64,
    },
    /// Triangle filter of base `window_s`: two moving averages of half the window each.
    Triangular {
        /// The base, s (an even number of sample periods).
        window_s: f64,
    },
    /// Band-stop: $\frac{\omega_d^2}{\omega_z^2}\,\frac{s^2 + 2\zeta_z\omega_z s + \omega_z^2}{s^2 + 2\zeta_d\omega_d s + \omega_d^2}$
    /// ([`vcnc_drive::ShapingFilter::BandStop`]).
    BandStop {
        /// Blocking frequency $f_z = \omega_z/2\pi$, Hz.
        frequency_hz: f64,
        /// $\zeta_z$ (notch depth; 0 blocks $f_z$ entirely).
        zeta_numerator: f64,
        /// $\zeta_d$ (width).
        zeta_denominator: f64,
        /// $f_d = \omega_d/2\pi$, Hz (default `frequency_hz`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        denominator_frequency_hz: Option<f64>,
    },
    /// FIR filter of the samples: $y_k = \sum_j h_j u_{k-j}$.
    Fir {
        /// The taps $h_0, h_1, \ldots$ (newest sample first), summing to 1.
        taps: Vec<f64>,
    },
}

fn default_zeta() -> f64 {
    1.0
}

/// `[control.sinumerik]`: the axial jerk filter of a Sinumerik 840D by its machine data
/// (MD32402 `AX_JERK_MODE`, MD32410 `AX_JERK_TIME`, MD32411 `AX_JERK_TIME_ADD`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SinumerikJerkFilterFile {
    /// MD32402: 2 moving average, 4 double moving average (1, 3 and 5 are not modelled; for 3,
    /// write a `band-stop` under `filters`).
    pub ax_jerk_mode: u8,
    /// MD32410, s.
    pub ax_jerk_time: f64,
    /// MD32411, s (mode 4; default `ax_jerk_time`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ax_jerk_time_add: Option<f64>,
}

/// `[gcode]`: dialect settings.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GcodeFile {
    /// M-codes that switch tool-centre-point mode on (LinuxCNC configs use e.g. M428).
    pub tcp_on_mcodes: Vec<u32>,
    /// M-codes that switch tool-centre-point mode off (e.g. M429).
    pub tcp_off_mcodes: Vec<u32>,
    /// The path mode before the program sets one (the control's start-up code): `"G61.1"`
    /// (default), `"G61"`, `"G64"`, `"G64 P<mm> [Q<mm>]"`. LinuxCNC 2.9 starts in a plain `G64`
    /// unless its INI file's start-up code names a mode.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub startup_path_mode: Option<String>,
}

/// `[identification]`: the identification program and the identifier.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IdentificationFile {
    /// The excitation program (paper section 4).
    pub program: ProgramFile,
    /// Identifier settings (PSO, bounds, prefilter, refinement, seed).
    pub options: IdentifyOptions,
}

/// `[identification.program]`: the paper's excitation, per axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProgramFile {
    /// Random moves per axis. Default 70.
    pub moves: usize,
    /// Moves stay within ±range, axis units. Default 50 (an axis may override it).
    pub range: f64,
    /// Highest feed, units/s. Default 250.
    pub max_feed: f64,
    /// Lowest feed, units/s. Default 25.
    pub min_feed: f64,
    /// Acceleration of the identification moves, units/s². Default: each axis' own
    /// `max_acceleration` (the paper used 2500 mm/s²).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_acceleration: Option<f64>,
    /// Seed of the estimation program. Default 1.
    pub seed: u64,
    /// Seed of the validation program (a different run of the same generator). Default 2.
    pub validation_seed: u64,
}

impl Default for ProgramFile {
    fn default() -> Self {
        ProgramFile {
            moves: 70,
            range: 50.0,
            max_feed: 250.0,
            min_feed: 25.0,
            max_acceleration: None,
            seed: 1,
            validation_seed: 2,
        }
    }
}

/// `[axes.<letter>]`: one feed drive and its limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisFile {
    /// `"mm"` (X Y Z) or `"deg"` (A B C).
    pub unit: Unit,
    /// Travel `[lower, upper]`, axis units. A continuous rotary axis may use ±1e9.
    pub travel: [f64; 2],
    /// Velocity limit, units/s.
    pub max_velocity: f64,
    /// Acceleration limit, units/s².
    pub max_acceleration: f64,
    /// Jerk limit, units/s³ (needed with `trajectory.profile = "jerk-limited"`). Default: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_jerk: Option<f64>,
    /// Mechanics and amplifier. Give it with `controller`, or neither: the axis is then known
    /// by its identified model (the machine's `model` file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plant: Option<Plant>,
    /// Controller gains, or desired poles to design them (with `plant`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller: Option<ControllerSpec>,
    /// Position encoder (default 1e-4 units, no noise).
    #[serde(default)]
    pub encoder: Encoder,
    /// Controller rate, Hz (default 20 000).
    #[serde(default = "default_servo_rate")]
    pub servo_rate_hz: f64,
    /// `[axes.<letter>.compliance]`: two-mass transmission and backlash (default: rigid).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compliance: Option<vcnc_drive::Compliance>,
    /// `[axes.<letter>.friction]`: Stribeck, direction-dependent, pre-sliding friction.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<vcnc_drive::Friction>,
    /// `[axes.<letter>.current_loop]`: current-loop dynamics and torque limit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub current_loop: Option<vcnc_drive::CurrentLoop>,
    /// `[axes.<letter>.feedback]`: position sensor, dead time, velocity filter.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feedback: Option<vcnc_drive::Feedback>,
    /// `[axes.<letter>.reference]`: nominal-position filter and interpolation delay.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<vcnc_drive::ReferenceShaping>,
    /// Identification-program half-range for this axis (default: `[identification.program]`'s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identification_range: Option<f64>,
    /// Centre of this axis' identification moves, axis units (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identification_centre: Option<f64>,
    /// Where the axis is when a program starts (machine coordinates, axis units): the first
    /// block moves from here, as on a control. Default 0, as after homing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<f64>,
}

fn default_servo_rate() -> f64 {
    vcnc_drive::params::DEFAULT_SERVO_RATE_HZ
}
