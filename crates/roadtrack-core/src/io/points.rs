//! Point measurements and filter estimates (INTERFACES.md): `step,x,y` and
//! `step,label,x,y,vx,vy,weight`.

use super::table::{Table, num};
use crate::error::Result;
use crate::geometry::Point;
use crate::limits::{MAX_COORDINATE, MAX_MEASUREMENTS_PER_STEP, MAX_STEP, at_most};
use std::collections::HashMap;
use std::path::Path;

/// One point measurement at a time step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// Time step (any integer origin; steps need not be contiguous).
    pub step: u64,
    /// Measured position (any units).
    pub pos: Point,
}

/// One labelled estimate of a filter at a time step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointEstimate {
    /// Time step.
    pub step: u64,
    /// Track label.
    pub label: u64,
    /// Position.
    pub pos: Point,
    /// Velocity, units per step.
    pub vel: Point,
    /// Weight (for the PHD filter, the label's share of the expected count).
    pub weight: f64,
}

/// Reads measurements; rows are returned sorted by step (stable).
///
/// # Errors
/// Names file, line and column of a missing or non-numeric value, a step above
/// [`MAX_STEP`] and the measurement that makes its step hold more than
/// [`MAX_MEASUREMENTS_PER_STEP`].
pub fn read_measurements(path: &Path) -> Result<Vec<Measurement>> {
    let table = Table::open(path)?;
    table.require(&["step", "x", "y"])?;
    let mut out = Vec::new();
    let mut per_step: HashMap<u64, usize> = HashMap::new();
    table.for_each(|row| {
        let step = row
            .opt_u64("step")?
            .ok_or_else(|| row.error("step", "empty step"))?;
        at_most(step, MAX_STEP, "largest step").map_err(|m| row.error("step", m))?;
        let n = per_step.entry(step).or_insert(0);
        *n += 1;
        at_most(*n, MAX_MEASUREMENTS_PER_STEP, "measurements in one step")
            .map_err(|m| row.error("step", format!("step {step}: {m}")))?;
        let coord = |c: &str| -> Result<f64> {
            let v = row.f64(c)?;
            at_most(v.abs(), MAX_COORDINATE, "coordinate magnitude")
                .map_err(|m| row.error(c, m))?;
            Ok(v)
        };
        out.push(Measurement {
            step,
            pos: Point::new(coord("x")?, coord("y")?),
        });
        Ok(())
    })?;
    out.sort_by_key(|m| m.step);
    Ok(out)
}

/// Writes measurements atomically.
pub fn write_measurements(path: &Path, rows: &[Measurement]) -> Result<()> {
    super::write_atomic(path, |w| {
        writeln!(w, "step,x,y")?;
        for m in rows {
            writeln!(w, "{},{},{}", m.step, num(m.pos.x, 6), num(m.pos.y, 6))?;
        }
        Ok(())
    })
}

/// Reads estimates.
pub fn read_estimates(path: &Path) -> Result<Vec<PointEstimate>> {
    let table = Table::open(path)?;
    table.require(&["step", "label", "x", "y", "vx", "vy", "weight"])?;
    let mut out = Vec::new();
    table.for_each(|row| {
        let weight = row.f64("weight")?;
        if weight < 0.0 {
            return Err(row.error("weight", format!("negative weight {weight}")));
        }
        let step = row
            .opt_u64("step")?
            .ok_or_else(|| row.error("step", "empty step"))?;
        at_most(step, MAX_STEP, "largest step").map_err(|m| row.error("step", m))?;
        out.push(PointEstimate {
            step,
            label: row
                .opt_u64("label")?
                .ok_or_else(|| row.error("label", "empty label"))?,
            pos: Point::new(row.f64("x")?, row.f64("y")?),
            vel: Point::new(row.f64("vx")?, row.f64("vy")?),
            weight,
        });
        Ok(())
    })?;
    Ok(out)
}

/// Writes estimates atomically (`-` for standard output).
pub fn write_estimates(path: &Path, rows: &[PointEstimate]) -> Result<()> {
    super::write_atomic(path, |w| {
        writeln!(w, "step,label,x,y,vx,vy,weight")?;
        for e in rows {
            writeln!(
                w,
                "{},{},{},{},{},{},{}",
                e.step,
                e.label,
                num(e.pos.x, 6),
                num(e.pos.y, 6),
                num(e.vel.x, 6),
                num(e.vel.y, 6),
                num(e.weight, 6)
            )?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips() -> Result<()> {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("m.csv");
        let m = vec![
            Measurement {
                step: 0,
                pos: Point::new(1.5, -2.0),
            },
            Measurement {
                step: 3,
                pos: Point::new(0.0, 9.0),
            },
        ];
        write_measurements(&p, &m)?;
        assert_eq!(read_measurements(&p)?, m);
        let e = vec![PointEstimate {
            step: 1,
            label: 4,
            pos: Point::new(1.0, 2.0),
            vel: Point::new(-0.5, 0.25),
            weight: 0.9,
        }];
        write_estimates(&p, &e)?;
        assert_eq!(read_estimates(&p)?, e);
        std::fs::write(&p, "step,x\n1,2\n").expect("write");
        assert!(
            read_measurements(&p)
                .expect_err("no y")
                .to_string()
                .contains("`y`")
        );
        Ok(())
    }
}
