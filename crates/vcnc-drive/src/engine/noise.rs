//! The readings of a drive's position sensors: quantisation ([`Quant`]) and seeded Gaussian
//! noise ([`Noise`]), one noise stream per sensor.
//!
//! The ideal drive's encoder draws its normal numbers by the Box–Muller method from
//! `rand_chacha::ChaCha8Rng` through `rand`'s uniform `f64` ([`BoxMuller`]), as it always has; a
//! drive with effects draws them from the same generator's words by the ziggurat method
//! ([`Normals`]), one stream number per sensor. Each stream depends on its seed alone, so the
//! engine draws a block of ticks' noise ahead of the ticks (`crate::engine`).
//!
//! # Ziggurat
//!
//! The ziggurat method of Marsaglia and Tsang (2000, *J. Statistical Software* 5(8)), 256 layers,
//! on 64-bit words of `ChaCha8Rng` filled in blocks of 128 (`rand`'s `fill` of a `[u64]`).
//! Why not `rand_distr::StandardNormal`: it draws one word at a time through the generic `Rng`
//! interface, about 55 instructions per number; the encoder is read at every servo tick
//! (20 000 per simulated second), where that was the largest single cost of a realistic drive.
//! The same algorithm on words filled in bulk costs about a quarter.
//!
//! Word use: the low 8 bits pick the layer $i$, the high 52 bits make $u \in [-1, 1)$; the
//! candidate is $x = u\,x_i$, accepted at once when $|x| < x_{i+1}$ (about 99 % of draws), else
//! by the wedge test $f_{i+1} + (f_i - f_{i+1})\,U < e^{-x^2/2}$, or from the tail beyond
//! $r = x_1$ by Marsaglia's (1964) method when $i = 0$.

use std::sync::OnceLock;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::lane::Lane;

/// $q\,\mathrm{round}(x/q)$ (ties to even), or $x$ when $q = 0$ (`inv_q` = $1/q$).
#[inline(always)]
pub(crate) fn quantise_to(x: f64, q: f64, inv_q: f64) -> f64 {
    if q > 0.0 {
        let y = x * inv_q;
        let n = if y.abs() < MAGIC_LIMIT {
            (y + MAGIC) - MAGIC
        } else {
            y.round()
        };
        n * q
    } else {
        x
    }
}

/// $1.5 \cdot 2^{52}$: adding and subtracting it rounds to an integer (ties to even) for
/// $|y| < 2^{51}$ ([`MAGIC_LIMIT`]), without a libm call.
const MAGIC: f64 = 6_755_399_441_055_744.0;
const MAGIC_LIMIT: f64 = 2_251_799_813_685_248.0;

/// A sensor's quantisation step $q$ (0: none), per lane.
#[derive(Clone, Copy)]
pub(crate) struct Quant<T: Lane> {
    q: T,
    inv_q: T,
    /// `q > 0`.
    on: T::Mask,
}

impl Quant<f64> {
    /// Quantisation to `q` (0: none).
    pub(crate) fn new(q: f64) -> Quant<f64> {
        Quant {
            q,
            inv_q: if q > 0.0 { 1.0 / q } else { 0.0 },
            on: q > 0.0,
        }
    }
}

impl<T: Lane> Quant<T> {
    /// Lane `l` quantises as `quants[l]` (the last one in the lanes beyond).
    pub(crate) fn gather(quants: &[&Quant<f64>]) -> Quant<T> {
        let pick = |l: usize| quants[l.min(quants.len() - 1)];
        Quant {
            q: T::from_fn(|l| pick(l).q),
            inv_q: T::from_fn(|l| pick(l).inv_q),
            on: T::mask_from_fn(|l| pick(l).on),
        }
    }

