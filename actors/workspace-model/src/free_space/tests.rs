//! Tests of the free-space search: the plain largest rectangle, and the placeable square the
//! tool answers, on random tables.

use super::*;
use robotd_protocol::geometry::{Point3, RobotModel};
use robotd_protocol::workspace::builtin_workspaces;

/// The Ned2's standard sheet, `niryo_ws`.
pub(crate) fn niryo() -> WorkspaceInfo {
    builtin_workspaces(RobotModel::Ned2)[0].to_info(RobotModel::Ned2)
}

fn object(x: f64, y: f64, w: f64, h: f64) -> DetectedObject {
    let mut o = DetectedObject::default();
    o.position.center_of_mass = Point3::new(x, y, 0.0);
    o.dimensions.width_m = w;
    o.dimensions.height_m = h;
    o.dimensions.size_m2 = w * h;
    o
}

/// Asserts that the largest free rectangle among `objects` (grown by `margin`) has `area`
/// and its centre at (`x`, 0), within `tolerance`.
fn assert_largest(objects: &[DetectedObject], margin: f64, area: f64, x: f64, tolerance: f64) {
    let (found, c) = largest_free_space(&niryo(), objects, margin);
    assert!(
        (found - area).abs() < tolerance,
        "area {found}, expected {area}"
    );
    assert!(
        (c.x_m - x).abs() < tolerance && c.y_m.abs() < 1e-9,
        "centre {c:?}, expected ({x}, 0)"
    );
}

#[test]
fn empty_workspace_is_all_free() {
    let ws = niryo();
    let (area, c) = largest_free_space(&ws, &[], 0.01);
    assert!((area - 0.174 * 0.174).abs() < 1e-12);
    assert!((c.x_m - 0.25).abs() < 1e-9 && c.y_m.abs() < 1e-9);
}

#[test]
fn a_strip_across_leaves_the_larger_side() {
    // A bar across the whole width at x = 0.20 (height 0.02 along x, margin 0.01):
    // occupied x ∈ [0.18, 0.22]. Cells are 1.74 mm; cell centres 0.163 + (i + 0.5)·0.00174.
    // Free near side: x < 0.18 → rows 0..=9 (centre of row 9 = 0.17953); far side:
    // x > 0.22 → rows 33..=99 (row 32 centre 0.21956 is occupied, row 33 0.2213 free):
    // 67 rows × 100 columns = 6700 cells → 0.67 × 0.030276 m² = 0.020285 m², centred at
    // x = 0.163 + (33 + 100) / 2 · 0.00174 = 0.27871, y = 0.
    let bar = object(0.20, 0.0, 0.3, 0.02);
    assert_largest(&[bar], 0.01, 0.67 * 0.174 * 0.174, 0.27871, 1e-6);
}

#[test]
fn one_cube_in_the_middle_leaves_the_near_strip() {
    // A 3 cm cube at the centre (0.25, 0) with a 1 cm margin occupies |x − 0.25| ≤ 0.025
    // and |y| ≤ 0.025. Row i's centre is x = 0.163 + (i + 0.5) · 0.00174: row 35 is at
    // 0.22477 (25.2 mm away, free), row 36 at 0.22651 (23.5 mm, occupied) … row 63 at
    // 0.27349 (occupied), row 64 at 0.27523 (25.2 mm, free) — rows 36..=63 are blocked,
    // and by symmetry columns 36..=63.
    // Four free strips of 36 × 100 = 3600 cells each (near, far, right, left); the first
    // found, scanning rows near → far, is the near strip, rows 0..=35:
    // x ∈ [0.163, 0.163 + 36 · 0.00174 = 0.22564], centre x = 0.19432, y = 0;
    // area = 0.36 · 0.174² = 0.01089936 m².
    assert_largest(
        &[object(0.25, 0.0, 0.03, 0.03)],
        0.01,
        0.01089936,
        0.19432,
        1e-9,
    );
}

#[test]
fn a_corner_object_leaves_an_l_whose_larger_arm_wins() {
    // A 5 cm × 5 cm object (no margin) centred on the far-left corner (0.337, 0.087)
    // covers x ≥ 0.312 and y ≥ 0.062. Row 85's centre, 0.163 + 85.5 · 0.00174 = 0.31177,
    // is 25.2 mm from 0.337 (free); row 86's, 0.31351, 23.5 mm (occupied): rows 86..=99
    // are blocked where the object is, and likewise columns 86..=99.
    // Free: rows 0..=85 × all 100 columns = 8600 cells, or all rows × columns 0..=85 =
    // 8600 cells; the row strip is found first (at row 85), the column strip ties and does
    // not replace it. Area 0.86 · 0.030276 = 0.02603736 m²; centre
    // x = 0.163 + 86 · 0.00174 / 2 = 0.23782, y = 0.
    let corner = object(0.337, 0.087, 0.05, 0.05);
    assert_largest(&[corner], 0.0, 0.02603736, 0.23782, 1e-9);
}

