//! `vcnc simulate` streamed (docs/performance.md, "Streamed prediction"): the reference of a
//! program of any length goes a piece at a time through the true drives and, optionally, the
//! models; each piece is handed to the caller (who writes it) and dropped, and the tracking
//! figures of `summary.json` are accumulated on the way. Memory does not grow with the
//! program's length. The values are [`crate::simulate::simulate`]'s and
//! [`crate::simulate::tracking`]'s bit for bit (tested in `tests/stream_predict.rs`).

use std::path::Path;

use rayon::prelude::*;
use vcnc_drive::{Channels, DriveModel, DriveTrace, SimOptions};
use vcnc_machine::Machine;

use crate::Error;
use crate::simulate::AxisFigures;
use crate::stats::MaxRms;
use crate::stream::{ReferenceChunk, ReferenceStream, StreamStats, drive_error, feed_drives};

/// A piece of a streamed simulation, samples `first..first + len()`.
#[derive(Debug, Clone, Default)]
pub struct SimulatePiece {
    /// Index of the first sample.
    pub first: usize,
    /// Per machine axis: the reference position, mm or deg.
    pub reference: Vec<Vec<f64>>,
    /// Per machine axis: the true drive's trace of these samples (every channel).
    pub traces: Vec<DriveTrace>,
    /// Per machine axis: the model's position, when models are simulated.
    pub predicted: Option<Vec<Vec<f64>>>,
}

impl SimulatePiece {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.reference.first().map_or(0, Vec::len)
    }

    /// `true` without samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// What a streamed simulation measured.
#[derive(Debug, Clone)]
pub struct StreamedSimulation {
    /// Per machine axis: the tracking figures of [`crate::simulate::tracking`], bit for bit.
    pub tracking: Vec<AxisFigures>,
    /// What streaming the reference measured (rates, warnings).
    pub stats: StreamStats,
    /// Samples simulated.
    pub samples: usize,
}

/// Runs `stream` (the program at `path`, planned on `machine`) through the true drives (every
/// channel) and, with `models` (one per machine axis), through the models, handing each piece
/// to `sink` in order.
pub fn simulate_streamed(
    machine: &Machine,
    stream: &ReferenceStream,
    path: &Path,
    models: Option<&[DriveModel]>,
    sink: &mut dyn FnMut(&SimulatePiece) -> Result<(), Error>,
) -> Result<StreamedSimulation, Error> {
    let axes = machine.axes.len();
    if let Some(m) = models
        && m.len() != axes
    {
        return Err(Error::Usage(format!("{} models for {axes} axes", m.len())));
    }
    let ts = stream.plan.ts;
    let drive_err = |i: usize| drive_error(machine, i);
    let mut drives = machine
        .axes
        .iter()
        .enumerate()
        .map(|(i, a)| a.drive.stream(ts, Channels::All).map_err(drive_err(i)))
        .collect::<Result<Vec<_>, Error>>()?;
    let opts = SimOptions::default();
    let mut model_streams = match models {
        Some(m) => Some(
            m.iter()
                .enumerate()
                .map(|(i, m)| m.stream(ts, &opts).map_err(drive_err(i)))
                .collect::<Result<Vec<_>, Error>>()?,
        ),
        None => None,
    };
    let mut piece = SimulatePiece {
        reference: vec![Vec::new(); axes],
        traces: (0..axes).map(|_| DriveTrace::default()).collect(),
        predicted: models.map(|_| vec![Vec::new(); axes]),
        first: 0,
    };
    let mut tracking = vec![MaxRms::default(); axes];
    let mut model_vs_true = vec![MaxRms::default(); axes];
    let mut samples = 0usize;
    let mut on_chunk = |c: &ReferenceChunk| -> Result<(), Error> {
        piece.first = c.first;
        let SimulatePiece {
            reference,
            traces,
            predicted,
            ..
        } = &mut piece;
        let (a, b) = rayon::join(
            || feed_drives(machine, &mut drives, traces, c),
            || match (model_streams.as_mut(), predicted.as_mut()) {
                (Some(ms), Some(out)) => ms
                    .par_iter_mut()
                    .zip(out.par_iter_mut())
                    .enumerate()
                    .try_for_each(|(i, (m, x))| {
                        x.clear();
                        m.feed(c.axis(i), x).map_err(drive_err(i))
                    }),
                _ => Ok(()),
            },
        );
        a?;
        b?;
        for (i, r) in reference.iter_mut().enumerate() {
            r.clear();
            r.extend_from_slice(&c.pos[i]);
        }
        // The figures of crate::simulate::tracking: the encoder reading against the reference,
        // the model against the encoder reading, µm or mdeg, summed in sample order.
        for (i, a) in machine.axes.iter().enumerate() {
            let k = a.unit.micro_factor();
            let x = &traces[i].position;
            for (r, x) in reference[i].iter().zip(x) {
                tracking[i].add((r - x) * k);
            }
            if let Some(p) = predicted.as_ref() {
                for (m, x) in p[i].iter().zip(x) {
                    model_vs_true[i].add((m - x) * k);
                }
            }
        }
        samples += c.len();
        sink(&piece)
    };
    let stats = stream.run(machine, path, &mut on_chunk)?;
    for (i, d) in drives.into_iter().enumerate() {
        d.finish().map_err(drive_err(i))?;
    }
    if let Some(ms) = model_streams {
        for (i, m) in ms.into_iter().enumerate() {
            m.finish().map_err(drive_err(i))?;
        }
    }
    let tracking = (0..axes)
        .map(|i| AxisFigures {
            tracking: tracking[i].max_rms(),
            model_vs_true: models.map(|_| model_vs_true[i].max_rms()),
        })
        .collect();
    Ok(StreamedSimulation {
        tracking,
        stats,
        samples,
    })
}
