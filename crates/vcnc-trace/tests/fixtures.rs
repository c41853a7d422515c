//! Every sample trace read and paired, checked against the motion it was written from.
//!
//! Truth: `tests/data/generate.py` wrote each file from one definition per axis — a cycloidal
//! move of known start, duration and length (the nominal position) and the response of a
//! second-order loop to it (the actual position). [`nominal`] and [`actual`] below compute the
//! same motion independently of the readers. Tolerances are half the last digit each format
//! printed (halscope `%.14f`, halsampler `%f`, TNCscope `%.4f`, …), converted to mm or deg.

use crate::common;

use std::path::{Path, PathBuf};

use approx::assert_abs_diff_eq;
use vcnc_axis::AxisName;
use vcnc_trace::{
    AxisMap, ChannelRef, Format, GapPolicy, PairOptions, Quantity, ReadOptions, TraceUnit,
    UnitSource, pair, read_path,
};

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(rel)
}

/// (start s, duration s, distance) of each axis's move, as in generate.py's MOVES.
fn moves(axis: AxisName) -> (f64, f64, f64) {
    match axis {
        AxisName::X => (0.020, 0.150, 25.0),
        AxisName::Y => (0.040, 0.120, -12.5),
        AxisName::Z => (0.060, 0.100, 5.0),
        AxisName::A => (0.030, 0.160, 30.0),
        AxisName::B => (0.025, 0.150, 20.0),
        AxisName::C => (0.050, 0.140, -45.0),
    }
}

/// The cycloidal move: 0 before the start, the distance after the end.
fn nominal(axis: AxisName, n: usize, period: f64) -> Vec<f64> {
    let (start, dur, dist) = moves(axis);
    (0..n)
        .map(|k| {
            let t = k as f64 * period - start;
            if t <= 0.0 {
                0.0
            } else if t >= dur {
                dist
            } else {
                let u = t / dur;
                dist * (u - (2.0 * std::f64::consts::PI * u).sin() / (2.0 * std::f64::consts::PI))
            }
        })
        .collect()
}

/// The loop's response: $\ddot x = \omega_n^2 (x_r - x) - 2\zeta\omega_n \dot x$, 40 Hz, ζ = 0.7,
/// semi-implicit Euler at period/20, sampled before each step (as generate.py).
fn actual(xr: &[f64], period: f64) -> Vec<f64> {
    let wn = 2.0 * std::f64::consts::PI * 40.0;
    let zeta = 0.7;
    let h = period / 20.0;
    let (mut x, mut v) = (0.0, 0.0);
    let mut out = Vec::with_capacity(xr.len());
    for &r in xr {
        out.push(x);
        for _ in 0..20 {
            let a = wn * wn * (r - x) - 2.0 * zeta * wn * v;
            v += h * a;
            x += h * v;
        }
    }
    out
}

fn check(got: &[f64], want: &[f64], tol: f64, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= tol,
            "{what}[{k}]: {g} vs {w} (tolerance {tol})"
        );
    }
}

#[test]
fn halscope_table_log_of_a_five_axis_machine() {
    let opts = common::xyzac_options();
    let trace = read_path(&data("halscope/xyzac-2.9.log"), &opts).unwrap();
    assert_eq!(trace.format, Format::HalscopeTable);
    assert_eq!(trace.channels.len(), 12);
    let p = pair(&trace, &PairOptions::default()).unwrap();
    let axes: Vec<AxisName> = p.axes.iter().map(|a| a.axis).collect();
    assert_eq!(
        axes,
        [
            AxisName::X,
            AxisName::Y,
            AxisName::Z,
            AxisName::A,
            AxisName::C
        ]
    );
    for a in &p.axes {
        assert_eq!(a.ts_s, 1e-3);
        assert_eq!(a.unit, a.axis.unit());
        assert_eq!(a.provenance.nominal.unit_source, UnitSource::Assumed);
        let xr = nominal(a.axis, 300, 1e-3);
        // %.14f: half a unit of the 14th decimal, plus the rounding of the value itself.
        check(&a.nominal, &xr, 1e-12, &format!("{} nominal", a.axis));
        check(
            &a.actual,
            &actual(&xr, 1e-3),
            1e-12,
            &format!("{} actual", a.axis),
        );
    }
    // The joint map decides: with the default XYZABC map joint 4 is B.
    let default = read_path(&data("halscope/xyzac-2.9.log"), &ReadOptions::default()).unwrap();
    assert_eq!(default.channels[8].axis, Some(AxisName::B));
    // Asked for only Y and C, in inches for linear axes: Y scaled by 25.4, C untouched.
    let mut only = PairOptions {
        axes: vec![AxisName::C, AxisName::Y],
        ..PairOptions::default()
    };
    assert!(only.set_unit(TraceUnit::Inch));
    let p = pair(&trace, &only).unwrap();
    assert_eq!(p.axes.len(), 2);
    assert_eq!(p.axes[0].axis, AxisName::Y);
    assert_eq!(p.axes[0].provenance.actual.unit_source, UnitSource::Caller);
    assert_abs_diff_eq!(p.axes[0].nominal[299], -12.5 * 25.4, epsilon = 1e-9);
    assert_abs_diff_eq!(p.axes[1].nominal[299], -45.0, epsilon = 1e-12);
}

