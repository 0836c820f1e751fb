//! The project's plot style and the scaffolding of its SVG figures (plotters, drawn into a
//! string): palette, fonts, line widths, chart layout, axes, legend and the series kinds
//! the figures use. Each figure (the triaxial curves, the force distributions) states only
//! its data, titles and sizes.
//!
//! Drawing errors are returned as the plotting library's message; the caller names the
//! file. Writing the SVG text to disk is [`crate::fs::write_atomically`].

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::prelude::*;

/// The plotting types a figure names: colours, legend positions and `.log_scale()` on a
/// range.
pub use plotters::prelude::{IntoLogRange, RGBColor, SeriesLabelPosition};

/// Line colours, cycled by [`colour`]: the Okabe-Ito colour-blind-safe palette.
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(240, 228, 66),
];

/// The font family of every text.
pub const FONT: &str = "sans-serif";

/// Stroke width of a data series (pixels).
pub const SERIES_WIDTH: u32 = 2;

/// Radius of the dots that mark points (pixels).
pub const DOT_RADIUS: i32 = 3;

/// Length of the line sample in front of a legend entry (pixels).
const LEGEND_SAMPLE: i32 = 20;

/// The colour of series number `index`, cycling through [`PALETTE`].
pub fn colour(index: usize) -> RGBColor {
    PALETTE[index % PALETTE.len()]
}

/// The drawing area of a figure (or of one panel of it).
pub type Area<'b> = DrawingArea<SVGBackend<'b>, Shift>;

/// A chart with axes `X` and `Y` on an [`Area`].
pub type Chart<'a, 'b, X, Y> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<X, Y>>;

/// The result of a drawing step: the plotting library's message on failure.
pub type DrawResult<T = ()> = Result<T, String>;

fn message(e: impl ToString) -> String {
    e.to_string()
}

/// Draws a figure of `size` pixels into SVG text: a white background, then `draw` on the
/// whole area.
///
/// # Errors
/// The first failure of `draw` or of the backend.
pub fn svg(size: (u32, u32), draw: impl FnOnce(&Area<'_>) -> DrawResult) -> DrawResult<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(message)?;
        draw(&root)?;
        root.present().map_err(message)?;
    }
    Ok(svg)
}

/// Sizes of one chart: caption, margin, label areas and the fonts of the axes and legend.
/// Font sizes left `None` are the plotting library's defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Style {
    /// Font size of the caption (title) above the chart.
    pub caption_size: u32,
    /// Margin around the chart (pixels).
    pub margin: u32,
    /// Height of the area below the x axis that holds its labels and description.
    pub x_label_area: u32,
    /// Width of the area left of the y axis that holds its labels and description.
    pub y_label_area: u32,
    /// Colour of the light grid lines.
    pub light_lines: Option<RGBColor>,
    /// Font size of the axis descriptions.
    pub axis_desc_size: Option<u32>,
    /// Font size of the tick labels.
    pub label_size: Option<u32>,
    /// Font size of the legend entries.
    pub legend_size: Option<u32>,
}

impl Style {
    /// A chart titled `title` on `area` with axes over `x` and `y` (ranges, possibly
    /// `.log_scale()`).
    ///
    /// # Errors
    /// The plotting library's message.
    pub fn chart<'a, 'b, X: AsRangedCoord, Y: AsRangedCoord>(
        &self,
        area: &'a Area<'b>,
        title: &str,
        x: X,
        y: Y,
    ) -> DrawResult<Chart<'a, 'b, X::CoordDescType, Y::CoordDescType>> {
        ChartBuilder::on(area)
            .caption(title, (FONT, self.caption_size))
            .margin(self.margin)
            .x_label_area_size(self.x_label_area)
            .y_label_area_size(self.y_label_area)
            .build_cartesian_2d(x, y)
            .map_err(message)
    }
}

/// The shape of a point marker ([`Draw::draw_markers`]), [`MARKER_SIZE`] pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Marker {
    /// A filled circle.
    Circle,
    /// A filled upward triangle.
    Triangle,
    /// An open square.
    Square,
}

/// Size of the point markers (pixels).
pub const MARKER_SIZE: i32 = 5;

