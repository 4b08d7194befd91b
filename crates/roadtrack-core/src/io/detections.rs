//! Detections CSV (INTERFACES.md): header-named columns, order free.
//!
//! Required `x,y` (centre, px). Optional `frame` (default 1), `id` (default: row number
//! from 1), `w,h`, `r,g,b`, `class`, `score`, `area`. Unknown columns are ignored.

use super::table::{Table, num};
use crate::class::ObjectClass;
use crate::detection::Detection;
use crate::error::Result;
use crate::geometry::Point;
use std::collections::HashSet;
use std::path::Path;

/// Reads a detections CSV.
///
/// # Errors
/// Names the file, line and column of: a missing `x`/`y` column, a non-numeric or
/// non-finite value, a negative `w`/`h`/`area`, a colour outside 0–255, a score outside
/// `[0, 1]`, a frame below 1, only one of `w`/`h` or of `r,g,b`, and an id repeated
/// within a frame.
pub fn read_detections(path: &Path) -> Result<Vec<Detection>> {
    let table = Table::open(path)?;
    table.require(&["x", "y"])?;
    let has_rgb = ["r", "g", "b"].map(|c| table.has(c));
    if has_rgb.iter().any(|&h| h) && !has_rgb.iter().all(|&h| h) {
        table.require(&["r", "g", "b"])?;
    }
    let mut out = Vec::new();
    let mut seen = HashSet::new();
    let mut row_number = 0u64;
    table.for_each(|row| {
        row_number += 1;
        let frame = row.opt_frame("frame")?.unwrap_or(1);
        let id = row.opt_u64("id")?.unwrap_or(row_number);
        if !seen.insert((frame, id)) {
            return Err(row.error("id", format!("id {id} appears twice in frame {frame}")));
        }
        let pos_px = Point::new(row.f64("x")?, row.f64("y")?);
        let size_px = match (row.opt_f64("w")?, row.opt_f64("h")?) {
            (None, None) => None,
            (Some(w), Some(h)) => {
                for (v, c) in [(w, "w"), (h, "h")] {
                    if v < 0.0 {
                        return Err(row.error(c, format!("negative size {v}")));
                    }
                }
                Some((w, h))
            }
            (Some(_), None) => return Err(row.error("h", "`w` given without `h`")),
            (None, Some(_)) => return Err(row.error("w", "`h` given without `w`")),
        };
        let rgb = [row.opt_f64("r")?, row.opt_f64("g")?, row.opt_f64("b")?];
        let colour_rgb = match rgb {
            [None, None, None] => None,
            [Some(r), Some(g), Some(b)] => {
                for (v, c) in [(r, "r"), (g, "g"), (b, "b")] {
                    if !(0.0..=255.0).contains(&v) {
                        return Err(row.error(c, format!("colour {v} outside 0–255")));
                    }
                }
                Some([r, g, b])
            }
            _ => {
                let c = ["r", "g", "b"][rgb.iter().position(Option::is_none).unwrap_or(0)];
                return Err(row.error(c, "colour needs all of r, g, b"));
            }
        };
        let score = row.opt_f64("score")?;
        if let Some(s) = score
            && !(0.0..=1.0).contains(&s)
        {
            return Err(row.error("score", format!("score {s} outside [0, 1]")));
        }
        let area_px = row.opt_f64("area")?;
        if let Some(a) = area_px
            && a < 0.0
        {
            return Err(row.error("area", format!("negative area {a}")));
        }
        out.push(Detection {
            frame,
            id,
            pos_px,
            size_px,
            colour_rgb,
            class: row
                .opt_str("class")
                .map(|s| ObjectClass::from(s.to_owned())),
            score,
            area_px,
        });
        Ok(())
    })?;
    Ok(out)
}

