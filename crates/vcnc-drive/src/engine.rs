//! The drive engine: the "true" drive in the time domain at the servo rate, one implementation
//! for every drive and every route (docs/drive-model.md, docs/machine-file.md#drive-effects).
//!
//! - The servo tick: of the ideal drive (`ideal`: rigid plant with Coulomb friction, one
//!   encoder reading) or of a drive with effects (`real`: two-mass mechanics, friction
//!   models, current loop, feedback path), with the control laws of `crate::law` and the
//!   plant steps of `crate::plant`.
//! - The run (`Run`): samples into servo ticks (fine interpolation, reference shaping,
//!   readings' noise), logging, saturation count; resumable between pieces of the reference,
//!   on one drive (`f64`) or on four drives in SIMD lanes (`crate::lane`).
//!
//! Every whole-run and streamed entry is this run: [`Drive::simulate`],
//! [`Drive::simulate_true_position`], [`crate::DriveStream`] (one drive),
//! [`crate::GroupStream`] and [`crate::simulate_batch`] (drives in lanes).
//!
//! # Timing
//!
//! The reference arrives as samples at the logging period $T_s$ (1 ms: the CNC interpolator
//! cycle). Between samples the servo loop sees the position, velocity and acceleration samples
//! each interpolated linearly ("fine interpolation", as a CNC's servo interpolates between
//! interpolator cycles). [`crate::ClosedLoopModel::simulate`] applies the same first-order hold
//! to the same samples, so a perfect model reproduces the drive up to the servo-rate
//! discretisation, which vanishes in proportion to the servo period $h$.
//!
//! At every servo tick $t_k$ the controller reads the encoder $\hat x_k$, computes $u_k$, and
//! holds it over $[t_k, t_k + h)$ (zero-order hold: the unavoidable half-period lag of a digital
//! controller, which makes the difference to the continuous loop first order in $h$). The drive
//! starts at rest at the first reference sample with every controller state zero; the trace
//! records each logging instant's encoder reading, true position and velocity, and $u$.
//!
//! The sample $k$ is logged at its first tick $t_k$; its other $n_{sub} - 1$ ticks interpolate
//! towards sample $k + 1$, and the last sample runs its first tick only. So the loop runs
//! sample by sample as the samples arrive: on sample $k$, the remaining ticks of sample $k - 1$,
//! then the first tick of sample $k$, logged (one block of $n_{sub}$ ticks; the first sample is
//! the block of its first tick alone). A run fed the reference in pieces therefore gives the
//! whole run's trace bit for bit, for any split.
//!
//! The references of a block are interpolated and shaped before its ticks, and the noise of the
//! next block's readings is drawn during its ticks, one tick's draws per tick (the generator's
//! work fills the gaps of the tick's dependency chain instead of running apart); each reading's
//! stream is drawn in tick order. Neither depends on the loop's state, so neither depends on how
//! the ticks are grouped.

pub(crate) mod ideal;
pub(crate) mod noise;
pub(crate) mod real;
mod shaping;

use crate::Error;
use crate::drive::{Drive, DriveParams};
use crate::effects::Shaping;
use crate::lane::{F4, LANES, Lane};
use crate::law::{Law, LawJob, RefSample, with_law};
use crate::model::Reference;
use crate::stream::Channels;
use ideal::Ideal;
use noise::{Noise, Quant};
use real::{Build, Real, RealJob, Structure, with_real};
use shaping::Shaper;

pub(crate) use shaping::Shaper as ReferenceShaper;

/// What a drive simulation logs at every sample of the reference (period `ts`). Memory is
/// O(samples), independent of the servo rate.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DriveTrace {
    /// Logging period $T_s$, s.
    pub ts: f64,
    /// Encoder reading $\hat x$ (quantised, with noise if configured), axis units. This is what
    /// a real drive's trace contains and what identification should use.
    pub position: Vec<f64>,
    /// True axis position $x$, axis units.
    pub true_position: Vec<f64>,
    /// True axis velocity $\dot x$, axis units/s.
    pub velocity: Vec<f64>,
    /// Control signal $u$ computed at the sample instant (after saturation), V.
    pub control: Vec<f64>,
    /// Servo ticks at which $u$ was saturated (0 without a limit).
    pub saturated_ticks: u64,
    /// True motor-side position $r_g\theta_m$, axis units: equal to `true_position` for a rigid
    /// drive, different with a compliant transmission or backlash (docs/machine-file.md#drive-effects).
    pub motor_position: Vec<f64>,
    /// Motor torque at the sample instant, N·m: $K_aK_t u$, or the current loop's output when
    /// the drive has one.
    pub motor_torque: Vec<f64>,
}

