//! Per-sample tables (`reference`, `trace`, `contour`), written chunk by chunk as CSV or as
//! columnar Parquet, with the columns and the decimation the user asked for. Like every output
//! file, a table goes to a temporary file in its folder and is renamed into place when finished,
//! so a reader never sees half a table.
//!
//! Format (`--format`): `csv`, `parquet`, or `auto` (the default): CSV while the table has at
//! most [`AUTO_CSV_ROWS`] rows — every short run, readable in any tool — and Parquet beyond,
//! where CSV costs gigabytes and most of the run time. The decision is taken when the first
//! [`AUTO_CSV_ROWS`] + 1 rows have arrived, so a streamed run needs no length up front.
//! Parquet files hold one `Float64` column per table column (Snappy-compressed, row groups of
//! [`ROW_GROUP_ROWS`] rows, so memory stays bounded).

use std::io::{BufWriter, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use parquet::basic::{Compression, Repetition, Type as Physical};
use parquet::data_type::DoubleType;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;

use vcnc_pipeline::predict::ActualPiece;
use vcnc_pipeline::{AxisName, Machine, PredictPiece, ReferenceChunk, SimulatePiece, Sink, Source};

use crate::files::{format_num, persist, temp_file};
use crate::{Error, Result};

/// Tables with at most this many rows are CSV under `--format auto`.
pub const AUTO_CSV_ROWS: usize = 200_000;

/// Rows per Parquet row group.
pub const ROW_GROUP_ROWS: usize = 65_536;

/// `--format`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Format {
    /// CSV up to 200 000 rows, Parquet beyond.
    #[default]
    Auto,
    /// Comma-separated text, shortest round-trip numbers.
    Csv,
    /// Apache Parquet, one Float64 column per table column.
    Parquet,
}

/// How per-sample tables are written (`--format`, `--decimate`, `--columns`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TableOptions {
    /// File format.
    pub format: Format,
    /// Keep every N-th row (rows 0, N, 2N, …); 1 or 0 keeps every row.
    pub decimate: usize,
    /// Columns to write, by name or `prefix*` pattern, in the table's own order; `None` writes
    /// every column.
    pub columns: Option<Vec<String>>,
}

impl TableOptions {
    /// The options as a report shows them (`--format auto --decimate 1 --columns all`).
    pub fn describe(&self) -> String {
        let format = match self.format {
            Format::Auto => "auto",
            Format::Csv => "csv",
            Format::Parquet => "parquet",
        };
        let columns = self
            .columns
            .as_ref()
            .map_or("all".to_string(), |c| c.join(","));
        format!(
            "--format {format} --decimate {} --columns {columns}",
            self.decimate.max(1)
        )
    }
}

/// A per-sample table being written.
pub struct TableWriter {
    dir: PathBuf,
    stem: String,
    header: Vec<String>,
    keep: Vec<usize>,
    decimate: usize,
    rows_in: usize,
    rows_out: usize,
    state: State,
    /// Parquet: the rows not yet written, handed to the writer in batches of exactly
    /// [`ROW_GROUP_ROWS`] (the rest at the end), so that the pages, and so the file, do not
    /// depend on how the caller splits the rows (a streamed run's pieces, `auto` deciding late
    /// or up front).
    rechunk: Option<Vec<Vec<f64>>>,
}

enum State {
    /// `auto`, still deciding: the rows so far, column-major.
    Pending(Vec<Vec<f64>>),
    Csv(BufWriter<tempfile::NamedTempFile>, PathBuf),
    Parquet(Box<SerializedFileWriter<tempfile::NamedTempFile>>, PathBuf),
    Done,
}

impl TableWriter {
    /// A table `DIR/STEM.csv` or `DIR/STEM.parquet` with the columns `header` (of which the
    /// options keep some). Unknown `--columns` names are bad input naming the available ones.
    /// (The commands know their tables' lengths and use [`TableWriter::create_sized`].)
    #[cfg(test)]
    pub fn create(
        dir: &Path,
        stem: &str,
        header: Vec<String>,
        opts: &TableOptions,
    ) -> Result<Self> {
        Self::create_sized(dir, stem, header, opts, None)
    }

