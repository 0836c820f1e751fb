//! Reading TOML input files with errors that name the key path, line and column.
//!
//! Shared by every TOML schema of the project (scenes here, specimens in fdem-triaxial):
//! range checks live in `deserialize_with` functions, so a bad value is reported where it
//! is, as `file:line:column: key.path: what is wrong and how to fix it`.

use serde::de::{DeserializeOwned, Error as _};
use serde::{Deserialize, Deserializer};
use std::fmt;

/// A TOML file that does not parse or does not fit its schema.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputError {
    /// The file (or another name for the text's origin).
    pub file: String,
    /// 1-based line of the offending key or value (0 when unknown).
    pub line: usize,
    /// 1-based column (0 when unknown).
    pub column: usize,
    /// Key path such as `particle[2].diameter` (`<document>` for syntax errors).
    pub key: String,
    /// What is wrong and how to fix it.
    pub message: String,
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: {}: {}",
            self.file, self.line, self.column, self.key, self.message
        )
    }
}

impl std::error::Error for InputError {}

/// 1-based line and column of byte `offset` in `text`.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let column = before.rfind('\n').map_or(offset, |p| offset - p - 1) + 1;
    (line, column)
}

/// Deserializes `text` as `T`; errors carry the key path and the position of the value.
pub fn parse_toml<T: DeserializeOwned>(text: &str, origin: &str) -> Result<T, InputError> {
    let error = |span: Option<std::ops::Range<usize>>, key: String, message: String| {
        let (line, column) = span.map_or((0, 0), |s| line_column(text, s.start));
        InputError {
            file: origin.to_string(),
            line,
            column,
            key,
            message,
        }
    };
    let de = toml::Deserializer::parse(text)
        .map_err(|e| error(e.span(), "<document>".into(), e.message().to_string()))?;
    serde_path_to_error::deserialize(de).map_err(|e| {
        let key = e.path().to_string();
        let inner = e.into_inner();
        error(inner.span(), key, inner.message().to_string())
    })
}

/// `deserialize_with` for a mesh subdivision level: an integer in 0..=4.
pub fn level<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    let v = i64::deserialize(d)?;
    if (0..=i64::from(fdem_mesh::MAX_LEVEL)).contains(&v) {
        Ok(v as u32)
    } else {
        Err(D::Error::custom(format!(
            "subdivision level must be 0, 1, 2, 3 or 4, got {v}"
        )))
    }
}

/// `deserialize_with` for a 3-vector whose components are all finite.
pub fn vector<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    let v = <[f64; 3]>::deserialize(d)?;
    if v.iter().all(|x| x.is_finite()) {
        Ok(v)
    } else {
        Err(D::Error::custom(format!(
            "every component must be finite, got {v:?}"
        )))
    }
}
