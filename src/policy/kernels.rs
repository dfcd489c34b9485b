//! Which kernels libtorch runs: the same on every x86-64 processor with AVX2, so that a
//! training gives the same weights, bit for bit, on Intel and AMD, with or without AVX-512.
//!
//! Two libraries pick their code by the processor. MKL (libtorch's matrix products and vector
//! math) is fixed to its `COMPATIBLE` branch, the one branch its documentation promises gives
//! the same results on Intel and compatible processors (conditional numerical reproducibility;
//! the `AVX2` branch falls back to the processor's own on non-Intel ones). ATen's own
//! element-wise and reduction kernels are fixed to their AVX2 build. Both read an environment
//! variable once, at their first use, so [`pin`] sets them before libtorch runs anything.
//! Measured on a 20-epoch paper training and checked on the smoke training (`tests/train.rs`):
//! the weights no longer change with `MKL_ENABLE_INSTRUCTIONS=AVX2` or `SSE4_2`; training takes
//! about 1.6x as long (MKL's compatible matrix product is its SSE2 one). Pinning is not all:
//! MKL's square root follows the processor's approximate instructions on every branch, so
//! training takes none (Adam's is Rust's, [`crate::train::adam`]); the same test trains under
//! QEMU's Intel and AMD processor models and compares the bytes.

/// The environment variables [`pin`] sets, and their values.
pub const PINNED: [(&str, &str); 2] = [("MKL_CBWR", "COMPATIBLE"), ("ATEN_CPU_CAPABILITY", "avx2")];

/// The environment variable that, set to `native`, keeps each library's own choice for the
/// processor (faster training, weights of that processor only).
pub const OPT_OUT: &str = "MPGDRIVE_KERNELS";

/// Sets [`PINNED`] in the process's environment, whatever it held, unless [`OPT_OUT`] is
/// `native`. Returns `false` when the processor has no AVX2: ATen then falls back to its
/// baseline kernels, and a training gives other weights than on an AVX2 processor.
///
/// # Safety
/// Call it first in `main`, before any other thread exists (it writes the environment) and
/// before any libtorch operation (later, MKL and ATen have already read it).
pub unsafe fn pin() -> bool {
    if std::env::var(OPT_OUT).is_ok_and(|v| v == "native") {
        return true;
    }
    for (key, value) in PINNED {
        // SAFETY: the caller guarantees no other thread exists that could read the environment.
        unsafe { std::env::set_var(key, value) };
    }
    has_avx2()
}

#[cfg(target_arch = "x86_64")]
fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

#[cfg(not(target_arch = "x86_64"))]
fn has_avx2() -> bool {
    false
}
