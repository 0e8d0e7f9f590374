//! Plots on request: the RCM point cloud of the paper's Figure 9 (three projections about the
//! pivot), the per-sample axis residuals (built by dvrk-calib) and the joint tracking of Figure 10
//! ([`crate::run::Trace::figure`]). A figure is a grid of panels of scatter points and lines,
//! rendered as SVG (with titles) or as PNG (deflate-compressed by the `png` crate, a 5x7 font for
//! ticks and axis names), so no plotting library is needed. Lives in dvrk-sim (dependency order
//! kin <- sim <- calib); dvrk-calib re-exports it as `dvrk_calib::plot`.

use crate::error::{Result, SimError};
use nalgebra::Vector3;
use std::fmt::Write as _;
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
const M: usize = 46;
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
        x_label: format!("{} mm", n[0]),
        y_label: format!("{} mm", n[1]),
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

struct Frame {
    x: (f64, f64),
    y: (f64, f64),
    ox: usize,
    oy: usize,
    w: usize,
    h: usize,
}

impl Frame {
    fn new(fig: &Figure, k: usize) -> Frame {
        let p = &fig.panels[k];
        let all = || p.points.iter().chain(&p.marks).chain(p.lines.iter().flat_map(|l| &l.points)).chain(p.scatter.iter().flat_map(|s| &s.points));
        let mut x = range(all().map(|q| q.0));
        let mut y = range(all().map(|q| q.1));
        if p.equal {
            let half = 0.5 * (x.1 - x.0).max(y.1 - y.0);
            let (cx, cy) = (0.5 * (x.0 + x.1), 0.5 * (y.0 + y.1));
            x = (cx - half, cx + half);
            y = (cy - half, cy + half);
        }
        let cols = fig.cols();
        let (w, h) = fig.panel_size;
        Frame { x, y, ox: (k % cols) * w, oy: TOP + (k / cols) * h, w, h }
    }
    fn px(&self, v: f64) -> f64 {
        self.ox as f64 + M as f64 + (v - self.x.0) / (self.x.1 - self.x.0) * (self.w - 2 * M) as f64
    }
    fn py(&self, v: f64) -> f64 {
        (self.oy + self.h - M) as f64 - (v - self.y.0) / (self.y.1 - self.y.0) * (self.h - 2 * M) as f64
    }
}