    /// The reading of position `x` with `noise`: [`quantise_to`]`(x + noise)` per lane.
    #[inline(always)]
    pub(crate) fn read(&self, x: T, noise: T) -> T {
        let x = x + noise;
        let y = x * self.inv_q;
        if T::all(y.abs().lt(T::splat(MAGIC_LIMIT)) | !self.on) {
            let n = (y + T::splat(MAGIC)) - T::splat(MAGIC);
            T::select(self.on, n * self.q, x)
        } else {
            T::from_fn(|l| quantise_to(x.at(l), self.q.at(l), self.inv_q.at(l)))
        }
    }
}

/// The noise of one sensor's readings, axis units: a stream of $\sigma n$, $n$ standard normal.
#[derive(Clone)]
pub(crate) enum Noise {
    /// No noise: every reading adds this number (+0 for a drive with effects, which always
    /// added its noise; −0 for the ideal drive, whose quiet reading is the position itself:
    /// $x + (-0) = x$ for every $x$).
    Quiet(f64),
    /// $\sigma$ and the ziggurat's normal numbers (drives with effects).
    Ziggurat(f64, Normals),
    /// The ideal drive's encoder.
    BoxMuller(BoxMuller),
}

impl Noise {
    /// The noise of a drive with effects' sensor: $\sigma$ = `std` (0: none), stream `stream`
    /// of `seed`.
    pub(crate) fn ziggurat(std: f64, seed: u64, stream: u64) -> Noise {
        if std > 0.0 {
            Noise::Ziggurat(std, Normals::new(seed, stream))
        } else {
            Noise::Quiet(0.0)
        }
    }

    /// The ideal drive's encoder noise: $\sigma$ = `std` (0: none) from `seed`.
    pub(crate) fn box_muller(std: f64, seed: u64) -> Noise {
        if std > 0.0 {
            Noise::BoxMuller(BoxMuller {
                std,
                rng: ChaCha8Rng::seed_from_u64(seed),
                spare: None,
            })
        } else {
            Noise::Quiet(-0.0)
        }
    }

    /// Whether the readings draw from a generator.
    pub(crate) fn is_noisy(&self) -> bool {
        !matches!(self, Noise::Quiet(_))
    }

    /// The next reading's noise.
    #[inline(always)]
    pub(crate) fn draw(&mut self) -> f64 {
        match self {
            Noise::Quiet(v) => *v,
            Noise::Ziggurat(std, n) => *std * n.sample(),
            Noise::BoxMuller(b) => b.std * b.gaussian(),
        }
    }
}

/// Normal numbers by the Box–Muller method from `ChaCha8Rng`'s uniform `f64`s, in pairs.
#[derive(Clone)]
pub(crate) struct BoxMuller {
    std: f64,
    rng: ChaCha8Rng,
    spare: Option<f64>,
}

impl BoxMuller {
    #[inline(never)]
    fn gaussian(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        // u1 in (0, 1] so the log is finite.
        let u1 = 1.0 - self.rng.random::<f64>();
        let u2 = self.rng.random::<f64>();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        self.spare = Some(r * s);
        r * c
    }
}

/// $x_1 = r$, the start of the tail (256 layers).
const R: f64 = 3.654_152_885_361_009;
/// Area of every layer, $v$.
const V: f64 = 4.928_673_233_99e-3;
/// Words per block.
const BLOCK: usize = 128;

/// Layer edges $x_0 > x_1 = r > \dots > x_{256} = 0$ and $f_i = e^{-x_i^2/2}$.
struct Tables {
    x: [f64; 257],
    f: [f64; 257],
}

fn pdf(x: f64) -> f64 {
    (-0.5 * x * x).exp()
}

fn tables() -> &'static Tables {
    static T: OnceLock<Tables> = OnceLock::new();
    T.get_or_init(|| {
        let mut x = [0.0; 257];
        // The base layer: the rectangle [0, x_0] × [0, f(r)] has the area v of every layer.
        x[0] = V / pdf(R);
        x[1] = R;
        for i in 1..255 {
            // Layer i spans [x_{i+1}, x_i] under f: x_i (f(x_{i+1}) - f(x_i)) = v.
            x[i + 1] = (-2.0 * (V / x[i] + pdf(x[i])).ln()).sqrt();
        }
        x[256] = 0.0;
        let mut f = [0.0; 257];
        for (fi, xi) in f.iter_mut().zip(&x) {
            *fi = pdf(*xi);
        }
        Tables { x, f }
    })
}

