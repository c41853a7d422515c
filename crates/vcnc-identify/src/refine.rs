//! Output-error refinement (docs/identification.md, the step beyond the paper), for every model
//! structure ([`ModelStructure`]).
//!
//! The paper fits the equation error (eq. 16), whose regressors hold differentiated, noisy data:
//! central differences bias the fit as $\omega_n T_s$ grows, and a real pole nearly cancelled
//! by a zero leaves the cost flat along $p$. Here the free-run simulation error of the model is
//! minimised instead.
//!
//! # Separable least squares
//!
//! For fixed poles (and dead time, filter, extra pole: the nonlinear parameters $\eta$) the
//! free run of [`DriveModel`] is linear in $(b_2, b_1, b_0, d_c)$ for a given friction input
//! $F$ (variable projection, Golub and Pereyra 1973):
//! $$ \hat x = c_u\,(a_3 + b_2 s + b_1 s^2 + b_0 s^3)\,W - c_f\,d_c\,s\,W_F, \qquad W = \frac{e^{-sT_d}}{D_u(s)} x_r,\quad W_F = \frac{1}{D_f(s)} F, $$
//! with $D_u = D\,R\,P_d$ (core, filter and extra-pole denominators, monic), $D_f = D\,P_d$, and
//! $c_u$, $c_f$ the constants that give each factor unit static gain. One pass simulates $W$
//! and $W_F$ in time-scaled companion form (exact discretisation; a sub-sample dead time moves
//! the knots of the first-order hold, handled by two exact pieces per sample as
//! [`DriveModel::simulate_positions`] does) and reads the columns from the states; a 4×4
//! least squares on the column-scaled Gram matrix gives the linear parameters. Positions alone
//! drive the model (the first-order hold of the samples and its exact derivatives), unless the
//! trace carries the exact reference velocity and acceleration of a simulated machine and the
//! structure is the paper's; then those drive it, as [`vcnc_drive::ClosedLoopModel::simulate`]
//! does.
//!
//! # Parameterisation without a seam
//!
//! The core's poles are searched as the coefficients of $D(s) = s^3 + a_1 s^2 + a_2 s + a_3$
//! mapped smoothly onto the stable region (Routh–Hurwitz: $a_1 > 0$, $a_3 > 0$,
//! $a_1 a_2 > a_3$):
//! $$ a_1 = e^{\theta_1},\qquad a_3 = e^{\theta_3},\qquad a_2 = a_3/a_1 + e^{\theta_2}. $$
//! Every $\theta \in \mathbb{R}^3$ is a stable cubic and every stable cubic has one $\theta$. In
//! pole coordinates $(p, \omega_n, \zeta)$, by contrast, three real poles have three
//! representations, and the path between two of them passes where $p$ meets a pole of the pair:
//! there the map to the coefficients is singular and a gradient method stalls (independent
//! drives piled up at $\zeta = 1$ with $\omega_n$ off by 10–60 %). Only when the unconstrained
//! optimum lies outside the pole bounds ([`PoleBounds`]) is the fit repeated in bounded pole
//! coordinates from the nearest point inside, and the parameters that end on a bound are
//! reported ([`BoundHit`]). Dead time, filter and extra pole are searched inside their bounds
//! ([`crate::ExtendedBounds`]), frequencies on a log scale.
//!
//! # Levenberg–Marquardt
//!
//! Bounded Levenberg–Marquardt (Moré 1978) on the projected residual, with a forward-difference
//! Jacobian whose columns are evaluated in parallel, solved through a QR factorisation of the
//! tall $N \times m$ Jacobian (faer) and of the small damped system: no normal equations, whose
//! condition number would be squared. It starts from several distinct good particles of the
//! swarm and keeps the candidate with the lowest cost.
//!
//! # Friction
//!
//! Stage A takes $F$ as the sign of the measured motion. The model's own free run applies
//! friction according to its velocity, with sticking; stage B repeats the fit with the friction
//! input of the previous model's free run ([`DriveModel::simulate_run`]), a fixed-point
//! iteration run until the friction input stops changing or a stage's cost repeats the
//! previous one's (each stage restarts Levenberg–Marquardt, which carries the fit down a long
//! curved valley of the cost). A stage that leaves the pole bounds is fitted again in bounded
//! pole coordinates and the stages go on there.
//!
//! The fixed point is not the minimum of the true free-run error: each stage holds the friction
//! input fixed and so ignores how the model's own sticking moves with its parameters. Where the
//! drive sticks often (strong Coulomb friction, a slow real pole) the two are far apart. Stage C
//! therefore fits the best stage's model directly on its own free run, sticking included: every
//! parameter, linear ones too, by the same Levenberg–Marquardt on the free run's residual
//! ([`FreeRunFit`]; the friction level of a sticking step is continuous in the parameters, so
//! the residual is too). On a drive with ζ = 0.35 and Coulomb friction a tenth of its
//! acceleration, stage B ended at 0.149 µm free-run RMS with $\zeta$ −5.8 %; stage C reached
//! 0.078 µm (the true model: 0.079 µm) with every pole within 1 %. Of every stage the model with
//! the smallest true free-run error is returned. On a trace that starts moving the free run
//! starts from an estimated state, and stage C also fits that estimate's error: on one drive
//! of the randomised suite it bent the linear parameters of an extra-pole model to it
//! (validation 0.94× → 1.54× the true model's) while it mends three moving starts of the
//! independent simulator (docs/identification.md, "Stage C").
//!
//! # Uncertainty
//!
//! At the solution, the Jacobian $J$ of the residual with respect to every parameter
//! (nonlinear and linear) gives the sandwich covariance
//! $$ \mathrm{Cov} = (J^TJ)^{-1}\,\Omega\,(J^TJ)^{-1}, \qquad \Omega = \frac{1}{b}\sum_{j} S_j S_j^T,\quad S_j = \sum_{t=j}^{j+b-1} J_t^T r_t, $$
//! the overlapping-batch-means (Bartlett-kernel) estimate of the long-run covariance of the
//! scores, which accounts for the strong autocorrelation of an output-error residual (the naive
//! $\sigma^2 (J^TJ)^{-1}$ assumes white residuals and is too small by orders of magnitude). The
//! window $b$ follows Andrews' (1991) AR(1) plug-in rule. The standard deviations of $p$,
//! $\omega_n$, $\zeta$, $d_c$ and the extra parameters follow by the delta method.
//!
//! Along a flat or curved valley of the cost the curvature at the optimum overstates how fast
//! the cost rises, and the linearised deviation is too small. Each pole of $p$, $\omega_n$,
//! $\zeta$ whose linearised relative deviation exceeds [`PROFILE_RELATIVE`] is therefore checked
//! against its profile $\Delta C_i(\delta)$, the cost rise with the pole held $\delta$ away and
//! everything else re-fitted. A quadratic cost has $\Delta C_i = \tfrac12\delta^2 /
//! (J^TJ)^{-1}_{ii}$, and the sandwich variance $V_{ii}$ puts one standard deviation at
//! $$ \Delta C_1 = \frac{V_{ii}}{2\,(J^TJ)^{-1}_{ii}}; $$
//! the reported deviation is the half-width, over $k = 2$, of the interval where the profile
//! stays below $k^2 \Delta C_1$ (a likelihood-ratio interval of about 95 % calibrated by the
//! sandwich: the linearised $\pm2\sigma$ when the cost is quadratic, wider when it is flatter),
//! and never less than the linearised deviation (docs/identification.md, Parameter
//! uncertainty).

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use vcnc_drive::drive_model::ReferenceInput;
use vcnc_drive::{ClosedLoopModel, DriveModel, ModelInput, Poles, ReferenceFilter, SimOptions};

use crate::Error;
use crate::options::{ExtendedBounds, ModelStructure, PoleBounds, RefineOptions};
use crate::regress::Regressors;
use crate::trace::Trace;

const TAU: f64 = std::f64::consts::TAU;

/// Result of the output-error refinement of one structure.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineResult {
    /// Refined model.
    pub model: DriveModel,
    /// Poles of its core (inside the bounds).
    pub poles: Poles,
    /// Output-error cost $\tfrac12\sum_k (x_k - \hat x_k)^2$ of the best start before the
    /// refinement (measured friction sign), axis units².
    pub start_cost: f64,
    /// Output-error cost of `model` with the friction input of its stage, axis units².
    pub cost: f64,
    /// RMS output error of `model` with the friction input of its stage, axis units.
    pub rms: f64,
    /// Cost after each accepted step of the run that produced `model`, axis units².
    pub cost_history: Vec<f64>,
    /// Every candidate considered, in order (the starts' stage A results, then stage B, then
    /// stage C when it lowers the free-run error).
    pub stages: Vec<RefineStage>,
    /// Index in `stages` of the one returned.
    pub chosen: usize,
    /// Levenberg–Marquardt iterations made, all starts and stages.
    pub iterations: usize,
    /// O(N) evaluations made.
    pub evaluations: usize,
    /// Parameters that ended on a bound of the search region.
    pub on_bounds: Vec<BoundHit>,
    /// Standard deviations of the physical parameters (see the module documentation), when
    /// they could be computed.
    pub uncertainty: Option<Uncertainty>,
}

/// One candidate of the refinement.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineStage {
    /// Where its friction input came from.
    pub sign: SignSource,
    /// Its model.
    pub model: DriveModel,
    /// Output-error cost with that friction input, axis units².
    pub cost: f64,
    /// RMS error of the model's true free run ([`crate::free_run_model`]) on the trace, axis
    /// units.
    pub freerun_rms: f64,
}

/// Source of the friction input of a refinement stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignSource {
    /// Measured motion (stage A), from the start with this index.
    Measured(usize),
    /// The previous model's own free run (stage B), with the iteration number from 1.
    Model(usize),
    /// The model's own free run throughout, fitted directly (stage C).
    FreeRun,
}

/// A parameter that ended on a bound of its search region.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BoundHit {
    /// Parameter name as in the options (`p_hz`, `wn_hz`, `zeta`, `delay_s`,
    /// `filter_tau_s`, `filter_wn_hz`, `filter_zeta`, `extra_pole_hz`).
    pub parameter: &'static str,
    /// Its value (unit of the parameter).
    pub value: f64,
    /// `"lower"` or `"upper"`.
    pub bound: &'static str,
}

/// Standard deviations of the physical parameters of a refined model.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Uncertainty {
    /// One entry per parameter, in a fixed order: `p_hz`, `wn_hz`, `zeta`, `dc`, then the
    /// structure's own (`delay_s`, `filter_tau_s`, `filter_wn_hz`, `filter_zeta`,
    /// `extra_pole_hz`).
    pub parameters: Vec<ParameterStd>,
    /// When the pair is real ($\zeta \ge 1$): its two real poles, `pair_slow_hz` and
    /// `pair_fast_hz` (Hz, the decay rates over $2\pi$), which is what the data determine
    /// there; near $\zeta = 1$ the split of the pair into $\omega_n$ and $\zeta$ is itself
    /// poorly determined.
    pub real_pair: Option<[ParameterStd; 2]>,
    /// Window of the long-run covariance estimate, samples.
    pub window_samples: usize,
}

/// One parameter's value and standard deviation.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ParameterStd {
    /// Parameter name (`p_hz`, `wn_hz`, `zeta`, `dc`, `delay_s`, ...).
    pub name: &'static str,
    /// Value, in the parameter's unit (Hz, dimensionless, axis units/s², s).
    pub value: f64,
    /// Standard deviation, same unit: the linearised one (`linear_std`) or, for a weakly
    /// determined pole whose cost profile is flatter than its curvature says, the profile's
    /// (see the module documentation).
    pub std: f64,
    /// Linearised (sandwich, delta-method) standard deviation, same unit.
    pub linear_std: f64,
    /// The part of `std` due to the model input's reconstruction (the parameter's sensitivity
    /// to it, weighed by how clearly validation chose the input; 0 when not assessed), same
    /// unit: `std` is the root sum of squares of it, `friction_std` and the rest.
    pub input_std: f64,
    /// The part of `std` due to the friction input (half the parameter's larger first-order
    /// change when the friction input moves by half a sample either way; 0 when not assessed,
    /// and for $d_c$), same unit.
    pub friction_std: f64,
}

impl ParameterStd {
    /// Relative standard deviation $\sigma/|v|$ (∞ for a zero value).
    pub fn relative(&self) -> f64 {
        if self.value == 0.0 {
            f64::INFINITY
        } else {
            self.std / self.value.abs()
        }
    }

    /// Whether the data determine the parameter: its relative deviation at most
    /// [`POORLY_DETERMINED`] ([`Determination::Determined`]), above it
    /// ([`Determination::Poor`]: print "poorly determined", not the number as if it were
    /// known), or undefined ([`Determination::Undetermined`]).
    pub fn determination(&self) -> Determination {
        let r = self.relative();
        if r.is_nan() {
            Determination::Undetermined
        } else if r <= POORLY_DETERMINED {
            Determination::Determined
        } else {
            Determination::Poor
        }
    }
}

/// Relative standard deviation (10 %) above which a parameter is reported as poorly
/// determined ([`ParameterStd::determination`]).
pub const POORLY_DETERMINED: f64 = 0.1;

/// How well the data determine a parameter ([`ParameterStd::determination`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Determination {
    /// Relative deviation at most [`POORLY_DETERMINED`].
    Determined,
    /// Relative deviation above [`POORLY_DETERMINED`]: the number is not known.
    Poor,
    /// No deviation can be given: the data do not constrain the parameter at all.
    Undetermined,
}

impl std::fmt::Display for Determination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Determination::Determined => "determined",
            Determination::Poor => "poorly determined",
            Determination::Undetermined => "not determined by the data",
        })
    }
}

