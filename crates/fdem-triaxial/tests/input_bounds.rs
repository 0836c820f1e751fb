//! Specimen definitions over the whole range of their inputs: every numeric field at the
//! extremes of the f64 range (and of the integers), every array from 0 to 5 entries.
//!
//! For each drawn definition, the steps a command runs before any heavy work (parsing and
//! validation, the counts, the memory check, the time step of one particle per size) must
//! return within a bound, never panic, and end in a usable result or one clear error: one
//! line naming the key, at the key that holds a value outside its own range.

use fdem_triaxial::{SpecimenSpec, TriaxialError, check_memory, specimen_time_step};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use std::time::Duration;

/// Longest time the steps before the heavy work may take for one definition (a debug
/// build on a shared machine; what is checked is that they end, not how fast).
const BOUND: Duration = Duration::from_secs(20);

/// The memory budget of the check (bytes): a definition is counted and refused or
/// accepted against it, independently of the machine running the test.
const BUDGET: u64 = 8 << 30;

/// Values drawn for a float field besides arbitrary bit patterns: zero, negative zero,
/// the smallest subnormal, the edges of the normal range, NaN, the infinities, negative
/// and ordinary values.
const FLOAT_EXTREMES: &[f64] = &[
    0.0,
    -0.0,
    5e-324,
    1e-308,
    1e-300,
    1e-12,
    0.5,
    1.0,
    -1.0,
    1e12,
    1e300,
    1e308,
    f64::MAX,
    -f64::MAX,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
];

/// Values drawn for an integer field (TOML integers are i64), and one of the wrong type.
const INT_EXTREMES: &[&str] = &[
    "0",
    "-1",
    "1",
    "4",
    "5",
    "100001",
    "9223372036854775807",
    "-9223372036854775808",
    "1.5",
];

/// Which signs a float field accepts: most fields are sizes, rates or fractions
/// (negative refused); a Poisson's ratio or a gravity component may be negative.
#[derive(Clone, Copy, PartialEq)]
enum Sign {
    NotNegative,
    Any,
}

/// A scalar field of the schema: its table (`""` for the top level), key, ordinary value
/// (`None`: absent unless drawn) and the signs it accepts.
struct Field {
    table: &'static str,
    key: &'static str,
    ordinary: Option<&'static str>,
    sign: Sign,
}

const fn f(table: &'static str, key: &'static str, ordinary: Option<&'static str>) -> Field {
    Field {
        table,
        key,
        ordinary,
        sign: Sign::NotNegative,
    }
}

const fn any_sign(table: &'static str, key: &'static str, ordinary: &'static str) -> Field {
    Field {
        table,
        key,
        ordinary: Some(ordinary),
        sign: Sign::Any,
    }
}

/// Every float field of a specimen definition but the gradation's and the gravity's
/// components, at the values of the quick specimen (a definition that is accepted).
const FLOATS: &[Field] = &[
    f("", "diameter", Some("0.150")),
    f("", "height", Some("0.225")),
    f("", "membrane_thickness", Some("0.002")),
    f("", "solid_fraction", Some("0.62")),
    f("", "coarse_graining", Some("1.0")),
    f("", "confining_pressure", Some("0.8e6")),
    f("", "loading_velocity", None),
    f("", "auto_threshold", None),
    f("material", "density", Some("2650.0")),
    f("material", "youngs_modulus", Some("10.0e9")),
    any_sign("material", "poisson_ratio", "0.2"),
    f("contact", "normal_penalty", Some("4.5e10")),
    f("contact", "penalty_ratio", Some("1.0")),
    f("contact", "friction", Some("0.3")),
    f("contact", "damping", Some("0.2")),
    f("contact", "damping_ratio", Some("1.0")),
    f("contact", "margin", Some("0.004")),
    f("contact", "depth_limit", None),
    f("preparation", "loose_solid_fraction", Some("0.40")),
    f("preparation", "platen_speed", Some("4.0")),
    f("preparation", "friction", Some("0.0")),
    f("preparation", "dt_safety", Some("0.5")),
    f("preparation", "clearance", Some("0.02")),
    f("preparation", "max_overlap", Some("0.03")),
    f("preparation", "unbalanced_force", Some("0.02")),
    f("preparation", "settle_time", None),
    f("membrane", "youngs_modulus", Some("40.0e6")),
    any_sign("membrane", "poisson_ratio", "0.45"),
    f("membrane", "density", Some("1100.0")),
    f("membrane", "damping", Some("8.0e4")),
    f("membrane", "speed_limit", None),
    f("membrane", "added_mass", None),
    f("test", "target_strain", Some("0.15")),
    f("test", "inertial_number", Some("5e-3")),
    f("test", "series_size", None),
    f("test", "output_strain", Some("0.0025")),
    f("test", "stress_tolerance", Some("0.01")),
    f("test", "unbalanced_force", Some("0.02")),
    f("test", "kinetic_ratio", Some("0.05")),
    f("test", "volume_rate", Some("0.1")),
    f("test", "consolidation_time", None),
    f("test", "ramp_time", None),
    f("test", "servo_speed", Some("2.0")),
    f("test", "servo_band", Some("0.25")),
    f("test", "residual_window", Some("0.02")),
    f("test", "dt_safety", None),
];

