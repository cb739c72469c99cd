//! Back out of the blob: GeoJSON of the true pieces, and a preview of the
//! pieces over the occupancy grid they came from (drawn with `plotters`,
//! [`crate::figure`]), whose layers the simulator's figures draw on too.

use echoloc::map::{MapSource, ObstacleKind};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use serde_json::{json, Value};

use crate::figure::{encode, err, legend, rgb, Figure, Format, Root, FONT};

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

/// Every colour the map's layers draw with, by legend label (the figures
/// that draw paths over them check theirs against these).
pub const COLOURS: [(&str, [u8; 3]); 6] = [
    ("convex pieces", PIECE_FILL),
    ("seams", PIECE_EDGE),
    ("true outline", OUTLINE),
    ("C-space buffer", BUFFER),
    ("occupied cells", OCCUPIED),
    ("unknown cells", UNKNOWN),
];
const UNKNOWN: [u8; 3] = [205, 205, 205];
const OCCUPIED: [u8; 3] = [70, 70, 70];
const PIECE_FILL: [u8; 3] = [255, 120, 0];
const PIECE_EDGE: [u8; 3] = [130, 0, 0];
const OUTLINE: [u8; 3] = [0, 90, 220];
const BUFFER: [u8; 3] = [150, 220, 60];
const FREE: [u8; 3] = [0, 170, 200];

/// A map chart: map coordinates in metres, x right, y up, equal scale.
pub type MapChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// What a map picture shows and where: the extent (m) and the grid under it.
pub struct MapLayers<'a, M: MapSource + ?Sized> {
    /// The map.
    pub map: &'a M,
    /// The occupancy grid it came from, drawn under it.
    pub grid: Option<&'a Grid>,
    /// What the grid's unknown cells are drawn as.
    pub unknown: Unknown,
    /// x0, x1, y0, y1, metres.
    pub extent: [f64; 4],
}

impl<'a, M: MapSource + ?Sized> MapLayers<'a, M> {
    /// The map (and grid) cropped to the known cells and the map's pieces,
    /// with a margin: 10 cells on a grid, else 1 m.
    pub fn new(map: &'a M, grid: Option<&'a Grid>, unknown: Unknown) -> Self {
        let pieces =
            map.bounds_of_pieces().map(|b| [metres(b.min.x), metres(b.max.x), metres(b.min.y), metres(b.max.y)]);
        let extent = match grid {
            Some(g) => {
                let res = g.yaml.resolution;
                let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
                for r in 0..g.height {
                    for c in 0..g.width {
                        if g.at(c, r) != Cell::Unknown {
                            (c0, c1, r0, r1) = (c0.min(c), c1.max(c), r0.min(r), r1.max(r));
                        }
                    }
                }
                if c0 > c1 {
                    (c0, c1, r0, r1) = (0, g.width - 1, 0, g.height - 1);
                }
                let (ox, oy) = (g.yaml.origin[0], g.yaml.origin[1]);
                let mut e = [
                    ox + c0 as f64 * res,
                    ox + (c1 + 1) as f64 * res,
                    oy + (g.height - 1 - r1) as f64 * res,
                    oy + (g.height - r0) as f64 * res,
                ];
                if let Some(p) = pieces {
                    e = [e[0].min(p[0]), e[1].max(p[1]), e[2].min(p[2]), e[3].max(p[3])];
                }
                [e[0] - 10.0 * res, e[1] + 10.0 * res, e[2] - 10.0 * res, e[3] + 10.0 * res]
            }
            None => pieces.map_or([0.0, 1.0, 0.0, 1.0], |p| [p[0] - 1.0, p[1] + 1.0, p[2] - 1.0, p[3] + 1.0]),
        };
        Self { map, grid, unknown, extent }
    }

    /// A figure's size for a plot area at most `max` pixels wide or high,
    /// with room for the axes, a title and a legend panel `legend_w` wide.
    pub fn size(&self, max: u32, legend_w: u32) -> (u32, u32, u32, u32) {
        let [x0, x1, y0, y1] = self.extent;
        let (w, h) = ((x1 - x0).max(1e-3), (y1 - y0).max(1e-3));
        let s = f64::from(max) / w.max(h);
        let (pw, ph) = ((w * s).round().max(200.0) as u32, (h * s).round().max(200.0) as u32);
        (pw + 90 + legend_w, ph + 110, pw, ph)
    }

