//! A camera frame made into the picture `get_camera_image` returns: scaled, annotated, and a
//! JPEG no bigger than a bound.
//!
//! The frame is first scaled down to the width asked for (an area average, so thin edges do
//! not alias away), then the objects are drawn on it the way the dashboard draws them
//! ([`robotd_render::annotate::draw_objects`]: a box per object and a tag `obj-3 pencil 0.90`)
//! — drawn after scaling, so the 8-pixel tags stay legible at any width. The JPEG is encoded
//! at [`QUALITIES`] in turn until it fits in the byte bound; if even the lowest quality does
//! not fit, the picture is made a quarter narrower and tried again, down to [`MIN_WIDTH`].
//!
//! ```
//! use robotd_tools::picture::{make, Request};
//! let (w, h) = (64, 48);
//! let rgb: Vec<u8> = (0..w * h * 3).map(|i| (i % 251) as u8).collect();
//! let request = Request { annotated: false, max_width: 32, max_bytes: 100_000 };
//! let picture = make(&rgb, w, h, &[], &request).unwrap();
//! assert_eq!((picture.width, picture.height), (32, 24));
//! assert!(picture.jpeg.len() <= 100_000 && picture.jpeg.starts_with(&[0xFF, 0xD8]));
//! ```

use robotd_protocol::objects::DetectedObject;

/// The default byte bound of a picture: small enough for any model's image input and an MCP
/// message, large enough for a full 640×480 view at a good quality.
pub const DEFAULT_MAX_BYTES: usize = 150_000;
/// The qualities tried, best first.
pub const QUALITIES: [u8; 4] = [85, 70, 55, 40];
/// Narrowest picture made to fit the byte bound, pixels.
pub const MIN_WIDTH: usize = 160;

/// What picture to make.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Request {
    /// Draw the objects' boxes and tags.
    pub annotated: bool,
    /// Widest picture, pixels (the frame's own width when smaller).
    pub max_width: usize,
    /// Largest JPEG, bytes.
    pub max_bytes: usize,
}

/// The picture made.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Picture {
    /// The JPEG file.
    pub jpeg: Vec<u8>,
    /// Its width, pixels.
    pub width: usize,
    /// Its height, pixels.
    pub height: usize,
    /// The quality it was encoded at.
    pub quality: u8,
}

/// Makes the picture of `rgb` (`width × height` RGB8) with `objects` drawn on it, or says why
/// it cannot (a frame of the wrong size, an encoder failure, a bound too small for any
/// picture).
pub fn make(
    rgb: &[u8],
    width: usize,
    height: usize,
    objects: &[DetectedObject],
    request: &Request,
) -> Result<Picture, String> {
    if width == 0 || height == 0 || rgb.len() < width * height * 3 {
        return Err(format!(
            "the frame holds {} bytes, not {width}×{height} RGB",
            rgb.len()
        ));
    }
    let mut target = request.max_width.clamp(1, width);
    loop {
        let (mut small, w, h) = scale_to_width(rgb, width, height, target);
        if request.annotated {
            robotd_render::annotate::draw_objects(&mut small, w, h, objects);
        }
        for quality in QUALITIES {
            let jpeg = robotd_render::encode_jpeg(&small, w as u32, h as u32, quality)
                .map_err(|e| format!("JPEG encoding failed: {e}"))?;
            if jpeg.len() <= request.max_bytes {
                return Ok(Picture {
                    jpeg,
                    width: w,
                    height: h,
                    quality,
                });
            }
        }
        if target <= MIN_WIDTH {
            return Err(format!(
                "even a {w}×{h} picture at quality {} is over {} bytes",
                QUALITIES[QUALITIES.len() - 1],
                request.max_bytes
            ));
        }
        target = (target * 3 / 4).max(MIN_WIDTH);
    }
}

/// `rgb` scaled to `target` pixels wide (never wider than it is), each output pixel the
/// average of the input pixels it covers. Returns the pixels and their size.
pub fn scale_to_width(
    rgb: &[u8],
    width: usize,
    height: usize,
    target: usize,
) -> (Vec<u8>, usize, usize) {
    let target = target.clamp(1, width);
    if target == width {
        return (rgb[..width * height * 3].to_vec(), width, height);
    }
    let out_h = ((height * target + width / 2) / width).max(1);
    let mut out = vec![0u8; target * out_h * 3];
    for oy in 0..out_h {
        let (y0, y1) = span(oy, out_h, height);
        for ox in 0..target {
            let (x0, x1) = span(ox, target, width);
            let mut sum = [0u32; 3];
            for y in y0..y1 {
                let row = &rgb[(y * width + x0) * 3..(y * width + x1) * 3];
                for px in row.chunks_exact(3) {
                    sum[0] += u32::from(px[0]);
                    sum[1] += u32::from(px[1]);
                    sum[2] += u32::from(px[2]);
                }
            }
            let n = ((y1 - y0) * (x1 - x0)) as u32;
            let o = (oy * target + ox) * 3;
            for c in 0..3 {
                out[o + c] = ((sum[c] + n / 2) / n) as u8;
            }
        }
    }
    (out, target, out_h)
}

