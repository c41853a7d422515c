//! Bad input, table-driven (issue 7): every case must exit with code 2 (bad input), print a
//! message that names the file (and line:column where there is one) and the offending value,
//! never panic, and never leave a partial output file.

use crate::util::{repo, tempdir, text, vcnc_in};

/// One bad-input case: files written into a fresh folder, the command, and fragments that must
/// all appear on stderr.
struct Case {
    name: &'static str,
    files: &'static [(&'static str, &'static str)],
    args: &'static [&'static str],
    expect: &'static [&'static str],
}

const PPI: &str = "MACHINE_PPI";
const NMV: &str = "MACHINE_NMV";

/// A valid single-axis machine file to derive broken ones from (kept in sync with
/// machines/ballscrew-ppi.toml by `base_machine_is_valid`).
const BASE: &str = r#"name = "t"
sample_period_s = 0.001
[axes.X]
unit = "mm"
travel = [-100.0, 100.0]
max_velocity = 250.0
max_acceleration = 2500.0
plant = { j = 0.01, b = 0.0418572, ka = 1.0, kt = 1.0, rg = 1.5915, coulomb_torque = 0.3 }
controller = { kind = "p-pi", kv = 70.0, kp = 2.342478, ki = 223.252126, vff = 0.5, bff = 0.1 }
"#;

const PROG: &str = "G21 G90\nG0 X0\nG1 X10 F600\nM2\n";

