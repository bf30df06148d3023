//! Batched location: the lattice locator's common case, W points at a time, one SIMD lane per point.
//!
//! Almost every point is found by one Newton inversion in its predicted cell (inversions per located
//! point are 1.0001–1.09 on the seed's scenes). That path is branch-light arithmetic, so
//! `locate_all` runs it across W points at once, structure of arrays: one register of W lanes per
//! scalar, with masks instead of branches. Lane types ([`Lanes`]): with AVX2 (detected at run time)
//! 4 × f64 or 8 × f32 in 256-bit registers; without it 4 × f32 in glam's `Vec4` (SSE2 on x86_64,
//! NEON on aarch64), and f64 points one at a time, because SSE2 pairs measured slower than the
//! scalar kernel. docs/benchmarks.md has the numbers.
//!
//! The lanes compute *exactly* what [`crate::hex8`]'s scalar kernel computes: the same IEEE
//! operations in the same order (Rust never fuses a multiply and an add on its own), so a batched
//! answer is bitwise the scalar answer. Every lane that leaves the common path (inactive predicted
//! cell, a singular Jacobian, a line search, an early or late `Outside`, a non-finite value, the
//! iteration limit) is marked, and its point is answered by the scalar search from scratch. Tests
//! check the identity point by point, forcing each lane type in turn.
//!
//! An AVX intrinsic is `unsafe` to call from a function not compiled with AVX enabled, and the lane
//! methods are plain `#[inline(always)]` functions (inlined into the `#[target_feature]` entry
//! points of `locate/batched.rs`), so each call is wrapped. It is sound because AVX lane values exist only
//! behind those entry points, which run only after detection found AVX2 (and AVX-512VL for the
//! second); each wrapped call is one register operation.

use std::ops::{Add, BitAnd, BitOr, Mul, Not, Sub};

use glam::DVec3;

use crate::hex8::{self, NewtonOptions};

/// A float type the lanes compute in: f64 or f32.
pub(crate) trait Real:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self>
{
    fn of(v: f64) -> Self;
    fn wide(self) -> f64;
}

impl Real for f64 {
    #[inline(always)]
    fn of(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn wide(self) -> f64 {
        self
    }
}

impl Real for f32 {
    #[inline(always)]
    fn of(v: f64) -> Self {
        v as f32
    }
    #[inline(always)]
    fn wide(self) -> f64 {
        f64::from(self)
    }
}

/// The most lanes of any lane type (the size of per-lane scratch arrays).
pub(crate) const MAX_W: usize = 8;

/// `W` lanes of one precision, with the operations the kernel uses, each exactly as glam's `DVec3`
/// (f64) or `Vec3A` (f32) does it per component. Masks convert to bits: lane `l` is bit `l`.
/// Implemented by glam's `Vec4` (4 × f32, SSE2 or NEON) and, with AVX2, by the 256-bit lane types
/// of `locate/avx.rs`, private to the module that holds the `#[target_feature]` entry points.
pub(crate) trait Lanes:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self>
{
    /// Number of lanes, at most [`MAX_W`].
    const W: usize;
    type S: Real;
    type Mask: Copy
        + BitAnd<Output = Self::Mask>
        + BitOr<Output = Self::Mask>
        + Not<Output = Self::Mask>;
    const EPSILON: Self::S;
    fn splat(v: Self::S) -> Self;
    fn abs(self) -> Self;
    fn max(self, other: Self) -> Self;
    fn min(self, other: Self) -> Self;
    fn recip(self) -> Self;
    fn le(self, other: Self) -> Self::Mask;
    fn gt(self, other: Self) -> Self::Mask;
    fn lt(self, other: Self) -> Self::Mask;
    fn is_nan(self) -> Self::Mask;
    fn is_finite(self) -> Self::Mask;
    /// `if mask { a } else { b }` per lane.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;
    fn lane(self, l: usize) -> Self::S;
    /// Lane `l` is `f(l)`.
    fn from_fn(f: impl Fn(usize) -> Self::S) -> Self;
    fn bits(mask: Self::Mask) -> u32;
    fn any(mask: Self::Mask) -> bool;
    fn mask_from_bits(bits: u32) -> Self::Mask;
    /// How the displacements these lanes read are stored, one per node: `DVec3` (the body's own) for
    /// f64 lanes, `Vec3A` (the locator's f32 copy, rounded as `as_vec3a` rounds) for f32 lanes.
    type Node: Copy;
    /// W nodes, `node(l)` in lane `l`, transposed into x, y and z registers.
    fn transpose<'n>(node: impl Fn(usize) -> &'n Self::Node) -> V3<Self>
    where
        Self::Node: 'n;
    /// f64 lanes, as many: the per-point bookkeeping runs there, in f64 as in the scalar search.
    type Wide: Wide;
    /// Each lane rounded to this precision (as `as f32` rounds), or unchanged in f64.
    fn narrow(wide: Self::Wide) -> Self;
    /// Each lane widened to f64 (exact).
    fn widen(self) -> Self::Wide;
}