/// Every integer field.
const INTS: &[Field] = &[
    f("", "seed", Some("1")),
    f("", "particles", None),
    f("mesh", "level", Some("1")),
    f("preparation", "check_interval", Some("100")),
    f("test", "check_interval", Some("500")),
    f("membrane", "divisions_around", None),
    f("membrane", "divisions_along", None),
];

/// Ordinary sizes of up to five distinct size classes.
const SIZES: [&str; 5] = ["0.0375", "0.03", "0.025", "0.02", "0.015"];

/// What replaces a field's ordinary value.
#[derive(Clone, Debug)]
enum Value {
    Absent,
    Float(f64),
    Text(&'static str),
}

impl Value {
    fn toml(&self) -> Option<String> {
        match self {
            Value::Absent => None,
            Value::Float(v) => Some(toml_float(*v)),
            Value::Text(t) => Some(t.to_string()),
        }
    }

    /// Whether this value breaks the rule of a field accepting `sign` whatever the
    /// other fields hold (a definite refusal at that field).
    fn outside(&self, sign: Sign) -> bool {
        match self {
            Value::Float(v) => !v.is_finite() || (sign == Sign::NotNegative && *v < 0.0),
            // Every integer of the schema is a count or a seed: negative or fractional
            // values have no meaning.
            Value::Text(t) => t.starts_with('-') || t.contains('.'),
            Value::Absent => false,
        }
    }
}

/// A float as TOML writes it (`nan`, `inf`, `-inf`, else Rust's shortest round-trip
/// form, which is also a TOML float).
fn toml_float(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { "inf" } else { "-inf" }.into()
    } else {
        format!("{v:?}")
    }
}

/// Where a drawn value goes.
#[derive(Clone, Debug)]
enum Target {
    Float(usize),
    Int(usize),
    /// `gradation[i].size` (false) or `.mass_fraction` (true).
    Class(usize, bool),
    /// Component `i` of `preparation.gravity`.
    Gravity(usize),
}

/// One drawn definition.
#[derive(Clone, Debug)]
struct Case {
    model: &'static str,
    classes: usize,
    gravity: usize,
    changes: Vec<(Target, Value)>,
}

fn float_value() -> impl Strategy<Value = Value> {
    prop_oneof![
        4 => proptest::sample::select(FLOAT_EXTREMES).prop_map(Value::Float),
        2 => proptest::num::f64::ANY.prop_map(Value::Float),
        1 => Just(Value::Absent),
    ]
}

fn int_value() -> impl Strategy<Value = Value> {
    prop_oneof![
        4 => proptest::sample::select(INT_EXTREMES).prop_map(Value::Text),
        1 => Just(Value::Absent),
    ]
}