impl DriveTrace {
    /// The names of the per-sample channels, in the order of [`DriveTrace::channels`].
    pub const CHANNELS: [&'static str; 6] = [
        "position",
        "true_position",
        "velocity",
        "control",
        "motor_position",
        "motor_torque",
    ];

    /// The per-sample channels, in the order of [`DriveTrace::CHANNELS`].
    pub fn channels(&self) -> [&[f64]; 6] {
        [
            &self.position,
            &self.true_position,
            &self.velocity,
            &self.control,
            &self.motor_position,
            &self.motor_torque,
        ]
    }

    /// Empties every channel, keeping each one's memory for `n` samples at least (a trace
    /// reused from run to run or from piece to piece of a stream).
    pub fn clear_channels(&mut self, n: usize) {
        for v in [
            &mut self.position,
            &mut self.true_position,
            &mut self.velocity,
            &mut self.control,
            &mut self.motor_position,
            &mut self.motor_torque,
        ] {
            v.clear();
            v.reserve(n);
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.position.len()
    }

    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }

    /// Appends `s` to the channels asked for.
    #[inline(always)]
    fn log(&mut self, channels: Channels, s: Logged<f64>) {
        match channels {
            Channels::All => {
                self.position.push(s.position);
                self.true_position.push(s.true_position);
                self.velocity.push(s.velocity);
                self.control.push(s.control);
                self.motor_position.push(s.motor_position);
                self.motor_torque.push(s.motor_torque);
            }
            Channels::TruePosition => self.true_position.push(s.true_position),
        }
    }
}

/// Validates `params` and simulates the drive through `reference` (samples at period `ts`, s).
/// See [`Drive::simulate`].
pub fn simulate_drive(
    params: &DriveParams,
    reference: Reference<'_>,
    ts: f64,
) -> Result<DriveTrace, Error> {
    params.validate()?.simulate(reference, ts)
}

/// One logged sample: every channel of a [`DriveTrace`] at a sample's first servo tick (the
/// states before the tick, the control and torque computed at it), per lane.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Logged<T> {
    /// Position reading the loop used, axis units.
    pub(crate) position: T,
    /// True (load) position, axis units.
    pub(crate) true_position: T,
    /// True (load) velocity, axis units/s.
    pub(crate) velocity: T,
    /// Control after the limit, V.
    pub(crate) control: T,
    /// Motor-side position, axis units.
    pub(crate) motor_position: T,
    /// Motor torque, N·m.
    pub(crate) motor_torque: T,
}

/// A servo loop's tick on lanes of `T`: the ideal drive's ([`Ideal`]) or a drive with
/// effects' ([`Real`]).
pub(crate) trait Servo<T: Lane>: Send + Sync + Clone {
    /// Plant and controller state.
    type State: Send + Clone;
    /// The position sensor's quantisation.
    fn quant(&self) -> &Quant<T>;
    /// At rest at position `x0` with the sensors reading `xm0`, every controller state zero.
    fn rest(&self, x0: T, xm0: T) -> Self::State;
    /// Whether the velocity path reads a second (motor) encoder with its own noise.
    fn second_encoder(&self) -> bool;
    /// Whether a quiet run of this loop can read with the noise −0 ([`Readings::MinusZero`]:
    /// the ideal drive's); the runs of the other loops never do, and are not compiled with
    /// that path.
    const MINUS_ZERO_QUIET: bool = false;
    /// One tick with loop reference `r` and the noise of the tick's position and motor
    /// readings; the lanes at the limit.
    fn tick(&self, st: &mut Self::State, r: &RefSample<T>, noise: (T, T)) -> T::Mask;
    /// [`Servo::tick`], and what it logs (a sample's first tick).
    fn logged_tick(
        &self,
        st: &mut Self::State,
        r: &RefSample<T>,
        noise: (T, T),
    ) -> (Logged<T>, T::Mask);
}

/// A run of one drive or of lanes of drives, resumable between pieces of the reference (module
/// docs, "Timing").
pub(crate) struct Run<T: Lane, S: Servo<T>> {
    servo: S,
    n_sub: usize,
    h: f64,
    /// Drives in the lanes (the lanes beyond repeat the last drive; nothing of them is logged).
    drives: usize,
    /// Each lane's reference shaping.
    shaping: Vec<Option<Shaping>>,
    /// Each lane's position- and motor-reading noise.
    noise_src: Vec<(Noise, Noise)>,
    /// Some lane's motor reading is noisy (else the motor noise stays +0).
    motor_noise: bool,
    /// How the readings get their noise.
    readings: Readings,
    /// After the first sample: the loop state, the shaping and the last sample.
    running: Option<Running<T, S::State>>,
    /// Ticks at the limit per lane, counted in floats (exact below 2^53).
    saturated: T,
    /// One block of ticks: the loop's references, and the readings' noise of this block and
    /// of the next one (drawn during this one).
    refs: Vec<RefSample<T>>,
    noise: Vec<(T, T)>,
    noise_next: Vec<(T, T)>,
}

