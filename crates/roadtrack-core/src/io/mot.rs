//! MOTChallenge text files (no header): tracks, ground truth and public detections.
//!
//! - tracks: `frame,id,bb_left,bb_top,bb_width,bb_height,conf,x,y,z` with `x,y,z = -1`;
//! - ground truth: `frame,id,bb_left,bb_top,bb_width,bb_height,consider,class,visibility`;
//! - detections (`det/det.txt`): the tracks layout with id `-1`.
//!
//! Readers accept rows in any order and return them sorted by frame, then id (a stable
//! sort, so equal keys keep file order). An empty file is an empty list. Fields may be
//! separated by commas (MOTChallenge) and surrounded by spaces.

use super::atomic::AtomicFile;
use super::table::{field_f64, num, trim};
use crate::detection::Detection;
use crate::error::{Error, Result};
use crate::geometry::BBox;
use crate::limits::{MAX_FRAME, at_most};
use crate::track_point::TrackPoint;
use std::io::Write as _;
use std::path::Path;

/// One row of a MOTChallenge tracks file.
#[derive(Debug, Clone, PartialEq)]
pub struct MotTrackRow {
    /// 1-based frame number.
    pub frame: u32,
    /// Track id.
    pub id: u64,
    /// Box, px.
    pub bbox: BBox,
    /// Confidence (1 when the file has no 7th field).
    pub conf: f64,
}

/// One row of a MOTChallenge ground-truth file.
#[derive(Debug, Clone, PartialEq)]
pub struct MotGtRow {
    /// 1-based frame number.
    pub frame: u32,
    /// Object id.
    pub id: u64,
    /// Box, px.
    pub bbox: BBox,
    /// Whether the row counts in evaluation (MOTChallenge "consider" / "active" flag).
    pub consider: bool,
    /// MOT17 class number (1 pedestrian, 3 car, …; see [`crate::ObjectClass::mot17_id`]).
    pub class: u32,
    /// Fraction of the object not occluded, in `[0, 1]`.
    pub visibility: f64,
}

/// The most fields a MOTChallenge row has; later fields are ignored.
const MAX_FIELDS: usize = 10;

/// The fields of one line, without a heap allocation.
struct Fields<'a> {
    f: [&'a str; MAX_FIELDS],
    n: usize,
}

impl<'a> Fields<'a> {
    fn as_slice(&self) -> &[&'a str] {
        &self.f[..self.n]
    }
}

/// Splits one line into (at most [`MAX_FIELDS`]) trimmed fields, returning `None` for blank
/// lines. One pass over the bytes (`str::split` searches per field, which dominated).
fn fields(line: &str) -> Option<Fields<'_>> {
    let t = trim(line);
    if t.is_empty() {
        return None;
    }
    let mut out = Fields {
        f: [""; MAX_FIELDS],
        n: 0,
    };
    let mut start = 0;
    for (i, &c) in t.as_bytes().iter().enumerate() {
        if c == b',' {
            // `,` is ASCII, so `start..i` lies on character boundaries.
            out.f[out.n] = trim(&t[start..i]);
            out.n += 1;
            start = i + 1;
            if out.n == MAX_FIELDS {
                return Some(out);
            }
        }
    }
    out.f[out.n] = trim(&t[start..]);
    out.n += 1;
    Some(out)
}

fn frame_of(path: &Path, line: u64, f: &[&str]) -> Result<u32> {
    // Fast path: a plain integer (what every writer produces).
    if let Some(Ok(x)) = f.first().map(|s| s.parse::<u32>())
        && (1..=MAX_FRAME).contains(&x)
    {
        return Ok(x);
    }
    let x = field_f64(path, line, f, 0, "frame")?;
    if x < 1.0 || x.fract() != 0.0 {
        return Err(Error::parse(
            path,
            line,
            "frame",
            format!("frame must be an integer ≥ 1, found {}", f[0]),
        ));
    }
    at_most(x, f64::from(MAX_FRAME), "largest frame number")
        .map_err(|m| Error::parse(path, line, "frame", m))?;
    Ok(x as u32)
}

fn id_of(path: &Path, line: u64, f: &[&str]) -> Result<u64> {
    if let Some(Ok(x)) = f.get(1).map(|s| s.parse::<u64>()) {
        return Ok(x);
    }
    let x = field_f64(path, line, f, 1, "id")?;
    if x < 0.0 || x.fract() != 0.0 {
        return Err(Error::parse(
            path,
            line,
            "id",
            format!("id must be a non-negative integer, found {}", f[1]),
        ));
    }
    Ok(x as u64)
}

