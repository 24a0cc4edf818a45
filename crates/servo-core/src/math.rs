//! Scalar helpers for the tick: fused multiply-add where the target has it, and flushing of
//! subnormal state values.

#[cfg(all(feature = "fma", target_arch = "x86_64", not(target_feature = "fma")))]
compile_error!(
    "servo-core feature `fma` needs hardware FMA: build with `-C target-cpu=native` (or \
     `-C target-feature=+fma`); without it f64::mul_add is a slow software routine"
);

/// `a·b + c`, fused (one rounding) with the `fma` feature, plain otherwise.
#[inline(always)]
pub(crate) fn mul_add(a: f64, b: f64, c: f64) -> f64 {
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
