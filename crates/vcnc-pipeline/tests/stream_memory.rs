//! The streamed prediction holds bounded memory (docs/performance.md, "Streaming"): the heap's
//! peak while a program file is predicted streamed does not grow with the program's length.
//!
//! The truth is the heap itself: this test binary counts every allocation (a global allocator
//! that wraps the system's and keeps the bytes live and their peak), so it measures what the
//! route holds, not what the system's allocator keeps around. Two generated 5-axis TCP programs
//! of the same kind, one four times as long as the other (about 150 000 and 600 000 samples),
//! are predicted streamed from files with the true drives as models; the peaks must agree
//! within 10 %. A route that kept every sample (as a whole run does) would hold four times as
//! much for the longer program.
//!
//! Both programs must be longer than every bounded buffer the route keeps. The parsed source is
//! one: the reader caches parsed pieces of up to three times its piece size of text (1 MiB by
//! default, so a program's parse trees grow with it up to about 4 MiB of G-code, some 70 000
//! lines of this kind). The test reads the source in pieces of 32 KiB (the results do not
//! depend on the piece sizes, `tests/route.rs`), so that both programs are past that bound
//! without a test minutes long; the other buffers (contour histories, the drives' and models'
//! states, the pieces of samples) have their default sizes.
//!
//! Its own test binary: the counting allocator sees every thread of the process, so nothing
//! else may run beside the measurement.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use vcnc_machine::{Machine, MachineModels};
use vcnc_pipeline::predict::{self, PredictOptions};
use vcnc_pipeline::sink::Discard;
use vcnc_pipeline::source::{self, Program};
use vcnc_pipeline::{Source, programs};

/// Source read per piece, bytes: small, so that both programs pass the parse cache's bound.
const CHUNK_BYTES: usize = 1 << 15;

/// The system allocator, counting the bytes live and their peak.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(bytes: usize) {
    let now = LIVE.fetch_add(bytes, Relaxed) + bytes;
    PEAK.fetch_max(now, Relaxed);
}

// SAFETY: every call is forwarded to `System` with the caller's arguments; the counters are
// only bookkeeping.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller upholds `alloc`'s contract, which `System.alloc` shares.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by this allocator (so by `System`) with `layout`.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: `ptr` was allocated by `System` with `layout`; the caller upholds the rest.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            grew(new_size);
            LIVE.fetch_sub(layout.size(), Relaxed);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Peak heap bytes above the bytes live before, while `program` is predicted streamed.
fn streamed_peak(machine: &Machine, models: &MachineModels, path: &std::path::Path) -> usize {
    let before = LIVE.load(Relaxed);
    PEAK.store(before, Relaxed);
    let opts = vcnc_gcode::StreamOptions {
        chunk_bytes: CHUNK_BYTES,
        chunk_samples: source::PIECE_SAMPLES,
    };
    let plan = source::plan_pieces(machine, Program::File(path.to_path_buf()), false, &opts)
        .expect("the generated program streams");
    let outcome = predict::predict(
        machine,
        Source::Streamed(&plan),
        &[models],
        &PredictOptions::default(),
        &mut Discard,
    )
    .expect("the generated program is predicted");
    assert!(outcome.summaries.iter().all(|s| s.samples > 100_000));
    drop(plan);
    PEAK.load(Relaxed) - before
}

#[test]
fn a_streamed_prediction_holds_the_same_peak_for_a_program_four_times_as_long() {
    let machine = Machine::embedded_nmv5000().expect("the embedded machine loads");
    let models = common::models(&machine, false);
    let dir = tempfile::tempdir().expect("a temporary folder");
    let mut peaks = Vec::new();
    for segments in [3_000, 12_000] {
        let text = programs::long_tcp_program(segments, 0.5, 0.05, 428).expect("a program");
        let path = dir.path().join(format!("long{segments}.ngc"));
        std::fs::write(&path, &text).expect("the program is written");
        drop(text);
        let peak = streamed_peak(&machine, &models, &path);
        println!("{segments} segments: streamed prediction peak {peak} heap bytes");
        peaks.push(peak as f64);
    }
    let ratio = peaks[1] / peaks[0];
    assert!(
        (ratio - 1.0).abs() <= 0.10,
        "peak heap {} -> {} bytes for a program 4x as long (ratio {ratio:.3}): the streamed route \
         holds memory that grows with the program",
        peaks[0],
        peaks[1]
    );
}
