//! Cases drawn fresh every run, beside the fixed fixtures: Sinumerik V20 traces and iTNC 530
//! TNCscope exports written here from random parameters, read back and checked against the
//! parameters they were written from. The seed is printed; `VCNC_SEED=N` repeats a run.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use vcnc_axis::AxisName;
use vcnc_trace::{
    AxisNumberMap, PairOptions, Quantity, ReadOptions, lost_motion, pair, read_bytes,
};

fn rng(test: &str) -> ChaCha8Rng {
    let seed = std::env::var("VCNC_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(1, |d| d.as_nanos() as u64)
        });
    println!("{test}: seed {seed} (VCNC_SEED={seed} repeats it)");
    ChaCha8Rng::seed_from_u64(seed)
}

/// Up-and-down pulses of `stroke` from `base`: a cycloidal move of `mv` samples, a hold of
/// `hold` samples, the move back.
fn pulses(n: usize, base: f64, stroke: f64, mv: usize, hold: usize) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let (j, tau) = (k / (mv + hold), k % (mv + hold));
            let u = (tau as f64 / mv as f64).min(1.0);
            let frac = u - (2.0 * std::f64::consts::PI * u).sin() / (2.0 * std::f64::consts::PI);
            base + stroke * if j % 2 == 0 { frac } else { 1.0 - frac }
        })
        .collect()
}

#[test]
fn sinumerik_v20_lost_motion_of_random_backlash() {
    let mut r = rng("sinumerik_v20_lost_motion_of_random_backlash");
    for case in 0..8 {
        let b = r.random_range(0.5e-3..20e-3); // mm
        let stroke = r.random_range(4.0 * b + 0.01..0.5);
        let base = r.random_range(-500.0..500.0);
        let offset = r.random_range(-1000.0..1000.0);
        let (mv, hold) = (r.random_range(20..40), r.random_range(15..30));
        let halves = r.random_range(3..10);
        let n = halves * (mv + hold);
        let p = [1e-3, 2e-3, 4e-3][r.random_range(0..3)];
        let number = r.random_range(1..13u32);
        let axis = [AxisName::X, AxisName::Y, AxisName::Z][r.random_range(0..3)];
        let xr = pulses(n, base, stroke, mv, hold);
        // Motor: a first-order lag without overshoot; table: behind the backlash (play operator).
        let alpha = r.random_range(0.2..0.5);
        let mut m = vec![xr[0]; n];
        for k in 1..n {
            m[k] = m[k - 1] + alpha * (xr[k] - m[k - 1]);
        }
        let mut x = vec![m[0] - b / 2.0; n];
        for k in 1..n {
            x[k] = x[k - 1].clamp(m[k] - b / 2.0, m[k] + b / 2.0);
        }
        let signals = [
            ("CmdPos2ndEnc64", "Position setpoint (64 bit)", xr.clone()),
            (
                "ActPos1stEnc64",
                "Position actual value measuring system 1 (64 bit)",
                m.iter().map(|v| v + offset).collect(),
            ),
            (
                "ActPos2ndEnc64",
                "Position actual value measuring system 2 (64 bit)",
                x.clone(),
            ),
        ];
        // The declaration order of the three signals, drawn.
        let mut order = [0usize, 1, 2];
        for i in (1..3).rev() {
            order.swap(i, r.random_range(0..=i));
        }
        let mut xml = String::from(
            "\u{feff}<?xml version=\"1.0\" encoding=\"UTF-8\"?>\r\n<traceSession version=\"01.00.03.02\">\r\n<traceCaptureSetup_V20><signalSettings>\r\n",
        );
        for (i, &o) in order.iter().enumerate() {
            let (nck, desc, _) = &signals[o];
            xml += &format!(
                "<signal key=\"s{i}\" unitsType=\"posn\" name=\"/Nck/!SD/nckServoData{nck} [u1, {number}]\" description=\"{desc}\"/>\r\n"
            );
        }
        xml += "</signalSettings></traceCaptureSetup_V20>\r\n<traceData dataFrames=\"1\"><dataFrame>\r\n";
        for i in 0..3 {
            xml += &format!(
                "<dataSignal key=\"s{i}\" id=\"f{}\" interval=\"{p:.6}\" datapointCount=\"{n}\"/>\r\n",
                i + 1
            );
        }
        let mut last = [String::new(), String::new(), String::new()];
        for k in 0..n {
            let mut attrs = vec![format!("time=\"{:.6}\"", k as f64 * p)];
            for (i, &o) in order.iter().enumerate() {
                let v = format!("{:.6}", signals[o].2[k]);
                if v != last[i] {
                    attrs.push(format!("f{}=\"{v}\"", i + 1));
                    last[i] = v;
                }
            }
            let rot = r.random_range(0..attrs.len());
            attrs.rotate_left(rot);
            xml += &format!("<rec {}/>\r\n", attrs.join(" "));
        }
        xml += "</dataFrame></traceData>\r\n</traceSession>\r\n";
        let read = ReadOptions {
            axis_map: AxisNumberMap::parse(&format!("{number}={axis}")).unwrap(),
            ..ReadOptions::default()
        };
        let trace = read_bytes("fresh.xml", xml.as_bytes(), &read).unwrap();
        let paired = pair(&trace, &PairOptions::default()).unwrap();
        let a = &paired.axes[0];
        assert_eq!(a.axis, axis, "case {case}");
        assert_eq!(a.ts_s, p, "case {case}");
        assert_eq!(
            a.provenance.actual.name, "Position actual value measuring system 2",
            "case {case}"
        );
        let lm = lost_motion(a).unwrap();
        // The two systems are printed to 1 nm (0.5 nm rounding each): 2 nm.
        assert_eq!(lm.reversals.len(), halves - 1, "case {case}");
        for rev in &lm.reversals {
            assert!(
                (rev.lost - b).abs() <= 2e-6,
                "case {case}: lost motion {} mm at {} s, backlash {b} mm",
                rev.lost,
                rev.t_s
            );
        }
    }
}

