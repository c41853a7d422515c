//! Where a run's pieces go: ripgrep's searcher and sink. A run ([`crate::interpolate`],
//! [`crate::simulate`], [`crate::predict`]) hands each finished piece of samples to a [`Sink`]
//! and computes its statistics itself; what is kept of the pieces — a table written as it goes,
//! a figure's envelope, every sample for full-resolution figures, nothing — is the sink's
//! choice. The whole-run result is just the sink that collects everything, so a run's outputs
//! are the same whichever sinks are chosen, by construction.
//!
//! Sinks combine: a pair `(a, b)` hands every piece to `a` then `b` (the pair fails as `a`
//! does), and `Option<S>` to `S` when it is there.

use crate::Error;

/// A consumer of a run's pieces of type `P`.
pub trait Sink<P> {
    /// What can go wrong consuming a piece; a run's own errors convert into it, so that the
    /// run returns one error type.
    type Error: From<Error>;

    /// Takes the next piece (pieces come in order, each sample once). An error stops the run,
    /// which returns it.
    fn piece(&mut self, piece: &P) -> Result<(), Self::Error>;
}

impl<P, S: Sink<P> + ?Sized> Sink<P> for &mut S {
    type Error = S::Error;
    fn piece(&mut self, piece: &P) -> Result<(), S::Error> {
        (**self).piece(piece)
    }
}

impl<P, A: Sink<P>, B: Sink<P>> Sink<P> for (A, B)
where
    A::Error: From<B::Error>,
{
    type Error = A::Error;
    fn piece(&mut self, piece: &P) -> Result<(), A::Error> {
        self.0.piece(piece)?;
        Ok(self.1.piece(piece)?)
    }
}

impl<P, S: Sink<P>> Sink<P> for Option<S> {
    type Error = S::Error;
    fn piece(&mut self, piece: &P) -> Result<(), S::Error> {
        match self {
            Some(s) => s.piece(piece),
            None => Ok(()),
        }
    }
}

/// The sink that keeps nothing: a run for its statistics alone (a sweep's configurations).
#[derive(Debug, Clone, Copy, Default)]
pub struct Discard;

impl<P> Sink<P> for Discard {
    type Error = Error;
    fn piece(&mut self, _: &P) -> Result<(), Error> {
        Ok(())
    }
}

/// A closure as a sink (tests, small callers).
pub struct FnSink<F>(pub F);

impl<P, F: FnMut(&P) -> Result<(), Error>> Sink<P> for FnSink<F> {
    type Error = Error;
    fn piece(&mut self, piece: &P) -> Result<(), Error> {
        (self.0)(piece)
    }
}
