//! The AVX lanes (four f64 or eight f32 per 256-bit register; four f32 per 128-bit register for
//! the adaptive locator) and the only ways in to them: the `#[target_feature]` entry points,
//! which `batched.rs` calls after detection.
//!
//! The lane types are private to this module, so privacy, not a comment, guarantees that an AVX
//! value exists only inside an entry point, that is after `is_x86_feature_detected!` found AVX2
//! (and AVX-512F and AVX-512VL for the second entry point). An AVX intrinsic is `unsafe` to call
//! from a function not compiled with AVX enabled, and the lane methods are plain
//! `#[inline(always)]` functions inlined into the entry points, so each call is wrapped (`avx!`).
#![allow(unsafe_code)]

use std::arch::x86_64::{
    __m128, __m256, __m256d, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_UNORD_Q, _MM_FROUND_NO_EXC,
    _MM_FROUND_TO_ZERO, _mm_add_ps, _mm_and_ps, _mm_andnot_ps, _mm_blendv_ps, _mm_cmp_ps,
    _mm_cvtsi128_si64, _mm_div_ps, _mm_extract_epi64, _mm_max_ps, _mm_min_ps, _mm_movehl_ps,
    _mm_movelh_ps, _mm_movemask_ps, _mm_mul_ps, _mm_or_ps, _mm_set_ps, _mm_set1_ps, _mm_sub_ps,
    _mm_unpackhi_ps, _mm_unpacklo_ps, _mm_xor_ps, _mm256_add_pd, _mm256_add_ps, _mm256_and_pd,
    _mm256_and_ps, _mm256_andnot_pd, _mm256_andnot_ps, _mm256_blendv_pd, _mm256_blendv_ps,
    _mm256_castpd_si256, _mm256_castps256_ps128, _mm256_castsi256_si128, _mm256_cmp_pd,
    _mm256_cmp_ps, _mm256_cvtpd_ps, _mm256_cvtps_pd, _mm256_div_pd, _mm256_div_ps,
    _mm256_extractf128_ps, _mm256_extracti128_si256, _mm256_max_pd, _mm256_max_ps, _mm256_min_pd,
    _mm256_min_ps, _mm256_movemask_pd, _mm256_movemask_ps, _mm256_mul_pd, _mm256_mul_ps,
    _mm256_or_pd, _mm256_or_ps, _mm256_round_pd, _mm256_set_m128, _mm256_set_pd, _mm256_set_ps,
    _mm256_set1_epi64x, _mm256_set1_pd, _mm256_set1_ps, _mm256_shuffle_ps, _mm256_sqrt_pd,
    _mm256_sub_pd, _mm256_sub_ps, _mm256_unpackhi_pd, _mm256_unpackhi_ps, _mm256_unpacklo_pd,
    _mm256_unpacklo_ps, _mm256_xor_pd, _mm256_xor_ps, _mm256_xor_si256,
};
use std::ops::{Add, BitAnd, BitOr, Mul, Not, Sub};

use glam::{DVec3, Vec3A};

use crate::lanes::{Lanes, Pair, V3, Wide};

/// Calls an AVX intrinsic.
macro_rules! avx {
    ($e:expr) => {
        // SAFETY: values of these types exist only on the path entered after
        // `is_x86_feature_detected!("avx2")` (see `LatticeLocator::locate_chunk`), and these
        // intrinsics only compute on registers.
        unsafe { $e }
    };
}

