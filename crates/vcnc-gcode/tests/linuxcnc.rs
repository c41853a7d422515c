//! vcnc against LinuxCNC's own interpreter.
//!
//! Truth: the canonical motion commands that LinuxCNC 2.9's stand-alone interpreter `rs274`
//! printed for each program of `tests/data/linuxcnc/programs` (our own programs, one per
//! feature; `tests/data/linuxcnc/README.md` gives the version, command line and date). The
//! goldens are committed, so this test does not need LinuxCNC.
//!
//! The canonical commands are in program coordinates and the current length unit; the test
//! replays the offsets they announce (`SET_G5X_OFFSET`, `SET_G92_OFFSET`, `SET_XY_ROTATION`,
//! `USE_TOOL_LENGTH_OFFSET`, `USE_LENGTH_UNITS`) the way LinuxCNC's motion layer applies them,
//! $\mathbf m = R_z(\theta)(\mathbf p + \mathbf o_{92}) + \mathbf o_{5x} + \mathbf t$, to get
//! machine coordinates in mm, and compares them with vcnc's moves one by one: kind (rapid,
//! feed, arc, dwell), end point, arc centre and signed turns, feed rate (inverse-time blocks as
//! LinuxCNC's equivalent rate, F × length), dwell time. Moves shorter than 1e-7 mm are skipped
//! on both sides (LinuxCNC emits zero-length moves; vcnc drops them).
//!
//! Tolerance: `rs274` prints 4 decimals. Programs marked `(golden: exact)` only produce values
//! that 4 decimals represent exactly, and must match within 1e-6 mm; programs marked
//! `(golden: rounded)` (trigonometry, rotations) within half the last printed digit, 5e-5
//! program units. Like `rs274`, vcnc reads the tool table and parameter file in inches here
//! (the stand-alone interpreter's machine unit).
//!
//! The `bad_*` programs are rejected by both; vcnc must report the line `rs274` names.

use std::path::{Path, PathBuf};

use vcnc_gcode::{
    Feed, InterpOptions, LengthUnit, Move, MoveKind, Plane, interpret, parse, parse_parameter_file,
    parse_tool_table,
};

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/linuxcnc")
}

/// A motion of the canonical output, in machine coordinates, mm and deg.
#[derive(Debug, Clone, PartialEq)]
enum Canon {
    Traverse([f64; 6]),
    /// End, feed rate (mm/min, or deg/min for a move of rotary axes alone).
    Feed([f64; 6], f64),
    /// End, centre in the plane's (first, second) axes, signed turns, feed rate.
    Arc([f64; 6], [f64; 2], i32, f64),
    Dwell(f64),
}

/// LinuxCNC's canonical state while replaying.
struct Replay {
    mm: f64,
    g5x: [f64; 6],
    g92: [f64; 6],
    rot_deg: f64,
    tool: [f64; 6],
    plane: Plane,
    feed: f64,
}

impl Replay {
    fn machine(&self, p: [f64; 6]) -> [f64; 6] {
        let mut m: [f64; 6] = std::array::from_fn(|i| p[i] + self.g92[i]);
        let (s, c) = self.rot_deg.to_radians().sin_cos();
        if self.rot_deg != 0.0 {
            let (x, y) = (m[0], m[1]);
            m[0] = x * c - y * s;
            m[1] = x * s + y * c;
        }
        std::array::from_fn(|i| m[i] + self.g5x[i] + self.tool[i])
    }

    /// Program coordinates (current unit) to mm and deg.
    fn mm6(&self, v: &[f64]) -> [f64; 6] {
        std::array::from_fn(|i| if i < 3 { v[i] * self.mm } else { v[i] })
    }
}

fn numbers(args: &str) -> Vec<f64> {
    args.replace(',', " ")
        .split_whitespace()
        .filter_map(|t| t.parse().ok())
        .collect()
}

