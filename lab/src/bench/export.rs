//! The bench's windows for the firmware (`--bin bench_windows`), so the
//! emulated Cortex-M4 times the very windows the host timed. Little-endian:
//!
//! | offset | field |
//! |---|---|
//! | 0 | magic `ECBW`, version u32 = 1 |
//! | 8 | windows n, half-angle (m°), R_max (mm): u32 ×3 |
//! | 20 | CRC-32 of the map blob the windows were made on: u32 |
//! | 24 | grid: width, height (cells), cell (mm): u32 ×3; origin x, y (mm): i32 ×2 |
//! | 44 | n windows: apex x, y (mm) i32 ×2, heading (rad) f32 |
//! | … | n host answers, exact: range mm f32 (−1: nothing in range) |
//! | … | n host answers, Bresenham 1°: range mm f32 (−1: nothing) |
//! | … | the grid's cells as bits, row-major (bit k%8 of byte k/8) |

use std::path::Path;

use super::grid::Grid;
use super::Win;
use crate::map::{AlignedBytes, LabError};

pub fn write(
    out: &Path,
    wins: &[Win],
    exact: &[Option<f64>],
    bresenham: &[Option<f64>],
    grid: &Grid,
    half_deg: f64,
    map: &AlignedBytes,
) -> Result<(), LabError> {
    let mut b = Vec::new();
    let u32s = |b: &mut Vec<u8>, v: u32| b.extend_from_slice(&v.to_le_bytes());
    b.extend_from_slice(b"ECBW");
    u32s(&mut b, 1);
    u32s(&mut b, wins.len() as u32);
    u32s(&mut b, (half_deg * 1000.0).round() as u32);
    u32s(&mut b, super::R_MAX_MM);
    u32s(&mut b, echoloc::map::crc32(map.bytes()));
    u32s(&mut b, grid.w as u32);
    u32s(&mut b, grid.h as u32);
    u32s(&mut b, (grid.res * 1000.0).round() as u32);
    b.extend_from_slice(&((grid.x0 * 1000.0).round() as i32).to_le_bytes());
    b.extend_from_slice(&((grid.y0 * 1000.0).round() as i32).to_le_bytes());
    for w in wins {
        b.extend_from_slice(&w.apex.x.to_le_bytes());
        b.extend_from_slice(&w.apex.y.to_le_bytes());
        b.extend_from_slice(&w.heading.to_le_bytes());
    }
    for answers in [exact, bresenham] {
        for r in answers {
            b.extend_from_slice(&r.map_or(-1.0f32, |m| (m * 1000.0) as f32).to_le_bytes());
        }
    }
    b.extend_from_slice(&grid.packed_bits());
    std::fs::write(out, b).map_err(|e| LabError(format!("--export-windows {}: {e}", out.display())))
}
