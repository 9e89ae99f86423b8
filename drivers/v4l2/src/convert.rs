//! From what a capture device delivers to RGB8: MJPG (one JPEG per buffer, decoded) and YUYV
//! (4:2:2, two pixels in four bytes `Y0 U Y1 V`, BT.601 limited range, what UVC cameras
//! send uncompressed).

use linuxvideo::format::PixelFormat;

/// The pixel formats robotd reads, best first: MJPG keeps USB bandwidth low at 640×480.
pub const PREFERRED_FORMATS: [PixelFormat; 3] =
    [PixelFormat::MJPG, PixelFormat::JPEG, PixelFormat::YUYV];

/// How to turn one buffer of the negotiated format into RGB8.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decoder {
    /// A JPEG per buffer.
    Jpeg,
    /// YUYV rows of `stride` bytes each.
    Yuyv { stride: usize },
}

impl Decoder {
    /// The decoder for `format`, rows of `stride` bytes; `None` when robotd cannot read it.
    pub fn for_format(format: PixelFormat, stride: u32) -> Option<Self> {
        if format == PixelFormat::MJPG || format == PixelFormat::JPEG {
            Some(Self::Jpeg)
        } else if format == PixelFormat::YUYV {
            Some(Self::Yuyv {
                stride: stride as usize,
            })
        } else {
            None
        }
    }

    /// Decodes one buffer of a `width × height` frame into RGB8.
    pub fn decode(self, data: &[u8], width: u32, height: u32) -> Result<Vec<u8>, String> {
        match self {
            Self::Jpeg => {
                let (rgb, w, h) = robotd_jpeg::decode_jpeg(data)
                    .map_err(|e| format!("a JPEG frame did not decode: {e}"))?;
                if (w, h) != (width, height) {
                    return Err(format!(
                        "a JPEG frame is {w}×{h}, the negotiated size is {width}×{height}"
                    ));
                }
                Ok(rgb)
            }
            Self::Yuyv { stride } => yuyv_to_rgb(data, width, height, stride),
        }
    }
}

/// Converts a YUYV frame to RGB8. `width` must be even (YUYV pairs pixels); `stride` is the
/// bytes per row, at least `2 × width` (drivers may pad rows).
pub fn yuyv_to_rgb(data: &[u8], width: u32, height: u32, stride: usize) -> Result<Vec<u8>, String> {
    let (w, h) = (width as usize, height as usize);
    if w % 2 != 0 {
        return Err(format!("a YUYV frame must have an even width, not {w}"));
    }
    let row_bytes = w * 2;
    let stride = stride.max(row_bytes);
    let needed = stride * h.saturating_sub(1) + row_bytes;
    if h == 0 || data.len() < needed {
        return Err(format!(
            "a YUYV frame of {w}×{h} needs {needed} bytes, the buffer holds {}",
            data.len()
        ));
    }
    let mut rgb = Vec::with_capacity(w * h * 3);
    for row in data.chunks(stride).take(h) {
        for quad in row[..row_bytes].chunks_exact(4) {
            let (y0, u, y1, v) = (quad[0], quad[1], quad[2], quad[3]);
            rgb.extend_from_slice(&ycbcr_to_rgb(y0, u, v));
            rgb.extend_from_slice(&ycbcr_to_rgb(y1, u, v));
        }
    }
    Ok(rgb)
}

/// One BT.601 limited-range pixel (Y 16–235, Cb/Cr 16–240) to RGB8, in fixed point.
fn ycbcr_to_rgb(y: u8, cb: u8, cr: u8) -> [u8; 3] {
    let c = (i32::from(y) - 16) * 298;
    let d = i32::from(cb) - 128;
    let e = i32::from(cr) - 128;
    let clamp = |v: i32| ((v + 128) >> 8).clamp(0, 255) as u8;
    [
        clamp(c + 409 * e),
        clamp(c - 100 * d - 208 * e),
        clamp(c + 516 * d),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn black_white_and_primaries_convert_to_their_rgb() {
        assert_eq!(ycbcr_to_rgb(16, 128, 128), [0, 0, 0]);
        assert_eq!(ycbcr_to_rgb(235, 128, 128), [255, 255, 255]);
        // BT.601 red, green and blue (limited range).
        let red = ycbcr_to_rgb(81, 90, 240);
        assert!(red[0] > 250 && red[1] < 5 && red[2] < 5, "{red:?}");
        let green = ycbcr_to_rgb(145, 54, 34);
        assert!(green[1] > 250 && green[0] < 5 && green[2] < 5, "{green:?}");
        let blue = ycbcr_to_rgb(41, 240, 110);
        assert!(blue[2] > 250 && blue[0] < 5 && blue[1] < 5, "{blue:?}");
    }

    #[test]
    fn padded_rows_are_skipped_and_pixel_pairs_share_their_chroma() {
        // 2×2 frame, rows padded to 6 bytes: a black and a white pixel per row.
        let data = [16, 128, 235, 128, 9, 9, 16, 128, 235, 128, 9, 9];
        let rgb = yuyv_to_rgb(&data, 2, 2, 6).unwrap();
        assert_eq!(
            rgb,
            [0, 0, 0, 255, 255, 255, 0, 0, 0, 255, 255, 255],
            "the padding bytes (9) must not show"
        );
    }

    #[test]
    fn short_buffers_and_odd_widths_are_errors_not_panics() {
        let error = yuyv_to_rgb(&[0; 10], 4, 2, 8).unwrap_err();
        assert!(error.contains("needs 16 bytes"), "{error}");
        assert!(yuyv_to_rgb(&[0; 12], 3, 2, 6).is_err());
        assert!(yuyv_to_rgb(&[], 2, 0, 4).is_err());
        // A garbage JPEG is an error too.
        assert!(Decoder::Jpeg.decode(&[0xff, 0xd8, 1, 2], 2, 2).is_err());
    }

    #[test]
    fn only_the_formats_robotd_reads_have_a_decoder() {
        assert_eq!(
            Decoder::for_format(PixelFormat::YUYV, 1280),
            Some(Decoder::Yuyv { stride: 1280 })
        );
        assert_eq!(
            Decoder::for_format(PixelFormat::MJPG, 0),
            Some(Decoder::Jpeg)
        );
        assert_eq!(Decoder::for_format(PixelFormat::RGB3, 1920), None);
    }
}
