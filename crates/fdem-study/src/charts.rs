//! The study's figures (SVG): per series the curves (paper Figs 5-8) and the contact-force
//! distributions (Figs 9-10); over all series the cost against h with the ideal h^-4
//! line (Fig 11) and the speed-accuracy chart.

use crate::StudyError;
use crate::report::{Group, Results};
use fdem_core::plot::{
    self as figure, Draw, IntoLogRange, Marker, SeriesLabelPosition, Style, colour,
};
use fdem_micro::plot_distributions;
use fdem_triaxial::{CurvePlot, CurveSeries, plot_curves};
use std::path::{Path, PathBuf};

const STYLE: Style = Style {
    caption_size: 20,
    margin: 15,
    x_label_area: 45,
    y_label_area: 70,
    light_lines: None,
    axis_desc_size: None,
    label_size: None,
    legend_size: Some(13),
};

/// Exponent of the ideal cost law: particles as h^-3 and steps as h^-1 (the step grows
/// with the particle under exact scaling; the paper's Fig 11).
const IDEAL_EXPONENT: f64 = -4.0;

fn draw_error(path: &Path) -> impl Fn(String) -> StudyError + '_ {
    move |message| StudyError::file(path, format!("cannot be drawn: {message}"))
}

fn write_svg(path: &Path, svg: &str) -> Result<(), StudyError> {
    fdem_core::fs::write_atomically(path, svg).map_err(|e| StudyError::io("writing", path, e))
}

/// Writes every chart of `results` into `dir`; returns the files written.
pub fn write_charts(results: &Results, dir: &Path) -> Result<Vec<PathBuf>, StudyError> {
    std::fs::create_dir_all(dir).map_err(|e| StudyError::io("creating", dir, e))?;
    let mut written = Vec::new();
    let mut keys: Vec<(String, String, String)> = results
        .groups
        .iter()
        .map(|g| (g.series.clone(), g.model.clone(), g.order.clone()))
        .collect();
    keys.dedup();
    for (series, model, order) in keys {
        let groups: Vec<&Group> = results
            .groups
            .iter()
            .filter(|g| g.series == series && g.model == model && g.order == order)
            .collect();
        let stem = format!("{series}_{model}_{order}");
        written.extend(series_charts(results, &groups, dir, &stem)?);
    }
    let cost = dir.join("cost.svg");
    cost_chart(results, &cost)?;
    written.push(cost);
    let speed = dir.join("speed_accuracy.svg");
    speed_accuracy_chart(results, &speed)?;
    written.push(speed);
    Ok(written)
}

/// The curves and force distributions of one series in one model (the first seed of
/// each test).
fn series_charts(
    results: &Results,
    groups: &[&Group],
    dir: &Path,
    stem: &str,
) -> Result<Vec<PathBuf>, StudyError> {
    let labels: Vec<String> = groups.iter().map(|g| g.test.clone()).collect();
    let first = |g: &Group| &results.entries[g.entries[0]].measured;
    let curves: Vec<CurveSeries<'_>> = groups
        .iter()
        .zip(&labels)
        .map(|(g, l)| CurveSeries {
            label: l,
            points: &first(g).curve,
        })
        .collect();
    let mut out = Vec::new();
    for (plot, name, what) in [
        (CurvePlot::StressRatio, "eta", "Stress ratio"),
        (CurvePlot::VolumetricStrain, "eps_v", "Volumetric strain"),
    ] {
        let path = dir.join(format!("{stem}_{name}.svg"));
        let title = format!("{what}, {}", stem.replace('_', " "));
        plot_curves(&path, plot, &title, &curves)
            .map_err(|e| StudyError::file(&path, e.to_string()))?;
        out.push(path);
    }
    let histograms: Vec<fdem_micro::Series<'_>> = groups
        .iter()
        .zip(&labels)
        .map(|(g, l)| fdem_micro::Series {
            label: l,
            histogram: &first(g).histogram,
        })
        .collect();
    let path = dir.join(format!("{stem}_forces.svg"));
    plot_distributions(&path, &histograms)?;
    out.push(path);
    Ok(out)
}

/// A log range around the finite positive values, padded by a quarter decade.
fn log_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (0.1, 10.0);
    }
    let pad = 10f64.powf(0.25);
    let (lo, hi) = (lo / pad, hi * pad);
    if hi / lo < 10.0 {
        let mid = (lo * hi).sqrt();
        return (mid / 10f64.sqrt(), mid * 10f64.sqrt());
    }
    (lo, hi)
}

fn marker_of(model: &str) -> Marker {
    match model {
        "rigid" => Marker::Triangle,
        "auto" => Marker::Square,
        _ => Marker::Circle,
    }
}

/// The series of points of one kind: (series, exact scaling, model).
fn kinds(results: &Results) -> Vec<(String, bool, String)> {
    let mut k: Vec<(String, bool, String)> = Vec::new();
    for g in &results.groups {
        let key = (
            g.series.clone(),
            g.exact_scaling || g.reference,
            g.model.clone(),
        );
        if !k.contains(&key) {
            k.push(key);
        }
    }
    k
}

