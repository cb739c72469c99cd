//! A ring of transducers on the robot: mounts, placement, one prediction each.

use super::{predict, PredictError, PredictParams, PredictStats, Prediction};
use crate::credence::Credence;
use crate::geometry::Point;
use crate::map::MapSource;
use crate::window::Window;

/// The robot's pose in the map frame (ROS: x forward, y left, heading
/// counter-clockwise from +x).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pose {
    /// x, mm.
    pub x_mm: f32,
    /// y, mm.
    pub y_mm: f32,
    /// Heading, radians.
    pub heading_rad: f32,
}

/// Where a transducer sits on the robot: position in the robot frame and the
/// direction its normal points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Mount {
    /// x (forward), mm.
    pub x_mm: i32,
    /// y (left), mm.
    pub y_mm: i32,
    /// Heading of the normal, millidegrees counter-clockwise from forward.
    pub heading_mdeg: i32,
}

const fn m(x: i32, y: i32, deg: i32) -> Mount {
    Mount { x_mm: x, y_mm: y, heading_mdeg: deg * 1000 }
}

/// The Pioneer 16-sonar ring (DESIGN §5): eight forward, eight aft.
pub const PIONEER16: [Mount; 16] = [
    m(75, 130, 90),
    m(115, 115, 50),
    m(150, 80, 30),
    m(170, 25, 10),
    m(170, -25, -10),
    m(150, -80, -30),
    m(115, -115, -50),
    m(75, -130, -90),
    m(-155, -130, -90),
    m(-195, -115, -130),
    m(-230, -80, -150),
    m(-250, -25, -170),
    m(-250, 25, 170),
    m(-230, 80, 150),
    m(-195, 115, 130),
    m(-155, 130, 90),
];

/// The transducer's position (rounded to the mm) and heading in the map:
/// `pose ∘ mount`.
pub fn place_sensor(pose: &Pose, mount: &Mount) -> (Point, f32) {
    // Reduced first: the f32 sine and cosine hold their precision within ±200 rad.
    let h = if pose.heading_rad.abs() > 100.0 {
        libm::fmodf(pose.heading_rad, core::f32::consts::TAU)
    } else {
        pose.heading_rad
    };
    let (s, c) = crate::f32math::sin_cos(h);
    let (mx, my) = (mount.x_mm as f32, mount.y_mm as f32);
    let x = pose.x_mm + c * mx - s * my;
    let y = pose.y_mm + s * mx + c * my;
    let heading = pose.heading_rad + (mount.heading_mdeg as f32 / 1000.0).to_radians();
    (Point::new(libm::roundf(x) as i32, libm::roundf(y) as i32), heading)
}

/// Predicts one transducer: its window placed at `pose ∘ mount`.
pub fn predict_mount<M: MapSource + ?Sized, K: Credence + ?Sized>(
    map: &M,
    pose: &Pose,
    mount: &Mount,
    params: &PredictParams,
    credence: &K,
) -> Result<(Option<Prediction>, PredictStats), PredictError> {
    let (apex, heading) = place_sensor(pose, mount);
    let window = Window::place_for(&params.window, apex, heading, params.strategy)?;
    predict(map, &window, params, credence)
}

/// Predicts every transducer of a ring for one pose into `out` (one slot per
/// mount; `out` must be at least as long as `mounts`). Returns the summed
/// work counts.
pub fn predict_ring<M: MapSource + ?Sized, K: Credence + ?Sized>(
    map: &M,
    pose: &Pose,
    mounts: &[Mount],
    params: &PredictParams,
    credence: &K,
    out: &mut [Option<Prediction>],
) -> Result<PredictStats, PredictError> {
    let mut total = PredictStats::default();
    for (mount, slot) in mounts.iter().zip(out.iter_mut()) {
        let (p, st) = predict_mount(map, pose, mount, params, credence)?;
        *slot = p;
        total += st;
    }
    Ok(total)
}
