//! The renderer: projection, clipping, visibility, painter's order, shading, noise, lens.

use crate::intrinsics::{Intrinsics, Undistorter};
use crate::mesh::{self, MeshBuffers, Relation, SolidMesh};
use crate::noise;
use crate::scene::{RenderOptions, RenderScene, Rgb};
use crate::RenderError;
use nalgebra::{Isometry3, Point2, Point3, UnitQuaternion, Vector3};
use rand::rngs::SmallRng;
use rand::{RngCore, SeedableRng};
use std::ops::Range;
use tiny_skia::{BlendMode, FillRule, Paint, PathBuilder, Pixmap, Transform};

/// Geometry closer to the camera than this (metres, along the viewing direction) is cut away.
const NEAR_M: f64 = 0.002;
/// Clipping margin around the drawn area, pixels (keeps anti-aliased edges right at the border).
const CLIP_MARGIN_PX: f64 = 16.0;
/// Largest image side the renderer accepts, pixels.
const MAX_SIDE: u32 = 4096;
/// What is seen above the horizon, beyond the table.
const ROOM: Rgb = [60, 60, 60];
/// Brightness of a vertical face relative to a face towards the light.
const AMBIENT: f64 = 0.55;

type NoiseTable = Box<[i16; noise::TABLE_LEN]>;

/// Draws [`RenderScene`]s as the wrist camera sees them, into RGB8 frame buffers.
///
/// Build one per camera and keep it: it owns the drawing surface, the noise generator and the
/// lens-distortion lookup table, so rendering a frame allocates (almost) nothing.
pub struct Renderer {
    intrinsics: Intrinsics,
    options: RenderOptions,
    /// `None` when the intrinsics are unusable.
    target: Option<Target>,
    noise: Option<NoiseTable>,
    rng: SmallRng,
    scratch: Scratch,
}

impl std::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Renderer")
            .field("intrinsics", &self.intrinsics)
            .field("options", &self.options)
            .field(
                "canvas",
                &self
                    .target
                    .as_ref()
                    .map(|t| (t.pixmap.width(), t.pixmap.height())),
            )
            .finish_non_exhaustive()
    }
}

/// The surface drawn on: the ideal (undistorted) image, larger than the output when the lens
/// distortion pulls in pixels from beyond the output's field of view.
struct Target {
    pixmap: Pixmap,
    /// Transparent layer of the canvas's size where one solid at a time is drawn, its faces
    /// added up, then composited onto `pixmap` (anti-aliasing without seams between faces).
    layer: Pixmap,
    /// Ideal pixel coordinates of the centre of canvas pixel (0, 0).
    origin: (f64, f64),
    /// With lens distortion: for each output pixel, the canvas pixel it shows.
    remap: Option<Vec<u32>>,
}

/// A face ready to draw: its projected outline in the scratch point buffer.
#[derive(Debug, Clone)]
struct DrawFace {
    points: Range<usize>,
    color: Rgb,
}

/// A solid with at least one visible face.
#[derive(Debug, Clone)]
struct SolidRec {
    mesh: SolidMesh,
    depth: f64,
    /// Canvas bounding box of the visible faces: min x, min y, max x, max y.
    bbox: [f32; 4],
    faces: Range<usize>,
}

/// Buffers reused from frame to frame.
#[derive(Default)]
struct Scratch {
    mesh: MeshBuffers,
    solids: Vec<SolidRec>,
    faces: Vec<DrawFace>,
    points: Vec<[f32; 2]>,
    poly: Vec<Vector3<f64>>,
    poly_tmp: Vec<Vector3<f64>>,
    edges: Vec<(usize, usize)>,
    indegree: Vec<u32>,
    done: Vec<bool>,
    order: Vec<usize>,
    builder: PathBuilder,
}

/// Camera-space clipping and projection onto the canvas.
struct Projector {
    camera_from_world: Isometry3<f64>,
    /// Half-spaces `a x + b y + c z + d >= 0`, camera frame: near plane and the four sides.
    planes: [[f64; 4]; 5],
    fx: f64,
    fy: f64,
    /// Principal point in tiny-skia canvas coordinates (pixel centres at +0.5).
    u0: f64,
    v0: f64,
}

