//! What the pipeline's integration tests share: models of the embedded machine's axes and the
//! O-word program (a subroutine in nested loops, a condition).

#![allow(dead_code)]

use vcnc_drive::{DriveModel, ReferenceFilter};
use vcnc_machine::{Machine, MachineModels};

/// Models of the true drives, or (`rich`) the same with a dead time of 0.4 samples, a
/// first-order reference filter, an extra pole and a stated actual-value latency on three axes
/// (whole and fractional samples).
pub fn models(machine: &Machine, rich: bool) -> MachineModels {
    let latency = [1e-4, 0.0, 2e-3, 0.0, 3.5e-4];
    let m = machine
        .axes
        .iter()
        .zip(latency)
        .map(|(a, l)| {
            let mut m = DriveModel::from(a.true_model());
            if rich {
                m.delay_s = 0.4e-3;
                m.reference_filter = Some(ReferenceFilter::FirstOrder { tau_s: 0.7e-3 });
                m.extra_pole_hz = Some(400.0);
                m.actual_latency_s = l;
            }
            m
        })
        .collect();
    MachineModels::new(machine, m, "test models").expect("models")
}

/// The O-word program: a subroutine called from nested loops, a condition.
pub const OWORD: &str = "\
G21 G90 G64 P0.01
G0 X0 Y0 Z0
o<pocket> sub
  G1 X[#1] Y[#2] F2400
  G1 X[#1 + #3] C[#4]
  G1 Y[#2 + #3]
  o1 if [#4 GT 40]
    G1 Z-2 F600
  o1 else
    G1 Z-1 F600
  o1 endif
  G1 X[#1] Y[#2]
o<pocket> endsub
#10 = 0
o2 while [#10 LT 12]
  o3 repeat [2]
    o<pocket> call [#10 * 3] [#10 * 2] [5] [#10 * 8]
  o3 endrepeat
  #10 = [#10 + 1]
o2 endwhile
G0 Z10
M2
";