/// Stamps a lane type and its mask from one 256-bit register type and its intrinsics (`_pd` for
/// f64, `_ps` for f32), so that both precisions share one definition.
macro_rules! avx_lanes {
    (
        $(#[$doc:meta])* $F:ident, $M:ident, $reg:ty, $S:ty, $W:literal, $bits:ty,
        add: $add:ident, sub: $sub:ident, mul: $mul:ident, div: $div:ident,
        and: $and:ident, or: $or:ident, xor: $xor:ident, andnot: $andnot:ident,
        max: $max:ident, min: $min:ident, cmp: $cmp:ident, blendv: $blendv:ident,
        movemask: $movemask:ident, set1: $set1:ident,
        from_fn: |$f:ident| $set:expr,
        node: $Node:ty, transpose: $transpose:ident,
        wide: $Wide:ty, narrow: |$n:ident| $narrow:expr, widen: |$w:ident| $widen:expr
    ) => {
        $(#[$doc])*
        #[derive(Clone, Copy)]
        struct $F($reg);

        /// A lane mask: all bits set where true.
        #[derive(Clone, Copy)]
        struct $M($reg);

        impl Add for $F {
            type Output = Self;
            #[inline(always)]
            fn add(self, o: Self) -> Self {
                Self(avx!($add(self.0, o.0)))
            }
        }
        impl Sub for $F {
            type Output = Self;
            #[inline(always)]
            fn sub(self, o: Self) -> Self {
                Self(avx!($sub(self.0, o.0)))
            }
        }
        impl Mul for $F {
            type Output = Self;
            #[inline(always)]
            fn mul(self, o: Self) -> Self {
                Self(avx!($mul(self.0, o.0)))
            }
        }
        impl BitAnd for $M {
            type Output = Self;
            #[inline(always)]
            fn bitand(self, o: Self) -> Self {
                Self(avx!($and(self.0, o.0)))
            }
        }
        impl BitOr for $M {
            type Output = Self;
            #[inline(always)]
            fn bitor(self, o: Self) -> Self {
                Self(avx!($or(self.0, o.0)))
            }
        }
        impl Not for $M {
            type Output = Self;
            #[inline(always)]
            fn not(self) -> Self {
                Self(avx!($xor(self.0, $set1(<$S>::from_bits(<$bits>::MAX)))))
            }
        }

        impl Lanes for $F {
            const W: usize = $W;
            type S = $S;
            type Mask = $M;
            const EPSILON: $S = <$S>::EPSILON;
            #[inline(always)]
            fn splat(v: $S) -> Self {
                Self(avx!($set1(v)))
            }
            #[inline(always)]
            fn abs(self) -> Self {
                Self(avx!($andnot($set1(-0.0), self.0)))
            }
            /// `MAXPD`/`MAXPS`: `if a > b { a } else { b }`, as glam's `DVec3::max` and
            /// `Vec3A::max` (SSE2 `MAXPS`), NaN included.
            #[inline(always)]
            fn max(self, o: Self) -> Self {
                Self(avx!($max(self.0, o.0)))
            }
            #[inline(always)]
            fn min(self, o: Self) -> Self {
                Self(avx!($min(self.0, o.0)))
            }
            #[inline(always)]
            fn recip(self) -> Self {
                Self(avx!($div($set1(1.0), self.0)))
            }
            #[inline(always)]
            fn le(self, o: Self) -> $M {
                $M(avx!($cmp::<_CMP_LE_OQ>(self.0, o.0)))
            }
            #[inline(always)]
            fn gt(self, o: Self) -> $M {
                $M(avx!($cmp::<_CMP_LT_OQ>(o.0, self.0)))
            }
            #[inline(always)]
            fn lt(self, o: Self) -> $M {
                $M(avx!($cmp::<_CMP_LT_OQ>(self.0, o.0)))
            }
            #[inline(always)]
            fn is_nan(self) -> $M {
                $M(avx!($cmp::<_CMP_UNORD_Q>(self.0, self.0)))
            }
            #[inline(always)]
            fn is_finite(self) -> $M {
                // |v| < ∞ is false for ±∞ and NaN.
                self.abs().lt(Self::splat(<$S>::INFINITY))
            }
            #[inline(always)]
            fn select(mask: $M, a: Self, b: Self) -> Self {
                Self(avx!($blendv(b.0, a.0, mask.0)))
            }
            #[inline(always)]
            fn lane(self, l: usize) -> $S {
                // SAFETY: the register and the array have the same size, and every bit pattern
                // is valid for both.
                let lanes = unsafe { std::mem::transmute::<$reg, [$S; $W]>(self.0) };
                lanes[l]
            }
            /// Built from scalars in registers (`_mm256_set_*`), not through memory: a vector
            /// load of freshly stored scalars stalls store forwarding (measured).
            #[inline(always)]
            fn from_fn($f: impl Fn(usize) -> $S) -> Self {
                Self(avx!($set))
            }
            #[inline(always)]
            fn bits(mask: $M) -> u32 {
                avx!($movemask(mask.0)) as u32
            }
            #[inline(always)]
            fn any(mask: $M) -> bool {
                avx!($movemask(mask.0)) != 0
            }
            #[inline(always)]
            fn mask_from_bits(bits: u32) -> $M {
                let all = <$S>::from_bits(<$bits>::MAX);
                $M(Self::from_fn(|l| if bits & (1 << l) != 0 { all } else { 0.0 }).0)
            }
            type Node = $Node;
            #[inline(always)]
            fn transpose<'n>(node: impl Fn(usize) -> &'n $Node) -> V3<Self> {
                let [x, y, z] = $transpose(node);
                V3 {
                    x: Self(x),
                    y: Self(y),
                    z: Self(z),
                }
            }
            type Wide = $Wide;
            #[inline(always)]
            fn narrow($n: $Wide) -> Self {
                $narrow
            }
            #[inline(always)]
            fn widen(self) -> $Wide {
                let $w = self;
                $widen
            }
        }
    };
}

/// Four `DVec3` into x, y and z registers: [x0 y0 | x2 y2] and [x1 y1 | x3 y3] unpacked.
#[inline(always)]
fn transpose_f64<'n>(node: impl Fn(usize) -> &'n DVec3) -> [__m256d; 3] {
    let n = [node(0), node(1), node(2), node(3)];
    let even = avx!(_mm256_set_pd(n[2].y, n[2].x, n[0].y, n[0].x));
    let odd = avx!(_mm256_set_pd(n[3].y, n[3].x, n[1].y, n[1].x));
    [
        avx!(_mm256_unpacklo_pd(even, odd)),
        avx!(_mm256_unpackhi_pd(even, odd)),
        avx!(_mm256_set_pd(n[3].z, n[2].z, n[1].z, n[0].z)),
    ]
}