    /// A table `DIR/STEM.csv` or `DIR/STEM.parquet` with the columns `header` (of which the
    /// options keep some; unknown `--columns` names are bad input naming the available ones).
    /// When the number of rows before decimation is known (`rows`), `auto` decides the format
    /// at once instead of buffering the first [`AUTO_CSV_ROWS`] rows (on a long run, 75 MB of
    /// a 47-column table); the file is the same.
    pub fn create_sized(
        dir: &Path,
        stem: &str,
        header: Vec<String>,
        opts: &TableOptions,
        rows: Option<usize>,
    ) -> Result<Self> {
        let keep = select(&header, opts.columns.as_deref(), stem)?;
        let mut w = TableWriter {
            dir: dir.to_path_buf(),
            stem: stem.to_string(),
            header,
            keep,
            decimate: opts.decimate.max(1),
            rows_in: 0,
            rows_out: 0,
            state: State::Done,
            rechunk: None,
        };
        let kept_rows = rows.map(|n| n.div_ceil(w.decimate));
        w.state = match opts.format {
            Format::Auto if kept_rows.is_some_and(|n| n > AUTO_CSV_ROWS) => w.open_parquet()?,
            Format::Auto if kept_rows.is_some() => w.open_csv()?,
            Format::Auto => State::Pending(vec![Vec::new(); w.keep.len()]),
            Format::Csv => w.open_csv()?,
            Format::Parquet => w.open_parquet()?,
        };
        if matches!(w.state, State::Parquet(..)) {
            w.rechunk = Some(vec![Vec::new(); w.keep.len()]);
        }
        Ok(w)
    }

    /// Appends rows: `columns[i][k]` is row k of column i of the full header; every column has
    /// the same length.
    pub fn write(&mut self, columns: &[&[f64]]) -> Result<()> {
        let n = columns.first().map_or(0, |c| c.len());
        if columns.len() != self.header.len() || columns.iter().any(|c| c.len() != n) {
            return Err(Error::Columns {
                table: self.stem.clone(),
                columns: columns.len(),
                width: self.header.len(),
            });
        }
        // Rows kept by the decimation: global index ≡ 0 (mod N).
        let first = (self.decimate - self.rows_in % self.decimate) % self.decimate;
        let rows: Vec<usize> = (first..n).step_by(self.decimate).collect();
        self.rows_in += n;
        if rows.is_empty() {
            return Ok(());
        }
        let picked: Vec<Vec<f64>> = self
            .keep
            .iter()
            .map(|&c| rows.iter().map(|&k| columns[c][k]).collect())
            .collect();
        self.push(picked)
    }

    fn push(&mut self, cols: Vec<Vec<f64>>) -> Result<()> {
        let n = cols.first().map_or(0, Vec::len);
        self.rows_out += n;
        if self.rechunk.is_some() {
            return self.regroup(cols, false);
        }
        if let State::Pending(buf) = &mut self.state {
            for (b, c) in buf.iter_mut().zip(&cols) {
                b.extend_from_slice(c);
            }
            if self.rows_out <= AUTO_CSV_ROWS {
                return Ok(());
            }
            // Too long for CSV: Parquet, starting with what was buffered.
            let State::Pending(buf) = std::mem::replace(&mut self.state, State::Done) else {
                unreachable!("matched above")
            };
            self.state = self.open_parquet()?;
            self.rechunk = Some(vec![Vec::new(); self.keep.len()]);
            return self.regroup(buf, false);
        }
        self.emit(cols)
    }

    /// Parquet: appends `cols` to the rows not yet written and writes every whole batch of
    /// [`ROW_GROUP_ROWS`] rows; with `last`, the rest too.
    fn regroup(&mut self, cols: Vec<Vec<f64>>, last: bool) -> Result<()> {
        let Some(mut buf) = self.rechunk.take() else {
            return Ok(());
        };
        if buf.first().is_some_and(Vec::is_empty) {
            buf = cols;
        } else {
            for (b, c) in buf.iter_mut().zip(cols) {
                b.extend(c);
            }
        }
        loop {
            let have = buf.first().map_or(0, Vec::len);
            if have == 0 || (have < ROW_GROUP_ROWS && !last) {
                break;
            }
            let batch = if have <= ROW_GROUP_ROWS {
                buf.iter_mut().map(std::mem::take).collect()
            } else {
                buf.iter_mut()
                    .map(|b| b.drain(..ROW_GROUP_ROWS).collect())
                    .collect()
            };
            self.emit(batch)?;
        }
        self.rechunk = Some(buf);
        Ok(())
    }

