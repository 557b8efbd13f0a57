//! Floating-point instructions that `core` does not expose on stable Rust.
//!
//! `no_std` code gets `sqrt` from `libm`, which is a software routine on 32-bit Arm (about 50
//! instructions on a Cortex-M7; `libm` has hardware paths for x86 and AArch64 only). The FPU
//! of a Cortex-M4F or M7 computes the same correctly rounded IEEE 754 square root in one
//! `VSQRT.F32` (14 cycles). This crate is the kernel's only `unsafe`: the one inline-assembly
//! block below. Every other target, and `f64` everywhere, uses `libm`, so the result is
//! bit-identical on every target (IEEE 754 requires the square root to be correctly rounded).

#![no_std]

/// The correctly rounded square root of `x` (NaN for `x < 0` and NaN, `±0` for `±0`): the
/// FPU's `VSQRT.F32` on Arm targets with a hardware-float ABI, `libm::sqrtf` elsewhere.
#[inline]
pub fn sqrt_f32(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        vsqrt_f32(x)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// The correctly rounded square root of `x` (`libm::sqrt`; the boards' FPUs are
/// single-precision or leave `f64` to software in this project).
#[inline]
pub fn sqrt_f64(x: f64) -> f64 {
    libm::sqrt(x)
}

/// `VSQRT.F32` through `s0`. The operand travels in a core register and `s0` is saved and
/// restored on the stack around the instruction, because stable Rust does not let inline
/// assembly name the single-precision registers of every Cortex-M FPU configuration
/// (`sreg` needs the `vfp2` target feature, which `thumbv7em-none-eabihf` with
/// `target-cpu=cortex-m4` does not report). Six instructions besides the `VSQRT` itself.
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
#[inline]
#[allow(unsafe_code, reason = "the FPU's square root has no stable intrinsic on 32-bit Arm")]
fn vsqrt_f32(x: f32) -> f32 {
    let bits: u32;
    // SAFETY: every `eabihf` target has an FPU with VSQRT.F32 (VFPv2 and later); the block
    // reads and writes only the named core registers and `s0`, which it restores, and uses
    // 4 bytes of stack below the stack pointer, which `asm!` permits without `nostack`.
    unsafe {
        core::arch::asm!(
            "vpush {{s0}}",
            "vmov s0, {x}",
            "vsqrt.f32 s0, s0",
            "vmov {y}, s0",
            "vpop {{s0}}",
            x = in(reg) x.to_bits(),
            y = lateout(reg) bits,
            options(pure, nomem, preserves_flags),
        );
    }
    f32::from_bits(bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit patterns spread over every exponent, with the special values.
    fn samples() -> impl Iterator<Item = f32> {
        let specials = [0.0, -0.0, 1.0, 4.0, 2.0, f32::MIN_POSITIVE, f32::MAX, f32::INFINITY, -1.0, f32::NAN];
        let spread = (0..200_000u32).map(|i| f32::from_bits(i.wrapping_mul(21_473)));
        specials.into_iter().chain(spread)
    }

    #[test]
    fn sqrt_f32_is_the_correctly_rounded_root() {
        for x in samples() {
            let root = sqrt_f32(x);
            if x.is_nan() || x < 0.0 {
                assert!(root.is_nan(), "sqrt({x}) = {root}");
                continue;
            }
            assert_eq!(root.to_bits(), libm::sqrtf(x).to_bits(), "sqrt({x})");
            // Correct rounding, checked in f64 (exact for the square of an f32).
            let wide = f64::from(root);
            let next = f64::from(f32::from_bits(root.to_bits() + 1));
            if x.is_finite() && root > 0.0 {
                assert!(wide * wide <= f64::from(x) * (1.0 + 2.0 * f64::from(f32::EPSILON)));
                assert!(next * next > f64::from(x) || next.is_infinite());
            }
        }
        assert_eq!(sqrt_f32(-0.0).to_bits(), (-0.0f32).to_bits());
    }

    #[test]
    fn sqrt_f64_matches_libm() {
        for x in [0.0, 2.0, 1e-300, 1e300, 0.5] {
            assert_eq!(sqrt_f64(x).to_bits(), libm::sqrt(x).to_bits());
        }
    }
}
