//! The integration tests of `vcnc-gcode` as one test binary, each file a module: a binary per
//! file linked every dependency again, which cost CI time. Run one file's tests by its name:
//! `cargo test -p vcnc-gcode --test integration golden`.

mod fuzz_regressions;
mod generators;
mod golden;
mod jerk_limited;
mod linuxcnc;
mod linuxcnc_planner;
mod properties;
mod streaming;
mod tcp_off_rests;
mod written_programs;
