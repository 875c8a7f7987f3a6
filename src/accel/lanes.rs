//! Four f32 lanes for the packet walk: SSE2 on x86_64 (part of the architecture's baseline, so
//! no runtime detection is needed), plain arrays elsewhere. Every operation is the lane-wise IEEE
//! operation, so a lane computes bit for bit what the scalar walk computes for its ray.
//!
//! `Lanes` is what the packet walk and its triangle test ask of a group of lanes, so that the same
//! code runs on these four lanes and on the eight of `lanes8.rs`.

#[cfg(target_arch = "x86_64")]
mod imp {
    use std::arch::x86_64::*;

    #[derive(Clone, Copy)]
    pub struct F4(__m128);

    #[derive(Clone, Copy)]
    pub struct M4(__m128);

    // SAFETY (every block below): SSE2 is enabled on every x86_64 target, and these intrinsics
    // only compute on registers.
    impl F4 {
        #[inline(always)]
        pub fn splat(v: f32) -> F4 {
            F4(unsafe { _mm_set1_ps(v) })
        }
        #[inline(always)]
        pub fn new(a: [f32; 4]) -> F4 {
            F4(unsafe { _mm_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        pub fn sub(self, o: F4) -> F4 {
            F4(unsafe { _mm_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn mul(self, o: F4) -> F4 {
            F4(unsafe { _mm_mul_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn add(self, o: F4) -> F4 {
            F4(unsafe { _mm_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn div(self, o: F4) -> F4 {
            F4(unsafe { _mm_div_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn sqrt(self) -> F4 {
            F4(unsafe { _mm_sqrt_ps(self.0) })
        }
        /// `|self|`: the sign bit cleared.
        #[inline(always)]
        pub fn abs(self) -> F4 {
            F4(unsafe { _mm_andnot_ps(_mm_set1_ps(-0.0), self.0) })
        }
        /// `self` with its sign flipped where `o` is negative (sign bit set).
        #[inline(always)]
        pub fn flip_sign_of(self, o: F4) -> F4 {
            F4(unsafe { _mm_xor_ps(self.0, _mm_and_ps(o.0, _mm_set1_ps(-0.0))) })
        }
        #[inline(always)]
        pub fn ge(self, o: F4) -> M4 {
            M4(unsafe { _mm_cmpge_ps(self.0, o.0) })
        }
        /// `f32::max` lane by lane: a NaN operand yields the other.
        #[inline(always)]
        pub fn max_num(self, o: F4) -> F4 {
            let m = F4(unsafe { _mm_max_ps(o.0, self.0) });
            F4::select(M4(unsafe { _mm_cmpunord_ps(self.0, self.0) }), o, m)
        }
        /// `f32::min` lane by lane: a NaN operand yields the other.
        #[inline(always)]
        pub fn min_num(self, o: F4) -> F4 {
            let m = F4(unsafe { _mm_min_ps(o.0, self.0) });
            F4::select(M4(unsafe { _mm_cmpunord_ps(self.0, self.0) }), o, m)
        }
        #[inline(always)]
        pub fn lt(self, o: F4) -> M4 {
            M4(unsafe { _mm_cmplt_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn le(self, o: F4) -> M4 {
            M4(unsafe { _mm_cmple_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn gt(self, o: F4) -> M4 {
            M4(unsafe { _mm_cmpgt_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn eq(self, o: F4) -> M4 {
            M4(unsafe { _mm_cmpeq_ps(self.0, o.0) })
        }
        /// `m ? a : b` lane by lane.
        #[inline(always)]
        pub fn select(m: M4, a: F4, b: F4) -> F4 {
            F4(unsafe { _mm_or_ps(_mm_and_ps(m.0, a.0), _mm_andnot_ps(m.0, b.0)) })
        }
        /// `f32::min` lane by lane where no lane is NaN (a NaN yields `o`), in one instruction.
        #[inline(always)]
        pub fn min(self, o: F4) -> F4 {
            F4(unsafe { _mm_min_ps(self.0, o.0) })
        }
        /// `f32::max` lane by lane where no lane is NaN (a NaN yields `o`), in one instruction.
        #[inline(always)]
        pub fn max(self, o: F4) -> F4 {
            F4(unsafe { _mm_max_ps(self.0, o.0) })
        }
        /// Each lane rounded toward zero to an integer: `x as i32` for every `x` an `i32` holds.
        #[inline(always)]
        pub fn trunc_i32(self) -> [i32; 4] {
            // SAFETY: an `__m128i` is four i32s.
            unsafe { std::mem::transmute::<__m128i, [i32; 4]>(_mm_cvttps_epi32(self.0)) }
        }
    }

    impl M4 {
        #[inline(always)]
        pub fn all(on: bool) -> M4 {
            M4(unsafe { _mm_castsi128_ps(_mm_set1_epi32(-(on as i32))) })
        }
        #[inline(always)]
        pub fn or(self, o: M4) -> M4 {
            M4(unsafe { _mm_or_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn and(self, o: M4) -> M4 {
            M4(unsafe { _mm_and_ps(self.0, o.0) })
        }
        /// `self & !o`.
        #[inline(always)]
        pub fn and_not(self, o: M4) -> M4 {
            M4(unsafe { _mm_andnot_ps(o.0, self.0) })
        }
        /// Bit `i` set when lane `i` is.
        #[inline(always)]
        pub fn bits(self) -> u32 {
            unsafe { _mm_movemask_ps(self.0) as u32 }
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
mod imp {
    #[derive(Clone, Copy)]
    pub struct F4([f32; 4]);

    #[derive(Clone, Copy)]
    pub struct M4([bool; 4]);

    impl F4 {
        #[inline(always)]
        pub fn splat(v: f32) -> F4 {
            F4([v; 4])
        }
        #[inline(always)]
        pub fn new(a: [f32; 4]) -> F4 {
            F4(a)
        }
        #[inline(always)]
        fn zip(self, o: F4, f: impl Fn(f32, f32) -> f32) -> F4 {
            F4(std::array::from_fn(|i| f(self.0[i], o.0[i])))
        }
        #[inline(always)]
        fn cmp(self, o: F4, f: impl Fn(f32, f32) -> bool) -> M4 {
            M4(std::array::from_fn(|i| f(self.0[i], o.0[i])))
        }
        #[inline(always)]
        pub fn sub(self, o: F4) -> F4 {
            self.zip(o, |a, b| a - b)
        }
        #[inline(always)]
        pub fn mul(self, o: F4) -> F4 {
            self.zip(o, |a, b| a * b)
        }
        #[inline(always)]
        pub fn add(self, o: F4) -> F4 {
            self.zip(o, |a, b| a + b)
        }
        #[inline(always)]
        pub fn div(self, o: F4) -> F4 {
            self.zip(o, |a, b| a / b)
        }
        #[inline(always)]
        pub fn sqrt(self) -> F4 {
            F4(self.0.map(f32::sqrt))
        }
        #[inline(always)]
        pub fn abs(self) -> F4 {
            F4(self.0.map(f32::abs))
        }
        #[inline(always)]
        pub fn flip_sign_of(self, o: F4) -> F4 {
            self.zip(o, |a, b| {
                f32::from_bits(a.to_bits() ^ (b.to_bits() & 0x8000_0000))
            })
        }
        #[inline(always)]
        pub fn ge(self, o: F4) -> M4 {
            self.cmp(o, |a, b| a >= b)
        }
        #[inline(always)]
        pub fn max_num(self, o: F4) -> F4 {
            self.zip(o, f32::max)
        }
        #[inline(always)]
        pub fn min_num(self, o: F4) -> F4 {
            self.zip(o, f32::min)
        }
        #[inline(always)]
        pub fn lt(self, o: F4) -> M4 {
            self.cmp(o, |a, b| a < b)
        }
        #[inline(always)]
        pub fn le(self, o: F4) -> M4 {
            self.cmp(o, |a, b| a <= b)
        }
        #[inline(always)]
        pub fn gt(self, o: F4) -> M4 {
            self.cmp(o, |a, b| a > b)
        }
        #[inline(always)]
        pub fn eq(self, o: F4) -> M4 {
            self.cmp(o, |a, b| a == b)
        }
        #[inline(always)]
        pub fn select(m: M4, a: F4, b: F4) -> F4 {
            F4(std::array::from_fn(
                |i| if m.0[i] { a.0[i] } else { b.0[i] },
            ))
        }
        #[inline(always)]
        pub fn min(self, o: F4) -> F4 {
            self.zip(o, f32::min)
        }
        #[inline(always)]
        pub fn max(self, o: F4) -> F4 {
            self.zip(o, f32::max)
        }
        #[inline(always)]
        pub fn trunc_i32(self) -> [i32; 4] {
            self.0.map(|x| x as i32)
        }
    }

    impl M4 {
        #[inline(always)]
        pub fn all(on: bool) -> M4 {
            M4([on; 4])
        }
        #[inline(always)]
        pub fn or(self, o: M4) -> M4 {
            M4(std::array::from_fn(|i| self.0[i] || o.0[i]))
        }
        #[inline(always)]
        pub fn and(self, o: M4) -> M4 {
            M4(std::array::from_fn(|i| self.0[i] && o.0[i]))
        }
        #[inline(always)]
        pub fn and_not(self, o: M4) -> M4 {
            M4(std::array::from_fn(|i| self.0[i] && !o.0[i]))
        }
        #[inline(always)]
        pub fn bits(self) -> u32 {
            (0..4).map(|i| (self.0[i] as u32) << i).sum()
        }
    }
}

pub use imp::{F4, M4};

/// `N` f32 lanes as the packet walk (`packet.rs`) and its triangle test (`triangle.rs`) use them:
/// each operation is the lane-wise IEEE operation, as `F4`'s are.
pub trait Lanes<const N: usize>: Copy {
    type Mask: LaneMask;
    fn splat(v: f32) -> Self;
    fn new(a: [f32; N]) -> Self;
    fn to_array(self) -> [f32; N];
    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn div(self, o: Self) -> Self;
    fn abs(self) -> Self;
    fn flip_sign_of(self, o: Self) -> Self;
    fn max_num(self, o: Self) -> Self;
    fn min_num(self, o: Self) -> Self;
    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    fn eq(self, o: Self) -> Self::Mask;
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
}

/// A comparison's result, lane by lane.
pub trait LaneMask: Copy {
    fn all(on: bool) -> Self;
    fn or(self, o: Self) -> Self;
    fn and_not(self, o: Self) -> Self;
    /// Bit `i` set when lane `i` is.
    fn bits(self) -> u32;
}

/// `Lanes` for a lane type with inherent methods of the same names (`F4`, `F8`).
macro_rules! impl_lanes {
    ($f:ident, $m:ident, $n:literal) => {
        impl $crate::accel::lanes::Lanes<$n> for $f {
            type Mask = $m;
            #[inline(always)]
            fn splat(v: f32) -> Self {
                $f::splat(v)
            }
            #[inline(always)]
            fn new(a: [f32; $n]) -> Self {
                $f::new(a)
            }
            #[inline(always)]
            fn to_array(self) -> [f32; $n] {
                $f::to_array(self)
            }
            #[inline(always)]
            fn add(self, o: Self) -> Self {
                $f::add(self, o)
            }
            #[inline(always)]
            fn sub(self, o: Self) -> Self {
                $f::sub(self, o)
            }
            #[inline(always)]
            fn mul(self, o: Self) -> Self {
                $f::mul(self, o)
            }
            #[inline(always)]
            fn div(self, o: Self) -> Self {
                $f::div(self, o)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                $f::abs(self)
            }
            #[inline(always)]
            fn flip_sign_of(self, o: Self) -> Self {
                $f::flip_sign_of(self, o)
            }
            #[inline(always)]
            fn max_num(self, o: Self) -> Self {
                $f::max_num(self, o)
            }
            #[inline(always)]
            fn min_num(self, o: Self) -> Self {
                $f::min_num(self, o)
            }
            #[inline(always)]
            fn lt(self, o: Self) -> $m {
                $f::lt(self, o)
            }
            #[inline(always)]
            fn le(self, o: Self) -> $m {
                $f::le(self, o)
            }
            #[inline(always)]
            fn gt(self, o: Self) -> $m {
                $f::gt(self, o)
            }
            #[inline(always)]
            fn ge(self, o: Self) -> $m {
                $f::ge(self, o)
            }
            #[inline(always)]
            fn eq(self, o: Self) -> $m {
                $f::eq(self, o)
            }
            #[inline(always)]
            fn select(m: $m, a: Self, b: Self) -> Self {
                $f::select(m, a, b)
            }
        }

        impl $crate::accel::lanes::LaneMask for $m {
            #[inline(always)]
            fn all(on: bool) -> Self {
                $m::all(on)
            }
            #[inline(always)]
            fn or(self, o: Self) -> Self {
                $m::or(self, o)
            }
            #[inline(always)]
            fn and_not(self, o: Self) -> Self {
                $m::and_not(self, o)
            }
            #[inline(always)]
            fn bits(self) -> u32 {
                $m::bits(self)
            }
        }
    };
}
pub(super) use impl_lanes;

impl_lanes!(F4, M4, 4);

impl F4 {
    /// A point's three coordinates in lanes 0-2, lane 3 zero.
    #[inline(always)]
    pub fn xyz(p: [f32; 3]) -> F4 {
        F4::new([p[0], p[1], p[2], 0.0])
    }

    /// `self.max(lo).min(hi)` lane by lane, as `f32::max` and `f32::min` give it, for
    /// `lo <= hi`; a NaN lane becomes `lo` (`max` yields its operand then).
    #[inline(always)]
    pub fn clamp(self, lo: F4, hi: F4) -> F4 {
        self.max(lo).min(hi)
    }

    /// The lanes as an array.
    #[inline(always)]
    pub fn to_array(self) -> [f32; 4] {
        // SAFETY: both representations are four f32s (an `__m128` or a `[f32; 4]`).
        unsafe { std::mem::transmute::<F4, [f32; 4]>(self) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_compute_what_scalars_compute() {
        let a = [1.5f32, -0.0, f32::NAN, 3.0];
        let b = [1.5f32, 0.0, 1.0, -2.0];
        let (x, y) = (F4::new(a), F4::new(b));
        // The same bits, or NaN on both sides (a NaN's payload is the hardware's choice).
        let same = |l: f32, r: f32| l.to_bits() == r.to_bits() || (l.is_nan() && r.is_nan());
        for i in 0..4 {
            assert!(same(x.sub(y).to_array()[i], a[i] - b[i]));
            assert!(same(x.mul(y).to_array()[i], a[i] * b[i]));
            assert!(same(x.add(y).to_array()[i], a[i] + b[i]));
            assert!(same(x.div(y).to_array()[i], a[i] / b[i]));
            assert!(same(y.abs().to_array()[i], b[i].abs()));
            let flipped = f32::from_bits(a[i].to_bits() ^ (b[i].to_bits() & 0x8000_0000));
            assert!(same(x.flip_sign_of(y).to_array()[i], flipped));
            assert_eq!(x.ge(y).bits() >> i & 1 == 1, a[i] >= b[i]);
            for (p, q, pv, qv) in [(x, y, a[i], b[i]), (y, x, b[i], a[i])] {
                let (max, min) = (p.max_num(q).to_array()[i], p.min_num(q).to_array()[i]);
                // Equal zeros of either sign are both right for `f32::max` and `f32::min`.
                assert!(same(max, pv.max(qv)) || (max == 0.0 && pv.max(qv) == 0.0));
                assert!(same(min, pv.min(qv)) || (min == 0.0 && pv.min(qv) == 0.0));
            }
            assert_eq!(x.lt(y).bits() >> i & 1 == 1, a[i] < b[i]);
            assert_eq!(x.le(y).bits() >> i & 1 == 1, a[i] <= b[i]);
            assert_eq!(x.gt(y).bits() >> i & 1 == 1, a[i] > b[i]);
            assert_eq!(x.eq(y).bits() >> i & 1 == 1, a[i] == b[i]);
            if !a[i].is_nan() {
                let (min, max) = (x.min(y).to_array()[i], x.max(y).to_array()[i]);
                assert!(same(min, a[i].min(b[i])) || (min == 0.0 && a[i].min(b[i]) == 0.0));
                assert!(same(max, a[i].max(b[i])) || (max == 0.0 && a[i].max(b[i]) == 0.0));
                assert_eq!(x.trunc_i32()[i], a[i] as i32);
            }
        }
        assert_eq!(
            F4::new([-2.7, 2.7, 511.99, 0.5]).trunc_i32(),
            [-2, 2, 511, 0]
        );
        let clamped = F4::new([f32::NAN, -1.0, 0.5, 9.0]).clamp(F4::splat(0.0), F4::splat(3.0));
        assert_eq!(clamped.to_array(), [0.0, 0.0, 0.5, 3.0]);
        let m = x.lt(F4::splat(2.0));
        assert_eq!(m.bits(), 0b0011);
        assert!(same(F4::select(m, x, y).to_array()[2], 1.0));
        assert_eq!(M4::all(true).and_not(m).bits(), 0b1100);
        assert_eq!(M4::all(false).or(m).bits(), 0b0011);
        assert_eq!(M4::all(true).and(m).bits(), 0b0011);
        assert_eq!(M4::all(false).and(m).bits(), 0);
    }
}
