//! Shared reading of header-named CSV files with precise error positions.

use crate::error::{Error, Result};
use crate::limits::{MAX_FRAME, at_most};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A CSV file with a header row, read record by record.
pub struct Table {
    /// The file, for error messages.
    pub path: PathBuf,
    reader: csv::Reader<std::fs::File>,
    columns: HashMap<String, usize>,
}

/// One record with its 1-based line number.
pub struct Row<'t> {
    table: &'t Table,
    /// 1-based line number in the file.
    pub line: u64,
    record: csv::StringRecord,
}

impl Table {
    /// Opens `path`; header names are trimmed and matched case-insensitively.
    pub fn open(path: &Path) -> Result<Self> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .flexible(false)
            .trim(csv::Trim::All)
            .from_reader(file);
        let headers = reader.headers().map_err(|e| csv_error(path, e))?.clone();
        if headers.is_empty() || (headers.len() == 1 && headers[0].is_empty()) {
            return Err(Error::format(path, "empty file: expected a header row"));
        }
        // Choice: no column of any roadtrack CSV is named by a number, so a first row of
        // numbers is data: the file has no header (most often MOTChallenge rows, such as
        // `track -o`'s tracks or a det.txt, saved under a `.csv` name).
        if headers.iter().all(|h| h.parse::<f64>().is_ok()) {
            return Err(Error::format(
                path,
                "line 1 is numbers, not column names: this CSV has no header row. \
                 MOTChallenge rows (`track -o`, det.txt, gt.txt) have none; give them a name \
                 not ending in `.csv` (e.g. tracks.txt), or write the CSV form \
                 (`track --trajectories F.csv`, `detect -o F.csv`)",
            ));
        }
        let mut columns = HashMap::new();
        for (i, h) in headers.iter().enumerate() {
            let key = h.trim_start_matches('\u{feff}').to_ascii_lowercase();
            if columns.insert(key.clone(), i).is_some() {
                return Err(Error::format(
                    path,
                    format!("column `{key}` appears twice in the header"),
                ));
            }
        }
        Ok(Self {
            path: path.to_owned(),
            reader,
            columns,
        })
    }

    /// Whether the header has `name`.
    pub fn has(&self, name: &str) -> bool {
        self.columns.contains_key(name)
    }

    /// Fails unless every name in `names` is in the header.
    pub fn require(&self, names: &[&str]) -> Result<()> {
        for n in names {
            if !self.has(n) {
                let mut found: Vec<_> = self.columns.iter().collect();
                found.sort_by_key(|(_, i)| **i);
                let found: Vec<_> = found.into_iter().map(|(k, _)| k.as_str()).collect();
                return Err(Error::format(
                    &self.path,
                    format!(
                        "missing required column `{n}` (header has: {})",
                        found.join(",")
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Calls `f` for every record.
    pub fn for_each(mut self, mut f: impl FnMut(&Row<'_>) -> Result<()>) -> Result<()> {
        let mut record = csv::StringRecord::new();
        loop {
            let more = self
                .reader
                .read_record(&mut record)
                .map_err(|e| csv_error(&self.path, e))?;
            if !more {
                return Ok(());
            }
            if record.len() == 1 && record[0].is_empty() {
                continue;
            }
            let line = record.position().map_or(0, |p| p.line());
            let row = Row {
                table: &self,
                line,
                record: std::mem::take(&mut record),
            };
            f(&row)?;
            record = row.record;
        }
    }
}

impl Row<'_> {
    fn raw(&self, name: &str) -> Option<&str> {
        self.table
            .columns
            .get(name)
            .and_then(|&i| self.record.get(i))
    }

    /// An error at this row, column `name`.
    pub fn error(&self, name: &str, message: impl Into<String>) -> Error {
        Error::parse(&self.table.path, self.line, name, message)
    }

    /// A finite number in column `name`, which must be present and non-empty.
    pub fn f64(&self, name: &str) -> Result<f64> {
        self.opt_f64(name)?
            .ok_or_else(|| self.error(name, "empty value where a number is required"))
    }

    /// A finite number in column `name`, or `None` when the column is absent or empty.
    pub fn opt_f64(&self, name: &str) -> Result<Option<f64>> {
        match self.raw(name) {
            None | Some("") => Ok(None),
            Some(s) => match s.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(Some(x)),
                Ok(_) => Err(self.error(name, format!("not a finite number: {s:?}"))),
                Err(_) => Err(self.error(name, format!("not a number: {s:?}"))),
            },
        }
    }

    /// A non-negative integer in column `name`, or `None` when absent or empty.
    pub fn opt_u64(&self, name: &str) -> Result<Option<u64>> {
        match self.raw(name) {
            None | Some("") => Ok(None),
            Some(s) => s
                .parse::<u64>()
                .map(Some)
                .map_err(|_| self.error(name, format!("not a non-negative integer: {s:?}"))),
        }
    }

    /// A frame number in column `name`: an integer in `1..=`[`MAX_FRAME`], or `None` when
    /// absent or empty.
    pub fn opt_frame(&self, name: &str) -> Result<Option<u32>> {
        match self.opt_u64(name)? {
            None => Ok(None),
            Some(0) => Err(self.error(name, "frame numbers start at 1")),
            Some(f) => {
                at_most(f, u64::from(MAX_FRAME), "largest frame number")
                    .map_err(|m| self.error(name, m))?;
                Ok(Some(f as u32))
            }
        }
    }

    /// The text in column `name`, or `None` when absent or empty.
    pub fn opt_str(&self, name: &str) -> Option<&str> {
        self.raw(name).filter(|s| !s.is_empty())
    }
}

fn csv_error(path: &Path, e: csv::Error) -> Error {
    let line = e.position().map_or(0, |p| p.line());
    match e.kind() {
        csv::ErrorKind::Io(_) => Error::format(path, e.to_string()),
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => Error::parse(
            path,
            line,
            "-",
            format!("row has {len} fields, header has {expected_len}"),
        ),
        _ => Error::parse(path, line, "-", e.to_string()),
    }
}

/// `str::trim`, skipped when both ends are visible ASCII (the usual case).
pub fn trim(s: &str) -> &str {
    match s.as_bytes() {
        [a, .., z] if a.is_ascii_graphic() && z.is_ascii_graphic() => s,
        [a] if a.is_ascii_graphic() => s,
        _ => s.trim(),
    }
}

/// Parses one number of a header-less, comma-separated line (MOTChallenge files).
pub fn field_f64(path: &Path, line: u64, fields: &[&str], i: usize, name: &str) -> Result<f64> {
    let s = fields.get(i).ok_or_else(|| {
        Error::parse(
            path,
            line,
            name,
            format!("missing: the line has {} fields", fields.len()),
        )
    })?;
    let s = trim(s);
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        Ok(_) => Err(Error::parse(
            path,
            line,
            name,
            format!("not a finite number: {s:?}"),
        )),
        Err(_) => Err(Error::parse(
            path,
            line,
            name,
            format!("not a number: {s:?}"),
        )),
    }
}

/// Formats `x` with at most `decimals` decimals and no trailing zeros (`12.5`, `3`).
pub fn num(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    };
    if s == "-0" { "0".to_owned() } else { s }
}

#[cfg(test)]
mod tests {
    use super::{Table, num};

    #[test]
    fn a_first_row_of_numbers_is_refused_as_a_missing_header() {
        let dir = tempfile::tempdir().unwrap();
        let mot = dir.path().join("tracks.csv");
        std::fs::write(&mot, "2,1,285.166,242.728,15.897,5.563,0.96,-1,-1,-1\n").unwrap();
        let e = Table::open(&mot)
            .err()
            .expect("a headerless file must be refused");
        let msg = e.to_string();
        assert!(
            msg.contains("tracks.csv") && msg.contains("no header row"),
            "{msg}"
        );
        assert!(msg.contains("line 1"), "names line 1: {msg}");
        // One named column is enough to be a header.
        let ok = dir.path().join("ok.csv");
        std::fs::write(&ok, "frame,1,2\n3,4,5\n").unwrap();
        assert!(Table::open(&ok).is_ok());
    }

    #[test]
    fn numbers_are_short_and_exact_to_the_decimals() {
        assert_eq!(num(12.5, 3), "12.5");
        assert_eq!(num(3.0, 3), "3");
        assert_eq!(num(-0.0001, 3), "0");
        assert_eq!(num(1.23456, 3), "1.235");
        assert_eq!(num(100.0, 0), "100");
    }
}
