//! Measured traces: read a scope file of any format `vcnc-trace` knows, pair each axis' nominal
//! and actual position, and identify every axis in parallel through the one identification
//! route ([`crate::identify::identify_trace`]).

use std::path::Path;

use rayon::prelude::*;
use vcnc_machine::OptionsFile;
use vcnc_trace::Paired;

use crate::Error;
use crate::identify::{AxisIdentification, identify_trace};

// The reading and pairing options the command line builds.
pub use vcnc_trace::{
    AxisMap, ChannelRef, Format, GapPolicy, PairOptions, ReadOptions, TraceArgs, TraceUnit,
    read_path,
};

/// A trace file read and paired.
#[derive(Debug, Clone)]
pub struct MeasuredTrace {
    /// The file as read (every channel).
    pub trace: vcnc_trace::Trace,
    /// Per axis: nominal and actual positions on one grid, in mm or deg.
    pub paired: Paired,
}

/// Reads `path` (its format detected from the content unless `read.format` is set) and pairs
/// its axes.
pub fn read_trace(
    path: &Path,
    read: &ReadOptions,
    pair: &PairOptions,
) -> Result<MeasuredTrace, Error> {
    let trace = vcnc_trace::read_path(path, read)?;
    let paired = vcnc_trace::pair(&trace, pair)?;
    Ok(MeasuredTrace { trace, paired })
}

/// Identifies every paired axis of `m` (in parallel, results in axis order).
pub fn identify_measured(
    m: &MeasuredTrace,
    options: &OptionsFile,
    seed: Option<u64>,
) -> Result<Vec<AxisIdentification>, Error> {
    m.paired
        .axes
        .par_iter()
        .map(|a| {
            let trace = vcnc_identify::Trace::new(a.ts_s, a.nominal.clone(), a.actual.clone())
                .map_err(|e| Error::identify(format!("{} axis {}", m.paired.file, a.axis), e))?;
            identify_trace(trace, a, options, seed)
        })
        .collect()
}
