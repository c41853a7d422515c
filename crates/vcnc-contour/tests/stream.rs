//! The streamed contour search (docs/contour.md#streamed-search) against the whole-path search.
//!
//! Truth: [`ContourSearch`] over the whole path, which `tests/contour.rs` ties bit for bit to
//! the brute-force oracle. The stream must give every sample's tip and orientation errors and
//! foot, and the statistics, to the same bits (`to_bits`), however the reference and the
//! actual poses are cut into pieces and interleaved, in memory bounded by its limits.

mod common;

use common::{Spiral, actual, low_pass, reference};
use proptest::prelude::*;
use vcnc_contour::{
    ContourPath, ContourReport, ContourSearch, ContourStream, Error, Foot, SearchWindow, Sequence,
    StreamHeld, StreamLimits,
};
use vcnc_kinematics::Pose;
use vcnc_kinematics::nalgebra::Vector3;

fn ok<T>(r: Result<T, Error>) -> T {
    match r {
        Ok(v) => v,
        Err(e) => panic!("{e}"),
    }
}

/// The whole-path search (feet kept).
fn whole(r: &[Pose], a: &[Pose]) -> ContourReport {
    let path = ok(ContourPath::new(r));
    let mut search = ok(ContourSearch::new(
        &path,
        &SearchWindow::default(),
        true,
        a.len(),
    ));
    for pose in a {
        ok(search.push(pose));
    }
    ok(search.finish())
}

/// One streamed sample: index, tip error (mm), orientation error (rad), foot.
type Sample = (usize, f64, f64, Foot);

/// How a run is cut: reference and actual piece sizes (cycled) and how far the reference is
/// pushed ahead of the actual (samples; negative: the actual is pushed ahead of its
/// reference).
#[derive(Debug, Clone)]
struct Schedule {
    reference: Vec<usize>,
    actual: Vec<usize>,
    lead: i64,
}

/// Streams `r` and `a` as `schedule` says, draining after every piece; returns the samples in
/// the order handed out, the report, and the most held at any time.
fn streamed(
    r: &[Pose],
    a: &[Pose],
    limits: StreamLimits,
    schedule: &Schedule,
) -> Result<(Vec<Sample>, ContourReport, StreamHeld), Error> {
    let mut s = ContourStream::new(&SearchWindow::default(), limits)?;
    let mut out: Vec<Sample> = Vec::with_capacity(a.len());
    let mut most = s.held();
    let (mut i, mut j) = (0usize, 0usize);
    let (mut ri, mut ai) = (0usize, 0usize);
    while i < r.len() || j < a.len() {
        let reference_next = j == a.len() || (i < r.len() && (i as i64) < j as i64 + schedule.lead);
        if reference_next {
            let n = schedule.reference[ri % schedule.reference.len()].max(1);
            ri += 1;
            let end = (i + n).min(r.len());
            s.push_reference(r[i..end].iter().copied())?;
            i = end;
            if i == r.len() {
                s.end_reference();
            }
        } else {
            let n = schedule.actual[ai % schedule.actual.len()].max(1);
            ai += 1;
            let end = (j + n).min(a.len());
            for pose in &a[j..end] {
                s.push_actual(pose)?;
            }
            j = end;
        }
        let h = s.held();
        most.knots = most.knots.max(h.knots);
        most.queued = most.queued.max(h.queued);
        s.drain(|k, tip, ori, foot| out.push((k, tip, ori, *foot)))?;
    }
    if r.is_empty() {
        s.end_reference();
    }
    let report = s.finish(|k, tip, ori, foot| out.push((k, tip, ori, *foot)))?;
    Ok((out, report, most))
}

fn same_foot(x: &Foot, y: &Foot) -> bool {
    x.u.to_bits() == y.u.to_bits()
        && (0..3).all(|i| {
            x.point[i].to_bits() == y.point[i].to_bits()
                && x.orientation[i].to_bits() == y.orientation[i].to_bits()
        })
}

