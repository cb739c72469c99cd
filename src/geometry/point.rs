/// Largest absolute coordinate, in millimetres (about 1073 km).
///
/// With `|x| ≤ COORD_MAX` a coordinate difference is below `2^31`, a product of
/// two differences below `2^62`, and a cross product (the difference of two
/// such products) below `2^63`: every predicate fits an `i64` exactly.
pub const COORD_MAX: i32 = (1 << 30) - 1;

/// A point in the map frame, integer millimetres.
///
/// `repr(C)` and plain old data, so a compiled map's vertex section is read
/// in place as `&[Point]` (two little-endian `i32`, 8 bytes, 4-aligned).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, bytemuck::Pod, bytemuck::Zeroable)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(C)]
pub struct Point {
    /// x (forward in the ROS map frame), mm.
    pub x: i32,
    /// y (left), mm.
    pub y: i32,
}

impl Point {
    /// A point from its coordinates in millimetres.
    pub const fn new(x: i32, y: i32) -> Self {
        Self { x, y }
    }

    /// Whether both coordinates lie within `±COORD_MAX`.
    pub const fn in_range(self) -> bool {
        self.x >= -COORD_MAX && self.x <= COORD_MAX && self.y >= -COORD_MAX && self.y <= COORD_MAX
    }

    /// `self - o` widened to `i64` (exact for in-range points).
    ///
    /// Two in-range coordinates differ by at most `2·COORD_MAX < 2³¹`, so the
    /// difference is taken in `i32` and sign-extended: a compiler then knows
    /// each product of two differences is a 32 × 32 → 64-bit multiply (one
    /// `SMULL` on a Cortex-M4 instead of a full 64-bit product). Out-of-range
    /// points break every predicate's precondition anyway.
    #[inline]
    pub const fn sub(self, o: Point) -> (i64, i64) {
        (self.x.wrapping_sub(o.x) as i64, self.y.wrapping_sub(o.y) as i64)
    }

    /// Squared Euclidean distance, exact for in-range points (below 2⁶³);
    /// beyond the range it wraps, as [`dot`](super::dot) does.
    #[inline]
    pub const fn dist2(self, o: Point) -> i64 {
        let d = self.sub(o);
        super::dot(d, d)
    }
}

/// A closed segment from `a` to `b`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Segment {
    /// Start point.
    pub a: Point,
    /// End point.
    pub b: Point,
}

impl Segment {
    /// The segment from `a` to `b`.
    pub const fn new(a: Point, b: Point) -> Self {
        Self { a, b }
    }

    /// Its axis-aligned bounding box.
    pub fn bbox(&self) -> Rect {
        Rect::around(self.a).union_point(self.b)
    }
}

/// An axis-aligned rectangle with inclusive bounds, mm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Rect {
    /// Lower-left corner.
    pub min: Point,
    /// Upper-right corner.
    pub max: Point,
}

impl Rect {
    /// The degenerate rectangle holding only `p`.
    pub const fn around(p: Point) -> Self {
        Self { min: p, max: p }
    }

    /// The smallest rectangle holding `self` and `p`.
    pub fn union_point(self, p: Point) -> Self {
        Self {
            min: Point::new(self.min.x.min(p.x), self.min.y.min(p.y)),
            max: Point::new(self.max.x.max(p.x), self.max.y.max(p.y)),
        }
    }

    /// The smallest rectangle holding both.
    pub fn union(self, o: Rect) -> Self {
        self.union_point(o.min).union_point(o.max)
    }

    /// Bounding box of a non-empty point set; `None` when empty.
    pub fn of_points(pts: &[Point]) -> Option<Self> {
        let (first, rest) = pts.split_first()?;
        Some(rest.iter().fold(Rect::around(*first), |r, p| r.union_point(*p)))
    }

    /// Whether the closed rectangles share a point.
    pub const fn overlaps(&self, o: &Rect) -> bool {
        self.min.x <= o.max.x && o.min.x <= self.max.x && self.min.y <= o.max.y && o.min.y <= self.max.y
    }

    /// Whether `p` lies in the closed rectangle.
    pub const fn contains(&self, p: Point) -> bool {
        p.x >= self.min.x && p.x <= self.max.x && p.y >= self.min.y && p.y <= self.max.y
    }
}
