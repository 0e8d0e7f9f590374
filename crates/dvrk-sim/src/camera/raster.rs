//! A triangle rasterizer with a depth buffer, on the CPU.
//!
//! Why not ray casting: 2 eyes x 800 x 800 = 1.28 M primary rays per frame against ~100 solids
//! would cost a BVH query per pixel, while a rasterizer touches each pixel a solid covers once and
//! skips empty pixels after the clear. Each body's triangles are tessellated once (in the body
//! frame) and only transformed per frame. Depth is interpolated as 1/z, which is linear in screen
//! space, so the depth image is exact for planar faces. Faces are flat-shaded by a headlight (the
//! endoscope's light sits at its lens): intensity `AMBIENT + (1 - AMBIENT) |n . v|`, two-sided so
//! meshes of either winding look the same.

use super::image::{to_u8, EyeImage};
use super::params::Intrinsics;
use dvrk_kin::Pose;
use nalgebra::{Point3, Vector3};

/// Share of the light that reaches faces seen edge-on.
const AMBIENT: f32 = 0.3;

/// The triangles of one body, in its body frame.
#[derive(Debug, Clone)]
pub struct BodyMesh {
    /// Arm and body (indices into [`crate::Sim::arms`] and the arm model's bodies).
    pub arm: usize,
    pub body: usize,
    /// m, body frame
    pub vertices: Vec<Vector3<f64>>,
    pub triangles: Vec<[u32; 3]>,
    /// Colour (RGB, 0-1) of each triangle.
    pub colors: Vec<[f32; 3]>,
}

/// A sphere drawn over the image (no depth test), to mark a point: a tool tip.
#[derive(Debug, Clone, Copy)]
pub struct Marker {
    /// m, world
    pub position: Vector3<f64>,
    /// m
    pub radius: f64,
    /// RGB, 0-1
    pub color: [f32; 3],
}

/// Renders a set of body meshes into an [`EyeImage`]. The scratch buffers are sized once.
#[derive(Debug, Clone)]
pub struct Renderer {
    pub meshes: Vec<BodyMesh>,
    /// Vertices in the eye's optical frame (m): the largest mesh's size.
    scratch: Vec<Vector3<f64>>,
    /// A unit ball's triangles for markers.
    ball: (Vec<Vector3<f64>>, Vec<[u32; 3]>),
}

impl Renderer {
    /// A renderer of `meshes`.
    pub fn new(meshes: Vec<BodyMesh>) -> Renderer {
        let n = meshes.iter().map(|m| m.vertices.len()).max().unwrap_or(0);
        let (v, i) = rapier3d_f64::parry::shape::Ball::new(1.0).to_trimesh(24, 12);
        let ball = (v.iter().map(|p| Vector3::new(p.x, p.y, p.z)).collect(), i);
        Renderer { meshes, scratch: vec![Vector3::zeros(); n.max(ball_len())], ball }
    }

    /// Render the meshes seen from `eye` (world pose of the optical frame: z forward, x right,
    /// y down) into `out`; `body_pose(arm, body)` is each body's world pose. Then `markers`.
    pub fn render(&mut self, body_pose: impl Fn(usize, usize) -> Pose, eye: &Pose, k: &Intrinsics, clip: (f64, f64), markers: &[Marker], out: &mut EyeImage) {
        out.clear();
        let to_eye = eye.inverse();
        for m in &self.meshes {
            let t = to_eye * body_pose(m.arm, m.body);
            for (s, v) in self.scratch.iter_mut().zip(&m.vertices) {
                *s = (t * Point3::from(*v)).coords;
            }
            for (tri, color) in m.triangles.iter().zip(&m.colors) {
                let p = [self.scratch[tri[0] as usize], self.scratch[tri[1] as usize], self.scratch[tri[2] as usize]];
                draw_clipped(p, *color, k, clip, true, out);
            }
        }
        for mk in markers {
            let c = (to_eye * Point3::from(mk.position)).coords;
            for tri in &self.ball.1 {
                let p = tri.map(|i| c + self.ball.0[i as usize] * mk.radius);
                draw_clipped(p, mk.color, k, clip, false, out);
            }
        }
        out.resolve_depth();
    }
}

fn ball_len() -> usize {
    // 24 x 12 subdivisions: (24 + 1) x (12 + 1) vertices at most.
    25 * 13
}