fn change() -> impl Strategy<Value = (Target, Value)> {
    prop_oneof![
        6 => (0..FLOATS.len(), float_value()).prop_map(|(i, v)| (Target::Float(i), v)),
        2 => (0..INTS.len(), int_value()).prop_map(|(i, v)| (Target::Int(i), v)),
        2 => (0..5usize, any::<bool>(), float_value())
            .prop_map(|(i, m, v)| (Target::Class(i, m), v)),
        1 => (0..5usize, float_value()).prop_map(|(i, v)| (Target::Gravity(i), v)),
    ]
}

fn case() -> impl Strategy<Value = Case> {
    (
        proptest::sample::select(&["deformable", "rigid", "auto"][..]),
        0..=5usize,
        prop_oneof![3 => Just(3usize), 1 => 0..=5usize],
        proptest::collection::vec(change(), 0..=3),
    )
        .prop_map(|(model, classes, gravity, changes)| Case {
            model,
            classes,
            gravity,
            changes,
        })
}

impl Case {
    /// The value of `target` in this case: the last change drawn for it, or `None`.
    fn changed(&self, target: impl Fn(&Target) -> bool) -> Option<&Value> {
        self.changes
            .iter()
            .rev()
            .find(|(t, _)| target(t))
            .map(|(_, v)| v)
    }

    /// A field's line (`None` when absent).
    fn line(&self, field: &Field, changed: Option<&Value>) -> Option<String> {
        let value = match changed {
            Some(v) => v.toml()?,
            None => field.ordinary?.to_string(),
        };
        Some(format!("{} = {value}\n", field.key))
    }

    /// The definition as TOML text.
    fn text(&self) -> String {
        let mut tables: Vec<(&str, String)> = Vec::new();
        push(&mut tables, "", format!("model = \"{}\"\n", self.model));
        push(&mut tables, "mesh", "order = \"linear\"\n".into());
        for (i, field) in FLOATS.iter().enumerate() {
            let changed = self.changed(|t| matches!(t, Target::Float(j) if *j == i));
            if let Some(line) = self.line(field, changed) {
                push(&mut tables, field.table, line);
            }
        }
        for (i, field) in INTS.iter().enumerate() {
            let changed = self.changed(|t| matches!(t, Target::Int(j) if *j == i));
            if let Some(line) = self.line(field, changed) {
                push(&mut tables, field.table, line);
            }
        }
        let fraction = format!("{:?}", 1.0 / self.classes.max(1) as f64);
        let classes: Vec<String> = (0..self.classes)
            .map(|i| {
                let size = self.changed(|t| matches!(t, Target::Class(j, false) if *j == i));
                let mass = self.changed(|t| matches!(t, Target::Class(j, true) if *j == i));
                let entry = |key: &str, changed: Option<&Value>, ordinary: &str| match changed {
                    Some(v) => v.toml().map(|v| format!("{key} = {v}")),
                    None => Some(format!("{key} = {ordinary}")),
                };
                let parts: Vec<String> = [
                    entry("size", size, SIZES[i]),
                    entry("mass_fraction", mass, &fraction),
                ]
                .into_iter()
                .flatten()
                .collect();
                format!("{{ {} }}", parts.join(", "))
            })
            .collect();
        push(
            &mut tables,
            "",
            format!("gradation = [{}]\n", classes.join(", ")),
        );
        let gravity: Vec<String> = (0..self.gravity)
            .map(|i| {
                let changed = self.changed(|t| matches!(t, Target::Gravity(j) if *j == i));
                // An absent component cannot be written; it stays ordinary.
                changed
                    .and_then(Value::toml)
                    .unwrap_or_else(|| "0.0".into())
            })
            .collect();
        push(
            &mut tables,
            "preparation",
            format!("gravity = [{}]\n", gravity.join(", ")),
        );
        let mut text = String::new();
        for (name, body) in &tables {
            if !name.is_empty() {
                text.push_str(&format!("\n[{name}]\n"));
            }
            text.push_str(body);
        }
        text
    }

