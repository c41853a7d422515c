//! Units written in trace files, and their conversion to vcnc's axis units (see [`TraceUnit`]).

use std::fmt;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A unit stated by a trace file (or by the caller for a file that states none), and its
/// conversion to vcnc's axis units.
///
/// vcnc works in mm and deg for positions, mm/s and deg/s for velocities, A for currents and s for
/// time (docs/machine-file.md). Every unit a trace may state is one [`TraceUnit`]; its
/// [`TraceUnit::to_base`] gives the base unit and the factor $k$ with
/// $$ v_\text{base} = k \, v_\text{file}. $$
///
/// | written (any case)                     | unit        | base   | factor $k$     |
/// |----------------------------------------|-------------|--------|----------------|
/// | `nm`                                   | nm          | mm     | 1e-6           |
/// | `µm` `um` `μm` `0.001 mm`              | µm          | mm     | 1e-3           |
/// | `mm`                                   | mm          | mm     | 1              |
/// | `cm`                                   | cm          | mm     | 10             |
/// | `m`                                    | m           | mm     | 1000           |
/// | `in` `inch` `"`                        | inch        | mm     | 25.4           |
/// | `deg` `°` `degree` `Grad`              | deg         | deg    | 1              |
/// | `mdeg` `0.001 deg` `0.001°`            | mdeg        | deg    | 1e-3           |
/// | `rad`                                  | rad         | deg    | 180/π          |
/// | `mm/min`                               | mm/min      | mm/s   | 1/60           |
/// | `mm/s` `mm/sec`                        | mm/s        | mm/s   | 1              |
/// | `µm/s` `um/s`                          | µm/s        | mm/s   | 1e-3           |
/// | `m/min`                                | m/min       | mm/s   | 1000/60        |
/// | `m/s`                                  | m/s         | mm/s   | 1000           |
/// | `in/min` `inch/min` `ipm`              | inch/min    | mm/s   | 25.4/60        |
/// | `in/s` `inch/s` `ips`                  | inch/s      | mm/s   | 25.4           |
/// | `deg/min` `°/min`                      | deg/min     | deg/s  | 1/60           |
/// | `deg/s` `°/s`                          | deg/s       | deg/s  | 1              |
/// | `rad/s`                                | rad/s       | deg/s  | 180/π          |
/// | `rpm` `1/min` `U/min` `rev/min`        | rev/min     | deg/s  | 6              |
/// | `A` `Ampere` `amp`                     | A           | A      | 1              |
/// | `mA`                                   | mA          | A      | 1e-3           |
/// | `s` `sec`                              | s           | s      | 1              |
/// | `ms`                                   | ms          | s      | 1e-3           |
/// | `µs` `us`                              | µs          | s      | 1e-6           |
/// | `ns`                                   | ns          | s      | 1e-9           |
///
/// `Grad` is German for degree (Heidenhain and Siemens screens in German), not the gon. A trailing
/// description in parentheses (TwinCAT's `V (Voltage)`) and surrounding brackets (`[mm]`) are
/// dropped before matching; `(None)`, `-` and an empty string mean "no unit". Anything else is kept
/// as [`TraceUnit::Other`]: such a channel can be listed, but a position channel in it cannot be
/// paired (`Error::UnknownUnit`).
///
/// In files (`summary.json`, `trace info --json`) a unit is its symbol, `"mm"`, `"µm"`, `"deg"`
/// — the same text [`fmt::Display`] prints — and reads back through [`TraceUnit::parse`].
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum TraceUnit {
    /// Nanometre.
    Nm,
    /// Micrometre.
    Um,
    /// Millimetre.
    Mm,
    /// Centimetre.
    Cm,
    /// Metre.
    M,
    /// Inch, 25.4 mm.
    Inch,
    /// Degree.
    Deg,
    /// Millidegree.
    Mdeg,
    /// Radian.
    Rad,
    /// Millimetre per minute.
    MmPerMin,
    /// Millimetre per second.
    MmPerS,
    /// Micrometre per second.
    UmPerS,
    /// Metre per minute.
    MPerMin,
    /// Metre per second.
    MPerS,
    /// Inch per minute.
    InchPerMin,
    /// Inch per second.
    InchPerS,
    /// Degree per minute.
    DegPerMin,
    /// Degree per second.
    DegPerS,
    /// Radian per second.
    RadPerS,
    /// Revolution per minute (360 deg/min).
    RevPerMin,
    /// Ampere.
    A,
    /// Milliampere.
    MilliA,
    /// Second.
    S,
    /// Millisecond.
    Ms,
    /// Microsecond.
    Us,
    /// Nanosecond.
    Ns,
    /// A unit vcnc does not convert (`V`, `Nm`, `%`, …), as written.
    Other(String),
}

