//! Flag checking beyond clap's types: value parsers for numbers with a range (so that
//! `--step 0` or `--fps nan` is a usage error, exit 2, like a typo), and usage errors found
//! after parsing (contradictory flags, a flag that breaks a value of the `--config` file).

use clap::error::ErrorKind;
use std::fmt;
use std::path::Path;

/// A usage error found after clap's parsing; `main` prints it with the subcommand's usage
/// and exits with 2.
#[derive(Debug)]
pub struct UsageError {
    /// clap's classification (conflict or invalid value).
    pub kind: ErrorKind,
    /// The message, naming the flags.
    pub message: String,
}

impl fmt::Display for UsageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for UsageError {}

/// Flags that cannot be used together (exit 2).
pub fn conflict(message: impl Into<String>) -> anyhow::Error {
    UsageError {
        kind: ErrorKind::ArgumentConflict,
        message: message.into(),
    }
    .into()
}

/// A flag's value that cannot be used (exit 2).
pub fn invalid(message: impl Into<String>) -> anyhow::Error {
    UsageError {
        kind: ErrorKind::ValueValidation,
        message: message.into(),
    }
    .into()
}

/// A conflict naming every given flag of `flags` (`(name, given)`) and `reason`, e.g.
/// `--mrf-variant, --object-maps: only for --method mrf`; `Ok` when none was given.
pub fn reject_given(flags: &[(&str, bool)], reason: &str) -> anyhow::Result<()> {
    let given: Vec<&str> = flags.iter().filter(|f| f.1).map(|f| f.0).collect();
    if given.is_empty() {
        return Ok(());
    }
    Err(conflict(format!("{}: {reason}", given.join(", "))))
}

/// Checks a config after flags overrode some of its fields. A bad field that a flag set
/// is a usage error naming the flag (`--min-area: …`); anything else is reported as found
/// in `file` (the `--config` file) when there is one.
///
/// `flags` pairs a field as [`roadtrack::Error::InvalidConfig`] names it
/// (`regions.min_area_px`) with the flag that set it, when it was given.
pub fn check_overrides(
    result: roadtrack::Result<()>,
    flags: &[(&str, &str, bool)],
    file: Option<&Path>,
) -> anyhow::Result<()> {
    let Err(e) = result else {
        return Ok(());
    };
    if let roadtrack::Error::InvalidConfig { field, reason, .. } = &e
        && let Some((_, flag, _)) = flags.iter().find(|(f, _, given)| *given && f == field)
    {
        return Err(invalid(format!("{flag}: {reason}")));
    }
    Err(match file {
        Some(p) => e.in_file(p).into(),
        None => e.into(),
    })
}

fn number(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("must be a finite number, found {s}"))
    }
}

/// A finite number.
pub fn finite(s: &str) -> Result<f64, String> {
    number(s)
}

/// A finite number > 0.
pub fn positive(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("must be > 0, found {s}"))
    }
}

/// A finite number > 0, as `f32`.
pub fn positive_f32(s: &str) -> Result<f32, String> {
    let v = positive(s)? as f32;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("must be a finite number, found {s}"))
    }
}

/// A finite number ≥ 0.
pub fn non_negative(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("must be ≥ 0, found {s}"))
    }
}

/// A probability: a number in [0, 1].
pub fn probability(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("must be in [0, 1], found {s}"))
    }
}

/// A fraction in (0, 1].
pub fn fraction(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v > 0.0 && v <= 1.0 {
        Ok(v)
    } else {
        Err(format!("must be in (0, 1], found {s}"))
    }
}

/// A fraction in (0, 1), both ends excluded.
pub fn open_fraction(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v > 0.0 && v < 1.0 {
        Ok(v)
    } else {
        Err(format!("must be in (0, 1), found {s}"))
    }
}

/// A fraction in [0, 1), 1 excluded.
pub fn unit_fraction(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if (0.0..1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("must be in [0, 1), found {s}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsers_reject_nan_infinity_and_out_of_range_values() {
        for bad in ["nan", "NaN", "inf", "-inf", "x", ""] {
            assert!(finite(bad).is_err(), "{bad}");
            assert!(positive(bad).is_err(), "{bad}");
        }
        assert!(positive("0").is_err() && positive("-1").is_err());
        assert_eq!(positive("0.5"), Ok(0.5));
        assert!(non_negative("-0.1").is_err());
        assert_eq!(non_negative("0"), Ok(0.0));
        assert!(probability("1.01").is_err() && probability("-0.01").is_err());
        assert_eq!(probability("1"), Ok(1.0));
        assert!(fraction("0").is_err() && fraction("1").is_ok());
        assert!(open_fraction("1").is_err() && open_fraction("0").is_err());
        assert!(unit_fraction("1").is_err() && unit_fraction("0").is_ok());
    }
}
