//! Pairing of nominal and actual positions per axis (see [`pair`]).

use std::fmt;

use serde::{Deserialize, Serialize};
use vcnc_axis::{AxisName, Unit};

use crate::error::Error;
use crate::infer;
use crate::model::{AxisSource, Channel, ChannelRef, Format, Quantity, Trace};
use crate::units::{BaseUnit, TraceUnit};

/// What to do with lost samples inside the chosen channels.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum GapPolicy {
    /// Fail with [`Error::Gap`] (default).
    #[default]
    Refuse,
    /// Use the longest gap-free stretch.
    LongestSegment,
}

/// The caller's choice of channels for one axis.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct AxisMap {
    /// The axis.
    pub axis: AxisName,
    /// Its nominal (reference) position channel.
    pub nominal: ChannelRef,
    /// Its actual (measured) position channel.
    pub actual: ChannelRef,
}

/// Options of [`pair`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PairOptions {
    /// The axes wanted; empty: every axis that has a position channel (axes with only one of the
    /// two are then skipped and listed in [`Paired::skipped`]).
    pub axes: Vec<AxisName>,
    /// Explicit channel choices; an axis mapped here is wanted even if not in `axes`.
    pub map: Vec<AxisMap>,
    /// Unit of linear-axis positions where the file states none (default mm). Where the file
    /// states one, a different unit here is an error ([`Error::UnitConflict`]).
    pub linear_unit: Option<TraceUnit>,
    /// Unit of rotary-axis positions where the file states none (default deg).
    pub rotary_unit: Option<TraceUnit>,
    /// Lost samples: refuse, or use the longest gap-free stretch.
    pub gaps: GapPolicy,
}

impl PairOptions {
    /// Sets the unit for the axes of its kind: a length unit for linear axes, an angle unit for
    /// rotary axes. `false` (and no change) for any other unit.
    pub fn set_unit(&mut self, unit: TraceUnit) -> bool {
        match unit.to_base() {
            Some((BaseUnit::Mm, _)) => self.linear_unit = Some(unit),
            Some((BaseUnit::Deg, _)) => self.rotary_unit = Some(unit),
            _ => return false,
        }
        true
    }
}

/// Where the unit of a paired channel came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum UnitSource {
    /// Stated by the file.
    File,
    /// The file states none; given by the caller.
    Caller,
    /// Neither states one; the axis unit (mm or deg) was assumed.
    Assumed,
}

impl fmt::Display for UnitSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            UnitSource::File => "from the file",
            UnitSource::Caller => "given (the file states none)",
            UnitSource::Assumed => "assumed (neither the file nor the caller states one)",
        })
    }
}

/// One channel as used for an axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelUse {
    /// The channel's name.
    pub name: String,
    /// Line of its declaration.
    pub line: usize,
    /// Its file column.
    pub column: usize,
    /// How its axis was found.
    pub axis_source: AxisSource,
    /// The unit its values were read in.
    pub unit: TraceUnit,
    /// Where that unit came from.
    pub unit_source: UnitSource,
    /// Factor from that unit to the axis unit.
    pub factor: f64,
    /// Its own sample period, s.
    pub period_s: f64,
    /// Its own first sample time, s.
    pub t0_s: f64,
    /// Its sample count in the file.
    pub samples: usize,
}

/// The part of a gapped record that was used ([`GapPolicy::LongestSegment`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// Which stretch (0-based) of how many gap-free stretches.
    pub index: usize,
    /// Number of gap-free stretches.
    pub of: usize,
    /// Line of the file where the stretch starts (after its gap), or of the channel declaration
    /// for the first.
    pub line: usize,
}

/// How an [`AxisTrace`] was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The file.
    pub file: String,
    /// Its format.
    pub format: Format,
    /// The nominal position channel.
    pub nominal: ChannelUse,
    /// The actual position channel.
    pub actual: ChannelUse,
    /// The actual position of the axis' other measuring system, when the file has one (a
    /// Sinumerik trace with `ActPos1stEnc` and `ActPos2ndEnc`): [`AxisTrace::other_actual`].
    pub other_actual: Option<ChannelUse>,
    /// Whether the channels were interpolated onto a common grid (different time bases).
    pub resampled: bool,
    /// The stretch used, when samples were lost and [`GapPolicy::LongestSegment`] chose one.
    pub segment: Option<Segment>,
}

