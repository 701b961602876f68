//! Run-time selection of the instruction set for the hot kernels.
//!
//! The workspace builds for baseline x86-64 (SSE2). `multiversion!` compiles a kernel twice, once
//! as is and once with AVX2 enabled, and picks the AVX2 copy when the CPU has it. The body is
//! duplicated token for token (closures inherit the target features of the function that defines
//! them, so the per-block closures handed to rayon are compiled for AVX2 too). No FMA is enabled:
//! both copies round exactly alike, the AVX2 one just processes 8 lanes at a time.

/// True if the CPU supports AVX2 (cached by the standard library).
#[inline(always)]
pub(crate) fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Defines `fn name(args) -> ret { body }` that runs an AVX2 build of `body` when available.
macro_rules! multiversion {
    ($(#[$meta:meta])* $vis:vis fn $name:ident ($($arg:ident : $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2")]
            fn avx2($($arg: $ty),*) $(-> $ret)? $body
            #[allow(clippy::too_many_arguments)]
            fn baseline($($arg: $ty),*) $(-> $ret)? $body
            #[cfg(target_arch = "x86_64")]
            if $crate::cpu::simd::has_avx2() {
                // SAFETY: the CPU supports AVX2 (checked at run time).
                return unsafe { avx2($($arg),*) };
            }
            baseline($($arg),*)
        }
    };
}
pub(crate) use multiversion;