/// How a run's readings get their noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Readings {
    /// Some lane draws from a generator, a block ahead (during the ticks of the block before).
    Drawn,
    /// Every lane is quiet: the noise is a constant, drawn once into both buffers, and the
    /// ticks run without draws between them.
    Constant,
    /// Quiet, the constant −0 in every lane, and no reference shaping (the ideal drive's quiet
    /// run): the ticks are given the literal, which the compiler folds away ($x + (-0) = x$
    /// for every $x$), and interpolate their references themselves ([`Run::minus_zero_ticks`]).
    MinusZero,
}

/// The state a run carries from one sample to the next.
struct Running<T: Lane, St> {
    st: St,
    shapers: Shapers<T>,
    /// The last sample fed (unshaped).
    prev: RefSample<T>,
}

/// The lanes' reference shaping: on lanes when the lanes' shapings share their structure, else
/// one shaper per lane.
enum Shapers<T: Lane> {
    Lanes(Shaper<T>),
    Each(Vec<Shaper<f64>>, Vec<RefSample<f64>>),
}

impl<T: Lane> Shapers<T> {
    fn new(shaping: &[Option<Shaping>], h: f64, r0: RefSample<T>) -> Result<Shapers<T>, Error> {
        if let Some(s) = Shaper::new(shaping, h, r0)? {
            return Ok(Shapers::Lanes(s));
        }
        let mut each = Vec::with_capacity(T::WIDTH);
        for (l, s) in shaping.iter().enumerate().take(T::WIDTH) {
            let r = RefSample {
                xr: r0.xr.at(l),
                vr: r0.vr.at(l),
                ar: r0.ar.at(l),
            };
            each.push(Shaper::new(std::slice::from_ref(s), h, r)?.expect("one lane"));
        }
        Ok(Shapers::Each(each, Vec::new()))
    }

    /// The loop's references of the next `out.len()` ticks: the fine interpolation from `prev`
    /// towards `next` ($\text{prev} + (j/n_{sub})(\text{next} - \text{prev})$ at tick $j$ of the
    /// block, `next` itself at its last), shaped.
    #[inline(always)]
    fn block(
        &mut self,
        out: &mut [RefSample<T>],
        prev: &RefSample<T>,
        next: &RefSample<T>,
        inv_sub: f64,
    ) {
        match self {
            // Inlined into the AVX2 loop (`lanes`): out of line, its lane operations were
            // calls (callgrind).
            Shapers::Lanes(s) => s.shape(
                out,
                #[inline(always)]
                |o| interpolate(o, prev, next, inv_sub),
            ),
            Shapers::Each(each, buf) => {
                let b = out.len();
                buf.resize(T::WIDTH * b, RefSample::zero());
                for (l, (s, lane)) in each.iter_mut().zip(buf.chunks_exact_mut(b)).enumerate() {
                    let at = |r: &RefSample<T>| RefSample {
                        xr: r.xr.at(l),
                        vr: r.vr.at(l),
                        ar: r.ar.at(l),
                    };
                    s.shape(lane, |o| interpolate(o, &at(prev), &at(next), inv_sub));
                }
                for (j, r) in out.iter_mut().enumerate() {
                    *r = RefSample::from_fn(|l| buf[l * b + j]);
                }
            }
        }
    }
}

/// `out[j]` = `prev + ((j + 1)/n_sub)(next - prev)` for all but the last tick, `next` itself at
/// the last (a sample is its own first tick: `prev + 1·d` could differ from it).
#[inline(always)]
fn interpolate<T: Lane>(
    out: &mut [RefSample<T>],
    prev: &RefSample<T>,
    next: &RefSample<T>,
    inv_sub: f64,
) {
    let (last, rest) = out.split_last_mut().expect("a block has a tick");
    let d = step(prev, next);
    for (j, r) in rest.iter_mut().enumerate() {
        *r = interpolated(prev, &d, j, inv_sub);
    }
    *last = *next;
}

/// `next - prev`, per channel.
#[inline(always)]
fn step<T: Lane>(prev: &RefSample<T>, next: &RefSample<T>) -> RefSample<T> {
    RefSample {
        xr: next.xr - prev.xr,
        vr: next.vr - prev.vr,
        ar: next.ar - prev.ar,
    }
}

/// The reference at tick `j` of a block (not its last): `prev + ((j + 1)/n_sub) d`, with `d`
/// = [`step`]`(prev, next)`.
#[inline(always)]
fn interpolated<T: Lane>(
    prev: &RefSample<T>,
    d: &RefSample<T>,
    j: usize,
    inv_sub: f64,
) -> RefSample<T> {
    let w = T::splat((j + 1) as f64 * inv_sub);
    RefSample {
        xr: prev.xr + w * d.xr,
        vr: prev.vr + w * d.vr,
        ar: prev.ar + w * d.ar,
    }
}

