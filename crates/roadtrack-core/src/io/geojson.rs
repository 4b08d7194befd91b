//! GeoJSON export of trajectories in ground coordinates, for GIS tools (issue 8, part 5).
//!
//! The output is one RFC 7946 `FeatureCollection` with one feature per track id, ids
//! ascending. A track with two or more points is a `LineString` through its ground
//! positions `[x_m, y_m]` in frame order; a track seen once is a `Point`. Properties:
//!
//! | key | meaning |
//! |---|---|
//! | `id` | track id |
//! | `class` | the class most often given to the track (ties: the first seen) |
//! | `start_frame`, `end_frame` | first and last frame |
//! | `start_time_s`, `end_time_s` | their times, s |
//! | `n_points` | points in the track |
//! | `mean_speed_mps` | mean of the points' `speed_mps` (the calibration's smoothed speeds) |
//! | `length_m` | length of the polyline, m |
//! | `times_s` | the time of every vertex, s, in the geometry's order |
//!
//! Coordinates are the calibration's local ground metres, not longitude/latitude: the file
//! has no `crs` member (RFC 7946 removed it) and instead carries a foreign member
//! `"roadtrack": {"coordinates": "local-metres", …}` saying so. Import it in a GIS as a
//! local engineering (Cartesian, metre) layer, or georeference it once the calibration has
//! a geographic origin. Numbers are rounded to 1 mm and 1 µs, so the files are small and
//! byte-identical for the same input.

use super::atomic::AtomicFile;
use crate::class::ObjectClass;
use crate::error::{Error, Result};
use crate::track_point::TrackPoint;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::Path;

fn round(x: f64, decimals: i32) -> f64 {
    let k = 10f64.powi(decimals);
    let r = (x * k).round() / k;
    // Avoid "-0.0" in the output.
    if r == 0.0 { 0.0 } else { r }
}

/// What the GeoJSON keeps of one track: its vertices and class votes, a few numbers per
/// point rather than whole track points.
#[derive(Debug, Default)]
struct TrackSummary {
    /// `(frame, time_s, x_m, y_m, speed_mps)` in frame order.
    vertices: Vec<(u32, f64, f64, f64, f64)>,
    /// Class counts in order of first appearance.
    classes: Vec<(ObjectClass, usize)>,
}

impl TrackSummary {
    fn push(&mut self, p: &TrackPoint) -> Result<()> {
        let g = p.ground.ok_or_else(|| {
            Error::Invalid(format!(
                "track {} at frame {} has no ground coordinates; GeoJSON export needs \
                 trajectories from a calibrated run (--calibration)",
                p.id, p.frame
            ))
        })?;
        self.vertices
            .push((p.frame, p.time_s, g.x_m, g.y_m, g.speed_mps));
        match self.classes.iter_mut().find(|(c, _)| *c == p.class) {
            Some((_, n)) => *n += 1,
            None => self.classes.push((p.class.clone(), 1)),
        }
        Ok(())
    }

    fn feature(&self, id: u64) -> Value {
        let v = &self.vertices;
        let coords: Vec<Value> = v
            .iter()
            .map(|&(_, _, x, y, _)| json!([round(x, 3), round(y, 3)]))
            .collect();
        let length_m: f64 = v
            .windows(2)
            .map(|w| (w[1].2 - w[0].2).hypot(w[1].3 - w[0].3))
            .sum();
        let mean_speed = v.iter().map(|t| t.4).sum::<f64>() / v.len() as f64;
        // Most frequent class; ties go to the class seen first.
        let class = self
            .classes
            .iter()
            .fold(None::<(&ObjectClass, usize)>, |best, (c, n)| match best {
                Some((_, bn)) if bn >= *n => best,
                _ => Some((c, *n)),
            })
            .map_or("unknown", |(c, _)| c.name());
        let (first, last) = (v[0], v[v.len() - 1]);
        let geometry = if coords.len() >= 2 {
            json!({"type": "LineString", "coordinates": coords})
        } else {
            json!({"type": "Point", "coordinates": coords[0]})
        };
        json!({
            "type": "Feature",
            "id": id,
            "geometry": geometry,
            "properties": {
                "id": id,
                "class": class,
                "start_frame": first.0,
                "end_frame": last.0,
                "start_time_s": round(first.1, 6),
                "end_time_s": round(last.1, 6),
                "n_points": v.len(),
                "mean_speed_mps": round(mean_speed, 3),
                "length_m": round(length_m, 3),
                "times_s": v.iter().map(|t| round(t.1, 6)).collect::<Vec<_>>(),
            }
        })
    }
}

