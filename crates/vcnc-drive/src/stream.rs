//! Streamed simulation (docs/performance.md, "Streamed simulation"): the true drives and the
//! models fed the reference a piece at a time, so that a long run never holds a whole-run
//! signal. Memory is O(piece) (plus, for a model with a dead time of $m$ samples, O($m$)).
//!
//! A stream keeps between pieces everything the whole-run loop keeps between samples: the
//! plant and controller states, the encoder readers' seeded noise streams, the dead-time and
//! reference-filter lines, the friction elements, and the last sample fed. Its output is the
//! whole run's **bit for bit, for any split of the reference into pieces** (down to one sample
//! a piece): [`Drive::simulate`], [`ClosedLoopModel::simulate`] and [`DriveModel::simulate`]
//! are these streams fed the whole reference at once.
//!
//! There is no output lag: the servo loop logs sample $k$ at its first tick, and the ticks
//! that follow interpolate towards sample $k + 1$ (module docs of [`crate::engine`], "Timing");
//! a stream receiving sample $k$ first runs those ticks of sample $k - 1$, then logs sample
//! $k$. The model's step to sample $k + 1$ (first-order hold) likewise needs samples up to
//! $k + 1$ only.
//!
//! ```
//! use vcnc_drive::{Channels, DriveTrace, Reference, table1_drive};
//!
//! let drive = table1_drive().validate()?;
//! let n = 3000;
//! let pos: Vec<f64> = (0..n).map(|k| 100.0 * k as f64 * 1e-3).collect();
//! let (vel, acc) = (vec![100.0; n], vec![0.0; n]);
//! let whole = drive.simulate(Reference { pos: &pos, vel: &vel, acc: &acc }, 1e-3)?;
//!
//! let mut stream = drive.stream(1e-3, Channels::All)?;
//! let mut trace = DriveTrace::default();
//! for ((p, v), a) in pos.chunks(1000).zip(vel.chunks(1000)).zip(acc.chunks(1000)) {
//!     stream.feed(Reference { pos: p, vel: v, acc: a }, &mut trace)?;
//! }
//! trace.saturated_ticks = stream.finish()?;
//! assert_eq!(trace, whole);
//! # Ok::<(), vcnc_drive::Error>(())
//! ```

use crate::Error;
use crate::drive::Drive;
use crate::drive_model::{DriveModel, ExtendedStream};
use crate::engine::{DriveTrace, Feed, run_of};
use crate::model::SimOptions;
use crate::model::{ClosedLoopModel, Discretized, FohState, Integrator, Reference, Rk4Stream};

/// The channels a [`DriveStream`] logs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channels {
    /// Every [`DriveTrace`] channel.
    All,
    /// The true (load) position alone, [`DriveTrace::true_position`] (what a prediction keeps:
    /// 8 bytes a sample instead of 48); the other channels are left untouched.
    TruePosition,
}

/// A true drive simulated a piece of the reference at a time ([`Drive::stream`]): the engine's
/// resumable run of the drive ([`crate::engine`]).
pub struct DriveStream {
    ts: f64,
    channels: Channels,
    /// Samples fed so far.
    fed: usize,
    run: Box<dyn Feed>,
    /// The error a feed returned: the stream is spent.
    failed: Option<Error>,
}

impl Drive {
    /// A stream of this drive at the sample period `ts` (s), logging `channels`: feed it the
    /// reference in pieces ([`DriveStream::feed`]), then [`DriveStream::finish`]. The trace it
    /// logs is [`Drive::simulate`]'s bit for bit, however the reference is split.
    ///
    /// Errors: [`Error::BadSamplePeriod`], [`Error::ServoRate`], and the discretisation's
    /// ([`Error::TooStiff`], [`Error::NonFiniteModel`]).
    pub fn stream(&self, ts: f64, channels: Channels) -> Result<DriveStream, Error> {
        Ok(DriveStream {
            ts,
            channels,
            fed: 0,
            run: run_of(self, ts)?,
            failed: None,
        })
    }
}

