//! The tool-tip path as VTK PolyData (`.vtp`, VTK's XML format, read by ParaView and any VTK
//! tool): points, one polyline cell per unbroken stretch, and per-point arrays (contour error,
//! orientation error, tool-axis vectors, block line numbers, sample index).
//!
//! Format: *VTK File Formats*, "XML File Formats" → "PolyData" (VTKFile type="PolyData",
//! version 1.0, `header_type="UInt64"`): `<Piece NumberOfPoints NumberOfLines …>` holding
//! `<PointData>`, `<Points>` (one 3-component array) and `<Lines>` (`connectivity` and
//! `offsets` arrays). With [`VtpEncoding::Base64`] each array is base64 of a UInt64 byte count
//! followed by the little-endian values ("binary" inline format); with [`VtpEncoding::Ascii`]
//! the values are written as text.
//!
//! Why hand-written and not the `vtkio` crate: its stable line (0.6.3) dates from March 2021 and
//! pins nom 3; the 0.7 line that modernised it has only release candidates (0.7.0-rc2). The file
//! is a fixed, small XML structure; the tests parse it back with `vtkio` as an independent
//! reader and compare points and arrays.

use std::fmt::Write as _;
use std::path::Path;

use crate::error::Error;
use crate::svg::escape;

/// A per-point scalar array.
#[derive(Debug, Clone, PartialEq)]
pub struct PointScalars<'a> {
    /// Array name as ParaView shows it; put the unit in it (`contour_error_um`).
    pub name: String,
    /// One value per path point (finite wherever the point is).
    pub values: &'a [f64],
}

/// A per-point vector array (3 components).
#[derive(Clone)]
pub struct PointVectors<'a> {
    /// Array name (`tool_axis`).
    pub name: String,
    /// One vector per path point.
    pub values: Vectors<'a>,
}

/// The vectors of a [`PointVectors`] array: given, or computed per point as they are
/// written (a long path's tool axes, from its axis positions, need not be held).
#[derive(Clone, Copy)]
pub enum Vectors<'a> {
    /// One vector per point.
    Given(&'a [[f64; 3]]),
    /// `len` vectors, vector `i` computed by `at(i)` (called more than once per point).
    Computed {
        /// Number of vectors.
        len: usize,
        /// Vector of point `i`.
        at: &'a dyn Fn(usize) -> [f64; 3],
    },
}

impl Vectors<'_> {
    /// Number of vectors.
    pub fn len(&self) -> usize {
        match self {
            Vectors::Given(v) => v.len(),
            Vectors::Computed { len, .. } => *len,
        }
    }

    /// No vectors.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Vector `i`.
    pub fn at(&self, i: usize) -> [f64; 3] {
        match self {
            Vectors::Given(v) => v[i],
            Vectors::Computed { at, .. } => at(i),
        }
    }
}

impl std::fmt::Debug for Vectors<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Vectors::Given(v) => f.debug_tuple("Given").field(&v.len()).finish(),
            Vectors::Computed { len, .. } => f.debug_struct("Computed").field("len", len).finish(),
        }
    }
}

impl std::fmt::Debug for PointVectors<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PointVectors")
            .field("name", &self.name)
            .field("values", &self.values)
            .finish()
    }
}

/// How array values are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VtpEncoding {
    /// Base64 of little-endian binary: about a third of the size of text, exact.
    #[default]
    Base64,
    /// Text, shortest round-trip decimal form: exact, readable, larger.
    Ascii,
}

/// A tool-tip path with its per-point data.
#[derive(Debug, Clone)]
pub struct VtpPath<'a> {
    /// Tool-tip positions in the workpiece frame, mm. Points with a non-finite coordinate are
    /// left out and break the polyline.
    pub points_mm: &'a [[f64; 3]],
    /// Scalar arrays (the first becomes the active scalars).
    pub scalars: Vec<PointScalars<'a>>,
    /// Vector arrays (the first becomes the active vectors, e.g. the tool axis for glyphs).
    pub vectors: Vec<PointVectors<'a>>,
    /// Source line of each point's block (written as `block_line`, UInt32).
    pub block_line: Option<&'a [u32]>,
}