/// Cost of the whole run (preparation and test CPU seconds) against h on log axes, one
/// marker set per series, variant and model, with the ideal `h^-4` line through each
/// reference.
fn cost_chart(results: &Results, path: &Path) -> Result<(), StudyError> {
    let hs = results.groups.iter().map(|g| g.h);
    let (h0, h1) = hs.fold((1.0f64, 1.0f64), |(a, b), h| (a.min(h), b.max(h)));
    let (y0, y1) = log_range(results.groups.iter().flat_map(|g| {
        [
            g.cpu_seconds,
            g.cpu_seconds * (h1 / h0).powf(IDEAL_EXPONENT),
        ]
    }));
    let svg = figure::svg((900, 600), |root| {
        let mut chart = STYLE.chart(
            root,
            "Cost of a run against the coarse-graining factor (line: ideal h^-4)",
            (h0 / 1.1..h1 * 1.1).log_scale(),
            (y0..y1).log_scale(),
        )?;
        chart.draw_axes(&STYLE, "h", "CPU seconds (preparation + test)")?;
        for (i, (series, exact, model)) in kinds(results).into_iter().enumerate() {
            let points: Vec<(f64, f64, f64)> = results
                .groups
                .iter()
                .filter(|g| {
                    g.series == series
                        && g.model == model
                        && (g.exact_scaling || g.reference) == exact
                })
                .map(|g| (g.h, g.cpu_seconds, g.cpu_spread))
                .collect();
            let name = format!(
                "{series}, {}, {model}",
                if exact { "exact scaling" } else { "plain" }
            );
            chart.draw_markers(&points, colour(i), marker_of(&model), Some(&name))?;
        }
        for g in results.groups.iter().filter(|g| g.reference) {
            let line = [h0, h1].map(|h| (h, g.cpu_seconds * (h / g.h).powf(IDEAL_EXPONENT)));
            chart.draw_reference_line(line[0], line[1], figure::RGBColor(120, 120, 120))?;
        }
        chart.draw_legend(&STYLE, SeriesLabelPosition::UpperRight)
    })
    .map_err(draw_error(path))?;
    write_svg(path, &svg)
}

/// Error against the reference (|relative error of the peak eta| and the RMS difference
/// of eta over the reference's peak eta, in %) against the speed-up over the reference;
/// one point per test with its spread over seeds, plain and exact-scaled variants in
/// different colours, models by marker.
fn speed_accuracy_chart(results: &Results, path: &Path) -> Result<(), StudyError> {
    let coarse: Vec<&Group> = results
        .groups
        .iter()
        .filter(|g| !g.reference && !g.errors.is_empty() && g.speedup.is_finite())
        .collect();
    let peak = |g: &Group| {
        let (m, s) = Results::error(g, |e| e.peak_eta);
        (100.0 * m.abs(), 100.0 * s)
    };
    let rms = |g: &Group| {
        let (m, s) = Results::error(g, |e| e.rms_eta);
        let r = results
            .reference_of(g)
            .map_or(f64::NAN, |r| results.metric(r, |m| m.peak_eta).0);
        (100.0 * m / r, 100.0 * s / r)
    };
    let (x0, x1) = log_range(coarse.iter().map(|g| g.speedup));
    let y_max = coarse
        .iter()
        .flat_map(|g| {
            let (a, sa) = peak(g);
            let (b, sb) = rms(g);
            [a + sa, b + sb]
        })
        .filter(|v| v.is_finite())
        .fold(1.0f64, f64::max)
        * 1.15;
    let svg = figure::svg((1300, 560), |root| {
        let (left, right) = root.split_horizontally(650);
        for (area, title, value) in [
            (
                &left,
                "|peak eta error| (%) against speed-up",
                &peak as &dyn Fn(&Group) -> (f64, f64),
            ),
            (
                &right,
                "RMS eta difference / peak eta (%) against speed-up",
                &rms,
            ),
        ] {
            let mut chart = STYLE.chart(area, title, (x0..x1).log_scale(), 0f64..y_max)?;
            chart.draw_axes(&STYLE, "speed-up over the original (CPU time)", "error (%)")?;
            for (i, (series, exact, model)) in kinds(results).into_iter().enumerate() {
                let points: Vec<(f64, f64, f64)> = coarse
                    .iter()
                    .filter(|g| g.series == series && g.model == model && g.exact_scaling == exact)
                    .map(|g| {
                        let (y, s) = value(g);
                        (g.speedup, y, s)
                    })
                    .filter(|p| p.1.is_finite())
                    .collect();
                if points.is_empty() {
                    continue;
                }
                let name = format!(
                    "{series}, {}, {model}",
                    if exact { "exact scaling" } else { "plain" }
                );
                chart.draw_markers(&points, colour(i), marker_of(&model), Some(&name))?;
            }
            chart.draw_legend(&STYLE, SeriesLabelPosition::UpperLeft)?;
        }
        Ok(())
    })
    .map_err(draw_error(path))?;
    write_svg(path, &svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_ranges_span_at_least_a_decade_and_ignore_bad_values() {
        let (a, b) = log_range([2.0, 3.0, f64::NAN, -1.0].into_iter());
        assert!(b / a >= 10.0 - 1e-9 && a < 2.0 && b > 3.0);
        assert_eq!(log_range([f64::NAN].into_iter()), (0.1, 10.0));
    }
}
