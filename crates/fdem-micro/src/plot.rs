//! `force_distribution.svg`: the distribution of `F_n / mean(F_n)` of one or several runs
//! (paper Figs 9/10 style), on a linear and on a logarithmic density axis side by side.

use crate::MicroError;
use crate::snapshot::write_atomically;
use crate::stats::{BINS, Histogram, STRONG_RATIO, WEAK_RATIO};
use fdem_core::plot::{
    self as figure, Draw, IntoLogRange, RGBColor, SeriesLabelPosition, Style, colour,
};
use std::path::Path;

/// One curve of the plot.
#[derive(Clone, Copy, Debug)]
pub struct Series<'a> {
    /// Legend entry (for example the run directory's name).
    pub label: &'a str,
    /// The distribution.
    pub histogram: &'a Histogram,
}

/// Layout of both panels.
const STYLE: Style = Style {
    caption_size: 20,
    margin: 15,
    x_label_area: 45,
    y_label_area: 65,
    light_lines: None,
    axis_desc_size: None,
    label_size: None,
    legend_size: None,
};

/// Colour of the vertical lines at the weak and strong thresholds.
const THRESHOLD: RGBColor = RGBColor(170, 0, 0);

/// Draws the distributions into an SVG file at `path` (written atomically).
pub fn plot_distributions(path: &Path, series: &[Series<'_>]) -> Result<(), MicroError> {
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
    let svg = figure::svg((1200, 500), |root| {
        let (left, right) = root.split_horizontally(600);
        // Linear density, step outline per bin.
        let mut chart = STYLE.chart(
            &left,
            "Normal contact forces (red: weak < 0.2, strong > 4)",
            0f64..x_max,
            0f64..1.1 * y_max,
        )?;
        chart.draw_axes(&STYLE, "F_n / mean(F_n)", "probability density")?;
        for (i, s) in series.iter().enumerate() {
            let h = s.histogram;
            let steps = (0..h.density.len()).flat_map(|k| {
                let x0 = k as f64 * h.bin_width;
                [(x0, h.density[k]), (x0 + h.bin_width, h.density[k])]
            });
            chart.draw_line(steps, colour(i), Some(s.label))?;
        }
        for threshold in [WEAK_RATIO, STRONG_RATIO] {
            let (from, to) = ((threshold, 0.0), (threshold, 1.1 * y_max));
            chart.draw_reference_line(from, to, THRESHOLD)?;
        }
        chart.draw_legend(&STYLE, SeriesLabelPosition::UpperRight)?;

        // Logarithmic density: bin centres, empty bins left out.
        let mut chart = STYLE.chart(
            &right,
            "Normal contact forces (log scale)",
            0f64..x_max,
            (log_min..log_max).log_scale(),
        )?;
        chart.draw_axes(&STYLE, "F_n / mean(F_n)", "probability density (log)")?;
        for (i, s) in series.iter().enumerate() {
            let h = s.histogram;
            let points: Vec<(f64, f64)> = (0..h.density.len())
                .filter(|&k| h.density[k] > 0.0)
                .map(|k| (h.centre(k), h.density[k]))
                .collect();
            chart.draw_line(points.iter().copied(), colour(i), Some(s.label))?;
            chart.draw_dots(points.iter().copied(), colour(i))?;
        }
        for threshold in [WEAK_RATIO, STRONG_RATIO] {
            let (from, to) = ((threshold, log_min), (threshold, log_max));
            chart.draw_reference_line(from, to, THRESHOLD)?;
        }
        chart.draw_legend(&STYLE, SeriesLabelPosition::UpperRight)
    })
    .map_err(|message| MicroError::Plot {
        path: path.to_path_buf(),
        message,
    })?;
    write_atomically(path, svg.as_bytes())
}