impl Projector {
    fn new(intr: &Intrinsics, target: &Target, camera_pose: &Isometry3<f64>) -> Self {
        let (ox, oy) = target.origin;
        let w = f64::from(target.pixmap.width());
        let h = f64::from(target.pixmap.height());
        let (umin, umax) = (ox - 0.5 - CLIP_MARGIN_PX, ox + w - 0.5 + CLIP_MARGIN_PX);
        let (vmin, vmax) = (oy - 0.5 - CLIP_MARGIN_PX, oy + h - 0.5 + CLIP_MARGIN_PX);
        let (fx, fy, cx, cy) = (intr.fx, intr.fy, intr.cx, intr.cy);
        Self {
            camera_from_world: camera_pose.inverse(),
            planes: [
                [0.0, 0.0, 1.0, -NEAR_M],
                [fx, 0.0, cx - umin, 0.0],
                [-fx, 0.0, umax - cx, 0.0],
                [0.0, fy, cy - vmin, 0.0],
                [0.0, -fy, vmax - cy, 0.0],
            ],
            fx,
            fy,
            u0: cx - ox + 0.5,
            v0: cy - oy + 0.5,
        }
    }

    /// Clips the camera-frame polygon `poly` to the view (Sutherland–Hodgman) and appends its
    /// projection to `out`. Returns the number of points appended (0 when nothing is left or
    /// anything is not finite).
    fn clip_project(
        &self,
        poly: &mut Vec<Vector3<f64>>,
        tmp: &mut Vec<Vector3<f64>>,
        out: &mut Vec<[f32; 2]>,
    ) -> usize {
        for [a, b, c, d] in self.planes {
            if poly.len() < 3 {
                return 0;
            }
            tmp.clear();
            let value = |p: &Vector3<f64>| a * p.x + b * p.y + c * p.z + d;
            let mut prev = poly[poly.len() - 1];
            let mut dp = value(&prev);
            for &cur in poly.iter() {
                let dc = value(&cur);
                if dc >= 0.0 {
                    if dp < 0.0 {
                        tmp.push(prev + (cur - prev) * (dp / (dp - dc)));
                    }
                    tmp.push(cur);
                } else if dp >= 0.0 {
                    tmp.push(prev + (cur - prev) * (dp / (dp - dc)));
                }
                prev = cur;
                dp = dc;
            }
            std::mem::swap(poly, tmp);
        }
        if poly.len() < 3 {
            return 0;
        }
        let start = out.len();
        for p in poly.iter() {
            let u = (self.fx * p.x / p.z + self.u0) as f32;
            let v = (self.fy * p.y / p.z + self.v0) as f32;
            if !(u.is_finite() && v.is_finite()) {
                out.truncate(start);
                return 0;
            }
            out.push([u, v]);
        }
        poly.len()
    }

    /// Transforms world points into `poly` (camera frame); false when one is not finite.
    fn load(
        &self,
        poly: &mut Vec<Vector3<f64>>,
        points: impl Iterator<Item = Point3<f64>>,
    ) -> bool {
        poly.clear();
        for p in points {
            let c = self.camera_from_world * p;
            if !c.iter().all(|v| v.is_finite()) {
                return false;
            }
            poly.push(c.coords);
        }
        true
    }
}

impl Renderer {
    /// A renderer for a camera with these intrinsics. Precomputes the noise table and, with
    /// `lens_distortion`, the distortion remap (a few tens of milliseconds, once).
    ///
    /// Never fails: with unusable intrinsics (zero or over 4096-pixel size, non-positive or
    /// non-finite focal length, non-finite coefficients) [`Renderer::render_into`] returns
    /// [`RenderError::InvalidIntrinsics`].
    pub fn new(intrinsics: Intrinsics, options: RenderOptions) -> Self {
        let target = make_target(&intrinsics, options.lens_distortion);
        let noise = (options.noise_stddev.is_finite() && options.noise_stddev > 0.0)
            .then(|| noise::gaussian_table(options.noise_stddev.min(255.0)))
            .and_then(|table| table.into_boxed_slice().try_into().ok());
        Self {
            intrinsics,
            options,
            target,
            noise,
            rng: SmallRng::seed_from_u64(options.seed),
            scratch: Scratch::default(),
        }
    }

