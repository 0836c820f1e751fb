//! The measurements of the triaxial test (paper eqs 12-15) and the shear curve.
//!
//! This module owns the conversion of raw specimen state (height, volume, axial force)
//! into the paper's strains and stresses, one row of `curve.csv` ([`CurvePoint`]), the
//! writing ([`CurveWriter`]) and reading ([`read_curve`]) of that file, the summary of a
//! curve ([`summarize`]) and the running peak detector ([`PeakTracker`]).
//!
//! Sign convention of the paper: compression positive, contraction positive. Strains are
//! logarithmic (true) strains, so they stay additive at large deformation.

use serde::{Deserialize, Serialize};
use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Eq 12: axial strain `eps_l = -ln(H / H0)` (logarithmic; shortening is positive).
pub fn axial_strain(h0: f64, h: f64) -> f64 {
    -(h / h0).ln()
}

/// Eq 13: volumetric strain `eps_v = -ln(V / V0)` (logarithmic; contraction is positive).
pub fn volumetric_strain(v0: f64, v: f64) -> f64 {
    -(v / v0).ln()
}

/// Eq 14: axial stress `sigma_l = F_l / A` with the mean cross-section area `A = V / H`.
pub fn axial_stress(force: f64, volume: f64, height: f64) -> f64 {
    force * height / volume
}

/// Eq 15: stress ratio `eta = q / p = 3 (sigma_l - sigma_0) / (sigma_l + 2 sigma_0)`.
///
/// Zero in the isotropic state, tending to 3 as `sigma_l` grows without bound; not finite
/// when `p = 0`.
pub fn stress_ratio(sigma_l: f64, sigma_0: f64) -> f64 {
    3.0 * (sigma_l - sigma_0) / (sigma_l + 2.0 * sigma_0)
}

/// The raw state of the specimen at one instant of the shear stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// Simulated time (s).
    pub time: f64,
    /// Specimen height `H`, platen to platen (m).
    pub height: f64,
    /// Specimen volume `V` enclosed by membrane and platens (m^3).
    pub volume: f64,
    /// Axial force `F_l` on the platens, compression positive (N).
    pub axial_force: f64,
    /// Total kinetic energy (J).
    pub kinetic_energy: f64,
    /// Unbalanced force ratio (-).
    pub unbalanced_force: f64,
    /// Energy-balance error over the guard's energy scale (-).
    pub energy_error: f64,
    /// Deepest node contact (m).
    pub max_depth: f64,
    /// Number of node contacts.
    pub contacts: u64,
    /// Time step index.
    pub step: u64,
}

/// The reference state of the shear stage: the end of isotropic consolidation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Reference {
    /// Height `H0` at the start of shear (m).
    pub h0: f64,
    /// Volume `V0` at the start of shear (m^3).
    pub v0: f64,
    /// Confining pressure `sigma_0` (Pa).
    pub sigma_0: f64,
}

/// One row of `curve.csv`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct CurvePoint {
    /// Simulated time (s).
    pub time: f64,
    /// Axial strain, eq 12 (-).
    pub eps_a: f64,
    /// Volumetric strain, eq 13 (-).
    pub eps_v: f64,
    /// Axial stress, eq 14 (Pa).
    pub sigma_a: f64,
    /// Stress ratio `q/p`, eq 15 (-).
    pub eta: f64,
    /// Specimen height (m).
    pub height: f64,
    /// Specimen volume (m^3).
    pub volume: f64,
    /// Axial force (N).
    pub axial_force: f64,
    /// Mean stress `(sigma_l + 2 sigma_0) / 3` (Pa).
    pub p: f64,
    /// Deviator stress `sigma_l - sigma_0` (Pa).
    pub q: f64,
    /// Total kinetic energy (J).
    pub kinetic_energy: f64,
    /// Unbalanced force ratio (-).
    pub unbalanced_force: f64,
    /// Energy-balance error over the stability guard's energy scale (-): bookkeeping
    /// drift stays at percents; an instability grows without bound.
    pub energy_error: f64,
    /// Deepest node contact (m), against half the contact depth limit.
    pub max_depth: f64,
    /// Number of node contacts.
    pub contacts: u64,
    /// Time step index.
    pub step: u64,
}

