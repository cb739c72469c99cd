//! GeoJSON (RFC 7946 shapes, planar metres): Polygon and MultiPolygon are
//! solids (interior rings are holes), LineString and MultiLineString are walls.

use serde_json::Value;

use super::Shape;
use echoloc::geometry::{Point, COORD_MAX};

/// Parses a FeatureCollection, a Feature or a bare geometry.
pub fn parse(text: &str) -> Result<Vec<Shape>, String> {
    let v: Value = serde_json::from_str(text).map_err(|e| format!("not JSON: {e}"))?;
    let mut out = Vec::new();
    match v.get("type").and_then(Value::as_str) {
        Some("FeatureCollection") => {
            let feats =
                v.get("features").and_then(Value::as_array).ok_or("FeatureCollection without a features array")?;
            for (i, f) in feats.iter().enumerate() {
                let g = f.get("geometry").ok_or_else(|| format!("features[{i}]: no geometry"))?;
                geometry(g, &format!("features[{i}].geometry"), &mut out)?;
            }
        }
        Some("Feature") => geometry(v.get("geometry").ok_or("Feature without a geometry")?, "geometry", &mut out)?,
        Some(_) => geometry(&v, "$", &mut out)?,
        None => return Err("no \"type\" member at the top level".into()),
    }
    Ok(out)
}

fn geometry(g: &Value, at: &str, out: &mut Vec<Shape>) -> Result<(), String> {
    let ty = g.get("type").and_then(Value::as_str).ok_or_else(|| format!("{at}: no type"))?;
    let coords = g.get("coordinates").ok_or_else(|| format!("{at}: no coordinates"))?;
    match ty {
        "Polygon" => out.push(polygon(coords, &format!("{at}.coordinates"))?),
        "MultiPolygon" => {
            for (i, p) in array(coords, at)?.iter().enumerate() {
                out.push(polygon(p, &format!("{at}.coordinates[{i}]"))?);
            }
        }
        "LineString" => out.push(Shape::Wall(line(coords, &format!("{at}.coordinates"))?)),
        "MultiLineString" => {
            for (i, l) in array(coords, at)?.iter().enumerate() {
                out.push(Shape::Wall(line(l, &format!("{at}.coordinates[{i}]"))?));
            }
        }
        other => {
            return Err(format!(
                "{at}: unsupported geometry type {other:?} (Polygon, MultiPolygon, LineString, MultiLineString)"
            ))
        }
    }
    Ok(())
}

fn array<'a>(v: &'a Value, at: &str) -> Result<&'a Vec<Value>, String> {
    v.as_array().ok_or_else(|| format!("{at}: expected an array"))
}

/// A polygon: the outer ring, then its holes (RFC 7946 §3.1.6; the rings'
/// orientation is not enforced: the splitter orients them).
fn polygon(v: &Value, at: &str) -> Result<Shape, String> {
    let rings = array(v, at)?;
    if rings.is_empty() {
        return Err(format!("{at}: a polygon needs an outer ring"));
    }
    let mut out = Vec::with_capacity(rings.len());
    for (k, r) in rings.iter().enumerate() {
        let mut ring = line(r, &format!("{at}[{k}]"))?;
        if ring.len() > 1 && ring.first() == ring.last() {
            ring.pop();
        }
        if ring.len() < 3 {
            let what = if k == 0 { "the outer ring".to_string() } else { format!("hole {}", k - 1) };
            return Err(format!("{at}[{k}]: {what} needs at least three distinct vertices"));
        }
        out.push(ring);
    }
    let outer = out.remove(0);
    Ok(Shape::Solid { outer, holes: out })
}

fn line(v: &Value, at: &str) -> Result<Vec<Point>, String> {
    let pts = array(v, at)?;
    let mut out = Vec::with_capacity(pts.len());
    for (i, p) in pts.iter().enumerate() {
        let here = format!("{at}[{i}]");
        let xy = array(p, &here)?;
        if xy.len() < 2 {
            return Err(format!("{here}: a position needs x and y"));
        }
        let mm = |c: &Value, axis: &str| -> Result<i32, String> {
            let m = c.as_f64().ok_or_else(|| format!("{here}: {axis} is not a number"))?;
            let v = (m * 1000.0).round();
            if !v.is_finite() || v.abs() > COORD_MAX as f64 {
                return Err(format!("{here}: {axis} = {m} m is beyond ±{} m", COORD_MAX / 1000));
            }
            Ok(v as i32)
        };
        out.push(Point::new(mm(&xy[0], "x")?, mm(&xy[1], "y")?));
    }
    if out.len() < 2 {
        return Err(format!("{at}: needs at least two positions"));
    }
    Ok(out)
}