fn tick(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.1}")
    } else if v == 0.0 || v.abs() >= 1e-3 {
        format!("{v:.3}")
    } else {
        format!("{v:.1e}")
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
        let (width, height) = self.size();
        let mut s = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" font-family=\"sans-serif\" font-size=\"11\">\n");
        let _ = writeln!(s, "<rect width=\"100%\" height=\"100%\" fill=\"white\"/><text x=\"8\" y=\"14\" font-size=\"13\">{}</text>", xml(&self.title));
        for (k, p) in self.panels.iter().enumerate() {
            let f = Frame::new(self, k);
            let (x0, x1, y0, y1) = (f.px(f.x.0), f.px(f.x.1), f.py(f.y.0), f.py(f.y.1));
            let _ = writeln!(s, "<rect x=\"{x0:.1}\" y=\"{y1:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"none\" stroke=\"black\"/>", x1 - x0, y0 - y1);
            let _ = writeln!(s, "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>", (x0 + x1) / 2.0, y1 - 6.0, xml(&p.title));
            let _ = writeln!(s, "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>", (x0 + x1) / 2.0, y0 + 32.0, xml(&p.x_label));
            let _ = writeln!(s, "<text transform=\"translate({:.1},{:.1}) rotate(-90)\" text-anchor=\"middle\">{}</text>", x0 - 34.0, (y0 + y1) / 2.0, xml(&p.y_label));
            for (v, anchor) in [(f.x.0, "start"), (f.x.1, "end")] {
                let _ = writeln!(s, "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"{anchor}\">{}</text>", f.px(v), y0 + 14.0, tick(v));
            }
            for v in [f.y.0, f.y.1] {
                let _ = writeln!(s, "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>", x0 - 3.0, f.py(v) + 4.0, tick(v));
            }
            if !p.points.is_empty() {
                s += "<g fill=\"#1f77b4\" fill-opacity=\"0.35\">";
                for (x, y) in &p.points {
                    let _ = write!(s, "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"1.3\"/>", f.px(*x), f.py(*y));
                }
                s += "</g>\n";
            }
            for sc in &p.scatter {
                let [r, g, b] = sc.color;
                let _ = write!(s, "<g fill=\"#{r:02x}{g:02x}{b:02x}\">");
                for (x, y) in sc.points.iter().filter(|(x, y)| x.is_finite() && y.is_finite()) {
                    let _ = write!(s, "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"1.3\"/>", f.px(*x), f.py(*y));
                }
                s += "</g>\n";
            }
            for l in &p.lines {
                let [r, g, b] = l.color;
                let _ = write!(s, "<polyline fill=\"none\" stroke=\"#{r:02x}{g:02x}{b:02x}\" stroke-width=\"{}\" points=\"", l.width.max(1));
                for (x, y) in &l.points {
                    let _ = write!(s, "{:.1},{:.1} ", f.px(*x), f.py(*y));
                }
                s += "\"/>\n";
            }
            for (x, y) in &p.marks {
                let (cx, cy) = (f.px(*x), f.py(*y));
                let _ = writeln!(s, "<path d=\"M{:.1} {cy:.1}H{:.1}M{cx:.1} {:.1}V{:.1}\" stroke=\"red\" stroke-width=\"2\"/>", cx - 6.0, cx + 6.0, cy - 6.0, cy + 6.0);
            }
        }
        s += "</svg>\n";
        s
    }

    /// The figure as an RGB PNG.
    pub fn png(&self) -> std::result::Result<Vec<u8>, png::EncodingError> {
        self.raster().encode()
    }

    /// The PNG's pixels: (width, height, RGB bytes row by row).
    pub fn pixels(&self) -> (usize, usize, Vec<u8>) {
        let r = self.raster();
        (r.w, r.h, r.px)
    }

    fn raster(&self) -> Raster {
        let (width, height) = self.size();
        let mut img = Raster { w: width, h: height, px: vec![255u8; width * height * 3] };
        img.text(8, 6, &self.title);
        for (k, p) in self.panels.iter().enumerate() {
            let f = Frame::new(self, k);
            let (x0, x1, y0, y1) = (f.px(f.x.0) as i64, f.px(f.x.1) as i64, f.py(f.y.0) as i64, f.py(f.y.1) as i64);
            for x in x0..=x1 {
                img.set(x, y0, [0, 0, 0]);
                img.set(x, y1, [0, 0, 0]);
            }
            for y in y1..=y0 {
                img.set(x0, y, [0, 0, 0]);
                img.set(x1, y, [0, 0, 0]);
            }
            for (x, y) in &p.points {
                let (cx, cy) = (f.px(*x).round() as i64, f.py(*y).round() as i64);
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (-1, 0), (0, -1)] {
                    img.blend(cx + dx, cy + dy, BLUE);
                }
            }
            for sc in &p.scatter {
                for (x, y) in sc.points.iter().filter(|(x, y)| x.is_finite() && y.is_finite()) {
                    let (cx, cy) = (f.px(*x).round() as i64, f.py(*y).round() as i64);
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (-1, 0), (0, -1)] {
                        img.set(cx + dx, cy + dy, sc.color);
                    }
                }
            }
            for l in &p.lines {
                let half = (l.width.max(1) as i64 - 1) / 2;
                for seg in l.points.windows(2) {
                    let (ax, ay, bx, by) = (f.px(seg[0].0), f.py(seg[0].1), f.px(seg[1].0), f.py(seg[1].1));
                    if !(ax.is_finite() && ay.is_finite() && bx.is_finite() && by.is_finite()) {
                        continue;
                    }
                    let n = (bx - ax).abs().max((by - ay).abs()).ceil().clamp(1.0, 1e5) as usize;
                    for i in 0..=n {
                        let u = i as f64 / n as f64;
                        let (x, y) = ((ax + u * (bx - ax)).round() as i64, (ay + u * (by - ay)).round() as i64);
                        for dy in -half..=half {
                            for dx in -half..=half {
                                img.set(x + dx, y + dy, l.color);
                            }
                        }
                    }
                }
            }
            for (x, y) in &p.marks {
                let (cx, cy) = (f.px(*x).round() as i64, f.py(*y).round() as i64);
                for d in -6..=6 {
                    for w in -1..=1 {
                        img.set(cx + d, cy + w, [220, 0, 0]);
                        img.set(cx + w, cy + d, [220, 0, 0]);
                    }
                }
            }
            img.text(x0, y0 + 6, &tick(f.x.0));
            let t = tick(f.x.1);
            img.text(x1 - 6 * t.len() as i64, y0 + 6, &t);
            let t = tick(f.y.0);
            img.text(x0 - 4 - 6 * t.len() as i64, y0 - 7, &t);
            let t = tick(f.y.1);
            img.text(x0 - 4 - 6 * t.len() as i64, y1, &t);
            img.text((x0 + x1) / 2 - 3 * p.x_label.len() as i64, y0 + 18, &p.x_label);
            img.text(x0, y1 - 12, &p.y_label);
        }
        img
    }
}

