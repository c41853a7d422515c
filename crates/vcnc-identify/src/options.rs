//! Options of [`crate::identify`]: plain data, serialisable, embedded by the machine file
//! (unknown keys are errors). Every field states its unit and default.

use serde::{Deserialize, Serialize};
use vcnc_drive::drive_model::ReferenceInput;

use crate::Error;

/// Everything [`crate::identify`] can be told.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IdentifyOptions {
    /// Particle swarm settings (paper section 3.3.3 defaults).
    pub pso: PsoSettings,
    /// Search region of the poles (paper eq. 12, Fig. 4).
    pub bounds: PoleBounds,
    /// Zero-phase low-pass applied to every regressor column and to Y.
    pub prefilter: Prefilter,
    /// Deadband of $\mathrm{sgn}(\dot x)$, axis units/s (mm/s or deg/s). Default 1.5: above the
    /// velocity noise of a 1 µm encoder at 1 kHz after the prefilter, below any feed of interest
    /// (docs/identification.md: 1–2 mm/s).
    pub deadband: f64,
    /// Output-error refinement (docs/identification.md, beyond the paper).
    pub refine: RefineOptions,
    /// Seed of the ChaCha8 generator driving the swarm. Default 1.
    pub seed: u64,
    /// Whether the trace starts at rest. Default [`StartCondition::Auto`].
    pub start: StartCondition,
    /// Largest accepted 2-norm condition number of the column-scaled regressor matrix; beyond it
    /// the data cannot identify the model and [`crate::Error::IllConditioned`] is returned.
    /// Default 1e6 (the Table 1 run gives about 1e3; a single sine, which cannot separate the
    /// parameters, about 1e8).
    pub max_condition: f64,
    /// Model structures to identify besides the paper's, chosen by validation error
    /// ([`crate::identify`]). Default none: the paper's 7-parameter model only.
    pub structures: Vec<ModelStructure>,
    /// Search bounds of the extended structures' own parameters.
    pub extended_bounds: ExtendedBounds,
    /// Fraction of a single trace held out (at its end) to choose between structures, when no
    /// separate validation trace is given. Default 0.3.
    pub holdout_fraction: f64,
    /// Relative margin by which a structure with more parameters must beat a simpler one's
    /// validation error to be chosen, and by which the paper's structure with the other model
    /// input must beat its whole-trace error with the compared stretch's input for the input
    /// to change (docs/identification.md, "Choosing a structure"). Default 0.05.
    pub selection_margin: f64,
    /// Model inputs to try ([`ReferenceInput`]: `"smooth"`, `"hold"`), chosen with the
    /// structures by validation error (docs/identification.md, "The model input"). Default
    /// none: the trace's own — smooth when it carries the interpolator's exact derivatives
    /// (a simulated machine), else hold.
    pub inputs: Vec<ReferenceInput>,
    /// Relative margin by which a candidate whose parameters are on a bound or not determined
    /// must beat the best trusted candidate's validation error to be chosen
    /// (docs/identification.md, "Choosing a structure"). Default 0.3.
    pub degenerate_margin: f64,
}

/// A model structure ([`vcnc_drive::DriveModel`], docs/identification.md): the paper's seven
/// parameters, the paper's core without its integral mode, or the paper's with one addition.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelStructure {
    /// The paper's 7-parameter model.
    Paper,
    /// A position loop without integral action: the paper's core with $p \equiv 0$ exactly
    /// ($a_3 = 0$: no integral state) and unit reference gain ($b_2 = a_2$), so
    /// $x = \frac{b_0 s^2 + b_1 s + a_2}{s^2 + a_1 s + a_2}\,x_r - \frac{d_c}{s^2 + a_1 s + a_2}\,\operatorname{sgn}\dot x$
    /// (a P or PD position loop on a rigid drive; Coulomb friction leaves the steady offset
    /// $d_c/a_2$). Five parameters: $\omega_n$, $\zeta$, $b_1$, $b_0$, $d_c$.
    NoIntegral,
    /// With an input dead time $T_d$ (sub-sample resolution).
    Delay,
    /// With a first-order reference filter $1/(\tau s + 1)$.
    FirstOrderFilter,
    /// With a second-order reference filter.
    SecondOrderFilter,
    /// With one extra real pole of the whole loop.
    ExtraPole,
}

