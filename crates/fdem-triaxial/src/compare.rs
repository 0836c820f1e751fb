//! Several finished tests side by side: their curves on one chart, and their results and
//! costs in one table against the first run (`fdem compare`).

use crate::TriaxialError;
use crate::measure::{CurvePoint, CurveSummary, read_curve, summarize};
use crate::plot::{CurvePlot, CurveSeries, plot_curves};
use std::path::{Path, PathBuf};

/// The residual window of the comparison: the last 2 % of axial strain, as in the tests'
/// own summaries.
const RESIDUAL_WINDOW: f64 = 0.02;

/// One finished test, read back from its output directory.
#[derive(Clone, Debug)]
pub struct FinishedRun {
    /// Legend entry.
    pub label: String,
    /// The run's directory.
    pub dir: PathBuf,
    /// The model the run used (`summary.json`'s `model`; `unknown` for older runs).
    pub model: String,
    /// The rows of its `curve.csv`.
    pub curve: Vec<CurvePoint>,
    /// Peak, residual and final strains of the curve.
    pub summary: CurveSummary,
    /// Wall and CPU seconds of consolidation and shear, and the shear's steps.
    pub cost: RunCost,
}

/// What a run cost, from its `summary.json`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RunCost {
    /// Consolidation steps.
    pub consolidation_steps: u64,
    /// Consolidation wall seconds.
    pub consolidation_wall: f64,
    /// Consolidation CPU seconds (NaN where the platform did not report them).
    pub consolidation_cpu: f64,
    /// Shear steps.
    pub shear_steps: u64,
    /// Shear wall seconds.
    pub shear_wall: f64,
    /// Shear CPU seconds (NaN where not reported).
    pub shear_cpu: f64,
}

impl RunCost {
    /// The costs a test's `summary.json` (parsed as `summary`) records: NaN seconds and
    /// zero steps for what it does not hold.
    pub fn of_summary(summary: &serde_json::Value) -> RunCost {
        let value = |path: &[&str]| path.iter().try_fold(summary, |v, k| v.get(k));
        let seconds = |path: &[&str]| {
            value(path)
                .and_then(serde_json::Value::as_f64)
                .unwrap_or(f64::NAN)
        };
        let steps = |path: &[&str]| value(path).and_then(serde_json::Value::as_u64).unwrap_or(0);
        RunCost {
            consolidation_steps: steps(&["consolidation", "cost", "steps"]),
            consolidation_wall: seconds(&["consolidation", "cost", "wall_seconds"]),
            consolidation_cpu: seconds(&["consolidation", "cost", "cpu_seconds"]),
            shear_steps: steps(&["shear", "steps"]),
            shear_wall: seconds(&["shear", "wall_seconds"]),
            shear_cpu: seconds(&["shear", "cpu_seconds"]),
        }
    }
}

fn file_error(path: &Path, message: String) -> TriaxialError {
    TriaxialError::File {
        path: path.to_path_buf(),
        message,
    }
}

impl FinishedRun {
    /// Reads `curve.csv` and `summary.json` of the test in `dir`.
    ///
    /// # Errors
    /// A missing or unreadable file, or a curve without rows, named with its path.
    pub fn load(label: &str, dir: &Path) -> Result<FinishedRun, TriaxialError> {
        let curve_path = dir.join("curve.csv");
        let curve = read_curve(&curve_path).map_err(|e| file_error(&curve_path, e.to_string()))?;
        let summary = summarize(&curve, RESIDUAL_WINDOW).ok_or_else(|| {
            file_error(
                &curve_path,
                "has no rows; the test did not reach the shear".into(),
            )
        })?;
        let summary_path = dir.join("summary.json");
        let text = std::fs::read_to_string(&summary_path).map_err(|cause| TriaxialError::Io {
            action: "reading",
            path: summary_path.clone(),
            cause,
        })?;
        let json: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| file_error(&summary_path, format!("is not JSON: {e}")))?;
        let cost = RunCost::of_summary(&json);
        let model = json
            .get("model")
            .and_then(serde_json::Value::as_str)
            .unwrap_or("unknown")
            .to_string();
        Ok(FinishedRun {
            label: label.to_string(),
            dir: dir.to_path_buf(),
            model,
            curve,
            summary,
            cost,
        })
    }
}

/// Header of `comparison.csv`: one row per run; `d_*` are differences from the first
/// run, `speedup` the first run's shear wall time over this one's.
pub const COMPARISON_HEADER: &str = "label,model,peak_eta,eps_a_at_peak,residual_eta,final_eps_a,final_eps_v,\
d_peak_eta,d_eps_a_at_peak,d_residual_eta,d_final_eps_v,consolidation_wall_s,consolidation_cpu_s,\
shear_steps,shear_wall_s,shear_cpu_s,speedup";

/// One row of `comparison.csv` for `run` against `first`.
pub fn comparison_row(run: &FinishedRun, first: &FinishedRun) -> String {
    let (s, f, c) = (&run.summary, &first.summary, &run.cost);
    format!(
        "{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.3},{:.3},{},{:.3},{:.3},{:.3}",
        run.label,
        run.model,
        s.peak_eta,
        s.eps_a_at_peak,
        s.residual_eta,
        s.final_eps_a,
        s.final_eps_v,
        s.peak_eta - f.peak_eta,
        s.eps_a_at_peak - f.eps_a_at_peak,
        s.residual_eta - f.residual_eta,
        s.final_eps_v - f.final_eps_v,
        c.consolidation_wall,
        c.consolidation_cpu,
        c.shear_steps,
        c.shear_wall,
        c.shear_cpu,
        first.cost.shear_wall / c.shear_wall
    )
}

/// Writes `eta.svg`, `eps_v.svg` (every run's curve, labelled) and `comparison.csv` into
/// `out` (created if missing), each atomically; returns the table's rows.
///
/// # Errors
/// Fewer than one run, a label with a comma or quote, or a file that cannot be written.
pub fn write_comparison(
    runs: &[FinishedRun],
    out: &Path,
    title: &str,
) -> Result<Vec<String>, TriaxialError> {
    let Some(first) = runs.first() else {
        return Err(file_error(
            out,
            "nothing to compare; give at least one run".into(),
        ));
    };
    if let Some(r) = runs.iter().find(|r| r.label.contains([',', '"', '\n'])) {
        return Err(file_error(
            &r.dir,
            format!(
                "label {:?} holds a comma, quote or newline; choose another",
                r.label
            ),
        ));
    }
    std::fs::create_dir_all(out).map_err(|cause| TriaxialError::Io {
        action: "creating",
        path: out.to_path_buf(),
        cause,
    })?;
    let series: Vec<CurveSeries<'_>> = runs
        .iter()
        .map(|r| CurveSeries {
            label: &r.label,
            points: &r.curve,
        })
        .collect();
    for (file, kind, what) in [
        ("eta.svg", CurvePlot::StressRatio, "stress ratio"),
        (
            "eps_v.svg",
            CurvePlot::VolumetricStrain,
            "volumetric strain",
        ),
    ] {
        plot_curves(&out.join(file), kind, &format!("{title}: {what}"), &series)
            .map_err(|e| file_error(&out.join(file), e.to_string()))?;
    }
    let rows: Vec<String> = runs.iter().map(|r| comparison_row(r, first)).collect();
    let text = format!("{COMPARISON_HEADER}\n{}\n", rows.join("\n"));
    let path = out.join("comparison.csv");
    fdem_core::fs::write_atomically(&path, &text).map_err(|cause| TriaxialError::Io {
        action: "writing",
        path,
        cause,
    })?;
    Ok(rows)
}
