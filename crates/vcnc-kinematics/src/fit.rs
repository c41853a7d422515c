//! Identifying a family's offsets from measured poses (docs/kinematics.md, "Fitting offsets").
//!
//! Every closed form's tool tip is affine in its offsets $\theta$ (six numbers: $r, d$ of a
//! table; $s_t, s_c$ of a head-head; $s_t, r$ of a head-table) at fixed joints:
//! $$ p_w(\theta) = p_w(0) + G\,\theta, \qquad G_{\cdot i} = p_w(e_i) - p_w(0), $$
//! so the offsets that best explain samples $(q_k, p_k)$ solve one linear least-squares problem,
//! $\min_\theta \sum_k \lVert p_w(0; q_k) + G(q_k)\,\theta - p_k \rVert^2$.
//!
//! Only four of the six numbers are determined: each offset is a point of a rotary axis, and a
//! point may slide along its axis. The fit pins one coordinate of each point to zero (the
//! canonical form) and solves for the other four:
//!
//! | family | pinned | determined |
//! |---|---|---|
//! | table-tilting | $r_z$ (the C point slides along Z), $d$ along the tilt axis | $r_x, r_y$ and $r + d$ across the tilt axis |
//! | head-head | $s_t$ along the tilt axis, $s_{c,z}$ | $s_t$ across the tilt axis, $s_{c,x}, s_{c,y}$ |
//! | head-table | $s_t$ along the tilt axis, $r_z$ | $s_t$ across the tilt axis, $r_x, r_y$ |

use nalgebra::{DMatrix, DVector, Vector3};

use crate::error::{Error, Result};
use crate::families::{HeadHead, HeadTable, TableTilting};
use crate::kinematics::Kinematics;
use crate::types::{Axes, Pose, Tilt};

/// Offsets fitted to samples ([`Kinematics::fit_offsets`]).
#[derive(Debug, Clone, PartialEq)]
pub struct OffsetFit {
    /// The family with the fitted offsets, in the canonical form (the pinned coordinates zero).
    pub kinematics: Kinematics,
    /// RMS of the tool-tip residual over the samples, mm.
    pub rms_mm: f64,
    /// Largest tool-tip residual, mm.
    pub max_mm: f64,
    /// Largest tool-axis residual (unit-vector difference): the offsets cannot change it, so a
    /// large value means the samples' joints follow other conventions than the family's.
    pub max_axis: f64,
    /// Number of offset combinations the samples determine (4 when the samples move every
    /// rotary axis enough; fewer means some offsets are still free, and were set to zero).
    pub rank: usize,
}

impl Kinematics {
    /// The six offsets of a closed five-axis family, mm: $(r, d)$, $(s_t, s_c)$ or $(s_t, r)$.
    fn offsets(&self) -> Option<[Vector3<f64>; 2]> {
        match self {
            Kinematics::TableTilting(m) => Some([m.r, m.d]),
            Kinematics::HeadHead(m) => Some([m.pivot, m.c_axis]),
            Kinematics::HeadTable(m) => Some([m.pivot, m.r]),
            Kinematics::Xyz(_) | Kinematics::Chain(_) => None,
        }
    }

    /// The indices (0..6, into the two offset vectors) of the coordinates that move no tip and
    /// are pinned to zero by the fit.
    fn pinned_offsets(&self) -> [usize; 2] {
        let along = |tilt: Tilt| match tilt {
            Tilt::A => 0,
            Tilt::B => 1,
        };
        match self {
            Kinematics::TableTilting(m) => [2, 3 + along(m.tilt)],
            Kinematics::HeadHead(m) => [along(m.tilt), 5],
            Kinematics::HeadTable(m) => [along(m.tilt), 5],
            Kinematics::Xyz(_) | Kinematics::Chain(_) => [0, 1],
        }
    }