/// Drawing on a [`Chart`] in the project's style: axes, legend and the kinds of series the
/// figures use. Implemented for every chart with `f64` axes (linear or logarithmic).
pub trait Draw {
    /// The axes, grid and tick labels, with the axis descriptions, sized by `style`.
    ///
    /// # Errors
    /// The plotting library's message.
    fn draw_axes(&mut self, style: &Style, x_desc: &str, y_desc: &str) -> DrawResult;

    /// The legend of the labelled series at `position`, on a translucent white box with a
    /// black border, in `style`'s legend font.
    ///
    /// # Errors
    /// The plotting library's message.
    fn draw_legend(&mut self, style: &Style, position: SeriesLabelPosition) -> DrawResult;

    /// A data series: a line through `points` in `colour` ([`SERIES_WIDTH`] wide), with a
    /// legend entry when `label` is given.
    ///
    /// # Errors
    /// The plotting library's message.
    fn draw_line(
        &mut self,
        points: impl IntoIterator<Item = (f64, f64)>,
        colour: RGBColor,
        label: Option<&str>,
    ) -> DrawResult;

    /// Filled dots of [`DOT_RADIUS`] at `points`, in `colour`.
    ///
    /// # Errors
    /// The plotting library's message.
    fn draw_dots(
        &mut self,
        points: impl IntoIterator<Item = (f64, f64)>,
        colour: RGBColor,
    ) -> DrawResult;

    /// Points with vertical error bars: a [`Marker`] of `colour` at each `(x, y)` and a
    /// 1-pixel bar from `y - spread` to `y + spread` (none where the spread is 0 or not
    /// finite), with a legend entry when `label` is given.
    ///
    /// # Errors
    /// The plotting library's message.
    fn draw_markers(
        &mut self,
        points: &[(f64, f64, f64)],
        colour: RGBColor,
        marker: Marker,
        label: Option<&str>,
    ) -> DrawResult;

    /// A thin (1 pixel) reference line from `from` to `to` in `colour`: a threshold, a
    /// zero line. It has no legend entry.
    ///
    /// # Errors
    /// The plotting library's message.
    fn draw_reference_line(
        &mut self,
        from: (f64, f64),
        to: (f64, f64),
        colour: RGBColor,
    ) -> DrawResult;
}

