//! Plots on request: the RCM point cloud of the paper's Figure 9 (three projections about the
//! pivot) and the per-sample axis residuals. A figure is a list of scatter panels, rendered as
//! SVG (with titles) or as PNG (uncompressed deflate, a 5x7 font for ticks and axis names), so
//! no plotting or image library is needed.

use crate::axes::AxesReport;
use crate::error::{CalibError, Result};
use nalgebra::Vector3;
use std::fmt::Write as _;
use std::path::Path;

/// One scatter panel.
#[derive(Debug, Clone, PartialEq)]
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
}

/// A row of panels.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    pub title: String,
    pub panels: Vec<Panel>,
}

const W: usize = 360;
const H: usize = 340;
const M: usize = 46;

/// The RCM cloud (tracker frame, m) about `pivot`: x-y, x-z and y-z projections in mm.
pub fn cloud(points: &[Vector3<f64>], pivot: &Vector3<f64>, title: &str) -> Result<Figure> {
    if points.is_empty() {
        return Err(CalibError::data("plot", "no point to draw"));
    }
    let rel: Vec<Vector3<f64>> = points.iter().map(|p| (p - pivot) * 1e3).collect();
    let panel = |i: usize, j: usize, n: [&str; 2]| Panel {
        title: format!("{} - {}", n[0], n[1]),
        x_label: format!("{} mm", n[0]),
        y_label: format!("{} mm", n[1]),
        points: rel.iter().map(|p| (p[i], p[j])).collect(),
        marks: vec![(0.0, 0.0)],
        equal: true,
    };
    Ok(Figure { title: title.into(), panels: vec![panel(0, 1, ["x", "y"]), panel(0, 2, ["x", "z"]), panel(1, 2, ["y", "z"])] })
}

/// Per-sample residual (mm) of every axis against the sample number.
pub fn axis_residuals(report: &AxesReport) -> Result<Figure> {
    if report.axes.is_empty() {
        return Err(CalibError::data("plot", "no axis to draw"));
    }
    let panels = report
        .axes
        .iter()
        .map(|a| Panel {
            title: format!("axis {} ({} / {})", a.name, a.reference, a.moving),
            x_label: "sample".into(),
            y_label: format!("axis {} residual mm", a.name),
            points: a.fit.residuals.iter().enumerate().map(|(i, r)| (i as f64, r * 1e3)).collect(),
            marks: vec![],
            equal: false,
        })
        .collect();
    Ok(Figure { title: format!("axis residuals: {}", report.source), panels })
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
}

impl Frame {
    fn new(p: &Panel, k: usize) -> Frame {
        let mut x = range(p.points.iter().chain(&p.marks).map(|q| q.0));
        let mut y = range(p.points.iter().chain(&p.marks).map(|q| q.1));
        if p.equal {
            let half = 0.5 * (x.1 - x.0).max(y.1 - y.0);
            let (cx, cy) = (0.5 * (x.0 + x.1), 0.5 * (y.0 + y.1));
            x = (cx - half, cx + half);
            y = (cy - half, cy + half);
        }
        Frame { x, y, ox: k * W }
    }
    fn px(&self, v: f64) -> f64 {
        self.ox as f64 + M as f64 + (v - self.x.0) / (self.x.1 - self.x.0) * (W - 2 * M) as f64
    }
    fn py(&self, v: f64) -> f64 {
        (H - M) as f64 - (v - self.y.0) / (self.y.1 - self.y.0) * (H - 2 * M) as f64
    }
}

