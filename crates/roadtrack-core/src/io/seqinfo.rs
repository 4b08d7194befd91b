//! MOTChallenge `seqinfo.ini`.

use crate::error::{Error, Result};
use crate::limits::{MAX_FPS, MAX_FRAME, MAX_IMAGE_SIDE, at_most};
use std::fmt::Write as _;
use std::path::Path;

/// The `[Sequence]` section of a MOTChallenge `seqinfo.ini`.
#[derive(Debug, Clone, PartialEq)]
pub struct SeqInfo {
    /// Sequence name.
    pub name: String,
    /// Image folder, relative to the sequence folder (normally `img1`).
    pub im_dir: String,
    /// Frames per second.
    pub frame_rate: f64,
    /// Number of frames.
    pub seq_length: u32,
    /// Image width, px.
    pub im_width: u32,
    /// Image height, px.
    pub im_height: u32,
    /// Image file extension with its dot, e.g. `.jpg`.
    pub im_ext: String,
}

impl SeqInfo {
    /// Reads `path` (a `seqinfo.ini`). Keys are matched case-insensitively; `name`,
    /// `imDir` and `imExt` default to the folder name, `img1` and `.jpg`; `frameRate`
    /// (positive) and the whole numbers `seqLength`, `imWidth` and `imHeight` (≥ 1) are
    /// required.
    pub fn read(path: &Path) -> Result<Self> {
        let text = super::read_text(path)?;
        let mut kv = std::collections::HashMap::new();
        for (i, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() || line.starts_with(['#', ';', '[']) {
                continue;
            }
            let Some((k, v)) = line.split_once('=') else {
                return Err(Error::parse(
                    path,
                    i as u64 + 1,
                    "-",
                    format!("expected key=value, found {line:?}"),
                ));
            };
            kv.insert(
                k.trim().to_ascii_lowercase(),
                (i as u64 + 1, v.trim().to_owned()),
            );
        }
        // Counts and sizes are whole numbers: `0.5` is positive but would become 0 frames
        // or pixels.
        for (k, key_name) in [
            ("seqlength", "seqLength"),
            ("imwidth", "imWidth"),
            ("imheight", "imHeight"),
        ] {
            if let Some((line, v)) = kv.get(k)
                && let Ok(x) = v.parse::<f64>()
                && x.is_finite()
                && x > 0.0
                && (x.fract() != 0.0 || x > f64::from(u32::MAX))
            {
                return Err(Error::parse(
                    path,
                    *line,
                    key_name,
                    format!("must be a whole number, found {v}"),
                ));
            }
        }
        let text_of = |k: &str, default: &str| {
            kv.get(k)
                .map(|(_, v)| v.clone())
                .unwrap_or_else(|| default.to_owned())
        };
        // Choice: every number has an upper bound (docs/FORMATS.md, Limits), checked here so
        // that a sequence of 10⁹ frames is refused before a per-frame table is allocated.
        let num = |k: &str, key_name: &str, max: f64| -> Result<f64> {
            let (line, v) = kv
                .get(k)
                .ok_or_else(|| Error::format(path, format!("missing key `{key_name}`")))?;
            let x: f64 = v
                .parse()
                .map_err(|_| Error::parse(path, *line, key_name, format!("not a number: {v:?}")))?;
            if !x.is_finite() || x <= 0.0 {
                return Err(Error::parse(
                    path,
                    *line,
                    key_name,
                    format!("must be positive, found {v}"),
                ));
            }
            at_most(x, max, key_name).map_err(|m| Error::parse(path, *line, key_name, m))?;
            Ok(x)
        };
        let default_name = path
            .parent()
            .and_then(|p| p.file_name())
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(Self {
            name: text_of("name", &default_name),
            im_dir: text_of("imdir", "img1"),
            frame_rate: num("framerate", "frameRate", MAX_FPS)?,
            seq_length: num("seqlength", "seqLength", f64::from(MAX_FRAME))? as u32,
            im_width: num("imwidth", "imWidth", f64::from(MAX_IMAGE_SIDE))? as u32,
            im_height: num("imheight", "imHeight", f64::from(MAX_IMAGE_SIDE))? as u32,
            im_ext: text_of("imext", ".jpg"),
        })
    }

    /// The file's text.
    pub fn to_ini(&self) -> String {
        let mut s = String::from("[Sequence]\n");
        let _ = writeln!(s, "name={}", self.name);
        let _ = writeln!(s, "imDir={}", self.im_dir);
        let _ = writeln!(s, "frameRate={}", self.frame_rate);
        let _ = writeln!(s, "seqLength={}", self.seq_length);
        let _ = writeln!(s, "imWidth={}", self.im_width);
        let _ = writeln!(s, "imHeight={}", self.im_height);
        let _ = writeln!(s, "imExt={}", self.im_ext);
        s
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        super::atomic::write_bytes_atomic(path, self.to_ini().as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_reports_bad_values() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = dir.path().join("seqinfo.ini");
        let info = SeqInfo {
            name: "s".into(),
            im_dir: "img1".into(),
            frame_rate: 10.0,
            seq_length: 3,
            im_width: 64,
            im_height: 48,
            im_ext: ".png".into(),
        };
        info.write(&p)?;
        assert_eq!(SeqInfo::read(&p)?, info);
        std::fs::write(
            &p,
            "[Sequence]\nframeRate=ten\nseqLength=3\nimWidth=1\nimHeight=1\n",
        )
        .map_err(|e| Error::io(&p, e))?;
        let msg = SeqInfo::read(&p).unwrap_err().to_string();
        assert!(msg.contains(":2:") && msg.contains("frameRate"), "{msg}");
        std::fs::write(&p, "[Sequence]\nframeRate=10\n").map_err(|e| Error::io(&p, e))?;
        let msg = SeqInfo::read(&p).unwrap_err().to_string();
        assert!(msg.contains("seqLength"), "{msg}");
        Ok(())
    }
}
