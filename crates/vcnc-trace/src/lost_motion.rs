//! Lost motion (backlash) between an axis' two measuring systems, at the reversals of its
//! setpoint (see [`lost_motion`]).

use std::fmt;

use serde::{Deserialize, Serialize};
use vcnc_axis::{AxisName, Unit};

use crate::error::Error;
use crate::pair::{AxisTrace, UnitSource};

/// Share of the setpoint's range it must retreat from an extreme for a reversal to count.
pub const REVERSAL_HYSTERESIS: f64 = 0.005;

/// One reversal of the setpoint and the lost motion measured at it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Reversal {
    /// Time of the last setpoint sample at the extreme, s (file time).
    pub t_s: f64,
    /// The setpoint there, axis unit.
    pub position: f64,
    /// The new direction: +1 or −1.
    pub direction: i8,
    /// Lost motion $|\bar d_{j+1} - \bar d_j|$, axis unit.
    pub lost: f64,
}

/// The lost motion of one axis between the measuring system its setpoint refers to and the
/// other one ([`lost_motion`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LostMotion {
    /// The axis.
    pub axis: AxisName,
    /// Unit of every length here: mm or deg.
    pub unit: Unit,
    /// Where the unit came from (a Sinumerik trace states none: mm or deg assumed).
    pub unit_source: UnitSource,
    /// The actual position of the setpoint's measuring system (the direct scale for a
    /// Sinumerik `CmdPos2ndEnc` setpoint).
    pub actual: String,
    /// The actual position of the other system (the motor encoder).
    pub other: String,
    /// Median over the reversals, axis unit.
    pub median: f64,
    /// Smallest, axis unit.
    pub min: f64,
    /// Largest, axis unit.
    pub max: f64,
    /// The smallest retreat from an extreme that counts as a reversal, axis unit.
    pub hysteresis: f64,
    /// Every reversal, in time order.
    pub reversals: Vec<Reversal>,
}

/// The lost motion of `axis` at the reversals of its setpoint: how much one measuring system
/// moves while the other stands, when the direction changes (backlash of the ball screw, the
/// coupling and the nut, and the elastic wind-up that friction holds).
///
/// With $x$ the actual position of the setpoint's measuring system, $x_o$ the other one's, and
/// $$ d_k = x_k - x_{o,k}, $$
/// $d$ is constant while the axis moves one way (up to the offset of the two systems' zeros and
/// their slowly varying pitch errors) and changes by the lost motion $b$ when it turns. So:
///
/// 1. **Runs.** The setpoint $x_r$ is cut at its reversals: an extreme counts once $x_r$ has
///    retreated from it by more than $h$ = [`REVERSAL_HYSTERESIS`] of its range (noise and
///    creeping never count); a run ends at the last sample at its extreme, so the standstill
///    after a move belongs to the move.
/// 2. **Settled difference.** Per run $j$, $\bar d_j$ is the median of $d$ over the run's second
///    half, after the lost motion of the turn has been taken up.
/// 3. **Lost motion** at the reversal between runs $j$ and $j + 1$:
///    $b_j = |\bar d_{j+1} - \bar d_j|$; [`LostMotion`] holds each and their median, least and
///    largest.
///
/// This is the reversal value of ISO 230-2 taken between the two measuring systems of the
/// machine itself rather than against a laser interferometer. Refused: an axis with one
/// measuring system ([`Error::NoOtherSystem`]), a setpoint that never reverses
/// ([`Error::NoReversal`]).
pub fn lost_motion(axis: &AxisTrace) -> Result<LostMotion, Error> {
    let pv = &axis.provenance;
    let (Some(other), Some(other_use)) = (&axis.other_actual, &pv.other_actual) else {
        return Err(Error::NoOtherSystem {
            file: pv.file.clone(),
            axis: axis.axis,
        });
    };
    let xr = &axis.nominal;
    let (lo, hi) = xr
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    let h = (REVERSAL_HYSTERESIS * (hi - lo)).max(f64::MIN_POSITIVE);
    let ends = run_ends(xr, h);
    if ends.len() < 2 {
        return Err(Error::NoReversal {
            file: pv.file.clone(),
            axis: axis.axis,
            reversals: ends.len().saturating_sub(1),
            hysteresis: h,
        });
    }
    let d: Vec<f64> = axis.actual.iter().zip(other).map(|(x, o)| x - o).collect();
    // Runs: [0, e_0], (e_0, e_1], …, (e_last, n).
    let mut bounds: Vec<(usize, usize, i8)> = Vec::with_capacity(ends.len() + 1);
    let mut start = 0;
    for &(e, dir) in &ends {
        bounds.push((start, e + 1, dir));
        start = e + 1;
    }
    bounds.push((start, d.len(), -ends[ends.len() - 1].1));
    let settled: Vec<f64> = bounds
        .iter()
        .map(|&(a, b, _)| median(&d[a + (b - a) / 2..b.max(a + 1).min(d.len())]))
        .collect();
    let reversals: Vec<Reversal> = ends
        .iter()
        .enumerate()
        .map(|(j, &(e, dir))| Reversal {
            t_s: axis.t0_s + e as f64 * axis.ts_s,
            position: xr[e],
            direction: -dir,
            lost: (settled[j + 1] - settled[j]).abs(),
        })
        .collect();
    let lost: Vec<f64> = reversals.iter().map(|r| r.lost).collect();
    Ok(LostMotion {
        axis: axis.axis,
        unit: axis.unit,
        unit_source: pv.actual.unit_source,
        actual: pv.actual.name.clone(),
        other: other_use.name.clone(),
        median: median(&lost),
        min: lost.iter().copied().fold(f64::INFINITY, f64::min),
        max: lost.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        hysteresis: h,
        reversals,
    })
}

