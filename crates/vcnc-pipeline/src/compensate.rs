//! Compensated programs (docs/compensation.md): each axis reference of a prepared program
//! compensated with its identified model (the math, stable inversion and learning on the model,
//! is `vcnc-compensate`'s), the limit margins, the fine-block program, and the judging of a
//! program on the true machine against the original path.

use rayon::prelude::*;
use serde::Serialize;
use vcnc_axis::{AxisName, Unit};
use vcnc_gcode::interpolate::time_exact_rates;
use vcnc_gcode::write::BlockRules;
use vcnc_kinematics::nalgebra::Complex;
use vcnc_machine::{Machine, MachineModels};

pub use vcnc_compensate::{
    CompensateOptions, CompensatedPositions, SampledModel, StableInverse, compensate_positions,
    padded,
};

use crate::Error;
use crate::run::{AxisSignals, Run};
use crate::stats::max_abs;

/// An axis reference and motion against the axis' limits (docs/compensation.md#limits).
///
/// A compensated set-point is not a motion: its acceleration has spikes wherever the desired
/// acceleration jumps (the inverse acts on the jerk there), which the closed loop filters out —
/// the axis performs the desired motion, not the set-point. What is judged is therefore the
/// set-point's **velocity** (what a control checks block by block) and the **acceleration of
/// the motion** the model predicts (what the motor must deliver); the set-point's own
/// acceleration is reported, not judged.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LimitMargin {
    /// The axis.
    pub axis: AxisName,
    /// The axis' velocity limit, units/s.
    pub velocity_limit: f64,
    /// The axis' acceleration limit, units/s².
    pub acceleration_limit: f64,
    /// Largest speed of a fine block of the set-point, $|r_k - r_{k-1}|/T_s$, units/s: what
    /// the interpolator checks block by block (docs/gcode.md). Judged.
    pub reference_velocity: f64,
    /// The set-point's sample (lead included) where that speed is reached (the end of the
    /// block).
    pub reference_velocity_sample: usize,
    /// Largest |acceleration| of the set-point (central differences), units/s². Reported only.
    pub reference_acceleration: f64,
    /// Largest |acceleration| of the motion the model predicts on the set-point (central
    /// differences of its positions), units/s². Judged.
    pub motion_acceleration: f64,
    /// Largest |acceleration| of the desired motion (the program's own references, central
    /// differences), units/s²: where it exceeds the limit (velocity jumps at polyline
    /// junctions), the motion may reach it too.
    pub desired_acceleration: f64,
    /// The acceleration the motion may reach, units/s²: the limit (or the desired motion's own
    /// peak where that is higher) plus $4\delta/T_s^2$, the resolution of a second difference of
    /// positions known to $\delta$ = the model's largest |motion − desired|.
    pub acceleration_allowed: f64,
}

impl LimitMargin {
    /// The margins of a set-point, the model's motion on it and the desired motion (positions
    /// at `ts`).
    pub fn of(
        axis: &vcnc_machine::Axis,
        reference: &[f64],
        motion: &[f64],
        desired: &[f64],
        ts: f64,
    ) -> LimitMargin {
        let (_, ra) = time_exact_rates(reference, ts);
        let (block_speed, at) =
            reference
                .windows(2)
                .enumerate()
                .fold((0.0f64, 0), |(m, at), (k, w)| {
                    let v = (w[1] - w[0]).abs() / ts;
                    if v > m { (v, k + 1) } else { (m, at) }
                });
        let (_, ma) = time_exact_rates(motion, ts);
        let (_, da) = time_exact_rates(desired, ts);
        let delta = motion
            .iter()
            .zip(desired)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let desired_acceleration = max_abs(&da);
        LimitMargin {
            acceleration_allowed: axis.max_acceleration.max(desired_acceleration)
                + 4.0 * delta / (ts * ts),
            axis: axis.name,
            velocity_limit: axis.max_velocity,
            acceleration_limit: axis.max_acceleration,
            reference_velocity: block_speed,
            reference_velocity_sample: at,
            reference_acceleration: max_abs(&ra),
            motion_acceleration: max_abs(&ma),
            desired_acceleration,
        }
    }

    /// Set-point velocity and motion acceleration within what is allowed.
    pub fn within(&self) -> bool {
        self.reference_velocity <= self.velocity_limit * (1.0 + 1e-9)
            && self.motion_acceleration <= self.acceleration_allowed
    }
}

/// The compensation of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisCompensation {
    /// Compensated set-point: positions, and velocity and acceleration by [`time_exact_rates`]
    /// (axis units, /s, /s²), lead and tail included.
    pub reference: AxisSignals,
    /// The model's positions on the set-point, axis units: the physical axis', advanced by the
    /// stated actual-value latency when one was given ([`compensate_run`]).
    pub model: Vec<f64>,
    /// The desired positions (the run's, with the lead and tail at rest), axis units.
    pub desired: Vec<f64>,
    /// Zeros of the sampled model ([`SampledModel::zeros`]).
    pub zeros: Vec<Complex<f64>>,
    /// [`CompensatedPositions::history`], axis units.
    pub history: Vec<f64>,
    /// The set-point and the motion against the axis' limits.
    pub margin: LimitMargin,
}

