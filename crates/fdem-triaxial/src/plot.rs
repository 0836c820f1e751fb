//! The shear-curve figures `eta.svg` and `eps_v.svg`: stress ratio and volumetric strain
//! against axial strain (paper Figs 4-8 style), one or several runs overlaid.
//!
//! This module owns the content of the figures (the project's plot style and the atomic
//! write of the file are `fdem_core`'s); the numbers come from [`crate::CurvePoint`] rows. Non-finite points (and absurd ones,
//! beyond `1e150`) are skipped, the line broken there, and empty or constant data get a sensible range,
//! so drawing never panics.

use crate::CurvePoint;
use fdem_core::plot::{self as figure, Draw, RGBColor, SeriesLabelPosition, Style, colour};
use std::path::{Path, PathBuf};

/// One curve of a figure.
#[derive(Clone, Copy, Debug)]
pub struct CurveSeries<'a> {
    /// Legend entry (for example the run's name).
    pub label: &'a str,
    /// The rows of the run's `curve.csv`.
    pub points: &'a [CurvePoint],
}

/// Which figure to draw; the x axis is always the axial strain in %.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurvePlot {
    /// `eta = q/p` (-) against `eps_a` (%): `eta.svg`.
    StressRatio,
    /// `eps_v` (%) against `eps_a` (%), with a zero line: `eps_v.svg`.
    VolumetricStrain,
}

/// Label of the x axis of both figures.
pub const AXIAL_STRAIN_LABEL: &str = "axial strain eps_a (%)";

impl CurvePlot {
    /// The conventional file name of the figure.
    pub fn file_name(self) -> &'static str {
        match self {
            CurvePlot::StressRatio => "eta.svg",
            CurvePlot::VolumetricStrain => "eps_v.svg",
        }
    }

    /// Label of the y axis, with units.
    pub fn y_label(self) -> &'static str {
        match self {
            CurvePlot::StressRatio => "stress ratio eta = q/p (-)",
            CurvePlot::VolumetricStrain => "volumetric strain eps_v (%) (contraction positive)",
        }
    }

    /// The plotted `(x, y)` of a row: `(100 eps_a, eta)` or `(100 eps_a, 100 eps_v)`.
    fn xy(self, p: &CurvePoint) -> (f64, f64) {
        let y = match self {
            CurvePlot::StressRatio => p.eta,
            CurvePlot::VolumetricStrain => 100.0 * p.eps_v,
        };
        (100.0 * p.eps_a, y)
    }
}

