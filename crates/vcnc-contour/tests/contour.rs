//! Contour errors (docs/contour.md): the windowed search against the brute-force oracle on the
//! spiral, and both against analytic truths.

mod common;

use std::f64::consts::TAU;

use common::{Spiral, TS, actual, low_pass, raster_passes, reference};
use proptest::prelude::*;
use vcnc_contour::{
    ContourReport, Error, SearchWindow, Sequence, contour_errors, contour_errors_brute_force,
    contour_errors_with, orientation_error,
};
use vcnc_kinematics::Pose;
use vcnc_kinematics::nalgebra::Vector3;

fn ok<T>(r: Result<T, Error>) -> T {
    match r {
        Ok(v) => v,
        Err(e) => panic!("{e}"),
    }
}

/// Windowed and brute force must agree on every sample, bit for bit (same foot parameter,
/// same foot point, same errors), and the windowed search must stay O(N + M).
fn assert_same_as_oracle(reference: &[Pose], actual: &[Pose]) -> (ContourReport, ContourReport) {
    let w = ok(contour_errors(reference, actual));
    let b = ok(contour_errors_brute_force(reference, actual));
    assert_eq!(w.tip_mm.len(), actual.len());
    for k in 0..actual.len() {
        assert!(
            w.tip_mm[k] == b.tip_mm[k]
                && w.orientation_rad[k] == b.orientation_rad[k]
                && w.foot[k] == b.foot[k],
            "sample {k}: windowed {:?} ({} mm, {} rad) vs brute force {:?} ({} mm, {} rad)",
            w.foot[k],
            w.tip_mm[k],
            w.orientation_rad[k],
            b.foot[k],
            b.tip_mm[k],
            b.orientation_rad[k]
        );
    }
    assert_eq!(w.tip_max_mm, b.tip_max_mm);
    assert_eq!(w.tip_rms_mm, b.tip_rms_mm);
    assert_eq!(w.orientation_max_rad, b.orientation_max_rad);
    assert_eq!(w.orientation_rms_rad, b.orientation_rms_rad);
    let n = actual.len() as u64;
    let m = reference.len() as u64;
    assert_eq!(b.segment_evaluations, n * (m - 1).max(1));
    assert!(
        w.segment_evaluations <= 64 * n + m,
        "windowed search did {} projections for N = {n}, M = {m}",
        w.segment_evaluations
    );
    (w, b)
}

#[test]
fn windowed_equals_brute_force_on_spiral_with_lag() {
    // docs/contour.md spiral at 1 kHz (≈ 10 100 samples); actual = reference delayed 4 ms with a
    // 5 µm tip offset and a 0.2 mrad axis tilt.
    let spiral = Spiral::new();
    let r = reference(&spiral, None, 0);
    assert!((spiral.length() - 755.0).abs() < 2.0, "{}", spiral.length());
    assert!((r.len() as f64 * TS - 10.1).abs() < 0.1, "{}", r.len());
    let a = actual(&spiral, None, r.len() + 10, 4e-3, 5.0, 0.2);
    let (w, _) = assert_same_as_oracle(&r, &a);
    // The contour error is the µm-scale offset (the 4 ms lag ≈ 0.3 mm along the path does not
    // count): at most the offset's length, √(5² + 2.5² + 2·5·2.5·0.6) = 6.80 µm (radial and
    // normal directions are at most 0.6 apart in cosine on this dome), plus the chord sag of
    // 75 µm segments (< 1e-4 µm).
    assert!(w.tip_max_mm < 6.81e-3, "{}", w.tip_max_mm);
    assert!(w.tip_max_mm > 4e-3, "{}", w.tip_max_mm);
    assert!(w.orientation_max_rad < 0.21e-3, "{}", w.orientation_max_rad);
}

#[test]
fn windowed_equals_brute_force_when_actual_leads() {
    let spiral = Spiral::new();
    // The first half of the spiral (5000 samples) keeps the O(N·M) oracle quick.
    let mut r = reference(&spiral, None, 0);
    r.truncate(5000);
    let a = actual(&spiral, None, r.len(), -3e-3, 3.0, 0.1);
    assert_same_as_oracle(&r, &a);
}

