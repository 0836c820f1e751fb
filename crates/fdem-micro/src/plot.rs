//! `force_distribution.svg`: the distribution of `F_n / mean(F_n)` of one or several runs
//! (paper Figs 9/10 style), on a linear and on a logarithmic density axis side by side.

use crate::MicroError;
use crate::snapshot::write_atomically;
use crate::stats::{BINS, Histogram, STRONG_RATIO, WEAK_RATIO};
use plotters::prelude::*;
use std::path::Path;

/// One curve of the plot.
#[derive(Clone, Copy, Debug)]
pub struct Series<'a> {
    /// Legend entry (for example the run directory's name).
    pub label: &'a str,
    /// The distribution.
    pub histogram: &'a Histogram,
}

/// Line colours, cycled (a colour-blind-safe qualitative palette).
const COLOURS: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(240, 228, 66),
];

/// Colour of the vertical lines at the weak and strong thresholds.
const THRESHOLD: RGBColor = RGBColor(170, 0, 0);

fn plot_error(path: &Path) -> impl Fn(String) -> MicroError + '_ {
    move |message| MicroError::Plot {
        path: path.to_path_buf(),
        message,
    }
}

/// Draws the distributions into an SVG file at `path` (written atomically).
pub fn plot_distributions(path: &Path, series: &[Series<'_>]) -> Result<(), MicroError> {
    let err = plot_error(path);
    let mut svg = String::new();
    let x_max = BINS as f64 * crate::stats::BIN_WIDTH;
    let densities = || {
        series
            .iter()
            .flat_map(|s| s.histogram.density.iter().copied())
    };
    let y_max = densities().fold(0.0f64, f64::max).max(1e-3);
    let y_min_positive = densities()
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    let log_max = 10f64.powf(y_max.log10().ceil());
    let log_min = if y_min_positive.is_finite() {
        10f64.powf(y_min_positive.log10().floor())
    } else {
        log_max / 1e3
    }
    .min(log_max / 100.0); // at least two decades, so that the axis has labels
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let (left, right) = root.split_horizontally(600);
        // Linear density, step outline per bin.
        let mut chart = ChartBuilder::on(&left)
            .caption(
                "Normal contact forces (red: weak < 0.2, strong > 4)",
                ("sans-serif", 20),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(65)
            .build_cartesian_2d(0f64..x_max, 0f64..1.1 * y_max)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("F_n / mean(F_n)")
            .y_desc("probability density")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for (i, s) in series.iter().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            let h = s.histogram;
            let steps = (0..h.density.len()).flat_map(|k| {
                let x0 = k as f64 * h.bin_width;
                [(x0, h.density[k]), (x0 + h.bin_width, h.density[k])]
            });
            chart
                .draw_series(LineSeries::new(steps, colour.stroke_width(2)))
                .map_err(|e| err(e.to_string()))?
                .label(s.label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
        }
        for threshold in [WEAK_RATIO, STRONG_RATIO] {
            chart
                .draw_series(LineSeries::new(
                    [(threshold, 0.0), (threshold, 1.1 * y_max)],
                    THRESHOLD.stroke_width(1),
                ))
                .map_err(|e| err(e.to_string()))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;

        // Logarithmic density: bin centres, empty bins left out.
        let mut chart = ChartBuilder::on(&right)
            .caption("Normal contact forces (log scale)", ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(65)
            .build_cartesian_2d(0f64..x_max, (log_min..log_max).log_scale())
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("F_n / mean(F_n)")
            .y_desc("probability density (log)")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for (i, s) in series.iter().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            let h = s.histogram;
            let points: Vec<(f64, f64)> = (0..h.density.len())
                .filter(|&k| h.density[k] > 0.0)
                .map(|k| (h.centre(k), h.density[k]))
                .collect();
            chart
                .draw_series(LineSeries::new(
                    points.iter().copied(),
                    colour.stroke_width(2),
                ))
                .map_err(|e| err(e.to_string()))?
                .label(s.label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(|e| err(e.to_string()))?;
        }
        for threshold in [WEAK_RATIO, STRONG_RATIO] {
            chart
                .draw_series(LineSeries::new(
                    [(threshold, log_min), (threshold, log_max)],
                    THRESHOLD.stroke_width(1),
                ))
                .map_err(|e| err(e.to_string()))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    write_atomically(path, svg.as_bytes())
}
