//! What a study runs: series of tests (the original, h = 1, and its coarse-grained
//! members with and without exact scaling), expanded over seeds into runs, each with a
//! key that names its whole definition.

use crate::StudyError;
use fdem_core::hash::Fnv1a;
use fdem_mesh::ElementOrder;
use fdem_solver::ParticleModel;
use fdem_triaxial::{Preset, SpecimenSpec, quick_spec, surface_order};
use serde::Deserialize;
use std::path::Path;

/// Version of the run key: raised when the meaning of a definition changes, so that
/// runs of an older meaning are not reused.
const KEY_VERSION: u32 = 1;

/// The tests of the paper's equal-size series (Table 4), the original first.
const EQUAL: &[&str] = &["E1", "E2", "E2s", "E3", "E3s", "E4", "E4s"];
/// The tests of the paper's binary series, the original first.
const BINARY: &[&str] = &["B1", "B2", "B2s", "B3", "B3s"];

/// Coarse-graining factors of the quick series, the original first; its coarsest member
/// is the quick specimen itself.
const QUICK_FACTORS: &[f64] = &[1.0, 1.5, 2.0];

/// One test of a series: its name and its definition (seed 1, the specimen's own model
/// and element order).
#[derive(Clone, Debug)]
pub struct Member {
    /// Test name (`E3s`, `Q1.5`, ...).
    pub test: String,
    /// Its definition.
    pub spec: SpecimenSpec,
}

impl Member {
    /// Coarse-graining factor h.
    pub fn h(&self) -> f64 {
        self.spec.coarse_graining
    }

    /// Whether exact scaling is applied.
    pub fn exact_scaling(&self) -> bool {
        self.spec.exact_scaling
    }
}

/// A series: the original (h = 1, the reference of every accuracy figure) first, then
/// its coarse-grained members.
#[derive(Clone, Debug)]
pub struct Series {
    /// Name (`equal`, `binary`, `quick`, or a custom series' own).
    pub name: String,
    /// The members; `members[0]` is the reference.
    pub members: Vec<Member>,
}

/// The built-in series sets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StudyPreset {
    /// A small series in the quick specimen's cylinder (h = 1, 1.5, 2, both variants).
    Quick,
    /// The paper's equal-size series E1-E4s.
    Equal,
    /// The paper's binary series B1-B3s.
    Binary,
    /// Both of the paper's series: the twelve tests of Table 4.
    Paper,
}

impl StudyPreset {
    /// The preset named `name` (`quick`, `equal`, `binary`, `paper`).
    pub fn find(name: &str) -> Result<StudyPreset, StudyError> {
        match name {
            "quick" => Ok(StudyPreset::Quick),
            "equal" => Ok(StudyPreset::Equal),
            "binary" => Ok(StudyPreset::Binary),
            "paper" => Ok(StudyPreset::Paper),
            other => Err(StudyError::Definition(format!(
                "unknown study preset '{other}'; the presets are quick, equal, binary and paper"
            ))),
        }
    }

    /// Name as typed.
    pub fn name(self) -> &'static str {
        match self {
            StudyPreset::Quick => "quick",
            StudyPreset::Equal => "equal",
            StudyPreset::Binary => "binary",
            StudyPreset::Paper => "paper",
        }
    }

    /// Its series.
    pub fn series(self) -> Result<Vec<Series>, StudyError> {
        Ok(match self {
            StudyPreset::Quick => vec![quick_series()?],
            StudyPreset::Equal => vec![paper_series("equal", EQUAL)?],
            StudyPreset::Binary => vec![paper_series("binary", BINARY)?],
            StudyPreset::Paper => vec![
                paper_series("equal", EQUAL)?,
                paper_series("binary", BINARY)?,
            ],
        })
    }
}

fn paper_series(name: &str, tests: &[&str]) -> Result<Series, StudyError> {
    let members = tests
        .iter()
        .map(|t| {
            Ok(Member {
                test: (*t).to_string(),
                spec: Preset::find(t)?.spec(),
            })
        })
        .collect::<Result<Vec<_>, StudyError>>()?;
    Ok(Series {
        name: name.to_string(),
        members,
    })
}

