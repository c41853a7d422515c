//! The ChaCha8 key stream of `rand_chacha::ChaCha8Rng` (same seed, same stream number, the same
//! words in the same order), sixteen blocks at a time on AVX-512F where the processor has it.
//!
//! Why our own: the encoder noise of a realistic drive draws one 64-bit word per reading, at
//! every servo tick of every axis, and `rand_chacha` (through `ppv-lite86`) generates on AVX2 at
//! most: four blocks per call, rotations by shifts, and its output copied once more from the
//! generator's buffer into ours. That was a tenth of a realistic machine's simulation time
//! (docs/machine-file.md#cost). With AVX-512F the sixteen blocks of a call are computed side by
//! side, word $j$ of every block in one register (Bernstein's "vertical" layout), with the
//! native 32-bit rotation, and written straight into the caller's words. Without AVX-512F
//! `rand_chacha` itself generates. Either way the words are those of `ChaCha8Rng`
//! (test `same_words_as_rand_chacha`).
//!
//! ChaCha (Bernstein 2008, "ChaCha, a variant of Salsa20"): the state is four constant words,
//! the eight key words, a 64-bit block counter (words 12, 13) and the 64-bit stream number
//! (words 14, 15), all little-endian 32-bit words; a block is the state after four double
//! rounds (a column round, then a diagonal round, of quarter rounds
//! $a \mathrel{+}= b,\ d \mathrel{\oplus}= a,\ d \lll 16,\ c \mathrel{+}= d,\ b \mathrel{\oplus}= c,\ b \lll 12,\ a \mathrel{+}= b,\ d \mathrel{\oplus}= a,\ d \lll 8,\ c \mathrel{+}= d,\ b \mathrel{\oplus}= c,\ b \lll 7$)
//! plus the state it started from; the key stream is the blocks' words in order, counter
//! 0, 1, 2, …; a 64-bit word of the stream is two consecutive 32-bit words, the first the low
//! half (as `rand` fills a `[u64]`).

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// 64-bit words a call of [`Chacha8::fill`] writes: 16 blocks of 64 bytes.
pub(crate) const FILL_WORDS: usize = 128;

/// A ChaCha8 key stream, positioned at a block boundary.
#[derive(Clone)]
pub(crate) struct Chacha8 {
    /// The state's first twelve words (constants and key) and the stream number.
    key: [u32; 8],
    stream: u64,
    /// The next block's number.
    block: u64,
    /// Where the processor has no AVX-512F: `rand_chacha`'s own generator, at the same place.
    fallback: Option<ChaCha8Rng>,
}

const SIGMA: [u32; 4] = [0x6170_7865, 0x3320_646e, 0x7962_2d32, 0x6b20_6574];

