//! Stability maps (docs/STABILITY.md): the test model of a small dense packing probed at
//! multiples of its computed stable step, over the normal penalty, the contact damping
//! and the membrane's Young's modulus, for rigid, linear and quadratic particles; each
//! run classified by what stopped it.

use crate::StudyError;
use fdem_core::fs::write_atomically;
use fdem_mesh::ElementOrder;
use fdem_solver::ParticleModel;
use fdem_triaxial::{
    Cached, Observer, PreparedSpecimen, StabilityClass, prepare, probe, probe_bound, quick_spec,
};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// The paper's normal penalty (Table 3), N/m^3: the centre of the penalty sweep.
pub const PAPER_PENALTY: f64 = 1.8e11;
/// The paper's Young's modulus (Table 3), Pa: the particles' material in the maps.
pub const PAPER_MODULUS: f64 = 40e9;

/// The header of `stability.csv`.
pub const STABILITY_HEADER: &str = "model,order,dt_factor,normal_penalty,damping,class,steps,\
max_energy_error,max_depth,dt,bound,bound_source,membrane_modulus";

/// The membrane's Young's modulus of the maps' specimen (Pa): the quick specimen's, and
/// that of rows written before the membrane was swept.
pub fn default_membrane_modulus() -> f64 {
    quick_spec().membrane.youngs_modulus
}

/// One particle model of a map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModelVariant {
    /// Rigid or deformable.
    pub model: ParticleModel,
    /// Element order (the surface for rigid particles).
    pub order: ElementOrder,
}

impl ModelVariant {
    /// `rigid`, `linear` or `quadratic`.
    pub fn name(self) -> &'static str {
        match (self.model, self.order) {
            (ParticleModel::Rigid, _) => "rigid",
            (_, ElementOrder::Linear) => "linear",
            (_, ElementOrder::Quadratic) => "quadratic",
        }
    }
}

/// What a map sweeps.
#[derive(Clone, Debug)]
pub struct MapSpec {
    /// The models.
    pub variants: Vec<ModelVariant>,
    /// Steps as multiples of the computed stable bound.
    pub dt_factors: Vec<f64>,
    /// Normal penalties (N/m^3), swept at `damping`.
    pub penalties: Vec<f64>,
    /// Contact damping ratios, swept at [`PAPER_PENALTY`].
    pub dampings: Vec<f64>,
    /// The damping of the penalty sweep (the paper's).
    pub damping: f64,
    /// Membrane Young's moduli (Pa) besides the specimen's own, swept at
    /// [`PAPER_PENALTY`] and `damping`.
    pub membrane_moduli: Vec<f64>,
    /// Steps of each probe.
    pub steps: u64,
}

/// One probe of a map: where it lies on every axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapPoint {
    /// The particle model.
    pub variant: ModelVariant,
    /// Normal penalty (N/m^3).
    pub penalty: f64,
    /// Contact damping ratio.
    pub damping: f64,
    /// The membrane's Young's modulus (Pa).
    pub membrane_modulus: f64,
    /// Step over the computed bound.
    pub factor: f64,
}

/// A line of the map (model, order, and the bits of penalty, damping and membrane
/// modulus): everything of a probe but its step factor.
type LineKey = (String, String, u64, u64, u64);

impl MapPoint {
    /// The line of the map it lies on, as bits.
    fn line(&self) -> LineKey {
        (
            self.variant.name().to_string(),
            order_name(self.variant.order).to_string(),
            self.penalty.to_bits(),
            self.damping.to_bits(),
            self.membrane_modulus.to_bits(),
        )
    }
}

const RIGID: ModelVariant = ModelVariant {
    model: ParticleModel::Rigid,
    order: ElementOrder::Linear,
};
const LINEAR: ModelVariant = ModelVariant {
    model: ParticleModel::Deformable,
    order: ElementOrder::Linear,
};
const QUADRATIC: ModelVariant = ModelVariant {
    model: ParticleModel::Deformable,
    order: ElementOrder::Quadratic,
};

