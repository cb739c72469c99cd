//! A window placed in the map: an annular sector with an integer apex and
//! integer edge directions, and the exact tests on it.
//!
//! The wedge `|φ| ≤ θ_o` is bounded by two rays whose directions are integer
//! vectors of length about 2¹⁴ (angles resolved to 0.0035°); membership and
//! clipping are then exact rational arithmetic, with squared distances of
//! clipped points compared in 256 bits ([`U256`]). Floats only place the
//! window (trigonometry of the heading) and report positions.

use crate::geometry::{cross, dot, Convex, Frac, ParamRange, Point, Rect, U256};

use super::WindowError;
use crate::f32math::sin_cos;

/// Length of the integer direction vectors.
const DIR_SCALE: f32 = 16384.0;

/// A sensor window in the map frame.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sector {
    /// The transducer's position, mm.
    pub apex: Point,
    /// The transducer's heading in the map frame, radians (counter-clockwise from +x).
    pub heading_rad: f32,
    /// `θ_o`, radians.
    pub half_angle_rad: f32,
    /// `R_min`, mm.
    pub r_min_mm: u32,
    /// `R_max`, mm.
    pub r_max_mm: u32,
    axis: (i64, i64),
    left: (i64, i64),
    right: (i64, i64),
    /// cos and sin of the heading, computed once.
    unit: (f32, f32),
}

fn dir(angle: f32) -> (i64, i64) {
    let (s, c) = sin_cos(angle);
    // |·| ≤ 2¹⁴: through i32, which the FPU converts.
    (libm::roundf(c * DIR_SCALE) as i32 as i64, libm::roundf(s * DIR_SCALE) as i32 as i64)
}

impl Sector {
    /// A window at `apex` looking along `heading_rad`, half-angle
    /// `half_angle_rad` (in `(0, π/2)`), ranges `r_min_mm ..= r_max_mm`.
    pub fn new(
        apex: Point,
        heading_rad: f32,
        half_angle_rad: f32,
        r_min_mm: u32,
        r_max_mm: u32,
    ) -> Result<Self, WindowError> {
        if !(half_angle_rad > 0.0 && half_angle_rad < core::f32::consts::FRAC_PI_2) {
            return Err(WindowError::BadHalfAngle);
        }
        if r_max_mm == 0 || r_max_mm > super::MAX_RANGE_MM || r_min_mm >= r_max_mm || !heading_rad.is_finite() {
            return Err(WindowError::BadRange);
        }
        let reach = r_max_mm as i64 + 2;
        let lim = crate::geometry::COORD_MAX as i64;
        if (apex.x as i64).abs() + reach > lim || (apex.y as i64).abs() + reach > lim {
            return Err(WindowError::BadRange);
        }
        // Into [0, 2π): a heading of many turns would otherwise swallow the
        // half-angle in f32 rounding (and the box below would never end).
        let heading_rad = {
            let r = libm::fmodf(heading_rad, core::f32::consts::TAU);
            let r = if r < 0.0 { r + core::f32::consts::TAU } else { r };
            if r >= core::f32::consts::TAU {
                0.0
            } else {
                r
            }
        };
        Ok(Self {
            apex,
            heading_rad,
            half_angle_rad,
            r_min_mm,
            r_max_mm,
            axis: dir(heading_rad),
            left: dir(heading_rad + half_angle_rad),
            right: dir(heading_rad - half_angle_rad),
            unit: {
                let (s, c) = sin_cos(heading_rad);
                (c, s)
            },
        })
    }

    /// Whether a vector from the apex lies in the closed wedge `|φ| ≤ θ_o`.
    #[inline]
    fn in_wedge(&self, v: (i64, i64)) -> bool {
        cross(self.right, v) >= 0 && cross(v, self.left) >= 0
    }