    /// Writes column-major rows to the open file (Parquet: a row group per [`ROW_GROUP_ROWS`]
    /// rows, encoded from the columns in place).
    fn emit(&mut self, cols: Vec<Vec<f64>>) -> Result<()> {
        let n = cols.first().map_or(0, Vec::len);
        match &mut self.state {
            State::Csv(w, path) => {
                let mut line = String::with_capacity(16 * cols.len());
                for k in 0..n {
                    line.clear();
                    for (i, c) in cols.iter().enumerate() {
                        if i > 0 {
                            line.push(',');
                        }
                        line.push_str(&format_num(c[k]));
                    }
                    line.push('\n');
                    w.write_all(line.as_bytes())
                        .map_err(|e| Error::io(format!("cannot write {}", path.display()), e))?;
                }
            }
            State::Parquet(w, path) => {
                // One row group per batch of at most ROW_GROUP_ROWS rows (`regroup` hands
                // exactly that many, the rest at the end).
                for start in (0..n).step_by(ROW_GROUP_ROWS) {
                    let end = (start + ROW_GROUP_ROWS).min(n);
                    let mut group = w.next_row_group().map_err(|e| encode(path, e))?;
                    for c in &cols {
                        let mut column = group
                            .next_column()
                            .map_err(|e| encode(path, e))?
                            .ok_or_else(|| encode(path, "more columns than the schema"))?;
                        column
                            .typed::<DoubleType>()
                            .write_batch(&c[start..end], None, None)
                            .map_err(|e| encode(path, e))?;
                        column.close().map_err(|e| encode(path, e))?;
                    }
                    group.close().map_err(|e| encode(path, e))?;
                }
            }
            State::Pending(_) | State::Done => {}
        }
        Ok(())
    }

    fn temp(&self) -> Result<tempfile::NamedTempFile> {
        std::fs::create_dir_all(&self.dir)
            .map_err(|e| Error::io(format!("cannot create folder {}", self.dir.display()), e))?;
        temp_file(&self.dir)
    }

    fn names(&self) -> Vec<&str> {
        self.keep.iter().map(|&c| self.header[c].as_str()).collect()
    }

    fn open_csv(&self) -> Result<State> {
        let path = self.dir.join(format!("{}.csv", self.stem));
        let mut w = BufWriter::with_capacity(1 << 20, self.temp()?);
        writeln!(w, "{}", self.names().join(",")).map_err(|e| self.write_error(&path, e))?;
        Ok(State::Csv(w, path))
    }

    fn open_parquet(&self) -> Result<State> {
        let path = self.dir.join(format!("{}.parquet", self.stem));
        // One required DOUBLE column per table column, written with the `parquet` crate's
        // column writers (its Arrow layer is not used: the Arrow crates were a sixth of the
        // project's build time, and the table is plain f64 columns).
        let fields = self
            .names()
            .iter()
            .map(|n| {
                Type::primitive_type_builder(n, Physical::DOUBLE)
                    .with_repetition(Repetition::REQUIRED)
                    .build()
                    .map(Arc::new)
            })
            .collect::<parquet::errors::Result<Vec<_>>>()
            .map_err(|e| encode(&path, e))?;
        let schema = Type::group_type_builder("schema")
            .with_fields(fields)
            .build()
            .map_err(|e| encode(&path, e))?;
        let props = WriterProperties::builder()
            .set_compression(Compression::SNAPPY)
            .set_dictionary_enabled(false)
            .build();
        let w = SerializedFileWriter::new(self.temp()?, Arc::new(schema), Arc::new(props))
            .map_err(|e| encode(&path, e))?;
        Ok(State::Parquet(Box::new(w), path))
    }

    fn write_error(&self, path: &Path, e: std::io::Error) -> Error {
        Error::io(format!("cannot write {}", path.display()), e)
    }

