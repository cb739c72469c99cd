//! Back out of the blob: GeoJSON of the true pieces, and a PNG preview of
//! the pieces over the occupancy grid they came from.

use echoloc::map::{MapSource, ObstacleKind};
use serde_json::{json, Value};

use super::ros::{Cell, Grid};
use super::Unknown;

fn metres(v: i32) -> f64 {
    v as f64 / 1000.0
}

/// A FeatureCollection with one Feature per obstacle: a MultiPolygon of its
/// convex pieces (true outlines, counter-clockwise, metres; the pieces of one
/// obstacle share edges) for a solid, a MultiLineString for a wall.
/// Importing it again gives the same pieces.
pub fn geojson<M: MapSource + ?Sized>(m: &M) -> Value {
    let mut feats = Vec::new();
    for (i, o) in m.obstacles_iter().enumerate() {
        let pieces = (o.first_piece..o.first_piece + o.piece_count).filter_map(|id| m.piece(id));
        let coords: Vec<Value> = pieces
            .map(|p| {
                let v = p.shape.vertices();
                let mut ring: Vec<Value> = v.iter().map(|q| json!([metres(q.x), metres(q.y)])).collect();
                if o.kind == ObstacleKind::Solid {
                    ring.push(ring[0].clone());
                    json!([ring])
                } else {
                    json!(ring)
                }
            })
            .collect();
        let (ty, kind) = match o.kind {
            ObstacleKind::Solid => ("MultiPolygon", "solid"),
            ObstacleKind::Wall => ("MultiLineString", "wall"),
        };
        feats.push(json!({
            "type": "Feature",
            "properties": { "obstacle": i, "kind": kind, "pieces": o.piece_count },
            "geometry": { "type": ty, "coordinates": coords },
        }));
    }
    json!({ "type": "FeatureCollection", "features": feats })
}

/// An RGB canvas with a map-frame transform.
/// A picture in map millimetres (y up), for previews and the simulator's figures.
pub struct Canvas {
    w: usize,
    h: usize,
    px: Vec<[u8; 3]>,
    /// Map x (mm) of the left edge, map y (mm) of the top edge, mm per pixel.
    x0: f64,
    y1: f64,
    mm_per_px: f64,
}

impl Canvas {
    fn to_px(&self, x: f64, y: f64) -> (f64, f64) {
        ((x - self.x0) / self.mm_per_px, (self.y1 - y) / self.mm_per_px)
    }

    fn blend(&mut self, x: i64, y: i64, c: [u8; 3], a: f64) {
        if x < 0 || y < 0 || x >= self.w as i64 || y >= self.h as i64 {
            return;
        }
        let p = &mut self.px[y as usize * self.w + x as usize];
        for k in 0..3 {
            p[k] = (p[k] as f64 * (1.0 - a) + c[k] as f64 * a).round() as u8;
        }
    }

    /// A line in map mm, `width` pixels wide.
    pub fn line(&mut self, a: (f64, f64), b: (f64, f64), c: [u8; 3], width: i64) {
        let (p, q) = (self.to_px(a.0, a.1), self.to_px(b.0, b.1));
        let n = ((q.0 - p.0).abs().max((q.1 - p.1).abs()).ceil() as usize).max(1);
        let r = width / 2;
        for s in 0..=n {
            let t = s as f64 / n as f64;
            let (x, y) = ((p.0 + (q.0 - p.0) * t).floor() as i64, (p.1 + (q.1 - p.1) * t).floor() as i64);
            for dx in -r..width - r {
                for dy in -r..width - r {
                    self.blend(x + dx, y + dy, c, 1.0);
                }
            }
        }
    }

