//! # robotd-jpeg: JPEG in and out, and nothing else
//!
//! Cameras send JPEG (the Ned2's `GET_IMAGE_COMPRESSED`, MJPEG-over-HTTP streams, USB cameras
//! in MJPG mode) and robotd publishes JPEG (the MJPEG server of the fakes and tests). This
//! crate is the codec the camera drivers share, so that a real driver needs neither the
//! simulator nor its renderer to read its own camera:
//!
//! - [`decode_jpeg`]: JPEG bytes to RGB8 and the image's size, through the `image` crate;
//!   bytes that are not a JPEG image are an error naming their length and why;
//! - [`encode_jpeg`]: RGB8 to a baseline JPEG, through `jpeg-encoder` (about 3× faster than
//!   `image`'s encoder on a 640×480 frame, `robotd bench jpeg`).
//!
//! `robotd-render`'s `encode_jpeg` and `decode_jpeg` call these (one codec in robotd).
//!
//! ```
//! let rgb = vec![200u8; 16 * 8 * 3];
//! let jpeg = robotd_jpeg::encode_jpeg(&rgb, 16, 8, 90).unwrap();
//! let (decoded, width, height) = robotd_jpeg::decode_jpeg(&jpeg).unwrap();
//! assert_eq!((width, height, decoded.len()), (16, 8, rgb.len()));
//! assert!(robotd_jpeg::decode_jpeg(b"not a jpeg").is_err());
//! ```

/// Why an image could not be encoded or decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum JpegError {
    /// The pixel buffer does not hold exactly `width × height × 3` bytes.
    #[error("frame buffer has {got} bytes, expected {expected} (width × height × 3)")]
    BufferSize {
        /// Bytes needed.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
    /// JPEG encoding failed.
    #[error("JPEG encoding failed: {0}")]
    Encode(String),
    /// The bytes are not a JPEG image robotd can decode.
    #[error("{0}")]
    NotJpeg(String),
}

/// Encodes an RGB8 image (row-major, `width × height × 3` bytes) as a baseline JPEG.
/// `quality` is 1..=100 (clamped).
pub fn encode_jpeg(rgb: &[u8], width: u32, height: u32, quality: u8) -> Result<Vec<u8>, JpegError> {
    let expected = (width as usize)
        .saturating_mul(height as usize)
        .saturating_mul(3);
    if rgb.len() != expected {
        return Err(JpegError::BufferSize {
            expected,
            got: rgb.len(),
        });
    }
    if width == 0 || height == 0 || width > 65_535 || height > 65_535 {
        return Err(JpegError::Encode(format!(
            "a JPEG image must be 1..=65535 pixels on a side, got {width}x{height}"
        )));
    }
    let mut jpeg = Vec::with_capacity(expected / 8);
    jpeg_encoder::Encoder::new(&mut jpeg, quality.clamp(1, 100))
        .encode(
            rgb,
            width as u16,
            height as u16,
            jpeg_encoder::ColorType::Rgb,
        )
        .map_err(|e| JpegError::Encode(e.to_string()))?;
    Ok(jpeg)
}

/// Decodes a JPEG image into RGB8 (row-major, `width × height × 3` bytes) and its size.
/// Bytes without the JPEG start marker, or that do not decode, are [`JpegError::NotJpeg`]
/// naming their length and the decoder's reason.
pub fn decode_jpeg(jpeg: &[u8]) -> Result<(Vec<u8>, u32, u32), JpegError> {
    if jpeg.len() < 4 || jpeg[..2] != [0xFF, 0xD8] {
        return Err(JpegError::NotJpeg(format!(
            "{} bytes that are not a JPEG image (no start-of-image marker)",
            jpeg.len()
        )));
    }
    let image = image::load_from_memory_with_format(jpeg, image::ImageFormat::Jpeg)
        .map_err(|e| {
            JpegError::NotJpeg(format!(
                "a JPEG of {} bytes does not decode: {e}",
                jpeg.len()
            ))
        })?
        .into_rgb8();
    let (width, height) = image.dimensions();
    Ok((image.into_raw(), width, height))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_survives_the_round_trip_within_jpeg_error() {
        let (w, h) = (64u32, 48u32);
        let rgb: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w);
                [(x * 4) as u8, (y * 5) as u8, 128]
            })
            .collect();
        let jpeg = encode_jpeg(&rgb, w, h, 95).unwrap();
        let (back, bw, bh) = decode_jpeg(&jpeg).unwrap();
        assert_eq!((bw, bh), (w, h));
        let worst = rgb
            .iter()
            .zip(&back)
            .map(|(a, b)| a.abs_diff(*b))
            .max()
            .unwrap();
        assert!(worst < 24, "worst channel error {worst}");
    }

    #[test]
    fn wrong_buffers_and_non_jpeg_bytes_are_errors_that_say_why() {
        assert_eq!(
            encode_jpeg(&[0; 5], 2, 1, 90),
            Err(JpegError::BufferSize {
                expected: 6,
                got: 5
            })
        );
        assert!(matches!(
            encode_jpeg(&[], 0, 0, 90),
            Err(JpegError::Encode(_))
        ));
        let not = decode_jpeg(b"GIF89a...").unwrap_err().to_string();
        assert!(not.contains("9 bytes that are not a JPEG image"), "{not}");
        let cut = decode_jpeg(&[0xFF, 0xD8, 0xFF, 0xE0, 0, 0])
            .unwrap_err()
            .to_string();
        assert!(cut.contains("a JPEG of 6 bytes does not decode"), "{cut}");
    }
}