/// Sorts rows by (frame, id), stably, and rejects an id repeated within a frame, naming the
/// line of the first repetition in file order. `lines[i]` is the line of `rows[i]`.
// Choice: duplicates are found after the sort instead of with a hash set while reading
// (a third of the reading time); a parse error anywhere is therefore reported before a
// repeated id.
fn sort_unique<T>(
    path: &Path,
    rows: Vec<T>,
    lines: Vec<u64>,
    key: impl Fn(&T) -> (u32, u64),
) -> Result<Vec<T>> {
    if rows.windows(2).all(|w| key(&w[0]) < key(&w[1])) {
        return Ok(rows);
    }
    let mut v: Vec<(T, u64)> = rows.into_iter().zip(lines).collect();
    v.sort_by_key(|(r, _)| key(r));
    // In a stable sort the later of two equal rows is the repetition.
    if let Some((frame, id, line)) = v
        .windows(2)
        .filter(|w| key(&w[0].0) == key(&w[1].0))
        .map(|w| (key(&w[1].0).0, key(&w[1].0).1, w[1].1))
        .min_by_key(|t| t.2)
    {
        return Err(Error::parse(
            path,
            line,
            "id",
            format!("id {id} appears twice in frame {frame}"),
        ));
    }
    Ok(v.into_iter().map(|(r, _)| r).collect())
}

fn bbox_of(path: &Path, line: u64, f: &[&str]) -> Result<BBox> {
    let left = field_f64(path, line, f, 2, "bb_left")?;
    let top = field_f64(path, line, f, 3, "bb_top")?;
    let width = field_f64(path, line, f, 4, "bb_width")?;
    let height = field_f64(path, line, f, 5, "bb_height")?;
    for (v, c) in [(width, "bb_width"), (height, "bb_height")] {
        if v < 0.0 {
            return Err(Error::parse(path, line, c, format!("negative size {v}")));
        }
    }
    Ok(BBox::new(left, top, width, height))
}

fn read_lines(path: &Path) -> Result<String> {
    super::read_text(path)
}

/// The reader behind [`read_tracks`] and [`read_gt`]: for every non-blank line, its frame,
/// id and box (fields 1–6), then `row` makes the record from them and the fields after the
/// box (`row(line, fields, frame, id, bbox)`). Rows come back sorted by (frame, id) with an
/// id repeated within a frame rejected ([`sort_unique`]).
///
/// With `same_fields`, every line must have as many fields as the first (up to
/// [`MAX_FIELDS`]): a line with a column cut out would otherwise be read with its later
/// fields shifted.
fn read_rows<T>(
    path: &Path,
    same_fields: bool,
    row: impl Fn(u64, &[&str], u32, u64, BBox) -> Result<T>,
    key: impl Fn(&T) -> (u32, u64),
) -> Result<Vec<T>> {
    let text = read_lines(path)?;
    let mut out = Vec::new();
    let mut lines = Vec::new();
    let mut first: Option<(u64, usize)> = None;
    for (i, l) in text.lines().enumerate() {
        let line = i as u64 + 1;
        let Some(f) = fields(l) else { continue };
        let f = f.as_slice();
        match first {
            None => first = Some((line, f.len())),
            Some((first_line, n)) if same_fields && n != f.len() => {
                return Err(Error::parse(
                    path,
                    line,
                    (f.len().min(n) + 1).to_string(),
                    format!(
                        "{} fields, but line {first_line} has {n}; every line needs the same fields",
                        f.len()
                    ),
                ));
            }
            Some(_) => {}
        }
        let frame = frame_of(path, line, f)?;
        let id = id_of(path, line, f)?;
        let bbox = bbox_of(path, line, f)?;
        out.push(row(line, f, frame, id, bbox)?);
        lines.push(line);
    }
    sort_unique(path, out, lines, key)
}

/// Reads a MOTChallenge tracks file: 6 fields (frame to box), 7 (and `conf`) or 10 (and
/// `x,y,z`), the same on every line.
///
/// # Errors
/// Names file, line and column of a missing or non-numeric field, a line with 8 or 9
/// fields or with another count than the first line, a frame below 1, a negative id or
/// size, and an id repeated within a frame.
pub fn read_tracks(path: &Path) -> Result<Vec<MotTrackRow>> {
    read_rows(
        path,
        true,
        |line, f, frame, id, bbox| {
            // Choice: `x,y,z` come as a triple, so 8 or 9 fields mean a column is missing.
            if matches!(f.len(), 8 | 9) {
                return Err(Error::parse(
                    path,
                    line,
                    (f.len() + 1).to_string(),
                    format!(
                        "{} fields; MOTChallenge tracks have 10 \
                         (frame,id,bb_left,bb_top,bb_width,bb_height,conf,x,y,z), 7 or 6",
                        f.len()
                    ),
                ));
            }
            let conf = if f.len() > 6 {
                field_f64(path, line, f, 6, "conf")?
            } else {
                1.0
            };
            Ok(MotTrackRow {
                frame,
                id,
                bbox,
                conf,
            })
        },
        |r| (r.frame, r.id),
    )
}

