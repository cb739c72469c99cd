//! GeoJSON (RFC 7946 shapes, planar metres), read with the `geojson`
//! crate: Polygon and MultiPolygon are solids (interior rings are holes),
//! LineString and MultiLineString are walls; a GeometryCollection's members
//! count one by one. A Feature with the property `"kind": "free"` (a Polygon
//! or MultiPolygon) is no obstacle but the map's free space
//! ([`super::free_space`]); other `kind`s (`solid`, `wall`, as `map export`
//! writes them) and other properties are read by their geometry.
//!
//! Errors say where: a JSON or GeoJSON syntax error its line and column (from
//! the parser), a shape the path to it (`features[2].geometry.coordinates[0][3]`).
//!
//! ```
//! use echoloc_lab::map::{geojson::parse, Shape};
//! let shapes = parse(r#"{"type":"FeatureCollection","features":[
//!   {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[0,0],[2.5,0]]}}]}"#).unwrap();
//! assert!(matches!(&shapes[0], Shape::Wall(w) if w.len() == 2 && w[1].x == 2500));
//! let e = parse(r#"{"type":"Point","coordinates":[1,2]}"#).unwrap_err();
//! assert!(e.contains("unsupported geometry type \"Point\""), "{e}");
//! ```

use ::geojson::{GeoJson, Geometry, GeometryValue, PolygonType, Position};

use super::free_space::Area;
use super::Shape;
use echoloc::geometry::{Point, COORD_MAX};

/// A GeoJSON map: its obstacles and the `free` polygons it gives.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GeoMap {
    pub shapes: Vec<Shape>,
    pub free: Vec<Area>,
}

/// Parses a FeatureCollection, a Feature or a bare geometry: the obstacles
/// (`free` features left out).
pub fn parse(text: &str) -> Result<Vec<Shape>, String> {
    parse_map(text).map(|m| m.shapes)
}

/// Parses a FeatureCollection, a Feature or a bare geometry: the obstacles
/// and the `free` polygons.
pub fn parse_map(text: &str) -> Result<GeoMap, String> {
    // JSON first, for its own message (with line and column); then the
    // top level's type, the commonest mistake; then GeoJSON proper.
    let v: serde_json::Value = serde_json::from_str(text).map_err(|e| format!("not JSON: {e}"))?;
    if v.get("type").and_then(serde_json::Value::as_str).is_none() {
        return Err("no \"type\" member at the top level".into());
    }
    let g: GeoJson = text.parse().map_err(|e: ::geojson::Error| match e {
        ::geojson::Error::MalformedGeoJson(e) => format!("not GeoJSON (RFC 7946): {e}"),
        e => format!("not GeoJSON (RFC 7946): {e}"),
    })?;
    let mut out = GeoMap::default();
    match &g {
        GeoJson::FeatureCollection(fc) => {
            for (i, f) in fc.features.iter().enumerate() {
                let g = f.geometry.as_ref().ok_or_else(|| format!("features[{i}]: no geometry"))?;
                feature(f, g, &format!("features[{i}]"), &mut out)?;
            }
        }
        GeoJson::Feature(f) => feature(f, f.geometry.as_ref().ok_or("Feature without a geometry")?, "$", &mut out)?,
        GeoJson::Geometry(g) => geometry(g, "$", &mut out.shapes)?,
    }
    Ok(out)
}

/// A Feature: an obstacle, or (`"kind": "free"`) free space.
fn feature(f: &::geojson::Feature, g: &Geometry, at: &str, out: &mut GeoMap) -> Result<(), String> {
    let at_g = if at == "$" { "geometry".to_string() } else { format!("{at}.geometry") };
    if f.property("kind").and_then(serde_json::Value::as_str) != Some("free") {
        return geometry(g, &at_g, &mut out.shapes);
    }
    let mut polys = Vec::new();
    match &g.value {
        GeometryValue::Polygon { coordinates } => polys.push(polygon(coordinates, &format!("{at_g}.coordinates"))?),
        GeometryValue::MultiPolygon { coordinates } => {
            for (i, p) in coordinates.iter().enumerate() {
                polys.push(polygon(p, &format!("{at_g}.coordinates[{i}]"))?);
            }
        }
        other => {
            return Err(format!(
                "{at}: a \"free\" feature must be a Polygon or MultiPolygon, not {:?}",
                other.type_name()
            ))
        }
    }
    for p in polys {
        if let Shape::Solid { outer, holes } = p {
            out.free.push(Area { outer, holes });
        }
    }
    Ok(())
}

