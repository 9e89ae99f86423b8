//! The camera model the perception pipeline needs: raw pixel ↔ ideal (undistorted) pixel.
//!
//! The lens bends straight lines; the homography of [`crate::plane`] holds only for ideal
//! pinhole pixels. Undistorting means inverting the lens model, which is iterative, so the
//! ideal position of every pixel of the sensor is computed once when the pipeline starts and
//! looked up afterwards. A camera without distortion (the simulator's default) skips all this.

use robotd_protocol::camera::CameraIntrinsics;
use robotd_render::Intrinsics;

/// Intrinsics plus the per-pixel undistortion table.
#[derive(Debug, Clone)]
pub struct Camera {
    intrinsics: Intrinsics,
    /// Ideal position of each raw pixel (row-major), or `None` without lens distortion.
    ideal: Option<Vec<[f32; 2]>>,
}

impl Camera {
    /// A camera with these intrinsics; builds the undistortion table when there is distortion.
    pub fn new(intrinsics: &CameraIntrinsics) -> Camera {
        let intrinsics = Intrinsics::from(intrinsics.clone());
        let ideal = intrinsics.distortion.iter().any(|k| *k != 0.0).then(|| {
            let (w, h) = (intrinsics.width as usize, intrinsics.height as usize);
            let mut table = Vec::with_capacity(w * h);
            for v in 0..h {
                for u in 0..w {
                    let p = intrinsics.undistort(nalgebra::Point2::new(u as f64, v as f64));
                    table.push([p.x as f32, p.y as f32]);
                }
            }
            table
        });
        Camera { intrinsics, ideal }
    }

    /// The intrinsics.
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    /// Image width and height the intrinsics are for.
    pub fn size(&self) -> (usize, usize) {
        (
            self.intrinsics.width as usize,
            self.intrinsics.height as usize,
        )
    }

    /// The ideal position of the raw pixel `(u, v)` (integer pixel centres).
    pub fn ideal_of_pixel(&self, u: usize, v: usize) -> [f64; 2] {
        match &self.ideal {
            Some(table) => {
                let i = v * self.intrinsics.width as usize + u;
                match table.get(i) {
                    Some(p) => [f64::from(p[0]), f64::from(p[1])],
                    None => self.ideal_of([u as f64, v as f64]),
                }
            }
            None => [u as f64, v as f64],
        }
    }

    /// The ideal position of any raw (sub-)pixel position.
    pub fn ideal_of(&self, raw: [f64; 2]) -> [f64; 2] {
        if self.ideal.is_none() {
            return raw;
        }
        let p = self
            .intrinsics
            .undistort(nalgebra::Point2::new(raw[0], raw[1]));
        [p.x, p.y]
    }

    /// Where an ideal pixel position appears in the raw image.
    pub fn raw_of(&self, ideal: [f64; 2]) -> [f64; 2] {
        if self.ideal.is_none() {
            return ideal;
        }
        let p = self
            .intrinsics
            .distort(nalgebra::Point2::new(ideal[0], ideal[1]));
        [p.x, p.y]
    }
}