impl MapSpec {
    /// The default map: rigid, linear and quadratic particles; the step from 0.5 to 2.5
    /// times the bound, finer near 1; the penalty over three decades around the paper's;
    /// the damping ratio from 0 to 1; a latex membrane (1 MPa) beside the specimen's
    /// 40 MPa; 2,000 steps per probe.
    pub fn full() -> MapSpec {
        MapSpec {
            variants: vec![RIGID, LINEAR, QUADRATIC],
            dt_factors: vec![0.5, 0.8, 0.9, 1.0, 1.1, 1.25, 1.5, 2.0, 2.5],
            penalties: vec![1.8e9, 1.8e10, 1.8e11, 1.8e12],
            dampings: vec![0.0, 0.2, 0.5, 1.0],
            damping: 0.2,
            membrane_moduli: vec![1e6],
            steps: 2000,
        }
    }

    /// The quick map of the test suite: rigid and linear particles at the paper's penalty
    /// and damping, at 0.9 and 2 times the bound, 1,000 steps.
    pub fn quick() -> MapSpec {
        MapSpec {
            variants: vec![RIGID, LINEAR],
            dt_factors: vec![0.9, 2.0],
            penalties: vec![PAPER_PENALTY],
            dampings: vec![],
            damping: 0.2,
            membrane_moduli: vec![],
            steps: 1000,
        }
    }

    /// Every probe of the map: the penalty sweep at the map's damping, then the damping
    /// sweep at the paper's penalty (without repeating the point both share), then the
    /// membrane sweep at the paper's penalty and the map's damping; all with the
    /// specimen's membrane but the last.
    pub fn points(&self) -> Vec<MapPoint> {
        let membrane = default_membrane_modulus();
        let mut lines = Vec::new();
        for &v in &self.variants {
            for &p in &self.penalties {
                lines.push((v, p, self.damping, membrane));
            }
            for &b in self.dampings.iter().filter(|b| **b != self.damping) {
                lines.push((v, PAPER_PENALTY, b, membrane));
            }
            for &e in self.membrane_moduli.iter().filter(|e| **e != membrane) {
                lines.push((v, PAPER_PENALTY, self.damping, e));
            }
        }
        let mut points = Vec::new();
        for (variant, penalty, damping, membrane_modulus) in lines {
            for &factor in &self.dt_factors {
                points.push(MapPoint {
                    variant,
                    penalty,
                    damping,
                    membrane_modulus,
                    factor,
                });
            }
        }
        points
    }
}

/// One probe of the map (one row of `stability.csv`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct MapRow {
    /// `rigid`, `linear` or `quadratic`.
    pub model: String,
    /// Element order.
    pub order: String,
    /// Step over the computed bound.
    pub dt_factor: f64,
    /// Normal penalty (N/m^3).
    pub normal_penalty: f64,
    /// Contact damping ratio.
    pub damping: f64,
    /// Class (`stable`, `slow_growth`, `blow_up`, `penetration`, `tunnelling`,
    /// `non_finite`).
    pub class: String,
    /// Steps done.
    pub steps: u64,
    /// Largest energy balance error over the energy scale.
    pub max_energy_error: f64,
    /// Deepest contact (m).
    pub max_depth: f64,
    /// Step (s).
    pub dt: f64,
    /// Computed bound (s).
    pub bound: f64,
    /// What sets the bound.
    pub bound_source: String,
    /// The membrane's Young's modulus (Pa).
    pub membrane_modulus: f64,
}

impl MapRow {
    /// The line of the map it lies on (as [`MapPoint::line`]).
    fn line(&self) -> LineKey {
        (
            self.model.clone(),
            self.order.clone(),
            self.normal_penalty.to_bits(),
            self.damping.to_bits(),
            self.membrane_modulus.to_bits(),
        )
    }

    /// Whether it is the probe of `point`.
    fn is_at(&self, point: &MapPoint) -> bool {
        self.line() == point.line() && self.dt_factor.to_bits() == point.factor.to_bits()
    }

    /// Whether the probe ran to its end.
    pub fn finished(&self) -> bool {
        self.class == StabilityClass::Stable.name()
            || self.class == StabilityClass::SlowGrowth.name()
    }
}

