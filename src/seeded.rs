//! Counter-based random numbers: a value is a pure function of a seed and integer
//! coordinates, so results never depend on evaluation order or thread count.

/// SplitMix64's finaliser over a seed and three coordinates.
pub fn hash(seed: u64, a: i64, b: i64, c: i64) -> u64 {
    let mut z = seed
        ^ (a as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (b as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (c as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Uniform in [0, 1).
pub fn unit(seed: u64, a: i64, b: i64, c: i64) -> f32 {
    (hash(seed, a, b, c) >> 40) as f32 / (1u64 << 24) as f32
}

/// Standard normal (Box–Muller).
pub fn normal(seed: u64, a: i64, b: i64) -> f32 {
    let u1 = ((hash(seed, a, b, 1) >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = (hash(seed, a, b, 2) >> 11) as f64 / (1u64 << 53) as f64;
    ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_has_zero_mean_and_unit_variance() {
        let xs: Vec<f64> = (0..20000).map(|i| normal(5, i, 0) as f64).collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64;
        assert!(mean.abs() < 0.03 && (var - 1.0).abs() < 0.05, "{mean} {var}");
    }
}
