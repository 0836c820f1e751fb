//! Reading TOML input files with errors that name the key path, line and column.
//!
//! Shared by every TOML schema of the project (scenes here, specimens in fdem-triaxial):
//! range checks live in `deserialize_with` functions, so a bad value is reported where it
//! is, as `file:line:column: key.path: what is wrong and how to fix it`. Each rule is also
//! a plain `check_*` function for sections built in code and validated afterwards, so a
//! rule and its message are written once.

use fdem_contact::Requirement;
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
    /// `file:line:column: key: message`; a rule across keys has no line of its own and
    /// prints as `file: key: message` (no `file:0:0`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.line, self.column) {
            (0, _) => write!(f, "{}: {}: {}", self.file, self.key, self.message),
            (line, 0) => write!(f, "{}:{line}: {}: {}", self.file, self.key, self.message),
            (line, column) => write!(
                f,
                "{}:{line}:{column}: {}: {}",
                self.file, self.key, self.message
            ),
        }
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

/// A number as messages print it (plain where short, in exponent form otherwise): the
/// shared rule of `fdem_core::number`, re-exported here for the schemas' messages.
pub use fdem_core::number::Number;

// ---- Range checks: one rule each, used while deserializing (the error then carries the
// value's line) and by code that validates sections built in code (`check_*`). ----

/// A value meeting `requirement` (a range of the contact law, or the generic sign rules).
pub fn check_requirement(requirement: Requirement, v: f64) -> Result<f64, String> {
    if requirement.holds(v) {
        Ok(v)
    } else {
        Err(match requirement {
            Requirement::Positive => {
                format!(
                    "must be a positive finite number (SI units), got {}",
                    Number(v)
                )
            }
            Requirement::NonNegative => {
                format!("must be a finite number >= 0, got {}", Number(v))
            }
        })
    }
}

/// A finite number > 0.
pub fn check_positive(v: f64) -> Result<f64, String> {
    check_requirement(Requirement::Positive, v)
}

/// A finite number >= 0.
pub fn check_non_negative(v: f64) -> Result<f64, String> {
    check_requirement(Requirement::NonNegative, v)
}

/// A fraction in (0, 1].
pub fn check_fraction(v: f64) -> Result<f64, String> {
    if v > 0.0 && v <= 1.0 {
        Ok(v)
    } else {
        Err(format!("must lie in (0, 1], got {}", Number(v)))
    }
}

/// A Poisson's ratio in (-1, 0.5).
pub fn check_poisson(v: f64) -> Result<f64, String> {
    if v > -1.0 && v < 0.5 {
        Ok(v)
    } else {
        Err(format!(
            "Poisson's ratio must lie in (-1, 0.5), got {}",
            Number(v)
        ))
    }
}

/// A count of at least 1.
pub fn check_at_least_one(v: u64) -> Result<u64, String> {
    if v >= 1 {
        Ok(v)
    } else {
        Err("must be at least 1".into())
    }
}

/// A mesh subdivision level: an integer in 0..=4.
pub fn check_level(v: i64) -> Result<u32, String> {
    if (0..=i64::from(fdem_mesh::MAX_LEVEL)).contains(&v) {
        Ok(v as u32)
    } else {
        Err(format!(
            "subdivision level must be 0, 1, 2, 3 or 4, got {v}"
        ))
    }
}

/// A 3-vector whose components are all finite.
pub fn check_vector(v: [f64; 3]) -> Result<[f64; 3], String> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(v)
    } else {
        Err(format!("every component must be finite, got {v:?}"))
    }
}

/// A direction (a wall's normal or axis): three finite numbers whose length is finite
/// and greater than 0 as computed, so that it can be normalised (a zero vector has no
/// direction; the length of one of subnormal or extreme components under- or overflows).
pub fn check_direction(v: [f64; 3]) -> Result<[f64; 3], String> {
    let length = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if v.iter().all(|x| x.is_finite()) && length.is_finite() && length > 0.0 {
        Ok(v)
    } else {
        Err(format!(
            "must be a direction: finite components of a length greater than 0 that does not \
             overflow, got {v:?}"
        ))
    }
}

/// Ellipsoid axes: three finite numbers greater than 0.
pub fn check_axes(v: [f64; 3]) -> Result<[f64; 3], String> {
    if v.iter().all(|x| x.is_finite() && *x > 0.0) {
        Ok(v)
    } else {
        Err(format!(
            "every axis must be finite and greater than 0 (relative to the diameter; [1, 1, 1] is the sphere), got {v:?}"
        ))
    }
}

/// A unit quaternion `[w, x, y, z]` (norm 1 within 1e-6), returned normalised.
pub fn check_unit_quaternion(q: [f64; 4]) -> Result<[f64; 4], String> {
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm.is_finite() && (norm - 1.0).abs() <= 1e-6 {
        Ok(q.map(|x| x / norm))
    } else {
        Err(format!(
            "must be a unit quaternion [w, x, y, z] (norm 1 within 1e-6), got {q:?} with norm {}",
            Number(norm)
        ))
    }
}

// ---- `deserialize_with` functions: the checks above applied while deserializing. ----

/// Deserializes a `T` and passes it through `check`.
fn checked<'de, D, T, U>(d: D, check: impl FnOnce(T) -> Result<U, String>) -> Result<U, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de>,
{
    check(T::deserialize(d)?).map_err(D::Error::custom)
}

