//! From an object's pixels to its footprint on the table.
//!
//! Every detector — the built-in colour detector, a neural network, an external detector
//! sending masks over Redis — ends up with the pixels of an object's top face. This module
//! turns them into world geometry the same way for all of them: each pixel is undistorted,
//! mapped through the table plane at the object's height (removing the parallax of a raised
//! top face), and the points are summarised as centre of mass, minimum-area rectangle
//! (centre, width along y, height along x, direction) and how much of that rectangle they
//! fill (a disc fills π/4 of it).

use crate::camera::Camera;
use crate::plane::TablePlane;
use crate::rect::{convex_hull, min_area_rect, RotatedRect};
use robotd_protocol::geometry::Point3;
use robotd_protocol::objects::{
    DetectedObject, Dimensions, ImageCoordinates, ObjectPosition, RelBox, RelPoint,
};

/// Pixels whose centres lie on the edge of a mask stand for about half a pixel beyond it; the
/// rectangle through the outermost pixel centres is grown by this many pixels in total.
const EDGE_GROWTH_PX: f64 = 0.75;

/// An object's footprint on the table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Mean of the mapped pixels (the mask's centre of mass), metres.
    pub centre_of_mass: [f64; 2],
    /// The minimum-area rectangle, metres.
    pub rect: RotatedRect,
    /// Area of the points' convex hull over the rectangle's area (1 for a box, π/4 for a disc).
    pub fill: f64,
    /// The height the pixels were mapped at, metres.
    pub height_m: f64,
}

/// Maps the pixels `pixels` (indices `v × width + u` of the raw image) as points at height
/// `height_m` and summarises them. `None` for fewer than three pixels.
pub fn measure(
    pixels: &[u32],
    width: usize,
    camera: &Camera,
    plane: &TablePlane,
    height_m: f64,
) -> Option<Footprint> {
    if pixels.len() < 3 || width == 0 {
        return None;
    }
    let mut points = Vec::with_capacity(pixels.len());
    let (mut sx, mut sy) = (0.0, 0.0);
    for &i in pixels {
        let (u, v) = (i as usize % width, i as usize / width);
        let p = plane.pixel_to_plane(camera.ideal_of_pixel(u, v), height_m);
        sx += p[0];
        sy += p[1];
        points.push(p);
    }
    let n = points.len() as f64;
    let centre_of_mass = [sx / n, sy / n];
    let mut rect = min_area_rect(&points)?;
    let hull = convex_hull(&points);
    let hull_area = polygon_area(&hull);

    // The world size of one pixel at the object, to account for the half pixel beyond the
    // outermost pixel centres.
    let first = pixels[pixels.len() / 2] as usize;
    let (u, v) = (first % width, first / width);
    let a = plane.pixel_to_plane(camera.ideal_of([u as f64, v as f64]), height_m);
    let b = plane.pixel_to_plane(camera.ideal_of([u as f64 + 1.0, v as f64]), height_m);
    let pixel_m = (a[0] - b[0]).hypot(a[1] - b[1]);
    rect.long += EDGE_GROWTH_PX * pixel_m;
    rect.short += EDGE_GROWTH_PX * pixel_m;
    let grown_hull = hull_area + perimeter(&hull) * EDGE_GROWTH_PX * pixel_m / 2.0;
    let fill = (grown_hull / rect.area()).clamp(0.0, 1.0);
    Some(Footprint {
        centre_of_mass,
        rect,
        fill,
        height_m,
    })
}

/// Who found an object and where in the image: what [`Footprint::to_object`] needs besides
/// the footprint.
#[derive(Debug, Clone, PartialEq)]
pub struct Sighting {
    /// The label.
    pub label: String,
    /// The detector's class index (−1: none).
    pub class_id: i64,
    /// The detector's confidence, 0..=1.
    pub confidence: f64,
    /// The workspace the object lies in.
    pub workspace_id: String,
    /// Capture time of the frame, seconds since the Unix epoch.
    pub timestamp_unix_s: f64,
    /// The object's box, as fractions of the image size.
    pub bbox: RelBox,
    /// The centre of mass of its pixels, as fractions of the image size.
    pub center_of_mass_rel: RelPoint,
    /// Yaw to turn the gripper by to grasp it, radians.
    pub gripper_rotation_rad: f64,
}

impl Footprint {
    /// The object of the tools' JSON that this footprint and `sighting` describe (id left
    /// empty: the workspace model assigns it). Its centre lies at half its height.
    pub fn to_object(&self, sighting: Sighting) -> DetectedObject {
        let (width_m, height_m) = self.rect.width_height();
        let z = self.height_m / 2.0;
        let centre = self.rect.centre;
        let bbox = sighting.bbox;
        DetectedObject {
            id: String::new(),
            label: sighting.label,
            workspace_id: sighting.workspace_id,
            timestamp_unix_s: sighting.timestamp_unix_s,
            position: ObjectPosition {
                center_of_mass: Point3::new(self.centre_of_mass[0], self.centre_of_mass[1], z),
                center: Point3::new(centre[0], centre[1], z),
            },
            image_coordinates: ImageCoordinates {
                center_rel: RelPoint {
                    u: (bbox.u_min + bbox.u_max) / 2.0,
                    v: (bbox.v_min + bbox.v_max) / 2.0,
                },
                center_of_mass_rel: sighting.center_of_mass_rel,
                bounding_box_rel: bbox,
            },
            dimensions: Dimensions {
                width_m,
                height_m,
                size_m2: width_m * height_m,
            },
            gripper_rotation_rad: sighting.gripper_rotation_rad,
            confidence: sighting.confidence,
            class_id: sighting.class_id,
        }
    }
}

fn polygon_area(poly: &[[f64; 2]]) -> f64 {
    let n = poly.len();
    if n < 3 {
        return 0.0;
    }
    let twice: f64 = (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    twice.abs() / 2.0
}

fn perimeter(poly: &[[f64; 2]]) -> f64 {
    let n = poly.len();
    if n < 2 {
        return 0.0;
    }
    (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            (a[0] - b[0]).hypot(a[1] - b[1])
        })
        .sum()
}