/// Compensated set-points of every axis of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Compensation {
    /// Sample period, s.
    pub ts: f64,
    /// Samples at rest added before the run's first sample (pre-actuation).
    pub lead: usize,
    /// Samples at rest added after the run's last sample (settling).
    pub tail: usize,
    /// Per machine axis, in machine order.
    pub axes: Vec<AxisCompensation>,
}

impl Compensation {
    /// Number of samples (lead + run + tail).
    pub fn len(&self) -> usize {
        self.axes.first().map_or(0, |a| a.reference.pos.len())
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Duration from the first to the last sample, s.
    pub fn duration_s(&self) -> f64 {
        self.len().saturating_sub(1) as f64 * self.ts
    }

    /// The margins of every axis, in machine order.
    pub fn margins(&self) -> Vec<LimitMargin> {
        self.axes.iter().map(|a| a.margin).collect()
    }

    /// Refuses ([`Error::Limit`]) a compensation of `run` (planned with the velocity
    /// `headroom`, 1 for none) whose set-point velocity or predicted motion acceleration exceeds
    /// an axis limit (the worst excess first), saying where and by how much the program's feed,
    /// or the headroom, would have to drop.
    pub fn check_limits(&self, run: &Run, headroom: f64) -> Result<(), Error> {
        let mut worst: Option<(f64, Error)> = None;
        for a in &self.axes {
            let m = &a.margin;
            let u = a.reference.unit;
            let vr = m.reference_velocity / m.velocity_limit;
            if vr > 1.0 + 1e-9 && worst.as_ref().is_none_or(|w| vr > w.0) {
                worst = Some((
                    vr,
                    Error::Limit {
                        axis: m.axis,
                        what: "compensated set-point's velocity",
                        value: m.reference_velocity,
                        limit: m.velocity_limit,
                        unit: format!("{u}/s"),
                        advice: format!(
                            "{}; lower the program's feeds there to at most {:.1} %, or, where it runs at the axis limits (rapids), plan it with a velocity headroom of at most {:.3} (a set-point leads the motion: a move at the velocity limit cannot be compensated)",
                            self.place(run, m.reference_velocity_sample),
                            100.0 / vr,
                            headroom / vr
                        ),
                    },
                ));
            }
            let ar = m.motion_acceleration / m.acceleration_allowed;
            if ar > 1.0 && worst.as_ref().is_none_or(|w| ar > w.0) {
                worst = Some((
                    ar,
                    Error::Limit {
                        axis: m.axis,
                        what: "acceleration of the motion the model predicts",
                        value: m.motion_acceleration,
                        limit: m.acceleration_limit,
                        unit: format!("{u}/s²"),
                        advice: format!(
                            "lower the machine's acceleration limits for this program to at most {:.1} % (accelerations scale with them)",
                            100.0 / ar
                        ),
                    },
                ));
            }
        }
        match worst {
            Some((_, e)) => Err(e),
            None => Ok(()),
        }
    }

    /// "at t = … s, line … (a rapid)" for set-point sample `k` (lead included) of `run`'s
    /// compensation.
    fn place(&self, run: &Run, k: usize) -> String {
        let t = (k as f64 - self.lead as f64) * self.ts;
        let j = k.saturating_sub(self.lead).min(run.len().saturating_sub(1));
        match run.loaded.trajectory.block_at(j) {
            Some(b) => format!(
                "at t = {t:.3} s, {}:{} (a {} move)",
                run.file,
                b.line,
                match b.class {
                    vcnc_gcode::MoveClass::Rapid => "rapid",
                    vcnc_gcode::MoveClass::Feed => "feed",
                    vcnc_gcode::MoveClass::Dwell => "dwell",
                }
            ),
            None => format!("at t = {t:.3} s"),
        }
    }

    /// The compensated set-points as a G-code program the control runs
    /// ([`vcnc_gcode::write::fine_blocks`], written by `rules`); `header` lines become
    /// comments.
    pub fn program(
        &self,
        header: &[String],
        rules: &vcnc_gcode::write::BlockRules,
    ) -> vcnc_gcode::write::FineProgram {
        let axes: Vec<(AxisName, &[f64])> = self
            .axes
            .iter()
            .map(|a| (a.reference.name, a.reference.pos.as_slice()))
            .collect();
        vcnc_gcode::write::fine_blocks(&axes, self.ts, header, rules)
    }
}

/// `machine` with every axis velocity limit and the tool-tip path velocity limit times
/// `headroom` (in (0, 1]): a program prepared on it leaves the set-points room to lead the
/// motion where the original runs at a limit (rapids, feeds above the limits). Accelerations are
/// kept: the motion the compensation produces is the desired one.
pub fn with_velocity_headroom(machine: &Machine, headroom: f64) -> Result<Machine, Error> {
    if !(headroom > 0.0 && headroom <= 1.0) {
        return Err(Error::Headroom { headroom });
    }
    let mut m = machine.clone();
    for a in &mut m.axes {
        a.max_velocity *= headroom;
    }
    m.tcp_max_vel *= headroom;
    Ok(m)
}

/// `models` with the machine's nominal-position filters (`[control]`) folded in: the control's
/// delay added to each model's dead time, and its one first- or second-order filter as the
/// model's reference filter — the same physics in the models instead of in front of them
/// (docs/machine-file.md#control). A compensation inverts the models, so it needs them so; a
/// chain with a moving average, a band-stop or an FIR filter (which the models' reference
/// filters cannot hold), or several filters, or a model with a filter of its own, is refused
/// ([`Error::ControlFilters`]).
pub fn with_control_filters(
    machine: &Machine,
    models: &MachineModels,
) -> Result<MachineModels, Error> {
    let Some(c) = &machine.control else {
        return Ok(models.clone());
    };
    let refuse = |what: String| Error::ControlFilters {
        machine: machine.source.clone(),
        what,
    };
    if c.fir().is_some() {
        return Err(refuse("an FIR filter".to_string()));
    }
    let filter = match c.filters() {
        [] => None,
        [vcnc_drive::ShapingFilter::FirstOrder { time_constant_s }] => {
            Some(vcnc_drive::ReferenceFilter::FirstOrder {
                tau_s: *time_constant_s,
            })
        }
        [
            vcnc_drive::ShapingFilter::SecondOrder {
                time_constant_s,
                zeta,
            },
        ] => Some(vcnc_drive::ReferenceFilter::SecondOrder {
            wn_hz: 1.0 / (std::f64::consts::TAU * time_constant_s),
            zeta: *zeta,
        }),
        [f] => return Err(refuse(format!("a {f:?} filter"))),
        many => return Err(refuse(format!("a chain of {} filters", many.len()))),
    };
    let mut folded = Vec::with_capacity(models.models().len());
    for (i, m) in models.models().iter().enumerate() {
        if filter.is_some() && m.reference_filter.is_some() {
            return Err(refuse(format!(
                "the model of axis {} has a reference filter of its own",
                machine.axes[i].name
            )));
        }
        folded.push(vcnc_drive::DriveModel {
            delay_s: m.delay_s + c.delay_s(),
            reference_filter: m.reference_filter.or(filter),
            ..*m
        });
    }
    Ok(MachineModels::new(
        machine,
        folded,
        format!("{} with the control's filters", models.source()),
    )?)
}

/// Replanning rounds [`compensate_within_limits`] may take when no headroom is given.
pub const MAX_REPLANS: usize = 3;

/// The smallest velocity headroom [`compensate_within_limits`] replans with by itself. A
/// set-point that needs more than ten times an axis' velocity limit is rarely a program's
/// rapids: it is a model that does not describe the drive (a near-cancelled zero, a dead time
/// the inverse cannot lead), and replanning would only hide it. An explicit headroom is
/// still honoured.
pub const MIN_AUTO_HEADROOM: f64 = 0.1;

/// A compensation within the axes' limits and the velocity headroom it was planned with.
#[derive(Debug, Clone)]
pub struct Planned {
    /// The compensation.
    pub compensation: Compensation,
    /// The velocity headroom the program was planned with (1: none).
    pub headroom: f64,
    /// The headrooms planned again with, in order, when none was given (empty: none needed).
    pub replanned: Vec<f64>,
}

/// Compensates `original` (the program at `program` prepared on `machine`) with `models` and
/// refuses ([`Error::Limit`]) a set-point beyond an axis limit. With `headroom` the program is
/// planned with it; without, it is planned as it is, and a set-point that must lead a move at a
/// velocity limit (a rapid, usually) makes the headroom just small enough, up to
/// [`MAX_REPLANS`] times. The path followed is the original's either way.
pub fn compensate_within_limits(
    machine: &Machine,
    program: &std::path::Path,
    original: &Run,
    models: &MachineModels,
    opts: &CompensateOptions,
    headroom: Option<f64>,
    lenient: bool,
) -> Result<Planned, Error> {
    let models = &with_control_filters(machine, models)?;
    let mut h = headroom.unwrap_or(1.0);
    let mut replanned = Vec::new();
    loop {
        let slower;
        let planned = if h < 1.0 {
            slower =
                crate::run::prepare_file(&with_velocity_headroom(machine, h)?, program, lenient)?;
            &slower
        } else {
            original
        };
        let compensation = compensate_run(machine, planned, models, opts)?;
        let Err(mut e) = compensation.check_limits(planned, h) else {
            return Ok(Planned {
                compensation,
                headroom: h,
                replanned,
            });
        };
        // The set-points' largest velocity over its limit (an excess of acceleration is not
        // helped by a headroom).
        let ratio = compensation
            .margins()
            .iter()
            .map(|m| m.reference_velocity / m.velocity_limit)
            .fold(0.0f64, f64::max);
        if headroom.is_some() || replanned.len() == MAX_REPLANS || ratio <= 1.0 {
            return Err(e);
        }
        let next = (h / ratio * 0.99).min(1.0);
        if next < MIN_AUTO_HEADROOM {
            if let Error::Limit { advice, .. } = &mut e {
                advice.push_str(&format!(
                    ". vcnc does not replan below a headroom of {MIN_AUTO_HEADROOM} by itself: a set-point {ratio:.1} times the velocity limit usually means a model that does not describe this drive; check it with `vcnc validate`, or give --headroom to plan with it anyway"
                ));
            }
            return Err(e);
        }
        h = next;
        replanned.push(h);
    }
}

/// Every axis reference of `run` compensated with its model (one per machine axis, in order):
/// lead and tail at rest, exact inverse, learning loop, limit margins. Axes run in parallel;
/// results come in machine order. The limits are not enforced here
/// ([`Compensation::check_limits`]).
///
/// **Actual-value latency.** A model predicts the logged actual position, which trails the
/// physical axis by the axis' stated latency $\tau$ (the model's `actual_latency_s`;
/// [`crate::latency`]). For the physical axis to follow the desired positions
/// $y_d(t)$ the model must follow $y_d(t - \tau)$: that is what is inverted, and the tail is
/// longer by $\lceil\tau/T_s\rceil$ samples so that it still ends at rest. The axes' `model`
/// positions are then the physical ones (the model's advanced by $\tau$).
pub fn compensate_run(
    machine: &Machine,
    run: &Run,
    models: &MachineModels,
    opts: &CompensateOptions,
) -> Result<Compensation, Error> {
    let latency = |i: usize| models.get(i).actual_latency_s;
    let models = models.models();
    if run.is_empty() {
        return Err(Error::EmptyProgram {
            file: run.file.clone(),
        });
    }
    let ts = run.ts;
    let inverses = models
        .iter()
        .zip(&run.axes)
        .map(|(m, s)| {
            let h = SampledModel::of_drive(m, ts).map_err(|e| axis_error(s.name, e))?;
            let inv = StableInverse::of(&h).map_err(|e| axis_error(s.name, e))?;
            Ok((h, inv))
        })
        .collect::<Result<Vec<_>, Error>>()?;
    let max_pad = (opts.max_lead_s / ts).ceil() as usize;
    let (mut lead, mut tail) = (0usize, 0usize);
    for ((_, inv), s) in inverses.iter().zip(&run.axes) {
        let (l, t) = inv.lead_tail(opts.decay);
        if l > max_pad || t > max_pad {
            return Err(Error::SlowInverse {
                axis: s.name,
                lead_s: l as f64 * ts,
                tail_s: t as f64 * ts,
                max_s: opts.max_lead_s,
            });
        }
        lead = lead.max(l);
        tail = tail.max(t);
    }
    let max_latency = (0..run.axes.len()).map(latency).fold(0.0f64, f64::max);
    tail += (max_latency / ts).ceil() as usize;
    let axes = inverses
        .par_iter()
        .zip(models.par_iter())
        .zip(run.axes.par_iter().zip(machine.axes.par_iter()))
        .enumerate()
        .map(|(i, (((h, inv), m), (s, axis)))| {
            let desired = padded(&s.pos, lead, tail);
            let tau = latency(i);
            let c = if tau == 0.0 {
                compensate_positions(m, inv, &desired, ts, opts)
            } else {
                let target = crate::latency::shifted(&desired, -tau, ts);
                compensate_positions(m, inv, &target, ts, opts).map(|c| CompensatedPositions {
                    model: crate::latency::shifted(&c.model, tau, ts),
                    ..c
                })
            }
            .map_err(|e| axis_error(s.name, e))?;
            let (vel, acc) = time_exact_rates(&c.reference, ts);
            Ok(AxisCompensation {
                margin: LimitMargin::of(axis, &c.reference, &c.model, &desired, ts),
                reference: AxisSignals {
                    name: s.name,
                    unit: s.unit,
                    pos: c.reference,
                    vel,
                    acc,
                },
                model: c.model,
                desired,
                zeros: h.zeros(),
                history: c.history,
            })
        })
        .collect::<Result<Vec<_>, Error>>()?;
    Ok(Compensation {
        ts,
        lead,
        tail,
        axes,
    })
}

fn axis_error(axis: AxisName, source: vcnc_compensate::Error) -> Error {
    Error::Compensate { axis, source }
}

/// How closely a program's run reproduces the set-points it was written from: the largest
/// |Δ| per axis of positions, velocities and accelerations (axis units, /s, /s²), the
/// program's last sample (its final rest) excluded from the rates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Reproduction {
    /// The axis.
    pub axis: AxisName,
    /// Largest |Δ position|, axis units.
    pub position: f64,
    /// Largest |Δ velocity|, units/s.
    pub velocity: f64,
    /// Largest |Δ acceleration|, units/s².
    pub acceleration: f64,
}

