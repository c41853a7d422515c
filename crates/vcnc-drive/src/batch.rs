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
    let mut out: Vec<Option<Result<DriveTrace, Error>>> = jobs.iter().map(|_| None).collect();
    for group in batch_groups(jobs, ts) {
        if group.len() > 1
            && let Some(traces) = run_group(jobs, &group, ts)
        {
            for (i, t) in group.iter().zip(traces) {
                out[*i] = Some(Ok(t));
            }
            continue;
        }
        for i in group {
            let (d, r) = &jobs[i];
            out[i] = Some(d.simulate(*r, ts));
        }
    }
    out.into_iter()
        .map(|r| r.unwrap_or(Err(Error::EmptySignal)))
        .collect()
}

/// One group in one loop; `None` if it cannot run so (then each drive runs alone and reports
/// its own result).
fn run_group(
    jobs: &[(&Drive, Reference<'_>)],
    group: &[usize],
    ts: f64,
) -> Option<Vec<DriveTrace>> {
    let drives: Vec<&Drive> = group.iter().map(|i| jobs[*i].0).collect();
    let references: Vec<Reference<'_>> = group.iter().map(|i| jobs[*i].1).collect();
    let n = references[0].check().ok()?;
    let n_sub = drives[0].ticks_per_sample(ts).ok()?;
    let h = ts / n_sub as f64;
    let mut traces: Vec<DriveTrace> = (0..group.len())
        .map(|_| DriveTrace::with_capacity(ts, n))
        .collect();
    match real_sim::simulate_lanes(&drives, &references, n_sub, h, &mut traces) {
        Ok(true) => Some(traces),
        _ => None,
    }
}