/// The packing of the maps: the quick specimen's with the paper's particle material and
/// penalty, prepared with rigid particles (saved in `dir` and reused). Every probe starts
/// from it, also those at another penalty: a preparation at a penalty a hundred times
/// softer than the paper's takes steps so long that the compaction tunnels
/// (docs/STABILITY.md), and a packing whose overlaps do not balance the new penalty is one
/// more transient for the probe to survive.
fn packing(dir: &Path, observer: &mut dyn Observer) -> Result<PreparedSpecimen, StudyError> {
    let penalty = PAPER_PENALTY;
    let mut spec = quick_spec();
    spec.name = "stability packing".into();
    spec.material.youngs_modulus = PAPER_MODULUS;
    spec.contact.normal_penalty = penalty;
    spec.model = ParticleModel::Rigid;
    spec.validate(&spec.name)?;
    let path = dir.join("packing.fdemspec");
    if let Cached::Reusable(s) = PreparedSpecimen::cached(&path, &spec) {
        return Ok(*s);
    }
    let prepared = prepare(&spec, observer)?;
    prepared.save(&path)?;
    Ok(prepared)
}

fn csv_text(rows: &[MapRow]) -> String {
    let mut text = String::from(STABILITY_HEADER);
    text.push('\n');
    for r in rows {
        text.push_str(&format!(
            "{},{},{},{:e},{},{},{},{:e},{:e},{:e},{:e},\"{}\",{:e}\n",
            r.model,
            r.order,
            r.dt_factor,
            r.normal_penalty,
            r.damping,
            r.class,
            r.steps,
            r.max_energy_error,
            r.max_depth,
            r.dt,
            r.bound,
            r.bound_source.replace('"', "'"),
            r.membrane_modulus
        ));
    }
    text
}

/// Reads the rows of an earlier (possibly interrupted) map; rows written before the
/// membrane was swept (no `membrane_modulus` column) have the specimen's membrane.
pub fn read_rows(path: &Path) -> Result<Vec<MapRow>, StudyError> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .from_path(path)
        .map_err(|e| StudyError::file(path, e.to_string()))?;
    let mut rows = Vec::new();
    for record in reader.records() {
        let r = record.map_err(|e| StudyError::file(path, e.to_string()))?;
        let num = |i: usize| -> Result<f64, StudyError> {
            r.get(i).and_then(|v| v.parse().ok()).ok_or_else(|| {
                StudyError::file(
                    path,
                    format!(
                        "row {:?}: column {i} is not a number",
                        r.position().map(|p| p.line())
                    ),
                )
            })
        };
        rows.push(MapRow {
            model: r.get(0).unwrap_or_default().to_string(),
            order: r.get(1).unwrap_or_default().to_string(),
            dt_factor: num(2)?,
            normal_penalty: num(3)?,
            damping: num(4)?,
            class: r.get(5).unwrap_or_default().to_string(),
            steps: num(6)? as u64,
            max_energy_error: num(7)?,
            max_depth: num(8)?,
            dt: num(9)?,
            bound: num(10)?,
            bound_source: r.get(11).unwrap_or_default().to_string(),
            membrane_modulus: match r.get(12) {
                Some(_) => num(12)?,
                None => default_membrane_modulus(),
            },
        });
    }
    Ok(rows)
}