/// Reads a MOTChallenge ground-truth file. Missing trailing fields default to
/// `consider = 1`, `class = 1`, `visibility = 1`.
///
/// # Errors
/// As [`read_tracks`], plus a class that is not a positive integer and a visibility outside
/// `[0, 1]`.
pub fn read_gt(path: &Path) -> Result<Vec<MotGtRow>> {
    // Choice: ground truth keeps its per-line defaults for missing trailing fields.
    read_rows(
        path,
        false,
        |line, f, frame, id, bbox| {
            let consider = if f.len() > 6 {
                field_f64(path, line, f, 6, "consider")? != 0.0
            } else {
                true
            };
            let class = if f.len() > 7 {
                let c = field_f64(path, line, f, 7, "class")?;
                if c < 1.0 || c.fract() != 0.0 {
                    return Err(Error::parse(
                        path,
                        line,
                        "class",
                        format!("class must be a positive integer, found {}", f[7]),
                    ));
                }
                c as u32
            } else {
                1
            };
            let visibility = if f.len() > 8 {
                field_f64(path, line, f, 8, "visibility")?
            } else {
                1.0
            };
            if !(0.0..=1.0).contains(&visibility) {
                return Err(Error::parse(
                    path,
                    line,
                    "visibility",
                    format!("visibility {visibility} outside [0, 1]"),
                ));
            }
            Ok(MotGtRow {
                frame,
                id,
                bbox,
                consider,
                class,
                visibility,
            })
        },
        |r| (r.frame, r.id),
    )
}

/// Reads MOTChallenge public detections (`det/det.txt`): the id field is ignored and each
/// detection gets its 1-based row number within its frame as id.
pub fn read_detections(path: &Path) -> Result<Vec<Detection>> {
    let text = read_lines(path)?;
    let mut out: Vec<Detection> = Vec::new();
    for (i, l) in text.lines().enumerate() {
        let line = i as u64 + 1;
        let Some(f) = fields(l) else { continue };
        let f = f.as_slice();
        let frame = frame_of(path, line, f)?;
        let bbox = bbox_of(path, line, f)?;
        let conf = if f.len() > 6 {
            Some(field_f64(path, line, f, 6, "conf")?)
        } else {
            None
        };
        let mut d = Detection::at(frame, 0, bbox.centre());
        d.size_px = Some((bbox.width, bbox.height));
        d.score = conf;
        out.push(d);
    }
    out.sort_by_key(|d| d.frame);
    let mut prev = 0;
    let mut n = 0;
    for d in &mut out {
        if d.frame != prev {
            prev = d.frame;
            n = 0;
        }
        n += 1;
        d.id = n;
    }
    Ok(out)
}

/// Writes tracks in MOTChallenge layout, atomically (`-` for standard output), sorted by
/// frame then id; 3 decimals.
pub fn write_tracks(path: &Path, points: &[TrackPoint]) -> Result<()> {
    let mut rows: Vec<&TrackPoint> = points.iter().collect();
    rows.sort_by_key(|p| (p.frame, p.id));
    let mut w = TracksWriter::create(path)?;
    for p in rows {
        w.write_point(p)?;
    }
    w.commit()
}

/// A MOTChallenge tracks file written as the points come ([`write_tracks`]'s format); the
/// caller gives the points in (frame, id) order. In place only after
/// [`TracksWriter::commit`].
#[derive(Debug)]
pub struct TracksWriter {
    out: AtomicFile,
}

impl TracksWriter {
    /// Starts `path` (`-` = standard output).
    ///
    /// # Errors
    /// As [`AtomicFile::create`].
    pub fn create(path: &Path) -> Result<Self> {
        Ok(Self {
            out: AtomicFile::create(path)?,
        })
    }

