//! The integration tests of `vcnc-trace` as one test binary, each file a module: a binary per
//! file linked every dependency again, which cost CI time. Run one file's tests by its name:
//! `cargo test -p vcnc-trace --test integration golden`.

mod common;

mod bad_input;
mod fixtures;
mod fresh;
mod golden;
mod no_panic;
mod parquet;
mod round_trip;