impl Uncertainty {
    /// The entry of parameter `name`.
    pub fn get(&self, name: &str) -> Option<&ParameterStd> {
        self.parameters.iter().find(|p| p.name == name)
    }

    /// Names of the parameters whose relative standard deviation exceeds `threshold` (the
    /// command line warns at 0.1: such a number should not be printed as if it were known).
    pub fn flagged(&self, threshold: f64) -> Vec<&'static str> {
        self.parameters
            .iter()
            .filter(|p| {
                matches!(
                    p.relative().partial_cmp(&threshold),
                    Some(std::cmp::Ordering::Greater) | None
                )
            })
            .map(|p| p.name)
            .collect()
    }
}

/// The output-error problem of one trace, in deviations from the first reference sample, with
/// one model input ([`ReferenceInput`]) — exactly as [`crate::free_run_model`] simulates it. A
/// trace that starts moving gets the model's initial state as further linear parameters (the
/// free responses of the model's modes, docs/identification.md, "Traces that start moving").
#[derive(Debug, Clone)]
pub struct OutputErrorProblem {
    ts: f64,
    /// Reference deviation, axis units.
    u: Vec<f64>,
    /// Reference velocity and acceleration of the smooth input (exact when the trace carries
    /// them, else central differences of the positions); empty for the hold input.
    ud: Vec<f64>,
    udd: Vec<f64>,
    /// Measured deviation, axis units.
    x: Vec<f64>,
    /// Friction input over $[t_k, t_{k+1}]$.
    f: Vec<f64>,
    input: ReferenceInput,
    /// The trace starts moving: the fit estimates the model's initial state (free responses).
    moving: bool,
    /// Samples at the start left out of the fit: those within the largest dead time searched,
    /// for a trace that starts moving (the reference before its first sample is not known).
    skip: usize,
}

impl OutputErrorProblem {
    /// The problem of `trace` with the model input `input` and the measured friction sign
    /// (prefiltered displacement over each sample with the deadband, from `regs`).
    pub fn new(trace: &Trace, regs: &Regressors, input: ReferenceInput) -> OutputErrorProblem {
        let offset = trace.xr[0];
        let (ud, udd) = match input {
            ReferenceInput::Hold => (vec![], vec![]),
            ReferenceInput::Smooth => trace.smooth_rates(),
        };
        OutputErrorProblem {
            ts: trace.ts,
            u: trace.xr.iter().map(|v| v - offset).collect(),
            ud,
            udd,
            x: trace.x.iter().map(|v| v - offset).collect(),
            f: regs.interval_signs(),
            input,
            moving: !trace.starts_at_rest(crate::trace::REST_SPEED),
            skip: 0,
        }
    }

    fn n(&self) -> usize {
        self.u.len().min(self.x.len()).min(self.f.len())
    }

    /// The reference as the model's input, over the first `n` samples.
    fn model_input(&self, n: usize) -> ModelInput<'_> {
        match self.input {
            ReferenceInput::Smooth => ModelInput::Derivatives(vcnc_drive::Reference {
                pos: &self.u[..n],
                vel: &self.ud[..n],
                acc: &self.udd[..n],
            }),
            ReferenceInput::Hold => ModelInput::Positions(&self.u[..n]),
        }
    }

    /// The free run of `model` through this problem's reference with the model's own friction
    /// (with sticking): from rest, or, for a trace that starts moving, from the state that best
    /// explains the measurement (the estimated state of [`crate::free_run_model`]'s scoring).
    /// Returns its RMS error over every sample (∞ when not finite) and its friction level over
    /// each sample.
    fn own_run(&self, model: &DriveModel) -> Result<(f64, Vec<f64>), Error> {
        let mut resid = vec![];
        let friction = self.own_residual(model, &mut resid)?;
        let s2: f64 = resid.iter().map(|r| r * r).sum();
        let rms = (s2 / resid.len().max(1) as f64).sqrt();
        Ok((if rms.is_finite() { rms } else { f64::INFINITY }, friction))
    }

    /// [`Self::own_run`]'s error over each sample (model minus measurement) into `resid`;
    /// returns the friction level over each sample.
    fn own_residual(&self, model: &DriveModel, resid: &mut Vec<f64>) -> Result<Vec<f64>, Error> {
        let n = self.n();
        // A moving start's run counts from the first sample its state is fitted on (the
        // skipped ones left out, as the projected fit leaves them out): before it the state,
        // fitted from later samples, can be anything. A delay model fitted from sample 202,
        // where its modes' free responses had decayed to 1e-10, ran from a state of 1e7 and
        // counted 19 mm RMS over a 570 k-sample trace.
        let (run, first) = if self.moving {
            let tr = Trace::new(self.ts, self.u[..n].to_vec(), self.x[..n].to_vec())?;
            let tr = match self.input {
                ReferenceInput::Smooth => {
                    tr.with_reference_derivatives(self.ud[..n].to_vec(), self.udd[..n].to_vec())?
                }
                ReferenceInput::Hold => tr,
            };
            let (run, _, first) =
                crate::metrics::run_from_estimated_state(model, &tr, self.skip..n)?;
            (run, first)
        } else {
            let input = self.model_input(n);
            (
                model.simulate_run(input, self.ts, &SimOptions::default())?,
                0,
            )
        };
        resid.clear();
        resid.extend(
            run.position[..n]
                .iter()
                .zip(&self.x[..n])
                .map(|(a, b)| a - b),
        );
        resid[..first.min(n)].fill(0.0);
        Ok(run.friction)
    }
}

/// Stage C (module documentation): the model's own free run, friction with sticking included,
/// fitted directly. Parameters: the nonlinear ones of `lay` followed by $b_2$ (not without the
/// integral mode, where $b_2 = a_2$), $b_1$, $b_0$, $d_c$.
struct FreeRunFit<'a> {
    prob: &'a OutputErrorProblem,
    lay: &'a Layout,
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// Magnitude below which a linear parameter's finite-difference step stops shrinking.
    floors: Vec<f64>,
}

impl<'a> FreeRunFit<'a> {
    fn new(prob: &'a OutputErrorProblem, lay: &'a Layout, start: &DriveModel) -> Self {
        let c = start.core;
        let mut lo = lay.lo.clone();
        let mut hi = lay.hi.clone();
        let mut floors: Vec<f64> = if lay.no_integral() {
            vec![]
        } else {
            vec![c.a2.abs()]
        };
        floors.extend([c.a1.abs(), 1e-2, c.dc.abs()]);
        for f in &mut floors {
            *f = f.max(1e-9);
        }
        lo.extend(floors.iter().map(|_| f64::NEG_INFINITY));
        hi.extend(floors.iter().map(|_| f64::INFINITY));
        FreeRunFit {
            prob,
            lay,
            lo,
            hi,
            floors,
        }
    }

    /// The parameter vector of `eta` (the layout's) and `model`'s linear parameters.
    fn params(&self, eta: &[f64], model: &DriveModel) -> Vec<f64> {
        let c = model.core;
        let mut v = eta.to_vec();
        if !self.lay.no_integral() {
            v.push(c.b2);
        }
        v.extend([c.b1, c.b0, c.dc]);
        v
    }

    /// The layout's parameters and the model of `v`.
    fn split<'v>(&self, v: &'v [f64]) -> (&'v [f64], DriveModel) {
        let m = self.lay.m();
        let (eta, lin) = v.split_at(m);
        let lin = if self.lay.no_integral() {
            [0.0, lin[0], lin[1], lin[2]]
        } else {
            [lin[0], lin[1], lin[2], lin[3]]
        };
        (eta, self.lay.model(eta, &lin))
    }
}

impl LeastSquares for FreeRunFit<'_> {
    fn n(&self) -> usize {
        self.prob.n()
    }
    fn bounds(&self) -> (&[f64], &[f64]) {
        (&self.lo, &self.hi)
    }
    fn work(&self) -> Work {
        Work::residuals_only(self.prob.n())
    }
    fn step(&self, j: usize, v: f64) -> f64 {
        let m = self.lay.m();
        if j < m {
            self.lay.step(j, v, self.prob.ts)
        } else {
            1e-6 * v.abs().max(self.floors[j - m])
        }
    }
    fn evaluate(&self, v: &[f64], w: &mut Work) {
        w.cost = f64::INFINITY;
        let (_, model) = self.split(v);
        if !model.is_stable() || self.prob.own_residual(&model, &mut w.resid).is_err() {
            return;
        }
        let cost = 0.5 * w.resid.iter().map(|r| r * r).sum::<f64>();
        if cost.is_finite() {
            w.cost = cost;
        }
    }
}

/// The nonlinear parameters of a structure and their search box.
#[derive(Debug, Clone)]
struct Layout {
    structure: ModelStructure,
    /// The model input (written into the models).
    input: ReferenceInput,
    /// Core in pole coordinates (p Hz, ωn Hz, ζ) instead of the coefficient map.
    boxed_core: bool,
    lo: Vec<f64>,
    hi: Vec<f64>,
}

impl Layout {
    fn new(
        s: ModelStructure,
        input: ReferenceInput,
        boxed_core: bool,
        pb: &PoleBounds,
        eb: &ExtendedBounds,
    ) -> Layout {
        // The core without the integral mode has no p: its pair alone.
        let skip = usize::from(s == ModelStructure::NoIntegral);
        let (mut lo, mut hi) = if boxed_core {
            (pb.lower()[skip..].to_vec(), pb.upper()[skip..].to_vec())
        } else {
            (
                vec![f64::NEG_INFINITY; 3 - skip],
                vec![f64::INFINITY; 3 - skip],
            )
        };
        let ln = |v: [f64; 2]| [v[0].ln(), v[1].ln()];
        let mut push = |b: [f64; 2]| {
            lo.push(b[0]);
            hi.push(b[1]);
        };
        match s {
            ModelStructure::Paper | ModelStructure::NoIntegral => {}
            ModelStructure::Delay => push(eb.delay_s),
            ModelStructure::FirstOrderFilter => push(ln(eb.filter_tau_s)),
            ModelStructure::SecondOrderFilter => {
                push(ln(eb.filter_wn_hz));
                push(eb.filter_zeta);
            }
            ModelStructure::ExtraPole => push(ln(eb.extra_pole_hz)),
        }
        Layout {
            structure: s,
            input,
            boxed_core,
            lo,
            hi,
        }
    }

    fn m(&self) -> usize {
        self.lo.len()
    }

    /// Whether the core has no integral mode ($a_3 \equiv 0$, $b_2 = a_2$).
    fn no_integral(&self) -> bool {
        self.structure == ModelStructure::NoIntegral
    }

    /// Entries of `eta` that are the core's: 3, or 2 without the integral mode (the pair
    /// alone: $(\ln a_1, \ln a_2)$, or $(\omega_n, \zeta)$ in pole coordinates). The
    /// structure's own parameters follow.
    fn nc(&self) -> usize {
        if self.no_integral() { 2 } else { 3 }
    }

    /// Entries of the physical poles $(p, \omega_n, \zeta)$ that the core does not search
    /// (without the integral mode, $p \equiv 0$): pole `i` is `eta[i - pole_offset()]`.
    fn pole_offset(&self) -> usize {
        3 - self.nc()
    }

    /// Core coefficients of `eta`.
    fn core(&self, eta: &[f64]) -> (f64, f64, f64) {
        match (self.no_integral(), self.boxed_core) {
            (true, true) => Poles::from_hz(0.0, eta[0], eta[1]).denominator(),
            (true, false) => (eta[0].exp(), eta[1].exp(), 0.0),
            (false, true) => Poles::from_hz(eta[0], eta[1], eta[2]).denominator(),
            (false, false) => {
                let a1 = eta[0].exp();
                let a3 = eta[2].exp();
                (a1, a3 / a1 + eta[1].exp(), a3)
            }
        }
    }

    /// The core's poles at `eta` as searched: exact in pole coordinates, $p = 0$ without the
    /// integral mode; `None` in coefficient space with the integral mode (the split is chosen
    /// against the bounds, [`poles_inside`]).
    fn searched_poles(&self, eta: &[f64]) -> Option<Poles> {
        match (self.no_integral(), self.boxed_core) {
            (true, true) => Some(Poles::from_hz(0.0, eta[0], eta[1])),
            (false, true) => Some(Poles::from_hz(eta[0], eta[1], eta[2])),
            (true, false) => {
                let (a1, a2, _) = self.core(eta);
                let wn = a2.sqrt();
                Some(Poles {
                    p: 0.0,
                    wn,
                    zeta: a1 / (2.0 * wn),
                })
            }
            (false, false) => None,
        }
    }

    /// The core's poles inside the pole bounds `b`, if they are (without the integral mode
    /// the pair alone is bounded).
    fn poles_inside(&self, core: &ClosedLoopModel, b: &PoleBounds) -> Option<Poles> {
        if !self.no_integral() {
            return poles_inside(core, b);
        }
        let wn = core.a2.sqrt();
        let p = Poles {
            p: 0.0,
            wn,
            zeta: core.a1 / (2.0 * wn),
        };
        let v = [p.wn_hz(), p.zeta];
        let (lo, hi) = (b.lower(), b.upper());
        (0..2)
            .all(|j| v[j] >= lo[j + 1] && v[j] <= hi[j + 1])
            .then_some(p)
    }