    /// Writes one row.
    ///
    /// # Errors
    /// The write fails.
    pub fn write_point(&mut self, p: &TrackPoint) -> Result<()> {
        writeln!(
            self.out,
            "{},{},{},{},{},{},{},-1,-1,-1",
            p.frame,
            p.id,
            num(p.bbox.left, 3),
            num(p.bbox.top, 3),
            num(p.bbox.width, 3),
            num(p.bbox.height, 3),
            num(p.score, 6)
        )
        .map_err(|e| Error::io(self.out.path(), e))
    }

    /// Puts the file in place.
    ///
    /// # Errors
    /// As [`AtomicFile::commit`].
    pub fn commit(self) -> Result<()> {
        self.out.commit()
    }
}

/// Writes MOTChallenge public detections (`det/det.txt`), atomically: id `-1`, the box from
/// the detection's size (0 × 0 when unknown), the score as confidence (1 when unknown).
pub fn write_detections(path: &Path, detections: &[Detection]) -> Result<()> {
    super::write_atomic(path, |w| {
        for d in detections {
            let b = d.bbox().unwrap_or(BBox::from_centre(d.pos_px, 0.0, 0.0));
            writeln!(
                w,
                "{},-1,{},{},{},{},{},-1,-1,-1",
                d.frame,
                num(b.left, 3),
                num(b.top, 3),
                num(b.width, 3),
                num(b.height, 3),
                num(d.score.unwrap_or(1.0), 6)
            )?;
        }
        Ok(())
    })
}

/// Writes ground truth in MOTChallenge layout, atomically, sorted by frame then id.
pub fn write_gt(path: &Path, rows: &[MotGtRow]) -> Result<()> {
    let mut rows: Vec<&MotGtRow> = rows.iter().collect();
    rows.sort_by_key(|r| (r.frame, r.id));
    super::write_atomic(path, |w| {
        for r in rows {
            writeln!(
                w,
                "{},{},{},{},{},{},{},{},{}",
                r.frame,
                r.id,
                num(r.bbox.left, 3),
                num(r.bbox.top, 3),
                num(r.bbox.width, 3),
                num(r.bbox.height, 3),
                u8::from(r.consider),
                r.class,
                num(r.visibility, 6)
            )?;
        }
        Ok(())
    })
}

impl MotTrackRow {
    /// The row as a [`TrackPoint`] with unknown class, time from `fps`.
    pub fn to_track_point(&self, fps: f64) -> TrackPoint {
        TrackPoint {
            frame: self.frame,
            time_s: f64::from(self.frame - 1) / fps,
            id: self.id,
            class: crate::ObjectClass::Unknown,
            bbox: self.bbox,
            score: self.conf,
            ground: None,
        }
    }
}