/// The quick series: the quick specimen's cylinder, parameters and loading velocity, with
/// original particles of half its size, so that its coarsest member (h = 2, plain) is the
/// quick specimen itself. The contact margin, a particle length, is given at h = 1 and
/// scaled by h like the sizes; the loading velocity is the quick specimen's for every
/// member (the series size is its simulated size).
pub fn quick_series() -> Result<Series, StudyError> {
    let coarsest = QUICK_FACTORS.iter().copied().fold(1.0, f64::max);
    let quick = quick_spec();
    let mut original = quick.clone();
    for class in &mut original.gradation {
        class.size /= coarsest;
    }
    original.contact.margin = quick.contact.margin.map(|m| m / coarsest);
    original.test.series_size = Some(quick.largest_simulated_size());
    let mut members = Vec::new();
    for &h in QUICK_FACTORS {
        let variants: &[bool] = if h == 1.0 { &[false] } else { &[false, true] };
        for &exact in variants {
            let mut spec = original.clone();
            spec.coarse_graining = h;
            spec.exact_scaling = exact;
            spec.name = format!("Q{h}{}", if exact { "s" } else { "" });
            members.push(Member {
                test: spec.name.clone(),
                spec,
            });
        }
    }
    Ok(Series {
        name: "quick".into(),
        members,
    })
}

/// A custom series file (TOML): `[[series]]` tables, each with a `name`, the original's
/// specimen definition `specimen` (a path relative to the file; docs/SPECIMENS.md), the
/// factors `h` (1 is added first when missing) and the `variants` of the members with
/// h > 1 (`"plain"`, `"exact"`; default both).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SeriesFile {
    series: Vec<SeriesEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SeriesEntry {
    name: String,
    specimen: String,
    h: Vec<f64>,
    #[serde(default = "both_variants")]
    variants: Vec<Variant>,
}

#[derive(Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum Variant {
    Plain,
    Exact,
}

fn both_variants() -> Vec<Variant> {
    vec![Variant::Plain, Variant::Exact]
}

/// Reads a custom series file (see [`SeriesFile`]'s keys in docs/STUDY.md).
pub fn load_series(path: &Path) -> Result<Vec<Series>, StudyError> {
    let text = std::fs::read_to_string(path).map_err(|e| StudyError::io("reading", path, e))?;
    let file: SeriesFile = toml::from_str(&text)
        .map_err(|e| StudyError::Definition(format!("{}: {}", path.display(), e.message())))?;
    if file.series.is_empty() {
        return Err(StudyError::Definition(format!(
            "{}: no [[series]]; give at least one with name, specimen and h",
            path.display()
        )));
    }
    let base = path.parent().unwrap_or(Path::new("."));
    file.series
        .into_iter()
        .map(|entry| custom_series(entry, base, path))
        .collect()
}

fn custom_series(entry: SeriesEntry, base: &Path, file: &Path) -> Result<Series, StudyError> {
    let bad = |key: &str, message: String| {
        StudyError::Definition(format!(
            "{}: series '{}': {key}: {message}",
            file.display(),
            entry.name
        ))
    };
    if entry.name.is_empty()
        || !entry
            .name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        return Err(bad(
            "name",
            "use letters, digits, '-' and '_' (it names files)".into(),
        ));
    }
    let mut factors = entry.h.clone();
    if let Some(bad_h) = factors.iter().find(|h| !(h.is_finite() && **h >= 1.0)) {
        return Err(bad("h", format!("{bad_h} is not a factor >= 1")));
    }
    if !factors.contains(&1.0) {
        factors.insert(0, 1.0);
    }
    factors.sort_by(f64::total_cmp);
    factors.dedup();
    if entry.variants.is_empty() {
        return Err(bad("variants", "give \"plain\", \"exact\" or both".into()));
    }
    let path = base.join(&entry.specimen);
    let mut original = SpecimenSpec::load(&path)?;
    original.coarse_graining = 1.0;
    original.exact_scaling = false;
    let mut members = Vec::new();
    for h in factors {
        for &variant in &entry.variants {
            let exact = variant == Variant::Exact;
            if h == 1.0 && exact {
                continue;
            }
            let mut spec = original.clone();
            spec.coarse_graining = h;
            spec.exact_scaling = exact;
            spec.name = format!("{}-h{h}{}", entry.name, if exact { "s" } else { "" });
            spec.validate(&path.display().to_string())?;
            members.push(Member {
                test: spec.name.clone(),
                spec,
            });
        }
        if h == 1.0 && members.is_empty() {
            let mut spec = original.clone();
            spec.name = format!("{}-h1", entry.name);
            members.push(Member {
                test: spec.name.clone(),
                spec,
            });
        }
    }
    Ok(Series {
        name: entry.name,
        members,
    })
}

