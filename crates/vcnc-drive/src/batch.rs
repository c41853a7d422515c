//! Several true drives simulated together (docs/machine-file.md#cost): drives with effects
//! that share their loop's structure run four at a time, one per SIMD lane, each lane's trace
//! bit for bit the one [`Drive::simulate`] gives for its drive alone. The five drives of a
//! machine usually share it (same control law, mechanics, friction model and feedback path;
//! different numbers), so a machine's true drives cost about two drives' time instead of five.
//!
//! [`GroupStream`] runs a group of drives a piece of the reference at a time (the streamed
//! route); [`simulate_batch`] and [`simulate_batch_into`] run whole references, group by group
//! of [`batch_groups`], through the same stream fed everything at once.
//!
//! ```
//! use vcnc_drive::{Channels, DriveTrace, GroupStream, Reference, batch, table1_drive};
//!
//! let drive = table1_drive().validate()?;
//! let pos: Vec<f64> = (0..500).map(|k| 0.1 * k as f64).collect();
//! let (vel, acc) = (vec![100.0; 500], vec![0.0; 500]);
//! let r = Reference { pos: &pos, vel: &vel, acc: &acc };
//! let traces = batch::simulate_batch(&[(&drive, r), (&drive, r)], 1e-3);
//! assert_eq!(traces[0].as_ref().unwrap(), &drive.simulate(r, 1e-3)?);
//!
//! // The same two drives streamed in pieces of 100 samples.
//! let mut group = GroupStream::new(&[&drive, &drive], 1e-3, Channels::All)?;
//! let mut out = vec![DriveTrace::default(); 2];
//! for k in (0..500).step_by(100) {
//!     let piece = Reference { pos: &pos[k..k + 100], vel: &vel[k..k + 100], acc: &acc[k..k + 100] };
//!     group.feed(&[piece, piece], &mut out)?;
//! }
//! for (t, saturated) in out.iter_mut().zip(group.finish()) {
//!     t.saturated_ticks = saturated?;
//! }
//! assert_eq!(out[1], drive.simulate(r, 1e-3)?);
//! # Ok::<(), vcnc_drive::Error>(())
//! ```

use crate::Error;
use crate::drive::Drive;
use crate::engine::real::Structure;
use crate::engine::{DriveTrace, Feed, lanes_run_of, run_of, structure};
use crate::lane::LANES;
use crate::model::Reference;
use crate::stream::Channels;

/// Drives per batch (lanes of 256-bit registers).
pub const BATCH_LANES: usize = LANES;

/// What drives must share to run in one batch.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Key {
    structure: Structure,
    n_sub: usize,
}

/// The batch key of a drive at the sample period `ts`; `None` for a drive that runs alone (no
/// effects: the ideal loop; or a period the drive refuses).
fn key(drive: &Drive, ts: f64) -> Option<Key> {
    if drive.effects().is_ideal() {
        return None;
    }
    let n_sub = drive.ticks_per_sample(ts).ok()?;
    let structure = structure(drive, ts / n_sub as f64).ok()?;
    Some(Key { structure, n_sub })
}