impl CurvePoint {
    /// Applies eqs 12-15 to a measurement relative to the start of shear.
    pub fn from_measurement(m: &Measurement, reference: &Reference) -> CurvePoint {
        let sigma_a = axial_stress(m.axial_force, m.volume, m.height);
        let s0 = reference.sigma_0;
        CurvePoint {
            time: m.time,
            eps_a: axial_strain(reference.h0, m.height),
            eps_v: volumetric_strain(reference.v0, m.volume),
            sigma_a,
            eta: stress_ratio(sigma_a, s0),
            height: m.height,
            volume: m.volume,
            axial_force: m.axial_force,
            p: (sigma_a + 2.0 * s0) / 3.0,
            q: sigma_a - s0,
            kinetic_energy: m.kinetic_energy,
            unbalanced_force: m.unbalanced_force,
            energy_error: m.energy_error,
            max_depth: m.max_depth,
            contacts: m.contacts,
            step: m.step,
        }
    }

    /// The real columns in [`CURVE_HEADER`] order (all but `contacts` and `step`).
    #[rustfmt::skip]
    fn reals(&self) -> [f64; 14] {
        [self.time, self.eps_a, self.eps_v, self.sigma_a, self.eta, self.height, self.volume,
         self.axial_force, self.p, self.q, self.kinetic_energy, self.unbalanced_force,
         self.energy_error, self.max_depth]
    }

    #[rustfmt::skip]
    fn from_columns(r: [f64; 14], contacts: u64, step: u64) -> CurvePoint {
        let [time, eps_a, eps_v, sigma_a, eta, height, volume, axial_force, p, q, ke, uf, ee,
             md] = r;
        CurvePoint { time, eps_a, eps_v, sigma_a, eta, height, volume, axial_force, p, q,
                     kinetic_energy: ke, unbalanced_force: uf, energy_error: ee, max_depth: md,
                     contacts, step }
    }

    fn csv_line(&self) -> String {
        let mut line = String::with_capacity(300);
        for v in self.reals() {
            line.push_str(&format!("{v:e},"));
        }
        line + &format!("{},{}\n", self.contacts, self.step)
    }
}

/// Header line of `curve.csv`; the column order of [`CurveWriter`].
pub const CURVE_HEADER: &str = "time,eps_a,eps_v,sigma_a,eta,height,volume,axial_force,p,q,kinetic_energy,unbalanced_force,energy_error,max_depth,contacts,step";

/// Writes `curve.csv` row by row.
///
/// [`CurveWriter::new`] creates (truncates) the file and writes [`CURVE_HEADER`]; every
/// [`CurveWriter::push`] writes one complete line with a single write and flushes, so an
/// interrupted run leaves only complete rows. Reals are written in shortest round-trip
/// scientific form (`{:e}`), so [`read_curve`] gets back the same bits.
#[derive(Debug)]
pub struct CurveWriter {
    file: File,
}

impl CurveWriter {
    /// Creates the file at `path` and writes the header.
    pub fn new(path: impl AsRef<Path>) -> io::Result<CurveWriter> {
        let mut file = File::create(path)?;
        file.write_all(format!("{CURVE_HEADER}\n").as_bytes())?;
        file.flush()?;
        Ok(CurveWriter { file })
    }

    /// Appends one row and flushes it.
    pub fn push(&mut self, point: &CurvePoint) -> io::Result<()> {
        self.file.write_all(point.csv_line().as_bytes())?;
        self.file.flush()
    }
}

/// Why a `curve.csv` could not be read. Every message is one line naming the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CurveError {
    /// The file could not be read.
    #[error("reading {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: io::Error,
    },
    /// A header without a required column, a short row, or a value that does not parse.
    #[error("{}:{line}: {message}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// 1-based line number (1 for the header).
        line: usize,
        /// What is wrong, naming the column.
        message: String,
    },
}

