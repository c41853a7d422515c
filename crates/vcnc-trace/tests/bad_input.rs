//! Bad input for every reader: truncated files, header/count mismatches, missing position
//! channels, unknown units, time that goes back, stalls or skips, names that match no axis, NaN.
//! Each case must give the typed error it names, with the file and line in the message — and no
//! panic. `VCNC_PRINT_MESSAGES=1 cargo test -p vcnc-trace --test integration bad_input -- --nocapture` prints
//! the table of messages.

use vcnc_axis::AxisName;
use vcnc_trace::{
    AxisMap, ChannelRef, Error, Format, PairOptions, ReadOptions, TraceUnit, pair, read_bytes,
};

struct Case {
    name: &'static str,
    file: &'static str,
    content: Vec<u8>,
    read: ReadOptions,
    /// `None`: reading fails; `Some`: reading succeeds and pairing with these options fails.
    pair: Option<PairOptions>,
    /// Pairing succeeds, and the lost motion of its first axis fails.
    lost_motion: bool,
    kind: fn(&Error) -> bool,
    expect: &'static [&'static str],
}

fn case(
    name: &'static str,
    file: &'static str,
    content: impl Into<Vec<u8>>,
    kind: fn(&Error) -> bool,
    expect: &'static [&'static str],
) -> Case {
    Case {
        name,
        file,
        content: content.into(),
        read: ReadOptions::default(),
        pair: None,
        lost_motion: false,
        kind,
        expect,
    }
}

impl Case {
    fn paired(mut self, opts: PairOptions) -> Case {
        self.pair = Some(opts);
        self
    }
    fn lost_motion(mut self) -> Case {
        self.pair = Some(PairOptions::default());
        self.lost_motion = true;
        self
    }
    fn read_with(mut self, opts: ReadOptions) -> Case {
        self.read = opts;
        self
    }
}

fn period(p: f64) -> ReadOptions {
    ReadOptions {
        period_s: Some(p),
        ..ReadOptions::default()
    }
}

const HS: &str = "# Sampling period is 1000000 ns\njoint.0.motor-pos-cmd;joint.0.motor-pos-fb\n0;0\n0.1;0.05\n0.2;0.15\n";

fn tnc(replace: &[(&str, &str)]) -> String {
    let mut s = "%TNCscopeNT data file\n%[GLOBAL]\nCONTROL=TNC 640\n\
         %[CURVE1]\nNAME=X s soll\nCHANNELTYPE=s soll\nAXISTYPE=X\nDIMENSION=mm\nCOUNT=3\nCYCLETIME=600\n\
         %[CURVE2]\nNAME=X s ist\nCHANNELTYPE=s ist\nAXISTYPE=X\nDIMENSION=mm\nCOUNT=3\nCYCLETIME=600\n\
         %[DATA]\n0; 0.0; 0.0;\n600; 0.1; 0.05;\n1200; 0.2; 0.15;\n"
        .to_string();
    for (a, b) in replace {
        assert!(s.contains(a), "{a}");
        s = s.replacen(a, b, 1);
    }
    s
}

fn sinu(replace: &[(&str, &str)]) -> String {
    let mut s = "<?xml version=\"1.0\"?>\n<traceFile>\n <traceData>\n  <dataFrame>\n\
   <dataSignal id=\"1\" name=\"/Nck/X1/PosSet\" description=\"Position setpoint X1\" unit=\"mm\"/>\n\
   <dataSignal id=\"2\" name=\"/Nck/X1/PosAct\" description=\"Position actual value X1\" unit=\"mm\"/>\n\
   <rec time=\"0.000\" f1=\"0\" f2=\"0\"/>\n\
   <rec time=\"0.002\" f1=\"0.1\" f2=\"0.05\"/>\n\
   <rec time=\"0.004\" f1=\"0.2\" f2=\"0.15\"/>\n  </dataFrame>\n </traceData>\n</traceFile>\n"
        .to_string();
    for (a, b) in replace {
        assert!(s.contains(a), "{a}");
        s = s.replacen(a, b, 1);
    }
    s
}

/// A TNCscope export as an iTNC 530 writes it: `% ` separators, %-prefixed keys, SAMPLING and
/// CYCLETIME, CRLF.
fn tnc530(replace: &[(&str, &str)]) -> String {
    let mut s = "%TNCscopeNT data file\r\n% \r\n%[GLOBAL]\r\n%CONTROL=iTNC 530\r\n%SAMPLING=3000\r\n% \r\n\
         %[CURVE1]\r\n%NAME=s soll/Y\r\n%AXISTYPE=Y\r\n%DIMENSION=mm\r\n%COUNT=3\r\n%SAMPLING=3000\r\n%CYCLETIME=3000\r\n% \r\n\
         %[CURVE2]\r\n%NAME=s ist/Y\r\n%AXISTYPE=Y\r\n%DIMENSION=mm\r\n%COUNT=3\r\n%SAMPLING=3000\r\n%CYCLETIME=3000\r\n% \r\n\
         %[DATA]\r\n0; 0.0; 0.0;\r\n3000; 0.1; 0.05;\r\n6000; 0.2; 0.15;\r\n"
        .to_string();
    for (a, b) in replace {
        assert!(s.contains(a), "{a}");
        s = s.replacen(a, b, 1);
    }
    s
}