    /// Finishes the file and renames it into place; returns its path.
    pub fn finish(mut self) -> Result<PathBuf> {
        let empty = vec![Vec::new(); self.keep.len()];
        self.regroup(empty, true)?;
        if matches!(self.state, State::Pending(_)) {
            let State::Pending(buf) = std::mem::replace(&mut self.state, State::Done) else {
                unreachable!("matched above")
            };
            self.state = self.open_csv()?;
            self.emit(buf)?;
        }
        let (tmp, path) = match std::mem::replace(&mut self.state, State::Done) {
            State::Csv(w, path) => {
                let tmp = w
                    .into_inner()
                    .map_err(|e| self.write_error(&path, e.into_error()))?;
                (tmp, path)
            }
            State::Parquet(w, path) => (w.into_inner().map_err(|e| encode(&path, e))?, path),
            State::Pending(_) | State::Done => unreachable!("opened above"),
        };
        tmp.as_file()
            .sync_all()
            .map_err(|e| self.write_error(&path, e))?;
        persist(tmp, &path)?;
        Ok(path)
    }

    /// The format this table ends up in so far (`auto` while still deciding).
    #[cfg(test)]
    fn format(&self) -> Format {
        match self.state {
            State::Csv(..) => Format::Csv,
            State::Parquet(..) => Format::Parquet,
            _ => Format::Auto,
        }
    }
}

/// Indices of the header's columns that `patterns` select (`name` or `prefix*`), in header
/// order; every pattern must select something.
fn select(header: &[String], patterns: Option<&[String]>, stem: &str) -> Result<Vec<usize>> {
    let Some(patterns) = patterns else {
        return Ok((0..header.len()).collect());
    };
    let matches = |p: &str, h: &str| match p.strip_suffix('*') {
        Some(prefix) => h.starts_with(prefix),
        None => p == h,
    };
    for p in patterns {
        if !header.iter().any(|h| matches(p, h)) {
            return Err(Error::UnknownColumn {
                pattern: p.clone(),
                table: stem.to_string(),
                available: header.join(" "),
            });
        }
    }
    Ok((0..header.len())
        .filter(|&i| patterns.iter().any(|p| matches(p, &header[i])))
        .collect())
}

/// Writes a whole per-sample table (`DIR/STEM.csv` or `.parquet`), handing it to the writer
/// [`ROW_GROUP_ROWS`] rows at a time (so the writer never copies the whole table).
pub fn write_table(
    out: &Path,
    stem: &str,
    header: Vec<String>,
    cols: &[&[f64]],
    opts: &TableOptions,
) -> Result<PathBuf> {
    let n = cols.first().map_or(0, |c| c.len());
    let mut w = TableWriter::create_sized(out, stem, header, opts, Some(n))?;
    for start in (0..n).step_by(ROW_GROUP_ROWS) {
        let end = (start + ROW_GROUP_ROWS).min(n);
        let part: Vec<&[f64]> = cols.iter().map(|c| &c[start..end]).collect();
        w.write(&part)?;
    }
    if n == 0 {
        w.write(cols)?;
    }
    w.finish()
}

/// Writes a per-sample table of `n` rows whose columns are computed [`ROW_GROUP_ROWS`] rows at
/// a time: `fill(rows, columns)` pushes rows `rows` onto each (emptied) column of the header,
/// in header order. Derived columns (unit changes, pose components) then never exist for the
/// whole run at once (docs/performance.md).
pub fn write_table_rows(
    out: &Path,
    stem: &str,
    header: Vec<String>,
    n: usize,
    opts: &TableOptions,
    mut fill: impl FnMut(std::ops::Range<usize>, &mut [Vec<f64>]),
) -> Result<PathBuf> {
    let width = header.len();
    let mut w = TableWriter::create_sized(out, stem, header, opts, Some(n))?;
    let mut bufs: Vec<Vec<f64>> = (0..width)
        .map(|_| Vec::with_capacity(ROW_GROUP_ROWS.min(n)))
        .collect();
    for start in (0..n).step_by(ROW_GROUP_ROWS) {
        let end = (start + ROW_GROUP_ROWS).min(n);
        bufs.iter_mut().for_each(Vec::clear);
        fill(start..end, &mut bufs);
        let cols: Vec<&[f64]> = bufs.iter().map(Vec::as_slice).collect();
        w.write(&cols)?;
    }
    w.finish()
}

/// Parses `--columns a,b,c*`.
pub fn parse_columns(s: &str) -> Vec<String> {
    s.split(',')
        .map(|c| c.trim().to_string())
        .filter(|c| !c.is_empty())
        .collect()
}