    /// The camera's intrinsics.
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    /// The options the renderer was built with.
    pub fn options(&self) -> &RenderOptions {
        &self.options
    }

    /// Renders `scene` seen from `camera_pose` into `out`.
    ///
    /// `camera_pose` is the pose of the camera's optical frame in the world: z is the viewing
    /// direction, x points to the image's right, y to the image's bottom.
    /// `out` receives RGB8, row-major, exactly `width × height × 3` bytes; every byte is
    /// written.
    ///
    /// Items with non-finite or non-positive dimensions are skipped. Errors: wrong buffer
    /// size, a camera pose that is not finite or whose rotation quaternion is zero, unusable
    /// intrinsics; `out` is left untouched then.
    pub fn render_into(
        &mut self,
        scene: &RenderScene,
        camera_pose: &Isometry3<f64>,
        out: &mut [u8],
    ) -> Result<(), RenderError> {
        let expected = (self.intrinsics.width as usize)
            .saturating_mul(self.intrinsics.height as usize)
            .saturating_mul(3);
        if out.len() != expected {
            return Err(RenderError::BufferSize {
                expected,
                got: out.len(),
            });
        }
        let Some(target) = self.target.as_mut() else {
            return Err(RenderError::InvalidIntrinsics);
        };
        // A rotation that drifted off unit length (accumulated round-off) is renormalised.
        let q = camera_pose.rotation.into_inner();
        let norm = q.norm();
        let finite = camera_pose.translation.vector.iter().all(|v| v.is_finite())
            && q.coords.iter().all(|v| v.is_finite());
        if !finite || norm <= 1e-6 {
            return Err(RenderError::InvalidCameraPose);
        }
        let camera_pose = &Isometry3::from_parts(
            camera_pose.translation,
            UnitQuaternion::new_unchecked(q / norm),
        );
        let projector = Projector::new(&self.intrinsics, target, camera_pose);
        let scratch = &mut self.scratch;
        let camera = Point3::from(camera_pose.translation.vector);
        let shading = self.options.shading;

        let c = ROOM;
        target
            .pixmap
            .fill(tiny_skia::Color::from_rgba8(c[0], c[1], c[2], 255));
        draw_flat(target, scratch, &projector, scene, &camera, shading);
        draw_solids(target, scratch, &projector, scene, &camera, shading);
        write_output(target, self.noise.as_deref(), &mut self.rng, out);
        Ok(())
    }
}

/// The drawing surface for these intrinsics, `None` when they are unusable.
fn make_target(intr: &Intrinsics, lens_distortion: bool) -> Option<Target> {
    if !intr.is_valid() || intr.width > MAX_SIDE || intr.height > MAX_SIDE {
        return None;
    }
    let (w, h) = (intr.width, intr.height);
    if !lens_distortion || intr.distortion.iter().all(|k| *k == 0.0) {
        return Some(Target {
            pixmap: Pixmap::new(w, h)?,
            layer: Pixmap::new(w, h)?,
            origin: (0.0, 0.0),
            remap: None,
        });
    }
    // For each output (distorted) pixel, the ideal pixel it shows.
    let undistorter = Undistorter::new(&intr.distortion);
    let mut sources = Vec::with_capacity(w as usize * h as usize);
    let (mut lo_x, mut lo_y, mut hi_x, mut hi_y) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for v in 0..h {
        for u in 0..w {
            let p = undistorter.ideal_pixel(intr, Point2::new(f64::from(u), f64::from(v)));
            let p = if p.x.is_finite() && p.y.is_finite() {
                p
            } else {
                Point2::new(f64::from(u), f64::from(v))
            };
            lo_x = lo_x.min(p.x);
            lo_y = lo_y.min(p.y);
            hi_x = hi_x.max(p.x);
            hi_y = hi_y.max(p.y);
            sources.push(p);
        }
    }
    // The canvas covers every source, within [-w/2, 1.5 w] × [-h/2, 1.5 h].
    let (wf, hf) = (f64::from(w), f64::from(h));
    let x0 = (lo_x.round() - 1.0).clamp(-wf / 2.0, 0.0);
    let y0 = (lo_y.round() - 1.0).clamp(-hf / 2.0, 0.0);
    let x1 = (hi_x.round() + 1.0).clamp(wf - 1.0, 1.5 * wf);
    let y1 = (hi_y.round() + 1.0).clamp(hf - 1.0, 1.5 * hf);
    let cw = (x1 - x0) as u32 + 1;
    let ch = (y1 - y0) as u32 + 1;
    let remap = sources
        .iter()
        .map(|p| {
            let kx = (p.x.round() - x0).clamp(0.0, f64::from(cw - 1)) as u32;
            let ky = (p.y.round() - y0).clamp(0.0, f64::from(ch - 1)) as u32;
            ky * cw + kx
        })
        .collect();
    Some(Target {
        pixmap: Pixmap::new(cw, ch)?,
        layer: Pixmap::new(cw, ch)?,
        origin: (x0, y0),
        remap: Some(remap),
    })
}

