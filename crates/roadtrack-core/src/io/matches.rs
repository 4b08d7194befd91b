//! Matches CSV (output of `roadtrack match`, INTERFACES.md): header `id1,id2,probability`.
//!
//! One row per frame-1 detection in input order (`id2` empty for "no partner"), then one row
//! per frame-2 detection that nobody chose, with `id1` empty (appeared).

use super::table::{Table, num};
use crate::error::Result;
use std::collections::HashSet;
use std::path::Path;

/// One row of a matches file.
#[derive(Debug, Clone, PartialEq)]
pub struct MatchRow {
    /// Frame-1 id; `None` for a frame-2 detection that appeared.
    pub id1: Option<u64>,
    /// Frame-2 id; `None` when the frame-1 detection has no partner.
    pub id2: Option<u64>,
    /// Final probability of the chosen label (empty in the file for appeared rows, read as
    /// `None`).
    pub probability: Option<f64>,
}

/// Reads a matches CSV.
///
/// # Errors
/// Missing columns, non-integer ids, probabilities outside `[0, 1]`, a row with neither id,
/// an `id1` listed twice.
pub fn read_matches(path: &Path) -> Result<Vec<MatchRow>> {
    let table = Table::open(path)?;
    table.require(&["id1", "id2"])?;
    let mut out = Vec::new();
    let mut seen = HashSet::new();
    table.for_each(|row| {
        let id1 = row.opt_u64("id1")?;
        let id2 = row.opt_u64("id2")?;
        if id1.is_none() && id2.is_none() {
            return Err(row.error("id1", "row has neither id1 nor id2"));
        }
        if let Some(i) = id1
            && !seen.insert(i)
        {
            return Err(row.error("id1", format!("id1 {i} listed twice")));
        }
        let probability = row.opt_f64("probability")?;
        if let Some(p) = probability
            && !(0.0..=1.0).contains(&p)
        {
            return Err(row.error("probability", format!("probability {p} outside [0, 1]")));
        }
        out.push(MatchRow {
            id1,
            id2,
            probability,
        });
        Ok(())
    })?;
    Ok(out)
}

/// Writes a matches CSV atomically (`-` for standard output); probabilities with 6 decimals.
pub fn write_matches(path: &Path, rows: &[MatchRow]) -> Result<()> {
    let opt = |x: Option<u64>| x.map(|v| v.to_string()).unwrap_or_default();
    super::write_atomic(path, |w| {
        writeln!(w, "id1,id2,probability")?;
        for r in rows {
            let p = r.probability.map(|p| num(p, 6)).unwrap_or_default();
            writeln!(w, "{},{},{}", opt(r.id1), opt(r.id2), p)?;
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
        let p = dir.path().join("m.csv");
        let rows = vec![
            MatchRow {
                id1: Some(1),
                id2: Some(4),
                probability: Some(0.75),
            },
            MatchRow {
                id1: Some(2),
                id2: None,
                probability: Some(1.0),
            },
            MatchRow {
                id1: None,
                id2: Some(9),
                probability: None,
            },
        ];
        write_matches(&p, &rows)?;
        assert_eq!(
            std::fs::read_to_string(&p).expect("read"),
            "id1,id2,probability\n1,4,0.75\n2,,1\n,9,\n"
        );
        assert_eq!(read_matches(&p)?, rows);
        std::fs::write(&p, "id1,id2,probability\n1,2,1.5\n").expect("write");
        let m = read_matches(&p).expect_err("p > 1").to_string();
        assert!(m.contains(":2:") && m.contains("probability"), "{m}");
        std::fs::write(&p, "id1,id2\n1,2\n1,3\n").expect("write");
        let m = read_matches(&p).expect_err("dup").to_string();
        assert!(m.contains(":3:") && m.contains("twice"), "{m}");
        Ok(())
    }
}