/// Clip a triangle (optical frame, m) against the near plane, cull it beyond the far plane, and
/// draw what is left.
fn draw_clipped(p: [Vector3<f64>; 3], color: [f32; 3], k: &Intrinsics, (near, far): (f64, f64), depth_test: bool, out: &mut EyeImage) {
    let inside = [p[0].z >= near, p[1].z >= near, p[2].z >= near];
    if !inside.iter().any(|x| *x) || p.iter().all(|v| v.z > far) {
        return;
    }
    // Headlight shading from the face normal and the direction to the face.
    let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
    let c = (p[0] + p[1] + p[2]) / 3.0;
    let (nn, cn) = (n.norm(), c.norm());
    if nn == 0.0 || cn == 0.0 {
        return;
    }
    let lambert = (n.dot(&c) / (nn * cn)).abs() as f32;
    // Markers (no depth test) keep their exact colour, so they can be found in the image.
    let shade = if depth_test { AMBIENT + (1.0 - AMBIENT) * lambert } else { 1.0 };
    let rgb = color.map(|x| to_u8(x * shade));
    if inside.iter().all(|x| *x) {
        raster(p, rgb, k, far, depth_test, out);
        return;
    }
    // Sutherland-Hodgman against z = near: a triangle becomes a triangle or a quad.
    let mut poly = [Vector3::zeros(); 4];
    let mut n = 0;
    for i in 0..3 {
        let (a, b) = (p[i], p[(i + 1) % 3]);
        let (ia, ib) = (a.z >= near, b.z >= near);
        if ia {
            poly[n] = a;
            n += 1;
        }
        if ia != ib {
            let t = (near - a.z) / (b.z - a.z);
            poly[n] = a + (b - a) * t;
            n += 1;
        }
    }
    for i in 1..n.saturating_sub(1) {
        raster([poly[0], poly[i], poly[i + 1]], rgb, k, far, depth_test, out);
    }
}

/// Fill the pixels whose centres lie in the projected triangle, nearer than what is there (or
/// all of them without the depth test).
fn raster(p: [Vector3<f64>; 3], rgb: [u8; 3], k: &Intrinsics, far: f64, depth_test: bool, out: &mut EyeImage) {
    let w = p.map(|v| 1.0 / v.z);
    let u = p.map(|v| k.fx * v.x / v.z + k.cx);
    let v = p.map(|v| k.fy * v.y / v.z + k.cy);
    let area = (u[1] - u[0]) * (v[2] - v[0]) - (u[2] - u[0]) * (v[1] - v[0]);
    if area.abs() < 1e-12 {
        return;
    }
    let (wd, ht) = (out.width as f64, out.height as f64);
    let x0 = u.iter().copied().fold(f64::INFINITY, f64::min).ceil().max(0.0);
    let x1 = u.iter().copied().fold(f64::NEG_INFINITY, f64::max).floor().min(wd - 1.0);
    let y0 = v.iter().copied().fold(f64::INFINITY, f64::min).ceil().max(0.0);
    let y1 = v.iter().copied().fold(f64::NEG_INFINITY, f64::max).floor().min(ht - 1.0);
    if x0 > x1 || y0 > y1 {
        return;
    }
    let inv_area = 1.0 / area;
    // Barycentric weight of vertex i at (x, y): the edge function of the opposite edge over the
    // area, affine in x and y: l_i = ax[i] x + ay[i] y + c[i].
    let mut ax = [0.0; 3];
    let mut ay = [0.0; 3];
    let mut c0 = [0.0; 3];
    for i in 0..3 {
        let (a, b) = ((i + 1) % 3, (i + 2) % 3);
        ax[i] = -(v[b] - v[a]) * inv_area;
        ay[i] = (u[b] - u[a]) * inv_area;
        c0[i] = -(ax[i] * u[a] + ay[i] * v[a]);
    }
    let min_w = (1.0 / far) as f32;
    let width = out.width as usize;
    for y in y0 as usize..=y1 as usize {
        let yf = y as f64;
        // The row's span inside all three half-planes, so long thin triangles (a tool shaft seen
        // obliquely) cost their pixels, not their bounding box.
        let (mut xa, mut xb) = (x0, x1);
        let mut empty = false;
        for i in 0..3 {
            let r = ay[i] * yf + c0[i];
            if ax[i] > 0.0 {
                xa = xa.max((-r / ax[i]).ceil());
            } else if ax[i] < 0.0 {
                xb = xb.min((-r / ax[i]).floor());
            } else if r < 0.0 {
                empty = true;
            }
        }
        if empty || xa > xb {
            continue;
        }
        let row = y * width;
        // 1/z is affine in (x, y) too: its value at the span's start and its step along x.
        let l = [0, 1, 2].map(|i| ax[i] * xa + ay[i] * yf + c0[i]);
        let mut iz = l[0] * w[0] + l[1] * w[1] + l[2] * w[2];
        let step = w[0] * ax[0] + w[1] * ax[1] + w[2] * ax[2];
        for x in xa as usize..=xb as usize {
            let z = iz as f32;
            let i = row + x;
            if !depth_test || (z > out.inv_depth[i] && z >= min_w) {
                if depth_test {
                    out.inv_depth[i] = z;
                }
                out.rgb[3 * i..3 * i + 3].copy_from_slice(&rgb);
            }
            iz += step;
        }
    }
}