/// Eight `Vec3A` into x, y and z registers: lanes l and l + 4 paired in one register, then the
/// 4 × 4 transpose of each 128-bit half.
#[inline(always)]
fn transpose_f32<'n>(node: impl Fn(usize) -> &'n Vec3A) -> [__m256; 3] {
    // No closures here: a closure is compiled without the caller's AVX2, and its intrinsics
    // become calls (measured: f32 19 -> 14 M points/s).
    let m: [__m128; 8] = [
        (*node(0)).into(),
        (*node(1)).into(),
        (*node(2)).into(),
        (*node(3)).into(),
        (*node(4)).into(),
        (*node(5)).into(),
        (*node(6)).into(),
        (*node(7)).into(),
    ];
    let r0 = avx!(_mm256_set_m128(m[4], m[0]));
    let r1 = avx!(_mm256_set_m128(m[5], m[1]));
    let r2 = avx!(_mm256_set_m128(m[6], m[2]));
    let r3 = avx!(_mm256_set_m128(m[7], m[3]));
    // [x0 x1 y0 y1 | x4 x5 y4 y5], [x2 x3 y2 y3 | x6 x7 y6 y7], and the same for z (and w).
    let (xy01, xy23) = (
        avx!(_mm256_unpacklo_ps(r0, r1)),
        avx!(_mm256_unpacklo_ps(r2, r3)),
    );
    let (zw01, zw23) = (
        avx!(_mm256_unpackhi_ps(r0, r1)),
        avx!(_mm256_unpackhi_ps(r2, r3)),
    );
    [
        avx!(_mm256_shuffle_ps::<0x44>(xy01, xy23)),
        avx!(_mm256_shuffle_ps::<0xEE>(xy01, xy23)),
        avx!(_mm256_shuffle_ps::<0x44>(zw01, zw23)),
    ]
}