/// Writes `detections` as a detections CSV, atomically (`-` for standard output).
///
/// Columns: `frame,id,x,y`, then `w,h`, `r,g,b`, `area`, `class`, `score` when any
/// detection has them (empty fields where one lacks a value). Positions and sizes with
/// 3 decimals, colours with 2.
pub fn write_detections(path: &Path, detections: &[Detection]) -> Result<()> {
    let any = |f: fn(&Detection) -> bool| detections.iter().any(f);
    let (has_size, has_rgb, has_area, has_class, has_score) = (
        any(|d| d.size_px.is_some()),
        any(|d| d.colour_rgb.is_some()),
        any(|d| d.area_px.is_some()),
        any(|d| d.class.is_some()),
        any(|d| d.score.is_some()),
    );
    super::write_atomic(path, |w| {
        let mut header = String::from("frame,id,x,y");
        if has_size {
            header.push_str(",w,h");
        }
        if has_rgb {
            header.push_str(",r,g,b");
        }
        if has_area {
            header.push_str(",area");
        }
        if has_class {
            header.push_str(",class");
        }
        if has_score {
            header.push_str(",score");
        }
        writeln!(w, "{header}")?;
        let mut line = String::new();
        for d in detections {
            line.clear();
            line.push_str(&format!(
                "{},{},{},{}",
                d.frame,
                d.id,
                num(d.pos_px.x, 3),
                num(d.pos_px.y, 3)
            ));
            if has_size {
                match d.size_px {
                    Some((sw, sh)) => line.push_str(&format!(",{},{}", num(sw, 3), num(sh, 3))),
                    None => line.push_str(",,"),
                }
            }
            if has_rgb {
                match d.colour_rgb {
                    Some([r, g, b]) => {
                        line.push_str(&format!(",{},{},{}", num(r, 2), num(g, 2), num(b, 2)))
                    }
                    None => line.push_str(",,,"),
                }
            }
            if has_area {
                line.push(',');
                if let Some(a) = d.area_px {
                    line.push_str(&num(a, 3));
                }
            }
            if has_class {
                line.push(',');
                if let Some(c) = &d.class {
                    line.push_str(&csv_word(c.name()));
                }
            }
            if has_score {
                line.push(',');
                if let Some(s) = d.score {
                    line.push_str(&num(s, 6));
                }
            }
            writeln!(w, "{line}")?;
        }
        Ok(())
    })
}

/// Quotes a word for CSV when it needs it.
pub fn csv_word(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, text).expect("write fixture");
        p
    }

    fn err(text: &str) -> String {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = write(&dir, "d.csv", text);
        read_detections(&p).expect_err("must fail").to_string()
    }

    #[test]
    fn reads_minimal_and_full_files() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = write(&dir, "a.csv", "y,x,extra\n2,1,zz\n4,3,\n");
        let d = read_detections(&p)?;
        assert_eq!(d.len(), 2);
        assert_eq!(
            (d[0].frame, d[0].id, d[0].pos_px),
            (1, 1, Point::new(1.0, 2.0))
        );
        assert_eq!(d[1].id, 2);
        let p = write(
            &dir,
            "b.csv",
            "frame,id,x,y,w,h,r,g,b,class,score\n3,7,1.5,2.5,4,5,10,20,30,car,0.9\n3,8,1,1,,,,,,,\n",
        );
        let d = read_detections(&p)?;
        assert_eq!(d[0].size_px, Some((4.0, 5.0)));
        assert_eq!(d[0].colour_rgb, Some([10.0, 20.0, 30.0]));
        assert_eq!(d[0].class, Some(ObjectClass::Car));
        assert_eq!(d[0].score, Some(0.9));
        assert_eq!(d[1].size_px, None);
        Ok(())
    }

    #[test]
    fn write_then_read_is_identity() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = dir.path().join("o.csv");
        let mut a = Detection::at(2, 5, Point::new(10.25, 20.5));
        a.size_px = Some((3.0, 4.0));
        a.colour_rgb = Some([1.5, 2.0, 250.0]);
        a.class = Some(ObjectClass::Other("tram, old".into()));
        a.area_px = Some(12.0);
        let b = Detection::at(2, 6, Point::new(0.0, 0.0));
        write_detections(&p, &[a.clone(), b.clone()])?;
        assert_eq!(read_detections(&p)?, vec![a, b]);
        Ok(())
    }

    #[test]
    fn bad_values_name_file_line_and_column() {
        let m = err("x,y\n1,2\n1,abc\n");
        assert!(
            m.contains("d.csv:3:") && m.contains("`y`") && m.contains("not a number"),
            "{m}"
        );
        let m = err("x,y\n1,NaN\n");
        assert!(m.contains(":2:") && m.contains("finite"), "{m}");
        let m = err("x,y,w,h\n1,2,-3,4\n");
        assert!(
            m.contains(":2:") && m.contains("`w`") && m.contains("negative"),
            "{m}"
        );
        let m = err("frame,id,x,y\n1,4,1,2\n2,4,1,2\n1,4,5,5\n");
        assert!(
            m.contains(":4:") && m.contains("`id`") && m.contains("twice"),
            "{m}"
        );
        let m = err("x,z\n1,2\n");
        assert!(m.contains("missing required column `y`"), "{m}");
        let m = err("");
        assert!(m.contains("empty file"), "{m}");
        let m = err("x,y,r,g,b\n1,2,3,4,300\n");
        assert!(m.contains("`b`") && m.contains("0–255"), "{m}");
        let m = err("x,y\n1,2,3\n");
        assert!(m.contains(":2:") && m.contains("fields"), "{m}");
        let m = err("frame,x,y\n0,1,2\n");
        assert!(m.contains("`frame`"), "{m}");
    }
}