/// Columns of `reference.csv`: `t`, the tool tip `px py pz` for TCP programs, then per axis
/// position, velocity and acceleration.
pub fn reference_header(tcp: bool, axes: &[AxisName]) -> Vec<String> {
    let mut header = vec!["t".to_string()];
    if tcp {
        header.extend(["px", "py", "pz"].map(String::from));
    }
    for a in axes {
        header.push(a.to_string());
        header.push(format!("{a}_vel"));
        header.push(format!("{a}_acc"));
    }
    header
}

/// The `reference` table of `vcnc interpolate`, written piece by piece.
pub struct ReferenceTable<'m> {
    writer: TableWriter,
    machine: &'m Machine,
    ts: f64,
    tcp: bool,
    t: Vec<f64>,
}

impl<'m> ReferenceTable<'m> {
    /// The table `DIR/reference.csv` (or `.parquet`) of the program `source` on `machine`.
    pub fn create(
        out: &Path,
        machine: &'m Machine,
        source: &Source<'_>,
        opts: &TableOptions,
    ) -> Result<ReferenceTable<'m>> {
        let names: Vec<AxisName> = machine.axes.iter().map(|a| a.name).collect();
        let tcp = source.has_tcp();
        let header = reference_header(tcp, &names);
        Ok(ReferenceTable {
            writer: TableWriter::create_sized(out, "reference", header, opts, Some(source.len()))?,
            machine,
            ts: source.ts(),
            tcp,
            t: Vec::new(),
        })
    }

    /// Finishes the file; returns its path.
    pub fn finish(self) -> Result<PathBuf> {
        self.writer.finish()
    }
}

impl Sink<ReferenceChunk> for ReferenceTable<'_> {
    type Error = Error;
    fn piece(&mut self, c: &ReferenceChunk) -> Result<()> {
        self.t.clear();
        self.t
            .extend((c.first..c.first + c.len()).map(|k| k as f64 * self.ts));
        let tip = if self.tcp {
            Some(vcnc_pipeline::interpolate::tool_tips(self.machine, c)?)
        } else {
            None
        };
        self.writer.write(&reference_columns(
            c,
            &self.t,
            tip.as_ref().map(|t| t.as_slice()),
        ))
    }
}

/// One piece of `reference.csv` as columns in [`reference_header`]'s order: its times `t`,
/// the tool tips `tip` of a TCP program, then per axis position, velocity and acceleration.
pub fn reference_columns<'a>(
    c: &'a ReferenceChunk,
    t: &'a [f64],
    tip: Option<&'a [Vec<f64>]>,
) -> Vec<&'a [f64]> {
    let mut cols: Vec<&[f64]> = vec![t];
    if let Some(tip) = tip {
        cols.extend(tip.iter().map(Vec::as_slice));
    }
    for i in 0..c.pos.len() {
        cols.extend([c.pos[i].as_slice(), &c.vel[i], &c.acc[i]]);
    }
    cols
}

/// The columns of `trace.csv`: `t`, then per axis `<A>_ref`, `<A>_act` and, with models,
/// `<A>_model`.
pub fn trace_header(axes: &[AxisName], models: bool) -> Vec<String> {
    let mut header = vec!["t".to_string()];
    for a in axes {
        header.push(format!("{a}_ref"));
        header.push(format!("{a}_act"));
        if models {
            header.push(format!("{a}_model"));
        }
    }
    header
}

/// The `trace` table of `vcnc simulate`, written piece by piece.
pub struct TraceTable {
    writer: TableWriter,
    ts: f64,
    t: Vec<f64>,
}

impl TraceTable {
    /// The table `DIR/trace.csv` (or `.parquet`) of the program `source` on `machine`, with a
    /// column per axis for the models when `models`.
    pub fn create(
        out: &Path,
        machine: &Machine,
        source: &Source<'_>,
        models: bool,
        opts: &TableOptions,
    ) -> Result<TraceTable> {
        let names: Vec<AxisName> = machine.axes.iter().map(|a| a.name).collect();
        let header = trace_header(&names, models);
        Ok(TraceTable {
            writer: TableWriter::create_sized(out, "trace", header, opts, Some(source.len()))?,
            ts: source.ts(),
            t: Vec::new(),
        })
    }