avx_lanes!(
    /// Four f64 lanes.
    F64x4, M64x4, __m256d, f64, 4, u64,
    add: _mm256_add_pd, sub: _mm256_sub_pd, mul: _mm256_mul_pd, div: _mm256_div_pd,
    and: _mm256_and_pd, or: _mm256_or_pd, xor: _mm256_xor_pd, andnot: _mm256_andnot_pd,
    max: _mm256_max_pd, min: _mm256_min_pd, cmp: _mm256_cmp_pd, blendv: _mm256_blendv_pd,
    movemask: _mm256_movemask_pd, set1: _mm256_set1_pd,
    from_fn: |f| _mm256_set_pd(f(3), f(2), f(1), f(0)),
    node: DVec3, transpose: transpose_f64,
    wide: F64x4, narrow: |w| w, widen: |v| v
);
avx_lanes!(
    /// Eight f32 lanes.
    F32x8, M32x8, __m256, f32, 8, u32,
    add: _mm256_add_ps, sub: _mm256_sub_ps, mul: _mm256_mul_ps, div: _mm256_div_ps,
    and: _mm256_and_ps, or: _mm256_or_ps, xor: _mm256_xor_ps, andnot: _mm256_andnot_ps,
    max: _mm256_max_ps, min: _mm256_min_ps, cmp: _mm256_cmp_ps, blendv: _mm256_blendv_ps,
    movemask: _mm256_movemask_ps, set1: _mm256_set1_ps,
    from_fn: |f| _mm256_set_ps(f(7), f(6), f(5), f(4), f(3), f(2), f(1), f(0)),
    node: Vec3A, transpose: transpose_f32,
    wide: Pair<F64x4>,
    narrow: |w| Self(avx!(_mm256_set_m128(_mm256_cvtpd_ps((w.1).0), _mm256_cvtpd_ps((w.0).0)))),
    widen: |v| Pair(
        F64x4(avx!(_mm256_cvtps_pd(_mm256_castps256_ps128(v.0)))),
        F64x4(avx!(_mm256_cvtps_pd(_mm256_extractf128_ps::<1>(v.0)))),
    )
);

/// Four `Vec3A` into x, y and z registers: the 4 × 4 transpose.
#[inline(always)]
fn transpose_f32x4<'n>(node: impl Fn(usize) -> &'n Vec3A) -> [__m128; 3] {
    let m: [__m128; 4] = [
        (*node(0)).into(),
        (*node(1)).into(),
        (*node(2)).into(),
        (*node(3)).into(),
    ];
    // [x0 x1 y0 y1], [x2 x3 y2 y3], [z0 z1 w0 w1], [z2 z3 w2 w3].
    let (xy01, xy23) = (
        avx!(_mm_unpacklo_ps(m[0], m[1])),
        avx!(_mm_unpacklo_ps(m[2], m[3])),
    );
    let (zw01, zw23) = (
        avx!(_mm_unpackhi_ps(m[0], m[1])),
        avx!(_mm_unpackhi_ps(m[2], m[3])),
    );
    [
        avx!(_mm_movelh_ps(xy01, xy23)),
        avx!(_mm_movehl_ps(xy23, xy01)),
        avx!(_mm_movelh_ps(zw01, zw23)),
    ]
}

avx_lanes!(
    /// Four f32 lanes (128-bit registers, VEX-encoded), whose f64 lanes are one F64x4: the
    /// adaptive locator's f32 lanes, which then find their leaves as the f64 ones do.
    F32x4, M32x4, __m128, f32, 4, u32,
    add: _mm_add_ps, sub: _mm_sub_ps, mul: _mm_mul_ps, div: _mm_div_ps,
    and: _mm_and_ps, or: _mm_or_ps, xor: _mm_xor_ps, andnot: _mm_andnot_ps,
    max: _mm_max_ps, min: _mm_min_ps, cmp: _mm_cmp_ps, blendv: _mm_blendv_ps,
    movemask: _mm_movemask_ps, set1: _mm_set1_ps,
    from_fn: |f| _mm_set_ps(f(3), f(2), f(1), f(0)),
    node: Vec3A, transpose: transpose_f32x4,
    wide: F64x4,
    narrow: |w| Self(avx!(_mm256_cvtpd_ps(w.0))),
    widen: |v| F64x4(avx!(_mm256_cvtps_pd(v.0)))
);