/// Runs every probe of `spec` not yet in `dir/stability.csv`, appending each row as it
/// finishes (the file is rewritten atomically after every probe, so an interrupted map
/// keeps what it had); `progress` hears of each probe. A stored probe is reused only
/// while the model's computed bound is the one it was run at (a change to the bound
/// makes its line new). Returns every row of the map.
pub fn run_map(
    spec: &MapSpec,
    dir: &Path,
    observer: &mut dyn Observer,
    progress: &mut dyn FnMut(usize, usize, &MapRow),
    interrupt: &AtomicBool,
) -> Result<Vec<MapRow>, StudyError> {
    std::fs::create_dir_all(dir).map_err(|e| StudyError::io("creating", dir, e))?;
    let csv = csv_path(dir);
    let mut rows = read_rows(&csv)?;
    let points = spec.points();
    let mut packed: Option<PreparedSpecimen> = None;
    // The line being probed (the points come line by line): its specimen and its bound.
    let mut line: Option<(LineKey, PreparedSpecimen, f64)> = None;
    for (i, point) in points.iter().enumerate() {
        if line.as_ref().is_none_or(|(key, ..)| *key != point.line()) {
            if packed.is_none() {
                packed = Some(packing(dir, observer)?);
            }
            let prepared = probe_specimen(packed.as_ref().expect("prepared above"), point)?;
            let bound = probe_bound(&prepared)?.dt;
            line = Some((point.line(), prepared, bound));
        }
        let (_, prepared, bound) = line.as_ref().expect("set above");
        let (prepared, bound) = (prepared, *bound);
        if let Some(done) = rows.iter().find(|r| r.is_at(point) && r.bound == bound) {
            progress(i, points.len(), done);
            continue;
        }
        if interrupt.load(Ordering::SeqCst) {
            return Err(StudyError::Interrupted {
                run: "the stability map".into(),
            });
        }
        rows.retain(|r| !r.is_at(point));
        let outcome = probe(prepared, point.factor, spec.steps)?;
        let row = MapRow {
            model: point.variant.name().to_string(),
            order: order_name(point.variant.order).to_string(),
            dt_factor: point.factor,
            normal_penalty: point.penalty,
            damping: point.damping,
            class: outcome.class.name().to_string(),
            steps: outcome.steps,
            max_energy_error: outcome.max_energy_error,
            max_depth: outcome.max_depth,
            dt: outcome.dt,
            bound: outcome.bound,
            bound_source: outcome.bound_source,
            membrane_modulus: point.membrane_modulus,
        };
        progress(i, points.len(), &row);
        rows.push(row);
        write_atomically(&csv, csv_text(&rows)).map_err(|e| StudyError::io("writing", &csv, e))?;
    }
    // Only the rows of this map, in its order.
    let ordered: Vec<MapRow> = points
        .iter()
        .filter_map(|p| rows.iter().find(|r| r.is_at(p)).cloned())
        .collect();
    write_atomically(&csv, csv_text(&ordered)).map_err(|e| StudyError::io("writing", &csv, e))?;
    Ok(ordered)
}

/// The map's packing in the model, penalty, damping and membrane of `point`.
fn probe_specimen(
    base: &PreparedSpecimen,
    point: &MapPoint,
) -> Result<PreparedSpecimen, StudyError> {
    let mut prepared = base.in_model_and_order(point.variant.model, point.variant.order)?;
    prepared.spec.contact.normal_penalty = point.penalty;
    prepared.spec.contact.damping = point.damping;
    prepared.spec.membrane.youngs_modulus = point.membrane_modulus;
    Ok(prepared)
}

/// `dir/stability.csv`.
pub fn csv_path(dir: &Path) -> PathBuf {
    dir.join("stability.csv")
}

fn order_name(order: ElementOrder) -> &'static str {
    match order {
        ElementOrder::Linear => "linear",
        ElementOrder::Quadratic => "quadratic",
    }
}

/// A measured boundary within this fraction of the computed bound agrees with it.
pub const AGREEMENT: f64 = 0.10;

/// How the measured boundary of a line compares with the bound (factor 1).
fn agreement(last_finished: Option<f64>, first_failed: Option<f64>) -> String {
    match (last_finished, first_failed) {
        (_, Some(f)) if f < 1.0 - AGREEMENT => format!("fails below the bound (at {f})"),
        (Some(ok), _) if ok > 1.0 + AGREEMENT => {
            format!("conservative: stable to {ok} at least")
        }
        (Some(_), Some(_)) | (None, Some(_)) => "agrees within 10 %".into(),
        (Some(ok), None) => format!("conservative: stable to {ok} at least"),
        (None, None) => "no probes".into(),
    }
}

/// The measured critical step factor of one (model, penalty, damping) line: the largest
/// factor that finished below the smallest that did not, as `(last finished, first
/// failed)`; `None` where every probe finished or none did.
pub fn critical(rows: &[&MapRow]) -> (Option<f64>, Option<f64>) {
    let mut sorted: Vec<&&MapRow> = rows.iter().collect();
    sorted.sort_by(|a, b| a.dt_factor.total_cmp(&b.dt_factor));
    let failed = sorted.iter().find(|r| !r.finished()).map(|r| r.dt_factor);
    let finished = sorted
        .iter()
        .filter(|r| r.finished() && failed.is_none_or(|f| r.dt_factor < f))
        .map(|r| r.dt_factor)
        .next_back();
    (finished, failed)
}