    /// Finishes the file; returns its path.
    pub fn finish(self) -> Result<PathBuf> {
        self.writer.finish()
    }
}

impl Sink<SimulatePiece> for TraceTable {
    type Error = Error;
    fn piece(&mut self, p: &SimulatePiece) -> Result<()> {
        self.t.clear();
        self.t
            .extend((p.first..p.first + p.len()).map(|k| k as f64 * self.ts));
        self.writer.write(&trace_columns(p, &self.t))
    }
}

/// One piece of `trace.csv` as columns in [`trace_header`]'s order: its times `t`, then per
/// axis reference, actual and (with models) predicted position.
pub fn trace_columns<'a>(p: &'a SimulatePiece, t: &'a [f64]) -> Vec<&'a [f64]> {
    let mut cols: Vec<&[f64]> = vec![t];
    for i in 0..p.reference.len() {
        cols.push(&p.reference[i]);
        cols.push(&p.traces[i].position);
        if let Some(pred) = &p.predicted {
            cols.push(&pred[i]);
        }
    }
    cols
}

/// Columns of `contour.csv` (axes `axes`, in machine order): `t`, `line`, per axis its
/// reference, true and predicted positions, the reference, true and predicted poses, and the
/// four errors (µm, mrad).
pub fn contour_header(axes: &[AxisName]) -> Vec<String> {
    let mut header = vec!["t".to_string(), "line".to_string()];
    for a in axes {
        header.push(format!("{a}_ref"));
        header.push(format!("{a}_true"));
        header.push(format!("{a}_pred"));
    }
    let pose = ["px", "py", "pz", "ox", "oy", "oz"];
    for prefix in ["ref", "true", "pred"] {
        for nm in pose {
            header.push(format!("{prefix}_{nm}"));
        }
    }
    header.extend(
        [
            "true_contour_um",
            "pred_contour_um",
            "true_orientation_mrad",
            "pred_orientation_mrad",
        ]
        .map(String::from),
    );
    header
}

/// Appends the columns of [`contour_header`] for the samples `rows` of piece `p` (indices
/// within the piece) with the model sequence `model` (sample period `ts`) to `cols`, one buffer
/// per header column: the layout of `contour.csv`, shared by the table and the Python binding.
pub fn append_contour_columns(
    p: &PredictPiece,
    model: &ActualPiece,
    ts: f64,
    rows: Range<usize>,
    cols: &mut [Vec<f64>],
) {
    let mut c = cols.iter_mut();
    let mut next = || c.next().expect("one buffer per header column");
    let first = p.first + rows.start;
    next().extend((first..first + rows.len()).map(|k| k as f64 * ts));
    next().extend(p.lines[rows.clone()].iter().map(|l| f64::from(*l)));
    for i in 0..p.reference.len() {
        for s in [&p.reference[i], &p.truth.positions[i], &model.positions[i]] {
            next().extend_from_slice(&s[rows.clone()]);
        }
    }
    for poses in [&p.reference_poses, &p.truth.poses, &model.poses] {
        for i in 0..6 {
            next().extend(
                poses[rows.clone()]
                    .iter()
                    .map(|q| if i < 3 { q.p[i] } else { q.o[i - 3] }),
            );
        }
    }
    for e in [
        &p.truth.tip_mm,
        &model.tip_mm,
        &p.truth.orientation_rad,
        &model.orientation_rad,
    ] {
        next().extend(e[rows.clone()].iter().map(|x| x * 1000.0));
    }
}

/// Rows of a piece that [`ContourTable`] lays out at a time: its column buffers stay at
/// 39 columns × 4 096 rows × 8 bytes (1.3 MB on five axes) whatever the piece's length (a
/// piece may hold tens of thousands of samples); the file does not depend on it.
const CONTOUR_BLOCK_ROWS: usize = 4096;

/// The `contour` table of `vcnc predict` (the first model set), written piece by piece.
pub struct ContourTable {
    writer: TableWriter,
    ts: f64,
    cols: Vec<Vec<f64>>,
}

