//! The one plotting style of every vcnc figure: colours and strokes per [`Role`], fonts and
//! sizes, axis labels written as "quantity (unit)", and the sequential colour map.
//!
//! Nothing in a figure builder chooses a colour, a font size or a line width: they come from
//! here, so a role looks the same in every command's figures.
//!
//! Colours are the eight-colour palette of Okabe & Ito (*Color Universal Design*, 2008), chosen
//! to stay distinguishable with the common colour-vision deficiencies; the colour map is
//! viridis (van der Walt & Smith, matplotlib), perceptually uniform and colour-blind safe.

use crate::svg::Stroke;

/// What a curve *is*, which fixes its colour, width, dash and drawing order in every figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// The commanded signal (reference position, reference tool path): grey, thin, dashed.
    Reference,
    /// The true machine (the simulated plant, the truth of a virtual experiment): blue, thick,
    /// drawn first so that thinner curves on top of it stay visible.
    TrueMachine,
    /// What was measured (a recorded trace, a scope file): black, medium, drawn first.
    Measurement,
    /// vcnc's identified model: vermillion, thin, drawn last (on top).
    Model,
    /// The paper's method (PSO on the equation error, no refinement): bluish green, dashed.
    Paper,
    /// Any other series (PSO best and mean, sweep results), by index: sky blue, reddish purple,
    /// orange, then the others again.
    Other(u8),
}

impl Role {
    /// `#rrggbb` of the role.
    pub fn colour(self) -> &'static str {
        match self {
            Role::Reference => GREY,
            Role::TrueMachine => OKABE_ITO_BLUE,
            Role::Measurement => BLACK,
            Role::Model => OKABE_ITO_VERMILLION,
            Role::Paper => OKABE_ITO_BLUISH_GREEN,
            Role::Other(i) => {
                const OTHERS: [&str; 4] = [
                    OKABE_ITO_SKY_BLUE,
                    OKABE_ITO_REDDISH_PURPLE,
                    OKABE_ITO_ORANGE,
                    BLACK,
                ];
                OTHERS[i as usize % OTHERS.len()]
            }
        }
    }

    /// Line width, px.
    pub fn width_px(self) -> f64 {
        match self {
            Role::TrueMachine => 3.2,
            Role::Measurement => 2.6,
            Role::Reference => 1.1,
            Role::Model => 1.3,
            Role::Paper => 1.4,
            Role::Other(_) => 1.6,
        }
    }

    /// Dash pattern, px (empty: solid).
    pub fn dash_px(self) -> &'static [f64] {
        match self {
            Role::Reference => &[6.0, 3.0],
            Role::Paper => &[5.0, 3.0],
            _ => &[],
        }
    }

    /// Drawing order: lower first. Thick "truth" curves go below thin model curves.
    pub fn z_order(self) -> u8 {
        match self {
            Role::TrueMachine | Role::Measurement => 0,
            Role::Other(_) => 1,
            Role::Reference => 2,
            Role::Paper => 3,
            Role::Model => 4,
        }
    }

    /// Default legend text of the role.
    pub fn default_label(self) -> &'static str {
        match self {
            Role::Reference => "reference",
            Role::TrueMachine => "true machine",
            Role::Measurement => "measurement",
            Role::Model => "vcnc model",
            Role::Paper => "paper's method",
            Role::Other(_) => "series",
        }
    }

    pub(crate) fn stroke(self) -> Stroke {
        Stroke {
            colour: self.colour().to_string(),
            width_px: self.width_px(),
            dash_px: self.dash_px().to_vec(),
            opacity: 1.0,
        }
    }
}

/// Okabe–Ito blue.
pub const OKABE_ITO_BLUE: &str = "#0072b2";
/// Okabe–Ito vermillion.
pub const OKABE_ITO_VERMILLION: &str = "#d55e00";
/// Okabe–Ito bluish green.
pub const OKABE_ITO_BLUISH_GREEN: &str = "#009e73";
/// Okabe–Ito sky blue.
pub const OKABE_ITO_SKY_BLUE: &str = "#56b4e9";
/// Okabe–Ito reddish purple.
pub const OKABE_ITO_REDDISH_PURPLE: &str = "#cc79a7";
/// Okabe–Ito orange.
pub const OKABE_ITO_ORANGE: &str = "#e69f00";
/// Black.
pub const BLACK: &str = "#000000";
/// Neutral grey (reference curves).
pub const GREY: &str = "#666666";

/// Fonts: the SVG names a family list; the viewer picks the first it has (DejaVu Sans ships
/// with Debian and has µ, −, ² and the superscript digits).
pub const FONT_FAMILY: &str = "DejaVu Sans, Helvetica, Arial, sans-serif";
/// Tick labels, px.
pub const TICK_FONT_PX: f64 = 11.0;
/// Axis labels and legend entries, px.
pub const LABEL_FONT_PX: f64 = 12.5;
/// Figure title, px.
pub const TITLE_FONT_PX: f64 = 14.5;
/// Panel title (inside a multi-panel figure), px.
pub const PANEL_TITLE_FONT_PX: f64 = 12.5;
/// Frame and tick colour.
pub const AXIS_COLOUR: &str = "#333333";
/// Major grid lines.
pub const GRID_COLOUR: &str = "#dddddd";
/// Minor grid lines (log axes).
pub const MINOR_GRID_COLOUR: &str = "#efefef";
/// Tick length, px.
pub const TICK_PX: f64 = 5.0;
/// Minor tick length, px.
pub const MINOR_TICK_PX: f64 = 3.0;
/// Default figure width, px.
pub const FIGURE_WIDTH_PX: f64 = 960.0;