/// The step safety factors the project uses by default, justified in STABILITY.md from
/// the measured critical factors: (what, factor).
fn project_safety_factors() -> [(&'static str, f64); 3] {
    [
        (
            "scenes (`simulation.dt_safety`)",
            fdem_solver::DEFAULT_DT_SAFETY,
        ),
        (
            "preparation (`preparation.dt_safety`)",
            fdem_triaxial::PreparationSection::default().dt_safety,
        ),
        (
            "the triaxial test (`test.dt_safety`)",
            fdem_triaxial::TEST_DT_SAFETY,
        ),
    ]
}

/// Colour and marker of each class in the charts.
fn class_style(class: &str) -> (fdem_core::plot::RGBColor, fdem_core::plot::Marker) {
    use fdem_core::plot::{Marker, RGBColor};
    match class {
        "stable" => (RGBColor(0, 158, 115), Marker::Circle),
        "slow_growth" => (RGBColor(230, 159, 0), Marker::Circle),
        "blow_up" => (RGBColor(213, 94, 0), Marker::Triangle),
        "penetration" => (RGBColor(204, 121, 167), Marker::Square),
        "tunnelling" => (RGBColor(0, 114, 178), Marker::Square),
        _ => (RGBColor(0, 0, 0), Marker::Triangle),
    }
}

const CLASSES: [&str; 6] = [
    "stable",
    "slow_growth",
    "blow_up",
    "penetration",
    "tunnelling",
    "non_finite",
];

/// One chart per model: the probes in the (penalty, step factor) plane at the map's
/// damping and in the (damping, step factor) plane at the paper's penalty, coloured by
/// class, with the computed bound (factor 1) drawn.
fn map_chart(rows: &[MapRow], spec: &MapSpec, model: &str, path: &Path) -> Result<(), StudyError> {
    use fdem_core::plot::{self as figure, Draw, IntoLogRange, SeriesLabelPosition, Style};
    const STYLE: Style = Style {
        caption_size: 18,
        margin: 15,
        x_label_area: 45,
        y_label_area: 60,
        light_lines: None,
        axis_desc_size: None,
        label_size: None,
        legend_size: Some(12),
    };
    let f_max = spec.dt_factors.iter().copied().fold(1.0, f64::max) * 1.1;
    let (p0, p1) = spec
        .penalties
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), p| (a.min(*p), b.max(*p)));
    // The penalty and damping sweeps, with the specimen's membrane (the membrane sweep is
    // in the table).
    let membrane = default_membrane_modulus();
    let ours: Vec<&MapRow> = rows
        .iter()
        .filter(|r| r.model == model && r.membrane_modulus == membrane)
        .collect();
    let svg = figure::svg((1200, 520), |root| {
        let (left, right) = root.split_horizontally(600);
        let mut chart = STYLE.chart(
            &left,
            &format!("{model}: step against penalty (damping {})", spec.damping),
            (p0 / 3.0..p1 * 3.0).log_scale(),
            0f64..f_max,
        )?;
        chart.draw_axes(&STYLE, "normal penalty (N/m^3)", "dt / computed bound")?;
        chart.draw_reference_line(
            (p0 / 3.0, 1.0),
            (p1 * 3.0, 1.0),
            figure::RGBColor(90, 90, 90),
        )?;
        for class in CLASSES {
            let points: Vec<(f64, f64, f64)> = ours
                .iter()
                .filter(|r| r.class == class && r.damping == spec.damping)
                .map(|r| (r.normal_penalty, r.dt_factor, 0.0))
                .collect();
            if !points.is_empty() {
                let (c, m) = class_style(class);
                chart.draw_markers(&points, c, m, Some(class))?;
            }
        }
        chart.draw_legend(&STYLE, SeriesLabelPosition::UpperRight)?;
        let mut chart = STYLE.chart(
            &right,
            &format!("{model}: step against damping (p_n = {PAPER_PENALTY:.1e})"),
            -0.05f64..1.05,
            0f64..f_max,
        )?;
        chart.draw_axes(&STYLE, "contact damping ratio beta", "dt / computed bound")?;
        chart.draw_reference_line((-0.05, 1.0), (1.05, 1.0), figure::RGBColor(90, 90, 90))?;
        for class in CLASSES {
            let points: Vec<(f64, f64, f64)> = ours
                .iter()
                .filter(|r| r.class == class && r.normal_penalty == PAPER_PENALTY)
                .map(|r| (r.damping, r.dt_factor, 0.0))
                .collect();
            if !points.is_empty() {
                let (c, m) = class_style(class);
                chart.draw_markers(&points, c, m, Some(class))?;
            }
        }
        chart.draw_legend(&STYLE, SeriesLabelPosition::UpperRight)
    })
    .map_err(|m| StudyError::file(path, format!("cannot be drawn: {m}")))?;
    write_atomically(path, svg).map_err(|e| StudyError::io("writing", path, e))
}