#[test]
fn windowed_equals_brute_force_through_stop_and_restart() {
    // The path stops at s = 300 mm for 0.3 s (300 identical reference samples) and restarts;
    // the actual lags 40 ms (30 samples at full feed), so it moves while the reference rests
    // and rests while the reference moves again.
    let spiral = Spiral::new();
    let stop = Some((300.0, 0.3));
    let r = reference(&spiral, stop, 50);
    let a = actual(&spiral, stop, r.len(), 40e-3, 4.0, 0.1);
    let (w, _) = assert_same_as_oracle(&r, &a);
    // While both rest at the stop, the foot stays at the rest knot: on the segment arriving at
    // it or the one leaving it (the µm offset decides which side), so u is within one sample
    // of the rest run.
    let first = r.windows(2).position(|p| p[0] == p[1]).unwrap_or(0);
    let len = r[first..].iter().take_while(|p| **p == r[first]).count();
    assert!(len > 290, "rest run of {len} samples");
    let (lo, hi) = ((first - 1) as f64, (first + len) as f64);
    let resting = w.foot.iter().filter(|f| f.u >= lo && f.u <= hi).count();
    assert!(
        resting > 250,
        "{resting} feet at the rest knot {first}..{}",
        first + len
    );
}

#[test]
fn windowed_equals_brute_force_with_a_low_pass_actual() {
    // A first-order lag (τ ≈ 4 ms) both lags and cuts the curve, like a drive.
    let spiral = Spiral::new();
    let mut r = reference(&spiral, Some((200.0, 0.1)), 0);
    r.truncate(5000);
    let a = low_pass(&r, 0.2);
    let (w, _) = assert_same_as_oracle(&r, &a);
    assert!(w.tip_max_mm > 0.0);
}

#[test]
fn windowed_equals_brute_force_on_a_decimated_actual() {
    // The actual logged at 40 Hz against the 1 kHz reference: the foot jumps ~25 segments
    // between consecutive actual samples, so the window must grow to follow it.
    let spiral = Spiral::new();
    let r = reference(&spiral, None, 0);
    let a: Vec<Pose> = actual(&spiral, None, r.len(), 4e-3, 5.0, 0.2)
        .into_iter()
        .step_by(25)
        .collect();
    assert_same_as_oracle(&r, &a);
}

#[test]
fn windowed_equals_brute_force_on_raster_passes_that_turn_back() {
    // A CAM raster as in LinuxCNC's 5-axis "boat" demo: 60 mm passes in alternating
    // directions, each a few mm over from the last and slanted towards the next one, at
    // 75 mm/s (1 kHz), followed by a first-order lag (τ ≈ 20 ms). After each reversal the
    // actual tip runs back alongside the pass it just left; the window around the previous
    // foot could stay on that pass (a distance growing to the pass spacing) while the true
    // foot lies on the new pass, whose start leaves the window's ball at the corner. The
    // brute force is the oracle.
    let (mut r, end) = raster_passes();
    r.extend(std::iter::repeat_n(Pose::new(end, Vector3::z()), 100));
    let a = low_pass(&r, 0.05);
    let (w, _) = assert_same_as_oracle(&r, &a);
    // The lag cuts each reversal: errors of a fraction of a mm there, far below the 3 mm
    // spacing a stuck window reports.
    assert!(w.tip_max_mm > 0.1 && w.tip_max_mm < 1.5, "{}", w.tip_max_mm);
}

#[test]
fn windowed_equals_brute_force_on_square_corners_cut_by_a_lag() {
    // A 20 mm square at 75 mm/s (1 kHz) followed by a first-order lag of τ ≈ 20 ms, which cuts
    // each 90° corner by ~0.3 mm: near the corner the nearest point jumps from the incoming
    // side to the outgoing one, several segments away.
    let corners = [
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(20.0, 0.0, 0.0),
        Vector3::new(20.0, 20.0, 0.0),
        Vector3::new(0.0, 20.0, 0.0),
        Vector3::new(0.0, 0.0, 0.0),
    ];
    let mut r = Vec::new();
    for w in corners.windows(2) {
        let n = 267; // 20 mm at 0.075 mm per sample
        for k in 0..n {
            r.push(Pose::new(
                w[0] + (w[1] - w[0]) * (k as f64 / n as f64),
                Vector3::z(),
            ));
        }
    }
    r.extend(std::iter::repeat_n(
        Pose::new(corners[4], Vector3::z()),
        100,
    ));
    let a = low_pass(&r, 0.05);
    let (w, _) = assert_same_as_oracle(&r, &a);
    assert!(w.tip_max_mm > 0.2, "{}", w.tip_max_mm);
}

