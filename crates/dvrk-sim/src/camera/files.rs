//! `dvrk sim --frames-dir DIR`: each camera frame as PNG files, `left_000001.png`,
//! `right_000001.png` (colour) and `left_depth_000001.png`, `right_depth_000001.png` (16-bit depth
//! in mm), numbered from 1. Each file is written beside its destination and renamed over it.

use super::stereo::{Eye, StereoCamera};
use crate::error::{Result, SimError};
use std::path::Path;

/// Write the camera's current frame (number `camera.frames`) into `dir`; `buf` and `scratch` are
/// reused between frames.
pub fn write_frame_files(camera: &StereoCamera, dir: &Path, buf: &mut Vec<u8>, scratch: &mut Vec<u8>) -> Result<()> {
    let n = camera.frames;
    for eye in [Eye::Left, Eye::Right] {
        let img = camera.image(eye);
        buf.clear();
        img.encode_rgb_png(buf).map_err(|e| png_error(dir, e))?;
        dvrk_kin::atomic::write_atomic(&dir.join(format!("{}_{n:06}.png", eye.name())), buf)?;
        buf.clear();
        img.encode_depth_png(buf, scratch).map_err(|e| png_error(dir, e))?;
        dvrk_kin::atomic::write_atomic(&dir.join(format!("{}_depth_{n:06}.png", eye.name())), buf)?;
    }
    Ok(())
}

fn png_error(dir: &Path, e: png::EncodingError) -> SimError {
    SimError::Io { path: dir.display().to_string(), source: std::io::Error::other(e.to_string()) }
}
