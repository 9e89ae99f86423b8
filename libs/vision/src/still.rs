//! Still images from files: what `robotd detect` and the real-photo tests feed the pipeline.
//!
//! The camera actor gets raw RGB frames from the driver; a photo on disk first has to be
//! decoded. [`load`] reads a JPEG or PNG file into the row-major RGB8 buffer the pipeline takes, and
//! turns every way that can go wrong — a missing or unreadable file, bytes that are not an
//! image, a format robotd does not decode, an image too large to hold — into a
//! [`StillError`] that says which file and why, never a panic. Decoding is bounded before any
//! pixel is allocated: at most [`MAX_SIDE`] pixels a side.

use std::path::Path;

/// Largest width or height accepted, pixels (a 64-megapixel photo; the pipeline's own limit
/// on camera sizes is the same).
pub const MAX_SIDE: u32 = 8192;

/// A decoded image.
#[derive(Debug, Clone, PartialEq)]
pub struct StillImage {
    /// Row-major RGB8 pixels, `width × height × 3` bytes.
    pub rgb: Vec<u8>,
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
}

/// Why an image file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum StillError {
    /// The file could not be opened or read.
    #[error("cannot read {path}: {reason}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// The bytes are not an image robotd decodes.
    #[error("{path} is not an image robotd can read ({reason}); robotd reads JPEG and PNG files")]
    NotAnImage {
        /// The file.
        path: String,
        /// What the decoder said.
        reason: String,
    },
    /// The image is larger than [`MAX_SIDE`] a side.
    #[error(
        "{path} is {width}x{height} pixels; at most {MAX_SIDE} a side is accepted (scale it down)"
    )]
    TooLarge {
        /// The file.
        path: String,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
    },
}

/// Decodes the image file at `path` into RGB8.
pub fn load(path: &Path) -> Result<StillImage, StillError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| StillError::Read {
        path: name.clone(),
        reason: e.to_string(),
    })?;
    decode(&bytes, &name)
}

/// Decodes image bytes (JPEG or PNG; grey, RGBA and 16-bit PNGs are converted) into RGB8; `name` names them in errors.
pub fn decode(bytes: &[u8], name: &str) -> Result<StillImage, StillError> {
    let not_an_image = |reason: String| StillError::NotAnImage {
        path: name.to_owned(),
        reason,
    };
    let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| not_an_image(e.to_string()))?;
    if reader.format().is_none() {
        return Err(not_an_image("unknown format".into()));
    }
    let (width, height) = reader
        .into_dimensions()
        .map_err(|e| not_an_image(e.to_string()))?;
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(StillError::TooLarge {
            path: name.to_owned(),
            width,
            height,
        });
    }
    if width == 0 || height == 0 {
        return Err(not_an_image(format!("it is {width}x{height} pixels")));
    }
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| not_an_image(e.to_string()))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    limits.max_alloc = Some(u64::from(MAX_SIDE) * u64::from(MAX_SIDE) * 4);
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| not_an_image(e.to_string()))?;
    let rgb = decoded.to_rgb8();
    Ok(StillImage {
        width: rgb.width() as usize,
        height: rgb.height() as usize,
        rgb: rgb.into_raw(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_input_is_an_error_naming_the_file() {
        let missing = load(Path::new("no/such/photo.jpg"))
            .unwrap_err()
            .to_string();
        assert!(missing.contains("no/such/photo.jpg"), "{missing}");
        let text = decode(b"hello, not a picture", "notes.txt")
            .unwrap_err()
            .to_string();
        assert!(
            text.contains("notes.txt") && text.contains("not an image"),
            "{text}"
        );
        // A JPEG header that claims 60000 x 60000 pixels is refused before decoding.
        let mut huge = vec![0xFF, 0xD8, 0xFF, 0xC0, 0x00, 0x11, 0x08];
        huge.extend_from_slice(&60000u16.to_be_bytes());
        huge.extend_from_slice(&60000u16.to_be_bytes());
        huge.extend_from_slice(&[3, 1, 0x22, 0, 2, 0x11, 1, 3, 0x11, 1]);
        let err = decode(&huge, "huge.jpg").unwrap_err().to_string();
        assert!(err.contains("huge.jpg"), "{err}");
        assert!(
            err.contains("8192") || err.contains("not an image"),
            "{err}"
        );
    }

    #[test]
    fn a_png_decodes_to_rgb_whatever_its_colour_type() {
        let mut rgba = Vec::new();
        for i in 0..(12 * 5) {
            rgba.extend_from_slice(&[200, (i % 256) as u8, 10, 255]);
        }
        let mut png = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut png),
            &rgba,
            12,
            5,
            image::ExtendedColorType::Rgba8,
        )
        .unwrap();
        let image = decode(&png, "frame.png").unwrap();
        assert_eq!((image.width, image.height), (12, 5));
        assert_eq!(&image.rgb[..6], &[200, 0, 10, 200, 1, 10]);
        // A truncated PNG is an error naming the file, not a panic.
        let err = decode(&png[..png.len() / 2], "cut.png")
            .unwrap_err()
            .to_string();
        assert!(err.contains("cut.png"), "{err}");
    }

    #[test]
    fn a_jpeg_decodes_to_rgb() {
        let rgb = vec![200u8; 16 * 8 * 3];
        let jpeg = robotd_render::encode_jpeg(&rgb, 16, 8, 90).unwrap();
        let image = decode(&jpeg, "small.jpg").unwrap();
        assert_eq!(
            (image.width, image.height, image.rgb.len()),
            (16, 8, 16 * 8 * 3)
        );
        assert!(image.rgb.iter().all(|&c| c.abs_diff(200) < 6));
    }
}
