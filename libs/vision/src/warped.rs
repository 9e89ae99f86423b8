//! Recognising an image that is already the workspace square.
//!
//! The Niryo software hands out "extracted workspace" images: the sheet warped so that its
//! four marker centres are the image's corners, the reference marker top-left. Such an image
//! has no whole marker left — only a quarter of one in each corner — so the marker finder
//! cannot place it; but its plane is known without markers (see
//! [`crate::pipeline::Pipeline::warped_plane`]). [`looks_warped`] tells such an image by its
//! shape and its corners: about square, and each of the four corners dark-ringed (a quarter
//! marker), judged against the brightness around it so shade and vignetting do not matter.

use crate::shade::LocalMean;

/// Whether an RGB8 image looks like an extracted workspace: within 10 % of square, at least
/// 32 pixels a side, and a quarter marker (between 12 % and 80 % dark pixels) in each corner.
pub fn looks_warped(rgb: &[u8], width: usize, height: usize) -> bool {
    if width < 32 || height < 32 || rgb.len() < width * height * 3 {
        return false;
    }
    let aspect = width as f64 / height as f64;
    if !(0.9..=1.1).contains(&aspect) {
        return false;
    }
    let mut shade = LocalMean::default();
    shade.compute(rgb, width, height);
    let side = width.min(height);
    let patch = (side / 14).max(4);
    let half = (side / 8).max(6);
    let corners = [
        (0, 0),
        (width - patch, 0),
        (0, height - patch),
        (width - patch, height - patch),
    ];
    corners.iter().all(|&(u0, v0)| {
        let mut dark = 0usize;
        for v in v0..v0 + patch {
            for u in u0..u0 + patch {
                dark += usize::from(shade.darker_than(u, v, half, 62));
            }
        }
        let share = dark as f64 / (patch * patch) as f64;
        (0.12..=0.8).contains(&share)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_markers_in_the_corners_make_a_warped_image() {
        let n = 120;
        let mut rgb = vec![230u8; n * n * 3];
        // Quarter rings around each corner.
        for v in 0..n {
            for u in 0..n {
                let d = [(0, 0), (n, 0), (0, n), (n, n)]
                    .iter()
                    .map(|&(cu, cv)| (u as f64 - cu as f64).hypot(v as f64 - cv as f64))
                    .fold(f64::MAX, f64::min);
                if d < 9.0 && !(3.0..6.0).contains(&d) {
                    rgb[(v * n + u) * 3..][..3].fill(20);
                }
            }
        }
        assert!(looks_warped(&rgb, n, n));
        // A plain sheet, or the same picture stretched out of square, is not.
        assert!(!looks_warped(&vec![230u8; n * n * 3], n, n));
        assert!(!looks_warped(&rgb, n, n * 3 / 4));
        assert!(!looks_warped(&rgb, 10, 10));
    }
}