impl ContourTable {
    /// The table `DIR/contour.csv` (or `.parquet`) of the program `source` on `machine`.
    pub fn create(
        out: &Path,
        machine: &Machine,
        source: &Source<'_>,
        opts: &TableOptions,
    ) -> Result<ContourTable> {
        let names: Vec<AxisName> = machine.axes.iter().map(|a| a.name).collect();
        let header = contour_header(&names);
        let width = header.len();
        Ok(ContourTable {
            writer: TableWriter::create_sized(out, "contour", header, opts, Some(source.len()))?,
            ts: source.ts(),
            cols: vec![Vec::new(); width],
        })
    }

    /// Finishes the file; returns its path.
    pub fn finish(self) -> Result<PathBuf> {
        self.writer.finish()
    }
}

impl Sink<PredictPiece> for ContourTable {
    type Error = Error;
    fn piece(&mut self, p: &PredictPiece) -> Result<()> {
        let Some(model) = p.models.first() else {
            return Ok(());
        };
        for start in (0..p.len()).step_by(CONTOUR_BLOCK_ROWS) {
            let rows = start..(start + CONTOUR_BLOCK_ROWS).min(p.len());
            self.cols.iter_mut().for_each(Vec::clear);
            append_contour_columns(p, model, self.ts, rows, &mut self.cols);
            let refs: Vec<&[f64]> = self.cols.iter().map(Vec::as_slice).collect();
            self.writer.write(&refs)?;
        }
        Ok(())
    }
}

