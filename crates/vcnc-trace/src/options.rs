//! The command line's trace options, raw as typed ([`TraceArgs`]), checked into the reader's
//! [`ReadOptions`] and the pairing's [`PairOptions`]; and the axis-number map
//! ([`AxisNumberMap`], `--axis-map 1=X,2=Y`). Every refusal names the option, the value and what
//! was expected ([`Error::Argument`]).
//!
//! | option | meaning | applies to |
//! |---|---|---|
//! | `--ts S` | sample period, s, of a file without a time base | halsampler, halscope (checked), delimited text without a time column; a file's own period wins, a `--ts` more than 0.1 % away from it is refused |
//! | `--units U` | unit of positions where the file states none (or states one vcnc does not know) | every format |
//! | `--trace-format F` | read as this format instead of detecting it | every format |
//! | `--joints AXES` | LinuxCNC joint `N` is the `N`-th letter (`XYZAC`) | halscope, halsampler |
//! | `--axis-map N=A,…` | the file's axis number `N` is axis `A` | Sinumerik (`…[u1, N]`) |
//! | `--axis A` | the axes to pair (repeatable); with one axis, a file whose position channels belong to one unnamed axis is that axis | every format |
//! | `--xr-col C --x-col C` | the nominal and actual position channels of the (first) `--axis`, X by default: a name as `vcnc trace info` lists it (exact, else ignoring case, else the description), or a 0-based column number | every format |
//! | `--t-col C` | the time column (s, or the unit its header states) | delimited text, halsampler, halscope, Parquet |
//! | `--gaps refuse\|longest` | refuse lost samples, or use the longest stretch without any | every format |

use std::fmt;

use vcnc_axis::AxisName;

use crate::error::Error;
use crate::model::{ChannelRef, Format, ReadOptions};
use crate::pair::{AxisMap, GapPolicy, PairOptions};
use crate::units::TraceUnit;

/// Axis numbers of a file to machine axes: Sinumerik servo-trace signals name their axis by the
/// NCK axis number (`/Nck/!SD/nckServoDataActPos2ndEnc64 [u1, 3]` is axis 3), which only the
/// machine's configuration ties to a letter. Written `1=X,2=Y` (`--axis-map`).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct AxisNumberMap {
    /// (axis number, axis), in the order given; numbers and axes each appear once.
    pub pairs: Vec<(u32, AxisName)>,
}

impl AxisNumberMap {
    /// Reads `N=A` pairs separated by commas (`1=X,2=Y,11=Z`; spaces allowed, letters in any
    /// case). Refused: an empty map, a pair without `=`, a number that is not a positive
    /// integer, a letter that is not an axis, a number or an axis given twice.
    pub fn parse(s: &str) -> Result<AxisNumberMap, Error> {
        let bad = |what: String| Error::Argument {
            option: "axis-map",
            value: s.to_string(),
            what,
        };
        const FORM: &str = "expected N=A pairs separated by commas, e.g. --axis-map 1=X,2=Y";
        let mut pairs: Vec<(u32, AxisName)> = Vec::new();
        for item in s.split(',') {
            let item = item.trim();
            if item.is_empty() {
                return Err(bad(format!("an empty pair; {FORM}")));
            }
            let Some((n, a)) = item.split_once('=') else {
                return Err(bad(format!("'{item}' has no '='; {FORM}")));
            };
            let number = match n.trim().parse::<u32>() {
                Ok(v) if v > 0 => v,
                _ => {
                    return Err(bad(format!(
                        "'{}' is not an axis number (a positive integer, the N of the file's \
                         '[u1, N]'); {FORM}",
                        n.trim()
                    )));
                }
            };
            let mut letters = a.trim().chars();
            let axis = match (letters.next(), letters.next()) {
                (Some(c), None) => AxisName::from_letter(c),
                _ => None,
            }
            .ok_or_else(|| {
                bad(format!(
                    "'{}' is not an axis letter (X Y Z A B C); {FORM}",
                    a.trim()
                ))
            })?;
            if pairs.iter().any(|&(m, _)| m == number) {
                return Err(bad(format!("axis number {number} is mapped twice")));
            }
            if let Some(&(m, _)) = pairs.iter().find(|&&(_, b)| b == axis) {
                return Err(bad(format!(
                    "axis {axis} is given to both {m} and {number}"
                )));
            }
            pairs.push((number, axis));
        }
        Ok(AxisNumberMap { pairs })
    }

    /// The axis of number `n`, if mapped.
    pub fn get(&self, n: u32) -> Option<AxisName> {
        self.pairs.iter().find(|&&(m, _)| m == n).map(|&(_, a)| a)
    }

