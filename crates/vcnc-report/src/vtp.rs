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
#[derive(Debug, Clone, PartialEq)]
pub struct PointVectors<'a> {
    /// Array name (`tool_axis`).
    pub name: String,
    /// One vector per path point.
    pub values: &'a [[f64; 3]],
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
#[derive(Debug, Clone, PartialEq)]
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
                if let Some(c) = v.values[i].iter().find(|c| !c.is_finite()) {
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

/// Values of one data array, before encoding.
enum Values {
    F64(Vec<f64>),
    I64(Vec<i64>),
    U32(Vec<u32>),
}

impl Values {
    fn type_name(&self) -> &'static str {
        match self {
            Values::F64(_) => "Float64",
            Values::I64(_) => "Int64",
            Values::U32(_) => "UInt32",
        }
    }

    fn write(&self, enc: VtpEncoding, out: &mut String) {
        match enc {
            VtpEncoding::Ascii => {
                let mut first = true;
                let mut sep = |out: &mut String| {
                    if !first {
                        out.push(' ');
                    }
                    first = false;
                };
                match self {
                    Values::F64(v) => v.iter().for_each(|x| {
                        sep(out);
                        let _ = write!(out, "{x:?}");
                    }),
                    Values::I64(v) => v.iter().for_each(|x| {
                        sep(out);
                        let _ = write!(out, "{x}");
                    }),
                    Values::U32(v) => v.iter().for_each(|x| {
                        sep(out);
                        let _ = write!(out, "{x}");
                    }),
                }
            }
            VtpEncoding::Base64 => {
                let mut bytes = Vec::new();
                match self {
                    Values::F64(v) => v.iter().for_each(|x| bytes.extend(x.to_le_bytes())),
                    Values::I64(v) => v.iter().for_each(|x| bytes.extend(x.to_le_bytes())),
                    Values::U32(v) => v.iter().for_each(|x| bytes.extend(x.to_le_bytes())),
                }
                // The "binary" inline format: base64 of the byte count (header_type UInt64)
                // followed by the data, encoded as one stream.
                let mut all = (bytes.len() as u64).to_le_bytes().to_vec();
                all.extend(bytes);
                base64(&all, out);
            }
        }
    }
}

fn data_array(out: &mut String, name: Option<&str>, comps: usize, v: &Values, enc: VtpEncoding) {
    let _ = write!(out, "<DataArray type=\"{}\"", v.type_name());
    if let Some(n) = name {
        let _ = write!(out, " Name=\"{}\"", escape(n));
    }
    if comps > 1 {
        let _ = write!(out, " NumberOfComponents=\"{comps}\"");
    }
    let format = match enc {
        VtpEncoding::Ascii => "ascii",
        VtpEncoding::Base64 => "binary",
    };
    let _ = write!(out, " format=\"{format}\">");
    v.write(enc, out);
    out.push_str("</DataArray>\n");
}

/// The `.vtp` document of a path.
pub fn vtp_string(path: &VtpPath, enc: VtpEncoding) -> Result<String, Error> {
    let mut doc = String::new();
    vtp_pieces(path, enc, &mut |piece| doc.push_str(piece))?;
    Ok(doc)
}

/// The `.vtp` document of a path, handed to `emit` a piece at a time (the header, then one
/// data array after another), so that a long path is never one string in memory
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
    let mut out = String::new();
    let mut flush = |out: &mut String| {
        emit(out);
        out.clear();
        out.shrink_to(1 << 16);
    };
    out.push_str("<?xml version=\"1.0\"?>\n");
    out.push_str("<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<PolyData>\n");
    let _ = writeln!(
        out,
        "<Piece NumberOfPoints=\"{}\" NumberOfVerts=\"0\" NumberOfLines=\"{}\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">",
        kept.len(),
        offsets.len()
    );
    out.push_str("<PointData");
    if let Some(s) = path.scalars.first() {
        let _ = write!(out, " Scalars=\"{}\"", escape(&s.name));
    }
    if let Some(v) = path.vectors.first() {
        let _ = write!(out, " Vectors=\"{}\"", escape(&v.name));
    }
    out.push_str(">\n");
    flush(&mut out);
    for s in &path.scalars {
        let v = Values::F64(kept.iter().map(|&i| s.values[i]).collect());
        data_array(&mut out, Some(&s.name), 1, &v, enc);
        flush(&mut out);
    }
    for vec in &path.vectors {
        let v = Values::F64(kept.iter().flat_map(|&i| vec.values[i]).collect());
        data_array(&mut out, Some(&vec.name), 3, &v, enc);
        flush(&mut out);
    }
    if let Some(l) = path.block_line {
        let v = Values::U32(kept.iter().map(|&i| l[i]).collect());
        data_array(&mut out, Some("block_line"), 1, &v, enc);
        flush(&mut out);
    }
    let idx = Values::I64(kept.iter().map(|&i| i as i64).collect());
    data_array(&mut out, Some("sample_index"), 1, &idx, enc);
    drop(idx);
    out.push_str("</PointData>\n<Points>\n");
    flush(&mut out);
    let pts = Values::F64(kept.iter().flat_map(|&i| path.points_mm[i]).collect());
    data_array(&mut out, Some("Points"), 3, &pts, enc);
    drop(pts);
    out.push_str("</Points>\n<Lines>\n");
    flush(&mut out);
    let connectivity = Values::I64((0..kept.len() as i64).collect());
    data_array(&mut out, Some("connectivity"), 1, &connectivity, enc);
    drop(connectivity);
    flush(&mut out);
    data_array(&mut out, Some("offsets"), 1, &Values::I64(offsets), enc);
    out.push_str("</Lines>\n</Piece>\n</PolyData>\n</VTKFile>\n");
    flush(&mut out);
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
