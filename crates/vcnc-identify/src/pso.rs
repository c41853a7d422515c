//! Particle swarm optimisation with bound clamping (paper section 3.3.2, Steps 1–7).
//!
//! What is optimised is a [`CostFunction`]; how is the [`Pso`] solver. Each iteration
//! evaluates every particle (in parallel, collected in particle order), updates the personal and
//! global bests sequentially, records the history, then moves the swarm (paper eq. 14):
//! $$ v_i \leftarrow w\,v_i + \eta_1 r_1 (\sigma_{i,pbest} - \sigma_i) + \eta_2 r_2 (\sigma_{gbest} - \sigma_i),\quad |v_i| \le v_{max},\quad \sigma_i \leftarrow \mathrm{clamp}(\sigma_i + v_i) $$
//! with $r_1, r_2$ uniform in [0, 1), drawn per particle and dimension.
//!
//! Determinism: every random number is drawn in a fixed order from the one generator passed in,
//! costs are pure functions of the particle, and ties are broken by the lowest particle index,
//! so the result is bit-identical for any number of threads.

use rand::Rng;
use rayon::prelude::*;

use crate::Error;
use crate::options::PsoSettings;

/// Two independent uniform numbers in [0, 1) with 32 random bits each, from one 64-bit draw:
/// ample resolution for the swarm's coefficients, at half the generator cost of two `f64`s.
#[inline]
fn uniform_pair<R: Rng + ?Sized>(rng: &mut R) -> (f64, f64) {
    let bits = rng.next_u64();
    let scale = 1.0 / 4_294_967_296.0;
    (
        (bits >> 32) as f64 * scale,
        (bits & 0xffff_ffff) as f64 * scale,
    )
}

/// Evaluation time of one iteration above which the swarm evaluates in parallel.
const PARALLEL_ABOVE: std::time::Duration = std::time::Duration::from_micros(200);

/// An objective to minimise over a box: what the swarm optimises.
pub trait CostFunction: Sync {
    /// Cost at `param` (one value per search dimension). NaN counts as +∞.
    fn cost(&self, param: &[f64]) -> f64;
}

impl<F: Fn(&[f64]) -> f64 + Sync> CostFunction for F {
    fn cost(&self, param: &[f64]) -> f64 {
        self(param)
    }
}

/// One line of the convergence history.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HistoryEntry {
    /// Iteration, from 1.
    pub iteration: usize,
    /// Global-best cost after this iteration's evaluations (units of the cost).
    pub best_cost: f64,
    /// Global-best position (for the pole search: p in Hz, ωn in Hz, ζ).
    pub best: Vec<f64>,
    /// Mean cost of the swarm this iteration (finite costs only).
    pub mean_cost: f64,
}

/// Result of a swarm run.
#[derive(Debug, Clone, PartialEq)]
pub struct PsoResult {
    /// Best position found.
    pub best: Vec<f64>,
    /// Its cost.
    pub best_cost: f64,
    /// One entry per iteration (plot: paper Fig. 7).
    pub history: Vec<HistoryEntry>,
    /// Cost evaluations made.
    pub evaluations: usize,
    /// The best distinct personal bests, best first, with their costs: no two within
    /// [`DISTINCT`] (relative, in every coordinate) of each other. The first is `best`.
    pub candidates: Vec<(Vec<f64>, f64)>,
}

/// Relative distance in some coordinate above which two positions count as distinct.
pub const DISTINCT: f64 = 0.1;

/// Most candidates kept.
const ARCHIVE: usize = 8;

/// Offers a position to the archive of distinct good candidates (sorted, best first).
fn offer(archive: &mut Vec<(Vec<f64>, f64)>, p: &[f64], c: f64, floor: &[f64]) {
    // Most offers are worse than every kept candidate: rejected before any distance check.
    if !c.is_finite() || (archive.len() == ARCHIVE && c >= archive[ARCHIVE - 1].1) {
        return;
    }
    let near = |q: &[f64]| {
        p.iter()
            .zip(q)
            .zip(floor)
            .all(|((a, b), f)| (a - b).abs() <= DISTINCT * a.abs().max(b.abs()).max(*f))
    };
    if let Some(i) = archive.iter().position(|(q, _)| near(q)) {
        if c < archive[i].1 {
            archive.remove(i);
        } else {
            return;
        }
    } else if archive.len() == ARCHIVE {
        if c >= archive[ARCHIVE - 1].1 {
            return;
        }
        archive.pop();
    }
    let at = archive.partition_point(|(_, q)| *q <= c);
    archive.insert(at, (p.to_vec(), c));
}