/// Nominal and actual position of one axis, ready for identification.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisTrace {
    /// The axis.
    pub axis: AxisName,
    /// Unit of [`AxisTrace::nominal`] and [`AxisTrace::actual`]: mm or deg.
    pub unit: Unit,
    /// Sample period $T_s$, s.
    pub ts_s: f64,
    /// Time of the first sample, s (file time).
    pub t0_s: f64,
    /// Nominal (reference) position $x_r$, axis unit.
    pub nominal: Vec<f64>,
    /// Actual (measured) position $x$, axis unit: the measuring system the setpoint refers to.
    pub actual: Vec<f64>,
    /// The actual position of the other measuring system, on the same grid, axis unit (the
    /// motor encoder when the setpoint is the direct scale's); `None` when the file has one
    /// system. Not identified: [`crate::lost_motion`] measures the lost motion between the two.
    pub other_actual: Option<Vec<f64>>,
    /// Channels, units, alignment.
    pub provenance: Provenance,
}

/// An axis with a position channel that could not be paired (only when axes were not named).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Skipped {
    /// The axis.
    pub axis: AxisName,
    /// Why.
    pub reason: String,
}

/// The result of [`pair`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Paired {
    /// The file.
    pub file: String,
    /// Its format.
    pub format: Format,
    /// One entry per axis, in axis order (X Y Z A B C).
    pub axes: Vec<AxisTrace>,
    /// Axes found with only one of the two position channels.
    pub skipped: Vec<Skipped>,
}

fn channel_list(trace: &Trace) -> Vec<String> {
    trace
        .channels
        .iter()
        .map(|c| {
            let axis = c.axis.map_or("-".to_string(), |a| a.to_string());
            format!("'{}' ({axis}, {})", c.name, c.quantity)
        })
        .collect()
}

impl Trace {
    /// The channel `r` names: a column number, or a name — exact, else the only one equal ignoring
    /// case, else the only one whose description is equal.
    pub fn find(&self, r: &ChannelRef) -> Option<&Channel> {
        match r {
            ChannelRef::Column(c) => self.channels.iter().find(|ch| ch.column == *c),
            ChannelRef::Name(n) => {
                let unique = |f: &dyn Fn(&Channel) -> bool| {
                    let mut it = self.channels.iter().filter(|c| f(c));
                    match (it.next(), it.next()) {
                        (Some(c), None) => Some(c),
                        _ => None,
                    }
                };
                self.channels
                    .iter()
                    .find(|c| c.name == *n)
                    .or_else(|| unique(&|c| c.name.eq_ignore_ascii_case(n)))
                    .or_else(|| unique(&|c| !c.description.is_empty() && c.description == *n))
            }
        }
    }
}

fn resolve<'t>(trace: &'t Trace, r: &ChannelRef) -> Result<&'t Channel, Error> {
    trace.find(r).ok_or_else(|| Error::UnknownChannel {
        file: trace.file.clone(),
        reference: r.to_string(),
        channels: channel_list(trace),
    })
}

/// The channel of `axis` and `quantity`: `Ok(None)` when there is none.
fn candidate(trace: &Trace, axis: AxisName, quantity: Quantity) -> Result<Option<&Channel>, Error> {
    let all: Vec<&Channel> = of_axis(trace, axis, quantity).collect();
    if all.len() <= 1 {
        return Ok(all.first().copied());
    }
    let motor: Vec<&Channel> = all
        .iter()
        .copied()
        .filter(|c| infer::words(&c.name).iter().any(|w| w == "motor"))
        .collect();
    if motor.len() == 1 {
        return Ok(Some(motor[0]));
    }
    Err(Error::Ambiguous {
        file: trace.file.clone(),
        axis,
        quantity,
        channels: all.iter().map(|c| c.name.clone()).collect(),
    })
}

fn of_axis(trace: &Trace, axis: AxisName, quantity: Quantity) -> impl Iterator<Item = &Channel> {
    trace
        .channels
        .iter()
        .filter(move |c| c.axis == Some(axis) && c.quantity == quantity)
}

