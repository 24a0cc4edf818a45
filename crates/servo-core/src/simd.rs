//! The run-time choice of vector instructions for the dense products of a tick: the one module
//! of servo-core that holds `unsafe` (a call into a `#[target_feature]` function).
//!
//! A default build targets the baseline of its architecture (x86-64: SSE2), so it runs on any
//! machine. Where the processor has more (x86-64-v3: AVX2; x86-64-v4: AVX-512), [`vectorised`]
//! runs the same code compiled for it: four or eight `f64` lanes instead of two. The arithmetic is unchanged —
//! each lane does the same multiplications and additions in the same order, and Rust never
//! contracts `a·b + c` into a fused multiply-add unless asked (the `fma` feature) — so results
//! are bit-identical on every CPU; only the speed differs.

#![allow(unsafe_code)]

/// The vector instructions the dense products of a tick run with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Simd {
    /// The architecture's baseline (x86-64: SSE2, two `f64` lanes; any other target).
    Baseline,
    /// x86-64-v3: AVX and AVX2 (four `f64` lanes) and FMA, present and enabled by the OS.
    X86_64V3,
    /// x86-64-v4: x86-64-v3 and AVX-512 F, BW, CD, DQ, VL (eight `f64` lanes).
    X86_64V4,
}

impl Simd {
    /// Short name for provenance records: `baseline` or `x86-64-v3`.
    pub fn name(self) -> &'static str {
        match self {
            Simd::Baseline => "baseline",
            Simd::X86_64V3 => "x86-64-v3",
            Simd::X86_64V4 => "x86-64-v4",
        }
    }
}

#[cfg(target_arch = "x86_64")]
cpufeatures::new!(x86_64_v3, "avx", "avx2", "fma");
#[cfg(target_arch = "x86_64")]
cpufeatures::new!(
    x86_64_v4, "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl"
);

/// The widest [`Simd`] this machine runs (detected once, then cached).
pub fn detected() -> Simd {
    #[cfg(target_arch = "x86_64")]
    if x86_64_v4::get() {
        return Simd::X86_64V4;
    }
    #[cfg(target_arch = "x86_64")]
    if x86_64_v3::get() {
        return Simd::X86_64V3;
    }
    Simd::Baseline
}

/// Runs `f` compiled for the widest vector instructions this machine has.
///
/// Mark the closure `#[inline(always)]` (and the kernel it calls): only code inlined into the
/// function built for those instructions runs with them.
#[inline(always)]
pub fn vectorised<R>(f: impl FnOnce() -> R) -> R {
    // SAFETY: the level is the one this machine was detected to have.
    unsafe { run(detected(), f) }
}

/// Runs `f` compiled for `simd`, or for the baseline where this machine lacks `simd`. Results
/// are the same either way (see the module documentation); tests and benches compare them.
#[inline(always)]
pub fn with<R>(simd: Simd, f: impl FnOnce() -> R) -> R {
    // SAFETY: capped at the level this machine was detected to have.
    unsafe { run(simd.min(detected()), f) }
}

/// Runs `f` compiled for `simd` (one detection per call of the two entry points above).
///
/// # Safety
/// `simd` must not exceed [`detected()`].
#[inline(always)]
unsafe fn run<R>(simd: Simd, f: impl FnOnce() -> R) -> R {
    match simd {
        #[cfg(target_arch = "x86_64")]
        Simd::X86_64V3 => {
            // SAFETY: by the caller's promise `detected()` found AVX, AVX2 and FMA on this
            // processor, with the OS saving their registers (cpufeatures checks XSAVE/XCR0),
            // so every instruction `x86_64_v3_call` may be compiled to exists and runs.
            unsafe { x86_64_v3_call(f) }
        }
        #[cfg(target_arch = "x86_64")]
        Simd::X86_64V4 => {
            // SAFETY: by the caller's promise `detected()` found every x86-64-v4 feature (AVX-512 F, BW, CD, DQ, VL
            // beside x86-64-v3's) on this processor, with the OS saving the AVX-512 state
            // (cpufeatures checks XCR0), so every instruction `x86_64_v4_call` may be compiled
            // to exists and runs correctly.
            unsafe { x86_64_v4_call(f) }
        }
        _ => f(),
    }
}

/// `f()`, compiled with AVX, AVX2 and FMA enabled (`f` is inlined into it).
///
/// # Safety
/// Only call on a processor that has AVX, AVX2 and FMA with their state enabled by the OS.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma")]
#[inline]
unsafe fn x86_64_v3_call<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// `f()`, compiled with the x86-64-v4 features enabled (`f` is inlined into it).
///
/// # Safety
/// Only call on a processor that has every x86-64-v4 feature with its state enabled by the OS.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma,avx512f,avx512bw,avx512cd,avx512dq,avx512vl")]
#[inline]
unsafe fn x86_64_v4_call<R>(f: impl FnOnce() -> R) -> R {
    f()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn never_more_than_the_machine_has() {
        assert!(Simd::Baseline <= detected());
        assert_eq!(with(Simd::X86_64V3, || 2.0 * 3.0 + 1.0), 7.0);
        assert_eq!(with(Simd::X86_64V4, || 2.0 * 3.0 + 1.0), 7.0);
        assert_eq!(Simd::X86_64V3.name(), "x86-64-v3");
    }
}
