//! # robotd-render: the simulated wrist camera's image
//!
//! When robotd runs without hardware, the camera still has to deliver pictures that a colour
//! and shape detector can work on, exactly as on the real robot. This crate draws them: given
//! what lies on the table (a [`RenderScene`] of flat sheets and markers plus boxes and
//! cylinders) and where the camera is, it renders a 640×480 RGB8 frame as the Niryo Ned2's
//! wrist camera would see it.
//!
//! - **Projection**: a pinhole camera with the real [`Intrinsics`]; the camera pose is its
//!   *optical* frame (z along the view, x to the image's right, y down).
//!   [`Intrinsics::project`] tells where a world point lands, so tests and detectors can check
//!   their pixels against the truth.
//! - **Visibility**: geometry is clipped against a near plane before projection, back faces
//!   are culled, and solids are painted far to near, ordered by separating planes (exact for
//!   convex solids that do not interpenetrate). Flat things (table, sheets, markers) come
//!   first.
//! - **Appearance**: flat shading keeps each solid's hue but darkens faces turned away from a
//!   light above (a box's top is brighter than its sides); edges are anti-aliased; Gaussian
//!   sensor noise; optionally the lens's barrel distortion through a precomputed remap.
//! - **Testing perception**: [`sheet_art`] draws Niryo's printed sheet designs (classic
//!   striped, Ned2 black-framed) and [`photo`] what a real room and lens do to a frame (light,
//!   white balance, vignetting, glare, blur), for the randomized perception benchmark.
//! - **Frames**: [`Renderer::render_into`] writes straight into a shared-memory frame buffer
//!   and allocates nothing per frame; [`encode_jpeg`] makes the JPEGs the edges publish.
//!
//! ```
//! use nalgebra::{Isometry3, Point3, Vector3};
//! use robotd_render::{
//!     look_at, Intrinsics, RenderOptions, RenderScene, Renderer, Shape, Solid,
//! };
//!
//! // A red 4 cm cube on a brown table, seen from 40 cm straight above.
//! let scene = RenderScene {
//!     background: [118, 96, 72],
//!     table_z_m: 0.0,
//!     quads: vec![],
//!     discs: vec![],
//!     solids: vec![Solid {
//!         shape: Shape::Box { size_m: Vector3::new(0.04, 0.04, 0.04) },
//!         pose: Isometry3::translation(0.25, 0.0, 0.02),
//!         color: [200, 30, 30],
//!     }],
//! };
//! let camera = look_at(
//!     &Point3::new(0.25, 0.0, 0.4),
//!     &Point3::new(0.25, 0.0, 0.0),
//!     &Vector3::x(), // the image's top points along +x
//! );
//! let intrinsics = Intrinsics::ned2();
//! let mut renderer = Renderer::new(intrinsics, RenderOptions::default());
//! let mut frame = vec![0u8; 640 * 480 * 3];
//! renderer.render_into(&scene, &camera, &mut frame)?;
//!
//! // The cube's top centre is where the pinhole model says, and it is red.
//! let p = intrinsics
//!     .project(&camera.inverse(), &Point3::new(0.25, 0.0, 0.04))
//!     .expect("in front of the camera");
//! let i = (p.y.round() as usize * 640 + p.x.round() as usize) * 3;
//! let [r, g, b] = [frame[i], frame[i + 1], frame[i + 2]];
//! assert!(r > 150 && g < 80 && b < 80, "saw {r} {g} {b}");
//!
//! // What the Redis edge publishes.
//! let jpeg = robotd_render::encode_jpeg(&frame, 640, 480, 85)?;
//! assert_eq!(&jpeg[..2], &[0xFF, 0xD8]);
//! # Ok::<(), robotd_render::RenderError>(())
//! ```

pub mod annotate;
pub mod canvas;
mod intrinsics;
mod mesh;
mod noise;
pub mod photo;
mod render;
mod scene;
pub mod sheet_art;