fn cases() -> Vec<Case> {
    let g = |name, prog: &'static str, expect: &'static [&'static str]| Case {
        name,
        files: Box::leak(Box::new([("p.ngc", prog)])),
        args: &["interpolate", PPI, "p.ngc", "--out", "out"],
        expect,
    };
    let m = |name, machine: &'static str, expect: &'static [&'static str]| Case {
        name,
        files: Box::leak(Box::new([("m.toml", machine), ("p.ngc", PROG)])),
        args: &["interpolate", "m.toml", "p.ngc", "--out", "out"],
        expect,
    };
    let t = |name, trace: &'static str, expect: &'static [&'static str]| Case {
        name,
        files: Box::leak(Box::new([("t.csv", trace)])),
        args: &["identify", "--trace", "t.csv", "--out", "out"],
        expect,
    };
    // A model file given to `cmd` (`predict`, `simulate`) on the P-PI machine.
    let model =
        |name, cmd: &'static str, model: &'static str, expect: &'static [&'static str]| Case {
            name,
            files: Box::leak(Box::new([("p.ngc", PROG), ("model.toml", model)])),
            args: Box::leak(Box::new([
                cmd,
                PPI,
                "p.ngc",
                "--model",
                "model.toml",
                "--out",
                "out",
            ])),
            expect,
        };
    // A bad options file is reported before the trace is read (this trace is valid CSV).
    let opts = |name, options: &'static str, expect: &'static [&'static str]| Case {
        name,
        files: Box::leak(Box::new([
            ("o.toml", options),
            ("t.csv", "t,xr,x\n0,0,0\n"),
        ])),
        args: &[
            "identify",
            "--trace",
            "t.csv",
            "--options",
            "o.toml",
            "--out",
            "out",
        ],
        expect,
    };
    let leak = |s: String| -> &'static str { Box::leak(s.into_boxed_str()) };
    let with = |from: &str, to: &str| -> &'static str {
        let s = BASE.replace(from, to);
        assert_ne!(s, BASE, "replacement {from:?} not found");
        leak(s)
    };
    vec![
        // --- G-code -------------------------------------------------------------------------
        g(
            "unknown word",
            "G21\nG0 X0\nG1 X1 Q5 F600\n",
            &["p.ngc:3:", "Q"],
        ),
        g(
            "unknown G-code",
            "G21\nG0 X0\nG38.2 X1\n",
            &["p.ngc:3:", "G38.2"],
        ),
        g(
            "unknown M-code",
            "G21\nG0 X0\nM700\n",
            &["p.ngc:3:", "M700"],
        ),
        g(
            "malformed number",
            "G21\nG0 X0\nG1 X1.2.3 F600\n",
            &["p.ngc:3:"],
        ),
        g(
            "word without value",
            "G21\nG0 X0\nG1 X F600\n",
            &["p.ngc:3:", "X"],
        ),
        g(
            "modal conflict G0 G1",
            "G21\nG0 X0\nG0 G1 X1 F600\n",
            &["p.ngc:3:", "G0", "G1"],
        ),
        g(
            "modal conflict G90 G91",
            "G21\nG0 X0\nG90 G91 X1\n",
            &["p.ngc:3:", "G90", "G91"],
        ),
        g(
            "arc radius does not fit",
            "G21 G17\nG0 X0 Y0\nG2 X10 Y0 R2 F600\n",
            &["p.ngc:3:", "R"],
        ),
        g(
            "arc centre radii differ",
            "G21 G17\nG0 X0 Y0\nG2 X10 Y0 I3 J0 F600\n",
            &["p.ngc:3:", "radi"],
        ),
        g(
            "arc without centre",
            "G21 G17\nG0 X0 Y0\nG2 X10 Y0 F600\n",
            &["p.ngc:3:"],
        ),
        g(
            "G93 without F",
            "G21\nG0 X0\nG93 G1 X10\n",
            &["p.ngc:3:", "F"],
        ),
        g(
            "feed move without feed",
            "G21\nG0 X0\nG1 X10\n",
            &["p.ngc:3:", "feed"],
        ),
        g("dwell without P", "G21\nG0 X0\nG4\n", &["p.ngc:3:", "P"]),
        g(
            "axis word twice",
            "G21\nG0 X0\nG1 X1 X2 F600\n",
            &["p.ngc:3:", "X"],
        ),
        g(
            "move beyond travel",
            "G21\nG0 X0\nG1 X500 F6000\n",
            &["p.ngc:3:", "travel", "500"],
        ),
        g(
            "axis the machine lacks",
            "G21\nG0 X0\nG1 B10 F600\n",
            &["p.ngc:3:", "B"],
        ),
        g(
            "TCP without kinematics",
            "G21\nG43.4\nG0 X0\nG1 X10 F600\n",
            &["kinematics"],
        ),
        g(
            "errors on several lines are all reported",
            "G21\nG0 X0\nG1 X1 Q1 F600\nG1 X2 Q2\n",
            &["p.ngc:3:", "p.ngc:4:"],
        ),
        Case {
            name: "invalid UTF-8",
            // Raw byte 0xFF on line 3 (written by `generated`): not UTF-8 at all.
            files: &[("p.ngc", "GEN_INVALID_UTF8")],
            args: &["interpolate", PPI, "p.ngc", "--out", "out"],
            expect: &["p.ngc:3:"],
        },
        Case {
            name: "program file missing",
            files: &[],
            args: &["interpolate", PPI, "nope.ngc", "--out", "out"],
            expect: &["nope.ngc", "cannot read"],
        },
        // --- machine files ------------------------------------------------------------------
        m(
            "TOML syntax",
            leak(format!("{BASE}[axes.Y\n")),
            &["m.toml:10:", "unclosed"],
        ),
        m(
            "unknown top-level key",
            leak(format!("colour = 1\n{BASE}")),
            &["m.toml:1:", "colour"],
        ),
        m(
            "unknown axis key",
            with("unit = \"mm\"", "unit = \"mm\"\nbogus = 3"),
            &["m.toml:5:", "bogus"],
        ),
        m(
            "unknown plant key",
            with("coulomb_torque = 0.3", "coulomb_torque = 0.3, stiction = 2"),
            &["m.toml:8:91", "stiction"],
        ),
        m(
            // The controller is an internally tagged enum: serde loses the key's span, the
            // loader finds the key in the inline table again.
            "unknown controller key",
            with("kv = 70.0", "kvv = 70.0"),
            &["m.toml:9:31", "unknown field `kvv`", "expected one of `kv`"],
        ),
        m(
            "missing key",
            with("max_velocity = 250.0\n", ""),
            &["m.toml:", "max_velocity"],
        ),
        m(
            "missing plant",
            with(
                "plant = { j = 0.01, b = 0.0418572, ka = 1.0, kt = 1.0, rg = 1.5915, coulomb_torque = 0.3 }\n",
                "",
            ),
            &["m.toml:", "plant"],
        ),
        m(
            "wrong type",
            with("max_velocity = 250.0", "max_velocity = \"fast\""),
            &["m.toml:6:", "string"],
        ),
        m(
            "negative inertia",
            with("j = 0.01", "j = -0.01"),
            &["m.toml:8:", "plant.j", "-0.01"],
        ),
        m(
            "NaN gain",
            with("kv = 70.0", "kv = nan"),
            &["m.toml:", "kv"],
        ),
        m(
            "unstable gains",
            with("kp = 2.342478", "kp = 0.001"),
            &["m.toml:9:", "unstable", "axis X"],
        ),
        m(
            "unknown controller kind",
            with("kind = \"p-pi\"", "kind = \"lqr\""),
            &["m.toml:9:", "lqr"],
        ),
        m(
            "gains and design together",
            with(
                "vff = 0.5",
                "design = { p_hz = 10.0, wn_hz = 30.0, zeta = 0.5 }, vff = 0.5",
            ),
            &["m.toml:9:", "design"],
        ),
        m(
            "unreachable design",
            with(
                "kv = 70.0, kp = 2.342478, ki = 223.252126",
                "design = { p_hz = 100.0, wn_hz = 1.0, zeta = 0.2 }",
            ),
            &["m.toml:9:", "axis X"],
        ),
        m(
            "wrong unit for a linear axis",
            with("unit = \"mm\"", "unit = \"deg\""),
            &["m.toml:4:", "mm"],
        ),
        m(
            "inverted travel",
            with("travel = [-100.0, 100.0]", "travel = [100.0, -100.0]"),
            &["m.toml:5:", "travel"],
        ),
        m(
            "servo rate not a multiple",
            with(
                "max_acceleration = 2500.0",
                "max_acceleration = 2500.0\nservo_rate_hz = 1500.0",
            ),
            &["m.toml:", "servo"],
        ),
        m(
            "zero sample period",
            with("sample_period_s = 0.001", "sample_period_s = 0.0"),
            &["m.toml:2:", "sample"],
        ),
        m(
            // Absurd values are printed compactly (1e-30, not thirty zeros).
            "sample period of 1e-30 s",
            with("sample_period_s = 0.001", "sample_period_s = 1e-30"),
            &[
                "m.toml:2:",
                "sample period must be in [1e-6, 0.1] s, got 1e-30",
            ],
        ),
        m(
            "absurd viscous damping",
            with("b = 0.0418572", "b = 1.3e69"),
            &["m.toml:8:", "plant.b = 1.3e69 is invalid"],
        ),
        m(
            "unknown axis letter",
            with("[axes.X]", "[axes.Q]"),
            &["m.toml:3:", "Q"],
        ),
        Case {
            name: "URDF file missing",
            files: &[],
            args: &[
                "interpolate",
                "m_urdf_missing.toml",
                "p.ngc",
                "--out",
                "out",
            ],
            expect: &["nope.urdf"],
        },
        Case {
            // Any serial chain is a machine now (issue 28); a URDF without the tool-tip link is
            // not one.
            name: "URDF without a tool tip",
            files: &[],
            args: &["interpolate", "m_urdf_bad.toml", "p.ngc", "--out", "out"],
            expect: &["bad.urdf", "tool_tip"],
        },
        Case {
            name: "machine file missing",
            files: &[("p.ngc", PROG)],
            args: &["interpolate", "none.toml", "p.ngc", "--out", "out"],
            expect: &["none.toml", "cannot read"],
        },
        // --- traces -------------------------------------------------------------------------
        t(
            "NaN in a trace",
            "t,xr,x\n0,0,0\n0.001,NaN,0\n",
            &["t.csv:3:", "xr"],
        ),
        t(
            "missing column",
            "t,ref,x\n0,0,0\n",
            &["t.csv", "no nominal position channel for axis X"],
        ),
        t(
            "not a number",
            "t,xr,x\n0,0,0\n0.001,abc,0\n",
            &["t.csv:3:", "abc"],
        ),
        t("ragged row", "t,xr,x\n0,0,0\n0.001,1\n", &["t.csv:3:"]),
        t("empty trace", "t,xr,x\n", &["t.csv", "too few samples"]),
        Case {
            name: "one column of a pair given",
            files: &[("t.csv", "t,xr,x\n0,0,0\n0.001,1,1\n")],
            args: &[
                "identify", "--trace", "t.csv", "--xr-col", "xr", "--out", "out",
            ],
            expect: &["--xr-col and --x-col go together"],
        },
        // --- scope-file importers (issue 12): every format's faults name the file and line --
        Case {
            name: "halscope log truncated",
            files: &[(
                "h.log",
                "# Sampling period is 1000000 ns\njoint.0.motor-pos-cmd;joint.0.motor-pos-fb\n0.0;0.0\n0.5\n",
            )],
            args: &["identify", "--trace", "h.log", "--out", "out"],
            expect: &["h.log:4:", "fields"],
        },
        Case {
            name: "TNCscope curve count does not match its data",
            files: &[(
                "s.txt",
                "%TNCscopeNT data file\n%[GLOBAL]\nCURVES=2\n%[CURVE1]\nNAME=X s soll\nCHANNELTYPE=s soll\nAXISTYPE=X\nDIMENSION=mm\nCOUNT=3\nCYCLETIME=1000\n%[CURVE2]\nNAME=X s ist\nCHANNELTYPE=s ist\nAXISTYPE=X\nDIMENSION=mm\nCOUNT=3\nCYCLETIME=1000\n%[DATA]\n0;0.0;0.0;\n1000;0.1;0.0;\n",
            )],
            args: &["identify", "--trace", "s.txt", "--out", "out"],
            expect: &["s.txt", "3", "2"],
        },
        Case {
            name: "unknown unit in a TNCscope file",
            files: &[(
                "s.txt",
                "%TNCscopeNT data file\n%[GLOBAL]\nCURVES=2\n%[CURVE1]\nNAME=X s soll\nCHANNELTYPE=s soll\nAXISTYPE=X\nDIMENSION=furlong\nCOUNT=2\nCYCLETIME=1000\n%[CURVE2]\nNAME=X s ist\nCHANNELTYPE=s ist\nAXISTYPE=X\nDIMENSION=mm\nCOUNT=2\nCYCLETIME=1000\n%[DATA]\n0;0.0;0.0;\n1000;0.1;0.0;\n",
            )],
            args: &["identify", "--trace", "s.txt", "--out", "out"],
            expect: &["s.txt:", "unknown unit 'furlong'"],
        },
        Case {
            name: "halsampler overrun (lost samples)",
            files: &[("h.txt", "GEN_OVERRUN")],
            args: &[
                "identify", "--trace", "h.txt", "--ts", "0.001", "--out", "out",
            ],
            expect: &["h.txt:", "lost", "refused"],
        },
        Case {
            name: "a channel that matches no axis",
            files: &[(
                "h.log",
                "# Sampling period is 1000000 ns\npid.pos-cmd;pid.pos-fb\n0.0;0.0\n0.5;0.1\n",
            )],
            args: &["identify", "--trace", "h.log", "--out", "out"],
            expect: &["h.log", "matches no axis"],
        },
        Case {
            name: "not a trace format",
            files: &[("notes.txt", "dear diary,\ntoday the machine ran\n")],
            args: &["trace", "info", "notes.txt"],
            expect: &["notes.txt", "not a trace format vcnc reads"],
        },
        Case {
            name: "--ts contradicts the time column",
            files: &[("t.csv", "GEN_STILL")],
            args: &[
                "identify", "--trace", "t.csv", "--ts", "0.002", "--out", "out",
            ],
            expect: &["t.csv", "the period given is 0.002 s"],
        },
        // --- identifier options file (identify --trace --options) -----------------------------
        opts(
            "options: unknown key",
            "deadband = 2.0\nparticels = 50\n",
            &["o.toml:2:1", "particels"],
        ),
        opts(
            "options: bounds in the wrong order",
            "[bounds]\nwn_hz = [200.0, 5.0]\n",
            &["o.toml:2:", "bounds.wn_hz", "min < max"],
        ),
        opts(
            "options: wrong type",
            "seed = \"seven\"\n",
            &["o.toml:1:", "invalid type"],
        ),
        opts(
            "options: a misspelt structure",
            "structures = [\"paper\", \"no-integrl\"]\n",
            &["o.toml:1:", "no-integrl", "no-integral"],
        ),
        opts(
            "options: negative deadband",
            "deadband = -1.0\n",
            &["o.toml:1:", "deadband", "-1"],
        ),
        Case {
            name: "options: with a machine file",
            files: &[("o.toml", "deadband = 2.0\n")],
            args: &["identify", PPI, "--options", "o.toml", "--out", "out"],
            expect: &[
                "--options apply to --trace only",
                "[identification.options]",
            ],
        },
        Case {
            name: "trace column name with a machine file",
            files: &[],
            args: &["identify", PPI, "--xr-col", "qg", "--out", "out"],
            expect: &["--xr-col", "apply to --trace only"],
        },
        Case {
            name: "options: file missing",
            files: &[("t.csv", "t,xr,x\n0,0,0\n")],
            args: &[
                "identify",
                "--trace",
                "t.csv",
                "--options",
                "none.toml",
                "--out",
                "out",
            ],
            expect: &["none.toml", "cannot read"],
        },
        Case {
            name: "non-monotonic time",
            files: &[("t.csv", "GEN_NONMONOTONIC")],
            args: &["identify", "--trace", "t.csv", "--out", "out"],
            expect: &["t.csv:1002:", "time does not increase"],
        },
        Case {
            name: "non-uniform time",
            files: &[("t.csv", "GEN_NONUNIFORM")],
            args: &["identify", "--trace", "t.csv", "--out", "out"],
            expect: &["t.csv:1002:", "irregular time step"],
        },
        Case {
            name: "too few samples",
            files: &[("t.csv", "GEN_SHORT")],
            args: &["identify", "--trace", "t.csv", "--out", "out"],
            expect: &["t.csv", "too few samples"],
        },
        Case {
            name: "no motion",
            files: &[("t.csv", "GEN_STILL")],
            args: &["identify", "--trace", "t.csv", "--out", "out"],
            expect: &["t.csv", "no motion"],
        },
        Case {
            name: "data that cannot identify the model",
            files: &[("t.csv", "GEN_RAMP")],
            args: &["identify", "--trace", "t.csv", "--out", "out"],
            expect: &["t.csv", "identification refused"],
        },
        // --- options and other files ---------------------------------------------------------
        Case {
            name: "zero threads",
            files: &[],
            args: &["--threads", "0", "gen", "spiral"],
            expect: &["--threads"],
        },
        Case {
            name: "unknown generator axis",
            files: &[],
            args: &["gen", "identification", "--axis", "Q"],
            expect: &["Q"],
        },
        Case {
            name: "malformed --set",
            files: &[("p.ngc", PROG)],
            args: &[
                "sweep",
                PPI,
                "p.ngc",
                "--set",
                "axes.X.plant.j",
                "--out",
                "out",
            ],
            expect: &["--set", "KEY="],
        },
        Case {
            name: "shard out of range",
            files: &[("p.ngc", PROG)],
            args: &[
                "sweep",
                PPI,
                "p.ngc",
                "--set",
                "axes.X.plant.j=0.01",
                "--shard",
                "4/3",
                "--out",
                "out",
            ],
            expect: &["--shard", "4/3"],
        },
        model(
            "unstable model file",
            "simulate",
            "[axes.X]\nunit = \"mm\"\na1 = 1.0\na2 = 1.0\na3 = 100.0\nb0 = 0.0\nb1 = 0.0\nb2 = 1.0\ndc = 0.0\n",
            &["model.toml:1:", "axis X", "not stable"],
        ),
        // A model without integral action (a3 = 0, the `no-integral` structure) is read by
        // the same rules as any other.
        model(
            "no-integral model file without b2",
            "predict",
            "[axes.X]\nunit = \"mm\"\na1 = 94.8\na2 = 16194.3\na3 = 0.0\nb0 = 0.0\nb1 = 0.0\ndc = 239.8\ninput = \"hold\"\n",
            &["model.toml", "missing field `b2`"],
        ),
        model(
            "no-integral model file with an unknown key",
            "predict",
            "[axes.X]\nunit = \"mm\"\na1 = 94.8\na2 = 16194.3\na3 = 0.0\nb0 = 0.0\nb1 = 0.0\nb2 = 16194.3\ndc = 239.8\nintegral = false\n",
            &["model.toml:10:", "unknown field `integral`"],
        ),
        model(
            "no-integral model file with a negative damping term",
            "simulate",
            "[axes.X]\nunit = \"mm\"\na1 = -94.8\na2 = 16194.3\na3 = 0.0\nb0 = 0.0\nb1 = 0.0\nb2 = 16194.3\ndc = 239.8\n",
            &["model.toml:1:", "axis X", "not stable"],
        ),
        model(
            "negative actual-value latency in a model file",
            "predict",
            "[axes.X]\nunit = \"mm\"\na1 = 238.4\na2 = 48421.6\na3 = 2487140.3\nb0 = 0.0\nb1 = 117.5\nb2 = 37259.0\ndc = 47.7\nactual_latency_s = -1e-4\n",
            &["model.toml:10:20:", "axes.X.actual_latency_s", "-0.0001"],
        ),
        model(
            "model file without the machine's axis",
            "simulate",
            "[axes.Y]\nunit = \"mm\"\na1 = 238.4\na2 = 48421.6\na3 = 2487140.3\nb0 = 0.0\nb1 = 117.5\nb2 = 37259.0\ndc = 47.7\n",
            &["model.toml", "no model for axis X"],
        ),
        Case {
            name: "actual-value latency in the wrong unit",
            files: &[],
            args: &["identify", NMV, "--actual-latency-s", "2", "--out", "out"],
            expect: &["--actual-latency-s 2", "≤ 0.1 s"],
        },
        Case {
            name: "unknown axis for identify",
            files: &[],
            args: &["identify", NMV, "--axis", "B", "--out", "out"],
            expect: &["--axis B", "no axis B"],
        },
        Case {
            name: "validate: the trace's axis has no model",
            files: &[
                ("t.csv", VALID_TRACE),
                (
                    "model.toml",
                    "[axes.Y]\nunit = \"mm\"\na1 = 238.4\na2 = 48421.6\na3 = 2487140.3\nb0 = 0.0\nb1 = 117.5\nb2 = 37259.0\ndc = 47.7\n",
                ),
            ],
            args: &[
                "validate",
                "--model",
                "model.toml",
                "--trace",
                "t.csv",
                "--out",
                "out",
            ],
            expect: &["t.csv", "(X)", "model.toml", "(Y)"],
        },
        Case {
            name: "validate: a model of another unit",
            files: &[
                ("t.csv", VALID_TRACE),
                (
                    "model.toml",
                    "[axes.X]\nunit = \"deg\"\na1 = 238.4\na2 = 48421.6\na3 = 2487140.3\nb0 = 0.0\nb1 = 117.5\nb2 = 37259.0\ndc = 47.7\n",
                ),
            ],
            args: &[
                "validate",
                "--model",
                "model.toml",
                "--trace",
                "t.csv",
                "--out",
                "out",
            ],
            expect: &["model.toml", "axis X", "deg", "mm"],
        },
        Case {
            name: "validate: a model file with an unknown key",
            files: &[
                ("t.csv", VALID_TRACE),
                (
                    "model.toml",
                    "[axes.X]\nunit = \"mm\"\na1 = 238.4\na2 = 48421.6\na3 = 2487140.3\nb0 = 0.0\nb1 = 117.5\nb2 = 37259.0\ndc = 47.7\ngain = 3\n",
                ),
            ],
            args: &[
                "validate",
                "--model",
                "model.toml",
                "--trace",
                "t.csv",
                "--out",
                "out",
            ],
            expect: &["model.toml", "gain"],
        },
        Case {
            name: "validate: a trace whose time runs back",
            files: &[
                ("t.csv", "t,xr,x\n0,0,0\n0.001,0,0\n0.0005,0,0\n0.002,0,0\n"),
                (
                    "model.toml",
                    "[axes.X]\nunit = \"mm\"\na1 = 238.4\na2 = 48421.6\na3 = 2487140.3\nb0 = 0.0\nb1 = 117.5\nb2 = 37259.0\ndc = 47.7\n",
                ),
            ],
            args: &[
                "validate",
                "--model",
                "model.toml",
                "--trace",
                "t.csv",
                "--out",
                "out",
            ],
            expect: &["t.csv", "0.0005"],
        },
    ]
}

