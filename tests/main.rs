//! End-to-end tests of the `vcnc` binary and of the pipeline on the shipped machine files.
//! Heavy cases (identification of whole machines, the spiral) assume `cargo test --release`,
//! the README's test command.

mod util;

mod bad_inputs;
mod cli;
mod compensate;
mod identify;
mod models_only;
mod predict;
mod realistic;
mod report;
mod spiral;
mod sweep;
mod traces;