fn with_system(c: &Channel) -> String {
    match c.measuring_system {
        Some(m) => format!("'{}' (measuring system {m})", c.name),
        None => format!("'{}'", c.name),
    }
}

/// The actual position for the setpoint `nominal`: of its measuring system when it names one,
/// else the only (or `motor`) candidate; and the actual position of the other measuring system.
fn actuals<'t>(
    trace: &'t Trace,
    axis: AxisName,
    nominal: &Channel,
) -> Result<(Option<&'t Channel>, Option<&'t Channel>), Error> {
    let Some(m) = nominal.measuring_system else {
        let actual = candidate(trace, axis, Quantity::ActualPosition)?;
        return Ok((actual, actual.and_then(|a| other_system(trace, axis, a))));
    };
    let mut same =
        of_axis(trace, axis, Quantity::ActualPosition).filter(|c| c.measuring_system == Some(m));
    match (same.next(), same.next()) {
        (Some(a), None) => Ok((Some(a), other_system(trace, axis, a))),
        (None, _) => {
            let actuals: Vec<String> = of_axis(trace, axis, Quantity::ActualPosition)
                .map(with_system)
                .collect();
            if actuals.is_empty() {
                return Ok((None, None));
            }
            Err(Error::NoActualOfSystem {
                file: trace.file.clone(),
                line: nominal.line,
                axis,
                setpoint: nominal.name.clone(),
                system: m,
                actuals,
            })
        }
        (Some(_), Some(_)) => Err(Error::Ambiguous {
            file: trace.file.clone(),
            axis,
            quantity: Quantity::ActualPosition,
            channels: of_axis(trace, axis, Quantity::ActualPosition)
                .filter(|c| c.measuring_system == Some(m))
                .map(|c| c.name.clone())
                .collect(),
        }),
    }
}

/// The one actual position of `axis` from another measuring system than `actual`'s.
fn other_system<'t>(trace: &'t Trace, axis: AxisName, actual: &Channel) -> Option<&'t Channel> {
    let m = actual.measuring_system?;
    let mut others = of_axis(trace, axis, Quantity::ActualPosition)
        .filter(|c| c.measuring_system.is_some_and(|o| o != m));
    match (others.next(), others.next()) {
        (Some(o), None) => Some(o),
        _ => None,
    }
}

/// With exactly one axis asked for and no channel of it, a file whose position channels have no
/// axis and share one axis number (or none) is that axis: a Sinumerik trace of one servo
/// without `--axis-map`, a text file with `pos_cmd`/`pos_fb` columns.
fn adopt_unnamed<'t>(trace: &'t Trace, opts: &PairOptions) -> std::borrow::Cow<'t, Trace> {
    use std::borrow::Cow;
    let [axis] = opts.axes[..] else {
        return Cow::Borrowed(trace);
    };
    let positions = || trace.channels.iter().filter(|c| c.quantity.is_position());
    let unnamed: Vec<usize> = trace
        .channels
        .iter()
        .enumerate()
        .filter(|(_, c)| c.quantity.is_position() && c.axis.is_none())
        .map(|(i, _)| i)
        .collect();
    let numbers_agree = unnamed
        .windows(2)
        .all(|w| trace.channels[w[0]].axis_number == trace.channels[w[1]].axis_number);
    if unnamed.is_empty()
        || !numbers_agree
        || opts.map.iter().any(|m| m.axis == axis)
        || positions().any(|c| c.axis == Some(axis))
    {
        return Cow::Borrowed(trace);
    }
    let mut t = trace.clone();
    for i in unnamed {
        t.channels[i].axis = Some(axis);
        t.channels[i].axis_source = Some(AxisSource::Caller);
    }
    Cow::Owned(t)
}

