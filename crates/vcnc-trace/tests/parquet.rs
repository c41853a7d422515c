//! Parquet tables: written here by the `parquet` crate's Arrow writer (the writer vcnc's own
//! tables use), read back as the CSV file of the same table reads (truth: the delimited reader,
//! tested on its own in round_trip.rs and fixtures.rs), and refused with their column and row
//! when a value is null, not finite or not a number.

mod common;

use std::sync::Arc;

use arrow_array::{ArrayRef, Float32Array, Float64Array, Int64Array, RecordBatch, StringArray};
use arrow_schema::{Field, Schema};
use common::values;
use parquet::arrow::ArrowWriter;
use parquet::file::properties::WriterProperties;
use proptest::prelude::*;
use vcnc_trace::{Error, Format, ReadOptions, detect, read_bytes, write};

/// A Parquet file of `columns` (name, array), row groups of at most `group` rows.
fn parquet_file(columns: Vec<(&str, ArrayRef)>, group: usize) -> Vec<u8> {
    let fields: Vec<Field> = columns
        .iter()
        .map(|(n, a)| Field::new(*n, a.data_type().clone(), true))
        .collect();
    let schema = Arc::new(Schema::new(fields));
    let batch =
        RecordBatch::try_new(schema.clone(), columns.into_iter().map(|c| c.1).collect()).unwrap();
    let props = WriterProperties::builder()
        .set_max_row_group_row_count(Some(group))
        .build();
    let mut buf = Vec::new();
    let mut w = ArrowWriter::try_new(&mut buf, schema, Some(props)).unwrap();
    w.write(&batch).unwrap();
    w.close().unwrap();
    buf
}

fn f64s(v: &[f64]) -> ArrayRef {
    Arc::new(Float64Array::from(v.to_vec()))
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

#[test]
fn other_numeric_types_read_as_their_values() {
    let pq = parquet_file(
        vec![
            (
                "time_ms",
                Arc::new(Int64Array::from(vec![0, 2, 4, 6])) as ArrayRef,
            ),
            (
                "X_ref",
                Arc::new(Float32Array::from(vec![0.5f32, 1.0, 1.5, 2.0])),
            ),
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
                Arc::new(Float64Array::from(vec![
                    Some(0.0),
                    Some(1.0),
                    None,
                    Some(2.0),
                ])),
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
            (
                "note",
                Arc::new(StringArray::from(vec!["a", "b"])) as ArrayRef,
            ),
        ],
        1024,
    );
    let e = read_bytes("text.parquet", &with_text, &ReadOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("column 'note' holds Utf8 values"),
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