impl<'a, 'b: 'a, X, Y> Draw for Chart<'a, 'b, X, Y>
where
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    fn draw_axes(&mut self, style: &Style, x_desc: &str, y_desc: &str) -> DrawResult {
        let mut mesh = self.configure_mesh();
        mesh.x_desc(x_desc).y_desc(y_desc);
        if let Some(colour) = style.light_lines {
            mesh.light_line_style(colour);
        }
        if let Some(size) = style.axis_desc_size {
            mesh.axis_desc_style((FONT, size));
        }
        if let Some(size) = style.label_size {
            mesh.label_style((FONT, size));
        }
        mesh.draw().map_err(message)
    }

    fn draw_legend(&mut self, style: &Style, position: SeriesLabelPosition) -> DrawResult {
        let mut labels = self.configure_series_labels();
        labels
            .position(position)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK);
        if let Some(size) = style.legend_size {
            labels.label_font((FONT, size));
        }
        labels.draw().map_err(message)
    }

    fn draw_line(
        &mut self,
        points: impl IntoIterator<Item = (f64, f64)>,
        colour: RGBColor,
        label: Option<&str>,
    ) -> DrawResult {
        let style = colour.stroke_width(SERIES_WIDTH);
        let drawn = self
            .draw_series(LineSeries::new(points, style))
            .map_err(message)?;
        if let Some(label) = label {
            drawn.label(label).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + LEGEND_SAMPLE, y)], style)
            });
        }
        Ok(())
    }

    fn draw_dots(
        &mut self,
        points: impl IntoIterator<Item = (f64, f64)>,
        colour: RGBColor,
    ) -> DrawResult {
        let dots = points
            .into_iter()
            .map(|p| Circle::new(p, DOT_RADIUS, colour.filled()));
        self.draw_series(dots).map(drop).map_err(message)
    }

    fn draw_markers(
        &mut self,
        points: &[(f64, f64, f64)],
        colour: RGBColor,
        marker: Marker,
        label: Option<&str>,
    ) -> DrawResult {
        let bars = points
            .iter()
            .filter(|p| p.2.is_finite() && p.2 > 0.0)
            .map(|&(x, y, e)| {
                PathElement::new(vec![(x, y - e), (x, y + e)], colour.stroke_width(1))
            });
        self.draw_series(bars).map_err(message)?;
        let r = MARKER_SIZE;
        let at = |&(x, y, _): &(f64, f64, f64)| EmptyElement::at((x, y));
        // One series per shape: a series holds one concrete element type.
        let drawn = match marker {
            Marker::Circle => self.draw_series(
                points
                    .iter()
                    .map(|p| at(p) + Circle::new((0, 0), r, colour.filled())),
            ),
            Marker::Triangle => self.draw_series(
                points
                    .iter()
                    .map(|p| at(p) + TriangleMarker::new((0, 0), r + 1, colour.filled())),
            ),
            Marker::Square => self.draw_series(
                points
                    .iter()
                    .map(|p| at(p) + Rectangle::new([(-r, -r), (r, r)], colour.stroke_width(2))),
            ),
        }
        .map_err(message)?;
        if let Some(label) = label {
            let drawn = drawn.label(label);
            let r = MARKER_SIZE;
            let at = |(x, y): (i32, i32)| EmptyElement::at((x + LEGEND_SAMPLE / 2, y));
            // One closure per shape: the legend takes a concrete element type.
            match marker {
                Marker::Circle => {
                    drawn.legend(move |p| at(p) + Circle::new((0, 0), r, colour.filled()))
                }
                Marker::Triangle => drawn
                    .legend(move |p| at(p) + TriangleMarker::new((0, 0), r + 1, colour.filled())),
                Marker::Square => drawn.legend(move |p| {
                    at(p) + Rectangle::new([(-r, -r), (r, r)], colour.stroke_width(2))
                }),
            };
        }
        Ok(())
    }

    fn draw_reference_line(
        &mut self,
        from: (f64, f64),
        to: (f64, f64),
        colour: RGBColor,
    ) -> DrawResult {
        let line = LineSeries::new([from, to], colour.stroke_width(1));
        self.draw_series(line).map(drop).map_err(message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const STYLE: Style = Style {
        caption_size: 20,
        margin: 10,
        x_label_area: 40,
        y_label_area: 50,
        light_lines: Some(RGBColor(235, 235, 235)),
        axis_desc_size: Some(15),
        label_size: Some(12),
        legend_size: Some(13),
    };

    #[test]
    fn the_palette_cycles() {
        assert_eq!(colour(0), RGBColor(0, 114, 178));
        assert_eq!(colour(PALETTE.len() + 1), PALETTE[1]);
    }

    #[test]
    fn a_figure_with_every_element() {
        let text = svg((400, 300), |root| {
            let mut chart = STYLE.chart(root, "title <t>", 0f64..1.0, (1e-3..1.0).log_scale())?;
            chart.draw_axes(&STYLE, "x (-)", "y (-)")?;
            chart.draw_line([(0.0, 1e-3), (1.0, 0.5)], colour(0), Some("first"))?;
            chart.draw_line([(0.0, 0.1), (1.0, 0.1)], colour(1), None)?;
            chart.draw_dots([(0.5, 0.01)], colour(2))?;
            for (i, marker) in [Marker::Circle, Marker::Triangle, Marker::Square]
                .into_iter()
                .enumerate()
            {
                let x = 0.2 * (i + 1) as f64;
                chart.draw_markers(
                    &[(x, 0.1, 0.05), (x, 0.5, 0.0)],
                    colour(i),
                    marker,
                    Some("marked"),
                )?;
            }
            chart.draw_reference_line((0.2, 1e-3), (0.2, 1.0), RGBColor(170, 0, 0))?;
            chart.draw_legend(&STYLE, SeriesLabelPosition::UpperRight)
        })
        .unwrap();
        assert!(text.starts_with("<svg") && text.trim_end().ends_with("</svg>"));
        for part in [
            "title &lt;t&gt;",
            "x (-)",
            "y (-)",
            "first",
            "<circle",
            "<polyline",
        ] {
            assert!(text.contains(part), "{part} missing");
        }
        assert!(text.contains("rgb(0,114,178)") || text.contains("#0072B2"));
    }

    #[test]
    fn drawing_errors_are_messages() {
        let e = svg((100, 100), |_| Err("broken".to_string())).unwrap_err();
        assert_eq!(e, "broken");
    }
}