impl<'a> VtpPath<'a> {
    /// The contour-error export: `contour_error_um`, `orientation_error_mrad` and the unit
    /// vector `tool_axis` per tool-tip point.
    pub fn contour(
        points_mm: &'a [[f64; 3]],
        contour_error_um: &'a [f64],
        orientation_error_mrad: &'a [f64],
        tool_axis: &'a [[f64; 3]],
        block_line: Option<&'a [u32]>,
    ) -> VtpPath<'a> {
        Self::contour_with(
            points_mm,
            contour_error_um,
            orientation_error_mrad,
            Vectors::Given(tool_axis),
            block_line,
        )
    }

    /// [`VtpPath::contour`] with the tool axes given as [`Vectors`] (e.g. computed per point).
    pub fn contour_with(
        points_mm: &'a [[f64; 3]],
        contour_error_um: &'a [f64],
        orientation_error_mrad: &'a [f64],
        tool_axis: Vectors<'a>,
        block_line: Option<&'a [u32]>,
    ) -> VtpPath<'a> {
        VtpPath {
            points_mm,
            scalars: vec![
                PointScalars {
                    name: "contour_error_um".into(),
                    values: contour_error_um,
                },
                PointScalars {
                    name: "orientation_error_mrad".into(),
                    values: orientation_error_mrad,
                },
            ],
            vectors: vec![PointVectors {
                name: "tool_axis".into(),
                values: tool_axis,
            }],
            block_line,
        }
    }

    fn check(&self) -> Result<Vec<usize>, Error> {
        let n = self.points_mm.len();
        for s in &self.scalars {
            if s.values.len() != n {
                return Err(Error::LengthMismatch {
                    what: format!("vtp array '{}'", s.name),
                    expected: n,
                    found: s.values.len(),
                });
            }
        }
        for v in &self.vectors {
            if v.values.len() != n {
                return Err(Error::LengthMismatch {
                    what: format!("vtp array '{}'", v.name),
                    expected: n,
                    found: v.values.len(),
                });
            }
        }
        if let Some(l) = self.block_line
            && l.len() != n
        {
            return Err(Error::LengthMismatch {
                what: "vtp array 'block_line'".into(),
                expected: n,
                found: l.len(),
            });
        }
        let kept: Vec<usize> = (0..n)
            .filter(|&i| self.points_mm[i].iter().all(|c| c.is_finite()))
            .collect();
        for &i in &kept {
            for s in &self.scalars {
                if !s.values[i].is_finite() {
                    return Err(Error::NonFinite {
                        what: format!("vtp array '{}'", s.name),
                        index: i,
                        value: s.values[i],
                    });
                }
            }
            for v in &self.vectors {
                if let Some(c) = v.values.at(i).iter().find(|c| !c.is_finite()) {
                    return Err(Error::NonFinite {
                        what: format!("vtp array '{}'", v.name),
                        index: i,
                        value: *c,
                    });
                }
            }
        }
        if kept.is_empty() {
            return Err(Error::Empty {
                what: "vtp path (no point with finite coordinates)".into(),
            });
        }
        Ok(kept)
    }
}

/// Standard base64 (RFC 4648 §4, with padding). Hand-written: twenty lines against a
/// dependency; tested on the RFC's vectors.
fn base64(bytes: &[u8], out: &mut String) {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for c in bytes.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let v = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        out.push(A[(v >> 18) as usize & 63] as char);
        out.push(A[(v >> 12) as usize & 63] as char);
        out.push(if c.len() > 1 {
            A[(v >> 6) as usize & 63] as char
        } else {
            '='
        });
        out.push(if c.len() > 2 {
            A[v as usize & 63] as char
        } else {
            '='
        });
    }
}

/// One value of a data array: its VTK type name, little-endian bytes and text form.
trait Elem: Copy {
    /// VTK type name (`Float64`, `Int64`, `UInt32`).
    const TYPE: &'static str;
    /// Size in bytes.
    const SIZE: usize;
    fn le_bytes(self, out: &mut Vec<u8>);
    fn text(self, out: &mut String);
}

/// The [`Elem`] of a number type: its VTK name and the `write!` format of its text form.
macro_rules! elem {
    ($t:ty, $name:literal, $fmt:literal) => {
        impl Elem for $t {
            const TYPE: &'static str = $name;
            const SIZE: usize = std::mem::size_of::<$t>();
            fn le_bytes(self, out: &mut Vec<u8>) {
                out.extend(self.to_le_bytes());
            }
            fn text(self, out: &mut String) {
                let _ = write!(out, $fmt, self);
            }
        }
    };
}