/// Every sample, in order, and the statistics bit for bit; the projections counted equal too
/// when `same_evals`.
fn assert_same(w: &ContourReport, out: &[Sample], report: &ContourReport, same_evals: bool) {
    assert_eq!(out.len(), w.tip_mm.len());
    for (n, (k, tip, ori, foot)) in out.iter().enumerate() {
        assert_eq!(*k, n);
        assert!(
            tip.to_bits() == w.tip_mm[n].to_bits()
                && ori.to_bits() == w.orientation_rad[n].to_bits()
                && same_foot(foot, &w.foot[n]),
            "sample {n}: streamed {foot:?} ({tip} mm, {ori} rad) vs whole {:?} ({} mm, {} rad)",
            w.foot[n],
            w.tip_mm[n],
            w.orientation_rad[n]
        );
    }
    assert_eq!(report.tip_max_mm.to_bits(), w.tip_max_mm.to_bits());
    assert_eq!(report.tip_rms_mm.to_bits(), w.tip_rms_mm.to_bits());
    assert_eq!(
        report.orientation_max_rad.to_bits(),
        w.orientation_max_rad.to_bits()
    );
    assert_eq!(
        report.orientation_rms_rad.to_bits(),
        w.orientation_rms_rad.to_bits()
    );
    assert!(
        report.tip_mm.is_empty() && report.orientation_rad.is_empty() && report.foot.is_empty()
    );
    if same_evals {
        assert_eq!(report.segment_evaluations, w.segment_evaluations);
    }
}

/// Pieces of 1, 13, 1000 and mixed sizes, with the reference 0, 3, 200 and 5000 samples
/// ahead of the actual and 1 and 700 behind it.
fn schedules() -> Vec<Schedule> {
    let mut v = Vec::new();
    for (rp, ap) in [
        (vec![1], vec![1]),
        (vec![13], vec![13]),
        (vec![1000], vec![1000]),
        (vec![1000], vec![1]),
        (vec![7, 1, 300, 64, 2], vec![5, 129, 1, 33]),
    ] {
        for lead in [0, 3, 200, 5000, -1, -700] {
            v.push(Schedule {
                reference: rp.clone(),
                actual: ap.clone(),
                lead,
            });
        }
    }
    v
}

/// The stream equals the whole-path search under every schedule.
fn check_all_schedules(r: &[Pose], a: &[Pose]) -> ContourReport {
    let w = whole(r, a);
    for schedule in schedules() {
        let (out, report, most) = match streamed(r, a, StreamLimits::default(), &schedule) {
            Ok(v) => v,
            Err(e) => panic!("{schedule:?}: {e}"),
        };
        assert_same(&w, &out, &report, true);
        assert!(most.queued <= StreamLimits::default().queue);
    }
    w
}

#[test]
fn spiral_with_lag_streams_bit_for_bit() {
    // docs/contour.md spiral at 1 kHz (≈ 10 100 samples); actual = reference delayed 4 ms
    // with a 5 µm offset and a 0.2 mrad tilt. Its first tip is 2.5 µm off the first
    // reference tip: the first foot comes from the global search over the first window
    // (here the whole path), so the projections counted are equal too.
    let spiral = Spiral::new();
    let r = reference(&spiral, None, 0);
    let a = actual(&spiral, None, r.len() + 10, 4e-3, 5.0, 0.2);
    assert_ne!(a[0].p, r[0].p);
    let w = check_all_schedules(&r, &a);
    assert!(w.tip_max_mm > 4e-3 && w.tip_max_mm < 6.81e-3);
}

