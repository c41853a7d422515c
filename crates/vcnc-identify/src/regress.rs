//! Regressors of the equation-error model and their Gram matrix (paper eqs. 7–10 and 16–19,
//! corrected in docs/identification.md).
//!
//! The time-domain model is the inverse Laplace transform of the closed-loop model, integrated
//! once and divided by $a_2$:
//! $$ x_k = \alpha_3 E_k - \alpha_1 \dot x_k - \alpha_2 \ddot x_k + \beta_0 x_{r,k} + \beta_1 \dot x_{r,k} + \beta_2 \ddot x_{r,k} - \delta\,\mathrm{sgn}(\dot x_k), $$
//! $$ \alpha_3 = \frac{a_3}{a_2},\ \alpha_1 = \frac{a_1}{a_2},\ \alpha_2 = \frac{1}{a_2},\ \beta_0 = \frac{b_2}{a_2},\ \beta_1 = \frac{b_1}{a_2},\ \beta_2 = \frac{b_0}{a_2},\ \delta = \frac{d_c}{a_2}. $$
//! The paper's eq. 18 drops $\zeta$ from $\Theta_1$; the correct forms (docs/identification.md) are
//! $$ \alpha_3 = \frac{p\,\omega_n^2}{\omega_n^2 + 2\zeta\omega_n p},\quad \alpha_1 = \frac{p + 2\zeta\omega_n}{\omega_n^2 + 2\zeta\omega_n p},\quad \alpha_2 = \frac{1}{\omega_n^2 + 2\zeta\omega_n p}. $$
//!
//! Numerics (docs/identification.md): the trace is shifted so that it starts at 0; $x$ and $x_r$ pass the
//! zero-phase prefilter $L$ once, and every column is computed from the filtered signals
//! ($L$ commutes with central differences and with the trapezoidal integral, which are LTI too,
//! so this equals filtering each column up to the ends, and costs three interleaved filter
//! recursions instead of eight); the sign is decided with the deadband on a central difference
//! of the position over about a quarter period of the cutoff, and the sign column is then
//! filtered by the same $L$ (the friction input of the filtered ODE is $L\,\mathrm{sgn}$, not
//! $\mathrm{sgn}\,L$); $E$ uses the trapezoidal rule; the first and last few samples, where the
//! filter's end padding acts, are left out of the sums.
//!
//! Y is the measured position minus the reference, $x - x_r = -e$, with $\beta_0 - 1$ in place of
//! $\beta_0$: the same regression, but the sums of squares are those of the tracking error
//! (about 0.5 mm) instead of the position (tens of mm), so no digits are lost to cancellation in
//! the cost.
//!
//! Why no dense linear-algebra crate for the O(N) part: the only quantity every later stage
//! needs is the 9×9 symmetric Gram matrix of $[\Phi_1\ \Phi_2\ 1\ Y]$. Each row is computed on the
//! fly from three filtered signals and folded into the upper triangle in the same loop, so the
//! N×8 regressor matrix is never stored; nalgebra is used only for the small (≤ 8×8) solves.

use nalgebra::{DMatrix, DVector};
use vcnc_drive::{ClosedLoopModel, Poles};

use crate::Error;
use crate::filter::Butterworth2;
use crate::options::{IdentifyOptions, StartCondition};
use crate::pso::CostFunction;
use crate::trace::Trace;

/// Columns of the regressor row, in order: $[E, -\dot x, -\ddot x, x_r, \dot x_r, \ddot x_r, -L\,\mathrm{sgn}\dot x, 1]$, then $Y$.
pub const COLUMN_NAMES: [&str; 9] = ["E", "-v", "-a", "xr", "vr", "ar", "-sgn(v)", "1", "Y"];

/// Row length (regressors plus Y).
const NC: usize = 9;
/// Index of Y in the row.
const IY: usize = 8;
/// Index of the constant column (used only when the trace starts moving).
const IC: usize = 7;

/// The paper's parameter vector $\Theta = [\alpha_3, \alpha_1, \alpha_2, \beta_0, \beta_1, \beta_2, \delta]$
/// (paper eq. 17; $\Theta_1$ the first three, $\Theta_2$ the rest).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Theta {
    /// $\alpha_3 = a_3/a_2$, 1/s.
    pub alpha3: f64,
    /// $\alpha_1 = a_1/a_2$, s.
    pub alpha1: f64,
    /// $\alpha_2 = 1/a_2$, s².
    pub alpha2: f64,
    /// $\beta_0 = b_2/a_2$, dimensionless.
    pub beta0: f64,
    /// $\beta_1 = b_1/a_2$, s.
    pub beta1: f64,
    /// $\beta_2 = b_0/a_2$, s².
    pub beta2: f64,
    /// $\delta = d_c/a_2$, axis units.
    pub delta: f64,
}

