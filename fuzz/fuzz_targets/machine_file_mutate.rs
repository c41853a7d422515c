//! Fuzz target `machine_file_mutate`: a shipped machine file, mutated under the fuzzer's control
//! (numbers → NaN, ±inf, negative, huge, scaled; wrong types; strings; renamed keys; deleted,
//! duplicated, swapped and junk lines), → `Machine::from_toml_str`.
//!
//! The mutated files stay mostly valid TOML of the right shape, so the fuzzer reaches the checks
//! behind the parser: sample period, travels, limits, drive validation (gain design from poles,
//! Routh–Hurwitz stability, encoder, servo rate), identification settings and, for
//! `nmv5000.toml` (loaded with the real `machines/` folder), the URDF chain and the kinematic
//! offsets and travels. Checks as in `machine_file`: no panic, errors name the file, accepted
//! machines have stable finite drive models.
//!
//! Input layout: byte 0 picks the base file, the rest drives `vcnc_fuzz::mutate`.

#![no_main]

use libfuzzer_sys::fuzz_target;
use vcnc_fuzz::{BASES, check_load, machines_dir, mutate};

fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let (base, needs_dir) = BASES[usize::from(pick) % BASES.len()];
    let src = mutate(base, rest);
    check_load(&src, needs_dir.then(machines_dir));
});