    /// `eta` of a core (coefficients) and extra parameters.
    fn eta_of(&self, core: (f64, f64, f64), extra: &[f64]) -> Option<Vec<f64>> {
        let (a1, a2, a3) = core;
        let mut v = if self.no_integral() {
            // The pair of the start's denominator (a start with an integral mode keeps its
            // a1, a2).
            if !(a1 > 0.0 && a2 > 0.0) {
                return None;
            }
            if self.boxed_core {
                let wn = a2.sqrt();
                vec![wn / TAU, a1 / (2.0 * wn)]
            } else {
                vec![a1.ln(), a2.ln()]
            }
        } else if self.boxed_core {
            let p = ClosedLoopModel::characteristic(a1, a2, a3).poles()?;
            vec![p.p_hz(), p.wn_hz(), p.zeta]
        } else {
            // A start with its pole at the origin (a drive without integral action) starts
            // just off it: the map reaches a3 = 0 only in the limit.
            let a3 = a3.max(1e-12 * a1 * a2);
            let g = a2 - a3 / a1;
            if !(a1 > 0.0 && a3 > 0.0 && g > 0.0) {
                return None;
            }
            vec![a1.ln(), g.ln(), a3.ln()]
        };
        v.extend_from_slice(extra);
        for (j, x) in v.iter_mut().enumerate() {
            *x = x.clamp(self.lo[j], self.hi[j]);
        }
        v.iter().all(|x| x.is_finite()).then_some(v)
    }

    /// The model of `eta` with linear parameters `lin = [b2, b1, b0, dc, ...]`.
    fn model(&self, eta: &[f64], lin: &[f64]) -> DriveModel {
        let (a1, a2, a3) = self.core(eta);
        let core = ClosedLoopModel {
            a1,
            a2,
            a3,
            b0: lin[2],
            b1: lin[1],
            // Unit reference gain without the integral mode (its column is held at 0).
            b2: if self.no_integral() { a2 } else { lin[0] },
            dc: lin[3],
        };
        let mut m = DriveModel {
            input: self.input,
            ..DriveModel::from(core)
        };
        match self.structure {
            ModelStructure::Paper | ModelStructure::NoIntegral => {}
            ModelStructure::Delay => m.delay_s = eta[3],
            ModelStructure::FirstOrderFilter => {
                m.reference_filter = Some(ReferenceFilter::FirstOrder {
                    tau_s: eta[3].exp(),
                })
            }
            ModelStructure::SecondOrderFilter => {
                m.reference_filter = Some(ReferenceFilter::SecondOrder {
                    wn_hz: eta[3].exp(),
                    zeta: eta[4],
                })
            }
            ModelStructure::ExtraPole => m.extra_pole_hz = Some(eta[3].exp()),
        }
        m
    }

    /// Names of the extra parameters, with the map from `eta` to their physical value.
    fn extra_names(&self) -> Vec<&'static str> {
        match self.structure {
            ModelStructure::Paper | ModelStructure::NoIntegral => vec![],
            ModelStructure::Delay => vec!["delay_s"],
            ModelStructure::FirstOrderFilter => vec!["filter_tau_s"],
            ModelStructure::SecondOrderFilter => vec!["filter_wn_hz", "filter_zeta"],
            ModelStructure::ExtraPole => vec!["extra_pole_hz"],
        }
    }

    fn extra_physical(&self, eta: &[f64]) -> Vec<f64> {
        match self.structure {
            ModelStructure::Paper | ModelStructure::NoIntegral => vec![],
            ModelStructure::Delay => vec![eta[3]],
            ModelStructure::FirstOrderFilter | ModelStructure::ExtraPole => vec![eta[3].exp()],
            ModelStructure::SecondOrderFilter => vec![eta[3].exp(), eta[4]],
        }
    }

    /// Forward-difference step of parameter `j` at `v`.
    fn step(&self, j: usize, v: f64, ts: f64) -> f64 {
        let h = if self.boxed_core && j < self.nc() {
            1e-6 * v.abs().max(1e-3 * (self.hi[j] - self.lo[j]))
        } else if self.structure == ModelStructure::Delay && j == 3 {
            1e-4 * ts
        } else {
            1e-6
        };
        if v + h > self.hi[j] { -h } else { h }
    }
}

/// The discretised denominators of one evaluation.
struct Disc {
    /// Tracking companion system: one piece, or two for a sub-sample dead time.
    pieces: Vec<Piece>,
    /// Friction companion system (one piece of $T_s$, zero-order hold).
    fric: Piece,
    /// Monic $D_u$ coefficients $d_0 .. d_{n-1}$ (of $s^0 .. s^{n-1}$).
    du: Vec<f64>,
    /// Time scale of the companion states, rad/s.
    om: f64,
    cu: f64,
    cf: f64,
    /// The numerator constant held by the unit static gain: $a_3$, or $a_2$ without the
    /// integral mode (where it is $b_2$, whose column is then held at 0).
    fixed: f64,
    /// Power of $s$ of the first linear column ($b_2$'s): 1 ($N = \ldots + b_2 s + a_3$ over
    /// $D$), or 0 without the integral mode (the common factor $s$ of $N$ and $D$ cancelled).
    lead: usize,
    /// Whole samples and fraction of the dead time.
    m: usize,
    phi: f64,
    /// 1 without the integral mode: a constant position offset is a state of the model
    /// ([`vcnc_drive::DriveModel::realisation`]), a free response of a trace that starts moving.
    offset: usize,
}

impl Disc {
    /// Transition matrix of a whole sample period of the tracking system.
    fn step_phi(&self) -> DMatrix<f64> {
        match &self.pieces[..] {
            [a, b] => &b.phi * &a.phi,
            [a] => a.phi.clone(),
            _ => DMatrix::zeros(0, 0),
        }
    }
}

/// One exact piece of a companion system: $y(h) = \Phi y + \gamma u_0 + \rho (u_1 - u_0)$.
struct Piece {
    phi: DMatrix<f64>,
    gamma: Vec<f64>,
    ramp: Vec<f64>,
}

fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// Companion piece of the monic polynomial with low-to-high coefficients `d` (length n + 1,
/// last 1), time scale `om`, length `h`.
fn companion_piece(d: &[f64], om: f64, h: f64) -> Option<Piece> {
    let n = d.len() - 1;
    let size = n + 2;
    let mut m = DMatrix::<f64>::zeros(size, size);
    for j in 0..n - 1 {
        m[(j, j + 1)] = om * h;
    }
    for (i, di) in d.iter().enumerate().take(n) {
        m[(n - 1, i)] = -di * om.powi(i as i32 - n as i32 + 1) * h;
    }
    m[(n - 1, n)] = h / om.powi(n as i32 - 1);
    m[(n, n + 1)] = h;
    let norm = (0..size)
        .map(|j| m.column(j).iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    if !(norm.is_finite() && norm <= vcnc_drive::model::MAX_EXP_NORM) {
        return None;
    }
    let e = m.exp();
    if e.iter().any(|v| !v.is_finite()) {
        return None;
    }
    Some(Piece {
        phi: e.view((0, 0), (n, n)).into_owned(),
        gamma: (0..n).map(|i| e[(i, n)]).collect(),
        ramp: (0..n).map(|i| e[(i, n + 1)] / h).collect(),
    })
}

impl Layout {
    fn discretize(&self, eta: &[f64], ts: f64) -> Option<Disc> {
        let (a1, a2, a3) = self.core(eta);
        if !(a1.is_finite() && a2.is_finite() && a3.is_finite() && a2 > 0.0) {
            return None;
        }
        let (d, fixed, lead) = if self.no_integral() {
            (vec![a2, a1, 1.0], a2, 0)
        } else {
            (vec![a3, a2, a1, 1.0], a3, 1)
        };
        let (mut du, mut df, mut cu, mut cf) = (d.clone(), d.clone(), 1.0, 1.0);
        let (mut m, mut phi) = (0usize, 0.0);
        match self.structure {
            ModelStructure::Paper | ModelStructure::NoIntegral => {}
            ModelStructure::Delay => {
                let mut q = eta[3] / ts;
                if (q - q.round()).abs() < 1e-9 {
                    q = q.round();
                }
                m = q.floor() as usize;
                phi = q - q.floor();
                if phi < 1e-12 {
                    phi = 0.0;
                }
            }
            ModelStructure::FirstOrderFilter => {
                let k = 1.0 / eta[3].exp();
                du = poly_mul(&d, &[k, 1.0]);
                cu = k;
            }
            ModelStructure::SecondOrderFilter => {
                let w = TAU * eta[3].exp();
                du = poly_mul(&d, &[w * w, 2.0 * eta[4] * w, 1.0]);
                cu = w * w;
            }
            ModelStructure::ExtraPole => {
                let p = TAU * eta[3].exp();
                du = poly_mul(&d, &[p, 1.0]);
                df = du.clone();
                cu = p;
                cf = p;
            }
        }
        let om = a2.sqrt();
        let pieces = if phi == 0.0 {
            vec![companion_piece(&du, om, ts)?]
        } else {
            vec![
                companion_piece(&du, om, phi * ts)?,
                companion_piece(&du, om, (1.0 - phi) * ts)?,
            ]
        };
        let fric = companion_piece(&df, om, ts)?;
        Some(Disc {
            pieces,
            fric,
            du,
            om,
            cu,
            cf,
            fixed,
            lead,
            m,
            phi,
            offset: 1 - lead,
        })
    }
}

/// Stage B stops when a stage's cost comes within this fraction of the previous stage's: the
/// friction input and the model have reached their fixed point
/// ([`RefineOptions::sign_iterations`] bounds the number of stages).
const SIGN_CONVERGED: f64 = 1e-6;

/// Stage B also stops after this many stages in a row without a better free run than the
/// best so far: the iteration has turned away from its fixed point (on some drives the
/// friction input and the model push each other off it, and the free-run error only grows
/// from there; docs/identification.md, "The friction input"). The chosen stage is the one with
/// the smallest free-run error among those run.
const STALE_STAGES: usize = 1;
/// Relative cost decrease that ends stage C (the direct free-run fit). A sticking drive gains
/// its large decreases in the first iterations; beyond this the fit creeps along a flat valley,
/// moving the poles by less than half their reported deviation for about 2.5 times the time
/// on a long trace (docs/identification.md, "Stage C").
const FREE_RUN_TOLERANCE: f64 = 1e-4;

/// Most linear columns: $b_2, b_1, b_0, d_c$ and up to five free responses.
const KMAX: usize = 9;

/// Reusable buffers of one evaluation: the residuals and cost (every [`LeastSquares`] problem),
/// and the projected problem's columns and linear parameters.
struct Work {
    /// Columns $[b_2, b_1, b_0, d_c$, free responses$]$, row-major with stride `k`.
    cols: Vec<f64>,
    k: usize,
    resid: Vec<f64>,
    cost: f64,
    lin: [f64; KMAX],
}

impl Work {
    /// Buffers for `n` samples of the problem `prob` with the structure of `lay` (room for
    /// the free responses of a trace that starts moving).
    fn new(n: usize, prob: &OutputErrorProblem, lay: &Layout) -> Work {
        let kmax = if prob.moving {
            4 + lay.structure.order()
        } else {
            4
        };
        Work {
            cols: vec![0.0; kmax * n],
            k: 4,
            resid: vec![0.0; n],
            cost: f64::INFINITY,
            lin: [0.0; KMAX],
        }
    }

    /// Buffers for the `n` residuals alone (a problem without projected columns).
    fn residuals_only(n: usize) -> Work {
        Work {
            cols: vec![],
            k: 0,
            resid: vec![0.0; n],
            cost: f64::INFINITY,
            lin: [0.0; KMAX],
        }
    }

    /// Column values of row `i` times `lin`.
    fn fitted(&self, i: usize, lin: &[f64; KMAX]) -> f64 {
        let c = &self.cols[self.k * i..self.k * (i + 1)];
        c.iter().zip(lin).map(|(a, b)| a * b).sum()
    }
}

type Gram = [[f64; KMAX + 1]; KMAX + 1];

/// Stores the first `dst.len()` values of `row` in `dst` by fixed moves, not a call to
/// `memcpy` per sample: at rest the four columns were most of the 7 % `memmove` share in a
/// profile of a 606 k-sample identification; a moving start's five to eight (on a 570 k-sample
/// one, stage A 3.90 → 3.78 s: most of that trace's `memmove` was [`FreeRows::put`]'s).
#[inline(always)]
fn put_row(dst: &mut [f64], row: &[f64; KMAX + 1]) {
    #[inline(always)]
    fn put<const K: usize>(dst: &mut [f64], row: &[f64; KMAX + 1]) {
        let d: &mut [f64; K] = dst.try_into().expect("a row of K columns");
        *d = std::array::from_fn(|i| row[i]);
    }
    match dst.len() {
        4 => put::<4>(dst, row),
        5 => put::<5>(dst, row),
        6 => put::<6>(dst, row),
        7 => put::<7>(dst, row),
        8 => put::<8>(dst, row),
        _ => dst.copy_from_slice(&row[..dst.len()]),
    }
}

/// The rest of a sample's row once its model columns are in, shared by both passes: the
/// initial state's free-response columns (a trace that starts moving: the first companion state
/// of $\Phi^k e_j$, and without the integral mode the constant offset), the target, $b_2$'s
/// column held at 0 without the integral mode, the skipped samples as zero rows.
struct FreeRows<const NU: usize> {
    /// Free-response columns: `NU` (+1 for the offset), or 0 for a trace that starts at rest.
    nh: usize,
    /// Columns with the free responses (target not counted).
    kk: usize,
    lead: usize,
    skip: usize,
    rho: [f64; NU],
    step_phi: DMatrix<f64>,
}

impl<const NU: usize> FreeRows<NU> {
    /// The rows of `prob` under `d`; sets `w.k`, the row width the pass stores.
    fn new(prob: &OutputErrorProblem, d: &Disc, w: &mut Work) -> FreeRows<NU> {
        let nh = if prob.moving { NU + d.offset } else { 0 };
        w.k = 4 + nh;
        let mut rho = [0.0; NU];
        rho[0] = 1.0;
        FreeRows {
            nh,
            kk: 4 + nh,
            lead: d.lead,
            skip: prob.skip,
            rho,
            step_phi: d.step_phi(),
        }
    }

    /// Completes `row` (model columns 0–3 filled) with the target and stores it as sample `k`.
    #[inline(always)]
    fn put(&self, w: &mut Work, k: usize, mut row: [f64; KMAX + 1], target: f64) {
        let (nh, kk) = (self.nh, self.kk);
        // nh is 0 or NU (+ 1): a copy of fixed length, not a call to memcpy per sample.
        if nh > 0 {
            row[4..4 + NU].copy_from_slice(&self.rho);
        }
        if nh > NU {
            row[4 + NU] = 1.0;
        }
        row[kk] = target;
        if self.lead == 0 {
            // b2 is the held constant.
            row[0] = 0.0;
        }
        if k < self.skip {
            row = [0.0; KMAX + 1];
        }
        put_row(&mut w.cols[kk * k..kk * (k + 1)], &row);
        w.resid[k] = row[kk];
    }

    /// The free responses one sample on (flushed to zero once negligible,
    /// [`crate::metrics::flush_negligible`]).
    #[inline(always)]
    fn step(&mut self) {
        if self.nh > 0 {
            let mut next = [0.0; NU];
            for (jj, v) in next.iter_mut().enumerate() {
                *v = (0..NU).map(|i| self.rho[i] * self.step_phi[(i, jj)]).sum();
            }
            crate::metrics::flush_negligible(&mut next);
            self.rho = next;
        }
    }
}

/// The upper triangle of the Gram matrix of `k` columns (row-major in `cols`) and the target
/// `resid` (last), summed over the samples in order. A separate pass over the stored rows
/// rather than a sum inside the model pass: with the column count fixed per instance the
/// products stay in registers (summed inside the pass, the runtime column count kept them in
/// memory, a third of an evaluation's time on long traces); the sums, and so the results, are
/// the same to the bit. `k` is 4 plus the free responses of a moving start, at most
/// [`KMAX`].
fn gram(cols: &[f64], resid: &[f64], k: usize) -> Gram {
    match k {
        4 => gram_of::<4>(cols, resid),
        5 => gram_of::<5>(cols, resid),
        6 => gram_of::<6>(cols, resid),
        7 => gram_of::<7>(cols, resid),
        8 => gram_of::<8>(cols, resid),
        _ => gram_of::<KMAX>(cols, resid),
    }
}

/// [`gram`] for rows of `K` columns.
fn gram_of<const K: usize>(cols: &[f64], resid: &[f64]) -> Gram {
    debug_assert_eq!(cols.len(), K * resid.len());
    let mut a = [[0.0; K]; K];
    let mut b = [0.0; K];
    let mut c = 0.0;
    for (row, &t) in cols.chunks_exact(K).zip(resid) {
        let r: [f64; K] = std::array::from_fn(|i| row[i]);
        for i in 0..K {
            for j in i..K {
                a[i][j] += r[i] * r[j];
            }
            b[i] += r[i] * t;
        }
        c += t * t;
    }
    let mut g = [[0.0; KMAX + 1]; KMAX + 1];
    for i in 0..K {
        g[i][i..K].copy_from_slice(&a[i][i..K]);
        g[i][K] = b[i];
    }
    g[K][K] = c;
    g
}

/// A [`Piece`] in fixed-size arrays for the inner loops.
struct Fixed<const N: usize> {
    phi: [[f64; N]; N],
    gamma: [f64; N],
    ramp: [f64; N],
}

impl<const N: usize> Fixed<N> {
    fn of(p: &Piece) -> Fixed<N> {
        Fixed {
            phi: std::array::from_fn(|i| std::array::from_fn(|j| p.phi[(i, j)])),
            gamma: std::array::from_fn(|i| p.gamma[i]),
            ramp: std::array::from_fn(|i| p.ramp[i]),
        }
    }
}

#[inline(always)]
fn advance<const N: usize>(p: &Fixed<N>, y: &[f64; N], u0: f64, u1: f64) -> [f64; N] {
    let mut out = [0.0; N];
    for (i, o) in out.iter_mut().enumerate() {
        let mut s = p.gamma[i] * u0 + p.ramp[i] * (u1 - u0);
        for (j, yj) in y.iter().enumerate() {
            s += p.phi[i][j] * yj;
        }
        *o = s;
    }
    out
}

/// Positions-mode pass: tracking through $1/D_u$ (order `NU`) driven by the delayed
/// first-order hold of the reference, friction through $1/D_f$ (order `NF`). Fills the
/// columns and the target $x - c_u a_3 W$ into `w.resid` (without the integral mode
/// $D = s^2 + a_1 s + a_2$, the columns one power of $s$ lower and the target $x - c_u a_2 W$,
/// $b_2$'s column held at 0: [`Disc::lead`]); returns the Gram matrix (target last).
fn pass_positions<const NU: usize, const NF: usize>(
    prob: &OutputErrorProblem,
    d: &Disc,
    w: &mut Work,
) -> Gram {
    let n = prob.n();
    let (u, x, f) = (&prob.u[..n], &prob.x[..n], &prob.f[..n]);
    let om = d.om;
    let sample = |j: isize| -> f64 {
        if j < 0 {
            0.0
        } else {
            u[(j as usize).min(n - 1)]
        }
    };
    let phi = d.phi;
    let between = |j: isize| -> f64 {
        let (a, b) = (sample(j - 1), sample(j));
        a + (1.0 - phi) * (b - a)
    };
    let mut y = [0.0; NU];
    let mut yf = [0.0; NF];
    let pw: [f64; 7] = std::array::from_fn(|k| om.powi(k as i32));
    let mut free = FreeRows::<NU>::new(prob, d, w);
    let p0 = Fixed::<NU>::of(&d.pieces[0]);
    let p1 = d.pieces.get(1).map(Fixed::<NU>::of);
    let pf = Fixed::<NF>::of(&d.fric);
    let (cu, cf, fixed, lead) = (d.cu, d.cf, d.fixed, d.lead);
    for k in 0..n {
        let j = k as isize - d.m as isize;
        let u_now = if phi == 0.0 { sample(j) } else { between(j) };
        // s^k W from the states; s^NU W from the ODE at this instant.
        let mut sw = [0.0; 4];
        for (q, v) in sw.iter_mut().enumerate() {
            *v = if q < NU {
                pw[q] * y[q]
            } else {
                let mut s = u_now;
                for i in 0..NU {
                    s -= d.du[i] * pw[i] * y[i];
                }
                s
            };
        }
        let mut row = [0.0; KMAX + 1];
        for (c, v) in row.iter_mut().enumerate().take(3) {
            *v = cu * sw[c + lead];
        }
        row[3] = -cf * pw[lead] * yf[lead];
        free.put(w, k, row, x[k] - cu * fixed * sw[0]);
        if k + 1 == n {
            break;
        }
        free.step();
        y = match &p1 {
            None => advance(&p0, &y, sample(j), sample(j + 1)),
            Some(p1) => {
                let mid = advance(&p0, &y, between(j), sample(j));
                advance(p1, &mid, sample(j), between(j + 1))
            }
        };
        yf = advance(&pf, &yf, f[k], f[k]);
    }
    gram(&w.cols[..free.kk * n], &w.resid[..n], free.kk)
}

/// Smooth-input pass: $x_r$, $\dot x_r$, $\ddot x_r$ each through $1/D_u$ (order `NU`, the
/// delayed first-order hold of each), friction through $1/D_f$ (order `NF`):
/// $\hat x = c_u (a_3 W_r + b_2 sW_r + b_1 sW_v + b_0 sW_a) - c_f d_c sW_F$. Fills the columns
/// and the target $x - c_u a_3 W_r$ as [`pass_positions`] does.
fn pass_derivatives<const NU: usize, const NF: usize>(
    prob: &OutputErrorProblem,
    d: &Disc,
    w: &mut Work,
) -> Gram {
    let n = prob.n();
    let (u, ud, udd, x, f) = (
        &prob.u[..n],
        &prob.ud[..n],
        &prob.udd[..n],
        &prob.x[..n],
        &prob.f[..n],
    );
    let om = d.om;
    let phi = d.phi;
    // Input sample j as [position, velocity, acceleration]; at rest before the first.
    let sample = |j: isize| -> [f64; 3] {
        if j < 0 {
            [0.0; 3]
        } else {
            let j = (j as usize).min(n - 1);
            [u[j], ud[j], udd[j]]
        }
    };
    let between = |j: isize| -> [f64; 3] {
        let (a, b) = (sample(j - 1), sample(j));
        std::array::from_fn(|i| a[i] + (1.0 - phi) * (b[i] - a[i]))
    };
    let p0 = Fixed::<NU>::of(&d.pieces[0]);
    let p1 = d.pieces.get(1).map(Fixed::<NU>::of);
    let pf = Fixed::<NF>::of(&d.fric);
    let mut y = [[0.0; NU]; 3];
    let mut yf = [0.0; NF];
    let mut free = FreeRows::<NU>::new(prob, d, w);
    let (cu, cf, fixed, lead) = (d.cu, d.cf, d.fixed, d.lead);
    let oml = om.powi(lead as i32);
    for k in 0..n {
        let j = k as isize - d.m as isize;
        let mut row = [0.0; KMAX + 1];
        for (c, v) in row.iter_mut().enumerate().take(3) {
            *v = cu * oml * y[c][lead];
        }
        row[3] = -cf * oml * yf[lead];
        free.put(w, k, row, x[k] - cu * fixed * y[0][0]);
        if k + 1 == n {
            break;
        }
        free.step();
        let (s0, s1) = (sample(j), sample(j + 1));
        for (c, yc) in y.iter_mut().enumerate() {
            *yc = match &p1 {
                None => advance(&p0, yc, s0[c], s1[c]),
                Some(p1) => {
                    let (b0, b1) = (between(j), between(j + 1));
                    let mid = advance(&p0, yc, b0[c], s0[c]);
                    advance(p1, &mid, s0[c], b1[c])
                }
            };
        }
        yf = advance(&pf, &yf, f[k], f[k]);
    }
    gram(&w.cols[..free.kk * n], &w.resid[..n], free.kk)
}

/// Least squares on the column-scaled Gram matrix (target last): $(S G S) z = S g$, Cholesky
/// (nalgebra), with LU as a fallback.
fn solve_gram(g: &Gram, k: usize) -> Option<[f64; KMAX]> {
    let s: [f64; KMAX] = std::array::from_fn(|j| {
        let d = g[j][j];
        if j < k && d > 0.0 && d.is_finite() {
            1.0 / d.sqrt()
        } else {
            0.0
        }
    });
    let a = DMatrix::from_fn(k, k, |i, j| {
        let (lo, hi) = (i.min(j), i.max(j));
        if s[i] == 0.0 || s[j] == 0.0 {
            if i == j { 1.0 } else { 0.0 }
        } else {
            g[lo][hi] * s[i] * s[j]
        }
    });
    let b = DVector::from_fn(k, |i, _| g[i][k] * s[i]);
    let z = a
        .clone()
        .cholesky()
        .map(|c| c.solve(&b))
        .or_else(|| a.lu().solve(&b))?;
    let out: [f64; KMAX] = std::array::from_fn(|j| if j < k { z[j] * s[j] } else { 0.0 });
    out.iter().all(|v| v.is_finite()).then_some(out)
}

impl OutputErrorProblem {
    /// Evaluates the projected residual at `eta` into `w`.
    fn evaluate(&self, lay: &Layout, eta: &[f64], w: &mut Work) {
        w.cost = f64::INFINITY;
        let Some(d) = lay.discretize(eta, self.ts) else {
            return;
        };
        use ReferenceInput::{Hold, Smooth};
        let g = match (self.input, d.du.len() - 1, d.fric.gamma.len()) {
            (Hold, 2, 2) => pass_positions::<2, 2>(self, &d, w),
            (Hold, 3, 3) => pass_positions::<3, 3>(self, &d, w),
            (Hold, 4, 3) => pass_positions::<4, 3>(self, &d, w),
            (Hold, 5, 3) => pass_positions::<5, 3>(self, &d, w),
            (Hold, 4, 4) => pass_positions::<4, 4>(self, &d, w),
            (Smooth, 2, 2) => pass_derivatives::<2, 2>(self, &d, w),
            (Smooth, 3, 3) => pass_derivatives::<3, 3>(self, &d, w),
            (Smooth, 4, 3) => pass_derivatives::<4, 3>(self, &d, w),
            (Smooth, 5, 3) => pass_derivatives::<5, 3>(self, &d, w),
            (Smooth, 4, 4) => pass_derivatives::<4, 4>(self, &d, w),
            _ => return,
        };
        let Some(lin) = solve_gram(&g, w.k) else {
            return;
        };
        let mut cost = 0.0;
        let kk = w.k;
        for (r, c) in w.resid.iter_mut().zip(w.cols.chunks_exact(kk)) {
            *r -= c.iter().zip(&lin).map(|(a, b)| a * b).sum::<f64>();
            cost += *r * *r;
        }
        w.cost = if cost.is_finite() {
            0.5 * cost
        } else {
            f64::INFINITY
        };
        w.lin = lin;
    }
}

/// Result of one Levenberg–Marquardt run on the projected residual.
struct LmRun {
    eta: Vec<f64>,
    lin: [f64; KMAX],
    cost: f64,
    start_cost: f64,
    history: Vec<f64>,
    iterations: usize,
    evaluations: usize,
}

/// A box-bounded nonlinear least-squares problem of [`lm`]: half the sum of the squared
/// residuals of its parameters.
trait LeastSquares: Sync {
    /// Number of residuals.
    fn n(&self) -> usize;
    /// Lower and upper bounds of the parameters.
    fn bounds(&self) -> (&[f64], &[f64]);
    /// Fresh buffers.
    fn work(&self) -> Work;
    /// Forward-difference step of parameter `j` at value `v`.
    fn step(&self, j: usize, v: f64) -> f64;
    /// The residuals and cost at `v` into `w` (an infinite cost when not defined there).
    fn evaluate(&self, v: &[f64], w: &mut Work);
}

/// The projected residual (variable projection) of a structure's nonlinear parameters.
struct Projected<'a> {
    prob: &'a OutputErrorProblem,
    lay: &'a Layout,
}

