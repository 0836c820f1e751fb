//! Accuracy: what each run measured (the curve's landmarks and the peak's contact
//! forces) and how far it lies from its series' original, with the spread over seeds.

use crate::StudyError;
use fdem_micro::{AnalysisOptions, Histogram, SnapshotChoice, analyse, locate_snapshot};
use fdem_triaxial::{CurvePoint, read_curve, summarize};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The residual window: the last 2 % of axial strain, as in the tests' own summaries.
pub const RESIDUAL_WINDOW: f64 = 0.02;
/// The initial tangent modulus is the least-squares slope of `q(eps_a)` over the first
/// this much axial strain (with the curve's first point).
pub const INITIAL_WINDOW: f64 = 0.01;
/// Points of the common strain grid on which two curves are compared.
const GRID_POINTS: usize = 200;

/// What one run measured.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RunMetrics {
    /// Peak stress ratio eta.
    pub peak_eta: f64,
    /// Axial strain at the peak.
    pub eps_a_peak: f64,
    /// Mean eta over the residual window.
    pub residual_eta: f64,
    /// Volumetric strain at the end of the shear (positive: contraction).
    pub eps_v_final: f64,
    /// Axial strain at the end of the shear.
    pub eps_a_final: f64,
    /// Initial tangent modulus `dq/deps_a` over [`INITIAL_WINDOW`] (Pa).
    pub initial_modulus: f64,
    /// Largest contraction (largest volumetric strain).
    pub max_contraction: f64,
    /// Dilatancy onset: the axial strain of the largest contraction, where `eps_v`
    /// turns.
    pub dilatancy_onset: f64,
    /// Mean normal contact force at the peak (N), from the clustered particle contacts.
    pub mean_normal_force: f64,
    /// Share of contacts above 4 times the mean.
    pub strong_share: f64,
    /// Share of contacts below 0.2 times the mean.
    pub weak_share: f64,
    /// Particle contacts at the peak.
    pub contacts: usize,
    /// Coordination number at the peak.
    pub coordination_number: f64,
}

/// A run's curve, metrics and force distribution, read from its directory.
#[derive(Clone, Debug)]
pub struct Measured {
    /// `curve.csv`'s rows.
    pub curve: Vec<CurvePoint>,
    /// The landmarks.
    pub metrics: RunMetrics,
    /// The distribution of `F_n / mean(F_n)` at the peak.
    pub histogram: Histogram,
    /// The energy balance error of the consolidation and of the shear, each over its
    /// phase's energy scale (`summary.json`; NaN where it does not say).
    pub energy_balance: [f64; 2],
}

impl Measured {
    /// Whether both phases closed their energy balance (error at most
    /// [`fdem_triaxial::STABLE_ENERGY_ERROR`] of the scale): a run whose balance does not
    /// close has its numbers reported, and flagged.
    pub fn balance_closed(&self) -> bool {
        closes(self.energy_balance)
    }
}

/// Whether every phase's balance error is known and at most
/// [`fdem_triaxial::STABLE_ENERGY_ERROR`].
fn closes(balance: [f64; 2]) -> bool {
    balance
        .iter()
        .all(|e| *e <= fdem_triaxial::STABLE_ENERGY_ERROR)
}

/// The energy balance errors `[consolidation, shear]` of the run in `dir`, from its
/// `summary.json` (NaN for what it does not hold).
fn energy_balance(dir: &Path) -> [f64; 2] {
    let Some(s) = crate::run::read_summary(&dir.join("summary.json")) else {
        return [f64::NAN; 2];
    };
    [
        &s["consolidation"]["energy_balance_error"],
        &s["energy_balance_error"],
    ]
    .map(|v| v.as_f64().unwrap_or(f64::NAN))
}

/// The contact forces at the peak, clustered into particle contacts by `fdem-micro`;
/// kept in the run's record so that the (large) snapshot is not needed again.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PeakContacts {
    /// Mean normal contact force (N).
    pub mean_normal_force: f64,
    /// Share of contacts above 4 times the mean.
    pub strong_share: f64,
    /// Share of contacts below 0.2 times the mean.
    pub weak_share: f64,
    /// Particle contacts.
    pub contacts: usize,
    /// Coordination number.
    pub coordination_number: f64,
    /// The distribution of `F_n / mean(F_n)`.
    pub histogram: Histogram,
}

/// Clusters the peak snapshot of the test in `dir` (`contacts_peak.csv`).
pub fn peak_contacts(dir: &Path, particles: usize) -> Result<PeakContacts, StudyError> {
    let files = locate_snapshot(dir, SnapshotChoice::Peak)?;
    let analysis = analyse(
        &files,
        &AnalysisOptions {
            particles: Some(particles),
            ..AnalysisOptions::default()
        },
    )?;
    let s = analysis.statistics;
    Ok(PeakContacts {
        mean_normal_force: s.mean_normal_force,
        strong_share: s.strong_share,
        weak_share: s.weak_share,
        contacts: s.contacts,
        coordination_number: s.coordination_number,
        histogram: s.histogram,
    })
}

