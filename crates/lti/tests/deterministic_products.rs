//! Matrix products round the same on every x86-64 processor: the workspace's
//! `.cargo/config.toml` limits matrixmultiply (nalgebra's kernel for products larger than about
//! 5×5) to SSE2, which rounds each multiplication and each addition, where its AVX2 kernel
//! fuses them. A design made at the start of a run then has the same bits on any processor,
//! and its recording replays bit for bit.

use nalgebra::DMatrix;

/// `[1, 1 + 2⁻³⁰] · [−1, 1 + 2⁻³⁰]ᵀ` as entry (0, 0) of a 16 × 16 product: rounding the
/// product `(1 + 2⁻³⁰)² = 1 + 2⁻²⁹ + 2⁻⁶⁰` before adding it to `−1` loses the `2⁻⁶⁰` (the sum
/// is `2⁻²⁹`); a fused multiply-add keeps it (`2⁻²⁹ + 2⁻⁶⁰`). On a processor without FMA the
/// two agree and this test cannot tell them apart; on one with FMA (CI's) it fails when the
/// fused kernel is chosen.
#[test]
fn a_product_rounds_each_multiplication() {
    let n = 16;
    let tiny = (2.0f64).powi(-30);
    let mut a = DMatrix::zeros(n, n);
    let mut b = DMatrix::zeros(n, n);
    a[(0, 0)] = 1.0;
    b[(0, 0)] = -1.0;
    a[(0, 1)] = 1.0 + tiny;
    b[(1, 0)] = 1.0 + tiny;
    let c = &a * &b;
    assert_eq!(
        c[(0, 0)],
        (2.0f64).powi(-29),
        "entry (0, 0) is {:e}: the product was fused (2⁻²⁹ + 2⁻⁶⁰ = {:e}); is MMTEST_FEATURE \
         = \"sse2\" still set in .cargo/config.toml and read by matrixmultiply?",
        c[(0, 0)],
        (2.0f64).powi(-29) + (2.0f64).powi(-60)
    );
}
