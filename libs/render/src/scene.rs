//! What the camera can see: the table, flat things lying on it, and solids.

use nalgebra::{Isometry3, Point3, Vector3};

/// A colour: red, green, blue, 0..=255.
pub type Rgb = [u8; 3];

/// The geometry of a [`Solid`], in the solid's own frame, centred on its origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// A rectangular box.
    Box {
        /// Full extents along the solid's local x, y and z, metres.
        size_m: Vector3<f64>,
    },
    /// An upright cylinder, drawn as a 32-sided prism with its top and bottom discs.
    Cylinder {
        /// Radius, metres.
        radius_m: f64,
        /// Height along the local z axis, metres.
        height_m: f64,
    },
}

/// A convex object: a box or a cylinder somewhere in the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solid {
    /// Its geometry.
    pub shape: Shape,
    /// World pose of the solid's **centre** (for an object standing on the table at height
    /// `z = 0`, the centre is at half its height).
    pub pose: Isometry3<f64>,
    /// Its colour as lit from straight above; faces turned away from the light are drawn darker.
    pub color: Rgb,
}

/// A flat filled circle on a horizontal plane (normal +z), e.g. one ring of a workspace marker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disc {
    /// Centre, world frame, metres.
    pub center: Point3<f64>,
    /// Radius, metres.
    pub radius_m: f64,
    /// Fill colour.
    pub color: Rgb,
}

/// Everything to draw in one frame.
///
/// Drawing order: the table, then `quads` in order, then `discs` in order (a later disc covers
/// an earlier one, so concentric rings are several discs from the largest to the smallest),
/// then the solids, nearest last. Flat things are not depth-tested against each other; lift
/// them by a fraction of a millimetre if they must not be hidden by a solid standing on them.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderScene {
    /// Colour of the table, which fills the view down to the horizon.
    pub background: Rgb,
    /// Height of the table plane, world frame, metres.
    pub table_z_m: f64,
    /// Flat polygons (corners in order around the edge, either direction), e.g. a white
    /// sheet of paper, with their colour.
    pub quads: Vec<([Point3<f64>; 4], Rgb)>,
    /// Flat discs, drawn in order (later on top).
    pub discs: Vec<Disc>,
    /// Boxes and cylinders. They must not interpenetrate.
    pub solids: Vec<Solid>,
}

/// How the image is made: noise, lens and lighting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Standard deviation of the Gaussian per-channel sensor noise, in 0..255 units (default 2).
    /// 0 turns the noise off. It is added to each output pixel (after the lens, as on the
    /// sensor), independently per pixel and channel, and clipped to 0..=255.
    pub noise_stddev: f64,
    /// Apply the intrinsics' lens distortion, as the real camera's raw image has it (default
    /// off).
    pub lens_distortion: bool,
    /// Seed of the noise: the same seed gives the same sequence of frames.
    pub seed: u64,
    /// Flat shading: faces are darker the more they turn away from a light above, so the top
    /// of a box is brighter than its sides (default on). Colours keep their hue.
    pub shading: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            noise_stddev: 2.0,
            lens_distortion: false,
            seed: 0,
            shading: true,
        }
    }
}