pub use intrinsics::Intrinsics;
pub use render::Renderer;
pub use scene::{Disc, RenderOptions, RenderScene, Rgb, Shape, Solid};

use nalgebra::{Isometry3, Point3, Vector3};

/// Why a frame could not be rendered or encoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RenderError {
    /// The output buffer does not hold exactly `width × height × 3` bytes.
    #[error("frame buffer has {got} bytes, expected {expected} (width × height × 3)")]
    BufferSize {
        /// Bytes needed.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
    /// The camera pose has a non-finite number or a zero rotation quaternion.
    #[error("camera pose is not finite or its rotation quaternion is zero")]
    InvalidCameraPose,
    /// The intrinsics cannot describe a camera (see [`Intrinsics::is_valid`]) or the image is
    /// larger than 4096 pixels on a side.
    #[error("camera intrinsics are unusable (zero or over 4096-pixel size, or a bad focal length, principal point or distortion)")]
    InvalidIntrinsics,
    /// JPEG encoding failed.
    #[error("JPEG encoding failed: {0}")]
    Jpeg(String),
    /// The bytes are not a JPEG image robotd can decode.
    #[error("{0}")]
    NotJpeg(String),
}

/// Encodes an RGB8 image (row-major, `width × height × 3` bytes) as a baseline JPEG.
/// `quality` is 1..=100 (clamped); the Redis edge uses 85. robotd's one encoder
/// ([`robotd_jpeg::encode_jpeg`]), with the renderer's error type.
pub fn encode_jpeg(
    rgb: &[u8],
    width: u32,
    height: u32,
    quality: u8,
) -> Result<Vec<u8>, RenderError> {
    robotd_jpeg::encode_jpeg(rgb, width, height, quality).map_err(RenderError::from)
}

/// The same frame through the `image` crate's JPEG encoder, robotd's encoder before
/// `jpeg-encoder`: kept as the benchmark's baseline (`robotd bench jpeg`), not for use.
pub fn encode_jpeg_with_image_crate(
    rgb: &[u8],
    width: u32,
    height: u32,
    quality: u8,
) -> Result<Vec<u8>, RenderError> {
    let mut jpeg = Vec::with_capacity(rgb.len() / 8);
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, quality.clamp(1, 100))
        .encode(rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| RenderError::Jpeg(e.to_string()))?;
    Ok(jpeg)
}

/// Decodes a JPEG image into RGB8 (row-major, `width × height × 3` bytes) and its size:
/// robotd's one decoder ([`robotd_jpeg::decode_jpeg`]), with the renderer's error type.
pub fn decode_jpeg(jpeg: &[u8]) -> Result<(Vec<u8>, u32, u32), RenderError> {
    robotd_jpeg::decode_jpeg(jpeg).map_err(RenderError::from)
}

impl From<robotd_jpeg::JpegError> for RenderError {
    fn from(error: robotd_jpeg::JpegError) -> Self {
        match error {
            robotd_jpeg::JpegError::BufferSize { expected, got } => {
                RenderError::BufferSize { expected, got }
            }
            robotd_jpeg::JpegError::Encode(reason) => RenderError::Jpeg(reason),
            robotd_jpeg::JpegError::NotJpeg(reason) => RenderError::NotJpeg(reason),
        }
    }
}

/// The pose of a camera's optical frame at `eye` looking at `target`, with the image's top
/// pointing as close to `image_up` as possible (z = viewing direction, x = image right,
/// y = image down): the `camera_pose` [`Renderer::render_into`] takes.
///
/// `image_up` must not be parallel to the viewing direction (the pose is not finite then, and
/// rendering with it returns an error).
pub fn look_at(eye: &Point3<f64>, target: &Point3<f64>, image_up: &Vector3<f64>) -> Isometry3<f64> {
    Isometry3::face_towards(eye, target, &(-image_up))
}

#[cfg(test)]
mod tests {
    #[test]
    fn renderer_can_move_between_threads() {
        fn send<T: Send>() {}
        send::<crate::Renderer>();
    }
}
