//! The measurements of the triaxial test (paper eqs 12-15) and the shear curve.
//!
//! This module owns the conversion of raw specimen state (height, volume, axial force)
//! into the paper's strains and stresses, one row of `curve.csv` ([`CurvePoint`]), the
//! writing ([`CurveWriter`]) and reading ([`read_curve`]) of that file, the summary of a
//! curve ([`summarize`]) and the running peak detector ([`PeakTracker`]); and the lateral
//! stress the membrane applies to the specimen, measured from the membrane-particle
//! contact forces ([`membrane_radial_force`], [`radial_stress`]; docs/TRIAXIAL.md,
//! "Lateral stress").
//!
//! Sign convention of the paper: compression positive, contraction positive. Strains are
//! logarithmic (true) strains, so they stay additive at large deformation.

use fdem_contact::{Counterpart, NodeContact};
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

/// Lateral area of the specimen `2 pi R H` with the mean radius `R = sqrt(V / (pi H))` of
/// the enclosed volume, i.e. `2 sqrt(pi V H)` (m^2): the lateral surface of the cylinder
/// whose cross-section is eq 14's `A = V / H`.
pub fn lateral_area(volume: f64, height: f64) -> f64 {
    2.0 * (std::f64::consts::PI * volume * height).sqrt()
}

/// The force each membrane-particle node contact applies to the membrane, with the point
/// where it acts: a membrane node pressed into a particle face receives the contact's force
/// at the node; a particle node pressed into a membrane face gives the face the opposite
/// of the node's force at the contact point. Each contact is counted once; contacts with
/// the platens and between particles are left out.
pub fn membrane_contact_forces(
    contacts: &[NodeContact],
    membrane: u32,
) -> impl Iterator<Item = ([f64; 3], [f64; 3])> + '_ {
    contacts.iter().filter_map(move |c| {
        let f = c.force();
        match c.counterpart {
            Counterpart::Body(b) if c.body == membrane && b != membrane => Some((c.position, f)),
            Counterpart::Body(b) if b == membrane && c.body != membrane => {
                Some((c.contact_point, [-f[0], -f[1], -f[2]]))
            }
            _ => None,
        }
    })
}

/// Sum of the radial components (outward from the specimen's axis, the z axis) of forces
/// acting at points (N); a force on the axis itself has no radial direction and counts 0.
pub fn radial_force(forces: impl IntoIterator<Item = ([f64; 3], [f64; 3])>) -> f64 {
    forces
        .into_iter()
        .map(|(x, f)| {
            let r = x[0].hypot(x[1]);
            if r > 0.0 {
                (f[0] * x[0] + f[1] * x[1]) / r
            } else {
                0.0
            }
        })
        .sum()
}

/// The radial force the particles push the membrane outward with (N): the sum of the
/// radial components of [`membrane_contact_forces`]; the membrane pushes the particles
/// inward with the same force.
pub fn membrane_radial_force(contacts: &[NodeContact], membrane: u32) -> f64 {
    radial_force(membrane_contact_forces(contacts, membrane))
}

/// The lateral stress the membrane applies to the specimen (Pa): `radial_force` over the
/// [`lateral_area`] of the specimen of `volume` and `height`.
pub fn radial_stress(radial_force: f64, volume: f64, height: f64) -> f64 {
    radial_force / lateral_area(volume, height)
}