#[test]
fn path_with_rests_streams_bit_for_bit() {
    // A stop of 0.3 s mid-path (300 identical reference samples, merged into one knot) and
    // 400 samples at rest at the end; the actual is a first-order lag of the reference, so it
    // starts exactly on the first reference tip (the first foot is u = 0 without a global
    // search) and moves while the reference rests. While the reference rests at the last knot
    // held, the actual samples wait: whether the path ends there decides the time hint.
    let spiral = Spiral::new();
    let r = reference(&spiral, Some((300.0, 0.3)), 400);
    let a = low_pass(&r, 0.1);
    assert_eq!(a[0].p, r[0].p);
    let w = check_all_schedules(&r, &a);
    assert_eq!(w.foot[0].u, 0.0);
    // The shortcut counts one projection for the first sample, not a pass over the path
    // (the whole-path search takes it too; tests/contour.rs checks its feet against the brute
    // force on low-pass actuals, which all start on the first reference tip).
    assert_eq!(whole(&r, &a[..1]).segment_evaluations, 1);
}

/// A CAM raster (tests/contour.rs): 60 mm passes in alternating directions 3 mm apart, at
/// 75 mm/s (1 kHz), 100 samples at rest at the end.
fn raster() -> Vec<Pose> {
    let (mut r, _) = common::raster_passes();
    let last = r[r.len() - 1];
    r.extend(std::iter::repeat_n(last, 100));
    r
}

#[test]
fn raster_with_reversals_streams_bit_for_bit() {
    // After each reversal the time hint (the segment at reference sample k) moves the foot to
    // the new pass (tests/contour.rs): its second window reads knots ahead of the foot, which
    // the stream must hold first.
    let r = raster();
    let a = low_pass(&r, 0.05);
    let w = check_all_schedules(&r, &a);
    assert!(w.tip_max_mm > 0.1 && w.tip_max_mm < 1.5, "{}", w.tip_max_mm);
}

#[test]
fn actual_far_from_the_path_streams_bit_for_bit() {
    // The actual tip 4 mm above the spiral (along the tool axis) and 30 ms behind: the reach
    // ball (2 × 4 mm) holds ≈ 100 segments of 75 µm either side, so every window grows far
    // forward and waits for that much reference.
    let spiral = Spiral::new();
    let mut r = reference(&spiral, None, 0);
    r.truncate(4000);
    let a: Vec<Pose> = actual(&spiral, None, r.len(), 30e-3, 0.0, 0.0)
        .into_iter()
        .map(|p| Pose::new(p.p + p.o * 4.0, p.o))
        .collect();
    let w = check_all_schedules(&r, &a);
    assert!(w.tip_max_mm > 3.9, "{}", w.tip_max_mm);
    let per_sample = w.segment_evaluations as f64 / a.len() as f64;
    eprintln!("{per_sample:.1} projections a sample");
    assert!(per_sample > 100.0, "{per_sample} projections a sample");
}

