//! The `.vtp` export read back by an independent VTK reader (the `vtkio` crate's XML parser):
//! points, polyline cells and every point array must come back bit for bit, in both encodings.

use vcnc_report::vtp::{VtpEncoding, VtpPath, vtp_string, write_vtp};
use vtkio::model::{Attribute, DataSet, ElementType, IOBuffer, Piece, VertexNumbers};

struct Sample {
    pts: Vec<[f64; 3]>,
    contour: Vec<f64>,
    orient: Vec<f64>,
    axis: Vec<[f64; 3]>,
    lines: Vec<u32>,
}

/// A helix of 2 000 points with a gap (NaN coordinates) at 700..703: two polylines.
fn sample() -> Sample {
    let n = 2000;
    let mut pts: Vec<[f64; 3]> = (0..n)
        .map(|k| {
            let a = k as f64 * 0.01;
            [
                40.0 * a.cos(),
                40.0 * a.sin(),
                0.05 * k as f64 + 1e-9 * k as f64,
            ]
        })
        .collect();
    for p in &mut pts[700..703] {
        *p = [f64::NAN; 3];
    }
    Sample {
        contour: (0..n).map(|k| 1.0 / (1.0 + k as f64) + 123.456).collect(),
        orient: (0..n).map(|k| (k as f64 * 0.3).sin() * 1e-3).collect(),
        axis: (0..n)
            .map(|k| {
                let a = k as f64 * 1e-3;
                [a.sin(), 0.0, a.cos()]
            })
            .collect(),
        lines: (0..n).map(|k| 10 + k as u32 / 25).collect(),
        pts,
    }
}

fn point_array<'a>(attrs: &'a [Attribute], name: &str) -> &'a vtkio::model::DataArray {
    attrs
        .iter()
        .find_map(|a| match a {
            Attribute::DataArray(d) if d.name == name => Some(d),
            _ => None,
        })
        .unwrap_or_else(|| panic!("array {name} missing"))
}

fn f64s(b: &IOBuffer) -> Vec<f64> {
    match b {
        IOBuffer::F64(v) => v.clone(),
        other => panic!("expected Float64, got {other:?}"),
    }
}

fn round_trip(enc: VtpEncoding) {
    let s = sample();
    let path = VtpPath::contour(&s.pts, &s.contour, &s.orient, &s.axis, Some(&s.lines));
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("path.vtp");
    write_vtp(&file, &path, enc).unwrap();
    let text = std::fs::read(&file).unwrap();
    assert_eq!(text, vtp_string(&path, enc).unwrap().into_bytes());
    let vtk = vtkio::Vtk::parse_xml(std::io::BufReader::new(text.as_slice()))
        .expect("vtkio parses the file");
    let DataSet::PolyData { pieces, .. } = vtk.data else {
        panic!("not PolyData");
    };
    assert_eq!(pieces.len(), 1);
    let Piece::Inline(p) = &pieces[0] else {
        panic!("piece not inline");
    };
    let kept: Vec<usize> = (0..s.pts.len())
        .filter(|&i| s.pts[i][0].is_finite())
        .collect();
    assert_eq!(kept.len(), 1997);
    // Points, exactly.
    let pts = f64s(&p.points);
    let want: Vec<f64> = kept.iter().flat_map(|&i| s.pts[i]).collect();
    assert_eq!(pts, want);
    // Two polylines: 0..700 and 700..1997 (the gap breaks the line).
    match p.lines.as_ref().expect("lines") {
        VertexNumbers::XML {
            connectivity,
            offsets,
        } => {
            assert_eq!(offsets, &vec![700u64, 1997]);
            assert_eq!(connectivity, &(0..1997u64).collect::<Vec<_>>());
        }
        other => panic!("unexpected cell layout {other:?}"),
    }
    // Arrays, exactly, with their component counts.
    let a = &p.data.point;
    let c = point_array(a, "contour_error_um");
    assert_eq!(
        f64s(&c.data),
        kept.iter().map(|&i| s.contour[i]).collect::<Vec<_>>()
    );
    let o = point_array(a, "orientation_error_mrad");
    assert_eq!(
        f64s(&o.data),
        kept.iter().map(|&i| s.orient[i]).collect::<Vec<_>>()
    );
    let t = point_array(a, "tool_axis");
    assert!(
        matches!(t.elem, ElementType::Vectors)
            || matches!(t.elem, ElementType::Scalars { num_comp: 3, .. })
            || matches!(t.elem, ElementType::Generic(3)),
        "tool_axis has 3 components: {:?}",
        t.elem
    );
    assert_eq!(
        f64s(&t.data),
        kept.iter().flat_map(|&i| s.axis[i]).collect::<Vec<_>>()
    );
    let l = point_array(a, "block_line");
    assert_eq!(
        l.data.cast_into::<u32>().unwrap(),
        kept.iter().map(|&i| s.lines[i]).collect::<Vec<_>>()
    );
    let idx = point_array(a, "sample_index");
    assert_eq!(
        idx.data.cast_into::<i64>().unwrap(),
        kept.iter().map(|&i| i as i64).collect::<Vec<_>>()
    );
}

#[test]
fn base64_vtp_reads_back_exactly_in_vtkio() {
    round_trip(VtpEncoding::Base64);
}

#[test]
fn ascii_vtp_reads_back_exactly_in_vtkio() {
    round_trip(VtpEncoding::Ascii);
}