#[test]
fn line_with_offset_and_rotation_matches_analytic_errors() {
    // Truth: a straight reference x ∈ [0, 50] mm with the tool axis turning in the XZ plane at
    // κ = 0.01 rad/mm; the actual is δ = 3 µm beside it (any lag: the foot is the
    // perpendicular projection) with its axis turned by β = 0.5 mrad further in the same plane.
    // Tip error = δ, orientation error = β (up to the nlerp parametrisation, < 1e-9 rad).
    let kappa = 0.01;
    let (delta, beta) = (3e-3, 0.5e-3);
    let axis = |ang: f64| Vector3::new(ang.sin(), 0.0, ang.cos());
    let r: Vec<Pose> = (0..=500)
        .map(|k| {
            let x = 0.1 * k as f64;
            Pose::new(Vector3::new(x, 0.0, 0.0), axis(kappa * x))
        })
        .collect();
    let a: Vec<Pose> = (0..480)
        .map(|k| {
            let x = 0.1 * k as f64 + 0.0371 - if k > 40 { 2.5 } else { 0.0 };
            let x = x.max(0.0);
            Pose::new(Vector3::new(x, delta, 0.0), axis(kappa * x + beta))
        })
        .collect();
    let (w, _) = assert_same_as_oracle(&r, &a);
    for (k, pose) in a.iter().enumerate() {
        assert!((w.tip_mm[k] - delta).abs() < 1e-12, "{k}: {}", w.tip_mm[k]);
        assert!(
            (w.orientation_rad[k] - beta).abs() < 1e-9,
            "{k}: {}",
            w.orientation_rad[k]
        );
        assert!((w.foot[k].u - pose.p.x / 0.1).abs() < 1e-9);
    }
}

#[test]
fn circle_error_equals_the_offset_on_the_reference_curve() {
    // Truth: a circle of radius R sampled every Δφ; an actual on radius R + δ is δ from the
    // circle. The chord polygon through the samples would give between δ and
    // δ + R (1 − cos(Δφ/2)) (25 nm here); the curve through them (docs/contour.md#the-foot-on-the-curve)
    // follows the circle to 0.05 pm, so the error is δ within 1 pm.
    let (radius, delta, n) = (20.0, 0.01, 2000);
    let dphi = TAU / n as f64;
    let at = |phi: f64, rr: f64| {
        Pose::new(
            Vector3::new(rr * phi.cos(), rr * phi.sin(), 0.0),
            Vector3::z(),
        )
    };
    let r: Vec<Pose> = (0..=n).map(|k| at(k as f64 * dphi, radius)).collect();
    let a: Vec<Pose> = (0..n)
        .map(|k| at((k as f64 - 7.3).max(0.0) * dphi, radius + delta))
        .collect();
    let (w, _) = assert_same_as_oracle(&r, &a);
    for (k, e) in w.tip_mm.iter().enumerate() {
        assert!((e - delta).abs() <= 1e-9, "{k}: {e} mm");
    }
}