fn geometry(g: &Geometry, at: &str, out: &mut Vec<Shape>) -> Result<(), String> {
    match &g.value {
        GeometryValue::Polygon { coordinates } => out.push(polygon(coordinates, &format!("{at}.coordinates"))?),
        GeometryValue::MultiPolygon { coordinates } => {
            for (i, p) in coordinates.iter().enumerate() {
                out.push(polygon(p, &format!("{at}.coordinates[{i}]"))?);
            }
        }
        GeometryValue::LineString { coordinates } => {
            out.push(Shape::Wall(line(coordinates, &format!("{at}.coordinates"))?))
        }
        GeometryValue::MultiLineString { coordinates } => {
            for (i, l) in coordinates.iter().enumerate() {
                out.push(Shape::Wall(line(l, &format!("{at}.coordinates[{i}]"))?));
            }
        }
        GeometryValue::GeometryCollection { geometries } => {
            for (i, g) in geometries.iter().enumerate() {
                geometry(g, &format!("{at}.geometries[{i}]"), out)?;
            }
        }
        other => {
            return Err(format!(
                "{at}: unsupported geometry type {:?} (Polygon, MultiPolygon, LineString, MultiLineString, \
                 GeometryCollection)",
                other.type_name()
            ))
        }
    }
    Ok(())
}

/// A polygon: the outer ring, then its holes (RFC 7946 §3.1.6; the rings'
/// orientation is not enforced: the splitter orients them).
fn polygon(rings: &PolygonType, at: &str) -> Result<Shape, String> {
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

fn line(pts: &[Position], at: &str) -> Result<Vec<Point>, String> {
    let mut out = Vec::with_capacity(pts.len());
    for (i, p) in pts.iter().enumerate() {
        let here = format!("{at}[{i}]");
        let xy = p.as_slice();
        if xy.len() < 2 {
            return Err(format!("{here}: a position needs x and y"));
        }
        let mm = |m: f64, axis: &str| -> Result<i32, String> {
            let v = (m * 1000.0).round();
            if !v.is_finite() || v.abs() > COORD_MAX as f64 {
                return Err(format!("{here}: {axis} = {m} m is beyond ±{} m", COORD_MAX / 1000));
            }
            Ok(v as i32)
        };
        out.push(Point::new(mm(xy[0], "x")?, mm(xy[1], "y")?));
    }
    if out.len() < 2 {
        return Err(format!("{at}: needs at least two positions"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn where_errors_are() {
        let e = parse("{\"type\": \"LineString\",\n \"coordinates\": [[0, 0], [\"a\", 0]]}").unwrap_err();
        assert_eq!(e, "not GeoJSON (RFC 7946): invalid type: string \"a\", expected f64 at line 2 column 29");
        let e =
            parse(r#"{"type":"FeatureCollection","features":[{"type":"Feature","properties":{},"geometry":null}]}"#)
                .unwrap_err();
        assert_eq!(e, "features[0]: no geometry");
        let fc = |g: &str| {
            format!(
                r#"{{"type":"FeatureCollection","features":[{{"type":"Feature","properties":{{}},"geometry":{g}}}]}}"#
            )
        };
        let e = parse(&fc(r#"{"type":"Polygon","coordinates":[[[0,0],[1],[1,1],[0,0]]]}"#)).unwrap_err();
        assert_eq!(e, "features[0].geometry.coordinates[0][1]: a position needs x and y");
        let e = parse(&fc(r#"{"type":"MultiPoint","coordinates":[[0,0]]}"#)).unwrap_err();
        assert!(e.starts_with("features[0].geometry: unsupported geometry type \"MultiPoint\""), "{e}");
        let e = parse(r#"{"type":"Polygonn","coordinates":[]}"#).unwrap_err();
        assert!(e.starts_with("not GeoJSON (RFC 7946): unknown variant `Polygonn`"), "{e}");
    }

    #[test]
    fn a_geometry_collection_counts_member_by_member() {
        let s = parse(
            r#"{"type":"GeometryCollection","geometries":[
                {"type":"LineString","coordinates":[[0,0],[1,0]]},
                {"type":"Polygon","coordinates":[[[2,2],[3,2],[3,3],[2,2]]]}]}"#,
        )
        .unwrap();
        assert!(matches!(&s[0], Shape::Wall(w) if w.len() == 2));
        assert!(matches!(&s[1], Shape::Solid { outer, holes } if outer.len() == 3 && holes.is_empty()));
        let e = parse(r#"{"type":"GeometryCollection","geometries":[{"type":"LineString","coordinates":[[0,0]]}]}"#)
            .unwrap_err();
        assert_eq!(e, "$.geometries[0].coordinates: needs at least two positions");
    }
}