/// The index of the last sample at each extreme the setpoint turns at, with the direction it
/// was moving before (+1 up, −1 down).
fn run_ends(xr: &[f64], h: f64) -> Vec<(usize, i8)> {
    let mut ends = Vec::new();
    let Some(&first) = xr.first() else {
        return ends;
    };
    let (mut dir, mut ext, mut ext_k) = (0i8, first, 0usize);
    let (mut lo, mut hi) = (first, first);
    for (k, &v) in xr.iter().enumerate() {
        match dir {
            0 => {
                lo = lo.min(v);
                hi = hi.max(v);
                if v - lo > h {
                    (dir, ext, ext_k) = (1, v, k);
                } else if hi - v > h {
                    (dir, ext, ext_k) = (-1, v, k);
                }
            }
            _ => {
                let s = f64::from(dir);
                if s * (v - ext) >= 0.0 {
                    (ext, ext_k) = (v, k);
                } else if s * (ext - v) > h {
                    ends.push((ext_k, dir));
                    (dir, ext, ext_k) = (-dir, v, k);
                }
            }
        }
    }
    ends
}

/// The median (the mean of the two middle values for an even count); NaN for none.
fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

impl fmt::Display for LostMotion {
    /// `X: 5.00 µm (median of 59 reversals; 4.98 … 5.02 µm), 'direct' − 'motor'`: µm for
    /// linear axes, mdeg for rotary ones.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (k, u) = match self.unit {
            Unit::Mm => (1e3, "µm"),
            Unit::Deg => (1e3, "mdeg"),
        };
        write!(
            f,
            "{}: {:.2} {u} (median of {} reversal{}; {:.2} … {:.2} {u}), '{}' − '{}'",
            self.axis,
            self.median * k,
            self.reversals.len(),
            if self.reversals.len() == 1 { "" } else { "s" },
            self.min * k,
            self.max * k,
            self.actual,
            self.other
        )?;
        if self.unit_source == UnitSource::Assumed {
            write!(f, "; the file states no unit, {} assumed", self.unit)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reversals_need_a_retreat_beyond_the_hysteresis() {
        // Up to 1, a wobble of 0.001 (below h = 0.005), down to 0, up to 1.
        let xr = [0.0, 0.5, 1.0, 1.0, 0.999, 1.0, 0.5, 0.0, 0.0, 0.5, 1.0];
        assert_eq!(run_ends(&xr, 0.005), [(5, 1), (8, -1)]);
        assert!(run_ends(&[0.0, 0.0, 0.0], 0.005).is_empty());
        assert_eq!(median(&[3.0, 1.0, 2.0, 10.0]), 2.5);
    }
}