    /// Fills a counter-clockwise convex polygon given in map mm.
    pub fn fill_convex(&mut self, v: &[(f64, f64)], c: [u8; 3], a: f64) {
        let p: Vec<(f64, f64)> = v.iter().map(|&(x, y)| self.to_px(x, y)).collect();
        let (xmin, xmax) = p.iter().fold((f64::MAX, f64::MIN), |(lo, hi), q| (lo.min(q.0), hi.max(q.0)));
        let (ymin, ymax) = p.iter().fold((f64::MAX, f64::MIN), |(lo, hi), q| (lo.min(q.1), hi.max(q.1)));
        for y in ymin.floor().max(0.0) as i64..=ymax.ceil().min(self.h as f64) as i64 {
            for x in xmin.floor().max(0.0) as i64..=xmax.ceil().min(self.w as f64) as i64 {
                let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
                // Pixel rows grow downwards: counter-clockwise in the map is
                // clockwise here, so inside is right of every edge.
                let inside = (0..p.len()).all(|i| {
                    let (a, b) = (p[i], p[(i + 1) % p.len()]);
                    (b.0 - a.0) * (cy - a.1) - (b.1 - a.1) * (cx - a.0) <= 0.0
                });
                if inside {
                    self.blend(x, y, c, a);
                }
            }
        }
    }

    /// Text at pixel (x, y) top-left, `scale` pixels per font dot.
    pub fn text(&mut self, x: i64, y: i64, s: &str, scale: i64, c: [u8; 3]) {
        for (k, ch) in s.chars().enumerate() {
            let g = crate::credence::plot::glyph(ch);
            for (row, bits) in g.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        for dy in 0..scale {
                            for dx in 0..scale {
                                let px = x + (k as i64 * 6 + col) * scale + dx;
                                self.blend(px, y + row as i64 * scale + dy, c, 1.0);
                            }
                        }
                    }
                }
            }
        }
    }

    /// The canvas as an RGB PNG.
    pub fn png(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, self.w as u32, self.h as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        // Writing into a Vec cannot fail for a well-sized buffer.
        if let Ok(mut wr) = enc.write_header() {
            let data: Vec<u8> = self.px.iter().flatten().copied().collect();
            let _ = wr.write_image_data(&data);
        }
        out
    }
}

const FREE: [u8; 3] = [255, 255, 255];
const UNKNOWN: [u8; 3] = [205, 205, 205];
const OCCUPIED: [u8; 3] = [40, 40, 40];
const PIECE_FILL: [u8; 3] = [255, 120, 0];
const PIECE_EDGE: [u8; 3] = [200, 60, 0];
const OUTLINE: [u8; 3] = [0, 90, 220];
const BUFFER: [u8; 3] = [0, 170, 80];

/// The preview: the grid (occupied dark, free white, unknown grey) under the
/// convex pieces (translucent orange, seams in dark orange) with each
/// piece's buffered outline (thin green) and the obstacles' true outline
/// (blue: edges that no other piece of the obstacle shares). Without a grid
/// the map's own bounds, with a 1 m margin, on white.
pub fn preview<M: MapSource + ?Sized>(m: &M, grid: Option<&Grid>, unknown: Unknown) -> Vec<u8> {
    preview_canvas(m, grid, unknown).png()
}

