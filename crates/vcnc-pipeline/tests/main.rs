//! The integration tests of `vcnc-pipeline` as one test binary, each file a module: a binary per
//! file linked every dependency again, which cost CI time. Run one file's tests by its name:
//! `cargo test --release -p vcnc-pipeline --test integration route`. `stream_memory.rs` stays
//! its own binary: its counting allocator must see no other test running.

mod common;

mod control_filters;
mod feed_plan;
mod latency;
mod machines;
mod route;