/// Mean hoop strain of a membrane's rings of nodes (-): for every ring in `rings`, the
/// length of the closed polygon through its `around` nodes (the membrane's faces are flat,
/// so that polygon is the membrane's own length around, draped into the surface voids or
/// not) over `reference_perimeter`, less 1, averaged over the rings. Ring `k` is nodes
/// `k * around .. (k + 1) * around` of `nodes`, in order around.
pub fn hoop_strain(
    nodes: &[[f64; 3]],
    around: usize,
    rings: std::ops::Range<usize>,
    reference_perimeter: f64,
) -> f64 {
    let count = rings.len();
    let sum: f64 = rings
        .map(|k| {
            let ring = &nodes[k * around..(k + 1) * around];
            let length: f64 = (0..around)
                .map(|j| {
                    let (a, b) = (ring[j], ring[(j + 1) % around]);
                    fdem_core::geometry::norm(fdem_core::geometry::sub(b, a))
                })
                .sum();
            length / reference_perimeter - 1.0
        })
        .sum();
    sum / count as f64
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
    /// Radial force of the particles on the membrane, outward positive (N): the sum over
    /// the membrane-particle node contacts ([`membrane_radial_force`]).
    pub lateral_force: f64,
    /// Mean hoop strain of the membrane's free rings ([`hoop_strain`]) (-).
    pub hoop_strain: f64,
    /// Volume by which the membrane drapes into the surface voids (m^3):
    /// [`crate::MembraneForces::draped_volume`].
    pub draped_volume: f64,
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
    /// The membrane's draped volume at the start of shear (m^3); `V0` plus this is the
    /// volume inside the envelope of the outermost particles.
    #[serde(default)]
    pub draped0: f64,
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
    /// Lateral stress the membrane applies to the specimen, measured from the
    /// membrane-particle contact forces ([`radial_stress`]) (Pa); NaN when read from a
    /// file without the column.
    pub sigma_r: f64,
    /// Stress ratio of the measured stresses, eq 15 with `sigma_r` in place of sigma_0:
    /// `3 (sigma_l - sigma_r) / (sigma_l + 2 sigma_r)` (-); NaN when read from a file
    /// without the column.
    pub eta_measured: f64,
    /// Mean hoop strain of the membrane's free rings of nodes, from its stress-free mesh
    /// ([`hoop_strain`]) (-); NaN when read from a file without the column.
    pub hoop_strain: f64,
    /// Volume by which the membrane drapes into the surface voids (m^3,
    /// [`crate::MembraneForces::draped_volume`]); NaN when read from a file without the
    /// column.
    pub draped_volume: f64,
    /// Volumetric strain of the specimen inside the envelope of its outermost particles,
    /// `-ln((V + V_d) / (V0 + V_d0))` with `V_d` the draped volume (-): eq 13 without the
    /// membrane's penetration into the surface voids, which is `eps_v - eps_v_specimen`;
    /// NaN when read from a file without the column.
    pub eps_v_specimen: f64,
}

impl CurvePoint {
    /// Numbers of [`CurvePoint::to_numbers`].
    pub const NUMBERS: usize = 21;

    /// The row as numbers, in the column order of `curve.csv` (counts as exact floats),
    /// for a checkpoint.
    pub fn to_numbers(&self) -> [f64; CurvePoint::NUMBERS] {
        [
            self.time,
            self.eps_a,
            self.eps_v,
            self.sigma_a,
            self.eta,
            self.height,
            self.volume,
            self.axial_force,
            self.p,
            self.q,
            self.kinetic_energy,
            self.unbalanced_force,
            self.energy_error,
            self.max_depth,
            self.contacts as f64,
            self.step as f64,
            self.sigma_r,
            self.eta_measured,
            self.hoop_strain,
            self.draped_volume,
            self.eps_v_specimen,
        ]
    }

    /// The row of [`CurvePoint::to_numbers`] (`n` holds at least [`CurvePoint::NUMBERS`]).
    pub fn from_numbers(n: &[f64]) -> CurvePoint {
        CurvePoint {
            time: n[0],
            eps_a: n[1],
            eps_v: n[2],
            sigma_a: n[3],
            eta: n[4],
            height: n[5],
            volume: n[6],
            axial_force: n[7],
            p: n[8],
            q: n[9],
            kinetic_energy: n[10],
            unbalanced_force: n[11],
            energy_error: n[12],
            max_depth: n[13],
            contacts: n[14] as u64,
            step: n[15] as u64,
            sigma_r: n[16],
            eta_measured: n[17],
            hoop_strain: n[18],
            draped_volume: n[19],
            eps_v_specimen: n[20],
        }
    }