impl DriveStream {
    /// Feeds the next samples of the reference (position, velocity and acceleration of equal
    /// length, one sample or more; the first sample of the first piece is where the drive
    /// starts at rest) and appends one logged sample per sample fed to `out`, in the channels
    /// asked for, with `out.ts` set (`out.saturated_ticks` is left alone: see
    /// [`DriveStream::finish`]). `out` may be cleared between pieces.
    ///
    /// Errors: an empty first piece ([`Error::EmptySignal`]; a later empty piece does
    /// nothing), [`Error::LengthMismatch`] (the piece's lengths), [`Error::NonFinite`] naming
    /// the sample's index in the whole reference (a run with one bad value gets the error the
    /// whole-run simulation gives), and a reference filter's discretisation at the first
    /// sample. After an error the stream is spent: every later call returns that error.
    pub fn feed(&mut self, piece: Reference<'_>, out: &mut DriveTrace) -> Result<(), Error> {
        let n = admit(piece, self.fed, &mut self.failed)?;
        let result = self.feed_checked(piece, out);
        latch(result.map(|()| n), &mut self.fed, &mut self.failed)
    }

    fn feed_checked(&mut self, piece: Reference<'_>, out: &mut DriveTrace) -> Result<(), Error> {
        out.ts = self.ts;
        self.run.feed(&[piece], self.channels, &mut [out])
    }

    /// Samples fed so far.
    pub fn samples(&self) -> usize {
        self.fed
    }

    /// Ends the stream: the servo ticks at which the control was saturated over the whole run
    /// ([`DriveTrace::saturated_ticks`] of the whole-run simulation). Errors: nothing fed
    /// ([`Error::EmptySignal`], as an empty reference), or the error a feed returned.
    pub fn finish(self) -> Result<u64, Error> {
        if let Some(e) = self.failed {
            return Err(e);
        }
        if self.fed == 0 {
            return Err(Error::EmptySignal);
        }
        Ok(self.run.saturated_ticks()[0])
    }
}

/// A model simulated a piece of the reference at a time ([`DriveModel::stream`],
/// [`ClosedLoopModel::stream`]).
#[derive(Debug, Clone)]
pub struct ModelStream {
    fed: usize,
    engine: ModelEngine,
    failed: Option<Error>,
}

/// The integration behind a [`ModelStream`].
#[derive(Debug, Clone)]
enum ModelEngine {
    /// [`ClosedLoopModel`], exact first-order hold.
    Foh {
        d: Box<Discretized>,
        opts: SimOptions,
        state: Option<FohState>,
    },
    /// [`ClosedLoopModel`], Runge–Kutta.
    Rk4(Box<Rk4Stream>),
    /// [`DriveModel`] with a dead time, reference filter or extra pole.
    Extended(Box<ExtendedStream>),
}

impl ClosedLoopModel {
    /// A stream of [`ClosedLoopModel::simulate`] at the sample period `ts` (s) with `opts`:
    /// feed it the reference in pieces ([`ModelStream::feed`]); the positions are the whole
    /// run's bit for bit, however the reference is split.
    ///
    /// Errors: as [`ClosedLoopModel::simulate`]'s besides the reference's
    /// ([`Error::BadSamplePeriod`], [`Error::NonFiniteModel`], [`Error::TooStiff`]).
    pub fn stream(&self, ts: f64, opts: &SimOptions) -> Result<ModelStream, Error> {
        let engine = match opts.integrator {
            Integrator::ExactFoh => ModelEngine::Foh {
                d: Box::new(self.discretize(ts)?),
                opts: *opts,
                state: None,
            },
            Integrator::Rk4 { substeps } => {
                if !(ts > 0.0 && ts.is_finite()) {
                    return Err(Error::BadSamplePeriod { ts });
                }
                ModelEngine::Rk4(Box::new(Rk4Stream::new(
                    self,
                    ts,
                    substeps.max(1),
                    opts.friction_deadband,
                )))
            }
        };
        Ok(ModelStream {
            fed: 0,
            engine,
            failed: None,
        })
    }
}