impl Theta {
    /// $\Theta_1$ of the poles (docs/identification.md, corrected eq. 18), rad/s.
    pub fn theta1(poles: &Poles) -> [f64; 3] {
        let (a1, a2, a3) = poles.denominator();
        [a3 / a2, a1 / a2, 1.0 / a2]
    }

    /// De-normalised model (paper eq. 8 inverted): $a_2 = 1/\alpha_2$, then the rest times $a_2$.
    /// Non-finite when $\alpha_2 = 0$.
    pub fn to_model(&self) -> ClosedLoopModel {
        let a2 = 1.0 / self.alpha2;
        ClosedLoopModel {
            a1: self.alpha1 * a2,
            a2,
            a3: self.alpha3 * a2,
            b0: self.beta2 * a2,
            b1: self.beta1 * a2,
            b2: self.beta0 * a2,
            dc: self.delta * a2,
        }
    }

    /// Normalised parameters of a model (paper eq. 8).
    pub fn from_model(m: &ClosedLoopModel) -> Theta {
        Theta {
            alpha3: m.a3 / m.a2,
            alpha1: m.a1 / m.a2,
            alpha2: 1.0 / m.a2,
            beta0: m.b2 / m.a2,
            beta1: m.b1 / m.a2,
            beta2: m.b0 / m.a2,
            delta: m.dc / m.a2,
        }
    }

    /// Coefficients of the row $[E, -\dot x, -\ddot x, x_r, \dot x_r, \ddot x_r, -\mathrm{sgn}]$
    /// for Y = $x - x_r$ (so $\beta_0 - 1$ on $x_r$).
    fn row_coefficients(&self) -> [f64; 7] {
        [
            self.alpha3,
            self.alpha1,
            self.alpha2,
            self.beta0 - 1.0,
            self.beta1,
            self.beta2,
            self.delta,
        ]
    }
}

/// Prepared signals and the Gram matrix of one trace: the O(N) pass of the identification.
#[derive(Debug, Clone)]
pub struct Regressors {
    /// Sample period, s.
    pub ts: f64,
    /// Initial measured position subtracted from both signals, axis units.
    pub x0: f64,
    /// Prefilter cutoff used, Hz (`None` when the prefilter is off).
    pub cutoff_hz: Option<f64>,
    /// Sign deadband used, axis units/s.
    pub deadband: f64,
    /// Whether the constant column (unknown integration constant of a moving start) is used.
    pub intercept: bool,
    /// Filtered $x - x_0$, axis units.
    pub(crate) xf: Vec<f64>,
    /// Filtered $x_r - x_0$, axis units.
    pub(crate) xrf: Vec<f64>,
    /// Filtered sign $L\,\mathrm{sgn}(\dot x)$.
    pub(crate) sf: Vec<f64>,
    /// Rows used: `first..last`.
    pub(crate) first: usize,
    pub(crate) last: usize,
    /// Raw Gram matrix (upper triangle filled, then mirrored) of the rows.
    gram: [[f64; NC]; NC],
}

impl Regressors {
    /// Builds the prefiltered signals and the Gram matrix (one O(N) pass).
    ///
    /// Errors: invalid options, a regressor column that is zero over the whole run (for example
    /// the sign column when the speed never leaves the deadband).
    pub fn build(trace: &Trace, opts: &IdentifyOptions) -> Result<Regressors, Error> {
        opts.validate()?;
        let n = trace.len();
        let ts = trace.ts;
        let x0 = trace.x.first().copied().unwrap_or(0.0);
        let intercept = match opts.start {
            StartCondition::Rest => false,
            StartCondition::Moving => true,
            StartCondition::Auto => !trace.starts_at_rest(opts.deadband),
        };
        let xf: Vec<f64> = trace.x.iter().map(|v| v - x0).collect();
        let xrf: Vec<f64> = trace.xr.iter().map(|v| v - x0).collect();
        let (filter, cutoff_hz) = if opts.prefilter.enabled {
            let fc = opts.prefilter.cutoff_for(ts);
            (Some(Butterworth2::new(fc, ts)?), Some(fc))
        } else {
            (None, None)
        };
        // Sign of the velocity, decided on a wide central difference of the raw position,
        // (x_{k+m} - x_{k-m}) / (2 m Ts) with m about a quarter period of the cutoff: about as
        // smooth as the prefiltered velocity, and known before the filter runs, so that the
        // three signals share one interleaved filter pass. The sign column is then filtered by
        // the same L as the others.
        let m = cutoff_hz.map_or(1, |fc| ((0.25 / (fc * ts)).round() as usize).max(1));
        let inv = 1.0 / (2.0 * m as f64 * ts);
        let mut sgn = vec![0.0; n];
        for (k, sg) in sgn.iter_mut().enumerate() {
            if let (Some(km), Some(xp)) = (k.checked_sub(m), trace.x.get(k + m)) {
                *sg = vcnc_drive::model::friction_sign((xp - trace.x[km]) * inv, opts.deadband);
            }
        }
        let (mut xf, mut xrf, mut sf) = (xf, xrf, sgn);
        if let Some(f) = &filter {
            f.filtfilt_many_in_place([&mut xf, &mut xrf, &mut sf]);
        }
        let margin = filter.map_or(2, |f| f.pad / 2 + 2);
        if n < 2 * margin + crate::trace::MIN_SAMPLES / 2 {
            return Err(Error::TooFewSamples {
                got: n,
                needed: 2 * margin + crate::trace::MIN_SAMPLES / 2,
            });
        }
        let r = Regressors {
            ts,
            x0,
            cutoff_hz,
            deadband: opts.deadband,
            intercept,
            xf,
            xrf,
            sf,
            first: margin,
            last: n - margin,
            gram: [[0.0; NC]; NC],
        };
        // One sequential pass: the other core is better spent elsewhere (it is usually busy on
        // a shared machine, and a join would wait for it).
        let mut g = r.gram_of(r.first, r.last);
        for i in 1..NC {
            let (upper, lower) = g.split_at_mut(i);
            for (j, row) in upper.iter().enumerate() {
                lower[0][j] = row[i];
            }
        }
        let r = Regressors { gram: g, ..r };
        for j in r.columns() {
            if !(r.gram[j][j] > 0.0 && r.gram[j][j].is_finite()) {
                return Err(Error::ZeroRegressor {
                    column: COLUMN_NAMES[j],
                    hint: match j {
                        6 => {
                            "the speed never leaves the sign deadband; lower `deadband` or move faster"
                        }
                        5 | 2 => "no acceleration: the run needs moves that start and stop",
                        _ => "the axis does not move",
                    },
                });
            }
        }
        Ok(r)
    }