/// Writes `STABILITY.md` into `dir`, and `results/stability.csv` and one chart per model
/// (`results/stability_MODEL.svg`) beside it; returns the files written.
pub fn write_stability(
    rows: &[MapRow],
    spec: &MapSpec,
    limits: Option<(
        &[crate::limits::LimitPoint],
        &crate::limits::ElementComparison,
    )>,
    dir: &Path,
    command: &str,
) -> Result<Vec<PathBuf>, StudyError> {
    let data = dir.join("results");
    std::fs::create_dir_all(&data).map_err(|e| StudyError::io("creating", &data, e))?;
    let mut written = Vec::new();
    let csv = data.join("stability.csv");
    write_atomically(&csv, csv_text(rows)).map_err(|e| StudyError::io("writing", &csv, e))?;
    written.push(csv);
    let mut charts = Vec::new();
    for v in &spec.variants {
        let name = format!("stability_{}.svg", v.name());
        let path = data.join(&name);
        map_chart(rows, spec, v.name(), &path)?;
        written.push(path);
        charts.push(name);
    }
    let mut text = stability_markdown(rows, spec, command, &charts);
    if let Some((points, elements)) = limits {
        written.extend(crate::limits::write_limits(points, &data)?);
        text.push_str(&crate::limits::limits_markdown(points));
        text.push_str("![limits.svg](results/limits.svg)\n\n");
        text.push_str(&crate::limits::elements_markdown(elements));
    }
    let doc = dir.join("STABILITY.md");
    write_atomically(&doc, text).map_err(|e| StudyError::io("writing", &doc, e))?;
    written.push(doc);
    Ok(written)
}

/// One line of the map: (model, penalty, damping, membrane modulus) with its rows.
type Line<'a> = ((String, f64, f64, f64), Vec<&'a MapRow>);

/// The lines of the map.
fn lines(rows: &[MapRow]) -> Vec<Line<'_>> {
    let mut out: Vec<Line<'_>> = Vec::new();
    for r in rows {
        let key = (
            r.model.clone(),
            r.normal_penalty,
            r.damping,
            r.membrane_modulus,
        );
        match out.iter_mut().find(|(k, _)| *k == key) {
            Some((_, v)) => v.push(r),
            None => out.push((key, vec![r])),
        }
    }
    out
}