/// Pairs the nominal and actual position channels of each axis: per axis, on one time grid, in
/// axis units, what identification takes (docs/identification.md: the reference $x_r$ and the measured $x$,
/// sampled at $T_s$).
///
/// 1. **Choose.** For each axis asked for (default: every axis with a position channel), the
///    [`AxisMap`] given for it, else the channels whose inferred axis is it and whose quantity is
///    [`Quantity::NominalPosition`] / [`Quantity::ActualPosition`]. Of several candidates the one
///    with the word `motor` is taken (LinuxCNC `joint.N.motor-pos-cmd` over `joint.N.pos-cmd`: the
///    servo loop's own signals); otherwise several are an error. A setpoint of a named measuring
///    system ([`Channel::measuring_system`]: Sinumerik `CmdPos2ndEnc`, the direct scale's) is
///    paired with the actual position of that system (`ActPos2ndEnc`) — the loop closed on it —
///    and refused when the file has none ([`Error::NoActualOfSystem`]); the actual position of
///    the other system, when there is one, is kept as [`AxisTrace::other_actual`]. With one
///    `--axis` asked for and no channel of it, position channels without an axis that share one
///    axis number (or have none) are taken as that axis.
/// 2. **Convert.** Values are multiplied by the factor of the file's unit to the axis unit, mm
///    (X Y Z) or deg (A B C); see [`TraceUnit`]. Where the file states no unit, the caller's unit for
///    the axis kind decides ([`PairOptions::linear_unit`], [`PairOptions::rotary_unit`]), else mm
///    or deg is assumed; [`UnitSource`] records which.
/// 3. **Align.** Channels on one time base (same period, first time and gaps) are taken sample by
///    sample. Otherwise (TNCscope curves of different cycle times, TwinCAT groups with offsets,
///    Sinumerik signals starting at different records) both are linearly interpolated onto the
///    grid of the coarser period, $T_s = \max(T_\text{nom}, T_\text{act})$, over the time span
///    they share:
///    $$ t_k = t_\text{start} + k\,T_s, \qquad v(t) = v_i + \frac{t - t_i}{T}\,(v_{i+1} - v_i). $$
///    Positions of a drive are smooth at the servo rate, so no anti-alias filter is applied.
/// 4. **Gaps.** With [`GapPolicy::Refuse`] (the default) any lost samples in the chosen channels
///    are an error: the identification's regressors (integral of the error, derivatives) would
///    join the two sides of the gap as if contiguous. With [`GapPolicy::LongestSegment`] the
///    longest gap-free stretch both channels share is used, and [`Provenance::segment`] says
///    which part of how many.
pub fn pair(trace: &Trace, opts: &PairOptions) -> Result<Paired, Error> {
    let adopted = adopt_unnamed(trace, opts);
    let trace: &Trace = &adopted;
    let explicit = !opts.axes.is_empty() || !opts.map.is_empty();
    let mut wanted: Vec<AxisName> = if explicit {
        opts.axes
            .iter()
            .copied()
            .chain(opts.map.iter().map(|m| m.axis))
            .collect()
    } else {
        trace
            .channels
            .iter()
            .filter(|c| c.quantity.is_position())
            .filter_map(|c| c.axis)
            .collect()
    };
    wanted.sort();
    wanted.dedup();

    let mut axes = Vec::new();
    let mut skipped = Vec::new();
    for axis in wanted {
        let (nominal, actual, other) = match opts.map.iter().find(|m| m.axis == axis) {
            Some(m) => {
                let a = resolve(trace, &m.actual)?;
                (resolve(trace, &m.nominal)?, a, other_system(trace, axis, a))
            }
            None => {
                let n = candidate(trace, axis, Quantity::NominalPosition)?;
                let (a, other) = match n {
                    Some(n) => actuals(trace, axis, n)?,
                    None => (candidate(trace, axis, Quantity::ActualPosition)?, None),
                };
                match (n, a) {
                    (Some(n), Some(a)) => (n, a, other),
                    (n, _) => {
                        let quantity = if n.is_none() {
                            Quantity::NominalPosition
                        } else {
                            Quantity::ActualPosition
                        };
                        if explicit {
                            return Err(Error::MissingChannel {
                                file: trace.file.clone(),
                                axis,
                                quantity,
                                channels: channel_list(trace),
                            });
                        }
                        skipped.push(Skipped {
                            axis,
                            reason: format!("no {quantity} channel"),
                        });
                        continue;
                    }
                }
            }
        };
        let caller_map = opts.map.iter().any(|m| m.axis == axis);
        axes.push(pair_axis(
            trace,
            opts,
            axis,
            (nominal, actual, other),
            caller_map,
        )?);
    }
    if axes.is_empty() {
        if let Some(c) = trace
            .channels
            .iter()
            .find(|c| c.quantity.is_position() && c.axis.is_none())
        {
            return Err(Error::NoAxis {
                file: trace.file.clone(),
                line: c.line,
                channel: c.name.clone(),
                quantity: c.quantity,
                axis_number: c.axis_number,
            });
        }
        if let Some(s) = skipped.first() {
            let quantity = if s.reason.contains("nominal") {
                Quantity::NominalPosition
            } else {
                Quantity::ActualPosition
            };
            return Err(Error::MissingChannel {
                file: trace.file.clone(),
                axis: s.axis,
                quantity,
                channels: channel_list(trace),
            });
        }
        return Err(Error::NoPositions {
            file: trace.file.clone(),
            channels: channel_list(trace),
        });
    }
    Ok(Paired {
        file: trace.file.clone(),
        format: trace.format,
        axes,
        skipped,
    })
}