/// A Parquet or Arrow encoding failure of the table at `path`.
fn encode(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Encode {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs::File;

    use parquet::column::reader::ColumnReader;
    use parquet::file::reader::{FileReader, SerializedFileReader};

    fn header() -> Vec<String> {
        ["t", "X_ref", "X_true", "Y_ref"].map(String::from).to_vec()
    }

    fn columns(n: usize) -> Vec<Vec<f64>> {
        (0..4)
            .map(|c| (0..n).map(|k| (c * 1000 + k) as f64 * 0.001).collect())
            .collect()
    }

    #[test]
    fn csv_keeps_the_asked_columns_and_rows_across_chunks() {
        let dir = tempfile::tempdir().unwrap();
        let opts = TableOptions {
            format: Format::Csv,
            decimate: 3,
            columns: Some(vec!["t".into(), "X_*".into()]),
        };
        let mut w = TableWriter::create(dir.path(), "trace", header(), &opts).unwrap();
        let c = columns(10);
        // Two chunks of 4 and 6 rows: decimation counts rows globally.
        let first: Vec<&[f64]> = c.iter().map(|v| &v[..4]).collect();
        let rest: Vec<&[f64]> = c.iter().map(|v| &v[4..]).collect();
        w.write(&first).unwrap();
        w.write(&rest).unwrap();
        let path = w.finish().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "t,X_ref,X_true");
        let t: Vec<f64> = lines[1..]
            .iter()
            .map(|l| l.split(',').next().unwrap().parse().unwrap())
            .collect();
        assert_eq!(t, vec![c[0][0], c[0][3], c[0][6], c[0][9]]);
        assert_eq!(lines[2], format!("{},{},{}", c[0][3], c[1][3], c[2][3]));
    }

    #[test]
    fn auto_switches_to_parquet_past_the_limit_and_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let mut w =
            TableWriter::create(dir.path(), "contour", header(), &TableOptions::default()).unwrap();
        let n = AUTO_CSV_ROWS + 10;
        let c = columns(n);
        for chunk in (0..n).step_by(70_000) {
            let end = (chunk + 70_000).min(n);
            let part: Vec<&[f64]> = c.iter().map(|v| &v[chunk..end]).collect();
            w.write(&part).unwrap();
        }
        assert_eq!(w.format(), Format::Parquet);
        let path = w.finish().unwrap();
        assert_eq!(path.extension().unwrap(), "parquet");
        let r = SerializedFileReader::new(File::open(&path).unwrap()).unwrap();
        let meta = r.metadata().file_metadata();
        assert_eq!(meta.num_rows() as usize, n);
        assert_eq!(meta.schema_descr().num_columns(), 4);
        // Values round-trip bit for bit, read by the `parquet` crate's column reader.
        let mut got = Vec::new();
        for g in 0..r.num_row_groups() {
            let group = r.get_row_group(g).unwrap();
            let rows = group.metadata().num_rows() as usize;
            let ColumnReader::DoubleColumnReader(mut col) = group.get_column_reader(1).unwrap()
            else {
                panic!("column 1 is not DOUBLE")
            };
            let mut values = Vec::new();
            let (n, _, _) = col.read_records(rows, None, None, &mut values).unwrap();
            assert_eq!(n, rows);
            got.extend(values);
        }
        assert_eq!(got, c[1]);
        // No temporary file left.
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(left.len(), 1);
    }

    /// Knowing the length up front (`create_sized`) changes when `auto` decides, never the
    /// file: byte for byte the same as deciding at row 200 001, with and without decimation,
    /// Parquet and CSV.
    #[test]
    fn auto_with_a_known_length_writes_the_same_file() {
        for (n, decimate) in [(AUTO_CSV_ROWS + 10, 1), (700_001, 3), (500_000, 3)] {
            let c = columns(n);
            let opts = TableOptions {
                decimate,
                ..TableOptions::default()
            };
            let write = |rows: Option<usize>| {
                let dir = tempfile::tempdir().unwrap();
                let mut w = TableWriter::create_sized(dir.path(), "contour", header(), &opts, rows)
                    .unwrap();
                for chunk in (0..n).step_by(ROW_GROUP_ROWS) {
                    let end = (chunk + ROW_GROUP_ROWS).min(n);
                    let part: Vec<&[f64]> = c.iter().map(|v| &v[chunk..end]).collect();
                    w.write(&part).unwrap();
                }
                let path = w.finish().unwrap();
                (
                    path.file_name().unwrap().to_owned(),
                    std::fs::read(&path).unwrap(),
                )
            };
            let (pending, sized) = (write(None), write(Some(n)));
            assert_eq!(pending.0, sized.0, "{n} rows / {decimate}");
            assert!(pending.1 == sized.1, "{n} rows / {decimate}: files differ");
        }
    }

    #[test]
    fn parquet_files_do_not_depend_on_how_the_rows_are_split() {
        // A streamed run hands rows over in pieces of any length (`vcnc predict --stream`);
        // the file must be the one written a row group at a time.
        let n = 300_007;
        let c = columns(n);
        for (format, decimate) in [
            (Format::Parquet, 1),
            (Format::Auto, 1),
            (Format::Parquet, 7),
        ] {
            let opts = TableOptions {
                format,
                decimate,
                ..TableOptions::default()
            };
            let write = |pieces: &[usize], rows: Option<usize>| {
                let dir = tempfile::tempdir().unwrap();
                let mut w = TableWriter::create_sized(dir.path(), "contour", header(), &opts, rows)
                    .unwrap();
                let (mut at, mut i) = (0, 0);
                while at < n {
                    let end = (at + pieces[i % pieces.len()]).min(n);
                    let part: Vec<&[f64]> = c.iter().map(|v| &v[at..end]).collect();
                    w.write(&part).unwrap();
                    at = end;
                    i += 1;
                }
                std::fs::read(w.finish().unwrap()).unwrap()
            };
            let whole = write(&[ROW_GROUP_ROWS], Some(n));
            for (pieces, rows) in [
                (&[16_380, 16_391, 7][..], Some(n)),
                (&[1_000][..], None),
                (&[99_999, 3][..], Some(n)),
            ] {
                assert!(
                    write(pieces, rows) == whole,
                    "{format:?} / {decimate}, pieces {pieces:?}: files differ"
                );
            }
        }
    }

    #[test]
    fn short_auto_tables_are_csv_and_unknown_columns_are_bad_input() {
        let dir = tempfile::tempdir().unwrap();
        let mut w =
            TableWriter::create(dir.path(), "reference", header(), &TableOptions::default())
                .unwrap();
        let c = columns(5);
        let cols: Vec<&[f64]> = c.iter().map(Vec::as_slice).collect();
        w.write(&cols).unwrap();
        let path = w.finish().unwrap();
        assert_eq!(path.file_name().unwrap(), "reference.csv");
        let e = TableWriter::create(
            dir.path(),
            "reference",
            header(),
            &TableOptions {
                columns: Some(vec!["Q".into()]),
                ..TableOptions::default()
            },
        )
        .err()
        .unwrap();
        assert!(e.to_string().contains("--columns Q"), "{e}");
        assert!(e.is_bad_input());
    }
}