/// f64 lanes for the per-point bookkeeping (the lattice hash, the guess, the local frame, the
/// answer): the points' own `DVec3` transposed in, and two operations more.
pub(crate) trait Wide: Lanes<S = f64, Node = DVec3> {
    /// Truncation toward zero, exact for lanes in [0, 2^32) (lattice indices).
    fn trunc(self) -> Self;
    fn sqrt(self) -> Self;
    /// Each lane as an index into `out[l]`, exactly, for lanes holding integers in [0, 2^52).
    fn indices_into(self, out: &mut [usize]);
}

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

/// Twice the lanes of `L`: lanes 0..L::W in the first, the rest in the second.
#[derive(Clone, Copy)]
pub(crate) struct Pair<L>(pub L, pub L);

macro_rules! pair_op {
    ($Trait:ident, $f:ident) => {
        impl<L: $Trait<Output = L>> $Trait for Pair<L> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                Pair(self.0.$f(o.0), self.1.$f(o.1))
            }
        }
    };
}
pair_op!(Add, add);
pair_op!(Sub, sub);
pair_op!(Mul, mul);
pair_op!(BitAnd, bitand);
pair_op!(BitOr, bitor);

impl<M: Not<Output = M>> Not for Pair<M> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        Pair(!self.0, !self.1)
    }
}

