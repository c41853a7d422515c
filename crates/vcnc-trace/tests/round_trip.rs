//! Round trips through the simple formats: written by `vcnc_trace::write`, read back, every
//! sample bit for bit, names, periods and gaps as written; and every format detected from its
//! content whatever the file is called.

use crate::common;

use common::values;
use proptest::prelude::*;
use vcnc_axis::AxisName;
use vcnc_trace::{
    Format, Quantity, ReadOptions, TraceUnit, detect, from_columns, read_bytes, write,
};

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn joint_names(k: usize) -> Vec<String> {
    (0..k)
        .map(|i| {
            let side = if i % 2 == 0 { "cmd" } else { "fb" };
            format!("joint.{}.motor-pos-{side}", i / 2)
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 24,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn halscope_table_round_trip(cols in values(40), period_ns in 1u64..10_000_000) {
        let names = joint_names(cols.len());
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let slices: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
        let mut buf = Vec::new();
        write::halscope_table(&mut buf, period_ns, &refs, &slices).unwrap();
        let t = read_bytes("rt.log", &buf, &ReadOptions::default()).unwrap();
        prop_assert_eq!(t.format, Format::HalscopeTable);
        prop_assert_eq!(t.channels.len(), cols.len());
        for (c, (ch, col)) in t.channels.iter().zip(&cols).enumerate() {
            prop_assert_eq!(&ch.name, &names[c]);
            prop_assert_eq!(bits(&ch.samples), bits(col));
            prop_assert_eq!(ch.period_s, Some(period_ns as f64 * 1e-9));
            prop_assert_eq!(ch.axis, AxisName::from_index(c / 2));
            let q = if c % 2 == 0 { Quantity::NominalPosition } else { Quantity::ActualPosition };
            prop_assert_eq!(ch.quantity, q);
        }
    }

    #[test]
    fn halscope_pairs_round_trip(cols in values(30)) {
        let names = joint_names(cols.len());
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let slices: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
        let mut buf = Vec::new();
        write::halscope_pairs(&mut buf, 250_000, &refs, &slices).unwrap();
        let t = read_bytes("rt.log", &buf, &ReadOptions::default()).unwrap();
        prop_assert_eq!(t.format, Format::HalscopeInterlaced);
        for (ch, col) in t.channels.iter().zip(&cols) {
            prop_assert_eq!(bits(&ch.samples), bits(col));
            prop_assert_eq!(ch.period_s, Some(2.5e-4));
        }
    }

    #[test]
    fn halsampler_round_trip(cols in values(50), tagged in any::<bool>(), at in 1usize..49, lost in 1usize..5) {
        let slices: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
        let mut buf = Vec::new();
        write::halsampler(&mut buf, tagged, &slices, &[(at, lost)]).unwrap();
        let opts = ReadOptions { period_s: Some(1e-3), ..ReadOptions::default() };
        let t = read_bytes("rt.txt", &buf, &opts).unwrap();
        prop_assert_eq!(t.format, Format::Halsampler);
        prop_assert_eq!(t.channels.len(), cols.len());
        for (ch, col) in t.channels.iter().zip(&cols) {
            prop_assert_eq!(bits(&ch.samples), bits(col));
            prop_assert_eq!(ch.gaps.len(), 1);
            prop_assert_eq!(ch.gaps[0].index, at);
            prop_assert_eq!(ch.gaps[0].lost, tagged.then_some(lost));
        }
    }

    #[test]
    fn delimited_round_trip(cols in values(25), sep in prop::sample::select(vec![b',', b';', b'\t', b' ']), comma in any::<bool>()) {
        let comma = comma && sep != b',';
        let n = cols[0].len();
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.5e-3).collect();
        let mut names = vec!["t[s]".to_string()];
        names.extend((0..cols.len()).map(|i| format!("c{i}[mm]")));
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let mut slices: Vec<&[f64]> = vec![&t];
        slices.extend(cols.iter().map(Vec::as_slice));
        let mut buf = Vec::new();
        write::delimited(&mut buf, sep, comma, Some(&refs), &slices).unwrap();
        let tr = read_bytes("rt.csv", &buf, &ReadOptions::default()).unwrap();
        prop_assert_eq!(tr.format, Format::Delimited);
        prop_assert_eq!(tr.channels.len(), cols.len());
        for (i, (ch, col)) in tr.channels.iter().zip(&cols).enumerate() {
            prop_assert_eq!(&ch.name, &format!("c{i}"));
            prop_assert_eq!(&ch.unit, &Some(TraceUnit::Mm));
            prop_assert_eq!(bits(&ch.samples), bits(col));
            prop_assert!((ch.period_s.unwrap() - 0.5e-3).abs() < 1e-15);
        }
    }

    /// Columns in memory (numpy arrays from Python) read as the delimited file holding them
    /// would be: the same trace (time base, gaps and their lines, names, units, axes),
    /// samples bit for bit. The time column has a gap of `lost` samples at `at` and jitter
    /// of printed digits.
    #[test]
    fn columns_read_as_their_delimited_file(cols in values(25), at in 1usize..24, lost in 1usize..4, with_t in any::<bool>()) {
        let n = cols[0].len();
        let t: Vec<f64> = (0..n)
            .map(|k| (k + if k >= at { lost } else { 0 }) as f64 * 1e-3 + 7.25)
            .collect();
        let mut names: Vec<String> = with_t.then(|| "t".to_string()).into_iter().collect();
        names.extend((0..cols.len()).map(|i| format!("c{i}[mm]")));
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let mut slices: Vec<&[f64]> = with_t.then_some(t.as_slice()).into_iter().collect();
        slices.extend(cols.iter().map(Vec::as_slice));
        let mut buf = Vec::new();
        write::delimited(&mut buf, b',', false, Some(&refs), &slices).unwrap();
        let opts = ReadOptions {
            period_s: (!with_t).then_some(1e-3),
            ..ReadOptions::default()
        };
        let file = read_bytes("arrays", &buf, &opts).unwrap();
        let named = names[usize::from(with_t)..]
            .iter()
            .cloned()
            .zip(cols.iter().cloned())
            .collect();
        let mem = from_columns("arrays", with_t.then_some(t.as_slice()), named, &opts).unwrap();
        prop_assert_eq!(&mem.channels, &file.channels);
        if with_t {
            prop_assert_eq!(mem.channels[0].gaps[0].line, at + 2);
        }
    }

    #[test]
    fn sinumerik_round_trip(cols in values(30), held in 0usize..30) {
        // Runs of equal values are left out of the records and carried forward by the reader.
        let mut cols = cols;
        for c in cols.iter_mut() {
            let v = c[held];
            for x in c[held..].iter_mut().take(5) {
                *x = v;
            }
        }
        let times: Vec<f64> = (0..cols[0].len()).map(|k| k as f64 * 2e-3).collect();
        let names: Vec<(String, String)> = (0..cols.len())
            .map(|i| {
                let axis = ["X1", "Y1", "Z1", "A1", "C1"][i];
                let what = if i % 2 == 0 { "setpoint" } else { "actual value" };
                (format!("/Nck/ServoTrace/Position[{axis}] <&\"'>"), format!("Position {what} {axis}"))
            })
            .collect();
        let signals: Vec<write::SinumerikSignal<'_>> = cols
            .iter()
            .zip(&names)
            .enumerate()
            .map(|(i, (c, (n, d)))| write::SinumerikSignal {
                id: i + 1,
                name: n,
                description: d,
                unit: (i % 2 == 0).then_some("mm"),
                samples: c,
            })
            .collect();
        let mut buf = Vec::new();
        write::sinumerik(&mut buf, &times, &signals).unwrap();
        let t = read_bytes("rt.xml", &buf, &ReadOptions::default()).unwrap();
        prop_assert_eq!(t.format, Format::SinumerikTrace);
        prop_assert_eq!(t.channels.len(), cols.len());
        for (i, (ch, col)) in t.channels.iter().zip(&cols).enumerate() {
            prop_assert_eq!(&ch.name, &names[i].1);
            prop_assert_eq!(&ch.description, &names[i].0);
            prop_assert_eq!(&ch.unit, &(i % 2 == 0).then_some(TraceUnit::Mm));
            prop_assert_eq!(bits(&ch.samples), bits(col));
            prop_assert!((ch.period_s.unwrap() - 2e-3).abs() < 1e-15);
            prop_assert_eq!(ch.axis, AxisName::from_index([0, 1, 2, 3, 5][i]));
        }
    }

    #[test]
    fn twincat_round_trip(
        cols in values(20),
        tab in any::<bool>(),
        comma in any::<bool>(),
        short in 1usize..20,
        sample_ms in prop::sample::select(vec![0.25, 1.0, 2.0]),
    ) {
        // The last channel may end early (its cells then stay empty).
        let mut cols = cols;
        let k = cols.len() - 1;
        cols[k].truncate(short);
        let names: Vec<(String, String)> = (0..cols.len())
            .map(|i| (format!("ActPos_{i}"), format!("MAIN.Axis{}.NcToPlc.ActPos", ["X", "Y", "Z", "A"][i])))
            .collect();
        let channels: Vec<write::TwinCatChannel<'_>> = cols
            .iter()
            .zip(&names)
            .map(|(c, (n, s))| write::TwinCatChannel {
                name: n,
                symbol: s,
                unit: "mm (Millimeter)",
                sample_ms,
                samples: c,
            })
            .collect();
        let mut buf = Vec::new();
        write::twincat(&mut buf, "rt", if tab { b'\t' } else { b';' }, comma, &channels).unwrap();
        let t = read_bytes("rt.csv", &buf, &ReadOptions::default()).unwrap();
        prop_assert_eq!(t.format, Format::TwinCatScope);
        prop_assert_eq!(t.channels.len(), cols.len());
        for (i, (ch, col)) in t.channels.iter().zip(&cols).enumerate() {
            prop_assert_eq!(&ch.name, &names[i].0);
            prop_assert_eq!(&ch.description, &names[i].1);
            prop_assert_eq!(&ch.unit, &Some(TraceUnit::Mm));
            prop_assert_eq!(bits(&ch.samples), bits(col));
            prop_assert_eq!(ch.period_s, Some(sample_ms * 1e-3));
            prop_assert_eq!(ch.axis, AxisName::from_index(i));
            prop_assert_eq!(ch.quantity, Quantity::ActualPosition);
        }
    }
}

#[test]
fn tncscope_round_trip_with_two_cycle_times() {
    let fine: Vec<f64> = (0..12).map(|k| k as f64 * 0.125).collect();
    let coarse: Vec<f64> = (0..4).map(|k| -(k as f64) * 1.5).collect();
    let curves = [
        write::TncCurve {
            name: "Z s soll",
            channel_type: "s soll",
            axis_type: "Z",
            dimension: "mm",
            cycle_us: 1800,
            samples: &coarse,
        },
        write::TncCurve {
            name: "Z s ist",
            channel_type: "s ist",
            axis_type: "Z",
            dimension: "mm",
            cycle_us: 600,
            samples: &fine,
        },
    ];
    let mut buf = Vec::new();
    write::tncscope(&mut buf, "TNC 640", &curves).unwrap();
    let t = read_bytes("rt.DTA", &buf, &ReadOptions::default()).unwrap();
    assert_eq!(t.format, Format::TncScope);
    assert_eq!(t.channels[0].samples, coarse);
    assert_eq!(t.channels[1].samples, fine);
    assert_eq!(t.channels[0].period_s, Some(1.8e-3));
    assert_eq!(t.channels[1].period_s, Some(0.6e-3));
    assert_eq!(t.channels[0].axis, Some(AxisName::Z));
}

#[test]
fn tncscope_itnc530_round_trip_at_the_recording_interval() {
    let s: Vec<f64> = (0..40).map(|k| -300.0 + k as f64 * 0.0125).collect();
    let i: Vec<f64> = (0..40).map(|k| (k as f64 * 0.3).sin()).collect();
    let curves = [
        write::TncCurve {
            name: "s soll/Y",
            channel_type: "s soll",
            axis_type: "Y",
            dimension: "mm",
            cycle_us: 3000,
            samples: &s,
        },
        write::TncCurve {
            name: "I ist/Y",
            channel_type: "I ist",
            axis_type: "Y",
            dimension: "A",
            cycle_us: 100,
            samples: &i,
        },
    ];
    let mut buf = Vec::new();
    write::tncscope_itnc530(&mut buf, 3000, &curves).unwrap();
    let t = read_bytes("rt.DTA", &buf, &ReadOptions::default()).unwrap();
    assert_eq!(t.channels[0].samples, s);
    assert_eq!(t.channels[1].samples, i);
    for ch in &t.channels {
        assert_eq!(ch.period_s, Some(3e-3));
        assert!(ch.gaps.is_empty());
    }
    assert_eq!(t.channels[1].cycle_s, Some(1e-4));
}

#[test]
fn sinumerik_v20_round_trip_with_two_measuring_systems() {
    let xr: Vec<f64> = (0..50)
        .map(|k| -300.0 + (k as f64 * 0.2).sin() * 0.03)
        .collect();
    let direct: Vec<f64> = xr.iter().map(|v| v - 1e-4).collect();
    let motor: Vec<f64> = xr.iter().map(|v| v - 800.0).collect();
    let sig = |signal, description, samples| write::SinumerikServoSignal {
        signal,
        axis_number: 3,
        description,
        units_type: "posn",
        samples,
    };
    let signals = [
        sig(
            "nckServoDataCmdPos2ndEnc64",
            "Position setpoint (64 bit)",
            &xr,
        ),
        sig(
            "nckServoDataActPos1stEnc64",
            "Position actual value measuring system 1 (64 bit)",
            &motor,
        ),
        sig(
            "nckServoDataActPos2ndEnc64",
            "Position actual value measuring system 2 (64 bit)",
            &direct,
        ),
    ];
    let mut buf = Vec::new();
    write::sinumerik_v20(&mut buf, 2e-3, &signals).unwrap();
    let read = ReadOptions {
        axis_map: vcnc_trace::AxisNumberMap::parse("3=Z").unwrap(),
        ..ReadOptions::default()
    };
    let t = read_bytes("rt.xml", &buf, &read).unwrap();
    for (ch, s) in t.channels.iter().zip(&signals) {
        assert_eq!(ch.samples, s.samples);
        assert_eq!(ch.axis, Some(AxisName::Z));
        assert_eq!(ch.period_s, Some(2e-3));
    }
    let z = &vcnc_trace::pair(&t, &vcnc_trace::PairOptions::default())
        .unwrap()
        .axes[0];
    assert_eq!(z.actual, direct);
    assert_eq!(z.other_actual.as_deref(), Some(&motor[..]));
}

#[test]
fn every_sample_file_is_detected_by_content_whatever_its_name() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let cases = [
        ("halscope/xyzac-2.9.log", Format::HalscopeTable),
        ("halscope/xy-pre2.9.log", Format::HalscopeInterlaced),
        ("halsampler/xz-tagged.txt", Format::Halsampler),
        ("halsampler/plain.txt", Format::Halsampler),
        ("tncscope/xyzc.txt", Format::TncScope),
        ("sinumerik/x1-y1.xml", Format::SinumerikTrace),
        ("tncscope/itnc530-y.txt", Format::TncScope),
        ("sinumerik/v20-x-two-systems.xml", Format::SinumerikTrace),
        ("sinumerik/v20-latin1-two-axes.xml", Format::SinumerikTrace),
        ("halsampler/pid-loop.txt", Format::Halsampler),
        ("twincat/nc-axes_semicolon.csv", Format::TwinCatScope),
        (
            "twincat/nc-axes_tab-decimal-comma_shared-time.csv",
            Format::TwinCatScope,
        ),
        (
            "twincat/tc3_scope_3_4_3145_3_noOS.csv",
            Format::TwinCatScope,
        ),
        (
            "twincat/tc3_scope_3_4_3145_3-DecimalMark_comma.csv",
            Format::TwinCatScope,
        ),
        ("delimited/t-xr-x.csv", Format::Delimited),
        ("delimited/semicolon-decimal-comma.csv", Format::Delimited),
        ("delimited/whitespace-rad.txt", Format::Delimited),
    ];
    for (rel, format) in cases {
        let bytes = std::fs::read(dir.join(rel)).unwrap();
        assert_eq!(detect(&bytes), Ok(format), "{rel}");
        // A byte-order mark and CRLF line ends change nothing.
        // (A file that has a byte-order mark keeps its one.)
        let mut bom = if bytes.starts_with(b"\xEF\xBB\xBF") {
            Vec::new()
        } else {
            b"\xEF\xBB\xBF".to_vec()
        };
        for (i, &b) in bytes.iter().enumerate() {
            if b == b'\n' && (i == 0 || bytes[i - 1] != b'\r') {
                bom.push(b'\r');
            }
            bom.push(b);
        }
        assert_eq!(detect(&bom), Ok(format), "{rel} with BOM and CRLF");
        let a = read_bytes(rel, &bytes, &ReadOptions::default());
        let b = read_bytes(rel, &bom, &ReadOptions::default());
        assert_eq!(a, b, "{rel}");
    }
}