impl LeastSquares for Projected<'_> {
    fn n(&self) -> usize {
        self.prob.n()
    }
    fn bounds(&self) -> (&[f64], &[f64]) {
        (&self.lay.lo, &self.lay.hi)
    }
    fn work(&self) -> Work {
        Work::new(self.prob.n(), self.prob, self.lay)
    }
    fn step(&self, j: usize, v: f64) -> f64 {
        self.lay.step(j, v, self.prob.ts)
    }
    fn evaluate(&self, v: &[f64], w: &mut Work) {
        self.prob.evaluate(self.lay, v, w)
    }
}

/// A finished [`lm`] run: the parameters, the evaluation there, and the run's record.
struct LmOut {
    v: Vec<f64>,
    work: Work,
    start_cost: f64,
    history: Vec<f64>,
    iterations: usize,
    evaluations: usize,
}

/// Bounded Levenberg–Marquardt on the projected residual from `eta0` (clamped into the box).
fn levenberg_marquardt(
    prob: &OutputErrorProblem,
    lay: &Layout,
    eta0: &[f64],
    opts: &RefineOptions,
) -> Option<LmRun> {
    let o = lm(&Projected { prob, lay }, eta0, opts)?;
    Some(LmRun {
        eta: o.v,
        lin: o.work.lin,
        cost: o.work.cost,
        start_cost: o.start_cost,
        history: o.history,
        iterations: o.iterations,
        evaluations: o.evaluations,
    })
}

/// Bounded Levenberg–Marquardt (module documentation) on `prob` from `v0` (clamped into the
/// box).
fn lm<P: LeastSquares>(prob: &P, v0: &[f64], opts: &RefineOptions) -> Option<LmOut> {
    let (lo, hi) = prob.bounds();
    let mdim = lo.len();
    let clamp = |e: &[f64]| -> Vec<f64> {
        e.iter()
            .enumerate()
            .map(|(j, v)| v.clamp(lo[j], hi[j]))
            .collect()
    };
    let n = prob.n();
    let mut eta = clamp(v0);
    let mut base = prob.work();
    let mut trial = prob.work();
    let mut jac: Vec<Work> = (0..mdim).map(|_| prob.work()).collect();
    prob.evaluate(&eta, &mut base);
    let mut evaluations = 1;
    if !base.cost.is_finite() {
        return None;
    }
    let start_cost = base.cost;
    let mut history = vec![base.cost];
    let mut lambda: f64 = 1e-3;
    let mut iterations = 0;
    'outer: for _ in 0..opts.max_iterations {
        iterations += 1;
        let steps: Vec<f64> = (0..mdim).map(|j| prob.step(j, eta[j])).collect();
        jac.par_iter_mut().enumerate().for_each(|(j, w)| {
            let mut e = eta.clone();
            e[j] += steps[j];
            prob.evaluate(&e, w);
            for (r, b) in w.resid.iter_mut().zip(&base.resid) {
                *r = (*r - b) / steps[j];
            }
        });
        evaluations += mdim;
        if jac.iter().any(|w| !w.cost.is_finite()) {
            break;
        }
        let grad: Vec<f64> = jac.iter().map(|w| dot(&w.resid, &base.resid)).collect();
        let free: Vec<usize> = (0..mdim)
            .filter(|&j| {
                !((eta[j] <= lo[j] && grad[j] > 0.0) || (eta[j] >= hi[j] && grad[j] < 0.0))
            })
            .collect();
        if free.is_empty() {
            break;
        }
        // QR of the tall Jacobian of the free parameters (faer).
        let jm = faer::Mat::<f64>::from_fn(n, free.len(), |i, c| jac[free[c]].resid[i]);
        let qr = jm.qr();
        let r = qr.thin_R().to_owned();
        let k = free.len();
        // Q^T r = R^-T J^T r (J = Q R), without forming Q.
        let jtr: Vec<f64> = free.iter().map(|&j| grad[j]).collect();
        let mut qtr_v = vec![0.0; k];
        for i in 0..k {
            let mut sum = jtr[i];
            for (l, q) in qtr_v.iter().enumerate().take(i) {
                sum -= r[(l, i)] * q;
            }
            if r[(i, i)] == 0.0 {
                break 'outer;
            }
            qtr_v[i] = sum / r[(i, i)];
        }
        // Converged: even the undamped Gauss-Newton step, which lowers the linearised cost by
        // ||Q^T r||^2 / 2, would lower it by less than the tolerance (Moré's relative-reduction
        // test). Without it a converged start rejects steps until the damping gives up.
        let predicted = 0.5 * dot(&qtr_v, &qtr_v);
        if predicted <= opts.tolerance * base.cost {
            break;
        }
        // Marquardt scaling by the column norms of J.
        let dscale: Vec<f64> = (0..k)
            .map(|c| {
                (0..=c)
                    .map(|i| r[(i, c)] * r[(i, c)])
                    .sum::<f64>()
                    .sqrt()
                    .max(1e-300)
            })
            .collect();
        loop {
            // Damped system [R; sqrt(lambda) D] delta = [-Q^T r; 0], by a small QR.
            let aug = DMatrix::from_fn(2 * k, k, |i, c| {
                if i < k {
                    r[(i, c)]
                } else if i - k == c {
                    lambda.sqrt() * dscale[c]
                } else {
                    0.0
                }
            });
            let rhs = DVector::from_fn(2 * k, |i, _| if i < k { -qtr_v[i] } else { 0.0 });
            let small = aug.qr();
            let Some(delta) = small
                .r()
                .solve_upper_triangular(&(small.q().transpose() * rhs))
            else {
                break 'outer;
            };
            let mut cand = eta.clone();
            for (c, &j) in free.iter().enumerate() {
                cand[j] += delta[c];
            }
            let cand = clamp(&cand);
            if cand == eta {
                break 'outer;
            }
            prob.evaluate(&cand, &mut trial);
            evaluations += 1;
            if trial.cost < base.cost {
                let rel = (base.cost - trial.cost) / base.cost;
                std::mem::swap(&mut base, &mut trial);
                eta = cand;
                history.push(base.cost);
                lambda = (lambda / 5.0).max(1e-12);
                if rel < opts.tolerance {
                    break 'outer;
                }
                break;
            }
            lambda *= 4.0;
            if lambda > 1e12 {
                break 'outer;
            }
        }
    }
    Some(LmOut {
        v: eta,
        work: base,
        start_cost,
        history,
        iterations,
        evaluations,
    })
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// A starting point of the refinement: a core (coefficients of $D$) and the structure's extra
/// parameters in search coordinates (dead time in s; log of τ, of the filter frequency in Hz,
/// of the extra pole in Hz; the filter's damping as is).
#[derive(Debug, Clone, PartialEq)]
pub struct Start {
    /// $(a_1, a_2, a_3)$ of the core's denominator.
    pub core: (f64, f64, f64),
    /// Extra parameters in search coordinates.
    pub extra: Vec<f64>,
}

impl Start {
    /// A start of the paper's structure from pole locations.
    pub fn from_poles(p: &Poles) -> Start {
        Start {
            core: p.denominator(),
            extra: vec![],
        }
    }
}

/// What [`refine`] needs besides the trace.
#[derive(Debug, Clone, Copy)]
pub struct RefineSetup<'a> {
    /// Model structure fitted.
    pub structure: ModelStructure,
    /// How the reference drives the model ([`ReferenceInput`]).
    pub input: ReferenceInput,
    /// Pole bounds (the core).
    pub bounds: &'a PoleBounds,
    /// Bounds of the extra parameters.
    pub extended: &'a ExtendedBounds,
    /// Iteration settings.
    pub opts: &'a RefineOptions,
    /// How much of the uncertainty to compute.
    pub uncertainty: UncertaintyLevel,
    /// The friction fixed point (stage B) and its model-own friction input: off for a quick
    /// screening fit (stage A only, the measured friction sign).
    pub friction_stages: bool,
    /// Stage C: the model's own free run fitted directly (module documentation). Off for a
    /// compared fit, which needs the model near its optimum, not at it.
    pub free_run_stage: bool,
}

impl<'a> RefineSetup<'a> {
    /// The full refinement of structure `s` with input `input` under the options `opts`:
    /// every stage, the full uncertainty.
    pub fn full(
        s: ModelStructure,
        input: ReferenceInput,
        opts: &'a crate::IdentifyOptions,
    ) -> RefineSetup<'a> {
        RefineSetup {
            structure: s,
            input,
            bounds: &opts.bounds,
            extended: &opts.extended_bounds,
            opts: &opts.refine,
            uncertainty: UncertaintyLevel::Full,
            friction_stages: true,
            free_run_stage: true,
        }
    }
}

/// How much of a refined model's uncertainty [`refine`] computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UncertaintyLevel {
    /// None (`RefineResult::uncertainty` is `None`).
    None,
    /// The linearised (sandwich) deviations only: enough to see a parameter the data do not
    /// determine.
    Linear,
    /// The linearised deviations, widened by the cost profile of a weakly determined pole and
    /// by the other local minima the starts found (module documentation).
    Full,
}

/// A stage-A result: its cost and its core.
type Alternative = (f64, ClosedLoopModel);