/// The unit a channel is read in, where it came from, and its factor to the axis unit.
fn unit_of(
    trace: &Trace,
    opts: &PairOptions,
    axis: AxisName,
    ch: &Channel,
) -> Result<(TraceUnit, UnitSource, f64), Error> {
    let (given, base, default, expected) = if axis.is_rotary() {
        (
            &opts.rotary_unit,
            BaseUnit::Deg,
            TraceUnit::Deg,
            "an angle unit (deg, mdeg, rad)",
        )
    } else {
        (
            &opts.linear_unit,
            BaseUnit::Mm,
            TraceUnit::Mm,
            "a length unit (nm, µm, mm, cm, m, inch)",
        )
    };
    let (unit, source) = match (&ch.unit, given) {
        // A unit the file states but vcnc does not know: the caller says which it is.
        (Some(TraceUnit::Other(_)), Some(g)) if !matches!(g, TraceUnit::Other(_)) => {
            (g.clone(), UnitSource::Caller)
        }
        (Some(TraceUnit::Other(u)), _) => {
            return Err(Error::UnknownUnit {
                file: trace.file.clone(),
                line: ch.line,
                channel: ch.name.clone(),
                unit: u.clone(),
            });
        }
        (Some(f), Some(g)) if f != g => {
            return Err(Error::UnitConflict {
                file: trace.file.clone(),
                line: ch.line,
                channel: ch.name.clone(),
                file_unit: f.to_string(),
                given_unit: g.to_string(),
            });
        }
        (Some(f), _) => (f.clone(), UnitSource::File),
        (None, Some(TraceUnit::Other(u))) => {
            return Err(Error::BadOption {
                file: trace.file.clone(),
                what: format!("unknown unit '{u}' given for axis {axis}"),
            });
        }
        (None, Some(g)) => (g.clone(), UnitSource::Caller),
        (None, None) => (default, UnitSource::Assumed),
    };
    match unit.to_base() {
        Some((b, k)) if b == base => Ok((unit, source, k)),
        _ => Err(Error::WrongUnit {
            file: trace.file.clone(),
            line: ch.line,
            channel: ch.name.clone(),
            unit: format!("{unit} ({})", source),
            axis,
            expected: expected.to_string(),
        }),
    }
}

/// A gap-free stretch of a channel: sample range and the time of its first sample.
#[derive(Debug, Clone, Copy)]
struct Stretch {
    start: usize,
    end: usize,
    /// Time of sample `start`, s (`None` when samples of unknown count were lost before).
    t0: Option<f64>,
    line: usize,
}

fn stretches(ch: &Channel, period: f64) -> Vec<Stretch> {
    let mut out = Vec::with_capacity(ch.gaps.len() + 1);
    let mut start = 0;
    let mut lost = Some(0usize);
    let mut line = ch.line;
    for g in &ch.gaps {
        out.push(Stretch {
            start,
            end: g.index,
            t0: lost.map(|l| ch.t0_s + start.saturating_add(l) as f64 * period),
            line,
        });
        lost = lost.zip(g.lost).map(|(a, b)| a.saturating_add(b));
        start = g.index;
        line = g.line;
    }
    out.push(Stretch {
        start,
        end: ch.samples.len(),
        t0: lost.map(|l| ch.t0_s + start.saturating_add(l) as f64 * period),
        line,
    });
    out
}