    /// Whether no number is mapped.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }
}

impl fmt::Display for AxisNumberMap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, (n, a)) in self.pairs.iter().enumerate() {
            if i > 0 {
                f.write_str(",")?;
            }
            write!(f, "{n}={a}")?;
        }
        Ok(())
    }
}

impl GapPolicy {
    /// `refuse` or `longest` (`--gaps`).
    pub fn parse(s: &str) -> Result<GapPolicy, Error> {
        match s.trim() {
            "refuse" => Ok(GapPolicy::Refuse),
            "longest" => Ok(GapPolicy::LongestSegment),
            _ => Err(Error::Argument {
                option: "gaps",
                value: s.to_string(),
                what: "expected refuse (identify across no lost samples) or longest (use the \
                       longest stretch without any)"
                    .to_string(),
            }),
        }
    }
}

/// The trace options of the command line, as typed: the same for `trace info`, `identify
/// --trace` and `validate` (the module documentation lists them). [`TraceArgs::read_options`]
/// and [`TraceArgs::pair_options`] check them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TraceArgs {
    /// `--ts`: sample period, s.
    pub ts: Option<f64>,
    /// `--units`: unit of positions where the file states none.
    pub units: Option<String>,
    /// `--trace-format`: a [`Format::key`].
    pub trace_format: Option<String>,
    /// `--joints`: LinuxCNC joint map, one axis letter per joint (`XYZAC`).
    pub joints: Option<String>,
    /// `--axis-map`: axis numbers to axes (`1=X,2=Y`).
    pub axis_map: Option<String>,
    /// `--axis`: the axes to pair.
    pub axes: Vec<AxisName>,
    /// `--t-col`: the time column.
    pub t_col: Option<String>,
    /// `--xr-col`: the nominal position channel of the first `--axis` (X by default).
    pub xr_col: Option<String>,
    /// `--x-col`: the actual position channel of the same axis.
    pub x_col: Option<String>,
    /// `--gaps`.
    pub gaps: Option<GapPolicy>,
}

impl TraceArgs {
    /// The reader's options: `--ts`, `--trace-format`, `--joints`, `--axis-map`, `--t-col`.
    pub fn read_options(&self) -> Result<ReadOptions, Error> {
        let mut read = ReadOptions::default();
        if let Some(ts) = self.ts {
            if !(ts.is_finite() && ts > 0.0) {
                return Err(Error::Argument {
                    option: "ts",
                    value: ts.to_string(),
                    what:
                        "the sample period must be a positive number of seconds (1 ms: --ts 0.001)"
                            .to_string(),
                });
            }
            read.period_s = Some(ts);
        }
        if let Some(f) = &self.trace_format {
            read.format = Some(Format::from_key(f.trim()).ok_or_else(|| Error::Argument {
                option: "trace-format",
                value: f.clone(),
                what: format!(
                    "expected one of {}",
                    Format::ALL.map(|f| f.key()).join(", ")
                ),
            })?);
        }
        if let Some(j) = &self.joints {
            let map: Vec<AxisName> = j
                .chars()
                .filter(|c| !c.is_whitespace())
                .map(|c| {
                    AxisName::from_letter(c).ok_or_else(|| Error::Argument {
                        option: "joints",
                        value: j.clone(),
                        what: format!(
                            "'{c}' is not an axis letter (X Y Z A B C); joint N is the N-th letter, \
                             e.g. --joints XYZAC"
                        ),
                    })
                })
                .collect::<Result<_, _>>()?;
            if map.is_empty() {
                return Err(Error::Argument {
                    option: "joints",
                    value: j.clone(),
                    what: "no axis letter; joint N is the N-th letter, e.g. --joints XYZAC"
                        .to_string(),
                });
            }
            read.joints = map;
        }
        if let Some(m) = &self.axis_map {
            read.axis_map = AxisNumberMap::parse(m)?;
        }
        if let Some(t) = &self.t_col {
            read.time_column = Some(ChannelRef::parse(t));
        }
        Ok(read)
    }

