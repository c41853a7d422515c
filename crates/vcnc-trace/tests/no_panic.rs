//! No input makes the readers or the pairing panic: every sample file, cut, spliced and sprinkled
//! with random bytes, and random bytes alone, give a trace or a typed error. 400 cases per test
//! in CI; `VCNC_FUZZ_CASES=20000` for a longer run.

use std::path::Path;

use proptest::prelude::*;
use vcnc_trace::{GapPolicy, PairOptions, ReadOptions, pair, read_bytes};

const FILES: [&str; 14] = [
    "halscope/xyzac-2.9.log",
    "halscope/xy-pre2.9.log",
    "halsampler/xz-tagged.txt",
    "halsampler/plain.txt",
    "tncscope/xyzc.txt",
    "sinumerik/x1-y1.xml",
    "twincat/nc-axes_semicolon.csv",
    "twincat/nc-axes_tab-decimal-comma_shared-time.csv",
    "twincat/tc3_scope_3_4_3145_3_noOS.csv",
    "twincat/tc3_scope_3_4_3145_3-DecimalMark_comma.csv",
    "delimited/t-xr-x.csv",
    "delimited/semicolon-decimal-comma.csv",
    "delimited/whitespace-rad.txt",
    "parquet/simulate-x.parquet",
];

fn cases() -> u32 {
    std::env::var("VCNC_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(400)
}

fn load(i: usize) -> Vec<u8> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    std::fs::read(dir.join(FILES[i])).unwrap()
}

/// Reads and pairs (both gap policies, with a period for files that lack one); any outcome but a
/// panic is fine.
fn exercise(bytes: &[u8]) {
    let opts = ReadOptions {
        period_s: Some(1e-3),
        ..ReadOptions::default()
    };
    for o in [ReadOptions::default(), opts] {
        if let Ok(t) = read_bytes("fuzz", bytes, &o) {
            let _ = t.info().to_string();
            for gaps in [GapPolicy::Refuse, GapPolicy::LongestSegment] {
                let _ = pair(
                    &t,
                    &PairOptions {
                        gaps,
                        ..PairOptions::default()
                    },
                );
            }
        }
    }
}

/// One edit of a file: cut it, remove a range, insert bytes, or overwrite bytes.
#[derive(Debug, Clone)]
enum Edit {
    Truncate(usize),
    Remove(usize, usize),
    Insert(usize, Vec<u8>),
    Overwrite(usize, Vec<u8>),
}

fn edit() -> impl Strategy<Value = Edit> {
    let bytes = prop::collection::vec(
        prop_oneof![
            any::<u8>(),
            prop::sample::select(b"0123456789.,;-+eE \t\n\r#%[]=<>\"/".to_vec())
        ],
        1..12,
    );
    prop_oneof![
        any::<usize>().prop_map(Edit::Truncate),
        (any::<usize>(), 1usize..400).prop_map(|(a, n)| Edit::Remove(a, n)),
        (any::<usize>(), bytes.clone()).prop_map(|(a, b)| Edit::Insert(a, b)),
        (any::<usize>(), bytes).prop_map(|(a, b)| Edit::Overwrite(a, b)),
    ]
}

fn apply(mut f: Vec<u8>, e: &Edit) -> Vec<u8> {
    let at = |a: usize, f: &Vec<u8>| if f.is_empty() { 0 } else { a % f.len() };
    match e {
        Edit::Truncate(a) => {
            let a = at(*a, &f);
            f.truncate(a);
        }
        Edit::Remove(a, n) => {
            let a = at(*a, &f);
            let b = (a + n).min(f.len());
            f.drain(a..b);
        }
        Edit::Insert(a, b) => {
            let a = at(*a, &f);
            f.splice(a..a, b.iter().copied());
        }
        Edit::Overwrite(a, b) => {
            let a = at(*a, &f);
            for (k, &x) in b.iter().enumerate() {
                if let Some(y) = f.get_mut(a + k) {
                    *y = x;
                }
            }
        }
    }
    f
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases(),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn edited_sample_files_never_panic(file in 0..FILES.len(), edits in prop::collection::vec(edit(), 1..4)) {
        let mut f = load(file);
        for e in &edits {
            f = apply(f, e);
        }
        exercise(&f);
    }

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        exercise(&bytes);
    }
}

#[test]
fn signal_id_zero_and_huge_numbers_are_no_panic() {
    let xml = "<traceData><dataFrame>\
        <dataSignal id=\"0\" name=\"a\" description=\"Position setpoint X1\"/>\
        <dataSignal id=\"1\" name=\"b\" description=\"Position actual value X1\"/>\
        <rec time=\"0\" f0=\"1\" f1=\"1\"/><rec time=\"0.001\" f0=\"2\" f1=\"2\"/>\
        <rec time=\"1e300\" f0=\"3\" f1=\"3\"/></dataFrame></traceData>";
    exercise(xml.as_bytes());
    let halscope = "# Sampling period is 1e-300 ns\nx-pos-cmd;x-pos-fb\n0;0\n1;1\n";
    exercise(halscope.as_bytes());
}
