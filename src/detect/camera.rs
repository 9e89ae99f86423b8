//! Which camera `robotd detect` assumes: a known one (`--camera ned2`), one from a file
//! (`--intrinsics FILE`, JSON or TOML), or a distortion-free pinhole guessed from the image size.
//!
//! The markers fix where the table is whatever the camera; the intrinsics add the lens model
//! (so a wide lens's bending is undone) and the camera's height (for the parallax of raised
//! objects). A camera calibrated for another image size cannot describe this image: that is
//! an error, except for images already warped to the workspace, which need no camera.

use super::DetectArgs;
use anyhow::{bail, Context, Result};
use clap::ValueEnum;
use robotd_protocol::camera::CameraIntrinsics;
use robotd_render::Intrinsics;
use std::path::Path;

/// Cameras whose intrinsics robotd knows.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum CameraModel {
    /// The Niryo Ned2 wrist camera (640×480, with its lens distortion).
    Ned2,
}

/// A distortion-free pinhole for an image of this size, about 53° across its wider side.
pub fn pinhole(width: usize, height: usize) -> CameraIntrinsics {
    pinhole_with(width, height, width.max(height) as f64)
}

/// A distortion-free pinhole for an image of this size with focal length `f` pixels.
pub fn pinhole_with(width: usize, height: usize, f: f64) -> CameraIntrinsics {
    Intrinsics {
        width: width as u32,
        height: height as u32,
        fx: f,
        fy: f,
        cx: (width as f64 - 1.0) / 2.0,
        cy: (height as f64 - 1.0) / 2.0,
        distortion: [0.0; 5],
    }
    .into()
}

/// The camera intrinsics to use, and how to describe them.
pub fn camera_for(
    args: &DetectArgs,
    width: usize,
    height: usize,
) -> Result<(CameraIntrinsics, String)> {
    let (intrinsics, name) = match (&args.camera, &args.intrinsics) {
        (Some(CameraModel::Ned2), _) => (Intrinsics::ned2().into(), "ned2".to_owned()),
        (None, Some(path)) => (
            read_intrinsics(path)?,
            format!("intrinsics from {}", path.display()),
        ),
        (None, None) => (
            pinhole(width, height),
            "pinhole guessed from the image size (no --camera or --intrinsics)".to_owned(),
        ),
    };
    let intrinsics: CameraIntrinsics = intrinsics;
    if intrinsics.width as usize != width || intrinsics.height as usize != height {
        bail!(
            "the camera intrinsics ({name}) are for {}x{} images but {} is {width}x{height}",
            intrinsics.width,
            intrinsics.height,
            args.image.display()
        );
    }
    Ok((intrinsics, name))
}

fn read_intrinsics(path: &Path) -> Result<CameraIntrinsics> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading the intrinsics file {}", path.display()))?;
    let parsed = if path.extension().is_some_and(|e| e == "json") {
        serde_json::from_str(&text).map_err(anyhow::Error::from)
    } else {
        toml::from_str(&text).map_err(anyhow::Error::from)
    };
    parsed.with_context(|| {
        format!(
            "{}: expected width, height, fx, fy, cx, cy and distortion = [k1, k2, p1, p2, k3]",
            path.display()
        )
    })
}
