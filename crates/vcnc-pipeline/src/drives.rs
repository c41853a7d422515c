//! The drive stages of a run, fed a piece of the reference at a time: the machine's true drives
//! ([`TrueDrives`]) and sets of identified models ([`ModelRuns`]), every axis in parallel, each
//! stream in order (so the thread count does not matter). A stream keeps between pieces exactly
//! what the whole-run loop keeps between samples, so any split gives the whole run's values bit
//! for bit (`vcnc_drive::stream`).

use rayon::prelude::*;
use vcnc_drive::{Channels, DriveStream, DriveTrace, ModelStream, NominalStream, SimOptions};
use vcnc_machine::{Dynamics, Machine, MachineModels};

use crate::Error;
use crate::latency::Shifter;
use crate::source::ReferenceChunk;

/// The pipeline's error for machine axis `i`'s drive error.
pub(crate) fn drive_error(machine: &Machine, i: usize) -> impl Fn(vcnc_drive::Error) -> Error + '_ {
    move |source| Error::Drive {
        axis: machine.axes[i].name,
        source,
    }
}

/// One machine axis' nominal-position filters (the machine file's `[control]`): what the
/// drive receives of the reference, a piece at a time.
struct AxisNominal {
    stream: NominalStream,
    pos: Vec<f64>,
    vel: Vec<f64>,
    acc: Vec<f64>,
}

impl AxisNominal {
    /// Per machine axis, the control's filter chain (`None` everywhere without one).
    fn of(machine: &Machine) -> Vec<Option<AxisNominal>> {
        machine
            .axes
            .iter()
            .map(|_| {
                machine.control.as_ref().map(|f| AxisNominal {
                    stream: f.stream(),
                    pos: Vec::new(),
                    vel: Vec::new(),
                    acc: Vec::new(),
                })
            })
            .collect()
    }

    /// The piece `r` as the drive receives it (`r` itself without filters).
    fn apply<'a>(
        this: &'a mut Option<AxisNominal>,
        r: vcnc_drive::Reference<'a>,
    ) -> Result<vcnc_drive::Reference<'a>, vcnc_drive::Error> {
        let Some(n) = this else {
            return Ok(r);
        };
        n.stream.feed(r, &mut n.pos, &mut n.vel, &mut n.acc)?;
        Ok(vcnc_drive::Reference {
            pos: &n.pos,
            vel: &n.vel,
            acc: &n.acc,
        })
    }
}

/// One machine axis of the true machine: its virtual drive, or (for an axis known only by its
/// identified model) the model with the shift from its logged to its physical position.
#[allow(clippy::large_enum_variant)] // one per axis and run: boxing buys nothing
enum TrueAxis {
    Drive(DriveStream),
    Model(AxisModel),
}

/// Every machine axis of the true machine, fed a piece at a time: the virtual drives, and on
/// a machine (partly) made of identified models, those models — what they predict is then the
/// truth of the run (docs/machine-file.md#a-machine-made-of-identified-models).
pub(crate) struct TrueDrives {
    axes: Vec<TrueAxis>,
    /// Per machine axis: the control's filters in front of it.
    nominal: Vec<Option<AxisNominal>>,
    /// Per machine axis: the trace of the last piece (the channels asked for). An axis known by
    /// its model logs only positions: its model's logged position in both `position` and
    /// `true_position` (the physical shift is in [`TrueDrives::physical`]).
    pub traces: Vec<DriveTrace>,
    /// Per machine axis known by its model: the physical positions that became known with the
    /// last piece (its logged positions advanced by its stated actual-value latency, which
    /// holds back a few samples until the end). Empty for a drive axis: see
    /// [`TrueDrives::physical`].
    shifted: Vec<Vec<f64>>,
}