/// The foreign member saying what the coordinates are.
fn coordinates_note() -> Value {
    json!({
        "coordinates": "local-metres",
        "note": "x_m, y_m in metres in the calibration's ground frame; not longitude/latitude \
                 unless the calibration has a geographic origin",
    })
}

/// Track summaries by id from `points` in any order (each track's points sorted by frame).
fn summaries(points: &[TrackPoint]) -> Result<BTreeMap<u64, TrackSummary>> {
    let mut by_id: BTreeMap<u64, Vec<&TrackPoint>> = BTreeMap::new();
    for p in points {
        if p.ground.is_none() {
            // Report the first such point in input order.
            TrackSummary::default().push(p)?;
        }
        by_id.entry(p.id).or_default().push(p);
    }
    let mut out = BTreeMap::new();
    for (id, mut track) in by_id {
        track.sort_by_key(|p| p.frame);
        let mut t = TrackSummary::default();
        for p in track {
            t.push(p)?;
        }
        out.insert(id, t);
    }
    Ok(out)
}

/// The trajectories as a GeoJSON `FeatureCollection` (see the module documentation).
///
/// # Errors
/// A point without a ground state (trajectories need a calibration first).
pub fn to_geojson(points: &[TrackPoint]) -> Result<Value> {
    let features: Vec<Value> = summaries(points)?
        .iter()
        .map(|(id, t)| t.feature(*id))
        .collect();
    Ok(json!({
        "type": "FeatureCollection",
        "roadtrack": coordinates_note(),
        "features": features,
    }))
}

/// Writes [`to_geojson`] to `path` atomically (`-` for standard output), one feature per
/// line.
///
/// # Errors
/// As [`to_geojson`], and a file that cannot be written.
pub fn write_geojson(path: &Path, points: &[TrackPoint]) -> Result<()> {
    write_summaries(path, &summaries(points)?)
}

fn write_summaries(path: &Path, tracks: &BTreeMap<u64, TrackSummary>) -> Result<()> {
    let text = |v: &Value| serde_json::to_string(v).map_err(|e| Error::Invalid(e.to_string()));
    let note = text(&coordinates_note())?;
    let mut out = AtomicFile::create(path)?;
    let io = |e| Error::io(path, e);
    writeln!(
        out,
        "{{\"type\":\"FeatureCollection\",\"roadtrack\":{note},\"features\":["
    )
    .map_err(io)?;
    for (i, (id, t)) in tracks.iter().enumerate() {
        let sep = if i + 1 < tracks.len() { "," } else { "" };
        writeln!(out, "{}{sep}", text(&t.feature(*id))?).map_err(io)?;
    }
    writeln!(out, "]}}").map_err(io)?;
    out.commit()
}

/// A GeoJSON file of trajectories built as the points come, in frame order; written on
/// [`GeoJsonWriter::commit`] (features are per track, so nothing can be written before the
/// last point). Memory: five numbers per point and a class tally per track.
#[derive(Debug)]
pub struct GeoJsonWriter {
    path: std::path::PathBuf,
    tracks: BTreeMap<u64, TrackSummary>,
}

impl GeoJsonWriter {
    /// A writer for `path` (`-` = standard output).
    pub fn new(path: &Path) -> Self {
        Self {
            path: path.to_owned(),
            tracks: BTreeMap::new(),
        }
    }

