//! The URDF chain: parsing the shipped machine, validation errors, and the generic forward
//! kinematics against the closed form of docs/kinematics.md.

use proptest::prelude::*;
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{Axes, AxisName, Error, JointKind, KinematicChain, TableTiltingAc};

const NMV5000: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../machines/nmv5000.urdf");

fn shipped() -> KinematicChain {
    match KinematicChain::from_urdf_file(NMV5000) {
        Ok(c) => c,
        Err(e) => panic!("the shipped URDF must load: {e}"),
    }
}

/// A table-tilting URDF with arbitrary r, d, written in the same form as the shipped file but
/// with intermediate fixed joints and rpy rotations that cancel, to exercise the generic
/// composition. Truth: docs/kinematics.md's structure (A origin r + d, C origin −d, workpiece −r).
fn custom_urdf(r: [f64; 3], d: [f64; 3]) -> String {
    let rd = [r[0] + d[0], r[1] + d[1], r[2] + d[2]];
    format!(
        r#"<?xml version="1.0"?>
<robot name="custom">
  <link name="base"/><link name="column"/><link name="sx"/><link name="sy"/><link name="sz"/>
  <link name="tool_tip"/><link name="cradle"/><link name="cradle2"/><link name="table"/><link name="workpiece"/>
  <joint name="column" type="fixed"><parent link="base"/><child link="column"/>
    <origin xyz="0 0 0" rpy="0 0 1.5707963267948966"/></joint>
  <joint name="x" type="prismatic"><parent link="column"/><child link="sx"/>
    <origin xyz="0 0 0" rpy="0 0 -1.5707963267948966"/><axis xyz="1 0 0"/>
    <limit lower="-500" upper="500" velocity="800"/></joint>
  <joint name="y" type="prismatic"><parent link="sx"/><child link="sy"/>
    <axis xyz="0 2 0"/><limit lower="-500" upper="500" velocity="800"/></joint>
  <joint name="z" type="prismatic"><parent link="sy"/><child link="sz"/>
    <origin xyz="5 6 7"/><axis xyz="0 0 1"/><limit lower="-500" upper="500" velocity="800"/></joint>
  <joint name="spindle" type="fixed"><parent link="sz"/><child link="tool_tip"/>
    <origin xyz="-5 -6 -7"/></joint>
  <joint name="a" type="revolute"><parent link="base"/><child link="cradle"/>
    <origin xyz="{} {} {}" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="0.5" velocity="5"/></joint>
  <joint name="trunnion" type="fixed"><parent link="cradle"/><child link="cradle2"/>
    <origin xyz="0 0 0" rpy="0.3 0 0"/></joint>
  <joint name="c" type="continuous"><parent link="cradle2"/><child link="table"/>
    <origin xyz="{} {} {}" rpy="-0.3 0 0"/><axis xyz="0 0 1"/><limit velocity="10"/></joint>
  <joint name="workpiece" type="fixed"><parent link="table"/><child link="workpiece"/>
    <origin xyz="{} {} {}"/></joint>
</robot>"#,
        rd[0],
        rd[1],
        rd[2],
        // C origin: −d expressed in the cradle2 frame, which is rotated by +0.3 rad about X.
        -d[0],
        -d[1] * 0.3f64.cos() - d[2] * 0.3f64.sin(),
        d[1] * 0.3f64.sin() - d[2] * 0.3f64.cos(),
        -r[0],
        -r[1],
        -r[2],
    )
}

fn load_str(text: &str) -> Result<KinematicChain, Error> {
    KinematicChain::from_urdf_str(text, "test.urdf")
}