/// The base units vcnc converts to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum BaseUnit {
    /// Millimetre: linear positions.
    Mm,
    /// Degree: angular positions.
    Deg,
    /// Millimetre per second: linear velocities.
    MmPerS,
    /// Degree per second: angular velocities.
    DegPerS,
    /// Ampere: currents.
    A,
    /// Second: time.
    S,
}

impl BaseUnit {
    /// The symbol (`mm`, `deg`, `mm/s`, `deg/s`, `A`, `s`).
    pub const fn as_str(self) -> &'static str {
        match self {
            BaseUnit::Mm => "mm",
            BaseUnit::Deg => "deg",
            BaseUnit::MmPerS => "mm/s",
            BaseUnit::DegPerS => "deg/s",
            BaseUnit::A => "A",
            BaseUnit::S => "s",
        }
    }
}

impl fmt::Display for BaseUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl TraceUnit {
    /// Reads a unit as written in a file. `None` for "no unit" (empty, `(None)`, `-`, `1`);
    /// [`TraceUnit::Other`] for a unit outside the table above.
    pub fn parse(written: &str) -> Option<TraceUnit> {
        let raw = written.trim();
        let mut s = raw;
        // "V (Voltage)" → "V"; "[mm]" → "mm"; "(mm)" → "mm".
        if let Some(i) = s.find(" (") {
            s = s[..i].trim();
        }
        for (open, close) in [('[', ']'), ('(', ')')] {
            if let Some(inner) = s.strip_prefix(open).and_then(|t| t.strip_suffix(close)) {
                s = inner.trim();
            }
        }
        let key: String = s
            .chars()
            .filter(|c| !c.is_whitespace())
            .map(|c| match c {
                'µ' | 'μ' => 'u',
                '°' => 'd',
                c => c.to_ascii_lowercase(),
            })
            .collect();
        // '°' became 'd': "d" alone is degree, "d/s" and "d/min" rates.
        let u = match key.as_str() {
            "" | "none" | "-" | "1" | "n/a" => return None,
            "nm" => TraceUnit::Nm,
            "um" | "0.001mm" | "micron" | "microns" => TraceUnit::Um,
            "mm" | "millimeter" | "millimetre" => TraceUnit::Mm,
            "cm" => TraceUnit::Cm,
            "m" | "meter" | "metre" => TraceUnit::M,
            "in" | "inch" | "inches" | "\"" => TraceUnit::Inch,
            "d" | "deg" | "degree" | "degrees" | "grad" => TraceUnit::Deg,
            "mdeg" | "0.001deg" | "0.001d" | "millidegree" => TraceUnit::Mdeg,
            "rad" | "radian" | "radians" => TraceUnit::Rad,
            "mm/min" => TraceUnit::MmPerMin,
            "mm/s" | "mm/sec" => TraceUnit::MmPerS,
            "um/s" | "um/sec" => TraceUnit::UmPerS,
            "m/min" => TraceUnit::MPerMin,
            "m/s" | "m/sec" => TraceUnit::MPerS,
            "in/min" | "inch/min" | "ipm" => TraceUnit::InchPerMin,
            "in/s" | "inch/s" | "in/sec" | "ips" => TraceUnit::InchPerS,
            "deg/min" | "d/min" | "grad/min" => TraceUnit::DegPerMin,
            "deg/s" | "d/s" | "deg/sec" | "grad/s" => TraceUnit::DegPerS,
            "rad/s" | "rad/sec" => TraceUnit::RadPerS,
            "rpm" | "1/min" | "u/min" | "rev/min" | "min^-1" | "min-1" => TraceUnit::RevPerMin,
            "a" | "ampere" | "amp" | "amps" => TraceUnit::A,
            "ma" => TraceUnit::MilliA,
            "s" | "sec" | "second" | "seconds" => TraceUnit::S,
            "ms" | "msec" => TraceUnit::Ms,
            "us" | "usec" => TraceUnit::Us,
            "ns" | "nsec" => TraceUnit::Ns,
            _ => TraceUnit::Other(raw.to_string()),
        };
        Some(u)
    }