#[test]
fn halscope_pair_log_before_2_9() {
    let trace = read_path(&data("halscope/xy-pre2.9.log"), &ReadOptions::default()).unwrap();
    assert_eq!(trace.format, Format::HalscopeInterlaced);
    let p = pair(&trace, &PairOptions::default()).unwrap();
    assert_eq!(p.axes.len(), 2);
    for a in &p.axes {
        let xr = nominal(a.axis, 200, 1e-3);
        check(&a.nominal, &xr, 1e-12, "nominal");
        check(&a.actual, &actual(&xr, 1e-3), 1e-12, "actual");
    }
}

#[test]
fn halsampler_with_sample_numbers_and_an_overrun() {
    let opts = ReadOptions {
        period_s: Some(1e-3),
        ..ReadOptions::default()
    };
    let trace = read_path(&data("halsampler/xz-tagged.txt"), &opts).unwrap();
    assert_eq!(trace.format, Format::Halsampler);
    let ch = &trace.channels[0];
    assert_eq!(ch.name, "x-pos-cmd");
    assert_eq!(ch.gaps.len(), 1);
    assert_eq!(
        (ch.gaps[0].index, ch.gaps[0].lost, ch.gaps[0].line),
        (180, Some(3), 182)
    );
    // Refused across the gap by default …
    let err = pair(&trace, &PairOptions::default()).unwrap_err();
    assert!(
        err.to_string()
            .contains(":182: channel 'x-pos-cmd': 3 samples lost"),
        "{err}"
    );
    // … or the longest stretch, samples 0..180, which match the motion (%f: 5e-7).
    let longest = PairOptions {
        gaps: GapPolicy::LongestSegment,
        ..PairOptions::default()
    };
    let p = pair(&trace, &longest).unwrap();
    for a in &p.axes {
        let xr = nominal(a.axis, 180, 1e-3);
        check(&a.nominal, &xr, 5.1e-7, "nominal");
        check(&a.actual, &actual(&xr, 1e-3), 5.1e-7, "actual");
        let seg = a.provenance.segment.unwrap();
        assert_eq!((seg.index, seg.of), (0, 2));
    }
    // Without a period the channels have none, and pairing says so.
    let no_period = read_path(&data("halsampler/xz-tagged.txt"), &ReadOptions::default()).unwrap();
    assert_eq!(no_period.channels[0].period_s, None);
    let err = pair(&no_period, &longest).unwrap_err();
    assert!(err.to_string().contains("no sample period"), "{err}");
}

#[test]
fn halsampler_plain_columns_mapped_by_index() {
    let opts = ReadOptions {
        period_s: Some(1e-3),
        ..ReadOptions::default()
    };
    let trace = read_path(&data("halsampler/plain.txt"), &opts).unwrap();
    assert_eq!(trace.channels[0].gaps[0].lost, None);
    let map = PairOptions {
        map: vec![AxisMap {
            axis: AxisName::Y,
            nominal: ChannelRef::Column(0),
            actual: ChannelRef::Name("pin.1".into()),
        }],
        gaps: GapPolicy::LongestSegment,
        ..PairOptions::default()
    };
    let p = pair(&trace, &map).unwrap();
    let y = &p.axes[0];
    let xr = nominal(AxisName::Y, 100, 1e-3);
    check(&y.nominal, &xr, 5.1e-7, "nominal");
    check(&y.actual, &actual(&xr, 1e-3), 5.1e-7, "actual");
}

