//! Apache Parquet tables: the tables vcnc itself writes (`vcnc simulate --format parquet`, and
//! `auto` above 200 000 rows), and those of data tools that write one numeric column per
//! channel (pandas, polars, MATLAB's `parquetwrite`).
//!
//! * Signature: the file starts and ends with the magic `PAR1` (the Parquet file format
//!   specification, "File Format").
//! * Columns: every column is a channel, named by its field name; a unit in brackets after the
//!   name (`x [mm]`) is the channel's unit, as in delimited text. Flat `DOUBLE`, `FLOAT`,
//!   `INT64` and `INT32` columns are read (integers signed or unsigned, by their logical or
//!   converted type; required or nullable, as pandas writes every column); a column of another
//!   type (text, a timestamp, a date, a decimal), a nested one, or a null value is refused with
//!   its column and row. Compression: none or Snappy (pandas' and pyarrow's default); other
//!   codecs (polars writes zstd by default) are refused by the `parquet` crate, naming them.
//! * Time column: the delimited reader's rule ([`crate::formats::delimited`]): the
//!   [`ReadOptions::time_column`], else a column named `t`, `time`, `zeit` or `timestamp`.
//! * Places in errors: row `k` (from 0) is reported as line `k + 2`, the line it would have in
//!   the CSV file of the same table (header on line 1).
//!
//! The reading is the `parquet` crate's column readers (its decoding of pages, encodings and
//! compression); nothing here decodes pages. Its Arrow layer is not used: the columns are read
//! straight into `f64`, and the Arrow crates it needs were a sixth of the project's build time.

use parquet::basic::{ConvertedType, LogicalType, Type as Physical};
use parquet::column::reader::{ColumnReader, ColumnReaderImpl};
use parquet::data_type::DataType;
use parquet::file::reader::{FileReader, SerializedFileReader};
use parquet::schema::types::ColumnDescriptor;

use crate::error::Error;
use crate::formats::delimited::{Header, named_channels, split_unit};
use crate::model::{Format, ReadOptions, Trace};

/// The magic that starts and ends a Parquet file.
pub(crate) const MAGIC: &[u8; 4] = b"PAR1";

/// The error for a file the `parquet` crate could not read.
fn unreadable(file: &str, e: impl std::fmt::Display) -> Error {
    let mut what = e.to_string();
    if what.contains("Disabled feature at compile time") {
        what.push_str(
            "; vcnc reads uncompressed and Snappy-compressed Parquet: write the file with compression=\"snappy\" (pandas, pyarrow and polars all take it)",
        );
    }
    Error::Parquet {
        file: file.to_string(),
        what,
    }
}

/// How a column's stored values become `f64`.
#[derive(Debug, Clone, Copy)]
enum Numeric {
    /// `DOUBLE`.
    F64,
    /// `FLOAT`.
    F32,
    /// `INT64` (signed or, with `true`, unsigned).
    I64(bool),
    /// `INT32` (signed or, with `true`, unsigned).
    I32(bool),
}

/// The numeric kind of column `c`, or what it holds instead (for the refusal).
fn numeric(c: &ColumnDescriptor) -> Result<Numeric, String> {
    // An integer's signedness: its logical type, else the legacy converted type (files
    // written before logical types existed), else signed.
    let integer = || match (c.logical_type_ref(), c.converted_type()) {
        (Some(LogicalType::Integer(int)), _) => Ok(!int.is_signed),
        (Some(other), _) => Err(describe(Some(other), c.converted_type())),
        (None, ConvertedType::NONE | ConvertedType::INT_8 | ConvertedType::INT_16)
        | (None, ConvertedType::INT_32 | ConvertedType::INT_64) => Ok(false),
        (None, ConvertedType::UINT_8 | ConvertedType::UINT_16)
        | (None, ConvertedType::UINT_32 | ConvertedType::UINT_64) => Ok(true),
        (None, other) => Err(describe(None, other)),
    };
    match c.physical_type() {
        Physical::DOUBLE => Ok(Numeric::F64),
        Physical::FLOAT => Ok(Numeric::F32),
        Physical::INT64 => integer().map(Numeric::I64),
        Physical::INT32 => integer().map(Numeric::I32),
        Physical::BYTE_ARRAY => Err(
            if matches!(c.logical_type_ref(), Some(LogicalType::String))
                || c.converted_type() == ConvertedType::UTF8
            {
                "text".to_string()
            } else {
                "binary".to_string()
            },
        ),
        Physical::BOOLEAN => Err("boolean".to_string()),
        Physical::INT96 => Err("INT96 timestamp".to_string()),
        Physical::FIXED_LEN_BYTE_ARRAY => Err(c
            .logical_type_ref()
            .map_or("fixed-length binary".to_string(), |l| {
                describe(Some(l), c.converted_type())
            })),
    }
}

/// A logical or converted type, as a user would name it.
fn describe(logical: Option<&LogicalType>, converted: ConvertedType) -> String {
    match logical {
        Some(LogicalType::Timestamp(_)) => "timestamp".to_string(),
        Some(LogicalType::Date) => "date".to_string(),
        Some(LogicalType::Time(_)) => "time-of-day".to_string(),
        Some(LogicalType::Decimal(_)) => "decimal".to_string(),
        Some(LogicalType::Float16) => "Float16".to_string(),
        Some(other) => format!("{other:?}"),
        None => format!("{converted}"),
    }
}