#[test]
fn first_sample_off_the_start_is_found_in_the_first_window() {
    // The actual leads the reference by 1.5 s (≈ 1700 samples into the path, accelerating
    // from rest): its first foot lies near reference sample 1700. Searched over a first window
    // of 2500 samples, it is the whole-path foot, and so is every later one; the whole-path
    // search projects on every segment for it, the stream on the window's only.
    let spiral = Spiral::new();
    let r = reference(&spiral, None, 0);
    let a = actual(&spiral, None, 3000, -1.5, 5.0, 0.2);
    let w = whole(&r, &a);
    assert!(
        w.foot[0].u > 1400.0 && w.foot[0].u < 2000.0,
        "{}",
        w.foot[0].u
    );
    let limits = StreamLimits {
        first_window: 2500,
        ..StreamLimits::default()
    };
    for schedule in schedules() {
        let (out, report, _) = ok(streamed(&r, &a, limits, &schedule));
        assert_same(&w, &out, &report, false);
        // The difference in the count: the global search over r.len() − 1 segments against
        // the window's 2499 (no rest in the first window: one knot a sample).
        assert_eq!(
            w.segment_evaluations - report.segment_evaluations,
            (r.len() - 1 - 2499) as u64
        );
    }
    // A first window that ends before the global foot confines the first polyline foot to it
    // (the curve refinement may then move it up to 4 pieces on): the stream no longer equals
    // the whole-path search — the documented condition for equality, not an error.
    let limits = StreamLimits {
        first_window: 1000,
        ..StreamLimits::default()
    };
    let (out, _, _) = ok(streamed(&r, &a, limits, &schedules()[0]));
    assert!(out[0].3.u < 1005.0, "{}", out[0].3.u);
    assert_ne!(out[0].3.u, w.foot[0].u);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Random piece sizes and leads on the raster (time hint) and the spiral with a stop.
    #[test]
    fn random_pieces_stream_bit_for_bit(
        reference_pieces in proptest::collection::vec(1usize..400, 1..6),
        actual_pieces in proptest::collection::vec(1usize..400, 1..6),
        lead in -300i64..600,
        which in 0usize..2,
    ) {
        let (r, a) = if which == 0 {
            let r = raster();
            let a = low_pass(&r, 0.05);
            (r, a)
        } else {
            let spiral = Spiral::new();
            let mut r = reference(&spiral, Some((100.0, 0.2)), 50);
            r.truncate(4000);
            let a = actual(&spiral, Some((100.0, 0.2)), r.len(), 20e-3, 5.0, 0.2);
            (r, a)
        };
        let w = whole(&r, &a);
        let schedule = Schedule { reference: reference_pieces, actual: actual_pieces, lead };
        let (out, report, _) = ok(streamed(&r, &a, StreamLimits::default(), &schedule));
        assert_same(&w, &out, &report, true);
    }
}

#[test]
fn bad_poses_name_the_same_sample_as_the_whole_path_search() {
    let spiral = Spiral::new();
    let mut r = reference(&spiral, None, 0);
    r.truncate(3000);
    let a = low_pass(&r, 0.2);
    let schedule = Schedule {
        reference: vec![100],
        actual: vec![100],
        lead: 100,
    };
    // A NaN reference tip at sample 2345.
    let mut bad_r = r.clone();
    bad_r[2345].p.y = f64::NAN;
    // (Compared through Debug: the NaN in the error makes `==` false.)
    let e_whole = ContourPath::new(&bad_r).map(|_| ());
    let e_stream = streamed(&bad_r, &a, StreamLimits::default(), &schedule).map(|_| ());
    assert!(
        matches!(
            e_whole,
            Err(Error::NonFinite {
                which: Sequence::Reference,
                sample: 2345,
                ..
            })
        ),
        "{e_whole:?}"
    );
    assert_eq!(format!("{e_stream:?}"), format!("{e_whole:?}"));
    // A NaN actual axis at sample 1777, and a zero one at 1778.
    for (k, pose) in [
        (1777, Pose::new(a[1777].p, Vector3::new(f64::NAN, 0.0, 1.0))),
        (1778, Pose::new(a[1778].p, Vector3::zeros())),
    ] {
        let mut bad_a = a.clone();
        bad_a[k] = pose;
        let path = ok(ContourPath::new(&r));
        let mut search = ok(ContourSearch::new(
            &path,
            &SearchWindow::default(),
            false,
            0,
        ));
        let e_whole = bad_a.iter().try_for_each(|p| search.push(p));
        let e_stream = streamed(&r, &bad_a, StreamLimits::default(), &schedule).map(|_| ());
        assert!(e_whole.is_err());
        assert_eq!(format!("{e_stream:?}"), format!("{e_whole:?}"));
    }
}

