//! The integration tests of `vcnc-drive` as one test binary, each file a module: a binary per
//! file linked every dependency again, which cost CI time. Run one file's tests by its name:
//! `cargo test --release -p vcnc-drive --test integration golden`.

mod common;

mod batch;
mod drive;
mod golden;
mod realism;
mod stream;