/// [`Reproduction`] of every axis of `comp` by `run` (the program re-read and interpolated);
/// an error when the sample counts differ.
pub fn reproduction(comp: &Compensation, run: &Run) -> Result<Vec<Reproduction>, Error> {
    if run.len() != comp.len() {
        return Err(Error::SampleCount {
            program: run.len(),
            set_points: comp.len(),
        });
    }
    let n = comp.len();
    let diff = |a: &[f64], b: &[f64], m: usize| {
        a[..m]
            .iter()
            .zip(&b[..m])
            .fold(0.0f64, |w, (x, y)| w.max((x - y).abs()))
    };
    Ok(comp
        .axes
        .iter()
        .zip(&run.axes)
        .map(|(c, r)| Reproduction {
            axis: c.reference.name,
            position: diff(&c.reference.pos, &r.pos, n),
            velocity: diff(&c.reference.vel, &r.vel, n - 1),
            acceleration: diff(&c.reference.acc, &r.acc, n - 1),
        })
        .collect())
}

/// Tool-tip and orientation contour statistics (µm, mrad) of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ContourStats {
    /// Largest tool-tip contour error, µm.
    pub contour_max_um: f64,
    /// RMS tool-tip contour error, µm.
    pub contour_rms_um: f64,
    /// Largest orientation contour error, mrad.
    pub orientation_max_mrad: f64,
    /// RMS orientation contour error, mrad.
    pub orientation_rms_mrad: f64,
}