/// Reads a finished run's `curve.csv` and takes its contacts at the peak from `peak`.
pub fn measure(dir: &Path, peak: &PeakContacts) -> Result<Measured, StudyError> {
    let path = dir.join("curve.csv");
    let curve = read_curve(&path).map_err(|e| StudyError::file(&path, e.to_string()))?;
    let summary = summarize(&curve, RESIDUAL_WINDOW)
        .ok_or_else(|| StudyError::file(&path, "has no rows; the test did not reach the shear"))?;
    Ok(Measured {
        metrics: RunMetrics {
            peak_eta: summary.peak_eta,
            eps_a_peak: summary.eps_a_at_peak,
            residual_eta: summary.residual_eta,
            eps_v_final: summary.final_eps_v,
            eps_a_final: summary.final_eps_a,
            initial_modulus: initial_modulus(&curve),
            max_contraction: summary.max_contraction,
            dilatancy_onset: summary.eps_a_at_max_contraction,
            mean_normal_force: peak.mean_normal_force,
            strong_share: peak.strong_share,
            weak_share: peak.weak_share,
            contacts: peak.contacts,
            coordination_number: peak.coordination_number,
        },
        histogram: peak.histogram.clone(),
        curve,
        energy_balance: energy_balance(dir),
    })
}

/// The least-squares slope of `q` over `eps_a` for the points with `eps_a <=`
/// [`INITIAL_WINDOW`] (NaN with fewer than two distinct strains).
pub fn initial_modulus(curve: &[CurvePoint]) -> f64 {
    let points: Vec<(f64, f64)> = curve
        .iter()
        .filter(|p| p.eps_a <= INITIAL_WINDOW && p.eps_a.is_finite() && p.q.is_finite())
        .map(|p| (p.eps_a, p.q))
        .collect();
    least_squares_slope(&points)
}

fn least_squares_slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    if points.len() < 2 {
        return f64::NAN;
    }
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    if sxx > 0.0 { sxy / sxx } else { f64::NAN }
}

/// Linear interpolation of `(eps_a, value)` at `x` (points sorted by `eps_a`); `None`
/// outside their range.
fn interpolate(points: &[(f64, f64)], x: f64) -> Option<f64> {
    let k = points.partition_point(|p| p.0 < x);
    if k == 0 {
        return (points.first()?.0 == x).then(|| points[0].1);
    }
    let (a, b) = (points[k - 1], *points.get(k)?);
    if b.0 == a.0 {
        return Some(b.1);
    }
    Some(a.1 + (b.1 - a.1) * (x - a.0) / (b.0 - a.0))
}

/// The root-mean-square difference of two curves `value(eps_a)` over their common
/// strain range, on a uniform grid of [`GRID_POINTS`] (NaN without a common range).
pub fn rms_difference(a: &[CurvePoint], b: &[CurvePoint], value: fn(&CurvePoint) -> f64) -> f64 {
    let series = |c: &[CurvePoint]| {
        let mut p: Vec<(f64, f64)> = c
            .iter()
            .map(|p| (p.eps_a, value(p)))
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .collect();
        p.sort_by(|x, y| x.0.total_cmp(&y.0));
        p
    };
    let (a, b) = (series(a), series(b));
    let (Some(a0), Some(b0), Some(a1), Some(b1)) = (a.first(), b.first(), a.last(), b.last())
    else {
        return f64::NAN;
    };
    let (lo, hi) = (a0.0.max(b0.0), a1.0.min(b1.0));
    if hi <= lo {
        return f64::NAN;
    }
    let mut sum = 0.0;
    for i in 0..GRID_POINTS {
        let x = lo + (hi - lo) * i as f64 / (GRID_POINTS - 1) as f64;
        let (Some(ya), Some(yb)) = (interpolate(&a, x), interpolate(&b, x)) else {
            return f64::NAN;
        };
        sum += (ya - yb) * (ya - yb);
    }
    (sum / GRID_POINTS as f64).sqrt()
}

/// How far one run lies from its reference. Relative errors are signed
/// `(run - reference) / reference`; strains are signed differences.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Errors {
    /// Relative error of the peak eta.
    pub peak_eta: f64,
    /// Difference of the axial strain at the peak.
    pub eps_a_peak: f64,
    /// Relative error of the residual eta.
    pub residual_eta: f64,
    /// Difference of the final volumetric strain.
    pub eps_v_final: f64,
    /// RMS difference of eta(eps_a).
    pub rms_eta: f64,
    /// RMS difference of eps_v(eps_a).
    pub rms_eps_v: f64,
    /// Relative error of the initial tangent modulus.
    pub initial_modulus: f64,
    /// Difference of the dilatancy onset.
    pub dilatancy_onset: f64,
    /// Ratio of the mean normal contact forces (run over reference; h^2 expected).
    pub mean_force_ratio: f64,
    /// Difference of the strong-contact share.
    pub strong_share: f64,
    /// Difference of the weak-contact share.
    pub weak_share: f64,
}

