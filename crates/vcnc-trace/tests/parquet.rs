//! Parquet tables: written here by the `parquet` crate's column writers (the writer vcnc's own
//! tables use) with the column types data tools write (DOUBLE, FLOAT, INT64, optional columns
//! with nulls, text), read back as the CSV file of the same table reads (truth: the delimited
//! reader, tested on its own in round_trip.rs and fixtures.rs), and refused with their column
//! and row when a value is null, not finite or not a number. The file `vcnc simulate` wrote
//! with the crate's Arrow writer (before vcnc used the column writers) is read too.

use crate::common;

use std::sync::Arc;

use common::values;
use parquet::basic::{LogicalType, Repetition, Type as Physical};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, FloatType, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;
use proptest::prelude::*;
use vcnc_trace::{Error, Format, ReadOptions, detect, read_bytes, write};

/// A column of a test table.
enum Col {
    F64(Vec<f64>),
    F32(Vec<f32>),
    I64(Vec<i64>),
    /// An optional DOUBLE column; `None` is a null.
    Nullable(Vec<Option<f64>>),
    /// UTF-8 text (BYTE_ARRAY, logical type String), as pandas writes a string column.
    Text(Vec<&'static str>),
}

impl Col {
    fn len(&self) -> usize {
        match self {
            Col::F64(v) => v.len(),
            Col::F32(v) => v.len(),
            Col::I64(v) => v.len(),
            Col::Nullable(v) => v.len(),
            Col::Text(v) => v.len(),
        }
    }

    fn field(&self, name: &str) -> Type {
        let (physical, repetition) = match self {
            Col::F64(_) => (Physical::DOUBLE, Repetition::REQUIRED),
            Col::F32(_) => (Physical::FLOAT, Repetition::REQUIRED),
            Col::I64(_) => (Physical::INT64, Repetition::REQUIRED),
            Col::Nullable(_) => (Physical::DOUBLE, Repetition::OPTIONAL),
            Col::Text(_) => (Physical::BYTE_ARRAY, Repetition::REQUIRED),
        };
        let logical = matches!(self, Col::Text(_)).then_some(LogicalType::String);
        Type::primitive_type_builder(name, physical)
            .with_repetition(repetition)
            .with_logical_type(logical)
            .build()
            .unwrap()
    }
}

/// A Parquet file of `columns` (name, values), row groups of at most `group` rows.
fn parquet_file(columns: Vec<(&str, Col)>, group: usize) -> Vec<u8> {
    let fields = columns.iter().map(|(n, c)| Arc::new(c.field(n))).collect();
    let schema = Arc::new(
        Type::group_type_builder("schema")
            .with_fields(fields)
            .build()
            .unwrap(),
    );
    let mut buf = Vec::new();
    let mut w =
        SerializedFileWriter::new(&mut buf, schema, Arc::new(WriterProperties::default())).unwrap();
    let rows = columns[0].1.len();
    for start in (0..rows).step_by(group) {
        let end = (start + group).min(rows);
        let mut g = w.next_row_group().unwrap();
        for (_, c) in &columns {
            let mut col = g.next_column().unwrap().unwrap();
            match c {
                Col::F64(v) => col
                    .typed::<DoubleType>()
                    .write_batch(&v[start..end], None, None),
                Col::F32(v) => col
                    .typed::<FloatType>()
                    .write_batch(&v[start..end], None, None),
                Col::I64(v) => col
                    .typed::<Int64Type>()
                    .write_batch(&v[start..end], None, None),
                Col::Nullable(v) => {
                    let part = &v[start..end];
                    let levels: Vec<i16> = part.iter().map(|x| i16::from(x.is_some())).collect();
                    let present: Vec<f64> = part.iter().flatten().copied().collect();
                    col.typed::<DoubleType>()
                        .write_batch(&present, Some(&levels), None)
                }
                Col::Text(v) => {
                    let text: Vec<ByteArray> = v[start..end].iter().map(|&s| s.into()).collect();
                    col.typed::<ByteArrayType>().write_batch(&text, None, None)
                }
            }
            .unwrap();
            col.close().unwrap();
        }
        g.close().unwrap();
    }
    w.close().unwrap();
    buf
}

fn f64s(v: &[f64]) -> Col {
    Col::F64(v.to_vec())
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 24,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// The same table as Parquet (in row groups of `group` rows) and as CSV reads to the same
    /// channels: names, units, time base, gaps and their lines, samples bit for bit.
    #[test]
    fn a_parquet_table_reads_as_its_csv(cols in values(40), at in 1usize..39, lost in 1usize..4, group in 3usize..50, with_t in any::<bool>()) {
        let n = cols[0].len();
        let t: Vec<f64> = (0..n)
            .map(|k| (k + if k >= at { lost } else { 0 }) as f64 * 1e-3 + 2.5)
            .collect();
        let mut names: Vec<String> = with_t.then(|| "t".to_string()).into_iter().collect();
        names.extend((0..cols.len()).map(|i| format!("c{i}[mm]")));
        let mut slices: Vec<&[f64]> = with_t.then_some(t.as_slice()).into_iter().collect();
        slices.extend(cols.iter().map(Vec::as_slice));
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let mut csv = Vec::new();
        write::delimited(&mut csv, b',', false, Some(&refs), &slices).unwrap();
        let pq = parquet_file(
            refs.iter().zip(&slices).map(|(n, s)| (*n, f64s(s))).collect(),
            group,
        );
        prop_assert!(matches!(detect(&pq), Ok(Format::Parquet)));
        let opts = ReadOptions {
            period_s: (!with_t).then_some(1e-3),
            ..ReadOptions::default()
        };
        let a = read_bytes("table", &csv, &opts).unwrap();
        let b = read_bytes("table", &pq, &opts).unwrap();
        prop_assert_eq!(b.format, Format::Parquet);
        prop_assert_eq!(&b.channels, &a.channels);
        if with_t {
            prop_assert_eq!(b.channels[0].gaps[0].line, at + 2);
        }
    }
}

/// The table `vcnc simulate --format parquet` wrote (tests/data/README.md) reads as the CSV
/// the same run wrote with `--format csv`.
#[test]
fn the_table_vcnc_simulate_writes_reads_as_its_csv() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/parquet");
    let opts = ReadOptions::default();
    let pq = vcnc_trace::read_path(&dir.join("simulate-x.parquet"), &opts).unwrap();
    let csv = vcnc_trace::read_path(&dir.join("simulate-x.csv"), &opts).unwrap();
    assert_eq!(pq.format, Format::Parquet);
    assert_eq!(pq.channels, csv.channels);
    assert_eq!(pq.channels[0].samples.len(), 246);
}