fn stability_markdown(rows: &[MapRow], spec: &MapSpec, command: &str, charts: &[String]) -> String {
    use std::fmt::Write as _;
    let mut d = String::new();
    let _ = writeln!(d, "# Stability maps: where the explicit step fails\n");
    let _ = writeln!(
        d,
        "Generated by `{command}`; the data is `results/stability.csv` (one row per probe). \
        \n"
    );
    let _ = writeln!(
        d,
        "**Method.** The quick specimen's packing (84 particles of 37.5 mm in a phi 150 x \
         225 mm cylinder) with the paper's particle material (E = {:.0} GPa) and penalty is \
         prepared once with rigid particles and put into each model at rest \
         (`PreparedSpecimen::in_model_and_order`); a probe at another penalty starts from \
         the same places (its overlaps then carry that penalty's forces: one more \
         transient; a preparation at the softest penalty takes steps so long that its \
         compaction tunnels). Each probe builds the triaxial test's \
         model around it (particles, membrane, platens), sets the step to a multiple of the \
         model's computed stable bound (the elastic bound of each body combined with the \
         contact springs', or the membrane's combined with the smaller of the contact \
         springs' and the membrane nodes' two-sided contact bound, if smaller; \
         docs/MODEL.md section 11), applies \
         the full confining pressure at once (a load step that excites every mode) and \
         runs {} steps with the platens held. The penalty and damping sweeps use the \
         specimen's membrane ({:.0} MPa); one more line per model takes a latex-like \
         membrane at the paper's penalty. Classes: `stable` (every step done, energy \
         balance error at most {:.0} % of its scale), `slow_growth` (done, error between \
         that and the guard's 5 %), `blow_up` (the guard stopped it), `penetration` (a \
         contact deeper than half the depth limit, grown to its cap), `tunnelling` (a node \
         moving farther in a step than half the margin relative to the membrane or half \
         the depth limit relative to a particle or platen, or a particle leaving the \
         membrane), `non_finite`.\n",
        PAPER_MODULUS / 1e9,
        spec.steps,
        default_membrane_modulus() / 1e6,
        100.0 * fdem_triaxial::STABLE_ENERGY_ERROR
    );
    let _ = writeln!(d, "## Measured critical step factor\n");
    let _ = writeln!(
        d,
        "Per line of the map: the largest factor that finished below the smallest that \
         failed (the boundary lies between them), what stopped the first failure, and what \
         sets the computed bound. The prediction is 1 (the bound itself).\n"
    );
    let _ = writeln!(
        d,
        "| model | penalty (N/m^3) | damping | membrane (MPa) | last finished | first failed (class) | against the bound | bound (s) | set by |"
    );
    let _ = writeln!(d, "|---|---|---|---|---|---|---|---|---|");
    for ((model, p, b, e), line) in lines(rows) {
        let (ok, failed) = critical(&line);
        let failed_class = failed
            .and_then(|f| line.iter().find(|r| r.dt_factor == f))
            .map_or(String::new(), |r| format!(" ({})", r.class));
        let bound = line.first().map_or(f64::NAN, |r| r.bound);
        let source = line.first().map_or("", |r| r.bound_source.as_str());
        let source: String = source.chars().take(90).collect();
        let _ = writeln!(
            d,
            "| {model} | {p:.1e} | {b} | {} | {} | {}{failed_class} | {} | {bound:.3e} | {source} |",
            e / 1e6,
            ok.map_or("none".into(), |f| format!("{f}")),
            failed.map_or("none".into(), |f| format!("{f}")),
            agreement(ok, failed),
        );
    }
    let _ = writeln!(d);
    let _ = writeln!(
        d,
        "Where the boundary lies more than {:.0} % from the bound, the bound's assumptions are \
         the places to look: it is computed for undamped springs (the contact springs' \
         damping ratio enters through the closed form of a damped oscillator, the \
         membrane's viscous damping and speed limiter not at all), the elastic and contact \
         bounds of a body are combined by Weyl's inequality (a sum of the largest \
         eigenvalues, larger than the largest eigenvalue of the sum), each body's elastic \
         bound comes from a power iteration on that body alone, a rigid body's contact \
         springs use its effective mass at the node, rotation included, the membrane \
         nodes' contact counts their own spring and at most one node's worth of the \
         particles' springs pressing their faces (Gershgorin's row bound), and the \
         membrane's bound is its stiffest element's. Each of these makes the bound smaller than the \
         true limit (conservative), never larger, with one exception: the springs that act \
         together on one rigid body add up, which the model's bound does not count (a run \
         with an automatic step follows their network's estimated frequency, docs/MODEL.md \
         section 12; the probes keep the step they were given). Otherwise a failure below \
         the bound would be a bug in the bound, or a failure that is not a step-size \
         instability (penetration under too soft a penalty, tunnelling of a fast \
         transient).\n",
        100.0 * AGREEMENT
    );
    let _ = writeln!(d, "## Where each method fails\n");
    for v in &spec.variants {
        let model = v.name();
        let ours: Vec<&MapRow> = rows.iter().filter(|r| r.model == model).collect();
        let below: Vec<&&MapRow> = ours.iter().filter(|r| r.dt_factor < 1.0).collect();
        let below_ok = below.iter().filter(|r| r.finished()).count();
        let above: Vec<&&MapRow> = ours.iter().filter(|r| r.dt_factor > 1.0).collect();
        let above_failed = above.iter().filter(|r| !r.finished()).count();
        let mut classes: Vec<String> = Vec::new();
        for c in CLASSES {
            let n = ours.iter().filter(|r| r.class == c).count();
            if n > 0 {
                classes.push(format!("{c} {n}"));
            }
        }
        let _ = writeln!(
            d,
            "- **{model}**: below the bound {below_ok} of {} probes finished; above it {above_failed} of {} failed. Classes over the map: {}.",
            below.len(),
            above.len(),
            classes.join(", ")
        );
    }
    let _ = writeln!(d);
    let _ = writeln!(d, "## The project's safety factors\n");
    let all = lines(rows);
    for (what, factor) in project_safety_factors() {
        let below: Vec<String> = all
            .iter()
            .filter_map(|((model, p, b, e), line)| {
                let failed = critical(line).1?;
                (failed <= factor).then(|| {
                    format!(
                        "{model} at p_n = {p:.1e}, beta = {b}, membrane {} MPa (fails at {failed})",
                        e / 1e6
                    )
                })
            })
            .collect();
        let _ = writeln!(
            d,
            "- {what}: {factor} of the computed bound; {}.",
            if below.is_empty() {
                "every line of the map finished at and below it".to_string()
            } else {
                format!(
                    "lines of the map that fail at or below it: {}",
                    below.join("; ")
                )
            }
        );
    }
    let _ = writeln!(d, "\n## Charts\n");
    for c in charts {
        let _ = writeln!(d, "![{c}](results/{c})\n");
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(f: f64, class: &str) -> MapRow {
        MapRow {
            model: "rigid".into(),
            order: "linear".into(),
            dt_factor: f,
            normal_penalty: 1.8e11,
            damping: 0.2,
            class: class.into(),
            steps: 10,
            max_energy_error: 0.0,
            max_depth: 0.0,
            dt: 1e-6,
            bound: 1e-6,
            bound_source: "contact: \"node\" 3".into(),
            membrane_modulus: 40e6,
        }
    }

    #[test]
    fn the_critical_factor_lies_between_the_last_finished_and_the_first_failed() {
        let rows = [
            row(1.5, "blow_up"),
            row(0.9, "stable"),
            row(1.1, "slow_growth"),
            row(2.0, "non_finite"),
        ];
        let refs: Vec<&MapRow> = rows.iter().collect();
        assert_eq!(critical(&refs), (Some(1.1), Some(1.5)));
        let stable = [row(0.5, "stable")];
        assert_eq!(
            critical(&stable.iter().collect::<Vec<_>>()),
            (Some(0.5), None)
        );
    }

    #[test]
    fn rows_survive_the_csv_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let rows = vec![row(0.9, "stable"), row(2.0, "blow_up")];
        let path = csv_path(dir.path());
        write_atomically(&path, csv_text(&rows)).unwrap();
        let back = read_rows(&path).unwrap();
        assert_eq!(back.len(), 2);
        assert_eq!(back[1].class, "blow_up");
        assert_eq!(back[0].dt_factor, 0.9);
        assert_eq!(back[0].bound_source, "contact: 'node' 3");
        assert_eq!(back[1].membrane_modulus, 40e6);
        // A map written before the membrane column reads with the specimen's membrane.
        let old: String = csv_text(&rows)
            .lines()
            .map(|l| l.rsplit_once(',').unwrap().0.to_string() + "\n")
            .collect();
        write_atomically(&path, old).unwrap();
        let back = read_rows(&path).unwrap();
        assert_eq!(back[0].bound_source, "contact: 'node' 3");
        assert_eq!(back[0].membrane_modulus, default_membrane_modulus());
    }

    #[test]
    fn the_full_map_sweeps_every_axis() {
        let m = MapSpec::full();
        let lines = m.penalties.len() + m.dampings.len() - 1 + m.membrane_moduli.len();
        let n = m.variants.len() * lines * m.dt_factors.len();
        assert_eq!(m.points().len(), n);
        let soft = m
            .points()
            .iter()
            .filter(|p| p.membrane_modulus < 40e6)
            .count();
        assert_eq!(soft, m.variants.len() * m.dt_factors.len());
        assert!(
            m.dt_factors.contains(&1.0) && m.dampings.contains(&0.0) && m.dampings.contains(&1.0)
        );
        let decades = (m.penalties.last().unwrap() / m.penalties[0]).log10();
        assert!(decades >= 3.0 - 1e-9);
    }
}
