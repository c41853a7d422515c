//! The vocabulary every vcnc stage shares: which machine axis a signal belongs to
//! ([`AxisName`]) and in which unit it is measured ([`Unit`]).
//!
//! G-code words, interpolated tracks, drives, kinematic joints, identified models and trace
//! channels all name their axis with [`AxisName`], so an axis is resolved once, where text
//! enters the program (a G-code word, a machine-file key, a trace header), and never looked up
//! by letter again.
//!
//! ```
//! use vcnc_axis::{AxisName, Unit};
//!
//! let c: AxisName = "c".parse().unwrap();
//! assert_eq!(c, AxisName::C);
//! assert_eq!(c.index(), 5);
//! assert_eq!(c.unit(), Unit::Deg);
//! assert_eq!(c.to_string(), "C");
//! assert!("Q".parse::<AxisName>().is_err());
//! ```

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A machine axis: linear X Y Z (mm) and rotary A B C (deg, about X Y Z).
///
/// The order of the variants is the canonical order of every per-axis array in vcnc
/// (`[f64; 6]` positions, machine axes, table columns).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum AxisName {
    /// Linear X, mm.
    X,
    /// Linear Y, mm.
    Y,
    /// Linear Z, mm.
    Z,
    /// Rotary about X, deg.
    A,
    /// Rotary about Y, deg.
    B,
    /// Rotary about Z, deg.
    C,
}

impl AxisName {
    /// All six, in canonical order.
    pub const ALL: [AxisName; 6] = [
        AxisName::X,
        AxisName::Y,
        AxisName::Z,
        AxisName::A,
        AxisName::B,
        AxisName::C,
    ];

    /// Position in [`AxisName::ALL`] (0 for X … 5 for C).
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The axis at `index` of [`AxisName::ALL`].
    pub fn from_index(index: usize) -> Option<AxisName> {
        AxisName::ALL.get(index).copied()
    }

    /// The axis of a letter, either case.
    pub fn from_letter(c: char) -> Option<AxisName> {
        match c.to_ascii_uppercase() {
            'X' => Some(AxisName::X),
            'Y' => Some(AxisName::Y),
            'Z' => Some(AxisName::Z),
            'A' => Some(AxisName::A),
            'B' => Some(AxisName::B),
            'C' => Some(AxisName::C),
            _ => None,
        }
    }

    /// The upper-case letter.
    pub const fn letter(self) -> char {
        match self {
            AxisName::X => 'X',
            AxisName::Y => 'Y',
            AxisName::Z => 'Z',
            AxisName::A => 'A',
            AxisName::B => 'B',
            AxisName::C => 'C',
        }
    }

    /// The letter as a string slice.
    pub const fn as_str(self) -> &'static str {
        match self {
            AxisName::X => "X",
            AxisName::Y => "Y",
            AxisName::Z => "Z",
            AxisName::A => "A",
            AxisName::B => "B",
            AxisName::C => "C",
        }
    }

    /// True for A, B and C.
    pub const fn is_rotary(self) -> bool {
        matches!(self, AxisName::A | AxisName::B | AxisName::C)
    }

    /// The unit positions of this axis are given in: mm (X Y Z) or deg (A B C).
    pub const fn unit(self) -> Unit {
        if self.is_rotary() {
            Unit::Deg
        } else {
            Unit::Mm
        }
    }
}

impl fmt::Display for AxisName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A string that names no axis.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown axis '{0}': expected one of X Y Z A B C")]
pub struct UnknownAxis(pub String);

impl FromStr for AxisName {
    type Err = UnknownAxis;

    /// One letter, either case, surrounding white space ignored.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim();
        let mut chars = t.chars();
        match (chars.next(), chars.next()) {
            (Some(c), None) => AxisName::from_letter(c).ok_or_else(|| UnknownAxis(s.to_string())),
            _ => Err(UnknownAxis(s.to_string())),
        }
    }
}

impl TryFrom<char> for AxisName {
    type Error = UnknownAxis;

    fn try_from(c: char) -> Result<Self, Self::Error> {
        AxisName::from_letter(c).ok_or_else(|| UnknownAxis(c.to_string()))
    }
}

impl Serialize for AxisName {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl<'de> Deserialize<'de> for AxisName {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// Axis unit: millimetres for linear axes, degrees for rotary axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Unit {
    /// Millimetres (X, Y, Z).
    Mm,
    /// Degrees (A, B, C).
    Deg,
}

impl Unit {
    /// `"mm"` or `"deg"`.
    pub const fn as_str(self) -> &'static str {
        match self {
            Unit::Mm => "mm",
            Unit::Deg => "deg",
        }
    }

    /// Unit of reported errors: µm for mm axes, millidegrees for deg axes, as written in
    /// summary keys (`freerun_rms_um`, `freerun_rms_mdeg`).
    pub const fn micro_label(self) -> &'static str {
        match self {
            Unit::Mm => "um",
            Unit::Deg => "mdeg",
        }
    }

    /// The same unit as printed for people (`µm`, `mdeg`).
    pub const fn micro_symbol(self) -> &'static str {
        match self {
            Unit::Mm => "µm",
            Unit::Deg => "mdeg",
        }
    }

    /// Factor from the axis unit to the reporting unit (µm or mdeg): 1000 for both.
    pub const fn micro_factor(self) -> f64 {
        1000.0
    }
}

impl fmt::Display for Unit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn letters_round_trip_in_canonical_order() {
        for (i, a) in AxisName::ALL.iter().enumerate() {
            assert_eq!(a.index(), i);
            assert_eq!(AxisName::from_index(i), Some(*a));
            assert_eq!(AxisName::from_letter(a.letter()), Some(*a));
            assert_eq!(a.as_str().parse::<AxisName>(), Ok(*a));
            assert_eq!(a.letter().to_ascii_lowercase().to_string().parse(), Ok(*a));
        }
        assert!("XY".parse::<AxisName>().is_err());
        assert!("".parse::<AxisName>().is_err());
        assert!(AxisName::X < AxisName::C);
    }

    #[test]
    fn units_follow_the_axis_kind() {
        assert_eq!(AxisName::Y.unit(), Unit::Mm);
        assert_eq!(AxisName::B.unit(), Unit::Deg);
        assert_eq!(Unit::Deg.micro_label(), "mdeg");
    }

    #[test]
    fn serde_uses_the_letter() {
        assert_eq!(serde_json::to_string(&AxisName::A).unwrap(), "\"A\"");
        let a: AxisName = serde_json::from_str("\"z\"").unwrap();
        assert_eq!(a, AxisName::Z);
        assert!(serde_json::from_str::<AxisName>("\"W\"").is_err());
        assert_eq!(serde_json::to_string(&Unit::Mm).unwrap(), "\"mm\"");
    }
}