impl<T: Lane, S: Servo<T>> Run<T, S> {
    /// The run of `servo` at `n_sub` ticks of `h` a sample, for `drives` drives (lanes) with
    /// these shapings and noise sources (one per drive), before its first sample.
    pub(crate) fn new(
        servo: S,
        n_sub: usize,
        h: f64,
        shaping: Vec<Option<Shaping>>,
        mut noise_src: Vec<(Noise, Noise)>,
    ) -> Run<T, S> {
        let drives = noise_src.len();
        // Lanes beyond the drives: quiet (nothing of them is kept).
        noise_src.resize_with(T::WIDTH, || (Noise::Quiet(0.0), Noise::Quiet(0.0)));
        let mut shaping = shaping;
        let last = shaping[drives - 1];
        shaping.resize(T::WIDTH, last);
        let motor_noise = servo.second_encoder() && noise_src.iter().any(|n| n.1.is_noisy());
        let quiet = noise_src.iter().all(|n| !n.0.is_noisy() && !n.1.is_noisy());
        let readings = if quiet {
            Readings::Constant
        } else {
            Readings::Drawn
        };
        let zero = T::splat(0.0);
        let mut run = Run {
            servo,
            n_sub,
            h,
            drives,
            shaping,
            noise_src,
            motor_noise,
            readings,
            running: None,
            saturated: zero,
            refs: vec![RefSample::zero(); n_sub],
            noise: vec![(zero, zero); n_sub],
            noise_next: vec![(zero, zero); n_sub],
        };
        if quiet {
            // A quiet reading's noise is the same number at every tick.
            for (now, next) in run.noise.iter_mut().zip(&mut run.noise_next) {
                Self::draw(&mut run.noise_src, motor_noise, now);
                *next = *now;
            }
            let minus_zero = |v: T| (0..T::WIDTH).all(|l| v.at(l).to_bits() == (-0.0f64).to_bits());
            // The motor reading's noise counts only where the loop reads a motor encoder: it is
            // +0 otherwise (never drawn), which kept every ideal drive off this path until
            // issue 27's measurement.
            let nz = run.noise[0];
            if S::MINUS_ZERO_QUIET
                && minus_zero(nz.0)
                && (!run.servo.second_encoder() || minus_zero(nz.1))
                && run.shaping.iter().all(Option::is_none)
            {
                run.readings = Readings::MinusZero;
            }
        }
        run
    }

    /// The noise of one tick's readings, each lane from its own streams.
    #[inline(always)]
    fn draw(noise_src: &mut [(Noise, Noise)], motor: bool, out: &mut (T, T)) {
        // The closures are inlined into the AVX2 loop (`lanes`); out of line they took a quarter
        // of its instructions (callgrind).
        out.0 = T::from_fn(
            #[inline(always)]
            |l| noise_src[l].0.draw(),
        );
        if motor {
            out.1 = T::from_fn(
                #[inline(always)]
                |l| noise_src[l].1.draw(),
            );
        }
    }

