//! Several true drives simulated together (docs/machine-file.md#cost): drives with effects
//! that share their loop's structure run four at a time, one per SIMD lane, each lane's trace
//! bit for bit the one [`Drive::simulate`] gives for its drive alone. The five drives of a
//! machine usually share it (same control law, mechanics, friction model and feedback path;
//! different numbers), so a machine's true drives cost about two drives' time instead of five.
//!
//! ```
//! use vcnc_drive::{Reference, batch, table1_drive};
//!
//! let drive = table1_drive().validate()?;
//! let pos: Vec<f64> = (0..500).map(|k| 0.1 * k as f64).collect();
//! let (vel, acc) = (vec![100.0; 500], vec![0.0; 500]);
//! let r = Reference { pos: &pos, vel: &vel, acc: &acc };
//! let traces = batch::simulate_batch(&[(&drive, r), (&drive, r)], 1e-3);
//! assert_eq!(traces[0].as_ref().unwrap(), &drive.simulate(r, 1e-3)?);
//! # Ok::<(), vcnc_drive::Error>(())
//! ```

use crate::model::Reference;
use crate::params::Drive;
use crate::real_sim::{self, Structure};
use crate::sim::DriveTrace;
use crate::{Error, real_sim::LANES};

/// Drives per batch (lanes of 256-bit registers).
pub const BATCH_LANES: usize = LANES;

/// What drives must share to run in one batch.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Key {
    structure: Structure,
    samples: usize,
    n_sub: usize,
}

/// The batch key of a drive on a reference of period `ts`; `None` for a drive that runs alone
/// (no effects: the ideal loop; or an input [`Drive::simulate`] refuses).
fn key(drive: &Drive, reference: &Reference<'_>, ts: f64) -> Option<Key> {
    if drive.effects().is_ideal() {
        return None;
    }
    let samples = reference.check().ok()?;
    let n_sub = drive.ticks_per_sample(ts).ok()?;
    let structure = real_sim::structure(drive, ts / n_sub as f64).ok()?;
    Some(Key {
        structure,
        samples,
        n_sub,
    })
}

/// How [`simulate_batch`] runs `jobs` (drive and reference, period `ts`): groups of indices
/// into `jobs`, in order of their first member, each at most [`BATCH_LANES`] long. A group of
/// two or more runs in one loop; a group of one (an ideal drive, a drive whose structure no
/// other shares, or an input that [`Drive::simulate`] refuses) runs alone. Run the groups in
/// parallel if wanted: each drive's trace does not depend on its group.
pub fn batch_groups(jobs: &[(&Drive, Reference<'_>)], ts: f64) -> Vec<Vec<usize>> {
    let keys: Vec<Option<Key>> = jobs.iter().map(|(d, r)| key(d, r, ts)).collect();
    let mut groups: Vec<(Option<Key>, Vec<usize>)> = Vec::new();
    for (i, k) in keys.iter().enumerate() {
        let open = k.and_then(|k| {
            groups
                .iter()
                .position(|(gk, g)| *gk == Some(k) && g.len() < LANES)
        });
        match open {
            Some(g) => groups[g].1.push(i),
            None => groups.push((*k, vec![i])),
        }
    }
    groups.into_iter().map(|(_, g)| g).collect()
}

/// Simulates each drive on its reference (period `ts`, s), as [`Drive::simulate`] does, the
/// drives of a group of [`batch_groups`] in one loop (SIMD lanes). Results in the order of
/// `jobs`; each is bit for bit [`Drive::simulate`]'s, error included.
pub fn simulate_batch(jobs: &[(&Drive, Reference<'_>)], ts: f64) -> Vec<Result<DriveTrace, Error>> {
    let mut traces = Vec::new();
    simulate_batch_into(jobs, ts, &mut traces)
        .into_iter()
        .zip(traces)
        .map(|(r, t)| r.map(|()| t))
        .collect()
}

/// As [`simulate_batch`], into `traces` (one per job, in the order of `jobs`; the vector is
/// resized to `jobs.len()` and each trace's buffers are reused, as [`Drive::simulate_into`]
/// reuses its one): a loop that simulates batch after batch allocates nothing. Where a job's
/// result is an error, its trace holds nothing meaningful.
pub fn simulate_batch_into(
    jobs: &[(&Drive, Reference<'_>)],
    ts: f64,
    traces: &mut Vec<DriveTrace>,
) -> Vec<Result<(), Error>> {
    traces.resize_with(jobs.len(), DriveTrace::default);
    let mut out: Vec<Option<Result<(), Error>>> = jobs.iter().map(|_| None).collect();
    for group in batch_groups(jobs, ts) {
        if group.len() > 1 && run_group(jobs, &group, ts, traces) {
            for i in group {
                out[i] = Some(Ok(()));
            }
            continue;
        }
        for i in group {
            let (d, r) = &jobs[i];
            out[i] = Some(d.simulate_into(*r, ts, &mut traces[i]));
        }
    }
    out.into_iter()
        .map(|r| r.unwrap_or(Err(Error::EmptySignal)))
        .collect()
}

/// One group in one loop, into its members' `traces`; `false` if it cannot run so (then each
/// drive runs alone and reports its own result).
fn run_group(
    jobs: &[(&Drive, Reference<'_>)],
    group: &[usize],
    ts: f64,
    traces: &mut [DriveTrace],
) -> bool {
    let drives: Vec<&Drive> = group.iter().map(|i| jobs[*i].0).collect();
    let references: Vec<Reference<'_>> = group.iter().map(|i| jobs[*i].1).collect();
    let (Ok(n), Ok(n_sub)) = (references[0].check(), drives[0].ticks_per_sample(ts)) else {
        return false;
    };
    let h = ts / n_sub as f64;
    // The group's traces, in the group's order (its indices rise: `batch_groups`).
    let mut members: Vec<&mut DriveTrace> = traces
        .iter_mut()
        .enumerate()
        .filter(|(i, _)| group.contains(i))
        .map(|(_, t)| t)
        .collect();
    for t in members.iter_mut() {
        t.ts = ts;
        t.clear_channels(n);
        t.saturated_ticks = 0;
    }
    matches!(
        real_sim::simulate_lanes(&drives, &references, n_sub, h, &mut members),
        Ok(true)
    )
}