/// Reads a `curve.csv` back. Columns are found by header name, so extra columns and any
/// order are tolerated; a missing required column is an error naming it. Blank lines are
/// skipped.
pub fn read_curve(path: impl AsRef<Path>) -> Result<Vec<CurvePoint>, CurveError> {
    let path = path.as_ref();
    let error = |line: usize, message: String| CurveError::Format {
        path: path.to_path_buf(),
        line,
        message,
    };
    let text = std::fs::read_to_string(path).map_err(|source| CurveError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut lines = text.lines().zip(1..);
    let header: Vec<&str> = lines
        .next()
        .map_or(vec![], |(h, _)| h.split(',').map(str::trim).collect());
    let names: Vec<&str> = CURVE_HEADER.split(',').collect();
    let mut index = [0usize; 16];
    for (slot, name) in index.iter_mut().zip(&names) {
        *slot = header.iter().position(|h| h == name).ok_or_else(|| {
            error(
                1,
                format!("missing column `{name}` in the header (expected {CURVE_HEADER})"),
            )
        })?;
    }
    let mut points = Vec::new();
    for (line, number) in lines.filter(|(l, _)| !l.trim().is_empty()) {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let field = |k: usize| {
            let (name, count) = (names[k], fields.len());
            let s = fields.get(index[k]).ok_or_else(|| {
                error(
                    number,
                    format!("no column `{name}`: row has {count} fields"),
                )
            })?;
            Ok((*s, move |what| {
                error(number, format!("column `{name}`: `{s}` is not {what}"))
            }))
        };
        let mut reals = [0.0f64; 14];
        for (k, value) in reals.iter_mut().enumerate() {
            let (s, bad) = field(k)?;
            *value = s.parse().map_err(|_| bad("a number"))?;
        }
        let integer = |k: usize| -> Result<u64, CurveError> {
            let (s, bad) = field(k)?;
            s.parse().map_err(|_| bad("a non-negative integer"))
        };
        points.push(CurvePoint::from_columns(reals, integer(14)?, integer(15)?));
    }
    Ok(points)
}

/// Width in axial strain of the sliding least-squares window of
/// [`CurveSummary::max_dilation_rate`] (1 % axial strain).
pub const DILATION_WINDOW: f64 = 0.01;

/// Summary of a shear curve.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurveSummary {
    /// Largest stress ratio (first occurrence).
    pub peak_eta: f64,
    /// Axial strain at the peak.
    pub eps_a_at_peak: f64,
    /// Time at the peak (s).
    pub time_at_peak: f64,
    /// Mean stress ratio over the last `residual_window` of axial strain.
    pub residual_eta: f64,
    /// The axial-strain window of `residual_eta`.
    pub residual_window: f64,
    /// Largest volumetric strain (largest contraction).
    pub max_contraction: f64,
    /// Axial strain at the largest contraction.
    pub eps_a_at_max_contraction: f64,
    /// Largest dilation rate `-d eps_v / d eps_a`: the least-squares slope over every
    /// window [`DILATION_WINDOW`] wide in axial strain holding at least three points
    /// spread over at least half the window (the whole curve when none does). Negative
    /// when the sample only contracts; NaN when no two points differ in `eps_a`.
    pub max_dilation_rate: f64,
    /// Axial strain of the last point.
    pub final_eps_a: f64,
    /// Volumetric strain of the last point.
    pub final_eps_v: f64,
    /// Number of points summarized.
    pub points: usize,
}

/// Summarizes a shear curve; `None` for an empty one. Non-finite values are ignored.
///
/// `residual_eta` is the mean `eta` of the points with `eps_a` in
/// `(final_eps_a - residual_window, final_eps_a]`, i.e. all points when the curve is
/// shorter than the window, and at least the last point.
pub fn summarize(points: &[CurvePoint], residual_window: f64) -> Option<CurveSummary> {
    let last = points.last()?;
    let mut tracker = PeakTracker::new();
    for p in points {
        tracker.observe(p.eta);
    }
    let peak = &points[tracker.index().unwrap_or(0)];
    let start = last.eps_a - residual_window.max(0.0);
    let (sum, count) = points
        .iter()
        .enumerate()
        .filter(|(i, p)| *i + 1 == points.len() || (p.eps_a > start && p.eps_a <= last.eps_a))
        .filter(|(_, p)| p.eta.is_finite())
        .fold((0.0, 0usize), |(s, n), (_, p)| (s + p.eta, n + 1));
    let mut contraction = (f64::NAN, f64::NAN);
    for p in points.iter().filter(|p| p.eps_v.is_finite()) {
        if contraction.0.is_nan() || p.eps_v > contraction.0 {
            contraction = (p.eps_v, p.eps_a);
        }
    }
    Some(CurveSummary {
        peak_eta: peak.eta,
        eps_a_at_peak: peak.eps_a,
        time_at_peak: peak.time,
        residual_eta: sum / count as f64,
        residual_window,
        max_contraction: contraction.0,
        eps_a_at_max_contraction: contraction.1,
        max_dilation_rate: max_dilation_rate(points, DILATION_WINDOW),
        final_eps_a: last.eps_a,
        final_eps_v: last.eps_v,
        points: points.len(),
    })
}