elem!(f64, "Float64", "{:?}");
elem!(i64, "Int64", "{}");
elem!(u32, "UInt32", "{}");

/// The document being emitted: text is gathered in `out` and handed to `emit` whenever it
/// passes [`Pieces::CHUNK`] bytes, so that no data array is ever whole in memory
/// (docs/performance.md).
struct Pieces<'e> {
    out: String,
    emit: &'e mut dyn FnMut(&str),
}

impl Pieces<'_> {
    /// Bytes of text gathered before they are emitted.
    const CHUNK: usize = 1 << 16;

    fn flush(&mut self) {
        if !self.out.is_empty() {
            (self.emit)(&self.out);
            self.out.clear();
        }
    }

    fn flush_if_full(&mut self) {
        if self.out.len() >= Self::CHUNK {
            self.flush();
        }
    }

    /// One `<DataArray>` of `count` values given by `values` (`comps` components a tuple).
    fn data_array<T: Elem>(
        &mut self,
        name: Option<&str>,
        comps: usize,
        count: usize,
        values: impl Iterator<Item = T>,
        enc: VtpEncoding,
    ) {
        let _ = write!(self.out, "<DataArray type=\"{}\"", T::TYPE);
        if let Some(n) = name {
            let _ = write!(self.out, " Name=\"{}\"", escape(n));
        }
        if comps > 1 {
            let _ = write!(self.out, " NumberOfComponents=\"{comps}\"");
        }
        let format = match enc {
            VtpEncoding::Ascii => "ascii",
            VtpEncoding::Base64 => "binary",
        };
        let _ = write!(self.out, " format=\"{format}\">");
        match enc {
            VtpEncoding::Ascii => {
                for (j, x) in values.enumerate() {
                    if j > 0 {
                        self.out.push(' ');
                    }
                    x.text(&mut self.out);
                    self.flush_if_full();
                }
            }
            VtpEncoding::Base64 => {
                // The "binary" inline format: base64 of the byte count (header_type UInt64)
                // followed by the data, encoded as one stream. Bytes are encoded a multiple of
                // three at a time, so the text is the same as one encoding of the whole.
                let mut bytes = ((count * T::SIZE) as u64).to_le_bytes().to_vec();
                for x in values {
                    x.le_bytes(&mut bytes);
                    if bytes.len() >= 3 * (Self::CHUNK / 4) {
                        let whole = bytes.len() / 3 * 3;
                        base64(&bytes[..whole], &mut self.out);
                        bytes.drain(..whole);
                        self.flush();
                    }
                }
                base64(&bytes, &mut self.out);
            }
        }
        self.out.push_str("</DataArray>\n");
        self.flush_if_full();
    }
}

/// The `.vtp` document of a path.
pub fn vtp_string(path: &VtpPath, enc: VtpEncoding) -> Result<String, Error> {
    let mut doc = String::new();
    vtp_pieces(path, enc, &mut |piece| doc.push_str(piece))?;
    Ok(doc)
}