    /// The key of `target` in this case (`None` for an entry the arrays do not have).
    fn key(&self, target: &Target) -> Option<String> {
        let path = |field: &Field| match field.table {
            "" => field.key.to_string(),
            t => format!("{t}.{}", field.key),
        };
        match target {
            Target::Float(i) => Some(path(&FLOATS[*i])),
            Target::Int(i) => Some(path(&INTS[*i])),
            Target::Class(i, m) if *i < self.classes => {
                let name = if *m { "mass_fraction" } else { "size" };
                Some(format!("gradation[{i}].{name}"))
            }
            Target::Gravity(i) if *i < self.gravity => Some("preparation.gravity".into()),
            _ => None,
        }
    }

    /// The keys written with a value that breaks their own rule whatever the other
    /// fields hold, and the drawn keys (with a gravity of the wrong length): the ordinary
    /// definition is accepted, so when any value breaks its own rule the refusal must be
    /// at one of the drawn keys (a parse-time rule fails before any rule across keys).
    fn keys(&self) -> (Vec<String>, Vec<String>) {
        let mut outside = Vec::new();
        let mut drawn = Vec::new();
        if self.gravity != 3 {
            outside.push("preparation.gravity".to_string());
            drawn.push("preparation.gravity".to_string());
        }
        for (target, value) in &self.changes {
            let Some(key) = self.key(target) else {
                continue;
            };
            let sign = match target {
                Target::Float(i) => FLOATS[*i].sign,
                Target::Gravity(_) => Sign::Any,
                _ => Sign::NotNegative,
            };
            // Only the last change of a target is written.
            let last = self.changes.iter().rev().find(|(t, _)| same(t, target));
            if last.is_some_and(|(_, v)| std::ptr::eq(v, value)) && value.outside(sign) {
                outside.push(key.clone());
            }
            drawn.push(key);
        }
        (outside, drawn)
    }

    /// Whether any written value is not finite (a message may then print it).
    fn has_non_finite(&self) -> bool {
        self.changes
            .iter()
            .any(|(_, v)| matches!(v, Value::Float(x) if !x.is_finite()))
    }
}

/// Appends `line` to table `name` (created at the end if new).
fn push(tables: &mut Vec<(&'static str, String)>, name: &'static str, line: String) {
    match tables.iter_mut().find(|(n, _)| *n == name) {
        Some((_, body)) => body.push_str(&line),
        None => tables.push((name, line)),
    }
}

fn same(a: &Target, b: &Target) -> bool {
    match (a, b) {
        (Target::Float(i), Target::Float(j)) | (Target::Int(i), Target::Int(j)) => i == j,
        (Target::Gravity(i), Target::Gravity(j)) => i == j,
        (Target::Class(i, m), Target::Class(j, n)) => i == j && m == n,
        _ => false,
    }
}

/// How a definition ended: refused (the message) or accepted through every step.
enum Outcome {
    Refused(String),
    Accepted,
}

/// Checks an error's message: one line, not empty, without a `:0:0` location, and
/// without a NaN when the input had none (a NaN in a message is a number that was never
/// checked; an infinite bound is a statement about the inputs).
fn check_message(e: &TriaxialError, case: &Case) -> Result<String, String> {
    let m = e.to_string();
    if m.is_empty() || m.contains('\n') {
        return Err(format!("not one line: {m:?}"));
    }
    if m.contains(":0:0:") || m.contains(":0:") {
        return Err(format!("a location without a line: {m}"));
    }
    if !case.has_non_finite() && m.to_lowercase().contains("nan") {
        return Err(format!("prints a NaN it derived: {m}"));
    }
    Ok(m)
}

/// The steps before the heavy work: parse and validate, count, check the memory, find
/// the time step; the definition also survives its own round trip through TOML (a
/// specimen file stores it as TOML).
fn steps_before_the_work(case: &Case) -> Result<Outcome, String> {
    let text = case.text();
    let refused = |e: TriaxialError| check_message(&e, case).map(Outcome::Refused);
    let spec = match SpecimenSpec::from_toml_str(&text, "case.toml") {
        Ok(spec) => spec,
        Err(e) => return refused(e),
    };
    let again = spec.to_toml_string().map_err(|e| e.to_string())?;
    match SpecimenSpec::from_toml_str(&again, "again.toml") {
        Ok(s) if s == spec => {}
        Ok(_) => return Err(format!("the TOML round trip changed it:\n{again}")),
        Err(e) => return Err(format!("its own TOML is refused: {e}\n{again}")),
    }
    let counts = match spec.counts() {
        Ok(c) => c,
        Err(e) => return refused(e),
    };
    if let Err(e) = check_memory(&spec, &counts, Some(BUDGET)) {
        return refused(e);
    }
    match specimen_time_step(&spec) {
        Ok((dt, bound, _)) if dt.is_finite() && dt > 0.0 && dt <= bound => Ok(Outcome::Accepted),
        Ok((dt, bound, source)) => Err(format!(
            "time step {dt:e} s against a bound of {bound:e} s ({source})"
        )),
        Err(e) => refused(e),
    }
}

/// Runs the steps of `case` on a thread of its own and checks the bound, the absence of a
/// panic, the message and where it points.
fn check(case: &Case) -> Result<Outcome, String> {
    let (send, receive) = std::sync::mpsc::channel();
    let owned = case.clone();
    std::thread::spawn(move || {
        let _ = send.send(steps_before_the_work(&owned));
    });
    let outcome = match receive.recv_timeout(BOUND) {
        Ok(outcome) => outcome,
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
            return Err(format!("did not return within {BOUND:?}"));
        }
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
            return Err("panicked".into());
        }
    }?;
    let (outside, drawn) = case.keys();
    match &outcome {
        Outcome::Accepted if !outside.is_empty() => {
            return Err(format!("accepted with {outside:?} outside their range"));
        }
        Outcome::Refused(m) if !outside.is_empty() && !drawn.iter().any(|k| names(m, k)) => {
            return Err(format!("refused, but not at one of {drawn:?}: {m}"));
        }
        _ => {}
    }
    Ok(outcome)
}