    /// Whether the box lies wholly outside the wedge `|φ| ≤ θ_o` (strictly
    /// beyond one of its two edges' lines): then nothing in it meets the
    /// sector. Exact; a cheap filter before the per-edge tests.
    #[inline]
    pub fn box_outside_wedge(&self, b: &Rect) -> bool {
        let corners = [b.min, Point::new(b.max.x, b.min.y), b.max, Point::new(b.min.x, b.max.y)];
        let (mut right, mut left) = (true, true);
        for c in corners {
            let v = c.sub(self.apex);
            right &= cross(self.right, v) < 0;
            left &= cross(v, self.left) < 0;
        }
        right || left
    }

    /// Exact: whether `p` lies in the closed annular sector.
    pub fn contains(&self, p: Point) -> bool {
        let v = p.sub(self.apex);
        // Non-negative for an in-range point; squares of `u32` fit `u64`.
        let d2 = dot(v, v) as u64;
        let (rmin, rmax) = (u64::from(self.r_min_mm), u64::from(self.r_max_mm));
        self.in_wedge(v) && d2 >= rmin * rmin && d2 <= rmax * rmax
    }

    /// A box holding the whole sector (conservative by a millimetre).
    pub fn bbox(&self) -> Rect {
        let r = self.r_max_mm as f32 + 1.0;
        let mut b = Rect::around(self.apex);
        let at = |a: f32| {
            let (s, c) = sin_cos(a);
            // `new` keeps the apex R_max + 2 inside ±COORD_MAX: exact there
            // (saturating only for fields changed afterwards).
            Point::new(
                self.apex.x.saturating_add(libm::roundf(c * r) as i32),
                self.apex.y.saturating_add(libm::roundf(s * r) as i32),
            )
        };
        let (lo, hi) = (self.heading_rad - self.half_angle_rad, self.heading_rad + self.half_angle_rad);
        b = b.union_point(at(lo)).union_point(at(hi));
        // Axis-aligned extremes of the arc that fall inside the wedge.
        // The heading is in [0, 2π) and θ_o < π/2: at most three quarter-turns lie inside.
        let mut k = libm::ceilf(lo / core::f32::consts::FRAC_PI_2);
        let mut n = 0;
        while k * core::f32::consts::FRAC_PI_2 <= hi && n < 4 {
            b = b.union_point(at(k * core::f32::consts::FRAC_PI_2));
            k += 1.0;
            n += 1;
        }
        Rect {
            min: Point::new(b.min.x.saturating_sub(1), b.min.y.saturating_sub(1)),
            max: Point::new(b.max.x.saturating_add(1), b.max.y.saturating_add(1)),
        }
    }

    /// The map point at sensor-frame coordinates `(x lateral, y along the
    /// normal)`, rounded to the millimetre, or `None` beyond `±COORD_MAX`.
    /// Lateral `x` points to the right of the heading.
    pub fn to_map(&self, x: f32, y: f32) -> Option<Point> {
        let (c, s) = self.unit;
        let (dx, dy) = (libm::roundf(x * s + y * c), libm::roundf(-x * c + y * s));
        // Finite and well inside i64 before converting; then range-checked.
        if !(dx.abs() <= 4.0e9 && dy.abs() <= 4.0e9) {
            return None;
        }
        let px = i64::from(self.apex.x).checked_add(dx as i64)?;
        let py = i64::from(self.apex.y).checked_add(dy as i64)?;
        let lim = crate::geometry::COORD_MAX as u64;
        (px.unsigned_abs() <= lim && py.unsigned_abs() <= lim).then(|| Point::new(px as i32, py as i32))
    }

    /// The unit vector of the axis (map frame).
    pub fn axis_unit(&self) -> (f32, f32) {
        self.unit
    }

    /// Clips edge `a → b` to the wedge (not yet to the ranges).
    pub(crate) fn clip_edge(&self, a: Point, b: Point) -> Option<ParamRange> {
        let ao = a.sub(self.apex);
        let e = b.sub(a);
        let mut r = ParamRange::UNIT;
        let inside =
            r.cut(cross(self.right, ao), cross(self.right, e)) && r.cut(cross(ao, self.left), cross(e, self.left));
        inside.then_some(r)
    }

