//! Reading speed: 1 M samples × 4 channels in each format (the goal: under 1 s), and the
//! `csv`-crate reader `vcnc identify --trace` used before this crate (`read_trace_csv` of
//! `crates/core/cmd_identify.rs`, copied below) on the same delimited file, for comparison.
//!
//! `cargo bench -p vcnc-trace` (the files, 40–110 MB each, are written to a temporary folder
//! first). `VCNC_BENCH_ROWS` changes the row count (default 1 000 000).

use std::fmt::Write as _;
use std::hint::black_box;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use criterion::{Criterion, criterion_group, criterion_main};
use vcnc_trace::{ReadOptions, read_path};

fn rows() -> usize {
    std::env::var("VCNC_BENCH_ROWS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1_000_000)
}

/// Four channels: X and Y nominal and actual positions, mm, at 1 kHz.
fn signal(k: usize) -> [f64; 4] {
    let t = k as f64 * 1e-3;
    let xr = 50.0 * (0.7 * t).sin();
    let yr = 30.0 * (0.45 * t).cos();
    [
        xr,
        xr - 0.002 * (0.7 * t).cos(),
        yr,
        yr + 0.0015 * (0.45 * t).sin(),
    ]
}

fn write_file(path: &Path, header: &str, row: impl Fn(&mut String, usize), n: usize) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    f.write_all(header.as_bytes()).unwrap();
    let mut line = String::new();
    for k in 0..n {
        line.clear();
        row(&mut line, k);
        f.write_all(line.as_bytes()).unwrap();
    }
}

struct Files {
    _dir: tempfile::TempDir,
    csv: PathBuf,
    halscope: PathBuf,
    halsampler: PathBuf,
    tncscope: PathBuf,
    twincat: PathBuf,
    sinumerik: PathBuf,
}

fn files(n: usize) -> Files {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name);
    let csv = p("trace.csv");
    write_file(
        &csv,
        "t,xr,x,yr,y\n",
        |l, k| {
            let s = signal(k);
            writeln!(
                l,
                "{:.3},{:.6},{:.6},{:.6},{:.6}",
                k as f64 * 1e-3,
                s[0],
                s[1],
                s[2],
                s[3]
            )
            .unwrap();
        },
        n,
    );
    let halscope = p("halscope.log");
    write_file(
        &halscope,
        "# Sampling period is 1000000 ns\njoint.0.motor-pos-cmd;joint.0.motor-pos-fb;joint.1.motor-pos-cmd;joint.1.motor-pos-fb\n# Position: 0.5;0.5;0.5;0.5\n# Scale: 0;0;0;0\n",
        |l, k| {
            let s = signal(k);
            writeln!(l, "{:.14};{:.14};{:.14};{:.14}", s[0], s[1], s[2], s[3]).unwrap();
        },
        n,
    );
    let halsampler = p("halsampler.txt");
    write_file(
        &halsampler,
        "# x-pos-cmd x-pos-fb y-pos-cmd y-pos-fb\n",
        |l, k| {
            let s = signal(k);
            writeln!(l, "{k} {:.6} {:.6} {:.6} {:.6} ", s[0], s[1], s[2], s[3]).unwrap();
        },
        n,
    );
    let tncscope = p("tncscope.txt");
    let mut head = String::from("%TNCscopeNT data file\n%[GLOBAL]\nCONTROL=TNC 640\n");
    for (i, name) in ["X s soll", "X s ist", "Y s soll", "Y s ist"]
        .iter()
        .enumerate()
    {
        write!(
            head,
            "%[CURVE{}]\nNAME={name}\nCHANNELTYPE={}\nAXISTYPE={}\nDIMENSION=mm\nCOUNT={n}\nCYCLETIME=1000\n",
            i + 1,
            &name[2..],
            &name[..1]
        )
        .unwrap();
    }
    head.push_str("%[DATA]\n");
    write_file(
        &tncscope,
        &head,
        |l, k| {
            let s = signal(k);
            writeln!(
                l,
                "{}; {:.4}; {:.4}; {:.4}; {:.4};",
                k * 1000,
                s[0],
                s[1],
                s[2],
                s[3]
            )
            .unwrap();
        },
        n,
    );
    let twincat = p("twincat.csv");
    write_file(
        &twincat,
        "Name;bench\nFile;bench.csv\nStarttime of export;0\nEndtime of export;0\n\n\
         Name;SetPos_X;Name;ActPos_X;Name;SetPos_Y;Name;ActPos_Y\n\
         SampleTime[ms];1;SampleTime[ms];1;SampleTime[ms];1;SampleTime[ms];1\n\
         Unit;mm;Unit;mm;Unit;mm;Unit;mm\n\n",
        |l, k| {
            let s = signal(k);
            writeln!(
                l,
                "{k};{:.6};{k};{:.6};{k};{:.6};{k};{:.6}",
                s[0], s[1], s[2], s[3]
            )
            .unwrap();
        },
        n,
    );
    let sinumerik = p("sinumerik.xml");
    let mut head = String::from("<?xml version=\"1.0\"?>\n<traceFile><traceData><dataFrame>\n");
    for (i, d) in [
        "Position setpoint X1",
        "Position actual value X1",
        "Position setpoint Y1",
        "Position actual value Y1",
    ]
    .iter()
    .enumerate()
    {
        writeln!(
            head,
            "<dataSignal id=\"{}\" name=\"/Nck/{i}\" description=\"{d}\"/>",
            i + 1
        )
        .unwrap();
    }
    write_file(
        &sinumerik,
        &head,
        |l, k| {
            let s = signal(k);
            writeln!(
                l,
                "<rec time=\"{:.3}\" f1=\"{:.6}\" f2=\"{:.6}\" f3=\"{:.6}\" f4=\"{:.6}\"/>",
                k as f64 * 1e-3,
                s[0],
                s[1],
                s[2],
                s[3]
            )
            .unwrap();
        },
        n,
    );
    std::fs::OpenOptions::new()
        .append(true)
        .open(&sinumerik)
        .unwrap()
        .write_all(b"</dataFrame></traceData></traceFile>\n")
        .unwrap();
    Files {
        _dir: dir,
        csv,
        halscope,
        halsampler,
        tncscope,
        twincat,
        sinumerik,
    }
}