fn gap_error(trace: &Trace, ch: &Channel) -> Error {
    let g = ch.gaps[0];
    Error::Gap {
        file: trace.file.clone(),
        line: g.line,
        channel: ch.name.clone(),
        lost: g.lost,
    }
}

/// One of the two channels of an axis, with what pairing needs of it.
struct Side<'c> {
    ch: &'c Channel,
    /// Sample period, s.
    period: f64,
    /// Factor to the axis unit.
    factor: f64,
    /// Gap-free stretches.
    stretches: Vec<Stretch>,
}

/// The two channels on one grid.
struct Aligned {
    ts_s: f64,
    t0_s: f64,
    nominal: Vec<f64>,
    actual: Vec<f64>,
    resampled: bool,
    segment: Option<Segment>,
}

/// Channels on one time base: the longest stretch, sample by sample (ties go to the earliest).
fn same_base(nom: &Side<'_>, act: &Side<'_>) -> Aligned {
    let sn = &nom.stretches;
    let (i, s) = sn
        .iter()
        .enumerate()
        .max_by(|(i, a), (j, b)| (a.end - a.start).cmp(&(b.end - b.start)).then(j.cmp(i)))
        .expect("a channel has at least one stretch");
    let scale = |side: &Side<'_>| {
        side.ch.samples[s.start..s.end]
            .iter()
            .map(|v| v * side.factor)
            .collect()
    };
    Aligned {
        ts_s: nom.period,
        t0_s: s.t0.unwrap_or(nom.ch.t0_s),
        nominal: scale(nom),
        actual: scale(act),
        resampled: false,
        segment: (sn.len() > 1).then_some(Segment {
            index: i,
            of: sn.len(),
            line: s.line,
        }),
    }
}

/// `count` samples of a stretch at $t_k = t_\text{start} + k\,T_s$, linearly interpolated, in
/// the axis unit.
fn interpolate(side: &Side<'_>, s: &Stretch, start: f64, ts: f64, count: usize) -> Vec<f64> {
    let v = &side.ch.samples[s.start..s.end];
    let t0 = s.t0.unwrap_or(side.ch.t0_s);
    (0..count)
        .map(|n| {
            let x = (start + n as f64 * ts - t0) / side.period;
            let i = (x.floor().max(0.0) as usize).min(v.len() - 1);
            let frac = (x - i as f64).clamp(0.0, 1.0);
            let y = if i + 1 < v.len() {
                v[i] + frac * (v[i + 1] - v[i])
            } else {
                v[i]
            };
            y * side.factor
        })
        .collect()
}

/// Channels on different time bases: the longest time span one stretch of each shares, on the
/// coarser period's grid.
fn resample(
    trace: &Trace,
    axis: AxisName,
    nom: &Side<'_>,
    act: &Side<'_>,
) -> Result<Aligned, Error> {
    let (sn, sa) = (&nom.stretches, &act.stretches);
    for side in [nom, act] {
        if side.stretches.iter().any(|s| s.t0.is_none()) {
            // Samples of unknown count were lost: the times after the gap are unknown.
            return Err(gap_error(trace, side.ch));
        }
    }
    let no_overlap = || Error::NoOverlap {
        file: trace.file.clone(),
        axis,
        nominal: nom.ch.name.clone(),
        actual: act.ch.name.clone(),
    };
    let ts = nom.period.max(act.period);
    let mut best: Option<(f64, f64, usize, usize)> = None;
    for (i, a) in sn.iter().enumerate() {
        for (j, b) in sa.iter().enumerate() {
            let (Some(ta), Some(tb)) = (a.t0, b.t0) else {
                continue;
            };
            if a.end <= a.start || b.end <= b.start {
                continue;
            }
            let start = ta.max(tb);
            let end = (ta + (a.end - a.start - 1) as f64 * nom.period)
                .min(tb + (b.end - b.start - 1) as f64 * act.period);
            if end > start && best.is_none_or(|(s, e, _, _)| end - start > e - s) {
                best = Some((start, end, i, j));
            }
        }
    }
    let (start, end, i, j) = best.ok_or_else(no_overlap)?;
    let count = ((end - start) / ts + 1e-9).floor() as usize + 1;
    if count < 2 {
        return Err(no_overlap());
    }
    let segment = (sn.len() > 1 || sa.len() > 1).then(|| {
        let (index, of) = if sn.len() >= sa.len() {
            (i, sn.len())
        } else {
            (j, sa.len())
        };
        Segment {
            index,
            of,
            line: sn[i].line.max(sa[j].line),
        }
    });
    Ok(Aligned {
        ts_s: ts,
        t0_s: start,
        nominal: interpolate(nom, &sn[i], start, ts, count),
        actual: interpolate(act, &sa[j], start, ts, count),
        resampled: true,
        segment,
    })
}

