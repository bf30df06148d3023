//! SIMD lanes: W points at a time, one lane per point, structure of arrays (one register of W
//! lanes per scalar, masks instead of branches). The lane Newton written over them is
//! `hex8/lanes.rs`; `locate/batched.rs` runs it and chooses the instruction set.
//!
//! | file | lanes |
//! |---|---|
//! | `mod.rs` | the [`Lanes`] and [`Wide`] traits every lane type implements, [`Pair`] (twice the lanes), [`V3`] (a 3-vector per lane) |
//! | `portable.rs` | one f64 (the scalar instructions) and glam's `Vec4` (4 × f32, SSE2 or NEON): no detection needed |
//! | `locate/avx.rs` | 4 × f64 and 8 × f32 in 256-bit AVX registers, private to the `#[target_feature]` entry points that detection guards |
//!
//! Without AVX2, f32 points go 4 at a time in `Vec4` and f64 points one at a time, because SSE2
//! pairs measured slower than the scalar kernel (docs/benchmarks.md has the numbers).
//!
//! Every lane type computes *exactly* what [`crate::hex8`]'s scalar kernel computes: the same IEEE
//! operations in the same order (Rust never fuses a multiply and an add on its own), so a batched
//! answer is bitwise the scalar answer.

use std::ops::{Add, BitAnd, BitOr, Mul, Not, Sub};

use glam::DVec3;

mod portable;

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
    /// glam's `max`, per component (the same for finite values).
    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        Self {
            x: self.x.max(o.x),
            y: self.y.max(o.y),
            z: self.z.max(o.z),
        }
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
impl<V: Lanes> Mul for V3<V> {
    type Output = Self;
    /// Component by component (glam's `DVec3 * DVec3`).
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self {
            x: self.x * o.x,
            y: self.y * o.y,
            z: self.z * o.z,
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