    /// Base unit and factor $k$ ($v_\text{base} = k\,v$); `None` for [`TraceUnit::Other`].
    pub fn to_base(&self) -> Option<(BaseUnit, f64)> {
        use BaseUnit as B;
        let r2d = 180.0 / std::f64::consts::PI;
        Some(match self {
            TraceUnit::Nm => (B::Mm, 1e-6),
            TraceUnit::Um => (B::Mm, 1e-3),
            TraceUnit::Mm => (B::Mm, 1.0),
            TraceUnit::Cm => (B::Mm, 10.0),
            TraceUnit::M => (B::Mm, 1000.0),
            TraceUnit::Inch => (B::Mm, 25.4),
            TraceUnit::Deg => (B::Deg, 1.0),
            TraceUnit::Mdeg => (B::Deg, 1e-3),
            TraceUnit::Rad => (B::Deg, r2d),
            TraceUnit::MmPerMin => (B::MmPerS, 1.0 / 60.0),
            TraceUnit::MmPerS => (B::MmPerS, 1.0),
            TraceUnit::UmPerS => (B::MmPerS, 1e-3),
            TraceUnit::MPerMin => (B::MmPerS, 1000.0 / 60.0),
            TraceUnit::MPerS => (B::MmPerS, 1000.0),
            TraceUnit::InchPerMin => (B::MmPerS, 25.4 / 60.0),
            TraceUnit::InchPerS => (B::MmPerS, 25.4),
            TraceUnit::DegPerMin => (B::DegPerS, 1.0 / 60.0),
            TraceUnit::DegPerS => (B::DegPerS, 1.0),
            TraceUnit::RadPerS => (B::DegPerS, r2d),
            TraceUnit::RevPerMin => (B::DegPerS, 6.0),
            TraceUnit::A => (B::A, 1.0),
            TraceUnit::MilliA => (B::A, 1e-3),
            TraceUnit::S => (B::S, 1.0),
            TraceUnit::Ms => (B::S, 1e-3),
            TraceUnit::Us => (B::S, 1e-6),
            TraceUnit::Ns => (B::S, 1e-9),
            TraceUnit::Other(_) => return None,
        })
    }

    /// The symbol as vcnc prints it (`mm`, `µm`, `mm/min`, …; an unknown unit as written).
    pub fn symbol(&self) -> &str {
        match self {
            TraceUnit::Nm => "nm",
            TraceUnit::Um => "µm",
            TraceUnit::Mm => "mm",
            TraceUnit::Cm => "cm",
            TraceUnit::M => "m",
            TraceUnit::Inch => "inch",
            TraceUnit::Deg => "deg",
            TraceUnit::Mdeg => "mdeg",
            TraceUnit::Rad => "rad",
            TraceUnit::MmPerMin => "mm/min",
            TraceUnit::MmPerS => "mm/s",
            TraceUnit::UmPerS => "µm/s",
            TraceUnit::MPerMin => "m/min",
            TraceUnit::MPerS => "m/s",
            TraceUnit::InchPerMin => "inch/min",
            TraceUnit::InchPerS => "inch/s",
            TraceUnit::DegPerMin => "deg/min",
            TraceUnit::DegPerS => "deg/s",
            TraceUnit::RadPerS => "rad/s",
            TraceUnit::RevPerMin => "rev/min",
            TraceUnit::A => "A",
            TraceUnit::MilliA => "mA",
            TraceUnit::S => "s",
            TraceUnit::Ms => "ms",
            TraceUnit::Us => "µs",
            TraceUnit::Ns => "ns",
            TraceUnit::Other(s) => s,
        }
    }
}

impl fmt::Display for TraceUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.symbol())
    }
}

/// The symbol, as printed: a summary shows `"mm"` for the unit, never the variant name `"Mm"`.
impl Serialize for TraceUnit {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.symbol())
    }
}