    /// Calls `f` with every used row $[E, -\dot x, -\ddot x, x_r, \dot x_r, \ddot x_r, -L\mathrm{sgn}, 1, Y]$
    /// in order, computing it on the fly from the filtered signals.
    pub(crate) fn for_each_row(&self, f: impl FnMut(&[f64; NC])) {
        self.for_each_row_in(self.first, self.last, f);
    }

    /// [`Regressors::for_each_row`] over the rows `lo..hi` (clamped to the used rows).
    fn for_each_row_in(&self, lo: usize, hi: usize, mut f: impl FnMut(&[f64; NC])) {
        let (xf, xrf, sf) = (&self.xf[..], &self.xrf[..], &self.sf[..]);
        let n = xf.len().min(xrf.len()).min(sf.len());
        let (inv2, inv_sq) = (0.5 / self.ts, 1.0 / (self.ts * self.ts));
        let lo = lo.max(self.first).max(1);
        let hi = hi.min(self.last).min(n.saturating_sub(1));
        // E_k, the trapezoidal integral of the filtered x_r - x from the first sample (docs/identification.md;
        // the paper's rectangle sum biases p by +4 %), accumulated as the rows go
        // (not stored: one array less to allocate and fill); the same additions in the same
        // order for any `lo`.
        let h2 = 0.5 * self.ts;
        let step = |k: usize| h2 * ((xrf[k - 1] - xf[k - 1]) + (xrf[k] - xf[k]));
        let mut e = 0.0;
        for k in 1..lo.min(n) {
            e += step(k);
        }
        for k in lo..hi {
            e += step(k);
            let (xm, xk, xp) = (xf[k - 1], xf[k], xf[k + 1]);
            let (rm, rk, rp) = (xrf[k - 1], xrf[k], xrf[k + 1]);
            f(&[
                e,
                -(xp - xm) * inv2,
                -(xp - 2.0 * xk + xm) * inv_sq,
                rk,
                (rp - rm) * inv2,
                (rp - 2.0 * rk + rm) * inv_sq,
                -sf[k],
                1.0,
                xk - rk,
            ]);
        }
    }