    /// Compares the distance from the apex of the point `a + s·e` with `r`:
    /// `|(a−o)·den + num·e|²` against `r²·den²`, in 256 bits.
    fn cmp_dist(&self, a: Point, e: (i64, i64), s: Frac, r: u32) -> core::cmp::Ordering {
        let ao = a.sub(self.apex);
        if let Some(o) = cmp_dist_filtered(ao, e, s, r) {
            return o;
        }
        let x = ao.0 as i128 * s.den as i128 + s.num as i128 * e.0 as i128;
        let y = ao.1 as i128 * s.den as i128 + s.num as i128 * e.1 as i128;
        let lhs = U256::square(x).add(U256::square(y));
        let r2 = (r as u128) * (r as u128);
        let d2 = s.den.unsigned_abs() as u128 * s.den.unsigned_abs() as u128;
        lhs.cmp(&U256::mul(r2, d2))
    }

    fn at_least(&self, a: Point, e: (i64, i64), s: Frac, r: u32) -> bool {
        self.cmp_dist(a, e, s, r).is_ge()
    }

    /// Exact: does the closed edge `a → b` contain a point of the sector?
    pub fn edge_meets(&self, a: Point, b: Point) -> bool {
        self.edge_window(a, b).is_some()
    }

    /// Exact: if the closed edge `a → b` contains a point of the sector, the
    /// part `[lo, hi]` of it inside the wedge, as parameters along the edge
    /// (not yet cut to the ranges); `None` if the edge misses the sector.
    pub fn edge_window(&self, a: Point, b: Point) -> Option<(f32, f32)> {
        let c = self.clip_edge(a, b)?;
        let e = b.sub(a);
        // The farther clipped end must reach R_min, the nearest point R_max.
        let far_ok = self.at_least(a, e, c.lo, self.r_min_mm) || self.at_least(a, e, c.hi, self.r_min_mm);
        (far_ok && self.nearest_within(a, e, c, self.r_max_mm)).then(|| (c.lo.to_f32(), c.hi.to_f32()))
    }

    /// Whether the clipped edge's nearest point to the apex is within `r`.
    fn nearest_within(&self, a: Point, e: (i64, i64), c: ParamRange, r: u32) -> bool {
        let oa = self.apex.sub(a);
        let ee = dot(e, e) as i128;
        if ee == 0 {
            return self.cmp_dist(a, e, c.lo, r).is_le();
        }
        let foot = Frac { num: dot(oa, e), den: ee as i64 };
        let s = if foot.lt(c.lo) {
            c.lo
        } else if c.hi.lt(foot) {
            c.hi
        } else {
            // The foot: squared distance cross²/|e|², exact in u128.
            let cr = cross(e, oa).unsigned_abs();
            let r2 = r as u64 * r as u64;
            // In u64 unless a side overflows it (then that side is larger).
            return match (cr.checked_mul(cr), r2.checked_mul(ee as u64)) {
                (Some(l), Some(rh)) => l <= rh,
                (None, Some(_)) => false,
                (Some(_), None) => true,
                // `ee` is a non-negative i64 here: through u64, so the
                // compiler sees both products of 64-bit values.
                (None, None) => (cr as u128) * (cr as u128) <= (r2 as u128) * (ee as u64 as u128),
            };
        };
        self.cmp_dist(a, e, s, r).is_le()
    }