    /// The same family with offsets `o` (mm).
    fn with_offset_values(&self, o: [Vector3<f64>; 2]) -> Kinematics {
        match self {
            Kinematics::TableTilting(m) => Kinematics::TableTilting(TableTilting {
                r: o[0],
                d: o[1],
                ..*m
            }),
            Kinematics::HeadHead(m) => Kinematics::HeadHead(HeadHead {
                pivot: o[0],
                c_axis: o[1],
                ..*m
            }),
            Kinematics::HeadTable(m) => Kinematics::HeadTable(HeadTable {
                pivot: o[0],
                r: o[1],
                ..*m
            }),
            other => other.clone(),
        }
    }

    /// Fits this family's offsets to `samples` of joints (mm, rad, in vcnc's conventions) and
    /// the tool poses they produced (mm, workpiece frame), by linear least squares; this
    /// value's own offsets are not used. A 3-axis machine has no offsets (only the residuals
    /// are reported); a chain's geometry is its URDF's (an error).
    pub fn fit_offsets(&self, samples: &[(Axes, Pose)]) -> Result<OffsetFit> {
        let fail = |reason: String| Error::Fit {
            family: self.family().to_string(),
            reason,
        };
        if samples
            .iter()
            .any(|(q, p)| !q.values().iter().chain(p.p.iter()).all(|v| v.is_finite()))
        {
            return Err(fail("a sample is not finite".into()));
        }
        let fitted = match (self, self.offsets()) {
            (Kinematics::Chain(_), _) => {
                return Err(fail(
                    "a chain's offsets are its URDF's joint origins".into(),
                ));
            }
            (_, None) => (self.clone(), 0),
            (_, Some(_)) => {
                if samples.len() < 3 {
                    return Err(fail(format!(
                        "{} samples given, at least 3 needed",
                        samples.len()
                    )));
                }
                let unit = |i: usize| {
                    let mut o = [Vector3::zeros(); 2];
                    o[i / 3][i % 3] = 1.0;
                    self.with_offset_values(o)
                };
                let zero = self.with_offset_values([Vector3::zeros(); 2]);
                let units: Vec<Kinematics> = (0..6).map(unit).collect();
                let n = samples.len();
                let mut g = DMatrix::zeros(3 * n, 6);
                let mut y = DVector::zeros(3 * n);
                for (k, (q, pose)) in samples.iter().enumerate() {
                    let p0 = zero.forward(q).p;
                    for (i, u) in units.iter().enumerate() {
                        let col = u.forward(q).p - p0;
                        for r in 0..3 {
                            g[(3 * k + r, i)] = col[r];
                        }
                    }
                    for r in 0..3 {
                        y[3 * k + r] = pose.p[r] - p0[r];
                    }
                }
                let pinned = self.pinned_offsets();
                let free: Vec<usize> = (0..6).filter(|i| !pinned.contains(i)).collect();
                let g = g.select_columns(free.iter());
                let svd = g.svd(true, true);
                let smax = svd.singular_values.max();
                let eps = smax * 1e-10;
                let rank = svd.singular_values.iter().filter(|s| **s > eps).count();
                let theta = svd.solve(&y, eps).map_err(|e| fail(e.to_string()))?;
                let mut o = [Vector3::zeros(); 2];
                for (k, &i) in free.iter().enumerate() {
                    o[i / 3][i % 3] = theta[k];
                }
                (self.with_offset_values(o), rank)
            }
        };
        let (kin, rank) = fitted;
        let (mut sum, mut max_mm, mut max_axis) = (0.0, 0.0f64, 0.0f64);
        for (q, pose) in samples {
            let f = kin.forward(q);
            let e = (f.p - pose.p).norm();
            sum += e * e;
            max_mm = max_mm.max(e);
            let o = pose.o.normalize();
            max_axis = max_axis.max((f.o - o).norm());
        }
        Ok(OffsetFit {
            kinematics: kin,
            rms_mm: (sum / samples.len().max(1) as f64).sqrt(),
            max_mm,
            max_axis,
            rank,
        })
    }
}