/// Brightness of a face with outward unit normal `n`: 1 facing straight up, `AMBIENT`
/// (± a little, so neighbouring sides differ) for vertical faces.
fn brightness(n: &Vector3<f64>) -> f64 {
    let side = Vector3::new(0.8, 0.6, 0.0);
    (AMBIENT + (1.0 - AMBIENT) * n.z.max(0.0) + 0.08 * n.dot(&side)).clamp(0.0, 1.0)
}

fn shade(color: Rgb, n: &Vector3<f64>, shading: bool) -> Rgb {
    if !shading {
        return color;
    }
    let b = brightness(n);
    color.map(|c| (f64::from(c) * b).round() as u8)
}

/// Fills the polygon `poly` (a range of `points`), anti-aliased, blending with `blend`.
fn fill(
    pixmap: &mut Pixmap,
    builder: &mut PathBuilder,
    points: &[[f32; 2]],
    poly: Range<usize>,
    color: Rgb,
    blend: BlendMode,
) {
    let mut b = std::mem::take(builder);
    b.clear();
    if let Some([first, rest @ ..]) = points.get(poly) {
        if rest.len() >= 2 {
            b.move_to(first[0], first[1]);
            for p in rest {
                b.line_to(p[0], p[1]);
            }
            b.close();
        }
    }
    if b.is_empty() {
        *builder = b;
        return;
    }
    if let Some(path) = b.finish() {
        let mut paint = Paint::default();
        paint.set_color_rgba8(color[0], color[1], color[2], 255);
        paint.anti_alias = true;
        paint.blend_mode = blend;
        pixmap.fill_path(
            &path,
            &paint,
            FillRule::Winding,
            Transform::identity(),
            None,
        );
        *builder = path.clear();
    }
}

/// Projects and fills one flat world polygon.
fn fill_world_polygon(
    target: &mut Target,
    scratch: &mut Scratch,
    projector: &Projector,
    points: impl Iterator<Item = Point3<f64>>,
    color: Rgb,
) {
    if !projector.load(&mut scratch.poly, points) {
        return;
    }
    scratch.points.clear();
    let n = projector.clip_project(
        &mut scratch.poly,
        &mut scratch.poly_tmp,
        &mut scratch.points,
    );
    if n >= 3 {
        fill(
            &mut target.pixmap,
            &mut scratch.builder,
            &scratch.points,
            0..n,
            color,
            BlendMode::SourceOver,
        );
    }
}

/// The table, the quads and the discs, in that order.
fn draw_flat(
    target: &mut Target,
    scratch: &mut Scratch,
    projector: &Projector,
    scene: &RenderScene,
    camera: &Point3<f64>,
    shading: bool,
) {
    let z = scene.table_z_m;
    if z.is_finite() && camera.z > z {
        let reach = 20.0 + 50.0 * (camera.z - z);
        let (x, y) = (camera.x, camera.y);
        let corners = [
            Point3::new(x - reach, y - reach, z),
            Point3::new(x + reach, y - reach, z),
            Point3::new(x + reach, y + reach, z),
            Point3::new(x - reach, y + reach, z),
        ];
        fill_world_polygon(
            target,
            scratch,
            projector,
            corners.into_iter(),
            scene.background,
        );
    }
    for (corners, color) in &scene.quads {
        let Some(mut n) = mesh::polygon_normal(corners.iter().copied()) else {
            continue;
        };
        if n.z < 0.0 {
            n = -n;
        }
        let color = shade(*color, &n, shading);
        fill_world_polygon(target, scratch, projector, corners.iter().copied(), color);
    }
    for disc in &scene.discs {
        let (c, r) = (disc.center, disc.radius_m);
        if !(c.iter().all(|v| v.is_finite()) && r.is_finite() && r > 0.0) {
            continue;
        }
        // Enough sides to keep the outline within ~0.1 px of the circle.
        let depth = (projector.camera_from_world * c).z;
        let sides = if depth > NEAR_M + r {
            let r_px = projector.fx.max(projector.fy) * r / (depth - r);
            (7.0 * r_px.sqrt()).ceil().clamp(16.0, 256.0) as usize
        } else {
            256
        };
        let step = std::f64::consts::TAU / sides as f64;
        let rim = (0..sides).map(|i| {
            let (s, co) = (step * i as f64).sin_cos();
            Point3::new(c.x + r * co, c.y + r * s, c.z)
        });
        fill_world_polygon(target, scratch, projector, rim, disc.color);
    }
}