fn err_text(text: &str) -> String {
    match load_str(text) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

fn shipped_text() -> String {
    match std::fs::read_to_string(NMV5000) {
        Ok(s) => s,
        Err(e) => panic!("{NMV5000}: {e}"),
    }
}

#[test]
fn shipped_urdf_has_spec_default_offsets_and_nominal_travels() {
    // Truth: docs/kinematics.md defaults r = 0, d = (0, 0, -100) mm; travels as written in the file.
    let chain = shipped();
    assert_eq!(chain.name(), "nmv5000");
    assert_eq!(chain.base_link(), "machine");
    assert_eq!(chain.tool_link(), "tool_tip");
    assert_eq!(chain.workpiece_link(), "workpiece");
    assert_eq!(chain.r(), Vector3::zeros());
    assert_eq!(chain.d(), Vector3::new(0.0, 0.0, -100.0));
    let l = chain.limits();
    assert_eq!((l.x.lower, l.x.upper), (-365.0, 365.0));
    assert_eq!((l.y.lower, l.y.upper), (-255.0, 255.0));
    assert_eq!((l.z.lower, l.z.upper), (-255.0, 255.0));
    assert!((l.a.lower.to_degrees() + 120.0).abs() < 1e-9);
    assert!((l.a.upper.to_degrees() - 30.0).abs() < 1e-9);
    assert!(l.c.lower == f64::NEG_INFINITY && l.c.upper == f64::INFINITY);
    let kinds: Vec<_> = chain
        .tool_joints()
        .iter()
        .map(|j| (j.name.as_str(), j.kind, j.role))
        .collect();
    assert_eq!(
        kinds,
        vec![
            ("x", JointKind::Prismatic, Some(AxisName::X)),
            ("y", JointKind::Prismatic, Some(AxisName::Y)),
            ("z", JointKind::Prismatic, Some(AxisName::Z)),
        ]
    );
    let kinds: Vec<_> = chain
        .workpiece_joints()
        .iter()
        .map(|j| (j.name.as_str(), j.kind, j.role))
        .collect();
    assert_eq!(
        kinds,
        vec![
            ("a", JointKind::Revolute, Some(AxisName::A)),
            ("c", JointKind::Continuous, Some(AxisName::C)),
            ("workpiece", JointKind::Fixed, None),
        ]
    );
    // The closed-form model takes r, d and limits from the chain.
    let m = chain.table_tilting_ac();
    assert_eq!((m.r, m.d, m.limits), (chain.r(), chain.d(), chain.limits()));
}

#[test]
fn reading_from_a_string_equals_reading_the_file() {
    let from_str = match KinematicChain::from_urdf_str(&shipped_text(), NMV5000) {
        Ok(c) => c,
        Err(e) => panic!("{e}"),
    };
    assert_eq!(from_str, shipped());
}

#[test]
fn custom_chain_offsets_come_from_the_joint_origins() {
    // Truth: r and d written into the URDF (through a rotated intermediate frame).
    let r = [12.5, -7.0, 3.0];
    let d = [0.0, 40.0, -150.0];
    let chain = match load_str(&custom_urdf(r, d)) {
        Ok(c) => c,
        Err(e) => panic!("{e}"),
    };
    assert!((chain.r() - Vector3::from(r)).norm() < 1e-12);
    assert!((chain.d() - Vector3::from(d)).norm() < 1e-12);
}

fn assert_chain_matches_closed_form(chain: &KinematicChain, axes: &Axes) {
    let model: TableTiltingAc = chain.table_tilting_ac();
    let g = chain.forward(axes);
    let c = model.forward(axes);
    assert!(
        (g.p - c.p).norm() < 1e-9,
        "p: URDF {:?} vs closed form {:?} at {axes:?}",
        g.p,
        c.p
    );
    assert!(
        (g.o - c.o).norm() < 1e-9,
        "o: URDF {:?} vs closed form {:?} at {axes:?}",
        g.o,
        c.o
    );
}

fn axes_strategy() -> impl Strategy<Value = Axes> {
    // Beyond the travels on purpose: forward kinematics never clamps.
    (
        -500.0..500.0f64,
        -400.0..400.0f64,
        -400.0..400.0f64,
        -3.5..3.5f64,
        -40.0..40.0f64,
    )
        .prop_map(|(x, y, z, a, c)| Axes::new(x, y, z, a, c))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The generic URDF forward kinematics equals the closed form of docs/kinematics.md within
    /// 1e-9 mm / 1e-9 (unit vector), on the shipped file.
    #[test]
    fn urdf_forward_equals_closed_form_on_shipped_machine(axes in axes_strategy()) {
        assert_chain_matches_closed_form(&shipped(), &axes);
    }

    /// Same on chains with arbitrary offsets, intermediate fixed joints and rpy rotations.
    #[test]
    fn urdf_forward_equals_closed_form_on_custom_chains(
        axes in axes_strategy(),
        r in (-100.0..100.0f64, -100.0..100.0f64, -100.0..100.0f64),
        d in (-100.0..100.0f64, -100.0..100.0f64, -300.0..300.0f64),
    ) {
        let urdf = custom_urdf([r.0, r.1, r.2], [d.0, d.1, d.2]);
        let chain = match load_str(&urdf) {
            Ok(c) => c,
            Err(e) => panic!("{e}"),
        };
        assert_chain_matches_closed_form(&chain, &axes);
    }
}

#[test]
fn forward_does_not_clamp_to_travel() {
    // X = 400 mm is beyond the 365 mm travel; at A = C = 0 the pose is the machine position.
    let chain = shipped();
    let p = chain.forward(&Axes::new(400.0, 0.0, 0.0, 0.0, 0.0)).p;
    assert_eq!(p, Vector3::new(400.0, 0.0, 0.0));
}

// ---- validation errors -------------------------------------------------------------------

#[test]
fn wrong_a_axis_is_named_with_the_numbers() {
    let text = shipped_text().replacen(
        "<axis xyz=\"1 0 0\"/>\n    <limit lower=\"-2.0943951023931953\"",
        "<axis xyz=\"0 1 0\"/>\n    <limit lower=\"-2.0943951023931953\"",
        1,
    );
    let e = err_text(&text);
    assert_eq!(
        e,
        "test.urdf: not a table-tilting A/C chain: joint 'a' axis is (0, 1, 0), expected +X (axis A)"
    );
}

#[test]
fn dependent_slides_are_reported() {
    // Joint 'y' (named Y) moves along Z like 'z': the slides no longer span space.
    let text = shipped_text().replacen("<axis xyz=\"0 1 0\"/>", "<axis xyz=\"0 0 1\"/>", 1);
    let e = err_text(&text);
    assert!(
        e.contains(
            "the slides X, Y, Z move along dependent directions (1, 0, 0), (0, 0, 1), (0, 0, 1)"
        ),
        "{e}"
    );
}

#[test]
fn missing_file_names_the_file() {
    let e = match KinematicChain::from_urdf_file("/nonexistent/dir/machine.urdf") {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.starts_with("/nonexistent/dir/machine.urdf: cannot read the URDF:"),
        "{e}"
    );
}

#[test]
fn malformed_xml_names_the_file() {
    let e = err_text("<robot name=\"x\"><link name=\"a\"></robot>");
    assert!(e.starts_with("test.urdf: cannot read the URDF:"), "{e}");
}

#[test]
fn limit_without_velocity_is_an_error() {
    // urdf-rs requires velocity on every <limit>.
    let text = shipped_text().replacen(" velocity=\"833\"", "", 1);
    let e = err_text(&text);
    assert!(e.starts_with("test.urdf: cannot read the URDF:"), "{e}");
}

#[test]
fn prismatic_joint_without_travel_is_an_error() {
    let text = shipped_text().replacen(
        "<limit lower=\"-365\" upper=\"365\" effort=\"0\" velocity=\"833\"/>",
        "<limit effort=\"0\" velocity=\"833\"/>",
        1,
    );
    let e = err_text(&text);
    assert!(e.contains("joint 'x' has no travel"), "{e}");
}

#[test]
fn workpiece_not_at_minus_r_is_an_error() {
    let text = shipped_text().replacen(
        "<!-- -r = (0, 0, 0) mm -->\n    <origin xyz=\"0 0 0\"",
        "<origin xyz=\"0 0 5\"",
        1,
    );
    let e = err_text(&text);
    assert!(
        e.contains("the workpiece link 'workpiece' is at (0, 0, 5) mm"),
        "{e}"
    );
}

#[test]
fn tool_tip_offset_is_an_error() {
    let text = shipped_text().replacen(
        "<child link=\"tool_tip\"/>\n    <origin xyz=\"0 0 0\"",
        "<child link=\"tool_tip\"/>\n    <origin xyz=\"0 0 150\"",
        1,
    );
    let e = err_text(&text);
    assert!(
        e.contains("the tool tip link 'tool_tip' is at (0, 0, 150) mm"),
        "{e}"
    );
}

#[test]
fn unsupported_joint_kind_is_an_error() {
    let text = shipped_text().replacen("type=\"fixed\"", "type=\"floating\"", 1);
    let e = err_text(&text);
    assert!(e.contains("joint 'workpiece' is Floating"), "{e}");
}

#[test]
fn extra_movable_joint_is_an_error() {
    let text = shipped_text().replacen(
        "</robot>",
        "<link name=\"probe\"/><joint name=\"w\" type=\"prismatic\"><parent link=\"cradle\"/>\
         <child link=\"probe\"/><axis xyz=\"0 0 1\"/>\
         <limit lower=\"0\" upper=\"10\" velocity=\"1\"/></joint></robot>",
        1,
    );
    let e = err_text(&text);
    assert!(
        e.contains("joint 'w' moves but is on neither the tool branch nor the workpiece branch"),
        "{e}"
    );
}

#[test]
fn disconnected_base_is_an_error() {
    let text = shipped_text().replacen(
        "<link name=\"machine\"/>",
        "<link name=\"machine\"/><link name=\"stray\"/>",
        1,
    );
    let e = err_text(&text);
    assert!(
        e.contains("links 'machine', 'stray' have no parent joint"),
        "{e}"
    );
}

#[test]
fn two_parents_is_an_error() {
    let text = shipped_text().replacen(
        "</robot>",
        "<joint name=\"dup\" type=\"fixed\"><parent link=\"machine\"/><child link=\"cradle\"/></joint></robot>",
        1,
    );
    let e = err_text(&text);
    assert!(
        e.contains("link 'cradle' is the child of two joints, 'a' and 'dup'"),
        "{e}"
    );
}

#[test]
fn a_slide_named_after_a_rotary_axis_is_an_error() {
    let text = shipped_text()
        .replacen("type=\"continuous\"", "type=\"prismatic\"", 1)
        .replacen(
            "<limit effort=\"0\" velocity=\"10.472\"/>",
            "<limit lower=\"-1\" upper=\"1\" effort=\"0\" velocity=\"10.472\"/>",
            1,
        );
    let e = err_text(&text);
    assert!(
        e.contains("joint 'c' is prismatic but its name makes it the rotary axis C"),
        "{e}"
    );
}

#[test]
fn a_machine_of_another_family_is_not_an_ac_chain() {
    // The cradle turned to tilt about Y, joint renamed: a table-tilting B/C machine, which the
    // A/C reader refuses and the general reader maps onto its closed form.
    let text = shipped_text()
        .replacen("<joint name=\"a\"", "<joint name=\"b\"", 1)
        .replacen(
            "<axis xyz=\"1 0 0\"/>\n    <limit lower=\"-2.0943951023931953\"",
            "<axis xyz=\"0 1 0\"/>\n    <limit lower=\"-2.0943951023931953\"",
            1,
        );
    let e = err_text(&text);
    assert_eq!(
        e,
        "test.urdf: not a table-tilting A/C chain: it is a table-tilting B/C machine"
    );
    match vcnc_kinematics::Kinematics::from_urdf_str(&text, "test.urdf") {
        Ok(k) => assert_eq!(
            k.family(),
            vcnc_kinematics::Family::TableTilting(vcnc_kinematics::Tilt::B)
        ),
        Err(e) => panic!("{e}"),
    }
}