#[test]
fn tncscope_with_two_cycle_times_and_micrometres() {
    let trace = read_path(&data("tncscope/xyzc.txt"), &ReadOptions::default()).unwrap();
    assert_eq!(trace.format, Format::TncScope);
    assert_eq!(trace.channels.len(), 10);
    let y = &trace.channels[2];
    assert_eq!(
        (y.unit.clone(), y.quantity),
        (Some(TraceUnit::Um), Quantity::NominalPosition)
    );
    assert_eq!(trace.channels[8].quantity, Quantity::NominalVelocity);
    assert_eq!(trace.channels[9].quantity, Quantity::Current);
    assert_eq!(trace.channels[9].unit, Some(TraceUnit::A));
    let p = pair(&trace, &PairOptions::default()).unwrap();
    let axes: Vec<AxisName> = p.axes.iter().map(|a| a.axis).collect();
    assert_eq!(axes, [AxisName::X, AxisName::Y, AxisName::Z, AxisName::C]);
    let period = 600e-6;
    for a in &p.axes {
        // %.4f in the file's unit: 5e-5 mm or deg, 5e-5 µm for Y.
        let tol = if a.axis == AxisName::Y {
            5.1e-8
        } else {
            5.1e-5
        };
        let xr = nominal(a.axis, 500, period);
        let x = actual(&xr, period);
        if a.axis == AxisName::X {
            // Nominal at the 3 ms interpolator cycle: the pair is on the 3 ms grid, the actual
            // position taken at every fifth 600 µs sample.
            assert!(a.provenance.resampled);
            assert_abs_diff_eq!(a.ts_s, 3e-3, epsilon = 1e-15);
            let every5 = |v: &[f64]| v.iter().step_by(5).copied().collect::<Vec<f64>>();
            check(&a.nominal, &every5(&xr), tol, "X nominal");
            check(&a.actual, &every5(&x), tol, "X actual");
        } else {
            assert!(!a.provenance.resampled);
            check(&a.nominal, &xr, tol, "nominal");
            check(&a.actual, &x, tol, "actual");
        }
    }
}

#[test]
fn sinumerik_trace_with_sparse_records() {
    let trace = read_path(&data("sinumerik/x1-y1.xml"), &ReadOptions::default()).unwrap();
    assert_eq!(trace.format, Format::SinumerikTrace);
    assert_eq!(
        trace.channels[1].name,
        "Position actual value measuring system 1 X1"
    );
    assert_eq!(
        trace.channels[1].description,
        "/Nck/ServoTrace/PositionActualValue1[X1]"
    );
    let p = pair(&trace, &PairOptions::default()).unwrap();
    let period = 2e-3;
    let x = &p.axes[0];
    let mut xr = nominal(AxisName::X, 150, period);
    // Record 70 holds the "no value" marker for the setpoint: the value before it carries on.
    xr[70] = (xr[69] * 1e6).round() / 1e6;
    check(&x.nominal, &xr, 5.1e-7, "X nominal");
    check(
        &x.actual,
        &actual(&nominal(AxisName::X, 150, period), period),
        5.1e-7,
        "X actual",
    );
    // Y's signals start at the 11th record.
    let y = &p.axes[1];
    assert_abs_diff_eq!(y.t0_s, 0.02, epsilon = 1e-12);
    let yr = nominal(AxisName::Y, 150, period);
    check(&y.nominal, &yr[10..], 5.1e-7, "Y nominal");
    check(&y.actual, &actual(&yr, period)[10..], 5.1e-7, "Y actual");
    assert_eq!(y.provenance.nominal.unit_source, UnitSource::Assumed);
    assert_eq!(x.provenance.nominal.unit_source, UnitSource::File);
}

#[test]
fn twincat_exports_of_nc_axes() {
    for rel in [
        "twincat/nc-axes_semicolon.csv",
        "twincat/nc-axes_tab-decimal-comma_shared-time.csv",
    ] {
        let trace = read_path(&data(rel), &ReadOptions::default()).unwrap();
        assert_eq!(trace.format, Format::TwinCatScope, "{rel}");
        assert_eq!(trace.channels[1].description, "MAIN.AxisX.NcToPlc.ActPos");
        assert_eq!(trace.channels[1].unit, Some(TraceUnit::Mm));
        assert_eq!(trace.channels[4].axis, None, "bEnable is no B axis");
        let p = pair(&trace, &PairOptions::default()).unwrap();
        assert_eq!(p.axes.len(), 2);
        for a in &p.axes {
            let xr = nominal(a.axis, 240, 1e-3);
            check(&a.nominal, &xr, 5.1e-7, rel);
            check(&a.actual, &actual(&xr, 1e-3), 5.1e-7, rel);
        }
    }
}

