//! A small, hand-written pseudo-random generator: xoshiro256++ seeded through SplitMix64, with
//! Box–Muller normal deviates.
//!
//! Why not `rand`: a scenario file plus its seed is a *recorded experiment*; its samples must stay
//! bit-identical across calib releases so that committed truth tables and test tolerances keep
//! meaning what they meant. `rand` does not promise value stability of `StdRng` or of
//! `rand_distr::Normal` across versions; thirty lines of a published algorithm (Blackman & Vigna,
//! "Scrambled linear pseudorandom number generators", 2021) do, and cost no dependency.

use std::f64::consts::TAU;

/// SplitMix64 step: used only to expand a seed into xoshiro's 256-bit state (the seeding its
/// authors recommend, so that similar seeds give unrelated streams).
fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// xoshiro256++ with a cached second Box–Muller deviate.
#[derive(Debug, Clone)]
pub(crate) struct Rng {
    s: [u64; 4],
    spare: Option<f64>,
}

impl Rng {
    /// An independent stream per `(seed, stream)`: each simulated channel draws from its own
    /// stream, so adding a sensor to a scenario does not change the noise of the others.
    pub(crate) fn new(seed: u64, stream: u64) -> Self {
        let mut sm = seed ^ splitmix64(&mut stream.wrapping_mul(0xD1B5_4A32_D192_ED03));
        let s = [
            splitmix64(&mut sm),
            splitmix64(&mut sm),
            splitmix64(&mut sm),
            splitmix64(&mut sm),
        ];
        Rng { s, spare: None }
    }

    fn next_u64(&mut self) -> u64 {
        let s = &mut self.s;
        let result = s[0].wrapping_add(s[3]).rotate_left(23).wrapping_add(s[0]);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    pub(crate) fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A standard normal deviate (Box–Muller; the second deviate of each pair is cached).
    pub(crate) fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        // 1 − U lies in (0, 1], so the logarithm is finite.
        let r = (-2.0 * (1.0 - self.uniform()).ln()).sqrt();
        let (s, c) = (TAU * self.uniform()).sin_cos();
        self.spare = Some(r * s);
        r * c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_values_of_xoshiro256plusplus() {
        // The reference implementation's output for state [1, 2, 3, 4] (Vigna's xoshiro256plusplus.c).
        let mut r = Rng {
            s: [1, 2, 3, 4],
            spare: None,
        };
        let got: Vec<u64> = (0..3).map(|_| r.next_u64()).collect();
        assert_eq!(got, [41943041, 58720359, 3588806011781223]);
    }

    #[test]
    fn normal_deviates_have_unit_variance_and_streams_differ() {
        let mut r = Rng::new(7, 0);
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        // Standard errors: mean 1/√n ≈ 0.0022, variance √(2/n) ≈ 0.0032; 5σ bounds.
        assert!(mean.abs() < 0.012, "{mean}");
        assert!((var - 1.0).abs() < 0.016, "{var}");
        assert_ne!(Rng::new(7, 0).normal(), Rng::new(7, 1).normal());
        assert_ne!(Rng::new(7, 0).normal(), Rng::new(8, 0).normal());
    }
}