/// Deserializes exactly `N` numbers: an array of another length is refused with both
/// lengths (a plain `[f64; N]` would take the first `N` of a longer array).
fn numbers<'de, D, const N: usize>(d: D) -> Result<[f64; N], D::Error>
where
    D: Deserializer<'de>,
{
    let v = Vec::<f64>::deserialize(d)?;
    <[f64; N]>::try_from(v.as_slice())
        .map_err(|_| D::Error::custom(format!("expected {N} numbers, got {}", v.len())))
}

/// `deserialize_with` body for a number meeting `requirement`.
pub fn meeting<'de, D: Deserializer<'de>>(d: D, requirement: Requirement) -> Result<f64, D::Error> {
    checked(d, |v| check_requirement(requirement, v))
}

/// `deserialize_with` for a finite number > 0.
pub fn positive<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    checked(d, check_positive)
}

/// `deserialize_with` for an optional finite number > 0.
pub fn positive_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    positive(d).map(Some)
}

/// `deserialize_with` for a finite number >= 0.
pub fn non_negative<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    checked(d, check_non_negative)
}

/// `deserialize_with` for an optional finite number >= 0.
pub fn non_negative_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    non_negative(d).map(Some)
}

/// `deserialize_with` for a fraction in (0, 1].
pub fn fraction<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    checked(d, check_fraction)
}

/// `deserialize_with` for an optional fraction in (0, 1].
pub fn fraction_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    fraction(d).map(Some)
}

/// `deserialize_with` for a Poisson's ratio in (-1, 0.5).
pub fn poisson<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    checked(d, check_poisson)
}

/// `deserialize_with` for a count of at least 1.
pub fn at_least_one<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
    checked(d, check_at_least_one)
}

/// `deserialize_with` for a mesh subdivision level: an integer in 0..=4.
pub fn level<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    checked(d, check_level)
}

/// `deserialize_with` for a 3-vector whose components are all finite.
pub fn vector<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    check_vector(numbers(d)?).map_err(D::Error::custom)
}

/// `deserialize_with` for an optional 3-vector whose components are all finite.
pub fn vector_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 3]>, D::Error> {
    vector(d).map(Some)
}

/// `deserialize_with` for an optional direction ([`check_direction`]).
pub fn direction_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 3]>, D::Error> {
    check_direction(numbers(d)?)
        .map(Some)
        .map_err(D::Error::custom)
}

/// `deserialize_with` for ellipsoid axes (finite, > 0).
pub fn axes<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    check_axes(numbers(d)?).map_err(D::Error::custom)
}

/// `deserialize_with` for an optional unit quaternion `[w, x, y, z]`, normalised.
pub fn unit_quaternion_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 4]>, D::Error> {
    check_unit_quaternion(numbers(d)?)
        .map(Some)
        .map_err(D::Error::custom)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_accept_their_range_and_say_what_is_wrong() {
        let refused = |r: Result<f64, String>| r.unwrap_err();
        assert_eq!(check_positive(2.0), Ok(2.0));
        assert!(refused(check_positive(0.0)).contains("positive finite number (SI units)"));
        assert!(refused(check_positive(f64::INFINITY)).contains("positive"));
        assert_eq!(check_non_negative(0.0), Ok(0.0));
        assert!(refused(check_non_negative(-1.0)).contains(">= 0, got -1"));
        assert_eq!(check_fraction(1.0), Ok(1.0));
        assert!(refused(check_fraction(0.0)).contains("(0, 1]"));
        assert_eq!(check_poisson(-0.5), Ok(-0.5));
        assert!(refused(check_poisson(0.5)).contains("(-1, 0.5), got 0.5"));
        assert_eq!(check_at_least_one(1), Ok(1));
        assert_eq!(check_at_least_one(0).unwrap_err(), "must be at least 1");
        assert_eq!(check_level(4), Ok(4));
        assert!(
            check_level(-1)
                .unwrap_err()
                .contains("0, 1, 2, 3 or 4, got -1")
        );
        assert!(check_vector([0.0, f64::NAN, 0.0]).is_err());
        assert_eq!(check_direction([0.0, 0.0, 2.0]), Ok([0.0, 0.0, 2.0]));
        for refused in [[0.0, -0.0, 0.0], [5e-324, 0.0, 0.0], [1e308, 1e308, 0.0]] {
            assert!(
                check_direction(refused)
                    .unwrap_err()
                    .starts_with("must be a direction"),
                "{refused:?}"
            );
        }
        assert!(check_unit_quaternion([2.0, 0.0, 0.0, 0.0]).is_err());
        assert_eq!(
            check_unit_quaternion([1.0 + 1e-7, 0.0, 0.0, 0.0]),
            Ok([1.0, 0.0, 0.0, 0.0])
        );
    }

    #[derive(Debug, serde::Deserialize)]
    struct Table {
        #[serde(deserialize_with = "positive")]
        _a: f64,
        #[serde(default, deserialize_with = "fraction_opt")]
        _b: Option<f64>,
    }

    #[test]
    fn deserializers_report_the_value_s_line() {
        let e = parse_toml::<Table>("_a = 1.0\n_b = 2.0\n", "f.toml").unwrap_err();
        assert_eq!((e.line, e.key.as_str()), (2, "_b"));
        assert_eq!(e.to_string(), "f.toml:2:6: _b: must lie in (0, 1], got 2");
        // A rule across keys has no line: no `f.toml:0:0`.
        let across = InputError {
            line: 0,
            column: 0,
            key: "simulation.dt".into(),
            ..e
        };
        assert!(across.to_string().starts_with("f.toml: simulation.dt: "));
    }
}