    /// Upper triangle of the Gram matrix of the rows `lo..hi`. Rows are gathered into blocks
    /// (column-major) and the used columns are taken two by two: each 2×2 tile of column pairs
    /// is reduced over a block with independent partial sums, so that every value loaded serves
    /// two products and the accumulators stay in registers (about five times faster than
    /// updating the triangle row by row). The constant column is only summed when it is used
    /// (a trace that starts moving).
    fn gram_of(&self, lo: usize, hi: usize) -> [[f64; NC]; NC] {
        // Used columns, padded to an even count with the all-zero row `NC` of the block.
        let mut cols = [NC; NC + 1];
        let mut used = 0;
        for c in (0..NC).filter(|&c| self.intercept || c != IC) {
            cols[used] = c;
            used += 1;
        }
        let groups = used.div_ceil(2);
        let flush = |blk: &[[f64; BLOCK]; NC + 1], g: &mut [[f64; NC]; NC]| {
            for gi in 0..groups {
                let (i0, i1) = (cols[2 * gi], cols[2 * gi + 1]);
                for gj in gi..groups {
                    let (j0, j1) = (cols[2 * gj], cols[2 * gj + 1]);
                    let s = tile_sums(&blk[i0], &blk[i1], &blk[j0], &blk[j1]);
                    // On the diagonal tile (i1, j0) repeats (i0, j1) below the diagonal.
                    let pairs = [(i0, j0, 0), (i0, j1, 1), (i1, j0, 2), (i1, j1, 3)];
                    for (i, j, t) in pairs {
                        if i < NC && j < NC && (gi != gj || i <= j) {
                            g[i][j] += s[t];
                        }
                    }
                }
            }
        };
        let mut g = [[0.0; NC]; NC];
        let mut blk = [[0.0; BLOCK]; NC + 1];
        // The block is filled column by column straight from the filtered signals (the rows of
        // `for_each_row_in`; the test `fused_gram_equals_materialised_product` checks the sums
        // against an independent materialisation): each column is a short loop over contiguous
        // slices that the compiler vectorises.
        let (xf, xrf, sf) = (&self.xf[..], &self.xrf[..], &self.sf[..]);
        let n = xf.len().min(xrf.len()).min(sf.len());
        let (inv2, inv_sq) = (0.5 / self.ts, 1.0 / (self.ts * self.ts));
        let lo = lo.max(self.first).max(1);
        let hi = hi.min(self.last).min(n.saturating_sub(1)).max(lo);
        let h2 = 0.5 * self.ts;
        let mut e = 0.0;
        for k in 1..lo {
            e += h2 * ((xrf[k - 1] - xf[k - 1]) + (xrf[k] - xf[k]));
        }
        let mut k0 = lo;
        while k0 < hi {
            let len = (hi - k0).min(BLOCK);
            let (x, r) = (&xf[k0 - 1..k0 + len + 1], &xrf[k0 - 1..k0 + len + 1]);
            for q in 0..len {
                e += h2 * ((r[q] - x[q]) + (r[q + 1] - x[q + 1]));
                blk[0][q] = e;
            }
            for (q, v) in blk[1][..len].iter_mut().enumerate() {
                *v = -(x[q + 2] - x[q]) * inv2;
            }
            for (q, v) in blk[2][..len].iter_mut().enumerate() {
                *v = -(x[q + 2] - 2.0 * x[q + 1] + x[q]) * inv_sq;
            }
            blk[3][..len].copy_from_slice(&r[1..len + 1]);
            for (q, v) in blk[4][..len].iter_mut().enumerate() {
                *v = (r[q + 2] - r[q]) * inv2;
            }
            for (q, v) in blk[5][..len].iter_mut().enumerate() {
                *v = (r[q + 2] - 2.0 * r[q + 1] + r[q]) * inv_sq;
            }
            for (v, s) in blk[6][..len].iter_mut().zip(&sf[k0..k0 + len]) {
                *v = -s;
            }
            blk[IC][..len].fill(1.0);
            for (q, v) in blk[IY][..len].iter_mut().enumerate() {
                *v = x[q + 1] - r[q + 1];
            }
            if len < BLOCK {
                // Zero the unused tail so that the partial block adds nothing for it.
                for col in blk.iter_mut() {
                    col[len..].fill(0.0);
                }
            }
            flush(&blk, &mut g);
            k0 += len;
        }
        g
    }

    /// Indices of the regressor columns in use (7, or 8 with the constant).
    fn columns(&self) -> Vec<usize> {
        if self.intercept {
            (0..8).collect()
        } else {
            (0..7).collect()
        }
    }

    /// Indices of $\Phi_2$ (solved by least squares for each particle).
    fn phi2_columns(&self) -> Vec<usize> {
        if self.intercept {
            vec![3, 4, 5, 6, IC]
        } else {
            vec![3, 4, 5, 6]
        }
    }

    /// Number of rows in the sums.
    pub fn samples_used(&self) -> usize {
        self.last.saturating_sub(self.first)
    }

    /// Raw Gram matrix of $[E, -\dot x, -\ddot x, x_r, \dot x_r, \ddot x_r, -L\mathrm{sgn}, 1, Y]$
    /// over the used rows.
    pub fn gram(&self) -> &[[f64; NC]; NC] {
        &self.gram
    }

    /// Column scale $s_j = 1/\sqrt{G_{jj}}$ (unit-norm columns; docs/identification.md: scaling takes
    /// cond($\Phi_2$) from 3.4e3 to 3.2 on the Table 1 drive).
    fn scale(&self, j: usize) -> f64 {
        1.0 / self.gram[j][j].sqrt()
    }

