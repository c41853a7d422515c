//! Which axis a channel belongs to and what it measures, from its name.
//!
//! A name is cut into words at every character that is not a letter or digit and at camel-case
//! humps (`fbAxisX.NcToPlc.ActPos` → `fb axis x nc to plc act pos`). Then:
//!
//! * **Axis.** A word that is an axis letter `x y z a b c`, optionally followed by digits (`X1`,
//!   the Sinumerik machine-axis names) or by a quantity suffix (`xr`, `xpos`, `xcmd`, `xfb`), names
//!   the axis. In LinuxCNC files a joint number also does: `joint.N.…` and, before 2.8,
//!   `axis.N.…`, through the joint map (default `XYZABC`). Two different axes in one name, or
//!   none, leave the axis unknown.
//! * **Quantity.** Words for a following error or an acceleration make it [`Quantity::Other`];
//!   otherwise current words (`current`, `i`, `strom`) make it [`Quantity::Current`]; velocity
//!   words (`vel`, `velo`, `velocity`, `speed`, `v`, `drehzahl`) or position words (`pos`,
//!   `position`, `s`, `lage`) choose the kind, and a side word chooses nominal (`cmd`, `command`,
//!   `set`, `setpoint`, `soll`, `ref`, `r`, `nom`, `demand`) or actual (`fb`, `feedback`, `act`,
//!   `actual`, `ist`, `meas`, `measured`, `enc`). An axis word with a side but no kind is a
//!   position (`xr`, `X_cmd`); a name that is nothing but an axis letter is the actual position
//!   (the `t, xr, x` layout). No side, or both sides, leaves [`Quantity::Other`].
//!
//! German compounds of Sinumerik screens are known whole (`Lagesollwert`, `Lageistwert`,
//! `Drehzahlsollwert`, `Drehzahlistwert`, `Schleppabstand`).

use vcnc_axis::AxisName;

use crate::model::{AxisSource, Quantity};

/// A word of a name.
struct Word {
    /// Lower case.
    lower: String,
    /// As written.
    original: String,
    /// A one-letter lower-case prefix glued to a capitalised word (`bEnable`, `fPos`, `sName`):
    /// the type prefix of PLC naming conventions, not an axis letter or a quantity.
    prefix: bool,
}

/// Cuts a name into words (see the module documentation).
fn cut(name: &str) -> Vec<Word> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut run_start = true;
    let chars: Vec<char> = name.chars().collect();
    let push = |cur: &mut String, out: &mut Vec<Word>, prefix: bool| {
        if !cur.is_empty() {
            out.push(Word {
                lower: cur.to_lowercase(),
                original: std::mem::take(cur),
                prefix,
            });
        }
    };
    for (i, &c) in chars.iter().enumerate() {
        if !c.is_alphanumeric() {
            push(&mut cur, &mut out, false);
            run_start = true;
            continue;
        }
        if !cur.is_empty() && c.is_uppercase() {
            let prev = chars[i - 1];
            let next_lower = chars.get(i + 1).is_some_and(|n| n.is_lowercase());
            // fooBar → foo|Bar; XMLFile → XML|File; but X1, REAL64 and AxisX stay as cut.
            if prev.is_lowercase() || (prev.is_uppercase() && next_lower) {
                let prefix = run_start && cur.chars().count() == 1 && prev.is_lowercase();
                push(&mut cur, &mut out, prefix);
                run_start = false;
            }
        }
        cur.push(c);
    }
    push(&mut cur, &mut out, false);
    out
}

/// Words of a name, lower case (see the module documentation).
pub(crate) fn words(name: &str) -> Vec<String> {
    cut(name).into_iter().map(|w| w.lower).collect()
}

const SIDE_SUFFIXES: &[&str] = &[
    "r", "ref", "cmd", "nom", "soll", "pos", "position", "fb", "act", "ist", "meas", "vel", "velo",
    "set", "setpos", "actpos",
];