impl Chacha8 {
    /// The stream of `ChaCha8Rng::seed_from_u64(seed)` with stream number `stream`.
    pub(crate) fn new(seed: u64, stream: u64) -> Chacha8 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        let bytes = rng.get_seed();
        let key = std::array::from_fn(|i| {
            u32::from_le_bytes([
                bytes[4 * i],
                bytes[4 * i + 1],
                bytes[4 * i + 2],
                bytes[4 * i + 3],
            ])
        });
        Chacha8 {
            key,
            stream,
            block: 0,
            fallback: (!wide_available()).then_some(rng),
        }
    }

    /// The next [`FILL_WORDS`] 64-bit words of the stream into `out`.
    #[inline]
    pub(crate) fn fill(&mut self, out: &mut [u64; FILL_WORDS]) {
        match &mut self.fallback {
            Some(rng) => rng.fill(&mut out[..]),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: no fallback only where AVX-512F is present (`new`).
            None => unsafe { self.fill_avx512(out) },
            #[cfg(not(target_arch = "x86_64"))]
            None => unreachable!("no wide generator off x86-64 (`wide_available`)"),
        }
        self.block = self.block.wrapping_add(16);
    }

    /// Sixteen blocks, block `self.block + i` in lane `i` of every register.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn fill_avx512(&self, out: &mut [u64; FILL_WORDS]) {
        use std::arch::x86_64::*;
        let lanes = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        let lo = _mm512_set1_epi32(self.block as u32 as i32);
        let ctr_lo = _mm512_add_epi32(lo, lanes);
        // The counter's high word gains the carry where the low word wrapped (unsigned
        // compare: ctr_lo < lo).
        let carry = _mm512_cmplt_epu32_mask(ctr_lo, lo);
        let hi = _mm512_set1_epi32((self.block >> 32) as u32 as i32);
        let ctr_hi = _mm512_mask_add_epi32(hi, carry, hi, _mm512_set1_epi32(1));
        let mut init = [_mm512_setzero_si512(); 16];
        for (j, s) in SIGMA.iter().enumerate() {
            init[j] = _mm512_set1_epi32(*s as i32);
        }
        for (j, k) in self.key.iter().enumerate() {
            init[4 + j] = _mm512_set1_epi32(*k as i32);
        }
        init[12] = ctr_lo;
        init[13] = ctr_hi;
        init[14] = _mm512_set1_epi32(self.stream as u32 as i32);
        init[15] = _mm512_set1_epi32((self.stream >> 32) as u32 as i32);
        let mut x = init;
        macro_rules! qr {
            ($a:expr, $b:expr, $c:expr, $d:expr) => {
                x[$a] = _mm512_add_epi32(x[$a], x[$b]);
                x[$d] = _mm512_rol_epi32::<16>(_mm512_xor_si512(x[$d], x[$a]));
                x[$c] = _mm512_add_epi32(x[$c], x[$d]);
                x[$b] = _mm512_rol_epi32::<12>(_mm512_xor_si512(x[$b], x[$c]));
                x[$a] = _mm512_add_epi32(x[$a], x[$b]);
                x[$d] = _mm512_rol_epi32::<8>(_mm512_xor_si512(x[$d], x[$a]));
                x[$c] = _mm512_add_epi32(x[$c], x[$d]);
                x[$b] = _mm512_rol_epi32::<7>(_mm512_xor_si512(x[$b], x[$c]));
            };
        }
        // ChaCha8: four double rounds.
        for _ in 0..4 {
            qr!(0, 4, 8, 12);
            qr!(1, 5, 9, 13);
            qr!(2, 6, 10, 14);
            qr!(3, 7, 11, 15);
            qr!(0, 5, 10, 15);
            qr!(1, 6, 11, 12);
            qr!(2, 7, 8, 13);
            qr!(3, 4, 9, 14);
        }
        for (xj, ij) in x.iter_mut().zip(&init) {
            *xj = _mm512_add_epi32(*xj, *ij);
        }
        // Transpose the 16 × 16 words: register j holds word j of blocks 0..16; the output
        // wants block i's sixteen words together (row i), in block order.
        // Stage 1: interleave 32-bit words of register pairs (j, j+1).
        let mut t = [_mm512_setzero_si512(); 16];
        for p in 0..8 {
            t[2 * p] = _mm512_unpacklo_epi32(x[2 * p], x[2 * p + 1]);
            t[2 * p + 1] = _mm512_unpackhi_epi32(x[2 * p], x[2 * p + 1]);
        }
        // Stage 2: interleave 64-bit pairs of (t[4q + r], t[4q + r + 2]).
        let mut u = [_mm512_setzero_si512(); 16];
        for q in 0..4 {
            for r in 0..2 {
                let (a, b) = (t[4 * q + r], t[4 * q + r + 2]);
                u[4 * q + 2 * r] = _mm512_unpacklo_epi64(a, b);
                u[4 * q + 2 * r + 1] = _mm512_unpackhi_epi64(a, b);
            }
        }
        // Now lane L of u[4q + s] holds the four words 4q..4q+4 of block 4L + s. Stages 3
        // and 4: gather the 128-bit pieces (see `row_of_block`).
        let mut v = [_mm512_setzero_si512(); 16];
        for s in 0..4 {
            // Pieces (lanes 0, 2 | 1, 3) of q = 0,1 and of q = 2,3.
            let a01 = _mm512_shuffle_i32x4::<0b10_00_10_00>(u[s], u[4 + s]);
            let b01 = _mm512_shuffle_i32x4::<0b11_01_11_01>(u[s], u[4 + s]);
            let a23 = _mm512_shuffle_i32x4::<0b10_00_10_00>(u[8 + s], u[12 + s]);
            let b23 = _mm512_shuffle_i32x4::<0b11_01_11_01>(u[8 + s], u[12 + s]);
            v[4 * s] = _mm512_shuffle_i32x4::<0b10_00_10_00>(a01, a23);
            v[4 * s + 1] = _mm512_shuffle_i32x4::<0b10_00_10_00>(b01, b23);
            v[4 * s + 2] = _mm512_shuffle_i32x4::<0b11_01_11_01>(a01, a23);
            v[4 * s + 3] = _mm512_shuffle_i32x4::<0b11_01_11_01>(b01, b23);
        }
        // v[4s + m] is block 4m + s.
        const ROW: [usize; 16] = row_of_block();
        for (b, r) in ROW.iter().enumerate() {
            // SAFETY: `out` holds 16 blocks of 64 bytes; block b's bytes at 64 b.
            unsafe { _mm512_storeu_si512(out.as_mut_ptr().add(8 * b).cast(), v[*r]) };
        }
    }
}