/// Per sample of a contour report measured against `reference`'s path: whether its foot point
/// lies on a feed move of `reference`. Contour statistics cover what is cut (docs/contour.md);
/// a program without feed moves counts every sample.
pub fn feed_samples(reference: &Run, r: &vcnc_contour::ContourReport) -> Vec<bool> {
    let feed = reference.measured(crate::run::Measured::Feed);
    if !feed.iter().any(|f| *f) {
        return vec![true; r.foot.len()];
    }
    r.foot
        .iter()
        .map(|f| {
            let k = f.u.round().max(0.0) as usize;
            feed.get(k.min(feed.len() - 1)).copied().unwrap_or(false)
        })
        .collect()
}

impl ContourStats {
    /// Over the samples of `r` that `mask` selects.
    pub fn over(r: &vcnc_contour::ContourReport, mask: &[bool]) -> ContourStats {
        let pick = |v: &[f64]| -> Vec<f64> {
            v.iter()
                .zip(mask)
                .filter_map(|(x, m)| m.then_some(*x))
                .collect()
        };
        let (tip, or) = (pick(&r.tip_mm), pick(&r.orientation_rad));
        ContourStats {
            contour_max_um: max_abs(&tip) * 1e3,
            contour_rms_um: crate::stats::rms(&tip) * 1e3,
            orientation_max_mrad: max_abs(&or) * 1e3,
            orientation_rms_mrad: crate::stats::rms(&or) * 1e3,
        }
    }