impl Wide for F64x4 {
    #[inline(always)]
    fn trunc(self) -> Self {
        Self(avx!(_mm256_round_pd::<
            { _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC },
        >(self.0)))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Self(avx!(_mm256_sqrt_pd(self.0)))
    }
    #[inline(always)]
    fn indices_into(self, out: &mut [usize]) {
        // v + 2^52 holds an integer v in [0, 2^52) in its low 52 bits, exactly: four
        // conversions in two instructions, where `as usize` costs a dozen per lane (it saturates).
        const TWO_52: f64 = 4_503_599_627_370_496.0;
        let shifted = avx!(_mm256_add_pd(self.0, _mm256_set1_pd(TWO_52)));
        let v = avx!(_mm256_xor_si256(
            _mm256_castpd_si256(shifted),
            _mm256_set1_epi64x(TWO_52.to_bits() as i64)
        ));
        let (low, high) = (
            avx!(_mm256_castsi256_si128(v)),
            avx!(_mm256_extracti128_si256::<1>(v)),
        );
        out[0] = avx!(_mm_cvtsi128_si64(low)) as usize;
        out[1] = avx!(_mm_extract_epi64::<1>(low)) as usize;
        out[2] = avx!(_mm_cvtsi128_si64(high)) as usize;
        out[3] = avx!(_mm_extract_epi64::<1>(high)) as usize;
    }
}

use super::{Answer, LatticeLocator};
use crate::settings::Precision;

impl LatticeLocator<'_> {
    /// The batch in AVX registers, the whole of it compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must have AVX2 (`is_x86_feature_detected!("avx2")`).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn locate_chunk_avx2(&self, points: &[DVec3], out: &mut [Answer]) {
        self.locate_chunk_avx::<false>(points, out);
    }

    /// [`Self::locate_chunk_avx2`] reading the locator's copy over the box of the body's nodes
    /// (f64 only). A function of its own: the two variants in one body cost the full block 6 %.
    ///
    /// # Safety
    /// The CPU must have AVX2 (`is_x86_feature_detected!("avx2")`).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn locate_chunk_avx2_boxed(&self, points: &[DVec3], out: &mut [Answer]) {
        self.locate_chunk_avx::<true>(points, out);
    }

    /// The same 256-bit lanes compiled with AVX-512VL as well: the compiler then has 32 vector
    /// registers instead of 16, and spills less (docs/benchmarks.md has the measured gain). The
    /// operations are the same IEEE operations, so the answers are the same bits.
    ///
    /// # Safety
    /// The CPU must have AVX2, AVX-512F and AVX-512VL.
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    pub(super) unsafe fn locate_chunk_avx512(&self, points: &[DVec3], out: &mut [Answer]) {
        self.locate_chunk_avx::<false>(points, out);
    }

    /// [`Self::locate_chunk_avx512`] reading the locator's box copy.
    ///
    /// # Safety
    /// The CPU must have AVX2, AVX-512F and AVX-512VL.
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    pub(super) unsafe fn locate_chunk_avx512_boxed(&self, points: &[DVec3], out: &mut [Answer]) {
        self.locate_chunk_avx::<true>(points, out);
    }

    /// The AVX lanes of the settings' precision; inlined into the caller's instruction set.
    #[inline(always)]
    fn locate_chunk_avx<const BOXED: bool>(&self, points: &[DVec3], out: &mut [Answer]) {
        match self.settings.precision {
            Precision::F32 => self.locate_chunk_with::<F32x8, false>(points, out),
            Precision::F64 => self.locate_chunk_with::<F64x4, BOXED>(points, out),
        }
    }

    /// The warm start's lanes (`warm.rs`) in AVX registers, compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must have AVX2 (`is_x86_feature_detected!("avx2")`).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn relocate_chunk_avx2(&self, points: &[DVec3], answers: &mut [Answer]) {
        self.relocate_chunk_avx(points, answers);
    }

    /// The same compiled with AVX-512VL as well (32 vector registers; the same IEEE operations).
    ///
    /// # Safety
    /// The CPU must have AVX2, AVX-512F and AVX-512VL.
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    pub(super) unsafe fn relocate_chunk_avx512(&self, points: &[DVec3], answers: &mut [Answer]) {
        self.relocate_chunk_avx(points, answers);
    }

    /// The warm start's AVX lanes of the settings' precision.
    #[inline(always)]
    fn relocate_chunk_avx(&self, points: &[DVec3], answers: &mut [Answer]) {
        match self.settings.precision {
            Precision::F32 => self.relocate_chunk_with::<F32x8>(points, answers),
            Precision::F64 => self.relocate_chunk_with::<F64x4>(points, answers),
        }
    }
}