impl ModelStructure {
    /// Every structure, simplest first (the paper's, which every search identifies first,
    /// before its reduction).
    pub const ALL: [ModelStructure; 6] = [
        ModelStructure::Paper,
        ModelStructure::NoIntegral,
        ModelStructure::Delay,
        ModelStructure::FirstOrderFilter,
        ModelStructure::ExtraPole,
        ModelStructure::SecondOrderFilter,
    ];

    /// Parameters fitted: the paper's seven (three poles, $b_0$, $b_1$, $b_2$, $d_c$), five
    /// without the integral mode (no $p$, $b_2 = a_2$), the paper's and one or two more with an
    /// addition. Fewer is simpler in the choice ([`crate::identify`]).
    pub fn parameters(&self) -> usize {
        match self {
            ModelStructure::NoIntegral => 5,
            ModelStructure::Paper => 7,
            ModelStructure::SecondOrderFilter => 9,
            _ => 8,
        }
    }

    /// Whether the paper's structure is a limit of this one (no dead time, no filter lag, the
    /// extra pole far away): a converged fit of it is never worse than the paper's on the same
    /// data.
    pub fn contains_paper(&self) -> bool {
        !matches!(self, ModelStructure::Paper | ModelStructure::NoIntegral)
    }

    /// Order of the tracking path's denominator (the core's three poles, the filter's and the
    /// extra pole): the number of free responses of the model's output. Without the integral
    /// mode, the pair's two and the constant offset that takes the integral state's place.
    pub fn order(&self) -> usize {
        match self {
            ModelStructure::NoIntegral | ModelStructure::Paper | ModelStructure::Delay => 3,
            ModelStructure::FirstOrderFilter | ModelStructure::ExtraPole => 4,
            ModelStructure::SecondOrderFilter => 5,
        }
    }

    /// Name as in the options file.
    pub fn name(&self) -> &'static str {
        match self {
            ModelStructure::Paper => "paper",
            ModelStructure::NoIntegral => "no-integral",
            ModelStructure::Delay => "delay",
            ModelStructure::FirstOrderFilter => "first-order-filter",
            ModelStructure::SecondOrderFilter => "second-order-filter",
            ModelStructure::ExtraPole => "extra-pole",
        }
    }
}

impl std::fmt::Display for ModelStructure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Search bounds `[min, max]` of the extended structures' parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExtendedBounds {
    /// Dead time, s. Default `[0, 0.2]`.
    pub delay_s: [f64; 2],
    /// First-order filter time constant, s. Default `[1e-4, 0.2]`.
    pub filter_tau_s: [f64; 2],
    /// Second-order filter natural frequency, Hz. Default `[1, 200]`.
    pub filter_wn_hz: [f64; 2],
    /// Second-order filter damping ratio. Default `[0.3, 2.0]`.
    pub filter_zeta: [f64; 2],
    /// Extra pole, Hz. Default `[2, 2000]`.
    pub extra_pole_hz: [f64; 2],
}

impl Default for ExtendedBounds {
    fn default() -> Self {
        ExtendedBounds {
            delay_s: [0.0, 0.2],
            filter_tau_s: [1e-4, 0.2],
            filter_wn_hz: [1.0, 200.0],
            filter_zeta: [0.3, 2.0],
            extra_pole_hz: [2.0, 2000.0],
        }
    }
}

impl ExtendedBounds {
    /// Checks order and positivity (the dead time may start at 0).
    pub fn validate(&self) -> Result<(), Error> {
        for (name, [lo, hi], zero_ok) in [
            ("extended_bounds.delay_s", self.delay_s, true),
            ("extended_bounds.filter_tau_s", self.filter_tau_s, false),
            ("extended_bounds.filter_wn_hz", self.filter_wn_hz, false),
            ("extended_bounds.filter_zeta", self.filter_zeta, false),
            ("extended_bounds.extra_pole_hz", self.extra_pole_hz, false),
        ] {
            let lower_ok = if zero_ok { lo >= 0.0 } else { lo > 0.0 };
            if !(lo.is_finite() && hi.is_finite() && lower_ok && hi > lo && hi <= 1e6) {
                return Err(Error::InvalidBounds {
                    name,
                    min: lo,
                    max: hi,
                    expected: "finite bounds with 0 <= min < max (min > 0 but for the dead time)",
                });
            }
        }
        if self.delay_s[1] > vcnc_drive::MAX_DELAY_S {
            return Err(Error::InvalidBounds {
                name: "extended_bounds.delay_s",
                min: self.delay_s[0],
                max: self.delay_s[1],
                expected: "a dead time of at most 10 s",
            });
        }
        Ok(())
    }
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        IdentifyOptions {
            pso: PsoSettings::default(),
            bounds: PoleBounds::default(),
            prefilter: Prefilter::default(),
            deadband: 1.5,
            refine: RefineOptions::default(),
            seed: 1,
            start: StartCondition::Auto,
            max_condition: 1e6,
            structures: vec![ModelStructure::Paper],
            extended_bounds: ExtendedBounds::default(),
            holdout_fraction: 0.3,
            selection_margin: 0.05,
            inputs: vec![],
            degenerate_margin: 0.3,
        }
    }
}

