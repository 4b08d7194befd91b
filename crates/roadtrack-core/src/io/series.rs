//! Chart series from any CSV table with a header (a sweep table, an experiment log): two
//! numeric columns as x and y, optionally split into one series per value of a third.

use super::table::Table;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One named line of a chart: `(x, y)` points drawn in order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Points, drawn in this order.
    pub points: Vec<(f64, f64)>,
}

/// Reads columns `x` and `y` of `path` (header names are case-insensitive) as chart
/// series: one series named after `y` or, with `group`, one per distinct value of that
/// column, named `"<group>=<value>"`, in order of first appearance. Points of a series
/// are sorted by x (stable), so lines run left to right.
///
/// # Errors
/// A missing column, a non-numeric or empty x or y (named by line and column), or a table
/// without rows.
pub fn read_series(path: &Path, x: &str, y: &str, group: Option<&str>) -> Result<Vec<Series>> {
    let (x, y) = (x.to_ascii_lowercase(), y.to_ascii_lowercase());
    let group = group.map(str::to_ascii_lowercase);
    let table = Table::open(path)?;
    let mut needed = vec![x.as_str(), y.as_str()];
    if let Some(g) = &group {
        needed.push(g);
    }
    table.require(&needed)?;
    let mut out: Vec<Series> = Vec::new();
    table.for_each(|row| {
        let point = (row.f64(&x)?, row.f64(&y)?);
        let label = match &group {
            Some(g) => format!("{g}={}", row.opt_str(g).unwrap_or("")),
            None => y.clone(),
        };
        match out.iter_mut().find(|s| s.label == label) {
            Some(s) => s.points.push(point),
            None => out.push(Series {
                label,
                points: vec![point],
            }),
        }
        Ok(())
    })?;
    if out.is_empty() {
        return Err(Error::format(path, "no data rows"));
    }
    for s in &mut out {
        s.points.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(text: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("t.csv");
        std::fs::write(&p, text).expect("write");
        (dir, p)
    }

    #[test]
    fn groups_become_series_in_order_of_appearance_sorted_by_x() -> Result<()> {
        let (_d, p) = file("variant,dt,rate\nd,2,0.9\nc,1,0.8\nd,1,0.95\n");
        let s = read_series(&p, "DT", "rate", Some("variant"))?;
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].label, "variant=d");
        assert_eq!(s[0].points, [(1.0, 0.95), (2.0, 0.9)]);
        assert_eq!(s[1].points, [(1.0, 0.8)]);
        let one = read_series(&p, "dt", "rate", None)?;
        assert_eq!((one.len(), one[0].label.as_str()), (1, "rate"));
        Ok(())
    }

    #[test]
    fn bad_values_and_missing_columns_are_named() {
        let (_d, p) = file("dt,rate\n1,0.5\n2,high\n");
        let e = read_series(&p, "dt", "rate", None).expect_err("bad");
        assert!(
            e.to_string().contains(":3:") && e.to_string().contains("rate"),
            "{e}"
        );
        let e = read_series(&p, "dt", "nope", None).expect_err("missing");
        assert!(e.to_string().contains("nope"), "{e}");
    }
}