#[test]
fn itnc530_exports_of_random_intervals_read_at_their_sampling() {
    let mut r = rng("itnc530_exports_of_random_intervals_read_at_their_sampling");
    for case in 0..8 {
        let sampling = 100 * r.random_range(5..60u32); // µs
        let n = r.random_range(20..300usize);
        let curves = r.random_range(2..7usize);
        let nl = if r.random_range(0..2) == 0 {
            "\r\n"
        } else {
            "\n"
        };
        let mut head = vec![
            "%TNCscopeNT data file".to_string(),
            "% ".to_string(),
            "%[GLOBAL]".to_string(),
            "%CONTROL=iTNC 530".to_string(),
            format!("%SAMPLING={sampling}"),
            format!("%UNKNOWN{}=x", r.random_range(0..1000)),
            "% ".to_string(),
        ];
        let mut values: Vec<Vec<f64>> = Vec::new();
        for c in 0..curves {
            let cycle = [100, 600, 3000][r.random_range(0..3)];
            let kind = ["s soll", "s ist", "v ist", "I ist"][c % 4];
            head.push(format!("%[CURVE{}]", c + 1));
            head.push(format!("%NAME={kind}/Z"));
            head.push("%DIMENSION=mm".to_string());
            head.push(format!("%COUNT={n}"));
            head.push(format!("%SAMPLING={sampling}"));
            head.push(format!("%CYCLETIME={cycle}"));
            head.push("% ".to_string());
            values.push((0..n).map(|_| r.random_range(-1e3..1e3)).collect());
        }
        head.push("%[DATA]".to_string());
        for k in 0..n {
            let mut row = format!("{}", k as u64 * u64::from(sampling));
            for v in &values {
                row += &format!("; {:.4}", v[k]);
            }
            head.push(row + ";");
        }
        let text = head.join(nl) + nl;
        let trace = read_bytes("fresh.txt", text.as_bytes(), &ReadOptions::default()).unwrap();
        assert_eq!(trace.channels.len(), curves, "case {case}");
        for (c, ch) in trace.channels.iter().enumerate() {
            assert_eq!(ch.period_s, Some(f64::from(sampling) / 1e6), "case {case}");
            assert_eq!(ch.len(), n, "case {case}");
            assert!(ch.gaps.is_empty(), "case {case}");
            assert_eq!(ch.axis, Some(AxisName::Z), "case {case}");
            for (k, v) in ch.samples.iter().enumerate() {
                assert!((v - values[c][k]).abs() <= 5e-5 + 1e-9, "case {case}");
            }
        }
        assert_eq!(trace.channels[0].quantity, Quantity::NominalPosition);
        assert_eq!(trace.channels[1].quantity, Quantity::ActualPosition);
    }
}