impl IdentifyOptions {
    /// Checks every setting; returns the first problem found.
    pub fn validate(&self) -> Result<(), Error> {
        self.pso.validate()?;
        self.bounds.validate()?;
        if let Some(fc) = self.prefilter.cutoff_hz
            && !(fc > 0.0 && fc.is_finite())
        {
            return Err(Error::InvalidOption {
                name: "prefilter.cutoff_hz",
                value: fc,
                expected: "a positive cutoff frequency in Hz",
            });
        }
        if !(self.deadband >= 0.0 && self.deadband.is_finite()) {
            return Err(Error::InvalidOption {
                name: "deadband",
                value: self.deadband,
                expected: "a speed >= 0 in axis units/s",
            });
        }
        if self.max_condition.is_nan() || self.max_condition <= 1.0 {
            return Err(Error::InvalidOption {
                name: "max_condition",
                value: self.max_condition,
                expected: "a condition number above 1",
            });
        }
        if !(self.holdout_fraction >= 0.05 && self.holdout_fraction <= 0.5) {
            return Err(Error::InvalidOption {
                name: "holdout_fraction",
                value: self.holdout_fraction,
                expected: "a fraction of the trace in [0.05, 0.5]",
            });
        }
        if !(self.selection_margin >= 0.0 && self.selection_margin < 1.0) {
            return Err(Error::InvalidOption {
                name: "selection_margin",
                value: self.selection_margin,
                expected: "a relative margin in [0, 1)",
            });
        }
        if !(self.degenerate_margin >= 0.0 && self.degenerate_margin < 1.0) {
            return Err(Error::InvalidOption {
                name: "degenerate_margin",
                value: self.degenerate_margin,
                expected: "a relative margin in [0, 1)",
            });
        }
        self.extended_bounds.validate()?;
        self.refine.validate()
    }
}

/// Particle swarm settings (paper section 3.3; defaults are the paper's, section 4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PsoSettings {
    /// Number of particles $M$. Default 200.
    pub particles: usize,
    /// Number of iterations. Default 100.
    pub iterations: usize,
    /// Inertia weight $w$, in (0, 1). Default 0.6.
    pub w: f64,
    /// Cognitive (personal-best) gain $\eta_1$. Default 0.103.
    pub eta1: f64,
    /// Social (global-best) gain $\eta_2$. Default 2.897.
    pub eta2: f64,
    /// Velocity limit as a fraction of each search range,
    /// $v_{max} = (\sigma_{max} - \sigma_{min})\cdot$ `vmax_fraction`; the paper advises 0.1–0.2.
    /// Default 0.15.
    pub vmax_fraction: f64,
}

impl Default for PsoSettings {
    fn default() -> Self {
        PsoSettings {
            particles: 200,
            iterations: 100,
            w: 0.6,
            eta1: 0.103,
            eta2: 2.897,
            vmax_fraction: 0.15,
        }
    }
}

