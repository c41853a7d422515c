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
//! [`F4`] is `wide::f64x4` (a maintained portable SIMD crate: SSE2, AVX, NEON or plain arrays,
//! by target). The engine's lane loop is compiled for AVX2 and chosen at run time
//! (`crate::engine`), so that `wide`'s operations become single 256-bit instructions where the
//! processor has them.

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// Drives in one [`F4`].
pub(crate) const LANES: usize = 4;

/// Four drives' numbers, one per lane.
pub(crate) type F4 = wide::f64x4;

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pow2_of_rounded_is_two_to_the_n() {
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