    /// Over the samples of `r` whose foot lies on a feed move of `reference`
    /// ([`feed_samples`]).
    pub fn over_feed(reference: &Run, r: &vcnc_contour::ContourReport) -> ContourStats {
        ContourStats::over(r, &feed_samples(reference, r))
    }

    /// Of a contour report, every sample.
    pub fn of(r: &vcnc_contour::ContourReport) -> ContourStats {
        ContourStats {
            contour_max_um: r.tip_max_mm * 1e3,
            contour_rms_um: r.tip_rms_mm * 1e3,
            orientation_max_mrad: r.orientation_max_rad * 1e3,
            orientation_rms_mrad: r.orientation_rms_rad * 1e3,
        }
    }
}

/// A program run on the true machine and judged against another run's reference path.
#[derive(Debug, Clone)]
pub struct Judged {
    /// The true drives' traces on the program.
    pub traces: Vec<vcnc_drive::DriveTrace>,
    /// Contour and orientation errors of the true tool poses against the reference run's path;
    /// `None` on a machine without kinematics.
    pub contour: Option<vcnc_contour::ContourReport>,
    /// The program's duration, s.
    pub cycle_time_s: f64,
}

impl Judged {
    /// The contour errors, or the error a machine without kinematics gives.
    pub fn contour(&self, machine: &Machine) -> Result<&vcnc_contour::ContourReport, Error> {
        self.contour.as_ref().ok_or_else(|| {
            vcnc_machine::Error::NoKinematics {
                file: machine.source.clone(),
            }
            .into()
        })
    }
}

