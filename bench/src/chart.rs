//! Line charts of the benchmarks: one chart written twice, as SVG and as PNG (plotters; the
//! PNG's text is drawn with the Ubuntu typeface that egui ships, through ab_glyph, so no
//! system font is needed).

use bevy_point_springs::core::cloud::io::write_atomically_to_path;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::element::DashedPathElement;
use plotters::prelude::*;

use crate::failure::Failure;

/// Chart size, pixels.
const SIZE: (u32, u32) = (900, 560);

/// The family name the typeface is registered under.
const FAMILY: &str = "sans-serif";

/// Series colours, in order (then repeated).
const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
];

/// One line of a chart.
#[derive(Debug, Clone)]
pub struct Series {
    /// Its name in the legend.
    pub name: String,
    /// Its points, drawn in order.
    pub points: Vec<(f64, f64)>,
    /// Its colour, an index into the palette (`None`: its place among the series).
    pub colour: Option<usize>,
    /// Dashes of this many pixels with as many between (`None`: a solid line).
    pub dash: Option<u32>,
}

impl Series {
    /// A solid line in the next colour.
    pub fn new(name: String, points: Vec<(f64, f64)>) -> Self {
        Self {
            name,
            points,
            colour: None,
            dash: None,
        }
    }
}

/// A chart: its text, its axes and its lines.
#[derive(Debug, Clone)]
pub struct Chart {
    /// The title.
    pub title: String,
    /// The x axis's label.
    pub x_label: String,
    /// The y axis's label.
    pub y_label: String,
    /// Whether the x axis is logarithmic (its values must be positive).
    pub log_x: bool,
    /// Whether the y axis is logarithmic (its values must be positive).
    pub log_y: bool,
    /// The lines.
    pub series: Vec<Series>,
    /// Points drawn as large rings over the lines (a Pareto front, say), with their name.
    pub marked: Option<(String, Vec<(f64, f64)>)>,
    /// Whether the legend goes in the upper right corner (else the lower right).
    pub legend_upper: bool,
}

impl Chart {
    /// Writes the chart to `stem` with the extensions `svg` and `png`, returning both paths.
    pub fn write(&self, stem: &Path) -> Result<[PathBuf; 2], Failure> {
        register_font()?;
        let svg = stem.with_extension("svg");
        let png = stem.with_extension("png");
        write_atomically_to_path(&svg, |tmp| {
            Ok(self.draw(SVGBackend::new(tmp, SIZE).into_drawing_area())?)
        })
        .map_err(|e| Failure::other(format!("{}: {e}", svg.display())))?;
        write_atomically_to_path(&png, |tmp| {
            Ok(self.draw(BitMapBackend::new(tmp, SIZE).into_drawing_area())?)
        })
        .map_err(|e| Failure::other(format!("{}: {e}", png.display())))?;
        Ok([svg, png])
    }

    /// Draws on one backend, with the axes the chart asks for.
    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String> {
        let points = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .chain(self.marked.iter().flat_map(|m| m.1.iter()));
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in points {
            if (self.log_x && x <= 0.0)
                || (self.log_y && y <= 0.0)
                || !x.is_finite()
                || !y.is_finite()
            {
                continue;
            }
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if x0 > x1 {
            return Err("no point to draw".to_owned());
        }
        let pad = |lo: f64, hi: f64, log: bool| {
            if log {
                (lo / 1.3, hi * 1.3)
            } else {
                let d = (hi - lo).max(hi.abs() * 1e-3).max(1e-9) * 0.08;
                (lo - d, hi + d)
            }
        };
        let (x0, x1) = pad(x0, x1, self.log_x);
        let (y0, y1) = pad(y0, y1, self.log_y);
        match (self.log_x, self.log_y) {
            (true, true) => self.plot(root, (x0..x1).log_scale(), (y0..y1).log_scale()),
            (true, false) => self.plot(root, (x0..x1).log_scale(), y0..y1),
            (false, true) => self.plot(root, x0..x1, (y0..y1).log_scale()),
            (false, false) => self.plot(root, x0..x1, y0..y1),
        }
    }

    /// Draws with the coordinates `x` and `y`.
    fn plot<DB, X, Y>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
        x: X,
        y: Y,
    ) -> Result<(), String>
    where
        DB: DrawingBackend,
        X: AsRangedCoord<Value = f64>,
        Y: AsRangedCoord<Value = f64>,
        X::CoordDescType: ValueFormatter<f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let e = |e: &dyn std::fmt::Display| e.to_string();
        root.fill(&WHITE).map_err(|x| e(&x))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(&self.title, (FAMILY, 22))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d(x, y)
            .map_err(|x| e(&x))?;
        let (log_x, log_y) = (self.log_x, self.log_y);
        let x_text = move |v: &f64| tick_label(*v, log_x);
        let y_text = move |v: &f64| tick_label(*v, log_y);
        chart
            .configure_mesh()
            .x_label_formatter(&x_text)
            .y_label_formatter(&y_text)
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style((FAMILY, 14))
            .axis_desc_style((FAMILY, 16))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(|x| e(&x))?;
        for (i, s) in self.series.iter().enumerate() {
            let colour = COLOURS[s.colour.unwrap_or(i) % COLOURS.len()];
            let style = ShapeStyle::from(colour).stroke_width(2);
            let drawn = match s.dash {
                None => chart.draw_series(LineSeries::new(s.points.iter().copied(), style)),
                Some(dash) => chart.draw_series(DashedLineSeries::new(
                    s.points.iter().copied(),
                    dash,
                    dash,
                    style,
                )),
            };
            let dash = s.dash.map_or(18, |d| d.min(8));
            drawn
                .map_err(|x| e(&x))?
                .label(s.name.as_str())
                .legend(move |(x, y)| {
                    DashedPathElement::new(vec![(x, y), (x + 18, y)], dash, dash, style)
                });
            chart
                .draw_series(s.points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(|x| e(&x))?;
        }
        if let Some((name, points)) = &self.marked {
            let style = ShapeStyle::from(BLACK).stroke_width(2);
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 8, style)))
                .map_err(|x| e(&x))?
                .label(name.as_str())
                .legend(move |(x, y)| Circle::new((x + 9, y), 6, style));
        }
        chart
            .configure_series_labels()
            .label_font((FAMILY, 14))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .position(if self.legend_upper {
                SeriesLabelPosition::UpperRight
            } else {
                SeriesLabelPosition::LowerRight
            })
            .draw()
            .map_err(|x| e(&x))?;
        root.present().map_err(|x| e(&x))
    }
}

/// A tick's text: on a logarithmic axis only 1, 2 and 5 times a power of ten are labelled
/// (the others stay grid lines), and numbers carry no more digits than they need.
fn tick_label(v: f64, log: bool) -> String {
    if log {
        let decade = 10f64.powf(v.abs().log10().floor());
        let lead = v / decade;
        if ![1.0, 2.0, 5.0].iter().any(|m| (lead - m).abs() < 1e-6) {
            return String::new();
        }
    }
    let text = format!("{v:.4}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_owned()
    } else {
        text.to_owned()
    }
}

/// Registers the typeface once per process (every call gives that one attempt's outcome).
fn register_font() -> Result<(), Failure> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let registered = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(
            FAMILY,
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .is_ok()
    });
    if registered {
        Ok(())
    } else {
        Err(Failure::other("the chart typeface could not be read"))
    }
}