/// The register of [`Chacha8::fill_avx512`]'s `v` that holds block `b` (checked by test
/// `same_words_as_rand_chacha`).
///
/// Stage 1 interleaves within 128-bit lanes: `t[2p]` holds, in lane L, words (2p, 2p+1) of
/// blocks 4L and 4L+1; `t[2p+1]` of blocks 4L+2 and 4L+3. Stage 2: `u[4q + 2r]` holds in lane
/// L words 4q..4q+4 of block 4L + 2r, `u[4q + 2r + 1]` of block 4L + 2r + 1; so `u[4q + s]`
/// holds block 4L + s in lane L. Stage 3: `a01` = lanes 0, 2 of `u[s]` then of `u[4+s]`,
/// `b01` lanes 1, 3 (likewise `a23`, `b23` from `u[8+s]`, `u[12+s]`). Stage 4: `v[4s]` takes
/// the first lanes of `a01` and `a23` (lane 0 of every `u`: block s), `v[4s+1]` of `b01`,
/// `b23` (block 4 + s), `v[4s+2]` and `v[4s+3]` their second lanes (blocks 8 + s, 12 + s).
/// So `v[4s + m]` holds block 4m + s.
const fn row_of_block() -> [usize; 16] {
    let mut row = [0; 16];
    let mut b = 0;
    while b < 16 {
        let (m, s) = (b / 4, b % 4);
        row[b] = 4 * s + m;
        b += 1;
    }
    row
}

/// Whether [`Chacha8`] generates on AVX-512F here.
fn wide_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `calls` fills of both generators, compared word for word.
    fn assert_same_words(ours: &mut Chacha8, theirs: &mut ChaCha8Rng, calls: usize, what: &str) {
        for call in 0..calls {
            let mut a = [0u64; FILL_WORDS];
            let mut b = [0u64; FILL_WORDS];
            ours.fill(&mut a);
            theirs.fill(&mut b[..]);
            assert_eq!(a, b, "{what}, call {call}");
        }
    }

    #[test]
    fn same_words_as_rand_chacha() {
        // Truth: `rand_chacha::ChaCha8Rng` (the reference implementation this crate used
        // before), its words filled into a `[u64]` as `rand` fills them; several seeds and
        // stream numbers, 40 calls (640 blocks) each, and a counter about to carry into its
        // high word.
        for (seed, stream) in [(0u64, 0u64), (11, 0), (12, 1), (u64::MAX, 7), (3, u64::MAX)] {
            let mut theirs = ChaCha8Rng::seed_from_u64(seed);
            theirs.set_stream(stream);
            let what = format!("seed {seed}, stream {stream}");
            assert_same_words(&mut Chacha8::new(seed, stream), &mut theirs, 40, &what);
        }
        let mut ours = Chacha8::new(5, 2);
        let mut theirs = ChaCha8Rng::seed_from_u64(5);
        theirs.set_stream(2);
        let start = (1u64 << 32) - 24;
        ours.block = start;
        theirs.set_word_pos(u128::from(start) * 16);
        assert_same_words(&mut ours, &mut theirs, 4, "across the counter's carry");
    }
}