#[test]
fn empty_sequences_and_misuse_are_typed_errors() {
    let p = Pose::new(Vector3::new(1.0, 2.0, 3.0), Vector3::z());
    let limits = StreamLimits::default();
    let window = SearchWindow::default();
    // No reference at all (as ContourPath::new(&[]) says).
    assert_eq!(
        ContourPath::new(&[]).map(|_| ()),
        Err(Error::Empty(Sequence::Reference))
    );
    let mut s = ok(ContourStream::new(&window, limits));
    ok(s.push_actual(&p));
    s.end_reference();
    assert_eq!(
        s.finish(|_, _, _, _| {}).map(|_| ()),
        Err(Error::Empty(Sequence::Reference))
    );
    // No actual pose (as ContourSearch::finish says).
    let mut s = ok(ContourStream::new(&window, limits));
    ok(s.push_reference([p, p]));
    s.end_reference();
    assert_eq!(
        s.finish(|_, _, _, _| {}).map(|_| ()),
        Err(Error::Empty(Sequence::Actual))
    );
    // Out of order.
    let mut s = ok(ContourStream::new(&window, limits));
    s.end_reference();
    assert!(matches!(s.push_reference([p]), Err(Error::StreamOrder(_))));
    let s = ok(ContourStream::new(&window, limits));
    assert!(matches!(
        s.finish(|_, _, _, _| {}),
        Err(Error::StreamOrder(_))
    ));
    // Unusable limits.
    for bad in [
        StreamLimits {
            history: 8,
            ..limits
        },
        StreamLimits {
            first_window: 0,
            ..limits
        },
        StreamLimits { queue: 0, ..limits },
        StreamLimits {
            knots: limits.first_window,
            ..limits
        },
    ] {
        assert!(matches!(
            ContourStream::new(&window, bad),
            Err(Error::BadLimits { .. })
        ));
    }
}

#[test]
fn full_queue_and_too_many_knots_are_typed_errors() {
    let line = |x: f64| Pose::new(Vector3::new(x, 0.0, 0.0), Vector3::z());
    let window = SearchWindow::default();
    // Ten actual samples wait for a reference that has not come: the eleventh is refused.
    let limits = StreamLimits {
        queue: 10,
        ..StreamLimits::default()
    };
    let mut s = ok(ContourStream::new(&window, limits));
    for k in 0..10 {
        ok(s.push_actual(&line(0.1 * k as f64)));
    }
    assert_eq!(
        s.push_actual(&line(1.0)),
        Err(Error::QueueFull {
            sample: 10,
            limit: 10
        })
    );
    // Before the first actual sample's foot is found no knot may be dropped: reference pushed
    // far ahead fills the knots allowed.
    let limits = StreamLimits {
        history: 16,
        first_window: 16,
        queue: 16,
        knots: 100,
    };
    let mut s = ok(ContourStream::new(&window, limits));
    assert_eq!(
        s.push_reference((0..1000).map(|k| line(0.1 * k as f64))),
        Err(Error::TooManyKnots {
            sample: 100,
            limit: 100
        })
    );
}

#[test]
fn a_search_reaching_back_beyond_the_history_is_an_error() {
    // A 2000 mm line, 20 000 samples; the actual follows it for 15 000 samples, then jumps
    // back to 0.5 mm beside its start. The window around the previous foot grows back while
    // the edge lies within twice the best distance (≈ 1500 mm): to the path's start, 15 000
    // knots back. The whole-path search finds the start; a stream keeping 1000 knots of
    // history cannot, and says so, naming the sample.
    let line = |x: f64, y: f64| Pose::new(Vector3::new(x, y, 0.0), Vector3::z());
    let r: Vec<Pose> = (0..20_000).map(|k| line(0.1 * k as f64, 0.0)).collect();
    let mut a: Vec<Pose> = (0..15_000)
        .map(|k| line(0.1 * (k as f64 - 3.0).max(0.0), 0.002))
        .collect();
    a.push(line(0.0, 0.5));
    let w = whole(&r, &a);
    assert_eq!(w.foot[15_000].u, 0.0);
    assert!((w.tip_mm[15_000] - 0.5).abs() < 1e-12);
    // (Its first tip is 2 µm beside the start: found in a first window of 64 samples.)
    let limits = StreamLimits {
        history: 1000,
        first_window: 64,
        ..StreamLimits::default()
    };
    let schedule = Schedule {
        reference: vec![500],
        actual: vec![500],
        lead: 500,
    };
    let e = streamed(&r, &a, limits, &schedule).map(|_| ());
    assert!(
        matches!(
            e,
            Err(Error::HistoryExceeded {
                sample: 15_000,
                history: 1000,
                ..
            })
        ),
        "{e:?}"
    );
    // With the history the path needs, the stream finds it.
    let limits = StreamLimits {
        history: 20_000,
        first_window: 64,
        ..StreamLimits::default()
    };
    let (out, report, _) = ok(streamed(&r, &a, limits, &schedule));
    assert_same(&w, &out, &report, false);
}