#[test]
fn twincat_sample_exports_read_as_pytcs_does() {
    // Independent truth: the pytcs README lists these channels with 1.0 ms and the units shown;
    // the values are the PLC's counters (var_* = sample index, modulo the type's range).
    let t = read_path(
        &data("twincat/tc3_scope_3_4_3145_3_noOS.csv"),
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(t.channels.len(), 19);
    let ch = |n: &str| t.channels.iter().find(|c| c.name == n).unwrap();
    assert_eq!(ch("var_REAL64").samples.len(), 1000);
    assert_eq!(ch("var_REAL64").period_s, Some(1e-3));
    assert_eq!(ch("var_REAL64").samples[999], 999.0);
    assert_eq!(ch("var_INT8").samples[200], -56.0); // 200 wraps to −56 in a signed byte
    assert_eq!(
        ch("func_units_scaled").unit,
        Some(TraceUnit::Other("dV (Voltage)".into()))
    );
    assert_eq!(&ch("func_units_scaled").samples[..3], &[10.0, 0.0, -10.0]);
    let c = read_path(
        &data("twincat/tc3_scope_3_4_3145_3-DecimalMark_comma.csv"),
        &ReadOptions::default(),
    )
    .unwrap();
    let ch = |n: &str| c.channels.iter().find(|ch| ch.name == n).unwrap();
    let os = ch("func_OS");
    assert_eq!(os.period_s, Some(2e-4));
    assert_eq!(os.samples.len(), 4996);
    assert_eq!(os.samples[5], 1.0); // decimal comma: "1" at 1 ms after 0,2 0,4 0,6 0,8
    assert_eq!(os.samples[1], 0.2);
    let free = ch("func_freesample");
    assert_eq!(
        (free.period_s, free.t0_s, free.samples.len()),
        (Some(5e-3), -3e-3, 201)
    );
}

#[test]
fn delimited_files_of_three_kinds() {
    let t = read_path(&data("delimited/t-xr-x.csv"), &ReadOptions::default()).unwrap();
    let p = pair(&t, &PairOptions::default()).unwrap();
    let xr = nominal(AxisName::X, 250, 1e-3);
    check(&p.axes[0].nominal, &xr, 5.1e-7, "t-xr-x nominal");
    check(
        &p.axes[0].actual,
        &actual(&xr, 1e-3),
        5.1e-7,
        "t-xr-x actual",
    );

    let t = read_path(
        &data("delimited/semicolon-decimal-comma.csv"),
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(t.channels[0].unit, Some(TraceUnit::Um));
    let p = pair(&t, &PairOptions::default()).unwrap();
    for a in &p.axes {
        // "Zeit [ms]" → 1 ms; values in µm with 4 decimals → 5e-8 mm.
        assert_abs_diff_eq!(a.ts_s, 1e-3, epsilon = 1e-15);
        let xr = nominal(a.axis, 250, 1e-3);
        check(&a.nominal, &xr, 5.1e-8, "nominal");
        check(&a.actual, &actual(&xr, 1e-3), 5.1e-8, "actual");
    }

    let t = read_path(
        &data("delimited/whitespace-rad.txt"),
        &ReadOptions::default(),
    )
    .unwrap();
    let p = pair(&t, &PairOptions::default()).unwrap();
    let b = &p.axes[0];
    assert_eq!(b.axis, AxisName::B);
    let br = nominal(AxisName::B, 250, 1e-3);
    // 9 decimals of a radian: 5e-10 rad = 2.9e-8 deg.
    check(&b.nominal, &br, 3e-8, "B nominal");
    check(&b.actual, &actual(&br, 1e-3), 3e-8, "B actual");
}

#[test]
fn emps_benchmark_file_reads_through_the_delimited_reader() {
    // The EMPS estimation set of the repository (real ball-screw drive, 1 kHz; columns t, qg,
    // qm in metres, vir in volts).
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/emps/DATA_EMPS.csv");
    let t = read_path(&path, &ReadOptions::default()).unwrap();
    assert_eq!(t.format, Format::Delimited);
    let names: Vec<&str> = t.channels.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["qg", "qm", "vir"]);
    let qg = &t.channels[0];
    assert_eq!(qg.period_s.map(|p| (p * 1e9).round()), Some(1e6));
    assert_eq!(qg.samples.len(), 24841);
    assert_eq!(qg.samples[0], 0.00010782208);
    // No axis in the names: the caller maps the columns and gives the unit.
    assert!(matches!(
        pair(&t, &PairOptions::default()),
        Err(vcnc_trace::Error::NoPositions { .. })
    ));
    let mut opts = PairOptions {
        map: vec![AxisMap {
            axis: AxisName::X,
            nominal: ChannelRef::Name("qg".into()),
            actual: ChannelRef::Name("qm".into()),
        }],
        ..PairOptions::default()
    };
    opts.set_unit(TraceUnit::M);
    let p = pair(&t, &opts).unwrap();
    let x = &p.axes[0];
    assert_eq!(x.provenance.nominal.unit_source, UnitSource::Caller);
    assert_abs_diff_eq!(x.nominal[0], 0.10782208, epsilon = 1e-12);
    assert_eq!(x.nominal.len(), 24841);
}

fn axis_map(m: &str) -> ReadOptions {
    ReadOptions {
        axis_map: vcnc_trace::AxisNumberMap::parse(m).unwrap(),
        ..ReadOptions::default()
    }
}

#[test]
fn itnc530_export_with_separators_reads_at_the_recording_interval() {
    // Issue 29: refused at line 2 ('% '), and read at the current's 100 µs CYCLETIME it seemed
    // to have lost 29 of every 30 samples. Truth: generate.py's Y move at the 3 ms SAMPLING.
    let trace = read_path(&data("tncscope/itnc530-y.txt"), &ReadOptions::default()).unwrap();
    assert_eq!(trace.format, Format::TncScope);
    assert_eq!(trace.channels.len(), 5);
    for c in &trace.channels {
        assert_eq!(c.period_s, Some(3e-3), "{}", c.name);
        assert_eq!(c.len(), 200, "{}", c.name);
        assert!(c.gaps.is_empty(), "{}", c.name);
    }
    let current = &trace.channels[3];
    assert_eq!(
        (current.name.as_str(), current.quantity, current.cycle_s),
        ("I ist/Y", Quantity::Current, Some(1e-4))
    );
    assert_eq!(trace.channels[2].quantity, Quantity::ActualVelocity);
    assert_eq!(trace.channels[4].axis, None);
    assert!(
        trace
            .metadata
            .iter()
            .any(|(k, v)| k == "RECORDEDBY" && v == "J. Müller")
    );
    let p = pair(&trace, &PairOptions::default()).unwrap();
    assert_eq!(p.axes.len(), 1);
    let y = &p.axes[0];
    assert_eq!((y.axis, y.ts_s), (AxisName::Y, 3e-3));
    assert_eq!(y.provenance.actual.unit, TraceUnit::Um);
    let xr = nominal(AxisName::Y, 200, 3e-3);
    // %.4f mm and %.1f µm: half the last digit, 5e-5 mm.
    check(&y.nominal, &xr, 5e-5 + 1e-12, "Y nominal");
    check(&y.actual, &actual(&xr, 3e-3), 5e-5 + 1e-12, "Y actual");
}

/// The play operator of generate.py: the table stands until the motor has crossed the gap.
const BACKLASH_MM: f64 = 0.005;

#[test]
fn sinumerik_v20_pairs_the_setpoint_with_its_measuring_system_and_measures_the_backlash() {
    let path = data("sinumerik/v20-x-two-systems.xml");
    let trace = read_path(&path, &axis_map("1=X")).unwrap();
    assert_eq!(trace.format, Format::SinumerikTrace);
    assert_eq!(trace.channels.len(), 10);
    for c in &trace.channels {
        assert_eq!((c.len(), c.period_s), (600, Some(2e-3)), "{}", c.name);
        assert_eq!(c.axis_number, Some(1), "{}", c.name);
        assert_eq!(c.axis, Some(AxisName::X), "{}", c.name);
    }
    let p = pair(&trace, &PairOptions::default()).unwrap();
    let x = &p.axes[0];
    let pv = &x.provenance;
    assert_eq!(pv.nominal.name, "Position setpoint");
    assert_eq!(pv.actual.name, "Position actual value measuring system 2");
    assert_eq!(
        pv.other_actual.as_ref().map(|o| o.name.as_str()),
        Some("Position actual value measuring system 1")
    );
    // Truth: the backlash generate.py drove the table through; the motor is critically damped,
    // so the difference of the two systems settles exactly at ±b/2 around their 800 mm offset.
    let lm = vcnc_trace::lost_motion(x).unwrap();
    assert_eq!(lm.reversals.len(), 11);
    for r in &lm.reversals {
        assert_abs_diff_eq!(r.lost, BACKLASH_MM, epsilon = 2e-6);
    }
    assert_abs_diff_eq!(lm.median, BACKLASH_MM, epsilon = 2e-6);
    let info = trace.info();
    assert_eq!(info.lost_motion, [lm]);
    assert!(
        info.to_string()
            .contains("X: 5.00 µm (median of 11 reversals")
    );
    // Without the axis map: no axis, and trace info and pairing say which option gives it.
    let bare = read_path(&path, &ReadOptions::default()).unwrap();
    let info = bare.info();
    assert!(info.lost_motion.is_empty());
    assert_eq!(
        info.notes,
        [
            "axis number 1 has two measuring systems; for its lost motion name its axis with --axis-map 1=A"
        ]
    );
    let e = pair(&bare, &PairOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("pass --axis-map 1=A"), "{e}");
    // One --axis for a file of one servo is enough.
    let one = PairOptions {
        axes: vec![AxisName::Y],
        ..PairOptions::default()
    };
    let y = &pair(&bare, &one).unwrap().axes[0];
    assert_eq!(y.axis, AxisName::Y);
    assert_eq!(y.actual, x.actual);
    assert_eq!(y.other_actual, x.other_actual);
}

#[test]
fn sinumerik_v20_latin1_two_axes_through_the_axis_map() {
    let trace = read_path(
        &data("sinumerik/v20-latin1-two-axes.xml"),
        &axis_map("1=X,2=Y"),
    )
    .unwrap();
    assert_eq!(trace.channels[0].name, "Lagesollwert Meßsystem 1 [u1, 1]");
    let p = pair(&trace, &PairOptions::default()).unwrap();
    assert_eq!(p.axes.len(), 2);
    for a in &p.axes {
        let xr = nominal(a.axis, 120, 4e-3);
        check(&a.nominal, &xr, 5e-7 + 1e-12, "nominal");
        check(&a.actual, &actual(&xr, 4e-3), 5e-7 + 1e-12, "actual");
        assert!(a.other_actual.is_none());
    }
}

#[test]
fn real_halsampler_recording_of_a_linuxcnc_pid_loop() {
    // A genuine halsampler recording (halsampler/record-pid-loop.sh): no names, no period.
    let path = data("halsampler/pid-loop.txt");
    let bare = read_path(&path, &ReadOptions::default()).unwrap();
    assert_eq!(bare.format, Format::Halsampler);
    let names: Vec<&str> = bare.channels.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["pin.0", "pin.1"]);
    // Every refusal says which option to pass.
    let e = pair(&bare, &PairOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no axis has both") && e.contains("--xr-col NOMINAL --x-col ACTUAL"),
        "{e}"
    );
    let map = PairOptions {
        map: vec![AxisMap {
            axis: AxisName::X,
            nominal: ChannelRef::Name("pin.0".into()),
            actual: ChannelRef::Name("pin.1".into()),
        }],
        ..PairOptions::default()
    };
    let e = pair(&bare, &map).unwrap_err().to_string();
    assert!(
        e.contains("'pin.0' has no sample period") && e.contains("--ts SECONDS"),
        "{e}"
    );
    let trace = read_path(
        &path,
        &ReadOptions {
            period_s: Some(1e-3),
            ..ReadOptions::default()
        },
    )
    .unwrap();
    let x = &pair(&trace, &map).unwrap().axes[0];
    assert_eq!((x.nominal.len(), x.ts_s), (1500, 1e-3));
    // Truth: the loop's law (LinuxCNC integ.comp and pid.c, record-pid-loop.sh):
    // fb[k] = fb[k-1] + T Pgain (cmd[k-1] - fb[k-1]), T = 1 ms, Pgain = 60; %f prints 1e-6.
    for k in 1..x.actual.len() {
        let want = x.actual[k - 1] + 1e-3 * 60.0 * (x.nominal[k - 1] - x.actual[k - 1]);
        assert!(
            (x.actual[k] - want).abs() <= 1.1e-6 * (1.0 + 2.0 * 0.06),
            "sample {k}: {} vs {want}",
            x.actual[k]
        );
    }
    // The command is siggen's 2 Hz sine of amplitude 5: 5 sin(2π·2·(k+1)·T).
    for (k, c) in x.nominal.iter().enumerate() {
        let want = 5.0 * (2.0 * std::f64::consts::PI * 2.0 * (k + 1) as f64 * 1e-3).sin();
        assert!((c - want).abs() <= 1e-5, "command {k}: {c} vs {want}");
    }
}
