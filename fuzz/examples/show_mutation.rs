//! Prints the machine file that a `machine_file_mutate` input produces (to read a finding, or to
//! turn it into a regression test), then loads it and prints the outcome.
//!
//! `cargo run --release --example show_mutation -- artifacts/machine_file_mutate/<file>`

use vcnc_fuzz::{BASES, SOURCE, machines_dir, mutate};
use vcnc_machine::Machine;

fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: show_mutation <input file>");
        std::process::exit(2);
    };
    let data = match std::fs::read(&path) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("{path}: {e}");
            std::process::exit(2);
        }
    };
    let Some((&pick, rest)) = data.split_first() else {
        eprintln!("{path}: empty input (the target ignores it)");
        return;
    };
    let (base, needs_dir) = BASES[usize::from(pick) % BASES.len()];
    let src = mutate(base, rest);
    println!("{src}");
    eprintln!(
        "--- base file #{}; loading as {SOURCE} ...",
        usize::from(pick) % BASES.len()
    );
    let dir = if needs_dir {
        machines_dir().to_path_buf()
    } else {
        "/nonexistent".into()
    };
    match Machine::from_toml_str(&src, SOURCE, &dir) {
        Ok(m) => {
            for a in &m.axes {
                eprintln!("axis {}: accepted, model {:?}", a.name, a.true_model());
            }
        }
        Err(e) => eprintln!("error: {e}"),
    }
}