/// A Sinumerik V20 trace of NCK axis 1: setpoint for the direct system, both actual positions.
fn v20(replace: &[(&str, &str)]) -> String {
    let mut s = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<traceSession version=\"01.00.03.02\">\n\
  <traceCaptureSetup_V20>\n   <signalSettings>\n\
   <signal key=\"s1\" unitsType=\"posn\" name=\"/Nck/!SD/nckServoDataCmdPos2ndEnc64 [u1, 1]\" description=\"Position setpoint (64 bit)\"/>\n\
   <signal key=\"s2\" unitsType=\"posn\" name=\"/Nck/!SD/nckServoDataActPos1stEnc64 [u1, 1]\" description=\"Position actual value measuring system 1 (64 bit)\"/>\n\
   <signal key=\"s3\" unitsType=\"posn\" name=\"/Nck/!SD/nckServoDataActPos2ndEnc64 [u1, 1]\" description=\"Position actual value measuring system 2 (64 bit)\"/>\n\
   </signalSettings>\n  </traceCaptureSetup_V20>\n  <traceData dataFrames=\"1\">\n   <dataFrame>\n\
   <dataSignal key=\"s1\" id=\"f1\" interval=\"0.002000\" datapointCount=\"3\"/>\n\
   <dataSignal key=\"s2\" id=\"f2\" interval=\"0.002000\" datapointCount=\"3\"/>\n\
   <dataSignal key=\"s3\" id=\"f3\" interval=\"0.002000\" datapointCount=\"3\"/>\n\
   <rec time=\"0.000000\" f1=\"-300\" f2=\"-1100\" f3=\"-300.0025\"/>\n\
   <rec time=\"0.002000\" f1=\"-299.99\" f3=\"-299.9975\" f2=\"-1099.99\"/>\n\
   <rec time=\"0.004000\" f2=\"-1099.98\" f1=\"-299.98\"/>\n\
   </dataFrame>\n  </traceData>\n</traceSession>\n"
        .to_string();
    for (a, b) in replace {
        assert!(s.contains(a), "{a}");
        s = s.replacen(a, b, 1);
    }
    s
}

fn twincat(replace: &[(&str, &str)]) -> String {
    let mut s = "Name;s\nFile;f.csv\nStarttime of export;0\nEndtime of export;0\n\n\
         Name;SetPos_X;Name;ActPos_X\nSampleTime[ms];1;SampleTime[ms];1\nUnit;mm;Unit;mm\n\
         SymbolName;MAIN.AxisX.SetPos;SymbolName;MAIN.AxisX.ActPos\n\n\
         0;0;0;0\n1;0.1;1;0.05\n2;0.2;2;0.15\n"
        .to_string();
    for (a, b) in replace {
        assert!(s.contains(a), "{a}");
        s = s.replacen(a, b, 1);
    }
    s
}