/// The axis a word names, with the quantity suffix it carries (`xr` → X, `r`).
fn axis_word(w: &str) -> Option<(AxisName, &str)> {
    let mut chars = w.chars();
    let axis = AxisName::from_letter(chars.next()?)?;
    let rest = chars.as_str();
    let after_digits = rest.trim_start_matches(|c: char| c.is_ascii_digit());
    if after_digits.is_empty() {
        return Some((axis, ""));
    }
    if after_digits.len() == rest.len() && SIDE_SUFFIXES.contains(&rest) {
        return Some((axis, rest));
    }
    None
}

/// The axis found in `name`, how, and the quantity suffix of the axis word.
pub(crate) fn axis_of(
    name: &str,
    field: &str,
    joints: Option<&[AxisName]>,
) -> Option<(AxisName, AxisSource, String)> {
    let cut = cut(name);
    let ws: Vec<&str> = cut.iter().map(|w| w.lower.as_str()).collect();
    let mut found: Option<(AxisName, AxisSource, String)> = None;
    let mut conflict = false;
    let mut note = |axis: AxisName, source: AxisSource, suffix: &str| match &found {
        Some((a, _, _)) if *a != axis => conflict = true,
        Some(_) => {}
        None => found = Some((axis, source, suffix.to_string())),
    };
    for (i, w) in ws.iter().enumerate() {
        if cut[i].prefix {
            continue;
        }
        if let Some(map) = joints {
            let is_joint_word = *w == "joint" || *w == "axis";
            if is_joint_word && let Some(n) = ws.get(i + 1).and_then(|n| n.parse::<usize>().ok()) {
                if let Some(&axis) = map.get(n) {
                    let letters: String = map.iter().map(|a| a.letter()).collect();
                    note(
                        axis,
                        AxisSource::Joint {
                            joint: n,
                            map: letters,
                        },
                        "",
                    );
                }
                continue;
            }
        }
        if let Some((axis, suffix)) = axis_word(w) {
            let token = cut[i].original.clone();
            note(
                axis,
                AxisSource::Token {
                    field: field.to_string(),
                    token,
                },
                suffix,
            );
        }
    }
    if conflict { None } else { found }
}

const OTHER_WORDS: &[&str] = &[
    "error",
    "err",
    "ferror",
    "following",
    "deviation",
    "schleppabstand",
    "acc",
    "accel",
    "acceleration",
    "jerk",
    "torque",
    "moment",
    "force",
];
const CURRENT_WORDS: &[&str] = &[
    "current",
    "i",
    "iq",
    "strom",
    "stromistwert",
    "stromsollwert",
];
const VELOCITY_WORDS: &[&str] = &[
    "vel",
    "velo",
    "velocity",
    "speed",
    "v",
    "feed",
    "drehzahl",
    "geschwindigkeit",
    "drehzahlsollwert",
    "drehzahlistwert",
];
const POSITION_WORDS: &[&str] = &[
    "pos",
    "position",
    "s",
    "lage",
    "lagesollwert",
    "lageistwert",
    "setpos",
    "actpos",
];
const NOMINAL_WORDS: &[&str] = &[
    "cmd",
    "command",
    "commanded",
    "set",
    "setpoint",
    "setpos",
    "soll",
    "sollwert",
    "ref",
    "reference",
    "r",
    "nom",
    "nominal",
    "demand",
    "lagesollwert",
    "drehzahlsollwert",
];
const ACTUAL_WORDS: &[&str] = &[
    "fb",
    "feedback",
    "act",
    "actpos",
    "actual",
    "ist",
    "istwert",
    "meas",
    "measured",
    "enc",
    "encoder",
    "lageistwert",
    "drehzahlistwert",
];

/// The quantity `name` measures; `axis_suffix` is the suffix of its axis word (`r` of `xr`).
pub(crate) fn quantity_of(name: &str, axis_suffix: &str) -> Quantity {
    let ws: Vec<String> = cut(name)
        .into_iter()
        .filter(|w| !w.prefix)
        .map(|w| w.lower)
        .collect();
    let has =
        |set: &[&str]| ws.iter().any(|w| set.contains(&w.as_str())) || set.contains(&axis_suffix);
    if has(OTHER_WORDS) {
        return Quantity::Other;
    }
    if has(CURRENT_WORDS) && !has(POSITION_WORDS) {
        return Quantity::Current;
    }
    let nominal = has(NOMINAL_WORDS);
    let actual = has(ACTUAL_WORDS);
    let velocity = has(VELOCITY_WORDS);
    let position = has(POSITION_WORDS);
    let axis_word_present = ws.iter().any(|w| axis_word(w).is_some());
    if ws.len() == 1 && axis_word_present && axis_suffix.is_empty() {
        // A bare axis letter: the measured position of the `t, xr, x` layout.
        return Quantity::ActualPosition;
    }
    match (nominal, actual) {
        (true, false) if velocity => Quantity::NominalVelocity,
        (false, true) if velocity => Quantity::ActualVelocity,
        (true, false) if position || axis_word_present => Quantity::NominalPosition,
        (false, true) if position || axis_word_present => Quantity::ActualPosition,
        _ => Quantity::Other,
    }
}

