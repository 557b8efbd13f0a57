//! The square root of the kernel's scalar, by the FPU where the target has one.
//!
//! nalgebra's `ComplexField::sqrt` goes to `libm` in `no_std`, a software routine on 32-bit
//! Arm; [`sqrt`] sends `f32` to [`fpu::sqrt_f32`] (`VSQRT.F32` on Cortex-M4F/M7) and every
//! other scalar to `ComplexField::sqrt`. Both are the correctly rounded IEEE 754 root, so the
//! result does not depend on the path.

use core::any::Any;

use nalgebra::RealField;

/// `√x`, correctly rounded (NaN for negative or NaN `x`): the FPU's instruction for `f32` on
/// hardware-float Arm targets, `ComplexField::sqrt` otherwise. The scalar is matched by its
/// type (`Any`), which monomorphisation resolves at compile time: no run-time dispatch.
#[inline]
pub fn sqrt<T: RealField + Copy>(x: T) -> T {
    if let Some(&single) = (&x as &dyn Any).downcast_ref::<f32>() {
        let root = fpu::sqrt_f32(single);
        if let Some(&root) = (&root as &dyn Any).downcast_ref::<T>() {
            return root;
        }
    }
    x.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sqrt_is_the_correctly_rounded_root_in_both_scalars() {
        for x in [0.0f64, 2.0, 1e-30, 3.5e7, 0.25] {
            assert_eq!(sqrt(x).to_bits(), x.sqrt().to_bits());
            let single = x as f32;
            assert_eq!(sqrt(single).to_bits(), single.sqrt().to_bits());
        }
        assert!(sqrt(-1.0f32).is_nan() && sqrt(f64::NAN).is_nan());
        assert_eq!(sqrt(-0.0f32).to_bits(), (-0.0f32).to_bits());
    }
}