/// A short valid single-axis trace (t, xr, x in mm), made for these cases: a raised-cosine
/// 1 mm move in 0.1 s, the actual position the nominal one 2 ms late.
const VALID_TRACE: &str = include_str!("data/validate-trace.csv");

/// Generated trace files (too long to write inline).
fn generated(marker: &str) -> Option<Vec<u8>> {
    if marker == "GEN_INVALID_UTF8" {
        return Some(b"G21\nG0 X0\nG1 X1 F600 \xff\n".to_vec());
    }
    let mut s = String::from("t,xr,x\n");
    let row = |s: &mut String, t: f64, xr: f64, x: f64| s.push_str(&format!("{t},{xr},{x}\n"));
    match marker {
        "GEN_NONMONOTONIC" => {
            for k in 0..2000 {
                let t = if k == 1000 { 0.5 } else { k as f64 * 1e-3 };
                row(&mut s, t, (k as f64 * 0.01).sin(), 0.0);
            }
        }
        "GEN_NONUNIFORM" => {
            for k in 0..2000 {
                let t = k as f64 * 1e-3 + if k >= 1000 { 0.0005 } else { 0.0 };
                row(&mut s, t, (k as f64 * 0.01).sin(), 0.0);
            }
        }
        "GEN_SHORT" => {
            for k in 0..20 {
                row(&mut s, k as f64 * 1e-3, k as f64, k as f64);
            }
        }
        "GEN_STILL" => {
            for k in 0..5000 {
                row(&mut s, k as f64 * 1e-3, 1.0, 1.0);
            }
        }
        "GEN_RAMP" => {
            // A constant-velocity ramp followed exactly: no acceleration, no tracking error.
            for k in 0..5000 {
                let x = k as f64 * 0.05;
                row(&mut s, k as f64 * 1e-3, x, x);
            }
        }
        "GEN_OVERRUN" => {
            // halsampler output (`-t`: sample number first) that lost samples after row 1500.
            let mut h = String::from("# x-pos-cmd x-pos-fb\n");
            for k in 0..3000usize {
                if k == 1500 {
                    h.push_str("overrun\n");
                }
                let xr = (k as f64 * 0.003).sin();
                h.push_str(&format!("{k} {xr} {}\n", 0.9 * xr));
            }
            return Some(h.into_bytes());
        }
        _ => return None,
    }
    Some(s.into_bytes())
}

