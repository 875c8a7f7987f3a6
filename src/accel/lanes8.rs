//! Eight f32 lanes for the packet walk on x86_64 CPUs with AVX: one 256-bit register, twice the
//! rays of `F4` for each node the packet fetches. Every operation is the lane-wise IEEE operation
//! `F4`'s is (the comparisons' ordered predicates give SSE's results), so a lane computes bit for
//! bit what the scalar walk computes for its ray.
//!
//! AVX is not part of the x86_64 baseline. Only code entered through `has_avx` runs these
//! operations (`query.rs` checks it once per batch and calls a function compiled for AVX, into
//! which they inline); on a CPU without AVX they would be illegal instructions.

use super::lanes::impl_lanes;
use std::arch::x86_64::*;

/// Whether this CPU runs `F8` (detected once by the standard library, then a cached load).
#[inline]
pub fn has_avx() -> bool {
    std::arch::is_x86_feature_detected!("avx")
}

#[derive(Clone, Copy)]
pub struct F8(__m256);

#[derive(Clone, Copy)]
pub struct M8(__m256);

// SAFETY (every block below): reached only on CPUs with AVX (see the module's note); the
// intrinsics compute on registers, and the loads and stores go through arrays of eight f32s.
impl F8 {
    #[inline(always)]
    pub fn splat(v: f32) -> F8 {
        F8(unsafe { _mm256_set1_ps(v) })
    }
    #[inline(always)]
    pub fn new(a: [f32; 8]) -> F8 {
        F8(unsafe { _mm256_loadu_ps(a.as_ptr()) })
    }
    #[inline(always)]
    pub fn to_array(self) -> [f32; 8] {
        let mut a = [0.0; 8];
        unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
        a
    }
    #[inline(always)]
    pub fn add(self, o: F8) -> F8 {
        F8(unsafe { _mm256_add_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn sub(self, o: F8) -> F8 {
        F8(unsafe { _mm256_sub_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn mul(self, o: F8) -> F8 {
        F8(unsafe { _mm256_mul_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn div(self, o: F8) -> F8 {
        F8(unsafe { _mm256_div_ps(self.0, o.0) })
    }
    /// `|self|`: the sign bit cleared.
    #[inline(always)]
    pub fn abs(self) -> F8 {
        F8(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
    }
    /// `self` with its sign flipped where `o` is negative (sign bit set).
    #[inline(always)]
    pub fn flip_sign_of(self, o: F8) -> F8 {
        F8(unsafe { _mm256_xor_ps(self.0, _mm256_and_ps(o.0, _mm256_set1_ps(-0.0))) })
    }
    /// `f32::max` lane by lane: a NaN operand yields the other.
    #[inline(always)]
    pub fn max_num(self, o: F8) -> F8 {
        let m = F8(unsafe { _mm256_max_ps(o.0, self.0) });
        F8::select(self.unordered(), o, m)
    }
    /// `f32::min` lane by lane: a NaN operand yields the other.
    #[inline(always)]
    pub fn min_num(self, o: F8) -> F8 {
        let m = F8(unsafe { _mm256_min_ps(o.0, self.0) });
        F8::select(self.unordered(), o, m)
    }
    /// Set where `self` is NaN.
    #[inline(always)]
    fn unordered(self) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_UNORD_Q>(self.0, self.0) })
    }
    #[inline(always)]
    pub fn lt(self, o: F8) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    pub fn le(self, o: F8) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    pub fn gt(self, o: F8) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    pub fn ge(self, o: F8) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_GE_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    pub fn eq(self, o: F8) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0) })
    }
    /// `m ? a : b` lane by lane.
    #[inline(always)]
    pub fn select(m: M8, a: F8, b: F8) -> F8 {
        F8(unsafe { _mm256_blendv_ps(b.0, a.0, m.0) })
    }
}

impl M8 {
    #[inline(always)]
    pub fn all(on: bool) -> M8 {
        M8(unsafe { _mm256_castsi256_ps(_mm256_set1_epi32(-(on as i32))) })
    }
    #[inline(always)]
    pub fn or(self, o: M8) -> M8 {
        M8(unsafe { _mm256_or_ps(self.0, o.0) })
    }
    /// `self & !o`.
    #[inline(always)]
    pub fn and_not(self, o: M8) -> M8 {
        M8(unsafe { _mm256_andnot_ps(o.0, self.0) })
    }
    /// Bit `i` set when lane `i` is.
    #[inline(always)]
    pub fn bits(self) -> u32 {
        unsafe { _mm256_movemask_ps(self.0) as u32 }
    }
}

impl_lanes!(F8, M8, 8);

#[cfg(test)]
mod tests {
    use super::*;

    /// Every operation against the scalar one on awkward values. Fails (never passes unchecked)
    /// on a CPU without AVX, where these lanes cannot run.
    #[test]
    fn eight_lanes_compute_what_scalars_compute() {
        assert!(
            has_avx(),
            "this CPU has no AVX: the eight-lane walk cannot be tested here"
        );
        let a = [
            1.5f32,
            -0.0,
            f32::NAN,
            3.0,
            0.0,
            f32::INFINITY,
            -7.25,
            1e-40,
        ];
        let b = [1.5f32, 0.0, 1.0, -2.0, f32::NAN, 2.0, -7.25, -3.0];
        let (x, y) = (F8::new(a), F8::new(b));
        let same = |l: f32, r: f32| l.to_bits() == r.to_bits() || (l.is_nan() && r.is_nan());
        for i in 0..8 {
            assert!(same(x.sub(y).to_array()[i], a[i] - b[i]));
            assert!(same(x.mul(y).to_array()[i], a[i] * b[i]));
            assert!(same(x.add(y).to_array()[i], a[i] + b[i]));
            assert!(same(x.div(y).to_array()[i], a[i] / b[i]));
            assert!(same(y.abs().to_array()[i], b[i].abs()));
            let flipped = f32::from_bits(a[i].to_bits() ^ (b[i].to_bits() & 0x8000_0000));
            assert!(same(x.flip_sign_of(y).to_array()[i], flipped));
            for (p, q, pv, qv) in [(x, y, a[i], b[i]), (y, x, b[i], a[i])] {
                let (max, min) = (p.max_num(q).to_array()[i], p.min_num(q).to_array()[i]);
                assert!(same(max, pv.max(qv)) || (max == 0.0 && pv.max(qv) == 0.0));
                assert!(same(min, pv.min(qv)) || (min == 0.0 && pv.min(qv) == 0.0));
            }
            assert_eq!(x.lt(y).bits() >> i & 1 == 1, a[i] < b[i], "lt {i}");
            assert_eq!(x.le(y).bits() >> i & 1 == 1, a[i] <= b[i], "le {i}");
            assert_eq!(x.gt(y).bits() >> i & 1 == 1, a[i] > b[i], "gt {i}");
            assert_eq!(x.ge(y).bits() >> i & 1 == 1, a[i] >= b[i], "ge {i}");
            assert_eq!(x.eq(y).bits() >> i & 1 == 1, a[i] == b[i], "eq {i}");
        }
        let m = x.lt(F8::splat(2.0));
        assert_eq!(m.bits(), 0b1101_0011);
        assert!(same(F8::select(m, x, y).to_array()[2], 1.0));
        assert!(same(F8::select(m, x, y).to_array()[0], 1.5));
        assert_eq!(M8::all(true).and_not(m).bits(), 0b0010_1100);
        assert_eq!(M8::all(false).or(m).bits(), m.bits());
        assert_eq!(F8::splat(4.0).to_array(), [4.0; 8]);
    }
}