/// The particle swarm solver: how the objective is optimised (paper section 3.3.2).
#[derive(Debug, Clone, PartialEq)]
pub struct Pso {
    lower: Vec<f64>,
    upper: Vec<f64>,
    settings: PsoSettings,
}

impl Pso {
    /// A swarm over the box `lower ..= upper` with the paper's settings.
    pub fn new(lower: Vec<f64>, upper: Vec<f64>) -> Result<Pso, Error> {
        if lower.len() != upper.len() || lower.is_empty() {
            return Err(Error::InvalidOption {
                name: "pso.bounds",
                value: lower.len() as f64,
                expected: "lower and upper bounds of the same, non-zero dimension",
            });
        }
        for (lo, hi) in lower.iter().zip(&upper) {
            if !(lo.is_finite() && hi.is_finite() && hi > lo) {
                return Err(Error::InvalidBounds {
                    name: "pso.bounds",
                    min: *lo,
                    max: *hi,
                    expected: "finite bounds with min < max",
                });
            }
        }
        Ok(Pso {
            lower,
            upper,
            settings: PsoSettings::default(),
        })
    }

    /// Replaces every setting at once, after checking them (paper eq. 24).
    pub fn with_settings(mut self, settings: PsoSettings) -> Result<Pso, Error> {
        settings.validate()?;
        self.settings = settings;
        Ok(self)
    }

    /// Number of particles $M$ (≥ 2).
    pub fn with_particles(self, m: usize) -> Result<Pso, Error> {
        let s = PsoSettings {
            particles: m,
            ..self.settings
        };
        self.with_settings(s)
    }

    /// Number of iterations (≥ 1).
    pub fn with_iterations(self, n: usize) -> Result<Pso, Error> {
        let s = PsoSettings {
            iterations: n,
            ..self.settings
        };
        self.with_settings(s)
    }

    /// Inertia weight and learning gains, checked against paper eq. 24.
    pub fn with_gains(self, w: f64, eta1: f64, eta2: f64) -> Result<Pso, Error> {
        let s = PsoSettings {
            w,
            eta1,
            eta2,
            ..self.settings
        };
        self.with_settings(s)
    }

    /// Velocity limit as a fraction of each range, in (0, 1].
    pub fn with_vmax_fraction(self, f: f64) -> Result<Pso, Error> {
        let s = PsoSettings {
            vmax_fraction: f,
            ..self.settings
        };
        self.with_settings(s)
    }

    /// The settings in force.
    pub fn settings(&self) -> &PsoSettings {
        &self.settings
    }