fn machine_variants(dir: &std::path::Path) {
    std::fs::write(
        dir.join("m_urdf_missing.toml"),
        BASE.replacen(
            "sample_period_s = 0.001\n",
            "sample_period_s = 0.001\n[kinematics]\nurdf = \"nope.urdf\"\n",
            1,
        ),
    )
    .unwrap();
    std::fs::write(
        dir.join("m_urdf_bad.toml"),
        BASE.replacen(
            "sample_period_s = 0.001\n",
            "sample_period_s = 0.001\n[kinematics]\nurdf = \"bad.urdf\"\n",
            1,
        ),
    )
    .unwrap();
    let urdf = std::fs::read_to_string(repo("machines/nmv5000.urdf")).unwrap();
    let bad = urdf.replace("tool_tip", "tool_end");
    assert_ne!(bad, urdf, "the URDF changed: update this test");
    std::fs::write(dir.join("bad.urdf"), bad).unwrap();
    if !dir.join("p.ngc").exists() {
        std::fs::write(dir.join("p.ngc"), PROG).unwrap();
    }
}

#[test]
fn a_100_mb_program_of_junk_is_rejected() {
    // Issue 7: a huge junk program is rejected with a clear reason. There is no size cap any
    // more (issue 15: a file is refused up front only when preparing it would exceed the
    // memory available, or it has more blocks than the parser takes); this one is parsed and
    // refused by the interpreter, naming the file and the first offending line, with the
    // diagnostics capped.
    let dir = tempdir();
    let path = dir.path().join("junk.ngc");
    {
        use std::io::Write;
        let mut f = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        let line = b"G1 X1.5 Y-2 Z3 (junk junk junk junk junk junk junk junk junk junk junk)\n";
        for _ in 0..(100 << 20) / line.len() {
            f.write_all(line).unwrap();
        }
    }
    let ppi = repo("machines/ballscrew-ppi.toml");
    let o = vcnc_in(
        dir.path(),
        &[
            "interpolate",
            ppi.to_str().unwrap(),
            "junk.ngc",
            "--out",
            "out",
        ],
        &[],
    );
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("junk.ngc:1:1: feed move with no feed rate set"),
        "{}",
        &err[..err.len().min(2000)]
    );
    assert!(err.len() < 1 << 20, "{} bytes of diagnostics", err.len());
}

