//! Plots on request: the RCM point cloud of the paper's Figure 9 (three projections about the
//! pivot), the per-sample axis residuals (built by dvrk-calib) and the joint tracking of Figure 10
//! ([`crate::run::Trace::figure`]). A figure is a grid of panels of scatter points and lines,
//! drawn by `plotters` as SVG or PNG with a title, axis labels with units and a legend of the
//! labelled series; the text is DejaVu Sans, embedded (no system font is needed). Lives in
//! dvrk-sim (dependency order kin <- sim <- calib); dvrk-calib re-exports it as `dvrk_calib::plot`.

use crate::error::{Result, SimError};
use nalgebra::Vector3;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::Path;

/// One scatter panel.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// Points (x, y) in the panel's units.
    pub points: Vec<(f64, f64)>,
    /// Highlighted points (drawn as red crosses).
    pub marks: Vec<(f64, f64)>,
    /// Same scale on both axes (projections of a point cloud).
    pub equal: bool,
    /// Polylines drawn over the points.
    pub lines: Vec<Line>,
    /// Scatter series in their own colours (opaque dots), in order over the points, under the lines.
    pub scatter: Vec<Scatter>,
}

/// A scatter series of a panel in one colour.
#[derive(Debug, Clone, PartialEq)]
pub struct Scatter {
    /// Points (x, y) in the panel's units.
    pub points: Vec<(f64, f64)>,
    /// RGB colour.
    pub color: [u8; 3],
    /// Legend entry (none when empty).
    pub label: String,
}

/// A polyline of a panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// Vertices (x, y) in the panel's units.
    pub points: Vec<(f64, f64)>,
    /// RGB colour.
    pub color: [u8; 3],
    /// Stroke width (px, odd).
    pub width: usize,
    /// Legend entry (none when empty).
    pub label: String,
}

/// Panels in a grid, filled row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    pub title: String,
    pub panels: Vec<Panel>,
    /// Panels per row; 0 puts every panel in one row.
    pub columns: usize,
    /// Width and height of one panel (px).
    pub panel_size: (usize, usize),
}

/// The default panel size (px).
pub const PANEL_SIZE: (usize, usize) = (360, 340);
/// Height of the title band above the panels (px).
const TOP: usize = 20;

/// Colour of the scatter points (and of the commanded trajectory in tracking plots).
pub const BLUE: [u8; 3] = [31, 119, 180];
/// Colour of a second series (the measured trajectory in tracking plots).
pub const ORANGE: [u8; 3] = [255, 127, 14];
/// Colour of a third series (the tracking error).
pub const GREEN: [u8; 3] = [44, 160, 44];

/// The RCM cloud (tracker frame, m) about `pivot`: x-y, x-z and y-z projections in mm.
pub fn cloud(points: &[Vector3<f64>], pivot: &Vector3<f64>, title: &str) -> Result<Figure> {
    if points.is_empty() {
        return Err(SimError::Build("plot: no point to draw".into()));
    }
    let rel: Vec<Vector3<f64>> = points.iter().map(|p| (p - pivot) * 1e3).collect();
    let panel = |i: usize, j: usize, n: [&str; 2]| Panel {
        title: format!("{} - {}", n[0], n[1]),
        x_label: format!("{} (mm)", n[0]),
        y_label: format!("{} (mm)", n[1]),
        points: rel.iter().map(|p| (p[i], p[j])).collect(),
        marks: vec![(0.0, 0.0)],
        equal: true,
        lines: vec![],
        scatter: vec![],
    };
    Ok(Figure {
        title: title.into(),
        panels: vec![panel(0, 1, ["x", "y"]), panel(0, 2, ["x", "z"]), panel(1, 2, ["y", "z"])],
        columns: 0,
        panel_size: PANEL_SIZE,
    })
}

/// A figure title's name for the file `source`: its file name (a recording's whole path does
/// not fit a title line).
pub fn file_label(source: &str) -> String {
    Path::new(source).file_name().map_or(source.to_string(), |f| f.to_string_lossy().into_owned())
}

/// The image formats [`Figure::encode`] writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    Png,
    Svg,
}

/// The image format `path`'s extension names (.png, .svg; any case), or an error naming
/// `--plot` and the path: checked before a long computation whose result is plotted.
pub fn check_path(path: &Path) -> Result<ImageFormat> {
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("svg") => Ok(ImageFormat::Svg),
        Some("png") => Ok(ImageFormat::Png),
        _ => Err(SimError::field(path.display().to_string(), "--plot", "unknown image format; valid: .png, .svg")),
    }
}

/// Axis range with a margin, never empty.
fn range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v.filter(|x| x.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-9);
    (lo - pad, hi + pad)
}

/// A panel's axis ranges: every point, mark, line and scatter point in, with a margin; the
/// same scale on both axes when the panel asks.
fn ranges(p: &Panel) -> ((f64, f64), (f64, f64)) {
    let all = || p.points.iter().chain(&p.marks).chain(p.lines.iter().flat_map(|l| &l.points)).chain(p.scatter.iter().flat_map(|s| &s.points));
    let mut x = range(all().map(|q| q.0));
    let mut y = range(all().map(|q| q.1));
    if p.equal {
        let half = 0.5 * (x.1 - x.0).max(y.1 - y.0);
        let (cx, cy) = (0.5 * (x.0 + x.1), 0.5 * (y.0 + y.1));
        x = (cx - half, cx + half);
        y = (cy - half, cy + half);
    }
    (x, y)
}