/// Boxes and cylinders: visible faces only, solids ordered far to near by separating planes.
fn draw_solids(
    target: &mut Target,
    scratch: &mut Scratch,
    projector: &Projector,
    scene: &RenderScene,
    camera: &Point3<f64>,
    shading: bool,
) {
    let s = scratch;
    s.mesh.clear();
    s.solids.clear();
    s.faces.clear();
    s.points.clear();
    for solid in &scene.solids {
        let Some(mesh) = mesh::push_solid(&mut s.mesh, solid) else {
            continue;
        };
        let depth = (projector.camera_from_world * Point3::from(solid.pose.translation.vector)).z;
        let first_face = s.faces.len();
        let mut bbox = [f32::MAX, f32::MAX, f32::MIN, f32::MIN];
        for face in &s.mesh.faces[mesh.faces.clone()] {
            let Some(&i0) = s.mesh.indices.get(face.indices.start) else {
                continue;
            };
            if face.normal.dot(&(camera - s.mesh.verts[i0])) <= 0.0 {
                continue; // back face
            }
            let verts = &s.mesh.verts;
            let corners = s.mesh.indices[face.indices.clone()]
                .iter()
                .map(|&i| verts[i]);
            if !projector.load(&mut s.poly, corners) {
                continue;
            }
            let start = s.points.len();
            let n = projector.clip_project(&mut s.poly, &mut s.poly_tmp, &mut s.points);
            if n < 3 {
                continue;
            }
            for p in &s.points[start..start + n] {
                bbox = [
                    bbox[0].min(p[0]),
                    bbox[1].min(p[1]),
                    bbox[2].max(p[0]),
                    bbox[3].max(p[1]),
                ];
            }
            s.faces.push(DrawFace {
                points: start..start + n,
                color: shade(solid.color, &face.normal, shading),
            });
        }
        if s.faces.len() > first_face {
            s.solids.push(SolidRec {
                mesh,
                depth,
                bbox,
                faces: first_face..s.faces.len(),
            });
        }
    }

    // Which solid must be drawn before which: only pairs whose outlines may overlap.
    let n = s.solids.len();
    s.edges.clear();
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (&s.solids[i], &s.solids[j]);
            let overlap = a.bbox[0] <= b.bbox[2] + 1.0
                && b.bbox[0] <= a.bbox[2] + 1.0
                && a.bbox[1] <= b.bbox[3] + 1.0
                && b.bbox[1] <= a.bbox[3] + 1.0;
            if !overlap {
                continue;
            }
            let m = &s.mesh;
            match mesh::relation(
                &m.verts[a.mesh.verts.clone()],
                &m.axes[a.mesh.axes.clone()],
                &m.verts[b.mesh.verts.clone()],
                &m.axes[b.mesh.axes.clone()],
                camera,
            ) {
                Relation::FirstInFront => s.edges.push((j, i)),
                Relation::SecondInFront => s.edges.push((i, j)),
                // Touching or interpenetrating: left to the depth order.
                Relation::Unrelated | Relation::Unknown => {}
            }
        }
    }

    // Topological order (behind before in front), farthest first among the free ones; a
    // cycle (possible with three or more solids) is broken at the farthest solid.
    s.indegree.clear();
    s.indegree.resize(n, 0);
    for &(_, front) in &s.edges {
        s.indegree[front] += 1;
    }
    s.done.clear();
    s.done.resize(n, false);
    s.order.clear();
    for _ in 0..n {
        let farthest = |free_only: bool| {
            (0..n)
                .filter(|&k| !s.done[k] && (!free_only || s.indegree[k] == 0))
                .max_by(|&a, &b| s.solids[a].depth.total_cmp(&s.solids[b].depth))
        };
        let Some(pick) = farthest(true).or_else(|| farthest(false)) else {
            break;
        };
        s.done[pick] = true;
        s.order.push(pick);
        for &(behind, front) in &s.edges {
            if behind == pick {
                s.indegree[front] = s.indegree[front].saturating_sub(1);
            }
        }
    }

    // Each solid: its visible faces (which do not overlap, the solid being convex) added up
    // on the transparent layer, so a pixel on an edge between two faces gets both colours in
    // proportion and full coverage; then the layer over the canvas.
    for &k in &s.order {
        let rec = &s.solids[k];
        for face in &s.faces[rec.faces.clone()] {
            fill(
                &mut target.layer,
                &mut s.builder,
                &s.points,
                face.points.clone(),
                face.color,
                BlendMode::Plus,
            );
        }
        composite_and_clear(&mut target.layer, &mut target.pixmap, rec.bbox);
    }
}