    /// Exact: does the closed piece share a point with the closed sector?
    ///
    /// `P ∩ W` (the piece cut by the wedge) is convex, so the distances of its
    /// points from the apex form an interval; the piece meets the sector when
    /// that interval meets `[R_min, R_max]`. Its extremes lie on the piece's
    /// edges clipped to the wedge (or at the apex, when the apex is inside).
    pub fn meets(&self, piece: Convex<'_>) -> bool {
        // Fast accept: a vertex in the sector (cheap i64 tests).
        if piece.vertices().iter().any(|&v| self.contains(v)) {
            return true;
        }
        let apex_inside = piece.tvector(self.apex).is_inside();
        let (mut near, mut far) = (apex_inside, false);
        for i in 0..piece.edge_count() {
            let (a, b) = piece.edge(i);
            let Some(c) = self.clip_edge(a, b) else { continue };
            let e = b.sub(a);
            if !far {
                far = self.at_least(a, e, c.lo, self.r_min_mm) || self.at_least(a, e, c.hi, self.r_min_mm);
            }
            if !near {
                near = self.nearest_within(a, e, c, self.r_max_mm);
            }
            if near && far {
                return true;
            }
        }
        false
    }

    /// The nearest point of the piece inside the wedge within `R_max`
    /// (ignoring `R_min`), as (distance, point relative to the map origin),
    /// in `f64`; `None` if none. This is `predict --geometric`.
    pub fn nearest(&self, piece: Convex<'_>) -> Option<(f64, (f64, f64))> {
        let o = (self.apex.x as f64, self.apex.y as f64);
        if piece.tvector(self.apex).is_inside() {
            return Some((0.0, o));
        }
        let mut best: Option<(f64, (f64, f64))> = None;
        // Exact decision on R_max (the f64 distance only reports it).
        let mut within = false;
        for i in 0..piece.edge_count() {
            let (a, b) = piece.edge(i);
            let Some(c) = self.clip_edge(a, b) else { continue };
            let e = b.sub(a);
            within = within || self.nearest_within(a, e, c, self.r_max_mm);
            let ee = dot(e, e) as f64;
            let oa = self.apex.sub(a);
            let (lo, hi) = (c.lo.to_f64(), c.hi.to_f64());
            let s = if ee == 0.0 { lo } else { (dot(oa, e) as f64 / ee).max(lo).min(hi) };
            let p = (a.x as f64 + s * e.0 as f64, a.y as f64 + s * e.1 as f64);
            let d = libm::hypot(p.0 - o.0, p.1 - o.1);
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, p));
            }
        }
        best.filter(|_| within)
    }
}