impl PsoSettings {
    /// Checks the settings, including the convergence condition of paper eq. 24: the eigenvalues
    /// of $H = \begin{bmatrix} w & -\eta \\ w & 1-\eta \end{bmatrix}$, roots of
    /// $\lambda^2 - (w + 1 - \eta)\lambda + w = 0$, lie inside the unit circle iff
    /// $$ 0 < w < 1, \qquad 0 < \eta = \eta_1 + \eta_2 < 2(1 + w) $$
    /// (Jury's test; the paper's $\eta = 3$ case needs $w > 0.5$).
    pub fn validate(&self) -> Result<(), Error> {
        if self.particles < 2 {
            return Err(Error::InvalidOption {
                name: "pso.particles",
                value: self.particles as f64,
                expected: "at least 2 particles",
            });
        }
        if self.iterations < 1 {
            return Err(Error::InvalidOption {
                name: "pso.iterations",
                value: self.iterations as f64,
                expected: "at least 1 iteration",
            });
        }
        for (name, v) in [("pso.eta1", self.eta1), ("pso.eta2", self.eta2)] {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(Error::InvalidOption {
                    name,
                    value: v,
                    expected: "a learning gain >= 0",
                });
            }
        }
        if !(self.vmax_fraction > 0.0 && self.vmax_fraction <= 1.0) {
            return Err(Error::InvalidOption {
                name: "pso.vmax_fraction",
                value: self.vmax_fraction,
                expected: "a fraction of the search range in (0, 1] (paper: 0.1-0.2)",
            });
        }
        let eta = self.eta1 + self.eta2;
        let limit = 2.0 * (1.0 + self.w);
        if !(self.w > 0.0 && self.w < 1.0 && eta > 0.0 && eta < limit) {
            return Err(Error::PsoDivergent {
                w: self.w,
                eta,
                limit,
            });
        }
        Ok(())
    }
}

/// Bounds of the search region $\sigma_{min} \le \sigma \le \sigma_{max}$ (paper eq. 12, Fig. 4).
///
/// Every model inside them is stable: a pole at $-p \le 0$ and a pair with $\omega_n > 0$,
/// $\zeta > 0$. The paper's bounds (the defaults) keep $p \ge 0.2$ Hz. A drive without integral
/// action (the EMPS benchmark, a P–P cascade) has its third pole at the origin: set
/// `p_hz = [0.0, ...]` so that $p$ can reach 0, where $a_3 = p\,\omega_n^2 = 0$ and the model is
/// the marginally stable integrator-free one (its numerator constant is $a_3 = 0$ too, so the
/// pole at the origin is cancelled in $G_{track}$ and the position stays bounded).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PoleBounds {
    /// Real pole $p$, `[min, max]` in Hz, min >= 0. Default `[0.2, 500]`.
    pub p_hz: [f64; 2],
    /// Natural frequency $\omega_n$, `[min, max]` in Hz, min > 0. Default `[0.2, 500]`.
    pub wn_hz: [f64; 2],
    /// Damping ratio $\zeta$, `[min, max]`, min > 0. Default `[0.2, 2.0]`.
    pub zeta: [f64; 2],
}

impl Default for PoleBounds {
    fn default() -> Self {
        PoleBounds {
            p_hz: [0.2, 500.0],
            wn_hz: [0.2, 500.0],
            zeta: [0.2, 2.0],
        }
    }
}

/// Largest pole-frequency bound accepted (Hz): a million times the bandwidth of a feed drive.
pub const MAX_POLE_HZ: f64 = 1e6;
/// Largest damping-ratio bound accepted.
pub const MAX_ZETA: f64 = 100.0;

impl PoleBounds {
    /// Checks order, finiteness, the stability-preserving lower limits and the upper limits
    /// (`MAX_POLE_HZ` = 1e6 Hz, `MAX_ZETA` = 100) beyond which a servo loop sampled at a few kHz means
    /// nothing and the discretisation would overflow.
    pub fn validate(&self) -> Result<(), Error> {
        let check = |name: &'static str, [lo, hi]: [f64; 2], strict: bool| {
            let lower_ok = if strict { lo > 0.0 } else { lo >= 0.0 };
            let cap = if name == "bounds.zeta" {
                MAX_ZETA
            } else {
                MAX_POLE_HZ
            };
            if !(lo.is_finite() && hi.is_finite() && lower_ok && hi > lo && hi <= cap) {
                return Err(Error::InvalidBounds {
                    name,
                    min: lo,
                    max: hi,
                    expected: match (strict, name == "bounds.zeta") {
                        (true, true) => "finite bounds with 0 < min < max <= 100",
                        (true, false) => "finite bounds with 0 < min < max <= 1e6 Hz",
                        _ => "finite bounds with 0 <= min < max <= 1e6 Hz",
                    },
                });
            }
            Ok(())
        };
        check("bounds.p_hz", self.p_hz, false)?;
        check("bounds.wn_hz", self.wn_hz, true)?;
        check("bounds.zeta", self.zeta, true)
    }

    /// Lower corner $\sigma_{min} = [p, \omega_n, \zeta]$ with frequencies in Hz.
    pub fn lower(&self) -> [f64; 3] {
        [self.p_hz[0], self.wn_hz[0], self.zeta[0]]
    }

    /// Upper corner $\sigma_{max}$ with frequencies in Hz.
    pub fn upper(&self) -> [f64; 3] {
        [self.p_hz[1], self.wn_hz[1], self.zeta[1]]
    }
}