/// Refines a model of `setup.structure` by output error from `starts` (see the module
/// documentation): stage A from every start in parallel, stage B from the best, stage C from
/// the best stage so far; the candidate with the best true free run is returned, with its
/// parameters on bounds and its uncertainty.
pub fn refine(
    trace: &Trace,
    regs: &Regressors,
    starts: &[Start],
    setup: RefineSetup<'_>,
) -> Result<RefineResult, Error> {
    setup.bounds.validate()?;
    setup.extended.validate()?;
    setup.opts.validate()?;
    let s = setup.structure;
    let mut prob = OutputErrorProblem::new(trace, regs, setup.input);
    if prob.moving && s == ModelStructure::Delay {
        prob.skip = ((setup.extended.delay_s[1] / trace.ts).ceil() as usize + 2).min(prob.n() / 10);
    }
    let free_lay = Layout::new(s, setup.input, false, setup.bounds, setup.extended);
    // Stage A from every start.
    let runs: Vec<Option<LmRun>> = starts
        .par_iter()
        .map(|st| {
            let eta = free_lay.eta_of(st.core, &st.extra)?;
            levenberg_marquardt(&prob, &free_lay, &eta, setup.opts)
        })
        .collect();
    let mut stages = Vec::new();
    let (mut iterations, mut evaluations) = (0, 0);
    let mut best: Option<(usize, &LmRun)> = None;
    for (i, r) in runs.iter().enumerate() {
        if let Some(r) = r {
            iterations += r.iterations;
            evaluations += r.evaluations;
            if best.is_none_or(|(_, b)| r.cost < b.cost) {
                best = Some((i, r));
            }
        }
    }
    // The other local minima the starts found (not the best's, the chosen model's own
    // ancestor), for the uncertainty (module documentation).
    let best_index = best.map(|(i, _)| i);
    let alternatives: Vec<Alternative> = runs
        .iter()
        .enumerate()
        .filter(|(i, _)| Some(*i) != best_index)
        .filter_map(|(_, r)| r.as_ref())
        .map(|r| (r.cost, free_lay.model(&r.eta, &r.lin).core))
        .collect();
    // No start usable in coefficient space: bounded pole coordinates from the starts.
    let boxed_runs: Vec<Option<LmRun>>;
    if best.is_none() {
        let boxed = Layout::new(s, setup.input, true, setup.bounds, setup.extended);
        boxed_runs = starts
            .par_iter()
            .map(|st| {
                let eta = boxed.eta_of(st.core, &st.extra)?;
                levenberg_marquardt(&prob, &boxed, &eta, setup.opts)
            })
            .collect();
        for (i, r) in boxed_runs.iter().enumerate() {
            if let Some(r) = r
                && best.is_none_or(|(_, b)| r.cost < b.cost)
            {
                best = Some((i, r));
            }
        }
    }
    let Some((best_i, best_run)) = best else {
        return Err(Error::RefinementFailed { structure: s });
    };
    let mut lay = free_lay.clone();
    let mut run = LmRun {
        eta: best_run.eta.clone(),
        lin: best_run.lin,
        cost: best_run.cost,
        start_cost: best_run.start_cost,
        history: best_run.history.clone(),
        iterations: 0,
        evaluations: 0,
    };
    let stage_a_cost = run.cost;
    // Outside the pole bounds: again in bounded pole coordinates from the nearest point inside.
    let model = lay.model(&run.eta, &run.lin);
    if lay.poles_inside(&model.core, setup.bounds).is_none() {
        let boxed = Layout::new(s, setup.input, true, setup.bounds, setup.extended);
        let (a1, a2, a3) = lay.core(&run.eta);
        let extra = run.eta[lay.nc()..].to_vec();
        // From the nearest point inside, else from the best start.
        let from_run = boxed.eta_of((a1, a2, a3), &extra);
        let from_start = starts
            .get(best_i)
            .and_then(|st| boxed.eta_of(st.core, &st.extra));
        for eta in [from_run, from_start].into_iter().flatten() {
            if let Some(r) = levenberg_marquardt(&prob, &boxed, &eta, setup.opts) {
                iterations += r.iterations;
                evaluations += r.evaluations;
                run = r;
                lay = boxed;
                break;
            }
        }
    }
    let m0 = lay.model(&run.eta, &run.lin);
    // Each stage's own free run: its error chooses, its friction feeds the next stage.
    let own = |prob: &OutputErrorProblem, m: &DriveModel| {
        prob.own_run(m).unwrap_or((f64::INFINITY, vec![]))
    };
    let (fr0, mut f_prev) = own(&prob, &m0);
    stages.push(RefineStage {
        sign: SignSource::Measured(best_i),
        model: m0,
        cost: run.cost,
        freerun_rms: fr0,
    });
    let mut chosen_run = (
        0usize,
        run.eta.clone(),
        run.history.clone(),
        run.cost,
        lay.clone(),
    );
    // The friction input each stage was fitted with.
    let mut stage_signs: Vec<Vec<f64>> = vec![prob.f.clone()];
    let start_cost = run.start_cost;
    // Stage B: the friction of the previous model's own free run.
    let mut eta = run.eta.clone();
    let sign_iterations = if setup.friction_stages {
        setup.opts.sign_iterations
    } else {
        0
    };
    for it in 1..=sign_iterations {
        let n = prob.n();
        if f_prev.len() < n || f_prev[..n] == prob.f[..n] {
            break;
        }
        prob.f[..n].copy_from_slice(&f_prev[..n]);
        let Some(mut r) = levenberg_marquardt(&prob, &lay, &eta, setup.opts) else {
            break;
        };
        iterations += r.iterations;
        evaluations += r.evaluations;
        let mut m = lay.model(&r.eta, &r.lin);
        // A stage that leaves the pole bounds (free coordinates) is fitted again, and the
        // stages go on, in bounded pole coordinates from the nearest point inside (a drive
        // whose pole lies on a bound: its friction stages still count).
        if !lay.boxed_core && lay.poles_inside(&m.core, setup.bounds).is_none() {
            let boxed = Layout::new(s, setup.input, true, setup.bounds, setup.extended);
            let extra = r.eta[lay.nc()..].to_vec();
            let Some(rb) = boxed
                .eta_of(lay.core(&r.eta), &extra)
                .and_then(|e| levenberg_marquardt(&prob, &boxed, &e, setup.opts))
            else {
                break;
            };
            iterations += rb.iterations;
            evaluations += rb.evaluations;
            lay = boxed;
            m = lay.model(&rb.eta, &rb.lin);
            r = rb;
        }
        let (fr, f_next) = own(&prob, &m);
        stages.push(RefineStage {
            sign: SignSource::Model(it),
            model: m,
            cost: r.cost,
            freerun_rms: fr,
        });
        stage_signs.push(prob.f.clone());
        if fr < stages[chosen_run.0].freerun_rms {
            chosen_run = (
                stages.len() - 1,
                r.eta.clone(),
                r.history.clone(),
                r.cost,
                lay.clone(),
            );
        }
        if stages.len() > chosen_run.0 + STALE_STAGES {
            break;
        }
        // Converged: the stage's cost repeats the previous stage's (the friction input and
        // the model have stopped moving each other).
        let last = stages[stages.len() - 2].cost;
        if it > 1 && (last - r.cost).abs() <= SIGN_CONVERGED * r.cost {
            break;
        }
        f_prev = f_next;
        eta = r.eta;
    }
    // Stage C: the chosen stage's model refitted on its own free run, sticking included.
    if setup.friction_stages && setup.free_run_stage && stages[chosen_run.0].model.core.dc != 0.0 {
        let (i, eta_i, _, _, lay_i) = &chosen_run;
        let direct = FreeRunFit::new(&prob, lay_i, &stages[*i].model);
        let v0 = direct.params(eta_i, &stages[*i].model);
        let opts_c = RefineOptions {
            tolerance: setup.opts.tolerance.max(FREE_RUN_TOLERANCE),
            ..*setup.opts
        };
        if let Some(o) = lm(&direct, &v0, &opts_c) {
            iterations += o.iterations;
            evaluations += o.evaluations;
            let (eta_c, m) = direct.split(&o.v);
            let inside = lay_i.boxed_core || lay_i.poles_inside(&m.core, setup.bounds).is_some();
            let fr = (2.0 * o.work.cost / prob.n().max(1) as f64).sqrt();
            if inside && fr < stages[*i].freerun_rms {
                let (_, friction) = own(&prob, &m);
                stages.push(RefineStage {
                    sign: SignSource::FreeRun,
                    model: m,
                    cost: o.work.cost,
                    freerun_rms: fr,
                });
                stage_signs.push(friction);
                chosen_run = (
                    stages.len() - 1,
                    eta_c.to_vec(),
                    o.history,
                    o.work.cost,
                    lay_i.clone(),
                );
            }
        }
    }
    // The chosen stage's coordinates (a later stage may have moved into bounded ones).
    let (chosen, eta, history, cost, lay) = chosen_run;
    let model = stages[chosen].model;
    // The friction input of the chosen stage, for the uncertainty's residual.
    prob.f = std::mem::take(&mut stage_signs[chosen]);
    let on_bounds = bound_hits(&lay, &eta, setup.bounds);
    // Poles as searched (exact on a bound) in pole coordinates; else the split inside the
    // bounds.
    let poles = lay
        .searched_poles(&eta)
        .or_else(|| poles_inside(&model.core, setup.bounds))
        .or_else(|| model.core.poles())
        .unwrap_or(Poles {
            p: 0.0,
            wn: 0.0,
            zeta: 0.0,
        });
    // Other local minima of stage A, their cost relative to stage A's best (same friction
    // input), for the uncertainty.
    let others: Vec<Alternative> = alternatives
        .into_iter()
        .map(|(c, v)| (c - stage_a_cost, v))
        .collect();
    let uncertainty = match setup.uncertainty {
        UncertaintyLevel::None => None,
        level => uncertainty(&prob, &lay, &eta, &setup, level, &others),
    };
    let n = prob.n().max(1) as f64;
    Ok(RefineResult {
        poles,
        model,
        start_cost,
        cost,
        rms: (2.0 * cost / n).sqrt(),
        cost_history: history,
        stages,
        chosen,
        iterations,
        evaluations,
        on_bounds,
        uncertainty,
    })
}

/// The core's poles written as $(p, \omega_n, \zeta)$ inside `b`, if they can be (with three
/// real poles any of them may be $p$; the canonical split of [`ClosedLoopModel::poles`] is
/// preferred).
fn poles_inside(core: &ClosedLoopModel, b: &PoleBounds) -> Option<Poles> {
    let ok = |p: &Poles| {
        let v = [p.p_hz(), p.wn_hz(), p.zeta];
        let (lo, hi) = (b.lower(), b.upper());
        (0..3).all(|j| v[j] >= lo[j] && v[j] <= hi[j])
    };
    splits(core).into_iter().find(ok)
}

/// Every way of writing the core's poles as $(p, \omega_n, \zeta)$: the canonical split of
/// [`ClosedLoopModel::poles`] first, then, with three real poles, each of them as $p$.
fn splits(core: &ClosedLoopModel) -> Vec<Poles> {
    let mut cands: Vec<Poles> = core.poles().into_iter().collect();
    let roots = core.roots();
    if roots.iter().all(|r| r.im == 0.0) {
        for i in 0..3 {
            let o: Vec<f64> = (0..3).filter(|&k| k != i).map(|k| roots[k].re).collect();
            let prod = o[0] * o[1];
            if prod > 0.0 {
                let wn = prod.sqrt();
                cands.push(Poles {
                    p: -roots[i].re,
                    wn,
                    zeta: -(o[0] + o[1]) / (2.0 * wn),
                });
            }
        }
    }
    cands
}

fn bound_hits(lay: &Layout, eta: &[f64], pb: &PoleBounds) -> Vec<BoundHit> {
    let mut out = Vec::new();
    let mut check = |name: &'static str, j: usize, value: f64| {
        let tol = 1e-9 * (lay.hi[j] - lay.lo[j]).abs().max(1e-12);
        if eta[j] <= lay.lo[j] + tol {
            out.push(BoundHit {
                parameter: name,
                value,
                bound: "lower",
            });
        } else if eta[j] >= lay.hi[j] - tol {
            out.push(BoundHit {
                parameter: name,
                value,
                bound: "upper",
            });
        }
    };
    if lay.boxed_core {
        let _ = pb;
        let off = lay.pole_offset();
        for (i, name) in ["p_hz", "wn_hz", "zeta"].into_iter().enumerate().skip(off) {
            check(name, i - off, eta[i - off]);
        }
    }
    let phys = lay.extra_physical(eta);
    for (i, name) in lay.extra_names().into_iter().enumerate() {
        check(name, lay.nc() + i, phys[i]);
    }
    out
}

/// Physical parameters of a refined model: core poles ($p = 0$ without the integral mode),
/// $d_c$, the extra ones.
fn physical(lay: &Layout, eta: &[f64], lin: &[f64]) -> Option<Vec<f64>> {
    let m = lay.model(eta, lin);
    let p = if lay.no_integral() {
        lay.searched_poles(eta)?
    } else {
        m.core.poles()?
    };
    let mut v = vec![p.p_hz(), p.wn_hz(), p.zeta, lin[3]];
    v.extend(lay.extra_physical(eta));
    v.iter().all(|x| x.is_finite()).then_some(v)
}