/// The measuring system a name says a position belongs to: `measuring system 2`,
/// `Messsystem 2` / `Meßsystem 2`, `MS2`, `2ndEnc` (2: the direct scale; 1: the motor encoder).
pub(crate) fn measuring_system_of(name: &str) -> Option<u8> {
    let ws = words(name);
    let system = |w: &str| match w {
        "1" | "1st" => Some(1),
        "2" | "2nd" => Some(2),
        _ => None,
    };
    for (i, w) in ws.iter().enumerate() {
        let next = ws.get(i + 1).map(String::as_str);
        let found = match w.as_str() {
            "system" if i > 0 && ws[i - 1] == "measuring" => next.and_then(system),
            "messsystem" | "meßsystem" | "ms" => next.and_then(system),
            "ms1" | "1stenc" | "enc1" => Some(1),
            "ms2" | "2ndenc" | "enc2" => Some(2),
            _ => None,
        };
        if found.is_some() {
            return found;
        }
    }
    None
}

/// The quantity a TNCscope `CHANNELTYPE` states (`s soll`, `s ist`, `v soll`, `v ist`, `I soll`,
/// `I ist`, …); `None` when the type is not one of these.
pub(crate) fn tnc_channel_type(t: &str) -> Option<Quantity> {
    let ws = words(t);
    let (kind, side) = match ws.as_slice() {
        [k, s] => (k.as_str(), s.as_str()),
        _ => return None,
    };
    Some(match (kind, side) {
        ("s", "soll") => Quantity::NominalPosition,
        ("s", "ist") => Quantity::ActualPosition,
        ("v", "soll") => Quantity::NominalVelocity,
        ("v", "ist") => Quantity::ActualVelocity,
        ("i", "soll" | "ist") => Quantity::Current,
        (_, "soll" | "ist") => Quantity::Other,
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const XYZABC: &[AxisName] = &AxisName::ALL;

    fn axis(name: &str, linuxcnc: bool) -> Option<AxisName> {
        axis_of(name, "name", linuxcnc.then_some(XYZABC)).map(|(a, _, _)| a)
    }

    fn q(name: &str) -> Quantity {
        let suffix = axis_of(name, "name", Some(XYZABC))
            .map(|(_, _, s)| s)
            .unwrap_or_default();
        quantity_of(name, &suffix)
    }

    #[test]
    fn words_cut_at_separators_and_humps() {
        assert_eq!(
            words("MAIN.fbAxisX.NcToPlc.ActPos"),
            ["main", "fb", "axis", "x", "nc", "to", "plc", "act", "pos"]
        );
        assert_eq!(
            words("joint.0.motor-pos-cmd"),
            ["joint", "0", "motor", "pos", "cmd"]
        );
        assert_eq!(words("var_REAL64"), ["var", "real64"]);
        assert_eq!(words("XMLFile X1"), ["xml", "file", "x1"]);
    }

    #[test]
    fn axes_from_linuxcnc_names() {
        assert_eq!(axis("joint.0.motor-pos-cmd", true), Some(AxisName::X));
        assert_eq!(axis("joint.4.pos-fb", true), Some(AxisName::B));
        assert_eq!(axis("axis.2.motor-pos-fb", true), Some(AxisName::Z));
        assert_eq!(axis("axis.x.pos-cmd", true), Some(AxisName::X));
        assert_eq!(axis("z-pos-fb", true), Some(AxisName::Z));
        assert_eq!(axis("joint.9.pos-fb", true), None);
        assert_eq!(axis("spindle.0.speed-cmd", true), None);
        let five = [
            AxisName::X,
            AxisName::Y,
            AxisName::Z,
            AxisName::A,
            AxisName::C,
        ];
        let (a, src, _) = axis_of("joint.4.pos-cmd", "name", Some(&five)).unwrap();
        assert_eq!(a, AxisName::C);
        assert_eq!(src.to_string(), "joint 4 (joint map XYZAC)");
        // Joint numbers mean nothing outside LinuxCNC files.
        assert_eq!(axis("joint.0.pos", false), None);
    }

    #[test]
    fn axes_from_other_controls() {
        assert_eq!(
            axis("MAIN.fbAxisY.NcToPlc.SetPos", false),
            Some(AxisName::Y)
        );
        assert_eq!(axis("Lagesollwert X1", false), Some(AxisName::X));
        assert_eq!(axis("X s soll", false), Some(AxisName::X));
        assert_eq!(axis("xr", false), Some(AxisName::X));
        assert_eq!(axis("qm", false), None);
        assert_eq!(axis("MAIN.var_REAL", false), None);
        // Two axes in one name: unknown.
        assert_eq!(axis("X-Y plot", false), None);
        // PLC type prefixes are not axes: bEnable, fPos, nC.
        assert_eq!(axis("bEnable", false), None);
        assert_eq!(axis("MAIN.fActPos", false), None);
        assert_eq!(axis("MAIN.fbAxisC.fActPos", false), Some(AxisName::C));
        let (_, src, _) = axis_of("MAIN.AxisX.ActPos", "symbol", None).unwrap();
        assert_eq!(src.to_string(), "symbol word 'X'");
    }

    #[test]
    fn quantities_from_names() {
        use Quantity::*;
        assert_eq!(q("joint.0.motor-pos-cmd"), NominalPosition);
        assert_eq!(q("joint.0.motor-pos-fb"), ActualPosition);
        assert_eq!(q("joint.0.vel-cmd"), NominalVelocity);
        assert_eq!(q("joint.0.f-error"), Other);
        assert_eq!(q("MAIN.AxisX.NcToPlc.SetPos"), NominalPosition);
        assert_eq!(q("MAIN.AxisX.NcToPlc.ActPos"), ActualPosition);
        assert_eq!(q("MAIN.AxisX.NcToPlc.ActVelo"), ActualVelocity);
        assert_eq!(q("Position setpoint X1"), NominalPosition);
        assert_eq!(
            q("Position actual value measuring system 1 X1"),
            ActualPosition
        );
        assert_eq!(q("Speed setpoint X1"), NominalVelocity);
        assert_eq!(q("Lageistwert X1"), ActualPosition);
        assert_eq!(q("Current actual value X1"), Current);
        assert_eq!(q("xr"), NominalPosition);
        assert_eq!(q("x"), ActualPosition);
        assert_eq!(q("X_cmd"), NominalPosition);
        assert_eq!(q("qg"), Other);
        assert_eq!(q("t"), Other);
        assert_eq!(q("sName"), Other);
        assert_eq!(q("iCount"), Other);
    }

    #[test]
    fn measuring_systems_from_names() {
        assert_eq!(
            measuring_system_of("Position actual value measuring system 2"),
            Some(2)
        );
        assert_eq!(measuring_system_of("Lageistwert Meßsystem 1"), Some(1));
        assert_eq!(measuring_system_of("Lageistwert Messsystem 2 X1"), Some(2));
        assert_eq!(measuring_system_of("Position setpoint X1"), None);
        assert_eq!(measuring_system_of("speed ms 1"), Some(1));
    }

    #[test]
    fn tncscope_channel_types() {
        assert_eq!(tnc_channel_type("s soll"), Some(Quantity::NominalPosition));
        assert_eq!(tnc_channel_type("S IST"), Some(Quantity::ActualPosition));
        assert_eq!(tnc_channel_type("v ist"), Some(Quantity::ActualVelocity));
        assert_eq!(tnc_channel_type("I ist"), Some(Quantity::Current));
        assert_eq!(tnc_channel_type("a soll"), Some(Quantity::Other));
        assert_eq!(tnc_channel_type("PLC"), None);
    }
}