    /// Column-scaled Gram submatrix over `rows × cols`.
    fn scaled(&self, rows: &[usize], cols: &[usize]) -> DMatrix<f64> {
        DMatrix::from_fn(rows.len(), cols.len(), |i, j| {
            let (a, b) = (rows[i], cols[j]);
            let sa = if a == IY { 1.0 } else { self.scale(a) };
            let sb = if b == IY { 1.0 } else { self.scale(b) };
            self.gram[a][b] * sa * sb
        })
    }

    /// 2-norm condition number of the column-scaled regressor matrix $\Phi S$ (all seven
    /// columns, plus the constant for a moving start): $\sqrt{\lambda_{max}/\lambda_{min}}$ of
    /// its Gram matrix. Infinite when rank-deficient.
    pub fn condition_number(&self) -> f64 {
        let c = self.columns();
        condition(&self.scaled(&c, &c))
    }

    /// Condition number of the column-scaled $\Phi_2$ (the per-particle least squares).
    pub fn condition_phi2(&self) -> f64 {
        let c = self.phi2_columns();
        condition(&self.scaled(&c, &c))
    }

    /// Checks that the data can identify the model: condition number of the scaled regressors
    /// at most `limit`.
    pub fn check_identifiable(&self, limit: f64) -> Result<f64, Error> {
        let condition = self.condition_number();
        if condition.is_nan() || condition > limit {
            return Err(Error::IllConditioned { condition, limit });
        }
        Ok(condition)
    }

    /// The equation-error cost of the paper (eq. 16) with $\Theta_2$ eliminated (eq. 19), ready
    /// for the swarm.
    pub fn equation_error_cost(&self) -> Result<EquationErrorCost, Error> {
        let i1 = [0usize, 1, 2];
        let i2 = self.phi2_columns();
        let g22 = self.scaled(&i2, &i2);
        let chol = g22.clone().cholesky().ok_or(Error::IllConditioned {
            condition: self.condition_phi2(),
            limit: f64::INFINITY,
        })?;
        let g21 = self.scaled(&i2, &i1);
        let g2y = self.scaled(&i2, &[IY]);
        let g11 = self.scaled(&i1, &i1);
        let g1y = self.scaled(&i1, &[IY]);
        let yy = self.gram[IY][IY];
        let x21 = chol.solve(&g21); // G22^-1 G21
        let x2y = chol.solve(&g2y); // G22^-1 g2y
        let m = &g11 - g21.transpose() * &x21;
        let q = &g1y - g21.transpose() * &x2y;
        let c0 = yy - (g2y.transpose() * &x2y)[(0, 0)];
        let mut mm = [[0.0; 3]; 3];
        let mut qq = [0.0; 3];
        let mut s1 = [0.0; 3];
        for i in 0..3 {
            qq[i] = q[(i, 0)];
            s1[i] = self.gram[i][i].sqrt();
            for j in 0..3 {
                mm[i][j] = m[(i, j)];
            }
        }
        Ok(EquationErrorCost {
            m: mm,
            q: qq,
            c0,
            inv_scale1: s1,
            x21,
            x2y,
            i2,
            scales: std::array::from_fn(|j| self.scale(j)),
        })
    }

    /// Unconstrained least squares of all seven parameters (plus the constant for a moving
    /// start) on the column-scaled normal equations. Returns $\Theta$, the intercept (axis units)
    /// and the cost $\tfrac12\|Y - \Phi\Theta\|^2$ (axis units²).
    pub fn least_squares(&self) -> Result<(Theta, f64, f64), Error> {
        let c = self.columns();
        let g = self.scaled(&c, &c);
        let gy = self.scaled(&c, &[IY]);
        let sol = g
            .clone()
            .cholesky()
            .map(|ch| ch.solve(&gy))
            .or_else(|| g.clone().lu().solve(&gy))
            .ok_or(Error::IllConditioned {
                condition: f64::INFINITY,
                limit: f64::INFINITY,
            })?;
        let th: Vec<f64> = c
            .iter()
            .enumerate()
            .map(|(i, &j)| sol[(i, 0)] * self.scale(j))
            .collect();
        let cost = 0.5 * (self.gram[IY][IY] - (gy.transpose() * &sol)[(0, 0)]).max(0.0);
        let intercept = if self.intercept {
            th.get(7).copied().unwrap_or(0.0)
        } else {
            0.0
        };
        Ok((
            Theta {
                alpha3: th[0],
                alpha1: th[1],
                alpha2: th[2],
                beta0: th[3] + 1.0,
                beta1: th[4],
                beta2: th[5],
                delta: th[6],
            },
            intercept,
            cost,
        ))
    }