    /// Runs the next samples (`pieces[l]` lane `l`'s, checked by the caller, all of one
    /// length; empty only after the first sample) and logs each drive's into `out[l]`.
    #[inline(always)]
    fn feed_body(
        &mut self,
        pieces: &[Reference<'_>],
        channels: Channels,
        out: &mut [&mut DriveTrace],
    ) -> Result<(), Error> {
        let n = pieces[0].pos.len();
        let pick = |l: usize| &pieces[l.min(pieces.len() - 1)];
        let sample = |k: usize| {
            RefSample::<T>::from_fn(|l| {
                let p = pick(l);
                RefSample {
                    xr: p.pos[k],
                    vr: p.vel[k],
                    ar: p.acc[k],
                }
            })
        };
        let (mut running, mut first) = match self.running.take() {
            Some(r) => (r, false),
            None => {
                if n == 0 {
                    return Ok(());
                }
                let r0 = sample(0);
                let xm0 = self.servo.quant().read(r0.xr, T::splat(-0.0));
                let running = Running {
                    st: self.servo.rest(r0.xr, xm0),
                    shapers: Shapers::new(&self.shaping, self.h, RefSample::rest(r0))?,
                    prev: r0,
                };
                (running, true)
            }
        };
        let inv_sub = 1.0 / self.n_sub as f64;
        // The loop's constants as a local copy, passed to every block: read through `self`
        // (which the blocks' log pushes may change, as far as the compiler knows) they were
        // copied from the run to the stack again at every sample, about 150 of the ideal
        // drive's 2 760 instructions a sample (valgrind callgrind over 1 M samples; issue 27).
        let servo = self.servo.clone();
        // One call of `run_block` (always inlined, with the servo's tick inlined in it): a
        // second call site for the first sample doubled the crate's machine code and build time.
        for k in 0..n {
            let r = sample(k);
            let ticks = if first {
                // The first sample is the block of its first tick alone; its reading's noise is
                // drawn now, the next blocks' ahead.
                first = false;
                running.shapers.block(&mut self.refs[..1], &r, &r, 0.0);
                Self::draw(&mut self.noise_src, self.motor_noise, &mut self.noise[0]);
                1
            } else {
                if self.readings != Readings::MinusZero {
                    running
                        .shapers
                        .block(&mut self.refs, &running.prev, &r, inv_sub);
                }
                self.n_sub
            };
            let ends = (&running.prev, &r, inv_sub);
            self.run_block(&servo, &mut running.st, ticks, ends, channels, out);
            running.prev = r;
        }
        self.running = Some(running);
        Ok(())
    }

    /// Runs the `ticks` ticks of `self.refs` and logs the last one: the ticks from the previous
    /// logged sample up to and including the first tick of the next sample (`ends`: the two
    /// samples and $1/n_{sub}$). The noise of this block's readings is in `self.noise`; the
    /// next block's is drawn during this block's ticks and takes its place. `s` is the run's
    /// servo (a copy held by the caller).
    #[inline(always)]
    fn run_block(
        &mut self,
        s: &S,
        st: &mut S::State,
        ticks: usize,
        ends: (&RefSample<T>, &RefSample<T>, f64),
        channels: Channels,
        out: &mut [&mut DriveTrace],
    ) {
        let motor = self.motor_noise;
        let n_next = self.n_sub;
        let one = T::splat(1.0);
        let mut sat = self.saturated;
        // The block's last tick is logged apart. A block has at most `n_sub` ticks (the first
        // has one), so every other tick draws the noise of one of the next block's.
        let last = ticks - 1;
        debug_assert!(last < n_next);
        let refs = &self.refs[..ticks];
        let cur = &self.noise[..ticks];
        if self.readings != Readings::Drawn {
            // Nothing to draw: the loop state stays in registers through the ticks (with the
            // draws between them it went through the stack, on the loop's critical path).
            let (sat, r_last) = if S::MINUS_ZERO_QUIET && self.readings == Readings::MinusZero {
                // Unshaped, `self.refs` left unfilled: the last tick's reference is the sample.
                let sat = Self::minus_zero_ticks(s, st, ends, last, sat);
                (sat, ends.1)
            } else {
                (
                    Self::quiet_ticks(s, st, &refs[..last], sat, cur[0]),
                    &refs[last],
                )
            };
            let (logged, saturated) = s.logged_tick(st, r_last, cur[last]);
            self.saturated = sat + one.masked(saturated);
            Self::log(logged, self.drives, channels, out);
            return;
        }
        let next = &mut self.noise_next[..n_next];
        for ((r, nz), dn) in refs[..last].iter().zip(&cur[..last]).zip(&mut next[..last]) {
            sat = sat + one.masked(s.tick(st, r, *nz));
            Self::draw(&mut self.noise_src, motor, dn);
        }
        let (logged, saturated) = s.logged_tick(st, &refs[last], cur[last]);
        sat = sat + one.masked(saturated);
        Self::log(logged, self.drives, channels, out);
        for dn in &mut next[last..] {
            Self::draw(&mut self.noise_src, motor, dn);
        }
        self.saturated = sat;
        std::mem::swap(&mut self.noise, &mut self.noise_next);
    }

    /// The ticks of `refs` with their readings' noise `nz`, without draws between them; `sat`
    /// plus their ticks at the limit.
    #[inline(always)]
    fn quiet_ticks(s: &S, st: &mut S::State, refs: &[RefSample<T>], sat: T, nz: (T, T)) -> T {
        let one = T::splat(1.0);
        refs.iter()
            .fold(sat, |sat, r| sat + one.masked(s.tick(st, r, nz)))
    }

    /// [`Run::quiet_ticks`] of a block's first `ticks` ticks from sample `ends.0` towards
    /// `ends.1` (`ends.2` = $1/n_{sub}$), for −0 readings ([`Readings::MinusZero`]: the ideal
    /// drive's quiet unshaped run, which the `drive` benchmark's ideal cases time).
    ///
    /// Three things keep its loop as short as the ideal drive's loop before the engine (issue
    /// 27: these cases were 15 % slower). The noise is the literal −0, folded away: one
    /// function called with the literal or with the buffer's noise was compiled as one loop
    /// adding a variable. The state is a local copy, so it stays in registers: through `st`
    /// the position went to the stack and back at every tick, on the loop's critical path.
    /// And the references are interpolated here, where the work fills the gaps of the tick's
    /// dependency chain, instead of in a pass over the block before its ticks ([`interpolated`]:
    /// the same numbers as [`Shapers::block`] without shaping).
    #[inline(always)]
    fn minus_zero_ticks(
        s: &S,
        st: &mut S::State,
        ends: (&RefSample<T>, &RefSample<T>, f64),
        ticks: usize,
        sat: T,
    ) -> T {
        let (prev, next, inv_sub) = ends;
        let d = step(prev, next);
        let nz = (T::splat(-0.0), T::splat(-0.0));
        let one = T::splat(1.0);
        let mut local = st.clone();
        let sat = (0..ticks).fold(sat, |sat, j| {
            let r = interpolated(prev, &d, j, inv_sub);
            sat + one.masked(s.tick(&mut local, &r, nz))
        });
        *st = local;
        sat
    }

    /// Logs the first `drives` lanes of a block's last tick into their traces.
    #[inline(always)]
    fn log(logged: Logged<T>, drives: usize, channels: Channels, out: &mut [&mut DriveTrace]) {
        for (l, trace) in out.iter_mut().enumerate().take(drives) {
            trace.log(
                channels,
                Logged {
                    position: logged.position.at(l),
                    true_position: logged.true_position.at(l),
                    velocity: logged.velocity.at(l),
                    control: logged.control.at(l),
                    motor_position: logged.motor_position.at(l),
                    motor_torque: logged.motor_torque.at(l),
                },
            );
        }
    }
}

/// A resumable run behind one type, whatever its loop and lane type.
pub(crate) trait Feed: Send {
    /// Runs the next samples: `pieces[l]` is drive `l`'s (checked, all of one length, not empty
    /// before the first sample), logged into `out[l]` in the channels asked for.
    fn feed(
        &mut self,
        pieces: &[Reference<'_>],
        channels: Channels,
        out: &mut [&mut DriveTrace],
    ) -> Result<(), Error>;
    /// Each drive's servo ticks at the limit so far.
    fn saturated_ticks(&self) -> Vec<u64>;
}

impl<S: Servo<f64>> Feed for Run<f64, S> {
    fn feed(
        &mut self,
        pieces: &[Reference<'_>],
        channels: Channels,
        out: &mut [&mut DriveTrace],
    ) -> Result<(), Error> {
        self.feed_body(pieces, channels, out)
    }
    fn saturated_ticks(&self) -> Vec<u64> {
        vec![self.saturated as u64]
    }
}

impl<S: Servo<F4>> Feed for Run<F4, S> {
    fn feed(
        &mut self,
        pieces: &[Reference<'_>],
        channels: Channels,
        out: &mut [&mut DriveTrace],
    ) -> Result<(), Error> {
        lanes::feed(self, pieces, channels, out)
    }
    fn saturated_ticks(&self) -> Vec<u64> {
        (0..self.drives)
            .map(|l| self.saturated.at(l) as u64)
            .collect()
    }
}

/// The lanes' run compiled for the processor's widest registers.
mod lanes {
    use super::*;

