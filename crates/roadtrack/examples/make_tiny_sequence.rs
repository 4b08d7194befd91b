//! Regenerates `tests/fixtures/tiny_sequence/`: 10 frames of 96 × 72 px, a textured grey
//! background and two rectangles with known motion (see `tests/fixtures/README.md`).
//!
//! `cargo run -p roadtrack --example make_tiny_sequence`

use image::{Rgb, RgbImage};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/tiny_sequence");
    std::fs::create_dir_all(&dir)?;
    for i in 1..=10u32 {
        let mut img = RgbImage::from_fn(96, 72, |x, y| {
            // Fixed texture: a few grey levels of asphalt-like pattern.
            let v = 100 + ((x * 7 + y * 13) % 11) as u8;
            Rgb([v, v, v + 2])
        });
        // Red rectangle 12 × 8 px, top-left (4 + 3i, 16), moving right 3 px/frame.
        for y in 16..24 {
            for x in 4 + 3 * i..16 + 3 * i {
                img.put_pixel(x, y, Rgb([200, 30, 30]));
            }
        }
        // Blue square 10 × 10 px, top-left (80 − 5i, 44), moving left 5 px/frame.
        for y in 44..54 {
            for x in 80 - 5 * i..90 - 5 * i {
                img.put_pixel(x, y, Rgb([30, 40, 210]));
            }
        }
        img.save(dir.join(format!("frame{i}.png")))?;
    }
    Ok(())
}