fn xml(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

struct Raster {
    w: usize,
    h: usize,
    px: Vec<u8>,
}

/// 5x7 glyphs (one byte per row, low 5 bits) of the characters ticks and labels use.
fn glyph(c: char) -> Option<[u8; 7]> {
    Some(match c {
        '0' => [14, 17, 19, 21, 25, 17, 14],
        '1' => [4, 12, 4, 4, 4, 4, 14],
        '2' => [14, 17, 1, 2, 4, 8, 31],
        '3' => [31, 2, 4, 2, 1, 17, 14],
        '4' => [2, 6, 10, 18, 31, 2, 2],
        '5' => [31, 16, 30, 1, 1, 17, 14],
        '6' => [6, 8, 16, 30, 17, 17, 14],
        '7' => [31, 1, 2, 4, 8, 8, 8],
        '8' => [14, 17, 17, 14, 17, 17, 14],
        '9' => [14, 17, 17, 15, 1, 2, 12],
        '.' => [0, 0, 0, 0, 0, 12, 12],
        '-' => [0, 0, 0, 31, 0, 0, 0],
        'x' => [0, 0, 17, 10, 4, 10, 17],
        'y' => [0, 0, 17, 17, 15, 1, 14],
        'z' => [0, 0, 31, 2, 4, 8, 31],
        'm' => [0, 0, 26, 21, 21, 17, 17],
        'a' => [0, 0, 14, 1, 15, 17, 15],
        'e' => [0, 0, 14, 17, 31, 16, 14],
        'i' => [4, 0, 12, 4, 4, 4, 14],
        'l' => [12, 4, 4, 4, 4, 4, 14],
        'p' => [0, 0, 30, 17, 30, 16, 16],
        'r' => [0, 0, 22, 25, 16, 16, 16],
        's' => [0, 0, 15, 16, 14, 1, 30],
        'd' => [1, 1, 13, 19, 17, 17, 15],
        'u' => [0, 0, 17, 17, 17, 19, 13],
        'c' => [0, 0, 14, 16, 16, 17, 14],
        'o' => [0, 0, 14, 17, 17, 17, 14],
        'n' => [0, 0, 22, 25, 17, 17, 17],
        't' => [8, 8, 28, 8, 8, 9, 6],
        'b' => [16, 16, 22, 25, 17, 17, 30],
        'k' => [16, 16, 18, 20, 24, 20, 18],
        'f' => [6, 9, 8, 28, 8, 8, 8],
        'g' => [0, 15, 17, 17, 15, 1, 14],
        'h' => [16, 16, 22, 25, 17, 17, 17],
        'v' => [0, 0, 17, 17, 17, 10, 4],
        'w' => [0, 0, 17, 17, 21, 21, 10],
        '(' => [2, 4, 8, 8, 8, 4, 2],
        ')' => [8, 4, 2, 2, 2, 4, 8],
        '/' => [0, 1, 2, 4, 8, 16, 0],
        '_' => [0, 0, 0, 0, 0, 0, 31],
        ':' => [0, 12, 12, 0, 12, 12, 0],
        ',' => [0, 0, 0, 0, 12, 4, 8],
        '+' => [0, 4, 4, 31, 4, 4, 0],
        'j' => [2, 0, 6, 2, 2, 18, 12],
        'q' => [0, 0, 13, 19, 15, 1, 1],
        _ => return None,
    })
}

impl Raster {
    fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.w && (y as usize) < self.h {
            let o = (y as usize * self.w + x as usize) * 3;
            self.px[o..o + 3].copy_from_slice(&c);
        }
    }
    fn blend(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.w && (y as usize) < self.h {
            let o = (y as usize * self.w + x as usize) * 3;
            for (px, ck) in self.px[o..o + 3].iter_mut().zip(c) {
                *px = ((*px as u16 * 2 + ck as u16) / 3) as u8;
            }
        }
    }
    fn text(&mut self, x: i64, y: i64, s: &str) {
        for (i, ch) in s.chars().enumerate() {
            if let Some(g) = glyph(ch.to_ascii_lowercase()) {
                for (r, bits) in g.iter().enumerate() {
                    for col in 0..5 {
                        if bits & (16 >> col) != 0 {
                            self.set(x + 6 * i as i64 + col, y + r as i64, [0, 0, 0]);
                        }
                    }
                }
            }
        }
    }
    /// PNG, 8-bit RGB. Plots are mostly flat colour: deflate takes the Figure-10 plot of a
    /// 60 s run from 4 MB (stored blocks, as this module first wrote it) to a few hundred kB.
    fn encode(&self) -> std::result::Result<Vec<u8>, png::EncodingError> {
        let mut out = Vec::new();
        let mut e = png::Encoder::new(&mut out, self.w as u32, self.h as u32);
        e.set_color(png::ColorType::Rgb);
        e.set_depth(png::BitDepth::Eight);
        e.set_compression(png::Compression::Balanced);
        let mut w = e.write_header()?;
        w.write_image_data(&self.px)?;
        w.finish()?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_decodes_to_the_pixels() {
        let fig = cloud(&[Vector3::new(1.0, 2.0, 3.0), Vector3::new(1.001, 2.0, 3.0)], &Vector3::new(1.0005, 2.0, 3.0), "t").unwrap();
        let png = fig.png().unwrap();
        // IHDR: 3 panels of 360 x 340 under a 20 px title band.
        assert_eq!(&png[16..24], &[0, 0, 4, 56, 0, 0, 1, 104]);
        let mut d = png::Decoder::new(std::io::Cursor::new(png.clone())).read_info().unwrap();
        let mut buf = vec![0; d.output_buffer_size().unwrap()];
        d.next_frame(&mut buf).unwrap();
        let (w, h, px) = fig.pixels();
        assert_eq!((w, h), (1080, 360));
        assert_eq!(buf, px);
        // Flat colour compresses: under a tenth of the raw 1.17 MB.
        assert!(png.len() < px.len() / 10, "{} bytes", png.len());
        assert!(fig.svg().contains("<circle"));
    }
}
