//! Axis ticks: "nice" linear steps (1, 2, 2.5, 5 × 10ⁿ) and log axes with decade labels
//! (0.1, 1, 10, 100 … or 10ⁿ) and minor ticks at 2 … 9 × 10ⁿ.

use crate::svg::escape;

/// One labelled tick.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Tick {
    /// Position in data units.
    pub value: f64,
    /// Label as plain text (for width estimates).
    pub text: String,
    /// Label as SVG text content (may hold a superscript `<tspan>`).
    pub markup: String,
}

/// Ticks of one axis.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Ticks {
    pub major: Vec<Tick>,
    pub minor: Vec<f64>,
    /// A common factor the labels were divided by, to print after the axis label (`×10⁻⁶`).
    pub factor_text: Option<String>,
}

/// The minus sign typographers use (U+2212), not the hyphen.
pub(crate) const MINUS: char = '−';

fn with_minus(s: String) -> String {
    if let Some(rest) = s.strip_prefix('-') {
        format!("{MINUS}{rest}")
    } else {
        s
    }
}

/// Superscript digits for exponents in plain text.
pub(crate) fn superscript(n: i32) -> String {
    const D: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut s = String::new();
    if n < 0 {
        s.push('⁻');
    }
    for c in n.unsigned_abs().to_string().chars() {
        s.push(D[c.to_digit(10).unwrap_or(0) as usize]);
    }
    s
}

/// A step of 1, 2, 2.5 or 5 × 10ⁿ near `raw`.
fn nice_step(raw: f64) -> f64 {
    let e = raw.log10().floor();
    let base = 10f64.powf(e);
    let m = raw / base;
    // The nice value nearest `raw` on a log scale (thresholds near the geometric means).
    let nice = if m < 1.45 {
        1.0
    } else if m < 2.24 {
        2.0
    } else if m < 3.5 {
        2.5
    } else if m < 7.1 {
        5.0
    } else {
        10.0
    };
    nice * base
}

/// Number of decimals needed to print multiples of `step` exactly.
fn decimals(step: f64) -> usize {
    for d in 0..12 {
        let s = step * 10f64.powi(d);
        if (s - s.round()).abs() < 1e-6 * s.max(1.0) {
            return d as usize;
        }
    }
    12
}

/// Linear ticks over `[lo, hi]` with about `target` labelled ticks.
pub(crate) fn linear(lo: f64, hi: f64, target: usize) -> Ticks {
    let span = (hi - lo).abs().max(f64::MIN_POSITIVE);
    let step = nice_step(span / target.max(2) as f64);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    let values: Vec<f64> = (first..=last)
        .map(|k| {
            let v = k as f64 * step;
            if v.abs() < step * 1e-9 { 0.0 } else { v }
        })
        .collect();
    let max_abs = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // Very large or very small numbers: a common power of ten goes to the axis label.
    let exp = if max_abs >= 1e5 || (max_abs > 0.0 && max_abs < 1e-3) {
        max_abs.log10().floor() as i32
    } else {
        0
    };
    let scale = 10f64.powi(exp);
    let dec = decimals(step / scale);
    let major = values
        .iter()
        .map(|&v| {
            let text = with_minus(format!("{:.*}", dec, v / scale));
            Tick {
                value: v,
                markup: escape(&text),
                text,
            }
        })
        .collect();
    let minor_step = step
        / if (step / 10f64.powf(step.log10().floor()) - 2.5).abs() < 1e-9 {
            5.0
        } else {
            2.0
        };
    let minor = ((lo / minor_step).ceil() as i64..=(hi / minor_step).floor() as i64)
        .map(|k| k as f64 * minor_step)
        .filter(|v| values.iter().all(|m| (m - v).abs() > minor_step * 1e-6))
        .collect();
    Ticks {
        major,
        minor,
        factor_text: (exp != 0).then(|| format!("×10{}", superscript(exp))),
    }
}

/// Decade label: plain decimals between 0.001 and 100 000, 10ⁿ beyond.
fn decade_label(k: i32, plain: bool) -> (String, String) {
    if plain {
        let text = if k >= 0 {
            format!("{}", 10u64.pow(k as u32))
        } else {
            format!("{:.*}", (-k) as usize, 10f64.powi(k))
        };
        (text.clone(), escape(&text))
    } else {
        let text = format!("10{}", superscript(k));
        let markup = format!(
            "10<tspan dy=\"-0.45em\" font-size=\"75%\">{}</tspan>",
            escape(&with_minus(k.to_string()))
        );
        (text, markup)
    }
}

