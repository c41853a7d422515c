//! The number type of the drive engine: one `f64` (one drive), or [`F4`], four `f64` side by
//! side in a SIMD register (four drives, one per lane; docs/machine-file.md#cost).
//!
//! The engine is written once over [`Lane`]. A lane performs, in the same order, the same IEEE
//! operations as the scalar engine does for its drive alone (no fused multiply-add: Rust never
//! contracts `a * b + c`), so each lane's results are the scalar engine's bit for bit. What the
//! scalar engine decides with a branch, lanes decide with a [`Lane::select`] between the
//! branches' values, each computed as the scalar branch computes it; the engine skips a branch
//! that no lane takes ([`Lane::any`], [`Lane::all`]), which for one `f64` is the branch itself.
//!
//! [`F4`] on x86-64 is this file's own type over AVX registers (`__m256d`), used only where the
//! processor has AVX2 ([`available`]; the engine's lane loop is compiled for AVX2 and chosen at
//! run time, `crate::engine`). Elsewhere it is `wide::f64x4` (a maintained portable SIMD crate:
//! NEON, SIMD128 or plain arrays, by target).
//!
//! Why not `wide` on x86-64 too: `wide` picks its instructions when the crate is compiled
//! (`cfg(target_feature = "avx")`), so in a build for the x86-64 baseline every `f64x4`
//! operation is two SSE2 operations on halves, and a `select` three (no `blendv` before
//! SSE4.1), however the calling function is compiled. The `drive` benchmark measured it
//! (`cargo bench -p vcnc-drive --bench drive`, 2-core AVX-512 Xeon VM, criterion means): with
//! `wide::f64x4` the five realistic NMV5000 axes in `simulate_batch` took 162.8 ms and the
//! 4-lane loop 116.1 ms; with this type 124.8 ms and 76.9–78.2 ms, against 115.4–115.6 and
//! 71.2–71.8 ms for the hand-written AVX-512 loop it replaced, run alternately (issue 27's
//! note). `wide::f64x4` with the same inlining fixes (`crate::engine`) stayed at 161.0 and
//! 115.5 ms. The type is small: each operation is one AVX instruction.

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// Drives in one [`F4`].
pub(crate) const LANES: usize = 4;

/// Four drives' numbers, one per lane.
#[cfg(target_arch = "x86_64")]
pub(crate) use avx::F4;
/// Four drives' numbers, one per lane.
#[cfg(not(target_arch = "x86_64"))]
pub(crate) type F4 = wide::f64x4;

/// Whether this processor runs lanes: everywhere but on an x86-64 without AVX2 (there the
/// drives run one at a time, with the same results). No [`F4`] is made where it is false.
pub(crate) fn available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        true
    }
}

/// The arithmetic the engine needs, on one drive (`f64`) or on [`LANES`] drives ([`F4`]).
pub(crate) trait Lane:
    Copy
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// A condition per lane (`bool` for one drive).
    type Mask: Copy
        + Send
        + Sync
        + BitAnd<Output = Self::Mask>
        + BitOr<Output = Self::Mask>
        + Not<Output = Self::Mask>;
    /// Drives side by side.
    const WIDTH: usize;
    /// Every lane `v`.
    fn splat(v: f64) -> Self;
    /// Lane `l` is `f(l)`.
    fn from_fn(f: impl FnMut(usize) -> f64) -> Self;
    /// Lane `l`.
    fn at(self, l: usize) -> f64;
    /// `self < o` per lane (false with a NaN, as Rust's `<`); and so on.
    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    fn eq(self, o: Self) -> Self::Mask;
    /// `f64::abs` (the sign bit cleared).
    fn abs(self) -> Self;
    /// `if m { a } else { b }` per lane.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// `self` in the lanes of `m`, else +0.
    fn masked(self, m: Self::Mask) -> Self;
    /// `f64::clamp` per lane (bounds ordered).
    fn clamp(self, lo: Self, hi: Self) -> Self;
    /// Some lane's condition holds.
    fn any(m: Self::Mask) -> bool;
    /// Every lane's condition holds.
    fn all(m: Self::Mask) -> bool;
    /// Lane `l`'s condition.
    fn test(m: Self::Mask, l: usize) -> bool;
    /// Lane `l`'s condition is `f(l)`.
    fn mask_from_fn(f: impl FnMut(usize) -> bool) -> Self::Mask;
    /// $2^n$ for `t` $= R + n$ exactly, $R = 1.5 \cdot 2^{52}$ (`n` in the low bits of `t`, as
    /// the rounding of [`crate::effects::exp_neg`] leaves it), $|n| < 1023$.
    fn pow2_of_rounded(t: Self) -> Self;
}