/// The errors of `run` against `reference`.
pub fn errors(run: &Measured, reference: &Measured) -> Errors {
    let (m, r) = (&run.metrics, &reference.metrics);
    let rel = |a: f64, b: f64| (a - b) / b;
    Errors {
        peak_eta: rel(m.peak_eta, r.peak_eta),
        eps_a_peak: m.eps_a_peak - r.eps_a_peak,
        residual_eta: rel(m.residual_eta, r.residual_eta),
        eps_v_final: m.eps_v_final - r.eps_v_final,
        rms_eta: rms_difference(&run.curve, &reference.curve, |p| p.eta),
        rms_eps_v: rms_difference(&run.curve, &reference.curve, |p| p.eps_v),
        initial_modulus: rel(m.initial_modulus, r.initial_modulus),
        dilatancy_onset: m.dilatancy_onset - r.dilatancy_onset,
        mean_force_ratio: m.mean_normal_force / r.mean_normal_force,
        strong_share: m.strong_share - r.strong_share,
        weak_share: m.weak_share - r.weak_share,
    }
}

/// Mean and sample standard deviation (0 for one value; NaN for none). Non-finite
/// values are left out.
pub fn mean_and_spread(values: impl IntoIterator<Item = f64>) -> (f64, f64) {
    let v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    if v.len() == 1 {
        return (mean, 0.0);
    }
    let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

#[cfg(test)]
mod tests {
    /// The balance of both phases comes from `summary.json`; a run closes it when both
    /// are known and at most 1 % of their scales.
    #[test]
    fn a_run_closes_its_balance_only_when_both_phases_do() {
        let dir = tempfile::tempdir().unwrap();
        assert!(energy_balance(dir.path()).iter().all(|e| e.is_nan()));
        std::fs::write(
            dir.path().join("summary.json"),
            r#"{"consolidation": {"energy_balance_error": 1.5e-4}, "energy_balance_error": 0.2}"#,
        )
        .unwrap();
        let balance = energy_balance(dir.path());
        assert_eq!(balance, [1.5e-4, 0.2]);
        assert!(!closes(balance));
        assert!(closes([1.5e-4, 9.7e-3]));
        assert!(!closes([f64::NAN, 1e-4]));
    }

    use super::*;

    fn point(eps_a: f64, eta: f64, eps_v: f64, q: f64) -> CurvePoint {
        CurvePoint {
            time: 0.0,
            eps_a,
            eps_v,
            sigma_a: 0.0,
            eta,
            height: 1.0,
            volume: 1.0,
            axial_force: 0.0,
            p: 1.0,
            q,
            kinetic_energy: 0.0,
            unbalanced_force: 0.0,
            energy_error: 0.0,
            max_depth: 0.0,
            contacts: 0,
            step: 0,
            sigma_r: f64::NAN,
            eta_measured: f64::NAN,
            hoop_strain: f64::NAN,
            draped_volume: f64::NAN,
            eps_v_specimen: f64::NAN,
        }
    }

    #[test]
    fn a_curve_against_itself_has_zero_difference_and_a_shift_its_size() {
        let a: Vec<CurvePoint> = (0..=30)
            .map(|i| {
                let x = i as f64 * 0.005;
                point(x, (20.0 * x).sin(), -x * x, 1e8 * x)
            })
            .collect();
        assert_eq!(rms_difference(&a, &a, |p| p.eta), 0.0);
        let shifted: Vec<CurvePoint> = a
            .iter()
            .map(|p| point(p.eps_a, p.eta + 0.25, p.eps_v, p.q))
            .collect();
        let d = rms_difference(&shifted, &a, |p| p.eta);
        assert!((d - 0.25).abs() < 1e-12, "{d}");
        // Different grids: the comparison interpolates; a linear curve is exact.
        let coarse: Vec<CurvePoint> = (0..=6)
            .map(|i| point(i as f64 * 0.025, 0.0, -0.1 * i as f64 * 0.025, 0.0))
            .collect();
        let fine: Vec<CurvePoint> = (0..=150)
            .map(|i| point(i as f64 * 0.001, 0.0, -0.1 * i as f64 * 0.001, 0.0))
            .collect();
        assert!(rms_difference(&coarse, &fine, |p| p.eps_v) < 1e-15);
    }

    #[test]
    fn the_initial_modulus_is_the_slope_over_the_first_percent() {
        let c: Vec<CurvePoint> = (0..=20)
            .map(|i| {
                let x = i as f64 * 0.0025;
                // 2e8 Pa per unit strain up to 1 %, flat after.
                point(x, 0.0, 0.0, 2e8 * x.min(0.01))
            })
            .collect();
        assert!((initial_modulus(&c) - 2e8).abs() < 1e-3);
        assert!(initial_modulus(&c[..1]).is_nan());
    }

    #[test]
    fn mean_and_spread_are_the_sample_statistics() {
        let (m, s) = mean_and_spread([1.0, 2.0, 3.0, f64::NAN]);
        assert_eq!(m, 2.0);
        assert!((s - 1.0).abs() < 1e-15);
        assert_eq!(mean_and_spread([4.0]), (4.0, 0.0));
        assert!(mean_and_spread([]).0.is_nan());
    }
}