/// Appends column `name`'s values in one row group (its first row `row0` of the file, `rows`
/// rows) to `out` as `f64`; a null is refused with its row.
fn append<T: DataType>(
    file: &str,
    name: &str,
    mut reader: ColumnReaderImpl<T>,
    nullable: bool,
    (row0, rows): (usize, usize),
    to_f64: impl Fn(&T::T) -> f64,
    out: &mut Vec<f64>,
) -> Result<(), Error> {
    // No capacity from the row count: it is the file's word, and a damaged footer may claim
    // any number.
    let (mut values, mut levels) = (Vec::new(), Vec::new());
    let mut read = 0;
    while read < rows {
        let (n, _, _) = reader
            .read_records(
                rows - read,
                nullable.then_some(&mut levels),
                None,
                &mut values,
            )
            .map_err(|e| unreadable(file, format!("column '{name}': {e}")))?;
        if n == 0 {
            return Err(unreadable(
                file,
                format!(
                    "column '{name}' ends after {} of its {rows} rows in a row group",
                    read
                ),
            ));
        }
        read += n;
    }
    // A required column has no levels; an optional one is null where its level is 0 (a flat
    // column's only definition level is 1).
    if let Some(k) = levels.iter().position(|&l| l == 0) {
        return Err(Error::NotANumber {
            file: file.to_string(),
            line: row0 + k + 2,
            column: name.to_string(),
            text: "null (an empty cell)".to_string(),
        });
    }
    out.extend(values.iter().map(to_f64));
    Ok(())
}

pub(crate) fn read(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    if !bytes.ends_with(MAGIC) {
        return Err(unreadable(
            file,
            "a Parquet file ends with 'PAR1' after its footer; this one does not (cut short while it was written or copied?)",
        ));
    }
    let reader = SerializedFileReader::new(bytes::Bytes::copy_from_slice(bytes))
        .map_err(|e| unreadable(file, e))?;
    let meta = reader.metadata();
    let schema = meta.file_metadata().schema_descr();
    let mut kinds = Vec::with_capacity(schema.num_columns());
    for c in schema.columns() {
        let name = c.path().string();
        if c.path().parts().len() > 1 || c.max_rep_level() > 0 {
            return Err(Error::Header {
                file: file.to_string(),
                line: 1,
                what: format!(
                    "column '{name}' is nested (a group, list or map); vcnc reads flat numeric columns: write one column per channel"
                ),
            });
        }
        let kind = numeric(c).map_err(|other| Error::Header {
            file: file.to_string(),
            line: 1,
            what: format!(
                "column '{name}' holds {other} values; vcnc reads numeric columns (DOUBLE, FLOAT, INT64, INT32): leave the others out when writing the file"
            ),
        })?;
        kinds.push(kind);
    }
    let names: Vec<String> = schema
        .columns()
        .iter()
        .map(|c| c.name().to_string())
        .collect();
    let rows = usize::try_from(meta.file_metadata().num_rows()).unwrap_or(0);
    // Reserved up front: at most as many bytes as the file holds, all columns together (the
    // row and column counts are the footer's word, and a damaged footer may claim any number;
    // a well-compressed column just grows past its share).
    let share = bytes.len() / (8 * names.len().max(1));
    let mut cols: Vec<Vec<f64>> = vec![Vec::with_capacity(rows.min(share)); names.len()];
    let mut row0 = 0;
    for g in 0..reader.num_row_groups() {
        let group = reader.get_row_group(g).map_err(|e| unreadable(file, e))?;
        let n = usize::try_from(group.metadata().num_rows()).unwrap_or(0);
        for (i, out) in cols.iter_mut().enumerate() {
            let (name, at) = (&names[i], (row0, n));
            let nullable = schema.column(i).max_def_level() > 0;
            let column = group
                .get_column_reader(i)
                .map_err(|e| unreadable(file, e))?;
            match (column, kinds[i]) {
                (ColumnReader::DoubleColumnReader(r), Numeric::F64) => {
                    append(file, name, r, nullable, at, |&v| v, out)?
                }
                (ColumnReader::FloatColumnReader(r), Numeric::F32) => {
                    append(file, name, r, nullable, at, |&v| f64::from(v), out)?
                }
                (ColumnReader::Int64ColumnReader(r), Numeric::I64(false)) => {
                    append(file, name, r, nullable, at, |&v| v as f64, out)?
                }
                (ColumnReader::Int64ColumnReader(r), Numeric::I64(true)) => {
                    append(file, name, r, nullable, at, |&v| v as u64 as f64, out)?
                }
                (ColumnReader::Int32ColumnReader(r), Numeric::I32(false)) => {
                    append(file, name, r, nullable, at, |&v| f64::from(v), out)?
                }
                (ColumnReader::Int32ColumnReader(r), Numeric::I32(true)) => {
                    append(file, name, r, nullable, at, |&v| f64::from(v as u32), out)?
                }
                _ => unreachable!("the reader's type is the column's physical type"),
            }
        }
        row0 += n;
    }
    if row0 == 0 {
        return Err(Error::Truncated {
            file: file.to_string(),
            line: 1,
            what: "the table has no rows".to_string(),
        });
    }
    for (name, c) in names.iter().zip(&cols) {
        if let Some(k) = c.iter().position(|v| !v.is_finite()) {
            return Err(Error::NotFinite {
                file: file.to_string(),
                line: k + 2,
                column: name.clone(),
                text: c[k].to_string(),
            });
        }
    }
    let (names, units) = names.iter().map(|n| split_unit(n)).unzip();
    let header = Header {
        first_line: 1,
        line: 1,
        names,
        units,
    };
    let (channels, time_column) = named_channels(file, header, cols, |row| row + 2, opts)?;
    let mut metadata = vec![("rows".to_string(), row0.to_string())];
    if let Some(name) = time_column {
        metadata.push(("time column".to_string(), name));
    }
    Ok(Trace {
        file: file.to_string(),
        format: Format::Parquet,
        channels,
        metadata,
    })
}
