//! Loading configuration structs from TOML files.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use std::path::Path;

/// A configuration that can check its own values (ranges, NaN, consistency).
///
/// Every struct read by [`load_toml`] implements it, so that a file's bad value is reported
/// once, here, as `file: field: reason`, before any flag overrides it.
pub trait Validate {
    /// `Ok` when every value is usable.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the first bad field (as `table.field` for nested
    /// tables).
    fn validate(&self) -> Result<()>;
}

/// Reads `path` as TOML into `T` (any `XxxConfig`: fields left out keep their defaults,
/// unknown fields are an error naming line and column) and validates it; a bad value is an
/// error naming the file and the field (`c.toml: pf.n_particles: must be ≥ 1`).
pub fn load_toml<T: DeserializeOwned + Validate>(path: &Path) -> Result<T> {
    let value: T = parse_toml(path)?;
    value.validate().map_err(|e| e.in_file(path))?;
    Ok(value)
}

/// Reads `path` as TOML into `T` without validating it (for callers that check the values
/// themselves, naming the file).
pub fn parse_toml<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = crate::io::read_text(path)?;
    toml::from_str(&text).map_err(|e| Error::Toml {
        path: path.to_owned(),
        message: e.to_string().trim_end().to_owned(),
    })
}

/// Serde helpers that read a fixed-size array only at its exact length.
///
/// serde reads `[T; N]` from the first `N` elements of a longer TOML array and drops the
/// rest, so `origin_m = [1, 2, 3, 4]` would be accepted; with
/// `#[serde(deserialize_with = "exact::array")]` it is an error naming the line.
pub mod exact {
    use serde::{Deserialize, Deserializer, de::Error as _};

    /// `[T; N]` read from a sequence of exactly `N` values.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct Exact<T, const N: usize>(pub [T; N]);

    impl<'de, T: Deserialize<'de>, const N: usize> Deserialize<'de> for Exact<T, N> {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            let v = Vec::<T>::deserialize(d)?;
            let len = v.len();
            let expected = format!("exactly {N} values");
            v.try_into()
                .map(Exact)
                .map_err(|_| D::Error::invalid_length(len, &expected.as_str()))
        }
    }

    /// A `[T; N]` field.
    ///
    /// # Errors
    /// Not a sequence of `N` `T`s.
    pub fn array<'de, D, T, const N: usize>(d: D) -> Result<[T; N], D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de>,
    {
        Exact::<T, N>::deserialize(d).map(|a| a.0)
    }

    /// An `Option<[T; N]>` field (give it `#[serde(default)]` too).
    ///
    /// # Errors
    /// Not a sequence of `N` `T`s.
    pub fn option_array<'de, D, T, const N: usize>(d: D) -> Result<Option<[T; N]>, D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de>,
    {
        Option::<Exact<T, N>>::deserialize(d).map(|a| a.map(|a| a.0))
    }

    /// A `[[T; C]; R]` field (a row-major matrix).
    ///
    /// # Errors
    /// Not `R` rows of `C` `T`s.
    pub fn matrix<'de, D, T, const R: usize, const C: usize>(d: D) -> Result<[[T; C]; R], D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de>,
    {
        Exact::<Exact<T, C>, R>::deserialize(d).map(|m| m.0.map(|r| r.0))
    }

    /// An `Option<[[T; C]; R]>` field (give it `#[serde(default)]` too).
    ///
    /// # Errors
    /// Not `R` rows of `C` `T`s.
    pub fn option_matrix<'de, D, T, const R: usize, const C: usize>(
        d: D,
    ) -> Result<Option<[[T; C]; R]>, D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de>,
    {
        Option::<Exact<Exact<T, C>, R>>::deserialize(d).map(|m| m.map(|m| m.0.map(|r| r.0)))
    }

    /// A `Vec<[T; N]>` field (a polygon).
    ///
    /// # Errors
    /// An element that is not a sequence of `N` `T`s.
    pub fn vec_of_arrays<'de, D, T, const N: usize>(d: D) -> Result<Vec<[T; N]>, D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de>,
    {
        Vec::<Exact<T, N>>::deserialize(d).map(|v| v.into_iter().map(|a| a.0).collect())
    }
}

/// `value` as TOML text.
pub fn to_toml<T: serde::Serialize>(value: &T) -> Result<String> {
    toml::to_string(value).map_err(|e| Error::Invalid(format!("cannot write TOML: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::{Deserialize, Serialize};

    #[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
    #[serde(default, deny_unknown_fields)]
    struct Regions {
        min_area_px: u32,
        max_area_px: u32,
    }

    impl Default for Regions {
        fn default() -> Self {
            Self {
                min_area_px: 60,
                max_area_px: 50_000,
            }
        }
    }

    #[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
    #[serde(default, deny_unknown_fields)]
    struct Outer {
        regions: Regions,
        name: String,
    }

    impl Validate for Outer {
        fn validate(&self) -> Result<()> {
            if self.regions.min_area_px > self.regions.max_area_px {
                return Err(
                    Error::config("Regions", "min_area_px", "exceeds max_area_px")
                        .in_table("regions"),
                );
            }
            Ok(())
        }
    }

    #[test]
    fn invalid_values_name_the_file_and_the_key() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = dir.path().join("c.toml");
        std::fs::write(&p, "[regions]\nmin_area_px = 90000\n").map_err(|e| Error::io(&p, e))?;
        let m = load_toml::<Outer>(&p).expect_err("invalid").to_string();
        assert!(
            m.ends_with("c.toml: regions.min_area_px: exceeds max_area_px"),
            "{m}"
        );
        Ok(())
    }

    #[test]
    fn partial_files_keep_defaults_and_typos_are_errors() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = dir.path().join("c.toml");
        std::fs::write(&p, "[regions]\nmin_area_px = 5\n").map_err(|e| Error::io(&p, e))?;
        let c: Outer = load_toml(&p)?;
        assert_eq!(c.regions.min_area_px, 5);
        assert_eq!(c.regions.max_area_px, Regions::default().max_area_px);
        std::fs::write(&p, "[regions]\nmin_area = 5\n").map_err(|e| Error::io(&p, e))?;
        let m = load_toml::<Outer>(&p).expect_err("typo").to_string();
        assert!(m.contains("c.toml") && m.contains("min_area"), "{m}");
        let text = to_toml(&Outer::default())?;
        assert_eq!(
            toml::from_str::<Outer>(&text).map_err(|e| Error::Invalid(e.to_string()))?,
            Outer::default()
        );
        Ok(())
    }
}