impl<L: Lanes> Lanes for Pair<L> {
    const W: usize = 2 * L::W;
    type S = L::S;
    type Mask = Pair<L::Mask>;
    const EPSILON: L::S = L::EPSILON;
    #[inline(always)]
    fn splat(v: L::S) -> Self {
        Pair(L::splat(v), L::splat(v))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Pair(self.0.abs(), self.1.abs())
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        Pair(self.0.max(o.0), self.1.max(o.1))
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        Pair(self.0.min(o.0), self.1.min(o.1))
    }
    #[inline(always)]
    fn recip(self) -> Self {
        Pair(self.0.recip(), self.1.recip())
    }
    #[inline(always)]
    fn le(self, o: Self) -> Self::Mask {
        Pair(self.0.le(o.0), self.1.le(o.1))
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self::Mask {
        Pair(self.0.gt(o.0), self.1.gt(o.1))
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self::Mask {
        Pair(self.0.lt(o.0), self.1.lt(o.1))
    }
    #[inline(always)]
    fn is_nan(self) -> Self::Mask {
        Pair(self.0.is_nan(), self.1.is_nan())
    }
    #[inline(always)]
    fn is_finite(self) -> Self::Mask {
        Pair(self.0.is_finite(), self.1.is_finite())
    }
    #[inline(always)]
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self {
        Pair(L::select(mask.0, a.0, b.0), L::select(mask.1, a.1, b.1))
    }
    #[inline(always)]
    fn lane(self, l: usize) -> L::S {
        if l < L::W {
            self.0.lane(l)
        } else {
            self.1.lane(l - L::W)
        }
    }
    #[inline(always)]
    fn from_fn(f: impl Fn(usize) -> L::S) -> Self {
        Pair(L::from_fn(&f), L::from_fn(|l| f(l + L::W)))
    }
    #[inline(always)]
    fn bits(mask: Self::Mask) -> u32 {
        L::bits(mask.0) | L::bits(mask.1) << L::W
    }
    #[inline(always)]
    fn any(mask: Self::Mask) -> bool {
        L::any(mask.0 | mask.1)
    }
    #[inline(always)]
    fn mask_from_bits(bits: u32) -> Self::Mask {
        Pair(L::mask_from_bits(bits), L::mask_from_bits(bits >> L::W))
    }
    type Node = L::Node;
    #[inline(always)]
    fn transpose<'n>(node: impl Fn(usize) -> &'n L::Node) -> V3<Self>
    where
        L::Node: 'n,
    {
        let (a, b) = (L::transpose(&node), L::transpose(|l| node(l + L::W)));
        V3 {
            x: Pair(a.x, b.x),
            y: Pair(a.y, b.y),
            z: Pair(a.z, b.z),
        }
    }
    type Wide = Pair<L::Wide>;
    #[inline(always)]
    fn narrow(wide: Self::Wide) -> Self {
        Pair(L::narrow(wide.0), L::narrow(wide.1))
    }
    #[inline(always)]
    fn widen(self) -> Self::Wide {
        Pair(self.0.widen(), self.1.widen())
    }
}

impl<L: Wide> Wide for Pair<L> {
    #[inline(always)]
    fn trunc(self) -> Self {
        Pair(self.0.trunc(), self.1.trunc())
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Pair(self.0.sqrt(), self.1.sqrt())
    }
    #[inline(always)]
    fn indices_into(self, out: &mut [usize]) {
        let (low, high) = out.split_at_mut(L::W);
        self.0.indices_into(low);
        self.1.indices_into(high);
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

/// A 3-vector per lane, with glam's operation order (dot = (x x' + y y') + z z', and its cross).
#[derive(Clone, Copy)]
pub(crate) struct V3<V> {
    pub x: V,
    pub y: V,
    pub z: V,
}

impl<V: Lanes> V3<V> {
    #[inline(always)]
    fn map(self, f: impl Fn(V) -> V) -> Self {
        Self {
            x: f(self.x),
            y: f(self.y),
            z: f(self.z),
        }
    }
    /// Each component times the lane's scalar `s`.
    #[inline(always)]
    pub fn scale(self, s: V) -> Self {
        self.map(|c| c * s)
    }
    #[inline(always)]
    pub fn dot(self, o: Self) -> V {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        Self {
            x: self.y * o.z - o.y * self.z,
            y: self.z * o.x - o.z * self.x,
            z: self.x * o.y - o.x * self.y,
        }
    }
    #[inline(always)]
    pub fn abs(self) -> Self {
        self.map(V::abs)
    }
    /// glam's `max_element`: max(x, max(y, z)), max(a, b) = if a > b { a } else { b }.
    #[inline(always)]
    pub fn max_element(self) -> V {
        let max = |a: V, b: V| V::select(a.gt(b), a, b);
        max(self.x, max(self.y, self.z))
    }
    /// glam's `element_sum`: (x + y) + z.
    #[inline(always)]
    pub fn element_sum(self) -> V {
        self.x + self.y + self.z
    }
    /// glam's `clamp(lo, hi)`: max(lo) then min(hi), per component.
    #[inline(always)]
    pub fn clamp(self, lo: V::S, hi: V::S) -> Self {
        self.map(|c| c.max(V::splat(lo)).min(V::splat(hi)))
    }
    #[inline(always)]
    pub fn is_finite(self) -> V::Mask {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }
    #[inline(always)]
    pub fn select(mask: V::Mask, a: Self, b: Self) -> Self {
        Self {
            x: V::select(mask, a.x, b.x),
            y: V::select(mask, a.y, b.y),
            z: V::select(mask, a.z, b.z),
        }
    }
    /// Each lane rounded to this precision.
    #[inline(always)]
    pub fn narrow(wide: V3<V::Wide>) -> Self {
        Self {
            x: V::narrow(wide.x),
            y: V::narrow(wide.y),
            z: V::narrow(wide.z),
        }
    }
    /// Each lane widened to f64.
    #[inline(always)]
    pub fn widen(self) -> V3<V::Wide> {
        V3 {
            x: self.x.widen(),
            y: self.y.widen(),
            z: self.z.widen(),
        }
    }
    /// Every lane `v`.
    #[inline(always)]
    pub fn splat(v: DVec3) -> Self {
        Self {
            x: V::splat(V::S::of(v.x)),
            y: V::splat(V::S::of(v.y)),
            z: V::splat(V::S::of(v.z)),
        }
    }
    /// Each component times the matching component of `v` (glam's `DVec3 * DVec3`).
    #[inline(always)]
    pub fn mul_each(self, v: DVec3) -> Self {
        Self {
            x: self.x * V::splat(V::S::of(v.x)),
            y: self.y * V::splat(V::S::of(v.y)),
            z: self.z * V::splat(V::S::of(v.z)),
        }
    }
    /// Lane `l` as an f64 vector.
    #[inline(always)]
    pub fn lane(&self, l: usize) -> DVec3 {
        DVec3::new(
            self.x.lane(l).wide(),
            self.y.lane(l).wide(),
            self.z.lane(l).wide(),
        )
    }
}

impl<V: Lanes> Add for V3<V> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }
}
impl<V: Lanes> Sub for V3<V> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }
}