#[test]
fn a_full_workspace_has_no_free_space() {
    let ws = niryo();
    let (area, c) = largest_free_space(&ws, &[object(0.25, 0.0, 0.5, 0.5)], 0.0);
    assert_eq!(area, 0.0);
    assert_eq!(c, ws.center());
    let skills = SkillsSettings::new(RobotModel::Ned2, vec![ws.clone()]);
    let full = [object(0.25, 0.0, 0.5, 0.5)];
    assert_eq!(placeable_free_space(&ws, &full, &full, 0.0, &skills), None);
}

/// A seeded xorshift: uniform in [lo, hi).
struct Random(u64);
impl Random {
    fn next(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        lo + (hi - lo) * (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Up to `count` objects that do not overlap, from at most `tries` candidates `candidate`
/// draws (given the next id), as objects stand on a real table.
fn scatter(
    random: &mut Random,
    count: usize,
    tries: usize,
    mut candidate: impl FnMut(&mut Random, usize) -> DetectedObject,
) -> Vec<DetectedObject> {
    let mut objects: Vec<DetectedObject> = Vec::new();
    for id in 0..tries {
        if objects.len() == count {
            break;
        }
        let o = candidate(random, id);
        let here = Rect::of_object(&o);
        if !objects.iter().any(|p| Rect::of_object(p).overlaps(&here)) {
            objects.push(o);
        }
    }
    objects
}

/// The default scene's pencil, red cube, blue square (too wide for the gripper) and green
/// cylinder at random places on the sheet, each where it overlaps none placed before it
/// (one that finds no such place in 50 draws is left out).
fn default_scene_at_random(random: &mut Random) -> Vec<DetectedObject> {
    let sizes = [
        (0.12, 0.012, 0.01),
        (0.03, 0.03, 0.03),
        (0.045, 0.045, 0.01),
        (0.03, 0.03, 0.04),
    ];
    let mut objects: Vec<DetectedObject> = Vec::new();
    for (id, (sx, sy, h)) in sizes.into_iter().enumerate() {
        for _ in 0..50 {
            let o = solid(
                id,
                random.next(0.19, 0.31),
                random.next(-0.07, 0.07),
                sx,
                sy,
                h,
            );
            let here = Rect::of_object(&o);
            if !objects.iter().any(|p| Rect::of_object(p).overlaps(&here)) {
                objects.push(o);
                break;
            }
        }
    }
    objects
}

/// Whether `takes` holds at some point of the sheet, tried every 5 mm.
fn anywhere_on_the_sheet(takes: impl Fn(Point2) -> bool) -> bool {
    (0..35).any(|i| {
        (0..35).any(|j| {
            takes(Point2::new(
                0.163 + 0.005 * i as f64,
                -0.087 + 0.005 * j as f64,
            ))
        })
    })
}

/// An object of `sx` × `sy` (along x, y), `h` high at (x, y), lying along its long side.
fn solid(id: usize, x: f64, y: f64, sx: f64, sy: f64, h: f64) -> DetectedObject {
    let mut o = object(x, y, sy, sx);
    o.id = format!("obj-{id}");
    o.label = format!("object {id}");
    o.position.center_of_mass.z_m = h / 2.0;
    o.gripper_rotation_rad = if sy > sx { PI / 2.0 } else { 0.0 };
    o
}

#[test]
fn any_object_that_fits_the_answered_square_can_be_put_down_at_its_centre() {
    let ws = niryo();
    let skills = SkillsSettings::new(RobotModel::Ned2, vec![ws.clone()]);
    let mut random = Random(0x005e_ed43);
    let (mut scenes, mut tried, mut plain_refused) = (0, 0, 0);
    while scenes < 300 {
        // 1 to 6 objects at random, none overlapping (as on a real table).
        let n = random.next(1.0, 7.0) as usize;
        let objects = scatter(&mut random, n, 50, |random, id| {
            let (sx, sy) = (random.next(0.01, 0.06), random.next(0.01, 0.06));
            let (x, y) = (random.next(0.17, 0.33), random.next(-0.08, 0.08));
            solid(id, x, y, sx, sy, random.next(0.005, 0.06))
        });
        scenes += 1;
        // The plain largest rectangle (the Python server's answer) is often refused.
        let (_, plain) = largest_free_space(&ws, &objects, 0.01);
        let dot = solid(99, plain.x_m, plain.y_m, 0.001, 0.001, 0.002);
        if (0..12).any(|k| {
            table_place_problem(&skills, &objects, &dot, k as f64 * PI / 12.0, plain).is_some()
        }) {
            plain_refused += 1;
        }
        let Some(free) = placeable_free_space(&ws, &objects, &[], 0.01, &skills) else {
            continue;
        };
        // Objects that fit the rectangle, at its centre, at both grasp yaws.
        for k in 0..8 {
            let sx = random.next(0.002, free.size_x_m - 0.002);
            let sy = random.next(0.002, free.size_y_m - 0.002);
            let o = solid(
                100 + k,
                free.center.x_m,
                free.center.y_m,
                sx,
                sy,
                random.next(0.002, 0.06),
            );
            for yaw in [o.gripper_rotation_rad, o.gripper_rotation_rad + PI / 2.0] {
                tried += 1;
                let problem = table_place_problem(&skills, &objects, &o, yaw, free.center);
                assert_eq!(problem, None, "{free:?} in {objects:#?}");
            }
        }
    }
    assert!(tried > 4000, "{tried} places tried");
    assert!(
        plain_refused > 10,
        "the plain answer was refused {plain_refused} times"
    );
}

/// Whether the skills put `o` down at `at` as it lies (at one of their grasp yaws), among
/// `objects` without itself.
fn put_down(
    skills: &SkillsSettings,
    objects: &[DetectedObject],
    o: &DetectedObject,
    at: Point2,
) -> bool {
    let others: Vec<DetectedObject> = objects.iter().filter(|p| p.id != o.id).cloned().collect();
    let long = o.dimensions.width_m.max(o.dimensions.height_m);
    let turned = long <= skills.gripper_max_width_m - 0.002;
    [
        Some(o.gripper_rotation_rad),
        turned.then_some(o.gripper_rotation_rad + PI / 2.0),
    ]
    .into_iter()
    .flatten()
    .any(|yaw| table_place_problem(skills, &others, o, yaw, at).is_none())
}

#[test]
fn every_object_memory_holds_that_fits_the_answered_square_is_put_down_at_its_centre() {
    let ws = niryo();
    let skills = SkillsSettings::new(RobotModel::Ned2, vec![ws.clone()]);
    let mut random = Random(0x0043_0043);
    let (mut fitting, mut too_large) = (0, 0);
    for _ in 0..200 {
        // Up to 5 objects of random sizes on the table, pencils among them, and one held.
        let objects = scatter(&mut random, 5, 60, |random, id| {
            let long = random.next(0.015, 0.12);
            let short = random.next(0.01, long.min(0.05));
            let (sx, sy) = if random.next(0.0, 1.0) < 0.5 {
                (long, short)
            } else {
                (short, long)
            };
            let (x, y) = (random.next(0.18, 0.32), random.next(-0.07, 0.07));
            solid(id, x, y, sx, sy, 0.03)
        });
        let (hx, hy) = (random.next(0.01, 0.08), random.next(0.01, 0.03));
        let held = solid(500, 0.0, 0.0, hx, hy, 0.02);
        let known: Vec<DetectedObject> = objects.iter().chain([&held]).cloned().collect();
        let Some(free) = placeable_free_space(&ws, &objects, &known, 0.01, &skills) else {
            continue;
        };
        assert!(
            (free.size_x_m - free.size_y_m).abs() < 1e-12,
            "a square: {free:?}"
        );
        assert!((free.area_m2 - free.size_x_m * free.size_y_m).abs() < 1e-12);
        for o in &known {
            let (w, h) = (o.dimensions.width_m, o.dimensions.height_m);
            if w.min(h) > skills.gripper_max_width_m - 0.002 {
                continue; // the gripper cannot hold it: it is never placed
            }
            if w.max(h) > free.area_m2.sqrt() {
                too_large += 1;
                continue;
            }
            fitting += 1;
            assert!(
                put_down(&skills, &objects, o, free.center),
                "{o:?} at {free:?} among {objects:#?}"
            );
        }
    }
    assert!(fitting > 300, "{fitting} objects fit the answered square");
    assert!(
        too_large > 100,
        "{too_large} did not: the test has long objects too"
    );
}

#[test]
fn the_default_scenes_objects_anywhere_fit_the_answer_as_its_area_says() {
    // The pencil, red cube, blue square (too wide for the gripper) and green cylinder at
    // random places: each that fits a square of the answered area is put down at its
    // centre, and the answer is never a square no object of the scene fits.
    let ws = niryo();
    let skills = SkillsSettings::new(RobotModel::Ned2, vec![ws.clone()]);
    let mut random = Random(0x0043_0001);
    let (mut fitting, mut answers) = (0, 0);
    for _ in 0..150 {
        let objects = default_scene_at_random(&mut random);
        let Some(free) = placeable_free_space(&ws, &objects, &objects, 0.01, &skills) else {
            continue;
        };
        answers += 1;
        for o in &objects {
            let (w, h) = (o.dimensions.width_m, o.dimensions.height_m);
            let holdable = w.min(h) <= skills.gripper_max_width_m - 0.002;
            if holdable && w.max(h) <= free.area_m2.sqrt() {
                fitting += 1;
                assert!(
                    put_down(&skills, &objects, o, free.center),
                    "{o:?} at {free:?}"
                );
            }
        }
    }
    assert!(answers > 140, "{answers}");
    assert!(
        fitting > answers,
        "{fitting} fitting objects in {answers} answers"
    );
}

#[test]
fn the_answer_takes_the_objects_memory_holds_when_some_free_rectangle_does() {
    let ws = niryo();
    let skills = SkillsSettings::new(RobotModel::Ned2, vec![ws.clone()]);
    let mut random = Random(0x0043_0043);
    // A pencil in the gripper, lying along x: 120 mm × 12 mm.
    let pencil = solid(999, 0.0, 0.0, 0.12, 0.012, 0.01);
    let (mut asked, mut generic_takes, mut known_takes) = (0, 0, 0);
    for _ in 0..200 {
        let objects = scatter(&mut random, 4, 40, |random, id| {
            let side = random.next(0.02, 0.05);
            let (x, y) = (random.next(0.18, 0.32), random.next(-0.07, 0.07));
            solid(id, x, y, side, side, 0.03)
        });
        let takes_at =
            |at: Point2| table_place_problem(&skills, &objects, &pencil, 0.0, at).is_none();
        let takes = |free: &FreeRect| takes_at(free.center);
        // Only scenes with a place for the pencil somewhere (every 5 mm) count.
        let somewhere = anywhere_on_the_sheet(takes_at);
        if !somewhere {
            continue;
        }
        let generic = placeable_free_space(&ws, &objects, &[], 0.01, &skills);
        let known =
            placeable_free_space(&ws, &objects, std::slice::from_ref(&pencil), 0.01, &skills);
        let (Some(generic), Some(known)) = (generic, known) else {
            continue;
        };
        asked += 1;
        generic_takes += usize::from(takes(&generic));
        known_takes += usize::from(takes(&known));
    }
    assert!(asked > 60, "{asked}");
    // 181 of 191: the rest have their only places off every free rectangle's centre.
    assert!(known_takes * 100 >= asked * 90, "{known_takes} of {asked}");
    assert!(
        generic_takes < known_takes,
        "{generic_takes} of {asked} without it"
    );
}

#[test]
fn with_the_default_scenes_objects_anywhere_the_answer_takes_the_pencil() {
    // The pencil, red cube, blue square (too wide for the gripper) and green cylinder at
    // random places: the answer takes the pencil wherever it fits somewhere else.
    let ws = niryo();
    let skills = SkillsSettings::new(RobotModel::Ned2, vec![ws.clone()]);
    let mut random = Random(0x0043_0001);
    let (mut asked, mut takes) = (0, 0);
    for _ in 0..150 {
        let objects = default_scene_at_random(&mut random);
        let pencil = objects[0].clone();
        let others: Vec<DetectedObject> = objects[1..].to_vec();
        let takes_at =
            |at: Point2| table_place_problem(&skills, &others, &pencil, 0.0, at).is_none();
        // Free space is free of the pencil too: a spot overlapping where it lies is none.
        let here = Rect::of_object(&pencil);
        let elsewhere =
            |at: Point2| !Rect::of_object_at(&pencil, at).overlaps(&here) && takes_at(at);
        let somewhere = anywhere_on_the_sheet(elsewhere);
        let Some(free) = placeable_free_space(&ws, &objects, &objects, 0.01, &skills) else {
            continue;
        };
        if somewhere {
            asked += 1;
            takes += usize::from(takes_at(free.center));
        }
    }
    assert!(asked > 50, "{asked}");
    // 119 of 149: where no free rectangle's centre takes all three objects the gripper
    // can hold, the one that takes most wins, and that is often not the pencil's.
    assert!(takes * 100 >= asked * 75, "{takes} of {asked}");
}