/// Largest `-d eps_v / d eps_a` by least squares over sliding windows `window` wide.
fn max_dilation_rate(points: &[CurvePoint], window: f64) -> f64 {
    let mut xy: Vec<(f64, f64)> = points
        .iter()
        .map(|p| (p.eps_a, p.eps_v))
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    xy.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = xy.len();
    if n < 2 {
        return f64::NAN;
    }
    // Prefix sums about the mean, so that window sums lose little to cancellation.
    let mx = xy.iter().map(|p| p.0).sum::<f64>() / n as f64;
    let my = xy.iter().map(|p| p.1).sum::<f64>() / n as f64;
    let mut prefix = vec![[0.0f64; 4]; n + 1];
    for (k, &(x, y)) in xy.iter().enumerate() {
        let (dx, dy) = (x - mx, y - my);
        let s = prefix[k];
        prefix[k + 1] = [s[0] + dx, s[1] + dy, s[2] + dx * dx, s[3] + dx * dy];
    }
    let slope = |i: usize, j: usize| {
        let m = (j - i) as f64;
        let s: [f64; 4] = std::array::from_fn(|c| prefix[j][c] - prefix[i][c]);
        let sxx = s[2] - s[0] * s[0] / m;
        let sxy = s[3] - s[0] * s[1] / m;
        (sxx > 0.0).then(|| sxy / sxx)
    };
    let mut best = f64::NEG_INFINITY;
    let mut end = 0;
    for start in 0..n {
        end = end.max(start);
        while end < n && xy[end].0 <= xy[start].0 + window {
            end += 1;
        }
        let spread = xy[end - 1].0 - xy[start].0;
        if end - start >= 3
            && spread >= 0.5 * window
            && let Some(b) = slope(start, end)
        {
            best = best.max(-b);
        }
    }
    if best == f64::NEG_INFINITY {
        slope(0, n).map_or(f64::NAN, |b| -b)
    } else {
        best
    }
}

/// Running detector of the peak of the stress ratio, fed one value at a time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PeakTracker {
    best: Option<(f64, usize)>,
    seen: usize,
}

impl PeakTracker {
    /// A tracker that has seen nothing.
    pub fn new() -> PeakTracker {
        PeakTracker::default()
    }

    /// Feeds the next value; true when it is a new maximum (strictly greater than every
    /// earlier value, so a plateau keeps its first point). Non-finite values are counted
    /// but never a maximum.
    pub fn observe(&mut self, eta: f64) -> bool {
        let index = self.seen;
        self.seen += 1;
        let new = eta.is_finite() && self.best.is_none_or(|(b, _)| eta > b);
        if new {
            self.best = Some((eta, index));
        }
        new
    }

    /// The largest value so far.
    pub fn best(&self) -> Option<f64> {
        self.best.map(|b| b.0)
    }