    /// Applies eqs 12-15 to a measurement relative to the start of shear.
    pub fn from_measurement(m: &Measurement, reference: &Reference) -> CurvePoint {
        let sigma_a = axial_stress(m.axial_force, m.volume, m.height);
        let s0 = reference.sigma_0;
        let sigma_r = radial_stress(m.lateral_force, m.volume, m.height);
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
            sigma_r,
            eta_measured: stress_ratio(sigma_a, sigma_r),
            hoop_strain: m.hoop_strain,
            draped_volume: m.draped_volume,
            eps_v_specimen: volumetric_strain(
                reference.v0 + reference.draped0,
                m.volume + m.draped_volume,
            ),
        }
    }

    /// The real columns in [`CURVE_HEADER`] order (all but `contacts` and `step`).
    #[rustfmt::skip]
    fn reals(&self) -> [f64; 14] {
        [self.time, self.eps_a, self.eps_v, self.sigma_a, self.eta, self.height, self.volume,
         self.axial_force, self.p, self.q, self.kinetic_energy, self.unbalanced_force,
         self.energy_error, self.max_depth]
    }

    /// The optional real columns, after `step` ([`CURVE_OPTIONAL`] order).
    fn lateral(&self) -> [f64; 5] {
        [
            self.sigma_r,
            self.eta_measured,
            self.hoop_strain,
            self.draped_volume,
            self.eps_v_specimen,
        ]
    }

    #[rustfmt::skip]
    fn from_columns(r: [f64; 14], contacts: u64, step: u64, lateral: [f64; 5]) -> CurvePoint {
        let [time, eps_a, eps_v, sigma_a, eta, height, volume, axial_force, p, q, ke, uf, ee,
             md] = r;
        let [sigma_r, eta_measured, hoop_strain, draped_volume, eps_v_specimen] = lateral;
        CurvePoint { time, eps_a, eps_v, sigma_a, eta, height, volume, axial_force, p, q,
                     kinetic_energy: ke, unbalanced_force: uf, energy_error: ee, max_depth: md,
                     contacts, step, sigma_r, eta_measured, hoop_strain, draped_volume,
                     eps_v_specimen }
    }

    fn csv_line(&self) -> String {
        let mut line = String::with_capacity(340);
        for v in self.reals() {
            line.push_str(&format!("{v:e},"));
        }
        line.push_str(&format!("{},{}", self.contacts, self.step));
        for v in self.lateral() {
            line.push_str(&format!(",{v:e}"));
        }
        line + "\n"
    }
}

/// Header line of `curve.csv`; the column order of [`CurveWriter`]: the required columns
/// of [`read_curve`], then the [`CURVE_OPTIONAL`] ones.
pub const CURVE_HEADER: &str = "time,eps_a,eps_v,sigma_a,eta,height,volume,axial_force,p,q,kinetic_energy,unbalanced_force,energy_error,max_depth,contacts,step,sigma_r,eta_measured,hoop_strain,draped_volume,eps_v_specimen";