impl MotGtRow {
    /// The row as a [`TrackPoint`]: class from the MOT17 number, visibility as score, time
    /// from `fps`.
    pub fn to_track_point(&self, fps: f64) -> TrackPoint {
        TrackPoint {
            frame: self.frame,
            time_s: f64::from(self.frame - 1) / fps,
            id: self.id,
            class: crate::ObjectClass::from_mot17_id(i64::from(self.class)),
            bbox: self.bbox,
            score: self.visibility,
            ground: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Point;

    fn file(text: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("f.txt");
        std::fs::write(&p, text).expect("write");
        (dir, p)
    }

    #[test]
    fn tracks_round_trip_and_sort_by_frame() -> Result<()> {
        let (_d, p) = file("2,1,1,2,3,4,0.5,-1,-1,-1\n1,9,0,0,1,1,1,-1,-1,-1\n\n");
        let rows = read_tracks(&p)?;
        assert_eq!(
            rows.iter().map(|r| (r.frame, r.id)).collect::<Vec<_>>(),
            [(1, 9), (2, 1)]
        );
        let pts: Vec<TrackPoint> = rows.iter().map(|r| r.to_track_point(10.0)).collect();
        write_tracks(&p, &pts)?;
        assert_eq!(read_tracks(&p)?, rows);
        assert_eq!(
            std::fs::read_to_string(&p)
                .map_err(|e| Error::io(&p, e))?
                .lines()
                .next(),
            Some("1,9,0,0,1,1,1,-1,-1,-1")
        );
        Ok(())
    }

    #[test]
    fn gt_defaults_and_round_trip() -> Result<()> {
        let (_d, p) = file("1,1,10,20,30,40\n1,2,10,20,30,40,0,3,0.25\n");
        let rows = read_gt(&p)?;
        assert!(rows[0].consider && rows[0].class == 1 && rows[0].visibility == 1.0);
        assert!(!rows[1].consider && rows[1].class == 3 && rows[1].visibility == 0.25);
        write_gt(&p, &rows)?;
        assert_eq!(read_gt(&p)?, rows);
        Ok(())
    }

    #[test]
    fn bad_rows_are_reported_with_line_and_column() {
        let cases = [
            ("1,1,0,0,1,1,1\n1,1,0,0,1,1,1\n", ":2:", "twice"),
            ("1,1,0,0,-1,1,1\n", ":1:", "bb_width"),
            ("1,1,0,x,1,1,1\n", ":1:", "bb_top"),
            ("0,1,0,0,1,1,1\n", ":1:", "frame"),
            ("1,1,0,0,1\n", ":1:", "missing"),
            ("1,-2,0,0,1,1,1\n", ":1:", "id"),
            ("1,1,0,0,1,nan,1\n", ":1:", "finite"),
        ];
        for (text, line, what) in cases {
            let (_d, p) = file(text);
            let m = read_tracks(&p).expect_err(text).to_string();
            assert!(
                m.contains("f.txt") && m.contains(line) && m.contains(what),
                "{text:?}: {m}"
            );
        }
        let (_d, p) = file("1,1,0,0,1,1,1,1,1.5\n");
        let m = read_gt(&p).expect_err("visibility").to_string();
        assert!(m.contains("visibility"), "{m}");
    }

    #[test]
    fn a_repeated_id_in_an_unsorted_file_names_the_first_repetition() {
        // Rows 1 and 4 repeat (2, 5), rows 2 and 3 repeat (1, 1): line 3 comes first.
        let (_d, p) = file("2,5,0,0,1,1\n1,1,0,0,1,1\n1,1,0,0,1,1\n2,5,0,0,1,1\n1,2,0,0,1,1\n");
        for m in [
            read_tracks(&p).expect_err("tracks").to_string(),
            read_gt(&p).expect_err("gt").to_string(),
        ] {
            assert!(
                m.contains(":3:") && m.contains("id 1 appears twice in frame 1"),
                "{m}"
            );
        }
    }

    #[test]
    fn a_line_with_a_column_cut_out_is_rejected_by_line() {
        // Column 3 (bb_left) cut from every line: 9 fields.
        let (_d, p) = file("1,1,20,30,40,0.9,-1,-1,-1\n");
        let m = read_tracks(&p).expect_err("9 fields").to_string();
        assert!(m.contains(":1:") && m.contains("9 fields"), "{m}");
        // Cut from the second line only.
        let (_d, p) = file("1,1,10,20,30,40,0.9\n2,1,20,30,40,0.9\n");
        let m = read_tracks(&p).expect_err("tracks").to_string();
        assert!(m.contains(":2:") && m.contains("line 1 has 7"), "{m}");
    }

    #[test]
    fn extra_fields_and_float_integers_are_accepted() -> Result<()> {
        let (_d, p) = file("3.0,7.0,1,2,3,4,0.5,-1,-1,-1,9,9\n");
        let r = read_tracks(&p)?;
        assert_eq!((r[0].frame, r[0].id, r[0].conf), (3, 7, 0.5));
        Ok(())
    }

    #[test]
    fn fields_are_trimmed_like_str_trim() -> Result<()> {
        let (_d, p) = file(" 1 ,\t2,3.5 , 4,\u{a0}5,6\u{a0}\r\n\n  \n1,3,0,0,1,1\n");
        let r = read_tracks(&p)?;
        assert_eq!(r.len(), 2);
        assert_eq!((r[0].frame, r[0].id), (1, 2));
        assert_eq!(r[0].bbox, BBox::new(3.5, 4.0, 5.0, 6.0));
        Ok(())
    }

    #[test]
    fn empty_file_is_no_rows() -> Result<()> {
        let (_d, p) = file("");
        assert!(read_tracks(&p)?.is_empty());
        Ok(())
    }

    #[test]
    fn public_detections_get_row_ids_per_frame() -> Result<()> {
        let (_d, p) =
            file("1,-1,0,0,2,2,0.9,-1,-1,-1\n1,-1,5,5,2,2,0.8,-1,-1,-1\n2,-1,1,1,2,2,1,-1,-1,-1\n");
        let d = read_detections(&p)?;
        assert_eq!(
            d.iter().map(|d| (d.frame, d.id)).collect::<Vec<_>>(),
            [(1, 1), (1, 2), (2, 1)]
        );
        assert_eq!(d[0].pos_px, Point::new(1.0, 1.0));
        write_detections(&p, &d)?;
        assert_eq!(read_detections(&p)?, d);
        Ok(())
    }
}