/// Runs `run` through the true drives and, on a machine with kinematics, measures its contour
/// errors against the tool path and tool axis of `reference` (the ORIGINAL program's poses,
/// whatever program `run` is).
pub fn on_true_machine(machine: &Machine, reference: &Run, run: &Run) -> Result<Judged, Error> {
    let traces = crate::simulate::true_traces(machine, run)?;
    let contour = match machine.kinematics {
        Some(_) => {
            let pos: Vec<&[f64]> = traces.iter().map(|t| t.true_position.as_slice()).collect();
            Some(contour_against(machine, reference, &pos)?)
        }
        None => None,
    };
    Ok(Judged {
        traces,
        contour,
        cycle_time_s: run.duration_s(),
    })
}

/// Where each sample of a contour report lies along the reference run's tool-tip path: the arc
/// length of its foot point from the path's start, mm (for plotting runs of different
/// durations over the same path).
/// Empty on a machine without kinematics.
pub fn path_position_mm(
    machine: &Machine,
    reference: &Run,
    report: &vcnc_contour::ContourReport,
) -> Vec<f64> {
    let poses = reference.reference_poses(machine).unwrap_or_default();
    let mut s = Vec::with_capacity(poses.len());
    let mut acc = 0.0;
    for (i, p) in poses.iter().enumerate() {
        if i > 0 {
            acc += (p.p - poses[i - 1].p).norm();
        }
        s.push(acc);
    }
    report
        .foot
        .iter()
        .map(|f| {
            if s.is_empty() {
                return 0.0;
            }
            let j = (f.u.floor().max(0.0) as usize).min(s.len() - 1);
            let frac = f.u - j as f64;
            let next = s.get(j + 1).copied().unwrap_or(s[j]);
            s[j] + frac * (next - s[j])
        })
        .collect()
}

/// The models' contour errors on `run` against the tool path of `reference` (the prediction a
/// plan is made with): the physical axes, each model's positions advanced by its stated
/// actual-value latency ([`crate::latency`]).
pub fn with_models(
    machine: &Machine,
    reference: &Run,
    run: &Run,
    models: &MachineModels,
) -> Result<vcnc_contour::ContourReport, Error> {
    let positions = crate::simulate::model_positions(machine, models, run, true)?;
    let pos: Vec<&[f64]> = positions.iter().map(Vec::as_slice).collect();
    contour_against(machine, reference, &pos)
}

/// Contour errors, with foot points, of actual axis positions (per machine axis, mm / deg)
/// against the tool path of `reference` (whatever program the positions come from): the
/// actual poses by the forward kinematics, searched along the reference path
/// ([`vcnc_contour::contour_errors`]).
pub fn contour_against(
    machine: &Machine,
    reference: &Run,
    actual: &[&[f64]],
) -> Result<vcnc_contour::ContourReport, Error> {
    let reference = reference.reference_poses(machine)?;
    let poses = crate::run::forward_poses(machine, actual)?;
    Ok(vcnc_contour::contour_errors(&reference, &poses)?)
}

/// One program's true drives on one axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AxisRunFigures {
    /// Largest |true position − desired position|, µm or mdeg (the desired positions are the
    /// original program's references).
    pub tracking_max: f64,
    /// Largest |acceleration| of the true motion (central differences of the true positions),
    /// units/s².
    pub motion_acceleration: f64,
    /// Largest |motor torque|, N·m; `None` for an axis known only by its identified model
    /// (no motor).
    pub torque_peak_nm: Option<f64>,
}

impl AxisRunFigures {
    /// Of a true drive's trace against desired positions (same sample times).
    pub fn of(trace: &vcnc_drive::DriveTrace, desired: &[f64], unit: Unit) -> AxisRunFigures {
        let (_, acc) = time_exact_rates(&trace.true_position, trace.ts);
        AxisRunFigures {
            tracking_max: desired
                .iter()
                .zip(&trace.true_position)
                .fold(0.0f64, |m, (d, x)| m.max((d - x).abs()))
                * unit.micro_factor(),
            motion_acceleration: max_abs(&acc),
            torque_peak_nm: (!trace.motor_torque.is_empty()).then(|| max_abs(&trace.motor_torque)),
        }
    }
}

/// One axis of [`CompensateSummary`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisCompensateSummary {
    /// `mm` or `deg`.
    pub unit: Unit,
    /// The limits judged and reported ([`LimitMargin`]).
    pub margin: LimitMargin,
    /// Both judged quantities within their limits.
    pub within_limits: bool,
    /// Model simulations of the learning loop.
    pub iterations: usize,
    /// |desired − model| after the exact linear inverse alone, µm or mdeg.
    pub model_error_linear_inverse: f64,
    /// |desired − model| of the set-point written, µm or mdeg.
    pub model_error: f64,
    /// The program re-read and interpolated against the set-points.
    pub reproduction: Reproduction,
    /// The original program on the true drive.
    pub before: AxisRunFigures,
    /// The compensated program on the true drive.
    pub after: AxisRunFigures,
}

