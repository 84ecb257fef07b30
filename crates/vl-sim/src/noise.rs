//! Gaussian noise from the simulator's seeded generators.

use rand::{Rng, RngExt};

/// A standard normal sample (Box–Muller; one of the pair is enough here).
pub(crate) fn gaussian(rng: &mut impl Rng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(f64::MIN_POSITIVE);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