/// The columns [`read_curve`] reads when present and sets to NaN when absent (files
/// written before the lateral stress or the draped volume was measured).
pub const CURVE_OPTIONAL: [&str; 5] = [
    "sigma_r",
    "eta_measured",
    "hoop_strain",
    "draped_volume",
    "eps_v_specimen",
];

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

    /// Creates the file at `path` with the header and `rows` (a resumed run's rows so
    /// far, replacing any written after its checkpoint).
    pub fn with_rows(path: impl AsRef<Path>, rows: &[CurvePoint]) -> io::Result<CurveWriter> {
        let mut writer = CurveWriter::new(path)?;
        for row in rows {
            writer.file.write_all(row.csv_line().as_bytes())?;
        }
        writer.file.flush()?;
        Ok(writer)
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
/// order are tolerated; a missing required column is an error naming it, a missing
/// [`CURVE_OPTIONAL`] column reads as NaN. Blank lines are skipped.
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
    let optional = CURVE_OPTIONAL.map(|name| header.iter().position(|h| *h == name));
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
        let mut lateral = [f64::NAN; CURVE_OPTIONAL.len()];
        for ((value, position), name) in lateral.iter_mut().zip(optional).zip(CURVE_OPTIONAL) {
            let Some(k) = position else { continue };
            let s = fields.get(k).ok_or_else(|| {
                error(
                    number,
                    format!("no column `{name}`: row has {} fields", fields.len()),
                )
            })?;
            *value = s
                .parse()
                .map_err(|_| error(number, format!("column `{name}`: `{s}` is not a number")))?;
        }
        points.push(CurvePoint::from_columns(
            reals,
            integer(14)?,
            integer(15)?,
            lateral,
        ));
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
    /// Largest stress ratio of the measured stresses, `eta_measured` (first occurrence;
    /// NaN when the curve has none, e.g. a file written before the column existed).
    pub peak_eta_measured: f64,
    /// Axial strain at the peak of `eta_measured`.
    pub eps_a_at_peak_eta_measured: f64,
    /// `eta_measured` at the peak of `eta` (the same row as `peak_eta`).
    pub eta_measured_at_peak: f64,
    /// Axial strain of the last point.
    pub final_eps_a: f64,
    /// Volumetric strain of the last point.
    pub final_eps_v: f64,
    /// `eps_v_specimen` of the last point: the specimen's own volumetric strain, without
    /// the membrane's penetration (NaN when the curve has no such column).
    pub final_eps_v_specimen: f64,
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
    let mut measured = PeakTracker::new();
    for p in points {
        measured.observe(p.eta_measured);
    }
    let (peak_eta_measured, eps_a_at_peak_eta_measured) =
        measured.index().map_or((f64::NAN, f64::NAN), |i| {
            (points[i].eta_measured, points[i].eps_a)
        });
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
        peak_eta_measured,
        eps_a_at_peak_eta_measured,
        eta_measured_at_peak: peak.eta_measured,
        final_eps_a: last.eps_a,
        final_eps_v: last.eps_v,
        final_eps_v_specimen: last.eps_v_specimen,
        points: points.len(),
    })
}

/// The lateral stress the membrane applied during the shear, over sigma_0
/// (`summary.json`'s `lateral_stress`; docs/TRIAXIAL.md, "Lateral stress").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LateralSummary {
    /// `sigma_r / sigma_0` at the first row of the shear.
    pub start: f64,
    /// Mean of `sigma_r / sigma_0` over the rows of the shear.
    pub mean: f64,
    /// Smallest `sigma_r / sigma_0` of a row.
    pub min: f64,
    /// Largest `sigma_r / sigma_0` of a row.
    pub max: f64,
    /// `sigma_r / sigma_0` at the peak of eq 15's `eta`.
    pub at_peak: f64,
    /// `sigma_r / sigma_0` at the last row.
    pub end: f64,
    /// Rows with a finite `sigma_r`.
    pub points: usize,
}