/// Indices grouped by equal keys (`None`: alone), in order of their first member, at most
/// [`BATCH_LANES`] a group.
fn group_by<K: PartialEq + Copy>(keys: &[Option<K>]) -> Vec<Vec<usize>> {
    let mut groups: Vec<(Option<K>, Vec<usize>)> = Vec::new();
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

/// How [`simulate_batch`] runs `jobs` (drive and reference, period `ts`): groups of indices
/// into `jobs`, in order of their first member, each at most [`BATCH_LANES`] long. A group of
/// two or more runs in one loop; a group of one (an ideal drive, a drive whose structure no
/// other shares, or an input that [`Drive::simulate`] refuses) runs alone. Run the groups in
/// parallel if wanted: each drive's trace does not depend on its group.
pub fn batch_groups(jobs: &[(&Drive, Reference<'_>)], ts: f64) -> Vec<Vec<usize>> {
    let keys: Vec<Option<(Key, usize)>> = jobs
        .iter()
        .map(|(d, r)| Some((key(d, ts)?, r.check().ok()?)))
        .collect();
    group_by(&keys)
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
/// reuses its one): a loop that simulates batch after batch allocates nothing but the loops'
/// constants. Where a job's result is an error, its trace holds nothing meaningful.
pub fn simulate_batch_into(
    jobs: &[(&Drive, Reference<'_>)],
    ts: f64,
    traces: &mut Vec<DriveTrace>,
) -> Vec<Result<(), Error>> {
    traces.resize_with(jobs.len(), DriveTrace::default);
    let mut out: Vec<Result<(), Error>> = jobs.iter().map(|_| Err(Error::EmptySignal)).collect();
    for group in batch_groups(jobs, ts) {
        if group.len() > 1 && run_group(jobs, &group, ts, traces, &mut out) {
            continue;
        }
        for i in group {
            let (d, r) = &jobs[i];
            out[i] = d.simulate_into(*r, ts, &mut traces[i]);
        }
    }
    out
}

/// One group of [`batch_groups`] as one [`GroupStream`] fed everything at once, into its
/// members' `traces` and `out`; `false` when a drive failed (each drive then runs alone and
/// reports its own result).
fn run_group(
    jobs: &[(&Drive, Reference<'_>)],
    group: &[usize],
    ts: f64,
    traces: &mut [DriveTrace],
    out: &mut [Result<(), Error>],
) -> bool {
    let drives: Vec<&Drive> = group.iter().map(|i| jobs[*i].0).collect();
    let pieces: Vec<Reference<'_>> = group.iter().map(|i| jobs[*i].1).collect();
    let Ok(mut stream) = GroupStream::new(&drives, ts, Channels::All) else {
        return false;
    };
    // The group's traces, in the group's order (its indices rise: `batch_groups`).
    let mut members: Vec<&mut DriveTrace> = traces
        .iter_mut()
        .enumerate()
        .filter(|(i, _)| group.contains(i))
        .map(|(_, t)| t)
        .collect();
    for t in members.iter_mut() {
        t.clear_channels(pieces[0].pos.len());
    }
    if stream.feed_into(&pieces, &mut members).is_err() {
        return false;
    }
    let saturated = stream.finish();
    if saturated.iter().any(|s| s.is_err()) {
        return false;
    }
    for ((t, s), i) in members.into_iter().zip(saturated).zip(group) {
        t.saturated_ticks = s.unwrap_or(0);
        out[*i] = Ok(());
    }
    true
}

/// A group of true drives simulated a piece of the reference at a time, sharing the clock: the
/// drives that share a loop structure (as [`batch_groups`] groups them) run together in SIMD
/// lanes, the others one at a time. Each drive's trace and result are its [`crate::DriveStream`]'s
/// bit for bit ([`Drive::simulate`]'s, for any split of the reference), so the pipeline's
/// streamed route can run a machine's drives in lanes piece by piece.
///
/// ```text
/// GroupStream::new(&[&x, &y, &z], ts, Channels::All)?      // the drives, the period
///   .feed(&[piece_x, piece_y, piece_z], &mut traces)?      // one piece per drive, same length
///   ...                                                    // as often as the reference lasts
///   .finish()                                              // each drive's saturated ticks
/// ```
pub struct GroupStream {
    ts: f64,
    channels: Channels,
    /// The runs, and the drives (indices) each one carries in its lanes.
    members: Vec<(Vec<usize>, Box<dyn Feed>)>,
    /// Per drive: samples fed, and the error that spent its stream.
    fed: Vec<usize>,
    failed: Vec<Option<Error>>,
    /// The logs of lanes whose drive's stream is spent (dropped).
    spare: Vec<DriveTrace>,
}

impl GroupStream {
    /// The stream of `drives` at the sample period `ts` (s), logging `channels`. A group of one
    /// runs the drive alone; drives with effects that share a loop structure run in lanes, four
    /// at a time, the others alone.
    ///
    /// Errors: [`Error::Group`] naming the first drive (its index in `drives`) whose stream
    /// cannot be made, with the error [`Drive::stream`] gives.
    pub fn new(drives: &[&Drive], ts: f64, channels: Channels) -> Result<GroupStream, Error> {
        let in_group = |drive: usize| {
            move |source| Error::Group {
                drive,
                source: Box::new(source),
            }
        };
        for (i, d) in drives.iter().enumerate() {
            d.ticks_per_sample(ts).map_err(in_group(i))?;
        }
        let keys: Vec<Option<Key>> = drives.iter().map(|d| key(d, ts)).collect();
        let mut members = Vec::new();
        for group in group_by(&keys) {
            if group.len() > 1 {
                let lanes: Vec<&Drive> = group.iter().map(|i| drives[*i]).collect();
                if let Ok(Some(run)) = lanes_run_of(&lanes, ts) {
                    members.push((group, run));
                    continue;
                }
            }
            for i in group {
                members.push((vec![i], run_of(drives[i], ts).map_err(in_group(i))?));
            }
        }
        Ok(GroupStream {
            ts,
            channels,
            members,
            fed: vec![0; drives.len()],
            failed: vec![None; drives.len()],
            spare: Vec::new(),
        })
    }

    /// Feeds the next samples: `pieces[i]` to drive `i` (position, velocity and acceleration of
    /// equal length; every piece of one call of the same length: the drives share the clock),
    /// appending one logged sample per sample fed to `out[i]`, in the channels asked for, with
    /// `ts` set (`saturated_ticks` is left alone: see [`GroupStream::finish`]).
    ///
    /// Each drive's piece is checked as [`crate::DriveStream::feed`] checks it (an empty first
    /// piece, lengths, non-finite values named by their index in the whole reference), and
    /// [`Error::PieceLength`] for a piece whose length is not the first piece's. A drive whose
    /// piece fails is spent, as its own stream would be: nothing of the piece is logged, every
    /// later call and [`GroupStream::finish`] report its error, and the other drives run on
    /// unchanged. Errors: the first spent drive's, as [`Error::Group`] naming it.
    ///
    /// Panics if `pieces` or `out` do not hold one entry per drive.
    pub fn feed(&mut self, pieces: &[Reference<'_>], out: &mut [DriveTrace]) -> Result<(), Error> {
        let mut refs: Vec<&mut DriveTrace> = out.iter_mut().collect();
        self.feed_into(pieces, &mut refs)
    }

    /// [`GroupStream::feed`] into one trace per drive wherever they live.
    fn feed_into(
        &mut self,
        pieces: &[Reference<'_>],
        out: &mut [&mut DriveTrace],
    ) -> Result<(), Error> {
        let n = self.fed.len();
        assert!(
            pieces.len() == n && out.len() == n,
            "{} pieces and {} traces for a group of {n} drives",
            pieces.len(),
            out.len()
        );
        let expected = pieces[0].pos.len();
        for (i, piece) in pieces.iter().enumerate() {
            if self.failed[i].is_some() {
                continue;
            }
            let checked = piece.check_piece(self.fed[i]).and_then(|len| {
                if len == expected {
                    Ok(len)
                } else {
                    Err(Error::PieceLength {
                        samples: len,
                        expected,
                    })
                }
            });
            match checked {
                Ok(len) => self.fed[i] += len,
                Err(e) => self.failed[i] = Some(e),
            }
        }
        for t in out.iter_mut() {
            t.ts = self.ts;
        }
        let GroupStream {
            channels,
            members,
            failed,
            spare,
            ..
        } = self;
        spare.resize_with(n, DriveTrace::default);
        let mut spare = spare.iter_mut();
        let mut slots: Vec<Option<&mut DriveTrace>> =
            out.iter_mut().map(|t| Some(&mut **t)).collect();
        for (drives, run) in members.iter_mut() {
            // A spent drive's lane runs on a live drive's piece, into a spare trace.
            let Some(live) = drives.iter().find(|i| failed[**i].is_none()) else {
                continue;
            };
            let mut lane_pieces = Vec::with_capacity(drives.len());
            let mut logs: Vec<&mut DriveTrace> = Vec::with_capacity(drives.len());
            for i in drives.iter() {
                if failed[*i].is_none() {
                    lane_pieces.push(pieces[*i]);
                    logs.push(slots[*i].take().expect("each drive in one run"));
                } else {
                    lane_pieces.push(pieces[*live]);
                    let s = spare.next().expect("a spare trace per drive");
                    s.clear_channels(0);
                    logs.push(s);
                }
            }
            if let Err(e) = run.feed(&lane_pieces, *channels, &mut logs) {
                for i in drives.iter() {
                    failed[*i].get_or_insert_with(|| e.clone());
                }
            }
        }
        match self.failed.iter().position(|f| f.is_some()) {
            None => Ok(()),
            Some(i) => Err(Error::Group {
                drive: i,
                source: Box::new(self.failed[i].clone().expect("a spent drive")),
            }),
        }
    }

    /// Samples fed so far to drive `i`.
    pub fn samples(&self, i: usize) -> usize {
        self.fed[i]
    }

    /// Ends the stream: per drive, the servo ticks at which its control was saturated over the
    /// whole run ([`DriveTrace::saturated_ticks`] of its whole-run simulation), or its error:
    /// nothing fed ([`Error::EmptySignal`]), or the error of the feed that spent it.
    pub fn finish(self) -> Vec<Result<u64, Error>> {
        let mut out: Vec<Result<u64, Error>> = self.fed.iter().map(|_| Ok(0)).collect();
        for (drives, run) in &self.members {
            for (i, s) in drives.iter().zip(run.saturated_ticks()) {
                out[*i] = Ok(s);
            }
        }
        for (i, (r, failed)) in out.iter_mut().zip(self.failed).enumerate() {
            if let Some(e) = failed {
                *r = Err(e);
            } else if self.fed[i] == 0 {
                *r = Err(Error::EmptySignal);
            }
        }
        out
    }
}
