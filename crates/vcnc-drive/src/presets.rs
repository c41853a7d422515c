//! Reference drives from the paper (docs/reference-numbers.md), shared by the machine files and the tests.

use std::f64::consts::PI;

use crate::drive::DriveParams;
use crate::params::{ControllerSpec, DEFAULT_SERVO_RATE_HZ, Encoder, Plant, PoleDesign};
use crate::{AxisName, Error};

/// The paper's Table 1 closed loop with the coefficients as the paper prints them
/// (docs/reference-numbers.md, "Actual", rounded there to 4-7 digits) and $d_c = 47.7$ mm/s², the
/// Coulomb level of [`table1_drive`]: the truth of the tests that need the Table 1 model itself
/// rather than its drive (vary `b0`, `dc` with struct update syntax).
pub const TABLE1_MODEL: crate::ClosedLoopModel = crate::ClosedLoopModel {
    a1: 238.4335,
    a2: 48421.586,
    a3: 2487140.3,
    b0: 0.0,
    b1: 117.5424,
    b2: 37258.98,
    dc: 47.7,
};

/// The paper's Table 1 virtual P-PI ball-screw drive (docs/reference-numbers.md): $r_g = 1.5915$ mm/rad,
/// $J = 0.01$ kg·m², $B = 0.0418572$ N·m·s/rad, $K_a = K_t = 1$, $K_v = 70$ (rad/s)/mm,
/// $K_p = 2.342478$, $K_i = 223.252126$, $V_{ff} = 0.5$, $B_{ff} = 0.1$, $J_{ff} = 0$.
/// Its exact poles are 30.569 Hz / 0.44519 / 10.7296 Hz.
///
/// Coulomb friction: the realistic $T_c = 0.3$ N·m ($d_c = 47.7$ mm/s²) instead of the
/// table's $d_c = 2.68$, which is too small to matter. Default encoder and servo rate.
pub fn table1_drive() -> DriveParams {
    table1_feed_forward_drive(
        TABLE1_PLANT,
        [Some(70.0), Some(2.342478), Some(223.252126)],
        None,
    )
}

/// The plant of the paper's Table 1 drive ([`table1_drive`]): $r_g = 1.5915$ mm/rad,
/// $J = 0.01$ kg·m², $B = 0.0418572$ N·m·s/rad, $K_a = K_t = 1$, the realistic
/// $T_c = 0.3$ N·m, no current limit.
pub const TABLE1_PLANT: Plant = Plant {
    j: 0.01,
    b: 0.0418572,
    ka: 1.0,
    kt: 1.0,
    rg: 1.5915,
    coulomb_torque: 0.3,
    u_max: None,
};

/// A P-PI drive of `plant` with gains `[kv, kp, ki]` or a pole `design`, Table 1's feed-forward
/// ($V_{ff} = 0.5$, $B_{ff} = 0.1$, $J_{ff} = 0$), the default encoder and servo rate, and none
/// of the realistic effects: the shape of every reference drive here.
fn table1_feed_forward_drive(
    plant: Plant,
    [kv, kp, ki]: [Option<f64>; 3],
    design: Option<PoleDesign>,
) -> DriveParams {
    DriveParams {
        plant,
        controller: ControllerSpec::PPi {
            kv,
            kp,
            ki,
            design,
            vff: 0.5,
            bff: 0.1,
            jff: 0.0,
        },
        encoder: Encoder::default(),
        servo_rate_hz: DEFAULT_SERVO_RATE_HZ,
        compliance: None,
        friction: None,
        current_loop: None,
        feedback: None,
        reference: None,
    }
}

/// The NMV5000's five P-PI axes, "Actual" columns of the paper's Table 3 (docs/reference-numbers.md):
/// `(axis, poles)`.
pub const NMV5000_TABLE3: [(AxisName, PoleDesign); 5] = [
    (
        AxisName::X,
        PoleDesign {
            p_hz: 19.30,
            wn_hz: 55.54,
            zeta: 0.39,
        },
    ),
    (
        AxisName::Y,
        PoleDesign {
            p_hz: 22.12,
            wn_hz: 73.50,
            zeta: 0.27,
        },
    ),
    (
        AxisName::Z,
        PoleDesign {
            p_hz: 22.20,
            wn_hz: 73.60,
            zeta: 0.28,
        },
    ),
    (
        AxisName::A,
        PoleDesign {
            p_hz: 9.29,
            wn_hz: 31.90,
            zeta: 0.47,
        },
    ),
    (
        AxisName::C,
        PoleDesign {
            p_hz: 8.45,
            wn_hz: 27.30,
            zeta: 0.57,
        },
    ),
];

/// Mechanical pole $B/J$ of every NMV5000 axis, 1/s (docs/reference-numbers.md).
pub const NMV5000_B_OVER_J: f64 = 4.19;

/// A drive for one NMV5000 axis (`'X'`, `'Y'`, `'Z'`, `'A'`, `'C'`, case-insensitive) whose P-PI
/// gains are designed from its Table 3 poles (docs/reference-numbers.md: the real physical parameters are
/// not public). The controller is returned as a design (`design = { .. }`); validate it to get
/// the gains.
///
/// Assumed physics (not from the paper): $K_a = K_t = 1$ as in Table 1, $B/J = 4.19$ 1/s, and
///
/// | axis | drive | $r_g$ | $J$ kg·m² | $T_c$ N·m | $d_c$ |
/// |---|---|---|---|---|---|
/// | X | ball screw, 10 mm pitch | 10/2π mm/rad | 0.012 | 0.3 | 39.8 mm/s² |
/// | Y | ball screw, 10 mm pitch | 10/2π mm/rad | 0.010 | 0.3 | 47.7 mm/s² |
/// | Z | ball screw, 10 mm pitch | 10/2π mm/rad | 0.008 | 0.3 | 59.7 mm/s² |
/// | A | direct-drive trunnion | 180/π deg/rad | 0.5 | 1.5 | 172 deg/s² |
/// | C | direct-drive table | 180/π deg/rad | 0.2 | 0.8 | 229 deg/s² |
///
/// Feed-forward as Table 1: $V_{ff} = 0.5$, $B_{ff} = 0.1$, $J_{ff} = 0$. Default encoder
/// (0.1 µm / 0.0001°) and servo rate (20 kHz).
pub fn nmv5000_axis_design(axis: AxisName) -> Result<DriveParams, Error> {
    let (_, design) = NMV5000_TABLE3
        .iter()
        .find(|(a, _)| *a == axis)
        .ok_or(Error::UnknownAxis { axis })?;
    let screw = 10.0 / (2.0 * PI);
    let direct = 180.0 / PI;
    let (rg, j, tc) = match axis {
        AxisName::X => (screw, 0.012, 0.3),
        AxisName::Y => (screw, 0.010, 0.3),
        AxisName::Z => (screw, 0.008, 0.3),
        AxisName::A => (direct, 0.5, 1.5),
        _ => (direct, 0.2, 0.8),
    };
    let plant = Plant {
        j,
        b: NMV5000_B_OVER_J * j,
        ka: 1.0,
        kt: 1.0,
        rg,
        coulomb_torque: tc,
        u_max: None,
    };
    Ok(table1_feed_forward_drive(
        plant,
        [None, None, None],
        Some(*design),
    ))
}