/// Whether message `m` is about `key`: at the key, or a missing field of its table.
fn names(m: &str, key: &str) -> bool {
    let (table, field) = key.rsplit_once('.').unwrap_or(("", key));
    let missing = format!("missing field `{field}`");
    m.contains(&format!(": {key}: "))
        || (m.contains(&missing) && (table.is_empty() || m.contains(&format!(": {table}: "))))
}

/// Runs `cases` drawn definitions; returns (accepted, refused).
fn run(cases: u32) -> (u32, u32) {
    let mut runner = TestRunner::new(Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    });
    let counts = std::cell::Cell::new((0u32, 0u32));
    let result = runner.run(&case(), |case| {
        let outcome = check(&case).map_err(|m| {
            TestCaseError::fail(format!("{m}\n--- definition ---\n{}", case.text()))
        })?;
        let (a, r) = counts.get();
        counts.set(match outcome {
            Outcome::Accepted => (a + 1, r),
            Outcome::Refused(_) => (a, r + 1),
        });
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    counts.get()
}

/// The untouched case is the quick specimen's definition, which is accepted: the cases
/// drawn around it reach every step.
#[test]
fn the_ordinary_definition_is_accepted() {
    let case = Case {
        model: "deformable",
        classes: 1,
        gravity: 3,
        changes: Vec::new(),
    };
    assert!(matches!(check(&case), Ok(Outcome::Accepted)));
}

#[test]
fn specimen_definitions_over_the_whole_range_end_in_a_result_or_one_clear_error() {
    let (accepted, refused) = run(300);
    eprintln!("300 definitions: {accepted} accepted, {refused} refused");
    assert!(accepted > 0 && refused > 0);
}

#[test]
#[ignore = "the long variant: cargo test -p fdem-triaxial --test input_bounds -- --ignored"]
fn specimen_definitions_over_the_whole_range_long() {
    let (accepted, refused) = run(10_000);
    eprintln!("10000 definitions: {accepted} accepted, {refused} refused");
    assert!(accepted > 0 && refused > 0);
}
