//! Trajectories CSV (INTERFACES.md): header
//! `frame,time_s,id,class,x_px,y_px,w_px,h_px,score`, followed by
//! `x_m,y_m,speed_mps,heading_deg` when a calibration was given.
//!
//! `x_px,y_px` is the box centre.

use super::atomic::AtomicFile;
use super::detections::csv_word;
use super::table::{Table, num};
use crate::class::ObjectClass;
use crate::error::{Error, Result};
use crate::geometry::{BBox, Point};
use crate::track_point::{GroundState, TrackPoint};
use std::collections::HashSet;
use std::io::Write as _;
use std::path::Path;

/// Writes `points` as a trajectories CSV, atomically (`-` for standard output), sorted by
/// frame then id. The ground columns are written when every point has a ground state.
///
/// # Errors
/// Some but not all points have a ground state (a programming error surfaced as an error).
pub fn write_trajectories(path: &Path, points: &[TrackPoint]) -> Result<()> {
    let n_ground = points.iter().filter(|p| p.ground.is_some()).count();
    if n_ground != 0 && n_ground != points.len() {
        return Err(Error::Invalid(format!(
            "{} of {} trajectory points have ground coordinates; expected all or none",
            n_ground,
            points.len()
        )));
    }
    let mut rows: Vec<&TrackPoint> = points.iter().collect();
    rows.sort_by_key(|p| (p.frame, p.id));
    let mut w = TrajectoriesWriter::create(path, n_ground > 0)?;
    for p in rows {
        w.write_point(p)?;
    }
    w.commit()
}

/// A trajectories CSV written as the points come ([`write_trajectories`]'s format); the
/// caller gives the points in (frame, id) order. In place only after
/// [`TrajectoriesWriter::commit`].
#[derive(Debug)]
pub struct TrajectoriesWriter {
    out: AtomicFile,
    with_ground: bool,
}

impl TrajectoriesWriter {
    /// Starts `path` (`-` = standard output) and writes the header, with the ground columns
    /// when `with_ground`.
    ///
    /// # Errors
    /// As [`AtomicFile::create`].
    pub fn create(path: &Path, with_ground: bool) -> Result<Self> {
        let mut out = AtomicFile::create(path)?;
        let header = if with_ground {
            "frame,time_s,id,class,x_px,y_px,w_px,h_px,score,x_m,y_m,speed_mps,heading_deg"
        } else {
            "frame,time_s,id,class,x_px,y_px,w_px,h_px,score"
        };
        writeln!(out, "{header}").map_err(|e| Error::io(path, e))?;
        Ok(Self { out, with_ground })
    }

    /// Writes one row.
    ///
    /// # Errors
    /// The point has a ground state and the file has no ground columns or the other way
    /// round; the write fails.
    pub fn write_point(&mut self, p: &TrackPoint) -> Result<()> {
        if p.ground.is_some() != self.with_ground {
            return Err(Error::Invalid(format!(
                "frame {}, id {}: {} ground coordinates in a trajectories file {} them",
                p.frame,
                p.id,
                if p.ground.is_some() { "has" } else { "lacks" },
                if self.with_ground { "with" } else { "without" }
            )));
        }
        let c = p.bbox.centre();
        let w = &mut self.out;
        let mut line = format!(
            "{},{},{},{},{},{},{},{},{}",
            p.frame,
            num(p.time_s, 6),
            p.id,
            csv_word(p.class.name()),
            num(c.x, 3),
            num(c.y, 3),
            num(p.bbox.width, 3),
            num(p.bbox.height, 3),
            num(p.score, 6)
        );
        if let Some(g) = p.ground {
            line.push_str(&format!(
                ",{},{},{},{}",
                num(g.x_m, 4),
                num(g.y_m, 4),
                num(g.speed_mps, 4),
                num(g.heading_deg, 3)
            ));
        }
        writeln!(w, "{line}").map_err(|e| Error::io(self.out.path(), e))
    }

    /// Puts the file in place.
    ///
    /// # Errors
    /// As [`AtomicFile::commit`].
    pub fn commit(self) -> Result<()> {
        self.out.commit()
    }
}

/// Reads a trajectories CSV.
///
/// # Errors
/// Missing columns, bad numbers, negative sizes, an id repeated within a frame.
pub fn read_trajectories(path: &Path) -> Result<Vec<TrackPoint>> {
    let table = Table::open(path)?;
    table.require(&["frame", "time_s", "id", "x_px", "y_px", "w_px", "h_px"])?;
    let ground_cols = ["x_m", "y_m", "speed_mps", "heading_deg"];
    let with_ground = ground_cols.iter().all(|c| table.has(c));
    let mut out = Vec::new();
    let mut seen = HashSet::new();
    table.for_each(|row| {
        let frame = row
            .opt_frame("frame")?
            .ok_or_else(|| row.error("frame", "frame must be an integer ≥ 1"))?;
        let id = row
            .opt_u64("id")?
            .ok_or_else(|| row.error("id", "empty id"))?;
        if !seen.insert((frame, id)) {
            return Err(row.error("id", format!("id {id} appears twice in frame {frame}")));
        }
        let (w, h) = (row.f64("w_px")?, row.f64("h_px")?);
        for (v, c) in [(w, "w_px"), (h, "h_px")] {
            if v < 0.0 {
                return Err(row.error(c, format!("negative size {v}")));
            }
        }
        let ground = if with_ground {
            Some(GroundState {
                x_m: row.f64("x_m")?,
                y_m: row.f64("y_m")?,
                speed_mps: row.f64("speed_mps")?,
                heading_deg: row.f64("heading_deg")?,
            })
        } else {
            None
        };
        out.push(TrackPoint {
            frame,
            time_s: row.f64("time_s")?,
            id,
            class: row
                .opt_str("class")
                .map_or(ObjectClass::Unknown, |s| ObjectClass::from(s.to_owned())),
            bbox: BBox::from_centre(Point::new(row.f64("x_px")?, row.f64("y_px")?), w, h),
            score: row.opt_f64("score")?.unwrap_or(1.0),
            ground,
        });
        Ok(())
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(frame: u32, id: u64, ground: bool) -> TrackPoint {
        TrackPoint {
            frame,
            time_s: f64::from(frame - 1) / 10.0,
            id,
            class: ObjectClass::Car,
            bbox: BBox::new(1.0, 2.0, 4.0, 6.0),
            score: 0.5,
            ground: ground.then_some(GroundState {
                x_m: 1.5,
                y_m: -2.0,
                speed_mps: 3.25,
                heading_deg: 90.0,
            }),
        }
    }

    #[test]
    fn round_trips_with_and_without_ground() -> Result<()> {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("t.csv");
        for ground in [false, true] {
            let pts = vec![point(1, 1, ground), point(2, 1, ground)];
            write_trajectories(&p, &pts)?;
            assert_eq!(read_trajectories(&p)?, pts);
        }
        let text = std::fs::read_to_string(&p).expect("read");
        assert!(text.starts_with("frame,time_s,id,class,x_px,y_px,w_px,h_px,score,x_m,y_m,speed_mps,heading_deg\n1,0,1,car,3,5,4,6,0.5,1.5,-2,3.25,90\n"), "{text}");
        Ok(())
    }

    #[test]
    fn mixed_ground_is_rejected() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("t.csv");
        assert!(write_trajectories(&p, &[point(1, 1, true), point(1, 2, false)]).is_err());
        assert!(!p.exists());
    }
}