/// The canonical motions, and the error lines if `rs274` stopped with an error.
fn read_canon(text: &str) -> (Vec<Canon>, Vec<String>) {
    let mut r = Replay {
        mm: 1.0,
        g5x: [0.0; 6],
        g92: [0.0; 6],
        rot_deg: 0.0,
        tool: [0.0; 6],
        plane: Plane::XY,
        feed: 0.0,
    };
    let mut out = Vec::new();
    let mut errors = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        let canonical = it.next().is_some_and(|t| t.parse::<u32>().is_ok())
            && it.next().is_some_and(|t| t.starts_with('N'));
        if !canonical {
            if line.trim() != "executing" && !line.trim().is_empty() {
                errors.push(line.trim().to_string());
            }
            continue;
        }
        // "<sequence> N<line or .....> COMMAND(args)": the command follows the second token.
        let rest = line.trim_start();
        let rest = rest
            .split_once(char::is_whitespace)
            .map_or("", |r| r.1)
            .trim_start();
        let rest = rest
            .split_once(char::is_whitespace)
            .map_or("", |r| r.1)
            .trim_start();
        let Some((name, args)) = rest.split_once('(') else {
            continue;
        };
        let args = args.trim_end_matches(')');
        let v = numbers(args);
        match name {
            "USE_LENGTH_UNITS" => r.mm = if args.contains("INCHES") { 25.4 } else { 1.0 },
            "SET_G5X_OFFSET" => r.g5x = r.mm6(&v[1..]),
            "SET_G92_OFFSET" => r.g92 = r.mm6(&v),
            "SET_XY_ROTATION" => r.rot_deg = v[0],
            "USE_TOOL_LENGTH_OFFSET" => r.tool = r.mm6(&v),
            "SELECT_PLANE" => {
                r.plane = if args.contains("XZ") {
                    Plane::ZX
                } else if args.contains("YZ") {
                    Plane::YZ
                } else {
                    Plane::XY
                }
            }
            "SET_FEED_RATE" => r.feed = v[0] * r.mm,
            "STRAIGHT_TRAVERSE" => out.push(Canon::Traverse(r.machine(r.mm6(&v)))),
            "STRAIGHT_FEED" => {
                let end = r.machine(r.mm6(&v));
                // A move of rotary axes alone takes F in deg/min, not scaled by the unit.
                out.push(Canon::Feed(end, r.feed));
            }
            "ARC_FEED" => {
                let (u, w2, w) = r.plane.axes();
                let mut end = [0.0; 6];
                end[u] = v[0];
                end[w2] = v[1];
                end[w] = v[5];
                end[3..6].copy_from_slice(&v[6..9]);
                let end_p = r.mm6(&end);
                let mut centre = end;
                centre[u] = v[2];
                centre[w2] = v[3];
                let cm = r.machine(r.mm6(&centre));
                out.push(Canon::Arc(
                    r.machine(end_p),
                    [cm[u], cm[w2]],
                    v[4] as i32,
                    r.feed,
                ));
            }
            "DWELL" => out.push(Canon::Dwell(v[0])),
            _ => {}
        }
    }
    (out, errors)
}

