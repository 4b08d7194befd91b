//! Loading configuration structs from TOML files.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use std::path::Path;

/// Reads `path` as TOML into `T` (any `XxxConfig`: fields left out keep their defaults,
/// unknown fields are an error naming line and column).
pub fn load_toml<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = crate::io::read_text(path)?;
    toml::from_str(&text).map_err(|e| Error::Toml {
        path: path.to_owned(),
        message: e.to_string().trim_end().to_owned(),
    })
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