#[test]
fn base_machine_is_valid() {
    let dir = tempdir();
    std::fs::write(dir.path().join("m.toml"), BASE).unwrap();
    std::fs::write(dir.path().join("p.ngc"), PROG).unwrap();
    let o = vcnc_in(
        dir.path(),
        &["interpolate", "m.toml", "p.ngc", "--out", "out"],
        &[],
    );
    assert!(o.status.success(), "{:?}", text(&o));
}

#[test]
fn every_bad_input_exits_2_with_a_message_that_names_it() {
    let all = cases();
    eprintln!("{} bad-input cases", all.len());
    assert!(
        all.len() >= 40,
        "issue 7 asks for at least 40 cases, have {}",
        all.len()
    );
    let mut failures = Vec::new();
    for c in &all {
        let dir = tempdir();
        for (name, content) in c.files {
            let content = generated(content).unwrap_or_else(|| content.as_bytes().to_vec());
            std::fs::write(dir.path().join(name), content).unwrap();
        }
        machine_variants(dir.path());
        let ppi = repo("machines/ballscrew-ppi.toml");
        let nmv = repo("machines/nmv5000.toml");
        let args: Vec<&str> = c
            .args
            .iter()
            .map(|a| match *a {
                PPI => ppi.to_str().unwrap(),
                NMV => nmv.to_str().unwrap(),
                other => other,
            })
            .collect();
        let o = vcnc_in(dir.path(), &args, &[]);
        let (_, err) = text(&o);
        let mut problems = Vec::new();
        if o.status.code() != Some(2) {
            problems.push(format!("exit code {:?}, expected 2", o.status.code()));
        }
        if err.contains("panicked") {
            problems.push("panicked".into());
        }
        for f in c.expect {
            if !err.contains(f) {
                problems.push(format!("stderr lacks {f:?}"));
            }
        }
        // Nothing half-written: no temporary files anywhere in the output folder.
        if let Ok(rd) = std::fs::read_dir(dir.path().join("out")) {
            for e in rd.flatten() {
                if e.file_name().to_string_lossy().ends_with(".tmp") {
                    problems.push(format!("temporary file left: {:?}", e.file_name()));
                }
            }
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{}: {}\n    stderr: {}",
                c.name,
                problems.join("; "),
                err.trim()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        all.len(),
        failures.join("\n")
    );
}

/// Every machine file the fuzzer found (fuzz/regressions/, see fuzz/README.md) is rejected as
/// bad input within seconds: absurd magnitudes that made a matrix exponential loop ~2^64 times,
/// a loop stable in continuous time but unstable at the servo rate, a subnormal encoder step, an
/// unbounded servo rate, travel and identification sizes that overflow.
#[test]
fn fuzz_findings_are_rejected_quickly() {
    let dir = repo("fuzz/regressions");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 8, "{files:?}");
    for f in files {
        let out = tempdir();
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_vcnc"))
            .args(["identify", f.to_str().unwrap(), "--quiet", "--out"])
            .arg(out.path())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let start = std::time::Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if start.elapsed() > std::time::Duration::from_secs(30) {
                child.kill().ok();
                panic!("{}: still running after 30 s", f.display());
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        };
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
        assert_eq!(status.code(), Some(2), "{}: {err}", f.display());
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        assert!(err.contains(&name) && !err.contains("panicked"), "{err}");
    }
}