    /// 0-based position of the largest value among all values observed.
    pub fn index(&self) -> Option<usize> {
        self.best.map(|b| b.1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn eqs_12_to_15_by_hand() {
        // Large strain: logarithmic ln(0.6/0.51), not the engineering 0.09/0.6 = 0.15.
        assert!(close(
            axial_strain(0.6, 0.51),
            0.162_518_929_497_774_9,
            1e-15
        ));
        assert_eq!(axial_strain(0.6, 0.6), 0.0);
        // Volume growth (dilation) is negative: -ln(1.1); shrinkage positive: -ln(0.9).
        assert!(close(
            volumetric_strain(2.0, 2.2),
            -0.095_310_179_804_324_87,
            1e-15
        ));
        assert!(close(
            volumetric_strain(1.0, 0.9),
            0.105_360_515_657_826_3,
            1e-15
        ));
        // 300 N on V = 1.5e-3 m^3, H = 0.1 m: A = 0.015 m^2, sigma = 2e4 Pa.
        assert!(close(axial_stress(300.0, 1.5e-3, 0.1), 2.0e4, 1e-9));
        // eta: isotropic 0; sigma_l = 2.5 sigma_0: 3 * 1.5 / 4.5 = 1; 4 sigma_0: 9/6 = 3/2.
        assert_eq!(stress_ratio(1e5, 1e5), 0.0);
        assert!(close(stress_ratio(2.5e5, 1e5), 1.0, 1e-15));
        assert!(close(stress_ratio(4e5, 1e5), 1.5, 1e-15));
        let eta = stress_ratio(1e15, 1e5); // -> 3 from below as sigma_l -> infinity
        assert!(close(eta, 3.0, 1e-9) && eta < 3.0);
    }

    #[test]
    fn point_from_measurement() {
        let r = Reference {
            h0: 0.2,
            v0: 0.002,
            sigma_0: 1e5,
        };
        let (height, volume) = (0.18, 0.002 * 0.99);
        let axial_force = 4e5 * volume / height; // sigma_l = 4 sigma_0
        let m = Measurement {
            time: 0.5,
            height,
            volume,
            axial_force,
            contacts: 12,
            step: 7,
            ..Measurement::default()
        };
        let p = CurvePoint::from_measurement(&m, &r);
        assert!(close(p.eps_a, (0.2f64 / 0.18).ln(), 1e-15));
        assert!(close(p.eps_v, -(0.99f64.ln()), 1e-15));
        assert!(close(p.sigma_a, 4e5, 1e-6) && close(p.eta, 1.5, 1e-12));
        assert!(close(p.p, 2e5, 1e-6) && close(p.q, 3e5, 1e-6));
        assert_eq!((p.contacts, p.step, p.time, p.height), (12, 7, 0.5, 0.18));
    }

    /// eta: 1.2 sin rise to the peak at eps 0.05, cosine fall to 0.9 at 0.1, then flat.
    /// eps_v: slope 0.5 - 25 eps up to 0.04 (max contraction 0.005 at 0.02), then linear
    /// dilation with slope -0.5. Irregular spacing (0.0007, 0.0007, 0.0002, ...).
    fn synthetic(noise: f64) -> Vec<CurvePoint> {
        let (mut points, mut e, mut seed) = (Vec::new(), 0.0f64, 12345u64);
        while e <= 0.2 {
            let eta = match e {
                e if e <= 0.05 => 1.2 * (FRAC_PI_2 * e / 0.05).sin(),
                e if e <= 0.1 => 0.9 + 0.15 * (1.0 + (PI * (e - 0.05) / 0.05).cos()),
                _ => 0.9,
            };
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5; // in [-0.5, 0.5)
            let eps_v = if e <= 0.04 {
                0.5 * e - 12.5 * e * e
            } else {
                -0.5 * (e - 0.04)
            };
            let step = points.len() as u64;
            let eps_v = eps_v + 2.0 * noise * u;
            points.push(CurvePoint {
                time: e * 10.0,
                eps_a: e,
                eps_v,
                eta,
                step,
                ..Default::default()
            });
            e += if step % 3 == 2 { 0.0002 } else { 0.0007 };
        }
        points
    }

    #[test]
    fn summary_of_a_synthetic_curve() {
        let points = synthetic(0.0);
        let s = summarize(&points, 0.02).unwrap();
        assert_eq!(s.points, points.len());
        assert!(
            close(s.peak_eta, 1.2, 1e-3) && close(s.eps_a_at_peak, 0.05, 1e-3),
            "{s:?}"
        );
        assert!(close(s.time_at_peak, 10.0 * s.eps_a_at_peak, 1e-12));
        assert!(close(s.residual_eta, 0.9, 1e-12), "{s:?}");
        assert!(close(s.max_contraction, 0.005, 1e-6), "{s:?}");
        assert!(close(s.eps_a_at_max_contraction, 0.02, 7e-4), "{s:?}");
        assert!(close(s.max_dilation_rate, 0.5, 1e-9), "{s:?}");
        let last = points.last().unwrap();
        assert_eq!((s.final_eps_a, s.final_eps_v), (last.eps_a, last.eps_v));
        // Noise of +-1e-4 on eps_v: the windowed fit stays within 0.03 of the slope.
        let s = summarize(&synthetic(1e-4), 0.02).unwrap();
        assert!(close(s.max_dilation_rate, 0.5, 0.03), "{s:?}");
        assert!(close(s.max_contraction, 0.005, 2e-4), "{s:?}");
    }

    #[test]
    fn summary_edge_cases() {
        assert!(summarize(&[], 0.02).is_none());
        // Contraction only: negative dilation rate; short curve: residual over all points.
        let points: Vec<CurvePoint> = synthetic(0.0)
            .into_iter()
            .filter(|p| p.eps_a < 0.015)
            .collect();
        let s = summarize(&points, 0.02).unwrap();
        assert!(s.max_dilation_rate < 0.0, "{s:?}");
        let mean = points.iter().map(|p| p.eta).sum::<f64>() / points.len() as f64;
        assert!(close(s.residual_eta, mean, 1e-12));
        // A single point: rate undefined (NaN), nothing panics.
        let s = summarize(&points[..1], 0.02).unwrap();
        assert!(s.max_dilation_rate.is_nan() && s.residual_eta == points[0].eta);
    }

    #[test]
    fn peak_tracker_reports_strict_new_maxima() {
        let mut t = PeakTracker::new();
        let etas = [0.1, 0.5, f64::NAN, 0.5, 0.4, 0.7, 0.7];
        let seen: Vec<bool> = etas.into_iter().map(|e| t.observe(e)).collect();
        assert_eq!(seen, [true, true, false, false, false, true, false]);
        assert_eq!((t.best(), t.index()), (Some(0.7), Some(5)));
        assert_eq!(PeakTracker::new().best(), None);
    }

    fn awkward_point(k: u64) -> CurvePoint {
        let x = 0.1 + k as f64 / 3.0;
        let reals = [
            x * 1e-7,
            -0.0,
            1.0 / 7.0,
            1e-300 * x,
            PI,
            f64::MIN_POSITIVE / 3.0,
            f64::MAX,
        ];
        let more = [
            -1.234_567_89e15,
            f64::NAN,
            f64::NEG_INFINITY,
            5e-324,
            0.1 + 0.2,
            -7.5e-3,
            2.0f64.sqrt(),
        ];
        CurvePoint::from_columns(
            std::array::from_fn(|i| *reals.iter().chain(&more).nth(i).unwrap()),
            u64::MAX,
            k,
        )
    }

    fn bits(p: &CurvePoint) -> Vec<u64> {
        p.reals()
            .map(f64::to_bits)
            .into_iter()
            .chain([p.contacts, p.step])
            .collect()
    }

    #[test]
    fn writer_round_trip_is_bit_exact_and_interruption_leaves_complete_rows() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("curve.csv");
        let mut w = CurveWriter::new(&path).unwrap();
        for k in 0..3 {
            w.push(&awkward_point(k)).unwrap();
            // Every push is on disk at once, before the writer goes away.
            assert_eq!(read_curve(&path).unwrap().len(), k as usize + 1);
        }
        drop(w); // interrupted after 3 pushes
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with(&format!("{CURVE_HEADER}\n")) && text.ends_with('\n'));
        assert_eq!(text.lines().count(), 4);
        assert!(text.lines().all(|l| l.split(',').count() == 16));
        let read = read_curve(&path).unwrap();
        assert_eq!(read.len(), 3);
        for (k, p) in read.iter().enumerate() {
            assert_eq!(bits(p), bits(&awkward_point(k as u64)));
        }
    }

    #[test]
    fn reader_tolerates_extra_columns_and_names_missing_ones() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("curve.csv");
        let header = format!("extra,{}", CURVE_HEADER.replace("eta,", ""));
        std::fs::write(&path, format!("{header}\n")).unwrap();
        let message = read_curve(&path).unwrap_err().to_string();
        assert!(
            message.contains("missing column `eta`") && message.contains("curve.csv"),
            "{message}"
        );
        assert!(!message.contains('\n'));

        let row = awkward_point(1).csv_line().replace('\n', ",x\n");
        std::fs::write(&path, format!("{CURVE_HEADER},extra\n\n{row}\n")).unwrap();
        assert_eq!(
            bits(&read_curve(&path).unwrap()[0]),
            bits(&awkward_point(1))
        );

        std::fs::write(&path, format!("{CURVE_HEADER}\n1,2,3\n")).unwrap();
        let message = read_curve(&path).unwrap_err().to_string();
        assert!(
            message.contains(":2:") && message.contains("`sigma_a`"),
            "{message}"
        );
        let missing = read_curve(dir.path().join("absent.csv")).unwrap_err();
        assert!(matches!(missing, CurveError::Io { .. }));
    }
}