/// Sandwich covariance with overlapping batch means (module documentation), mapped onto the
/// physical parameters by the delta method.
fn uncertainty(
    prob: &OutputErrorProblem,
    lay: &Layout,
    eta: &[f64],
    setup: &RefineSetup<'_>,
    level: UncertaintyLevel,
    others: &[Alternative],
) -> Option<Uncertainty> {
    let n = prob.n();
    let mdim = lay.m();
    let mut base = Work::new(n, prob, lay);
    prob.evaluate(lay, eta, &mut base);
    if !base.cost.is_finite() || n < 50 {
        return None;
    }
    // Jacobian of the residual in (eta, lin): nonlinear columns by forward differences of the
    // full (unprojected) residual at fixed lin, linear columns -cols.
    let lin = base.lin;
    let kk = base.k;
    let cols = base.cols.clone();
    let resid = base.resid.clone();
    let np = mdim + kk;
    let mut jcols: Vec<Vec<f64>> = (0..mdim)
        .into_par_iter()
        .map(|j| {
            let h = lay.step(j, eta[j], prob.ts);
            let mut e = eta.to_vec();
            e[j] += h;
            let mut w = Work::new(n, prob, lay);
            prob.evaluate(lay, &e, &mut w);
            // Unprojected residual at e with the base's linear parameters: target(e) - cols(e) lin.
            let mut c = vec![0.0; n];
            for (i, ci) in c.iter_mut().enumerate() {
                let full = w.resid[i] + w.fitted(i, &w.lin) - w.fitted(i, &lin);
                *ci = (full - resid[i]) / h;
            }
            c
        })
        .collect();
    for q in 0..kk {
        jcols.push((0..n).map(|i| -cols[kk * i + q]).collect());
    }
    if jcols.iter().any(|c| c.iter().any(|v| !v.is_finite())) {
        return None;
    }
    // A column that vanishes (the friction column when the model applies no friction; the
    // constant term of a drive without integral action, a3 -> 0) leaves its parameter
    // undetermined: it is decoupled (a unit column of its own), and every physical parameter
    // that depends on it is reported with a NaN deviation.
    let norms: Vec<f64> = jcols.iter().map(|c| dot(c, c).sqrt()).collect();
    let top = norms.iter().fold(0.0f64, |a, b| a.max(*b));
    let vanishing: Vec<usize> = (0..np)
        .filter(|&c| norms[c].is_nan() || norms[c] <= 1e-12 * top)
        .collect();
    for &c in &vanishing {
        jcols[c].iter_mut().for_each(|v| *v = 0.0);
        jcols[c][c.min(n - 1)] = 1.0;
    }
    // Column scaling, then QR (faer) of the tall Jacobian.
    let scale: Vec<f64> = jcols
        .iter()
        .map(|c| {
            let s = dot(c, c).sqrt();
            if s > 0.0 { 1.0 / s } else { 1.0 }
        })
        .collect();
    let jm = faer::Mat::<f64>::from_fn(n, np, |i, c| jcols[c][i] * scale[c]);
    let qr = jm.qr();
    let r = qr.thin_R().to_owned();
    let rmat = DMatrix::from_fn(np, np, |i, j| if i <= j { r[(i, j)] } else { 0.0 });
    let rinv = rmat.try_inverse()?;
    let bread = &rinv * rinv.transpose(); // (J^T J)^-1 in scaled coordinates
    // Long-run covariance of the scores s_t = J_t r_t (overlapping batch means).
    let window = andrews_window(&resid);
    let mut meat = DMatrix::<f64>::zeros(np, np);
    let mut run = vec![0.0; np];
    let score = |t: usize, c: usize| jcols[c][t] * scale[c] * resid[t];
    for t in 0..n {
        for (c, v) in run.iter_mut().enumerate() {
            *v += score(t, c);
        }
        if t >= window {
            for (c, v) in run.iter_mut().enumerate() {
                *v -= score(t - window, c);
            }
        }
        if t + 1 >= window {
            for a in 0..np {
                for b in a..np {
                    meat[(a, b)] += run[a] * run[b];
                }
            }
        }
    }
    let batches = (n + 1 - window) as f64;
    for a in 0..np {
        for b in a..np {
            let v = meat[(a, b)] / window as f64 * n as f64 / batches;
            meat[(a, b)] = v;
            meat[(b, a)] = v;
        }
    }
    let cov_scaled = &bread * meat * &bread;
    let cov = DMatrix::from_fn(np, np, |i, j| cov_scaled[(i, j)] * scale[i] * scale[j]);
    // Delta method onto the physical parameters.
    let theta: Vec<f64> = eta
        .iter()
        .copied()
        .chain(lin[..kk].iter().copied())
        .collect();
    let phys = |th: &[f64]| -> Option<Vec<f64>> { physical(lay, &th[..mdim], &th[mdim..]) };
    let p0 = phys(&theta)?;
    let mut g = DMatrix::<f64>::zeros(p0.len(), np);
    for j in 0..np {
        let h = if j < mdim {
            lay.step(j, theta[j], prob.ts)
        } else {
            1e-7 * theta[j].abs().max(1e-9)
        };
        let mut th = theta.clone();
        th[j] += h;
        let pj = phys(&th)?;
        for i in 0..p0.len() {
            g[(i, j)] = (pj[i] - p0[i]) / h;
        }
    }
    let cp = &g * cov * g.transpose();
    // The friction input's sensitivity (module documentation): the first-order change of the
    // parameters, (J^T J)^-1 J^T Δr, when the friction input moves by half a sample either way
    // (Δr = -d_c Δ(friction column)); half the larger change, in quadrature.
    let friction: Vec<f64> = if level == UncertaintyLevel::Full {
        let col = |w: &Work, i: usize| w.cols[w.k * i + 3];
        let dc = lin[3];
        let mut worst = vec![0.0f64; p0.len()];
        for shift in [-1isize, 1] {
            let mut shifted = prob.clone();
            for k in 0..n {
                let j = (k as isize + shift).clamp(0, n as isize - 1) as usize;
                shifted.f[k] = 0.5 * (prob.f[k] + prob.f[j]);
            }
            let mut w = Work::new(n, &shifted, lay);
            shifted.evaluate(lay, eta, &mut w);
            if !w.cost.is_finite() {
                continue;
            }
            // J^T Δr in scaled coordinates, then (J^T J)^-1.
            let jtr = DVector::from_fn(np, |c, _| {
                (0..n)
                    .map(|t| jcols[c][t] * scale[c] * (-dc * (col(&w, t) - cols[kk * t + 3])))
                    .sum::<f64>()
            });
            let dtheta = &bread * jtr;
            let dphys = &g * DVector::from_fn(np, |c, _| dtheta[c] * scale[c]);
            for (i, v) in worst.iter_mut().enumerate() {
                if i != 3 && dphys[i].is_finite() {
                    *v = v.max(0.5 * dphys[i].abs());
                }
            }
        }
        worst
    } else {
        vec![0.0; p0.len()]
    };
    // (J^T J)^-1 on the physical parameters: the curvature that the profile is compared with.
    let bread_u = DMatrix::from_fn(np, np, |i, j| bread[(i, j)] * scale[i] * scale[j]);
    let hinv = &g * bread_u * g.transpose();
    let mut names = vec!["p_hz", "wn_hz", "zeta", "dc"];
    names.extend(lay.extra_names());
    let linear: Vec<f64> = (0..names.len())
        .map(|i| {
            if vanishing.iter().any(|&j| g[(i, j)] != 0.0) {
                f64::NAN
            } else {
                cp[(i, i)].max(0.0).sqrt()
            }
        })
        .collect();
    // Profiles of the weakly determined poles p, ωn, ζ (module documentation); 0 for the
    // others.
    let full = level == UncertaintyLevel::Full;
    let profiled: Vec<f64> = (0..3usize)
        .into_par_iter()
        .map(|i| {
            if full && linear[i].is_finite() && linear[i] > PROFILE_RELATIVE * p0[i].abs() {
                let level = 0.5 * cp[(i, i)] / hinv[(i, i)];
                profile_std(prob, lay, eta, setup, base.cost, &p0, i, linear[i], level)
            } else {
                0.0
            }
        })
        .collect();
    // Other local minima that the data do not tell from this one (module documentation): a
    // stage-A minimum whose cost is within the rise k^2 ΔC_1 of the best widens the pole's
    // interval to reach it.
    let branch: Vec<f64> = (0..p0.len())
        .map(|i| {
            if !full || i >= 3 || hinv[(i, i)].is_nan() || hinv[(i, i)] <= 0.0 {
                return 0.0;
            }
            let delta_c1 = 0.5 * cp[(i, i)] / hinv[(i, i)];
            others
                .iter()
                .filter(|(rise, _)| *rise <= PROFILE_LEVEL * PROFILE_LEVEL * delta_c1)
                .filter_map(|(_, core)| {
                    // The alternative written in the split nearest to the estimate's (with
                    // three real poles the split is a convention, not a second minimum).
                    let d = |q: &Poles| {
                        let v = [q.p_hz(), q.wn_hz(), q.zeta];
                        (0..3)
                            .map(|j| ((v[j] - p0[j]) / p0[j]).abs())
                            .fold(0.0, f64::max)
                    };
                    let q = splits(core)
                        .into_iter()
                        .min_by(|a, b| d(a).total_cmp(&d(b)))?;
                    let v = [q.p_hz(), q.wn_hz(), q.zeta];
                    Some((v[i] - p0[i]).abs() / PROFILE_LEVEL)
                })
                .fold(0.0, f64::max)
        })
        .collect();
    let parameters: Vec<ParameterStd> = names
        .into_iter()
        .enumerate()
        .map(|(i, name)| ParameterStd {
            name,
            value: p0[i],
            std: wider_std(
                wider_std(linear[i], profiled.get(i).copied().unwrap_or(0.0)),
                branch[i],
            )
            .hypot(friction[i]),
            linear_std: linear[i],
            input_std: 0.0,
            friction_std: friction[i],
        })
        .collect();
    let real_pair = real_pair_std(&parameters, &cp);
    // Without the integral mode p is no parameter (held at 0, not estimated).
    let mut parameters = parameters;
    if lay.no_integral() {
        parameters.retain(|p| p.name != "p_hz");
    }
    Some(Uncertainty {
        parameters,
        real_pair,
        window_samples: window,
    })
}

/// The two real poles of the pair when $\zeta \ge 1$, Hz (decay rates over $2\pi$,
/// $\omega_n(\zeta \mp \sqrt{\zeta^2 - 1})$), with their linearised deviations from the
/// covariance `cp` of $(p, \omega_n, \zeta, \ldots)$ and, as for the poles, widened in
/// proportion to the reported deviations of $\omega_n$ and $\zeta$.
fn real_pair_std(parameters: &[ParameterStd], cp: &DMatrix<f64>) -> Option<[ParameterStd; 2]> {
    let (wn, z) = (parameters.get(1)?, parameters.get(2)?);
    if z.value < 1.0 {
        return None;
    }
    let root = |w: f64, z: f64, sign: f64| w * (z + sign * (z * z - 1.0).max(0.0).sqrt());
    let widen = |l: f64, r: f64| if l > 0.0 && r.is_finite() { r / l } else { 1.0 };
    let scale = widen(wn.linear_std, wn.std).max(widen(z.linear_std, z.std));
    let one = |name: &'static str, sign: f64| {
        let v = root(wn.value, z.value, sign);
        let hw = 1e-7 * wn.value;
        let hz = 1e-7 * z.value;
        let gw = (root(wn.value + hw, z.value, sign) - v) / hw;
        let gz = (root(wn.value, z.value + hz, sign) - v) / hz;
        let var = gw * gw * cp[(1, 1)] + 2.0 * gw * gz * cp[(1, 2)] + gz * gz * cp[(2, 2)];
        let linear_std = var.max(0.0).sqrt();
        ParameterStd {
            name,
            value: v,
            std: linear_std * scale,
            linear_std,
            input_std: 0.0,
            friction_std: 0.0,
        }
    };
    Some([one("pair_slow_hz", -1.0), one("pair_fast_hz", 1.0)])
}

/// The reported deviation: the profile's when it is wider than the linearised one. An undefined
/// linearised deviation (NaN: a parameter the data cannot determine) stays undefined rather
/// than becoming the profile's 0 ("not profiled"), which would read as certainty.
fn wider_std(linear: f64, profiled: f64) -> f64 {
    if profiled > linear { profiled } else { linear }
}

/// Relative linearised standard deviation (0.5 %) above which the deviation of $p$, $\omega_n$
/// or $\zeta$ is checked against the profile of the cost (module documentation; below it the
/// pole is determined so well that a correction would change no decision).
pub const PROFILE_RELATIVE: f64 = 0.005;

/// Level of the profile interval: the likelihood-ratio interval of about 95 %, two standard
/// deviations wide on either side.
const PROFILE_LEVEL: f64 = 2.0;

/// Profile evaluations per side at most.
const PROFILE_STEPS: usize = 3;

/// Standard deviation of physical pole `i` (0 = $p$, 1 = $\omega_n$, 2 = $\zeta$) from the
/// profile of the cost (module documentation): with the pole held at $v_i \pm \delta$ and
/// every other parameter re-fitted (bounded pole coordinates), the cost rise $\Delta C(\delta)$
/// is compared with the rise $k^2 \Delta C_1$ that the linearised covariance puts at
/// $k = 2$ standard deviations, $\Delta C_1 = \tfrac12 V_{ii} / (J^TJ)^{-1}_{ii}$; the
/// deviation is the half-width, divided by $k$, where the profile reaches that level (secant
/// steps from $\delta = k\sigma_{lin}$, at most [`PROFILE_STEPS`] per side, each at most 4×
/// the previous). Returns the larger side's, or 0 when the profile cannot be evaluated.
#[allow(clippy::too_many_arguments)]
fn profile_std(
    prob: &OutputErrorProblem,
    lay: &Layout,
    eta: &[f64],
    setup: &RefineSetup<'_>,
    cost0: f64,
    phys: &[f64],
    i: usize,
    linear: f64,
    level: f64,
) -> f64 {
    if !(level > 0.0 && level.is_finite() && cost0.is_finite()) {
        return 0.0;
    }
    let boxed = Layout::new(lay.structure, lay.input, true, setup.bounds, setup.extended);
    // Pole i in the bounded coordinates (without the integral mode there is no p).
    let off = lay.pole_offset();
    let extra = eta[lay.nc()..].to_vec();
    let start: Vec<f64> = phys[off..3].iter().copied().chain(extra).collect();
    let j = i - off;
    let target = PROFILE_LEVEL * PROFILE_LEVEL * level;
    let side = |sign: f64| -> f64 {
        let mut sigma = linear;
        for _ in 0..PROFILE_STEPS {
            let want = phys[i] + sign * PROFILE_LEVEL * sigma;
            let v = want.clamp(boxed.lo[j], boxed.hi[j]);
            let delta = (v - phys[i]).abs();
            if delta <= 0.0 {
                break;
            }
            let mut pinned = boxed.clone();
            pinned.lo[j] = v;
            pinned.hi[j] = v;
            let mut e = start.clone();
            e[j] = v;
            let Some(run) = levenberg_marquardt(prob, &pinned, &e, setup.opts) else {
                break;
            };
            let rise = run.cost - cost0;
            // Where the profile reaches the target, by the secant through the optimum (a
            // quadratic profile gives it in one step); at most 4x further out per step.
            let factor = if rise > 0.0 {
                (target / rise).sqrt().clamp(0.25, 4.0)
            } else {
                4.0
            };
            let next = (delta * factor / PROFILE_LEVEL).max(linear);
            let done = (next / sigma - 1.0).abs() < 0.1 || v != want;
            sigma = next;
            if done {
                break;
            }
        }
        sigma
    };
    side(-1.0).max(side(1.0))
}