    /// One-step (equation-error) prediction error of a model: RMS of
    /// $Y_k - \Phi_k \Theta$ over the used rows, axis units, with the constant (moving start)
    /// re-fitted as the mean residual.
    pub fn one_step_rms(&self, model: &ClosedLoopModel) -> f64 {
        let c = Theta::from_model(model).row_coefficients();
        let (mut s1, mut s2, mut n) = (0.0, 0.0, 0usize);
        self.for_each_row(|z| {
            let pred: f64 = (0..7).map(|j| c[j] * z[j]).sum();
            let r = z[IY] - pred;
            s1 += r;
            s2 += r * r;
            n += 1;
        });
        if n == 0 {
            return f64::NAN;
        }
        let nf = n as f64;
        let var = if self.intercept {
            s2 / nf - (s1 / nf).powi(2)
        } else {
            s2 / nf
        };
        var.max(0.0).sqrt()
    }
}

impl Regressors {
    /// Velocity sign over each sample interval, from the filtered position:
    /// $F_k = \mathrm{sgn}((x_{f,k+1} - x_{f,k})/T_s)$ with the deadband.
    pub(crate) fn interval_signs(&self) -> Vec<f64> {
        let n = self.xf.len();
        let inv = 1.0 / self.ts;
        (0..n)
            .map(|k| match self.xf.get(k + 1) {
                Some(xp) => {
                    vcnc_drive::model::friction_sign((xp - self.xf[k]) * inv, self.deadband)
                }
                None => 0.0,
            })
            .collect()
    }
}

/// Rows per block of the Gram pass.
const BLOCK: usize = 64;

/// The four sums $a_0\cdot b_0$, $a_0\cdot b_1$, $a_1\cdot b_0$, $a_1\cdot b_1$ over a block,
/// with four partial sums each (fixed lengths, so no bounds checks; kept out of line so that
/// its sixteen accumulators do not compete for registers with the caller's loop).
#[inline(never)]
#[allow(clippy::needless_range_loop)] // lane l of four products at once
fn tile_sums(
    a0: &[f64; BLOCK],
    a1: &[f64; BLOCK],
    b0: &[f64; BLOCK],
    b1: &[f64; BLOCK],
) -> [f64; 4] {
    let mut s = [[0.0; 4]; 4];
    for q in 0..BLOCK / 4 {
        for l in 0..4 {
            let i = 4 * q + l;
            s[0][l] += a0[i] * b0[i];
            s[1][l] += a0[i] * b1[i];
            s[2][l] += a1[i] * b0[i];
            s[3][l] += a1[i] * b1[i];
        }
    }
    s.map(|v| (v[0] + v[1]) + (v[2] + v[3]))
}

fn condition(g: &DMatrix<f64>) -> f64 {
    let ev = g.clone().symmetric_eigenvalues();
    let (lo, hi) = ev.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
        (lo.min(*v), hi.max(*v))
    });
    if lo <= 0.0 || !lo.is_finite() {
        f64::INFINITY
    } else {
        (hi / lo).sqrt()
    }
}

/// The paper's objective (eq. 16) as a function of the particle $\sigma = [p, \omega_n, \zeta]$
/// (frequencies in Hz), with $\Theta_2$ from the least-squares subproblem (eq. 19)
/// $\Theta_2 = (\Phi_2^T\Phi_2)^{-1}\Phi_2^T (Y - \Phi_1\Theta_1)$.
///
/// Eliminating $\Theta_2$ leaves a quadratic in $\Theta_1$ whose matrices follow from the Gram
/// matrix once (Schur complement): with column-scaled blocks,
/// $$ f = \tfrac12\left(c_0 - 2\,\hat\Theta_1^T q + \hat\Theta_1^T M \hat\Theta_1\right),\quad M = G_{11} - G_{12}G_{22}^{-1}G_{21},\quad q = g_{1y} - G_{12}G_{22}^{-1}g_{2y}, $$
/// $c_0 = y^Ty - g_{2y}^T G_{22}^{-1} g_{2y}$: each particle costs a few dozen flops,
/// independent of N (the same value as the 4×4 solve of eq. 19).
#[derive(Debug, Clone)]
pub struct EquationErrorCost {
    m: [[f64; 3]; 3],
    q: [f64; 3],
    c0: f64,
    /// $\sqrt{G_{jj}}$ of the three $\Phi_1$ columns (unscaled → scaled parameter).
    inv_scale1: [f64; 3],
    x21: DMatrix<f64>,
    x2y: DMatrix<f64>,
    i2: Vec<usize>,
    scales: [f64; NC],
}

impl EquationErrorCost {
    /// Cost $\tfrac12\|Y - \Phi\Theta\|^2$ (axis units²) at poles $\sigma$ = (p, ωn in Hz, ζ).
    #[inline]
    #[allow(clippy::needless_range_loop)] // 3×3 quadratic form
    pub fn cost_hz(&self, p_hz: f64, wn_hz: f64, zeta: f64) -> f64 {
        let t1 = Theta::theta1(&Poles::from_hz(p_hz, wn_hz, zeta));
        let t = [
            t1[0] * self.inv_scale1[0],
            t1[1] * self.inv_scale1[1],
            t1[2] * self.inv_scale1[2],
        ];
        let mut quad = 0.0;
        for i in 0..3 {
            let mut row = 0.0;
            for j in 0..3 {
                row += self.m[i][j] * t[j];
            }
            quad += t[i] * (row - 2.0 * self.q[i]);
        }
        let f = 0.5 * (self.c0 + quad);
        if f.is_finite() {
            f.max(0.0)
        } else {
            f64::INFINITY
        }
    }