impl<'de> Deserialize<'de> for TraceUnit {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        TraceUnit::parse(&s).ok_or_else(|| serde::de::Error::custom(format!("'{s}' is no unit")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn written_forms_map_to_units() {
        let cases = [
            ("mm", TraceUnit::Mm),
            (" [mm] ", TraceUnit::Mm),
            ("µm", TraceUnit::Um),
            ("\u{3bc}m", TraceUnit::Um),
            ("um", TraceUnit::Um),
            ("0.001 mm", TraceUnit::Um),
            ("m", TraceUnit::M),
            ("inch", TraceUnit::Inch),
            ("°", TraceUnit::Deg),
            ("Grad", TraceUnit::Deg),
            ("rad", TraceUnit::Rad),
            ("mm/min", TraceUnit::MmPerMin),
            ("mm / min", TraceUnit::MmPerMin),
            ("°/s", TraceUnit::DegPerS),
            ("1/min", TraceUnit::RevPerMin),
            ("Ampere", TraceUnit::A),
            ("A (Current)", TraceUnit::A),
            ("mm (Millimeter)", TraceUnit::Mm),
            ("ms", TraceUnit::Ms),
            ("µs", TraceUnit::Us),
        ];
        for (w, u) in cases {
            assert_eq!(TraceUnit::parse(w), Some(u), "{w:?}");
        }
        for none in ["", "(None)", "-", " "] {
            assert_eq!(TraceUnit::parse(none), None, "{none:?}");
        }
        assert_eq!(
            TraceUnit::parse("V (Voltage)"),
            Some(TraceUnit::Other("V (Voltage)".into()))
        );
        assert_eq!(
            TraceUnit::parse("furlong"),
            Some(TraceUnit::Other("furlong".into()))
        );
    }

    /// Issue 29: `summary.json` recorded a channel's unit as `"Mm"` (the variant name) beside the
    /// axis unit `"mm"`.
    #[test]
    fn summary_unit_is_mm_not_capitalised_mm() {
        let units = vec![TraceUnit::Mm, TraceUnit::Um, TraceUnit::Other("V".into())];
        assert_eq!(
            serde_json::to_string(&units).unwrap(),
            "[\"mm\",\"µm\",\"V\"]"
        );
    }

    #[test]
    fn conversions_to_base_units() {
        // Truth: definitions (1 inch = 25.4 mm exactly; 1 rev = 360 deg; π rad = 180 deg).
        assert_eq!(TraceUnit::Inch.to_base(), Some((BaseUnit::Mm, 25.4)));
        assert_eq!(TraceUnit::M.to_base(), Some((BaseUnit::Mm, 1000.0)));
        let (b, k) = TraceUnit::Rad.to_base().unwrap();
        assert_eq!(b, BaseUnit::Deg);
        assert_relative_eq!(k * std::f64::consts::PI, 180.0, max_relative = 1e-15);
        let (b, k) = TraceUnit::MmPerMin.to_base().unwrap();
        assert_eq!(b, BaseUnit::MmPerS);
        assert_relative_eq!(k * 6000.0, 100.0, max_relative = 1e-15);
        assert_eq!(
            TraceUnit::RevPerMin.to_base(),
            Some((BaseUnit::DegPerS, 6.0))
        );
        assert_eq!(TraceUnit::Us.to_base(), Some((BaseUnit::S, 1e-6)));
        assert_eq!(TraceUnit::Other("V".into()).to_base(), None);
        // Every known unit prints a symbol that parses back to itself.
        for u in [
            TraceUnit::Nm,
            TraceUnit::Um,
            TraceUnit::Mm,
            TraceUnit::Cm,
            TraceUnit::M,
            TraceUnit::Inch,
            TraceUnit::Deg,
            TraceUnit::Mdeg,
            TraceUnit::Rad,
            TraceUnit::MmPerMin,
            TraceUnit::MmPerS,
            TraceUnit::UmPerS,
            TraceUnit::MPerMin,
            TraceUnit::MPerS,
            TraceUnit::InchPerMin,
            TraceUnit::InchPerS,
            TraceUnit::DegPerMin,
            TraceUnit::DegPerS,
            TraceUnit::RadPerS,
            TraceUnit::RevPerMin,
            TraceUnit::A,
            TraceUnit::MilliA,
            TraceUnit::S,
            TraceUnit::Ms,
            TraceUnit::Us,
            TraceUnit::Ns,
        ] {
            assert_eq!(TraceUnit::parse(u.symbol()), Some(u.clone()), "{u}");
            // Summaries write the symbol, and read it back.
            let json = serde_json::to_string(&u).unwrap();
            assert_eq!(json, format!("\"{}\"", u.symbol()));
            assert_eq!(serde_json::from_str::<TraceUnit>(&json).unwrap(), u);
        }
    }
}
