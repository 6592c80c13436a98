//! The one seeded random number generator of the tests, benchmarks and fixed scenarios
//! (SplitMix64, Steele, Lea and Flood 2014): the same seed gives the same numbers on every machine
//! and in every build, so a failing case reproduces and a benchmark measures the same scenario.
//! Not for anything that needs unpredictable numbers.

/// SplitMix64: a 64-bit counter stepped by the golden-ratio increment, then mixed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1), the top 53 bits.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [0, 1) in single precision, the top 24 bits (every value exact in f32).
    pub fn unit_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform in [lo, hi), single precision.
    pub fn range_f32(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit_f32()
    }

    /// Uniform index in `0..count` (`count > 0`).
    pub fn below(&mut self, count: usize) -> usize {
        ((self.unit() * count as f64) as usize).min(count - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The published SplitMix64 sequence for seed 0 (first outputs of the reference C code).
    #[test]
    fn matches_the_reference_sequence() {
        let mut rng = SplitMix64::new(0);
        assert_eq!(rng.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(rng.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        assert_eq!(rng.next_u64(), 0x06C4_5D18_8009_454F);
    }

    #[test]
    fn units_stay_in_range_and_cover_it() {
        let mut rng = SplitMix64::new(7);
        let (mut low, mut high) = (1.0_f64, 0.0_f64);
        for _ in 0..10_000 {
            let u = rng.unit();
            let v = rng.unit_f32();
            assert!((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v));
            assert!(rng.below(3) < 3);
            (low, high) = (low.min(u), high.max(u));
        }
        assert!(low < 1e-3 && high > 1.0 - 1e-3, "{low} {high}");
    }
}