/// Bartlett window by Andrews' (1991) AR(1) plug-in rule,
/// $b = 1.1447\,(\alpha N)^{1/3}$, $\alpha = 4\rho^2/((1-\rho)^2(1+\rho)^2)$, with $\rho$ the
/// lag-one autocorrelation of the residual; kept within $[1, N/4]$.
fn andrews_window(r: &[f64]) -> usize {
    let n = r.len();
    let (mut num, mut den) = (0.0, 0.0);
    for t in 1..n {
        num += r[t] * r[t - 1];
        den += r[t - 1] * r[t - 1];
    }
    let rho = if den > 0.0 {
        (num / den).clamp(-0.999_999, 0.999_999)
    } else {
        0.0
    };
    let alpha = 4.0 * rho * rho / ((1.0 - rho).powi(2) * (1.0 + rho).powi(2));
    let b = 1.1447 * (alpha * n as f64).cbrt();
    (b.ceil() as usize).clamp(1, (n / 4).max(1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::options::IdentifyOptions;
    use crate::test_support;
    use vcnc_drive::SimOptions;

    /// Rest-to-rest smooth moves with reversals, 1 ms.
    fn reference(n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        test_support::smooth_moves(n, &test_support::MOVES)
    }

    fn setup<'a>(
        opts: &'a IdentifyOptions,
        s: ModelStructure,
        input: ReferenceInput,
    ) -> RefineSetup<'a> {
        RefineSetup::full(s, input, opts)
    }

    /// `clean` plus a first-order filtered uniform noise (pole 0.95 a sample, about 2 µm),
    /// drawn from `seed`: an unmodelled slow error.
    fn with_coloured_noise(clean: &[f64], seed: u64) -> Vec<f64> {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut e = 0.0;
        clean
            .iter()
            .map(|v| {
                let w: f64 = rng.random::<f64>() - 0.5;
                e = 0.95 * e + 0.002 * w;
                v + e
            })
            .collect()
    }

    fn table1(dc: f64) -> ClosedLoopModel {
        ClosedLoopModel {
            b0: 0.2,
            dc,
            ..vcnc_drive::TABLE1_MODEL
        }
    }

    #[test]
    fn crosses_the_seam_where_the_real_pole_meets_the_pair() {
        // Truth: the model that generated the data with the very simulation the refinement
        // fits. The start has three real poles, the real one equal to one of the pair's
        // ((s + 36.3)^2 (s + 9.1) in Hz): in pole coordinates the path to the truth's complex
        // pair swaps the roles of p and a pair pole, where the map to the coefficients is
        // singular (a gradient method stalled there at zeta = 1). The coefficient map has no
        // such point.
        let truth = table1(47.7);
        let (p, v, a) = reference(3000);
        let x = test_support::follow(&truth, &p, &v, &a);
        let tr = Trace::new(1e-3, p, x)
            .unwrap()
            .with_reference_derivatives(v, a)
            .unwrap();
        let opts = IdentifyOptions::default();
        let regs = Regressors::build(&tr, &opts).unwrap();
        let start = Start::from_poles(&Poles::from_hz(36.3, 18.2, 1.2477));
        let r = refine(
            &tr,
            &regs,
            &[start],
            setup(&opts, ModelStructure::Paper, ReferenceInput::Smooth),
        )
        .unwrap();
        let (tp, rp) = (truth.poles().unwrap(), r.poles);
        let rel = |a: f64, b: f64| ((a - b) / b).abs();
        assert!(
            rel(rp.p, tp.p) < 1e-4 && rel(rp.wn, tp.wn) < 1e-4 && rel(rp.zeta, tp.zeta) < 1e-4,
            "{rp:?} vs {tp:?}"
        );
        let m = r.model.core;
        assert!(
            rel(m.b2, truth.b2) < 1e-4 && rel(m.dc, truth.dc) < 1e-3,
            "{m:?}"
        );
        assert!(r.stages[r.chosen].freerun_rms < 1e-6, "{:?}", r.stages);
        assert!(r.on_bounds.is_empty());
    }

    #[test]
    fn an_optimum_outside_the_bounds_ends_on_them_and_says_so() {
        // Data from a 60 Hz drive searched with wn <= 40 Hz: the result is on that bound and
        // the bound is reported.
        let truth = ClosedLoopModel::from_poles(
            &Poles::from_hz(20.0, 60.0, 0.5),
            0.0,
            150.0,
            120000.0,
            30.0,
        );
        let (p, v, a) = reference(3000);
        let x = test_support::follow(&truth, &p, &v, &a);
        let tr = Trace::new(1e-3, p, x).unwrap();
        let opts = IdentifyOptions {
            bounds: PoleBounds {
                p_hz: [0.2, 500.0],
                wn_hz: [0.2, 40.0],
                zeta: [0.2, 2.0],
            },
            ..Default::default()
        };
        let regs = Regressors::build(&tr, &opts).unwrap();
        let start = Start::from_poles(&Poles::from_hz(10.0, 30.0, 0.7));
        let r = refine(
            &tr,
            &regs,
            &[start],
            setup(&opts, ModelStructure::Paper, ReferenceInput::Smooth),
        )
        .unwrap();
        assert!(r.model.is_stable());
        let b = &opts.bounds;
        assert!(
            r.poles.wn_hz() <= b.wn_hz[1]
                && r.poles.p_hz() >= b.p_hz[0]
                && r.poles.zeta >= b.zeta[0],
            "{:?}",
            r.poles
        );
        assert!(
            r.on_bounds
                .iter()
                .any(|h| h.parameter == "wn_hz" && h.bound == "upper"),
            "{:?}",
            r.on_bounds
        );
    }

    /// The delayed drive of the dead-time tests: the Table 1 core with a 17.3 ms dead time (not
    /// a whole number of samples) driven by positions alone, its noise-free positions over
    /// the reference, and the options that fit the dead-time structure alone.
    fn delayed_truth() -> (ClosedLoopModel, Vec<f64>, Vec<f64>, IdentifyOptions) {
        let core = table1(47.7);
        let m = DriveModel {
            delay_s: 0.0173,
            input: ReferenceInput::Hold,
            ..DriveModel::from(core)
        };
        let (p, _, _) = reference(3000);
        let clean = m
            .simulate_positions(&p, 1e-3, &SimOptions::default())
            .unwrap();
        let opts = IdentifyOptions {
            structures: vec![ModelStructure::Delay],
            ..Default::default()
        };
        (core, p, clean, opts)
    }

    /// The dead-time structure refined on `tr` from the true core and a 10 ms dead time.
    fn refine_delay(tr: &Trace, core: &ClosedLoopModel, opts: &IdentifyOptions) -> RefineResult {
        let regs = Regressors::build(tr, opts).unwrap();
        let start = Start {
            core: core.poles().unwrap().denominator(),
            extra: vec![0.01],
        };
        refine(
            tr,
            &regs,
            &[start],
            setup(opts, ModelStructure::Delay, ReferenceInput::Hold),
        )
        .unwrap()
    }

    #[test]
    fn recovers_a_sub_sample_dead_time_and_its_uncertainty_is_honest() {
        // Truth: a delayed model (17.3 ms, not a whole number of samples) driven by positions
        // alone, with a coloured disturbance added to the measurement (a first-order filtered
        // white noise, 2 µm, correlated over about 20 ms, as an unmodelled slow error would
        // be). Over 24 noise seeds the spread of the estimates is compared with the reported
        // standard deviations: a white-noise formula would understate it many times over.
        let (core, p, clean, opts) = delayed_truth();
        let mut est = vec![];
        let mut std = vec![];
        for seed in 0..24u64 {
            let x = with_coloured_noise(&clean, seed);
            let tr = Trace::new(1e-3, p.clone(), x).unwrap();
            let r = refine_delay(&tr, &core, &opts);
            let u = r.uncertainty.expect("uncertainty");
            est.push([r.model.delay_s, r.poles.wn_hz()]);
            std.push([u.get("delay_s").unwrap().std, u.get("wn_hz").unwrap().std]);
        }
        for i in 0..2 {
            let mean = est.iter().map(|e| e[i]).sum::<f64>() / est.len() as f64;
            let spread = (est.iter().map(|e| (e[i] - mean).powi(2)).sum::<f64>()
                / (est.len() - 1) as f64)
                .sqrt();
            // The median report: in a few runs the joint fit of dead time and poles is
            // nearly collinear and the reported deviation is much larger (conservative).
            let mut r: Vec<f64> = std.iter().map(|s| s[i]).collect();
            r.sort_by(f64::total_cmp);
            let reported = r[r.len() / 2];
            let truth = [0.0173, core.poles().unwrap().wn_hz()][i];
            assert!(
                (mean - truth).abs() < 3.0 * spread.max(1e-12) + 1e-4 * truth,
                "{i}: {mean} vs {truth}"
            );
            // Calibrated within a factor of 3 either way (24 runs estimate a spread to ±15 %;
            // the long-run covariance of a 3000-sample trace is itself uncertain). The
            // white-noise formula sigma^2 (J^T J)^-1 is about 2-3 times smaller here.
            assert!(
                reported > spread / 3.0 && reported < spread * 3.0,
                "parameter {i}: reported {reported:e}, observed spread {spread:e}"
            );
        }
    }

    #[test]
    fn a_dead_time_fitted_on_a_moving_start_runs_free_from_its_estimated_state() {
        // Truth: the 17.3 ms delayed model above with 2 µm of coloured noise, cut to start at
        // full speed in the first move (0.22 s). The fit leaves out the samples within the
        // largest dead time searched (0.2 s) and estimates the state from those after; its
        // own free run was counted from the first sample, where that state can be anything,
        // and stage C bent the coefficients to it.
        let (core, p, clean, opts) = delayed_truth();
        let x = with_coloured_noise(&clean, 3);
        let cut = 220;
        let tr = Trace::new(1e-3, p[cut..].to_vec(), x[cut..].to_vec()).unwrap();
        assert!(!tr.starts_at_rest(crate::trace::REST_SPEED));
        let r = refine_delay(&tr, &core, &opts);
        let fit = crate::metrics::score(&r.model, &tr, None, &opts).unwrap();
        // Measured 1.7 µm (the noise is about 2 µm); twice that allowed. Counted from the first
        // sample: 259 µm, b1 −453 and dc −520 against the truth's 117.5 and 47.7. The
        // parameters are not asserted: on 2.8 s of smooth moves less the 0.2 s left out the
        // dead time trades against the poles and b1 (8.4 ms, ωn −4 %, b1 −100, dc 101 here;
        // issue 30); the rest-start test above checks the estimate and its deviation.
        assert!(
            fit.freerun_rms < 3.5e-3,
            "free run {} mm RMS",
            fit.freerun_rms
        );
    }

    #[test]
    fn an_undetermined_parameter_keeps_an_undefined_deviation() {
        // f64::max would turn NaN and an unprofiled 0 into a deviation of 0, i.e. certainty.
        assert!(wider_std(f64::NAN, 0.0).is_nan());
        assert_eq!(wider_std(1.0, 0.0), 1.0);
        assert_eq!(wider_std(1.0, 3.0), 3.0);
    }

    #[test]
    fn weakly_determined_poles_are_covered_by_their_reported_deviations() {
        // Truth: the model that generated the data (a slow real pole, 8.4 Hz, and a fast pair,
        // 75 Hz, ζ = 0.9, with the numerator of the randomised suite's drive 56: the pair is
        // weakly determined by 4 s of quick moves under a 2 µm disturbance), driven by
        // positions alone, with a coloured disturbance added (first-order filtered white
        // noise, correlated over about 20 ms). Over 24 noise seeds the true p, ωn and ζ must
        // lie within three reported standard deviations of the estimate in at least 22 cases
        // each (a calibrated Gaussian interval misses 0.3 %; 22 of 24 allows for the few
        // seeds whose report is itself low). A complex pair, so that (p, ωn, ζ) name the same
        // poles in truth and estimate (three real poles may be split either way).
        use rand::{RngExt, SeedableRng};
        let truth = ClosedLoopModel::from_poles(
            &Poles::from_hz(8.4, 75.0, 0.9),
            0.099,
            337.7,
            124837.0,
            62.2,
        );
        let tp = truth.poles().unwrap();
        // Short smooth moves (25-100 ms, 0.5-5 mm, either way) with pauses: they excite the
        // pair as a scope recording of quick positioning moves would.
        let n = 4000;
        let mut p = vec![0.0; n];
        let mut moves = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut t0, mut level) = (0.05, 0.0);
        while t0 < 3.8 {
            let dur: f64 = 0.025 + 0.075 * moves.random::<f64>();
            let d: f64 = (0.5 + 4.5 * moves.random::<f64>())
                * if moves.random::<bool>() { 1.0 } else { -1.0 };
            for (k, v) in p.iter_mut().enumerate() {
                let s = ((k as f64 * 1e-3 - t0) / dur).clamp(0.0, 1.0);
                if k as f64 * 1e-3 >= t0 {
                    *v = level + d * (3.0 * s * s - 2.0 * s * s * s);
                }
            }
            level += d;
            t0 += dur + 0.02 + 0.1 * moves.random::<f64>();
        }
        let m = DriveModel {
            input: ReferenceInput::Hold,
            ..DriveModel::from(truth)
        };
        let clean = m
            .simulate_positions(&p, 1e-3, &SimOptions::default())
            .unwrap();
        let opts = IdentifyOptions::default();
        let mut covered = [0usize; 3];
        let mut errors: [Vec<f64>; 3] = Default::default();
        let mut reported: [Vec<f64>; 3] = Default::default();
        for seed in 0..24u64 {
            let x = with_coloured_noise(&clean, 100 + seed);
            let tr = Trace::new(1e-3, p.clone(), x).unwrap();
            let regs = Regressors::build(&tr, &opts).unwrap();
            let start =
                Start::from_poles(&Poles::from_hz(0.8 * tp.p_hz(), 0.8 * tp.wn_hz(), tp.zeta));
            let r = refine(
                &tr,
                &regs,
                &[start],
                setup(&opts, ModelStructure::Paper, ReferenceInput::Hold),
            )
            .unwrap();
            let u = r.uncertainty.expect("uncertainty");
            let truth_v = [tp.p_hz(), tp.wn_hz(), tp.zeta];
            for (i, name) in ["p_hz", "wn_hz", "zeta"].iter().enumerate() {
                let q = u.get(name).unwrap();
                assert!(q.std >= q.linear_std, "{q:?}");
                let err = q.value - truth_v[i];
                if err.abs() <= 3.0 * q.std {
                    covered[i] += 1;
                }
                errors[i].push(err);
                reported[i].push(q.std);
            }
        }
        assert!(
            covered.iter().all(|&c| c >= 22),
            "covered {covered:?} of 24"
        );
        // Not merely wide: the median report of the weak ones (ωn about 5 %, ζ about 20 %
        // here, both profiled) within a factor 3 of the RMS error about the truth.
        for i in 1..3 {
            let rms = (errors[i].iter().map(|e| e * e).sum::<f64>() / 24.0).sqrt();
            let mut r = reported[i].clone();
            r.sort_by(f64::total_cmp);
            let median = r[12];
            assert!(
                median > rms / 3.0 && median < 3.0 * rms,
                "parameter {i}: median report {median:e}, RMS error {rms:e}"
            );
        }
    }
}