fn cases() -> Vec<Case> {
    use Error as E;
    let linear_furlong = PairOptions {
        linear_unit: Some(TraceUnit::Other("furlong".into())),
        ..PairOptions::default()
    };
    let want_y = PairOptions {
        axes: vec![AxisName::Y],
        ..PairOptions::default()
    };
    let map_qg = PairOptions {
        map: vec![AxisMap {
            axis: AxisName::X,
            nominal: ChannelRef::Name("qg".into()),
            actual: ChannelRef::Name("x".into()),
        }],
        ..PairOptions::default()
    };
    let d = PairOptions::default;
    vec![
        // ---- halscope table (2.9+)
        case(
            "halscope: truncated after the period",
            "h.log",
            "# Sampling period is 1000000 ns\n",
            |e| matches!(e, E::Truncated { .. }),
            &["h.log:1:", "no channel-name line"],
        ),
        case(
            "halscope: last row cut",
            "h.log",
            format!("{HS}0.3"),
            |e| matches!(e, E::Truncated { .. }),
            &["h.log:6:", "1 of 2 fields"],
        ),
        case(
            "halscope: row longer than the header",
            "h.log",
            format!("{HS}0.3;0.2;0.1\n"),
            |e| {
                matches!(
                    e,
                    E::FieldCount {
                        expected: 2,
                        found: 3,
                        ..
                    }
                )
            },
            &["h.log:6:", "3 fields where 2 are expected"],
        ),
        case(
            "halscope: period not a number",
            "h.log",
            "# Sampling period is fast ns\na;b\n",
            |e| matches!(e, E::Header { line: 1, .. }),
            &["h.log:1:", "'fast'"],
        ),
        case(
            "halscope: NaN",
            "h.log",
            format!("{HS}nan;0\n"),
            |e| matches!(e, E::NotFinite { .. }),
            &["h.log:6:", "joint.0.motor-pos-cmd is nan"],
        ),
        case(
            "halscope: a name that matches no axis",
            "h.log",
            "# Sampling period is 1000000 ns\npid.pos-cmd;pid.pos-fb\n0;0\n",
            |e| matches!(e, E::NoAxis { .. }),
            &["h.log:2:", "'pid.pos-cmd'", "matches no axis"],
        )
        .paired(d()),
        case(
            "halscope: no actual position",
            "h.log",
            "# Sampling period is 1000000 ns\njoint.0.motor-pos-cmd;joint.0.vel-cmd\n0;0\n",
            |e| {
                matches!(
                    e,
                    E::MissingChannel {
                        axis: AxisName::X,
                        ..
                    }
                )
            },
            &["h.log", "no actual position channel for axis X"],
        )
        .paired(d()),
        case(
            "halscope: axis asked for is absent",
            "h.log",
            HS,
            |e| {
                matches!(
                    e,
                    E::MissingChannel {
                        axis: AxisName::Y,
                        ..
                    }
                )
            },
            &["h.log", "axis Y"],
        )
        .paired(want_y.clone()),
        case(
            "halscope: unknown unit given",
            "h.log",
            HS,
            |e| matches!(e, E::BadOption { .. }),
            &["h.log", "unknown unit 'furlong'"],
        )
        .paired(linear_furlong),
        // ---- halscope pairs (before 2.9)
        case(
            "halscope pairs: last pair cut",
            "p.log",
            "Sampling period is 1000000 ns \n\nx-pos-cmd +0.1 x-pos-fb",
            |e| matches!(e, E::Truncated { .. }),
            &["p.log:3:", "'x-pos-fb' has no value"],
        ),
        case(
            "halscope pairs: channel counts differ",
            "p.log",
            "Sampling period is 1000000 ns \n\na +1 b +2 \na +1 \n",
            |e| matches!(e, E::CountMismatch { .. }),
            &["p.log:3:", "'b' holds 1 samples where 2 are expected"],
        ),
        case(
            "halscope pairs: NaN",
            "p.log",
            "Sampling period is 1000000 ns \n\nx-pos-cmd +nan x-pos-fb +0 \n",
            |e| matches!(e, E::NotFinite { .. }),
            &["p.log:3:", "x-pos-cmd is +nan"],
        ),
        // ---- halsampler
        case(
            "halsampler: last line cut",
            "s.txt",
            "0.1 0.2 \n0.3",
            |e| matches!(e, E::Truncated { .. }),
            &["s.txt:2:", "1 of 2 fields"],
        ),
        case(
            "halsampler: line with more fields",
            "s.txt",
            "0.1 0.2 \n0.3 0.4 0.5 \n0.6 0.7\n",
            |e| matches!(e, E::FieldCount { .. }),
            &["s.txt:2:", "3 fields where 2 are expected"],
        ),
        case(
            "halsampler: sample number goes back",
            "s.txt",
            "0 0.1 0.2 \n1 0.1 0.2 \n2 0.1 0.2 \n1 0.1 0.2 \n",
            |e| matches!(e, E::Header { line: 4, .. }),
            &["s.txt:4:", "sample number 1 does not follow 2"],
        ),
        case(
            "halsampler: NaN",
            "s.txt",
            "0.1 nan \n",
            |e| matches!(e, E::NotFinite { .. }),
            &["s.txt:1:", "pin.1 is nan"],
        ),
        case(
            "halsampler: overrun refused",
            "s.txt",
            "# x-pos-cmd x-pos-fb\n0.1 0.1 \noverrun\n0.2 0.2 \n",
            |e| matches!(e, E::Gap { lost: None, .. }),
            &["s.txt:3:", "unknown number of samples lost", "refused"],
        )
        .read_with(period(1e-3))
        .paired(d()),
        case(
            "halsampler: no period",
            "s.txt",
            "# x-pos-cmd x-pos-fb\n0.1 0.1 \n0.2 0.2 \n",
            |e| matches!(e, E::MissingPeriod { .. }),
            &["s.txt", "'x-pos-cmd' has no sample period"],
        )
        .paired(d()),
        case(
            "halsampler: wrong number of names",
            "s.txt",
            "0.1 0.1 \n",
            |e| matches!(e, E::BadOption { .. }),
            &["s.txt", "1 channel names given for 2 value columns"],
        )
        .read_with(ReadOptions {
            channel_names: vec!["a".into()],
            ..ReadOptions::default()
        }),
        case(
            "halsampler: names that match no axis",
            "s.txt",
            "# pos-cmd pos-fb\n0 0 \n0.1 0.1 \n",
            |e| matches!(e, E::NoAxis { .. }),
            &["s.txt:1:", "'pos-cmd'"],
        )
        .read_with(period(1e-3))
        .paired(d()),
        // ---- TNCscope
        case(
            "tncscope: no data section",
            "t.txt",
            tnc(&[(
                "%[DATA]\n0; 0.0; 0.0;\n600; 0.1; 0.05;\n1200; 0.2; 0.15;\n",
                "",
            )]),
            |e| matches!(e, E::Truncated { .. }),
            &["t.txt:17:", "no %[DATA] section"],
        ),
        case(
            "tncscope: last row cut",
            "t.txt",
            tnc(&[("1200; 0.2; 0.15;\n", "1200; 0.2")]),
            |e| matches!(e, E::Truncated { .. }),
            &["t.txt:21:", "2 of 3 fields"],
        ),
        case(
            "tncscope: data stop before COUNT (a cut export)",
            "t.txt",
            tnc(&[("COUNT=3", "COUNT=4")]),
            |e| matches!(e, E::Truncated { line: 21, .. }),
            &[
                "t.txt:21:",
                "the data stop after 3 of the 4 samples curve 'X s soll' declares (COUNT, line 9)",
            ],
        ),
        case(
            "tncscope: COUNT smaller than the data",
            "t.txt",
            tnc(&[("COUNT=3", "COUNT=2")]),
            |e| {
                matches!(
                    e,
                    E::CountMismatch {
                        declared: 2,
                        found: 3,
                        ..
                    }
                )
            },
            &[
                "t.txt:9:",
                "'X s soll' holds 3 samples where 2 are expected",
            ],
        ),
        case(
            "tncscope: no CYCLETIME",
            "t.txt",
            tnc(&[("CYCLETIME=600\n%[DATA]", "%[DATA]")]),
            |e| matches!(e, E::Header { .. }),
            &[
                "t.txt:11:",
                "'X s ist' has no SAMPLING (recording interval) and no CYCLETIME",
            ],
        ),
        case(
            "tncscope: row longer than the curves",
            "t.txt",
            tnc(&[("600; 0.1; 0.05;", "600; 0.1; 0.05; 7;")]),
            |e| matches!(e, E::FieldCount { .. }),
            &["t.txt:20:", "4 fields where 3 are expected"],
        ),
        case(
            "tncscope: unknown unit",
            "t.txt",
            tnc(&[("DIMENSION=mm", "DIMENSION=furlong")]),
            |e| matches!(e, E::UnknownUnit { .. }),
            &["t.txt:4:", "unknown unit 'furlong'"],
        )
        .paired(d()),
        case(
            "tncscope: velocity unit on a position",
            "t.txt",
            tnc(&[("DIMENSION=mm", "DIMENSION=mm/min")]),
            |e| matches!(e, E::WrongUnit { .. }),
            &["t.txt:4:", "is in mm/min", "needs a length unit"],
        )
        .paired(d()),
        case(
            "tncscope: time stands still",
            "t.txt",
            tnc(&[("1200; 0.2", "600; 0.2")]),
            |e| matches!(e, E::TimeNotIncreasing { .. }),
            &["t.txt:21:", "time does not increase"],
        ),
        case(
            "tncscope: irregular step",
            "t.txt",
            tnc(&[("1200; 0.2", "1500; 0.2")]),
            |e| matches!(e, E::IrregularTime { .. }),
            &["t.txt:21:", "irregular time step"],
        ),
        case(
            "tncscope: gap refused",
            "t.txt",
            tnc(&[("1200; 0.2", "1800; 0.2")]),
            |e| matches!(e, E::Gap { lost: Some(1), .. }),
            &["t.txt:21:", "1 sample lost"],
        )
        .paired(d()),
        case(
            "tncscope: NaN",
            "t.txt",
            tnc(&[("600; 0.1", "600; NaN")]),
            |e| matches!(e, E::NotFinite { .. }),
            &["t.txt:20:", "X s soll is NaN"],
        ),
        case(
            "tncscope: a curve that matches no axis",
            "t.txt",
            tnc(&[("NAME=X s soll", "NAME=Lage soll"), ("AXISTYPE=X\n", "")]),
            |e| matches!(e, E::NoAxis { .. }),
            &["t.txt:4:", "'Lage soll'"],
        )
        .paired(d()),
        case(
            "tncscope: no actual position",
            "t.txt",
            tnc(&[("CHANNELTYPE=s ist", "CHANNELTYPE=v ist")]),
            |e| matches!(e, E::MissingChannel { .. }),
            &["t.txt", "no actual position channel for axis X"],
        )
        .paired(d()),
        case(
            "tncscope (iTNC 530): the file ends inside a curve block",
            "t.txt",
            {
                let full = tnc530(&[]);
                full[..full.find("%COUNT=3\r\n%SAMPLING=3000\r\n%CYCLETIME=3000\r\n% \r\n%[DATA]").unwrap()].to_string()
            },
            |e| matches!(e, E::Truncated { line: 18, .. }),
            &[
                "t.txt:18:",
                "it stops inside %[CURVE2] (line 15), before %[DATA]",
            ],
        ),
        case(
            "tncscope (iTNC 530): the data stop in the middle of a curve",
            "t.txt",
            tnc530(&[("6000; 0.2; 0.15;\r\n", "")]),
            |e| matches!(e, E::Truncated { line: 25, .. }),
            &[
                "t.txt:25:",
                "the data stop after 2 of the 3 samples curve 's soll/Y' declares",
            ],
        ),
        case(
            "tncscope (iTNC 530): a row cut inside a field",
            "t.txt",
            tnc530(&[("6000; 0.2; 0.15;\r\n", "6000; 0.2")]),
            |e| matches!(e, E::Truncated { line: 26, .. }),
            &["t.txt:26:", "2 of 3 fields"],
        ),
        case(
            "tncscope (iTNC 530): a line that is not a key",
            "t.txt",
            tnc530(&[("%CONTROL=iTNC 530", "%CONTROL iTNC 530")]),
            |e| matches!(e, E::Header { line: 4, .. }),
            &["t.txt:4:", "expected KEY=VALUE, a %[SECTION] line or a '%' separator"],
        ),
        case(
            "tncscope: --t-col names a column of a format with its own time base",
            "t.txt",
            tnc530(&[]),
            |e| matches!(e, E::TimeColumnNotApplicable { .. }),
            &["t.txt: --t-col t:", "carry their own time base"],
        )
        .read_with(ReadOptions {
            time_column: Some(ChannelRef::Name("t".into())),
            ..ReadOptions::default()
        }),
        case(
            "sinumerik V20: a record attribute no signal declares",
            "s.xml",
            v20(&[("f2=\"-1099.98\"", "f4=\"-1099.98\"")]),
            |e| matches!(e, E::Header { line: 17, .. }),
            &[
                "s.xml:17:",
                "record attribute 'f4' is neither 'time' nor a declared dataSignal (declared: f1, f2, f3)",
            ],
        ),
        case(
            "sinumerik V20: a setpoint with no actual of its measuring system",
            "s.xml",
            v20(&[
                ("nckServoDataActPos2ndEnc64", "nckServoDataActVel2ndEnc64"),
                ("Position actual value measuring system 2", "Velocity actual value measuring system 2"),
            ]),
            |e| matches!(e, E::NoActualOfSystem { system: 2, line: 12, .. }),
            &[
                "s.xml:12: axis X: the setpoint 'Position setpoint' is for measuring system 2 (the direct measuring system)",
                "actual positions: 'Position actual value measuring system 1' (measuring system 1)",
                "--xr-col NOMINAL --x-col ACTUAL",
            ],
        )
        .read_with(ReadOptions {
            axis_map: vcnc_trace::AxisNumberMap::parse("1=X").unwrap(),
            ..ReadOptions::default()
        })
        .paired(d()),
        case(
            "sinumerik V20: fewer records than datapointCount (a cut file)",
            "s.xml",
            v20(&[("<rec time=\"0.004000\" f2=\"-1099.98\" f1=\"-299.98\"/>\n", "")]),
            |e| matches!(e, E::Truncated { .. }),
            &["s.xml:16:", "signal 'Position setpoint' declares 3 datapoints (line 12), the records hold 2"],
        ),
        case(
            "sinumerik V20: axis numbers without an axis map",
            "s.xml",
            v20(&[]),
            |e| matches!(e, E::NoAxis { axis_number: Some(1), .. }),
            &["s.xml:12:", "axis number 1 of the file", "--axis-map 1=A"],
        )
        .paired(d()),
        case(
            "sinumerik V20: lost motion of a setpoint that never reverses",
            "s.xml",
            v20(&[]),
            |e| matches!(e, E::NoReversal { reversals: 0, .. }),
            &["s.xml: axis X: the setpoint reverses 0 time(s)"],
        )
        .read_with(ReadOptions {
            axis_map: vcnc_trace::AxisNumberMap::parse("1=X").unwrap(),
            ..ReadOptions::default()
        })
        .lost_motion(),
        case(
            "halsampler: no period, the message names --ts",
            "s.txt",
            "0.1 0.1 \n0.2 0.2 \n",
            |e| matches!(e, E::MissingPeriod { .. }),
            &["s.txt: channel 'pin.0' has no sample period", "--ts SECONDS"],
        )
        .paired(PairOptions {
            map: vec![AxisMap {
                axis: AxisName::X,
                nominal: ChannelRef::Column(0),
                actual: ChannelRef::Column(1),
            }],
            ..PairOptions::default()
        }),
        case(
            "delimited (EMPS): no axis in the names, the message names the options",
            "DATA_EMPS.csv",
            "t,qg,qm,vir\n0,0.0001,0.00001,2.5\n0.001,0.0002,0.00002,2.4\n",
            |e| matches!(e, E::NoPositions { .. }),
            &[
                "no axis has both a nominal and an actual position channel",
                "--axis A --xr-col NOMINAL --x-col ACTUAL",
                "--units U",
            ],
        )
        .paired(d()),
        // ---- Sinumerik
        case(
            "sinumerik: file ends inside the frame",
            "s.xml",
            sinu(&[(
                "<rec time=\"0.004\" f1=\"0.2\" f2=\"0.15\"/>\n  </dataFrame>\n </traceData>\n</traceFile>\n",
                "",
            )]),
            |e| matches!(e, E::Truncated { .. }),
            &["s.xml:9:", "ends inside <dataFrame>"],
        ),
        case(
            "sinumerik: file cut inside an element",
            "s.xml",
            sinu(&[(
                "f2=\"0.15\"/>\n  </dataFrame>\n </traceData>\n</traceFile>\n",
                "f2=",
            )]),
            |e| matches!(e, E::Xml { .. }),
            &["s.xml:9:", "XML"],
        ),
        case(
            "sinumerik: value of an undeclared signal",
            "s.xml",
            sinu(&[("f2=\"0.15\"", "f3=\"0.15\"")]),
            |e| matches!(e, E::Header { .. }),
            &[
                "s.xml:9:",
                "record attribute 'f3' is neither 'time' nor a declared dataSignal (declared: f1, f2)",
            ],
        ),
        case(
            "sinumerik: record without time",
            "s.xml",
            sinu(&[("time=\"0.004\" ", "")]),
            |e| matches!(e, E::Header { .. }),
            &["s.xml:9:", "record without a time"],
        ),
        case(
            "sinumerik: unknown unit",
            "s.xml",
            sinu(&[("unit=\"mm\"", "unit=\"furlong\"")]),
            |e| matches!(e, E::UnknownUnit { .. }),
            &["s.xml:5:", "unknown unit 'furlong'"],
        )
        .paired(d()),
        case(
            "sinumerik: time goes back",
            "s.xml",
            sinu(&[("time=\"0.004\"", "time=\"0.001\"")]),
            |e| matches!(e, E::TimeNotIncreasing { .. }),
            &["s.xml:9:", "0.002 s, then 0.001 s"],
        ),
        case(
            "sinumerik: gap refused",
            "s.xml",
            sinu(&[("time=\"0.004\"", "time=\"0.006\"")]),
            |e| matches!(e, E::Gap { lost: Some(1), .. }),
            &["s.xml:9:", "1 sample lost"],
        )
        .paired(d()),
        case(
            "sinumerik: NaN",
            "s.xml",
            sinu(&[("f2=\"0.05\"", "f2=\"NaN\"")]),
            |e| matches!(e, E::NotFinite { .. }),
            &["s.xml:8:", "Position actual value X1 is NaN"],
        ),
        case(
            "sinumerik: signals that match no axis",
            "s.xml",
            sinu(&[
                ("Position setpoint X1", "Position setpoint"),
                ("/Nck/X1/PosSet", "/Nck/PosSet"),
                ("Position actual value X1", "Position actual value"),
                ("/Nck/X1/PosAct", "/Nck/PosAct"),
            ]),
            |e| matches!(e, E::NoAxis { .. }),
            &["s.xml:5:", "'Position setpoint'"],
        )
        .paired(d()),
        case(
            "sinumerik: no actual position",
            "s.xml",
            sinu(&[("Position actual value X1", "Speed actual value X1")]),
            |e| matches!(e, E::MissingChannel { .. }),
            &["s.xml", "no actual position channel for axis X"],
        )
        .paired(d()),
        // ---- TwinCAT Scope
        case(
            "twincat: no data block",
            "c.csv",
            twincat(&[("\n\n0;0;0;0\n1;0.1;1;0.05\n2;0.2;2;0.15\n", "\n")]),
            |e| matches!(e, E::Truncated { .. }),
            &["c.csv:9:", "no data after the channel block"],
        ),
        case(
            "twincat: last row cut",
            "c.csv",
            twincat(&[("2;0.2;2;0.15\n", "2;0.2;2")]),
            |e| matches!(e, E::Truncated { .. }),
            &["c.csv:13:", "stops before channel 'ActPos_X'"],
        ),
        case(
            "twincat: row longer than the channel block",
            "c.csv",
            twincat(&[("2;0.2;2;0.15", "2;0.2;2;0.15;7")]),
            |e| matches!(e, E::FieldCount { .. }),
            &["c.csv:13:", "5 fields where 4 are expected"],
        ),
        case(
            "twincat: unit row out of line",
            "c.csv",
            twincat(&[("Unit;mm;Unit;mm", "Unit;mm;mm;Unit;mm")]),
            |e| matches!(e, E::Header { .. }),
            &["c.csv:8:", "'Unit' does not line up"],
        ),
        case(
            "twincat: unknown unit",
            "c.csv",
            twincat(&[("Unit;mm;Unit;mm", "Unit;furlong;Unit;mm")]),
            |e| matches!(e, E::UnknownUnit { .. }),
            &["c.csv:6:", "'SetPos_X': unknown unit 'furlong'"],
        )
        .paired(d()),
        case(
            "twincat: time stands still",
            "c.csv",
            twincat(&[("2;0.2;2;0.15", "1;0.2;1;0.15")]),
            |e| matches!(e, E::TimeNotIncreasing { .. }),
            &["c.csv:13:", "0.001 s, then 0.001 s"],
        ),
        case(
            "twincat: gap refused",
            "c.csv",
            twincat(&[("2;0.2;2;0.15", "3;0.2;3;0.15")]),
            |e| matches!(e, E::Gap { .. }),
            &["c.csv:13:", "1 sample lost"],
        )
        .paired(d()),
        case(
            "twincat: sample time contradicts the time column",
            "c.csv",
            twincat(&[(
                "SampleTime[ms];1;SampleTime[ms];1",
                "SampleTime[ms];2;SampleTime[ms];2",
            )]),
            |e| matches!(e, E::IrregularTime { .. }),
            &["c.csv:12:", "irregular time step 0.001 s"],
        ),
        case(
            "twincat: NaN",
            "c.csv",
            twincat(&[("1;0.1;1;0.05", "1;0.1;1;nan")]),
            |e| matches!(e, E::NotFinite { .. }),
            &["c.csv:12:", "ActPos_X is nan"],
        ),
        case(
            "twincat: value without time",
            "c.csv",
            twincat(&[("2;0.2;2;0.15", ";0.2;2;0.15")]),
            |e| matches!(e, E::Header { .. }),
            &[
                "c.csv:13:",
                "'SetPos_X' has a value where its time column (column 1) has none",
            ],
        ),
        case(
            "twincat: names that match no axis",
            "c.csv",
            twincat(&[
                ("SetPos_X;Name;ActPos_X", "SetPos;Name;ActPos"),
                ("MAIN.AxisX.SetPos", "MAIN.Axis1.SetPos"),
                ("MAIN.AxisX.ActPos", "MAIN.Axis1.ActPos"),
            ]),
            |e| matches!(e, E::NoAxis { .. }),
            &["c.csv:6:", "'SetPos'"],
        )
        .paired(d()),
        case(
            "twincat: no actual position",
            "c.csv",
            twincat(&[
                ("ActPos_X\n", "ActVelo_X\n"),
                ("MAIN.AxisX.ActPos", "MAIN.AxisX.ActVelo"),
            ]),
            |e| matches!(e, E::MissingChannel { .. }),
            &["c.csv", "no actual position channel for axis X"],
        )
        .paired(d()),
        // ---- delimited text
        case(
            "delimited: last row cut",
            "t.csv",
            "t,xr,x\n0,0,0\n0.001,1",
            |e| matches!(e, E::Truncated { .. }),
            &["t.csv:3:", "2 of 3 fields"],
        ),
        case(
            "delimited: ragged row",
            "t.csv",
            "t,xr,x\n0,0,0\n0.001,1\n",
            |e| matches!(e, E::FieldCount { .. }),
            &["t.csv:3:", "2 fields where 3 are expected"],
        ),
        case(
            "delimited: NaN",
            "t.csv",
            "t,xr,x\n0,0,0\n0.001,NaN,0\n",
            |e| matches!(e, E::NotFinite { .. }),
            &["t.csv:3:", "xr is NaN"],
        ),
        case(
            "delimited: not a number",
            "t.csv",
            "t,xr,x\n0,0,0\n0.001,abc,0\n",
            |e| matches!(e, E::NotANumber { .. }),
            &["t.csv:3:", "xr: 'abc' is not a number"],
        ),
        case(
            "delimited: unknown unit",
            "t.csv",
            "t,xr [furlong],x [furlong]\n0,0,0\n0.001,0,0\n",
            |e| matches!(e, E::UnknownUnit { .. }),
            &["t.csv:1:", "unknown unit 'furlong'"],
        )
        .paired(d()),
        case(
            "delimited: time in a length unit",
            "t.csv",
            "t [mm],xr,x\n0,0,0\n",
            |e| matches!(e, E::Header { .. }),
            &["t.csv:1:", "time column 't' is in mm"],
        ),
        case(
            "delimited: time stands still",
            "t.csv",
            "t,xr,x\n0,0,0\n0.001,0,0\n0.001,0,0\n",
            |e| matches!(e, E::TimeNotIncreasing { .. }),
            &["t.csv:4:", "0.001 s, then 0.001 s"],
        ),
        case(
            "delimited: irregular step",
            "t.csv",
            "t,xr,x\n0,0,0\n0.001,0,0\n0.0025,0,0\n",
            |e| matches!(e, E::IrregularTime { .. }),
            &["t.csv:4:", "irregular time step"],
        ),
        case(
            "delimited: gap refused",
            "t.csv",
            "t,xr,x\n0,0,0\n0.001,0,0\n0.003,0,0\n",
            |e| matches!(e, E::Gap { lost: Some(1), .. }),
            &["t.csv:4:", "'xr': 1 sample lost"],
        )
        .paired(d()),
        case(
            "delimited: names that match no axis",
            "t.csv",
            "t,pos_cmd,pos_fb\n0,0,0\n",
            |e| matches!(e, E::NoAxis { .. }),
            &["t.csv:1:", "'pos_cmd'"],
        )
        .paired(d()),
        case(
            "delimited: no actual position",
            "t.csv",
            "t,xr,v\n0,0,0\n",
            |e| matches!(e, E::MissingChannel { .. }),
            &["t.csv", "no actual position channel for axis X"],
        )
        .paired(d()),
        case(
            "delimited: mapped column absent",
            "t.csv",
            "t,xr,x\n0,0,0\n",
            |e| matches!(e, E::UnknownChannel { .. }),
            &["t.csv", "no channel 'qg'", "'xr' (X, nominal position)"],
        )
        .paired(map_qg),
        case(
            "delimited: period contradicts the time column",
            "t.csv",
            "t,xr,x\n0,0,0\n0.001,0,0\n",
            |e| matches!(e, E::PeriodConflict { .. }),
            &["t.csv:1:", "0.001 s", "0.002 s"],
        )
        .read_with(period(2e-3)),
        // ---- detection
        case(
            "prose",
            "notes.txt",
            "Dear diary,\nthe machine was quick today.\n",
            |e| matches!(e, E::UnknownFormat { tried, .. } if tried.len() == Format::ALL.len()),
            &[
                "notes.txt: not a trace format",
                "sinumerik",
                "tncscope",
                "halscope",
                "twincat",
                "halsampler",
                "delimited",
            ],
        ),
        case(
            "binary",
            "scope.DTA",
            b"\x00\x01\x02\xff".to_vec(),
            |e| matches!(e, E::UnknownFormat { .. }),
            &["scope.DTA", "binary content"],
        ),
        case(
            "empty",
            "empty.csv",
            "",
            |e| matches!(e, E::UnknownFormat { .. }),
            &["empty.csv", "no line other than blanks"],
        ),
        case(
            "forced format on other content",
            "t.csv",
            "t,xr,x\n0,0,0\n",
            |e| matches!(e, E::Header { line: 1, .. }),
            &["t.csv:1:", "expected '%TNCscope"],
        )
        .read_with(ReadOptions {
            format: Some(Format::TncScope),
            ..ReadOptions::default()
        }),
    ]
}

