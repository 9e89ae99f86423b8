//! What a real camera and a real room do to a rendered frame: light, colour, lens, focus.
//!
//! The renderer draws a table as flat colours under a light from straight above. Real frames
//! differ: the light comes from a window on one side and is brighter or dimmer, lamps are warm
//! or cold and the camera's white balance does not fully correct it, lenses darken the corners
//! (vignetting), a glossy sheet throws a glare, the focus is soft. [`PhotoEffects::apply`]
//! applies those to an RGB8 frame in place, so that perception can be measured on frames that
//! vary the way real ones do (`robotd bench perception --randomized`). The JPEG compression of
//! a real camera's stream is applied by the caller ([`crate::encode_jpeg`] and a decoder).

/// One frame's photographic conditions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhotoEffects {
    /// Overall exposure gain (1 = as rendered).
    pub exposure: f32,
    /// Light falling off across the frame: gain `1 + g·(position − centre)`, with `g` given
    /// as per-image-width change along u and along v (`[0.3, 0]`: the right edge 30 % brighter
    /// than the left, relative to the centre).
    pub light_gradient: [f32; 2],
    /// Per-channel gains of the light's colour as the camera records it (`[1, 1, 1]`: neutral;
    /// warm lamps `[1.1, 1.0, 0.8]`).
    pub white_balance: [f32; 3],
    /// Darkening at the corners: the gain there is `1 − vignetting` (0 = none).
    pub vignetting: f32,
    /// A glare spot: centre (relative u, v), radius (relative to the image width) and strength
    /// (0 … 1: how far towards white its centre goes).
    pub glare: Option<([f32; 2], f32, f32)>,
    /// Box-blur radius in pixels, applied twice (0 = sharp).
    pub blur_px: u32,
}

impl Default for PhotoEffects {
    fn default() -> Self {
        Self {
            exposure: 1.0,
            light_gradient: [0.0, 0.0],
            white_balance: [1.0, 1.0, 1.0],
            vignetting: 0.0,
            glare: None,
            blur_px: 0,
        }
    }
}

impl PhotoEffects {
    /// Applies the effects to a row-major RGB8 frame of `width` × `height` pixels in place
    /// (nothing happens when the buffer is shorter than that).
    pub fn apply(&self, rgb: &mut [u8], width: usize, height: usize) {
        if width == 0 || height == 0 || rgb.len() < width * height * 3 {
            return;
        }
        if self.blur_px > 0 {
            let mut scratch = Vec::new();
            for _ in 0..2 {
                box_blur(rgb, width, height, self.blur_px as usize, &mut scratch);
            }
        }
        let (wf, hf) = (width as f32, height as f32);
        let half_diagonal = 0.5 * wf.hypot(hf);
        for v in 0..height {
            let dv = (v as f32 + 0.5 - 0.5 * hf) / wf;
            for u in 0..width {
                let du = (u as f32 + 0.5 - 0.5 * wf) / wf;
                let r = (du * wf).hypot(dv * wf) / half_diagonal;
                let mut gain = self.exposure
                    * (1.0 + self.light_gradient[0] * du + self.light_gradient[1] * dv)
                    * (1.0 - self.vignetting * r * r);
                gain = gain.max(0.0);
                let glare = self.glare.map_or(0.0, |(c, radius, strength)| {
                    let d = (u as f32 / wf - c[0]).hypot(v as f32 / wf - c[1] * hf / wf);
                    strength * (-(d / radius.max(1e-3)).powi(2)).exp()
                });
                let i = (v * width + u) * 3;
                for c in 0..3 {
                    let lit = f32::from(rgb[i + c]) * gain * self.white_balance[c];
                    let out = lit + (255.0 - lit).max(0.0) * glare;
                    rgb[i + c] = out.round().clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
}

/// One pass of a box blur of radius `r` (a (2r+1)² mean), rows then columns, edges clamped.
fn box_blur(rgb: &mut [u8], width: usize, height: usize, r: usize, scratch: &mut Vec<u8>) {
    scratch.clear();
    scratch.extend_from_slice(&rgb[..width * height * 3]);
    let n = (2 * r + 1) as u32;
    // Rows: scratch → rgb.
    for v in 0..height {
        let row = v * width;
        for c in 0..3 {
            let at = |u: isize| {
                let u = u.clamp(0, width as isize - 1) as usize;
                u32::from(scratch[(row + u) * 3 + c])
            };
            let mut sum: u32 = (-(r as isize)..=r as isize).map(at).sum();
            for u in 0..width {
                rgb[(row + u) * 3 + c] = ((sum + n / 2) / n) as u8;
                sum = sum + at(u as isize + r as isize + 1) - at(u as isize - r as isize);
            }
        }
    }
    // Columns: rgb → scratch → rgb.
    scratch.copy_from_slice(&rgb[..width * height * 3]);
    for u in 0..width {
        for c in 0..3 {
            let at = |v: isize| {
                let v = v.clamp(0, height as isize - 1) as usize;
                u32::from(scratch[(v * width + u) * 3 + c])
            };
            let mut sum: u32 = (-(r as isize)..=r as isize).map(at).sum();
            for v in 0..height {
                rgb[(v * width + u) * 3 + c] = ((sum + n / 2) / n) as u8;
                sum = sum + at(v as isize + r as isize + 1) - at(v as isize - r as isize);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effects_change_what_they_say_and_nothing_else() {
        let (w, h) = (40, 30);
        let grey = vec![100u8; w * h * 3];
        // None: unchanged.
        let mut same = grey.clone();
        PhotoEffects::default().apply(&mut same, w, h);
        assert_eq!(same, grey);
        // Warm light: red up, blue down.
        let mut warm = grey.clone();
        PhotoEffects {
            white_balance: [1.2, 1.0, 0.7],
            ..PhotoEffects::default()
        }
        .apply(&mut warm, w, h);
        assert_eq!(&warm[..3], &[120, 100, 70]);
        // A gradient along u: the right edge brighter than the left.
        let mut lit = grey.clone();
        PhotoEffects {
            light_gradient: [0.4, 0.0],
            ..PhotoEffects::default()
        }
        .apply(&mut lit, w, h);
        assert!(lit[(w - 1) * 3] > lit[0] + 30);
        // Vignetting darkens corners, not the centre.
        let mut vignetted = grey.clone();
        PhotoEffects {
            vignetting: 0.4,
            ..PhotoEffects::default()
        }
        .apply(&mut vignetted, w, h);
        assert!(vignetted[0] < 70 && vignetted[((h / 2) * w + w / 2) * 3] >= 99);
        // Blur spreads an edge; a flat image stays flat.
        let mut edge = vec![0u8; w * h * 3];
        for v in 0..h {
            for u in w / 2..w {
                edge[(v * w + u) * 3..][..3].fill(200);
            }
        }
        PhotoEffects {
            blur_px: 2,
            ..PhotoEffects::default()
        }
        .apply(&mut edge, w, h);
        let mid = edge[(10 * w + w / 2) * 3];
        assert!(mid > 20 && mid < 200, "{mid}");
        let mut flat = grey.clone();
        PhotoEffects {
            blur_px: 3,
            ..PhotoEffects::default()
        }
        .apply(&mut flat, w, h);
        assert_eq!(flat, grey);
    }
}