impl TrueDrives {
    /// The true machine of `machine` at sample period `ts`, its drives logging `channels`.
    pub fn new(machine: &Machine, ts: f64, channels: Channels) -> Result<TrueDrives, Error> {
        let opts = SimOptions::default();
        let axes = machine
            .axes
            .iter()
            .enumerate()
            .map(|(i, a)| {
                Ok(match &a.dynamics {
                    Dynamics::Drive(d) => {
                        TrueAxis::Drive(d.stream(ts, channels).map_err(drive_error(machine, i))?)
                    }
                    Dynamics::Model(m) => TrueAxis::Model(
                        AxisModel::new(m, ts, m.actual_latency_s, &opts)
                            .map_err(drive_error(machine, i))?,
                    ),
                })
            })
            .collect::<Result<Vec<_>, Error>>()?;
        let n = axes.len();
        Ok(TrueDrives {
            axes,
            nominal: AxisNominal::of(machine),
            traces: (0..n).map(|_| DriveTrace::default()).collect(),
            shifted: vec![Vec::new(); n],
        })
    }

    /// Machine axis `i`'s physical positions that became known with the last piece: a drive's
    /// true positions, a model's shifted ones.
    pub fn physical(&self, i: usize) -> &[f64] {
        match self.axes[i] {
            TrueAxis::Drive(_) => &self.traces[i].true_position,
            TrueAxis::Model(_) => &self.shifted[i],
        }
    }

    /// Feeds chunk `c` to each axis (through the control's filters), every axis in parallel,
    /// into [`TrueDrives::traces`] and the models' shifted positions (one per axis, cleared
    /// first).
    pub fn feed(&mut self, machine: &Machine, c: &ReferenceChunk) -> Result<(), Error> {
        self.axes
            .par_iter_mut()
            .zip(self.traces.par_iter_mut())
            .zip(self.shifted.par_iter_mut())
            .zip(self.nominal.par_iter_mut())
            .enumerate()
            .try_for_each(|(i, (((d, t), y), nominal))| {
                t.clear_channels(0);
                y.clear();
                let r = AxisNominal::apply(nominal, c.axis(i)).map_err(drive_error(machine, i))?;
                match d {
                    TrueAxis::Drive(d) => {
                        d.feed(r, t).map_err(drive_error(machine, i))?;
                    }
                    TrueAxis::Model(m) => {
                        m.feed(r, y).map_err(drive_error(machine, i))?;
                        t.position.extend_from_slice(&m.logged);
                        t.true_position.extend_from_slice(&m.logged);
                    }
                }
                Ok(())
            })
    }

    /// The end of the reference: per machine axis, the servo ticks at which the drive's
    /// command saturated (0 for a model), and the physical positions still held back.
    pub fn finish(self, machine: &Machine) -> Result<(Vec<u64>, Vec<Vec<f64>>), Error> {
        let mut ticks = Vec::with_capacity(self.axes.len());
        let mut rest = Vec::with_capacity(self.axes.len());
        for (i, d) in self.axes.into_iter().enumerate() {
            let mut y = Vec::new();
            match d {
                TrueAxis::Drive(d) => ticks.push(d.finish().map_err(drive_error(machine, i))?),
                TrueAxis::Model(m) => {
                    m.finish(&mut y).map_err(drive_error(machine, i))?;
                    ticks.push(0);
                }
            }
            rest.push(y);
        }
        Ok((ticks, rest))
    }
}

/// One axis of one model set: the model's stream and the latency shift of its output.
struct AxisModel {
    stream: ModelStream,
    shifter: Shifter,
    /// The model's logged positions of the last piece (before the shift).
    logged: Vec<f64>,
}

impl AxisModel {
    /// The model `m` at sample period `ts`, its output advanced by `shift_s` (0: none).
    fn new(
        m: &vcnc_drive::DriveModel,
        ts: f64,
        shift_s: f64,
        opts: &SimOptions,
    ) -> Result<AxisModel, vcnc_drive::Error> {
        Ok(AxisModel {
            stream: m.stream(ts, opts)?,
            shifter: Shifter::new(shift_s, ts),
            logged: Vec::new(),
        })
    }