    /// The pairing's options: `--axis`, `--units`, `--xr-col`/`--x-col`, `--gaps`.
    pub fn pair_options(&self) -> Result<PairOptions, Error> {
        let mut pair = PairOptions {
            axes: self.axes.clone(),
            gaps: self.gaps.unwrap_or_default(),
            ..PairOptions::default()
        };
        if let Some(u) = &self.units {
            let bad = || Error::Argument {
                option: "units",
                value: u.clone(),
                what: "expected a length (nm, um, mm, cm, m, inch) for linear axes or an angle \
                       (deg, mdeg, rad) for rotary axes"
                    .to_string(),
            };
            let unit = TraceUnit::parse(u).ok_or_else(bad)?;
            if !pair.set_unit(unit) {
                return Err(bad());
            }
        }
        match (&self.xr_col, &self.x_col) {
            (Some(xr), Some(x)) => pair.map.push(AxisMap {
                axis: self.axes.first().copied().unwrap_or(AxisName::X),
                nominal: ChannelRef::parse(xr),
                actual: ChannelRef::parse(x),
            }),
            (None, None) => {}
            (Some(c), None) | (None, Some(c)) => {
                let (given, missing) = if self.xr_col.is_some() {
                    ("xr-col", "--x-col ACTUAL")
                } else {
                    ("x-col", "--xr-col NOMINAL")
                };
                return Err(Error::Argument {
                    option: given,
                    value: c.clone(),
                    what: format!(
                        "--xr-col and --x-col go together (one axis' nominal and actual position \
                         channels): add {missing}"
                    ),
                });
            }
        }
        Ok(pair)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_maps_read_and_refuse_with_the_option_named() {
        let m = AxisNumberMap::parse(" 1=X, 2=y,11=Z").unwrap();
        assert_eq!(m.get(2), Some(AxisName::Y));
        assert_eq!(m.get(11), Some(AxisName::Z));
        assert_eq!(m.get(3), None);
        assert_eq!(m.to_string(), "1=X,2=Y,11=Z");
        for (bad, says) in [
            ("", "an empty pair"),
            ("1X", "'1X' has no '='"),
            ("0=X", "'0' is not an axis number"),
            ("one=X", "'one' is not an axis number"),
            ("1=Q", "'Q' is not an axis letter"),
            ("1=XY", "'XY' is not an axis letter"),
            ("1=X,1=Y", "axis number 1 is mapped twice"),
            ("1=X,2=X", "axis X is given to both 1 and 2"),
        ] {
            let e = AxisNumberMap::parse(bad).unwrap_err().to_string();
            assert!(e.starts_with(&format!("--axis-map {bad}: ")), "{e}");
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn raw_options_check_into_read_and_pair_options() {
        let args = TraceArgs {
            ts: Some(1e-3),
            units: Some("m".into()),
            joints: Some("XYZAC".into()),
            axis_map: Some("1=Y".into()),
            axes: vec![AxisName::Y],
            xr_col: Some("qg".into()),
            x_col: Some("3".into()),
            gaps: Some(GapPolicy::parse("longest").unwrap()),
            ..TraceArgs::default()
        };
        let r = args.read_options().unwrap();
        assert_eq!(r.period_s, Some(1e-3));
        assert_eq!(r.joints.len(), 5);
        assert_eq!(r.axis_map.get(1), Some(AxisName::Y));
        let p = args.pair_options().unwrap();
        assert_eq!(p.linear_unit, Some(TraceUnit::M));
        assert_eq!(p.gaps, GapPolicy::LongestSegment);
        assert_eq!(
            p.map,
            [AxisMap {
                axis: AxisName::Y,
                nominal: ChannelRef::Name("qg".into()),
                actual: ChannelRef::Column(3),
            }]
        );
        for (args, says) in [
            (
                TraceArgs {
                    ts: Some(0.0),
                    ..TraceArgs::default()
                },
                "--ts 0: the sample period must be a positive",
            ),
            (
                TraceArgs {
                    units: Some("mm/min".into()),
                    ..TraceArgs::default()
                },
                "--units mm/min: expected a length",
            ),
            (
                TraceArgs {
                    xr_col: Some("qg".into()),
                    ..TraceArgs::default()
                },
                "--xr-col qg: --xr-col and --x-col go together",
            ),
            (
                TraceArgs {
                    trace_format: Some("csv".into()),
                    ..TraceArgs::default()
                },
                "--trace-format csv: expected one of parquet, sinumerik, tncscope",
            ),
            (
                TraceArgs {
                    joints: Some("XYW".into()),
                    ..TraceArgs::default()
                },
                "--joints XYW: 'W' is not an axis letter",
            ),
        ] {
            let e = args
                .read_options()
                .and_then(|_| args.pair_options())
                .unwrap_err()
                .to_string();
            assert!(e.contains(says), "{e}");
        }
        assert!(
            GapPolicy::parse("skip")
                .unwrap_err()
                .to_string()
                .starts_with("--gaps skip: ")
        );
    }
}
