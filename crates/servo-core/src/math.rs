//! Scalar helpers for the tick: the multiply-add of the dense products, and flushing of
//! subnormal state values.

/// How this build rounds the multiply-adds of its dense products (state-space controllers,
/// the simulator's tick), for provenance records: `separate multiply and add` (IEEE 754: two
/// roundings, the same bits on every processor and target) or, with the `fma` feature,
/// `fused multiply-add` (one rounding; other numbers than a default build's).
pub const ARITHMETIC: &str = if cfg!(feature = "fma") {
    FUSED_ARITHMETIC
} else {
    "separate multiply and add"
};

/// [`ARITHMETIC`] of a build with the `fma` feature (and of recordings that name none: they
/// were made before the choice existed, fused).
pub const FUSED_ARITHMETIC: &str = "fused multiply-add";

/// `a·b + c` as this build rounds it ([`ARITHMETIC`]): two roundings by default; one with the
/// `fma` feature (exact on every processor: an FMA instruction where the dispatched code has
/// one, the C library's `fma` otherwise).
#[inline(always)]
pub fn mul_add(a: f64, b: f64, c: f64) -> f64 {
    #[cfg(feature = "fma")]
    {
        a.mul_add(b, c)
    }
    #[cfg(not(feature = "fma"))]
    {
        a * b + c
    }
}

/// `x`, or 0 when `x` is subnormal.
///
/// A filter state that decays under a constant input ends in the subnormal range and stays
/// there (0.95 × the smallest subnormal rounds back to it); every operation on it then costs
/// ~100 cycles on x86. Flushing keeps the tick time flat (measured: PID tick 92 ns → 3 ns).
#[inline(always)]
pub(crate) fn flush(x: f64) -> f64 {
    if x.abs() < f64::MIN_POSITIVE {
        0.0
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flush_zeroes_only_subnormals() {
        assert_eq!(flush(f64::MIN_POSITIVE / 2.0), 0.0);
        assert_eq!(flush(-f64::MIN_POSITIVE / 3.0), 0.0);
        assert_eq!(flush(f64::MIN_POSITIVE), f64::MIN_POSITIVE);
        assert_eq!(flush(-1e-300), -1e-300);
        assert!(flush(f64::NAN).is_nan(), "faults must still see NaN");
        assert_eq!(flush(f64::INFINITY), f64::INFINITY);
    }
}