    pub(super) use crate::lane::available;

    /// [`Run::feed_body`] on lanes, compiled for AVX2 on x86-64. No AVX-512 variant: on an
    /// AVX-512 Xeon the `drive` benchmark's lane cases ran equally fast with and without one
    /// (162.9 and 162.8 ms for the five realistic NMV5000 axes), and compiling it took 185 s of
    /// the crate's 323 s release build (issue 27's note).
    pub(super) fn feed<S: Servo<F4>>(
        run: &mut Run<F4, S>,
        pieces: &[Reference<'_>],
        channels: Channels,
        out: &mut [&mut DriveTrace],
    ) -> Result<(), Error> {
        #[cfg(target_arch = "x86_64")]
        {
            // SAFETY: a run on lanes is made only where AVX2 is present (`available`).
            unsafe { feed_avx2(run, pieces, channels, out) }
        }
        #[cfg(not(target_arch = "x86_64"))]
        run.feed_body(pieces, channels, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn feed_avx2<S: Servo<F4>>(
        run: &mut Run<F4, S>,
        pieces: &[Reference<'_>],
        channels: Channels,
        out: &mut [&mut DriveTrace],
    ) -> Result<(), Error> {
        run.feed_body(pieces, channels, out)
    }
}

/// Servo ticks per logging period: `servo_rate_hz * ts` rounded, which must match to 1e-9.
fn ticks_per_sample(servo_rate_hz: f64, ts: f64) -> Result<usize, Error> {
    if !(ts > 0.0 && ts.is_finite()) {
        return Err(Error::BadSamplePeriod { ts });
    }
    let ratio = servo_rate_hz * ts;
    let n = ratio.round();
    if !(n >= 1.0 && (ratio - n).abs() <= 1e-9 * n && n < 1e9) {
        return Err(Error::ServoRate { servo_rate_hz, ts });
    }
    Ok(n as usize)
}

/// The readings' noise of `drive`: position sensor and motor encoder.
fn noise_of(drive: &Drive) -> (Noise, Noise) {
    let enc = drive.encoder();
    if drive.effects().is_ideal() {
        (
            Noise::box_muller(enc.noise_std, enc.seed),
            Noise::Quiet(0.0),
        )
    } else {
        real_noise(drive)
    }
}

/// The readings' noise of `drive` in the loop of a drive with effects ([`real`]): position
/// sensor (stream 0 of the encoder's seed) and motor encoder (stream 1).
pub(crate) fn real_noise(drive: &Drive) -> (Noise, Noise) {
    let enc = drive.encoder();
    let motor_std = drive.effects().feedback.map_or(0.0, |f| f.motor_noise_std);
    (
        Noise::ziggurat(enc.noise_std, enc.seed, 0),
        Noise::ziggurat(motor_std, enc.seed, 1),
    )
}

/// The resumable run of one drive at the sample period `ts`.
pub(crate) fn run_of(drive: &Drive, ts: f64) -> Result<Box<dyn Feed>, Error> {
    let n_sub = drive.ticks_per_sample(ts)?;
    let h = ts / n_sub as f64;
    let shaping = vec![drive.effects().shaping];
    let noise = vec![noise_of(drive)];
    if drive.effects().is_ideal() {
        struct MakeIdeal<'a> {
            drive: &'a Drive,
            n_sub: usize,
            h: f64,
            shaping: Vec<Option<Shaping>>,
            noise: Vec<(Noise, Noise)>,
        }
        impl LawJob for MakeIdeal<'_> {
            type Out = Result<Box<dyn Feed>, Error>;
            fn run<L: Law>(self, law: L) -> Self::Out {
                let d = self.drive;
                let servo = Ideal::new(law, d.plant(), d.encoder().resolution, self.h)?;
                Ok(Box::new(Run::<f64, _>::new(
                    servo,
                    self.n_sub,
                    self.h,
                    self.shaping,
                    self.noise,
                )))
            }
        }
        let job = MakeIdeal {
            drive,
            n_sub,
            h,
            shaping,
            noise,
        };
        return with_law(drive.controller(), drive.plant(), h, job);
    }
    struct MakeReal {
        n_sub: usize,
        h: f64,
        shaping: Vec<Option<Shaping>>,
        noise: Vec<(Noise, Noise)>,
    }
    impl RealJob for MakeReal {
        type Out = Box<dyn Feed>;
        fn run<L: Law, const N: usize, const TM: bool>(self, e: Real<f64, L, N, TM>) -> Self::Out {
            Box::new(Run::<f64, _>::new(
                e,
                self.n_sub,
                self.h,
                self.shaping,
                self.noise,
            ))
        }
    }
    with_real(
        drive,
        h,
        Build::Full,
        MakeReal {
            n_sub,
            h,
            shaping,
            noise,
        },
    )
}

/// The loop structure of a drive with effects at servo period `h`: what drives must share to
/// run in lanes.
pub(crate) fn structure(drive: &Drive, h: f64) -> Result<Structure, Error> {
    struct S;
    impl RealJob for S {
        type Out = Structure;
        fn run<L: Law, const N: usize, const TM: bool>(self, e: Real<f64, L, N, TM>) -> Structure {
            e.structure()
        }
    }
    with_real(drive, h, Build::Full, S)
}

/// The resumable run of 2 to [`LANES`] drives with effects of one [`Structure`] in SIMD lanes,
/// at the sample period `ts`; `Ok(None)` when they cannot run so (not of one structure, an
/// ideal drive, other servo rates, no lanes on this processor).
pub(crate) fn lanes_run_of(drives: &[&Drive], ts: f64) -> Result<Option<Box<dyn Feed>>, Error> {
    if drives.len() < 2
        || drives.len() > LANES
        || drives.iter().any(|d| d.effects().is_ideal())
        || !lanes::available()
    {
        return Ok(None);
    }
    let n_sub = drives[0].ticks_per_sample(ts)?;
    for d in &drives[1..] {
        if d.ticks_per_sample(ts)? != n_sub {
            return Ok(None);
        }
    }
    let h = ts / n_sub as f64;
    struct MakeLanes<'a> {
        drives: &'a [&'a Drive],
        n_sub: usize,
        h: f64,
    }
    impl RealJob for MakeLanes<'_> {
        type Out = Result<Option<Box<dyn Feed>>, Error>;
        fn run<L: Law, const N: usize, const TM: bool>(self, e0: Real<f64, L, N, TM>) -> Self::Out {
            let (drives, h) = (self.drives, self.h);
            let mut loops = vec![e0];
            for d in &drives[1..] {
                let Some(law) = L::of(d.controller(), d.plant(), h) else {
                    return Ok(None);
                };
                if crate::plant::Layout::of(d.effects())
                    != crate::plant::Layout::of(drives[0].effects())
                {
                    return Ok(None);
                }
                let e = Real::<f64, L, N, TM>::new(d, h, Build::Full, law)?;
                if e.structure() != loops[0].structure() {
                    return Ok(None);
                }
                loops.push(e);
            }
            let refs: Vec<&Real<f64, L, N, TM>> = loops.iter().collect();
            let servo = Real::<F4, L, N, TM>::gather(&refs);
            let shaping = drives.iter().map(|d| d.effects().shaping).collect();
            let noise = drives.iter().map(|d| noise_of(d)).collect();
            Ok(Some(Box::new(Run::<F4, _>::new(
                servo, self.n_sub, h, shaping, noise,
            ))))
        }
    }
    with_real(drives[0], h, Build::Full, MakeLanes { drives, n_sub, h })?
}

impl Drive {
    /// Servo ticks per logged sample of period `ts`: the servo rate must be a whole multiple
    /// (≥ 1) of the logging rate. The machine-file loader checks this with the same rule the
    /// simulation uses.
    pub fn ticks_per_sample(&self, ts: f64) -> Result<usize, Error> {
        ticks_per_sample(self.servo_rate_hz(), ts)
    }