fn tick(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

impl Figure {
    /// SVG or PNG bytes, chosen by `path`'s extension.
    pub fn encode(&self, path: &Path) -> Result<Vec<u8>> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("svg") => Ok(self.svg().into_bytes()),
            Some("png") => Ok(self.png()),
            _ => Err(CalibError::file(path, "--plot: unknown image format; valid: .png, .svg")),
        }
    }

    /// The figure as SVG.
    pub fn svg(&self) -> String {
        let width = W * self.panels.len();
        let mut s = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{}\" font-family=\"sans-serif\" font-size=\"11\">\n", H + 20);
        let _ = writeln!(s, "<rect width=\"100%\" height=\"100%\" fill=\"white\"/><text x=\"8\" y=\"14\" font-size=\"13\">{}</text>", xml(&self.title));
        s += "<g transform=\"translate(0,20)\">\n";
        for (k, p) in self.panels.iter().enumerate() {
            let f = Frame::new(p, k);
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
            s += "<g fill=\"#1f77b4\" fill-opacity=\"0.35\">";
            for (x, y) in &p.points {
                let _ = write!(s, "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"1.3\"/>", f.px(*x), f.py(*y));
            }
            s += "</g>\n";
            for (x, y) in &p.marks {
                let (cx, cy) = (f.px(*x), f.py(*y));
                let _ = writeln!(s, "<path d=\"M{:.1} {cy:.1}H{:.1}M{cx:.1} {:.1}V{:.1}\" stroke=\"red\" stroke-width=\"2\"/>", cx - 6.0, cx + 6.0, cy - 6.0, cy + 6.0);
            }
        }
        s += "</g></svg>\n";
        s
    }

    /// The figure as an RGB PNG.
    pub fn png(&self) -> Vec<u8> {
        let width = W * self.panels.len();
        let mut img = Raster { w: width, h: H, px: vec![255u8; width * H * 3] };
        for (k, p) in self.panels.iter().enumerate() {
            let f = Frame::new(p, k);
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
                    img.blend(cx + dx, cy + dy, [31, 119, 180]);
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
        img.encode()
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
    /// PNG: signature, IHDR, one IDAT of stored (uncompressed) deflate blocks, IEND.
    fn encode(&self) -> Vec<u8> {
        let mut raw = Vec::with_capacity((self.w * 3 + 1) * self.h);
        for row in self.px.chunks(self.w * 3) {
            raw.push(0);
            raw.extend_from_slice(row);
        }
        let mut z = vec![0x78, 0x01];
        let blocks: Vec<&[u8]> = raw.chunks(65_535).collect();
        for (i, b) in blocks.iter().enumerate() {
            z.push(u8::from(i + 1 == blocks.len()));
            z.extend_from_slice(&(b.len() as u16).to_le_bytes());
            z.extend_from_slice(&(!(b.len() as u16)).to_le_bytes());
            z.extend_from_slice(b);
        }
        let (mut a, mut b) = (1u32, 0u32);
        for x in &raw {
            a = (a + *x as u32) % 65_521;
            b = (b + a) % 65_521;
        }
        z.extend_from_slice(&((b << 16) | a).to_be_bytes());
        let mut out = vec![0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
        let mut ihdr = Vec::new();
        ihdr.extend_from_slice(&(self.w as u32).to_be_bytes());
        ihdr.extend_from_slice(&(self.h as u32).to_be_bytes());
        ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
        for (kind, data) in [(b"IHDR", ihdr.as_slice()), (b"IDAT", z.as_slice()), (b"IEND", &[][..])] {
            out.extend_from_slice(&(data.len() as u32).to_be_bytes());
            let start = out.len();
            out.extend_from_slice(kind);
            out.extend_from_slice(data);
            let crc = crc32(&out[start..]);
            out.extend_from_slice(&crc.to_be_bytes());
        }
        out
    }
}

fn crc32(data: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for b in data {
        c ^= *b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_checksums_match_the_standard_values() {
        // CRC-32 of "IEND" is the constant every PNG ends with.
        assert_eq!(crc32(b"IEND"), 0xae42_6082);
        let fig = cloud(&[Vector3::new(1.0, 2.0, 3.0), Vector3::new(1.001, 2.0, 3.0)], &Vector3::new(1.0005, 2.0, 3.0), "t").unwrap();
        let png = fig.png();
        assert_eq!(&png[png.len() - 12..], &[0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xae, 0x42, 0x60, 0x82]);
        // IHDR: 3 panels of 360 x 340.
        assert_eq!(&png[16..24], &[0, 0, 4, 56, 0, 0, 1, 84]);
        assert!(fig.svg().contains("<circle"));
    }
}