    /// Runs the swarm with the random generator `rng` (seeded by the caller).
    ///
    /// Step 1: positions uniform in the box, velocities uniform in $[-v_{max}, v_{max}]$.
    /// Steps 2–4: evaluate, update personal bests ($f \le f_{pbest}$, paper Step 3) and the
    /// global best (lowest cost, lowest index on ties). Steps 5–6: move with eq. 14 and clamp to
    /// the box. Step 7: stop after the set number of iterations.
    pub fn run<C: CostFunction + ?Sized, R: Rng + ?Sized>(
        &self,
        cost: &C,
        rng: &mut R,
    ) -> PsoResult {
        let d = self.lower.len();
        let m = self.settings.particles;
        let (w, eta1, eta2) = (self.settings.w, self.settings.eta1, self.settings.eta2);
        let vmax: Vec<f64> = (0..d)
            .map(|j| (self.upper[j] - self.lower[j]) * self.settings.vmax_fraction)
            .collect();
        let mut pos = vec![0.0; m * d];
        let mut vel = vec![0.0; m * d];
        for i in 0..m {
            for j in 0..d {
                let (r, _) = uniform_pair(rng);
                pos[i * d + j] = self.lower[j] + r * (self.upper[j] - self.lower[j]);
            }
        }
        for i in 0..m {
            for j in 0..d {
                let (r, _) = uniform_pair(rng);
                vel[i * d + j] = vmax[j] * (2.0 * r - 1.0);
            }
        }
        let mut pbest = pos.clone();
        let mut pbest_cost = vec![f64::INFINITY; m];
        let mut gbest = pos[0..d].to_vec();
        let mut gbest_cost = f64::INFINITY;
        let mut costs = vec![0.0; m];
        let mut history = Vec::with_capacity(self.settings.iterations);
        // One contiguous chunk per worker. A cost of a few dozen flops (the equation-error
        // cost) is cheaper than waking the workers, so the first iteration runs serially and is
        // timed: the swarm goes parallel only when an iteration's evaluations take longer than
        // `PARALLEL_ABOVE`. The schedule never changes the result (costs are pure, collected in
        // particle order), so this is invisible but for speed.
        let min_len = m.div_ceil(rayon::current_num_threads().max(1)).max(1);
        let floor: Vec<f64> = (0..d)
            .map(|j| 1e-3 * (self.upper[j] - self.lower[j]))
            .collect();
        let mut archive: Vec<(Vec<f64>, f64)> = Vec::with_capacity(ARCHIVE + 1);
        let mut parallel = false;
        for it in 0..self.settings.iterations {
            let eval = |p: &[f64]| {
                let c = cost.cost(p);
                if c.is_nan() { f64::INFINITY } else { c }
            };
            if parallel {
                pos.par_chunks(d)
                    .with_min_len(min_len)
                    .map(eval)
                    .collect_into_vec(&mut costs);
            } else {
                let t0 = std::time::Instant::now();
                costs.clear();
                costs.extend(pos.chunks(d).map(eval));
                parallel = it == 0 && t0.elapsed() > PARALLEL_ABOVE;
            }
            for i in 0..m {
                if costs[i] <= pbest_cost[i] {
                    pbest_cost[i] = costs[i];
                    pbest[i * d..(i + 1) * d].copy_from_slice(&pos[i * d..(i + 1) * d]);
                }
            }
            for i in 0..m {
                if pbest_cost[i] < gbest_cost {
                    gbest_cost = pbest_cost[i];
                    gbest.copy_from_slice(&pbest[i * d..(i + 1) * d]);
                }
            }
            let (sum, cnt) = costs
                .iter()
                .filter(|c| c.is_finite())
                .fold((0.0, 0usize), |(s, n), c| (s + c, n + 1));
            history.push(HistoryEntry {
                iteration: it + 1,
                best_cost: gbest_cost,
                best: gbest.clone(),
                mean_cost: if cnt > 0 {
                    sum / cnt as f64
                } else {
                    f64::INFINITY
                },
            });
            if it + 1 == self.settings.iterations {
                break;
            }
            let bounds = self.lower.iter().zip(&self.upper).zip(&vmax).zip(&gbest);
            let bounds: Vec<(f64, f64, f64, f64)> = bounds
                .map(|(((lo, hi), vm), g)| (*lo, *hi, *vm, *g))
                .collect();
            for ((p, v), pb) in pos
                .chunks_exact_mut(d)
                .zip(vel.chunks_exact_mut(d))
                .zip(pbest.chunks_exact(d))
            {
                for ((pj, vj), (pbj, &(lo, hi, vm, g))) in
                    p.iter_mut().zip(v.iter_mut()).zip(pb.iter().zip(&bounds))
                {
                    let (r1, r2) = uniform_pair(rng);
                    let nv =
                        (w * *vj + eta1 * r1 * (pbj - *pj) + eta2 * r2 * (g - *pj)).clamp(-vm, vm);
                    *vj = nv;
                    *pj = (*pj + nv).clamp(lo, hi);
                }
            }
        }
        // Distinct good candidates from the personal bests (each particle's best position of the
        // whole run; gbest among them).
        for i in 0..m {
            offer(
                &mut archive,
                &pbest[i * d..(i + 1) * d],
                pbest_cost[i],
                &floor,
            );
        }
        PsoResult {
            best: gbest,
            best_cost: gbest_cost,
            history,
            evaluations: m * self.settings.iterations,
            candidates: archive,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn finds_the_minimum_of_a_shifted_bowl() {
        // Truth: the analytic minimiser (1.5, -2, 0.25) of a quadratic bowl.
        let f = |x: &[f64]| {
            (x[0] - 1.5).powi(2) + 3.0 * (x[1] + 2.0).powi(2) + 10.0 * (x[2] - 0.25).powi(2)
        };
        let pso = Pso::new(vec![-5.0, -5.0, -1.0], vec![5.0, 5.0, 1.0]).unwrap();
        let r = pso.run(&f, &mut ChaCha8Rng::seed_from_u64(3));
        assert!(
            (r.best[0] - 1.5).abs() < 1e-4
                && (r.best[1] + 2.0).abs() < 1e-4
                && (r.best[2] - 0.25).abs() < 1e-4,
            "{:?}",
            r.best
        );
        assert_eq!(r.history.len(), 100);
        assert!(
            r.history
                .windows(2)
                .all(|h| h[1].best_cost <= h[0].best_cost)
        );
    }

    #[test]
    fn minimum_on_a_bound_is_reached_by_clamping() {
        // Truth: the bowl's centre (-3) lies outside the box [0, 1], so the minimiser is x = 0.
        let f = |x: &[f64]| (x[0] + 3.0).powi(2);
        let pso = Pso::new(vec![0.0], vec![1.0]).unwrap();
        let r = pso.run(&f, &mut ChaCha8Rng::seed_from_u64(1));
        assert_eq!(r.best[0], 0.0);
    }

    #[test]
    fn settings_outside_eq24_are_rejected() {
        let pso = Pso::new(vec![0.0], vec![1.0]).unwrap();
        // eta = 4 with w = 0.6 diverges (paper case 5); w = 1 is the border.
        assert!(matches!(
            pso.clone().with_gains(0.6, 1.0, 3.0),
            Err(Error::PsoDivergent { .. })
        ));
        assert!(pso.clone().with_gains(1.0, 0.1, 1.0).is_err());
        assert!(pso.clone().with_gains(0.6, 0.0, 0.0).is_err());
        assert!(pso.clone().with_gains(0.6, 0.103, 2.897).is_ok());
        assert!(pso.clone().with_particles(1).is_err());
        assert!(pso.clone().with_iterations(0).is_err());
        assert!(pso.with_vmax_fraction(0.0).is_err());
    }

    #[test]
    fn nan_costs_never_win() {
        let f = |x: &[f64]| if x[0] < 0.5 { f64::NAN } else { x[0] };
        let pso = Pso::new(vec![0.0], vec![1.0]).unwrap();
        let r = pso.run(&f, &mut ChaCha8Rng::seed_from_u64(9));
        assert!(r.best[0] >= 0.5 && r.best_cost.is_finite());
    }

    #[test]
    fn same_seed_gives_identical_bits_on_one_and_two_threads() {
        // A deliberately slow cost (about 30 µs a particle), so that the swarm takes its
        // parallel path on two threads.
        let f = |x: &[f64]| {
            let mut s = 0.0;
            for i in 0..3000 {
                s += ((x[0] + i as f64 * 1e-6) * 3.0).sin();
            }
            s / 3000.0 + (x[1] - 0.3).powi(2) + 0.1 * (x[2] * 7.0).cos()
        };
        let pso = Pso::new(vec![-2.0, -2.0, -2.0], vec![2.0, 2.0, 2.0])
            .and_then(|p| p.with_particles(40))
            .and_then(|p| p.with_iterations(15))
            .unwrap();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| pso.run(&f, &mut ChaCha8Rng::seed_from_u64(42)))
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(a, b);
        let bits = |r: &PsoResult| {
            r.history
                .iter()
                .flat_map(|h| h.best.iter().map(|v| v.to_bits()))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&a), bits(&b));
        // A different seed explores differently.
        let c = pso.run(&f, &mut ChaCha8Rng::seed_from_u64(43));
        assert_ne!(bits(&a), bits(&c));
    }
}
