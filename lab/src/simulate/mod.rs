//! The simulator and what runs on it: a route through the map, wheel
//! odometry, a physical sonar independent of the predictor ([`world`]), and
//! the core's verdicts, threshold method and EKF run on the readings
//! ([`filters`]), the way the firmware runs them; figures ([`figures`]) and
//! the JSON report ([`mod@report`]). The `simulate` command itself, which also
//! writes scenarios, recordings and runs on lidar scans, is
//! [`crate::simulate_cmd`], above the rooms it uses.

pub mod agreement;
pub mod figures;
pub mod filters;
pub mod localization;
pub mod places;
pub mod report;
pub mod world;

pub use crate::files::{check_writable, error_plot_path, write_all};
pub use report::{apply_start, log_of, motion_f64, report, rows_of, start_of, to_records, BOUNDS, START_SIGMA};