    /// Simulates the drive through `reference` (samples at period `ts`, s), with the controller
    /// at the servo rate, which must be an integer multiple of $1/T_s$. The drive starts at rest
    /// at `reference.pos[0]` with every controller state zero. See the module documentation of
    /// [`crate::engine`] for the timing, `crate::plant` for the plant step and
    /// `crate::law` for the controllers. This is [`Drive::stream`] fed the whole reference at
    /// once: a stream fed the same samples in pieces gives the same trace bit for bit.
    ///
    /// Errors: the reference's ([`Reference::check`]: empty, lengths, non-finite),
    /// [`Error::BadSamplePeriod`], [`Error::ServoRate`]. Cost: about 10 ns per servo tick
    /// (30 s at 20 kHz ≈ 10 ms; see `benches/drive.rs`), memory O(samples).
    pub fn simulate(&self, reference: Reference<'_>, ts: f64) -> Result<DriveTrace, Error> {
        let mut trace = DriveTrace::default();
        self.simulate_into(reference, ts, &mut trace)?;
        Ok(trace)
    }

    /// [`Drive::simulate`]'s true position alone, and its saturated servo ticks: the same
    /// values bit for bit, without the other channels (a long run's prediction needs only
    /// this, at 8 bytes a sample instead of 48; docs/performance.md).
    pub fn simulate_true_position(
        &self,
        reference: Reference<'_>,
        ts: f64,
    ) -> Result<(Vec<f64>, u64), Error> {
        let n = reference.check()?;
        let mut stream = self.stream(ts, Channels::TruePosition)?;
        let mut out = DriveTrace {
            true_position: Vec::with_capacity(n),
            ..DriveTrace::default()
        };
        stream.feed(reference, &mut out)?;
        let saturated_ticks = stream.finish()?;
        Ok((out.true_position, saturated_ticks))
    }

    /// As [`Drive::simulate`], reusing `trace`'s buffers (cleared first).
    pub fn simulate_into(
        &self,
        reference: Reference<'_>,
        ts: f64,
        trace: &mut DriveTrace,
    ) -> Result<(), Error> {
        let n = reference.check()?;
        let mut stream = self.stream(ts, Channels::All)?;
        trace.clear_channels(n);
        trace.saturated_ticks = 0;
        stream.feed(reference, trace)?;
        trace.saturated_ticks = stream.finish()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn servo_rate_must_be_a_multiple_of_the_logging_rate() {
        assert_eq!(ticks_per_sample(20_000.0, 1e-3).unwrap(), 20);
        assert_eq!(ticks_per_sample(1_000.0, 1e-3).unwrap(), 1);
        assert!(matches!(
            ticks_per_sample(15_500.0, 1e-3 / 3.0),
            Err(Error::ServoRate { .. })
        ));
        assert!(matches!(
            ticks_per_sample(500.0, 1e-3),
            Err(Error::ServoRate { .. })
        ));
        assert!(matches!(
            ticks_per_sample(20_000.0, 0.0),
            Err(Error::BadSamplePeriod { .. })
        ));
    }
}