/// W trilinear maps: monomial coefficients 1, ξ, η, ξη, ζ, ξζ, ηζ, ξηζ (as [`crate::hex8::Hex8Map`]).
#[derive(Clone, Copy)]
pub(crate) struct Maps<V> {
    pub a: [V3<V>; 8],
}

impl<V: Lanes> Maps<V> {
    /// The maps of W hexahedra whose corner `c` in lane `l` is `node(l, c)`.
    #[inline(always)]
    pub fn from_nodes<'n>(node: impl Fn(usize, usize) -> &'n V::Node) -> Self
    where
        V::Node: 'n,
    {
        // Written out: `array::from_fn`'s closure is not inlined into the caller's AVX2 context, and
        // a loop over a zeroed array costs a memset call.
        let corner = |c: usize| V::transpose(|l| node(l, c));
        Self::new(&[
            corner(0),
            corner(1),
            corner(2),
            corner(3),
            corner(4),
            corner(5),
            corner(6),
            corner(7),
        ])
    }

    /// The maps of W hexahedra with corners `c` (VTK order): `Hex8Map::new`'s butterfly, the same code.
    #[inline(always)]
    pub fn new(c: &[V3<V>; 8]) -> Self {
        let eighth = V::splat(V::S::of(0.125));
        Self {
            a: hex8::monomials(c, |v: V3<V>| v.scale(eighth)),
        }
    }

    /// `Kernel::add_lattice`: the undeformed part h (1 + ξ) / 2 per axis (zeros added too, as there).
    #[inline(always)]
    pub fn add_lattice(&mut self, h: DVec3) {
        let half = h * 0.5;
        let (hx, hy, hz) = (
            V::splat(V::S::of(half.x)),
            V::splat(V::S::of(half.y)),
            V::splat(V::S::of(half.z)),
        );
        let zero = V::splat(V::S::of(0.0));
        let a = &mut self.a;
        a[0] = a[0]
            + V3 {
                x: hx,
                y: hy,
                z: hz,
            };
        a[1] = a[1]
            + V3 {
                x: hx,
                y: zero,
                z: zero,
            };
        a[2] = a[2]
            + V3 {
                x: zero,
                y: hy,
                z: zero,
            };
        a[4] = a[4]
            + V3 {
                x: zero,
                y: zero,
                z: hz,
            };
    }

    /// x(ξ) and the columns of J: `Hex8Map::map_and_jacobian`, the same code.
    #[inline(always)]
    pub fn map_and_jacobian(&self, xi: V3<V>) -> (V3<V>, [V3<V>; 3]) {
        hex8::map_and_jacobian(&self.a, xi.x, xi.y, xi.z, V3::scale)
    }

    /// x(ξ): `Hex8Map::map`, the same code.
    #[inline(always)]
    pub fn map(&self, xi: V3<V>) -> V3<V> {
        hex8::map(&self.a, xi.x, xi.y, xi.z, V3::scale)
    }

    /// `Hex8Map::magnitude`.
    #[inline(always)]
    fn magnitude(&self, x: V3<V>) -> V {
        let a = &self.a;
        x.abs().max_element()
            + a[0].abs().max_element()
            + (a[1].abs() + a[2].abs() + a[4].abs()).max_element()
    }

    /// `Hex8Map::step_noise`.
    #[inline(always)]
    fn step_noise(&self, magnitude: V, k: [V3<V>; 3], inv_det: V) -> V {
        let zero = V::splat(V::S::of(0.0));
        let inverse_norm = zero
            .max(k[0].abs().element_sum())
            .max(k[1].abs().element_sum())
            .max(k[2].abs().element_sum())
            * inv_det.abs();
        V::splat(V::S::of(16.0)) * V::splat(V::EPSILON) * magnitude * inverse_norm
    }

    /// `Hex8Map::det_at_center`.
    #[inline(always)]
    fn det_at_center(&self) -> V {
        self.a[1].dot(self.a[2].cross(self.a[4]))
    }

    /// The common path of `Hex8Map::invert` for W points at once: plain Newton steps, no line search.
    /// `inside` is 1 + each lane's inside tolerance. Lanes with `take` unset are ignored. Returns, per
    /// lane, the final ξ, |residual|², the iterations and whether the lane ended `Inside` on the common
    /// path (the scalar kernel then gives exactly this answer); a lane not `Inside` must be redone.
    #[inline(always)]
    pub fn invert(
        &self,
        x: V3<V>,
        xi0: V3<V>,
        inside: V,
        take: V::Mask,
        options: &NewtonOptions,
    ) -> (V3<V>, V, [u32; MAX_W], u32) {
        let tol = V::splat(V::S::of(options.tol));
        let det_floor = V::splat(V::S::of(options.det_ratio_min)) * self.det_at_center().abs();
        // The scalar kernel's safeguards (`hex8`), so that both loops take the same decisions.
        let line_search_above = V::splat(V::S::of(hex8::LINE_SEARCH_ABOVE));
        let early_outside_step = V::splat(V::S::of(hex8::EARLY_OUTSIDE_STEP));
        let early_outside = inside + V::splat(V::S::of(hex8::EARLY_OUTSIDE_MARGIN));
        let (low, high) = (V::S::of(-hex8::NEWTON_BOX), V::S::of(hex8::NEWTON_BOX));
        let magnitude = self.magnitude(x);
        let mut xi = xi0.clamp(V::S::of(-1.0), V::S::of(1.0));
        let (fx, mut jac) = self.map_and_jacobian(xi);
        let mut r = x - fx;
        let mut rr = r.dot(r);
        let mut pending = take;
        let mut found = V::mask_from_bits(0);
        let mut iterations = [0u32; MAX_W];
        for iteration in 1..=options.max_iter {
            let [c0, c1, c2] = jac;
            let k0 = c1.cross(c2);
            let det = c0.dot(k0);
            let singular = det.is_nan() | det.le(det_floor);
            let (k1, k2) = (c2.cross(c0), c0.cross(c1));
            let inv_det = det.recip();
            let delta = V3 {
                x: k0.dot(r),
                y: k1.dot(r),
                z: k2.dot(r),
            }
            .scale(inv_det);
            let size = delta.abs().max_element();
            let converged =
                size.le(tol) | size.le(self.step_noise(magnitude, [k0, k1, k2], inv_det));
            // The converged lanes take the full step; the others the step clamped to the box.
            let sum = xi + delta;
            let trial = V3::select(converged, sum, sum.clamp(low, high));
            let (f_trial, jac_trial) = self.map_and_jacobian(trial);
            let r_trial = x - f_trial;
            let rr_trial = r_trial.dot(r_trial);
            let finite = trial.is_finite() & rr_trial.is_finite() & delta.is_finite();
            let far = trial.abs().max_element();
            // Converged: Inside, or (Outside / not finite) left to the scalar search.
            let inside_now = pending & !singular & converged & finite & far.le(inside);
            // Not converged: a step the scalar kernel would shorten (line search), a non-finite value
            // or an early Outside all leave the common path.
            let line_search = rr_trial.gt(rr) & size.gt(line_search_above);
            let moved = (trial - xi).abs().max_element();
            let early_out = moved.lt(early_outside_step) & far.gt(early_outside);
            let go_on = pending & !(converged | singular | line_search | early_out) & finite;
            let keep = inside_now | go_on;
            xi = V3::select(keep, trial, xi);
            rr = V::select(keep, rr_trial, rr);
            r = V3::select(go_on, r_trial, r);
            jac = [
                V3::select(go_on, jac_trial[0], jac[0]),
                V3::select(go_on, jac_trial[1], jac[1]),
                V3::select(go_on, jac_trial[2], jac[2]),
            ];
            let now = V::bits(inside_now);
            for (l, iterations) in iterations.iter_mut().enumerate().take(V::W) {
                if now & (1 << l) != 0 {
                    *iterations = iteration;
                }
            }
            found = found | inside_now;
            pending = go_on;
            if !V::any(pending) {
                break;
            }
        }
        (xi, rr, iterations, V::bits(found))
    }
}