/// The table pyarrow writes (what pandas' `to_parquet` uses: nullable columns, dictionary
/// pages, version-2 data pages, several row groups; tests/data/parquet/make_pyarrow.py) reads
/// as its CSV twin, FLOAT and UINT16 columns included, bit for bit.
#[test]
fn a_table_pyarrow_writes_reads_as_its_csv() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/parquet");
    let opts = ReadOptions::default();
    let pq = vcnc_trace::read_path(&dir.join("pyarrow.parquet"), &opts).unwrap();
    let csv = vcnc_trace::read_path(&dir.join("pyarrow.csv"), &opts).unwrap();
    assert_eq!(pq.format, Format::Parquet);
    assert_eq!(pq.channels, csv.channels);
    assert_eq!(pq.channels.len(), 4);
    assert_eq!(pq.channels[0].samples.len(), 300);
    // Row 255 of `status` is 255 · 257 = 65535: an unsigned 16-bit value beyond i16's range.
    assert_eq!(pq.channels[3].samples[255], 65535.0);
    // The same table compressed with zstd (polars' default codec), which vcnc does not build.
    let e = vcnc_trace::read_path(&dir.join("zstd.parquet"), &opts).unwrap_err();
    assert!(
        matches!(&e, Error::Parquet { .. })
            && e.to_string().contains("zstd")
            && e.to_string().contains("compression=\"snappy\""),
        "{e}"
    );
}

#[test]
fn other_numeric_types_read_as_their_values() {
    let pq = parquet_file(
        vec![
            ("time_ms", Col::I64(vec![0, 2, 4, 6])),
            ("X_ref", Col::F32(vec![0.5, 1.0, 1.5, 2.0])),
            ("X_act", f64s(&[0.0, 0.25, 0.75, 1.25])),
        ],
        1024,
    );
    let t = read_bytes("typed.parquet", &pq, &ReadOptions::default()).unwrap();
    assert_eq!(t.channels.len(), 2);
    assert_eq!(t.channels[0].samples, [0.5, 1.0, 1.5, 2.0]);
    assert!((t.channels[0].period_s.unwrap() - 2e-3).abs() < 1e-15);
}

#[test]
fn bad_tables_name_the_column_and_row() {
    // A null in row 2 (line 4 of the same table as CSV).
    let with_null = parquet_file(
        vec![
            ("t", f64s(&[0.0, 0.001, 0.002, 0.003])),
            (
                "X_ref",
                Col::Nullable(vec![Some(0.0), Some(1.0), None, Some(2.0)]),
            ),
        ],
        1024,
    );
    let e = read_bytes("null.parquet", &with_null, &ReadOptions::default()).unwrap_err();
    assert!(
        matches!(&e, Error::NotANumber { line: 4, column, .. } if column == "X_ref"),
        "{e}"
    );
    // A NaN in row 1 of the second row group.
    let with_nan = parquet_file(
        vec![
            ("t", f64s(&[0.0, 0.001, 0.002, 0.003])),
            ("X_ref", f64s(&[0.0, 1.0, 2.0, f64::NAN])),
        ],
        2,
    );
    let e = read_bytes("nan.parquet", &with_nan, &ReadOptions::default()).unwrap_err();
    assert!(
        matches!(&e, Error::NotFinite { line: 5, column, .. } if column == "X_ref"),
        "{e}"
    );
    // A text column.
    let with_text = parquet_file(
        vec![
            ("t", f64s(&[0.0, 0.001])),
            ("note", Col::Text(vec!["a", "b"])),
        ],
        1024,
    );
    let e = read_bytes("text.parquet", &with_text, &ReadOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("column 'note' holds text values"),
        "{e}"
    );
    // Cut short: the footer is missing.
    let good = parquet_file(
        vec![("t", f64s(&[0.0, 0.001])), ("x", f64s(&[1.0, 2.0]))],
        1024,
    );
    let e = read_bytes(
        "cut.parquet",
        &good[..good.len() - 9],
        &ReadOptions::default(),
    )
    .unwrap_err();
    assert!(
        matches!(&e, Error::Parquet { .. }) && e.to_string().contains("cut.parquet"),
        "{e}"
    );
    // A damaged footer length.
    let mut damaged = good.clone();
    let k = damaged.len() - 8;
    damaged[k..k + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = read_bytes("damaged.parquet", &damaged, &ReadOptions::default()).unwrap_err();
    assert!(matches!(&e, Error::Parquet { .. }), "{e}");
    // Not Parquet at all, but binary: every format named, Parquet's magic among the reasons.
    let e = read_bytes("blob.bin", b"\x00\x01PAR1", &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("Parquet magic"), "{e}");
}