impl crate::adaptive::AdaptiveLocator<'_> {
    /// The adaptive locator's lanes in AVX registers, the whole of it compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must have AVX2 (`is_x86_feature_detected!("avx2")`).
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn locate_chunk_avx2(
        &self,
        points: &[DVec3],
        out: &mut [Answer],
        memo: bool,
    ) {
        self.locate_chunk_avx(points, out, memo);
    }

    /// The same compiled with AVX-512VL as well (32 vector registers; the same IEEE operations).
    ///
    /// # Safety
    /// The CPU must have AVX2, AVX-512F and AVX-512VL.
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    pub(crate) unsafe fn locate_chunk_avx512(
        &self,
        points: &[DVec3],
        out: &mut [Answer],
        memo: bool,
    ) {
        self.locate_chunk_avx(points, out, memo);
    }

    /// The AVX lanes of the settings' precision, remembering each batch's leaves for the next
    /// with `memo` (points sorted by leaf); inlined into the caller's instruction set.
    #[inline(always)]
    fn locate_chunk_avx(&self, points: &[DVec3], out: &mut [Answer], memo: bool) {
        if memo {
            self.locate_chunk_avx_with::<true>(points, out);
        } else {
            self.locate_chunk_avx_with::<false>(points, out);
        }
    }

    /// [`Self::locate_chunk_avx`] for one value of `memo`.
    #[inline(always)]
    fn locate_chunk_avx_with<const MEMO: bool>(&self, points: &[DVec3], out: &mut [Answer]) {
        use crate::hex8::{Hex8Map, Hex8Map32};
        match self.settings().precision {
            Precision::F32 if self.one_level.is_some() => {
                self.locate_chunk_lanes::<Hex8Map32, F32x8, MEMO>(points, out);
            }
            Precision::F32 => self.locate_chunk_lanes::<Hex8Map32, F32x4, MEMO>(points, out),
            Precision::F64 => self.locate_chunk_lanes::<Hex8Map, F64x4, MEMO>(points, out),
        }
    }

    /// The warm start's lanes in AVX registers, compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must have AVX2 (`is_x86_feature_detected!("avx2")`).
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn relocate_chunk_avx2(&self, points: &[DVec3], answers: &mut [Answer]) {
        self.relocate_chunk_avx(points, answers);
    }

    /// The same compiled with AVX-512VL as well (32 vector registers; the same IEEE operations).
    ///
    /// # Safety
    /// The CPU must have AVX2, AVX-512F and AVX-512VL.
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    pub(crate) unsafe fn relocate_chunk_avx512(&self, points: &[DVec3], answers: &mut [Answer]) {
        self.relocate_chunk_avx(points, answers);
    }

    /// The warm start's AVX lanes of the settings' precision.
    #[inline(always)]
    fn relocate_chunk_avx(&self, points: &[DVec3], answers: &mut [Answer]) {
        match self.settings().precision {
            Precision::F32 => self.relocate_chunk_lanes::<F32x8>(points, answers),
            Precision::F64 => self.relocate_chunk_lanes::<F64x4>(points, answers),
        }
    }
}