impl DriveModel {
    /// A stream of this model at the sample period `ts` (s) with `opts`: what a prediction
    /// runs per axis, [`ClosedLoopModel::stream`] of the core when the model is the paper's
    /// seven parameters alone ([`DriveModel::is_core_only`]), else the stream of
    /// [`DriveModel::simulate`]. The positions are those simulations' bit for bit, however the
    /// reference is split.
    ///
    /// Errors: the model's ([`DriveModel::validate`]), [`Error::BadSamplePeriod`], the
    /// discretisation's ([`Error::TooStiff`], [`Error::NonFiniteModel`]).
    pub fn stream(&self, ts: f64, opts: &SimOptions) -> Result<ModelStream, Error> {
        if self.is_core_only() {
            return self.core.stream(ts, opts);
        }
        self.validate()?;
        if !(ts > 0.0 && ts.is_finite()) {
            return Err(Error::BadSamplePeriod { ts });
        }
        Ok(ModelStream {
            fed: 0,
            engine: ModelEngine::Extended(Box::new(ExtendedStream::of(self, ts, *opts)?)),
            failed: None,
        })
    }
}

impl ModelStream {
    /// Feeds the next samples of the reference (as [`DriveStream::feed`]) and appends the
    /// model position at each to `out`, axis units.
    ///
    /// Errors: those of the piece (as [`DriveStream::feed`]), and
    /// [`Error::NonFiniteModel`] when an extended model's position is not finite (as
    /// [`DriveModel::simulate`]; the piece's positions are appended). After an error the
    /// stream is spent: every later call returns that error.
    pub fn feed(&mut self, piece: Reference<'_>, out: &mut Vec<f64>) -> Result<(), Error> {
        let n = admit(piece, self.fed, &mut self.failed)?;
        let result = self.feed_checked(piece, out);
        latch(result.map(|()| n), &mut self.fed, &mut self.failed)
    }

    fn feed_checked(&mut self, piece: Reference<'_>, out: &mut Vec<f64>) -> Result<(), Error> {
        let samples = piece.pos.iter().zip(piece.vel).zip(piece.acc);
        match &mut self.engine {
            ModelEngine::Foh { d, opts, state } => {
                out.reserve(piece.pos.len());
                for ((p, v), a) in samples {
                    let x = match state {
                        Some(st) => d.step(st, *p, *v, *a, opts),
                        None => {
                            let st = d.start(*p, *v, *a);
                            *state = Some(st);
                            *p
                        }
                    };
                    out.push(x);
                }
                Ok(())
            }
            ModelEngine::Rk4(s) => {
                out.extend(samples.map(|((p, v), a)| s.sample(*p, *v, *a)));
                Ok(())
            }
            ModelEngine::Extended(s) => s.feed(piece, self.fed, out, None),
        }
    }

    /// Samples fed so far.
    pub fn samples(&self) -> usize {
        self.fed
    }

    /// Ends the stream. Errors: nothing fed ([`Error::EmptySignal`], as an empty
    /// reference), or the error a feed returned.
    pub fn finish(self) -> Result<(), Error> {
        if let Some(e) = self.failed {
            return Err(e);
        }
        if self.fed == 0 {
            return Err(Error::EmptySignal);
        }
        Ok(())
    }
}

/// Whether a stream takes `piece`: the error it is spent on, if any, else the piece's checks
/// against the `fed` samples before it (an error is kept in `failed`), else the piece's length.
fn admit(piece: Reference<'_>, fed: usize, failed: &mut Option<Error>) -> Result<usize, Error> {
    if let Some(e) = failed {
        return Err(e.clone());
    }
    piece
        .check_piece(fed)
        .inspect_err(|e| *failed = Some(e.clone()))
}

/// A piece's outcome in a stream: its samples counted (`fed`), or its error kept (`failed`) so
/// that every later call returns it.
fn latch(
    result: Result<usize, Error>,
    fed: &mut usize,
    failed: &mut Option<Error>,
) -> Result<(), Error> {
    match result {
        Ok(n) => {
            *fed += n;
            Ok(())
        }
        Err(e) => {
            *failed = Some(e.clone());
            Err(e)
        }
    }
}