/// Log ticks over `[lo, hi]` (both > 0): labelled decades, minor ticks at 2 … 9 × 10ⁿ; when the
/// range holds fewer than two decades, 2 × and 5 × 10ⁿ are labelled too.
pub(crate) fn log(lo: f64, hi: f64) -> Ticks {
    let (lo, hi) = (lo.min(hi), hi.max(lo));
    let k0 = lo.log10().floor() as i32;
    let k1 = hi.log10().ceil() as i32;
    let inside = |v: f64| v >= lo * (1.0 - 1e-9) && v <= hi * (1.0 + 1e-9);
    let plain = k0 >= -3 && k1 <= 5;
    let decades: Vec<i32> = (k0..=k1).filter(|&k| inside(10f64.powi(k))).collect();
    // Many decades: label every second or third so labels never collide.
    let every = match decades.len() {
        0..=8 => 1,
        9..=16 => 2,
        _ => 3,
    };
    let mut major = Vec::new();
    let mut minor = Vec::new();
    let few = decades.len() < 2;
    for k in k0..=k1 {
        let d = 10f64.powi(k);
        if inside(d) {
            if k.rem_euclid(every) == 0 {
                let (text, markup) = decade_label(k, plain);
                major.push(Tick {
                    value: d,
                    text,
                    markup,
                });
            } else {
                minor.push(d);
            }
        }
        if every > 1 {
            continue;
        }
        for m in 2..=9 {
            let v = m as f64 * d;
            if !inside(v) {
                continue;
            }
            if few && (m == 2 || m == 5) {
                let text = if plain {
                    let dec = (-k).max(0) as usize;
                    format!("{:.*}", dec, v)
                } else {
                    format!("{m}×10{}", superscript(k))
                };
                major.push(Tick {
                    value: v,
                    markup: escape(&text),
                    text,
                });
            } else {
                minor.push(v);
            }
        }
    }
    major.sort_by(|a, b| a.value.total_cmp(&b.value));
    Ticks {
        major,
        minor,
        factor_text: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(t: &Ticks) -> Vec<&str> {
        t.major.iter().map(|m| m.text.as_str()).collect()
    }

    #[test]
    fn linear_ticks_are_round_and_use_a_real_minus() {
        let t = linear(-0.27, 0.51, 4);
        assert_eq!(labels(&t), ["−0.2", "0.0", "0.2", "0.4"]);
        let t = linear(0.0, 10.0, 5);
        assert_eq!(labels(&t), ["0", "2", "4", "6", "8", "10"]);
        assert!(t.minor.contains(&1.0));
    }

    #[test]
    fn huge_and_tiny_numbers_move_a_power_of_ten_to_the_label() {
        let t = linear(0.0, 3.0e-6, 4);
        assert_eq!(t.factor_text.as_deref(), Some("×10⁻⁶"));
        assert_eq!(labels(&t).last(), Some(&"3"));
    }

    #[test]
    fn bode_frequency_axis_has_decade_labels_without_decimals_and_minor_ticks() {
        let t = log(0.1, 500.0);
        assert_eq!(labels(&t), ["0.1", "1", "10", "100"]);
        assert!(t.minor.iter().any(|v| (v - 200.0).abs() < 1e-9));
        assert!(t.minor.iter().any(|v| (v - 0.3).abs() < 1e-12));
        assert_eq!(t.minor.len(), 8 * 3 + 4); // 0.2…0.9, 2…9, 20…90, 200…500
    }

    #[test]
    fn wide_log_ranges_use_powers_of_ten() {
        let t = log(1e-9, 1e2);
        assert_eq!(t.major.first().map(|m| m.text.as_str()), Some("10⁻⁸"));
        assert!(t.major.len() <= 8);
    }

    #[test]
    fn narrow_log_ranges_label_two_and_five() {
        let t = log(15.0, 80.0);
        assert_eq!(labels(&t), ["20", "50"]);
    }
}
