//! The drive stages of a run, fed a piece of the reference at a time: the machine's true drives
//! ([`TrueDrives`]) and sets of identified models ([`ModelRuns`]), every axis in parallel, each
//! stream in order (so the thread count does not matter). A stream keeps between pieces exactly
//! what the whole-run loop keeps between samples, so any split gives the whole run's values bit
//! for bit (`vcnc_drive::stream`).

use rayon::prelude::*;
use vcnc_drive::{Channels, DriveStream, DriveTrace, ModelStream, SimOptions};
use vcnc_machine::{Machine, MachineModels};

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

/// Every machine axis' true drive, fed a piece at a time.
pub(crate) struct TrueDrives {
    streams: Vec<DriveStream>,
    /// Per machine axis: the trace of the last piece (the channels asked for).
    pub traces: Vec<DriveTrace>,
}

impl TrueDrives {
    /// The drives of `machine` at sample period `ts`, logging `channels`.
    pub fn new(machine: &Machine, ts: f64, channels: Channels) -> Result<TrueDrives, Error> {
        let streams = machine
            .axes
            .iter()
            .enumerate()
            .map(|(i, a)| {
                a.drive
                    .stream(ts, channels)
                    .map_err(drive_error(machine, i))
            })
            .collect::<Result<Vec<_>, Error>>()?;
        let traces = (0..streams.len()).map(|_| DriveTrace::default()).collect();
        Ok(TrueDrives { streams, traces })
    }

    /// Feeds chunk `c` to each axis' drive, every axis in parallel, into [`TrueDrives::traces`]
    /// (one per axis, its channels cleared first).
    pub fn feed(&mut self, machine: &Machine, c: &ReferenceChunk) -> Result<(), Error> {
        self.streams
            .par_iter_mut()
            .zip(self.traces.par_iter_mut())
            .enumerate()
            .try_for_each(|(i, (d, t))| {
                t.clear_channels(0);
                d.feed(c.axis(i), t).map_err(drive_error(machine, i))
            })
    }

    /// The end of the reference: per machine axis, the servo ticks at which the drive's
    /// command saturated.
    pub fn finish(self, machine: &Machine) -> Result<Vec<u64>, Error> {
        self.streams
            .into_iter()
            .enumerate()
            .map(|(i, d)| d.finish().map_err(drive_error(machine, i)))
            .collect()
    }
}

/// One axis of one model set: the model's stream and the latency shift of its output.
struct AxisModel {
    stream: ModelStream,
    shifter: Shifter,
    /// The model's logged positions of the last piece (before the shift).
    logged: Vec<f64>,
}

/// Sets of models (one model per machine axis each), fed a piece at a time.
pub(crate) struct ModelRuns {
    sets: Vec<Vec<AxisModel>>,
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
                        Ok(AxisModel {
                            stream: m.stream(ts, &opts).map_err(drive_error(machine, i))?,
                            shifter: Shifter::new(
                                if physical { m.actual_latency_s } else { 0.0 },
                                ts,
                            ),
                            logged: Vec::new(),
                        })
                    })
                    .collect::<Result<Vec<_>, Error>>()
            })
            .collect::<Result<Vec<_>, Error>>()?;
        let out = sets.iter().map(|s| vec![Vec::new(); s.len()]).collect();
        Ok(ModelRuns { sets, out })
    }

    /// Feeds chunk `c` to every model, every axis of every set in parallel, into
    /// [`ModelRuns::out`] (cleared first).
    pub fn feed(&mut self, machine: &Machine, c: &ReferenceChunk) -> Result<(), Error> {
        self.sets
            .par_iter_mut()
            .zip(self.out.par_iter_mut())
            .try_for_each(|(set, out)| {
                set.par_iter_mut()
                    .zip(out.par_iter_mut())
                    .enumerate()
                    .try_for_each(|(i, (m, y))| {
                        m.logged.clear();
                        y.clear();
                        m.stream
                            .feed(c.axis(i), &mut m.logged)
                            .map_err(drive_error(machine, i))?;
                        m.shifter.feed(&m.logged, y);
                        Ok::<(), Error>(())
                    })
            })
    }

    /// The end of the reference: [`ModelRuns::out`] becomes the positions still held back by
    /// the latency shift.
    pub fn finish(self, machine: &Machine) -> Result<Vec<Vec<Vec<f64>>>, Error> {
        let mut out = self.out;
        for (set, o) in self.sets.into_iter().zip(&mut out) {
            for (i, (m, y)) in set.into_iter().zip(o.iter_mut()).enumerate() {
                m.stream.finish().map_err(drive_error(machine, i))?;
                y.clear();
                m.shifter.finish(y);
            }
        }
        Ok(out)
    }
}