/// [`preview`] before it is encoded, to draw on.
pub fn preview_canvas<M: MapSource + ?Sized>(m: &M, grid: Option<&Grid>, unknown: Unknown) -> Canvas {
    let mut cv = match grid {
        Some(g) => {
            let res = g.yaml.resolution * 1000.0;
            // Crop to the known cells and the map, with a margin of 10 cells.
            let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
            for r in 0..g.height {
                for c in 0..g.width {
                    if g.at(c, r) != Cell::Unknown {
                        (c0, c1, r0, r1) = (c0.min(c), c1.max(c), r0.min(r), r1.max(r));
                    }
                }
            }
            if let Some(b) = m.bounds_of_pieces() {
                let col = |x: i32| ((x as f64 - g.yaml.origin[0] * 1000.0) / res).floor().max(0.0) as usize;
                let row =
                    |y: i32| (g.height as f64 - (y as f64 - g.yaml.origin[1] * 1000.0) / res).floor().max(0.0) as usize;
                (c0, c1) = (c0.min(col(b.min.x)), c1.max(col(b.max.x)));
                (r0, r1) = (r0.min(row(b.max.y)), r1.max(row(b.min.y)));
            }
            if c0 > c1 {
                (c0, c1, r0, r1) = (0, g.width - 1, 0, g.height - 1);
            }
            let (c0, r0) = (c0.saturating_sub(10), r0.saturating_sub(10));
            let (c1, r1) = ((c1 + 10).min(g.width - 1), (r1 + 10).min(g.height - 1));
            let (gw, gh) = (c1 + 1 - c0, r1 + 1 - r0);
            let s = (1800 / gw.max(gh)).clamp(1, 8);
            let (w, h) = (gw * s, gh * s);
            let mut px = vec![FREE; w * h];
            for r in r0..=r1 {
                for c in c0..=c1 {
                    let col = match (g.at(c, r), unknown) {
                        (Cell::Occupied, _) | (Cell::Unknown, Unknown::Occupied) => OCCUPIED,
                        (Cell::Free, _) => FREE,
                        (Cell::Unknown, Unknown::Free) => UNKNOWN,
                    };
                    for dy in 0..s {
                        px[((r - r0) * s + dy) * w + (c - c0) * s..][..s].fill(col);
                    }
                }
            }
            Canvas {
                w,
                h,
                px,
                x0: g.yaml.origin[0] * 1000.0 + c0 as f64 * res,
                y1: g.yaml.origin[1] * 1000.0 + (g.height - r0) as f64 * res,
                mm_per_px: res / s as f64,
            }
        }
        None => {
            let b = m.bounds_of_pieces();
            let (x0, y0, x1, y1) = b.map_or((0.0, 0.0, 1.0, 1.0), |b| {
                (b.min.x as f64 - 1000.0, b.min.y as f64 - 1000.0, b.max.x as f64 + 1000.0, b.max.y as f64 + 1000.0)
            });
            let mm_per_px = ((x1 - x0).max(y1 - y0) / 1200.0).max(1.0);
            let (w, h) = (((x1 - x0) / mm_per_px).ceil() as usize, ((y1 - y0) / mm_per_px).ceil() as usize);
            Canvas { w, h, px: vec![FREE; w * h], x0, y1, mm_per_px }
        }
    };
    let f = |p: &echoloc::geometry::Point| (p.x as f64, p.y as f64);
    for p in m.pieces_iter() {
        let v: Vec<(f64, f64)> = p.shape.vertices().iter().map(f).collect();
        if v.len() >= 3 {
            cv.fill_convex(&v, PIECE_FILL, 0.35);
        }
    }
    for p in m.pieces_iter() {
        let b: Vec<(f64, f64)> = p.buffered.vertices().iter().map(f).collect();
        for i in 0..b.len() {
            let (a, c) = (b[i], b[(i + 1) % b.len()]);
            let (pa, pc) = (cv.to_px(a.0, a.1), cv.to_px(a.0 + (c.0 - a.0), a.1 + (c.1 - a.1)));
            // Dotted: every other 3 px.
            let n = ((pc.0 - pa.0).hypot(pc.1 - pa.1) / 3.0).ceil() as usize;
            for k in (0..n).step_by(2) {
                let (t0, t1) = (k as f64 / n as f64, ((k + 1) as f64 / n as f64).min(1.0));
                cv.line(
                    (a.0 + (c.0 - a.0) * t0, a.1 + (c.1 - a.1) * t0),
                    (a.0 + (c.0 - a.0) * t1, a.1 + (c.1 - a.1) * t1),
                    BUFFER,
                    1,
                );
            }
        }
    }
    for o in m.obstacles_iter() {
        let pieces: Vec<Vec<(i32, i32)>> = (o.first_piece..o.first_piece + o.piece_count)
            .filter_map(|id| m.piece(id))
            .map(|p| p.shape.vertices().iter().map(|q| (q.x, q.y)).collect())
            .collect();
        // Edges shared (in opposite directions) by two pieces are seams.
        let mut edges = std::collections::HashMap::new();
        for v in &pieces {
            for i in 0..v.len() {
                *edges.entry((v[i], v[(i + 1) % v.len()])).or_insert(0) += 1;
            }
        }
        for v in &pieces {
            for i in 0..v.len() {
                let (a, b) = (v[i], v[(i + 1) % v.len()]);
                let seam = v.len() > 2 && edges.contains_key(&(b, a));
                let (c, w) = if seam { (PIECE_EDGE, 1) } else { (OUTLINE, 1) };
                cv.line((a.0 as f64, a.1 as f64), (b.0 as f64, b.1 as f64), c, w);
            }
        }
    }
    cv
}