/// Summarizes `sigma_r / sigma_0` over a shear curve; `None` when no row has a finite
/// `sigma_r`.
pub fn summarize_lateral(points: &[CurvePoint], sigma_0: f64) -> Option<LateralSummary> {
    let ratios: Vec<f64> = points
        .iter()
        .map(|p| p.sigma_r / sigma_0)
        .filter(|r| r.is_finite())
        .collect();
    let (first, last) = (*ratios.first()?, *ratios.last()?);
    let mut tracker = PeakTracker::new();
    for p in points {
        tracker.observe(p.eta);
    }
    let at_peak = tracker
        .index()
        .map_or(f64::NAN, |i| points[i].sigma_r / sigma_0);
    Some(LateralSummary {
        start: first,
        mean: ratios.iter().sum::<f64>() / ratios.len() as f64,
        min: ratios.iter().copied().fold(f64::INFINITY, f64::min),
        max: ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        at_peak,
        end: last,
        points: ratios.len(),
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
            draped0: 1e-5,
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
            draped_volume: 3e-5,
            ..Measurement::default()
        };
        let p = CurvePoint::from_measurement(&m, &r);
        assert!(close(p.eps_a, (0.2f64 / 0.18).ln(), 1e-15));
        assert!(close(p.eps_v, -(0.99f64.ln()), 1e-15));
        // The volume lost to the membrane's draping (2e-5 m^3 more) is not the specimen's:
        // inside the envelope, 0.00201 -> 0.00201 (1.98e-3 + 3e-5).
        assert_eq!(p.draped_volume, 3e-5);
        assert!(p.eps_v_specimen.abs() < 1e-12 && p.eps_v > 0.009);
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
        assert_eq!(
            s.final_eps_v_specimen.to_bits(),
            last.eps_v_specimen.to_bits()
        );
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
            [-2.5e-310 * x, f64::INFINITY, 1.0 / x, 3.0e-7 * x, -x],
        )
    }

    fn bits(p: &CurvePoint) -> Vec<u64> {
        p.reals()
            .into_iter()
            .chain(p.lateral())
            .map(f64::to_bits)
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
        assert!(text.lines().all(|l| l.split(',').count() == 21));
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

    /// A file written before the lateral stress was measured (16 columns) still reads,
    /// with NaN in the new columns; a bad value in a present optional column is an error
    /// naming it.
    #[test]
    fn reader_reads_files_without_the_lateral_columns() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("curve.csv");
        let old_header = CURVE_HEADER.replace(
            ",sigma_r,eta_measured,hoop_strain,draped_volume,eps_v_specimen",
            "",
        );
        assert_eq!(old_header.split(',').count(), 16);
        let point = awkward_point(2);
        let line = point.csv_line();
        let old_row = line.rsplitn(6, ',').nth(5).unwrap();
        std::fs::write(&path, format!("{old_header}\n{old_row}\n")).unwrap();
        let read = read_curve(&path).unwrap();
        assert_eq!(read.len(), 1);
        assert!(read[0].lateral().iter().all(|v| v.is_nan()));
        assert_eq!(bits(&read[0])[..14], bits(&point)[..14]);
        assert_eq!(
            (read[0].contacts, read[0].step),
            (point.contacts, point.step)
        );
        // Old files summarize as before; the measured peak is NaN.
        let s = summarize(&read, 0.02).unwrap();
        assert!(s.peak_eta_measured.is_nan() && s.eta_measured_at_peak.is_nan());
        assert!(summarize_lateral(&read, 1e5).is_none());

        let bad = line.replacen(",inf,", ",x,", 1);
        std::fs::write(&path, format!("{CURVE_HEADER}\n{bad}")).unwrap();
        let message = read_curve(&path).unwrap_err().to_string();
        assert!(message.contains("`eta_measured`"), "{message}");
    }

    /// A node contact as the contact model reports it: `body`'s node at `position` pressed
    /// into `counterpart`, the force on the node `force`, acting on the face at `point`.
    fn contact(
        body: u32,
        counterpart: Counterpart,
        position: [f64; 3],
        point: [f64; 3],
        force: [f64; 3],
    ) -> NodeContact {
        // Split the force into a normal and a tangential part, as the contact law does.
        let normal = force.map(|f| 0.75 * f);
        let tangential = force.map(|f| 0.25 * f);
        serde_json::from_value(serde_json::json!({
            "node": 0, "body": body, "counterpart": counterpart, "face": Some(0),
            "weights": [1.0, 0.0, 0.0], "position": position, "contact_point": point,
            "depth": 1e-4, "normal_force": normal, "tangential_force": tangential,
            "tangential_displacement": [0.0, 0.0, 0.0], "sliding": false,
        }))
        .unwrap()
    }

    /// A ring of membrane contacts at known angles with a known outward push: both
    /// directions (membrane nodes on particle faces, particle nodes on membrane faces)
    /// count once with the force on the membrane; platen and particle-particle contacts
    /// do not count; the stress is the force over `2 sqrt(pi V H)`.
    #[test]
    fn radial_stress_of_a_ring_of_membrane_contacts() {
        let (membrane, r, h) = (7u32, 0.075, 0.2);
        let n = 24;
        // Outward push F on the membrane at each of n angles, with a hoop and an axial
        // component that must not count.
        let (push, hoop, axial) = (1500.0, 300.0, -80.0);
        let mut contacts = Vec::new();
        for k in 0..n {
            let a = 2.0 * PI * (k as f64 + 0.3) / n as f64;
            let (c, s) = (a.cos(), a.sin());
            let on_membrane = [push * c - hoop * s, push * s + hoop * c, axial];
            let z = h * (k as f64 + 0.5) / n as f64;
            let at = |radius: f64| [radius * c, radius * s, z];
            if k % 2 == 0 {
                // The membrane's node in a particle's face: the force on the node is the
                // force on the membrane.
                contacts.push(contact(
                    membrane,
                    Counterpart::Body(k % 5),
                    at(r),
                    at(r - 1e-4),
                    on_membrane,
                ));
            } else {
                // A particle's node in a membrane face: the node feels the opposite.
                let f = on_membrane.map(|f| -f);
                contacts.push(contact(
                    k % 5,
                    Counterpart::Body(membrane),
                    at(r - 1e-4),
                    at(r),
                    f,
                ));
            }
        }
        // Not lateral: a particle on a platen, the membrane on a platen, two particles.
        let x = [0.05, 0.0, 0.0];
        contacts.push(contact(3, Counterpart::Wall(1), x, x, [900.0, 0.0, -1e4]));
        contacts.push(contact(
            membrane,
            Counterpart::Wall(0),
            x,
            x,
            [900.0, 0.0, 1e4],
        ));
        contacts.push(contact(2, Counterpart::Body(4), x, x, [5e3, 0.0, 0.0]));

        let total = membrane_radial_force(&contacts, membrane);
        assert!(close(total, n as f64 * push, 1e-9), "{total}");
        assert_eq!(
            membrane_contact_forces(&contacts, membrane).count(),
            n as usize
        );
        let volume = PI * r * r * h;
        let area = lateral_area(volume, h);
        assert!(close(area, 2.0 * PI * r * h, 1e-15), "{area}");
        let sigma = radial_stress(total, volume, h);
        let want = n as f64 * push / (2.0 * PI * r * h);
        assert!(close(sigma, want, 1e-9 * want), "{sigma} vs {want}");
        // A membrane pulled inward by the particles gives a negative stress.
        let pulled: Vec<NodeContact> = contacts
            .iter()
            .map(|c| {
                let mut c = *c;
                c.normal_force = c.normal_force.map(|f| -f);
                c.tangential_force = c.tangential_force.map(|f| -f);
                c
            })
            .collect();
        assert!(close(
            membrane_radial_force(&pulled, membrane),
            -total,
            1e-9
        ));
    }

    /// A membrane ring of 40 nodes on the circle of radius r_n, then stretched to 1.05 r_n
    /// with every other node pushed 2 mm inward (draped): the hoop strain is the polygon's
    /// length over the reference, averaged over the rings asked for.
    #[test]
    fn hoop_strain_of_rings() {
        let (n, rn) = (40usize, 0.075);
        let ring = |k: usize, scale: f64, dent: f64| -> Vec<[f64; 3]> {
            (0..n)
                .map(|j| {
                    let a = 2.0 * PI * j as f64 / n as f64;
                    let r = scale * rn - if j % 2 == 1 { dent } else { 0.0 };
                    [r * a.cos(), r * a.sin(), 0.01 * k as f64]
                })
                .collect()
        };
        let reference = 2.0 * n as f64 * rn * (PI / n as f64).sin();
        let mut nodes = ring(0, 1.0, 0.0);
        nodes.extend(ring(1, 1.05, 0.0));
        nodes.extend(ring(2, 1.05, 0.002));
        assert!(hoop_strain(&nodes, n, 0..1, reference).abs() < 1e-14);
        assert!(close(hoop_strain(&nodes, n, 1..2, reference), 0.05, 1e-14));
        // The dented ring: n zigzag sides between radii 1.05 r_n and 1.05 r_n - 2 mm.
        let (a, d) = (2.0 * PI / n as f64, 0.002);
        let (r1, r2) = (1.05 * rn, 1.05 * rn - d);
        let side = (r1 * r1 + r2 * r2 - 2.0 * r1 * r2 * a.cos()).sqrt();
        let want = n as f64 * side / reference - 1.0;
        assert!(close(hoop_strain(&nodes, n, 2..3, reference), want, 1e-14));
        let mean = hoop_strain(&nodes, n, 1..3, reference);
        assert!(close(mean, 0.5 * (0.05 + want), 1e-14), "{mean}");
    }

    /// The row carries sigma_r from the measured lateral force and eq 15 with it; the
    /// summaries find the measured peak and the ratio statistics.
    #[test]
    fn measured_lateral_stress_in_rows_and_summaries() {
        let r = Reference {
            h0: 0.2,
            v0: 0.002,
            sigma_0: 1e5,
            draped0: 0.0,
        };
        let (height, volume) = (0.2, 0.002);
        let area = lateral_area(volume, height);
        let m = Measurement {
            height,
            volume,
            axial_force: 4e5 * volume / height,
            lateral_force: 1.25e5 * area,
            ..Measurement::default()
        };
        let p = CurvePoint::from_measurement(&m, &r);
        assert!(close(p.sigma_r, 1.25e5, 1e-6), "{}", p.sigma_r);
        // eta = 1.5 with sigma_0; with sigma_r: 3 * 2.75 / 6.5.
        assert!(close(p.eta, 1.5, 1e-12));
        assert!(
            close(p.eta_measured, 3.0 * 2.75 / 6.5, 1e-12),
            "{}",
            p.eta_measured
        );

        let mut points = synthetic(0.0);
        let n = points.len();
        for (k, p) in points.iter_mut().enumerate() {
            // sigma_r / sigma_0 rises linearly from 0.9 to 1.1; eta_measured peaks later.
            p.sigma_r = 1e5 * (0.9 + 0.2 * k as f64 / (n - 1) as f64);
            p.eta_measured = p.eta + 2.0 * p.eps_a;
        }
        let s = summarize(&points, 0.02).unwrap();
        let peak = points
            .iter()
            .map(|p| p.eta_measured)
            .fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(s.peak_eta_measured, peak);
        assert!(s.eps_a_at_peak_eta_measured > s.eps_a_at_peak, "{s:?}");
        let at_peak = points
            .iter()
            .position(|p| p.eps_a == s.eps_a_at_peak)
            .unwrap();
        assert_eq!(s.eta_measured_at_peak, points[at_peak].eta_measured);
        let l = summarize_lateral(&points, 1e5).unwrap();
        assert_eq!(l.points, n);
        assert!(
            close(l.start, 0.9, 1e-12) && close(l.end, 1.1, 1e-12),
            "{l:?}"
        );
        assert!(
            close(l.min, 0.9, 1e-12) && close(l.max, 1.1, 1e-12),
            "{l:?}"
        );
        assert!(close(l.mean, 1.0, 1e-12), "{l:?}");
        assert!(
            close(l.at_peak, points[at_peak].sigma_r / 1e5, 1e-15),
            "{l:?}"
        );
    }
}