#[test]
fn orientation_at_the_foot_has_no_jumps_at_reference_samples() {
    // Truth: a circle of radius R sampled every Δφ, the reference tool axis a smooth function
    // of φ (tilted β, its azimuth turning three times as fast as φ). An actual tip δ inside the
    // circle at angle φ whose tool axis is the reference's at φ has zero orientation contour
    // error: its nearest point of the circle is at the same φ. From inside a bend the nearest
    // point of the chord polygon jumps by about δ/R of a sample as the tip passes each sample
    // (the tool axis turns 3 sin β Δφ per sample), which the orientation taken there shows;
    // the foot on the curve does not jump.
    let (radius, delta, n, beta) = (20.0, 0.45, 2000, 0.5f64);
    let dphi = TAU / n as f64;
    let axis = |phi: f64| {
        Vector3::new(
            beta.sin() * (3.0 * phi).cos(),
            beta.sin() * (3.0 * phi).sin(),
            beta.cos(),
        )
    };
    let tip = |phi: f64, rr: f64| Vector3::new(rr * phi.cos(), rr * phi.sin(), 0.0);
    let r: Vec<Pose> = (0..=n)
        .map(|k| Pose::new(tip(k as f64 * dphi, radius), axis(k as f64 * dphi)))
        .collect();
    // Actual samples between the reference's, at 0.37 of a sample's spacing.
    let phis: Vec<f64> = (40..n - 40).map(|k| k as f64 * 0.37 * dphi).collect();
    let a: Vec<Pose> = phis
        .iter()
        .map(|&phi| Pose::new(tip(phi, radius - delta), axis(phi)))
        .collect();
    let (w, _) = assert_same_as_oracle(&r, &a);
    let worst = w.orientation_max_rad;
    // 0.1 µrad: the tool axis is interpolated by the same cubic (0.005 µrad measured; the
    // great-circle interpolation between samples alone would cut the cone by 4.7 µrad).
    assert!(worst < 1e-7, "orientation error {} mrad", worst * 1e3);
    for (k, e) in w.tip_mm.iter().enumerate() {
        assert!((e - delta).abs() <= 1e-9, "{k}: {e} mm");
    }
    // The same on the chord polygon (its nearest point by brute force, the tool axis
    // interpolated linearly there): jumps of about 3 sin β Δφ δ/R ≈ 0.1 mrad.
    let polygon_worst = a
        .iter()
        .map(|q| {
            let (mut best, mut best_o) = (f64::INFINITY, Vector3::z());
            for j in 0..n {
                let (pa, pb) = (r[j].p, r[j + 1].p);
                let ab = pb - pa;
                let t = ((q.p - pa).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                let d = (q.p - (pa + ab * t)).norm();
                if d < best {
                    best = d;
                    best_o = (r[j].o * (1.0 - t) + r[j + 1].o * t).normalize();
                }
            }
            vcnc_contour::orientation_error(&q.o, &best_o)
        })
        .fold(0.0, f64::max);
    assert!(polygon_worst > 5e-5, "{} mrad", polygon_worst * 1e3);
}

#[test]
fn contour_error_is_not_the_same_index_error() {
    // On the lagging spiral the same-index distance is the lag (≈ 0.3 mm), the contour error
    // only the µm offset: the report must hold the latter.
    let spiral = Spiral::new();
    let r = reference(&spiral, None, 0);
    let a = actual(&spiral, None, r.len(), 4e-3, 0.0, 0.0);
    let w = ok(contour_errors(&r, &a));
    let same_index = r
        .iter()
        .zip(&a)
        .map(|(p, q)| (p.p - q.p).norm())
        .fold(0.0, f64::max);
    assert!(same_index > 0.29, "{same_index}");
    assert!(w.tip_max_mm < 2e-3, "{}", w.tip_max_mm);
}

#[test]
fn rest_only_and_single_sample_references() {
    let p = Pose::new(Vector3::new(1.0, 2.0, 3.0), Vector3::z());
    let q = Pose::new(Vector3::new(1.0, 2.0, 3.004), Vector3::new(0.001, 0.0, 1.0));
    for r in [vec![p], vec![p; 100]] {
        let (w, _) = assert_same_as_oracle(&r, &[q, p, q]);
        assert!((w.tip_mm[0] - 0.004).abs() < 1e-12);
        assert_eq!(w.tip_mm[1], 0.0);
        assert!((w.orientation_rad[0] - 0.001f64.atan()).abs() < 1e-12);
        assert!(w.foot.iter().all(|f| f.u == 0.0));
    }
}

#[test]
fn bad_inputs_are_typed_errors() {
    let p = Pose::default();
    assert_eq!(
        contour_errors(&[], &[p]),
        Err(Error::Empty(Sequence::Reference))
    );
    assert_eq!(
        contour_errors(&[p], &[]),
        Err(Error::Empty(Sequence::Actual))
    );
    assert_eq!(
        contour_errors_brute_force(&[p], &[]),
        Err(Error::Empty(Sequence::Actual))
    );
    let nan = Pose::new(Vector3::new(0.0, f64::NAN, 0.0), Vector3::z());
    let e = contour_errors(&[p, nan], &[p]);
    assert!(
        matches!(
            e,
            Err(Error::NonFinite {
                which: Sequence::Reference,
                sample: 1,
                ..
            })
        ),
        "{e:?}"
    );
    let zero = Pose::new(Vector3::zeros(), Vector3::zeros());
    let e = contour_errors(&[p, p], &[p, p, zero]);
    assert!(
        matches!(
            e,
            Err(Error::ZeroOrientation {
                which: Sequence::Actual,
                sample: 2,
                ..
            })
        ),
        "{e:?}"
    );
    let bad = SearchWindow {
        min_margin: 0,
        ..SearchWindow::default()
    };
    assert!(matches!(
        contour_errors_with(&[p], &[p], &bad),
        Err(Error::BadWindow { .. })
    ));
    let bad = SearchWindow {
        reach_factor: f64::NAN,
        ..SearchWindow::default()
    };
    assert!(matches!(
        contour_errors_with(&[p], &[p], &bad),
        Err(Error::BadWindow { .. })
    ));
}

#[test]
fn orientation_error_is_accurate_at_small_and_large_angles() {
    let z = Vector3::z();
    for ang in [1e-9, 1e-6, 0.3, 3.0, std::f64::consts::PI - 1e-9] {
        let o = Vector3::new(ang.sin(), 0.0, ang.cos());
        let e = orientation_error(&o, &z);
        assert!((e - ang).abs() < 1e-15 * ang.max(1.0) * 4.0, "{ang}: {e}");
    }
}

#[test]
fn same_input_gives_bit_identical_output() {
    let spiral = Spiral::new();
    let r = reference(&spiral, Some((200.0, 0.05)), 0);
    let a = low_pass(&r, 0.3);
    assert_eq!(ok(contour_errors(&r, &a)), ok(contour_errors(&r, &a)));
}

/// A smooth random space curve (sum of low-frequency sinusoids), sampled with random pauses
/// (repeated samples), and an actual copy delayed by `lag` samples with a µm-scale offset.
fn smooth_case(
    coef: [f64; 9],
    pauses: Vec<(usize, usize)>,
    lag: f64,
    offset_um: f64,
) -> (Vec<Pose>, Vec<Pose>) {
    let curve = |t: f64| {
        Vector3::new(
            coef[0] * (0.7 * t).sin() + coef[1] * (1.3 * t).cos() + 10.0 * t,
            coef[2] * (0.9 * t).sin() + coef[3] * (0.4 * t).cos(),
            coef[4] * (0.5 * t).sin() + coef[5] * t,
        )
    };
    let axis = |t: f64| {
        Vector3::new(
            coef[6] * (0.3 * t).sin(),
            coef[7] * (0.2 * t).cos(),
            1.0 + coef[8],
        )
        .normalize()
    };
    // Parameter samples with pauses.
    let mut ts = Vec::new();
    let mut t = 0.0;
    for k in 0..600 {
        for &(at, len) in &pauses {
            if at == k {
                ts.extend(std::iter::repeat_n(t, len));
            }
        }
        ts.push(t);
        t += 0.01;
    }
    let r: Vec<Pose> = ts.iter().map(|&t| Pose::new(curve(t), axis(t))).collect();
    let a: Vec<Pose> = (0..ts.len())
        .map(|k| {
            let kk = (k as f64 - lag).clamp(0.0, (ts.len() - 1) as f64);
            let (i, f) = (kk.floor() as usize, kk.fract());
            let t = ts[i] + f * (ts[(i + 1).min(ts.len() - 1)] - ts[i]);
            let off = Vector3::new((3.0 * t).sin(), (2.0 * t).cos(), 0.5) * (offset_um * 1e-3);
            Pose::new(
                curve(t) + off,
                (axis(t) + Vector3::new(1e-4, 0.0, 0.0)).normalize(),
            )
        })
        .collect();
    (r, a)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Windowed = brute force on random smooth curves with pauses, lags from −10 to +40
    /// samples and offsets up to 50 µm.
    #[test]
    fn windowed_equals_brute_force_on_random_smooth_paths(
        coef in proptest::array::uniform9(-5.0..5.0f64),
        pauses in proptest::collection::vec((0usize..600, 1usize..80), 0..4),
        lag in -10.0..40.0f64,
        offset_um in 0.0..50.0f64,
    ) {
        let (r, a) = smooth_case(coef, pauses, lag, offset_um);
        assert_same_as_oracle(&r, &a);
    }
}
