//! Reducing long series to what a screen can show without losing a spike.
//!
//! A time series of 10⁶ samples drawn 900 px wide has over a thousand samples per pixel
//! column. Per column, the line a renderer draws through all samples touches exactly four of
//! them that matter: the first and last (where the line enters and leaves the column) and the
//! minimum and maximum (its vertical extent). Keeping those four per column (the M4 reduction of
//! Jugel et al., *M4: A Visualization-Oriented Time Series Data Aggregation*, VLDB 2014) draws
//! the same picture as all samples, so a one-sample spike is never lost. A Ramer–Douglas–Peucker
//! pass with a 0.15 px tolerance then drops points that lie on the straight line through their
//! neighbours (smooth stretches), which is invisible and shrinks the file further.

/// Indices of the samples to keep so that a line through them, drawn over `columns` pixel
/// columns spanning `x_range`, looks exactly like the line through all samples: per column the
/// first, minimum, maximum and last sample, in sample order.
///
/// `x` must be non-decreasing (a time or arc-length axis); samples with a non-finite `x` or
/// `y` are skipped. Returns all finite indices when there are fewer than four per column.
pub fn min_max_per_column(x: &[f64], y: &[f64], x_range: (f64, f64), columns: usize) -> Vec<usize> {
    let n = x.len().min(y.len());
    let finite = |k: usize| x[k].is_finite() && y[k].is_finite();
    if n <= 4 * columns.max(1) {
        return (0..n).filter(|&k| finite(k)).collect();
    }
    let (x0, x1) = x_range;
    let w = if x1 > x0 { x1 - x0 } else { 1.0 };
    let col = |v: f64| (((v - x0) / w) * columns as f64).floor() as i64;
    let mut out = Vec::with_capacity(4 * columns + 4);
    let mut k = 0;
    while k < n {
        if !finite(k) {
            k += 1;
            continue;
        }
        let c = col(x[k]);
        let (first, mut last, mut kmin, mut kmax) = (k, k, k, k);
        let mut j = k + 1;
        while j < n && (!finite(j) || col(x[j]) == c) {
            if finite(j) {
                last = j;
                if y[j] < y[kmin] {
                    kmin = j;
                }
                if y[j] > y[kmax] {
                    kmax = j;
                }
            }
            j += 1;
        }
        let mut idx = [first, kmin, kmax, last];
        idx.sort_unstable();
        for (i, &v) in idx.iter().enumerate() {
            if i == 0 || v != idx[i - 1] {
                out.push(v);
            }
        }
        k = j;
    }
    out
}

/// Ramer–Douglas–Peucker on pixel coordinates: keeps the ends and every point farther than
/// `tol_px` from the chord of the points around it.
pub(crate) fn simplify(pts: &[(f64, f64)], tol_px: f64) -> Vec<(f64, f64)> {
    let n = pts.len();
    if n < 3 {
        return pts.to_vec();
    }
    let mut keep = vec![false; n];
    keep[0] = true;
    keep[n - 1] = true;
    let mut stack = vec![(0usize, n - 1)];
    while let Some((a, b)) = stack.pop() {
        if b <= a + 1 {
            continue;
        }
        let (ax, ay) = pts[a];
        let (bx, by) = pts[b];
        let (dx, dy) = (bx - ax, by - ay);
        let len = (dx * dx + dy * dy).sqrt();
        let mut worst = (0.0f64, a);
        for (k, &(px, py)) in pts.iter().enumerate().take(b).skip(a + 1) {
            let d = if len > 0.0 {
                ((px - ax) * dy - (py - ay) * dx).abs() / len
            } else {
                ((px - ax).powi(2) + (py - ay).powi(2)).sqrt()
            };
            if d > worst.0 {
                worst = (d, k);
            }
        }
        if worst.0 > tol_px {
            keep[worst.1] = true;
            stack.push((a, worst.1));
            stack.push((worst.1, b));
        }
    }
    pts.iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(*p))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_one_sample_spike_in_a_million_survives() {
        let n = 1_000_000;
        let x: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let mut y: Vec<f64> = x.iter().map(|t| (t * 0.7).sin()).collect();
        y[654_321] = 40.0;
        y[123_457] = -35.0;
        let keep = min_max_per_column(&x, &y, (0.0, x[n - 1]), 900);
        assert!(keep.len() <= 4 * 901);
        assert!(keep.contains(&654_321));
        assert!(keep.contains(&123_457));
        assert_eq!(keep.first(), Some(&0));
        assert_eq!(keep.last(), Some(&(n - 1)));
        assert!(keep.windows(2).all(|w| w[0] < w[1]), "sample order kept");
    }

    #[test]
    fn every_column_keeps_its_extremes() {
        // Oracle: brute-force min and max per column equal those of the kept samples.
        let n = 50_000;
        let x: Vec<f64> = (0..n).map(|k| k as f64).collect();
        let y: Vec<f64> = (0..n).map(|k| ((k * 7919) % 1000) as f64 - 500.0).collect();
        let cols = 300;
        let keep = min_max_per_column(&x, &y, (0.0, (n - 1) as f64), cols);
        let col = |v: f64| ((v / (n - 1) as f64) * cols as f64).floor() as usize;
        let mut all = vec![(f64::INFINITY, f64::NEG_INFINITY); cols + 1];
        let mut kept = all.clone();
        for k in 0..n {
            let c = &mut all[col(x[k])];
            *c = (c.0.min(y[k]), c.1.max(y[k]));
        }
        for &k in &keep {
            let c = &mut kept[col(x[k])];
            *c = (c.0.min(y[k]), c.1.max(y[k]));
        }
        assert_eq!(all, kept);
    }

    #[test]
    fn non_finite_samples_are_skipped() {
        let x: Vec<f64> = (0..10_000).map(|k| k as f64).collect();
        let mut y = vec![1.0; 10_000];
        y[5] = f64::NAN;
        let keep = min_max_per_column(&x, &y, (0.0, 9999.0), 100);
        assert!(!keep.contains(&5));
    }

    #[test]
    fn simplification_keeps_corners_and_drops_collinear_points() {
        let mut pts: Vec<(f64, f64)> = (0..=100).map(|k| (k as f64, 0.0)).collect();
        pts.extend((1..=100).map(|k| (100.0, k as f64)));
        let s = simplify(&pts, 0.15);
        assert_eq!(s, vec![(0.0, 0.0), (100.0, 0.0), (100.0, 100.0)]);
    }
}
