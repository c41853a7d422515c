//! Apache Parquet tables: the tables vcnc itself writes (`vcnc simulate --format parquet`, and
//! `auto` above 200 000 rows), and those of data tools that write one numeric column per
//! channel (pandas, polars, MATLAB's `parquetwrite`).
//!
//! * Signature: the file starts and ends with the magic `PAR1` (the Parquet file format
//!   specification, "File Format").
//! * Columns: every column is a channel, named by its field name; a unit in brackets after the
//!   name (`x [mm]`) is the channel's unit, as in delimited text. `Float64`, `Float32`, `Int64`
//!   and `Int32` columns are read; a column of another type, or a null value, is refused with
//!   its column and row.
//! * Time column: the delimited reader's rule ([`crate::formats::delimited`]): the
//!   [`ReadOptions::time_column`], else a column named `t`, `time`, `zeit` or `timestamp`.
//! * Places in errors: row `k` (from 0) is reported as line `k + 2`, the line it would have in
//!   the CSV file of the same table (header on line 1).
//!
//! The reading is the `parquet` crate's (Arrow record batches); nothing here decodes pages.

use arrow_array::cast::AsArray;
use arrow_array::types::{Float32Type, Float64Type, Int32Type, Int64Type};
use arrow_array::{Array, ArrayRef};
use arrow_schema::DataType;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

use crate::error::Error;
use crate::formats::delimited::{Header, named_channels, split_unit};
use crate::model::{Format, ReadOptions, Trace};

/// The magic that starts and ends a Parquet file.
pub(crate) const MAGIC: &[u8; 4] = b"PAR1";

/// The error for a file the `parquet` crate could not read.
fn unreadable(file: &str, e: impl std::fmt::Display) -> Error {
    Error::Parquet {
        file: file.to_string(),
        what: e.to_string(),
    }
}

/// Appends the values of `a` (column `name`, whose first row is `row0`) to `out` as `f64`.
fn append(
    file: &str,
    name: &str,
    row0: usize,
    a: &ArrayRef,
    out: &mut Vec<f64>,
) -> Result<(), Error> {
    if a.null_count() > 0
        && let Some(k) = (0..a.len()).find(|&k| a.is_null(k))
    {
        return Err(Error::NotANumber {
            file: file.to_string(),
            line: row0 + k + 2,
            column: name.to_string(),
            text: "null (an empty cell)".to_string(),
        });
    }
    match a.data_type() {
        DataType::Float64 => out.extend_from_slice(a.as_primitive::<Float64Type>().values()),
        DataType::Float32 => out.extend(
            a.as_primitive::<Float32Type>()
                .values()
                .iter()
                .map(|&v| f64::from(v)),
        ),
        DataType::Int64 => out.extend(
            a.as_primitive::<Int64Type>()
                .values()
                .iter()
                .map(|&v| v as f64),
        ),
        DataType::Int32 => out.extend(
            a.as_primitive::<Int32Type>()
                .values()
                .iter()
                .map(|&v| f64::from(v)),
        ),
        other => {
            return Err(Error::Header {
                file: file.to_string(),
                line: 1,
                what: format!(
                    "column '{name}' holds {other} values; vcnc reads numeric columns (Float64, Float32, Int64, Int32): leave the others out when writing the file"
                ),
            });
        }
    }
    Ok(())
}

pub(crate) fn read(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    if !bytes.ends_with(MAGIC) {
        return Err(unreadable(
            file,
            "a Parquet file ends with 'PAR1' after its footer; this one does not (cut short while it was written or copied?)",
        ));
    }
    let builder = ParquetRecordBatchReaderBuilder::try_new(bytes::Bytes::copy_from_slice(bytes))
        .map_err(|e| unreadable(file, e))?;
    let schema = builder.schema().clone();
    let rows = usize::try_from(builder.metadata().file_metadata().num_rows()).unwrap_or(0);
    let mut cols: Vec<Vec<f64>> = vec![Vec::with_capacity(rows); schema.fields().len()];
    let mut row0 = 0;
    for batch in builder.build().map_err(|e| unreadable(file, e))? {
        let batch = batch.map_err(|e| unreadable(file, e))?;
        for ((field, a), out) in schema.fields().iter().zip(batch.columns()).zip(&mut cols) {
            append(file, field.name(), row0, a, out)?;
        }
        row0 += batch.num_rows();
    }
    if row0 == 0 {
        return Err(Error::Truncated {
            file: file.to_string(),
            line: 1,
            what: "the table has no rows".to_string(),
        });
    }
    for (field, c) in schema.fields().iter().zip(&cols) {
        if let Some(k) = c.iter().position(|v| !v.is_finite()) {
            return Err(Error::NotFinite {
                file: file.to_string(),
                line: k + 2,
                column: field.name().clone(),
                text: c[k].to_string(),
            });
        }
    }
    let (names, units) = schema.fields().iter().map(|f| split_unit(f.name())).unzip();
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