/// The `.vtp` document of a path, handed to `emit` a piece at a time (at most about 64 KiB
/// each), so that a long path is never one string in memory, nor any of its arrays
/// (docs/performance.md).
fn vtp_pieces(path: &VtpPath, enc: VtpEncoding, emit: &mut dyn FnMut(&str)) -> Result<(), Error> {
    let kept = path.check()?;
    // Polylines: runs of consecutive kept samples (a left-out point breaks the line).
    let mut offsets: Vec<i64> = Vec::new();
    for (j, w) in kept.windows(2).enumerate() {
        if w[1] != w[0] + 1 {
            offsets.push(j as i64 + 1);
        }
    }
    offsets.push(kept.len() as i64);
    let mut p = Pieces {
        out: String::with_capacity(2 * Pieces::CHUNK),
        emit,
    };
    p.out.push_str("<?xml version=\"1.0\"?>\n");
    p.out.push_str("<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<PolyData>\n");
    let _ = writeln!(
        p.out,
        "<Piece NumberOfPoints=\"{}\" NumberOfVerts=\"0\" NumberOfLines=\"{}\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">",
        kept.len(),
        offsets.len()
    );
    p.out.push_str("<PointData");
    if let Some(s) = path.scalars.first() {
        let _ = write!(p.out, " Scalars=\"{}\"", escape(&s.name));
    }
    if let Some(v) = path.vectors.first() {
        let _ = write!(p.out, " Vectors=\"{}\"", escape(&v.name));
    }
    p.out.push_str(">\n");
    let m = kept.len();
    for s in &path.scalars {
        let values = kept.iter().map(|&i| s.values[i]);
        p.data_array(Some(&s.name), 1, m, values, enc);
    }
    for vec in &path.vectors {
        let values = kept.iter().flat_map(|&i| vec.values.at(i));
        p.data_array(Some(&vec.name), 3, 3 * m, values, enc);
    }
    if let Some(l) = path.block_line {
        p.data_array(Some("block_line"), 1, m, kept.iter().map(|&i| l[i]), enc);
    }
    let idx = kept.iter().map(|&i| i as i64);
    p.data_array(Some("sample_index"), 1, m, idx, enc);
    p.out.push_str("</PointData>\n<Points>\n");
    let pts = kept.iter().flat_map(|&i| path.points_mm[i]);
    p.data_array(Some("Points"), 3, 3 * m, pts, enc);
    p.out.push_str("</Points>\n<Lines>\n");
    p.data_array(Some("connectivity"), 1, m, 0..m as i64, enc);
    let n_lines = offsets.len();
    p.data_array(Some("offsets"), 1, n_lines, offsets.into_iter(), enc);
    p.out
        .push_str("</Lines>\n</Piece>\n</PolyData>\n</VTKFile>\n");
    p.flush();
    Ok(())
}

/// Writes the `.vtp` file atomically, a data array at a time.
pub fn write_vtp(file: &Path, path: &VtpPath, enc: VtpEncoding) -> Result<(), Error> {
    crate::figure::write_atomic_with(file, |w| {
        let mut failed: Option<std::io::Error> = None;
        vtp_pieces(path, enc, &mut |piece| {
            if failed.is_none()
                && let Err(e) = w.write_all(piece.as_bytes())
            {
                failed = Some(e);
            }
        })?;
        failed.map_or(Ok(()), |e| Err(Error::io(file, e)))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            let mut s = String::new();
            base64(i.as_bytes(), &mut s);
            assert_eq!(s, o);
        }
    }

    /// An array many chunks long is encoded as one base64 stream: the same text as the whole
    /// array's bytes (with the UInt64 byte count before them) encoded at once.
    #[test]
    fn long_arrays_stream_as_one_base64_text() {
        let n = 100_003;
        let p: Vec<[f64; 3]> = (0..n).map(|k| [k as f64, 0.5 * k as f64, 1.0]).collect();
        let e: Vec<f64> = (0..n).map(|k| (k as f64).sin()).collect();
        let a = vec![[0.0, 0.0, 1.0]; n];
        let doc = vtp_string(&VtpPath::contour(&p, &e, &e, &a, None), VtpEncoding::Base64).unwrap();
        for (name, bytes) in [
            (
                "contour_error_um",
                e.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>(),
            ),
            (
                "Points",
                p.iter().flatten().flat_map(|x| x.to_le_bytes()).collect(),
            ),
        ] {
            let mut all = (bytes.len() as u64).to_le_bytes().to_vec();
            all.extend(bytes);
            let mut want = String::new();
            base64(&all, &mut want);
            let tag = format!("Name=\"{name}\"");
            let at = doc.find(&tag).unwrap();
            let body = &doc[at..];
            let start = body.find('>').unwrap() + 1;
            let end = body.find("</DataArray>").unwrap();
            assert_eq!(&body[start..end], want, "array {name}");
        }
    }

    #[test]
    fn lengths_and_non_finite_values_are_errors() {
        let p = [[0.0; 3]; 3];
        let e = [1.0, 2.0];
        let a = [[0.0, 0.0, 1.0]; 3];
        let path = VtpPath::contour(&p, &e, &e, &a, None);
        assert!(matches!(
            vtp_string(&path, VtpEncoding::Ascii),
            Err(Error::LengthMismatch {
                expected: 3,
                found: 2,
                ..
            })
        ));
        let e3 = [1.0, f64::NAN, 2.0];
        let path = VtpPath::contour(&p, &e3, &e3, &a, None);
        assert!(matches!(
            vtp_string(&path, VtpEncoding::Ascii),
            Err(Error::NonFinite { index: 1, .. })
        ));
    }
}