impl Lane for f64 {
    type Mask = bool;
    const WIDTH: usize = 1;
    #[inline(always)]
    fn splat(v: f64) -> f64 {
        v
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f64) -> f64 {
        f(0)
    }
    #[inline(always)]
    fn at(self, _l: usize) -> f64 {
        self
    }
    #[inline(always)]
    fn lt(self, o: f64) -> bool {
        self < o
    }
    #[inline(always)]
    fn le(self, o: f64) -> bool {
        self <= o
    }
    #[inline(always)]
    fn gt(self, o: f64) -> bool {
        self > o
    }
    #[inline(always)]
    fn ge(self, o: f64) -> bool {
        self >= o
    }
    #[inline(always)]
    fn eq(self, o: f64) -> bool {
        self == o
    }
    #[inline(always)]
    fn abs(self) -> f64 {
        f64::abs(self)
    }
    #[inline(always)]
    fn select(m: bool, a: f64, b: f64) -> f64 {
        if m { a } else { b }
    }
    #[inline(always)]
    fn masked(self, m: bool) -> f64 {
        if m { self } else { 0.0 }
    }
    #[inline(always)]
    fn clamp(self, lo: f64, hi: f64) -> f64 {
        f64::clamp(self, lo, hi)
    }
    #[inline(always)]
    fn any(m: bool) -> bool {
        m
    }
    #[inline(always)]
    fn all(m: bool) -> bool {
        m
    }
    #[inline(always)]
    fn test(m: bool, _l: usize) -> bool {
        m
    }
    #[inline(always)]
    fn mask_from_fn(mut f: impl FnMut(usize) -> bool) -> bool {
        f(0)
    }
    #[inline(always)]
    fn pow2_of_rounded(t: f64) -> f64 {
        let k = t.to_bits() as i64 - ROUND_BITS as i64;
        f64::from_bits(((k + 1023) as u64) << 52)
    }
}

/// The bits of $1.5 \cdot 2^{52}$.
const ROUND_BITS: u64 = 6_755_399_441_055_744.0f64.to_bits();

#[cfg(not(target_arch = "x86_64"))]
impl Lane for F4 {
    /// All bits set (true) or none (false) per lane, as a vector comparison leaves them.
    type Mask = F4;
    const WIDTH: usize = LANES;
    #[inline(always)]
    fn splat(v: f64) -> F4 {
        F4::splat(v)
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f64) -> F4 {
        F4::new(std::array::from_fn(f))
    }
    #[inline(always)]
    fn at(self, l: usize) -> f64 {
        self.as_array()[l]
    }
    #[inline(always)]
    fn lt(self, o: F4) -> F4 {
        self.simd_lt(o)
    }
    #[inline(always)]
    fn le(self, o: F4) -> F4 {
        self.simd_le(o)
    }
    #[inline(always)]
    fn gt(self, o: F4) -> F4 {
        self.simd_gt(o)
    }
    #[inline(always)]
    fn ge(self, o: F4) -> F4 {
        self.simd_ge(o)
    }
    #[inline(always)]
    fn eq(self, o: F4) -> F4 {
        self.simd_eq(o)
    }
    #[inline(always)]
    fn abs(self) -> F4 {
        F4::abs(self)
    }
    #[inline(always)]
    fn select(m: F4, a: F4, b: F4) -> F4 {
        m.select(a, b)
    }
    #[inline(always)]
    fn masked(self, m: F4) -> F4 {
        self & m
    }
    #[inline(always)]
    fn clamp(self, lo: F4, hi: F4) -> F4 {
        let x = Lane::select(self.simd_lt(lo), lo, self);
        Lane::select(x.simd_gt(hi), hi, x)
    }
    #[inline(always)]
    fn any(m: F4) -> bool {
        m.any()
    }
    #[inline(always)]
    fn all(m: F4) -> bool {
        m.all()
    }
    #[inline(always)]
    fn test(m: F4, l: usize) -> bool {
        m.as_array()[l].to_bits() != 0
    }
    #[inline(always)]
    fn mask_from_fn(mut f: impl FnMut(usize) -> bool) -> F4 {
        let all = f64::from_bits(u64::MAX);
        F4::new(std::array::from_fn(|l| if f(l) { all } else { 0.0 }))
    }
    #[inline(always)]
    fn pow2_of_rounded(t: F4) -> F4 {
        let k = t.to_bits() - wide::u64x4::splat(ROUND_BITS);
        F4::from_bits((k + wide::u64x4::splat(1023)) << 52u32)
    }
}