/// The element order of a study's runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OrderChoice {
    /// The order [`surface_order`] chooses for the study's model.
    #[default]
    Auto,
    /// This order for every run.
    Fixed(ElementOrder),
}

/// How a study's series become runs.
#[derive(Clone, Debug)]
pub struct StudyOptions {
    /// Particle model of every run.
    pub model: ParticleModel,
    /// Element order.
    pub order: OrderChoice,
    /// Independent packings per test (placement seeds 1..=seeds).
    pub seeds: u32,
    /// Only these tests (all when `None`); the others still count as references when
    /// their runs are present from an earlier invocation.
    pub tests: Option<Vec<String>>,
    /// Target axial strain of every run (the specimens' own when `None`).
    pub strain: Option<f64>,
}

impl Default for StudyOptions {
    fn default() -> Self {
        StudyOptions {
            model: ParticleModel::Auto,
            order: OrderChoice::Auto,
            seeds: 1,
            tests: None,
            strain: None,
        }
    }
}

/// One run of a study: a member of a series with its seed, model and order.
#[derive(Clone, Debug)]
pub struct RunDef {
    /// Series name.
    pub series: String,
    /// Test name.
    pub test: String,
    /// Whether this is the series' reference (h = 1).
    pub reference: bool,
    /// Placement seed.
    pub seed: u64,
    /// The whole definition (seed, model and order applied).
    pub spec: SpecimenSpec,
}

impl RunDef {
    /// Coarse-graining factor h.
    pub fn h(&self) -> f64 {
        self.spec.coarse_graining
    }

    /// Whether exact scaling is applied.
    pub fn exact_scaling(&self) -> bool {
        self.spec.exact_scaling
    }

    /// The particle model asked for.
    pub fn model(&self) -> ParticleModel {
        self.spec.model
    }

    /// The element order's name.
    pub fn order(&self) -> &'static str {
        match self.spec.mesh.order {
            ElementOrder::Linear => "linear",
            ElementOrder::Quadratic => "quadratic",
        }
    }

    /// A name for files: test, model, order and seed.
    pub fn label(&self) -> String {
        format!(
            "{}-{}-{}-seed{}",
            self.test,
            self.model().name(),
            self.order(),
            self.seed
        )
    }

    /// The key of the whole definition: 16 hex digits of FNV-1a over the key version, the
    /// program version and the definition's TOML (every key written out). Two runs with
    /// the same key compute the same thing; a finished run is reused only under its key.
    pub fn key(&self) -> Result<String, StudyError> {
        let text = self.spec.to_toml_string()?;
        let mut h = Fnv1a::new();
        h.update(
            format!(
                "fdem-study key {KEY_VERSION}, fdem {}\n",
                env!("CARGO_PKG_VERSION")
            )
            .as_bytes(),
        );
        h.update(text.as_bytes());
        Ok(format!("{:016x}", h.0))
    }
}