/// The input rows (or columns) `[from, to)` that output index `i` of `n` covers in `size`.
fn span(i: usize, n: usize, size: usize) -> (usize, usize) {
    let from = i * size / n;
    let to = ((i + 1) * size / n).max(from + 1).min(size);
    (from, to)
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::objects::RelBox;

    fn noise(w: usize, h: usize, seed: u32) -> Vec<u8> {
        let mut x = seed;
        (0..w * h * 3)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                x as u8
            })
            .collect()
    }

    #[test]
    fn scaling_averages_and_keeps_the_aspect() {
        let (w, h) = (4, 2);
        let mut rgb = vec![0u8; w * h * 3];
        // Left half white, right half black.
        for y in 0..h {
            for x in 0..2 {
                rgb[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&[255, 255, 255]);
            }
        }
        let (small, sw, sh) = scale_to_width(&rgb, w, h, 2);
        assert_eq!((sw, sh), (2, 1));
        assert_eq!(small, [255, 255, 255, 0, 0, 0]);
        let (same, ..) = scale_to_width(&rgb, w, h, 999);
        assert_eq!(same, rgb, "never wider than the frame");
        let (_, w3, h3) = scale_to_width(&noise(640, 480, 1), 640, 480, 333);
        assert_eq!((w3, h3), (333, 250));
    }

    #[test]
    fn a_picture_too_big_is_encoded_worse_then_smaller_until_it_fits() {
        // Noise compresses badly: at full size and the best quality it is far over 60 kB.
        let rgb = noise(640, 480, 7);
        let big = make(
            &rgb,
            640,
            480,
            &[],
            &Request {
                annotated: false,
                max_width: 640,
                max_bytes: usize::MAX,
            },
        )
        .unwrap();
        assert_eq!((big.width, big.quality), (640, QUALITIES[0]));
        assert!(big.jpeg.len() > 60_000, "{}", big.jpeg.len());
        let bound = 60_000;
        let fitted = make(
            &rgb,
            640,
            480,
            &[],
            &Request {
                annotated: false,
                max_width: 640,
                max_bytes: bound,
            },
        )
        .unwrap();
        assert!(fitted.jpeg.len() <= bound, "{}", fitted.jpeg.len());
        assert!(fitted.width < 640 || fitted.quality < QUALITIES[0]);
        let (decoded, w, h) = robotd_render::decode_jpeg(&fitted.jpeg).unwrap();
        assert_eq!((w as usize, h as usize), (fitted.width, fitted.height));
        assert_eq!(decoded.len(), w as usize * h as usize * 3);
        let impossible = Request {
            annotated: false,
            max_width: 640,
            max_bytes: 500,
        };
        let error = make(&rgb, 640, 480, &[], &impossible).unwrap_err();
        assert!(error.contains("over 500 bytes"), "{error}");
    }

    #[test]
    fn the_overlay_is_drawn_only_when_asked() {
        let (w, h) = (320, 240);
        let grey = vec![128u8; w * h * 3];
        let mut object = DetectedObject {
            id: "obj-1".into(),
            label: "screwdriver".into(),
            confidence: 0.9,
            ..Default::default()
        };
        object.image_coordinates.bounding_box_rel = RelBox {
            u_min: 0.25,
            v_min: 0.25,
            u_max: 0.75,
            v_max: 0.75,
        };
        let request = |annotated| Request {
            annotated,
            max_width: 160,
            max_bytes: DEFAULT_MAX_BYTES,
        };
        let plain = make(&grey, w, h, std::slice::from_ref(&object), &request(false)).unwrap();
        let drawn = make(&grey, w, h, &[object], &request(true)).unwrap();
        let (plain, ..) = robotd_render::decode_jpeg(&plain.jpeg).unwrap();
        let (drawn, ..) = robotd_render::decode_jpeg(&drawn.jpeg).unwrap();
        let off_grey = |px: &[u8]| px.iter().any(|&c| c.abs_diff(128) > 40);
        let count = |rgb: &[u8]| rgb.chunks_exact(3).filter(|p| off_grey(p)).count();
        assert_eq!(count(&plain), 0);
        assert!(count(&drawn) > 200, "{}", count(&drawn));
    }

    #[test]
    fn a_frame_of_the_wrong_size_is_refused() {
        let request = Request {
            annotated: true,
            max_width: 640,
            max_bytes: DEFAULT_MAX_BYTES,
        };
        let error = make(&[0; 10], 640, 480, &[], &request).unwrap_err();
        assert!(error.contains("not 640×480"), "{error}");
    }
}