/// Why a figure could not be written: one line naming the file and what failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// Drawing failed.
    #[error("plotting {}: {message}", path.display())]
    Draw {
        /// The figure's path.
        path: PathBuf,
        /// What failed.
        message: String,
    },
    /// Writing or renaming the file failed.
    #[error("{action} {}: {source}", path.display())]
    Io {
        /// What was being done (`writing`).
        action: &'static str,
        /// The figure's path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Layout of the figures.
const STYLE: Style = Style {
    caption_size: 22,
    margin: 20,
    x_label_area: 50,
    y_label_area: 70,
    light_lines: Some(RGBColor(235, 235, 235)),
    axis_desc_size: Some(16),
    label_size: Some(13),
    legend_size: Some(14),
};

/// Colour of the zero line of the volumetric strain.
const ZERO_LINE: RGBColor = RGBColor(96, 96, 96);

/// Points with a coordinate larger in magnitude are skipped like non-finite ones (the
/// axis arithmetic would overflow).
const RANGE_LIMIT: f64 = 1e150;

/// A range holding zero and every value, padded by 5 %; `0..1` when that is empty.
fn axis_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((0.0f64, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let span = hi - lo;
    if span > 0.0 {
        (lo - 0.05 * span, hi + 0.05 * span)
    } else {
        (0.0, 1.0)
    }
}

/// The runs of consecutive plottable points of a series, as plotted coordinates.
fn segments(plot: CurvePlot, points: &[CurvePoint]) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = vec![];
    let mut current = vec![];
    for (x, y) in points.iter().map(|p| plot.xy(p)) {
        if x.is_finite() && y.is_finite() && x.abs() <= RANGE_LIMIT && y.abs() <= RANGE_LIMIT {
            current.push((x, y));
        } else if !current.is_empty() {
            out.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// Draws `series` as figure `plot` with `title` on top into an SVG file at `path`.
///
/// The file is written atomically: to a temporary file in the same directory, then
/// renamed, so a crash leaves either the old figure or the new one. A legend is drawn
/// when there is more than one series.
pub fn plot_curves(
    path: &Path,
    plot: CurvePlot,
    title: &str,
    series: &[CurveSeries<'_>],
) -> Result<(), PlotError> {
    let err = |message: String| PlotError::Draw {
        path: path.to_path_buf(),
        message,
    };
    let lines: Vec<Vec<Vec<(f64, f64)>>> =
        series.iter().map(|s| segments(plot, s.points)).collect();
    let all = || lines.iter().flatten().flatten();
    let (x0, x1) = axis_range(all().map(|p| p.0));
    let (y0, y1) = axis_range(all().map(|p| p.1));
    let svg = figure::svg((800, 600), |root| {
        let mut chart = STYLE.chart(root, title, x0..x1, y0..y1)?;
        chart.draw_axes(&STYLE, AXIAL_STRAIN_LABEL, plot.y_label())?;
        if plot == CurvePlot::VolumetricStrain {
            chart.draw_reference_line((x0, 0.0), (x1, 0.0), ZERO_LINE)?;
        }
        for (i, (s, segs)) in series.iter().zip(&lines).enumerate() {
            let colour = colour(i);
            // The first (possibly empty) line carries the legend entry.
            let first = segs.first().cloned().unwrap_or_default();
            chart.draw_line(first, colour, Some(s.label))?;
            for seg in segs.iter().skip(1) {
                chart.draw_line(seg.iter().copied(), colour, None)?;
            }
            // Isolated or coincident points would be invisible as lines.
            let dots = segs.iter().filter(|seg| seg.iter().all(|&p| p == seg[0]));
            chart.draw_dots(dots.map(|seg| seg[0]), colour)?;
        }
        if series.len() > 1 {
            let position = match plot {
                CurvePlot::StressRatio => SeriesLabelPosition::LowerRight,
                CurvePlot::VolumetricStrain => SeriesLabelPosition::UpperRight,
            };
            chart.draw_legend(&STYLE, position)?;
        }
        Ok(())
    })
    .map_err(err)?;
    fdem_core::fs::write_atomically(path, svg).map_err(|source| PlotError::Io {
        action: "writing",
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(n: usize, dilation: f64) -> Vec<CurvePoint> {
        (0..n)
            .map(|k| {
                let e = 0.2 * k as f64 / (n - 1) as f64;
                CurvePoint {
                    eps_a: e,
                    eps_v: 0.3 * e - dilation * e * e,
                    eta: 1.2 * (1.0 - (-40.0 * e).exp()),
                    step: k as u64,
                    ..CurvePoint::default()
                }
            })
            .collect()
    }

    fn draw(plot: CurvePlot, series: &[CurveSeries<'_>]) -> String {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(plot.file_name());
        plot_curves(&path, plot, "Test E1: p0 = 100 kPa", series).unwrap();
        let leftovers = std::fs::read_dir(dir.path()).unwrap().count();
        assert_eq!(leftovers, 1, "the temporary file is gone");
        std::fs::read_to_string(&path).unwrap()
    }

    #[test]
    fn one_series_has_labels_title_and_no_legend() {
        let points = curve(200, 4.0);
        let one = [CurveSeries {
            label: "run-a",
            points: &points,
        }];
        let svg = draw(CurvePlot::StressRatio, &one);
        assert!(svg.contains("<svg") && svg.trim_end().ends_with("</svg>"));
        assert!(svg.contains(AXIAL_STRAIN_LABEL));
        assert!(svg.contains("stress ratio eta = q/p (-)"));
        assert!(svg.contains("Test E1: p0 = 100 kPa"));
        assert!(!svg.contains("run-a"), "no legend for a single series");
        let svg = draw(CurvePlot::VolumetricStrain, &one);
        assert!(svg.contains("volumetric strain eps_v (%) (contraction positive)"));
    }

    #[test]
    fn two_series_overlay_with_legend() {
        let (a, b) = (curve(150, 4.0), curve(90, 2.0));
        let two = [
            CurveSeries {
                label: "dense <h=1>",
                points: &a,
            },
            CurveSeries {
                label: "loose",
                points: &b,
            },
        ];
        for plot in [CurvePlot::StressRatio, CurvePlot::VolumetricStrain] {
            let svg = draw(plot, &two);
            assert!(svg.contains("dense &lt;h=1&gt;") && svg.contains("loose"));
            assert!(svg.contains("rgb(0,114,178)") || svg.contains("#0072B2"));
            assert!(svg.matches("<polyline").count() >= 2, "{svg}");
        }
    }

    #[test]
    fn empty_constant_and_non_finite_data_do_not_panic() {
        let mut nan = curve(50, 4.0);
        nan[10].eta = f64::NAN;
        nan[11].eps_v = f64::INFINITY;
        nan[30].eps_a = f64::NAN;
        nan[40].eta = 1e300;
        let mut constant = curve(5, 0.0);
        for p in &mut constant {
            (p.eps_a, p.eps_v, p.eta) = (0.01, 0.0, 0.5);
        }
        let all_nan = vec![
            CurvePoint {
                eta: f64::NAN,
                ..CurvePoint::default()
            };
            3
        ];
        let cases: [&[CurvePoint]; 5] = [&[], &nan, &constant, &all_nan, &nan[..1]];
        for points in cases {
            for plot in [CurvePlot::StressRatio, CurvePlot::VolumetricStrain] {
                let s = [CurveSeries { label: "x", points }];
                assert!(draw(plot, &s).contains("<svg"));
            }
        }
        assert!(draw(CurvePlot::StressRatio, &[]).contains("<svg"));
        let s = [
            CurveSeries {
                label: "a",
                points: &[],
            },
            CurveSeries {
                label: "b",
                points: &nan,
            },
        ];
        let svg = draw(CurvePlot::VolumetricStrain, &s);
        assert!(
            svg.contains(">\na\n</text>") && svg.contains(">\nb\n</text>"),
            "{svg}"
        );
    }

    #[test]
    fn failures_name_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("missing-dir").join("eta.svg");
        let e = plot_curves(&path, CurvePlot::StressRatio, "t", &[]).unwrap_err();
        let message = e.to_string();
        assert!(
            message.contains("missing-dir") && !message.contains('\n'),
            "{message}"
        );
    }
}
