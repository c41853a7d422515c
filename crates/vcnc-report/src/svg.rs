//! A minimal SVG writer: the handful of elements the figures need, written as text.
//!
//! Why not plotters' SVG backend (the binary's plots used it): it places every coordinate on an
//! integer pixel grid (`BackendCoord = (i32, i32)`), which is where the stair-steps on flat
//! curves came from, and it has no dash arrays, clip paths or grouped styles, so dashed lines
//! became thousands of separate segments and every segment repeated its style. SVG is a text
//! format that the report inlines anyway; writing its few elements here keeps coordinates at
//! 0.1 px, paths relative (`l dx dy`) and files small.

use std::fmt::Write as _;

/// Horizontal anchor of a text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Anchor {
    Start,
    Middle,
    End,
}

impl Anchor {
    fn as_str(self) -> &'static str {
        match self {
            Anchor::Start => "start",
            Anchor::Middle => "middle",
            Anchor::End => "end",
        }
    }
}

/// Stroke of a line or path.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Stroke {
    /// `#rrggbb`.
    pub colour: String,
    /// Width, px.
    pub width_px: f64,
    /// Dash pattern, px (empty: solid).
    pub dash_px: Vec<f64>,
    /// Opacity in [0, 1].
    pub opacity: f64,
}

impl Stroke {
    pub fn solid(colour: &str, width_px: f64) -> Stroke {
        Stroke {
            colour: colour.to_string(),
            width_px,
            dash_px: Vec::new(),
            opacity: 1.0,
        }
    }

    fn attrs(&self, out: &mut String) {
        let _ = write!(
            out,
            " fill=\"none\" stroke=\"{}\" stroke-width=\"{}\"",
            self.colour,
            num(self.width_px)
        );
        if !self.dash_px.is_empty() {
            let d: Vec<String> = self.dash_px.iter().map(|v| num(*v)).collect();
            let _ = write!(out, " stroke-dasharray=\"{}\"", d.join(" "));
        }
        if self.opacity < 1.0 {
            let _ = write!(out, " stroke-opacity=\"{}\"", num(self.opacity));
        }
    }
}