    /// Feeds a piece: its logged positions into `self.logged`, and the shifted positions that
    /// became known with it into `shifted` (cleared first).
    fn feed(
        &mut self,
        piece: vcnc_drive::Reference<'_>,
        shifted: &mut Vec<f64>,
    ) -> Result<(), vcnc_drive::Error> {
        self.logged.clear();
        shifted.clear();
        self.stream.feed(piece, &mut self.logged)?;
        self.shifter.feed(&self.logged, shifted);
        Ok(())
    }

    /// The end of the reference: the shifted positions still held back into `rest`.
    fn finish(self, rest: &mut Vec<f64>) -> Result<(), vcnc_drive::Error> {
        self.stream.finish()?;
        self.shifter.finish(rest);
        Ok(())
    }
}

/// Sets of models (one model per machine axis each), fed a piece at a time.
pub(crate) struct ModelRuns {
    sets: Vec<Vec<AxisModel>>,
    /// Per machine axis: the control's filters in front of every set's model.
    nominal: Vec<Option<AxisNominal>>,
    /// Per set, per machine axis: the positions that became known with the last piece (or at
    /// the end), advanced by the model's stated actual-value latency when the runs were made
    /// for the physical axes.
    pub out: Vec<Vec<Vec<f64>>>,
}

impl ModelRuns {
    /// The model sets at sample period `ts`. With `physical`, each model's positions are
    /// advanced by its stated actual-value latency (the physical axis, a few samples later:
    /// [`crate::latency`]); without, they are the logged positions the model predicts.
    pub fn new(
        machine: &Machine,
        sets: &[&MachineModels],
        ts: f64,
        physical: bool,
    ) -> Result<ModelRuns, Error> {
        let opts = SimOptions::default();
        let sets = sets
            .iter()
            .map(|set| {
                set.models()
                    .iter()
                    .enumerate()
                    .map(|(i, m)| {
                        let shift = if physical { m.actual_latency_s } else { 0.0 };
                        AxisModel::new(m, ts, shift, &opts).map_err(drive_error(machine, i))
                    })
                    .collect::<Result<Vec<_>, Error>>()
            })
            .collect::<Result<Vec<_>, Error>>()?;
        let out = sets.iter().map(|s| vec![Vec::new(); s.len()]).collect();
        Ok(ModelRuns {
            sets,
            nominal: AxisNominal::of(machine),
            out,
        })
    }

    /// Feeds chunk `c` to every model (through the control's filters), every axis of every
    /// set in parallel, into [`ModelRuns::out`] (cleared first).
    pub fn feed(&mut self, machine: &Machine, c: &ReferenceChunk) -> Result<(), Error> {
        let refs = self
            .nominal
            .par_iter_mut()
            .enumerate()
            .map(|(i, n)| AxisNominal::apply(n, c.axis(i)).map_err(drive_error(machine, i)))
            .collect::<Result<Vec<_>, Error>>()?;
        self.sets
            .par_iter_mut()
            .zip(self.out.par_iter_mut())
            .try_for_each(|(set, out)| {
                set.par_iter_mut()
                    .zip(out.par_iter_mut())
                    .enumerate()
                    .try_for_each(|(i, (m, y))| m.feed(refs[i], y).map_err(drive_error(machine, i)))
            })
    }

    /// The end of the reference: [`ModelRuns::out`] becomes the positions still held back by
    /// the latency shift.
    pub fn finish(self, machine: &Machine) -> Result<Vec<Vec<Vec<f64>>>, Error> {
        let mut out = self.out;
        for (set, o) in self.sets.into_iter().zip(&mut out) {
            for (i, (m, y)) in set.into_iter().zip(o.iter_mut()).enumerate() {
                y.clear();
                m.finish(y).map_err(drive_error(machine, i))?;
            }
        }
        Ok(out)
    }
}