/// The reader of `crates/core/cmd_identify.rs` before this crate (`read_trace_csv`), its
/// `anyhow` errors replaced by strings: `#` comments, a header row, one `csv::StringRecord` per
/// row, trimmed, each field parsed with `str::parse`.
fn baseline_read_trace_csv(path: &Path, cols: [&str; 3]) -> Result<[Vec<f64>; 3], String> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| format!("{file}: cannot read: {e}"))?;
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(false)
        .from_reader(bytes.as_slice());
    let header = rdr.headers().map_err(|e| format!("{file}: {e}"))?.clone();
    let mut idx = [0usize; 3];
    for (i, name) in cols.iter().enumerate() {
        idx[i] = header
            .iter()
            .position(|h| h == *name)
            .ok_or_else(|| format!("{file}: missing column '{name}'"))?;
    }
    let mut out: [Vec<f64>; 3] = Default::default();
    for (row, rec) in rdr.records().enumerate() {
        let rec = rec.map_err(|e| format!("{file}: {e}"))?;
        let line = rec.position().map_or(row as u64 + 2, |p| p.line());
        for (i, &c) in idx.iter().enumerate() {
            let s = rec.get(c).unwrap_or("");
            let v: f64 = s
                .parse()
                .map_err(|_| format!("{file}:{line}: '{s}' is not a number"))?;
            if !v.is_finite() {
                return Err(format!("{file}:{line}: not finite"));
            }
            out[i].push(v);
        }
    }
    Ok(out)
}

fn bench(c: &mut Criterion) {
    let n = rows();
    let f = files(n);
    let opts = ReadOptions {
        period_s: Some(1e-3),
        ..ReadOptions::default()
    };
    let mut g = c.benchmark_group(format!("read {n} samples x 4 channels"));
    g.sample_size(10);
    for (name, path) in [
        ("delimited csv (t,xr,x,yr,y)", &f.csv),
        ("halscope table", &f.halscope),
        ("halsampler -t", &f.halsampler),
        ("tncscope", &f.tncscope),
        ("twincat scope csv", &f.twincat),
        ("sinumerik xml", &f.sinumerik),
    ] {
        let t = read_path(path, &opts).unwrap();
        assert_eq!(t.channels.len(), 4, "{name}");
        assert!(t.channels.iter().all(|c| c.samples.len() == n), "{name}");
        g.bench_function(name, |b| {
            b.iter(|| black_box(read_path(black_box(path), &opts).unwrap()))
        });
    }
    let base = baseline_read_trace_csv(&f.csv, ["t", "xr", "x"]).unwrap();
    assert_eq!(base[0].len(), n);
    g.bench_function(
        "baseline csv crate, 3 of the 5 columns (before vcnc-trace)",
        |b| {
            b.iter(|| {
                black_box(baseline_read_trace_csv(black_box(&f.csv), ["t", "xr", "x"]).unwrap())
            })
        },
    );
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