/// A number with at most two decimals, no trailing zeros (`12`, `12.5`, `-0.25`).
pub(crate) fn num(v: f64) -> String {
    let r = (v * 100.0).round() / 100.0;
    let r = if r == 0.0 { 0.0 } else { r };
    let s = format!("{r:.2}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

/// Coordinates are written in tenths of a pixel; points beyond this are outside any figure and
/// are pulled in (the clip path hides them) so that absurd values cannot bloat the file.
const LIMIT_TENTHS: i64 = 1_000_000;

fn tenths(v: f64) -> i64 {
    if v.is_nan() {
        return 0;
    }
    ((v * 10.0).round() as i64).clamp(-LIMIT_TENTHS, LIMIT_TENTHS)
}

/// Writes an integer count of tenths as a decimal (`13` → `1.3`, `-5` → `-.5`, `20` → `2`).
fn push_tenths(out: &mut String, t: i64) {
    let neg = t < 0;
    let a = t.unsigned_abs();
    if neg {
        out.push('-');
    }
    let (int, frac) = (a / 10, a % 10);
    if int != 0 || frac == 0 {
        let _ = write!(out, "{int}");
    }
    if frac != 0 {
        let _ = write!(out, ".{frac}");
    }
}

/// Appends the `d` data of a polyline to `d`: `M x y` then relative `l` steps; points that
/// round to the same tenth of a pixel as the previous one are dropped.
pub(crate) fn push_polyline_data(d: &mut String, pts: &[(f64, f64)]) {
    let mut prev: Option<(i64, i64)> = None;
    let mut in_l = false;
    for &(x, y) in pts {
        let p = (tenths(x), tenths(y));
        match prev {
            None => {
                if !d.is_empty() {
                    d.push(' ');
                }
                d.push('M');
                push_tenths(d, p.0);
                d.push(' ');
                push_tenths(d, p.1);
            }
            Some(q) if q == p => continue,
            Some(q) => {
                if in_l {
                    d.push(' ');
                } else {
                    d.push('l');
                    in_l = true;
                }
                push_tenths(d, p.0 - q.0);
                d.push(' ');
                push_tenths(d, p.1 - q.1);
            }
        }
        prev = Some(p);
    }
    // A single point draws nothing with a plain `M`: make it a zero-length segment so that a
    // round cap shows it as a dot (an isolated sample between two gaps is still visible).
    if let Some(_p) = prev
        && !in_l
    {
        d.push_str("l0 0");
    }
}

/// A line segment from one point (px) to another.
pub(crate) type Segment = ((f64, f64), (f64, f64));

/// An SVG document under construction. Coordinates are px from the top-left corner.
pub(crate) struct Svg {
    pub width: f64,
    pub height: f64,
    body: String,
    defs: String,
    next_id: usize,
}

/// Prefix of every `id` this writer makes; the report rewrites it per figure so that several
/// inlined figures never share an id.
pub(crate) const ID_PREFIX: &str = "vcnc-id-";

impl Svg {
    pub fn new(width: f64, height: f64) -> Svg {
        Svg {
            width,
            height,
            body: String::new(),
            defs: String::new(),
            next_id: 0,
        }
    }

    /// A clip rectangle; returns its id (use with [`Svg::open_group_clipped`]).
    pub fn clip_rect(&mut self, x: f64, y: f64, w: f64, h: f64) -> String {
        let id = format!("{ID_PREFIX}{}", self.next_id);
        self.next_id += 1;
        let _ = write!(
            self.defs,
            "<clipPath id=\"{id}\"><rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"/></clipPath>",
            num(x),
            num(y),
            num(w),
            num(h)
        );
        id
    }

    pub fn open_group_clipped(&mut self, clip_id: &str) {
        let _ = write!(self.body, "<g clip-path=\"url(#{clip_id})\">");
    }

    pub fn close_group(&mut self) {
        self.body.push_str("</g>");
    }

    pub fn rect(&mut self, x: f64, y: f64, w: f64, h: f64, fill: &str, stroke: Option<&Stroke>) {
        let _ = write!(
            self.body,
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"",
            num(x),
            num(y),
            num(w),
            num(h)
        );
        self.close_shape(fill, stroke);
    }

    /// Ends a shape's element opened by the caller: its fill and its optional stroke.
    fn close_shape(&mut self, fill: &str, stroke: Option<&Stroke>) {
        let _ = write!(self.body, " fill=\"{fill}\"");
        if let Some(s) = stroke {
            let _ = write!(
                self.body,
                " stroke=\"{}\" stroke-width=\"{}\"",
                s.colour,
                num(s.width_px)
            );
        }
        self.body.push_str("/>");
    }

    pub fn line(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, stroke: &Stroke) {
        let mut d = String::new();
        push_polyline_data(&mut d, &[(x0, y0), (x1, y1)]);
        self.path_d(&d, stroke);
    }

    /// Several line segments with one stroke, as one `<path>` (grid lines, ticks).
    pub fn segments(&mut self, segs: &[Segment], stroke: &Stroke) {
        if segs.is_empty() {
            return;
        }
        let mut d = String::new();
        for (a, b) in segs {
            push_polyline_data(&mut d, &[*a, *b]);
        }
        self.path_d(&d, stroke);
    }

    /// One path element from prepared `d` data.
    pub fn path_d(&mut self, d: &str, stroke: &Stroke) {
        if d.is_empty() {
            return;
        }
        self.body.push_str("<path");
        stroke.attrs(&mut self.body);
        let _ = write!(
            self.body,
            " stroke-linejoin=\"round\" stroke-linecap=\"round\" d=\"{d}\"/>"
        );
    }

    /// A filled polygon.
    pub fn polygon(&mut self, pts: &[(f64, f64)], fill: &str) {
        let mut d = String::new();
        push_polyline_data(&mut d, pts);
        let _ = write!(self.body, "<path fill=\"{fill}\" d=\"{d}Z\"/>");
    }

    pub fn circle(&mut self, cx: f64, cy: f64, r: f64, fill: &str, stroke: Option<&Stroke>) {
        let _ = write!(
            self.body,
            "<circle cx=\"{}\" cy=\"{}\" r=\"{}\"",
            num(cx),
            num(cy),
            num(r)
        );
        self.close_shape(fill, stroke);
    }

    /// Plain text; `rotate_deg` turns it about its anchor point (−90: reads bottom to top).
    #[allow(clippy::too_many_arguments)]
    pub fn text(
        &mut self,
        x: f64,
        y: f64,
        text: &str,
        size_px: f64,
        anchor: Anchor,
        rotate_deg: f64,
        colour: &str,
    ) {
        self.text_markup(
            x,
            y,
            &escape(text),
            size_px,
            anchor,
            rotate_deg,
            colour,
            false,
        );
    }

    /// Text whose content is already SVG markup (escaped text and `<tspan>`s).
    #[allow(clippy::too_many_arguments)]
    pub fn text_markup(
        &mut self,
        x: f64,
        y: f64,
        markup: &str,
        size_px: f64,
        anchor: Anchor,
        rotate_deg: f64,
        colour: &str,
        bold: bool,
    ) {
        let _ = write!(
            self.body,
            "<text x=\"{}\" y=\"{}\" font-size=\"{}\"",
            num(x),
            num(y),
            num(size_px)
        );
        if anchor != Anchor::Start {
            let _ = write!(self.body, " text-anchor=\"{}\"", anchor.as_str());
        }
        if rotate_deg != 0.0 {
            let _ = write!(
                self.body,
                " transform=\"rotate({} {} {})\"",
                num(rotate_deg),
                num(x),
                num(y)
            );
        }
        if colour != "#000000" {
            let _ = write!(self.body, " fill=\"{colour}\"");
        }
        if bold {
            self.body.push_str(" font-weight=\"bold\"");
        }
        let _ = write!(self.body, ">{markup}</text>");
    }

    /// Text with a white halo (legible over curves), e.g. block labels on a path.
    pub fn text_halo(&mut self, x: f64, y: f64, text: &str, size_px: f64, anchor: Anchor) {
        let _ = write!(
            self.body,
            "<text x=\"{}\" y=\"{}\" font-size=\"{}\" text-anchor=\"{}\" stroke=\"#ffffff\" stroke-width=\"3\" stroke-linejoin=\"round\" paint-order=\"stroke\">{}</text>",
            num(x),
            num(y),
            num(size_px),
            anchor.as_str(),
            escape(text)
        );
    }

    /// A `<title>` for the whole document (read by screen readers and shown as a tooltip).
    pub fn finish(self, title: &str, font_family: &str) -> String {
        let mut s = String::with_capacity(self.body.len() + self.defs.len() + 400);
        let _ = write!(
            s,
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"{font_family}\">",
            w = num(self.width),
            h = num(self.height)
        );
        let _ = write!(s, "<title>{}</title>", escape(title));
        if !self.defs.is_empty() {
            let _ = write!(s, "<defs>{}</defs>", self.defs);
        }
        let _ = write!(
            s,
            "<rect width=\"{}\" height=\"{}\" fill=\"#ffffff\"/>",
            num(self.width),
            num(self.height)
        );
        s.push_str(&self.body);
        s.push_str("</svg>\n");
        s
    }
}

/// Escapes text for XML content and attribute values.
pub(crate) fn escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            _ => o.push(c),
        }
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tenths_are_written_exactly_and_relative_steps_do_not_drift() {
        let mut d = String::new();
        push_polyline_data(
            &mut d,
            &[(1.0, 2.0), (1.34, 2.0), (0.5, -1.25), (0.5, -1.25)],
        );
        assert_eq!(d, "M1 2l.3 0 -.8 -3.3");
        // Summing the relative steps gives back the last point to the tenth.
        let mut d2 = String::new();
        let pts: Vec<(f64, f64)> = (0..1000).map(|k| (k as f64 * 0.37, 5.0)).collect();
        push_polyline_data(&mut d2, &pts);
        let mut sum = 0.0;
        for (i, tok) in d2.trim_start_matches('M').split(['l', ' ']).enumerate() {
            if i % 2 == 0 {
                sum += tok.parse::<f64>().unwrap();
            }
        }
        approx::assert_abs_diff_eq!(sum, 999.0 * 0.37, epsilon = 0.051);
    }

    #[test]
    fn numbers_are_short() {
        assert_eq!(num(12.0), "12");
        assert_eq!(num(-0.25), "-0.25");
        assert_eq!(num(-0.0001), "0");
        assert_eq!(escape("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
    }

    #[test]
    fn a_lone_point_is_drawn_as_a_dot() {
        let mut d = String::new();
        push_polyline_data(&mut d, &[(3.0, 4.0)]);
        assert_eq!(d, "M3 4l0 0");
    }
}
