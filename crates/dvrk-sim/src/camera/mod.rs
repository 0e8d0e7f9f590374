//! A stereo endoscope camera rendered in pure Rust (a CPU rasterizer, no GPU): colour and depth
//! per eye, at its own rate inside the simulation loop, with the paper's parameters by default
//! (section 4.4: 30 Hz, 800 x 800 per eye, 1.396 rad horizontal field of view, eyes 10 mm either
//! side of the axis, noise sigma 0.007, clip planes 0.02-300 m).

mod files;
mod image;
mod params;
mod raster;
mod stereo;

pub use files::write_frame_files;
pub use image::{depth_mm, EyeImage, Noise, BACKGROUND};
pub use params::{CameraParams, Intrinsics, MAX_SIDE_PX};
pub use raster::{BodyMesh, Marker, Renderer};
pub use stereo::{Eye, StereoCamera};