/// [`Sector::cmp_dist`] decided in `f32` when the answer is clear: `None`
/// near a tie (or outside the bound's assumptions), for the exact test.
///
/// The bound: with `s = num/den ∈ [0, 1]`, integers below 2²⁴ (converted
/// exactly) and `u = 2⁻²⁴`, the computed `s` is within `4u·s`, each computed
/// coordinate `p` within `6u·|e| + u·|p|`, and the computed `|p|²` within
/// about `20·M²·u` of the true one, `M = |ao|₁ + |e|₁`. The margin used,
/// `M²/2¹⁶ + r²/2²⁰`, is more than twelve times that, rounding of the margin
/// and of `r²` included.
fn cmp_dist_filtered(ao: (i64, i64), e: (i64, i64), s: Frac, r: u32) -> Option<core::cmp::Ordering> {
    const LIM: i64 = 1 << 24;
    let fits = |v: i64| -LIM < v && v < LIM;
    if !(fits(ao.0) && fits(ao.1) && fits(e.0) && fits(e.1)) || r >= 1 << 24 {
        return None;
    }
    let (num, den) = (i32::try_from(s.num).ok()?, i32::try_from(s.den).ok()?);
    if !(0 <= num && num <= den && den > 0) {
        return None;
    }
    let sf = num as f32 / den as f32;
    let f = |v: i64| v as i32 as f32;
    let (px, py) = (f(ao.0) + sf * f(e.0), f(ao.1) + sf * f(e.1));
    let d2 = px * px + py * py;
    let rf = r as f32;
    let r2 = rf * rf;
    let m = (ao.0.abs() + ao.1.abs() + e.0.abs() + e.1.abs()) as i32 as f32;
    let tol = m * m * (1.0 / 65_536.0) + r2 * (1.0 / 1_048_576.0);
    if d2 > r2 + tol {
        Some(core::cmp::Ordering::Greater)
    } else if d2 < r2 - tol {
        Some(core::cmp::Ordering::Less)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    const fn p(x: i32, y: i32) -> Point {
        Point::new(x, y)
    }

    fn east() -> Sector {
        // At the origin, looking along +x, ±30°, 500..5000 mm.
        Sector::new(p(0, 0), 0.0, 30f32.to_radians(), 500, 5000).unwrap()
    }

    #[test]
    fn membership() {
        let s = east();
        assert!(s.contains(p(1000, 0)));
        assert!(!s.contains(p(400, 0)), "inside R_min");
        assert!(s.contains(p(500, 0)) && s.contains(p(5000, 0)), "closed ranges");
        assert!(!s.contains(p(5001, 0)));
        assert!(s.contains(p(1000, 577)) && !s.contains(p(1000, 578)), "tan 30° = 0.57735");
        assert!(!s.contains(p(-1000, 0)));
    }

    #[test]
    fn pieces_meet_the_sector_exactly() {
        let s = east();
        // A wall across the axis at x = 3000.
        let w = [p(3000, -100), p(3000, 100)];
        assert!(s.meets(Convex::new(&w).unwrap()));
        // Beyond R_max, and just within it.
        let far = [p(5001, -10), p(5001, 10)];
        assert!(!s.meets(Convex::new(&far).unwrap()));
        let edge = [p(5000, -10), p(5000, 10)];
        assert!(s.meets(Convex::new(&edge).unwrap()), "touching the arc at (5000, 0)");
        // Inside R_min only.
        let near = [p(100, -10), p(100, 10)];
        assert!(!s.meets(Convex::new(&near).unwrap()));
        // A piece that straddles R_min: clipped edges reach beyond it.
        let sq = [p(300, -50), p(700, -50), p(700, 50), p(300, 50)];
        assert!(s.meets(Convex::new(&sq).unwrap()));
        // Outside the wedge, though within range.
        let side = [p(1000, 700), p(1100, 700), p(1100, 800), p(1000, 800)];
        assert!(!s.meets(Convex::new(&side).unwrap()));
        // A piece that contains the apex and reaches out of R_min.
        let around = [p(-100, -100), p(800, -100), p(800, 100), p(-100, 100)];
        assert!(s.meets(Convex::new(&around).unwrap()));
        // Contains the apex but everything of it in the wedge is nearer than R_min.
        let small = [p(-100, -100), p(300, -100), p(300, 100), p(-100, 100)];
        assert!(!s.meets(Convex::new(&small).unwrap()));
        // A long wall passing beside the window: its nearest point is outside
        // the wedge, but part of it lies inside at range.
        let pass = [p(-3000, 1500), p(6000, 1500)];
        assert!(s.meets(Convex::new(&pass).unwrap()), "(2598..4770, 1500) is inside");
        let pass_far = [p(-3000, 2600), p(6000, 2600)];
        assert!(!s.meets(Convex::new(&pass_far).unwrap()), "y = 2600 meets the wedge only beyond 5000 mm");
    }

    #[test]
    fn nearest_point_in_the_wedge() {
        let s = east();
        let w = [p(3000, -100), p(3000, 100)];
        let (d, q) = s.nearest(Convex::new(&w).unwrap()).unwrap();
        assert!((d - 3000.0).abs() < 1e-9 && q == (3000.0, 0.0));
        // Nearest point clipped to the wedge's edge.
        let wall = [p(-3000, 1500), p(6000, 1500)];
        let (d, _) = s.nearest(Convex::new(&wall).unwrap()).unwrap();
        assert!((d - 3000.0).abs() < 1.0, "1500 / sin 30° = 3000, got {d}");
    }

    #[test]
    fn bbox_holds_the_sector() {
        for h in [0.0f32, 0.7, 1.6, 3.0, -2.2, 5.5] {
            let s = Sector::new(p(100, -200), h, 0.6, 0, 3000).unwrap();
            let b = s.bbox();
            for k in 0..=64 {
                let a = h - 0.6 + 1.2 * k as f32 / 64.0;
                let q = p(100 + (libm::cosf(a) * 3000.0) as i32, -200 + (libm::sinf(a) * 3000.0) as i32);
                assert!(b.contains(q), "heading {h}: {q:?} outside {b:?}");
            }
            assert!(b.contains(p(100, -200)));
        }
    }

    #[test]
    fn filtered_distance_agrees_with_the_exact_comparison() {
        // Random clipped points against random radii, many of them near a
        // tie: whenever the filter decides, it decides as the 256-bit test.
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move |m: u64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x % m
        };
        let s = Sector::new(p(0, 0), 0.0, 0.5, 0, 100_000).unwrap();
        let (mut decided, mut near) = (0, 0);
        for i in 0..200_000 {
            let big = if i % 3 == 0 { 20_000_000 } else { 20_000 };
            let a = p(next(big) as i32 - big as i32 / 2, next(big) as i32 - big as i32 / 2);
            let e = (next(big) as i64 - big as i64 / 2, next(big) as i64 - big as i64 / 2);
            let den = next(1 << 30) as i64 + 1;
            let frac = Frac { num: next(den as u64 + 1) as i64, den };
            let ao = a.sub(s.apex);
            // Half the radii at the point's own distance, rounded: near ties.
            let d = ((ao.0 as f64 + frac.to_f64() * e.0 as f64).hypot(ao.1 as f64 + frac.to_f64() * e.1 as f64)) as i64;
            let r = if i % 2 == 0 { (d + next(3) as i64 - 1).clamp(0, 99_999) as u32 } else { next(100_000) as u32 };
            let ao_exact = {
                let x = ao.0 as i128 * frac.den as i128 + frac.num as i128 * e.0 as i128;
                let y = ao.1 as i128 * frac.den as i128 + frac.num as i128 * e.1 as i128;
                let d2 = frac.den.unsigned_abs() as u128 * frac.den.unsigned_abs() as u128;
                U256::square(x).add(U256::square(y)).cmp(&U256::mul(r as u128 * r as u128, d2))
            };
            match cmp_dist_filtered(ao, e, frac, r) {
                Some(o) => {
                    decided += 1;
                    assert_eq!(o, ao_exact, "a {a:?} e {e:?} s {frac:?} r {r}");
                }
                None => near += 1,
            }
        }
        assert!(decided > 150_000 && near > 100, "decided {decided}, left to the exact test {near}");
    }

    #[test]
    fn a_box_outside_the_wedge_has_no_point_in_it() {
        // Brute force: every integer point of a box the filter rejects lies
        // outside the wedge; and boxes straddling the axis are never rejected.
        let s = Sector::new(p(100, -200), 0.7, 0.26, 0, 5000).unwrap();
        let mut rejected = 0;
        for x0 in (-3000..3000).step_by(250) {
            for y0 in (-3000..3000).step_by(250) {
                let b = Rect { min: p(x0, y0), max: p(x0 + 140, y0 + 90) };
                if s.box_outside_wedge(&b) {
                    rejected += 1;
                    for x in b.min.x..=b.max.x {
                        for y in b.min.y..=b.max.y {
                            assert!(!s.in_wedge(p(x, y).sub(s.apex)), "({x}, {y}) in a rejected box {b:?}");
                        }
                    }
                }
            }
        }
        assert!(rejected > 300, "only {rejected} boxes rejected");
        let on_axis = Rect { min: p(1000, 600), max: p(1200, 900) };
        assert!(!s.box_outside_wedge(&on_axis));
    }
}