/// A stream of standard normal numbers.
#[derive(Clone)]
pub(crate) struct Normals {
    rng: ChaCha8Rng,
    words: Box<[u64; BLOCK]>,
    next: usize,
    t: &'static Tables,
}

impl Normals {
    /// The stream of `seed` (ChaCha8, stream number `stream`).
    pub(crate) fn new(seed: u64, stream: u64) -> Normals {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        Normals {
            rng,
            words: Box::new([0; BLOCK]),
            next: BLOCK,
            t: tables(),
        }
    }

    #[inline(always)]
    fn word(&mut self) -> u64 {
        if self.next == BLOCK {
            self.refill();
        }
        let w = self.words[self.next];
        self.next += 1;
        w
    }

    #[inline(never)]
    fn refill(&mut self) {
        self.rng.fill(&mut self.words[..]);
        self.next = 0;
    }

    /// Uniform in [0, 1) from the high 53 bits of a word.
    #[inline(always)]
    fn uniform(&mut self) -> f64 {
        (self.word() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// One standard normal number.
    #[inline(always)]
    pub(crate) fn sample(&mut self) -> f64 {
        loop {
            let bits = self.word();
            let i = (bits & 0xff) as usize;
            // 52 high bits as a mantissa in [2, 4), minus 3: u in [-1, 1).
            let u = f64::from_bits((bits >> 12) | 0x4000_0000_0000_0000) - 3.0;
            let x = u * self.t.x[i];
            if x.abs() < self.t.x[i + 1] {
                return x;
            }
            if let Some(x) = self.slow(i, u, x) {
                return x;
            }
        }
    }

    /// The rare draws: tail or wedge.
    #[inline(never)]
    fn slow(&mut self, i: usize, u: f64, x: f64) -> Option<f64> {
        if i == 0 {
            // Tail beyond r (Marsaglia 1964): x = -ln(U1)/r, y = -ln(U2), accept if 2y > x².
            loop {
                let a = -(1.0 - self.uniform()).ln() / R;
                let b = -(1.0 - self.uniform()).ln();
                if 2.0 * b > a * a {
                    return Some(if u < 0.0 { -(R + a) } else { R + a });
                }
            }
        }
        let (f0, f1) = (self.t.f[i], self.t.f[i + 1]);
        (f1 + (f0 - f1) * self.uniform() < pdf(x)).then_some(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lane::F4;

    #[test]
    fn quantiser_rounds_to_the_grid() {
        let q = Quant::new(1e-4);
        let read = |x: f64| q.read(x, 0.0);
        assert_eq!(read(0.00014), 1e-4);
        assert_eq!(read(-0.00016), -2e-4);
        approx::assert_relative_eq!(read(123.456_789), 123.4568, max_relative = 1e-15);
        // Beyond the magic-number range it falls back to round().
        assert_eq!(read(1e12), 1e12);
        assert_eq!(Quant::new(0.0).read(0.123_456_789, -0.0), 0.123_456_789);
        // Lanes: each lane its own step, the fallback per lane.
        if !crate::lane::available() {
            eprintln!("lanes skipped: no AVX2 on this processor");
            return;
        }
        let quants = [Quant::new(1e-4), Quant::new(0.0), Quant::new(1e-5)];
        let lanes = Quant::<F4>::gather(&[&quants[0], &quants[1], &quants[2]]);
        for x in [0.00014, -0.00016, 123.456_789, 1e12, -0.0] {
            let xs = F4::from_fn(|l| x * (l + 1) as f64);
            let got = lanes.read(xs, F4::splat(0.0));
            for l in 0..4 {
                let want = quants[l.min(2)].read(xs.at(l), 0.0);
                assert_eq!(got.at(l).to_bits(), want.to_bits(), "{x}, lane {l}");
            }
        }
    }

    #[test]
    fn ziggurat_words_are_chacha8rng_words() {
        // Truth: `rand_chacha::ChaCha8Rng` with the stream number set, its 64-bit words as
        // `next_u64` gives them: the normal numbers of a stream are made from these words in
        // order (the word a draw uses decides its layer and value).
        use rand::Rng;
        for (seed, stream) in [(0u64, 0u64), (11, 0), (12, 1), (u64::MAX, 7)] {
            let mut g = Normals::new(seed, stream);
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(stream);
            for _ in 0..3 * BLOCK + 5 {
                assert_eq!(g.word(), rng.next_u64(), "seed {seed}, stream {stream}");
            }
        }
    }

    #[test]
    fn tables_close_the_ziggurat() {
        // Truth: the construction. Layer 255 must end at 0 (its width x_255 must make the
        // area v with f from f(x_255) up to 1), and the total area under f on [0, inf) is
        // sqrt(pi/2) = 256 v minus the part of the base rectangle beyond the curve.
        let t = tables();
        let top = t.x[255] * (1.0 - pdf(t.x[255]));
        assert!((top - V).abs() < 1e-9 * V, "top layer area {top} vs {V}");
        assert!(t.x.windows(2).all(|w| w[0] > w[1]));
    }

    #[test]
    fn moments_and_distribution_are_standard_normal() {
        // Truth: N(0, 1): mean 0, variance 1, kurtosis 3, and the CDF Φ (Kolmogorov–Smirnov
        // distance below 1.63/sqrt(n), the 1 % critical value, on 10^6 draws).
        let mut g = Normals::new(7, 0);
        let n = 1_000_000;
        let mut v: Vec<f64> = (0..n).map(|_| g.sample()).collect();
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        let kurt = v.iter().map(|x| (x - mean).powi(4)).sum::<f64>() / (n as f64 * var * var);
        assert!(mean.abs() < 5.0 / (n as f64).sqrt(), "mean {mean}");
        assert!(
            (var - 1.0).abs() < 5.0 * (2.0 / n as f64).sqrt(),
            "variance {var}"
        );
        assert!(
            (kurt - 3.0).abs() < 5.0 * (24.0 / n as f64).sqrt(),
            "kurtosis {kurt}"
        );
        v.sort_by(f64::total_cmp);
        // Φ by the complementary error function's continued fraction-free series is not in
        // std; use the Abramowitz–Stegun 7.1.26 erf (|error| < 1.5e-7, far below the KS bound).
        let phi = |x: f64| {
            let z = x.abs() / std::f64::consts::SQRT_2;
            let t = 1.0 / (1.0 + 0.327_591_1 * z);
            let poly = t
                * (0.254_829_592
                    + t * (-0.284_496_736
                        + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
            let erf = 1.0 - poly * (-z * z).exp();
            0.5 * (1.0 + erf.copysign(x))
        };
        let ks = v
            .iter()
            .enumerate()
            .map(|(k, x)| {
                let c = phi(*x);
                (c - k as f64 / n as f64)
                    .abs()
                    .max((c - (k + 1) as f64 / n as f64).abs())
            })
            .fold(0.0, f64::max);
        assert!(ks < 1.63 / (n as f64).sqrt(), "KS distance {ks}");
        // Tails are drawn: about 2.6e-4 of draws beyond 3.65.
        let tail = v.iter().filter(|x| x.abs() > R).count() as f64 / n as f64;
        assert!((tail - 2.58e-4).abs() < 0.6e-4, "tail fraction {tail}");
    }

    #[test]
    fn same_seed_same_stream() {
        let mut a = Normals::new(3, 1);
        let mut b = Normals::new(3, 1);
        let mut c = Normals::new(3, 0);
        let va: Vec<f64> = (0..1000).map(|_| a.sample()).collect();
        let vb: Vec<f64> = (0..1000).map(|_| b.sample()).collect();
        let vc: Vec<f64> = (0..1000).map(|_| c.sample()).collect();
        assert_eq!(va, vb);
        assert_ne!(va, vc);
    }
}