/// Approximate advance width of a string in px at `size_px` (DejaVu Sans averages about
/// 0.6 em per character for digits and lower case). Used only to lay out labels so they do
/// not overlap; a viewer with another font may differ by a few px.
pub fn text_width_px(s: &str, size_px: f64) -> f64 {
    let mut em = 0.0;
    for c in s.chars() {
        em += match c {
            'i' | 'l' | 'j' | '.' | ',' | ':' | ';' | '|' | '\'' | '!' => 0.30,
            'f' | 't' | 'r' | '(' | ')' | '[' | ']' | ' ' | '/' => 0.38,
            'm' | 'w' | 'M' | 'W' => 0.90,
            'A'..='Z' => 0.70,
            '−' | '-' => 0.55,
            _ => 0.62,
        };
    }
    em * size_px
}

/// An axis label: quantity and unit, written "quantity (unit)"; a dimensionless quantity has
/// an empty unit and is written alone.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Quantity {
    /// What is measured, e.g. "tracking error x_r − x".
    pub name: String,
    /// Its unit as printed: "µm", "mrad", "mm/s", "Hz", "dB", "deg", "s", "mm" (empty if none).
    pub unit: String,
}

impl Quantity {
    /// A quantity with a unit.
    pub fn new(name: impl Into<String>, unit: impl Into<String>) -> Quantity {
        Quantity {
            name: name.into(),
            unit: unit.into(),
        }
    }

    /// The text printed along the axis.
    pub fn label(&self) -> String {
        if self.unit.is_empty() {
            self.name.clone()
        } else {
            format!("{} ({})", self.name, self.unit)
        }
    }
}

/// The printed unit of errors of an axis measured in `unit`: µm for mm axes, mdeg for deg axes.
pub fn error_unit(unit: vcnc_axis::Unit) -> &'static str {
    unit.micro_symbol()
}

/// Common units, as printed (real µ, not "u").
pub mod units {
    /// Micrometres.
    pub const UM: &str = "µm";
    /// Millimetres.
    pub const MM: &str = "mm";
    /// Milliradians.
    pub const MRAD: &str = "mrad";
    /// Millidegrees.
    pub const MDEG: &str = "mdeg";
    /// Degrees.
    pub const DEG: &str = "deg";
    /// Millimetres per second.
    pub const MM_PER_S: &str = "mm/s";
    /// Hertz.
    pub const HZ: &str = "Hz";
    /// Decibels.
    pub const DB: &str = "dB";
    /// Seconds.
    pub const S: &str = "s";
}

/// viridis at eleven evenly spaced stops (matplotlib's table, rounded to 8 bits).
const VIRIDIS: [(u8, u8, u8); 11] = [
    (68, 1, 84),
    (72, 36, 117),
    (65, 68, 135),
    (53, 95, 141),
    (42, 120, 142),
    (33, 145, 140),
    (34, 168, 132),
    (68, 191, 112),
    (122, 209, 81),
    (189, 223, 38),
    (253, 231, 37),
];

/// The colour of `f` in [0, 1] on the sequential map (values outside are clamped, NaN → 0).
pub fn colour_map(f: f64) -> (u8, u8, u8) {
    let f = if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = f * (VIRIDIS.len() - 1) as f64;
    let i = (s.floor() as usize).min(VIRIDIS.len() - 2);
    let t = s - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |p: u8, q: u8| (p as f64 + t * (q as f64 - p as f64)).round() as u8;
    (mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// `#rrggbb` of an RGB triple.
pub fn hex((r, g, b): (u8, u8, u8)) -> String {
    format!("#{r:02x}{g:02x}{b:02x}")
}

/// Number of discrete colours a coloured path is drawn with (one SVG path per colour).
pub const COLOUR_LEVELS: usize = 64;

/// Text colour readable on a background colour (black on light, white on dark).
pub(crate) fn text_on((r, g, b): (u8, u8, u8)) -> &'static str {
    let lum = 0.2126 * r as f64 + 0.7152 * g as f64 + 0.0722 * b as f64;
    if lum > 140.0 { "#000000" } else { "#ffffff" }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_fixed_role_has_its_own_colour() {
        let roles = [
            Role::Reference,
            Role::TrueMachine,
            Role::Measurement,
            Role::Model,
            Role::Paper,
            Role::Other(0),
            Role::Other(1),
            Role::Other(2),
        ];
        for (i, a) in roles.iter().enumerate() {
            for b in &roles[i + 1..] {
                assert_ne!(a.colour(), b.colour(), "{a:?} and {b:?} share a colour");
            }
        }
    }

    #[test]
    fn colour_map_ends_are_viridis_ends() {
        assert_eq!(hex(colour_map(0.0)), "#440154");
        assert_eq!(hex(colour_map(1.0)), "#fde725");
        assert_eq!(hex(colour_map(f64::NAN)), "#440154");
        assert_eq!(colour_map(0.5), (33, 145, 140));
    }

    #[test]
    fn labels_carry_quantity_and_unit() {
        assert_eq!(
            Quantity::new("contour error", units::UM).label(),
            "contour error (µm)"
        );
        assert_eq!(Quantity::new("cost", "").label(), "cost");
        assert_eq!(error_unit(vcnc_axis::Unit::Mm), "µm");
    }
}