/// A tick label on an axis spanning `lo..hi`: as many decimals as a fifth of the span needs
/// (so 0.3 +- 1e-6 reads 0.3000010, not 0.300 five times), zero for round-off of zero, and
/// exponent form for values that small.
fn tick(v: f64, lo: f64, hi: f64) -> String {
    let span = (hi - lo).abs().max(1e-300);
    if v.abs() < 1e-9 * span {
        return "0".into();
    }
    let decimals = (-(span / 5.0).log10().floor() + 1.0).clamp(0.0, 12.0) as usize;
    if lo.abs().max(hi.abs()) < 1e-3 && decimals > 4 {
        format!("{v:.1e}")
    } else {
        format!("{v:.decimals$}")
    }
}

impl Figure {
    fn cols(&self) -> usize {
        if self.columns == 0 {
            self.panels.len().max(1)
        } else {
            self.columns
        }
    }

    /// Image size (px): the panel grid and the title band above it.
    pub fn size(&self) -> (usize, usize) {
        let cols = self.cols();
        let rows = self.panels.len().div_ceil(cols).max(1);
        (cols.min(self.panels.len().max(1)) * self.panel_size.0, TOP + rows * self.panel_size.1)
    }

    /// SVG or PNG bytes, chosen by `path`'s extension.
    pub fn encode(&self, path: &Path) -> Result<Vec<u8>> {
        match check_path(path)? {
            ImageFormat::Svg => Ok(self.svg().into_bytes()),
            ImageFormat::Png => self.png().map_err(|e| SimError::field(path.display().to_string(), "--plot", e.to_string())),
        }
    }

    /// The figure as SVG.
    pub fn svg(&self) -> String {
        let (w, h) = self.size();
        let mut out = String::new();
        {
            let root = SVGBackend::with_string(&mut out, (w as u32, h as u32)).into_drawing_area();
            // Drawing into a string cannot fail but for a font, which is embedded.
            let _ = self.draw(root);
        }
        out
    }

    /// The figure as an RGB PNG.
    pub fn png(&self) -> std::result::Result<Vec<u8>, png::EncodingError> {
        let (w, h, px) = self.pixels();
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, w as u32, h as u32);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.write_header()?.write_image_data(&px)?;
        Ok(out)
    }

    /// The PNG's pixels: (width, height, RGB bytes row by row).
    pub fn pixels(&self) -> (usize, usize, Vec<u8>) {
        let (w, h) = self.size();
        let mut px = vec![255u8; w * h * 3];
        {
            let root = BitMapBackend::with_buffer(&mut px, (w as u32, h as u32)).into_drawing_area();
            let _ = self.draw(root);
        }
        (w, h, px)
    }

    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, plotters::coord::Shift>) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        register_fonts();
        root.fill(&WHITE)?;
        let (title, body) = root.split_vertically(TOP as u32);
        title.draw_text(&self.title, &TextStyle::from(("sans-serif", 13).into_font()).color(&BLACK), (8, 4))?;
        let cols = self.cols();
        let rows = self.panels.len().div_ceil(cols).max(1);
        let areas = body.split_evenly((rows, cols));
        let rgb = |c: [u8; 3]| RGBColor(c[0], c[1], c[2]);
        for (p, area) in self.panels.iter().zip(areas) {
            let ((x0, x1), (y0, y1)) = ranges(p);
            let mut chart = ChartBuilder::on(&area)
                .caption(&p.title, ("sans-serif", 12))
                .margin(6)
                .x_label_area_size(34)
                .y_label_area_size(62)
                .build_cartesian_2d(x0..x1, y0..y1)?;
            chart
                .configure_mesh()
                .x_desc(p.x_label.as_str())
                .y_desc(p.y_label.as_str())
                .x_labels(5)
                .y_labels(5)
                .x_label_formatter(&|v| tick(*v, x0, x1))
                .y_label_formatter(&|v| tick(*v, y0, y1))
                .label_style(("sans-serif", 10))
                .axis_desc_style(("sans-serif", 11))
                .light_line_style(RGBColor(235, 235, 235))
                .bold_line_style(RGBColor(215, 215, 215))
                .draw()?;
            if !p.points.is_empty() {
                chart.draw_series(p.points.iter().map(|&q| Circle::new(q, 1, rgb(BLUE).mix(0.35).filled())))?;
            }
            let mut labelled = false;
            for sc in &p.scatter {
                let c = rgb(sc.color);
                let series = chart.draw_series(sc.points.iter().filter(|(x, y)| x.is_finite() && y.is_finite()).map(|&q| Circle::new(q, 1, c.filled())))?;
                if !sc.label.is_empty() {
                    series.label(sc.label.as_str()).legend(move |(x, y)| Circle::new((x + 8, y), 3, c.filled()));
                    labelled = true;
                }
            }
            for l in &p.lines {
                let style = ShapeStyle { color: rgb(l.color).to_rgba(), filled: false, stroke_width: l.width.max(1) as u32 };
                let series = chart.draw_series(LineSeries::new(l.points.iter().copied().filter(|(x, y)| x.is_finite() && y.is_finite()), style))?;
                if !l.label.is_empty() {
                    series.label(l.label.as_str()).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], style));
                    labelled = true;
                }
            }
            if !p.marks.is_empty() {
                chart.draw_series(p.marks.iter().map(|&q| Cross::new(q, 6, RED.stroke_width(2))))?;
            }
            if labelled {
                chart
                    .configure_series_labels()
                    .label_font(("sans-serif", 10))
                    .background_style(WHITE.mix(0.85))
                    .border_style(RGBColor(160, 160, 160))
                    .position(SeriesLabelPosition::UpperRight)
                    .draw()?;
            }
        }
        root.present()
    }
}

/// DejaVu Sans as plotters' "sans-serif", once per process.
fn register_fonts() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The embedded font parses; were it not to, the text would be missing, not the plot.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
        let _ = plotters::style::register_font("sans-serif", FontStyle::Bold, dejavu::sans::bold());
    });
}