/// [`F4`] on x86-64: four `f64` in an AVX register, each operation one AVX (AVX2 for the
/// integer shifts of [`Lane::pow2_of_rounded`]) instruction with the IEEE result of the scalar
/// operation in each lane.
#[cfg(target_arch = "x86_64")]
mod avx {
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

    use super::{LANES, Lane, ROUND_BITS};

    /// Four drives' numbers, one per lane; as a mask, all bits set (true) or none (false) per
    /// lane, as a vector comparison leaves them.
    ///
    /// Every method runs AVX or AVX2 instructions. SAFETY, for the whole module: an `F4` is
    /// made only by a run on lanes, which the engine makes only where [`super::available`]
    /// (AVX2 present), and by tests that check it first; the type is private to the crate.
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub(crate) struct F4(__m256d);

    impl F4 {
        /// The four lanes.
        #[inline(always)]
        pub(crate) fn to_array(self) -> [f64; LANES] {
            // SAFETY: `__m256d` and `[f64; 4]` have one size and every bit pattern is valid.
            unsafe { std::mem::transmute::<__m256d, [f64; LANES]>(self.0) }
        }
        #[inline(always)]
        fn new(v: [f64; LANES]) -> F4 {
            // SAFETY: as in `to_array`.
            F4(unsafe { std::mem::transmute::<[f64; LANES], __m256d>(v) })
        }
    }

    /// The AVX binary operators.
    macro_rules! binary {
        ($($tr:ident $f:ident $op:ident;)*) => {$(
            impl $tr for F4 {
                type Output = F4;
                #[inline(always)]
                fn $f(self, o: F4) -> F4 {
                    // SAFETY: module documentation.
                    F4(unsafe { $op(self.0, o.0) })
                }
            }
        )*};
    }
    binary! {
        Add add _mm256_add_pd;
        Sub sub _mm256_sub_pd;
        Mul mul _mm256_mul_pd;
        Div div _mm256_div_pd;
        BitAnd bitand _mm256_and_pd;
        BitOr bitor _mm256_or_pd;
    }

    impl Neg for F4 {
        type Output = F4;
        /// The sign bit flipped, as `-x` does (−0 for +0).
        #[inline(always)]
        fn neg(self) -> F4 {
            // SAFETY: module documentation.
            F4(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
        }
    }

    impl Not for F4 {
        type Output = F4;
        /// Every bit flipped (a mask's negation).
        #[inline(always)]
        fn not(self) -> F4 {
            // SAFETY: module documentation.
            F4(unsafe { _mm256_xor_pd(self.0, _mm256_castsi256_pd(_mm256_set1_epi64x(-1))) })
        }
    }

    /// A comparison by the AVX predicate `P` (ordered, quiet: false with a NaN, as Rust's).
    #[inline(always)]
    fn cmp<const P: i32>(a: F4, b: F4) -> F4 {
        // SAFETY: module documentation.
        F4(unsafe { _mm256_cmp_pd::<P>(a.0, b.0) })
    }

