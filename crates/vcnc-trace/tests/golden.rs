//! Golden files of the parsed channels of every sample trace in `tests/data`: format, every
//! channel's axis, quantity, unit, period, count, gaps, and a digest of its samples (first,
//! middle and last values, sum), and the per-axis pairing where the file has pairs.
//!
//! The expected outputs live in `tests/data/golden/<file>.txt`. After an intended change,
//! regenerate with `VCNC_BLESS=1 cargo test -p vcnc-trace --test integration golden` and review the diff.
//! The values themselves are checked against the motion the files were written from in
//! `tests/fixtures.rs`; these files pin everything else.

use crate::common;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use vcnc_axis::AxisName;
use vcnc_trace::{GapPolicy, PairOptions, ReadOptions, pair, read_path};

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

fn axis_map(m: &str) -> ReadOptions {
    ReadOptions {
        axis_map: vcnc_trace::AxisNumberMap::parse(m).unwrap(),
        ..ReadOptions::default()
    }
}

/// Sample files and the options they are read with.
fn corpus() -> Vec<(&'static str, ReadOptions, PairOptions)> {
    let xyzac = common::xyzac_options();
    let one_ms = ReadOptions {
        period_s: Some(1e-3),
        ..ReadOptions::default()
    };
    let longest = PairOptions {
        gaps: GapPolicy::LongestSegment,
        ..PairOptions::default()
    };
    let plain_pair = PairOptions {
        map: vec![vcnc_trace::AxisMap {
            axis: AxisName::Y,
            nominal: vcnc_trace::ChannelRef::Column(0),
            actual: vcnc_trace::ChannelRef::Column(1),
        }],
        gaps: GapPolicy::LongestSegment,
        ..PairOptions::default()
    };
    vec![
        ("halscope/xyzac-2.9.log", xyzac, PairOptions::default()),
        (
            "halscope/xy-pre2.9.log",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        ("halsampler/xz-tagged.txt", one_ms.clone(), longest.clone()),
        ("halsampler/plain.txt", one_ms.clone(), plain_pair),
        (
            "halsampler/pid-loop.txt",
            one_ms,
            PairOptions {
                map: vec![vcnc_trace::AxisMap {
                    axis: AxisName::X,
                    nominal: vcnc_trace::ChannelRef::Name("pin.0".into()),
                    actual: vcnc_trace::ChannelRef::Name("pin.1".into()),
                }],
                ..PairOptions::default()
            },
        ),
        (
            "tncscope/xyzc.txt",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        (
            "sinumerik/x1-y1.xml",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        (
            "tncscope/itnc530-y.txt",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        (
            "sinumerik/v20-x-two-systems.xml",
            axis_map("1=X"),
            PairOptions::default(),
        ),
        (
            "sinumerik/v20-latin1-two-axes.xml",
            axis_map("1=X,2=Y"),
            PairOptions::default(),
        ),
        (
            "twincat/nc-axes_semicolon.csv",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        (
            "twincat/nc-axes_tab-decimal-comma_shared-time.csv",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        (
            "twincat/tc3_scope_3_4_3145_3_noOS.csv",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        (
            "twincat/tc3_scope_3_4_3145_3-DecimalMark_comma.csv",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        (
            "delimited/t-xr-x.csv",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        (
            "delimited/semicolon-decimal-comma.csv",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        (
            "delimited/whitespace-rad.txt",
            ReadOptions::default(),
            PairOptions::default(),
        ),
        (
            "parquet/simulate-x.parquet",
            ReadOptions::default(),
            PairOptions::default(),
        ),
    ]
}

fn g(v: f64) -> String {
    format!("{v:.9e}")
}

fn render(rel: &str, read: &ReadOptions, pairing: &PairOptions) -> String {
    let path = data().join(rel);
    let mut trace = read_path(&path, read).unwrap_or_else(|e| panic!("{rel}: {e}"));
    trace.file = rel.to_string();
    let mut out = String::new();
    write!(out, "{}", trace.info()).unwrap();
    writeln!(out, "\nsamples (first, second, middle, last, sum):").unwrap();
    for c in &trace.channels {
        let s = &c.samples;
        let digest = if s.is_empty() {
            "none".to_string()
        } else {
            format!(
                "{} {} {} {} {}",
                g(s[0]),
                g(s[1.min(s.len() - 1)]),
                g(s[s.len() / 2]),
                g(s[s.len() - 1]),
                g(s.iter().sum())
            )
        };
        writeln!(out, "  {}: t0 {} s: {digest}", c.name, g(c.t0_s)).unwrap();
        for gap in &c.gaps {
            writeln!(
                out,
                "    gap before sample {} (line {}): {:?} lost",
                gap.index, gap.line, gap.lost
            )
            .unwrap();
        }
    }
    writeln!(out, "\npairing:").unwrap();
    match pair(&trace, pairing) {
        Ok(p) => {
            for a in &p.axes {
                let pv = &a.provenance;
                writeln!(
                    out,
                    "  {} [{}]: {} samples at {} s from {} s; nominal '{}' ({} {}, x{}), actual '{}' ({} {}, x{}); resampled {}; segment {:?}",
                    a.axis,
                    a.unit,
                    a.nominal.len(),
                    g(a.ts_s),
                    g(a.t0_s),
                    pv.nominal.name,
                    pv.nominal.unit,
                    pv.nominal.unit_source,
                    g(pv.nominal.factor),
                    pv.actual.name,
                    pv.actual.unit,
                    pv.actual.unit_source,
                    g(pv.actual.factor),
                    pv.resampled,
                    pv.segment
                )
                .unwrap();
                if let (Some(o), Some(u)) = (&a.other_actual, &pv.other_actual) {
                    writeln!(
                        out,
                        "    other measuring system '{}' ({} {}): {} {} {}",
                        u.name,
                        u.unit,
                        u.unit_source,
                        g(o[0]),
                        g(o[o.len() / 2]),
                        g(o[o.len() - 1])
                    )
                    .unwrap();
                }
                let n = a.nominal.len();
                writeln!(
                    out,
                    "    nominal {} {} {}; actual {} {} {}",
                    g(a.nominal[0]),
                    g(a.nominal[n / 2]),
                    g(a.nominal[n - 1]),
                    g(a.actual[0]),
                    g(a.actual[n / 2]),
                    g(a.actual[n - 1])
                )
                .unwrap();
            }
            for s in &p.skipped {
                writeln!(out, "  skipped {}: {}", s.axis, s.reason).unwrap();
            }
        }
        Err(e) => writeln!(out, "  error: {e}").unwrap(),
    }
    out
}

#[test]
fn parsed_channels_match_the_golden_files() {
    let bless = std::env::var("VCNC_BLESS").is_ok_and(|v| v == "1");
    let dir = data().join("golden");
    let mut failures = Vec::new();
    for (rel, read, pairing) in corpus() {
        let out = render(rel, &read, &pairing);
        let golden = dir.join(format!("{}.txt", rel.replace('/', "__")));
        if bless {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(&golden, &out).unwrap();
            continue;
        }
        let want = std::fs::read_to_string(&golden).unwrap_or_else(|_| {
            panic!(
                "missing golden file {}; run with VCNC_BLESS=1",
                golden.display()
            )
        });
        if want != out {
            let line = want
                .lines()
                .zip(out.lines())
                .position(|(a, b)| a != b)
                .unwrap_or(want.lines().count().min(out.lines().count()));
            failures.push(format!(
                "{rel}: differs from {} at line {}:\n  golden: {:?}\n  output: {:?}",
                golden.display(),
                line + 1,
                want.lines().nth(line),
                out.lines().nth(line)
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{}\n(run with VCNC_BLESS=1 if the change is intended)",
        failures.join("\n")
    );
}
