//! Fuzz target `machine_file`: arbitrary bytes (as lossy UTF-8) → `Machine::from_toml_str`.
//!
//! Mostly exercises the TOML parser and the serde mapping (unknown, missing and mistyped keys);
//! `machine_file_mutate` reaches the validation behind them. Checks: no panic, and an error's
//! `Display` names the source ("fuzz.toml"), so a user knows which file to fix.

#![no_main]

use libfuzzer_sys::fuzz_target;
use vcnc_fuzz::check_load;

fuzz_target!(|data: &[u8]| {
    let src = String::from_utf8_lossy(data);
    check_load(&src, None);
});