    /// $\Theta$ at poles (Hz): $\Theta_1$ from eq. 18 (corrected), $\Theta_2$ from eq. 19. Also
    /// returns the intercept (axis units, 0 unless the trace starts moving).
    pub fn theta_hz(&self, p_hz: f64, wn_hz: f64, zeta: f64) -> (Theta, f64) {
        let t1 = Theta::theta1(&Poles::from_hz(p_hz, wn_hz, zeta));
        let t = DVector::from_fn(3, |i, _| t1[i] * self.inv_scale1[i]);
        let t2 = self.x2y.column(0) - &self.x21 * t;
        let un = |i: usize| t2[i] * self.scales[self.i2[i]];
        let intercept = if self.i2.len() > 4 { un(4) } else { 0.0 };
        (
            Theta {
                alpha3: t1[0],
                alpha1: t1[1],
                alpha2: t1[2],
                beta0: un(0) + 1.0,
                beta1: un(1),
                beta2: un(2),
                delta: un(3),
            },
            intercept,
        )
    }
}

impl CostFunction for EquationErrorCost {
    fn cost(&self, sigma: &[f64]) -> f64 {
        match sigma {
            [p, wn, zeta] => self.cost_hz(*p, *wn, *zeta),
            _ => f64::INFINITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support;
    use nalgebra::DMatrix;

    /// Rest-to-rest smooth moves with reversals, 1 ms.
    fn reference(n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        test_support::smooth_moves(n, &test_support::MOVES[..5])
    }

    fn table1() -> ClosedLoopModel {
        vcnc_drive::TABLE1_MODEL
    }

    fn model_trace(m: &ClosedLoopModel, n: usize) -> Trace {
        let (p, v, a) = reference(n);
        let x = test_support::follow(m, &p, &v, &a);
        Trace::new(1e-3, p, x).unwrap()
    }

    /// Independent materialisation of the regressor matrix: columns computed one by one with
    /// plain loops from the filtered signals (the oracle for the fused pass).
    fn materialise(r: &Regressors) -> DMatrix<f64> {
        let n = r.xf.len();
        let ts = r.ts;
        let mut e_int = vec![0.0; n];
        for k in 1..n {
            e_int[k] =
                e_int[k - 1] + 0.5 * ts * ((r.xrf[k - 1] - r.xf[k - 1]) + (r.xrf[k] - r.xf[k]));
        }
        let d1 = |s: &[f64], k: usize| (s[k + 1] - s[k - 1]) / (2.0 * ts);
        let d2 = |s: &[f64], k: usize| (s[k + 1] - 2.0 * s[k] + s[k - 1]) / (ts * ts);
        let rows: Vec<usize> = (r.first..r.last).collect();
        DMatrix::from_fn(rows.len(), NC, |i, j| {
            let k = rows[i];
            match j {
                0 => e_int[k],
                1 => -d1(&r.xf, k),
                2 => -d2(&r.xf, k),
                3 => r.xrf[k],
                4 => d1(&r.xrf, k),
                5 => d2(&r.xrf, k),
                6 => -r.sf[k],
                7 => 1.0,
                _ => r.xf[k] - r.xrf[k],
            }
        })
    }

    #[test]
    fn fused_gram_equals_materialised_product() {
        let tr = model_trace(&table1(), 2600);
        // At rest: 8 columns (the constant is only summed for a moving start); moving start:
        // all 9, an odd count that exercises the padding of the 2×2 tiles.
        for (start, intercept) in [
            (StartCondition::Rest, false),
            (StartCondition::Moving, true),
        ] {
            let opts = IdentifyOptions {
                start,
                ..Default::default()
            };
            let r = Regressors::build(&tr, &opts).unwrap();
            assert_eq!(r.intercept, intercept);
            let phi = materialise(&r);
            let g = phi.transpose() * &phi;
            let used: Vec<usize> = (0..NC).filter(|&j| intercept || j != IC).collect();
            for &i in &used {
                for &j in &used {
                    let scale = (g[(i, i)] * g[(j, j)]).sqrt();
                    assert!(
                        (r.gram()[i][j] - g[(i, j)]).abs() <= 1e-11 * scale,
                        "G[{i}][{j}] with {start:?}"
                    );
                }
            }
            // The rows streamed by `for_each_row` are the materialised rows.
            let mut k = 0;
            r.for_each_row(|z| {
                for (j, v) in z.iter().enumerate() {
                    assert!((v - phi[(k, j)]).abs() <= 1e-12 * (1.0 + phi[(k, j)].abs()));
                }
                k += 1;
            });
            assert_eq!(k, phi.nrows());
        }
    }

    #[test]
    fn particle_cost_equals_explicit_least_squares_subproblem() {
        // Oracle: paper eq. 19 solved by QR on the materialised matrices, eq. 16 evaluated.
        let tr = model_trace(&table1(), 2600);
        let r = Regressors::build(&tr, &IdentifyOptions::default()).unwrap();
        let cost = r.equation_error_cost().unwrap();
        let phi = materialise(&r);
        let y = phi.column(IY).into_owned();
        for &(p, wn, z) in &[(10.73, 30.57, 0.445), (3.0, 80.0, 1.2), (150.0, 12.0, 0.3)] {
            let t1 = Theta::theta1(&Poles::from_hz(p, wn, z));
            let phi1 = phi.columns(0, 3).into_owned();
            let phi2 = phi.columns(3, 4).into_owned();
            let rhs = &y - &phi1 * nalgebra::Vector3::new(t1[0], t1[1], t1[2]);
            let t2 = phi2.clone().svd(true, true).solve(&rhs, 1e-300).unwrap();
            let res = &rhs - &phi2 * &t2;
            let f = 0.5 * res.norm_squared();
            let fc = cost.cost_hz(p, wn, z);
            // The Schur-complement form loses about 1e-16 cond(Phi) |Y|^2 to rounding: a few
            // 1e-7 of a cost this small, far below what moves the poles.
            assert!((fc - f).abs() <= 2e-6 * f, "{fc} vs {f}");
            let (th, _) = cost.theta_hz(p, wn, z);
            assert!((th.beta0 - 1.0 - t2[0]).abs() <= 1e-6 * t2[0].abs().max(1e-9));
            assert!((th.delta - t2[3]).abs() <= 1e-6 * t2[3].abs().max(1e-12));
        }
    }

    #[test]
    fn theta_round_trips_through_the_model() {
        let m = table1();
        let back = Theta::from_model(&m).to_model();
        for (a, b) in [
            (m.a1, back.a1),
            (m.a2, back.a2),
            (m.a3, back.a3),
            (m.b1, back.b1),
            (m.b2, back.b2),
            (m.dc, back.dc),
        ] {
            assert!((a - b).abs() <= 1e-12 * a.abs());
        }
        // docs/identification.md's corrected eq. 18 against alpha = a/a2 of the same poles.
        let poles = m.poles().unwrap();
        let t1 = Theta::theta1(&poles);
        let th = Theta::from_model(&m);
        assert!((t1[0] - th.alpha3).abs() < 1e-9 * th.alpha3);
        assert!((t1[1] - th.alpha1).abs() < 1e-9 * th.alpha1);
        assert!((t1[2] - th.alpha2).abs() < 1e-9 * th.alpha2);
    }

    #[test]
    fn least_squares_recovers_a_model_from_its_own_simulation() {
        // Truth: the model that generated the data (noise-free, exact FOH simulation). The
        // equation error with central differences at 1 kHz is biased by O((w Ts)^2): about
        // 0.6 % at 30 Hz, so 2 % bounds the poles.
        let m = table1();
        let tr = model_trace(&m, 2600);
        let r = Regressors::build(&tr, &IdentifyOptions::default()).unwrap();
        let (th, _, _) = r.least_squares().unwrap();
        let est = th.to_model();
        let (pe, pt) = (est.poles().unwrap(), m.poles().unwrap());
        assert!(((pe.wn - pt.wn) / pt.wn).abs() < 0.02, "{pe:?} vs {pt:?}");
        assert!(((pe.p - pt.p) / pt.p).abs() < 0.02, "{pe:?} vs {pt:?}");
        assert!(
            ((pe.zeta - pt.zeta) / pt.zeta).abs() < 0.03,
            "{pe:?} vs {pt:?}"
        );
        // Column scaling keeps the per-particle subproblem well conditioned (docs/identification.md:
        // cond(Phi2) 3.4e3 unscaled, 3.2 scaled on its Table 1 run; 3.6 on this run) and the
        // whole regressor identifiable (about 8e2 here, the refusal limit is 1e6).
        let (c2, c) = (r.condition_phi2(), r.condition_number());
        assert!(c2 < 10.0, "cond(Phi2 S) = {c2}");
        assert!(c < 1e4, "cond(Phi S) = {c}");
    }

    #[test]
    fn zero_sign_column_is_reported_with_a_hint() {
        let tr = model_trace(&table1(), 2600);
        let opts = IdentifyOptions {
            deadband: 1e6,
            ..Default::default()
        };
        match Regressors::build(&tr, &opts) {
            Err(Error::ZeroRegressor {
                column: "-sgn(v)", ..
            }) => {}
            other => panic!("{other:?}"),
        }
    }
}
