//! Integer-millimetre geometry with exact predicates.
//!
//! Coordinates are `i32` millimetres bounded by [`COORD_MAX`], so that every
//! difference fits in 31 bits and every cross or dot product of two
//! differences fits in an `i64` without overflow. All *decisions* (which side,
//! whether two things meet) are made with these exact integers.

mod clip;
mod convex;
mod holes;
mod isqrt;
mod point;
mod predicates;
mod split;
mod wide;

pub(crate) use clip::{Frac, ParamRange};
pub use convex::{Convex, ConvexError, MAX_BUFFERED_VERTICES, MAX_PIECE_VERTICES};
pub use holes::{split_convex_with_holes, strictly_inside, HolesError, Ring};
pub use isqrt::isqrt;
pub use point::{Point, Rect, Segment, COORD_MAX};
pub use predicates::{cross, dot, orient, point_on_segment, segments_intersect, Side};
pub use split::{ring_area2, split_convex, SplitError};
pub use wide::U256;