/// Before and after figures of one program on the true machine.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RunFigures {
    /// Contour statistics against the original program's path (absent on a machine without
    /// kinematics).
    #[serde(flatten)]
    pub contour: Option<ContourStats>,
    /// The program's duration, s.
    pub cycle_time_s: f64,
}

/// The compensated program as written ([`vcnc_gcode::write::fine_blocks`]) and the rules it
/// was written by (the machine file's `[program_output]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WrittenProgram {
    /// `G1` blocks.
    pub blocks: usize,
    /// `G4` dwells.
    pub dwells: usize,
    /// The shortest `G1` block, s.
    pub shortest_block_s: f64,
    /// The shortest block the rules allow (the block cycle rounded up to sample periods), s.
    pub block_cycle_s: f64,
    /// Word resolution of linear axes, mm (0: full precision).
    pub resolution_mm: f64,
    /// Word resolution of rotary axes, deg (0: full precision).
    pub rotary_resolution_deg: f64,
    /// Chord tolerance of merged blocks, linear axes, mm.
    pub chord_tolerance_mm: f64,
    /// Chord tolerance of merged blocks, rotary axes, deg.
    pub rotary_chord_tolerance_deg: f64,
}

impl WrittenProgram {
    fn new(p: &vcnc_gcode::write::FineProgram, rules: &BlockRules, ts: f64) -> WrittenProgram {
        WrittenProgram {
            blocks: p.blocks,
            dwells: p.dwells,
            shortest_block_s: p.shortest_block as f64 * ts,
            block_cycle_s: rules.min_samples as f64 * ts,
            resolution_mm: rules.resolution,
            rotary_resolution_deg: rules.rotary_resolution,
            chord_tolerance_mm: rules.tolerance,
            rotary_chord_tolerance_deg: rules.rotary_tolerance,
        }
    }
}

/// `summary.json` of `vcnc compensate`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompensateSummary {
    /// Machine name.
    pub machine: String,
    /// The original program.
    pub program: String,
    /// The model file.
    pub models: String,
    /// The compensated program written.
    pub compensated_program: String,
    /// What it is made of.
    pub written: WrittenProgram,
    /// Sample period, s.
    pub ts_s: f64,
    /// Pre-actuation before the original's first sample, s.
    pub lead_s: f64,
    /// Settling after the original's last sample, s.
    pub tail_s: f64,
    /// Options of the compensation.
    pub options: CompensateOptions,
    /// The velocity headroom the program was planned with ([`with_velocity_headroom`]; 1:
    /// none).
    pub velocity_headroom: f64,
    /// The original program on the true machine.
    pub before: RunFigures,
    /// The compensated program on the true machine.
    pub after: RunFigures,
    /// The models on the compensated program (what the compensation aims at; absent without
    /// kinematics).
    pub after_models: Option<ContourStats>,
    /// Per axis.
    pub axes: std::collections::BTreeMap<String, AxisCompensateSummary>,
    /// Every axis within its judged limits.
    pub within_limits: bool,
}

/// A program compensated, written, read back and judged (`vcnc compensate`).
#[derive(Debug, Clone)]
pub struct CompensatedProgram {
    /// The original program prepared.
    pub original: Run,
    /// The compensation and the velocity headroom it was planned with.
    pub planned: Planned,
    /// The compensated program's text (the fine-block program).
    pub text: String,
    /// The compensated program as the control runs it: read back and interpolated.
    pub rerun: Run,
    /// How the read-back program reproduces the set-points, per axis.
    pub reproduction: Vec<Reproduction>,
    /// The original program on the true machine.
    pub before: Judged,
    /// The compensated program on the true machine.
    pub after: Judged,
    /// The models on the compensated program (absent without kinematics).
    pub after_models: Option<vcnc_contour::ContourReport>,
    /// `summary.json`.
    pub summary: CompensateSummary,
}