/// `layer` (premultiplied) over `canvas` within `bbox` (canvas coordinates), then clears that
/// part of `layer`.
fn composite_and_clear(layer: &mut Pixmap, canvas: &mut Pixmap, bbox: [f32; 4]) {
    let (w, h) = (layer.width() as usize, layer.height() as usize);
    if (canvas.width() as usize, canvas.height() as usize) != (w, h) || w == 0 || h == 0 {
        return;
    }
    let clamp = |v: f32, max: usize| (v.max(0.0) as usize).min(max);
    let (x0, x1) = (clamp(bbox[0] - 2.0, w - 1), clamp(bbox[2] + 2.0, w - 1));
    let (y0, y1) = (clamp(bbox[1] - 2.0, h - 1), clamp(bbox[3] + 2.0, h - 1));
    if x0 > x1 || y0 > y1 {
        return;
    }
    let src = layer.data_mut();
    let dst = canvas.data_mut();
    for y in y0..=y1 {
        let row = (y * w + x0) * 4..(y * w + x1 + 1) * 4;
        let (Some(s_row), Some(d_row)) = (src.get_mut(row.clone()), dst.get_mut(row)) else {
            continue;
        };
        for (s, d) in s_row.chunks_exact_mut(4).zip(d_row.chunks_exact_mut(4)) {
            let a = u16::from(s[3]);
            if a == 0 {
                continue;
            }
            let keep = 255 - a;
            for i in 0..3 {
                let v = u16::from(s[i]) + (u16::from(d[i]) * keep + 127) / 255;
                d[i] = v.min(255) as u8;
            }
            s.fill(0);
        }
    }
}

/// RGBA canvas → RGB output, through the lens remap, with noise.
fn write_output(
    target: &Target,
    noise: Option<&[i16; noise::TABLE_LEN]>,
    rng: &mut SmallRng,
    out: &mut [u8],
) {
    let data = target.pixmap.data();
    let put = |o: &mut [u8], src: usize, rng: &mut SmallRng| {
        let px = data.get(src * 4..src * 4 + 3).unwrap_or(&[0, 0, 0]);
        match noise {
            None => o.copy_from_slice(px),
            Some(table) => {
                let r = rng.next_u64();
                let mut add = |i: usize, bits: u64| {
                    let n = table[(bits & 0xffff) as usize];
                    o[i] = (i16::from(px[i]) + n).clamp(0, 255) as u8;
                };
                add(0, r);
                add(1, r >> 16);
                add(2, r >> 32);
            }
        }
    };
    match &target.remap {
        Some(remap) => {
            for (o, &src) in out.chunks_exact_mut(3).zip(remap.iter()) {
                put(o, src as usize, rng);
            }
        }
        None => {
            for (i, o) in out.chunks_exact_mut(3).enumerate() {
                put(o, i, rng);
            }
        }
    }
}