    impl Lane for F4 {
        type Mask = F4;
        const WIDTH: usize = LANES;
        #[inline(always)]
        fn splat(v: f64) -> F4 {
            // SAFETY: module documentation.
            F4(unsafe { _mm256_set1_pd(v) })
        }
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> f64) -> F4 {
            // Not `std::array::from_fn`: its closure was left out of line in the AVX2 loop
            // (23 % of the lane loop's instructions, callgrind).
            F4::new([f(0), f(1), f(2), f(3)])
        }
        #[inline(always)]
        fn at(self, l: usize) -> f64 {
            self.to_array()[l]
        }
        #[inline(always)]
        fn lt(self, o: F4) -> F4 {
            cmp::<_CMP_LT_OQ>(self, o)
        }
        #[inline(always)]
        fn le(self, o: F4) -> F4 {
            cmp::<_CMP_LE_OQ>(self, o)
        }
        #[inline(always)]
        fn gt(self, o: F4) -> F4 {
            cmp::<_CMP_GT_OQ>(self, o)
        }
        #[inline(always)]
        fn ge(self, o: F4) -> F4 {
            cmp::<_CMP_GE_OQ>(self, o)
        }
        #[inline(always)]
        fn eq(self, o: F4) -> F4 {
            cmp::<_CMP_EQ_OQ>(self, o)
        }
        #[inline(always)]
        fn abs(self) -> F4 {
            // SAFETY: module documentation.
            F4(unsafe { _mm256_andnot_pd(_mm256_set1_pd(-0.0), self.0) })
        }
        #[inline(always)]
        fn select(m: F4, a: F4, b: F4) -> F4 {
            // `blendv` takes the second operand where the mask's sign bit is set.
            // SAFETY: module documentation.
            F4(unsafe { _mm256_blendv_pd(b.0, a.0, m.0) })
        }
        #[inline(always)]
        fn masked(self, m: F4) -> F4 {
            self & m
        }
        #[inline(always)]
        fn clamp(self, lo: F4, hi: F4) -> F4 {
            let x = Lane::select(Lane::lt(self, lo), lo, self);
            Lane::select(Lane::gt(x, hi), hi, x)
        }
        #[inline(always)]
        fn any(m: F4) -> bool {
            // SAFETY: module documentation.
            unsafe { _mm256_movemask_pd(m.0) != 0 }
        }
        #[inline(always)]
        fn all(m: F4) -> bool {
            // SAFETY: module documentation.
            unsafe { _mm256_movemask_pd(m.0) == 0b1111 }
        }
        #[inline(always)]
        fn test(m: F4, l: usize) -> bool {
            m.at(l).to_bits() != 0
        }
        #[inline(always)]
        fn mask_from_fn(mut f: impl FnMut(usize) -> bool) -> F4 {
            let all = f64::from_bits(u64::MAX);
            <F4 as Lane>::from_fn(|l| if f(l) { all } else { 0.0 })
        }
        #[inline(always)]
        fn pow2_of_rounded(t: F4) -> F4 {
            // SAFETY: module documentation.
            unsafe {
                let k = _mm256_sub_epi64(
                    _mm256_castpd_si256(t.0),
                    _mm256_set1_epi64x(ROUND_BITS as i64),
                );
                let e = _mm256_slli_epi64::<52>(_mm256_add_epi64(k, _mm256_set1_epi64x(1023)));
                F4(_mm256_castsi256_pd(e))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pow2_of_rounded_is_two_to_the_n() {
        if !crate::lane::available() {
            eprintln!("skipped: no AVX2 on this processor, so no lanes");
            return;
        }
        // Truth: 2^n by powi, for every exponent exp_neg produces and some beyond.
        for n in -1022i32..=1022 {
            let t = 6_755_399_441_055_744.0 + n as f64;
            assert_eq!(<f64 as Lane>::pow2_of_rounded(t), 2f64.powi(n), "n = {n}");
            let v = <F4 as Lane>::pow2_of_rounded(F4::splat(t));
            assert_eq!(v.to_array(), [2f64.powi(n); LANES], "n = {n}");
        }
    }

    #[test]
    fn lanes_compare_select_and_clamp_as_scalars_do() {
        if !crate::lane::available() {
            eprintln!("skipped: no AVX2 on this processor, so no lanes");
            return;
        }
        // Truth: the scalar operations, lane by lane, on values with signed zeros, NaN and
        // infinities.
        let xs = [
            -0.0,
            0.0,
            1.5,
            -2.25,
            f64::NAN,
            f64::INFINITY,
            -f64::INFINITY,
            3e-310,
        ];
        for a in xs {
            for b in xs {
                let (fa, fb) = (F4::splat(a), F4::from_fn(|l| if l == 2 { a } else { b }));
                for (m, s) in [
                    (Lane::lt(fa, fb), a < b),
                    (Lane::le(fa, fb), a <= b),
                    (Lane::gt(fa, fb), a > b),
                    (Lane::ge(fa, fb), a >= b),
                    (Lane::eq(fa, fb), a == b),
                ] {
                    assert_eq!(<F4 as Lane>::test(m, 0), s, "{a} {b}");
                }
                let sel = <F4 as Lane>::select(Lane::lt(fa, fb), fa, fb).at(1);
                assert_eq!(sel.to_bits(), (if a < b { a } else { b }).to_bits());
                assert_eq!(Lane::abs(fa).at(3).to_bits(), a.abs().to_bits());
                assert_eq!(
                    fa.masked(Lane::gt(fa, fb)).at(0).to_bits(),
                    (if a > b { a } else { 0.0 }).to_bits()
                );
                if !a.is_nan() && !b.is_nan() {
                    let (lo, hi) = (a.min(b), a.max(b));
                    for x in xs.iter().filter(|x| !x.is_nan()) {
                        let c = Lane::clamp(F4::splat(*x), F4::splat(lo), F4::splat(hi));
                        assert_eq!(c.at(0).to_bits(), x.clamp(lo, hi).to_bits());
                    }
                }
            }
        }
    }
}