/// Compensates the program at `program` on `machine` with `models`
/// ([`compensate_within_limits`]), writes the fine-block program (its name in messages:
/// `program_name`), reads it back as the control would and checks that it reproduces the
/// set-points exactly, and judges the original and the compensated program on the true machine
/// against the original path (docs/compensation.md).
pub fn compensate_program(
    machine: &Machine,
    program: &std::path::Path,
    program_name: &str,
    models: &MachineModels,
    opts: &CompensateOptions,
    headroom: Option<f64>,
    lenient: bool,
) -> Result<CompensatedProgram, Error> {
    let original = crate::run::prepare_file(machine, program, lenient)?;
    let planned =
        compensate_within_limits(machine, program, &original, models, opts, headroom, lenient)?;
    let comp = &planned.compensation;
    let rules = &machine.program_output;
    let header = vec![
        format!(
            "vcnc compensate: {} on machine {}, models {}",
            original.file,
            machine.name,
            models.source()
        ),
        format!(
            "{} set-points at {} s in G93 blocks of {} to {} periods (resolution {} mm, {} deg; chord tolerance {} mm, {} deg); lead {} s, tail {} s; velocity headroom {}; docs/compensation.md",
            comp.len(),
            comp.ts,
            rules.min_samples,
            vcnc_gcode::FINE_BLOCK_MAX_SAMPLES,
            rules.resolution,
            rules.rotary_resolution,
            rules.tolerance,
            rules.rotary_tolerance,
            comp.lead as f64 * comp.ts,
            comp.tail as f64 * comp.ts,
            planned.headroom
        ),
    ];
    let written = comp.program(&header, rules);
    // The program as the control runs it: re-read and interpolated, it must run through the
    // positions it was written for (the set-points within the rounding and chord error the
    // writer measured); the true drives are judged on it.
    let rerun = crate::run::prepare(machine, &written.text, program_name, false)?;
    let reproduction = reproduction(comp, &rerun)?;
    if let Some((r, bound)) = reproduction
        .iter()
        .zip(&written.deviation)
        .find(|(r, d)| r.position > **d * (1.0 + 1e-9) + 1e-12)
    {
        return Err(Error::NotReproduced {
            program: program_name.to_string(),
            axis: r.axis,
            off: r.position,
            bound: *bound,
        });
    }
    let program_figures = WrittenProgram::new(&written, rules, comp.ts);
    let text = written.text;
    let before = on_true_machine(machine, &original, &original)?;
    let after = on_true_machine(machine, &original, &rerun)?;
    let after_models = match machine.kinematics {
        Some(_) => Some(with_models(machine, &original, &rerun, models)?),
        None => None,
    };
    let summary = CompensateSummary::new(
        machine,
        &original,
        models.source(),
        (program_name, program_figures),
        (opts, &planned),
        (&before, &after, after_models.as_ref()),
        &reproduction,
    );
    Ok(CompensatedProgram {
        original,
        planned,
        text,
        rerun,
        reproduction,
        before,
        after,
        after_models,
        summary,
    })
}

impl CompensateSummary {
    /// The summary of a compensation of `original` with the models of `model_file`, written as
    /// `program_name`, judged `before` and `after` (and on the models).
    #[allow(clippy::type_complexity)]
    fn new(
        machine: &Machine,
        original: &Run,
        model_file: &str,
        (program_name, written): (&str, WrittenProgram),
        (opts, planned): (&CompensateOptions, &Planned),
        (before, after, after_models): (&Judged, &Judged, Option<&vcnc_contour::ContourReport>),
        repro: &[Reproduction],
    ) -> CompensateSummary {
        let comp = &planned.compensation;
        let axes: std::collections::BTreeMap<String, AxisCompensateSummary> = comp
            .axes
            .iter()
            .zip(repro)
            .zip(before.traces.iter().zip(&after.traces))
            .zip(&original.axes)
            .map(|(((a, r), (tb, ta)), o)| {
                let unit = a.reference.unit;
                let k = unit.micro_factor();
                (
                    a.reference.name.to_string(),
                    AxisCompensateSummary {
                        unit,
                        margin: a.margin,
                        within_limits: a.margin.within(),
                        iterations: a.history.len(),
                        model_error_linear_inverse: a.history.first().copied().unwrap_or(0.0) * k,
                        model_error: a
                            .desired
                            .iter()
                            .zip(&a.model)
                            .fold(0.0f64, |m, (d, y)| m.max((d - y).abs()))
                            * k,
                        reproduction: *r,
                        before: AxisRunFigures::of(tb, &o.pos, unit),
                        after: AxisRunFigures::of(ta, &a.desired, unit),
                    },
                )
            })
            .collect();
        let figures = |j: &Judged| RunFigures {
            contour: j
                .contour
                .as_ref()
                .map(|c| ContourStats::over_feed(original, c)),
            cycle_time_s: j.cycle_time_s,
        };
        CompensateSummary {
            machine: machine.name.clone(),
            program: original.file.clone(),
            models: model_file.to_string(),
            compensated_program: program_name.to_string(),
            written,
            ts_s: comp.ts,
            lead_s: comp.lead as f64 * comp.ts,
            tail_s: comp.tail as f64 * comp.ts,
            options: *opts,
            velocity_headroom: planned.headroom,
            before: figures(before),
            after: figures(after),
            after_models: after_models.map(|c| ContourStats::over_feed(original, c)),
            within_limits: comp.axes.iter().all(|a| a.margin.within()),
            axes,
        }
    }
}
