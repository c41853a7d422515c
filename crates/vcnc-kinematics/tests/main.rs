//! The integration tests of `vcnc-kinematics` as one test binary, each file a module: a binary per
//! file linked every dependency again, which cost CI time. Run one file's tests by its name:
//! `cargo test -p vcnc-kinematics --test integration golden`.

mod common;

mod ac_bits;
mod closed_form;
mod families;
mod heldout;
mod linuxcnc;
mod machines;
mod sequences;
mod urdf;