/// A channel's period and stretches; with [`GapPolicy::Refuse`], refused if it has gaps.
fn side<'c>(
    trace: &Trace,
    opts: &PairOptions,
    c: &'c Channel,
    factor: f64,
) -> Result<Side<'c>, Error> {
    // An empty channel has no period to state; say what is really wrong.
    if c.samples.len() < 2 {
        return Err(Error::Truncated {
            file: trace.file.clone(),
            line: c.line,
            what: format!(
                "channel '{}' has {} sample(s); too few samples to pair",
                c.name,
                c.samples.len()
            ),
        });
    }
    let period = c.period_s.ok_or_else(|| Error::MissingPeriod {
        file: trace.file.clone(),
        channel: c.name.clone(),
    })?;
    if opts.gaps == GapPolicy::Refuse && !c.gaps.is_empty() {
        return Err(gap_error(trace, c));
    }
    Ok(Side {
        ch: c,
        period,
        factor,
        stretches: stretches(c, period),
    })
}

/// Whether two channels are on one time base (same period, first time, gaps and length).
fn one_base(n: &Side<'_>, a: &Side<'_>) -> bool {
    (n.period - a.period).abs() <= 1e-9 * n.period
        && (n.ch.t0_s - a.ch.t0_s).abs() <= 1e-6 * n.period
        && n.ch.gaps == a.ch.gaps
        && n.ch.samples.len() == a.ch.samples.len()
}