#[test]
fn every_bad_input_gives_its_typed_error_with_file_and_line() {
    let print = std::env::var("VCNC_PRINT_MESSAGES").is_ok_and(|v| v == "1");
    let mut failures = Vec::new();
    for c in cases() {
        let read = read_bytes(c.file, &c.content, &c.read);
        let err = match (&c.pair, read) {
            (None, Err(e)) => e,
            (None, Ok(_)) => {
                failures.push(format!("{}: read without error", c.name));
                continue;
            }
            (Some(_), Err(e)) => {
                failures.push(format!("{}: read failed, pairing expected to: {e}", c.name));
                continue;
            }
            (Some(opts), Ok(t)) => match pair(&t, opts) {
                Err(e) if !c.lost_motion => e,
                Ok(p) if c.lost_motion => match vcnc_trace::lost_motion(&p.axes[0]) {
                    Err(e) => e,
                    Ok(_) => {
                        failures.push(format!("{}: lost motion without error", c.name));
                        continue;
                    }
                },
                Err(e) => {
                    failures.push(format!("{}: pairing failed: {e}", c.name));
                    continue;
                }
                Ok(_) => {
                    failures.push(format!("{}: paired without error", c.name));
                    continue;
                }
            },
        };
        let msg = err.to_string();
        if print {
            println!("| {} | `{msg}` |", c.name);
        }
        if !(c.kind)(&err) {
            failures.push(format!("{}: wrong error kind: {err:?}", c.name));
        }
        for e in c.expect {
            if !msg.contains(e) {
                failures.push(format!("{}: message lacks {e:?}: {msg}", c.name));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Columns in memory (numpy arrays from Python, `vcnc_trace::from_columns`) are refused as
/// their file would be: a NaN names its column and the line its sample would be on (sample
/// `k` on line `k + 2`), an irregular time the same; unequal or empty columns name the
/// lengths.
#[test]
fn bad_columns_in_memory_give_their_typed_error() {
    let t: Vec<f64> = (0..10).map(|k| k as f64 * 1e-3).collect();
    let opts = ReadOptions::default();
    let cols = |xr: Vec<f64>| vec![("xr".to_string(), xr), ("x".to_string(), vec![0.0; 10])];
    let mut xr = vec![0.0; 10];
    xr[3] = f64::NAN;
    let e = vcnc_trace::from_columns("<arrays>", Some(&t), cols(xr), &opts).unwrap_err();
    assert!(matches!(e, Error::NotFinite { line: 5, .. }), "{e}");
    assert_eq!(e.to_string(), "<arrays>:5: xr is NaN: not a finite number");
    let e = vcnc_trace::from_columns("<arrays>", Some(&t), cols(vec![0.0; 9]), &opts).unwrap_err();
    assert!(matches!(e, Error::BadOption { .. }), "{e}");
    assert!(e.to_string().contains("t 10, xr 9, x 10"), "{e}");
    let e = vcnc_trace::from_columns("<arrays>", None, vec![], &opts).unwrap_err();
    assert!(matches!(e, Error::BadOption { .. }), "{e}");
    let mut jitter = t.clone();
    jitter[6] += 0.5e-3;
    let e = vcnc_trace::from_columns("<arrays>", Some(&jitter), cols(vec![0.0; 10]), &opts)
        .unwrap_err();
    assert!(matches!(e, Error::IrregularTime { line: 8, .. }), "{e}");
}