    /// Adds one point; points must come in frame order.
    ///
    /// # Errors
    /// The point has no ground state.
    pub fn add_point(&mut self, p: &TrackPoint) -> Result<()> {
        self.tracks.entry(p.id).or_default().push(p)
    }

    /// Writes the file, atomically.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn commit(self) -> Result<()> {
        write_summaries(&self.path, &self.tracks)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ObjectClass;
    use crate::geometry::BBox;
    use crate::track_point::GroundState;

    fn point(frame: u32, id: u64, x_m: f64, speed: f64, class: ObjectClass) -> TrackPoint {
        TrackPoint {
            frame,
            time_s: f64::from(frame - 1) * 0.1,
            id,
            class,
            bbox: BBox::new(0.0, 0.0, 1.0, 1.0),
            score: 1.0,
            ground: Some(GroundState {
                x_m,
                y_m: 2.0 * x_m,
                speed_mps: speed,
                heading_deg: 0.0,
            }),
        }
    }

    fn sample() -> Vec<TrackPoint> {
        let mut v = Vec::new();
        for f in 1..=4u32 {
            let class = if f == 2 {
                ObjectClass::Truck
            } else {
                ObjectClass::Car
            };
            v.push(point(f, 7, 3.0 * f64::from(f), 10.0 + f64::from(f), class));
        }
        v.push(point(3, 2, 1.0, 1.5, ObjectClass::Pedestrian));
        v.reverse(); // input order must not matter
        v
    }

    #[test]
    fn one_feature_per_id_with_its_line_and_properties() -> Result<()> {
        let g = to_geojson(&sample())?;
        assert_eq!(g["type"], "FeatureCollection");
        let f = g["features"].as_array().expect("features");
        assert_eq!(f.len(), 2);
        assert_eq!(f[0]["properties"]["id"], 2);
        assert_eq!(f[0]["geometry"]["type"], "Point");
        let car = &f[1];
        assert_eq!(car["geometry"]["type"], "LineString");
        assert_eq!(
            car["geometry"]["coordinates"],
            json!([[3.0, 6.0], [6.0, 12.0], [9.0, 18.0], [12.0, 24.0]])
        );
        let p = &car["properties"];
        assert_eq!(p["class"], "car");
        assert_eq!(
            (p["start_frame"].clone(), p["end_frame"].clone()),
            (json!(1), json!(4))
        );
        assert_eq!(p["end_time_s"], 0.3);
        assert_eq!(p["mean_speed_mps"], 12.5);
        // Three steps of (3, 6) m: 3·√45.
        assert_eq!(p["length_m"], round(3.0 * 45f64.sqrt(), 3));
        assert_eq!(p["times_s"], json!([0.0, 0.1, 0.2, 0.3]));
        assert_eq!(g["roadtrack"]["coordinates"], "local-metres");
        Ok(())
    }

    #[test]
    fn the_written_file_round_trips_through_serde_json_and_is_stable() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = dir.path().join("t.geojson");
        write_geojson(&p, &sample())?;
        let text = std::fs::read_to_string(&p).map_err(|e| Error::io(&p, e))?;
        let back: Value = serde_json::from_str(&text).map_err(|e| Error::Invalid(e.to_string()))?;
        assert_eq!(back, to_geojson(&sample())?);
        assert_eq!(
            text.lines().count(),
            4,
            "header, two features, footer:\n{text}"
        );
        write_geojson(&p, &sample())?;
        assert_eq!(
            std::fs::read_to_string(&p).map_err(|e| Error::io(&p, e))?,
            text
        );
        Ok(())
    }

    #[test]
    fn points_without_ground_coordinates_are_refused() {
        let mut pts = sample();
        pts[1].ground = None;
        let e = to_geojson(&pts).expect_err("no ground");
        assert!(e.to_string().contains("calibration"), "{e}");
    }

    #[test]
    fn no_points_is_an_empty_collection() -> Result<()> {
        assert_eq!(to_geojson(&[])?["features"], json!([]));
        Ok(())
    }
}