fn pair_axis(
    trace: &Trace,
    opts: &PairOptions,
    axis: AxisName,
    (nom, act, other): (&Channel, &Channel, Option<&Channel>),
    caller_map: bool,
) -> Result<AxisTrace, Error> {
    let (nu, nsrc, nk) = unit_of(trace, opts, axis, nom)?;
    let (au, asrc, ak) = unit_of(trace, opts, axis, act)?;
    let (n, a) = (side(trace, opts, nom, nk)?, side(trace, opts, act, ak)?);
    let aligned = if one_base(&n, &a) {
        same_base(&n, &a)
    } else {
        resample(trace, axis, &n, &a)?
    };
    // The other measuring system, on the grid of the pair (by the same two routes).
    let other = match other {
        Some(o) => {
            let (ou, osrc, ok) = unit_of(trace, opts, axis, o)?;
            let os = side(trace, opts, o, ok)?;
            let samples = if one_base(&n, &os) && !aligned.resampled {
                same_base(&n, &os).actual
            } else {
                resample(trace, axis, &n, &os)
                    .ok()
                    .filter(|r| r.t0_s == aligned.t0_s && r.ts_s == aligned.ts_s)
                    .map(|r| r.actual)
                    .unwrap_or_default()
            };
            (samples.len() == aligned.actual.len()).then_some((samples, os, ou, osrc))
        }
        None => None,
    };
    let use_of = |s: &Side<'_>, unit: TraceUnit, unit_source| ChannelUse {
        name: s.ch.name.clone(),
        line: s.ch.line,
        column: s.ch.column,
        axis_source: if caller_map {
            AxisSource::Caller
        } else {
            s.ch.axis_source.clone().unwrap_or(AxisSource::Caller)
        },
        unit,
        unit_source,
        factor: s.factor,
        period_s: s.period,
        t0_s: s.ch.t0_s,
        samples: s.ch.samples.len(),
    };
    let other_use = other
        .as_ref()
        .map(|(_, os, ou, osrc)| use_of(os, ou.clone(), *osrc));
    Ok(AxisTrace {
        axis,
        unit: axis.unit(),
        ts_s: aligned.ts_s,
        t0_s: aligned.t0_s,
        nominal: aligned.nominal,
        actual: aligned.actual,
        other_actual: other.map(|(v, ..)| v),
        provenance: Provenance {
            file: trace.file.clone(),
            format: trace.format,
            nominal: use_of(&n, nu, nsrc),
            actual: use_of(&a, au, asrc),
            other_actual: other_use,
            resampled: aligned.resampled,
            segment: aligned.segment,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Gap;

    fn channel(name: &str, quantity: Quantity, period: f64, t0: f64, samples: Vec<f64>) -> Channel {
        let mut c = Channel::new(name, 1, 0);
        c.axis = Some(AxisName::X);
        c.quantity = quantity;
        c.unit = Some(TraceUnit::Mm);
        c.period_s = Some(period);
        c.t0_s = t0;
        c.samples = samples;
        c
    }

    /// Truth: linear signals, which linear interpolation reproduces exactly, so every aligned
    /// sample is known in closed form.
    #[test]
    fn different_time_bases_with_a_gap_use_the_longest_shared_span() {
        let nominal = channel(
            "X nominal",
            Quantity::NominalPosition,
            2e-3,
            0.0,
            (0..51).map(|k| 10.0 * (k as f64 * 2e-3)).collect(),
        );
        // Actual at 1 ms from 0.5 ms; 5 samples lost before its 41st sample.
        let t_act = |k: usize| 0.5e-3 + (if k < 40 { k } else { k + 5 }) as f64 * 1e-3;
        let mut actual = channel(
            "X actual",
            Quantity::ActualPosition,
            1e-3,
            0.5e-3,
            (0..100).map(|k| 10.0 * t_act(k) + 1.0).collect(),
        );
        actual.gaps = vec![Gap {
            index: 40,
            line: 42,
            lost: Some(5),
        }];
        let trace = Trace {
            file: "t".into(),
            format: Format::TncScope,
            channels: vec![nominal, actual],
            metadata: Vec::new(),
        };
        let refused = pair(&trace, &PairOptions::default()).unwrap_err();
        assert!(
            matches!(
                refused,
                Error::Gap {
                    line: 42,
                    lost: Some(5),
                    ..
                }
            ),
            "{refused:?}"
        );
        let opts = PairOptions {
            gaps: GapPolicy::LongestSegment,
            ..PairOptions::default()
        };
        let x = &pair(&trace, &opts).unwrap().axes[0];
        // The stretch after the gap, 45.5 ms … 100 ms, beats 0.5 … 39.5 ms.
        assert!(x.provenance.resampled);
        assert_eq!(x.ts_s, 2e-3);
        assert!((x.t0_s - 45.5e-3).abs() < 1e-15);
        assert_eq!(x.nominal.len(), 28);
        for k in 0..28 {
            let t = x.t0_s + k as f64 * 2e-3;
            assert!((x.nominal[k] - 10.0 * t).abs() < 1e-12, "{k}");
            assert!((x.actual[k] - (10.0 * t + 1.0)).abs() < 1e-12, "{k}");
        }
        let seg = x.provenance.segment.unwrap();
        assert_eq!((seg.index, seg.of, seg.line), (1, 2, 42));
    }

    #[test]
    fn motor_channels_win_and_two_others_are_ambiguous() {
        let c = |n: &str, q| channel(n, q, 1e-3, 0.0, vec![0.0; 3]);
        let mut trace = Trace {
            file: "t".into(),
            format: Format::HalscopeTable,
            channels: vec![
                c("joint.0.pos-cmd", Quantity::NominalPosition),
                c("joint.0.motor-pos-cmd", Quantity::NominalPosition),
                c("joint.0.motor-pos-fb", Quantity::ActualPosition),
            ],
            metadata: Vec::new(),
        };
        let p = pair(&trace, &PairOptions::default()).unwrap();
        assert_eq!(p.axes[0].provenance.nominal.name, "joint.0.motor-pos-cmd");
        trace.channels[0].name = "joint.0.motor-pos-cmd-2".into();
        let e = pair(&trace, &PairOptions::default()).unwrap_err();
        assert!(matches!(e, Error::Ambiguous { .. }), "{e:?}");
    }
}
