//! Inspection output: the Object-map per frame as a PNG (block colours per id, over the
//! frame, with each reported box) or as CSV rows `frame,bx,by,id`.

use crate::overlay::{draw_box, id_colour};
use image::RgbImage;
use roadtrack_core::error::{Error, Result};
use roadtrack_core::frame::Frame;
use roadtrack_core::io::atomic::{AtomicDir, write_atomic, write_bytes_atomic};
use roadtrack_core::track_point::TrackPoint;

/// A grid of per-block object ids, row-major, `0` = no object: the MRF tracker's
/// Object-map as plain data (seed 002's blocks are [`BlockLabels::block_px`] px square).
#[derive(Debug, Clone, Copy)]
pub struct BlockLabels<'a> {
    /// Blocks per row.
    pub cols: u32,
    /// Block rows.
    pub rows: u32,
    /// Block side, px.
    pub block_px: u32,
    /// One id per block, row-major; 0 = no object.
    pub ids: &'a [u32],
}

impl BlockLabels<'_> {
    fn coords(&self, index: usize) -> (u32, u32) {
        let cols = self.cols.max(1) as usize;
        ((index % cols) as u32, (index / cols) as u32)
    }
}
use std::fmt::Write as _;
use std::path::Path;

/// The Object-map drawn over `frame` (or over black when `None`, at the grid's size): each
/// labelled block is tinted with its id's colour (half and half), and every point's box is
/// outlined in its id's colour.
pub fn render_object_map(
    map: &BlockLabels<'_>,
    frame: Option<&RgbImage>,
    points: &[TrackPoint],
) -> RgbImage {
    let (w, h) = match frame {
        Some(f) => f.dimensions(),
        None => (map.cols * map.block_px, map.rows * map.block_px),
    };
    let mut img = frame.cloned().unwrap_or_else(|| RgbImage::new(w, h));
    for (i, &id) in map.ids.iter().enumerate() {
        if id == 0 {
            continue;
        }
        let c = id_colour(u64::from(id)).0;
        let (bx, by) = map.coords(i);
        for y in by * map.block_px..((by + 1) * map.block_px).min(h) {
            for x in bx * map.block_px..((bx + 1) * map.block_px).min(w) {
                let p = img.get_pixel_mut(x, y);
                for k in 0..3 {
                    p[k] = ((u16::from(p[k]) + u16::from(c[k])) / 2) as u8;
                }
            }
        }
    }
    for p in points {
        draw_box(&mut img, &p.bbox, id_colour(p.id));
    }
    img
}

/// Writes `image` as a PNG at `path`, atomically.
pub fn write_png(path: &Path, image: &RgbImage) -> Result<()> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut bytes, image::ImageFormat::Png)
        .map_err(|source| Error::Image {
            source,
            path: path.to_owned(),
        })?;
    write_bytes_atomic(path, bytes.get_ref())
}

/// Writes the Object-map over `frame` with the points' boxes as a PNG (see
/// [`render_object_map`]).
pub fn object_map_png(
    path: &Path,
    map: &BlockLabels<'_>,
    frame: Option<&RgbImage>,
    points: &[TrackPoint],
) -> Result<()> {
    write_png(path, &render_object_map(map, frame, points))
}

/// CSV rows `frame,bx,by,id` for every labelled block of `map` (no header).
pub fn object_map_csv_rows(frame: u32, map: &BlockLabels<'_>) -> String {
    let mut s = String::new();
    for (i, &id) in map.ids.iter().enumerate() {
        if id != 0 {
            let (bx, by) = map.coords(i);
            let _ = writeln!(s, "{frame},{bx},{by},{id}");
        }
    }
    s
}

/// Collects a per-frame dump of Object-maps: one PNG per frame as it comes, and
/// `object_maps.csv` (header `frame,bx,by,id`), in a folder swapped in whole on
/// [`MapDump::finish`] (an interrupted run leaves nothing, a rerun no stale frames).
#[derive(Debug)]
pub struct MapDump {
    dir: AtomicDir,
    csv: String,
}

impl MapDump {
    /// A dump into folder `dir`.
    ///
    /// # Errors
    /// `dir` exists and is not a folder; the temporary folder cannot be made.
    pub fn new(dir: &Path) -> Result<Self> {
        Ok(Self {
            dir: AtomicDir::create(dir)?,
            csv: String::from("frame,bx,by,id\n"),
        })
    }

    /// Adds one frame: writes `object_map_NNNNNN.png` and keeps its CSV rows.
    pub fn add(
        &mut self,
        frame: &Frame,
        map: &BlockLabels<'_>,
        points: &[TrackPoint],
    ) -> Result<()> {
        let path = self
            .dir
            .temp_path()
            .join(format!("object_map_{:06}.png", frame.index));
        object_map_png(&path, map, Some(&frame.image), points)?;
        self.csv.push_str(&object_map_csv_rows(frame.index, map));
        Ok(())
    }

    /// Writes `object_maps.csv` and puts the folder in place.
    pub fn finish(self) -> Result<()> {
        let path = self.dir.temp_path().join("object_maps.csv");
        write_atomic(&path, |w| w.write_all(self.csv.as_bytes()))?;
        self.dir.commit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use roadtrack_core::geometry::BBox;

    #[test]
    fn csv_lists_labelled_blocks_and_png_tints_them() -> Result<()> {
        let mut ids = vec![0u32; 8];
        ids[1] = 5;
        ids[4 + 3] = 2;
        let map = BlockLabels {
            cols: 4,
            rows: 2,
            block_px: 8,
            ids: &ids,
        };
        assert_eq!(object_map_csv_rows(4, &map), "4,1,0,5\n4,3,1,2\n");
        let pt = TrackPoint {
            frame: 4,
            time_s: 0.0,
            id: 5,
            class: roadtrack_core::ObjectClass::Unknown,
            bbox: BBox::new(8.0, 0.0, 8.0, 8.0),
            score: 1.0,
            ground: None,
        };
        let img = render_object_map(&map, None, &[pt]);
        assert_eq!(img.dimensions(), (32, 16));
        assert_eq!(img.get_pixel(0, 0), &image::Rgb([0, 0, 0]));
        assert_eq!(img.get_pixel(8, 0), &id_colour(5), "box outline");
        let c = id_colour(2).0;
        assert_eq!(img.get_pixel(28, 12).0, c.map(|v| v / 2));
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = dir.path().join("m.png");
        object_map_png(&p, &map, None, &[])?;
        assert!(p.is_file());
        Ok(())
    }
}