/// LinuxCNC's equivalent feed rate of a vcnc move: F, or for inverse time F × length.
fn rate(m: &Move) -> f64 {
    let xyz = (0..3)
        .map(|i| (m.end[i] - m.start[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    let rot = (3..6)
        .map(|i| (m.end[i] - m.start[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    let len = match m.kind {
        MoveKind::Arc(a) => {
            let (_, _, w) = a.plane.axes();
            let planar = 0.5 * (a.radius_start_mm + a.radius_end_mm) * a.sweep_rad.abs();
            planar.hypot(m.end[w] - m.start[w])
        }
        _ if xyz > 0.0 => xyz,
        _ => rot,
    };
    match m.feed {
        Some(Feed::UnitsPerMin(f)) => f,
        Some(Feed::InverseTime(f)) => f * len,
        None => 0.0,
    }
}

fn options() -> InterpOptions {
    let tools = std::fs::read_to_string(dir().join("tools.tbl")).unwrap();
    let params = std::fs::read_to_string(dir().join("params.var")).unwrap();
    InterpOptions {
        tools: parse_tool_table(&tools, "tools.tbl").unwrap(),
        parameters: parse_parameter_file(&params, "params.var").unwrap(),
        machine_units: LengthUnit::Inch,
        ..InterpOptions::default()
    }
}

fn programs() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir().join("programs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

fn length(a: [f64; 6], b: [f64; 6]) -> f64 {
    (0..6).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

/// Compare one program; returns the number of motions compared and the largest deviation of
/// an end point or arc centre, mm.
fn compare(name: &str, src: &str, canon: &str) -> (usize, f64) {
    let tol = if src.contains("(golden: exact)") {
        1e-6
    } else {
        assert!(
            src.contains("(golden: rounded)"),
            "{name}: no golden tolerance tag"
        );
        // Half the last printed digit, in inches for inch programs.
        5e-5 * if src.to_uppercase().contains("G20") {
            25.4
        } else {
            1.0
        } + 1e-9
    };
    let (want, errors) = read_canon(canon);
    assert!(errors.is_empty(), "{name}: rs274 reported {errors:?}");
    let (program, d) = parse(src);
    assert!(d.is_empty(), "{name}: {d:?}");
    let (tp, _) = interpret(&program, &options()).unwrap_or_else(|e| panic!("{name}: {e:?}"));
    // Drop zero-length straight moves on both sides.
    let mut prev = [0.0; 6];
    let want: Vec<Canon> = want
        .into_iter()
        .filter(|c| {
            let keep = match c {
                Canon::Traverse(e) | Canon::Feed(e, _) => length(*e, prev) > 1e-7,
                _ => true,
            };
            if let Canon::Traverse(e) | Canon::Feed(e, _) | Canon::Arc(e, ..) = c {
                prev = *e;
            }
            keep
        })
        .collect();
    let got: Vec<&Move> = tp
        .moves
        .iter()
        .filter(|m| {
            !matches!(m.kind, MoveKind::Rapid | MoveKind::Linear) || length(m.end, m.start) > 1e-7
        })
        .collect();
    assert_eq!(
        got.len(),
        want.len(),
        "{name}: vcnc made {} moves, rs274 {}\nvcnc: {:?}\nrs274: {want:?}",
        got.len(),
        want.len(),
        got.iter().map(|m| (m.line, m.end)).collect::<Vec<_>>()
    );
    let mut worst = 0.0f64;
    let mut near = |a: [f64; 6], b: [f64; 6]| {
        for i in 0..6 {
            worst = worst.max((a[i] - b[i]).abs());
        }
        (0..6).all(|i| (a[i] - b[i]).abs() <= tol)
    };
    let rate_ok = |a: f64, b: f64| (a - b).abs() <= 5e-5 * 25.4 + 1e-9 * b.abs();
    for (k, (m, c)) in got.iter().zip(&want).enumerate() {
        let ctx = format!(
            "{name}: move {k} (line {}): vcnc {m:?}\nrs274 {c:?}",
            m.line
        );
        match (m.kind, c) {
            (MoveKind::Rapid, Canon::Traverse(e)) => assert!(near(m.end, *e), "{ctx}"),
            (MoveKind::Linear, Canon::Feed(e, f)) => {
                assert!(near(m.end, *e), "{ctx}");
                assert!(rate_ok(rate(m), *f), "{ctx}: feed {} vs {f}", rate(m));
            }
            (MoveKind::Arc(a), Canon::Arc(e, centre, turns, f)) => {
                assert!(near(m.end, *e), "{ctx}");
                let mut c6 = [0.0; 6];
                let mut w6 = [0.0; 6];
                c6[..2].copy_from_slice(&a.centre);
                w6[..2].copy_from_slice(centre);
                assert!(near(c6, w6), "{ctx}: centre");
                let signed = a.turns as i32 * a.sweep_rad.signum() as i32;
                assert_eq!(signed, *turns, "{ctx}: turns");
                assert!(rate_ok(rate(m), *f), "{ctx}: feed {} vs {f}", rate(m));
            }
            (MoveKind::Dwell { seconds }, Canon::Dwell(s)) => {
                assert!((seconds - s).abs() <= 5e-5, "{ctx}");
            }
            _ => panic!("{ctx}: different kinds of move"),
        }
    }
    (got.len(), worst)
}

#[test]
fn corpus_matches_linuxcnc_rs274() {
    let mut total = 0;
    let mut compared = 0;
    for p in programs() {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        if name.starts_with("bad_") {
            continue;
        }
        let src = std::fs::read_to_string(&p).unwrap();
        let canon =
            std::fs::read_to_string(dir().join("canon").join(name.replace(".ngc", ".canon")))
                .unwrap_or_else(|_| {
                    panic!("{name}: no golden; run tests/data/linuxcnc/generate.sh")
                });
        let (n, worst) = compare(&name, &src, &canon);
        println!("{name}: {n} motions match rs274 (largest deviation {worst:.2e} mm)");
        total += n;
        compared += 1;
    }
    assert!(compared >= 14, "{compared} programs");
    println!("{compared} programs, {total} motions");
}

#[test]
fn bad_programs_are_rejected_at_the_line_rs274_names() {
    let mut checked = 0;
    for p in programs() {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        if !name.starts_with("bad_") {
            continue;
        }
        let src = std::fs::read_to_string(&p).unwrap();
        let canon =
            std::fs::read_to_string(dir().join("canon").join(name.replace(".ngc", ".canon")))
                .unwrap();
        let (_, errors) = read_canon(&canon);
        assert_eq!(
            errors.len(),
            2,
            "{name}: rs274 should stop with an error: {errors:?}"
        );
        // rs274 prints the message and the offending line's text (or "from line: N").
        let line = match errors[0].split_once("from line: ") {
            Some((_, n)) => n.trim().parse::<u32>().unwrap(),
            None => src.lines().position(|l| l.trim() == errors[1]).unwrap() as u32 + 1,
        };
        let (program, mut diags) = parse(&src);
        if !diags.iter().any(|d| d.is_error())
            && let Err(d) = interpret(&program, &options())
        {
            diags.extend(d);
        }
        let first = diags
            .iter()
            .find(|d| d.is_error())
            .unwrap_or_else(|| panic!("{name}: vcnc accepts it"));
        assert_eq!(
            first.line, line,
            "{name}: vcnc says {first}, rs274 says {errors:?}"
        );
        println!("{name}: rs274 '{}', vcnc '{first}'", errors[0]);
        checked += 1;
    }
    assert_eq!(checked, 17);
}