/// Zero-phase prefilter of the regressors (docs/identification.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Prefilter {
    /// Apply the filter. Default true. Without it, a quantised encoder biases the second
    /// differences badly (docs/identification.md: $\omega_n$ +17 % and worse at 1 µm).
    pub enabled: bool,
    /// Cutoff of the second-order Butterworth section, Hz (the forward-backward pair is −6 dB
    /// there). Default: none given, which means $0.1/T_s$ (100 Hz at 1 kHz): above the
    /// closed-loop bandwidth of CNC feed drives (≤ 75 Hz in the paper's Table 3), and a decade below the
    /// sample rate, where the quantisation noise of second differences lives.
    pub cutoff_hz: Option<f64>,
}

impl Default for Prefilter {
    fn default() -> Self {
        Prefilter {
            enabled: true,
            cutoff_hz: None,
        }
    }
}

impl Prefilter {
    /// Default cutoff as a fraction of the sample rate.
    pub const DEFAULT_CUTOFF_FRACTION: f64 = 0.1;

    /// The cutoff used at sample period `ts`, Hz.
    pub fn cutoff_for(&self, ts: f64) -> f64 {
        self.cutoff_hz.unwrap_or(Self::DEFAULT_CUTOFF_FRACTION / ts)
    }
}

/// Output-error refinement settings (docs/identification.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RefineOptions {
    /// Run the refinement. Default true; when false, `identified` is the paper's PSO result.
    pub enabled: bool,
    /// Largest number of Levenberg–Marquardt iterations per stage. Default 40.
    pub max_iterations: usize,
    /// Stop when an accepted step, or the predicted undamped Gauss–Newton step, lowers the cost
    /// by less than this fraction. Default 1e-9.
    pub tolerance: f64,
    /// Most stage-B passes with the friction input of the previous model's own free run (0
    /// keeps the measured sign only; see [`crate::refine`]); the passes stop earlier when the
    /// friction input no longer changes or a pass's cost repeats the previous one's within
    /// 10⁻⁶. Default 8.
    pub sign_iterations: usize,
    /// Most starting points of the refinement: the swarm's distinct good particles, best
    /// first. Default 3.
    pub starts: usize,
}

impl Default for RefineOptions {
    fn default() -> Self {
        RefineOptions {
            enabled: true,
            max_iterations: 40,
            tolerance: 1e-9,
            sign_iterations: 8,
            starts: 3,
        }
    }
}

impl RefineOptions {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), Error> {
        if !(self.tolerance >= 0.0 && self.tolerance < 1.0) {
            return Err(Error::InvalidOption {
                name: "refine.tolerance",
                value: self.tolerance,
                expected: "a relative cost decrease in [0, 1)",
            });
        }
        if self.starts < 1 {
            return Err(Error::InvalidOption {
                name: "refine.starts",
                value: self.starts as f64,
                expected: "at least 1 starting point",
            });
        }
        Ok(())
    }
}

/// Whether the trace starts at rest (docs/identification.md assumes it does).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StartCondition {
    /// Decide from the data ([`crate::Trace::starts_at_rest`] with the sign deadband).
    #[default]
    Auto,
    /// At rest: zero initial conditions after subtracting the initial position.
    Rest,
    /// Moving (a cut-out of a longer log, such as the EMPS benchmark): the equation-error
    /// regression gets a constant column for the unknown integration constant; the
    /// output-error fit and the free run start the model at rest at the measured $x_0$ one
    /// sample before the first ([`crate::Trace::prefixed_reference`]).
    Moving,
}