    /// Builds the chart on `area` (axes in metres, a title) and draws the
    /// grid, the pieces, their buffers and the outlines; callers draw on top.
    pub fn chart<'b, DB: DrawingBackend>(&self, area: &'b Root<DB>, title: &str) -> Result<MapChart<'b, DB>, String> {
        let [x0, x1, y0, y1] = self.extent;
        let mut chart = ChartBuilder::on(area)
            .caption(title, (FONT, 22))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 16))
            .draw()
            .map_err(err)?;
        if let Some(g) = self.grid {
            // Runs of occupied (and unknown) cells along each row.
            let res = g.yaml.resolution;
            let (ox, oy) = (g.yaml.origin[0], g.yaml.origin[1]);
            let colour = |c: Cell| match (c, self.unknown) {
                (Cell::Occupied, _) | (Cell::Unknown, Unknown::Occupied) => Some(OCCUPIED),
                (Cell::Free, _) => None,
                (Cell::Unknown, Unknown::Free) => Some(UNKNOWN),
            };
            let mut runs = Vec::new();
            for r in 0..g.height {
                let y = oy + (g.height - 1 - r) as f64 * res;
                if y + res < y0 || y > y1 {
                    continue;
                }
                let mut c = 0;
                while c < g.width {
                    let col = colour(g.at(c, r));
                    let start = c;
                    while c < g.width && colour(g.at(c, r)) == col {
                        c += 1;
                    }
                    if let Some(col) = col {
                        let (a, b) = (ox + start as f64 * res, ox + c as f64 * res);
                        if b >= x0 && a <= x1 {
                            runs.push(Rectangle::new([(a.max(x0), y), (b.min(x1), y + res)], rgb(col).filled()));
                        }
                    }
                }
            }
            chart.draw_series(runs).map_err(err)?;
        }
        let f = |p: &echoloc::geometry::Point| (metres(p.x), metres(p.y));
        let m = self.map;
        chart
            .draw_series(m.pieces_iter().filter(|p| p.shape.vertices().len() >= 3).map(|p| {
                Polygon::new(p.shape.vertices().iter().map(f).collect::<Vec<_>>(), rgb(PIECE_FILL).mix(0.35).filled())
            }))
            .map_err(err)?;
        chart
            .draw_series(m.pieces_iter().map(|p| {
                let mut b: Vec<(f64, f64)> = p.buffered.vertices().iter().map(f).collect();
                if let Some(&first) = b.first() {
                    b.push(first);
                }
                PathElement::new(b, rgb(BUFFER).mix(0.8).stroke_width(1))
            }))
            .map_err(err)?;
        let mut lines = Vec::new();
        for o in m.obstacles_iter() {
            let pieces: Vec<Vec<(i32, i32)>> = (o.first_piece..o.first_piece + o.piece_count)
                .filter_map(|id| m.piece(id))
                .map(|p| p.shape.vertices().iter().map(|q| (q.x, q.y)).collect())
                .collect();
            // Edges shared (in opposite directions) by two pieces are seams.
            let mut edges = std::collections::HashSet::new();
            for v in &pieces {
                for i in 0..v.len() {
                    edges.insert((v[i], v[(i + 1) % v.len()]));
                }
            }
            for v in &pieces {
                for i in 0..v.len() {
                    let (a, b) = (v[i], v[(i + 1) % v.len()]);
                    let seam = v.len() > 2 && edges.contains(&(b, a));
                    let c = if seam { PIECE_EDGE } else { OUTLINE };
                    let (pa, pb) = ((metres(a.0), metres(a.1)), (metres(b.0), metres(b.1)));
                    lines.push(PathElement::new(vec![pa, pb], rgb(c).stroke_width(1)));
                }
            }
        }
        chart.draw_series(lines).map_err(err)?;
        Ok(chart)
    }

    /// The legend entries of [`chart`](Self::chart)'s layers.
    pub fn legend(&self) -> Vec<(&'static str, RGBColor)> {
        let mut v = vec![
            ("convex pieces", rgb(PIECE_FILL)),
            ("seams", rgb(PIECE_EDGE)),
            ("true outline", rgb(OUTLINE)),
            ("C-space buffer", rgb(BUFFER)),
        ];
        if self.grid.is_some() {
            v.push(("occupied cells", rgb(OCCUPIED)));
            if self.unknown == Unknown::Free {
                v.push(("unknown cells", rgb(UNKNOWN)));
            }
        }
        v
    }
}

/// The preview figure: the layers, its size, the field's free nodes (m).
struct Preview<'a, M: MapSource + ?Sized>(MapLayers<'a, M>, (u32, u32, u32, u32), Vec<(f64, f64)>);

impl<M: MapSource + ?Sized> Figure for Preview<'_, M> {
    fn size(&self) -> (u32, u32) {
        (self.1 .0, self.1 .1)
    }

    fn draw<DB: DrawingBackend>(&self, root: &Root<DB>) -> Result<(), String> {
        let (plot, side) = root.split_horizontally(self.1 .0 - LEGEND_W);
        let mut chart = self.0.chart(&plot, "Map: convex pieces, buffers and outlines")?;
        let mut keys = self.0.legend();
        if !self.2.is_empty() {
            chart.draw_series(self.2.iter().map(|&p| Circle::new(p, 2, rgb(FREE).filled()))).map_err(err)?;
            keys.push(("free field nodes", rgb(FREE)));
        }
        legend(&side.margin(60, 0, 0, 0), &keys, false)
    }
}

const LEGEND_W: u32 = 220;

/// The preview: the grid (occupied dark, free white, unknown grey) under the
/// convex pieces (translucent orange, seams in dark orange) with each
/// piece's buffered outline (thin green) and the obstacles' true outline
/// (blue: edges that no other piece of the obstacle shares). Without a grid
/// the map's own bounds, with a 1 m margin, on white. A PNG.
pub fn preview<M: MapSource + ?Sized>(m: &M, grid: Option<&Grid>, unknown: Unknown) -> Vec<u8> {
    preview_as(m, grid, unknown, &[], Format::Png).unwrap_or_default()
}

/// [`preview`] as PNG or SVG, with the localization field's free nodes
/// (`free`, metres: where particles may be drawn) as dots.
pub fn preview_as<M: MapSource + ?Sized>(
    m: &M,
    grid: Option<&Grid>,
    unknown: Unknown,
    free: &[(f64, f64)],
    format: Format,
) -> Result<Vec<u8>, String> {
    let layers = MapLayers::new(m, grid, unknown);
    let size = layers.size(1300, LEGEND_W);
    encode(&Preview(layers, size, free.to_vec()), format)
}

/// The free nodes of a compiled map's localization field, metres.
pub fn free_nodes(m: &echoloc::map::MapView<'_>) -> Vec<(f64, f64)> {
    let f = m.field();
    (0..f.nodes())
        .filter(|&n| f.is_free(n))
        .filter_map(|n| f.position_mm(n))
        .map(|(x, y)| (f64::from(x) / 1e3, f64::from(y) / 1e3))
        .collect()
}