/// The runs of `series` under `options`, in series order, each member's seeds together;
/// with `all`, the test filter is ignored (every run of the series, for reports).
pub fn expand(
    series: &[Series],
    options: &StudyOptions,
    all: bool,
) -> Result<Vec<RunDef>, StudyError> {
    if options.seeds == 0 {
        return Err(StudyError::Definition("--seeds must be at least 1".into()));
    }
    if let Some(tests) = &options.tests {
        let known: Vec<&str> = series
            .iter()
            .flat_map(|s| s.members.iter().map(|m| m.test.as_str()))
            .collect();
        if let Some(unknown) = tests.iter().find(|t| !known.contains(&t.as_str())) {
            return Err(StudyError::Definition(format!(
                "--tests: '{unknown}' is not a test of this study; its tests are {}",
                known.join(", ")
            )));
        }
    }
    let mut runs = Vec::new();
    for s in series {
        for (i, member) in s.members.iter().enumerate() {
            let chosen = all
                || options
                    .tests
                    .as_ref()
                    .is_none_or(|t| t.contains(&member.test));
            if !chosen {
                continue;
            }
            for seed in 1..=u64::from(options.seeds) {
                let mut spec = member.spec.clone();
                spec.seed = seed;
                spec.model = options.model;
                spec.mesh.order = match options.order {
                    OrderChoice::Fixed(order) => order,
                    OrderChoice::Auto => surface_order(options.model, spec.mesh.order),
                };
                if let Some(strain) = options.strain {
                    spec.test.target_strain = strain;
                }
                spec.validate(&format!("study run {}", member.test))?;
                runs.push(RunDef {
                    series: s.name.clone(),
                    test: member.test.clone(),
                    reference: i == 0,
                    seed,
                    spec,
                });
            }
        }
    }
    Ok(runs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_quick_series_coarsest_plain_member_is_the_quick_specimen() {
        let series = quick_series().unwrap();
        let names: Vec<&str> = series.members.iter().map(|m| m.test.as_str()).collect();
        assert_eq!(names, ["Q1", "Q1.5", "Q1.5s", "Q2", "Q2s"]);
        let q2 = &series.members[3].spec;
        let quick = quick_spec();
        let (a, b) = (q2.simulated().unwrap(), quick.simulated().unwrap());
        assert_eq!(a.sizes, b.sizes);
        assert_eq!(a.contact.margin, b.contact.margin);
        assert_eq!(a.contact.normal_penalty, b.contact.normal_penalty);
        assert_eq!(q2.loading_velocity(), quick.loading_velocity());
        // Every member shares the velocity; h = 1 has eight times the particles.
        let v: Vec<f64> = series
            .members
            .iter()
            .map(|m| m.spec.loading_velocity())
            .collect();
        assert!(v.iter().all(|x| *x == v[0]));
        let n1 = series.members[0].spec.counts().unwrap().particles;
        let n2 = quick.counts().unwrap().particles;
        assert!((n1 as f64 / n2 as f64 - 8.0).abs() < 0.5, "{n1} vs {n2}");
    }

    #[test]
    fn keys_change_with_the_definition_and_only_with_it() {
        let series = quick_series().unwrap();
        let options = StudyOptions {
            model: ParticleModel::Rigid,
            seeds: 2,
            ..StudyOptions::default()
        };
        let runs = expand(&[series], &options, false).unwrap();
        assert_eq!(runs.len(), 10);
        let keys: Vec<String> = runs.iter().map(|r| r.key().unwrap()).collect();
        let mut unique = keys.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), keys.len());
        assert_eq!(runs[0].key().unwrap(), runs[0].clone().key().unwrap());
        assert_eq!(runs[0].order(), "linear");
        assert_eq!(runs[0].label(), "Q1-rigid-linear-seed1");
    }

    #[test]
    fn unknown_tests_and_zero_seeds_are_refused() {
        let series = [quick_series().unwrap()];
        let mut options = StudyOptions {
            tests: Some(vec!["E9".into()]),
            ..StudyOptions::default()
        };
        let e = expand(&series, &options, false).unwrap_err().to_string();
        assert!(e.contains("'E9'") && e.contains("Q1.5s"), "{e}");
        options.tests = None;
        options.seeds = 0;
        assert!(expand(&series, &options, false).is_err());
    }
}