/// Reference pose `k` of a long generated run: a helix of radius 20 mm climbing 1 mm a turn,
/// 0.05 mm a sample, with the tool axis tilting to and fro, and a 500-sample stop every
/// 100 000 samples.
fn long_reference(k: usize) -> Pose {
    let stop = 500;
    let period = 100_000;
    let moving = (k / period) * (period - stop) + (k % period).min(period - stop);
    let s = 0.05 * moving as f64;
    let phi = s / 20.0;
    let p = Vector3::new(
        20.0 * phi.cos(),
        20.0 * phi.sin(),
        phi / std::f64::consts::TAU,
    );
    let o = Vector3::new(0.2 * (0.01 * phi).sin(), 0.0, 1.0).normalize();
    Pose::new(p, o)
}

#[test]
fn a_two_million_sample_run_streams_in_bounded_memory() {
    // 2 M reference samples and 2 M actual ones (the reference 4 samples late, 3 µm outward),
    // pushed in pieces of 65 536: the reference piece, then the actual piece of the same
    // samples, then a drain. The knots held stay below the limits (the history and the piece
    // in flight), whatever the run's length; the contour error is the 3 µm offset.
    const N: usize = 2_000_000;
    const PIECE: usize = 65_536;
    let limits = StreamLimits {
        history: 4096,
        first_window: 4096,
        queue: 2 * PIECE,
        knots: 3 * PIECE,
    };
    let act = |k: usize| {
        let p = long_reference(k.saturating_sub(4));
        let radial = Vector3::new(p.p.x, p.p.y, 0.0).normalize();
        Pose::new(p.p + radial * 3e-3, p.o)
    };
    let mut s = ok(ContourStream::new(&SearchWindow::default(), limits));
    let mut most = s.held();
    let mut count = 0usize;
    let mut worst = 0.0f64;
    let mut check = |k: usize, tip: f64| {
        assert_eq!(k, count);
        count += 1;
        worst = worst.max(tip);
    };
    let mut start = 0;
    while start < N {
        let end = (start + PIECE).min(N);
        ok(s.push_reference((start..end).map(long_reference)));
        if end == N {
            s.end_reference();
        }
        for k in start..end {
            ok(s.push_actual(&act(k)));
        }
        let h = s.held();
        most.knots = most.knots.max(h.knots);
        most.queued = most.queued.max(h.queued);
        ok(s.drain(|k, tip, _, _| check(k, tip)));
        start = end;
    }
    let report = ok(s.finish(|k, tip, _, _| check(k, tip)));
    assert_eq!(count, N);
    eprintln!("most held: {most:?}; tip max {} mm", report.tip_max_mm);
    assert!(most.knots <= limits.knots, "{most:?}");
    assert!(most.queued <= limits.queue, "{most:?}");
    // Pushed a piece at a time and drained, the stream holds the history, one piece and the
    // few knots around the foot (69 639 measured), not the run's 2 M knots.
    assert!(most.knots <= limits.history + PIECE + 64, "{most:?}");
    // The 3 µm offset, within the helix's chord sag (0.05² / (8 · 20) mm ≈ 16 nm, absent on
    // the curve) and its 1 mm a turn climb (the offset is radial, the curve's normal is too).
    assert!(
        (report.tip_max_mm - 3e-3).abs() < 1e-6,
        "{}",
        report.tip_max_mm
    );
    assert_eq!(worst, report.tip_max_mm);
}
