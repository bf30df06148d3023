//! The lanes every target has: one f64 (the scalar instructions) and glam's `Vec4` (4 × f32).

use glam::DVec3;

use super::{Lanes, Pair, V3, Wide};

/// One f64 lane: the scalar instructions, with the lane types' semantics (`max` is MAXPD's
/// `if a > b { a } else { b }`). Pairs of it make the wide lanes of the portable f32 path.
impl Lanes for f64 {
    const W: usize = 1;
    type S = f64;
    type Mask = bool;
    const EPSILON: f64 = f64::EPSILON;
    #[inline(always)]
    fn splat(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        if self > o { self } else { o }
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        if self < o { self } else { o }
    }
    #[inline(always)]
    fn recip(self) -> Self {
        1.0 / self
    }
    #[inline(always)]
    fn le(self, o: Self) -> bool {
        self <= o
    }
    #[inline(always)]
    fn gt(self, o: Self) -> bool {
        self > o
    }
    #[inline(always)]
    fn lt(self, o: Self) -> bool {
        self < o
    }
    #[inline(always)]
    fn is_nan(self) -> bool {
        f64::is_nan(self)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    #[inline(always)]
    fn select(mask: bool, a: Self, b: Self) -> Self {
        if mask { a } else { b }
    }
    #[inline(always)]
    fn lane(self, _: usize) -> f64 {
        self
    }
    #[inline(always)]
    fn from_fn(f: impl Fn(usize) -> f64) -> Self {
        f(0)
    }
    #[inline(always)]
    fn bits(mask: bool) -> u32 {
        u32::from(mask)
    }
    #[inline(always)]
    fn any(mask: bool) -> bool {
        mask
    }
    #[inline(always)]
    fn mask_from_bits(bits: u32) -> bool {
        bits & 1 != 0
    }
    type Node = DVec3;
    #[inline(always)]
    fn transpose<'n>(node: impl Fn(usize) -> &'n DVec3) -> V3<Self> {
        let n = node(0);
        V3 {
            x: n.x,
            y: n.y,
            z: n.z,
        }
    }
    type Wide = f64;
    #[inline(always)]
    fn narrow(wide: f64) -> Self {
        wide
    }
    #[inline(always)]
    fn widen(self) -> f64 {
        self
    }
}

impl Wide for f64 {
    #[inline(always)]
    fn trunc(self) -> Self {
        // `as` truncates (and saturates); no libm call, unlike `f64::trunc` without SSE4.1.
        self as u32 as f64
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn indices_into(self, out: &mut [usize]) {
        out[0] = self as usize;
    }
}

/// 4 × f32 in glam's `Vec4`: SSE2 or NEON, the instructions of its `Vec3A` (the scalar f32 kernel).
impl Lanes for glam::Vec4 {
    const W: usize = 4;
    type S = f32;
    type Mask = glam::BVec4A;
    const EPSILON: f32 = f32::EPSILON;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        glam::Vec4::splat(v)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        glam::Vec4::abs(self)
    }
    #[inline(always)]
    fn max(self, other: Self) -> Self {
        glam::Vec4::max(self, other)
    }
    #[inline(always)]
    fn min(self, other: Self) -> Self {
        glam::Vec4::min(self, other)
    }
    #[inline(always)]
    fn recip(self) -> Self {
        glam::Vec4::recip(self)
    }
    #[inline(always)]
    fn le(self, other: Self) -> glam::BVec4A {
        self.cmple(other)
    }
    #[inline(always)]
    fn gt(self, other: Self) -> glam::BVec4A {
        self.cmpgt(other)
    }
    #[inline(always)]
    fn lt(self, other: Self) -> glam::BVec4A {
        self.cmplt(other)
    }
    #[inline(always)]
    fn is_nan(self) -> glam::BVec4A {
        self.is_nan_mask()
    }
    #[inline(always)]
    fn is_finite(self) -> glam::BVec4A {
        self.is_finite_mask()
    }
    #[inline(always)]
    fn select(mask: glam::BVec4A, a: Self, b: Self) -> Self {
        glam::Vec4::select(mask, a, b)
    }
    #[inline(always)]
    fn lane(self, l: usize) -> f32 {
        self[l]
    }
    #[inline(always)]
    fn from_fn(f: impl Fn(usize) -> f32) -> Self {
        glam::Vec4::new(f(0), f(1), f(2), f(3))
    }
    #[inline(always)]
    fn bits(mask: glam::BVec4A) -> u32 {
        mask.bitmask()
    }
    #[inline(always)]
    fn any(mask: glam::BVec4A) -> bool {
        mask.any()
    }
    #[inline(always)]
    fn mask_from_bits(bits: u32) -> glam::BVec4A {
        <glam::BVec4A>::new(bits & 1 != 0, bits & 2 != 0, bits & 4 != 0, bits & 8 != 0)
    }
    type Node = glam::Vec3A;
    #[inline(always)]
    fn transpose<'n>(node: impl Fn(usize) -> &'n glam::Vec3A) -> V3<Self> {
        let n = [node(0), node(1), node(2), node(3)];
        V3 {
            x: glam::Vec4::new(n[0].x, n[1].x, n[2].x, n[3].x),
            y: glam::Vec4::new(n[0].y, n[1].y, n[2].y, n[3].y),
            z: glam::Vec4::new(n[0].z, n[1].z, n[2].z, n[3].z),
        }
    }
    type Wide = Pair<Pair<f64>>;
    #[inline(always)]
    fn narrow(w: Self::Wide) -> Self {
        glam::Vec4::new(w.0.0 as f32, w.0.1 as f32, w.1.0 as f32, w.1.1 as f32)
    }
    #[inline(always)]
    fn widen(self) -> Self::Wide {
        let w = self.as_dvec4();
        Pair(Pair(w.x, w.y), Pair(w.z, w.w))
    }
}
