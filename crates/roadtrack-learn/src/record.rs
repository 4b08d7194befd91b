//! Training samples as bytes, for a trainer outside this crate (`scripts/train_gpu.py`, fed
//! by `examples/dump_samples.rs`): the crops and targets [`crate::data::make_sample`] cuts,
//! so that a GPU stage trains on exactly what `roadtrack train --detector` trains on.
//!
//! Record, little-endian: `b"RTS1"`, `u32` crop side S, `u32` P (positives), `u32` R (box
//! cells), `u32` n_pos; the input as `3 × S × S` `u8` (the crop's 0–255 values, the
//! preprocessing undone and rounded); the negatives' weights `4 × G × G` `f32` (G = S / 4);
//! P `u32` indices into `4 × G × G` where `pos` is 1; R entries of a `u32` cell index into
//! `G × G` and 4 `f32` (`ln(w/4)`, `ln(h/4)`, `dx`, `dy`).

use roadtrack::error::{Error, Result};

use crate::arch::{CLASSES, Preprocessing, STRIDE};
use crate::data::Sample;

/// First bytes of every record.
pub const MAGIC: &[u8; 4] = b"RTS1";

/// `sample` (crop side `crop`, input made with `prep`) as one record.
pub fn encode(sample: &Sample, crop: usize, prep: &Preprocessing) -> Vec<u8> {
    let g = crop / STRIDE;
    let plane = crop * crop;
    let pos: Vec<u32> = (0..sample.pos.len())
        .filter(|&i| sample.pos[i] != 0.0)
        .map(|i| i as u32)
        .collect();
    let cells: Vec<u32> = (0..g * g)
        .filter(|&i| sample.reg_mask[i] != 0.0)
        .map(|i| i as u32)
        .collect();
    let mut rec =
        Vec::with_capacity(20 + 3 * plane + 4 * CLASSES * g * g + 4 * pos.len() + 20 * cells.len());
    rec.extend_from_slice(MAGIC);
    for v in [crop, pos.len(), cells.len(), sample.n_pos] {
        rec.extend_from_slice(&(v as u32).to_le_bytes());
    }
    for (i, &x) in sample.input.iter().enumerate() {
        let c = i / plane;
        let px = (x * prep.std[c] + prep.mean[c]) / prep.input_scale;
        rec.push(px.round().clamp(0.0, 255.0) as u8);
    }
    for &w in &sample.neg_weight {
        rec.extend_from_slice(&w.to_le_bytes());
    }
    for &p in &pos {
        rec.extend_from_slice(&p.to_le_bytes());
    }
    for &c in &cells {
        rec.extend_from_slice(&c.to_le_bytes());
        for k in 0..4 {
            rec.extend_from_slice(&sample.reg[k * g * g + c as usize].to_le_bytes());
        }
    }
    rec
}

/// The first record of `bytes` as a sample (input preprocessed with `prep`) and the bytes it
/// took.
///
/// # Errors
/// A record that is cut short, has another magic, or indexes outside its grid.
pub fn decode(bytes: &[u8], prep: &Preprocessing) -> Result<(Sample, usize)> {
    let bad = |m: String| Err(Error::Invalid(format!("sample record: {m}")));
    let u32_at = |o: usize| -> Option<u32> {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let f32_at = |o: usize| -> Option<f32> { u32_at(o).map(f32::from_bits) };
    if bytes.get(..4) != Some(MAGIC.as_slice()) {
        return bad("missing magic RTS1".into());
    }
    let head: Option<Vec<usize>> = (0..4)
        .map(|k| u32_at(4 + 4 * k).map(|v| v as usize))
        .collect();
    let Some(&[s, p, r, n_pos]) = head.as_deref() else {
        return bad("header cut short".into());
    };
    let g = s / STRIDE;
    let (plane, grid) = (s * s, g * g);
    let len = 20 + 3 * plane + 4 * CLASSES * grid + 4 * p + 20 * r;
    if s == 0 || !s.is_multiple_of(STRIDE) || bytes.len() < len {
        return bad(format!(
            "crop side {s} or length {} (need {len})",
            bytes.len()
        ));
    }
    let mut o = 20;
    let input = (0..3 * plane)
        .map(|i| {
            let c = i / plane;
            (f32::from(bytes[o + i]) * prep.input_scale - prep.mean[c]) / prep.std[c]
        })
        .collect();
    o += 3 * plane;
    let neg_weight = (0..CLASSES * grid)
        .map(|i| f32_at(o + 4 * i).unwrap_or(f32::NAN))
        .collect();
    o += 4 * CLASSES * grid;
    let mut pos = vec![0.0f32; CLASSES * grid];
    for k in 0..p {
        let i = u32_at(o + 4 * k).unwrap_or(u32::MAX) as usize;
        let Some(v) = pos.get_mut(i) else {
            return bad(format!("positive index {i} outside 4 × {g} × {g}"));
        };
        *v = 1.0;
    }
    o += 4 * p;
    let mut reg = vec![0.0f32; 4 * grid];
    let mut reg_mask = vec![0.0f32; 4 * grid];
    for k in 0..r {
        let e = o + 20 * k;
        let c = u32_at(e).unwrap_or(u32::MAX) as usize;
        if c >= grid {
            return bad(format!("box cell {c} outside {g} × {g}"));
        }
        for j in 0..4 {
            reg[j * grid + c] = f32_at(e + 4 + 4 * j).unwrap_or(f32::NAN);
            reg_mask[j * grid + c] = 1.0;
        }
    }
    let sample = Sample {
        input,
        pos,
        neg_weight,
        reg,
        reg_mask,
        n_pos,
    };
    Ok((sample, len))
}
