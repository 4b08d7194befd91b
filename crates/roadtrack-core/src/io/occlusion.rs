//! Occlusion outcomes CSV (input of the seed 002 separation measure, Fig. 10): header
//! `frame,id,visible_blocks,separated`.
//!
//! One row per occluded object per frame: `visible_blocks` is how many 8 × 8 px blocks of
//! the object are visible in that frame (from the ground truth), `separated` is 1 when the
//! tracker still produced a region of its own for the object and 0 when the object was
//! absorbed by a neighbour or lost (see `metrics::papers::separation_outcomes`, which makes
//! these rows from object maps). Unknown columns are ignored.

use super::table::Table;
use crate::error::Result;
use std::path::Path;

/// One occluded object in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OcclusionRow {
    /// 1-based frame number.
    pub frame: u32,
    /// Ground-truth object id.
    pub id: u64,
    /// Visible area, blocks.
    pub visible_blocks: u32,
    /// Whether the tracker kept the object as a region of its own.
    pub separated: bool,
}

/// Reads an occlusion outcomes CSV.
///
/// # Errors
/// Missing columns, non-integer values, `separated` other than 0 or 1.
pub fn read_occlusion(path: &Path) -> Result<Vec<OcclusionRow>> {
    let table = Table::open(path)?;
    table.require(&["frame", "id", "visible_blocks", "separated"])?;
    let mut out = Vec::new();
    table.for_each(|row| {
        let int = |name: &str| -> Result<u64> {
            row.opt_u64(name)?
                .ok_or_else(|| row.error(name, "value missing"))
        };
        let frame = int("frame")?;
        crate::limits::at_most(
            frame,
            u64::from(crate::limits::MAX_FRAME),
            "largest frame number",
        )
        .map_err(|m| row.error("frame", m))?;
        let separated = match int("separated")? {
            0 => false,
            1 => true,
            v => return Err(row.error("separated", format!("must be 0 or 1, found {v}"))),
        };
        out.push(OcclusionRow {
            frame: u32::try_from(frame).map_err(|_| row.error("frame", "too large"))?,
            id: int("id")?,
            visible_blocks: u32::try_from(int("visible_blocks")?)
                .map_err(|_| row.error("visible_blocks", "too large"))?,
            separated,
        });
        Ok(())
    })?;
    Ok(out)
}

/// Writes an occlusion outcomes CSV atomically (`-` for standard output).
pub fn write_occlusion(path: &Path, rows: &[OcclusionRow]) -> Result<()> {
    super::write_atomic(path, |w| {
        writeln!(w, "frame,id,visible_blocks,separated")?;
        for r in rows {
            writeln!(
                w,
                "{},{},{},{}",
                r.frame,
                r.id,
                r.visible_blocks,
                u8::from(r.separated)
            )?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors() -> Result<()> {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("o.csv");
        let rows = vec![
            OcclusionRow {
                frame: 3,
                id: 7,
                visible_blocks: 2,
                separated: true,
            },
            OcclusionRow {
                frame: 4,
                id: 7,
                visible_blocks: 1,
                separated: false,
            },
        ];
        write_occlusion(&p, &rows)?;
        assert_eq!(read_occlusion(&p)?, rows);
        std::fs::write(&p, "frame,id,visible_blocks,separated\n1,2,3,2\n").expect("write");
        let m = read_occlusion(&p).expect_err("separated 2").to_string();
        assert!(m.contains(":2:") && m.contains("separated"), "{m}");
        Ok(())
    }
}
