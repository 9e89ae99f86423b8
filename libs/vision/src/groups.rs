//! Fragments of one object: blobs that (nearly) touch are one object.
//!
//! On a flat-shaded simulated object one colour covers the whole top face, so one blob is one
//! object. Real objects come apart: a sweet's wrapper is blue with white letters and silver
//! twists, a pad has a black rim around its colour, glare cuts a stripe through a cube, the
//! deep shadow at a cube's foot is dark. [`group_fragments`] joins blobs whose pixels come
//! within a few pixels of each other and decides what the group is:
//! - mostly coloured (by area): a coloured object, measured on its coloured pixels only (a
//!   rim or a shadow does not make it larger), named by its main colour;
//! - mostly dark or of unknown colour: an unknown object, measured on all its pixels.
//!
//! Distinct objects a few millimetres apart stay apart: the gap is a few pixels, and only
//! blobs whose boxes come that close are compared at all (the usual case costs nothing).
//! Pieces of two distinct colours are never one object, even when they touch (a cube pushed
//! against a pad) or a shadow joins them; neighbouring hues (the blue and cyan of one printed
//! wrapper) and slivers of another hue along a shaded edge do join.

use crate::components::{union_root, Blob, Components};

/// One object's pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Its class: the colour (1-based index in the label table) with the most pixels, or the
    /// unknown class.
    pub class: u8,
    /// The pixels it is measured on (indices `v × width + u`).
    pub pixels: Vec<u32>,
    /// Bounding box of those pixels: first and last column and row.
    pub u_min: u32,
    /// Last column.
    pub u_max: u32,
    /// First row.
    pub v_min: u32,
    /// Last row.
    pub v_max: u32,
    /// Mean column of those pixels.
    pub u_mean: f64,
    /// Mean row.
    pub v_mean: f64,
}

/// A piece is small next to a group with more than this many times its area.
const SMALL_PIECE_RATIO: u32 = 5;

/// Distances and sizes, in pixels, that decide which blobs are one object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Gaps {
    /// Blobs whose pixels come this close are one object.
    pub join_px: u32,
    /// A small dark or unknown piece whose box comes this close to a larger group joins it.
    pub absorb_px: u32,
    /// A piece of another colour this small (in pixels) is a sliver of its neighbour (a shaded
    /// edge classified as the next hue), not an object of its own.
    pub sliver_px: u32,
}

/// Groups the blobs of `components` (labelled on a `width`-wide class map) whose pixels come
/// within `gaps.join_px` of each other — never two colours in one group, unless they are
/// neighbouring hues (`neighbour_hues`: one printed wrapper's blue and cyan) or one side is a
/// sliver (at most `gaps.sliver_px`) — then joins each small dark or unknown-coloured piece
/// (under a fifth of the other's area: a dark object as large as a pen stays one) to a group whose box comes within `gaps.absorb_px` of its
/// box. A coloured object is never joined to another this way. `unknown` is the class of dark
/// and unknown-coloured pixels.
pub fn group_fragments(
    components: &Components,
    unknown: u8,
    width: usize,
    gaps: Gaps,
    neighbour_hues: impl Fn(u8, u8) -> bool,
) -> Vec<Group> {
    let (gap, absorb_gap) = (gaps.join_px, gaps.absorb_px);
    let blobs = components.blobs();
    let n = blobs.len();
    let mut parent: Vec<usize> = (0..n).collect();
    let near = |a: &Blob, b: &Blob| {
        a.u_min <= b.u_max + gap
            && b.u_min <= a.u_max + gap
            && a.v_min <= b.v_max + gap
            && b.v_min <= a.v_max + gap
    };
    // The colour of each group (by its root), `None` while it holds only dark or unknown
    // pixels: two groups of different colours are never joined, not even through a dark piece
    // (a shadow) between them, because touching objects of two colours are two objects.
    let mut colour: Vec<Option<u8>> = blobs
        .iter()
        .map(|b| (b.class != unknown).then_some(b.class))
        .collect();
    let mut group_area: Vec<u32> = blobs.iter().map(|b| b.area).collect();
    for i in 0..n {
        for j in i + 1..n {
            let (ri, rj) = (union_root(&mut parent, i), union_root(&mut parent, j));
            if !near(&blobs[i], &blobs[j]) || ri == rj {
                continue;
            }
            let two_colours = matches!(
                (colour[ri], colour[rj]),
                (Some(a), Some(b)) if a != b && !neighbour_hues(a, b)
            );
            if two_colours && group_area[ri].min(group_area[rj]) > gaps.sliver_px {
                continue;
            }
            if pixels_within(components, &blobs[i], &blobs[j], width, gap) {
                let (keep, gone) = (ri.min(rj), ri.max(rj));
                // The larger side names the colour of a group joined with a sliver.
                let larger = if group_area[ri] >= group_area[rj] {
                    ri
                } else {
                    rj
                };
                let merged_colour = colour[larger].or(colour[ri]).or(colour[rj]);
                parent[gone] = keep;
                colour[keep] = merged_colour;
                group_area[keep] = group_area[ri] + group_area[rj];
            }
        }
    }
    // Small dark pieces near a larger group belong to it: a sweet's twisted ends beyond the
    // glare of their silver foil, a shadow's tail.
    let mut area = vec![0u32; n];
    let mut unknown_area = vec![0u32; n];
    let mut boxes = vec![[u32::MAX, u32::MAX, 0, 0]; n];
    for (i, blob) in blobs.iter().enumerate() {
        let r = union_root(&mut parent, i);
        area[r] += blob.area;
        if blob.class == unknown {
            unknown_area[r] += blob.area;
        }
        let b = &mut boxes[r];
        b[0] = b[0].min(blob.u_min);
        b[1] = b[1].min(blob.v_min);
        b[2] = b[2].max(blob.u_max);
        b[3] = b[3].max(blob.v_max);
    }
    let roots: Vec<usize> = (0..n).filter(|&i| parent[i] == i).collect();
    for &small in roots.iter().filter(|&&r| unknown_area[r] * 2 > area[r]) {
        let b = boxes[small];
        let host = roots
            .iter()
            .copied()
            .filter(|&big| {
                let c = boxes[big];
                big != small
                    && area[small] * SMALL_PIECE_RATIO < area[big]
                    && b[0] <= c[2] + absorb_gap
                    && c[0] <= b[2] + absorb_gap
                    && b[1] <= c[3] + absorb_gap
                    && c[1] <= b[3] + absorb_gap
            })
            .max_by_key(|&big| area[big]);
        if let Some(big) = host {
            parent[small] = union_root(&mut parent, big);
        }
    }
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); n];
    for i in 0..n {
        let r = union_root(&mut parent, i);
        members[r].push(i);
    }
    join_parts_of_one_object(components, &mut members, width, (gap, absorb_gap));
    members
        .into_iter()
        .filter(|m| !m.is_empty())
        .map(|m| summarise(components, &m, unknown, width))
        .collect()
}

/// A group whose box lies this much (share of its box) inside a larger group's box, within
/// the absorbing distance of it, is part of it (printing on a wrapper, a label on a box).
const INSIDE_SHARE: f64 = 0.6;
/// Joins groups that are parts of one object: a smaller one (under half the area) lying mostly
/// inside a larger one's outline and within the absorbing distance of it (a label printed on a
/// wrapper, letters on a box), and a piece touching two groups of one other colour (a band
/// printed across a wrapper, which cuts its colour in two). Two colours that only meet side by side stay two
/// objects: a square pushed flush against a cube looks exactly like a bar printed in two
/// halves, and the robot must not take two objects for one.
fn join_parts_of_one_object(
    components: &Components,
    members: &mut [Vec<usize>],
    width: usize,
    (gap, absorb_gap): (u32, u32),
) {
    let blobs = components.blobs();
    loop {
        let boxes: Vec<[u32; 4]> = members
            .iter()
            .map(|m| {
                m.iter().fold([u32::MAX, u32::MAX, 0, 0], |b, &i| {
                    [
                        b[0].min(blobs[i].u_min),
                        b[1].min(blobs[i].v_min),
                        b[2].max(blobs[i].u_max),
                        b[3].max(blobs[i].v_max),
                    ]
                })
            })
            .collect();
        let area = |m: &[usize]| m.iter().map(|&i| blobs[i].area).sum::<u32>();
        let part_of = |a: usize, b: usize| {
            let (ba, bb) = (boxes[a], boxes[b]);
            a != b
                && !members[a].is_empty()
                && 2 * area(&members[a]) < area(&members[b])
                && overlap(ba, bb) as f64 / box_area(ba) as f64 >= INSIDE_SHARE
                && inside_outline(components, &members[a], &members[b], width)
                && members[a].iter().any(|&i| {
                    members[b].iter().any(|&j| {
                        pixels_within(components, &blobs[i], &blobs[j], width, absorb_gap)
                    })
                })
        };
        let n = members.len();
        if let Some((a, b)) = (0..n)
            .flat_map(|a| (0..n).map(move |b| (a, b)))
            .find(|&(a, b)| part_of(a, b))
        {
            let moved = std::mem::take(&mut members[a]);
            members[b].extend(moved);
            continue;
        }
        // A band across a wrapper cuts its colour in two: a piece touching two groups of one
        // other colour joins all three.
        let class = |m: &[usize]| {
            let mut by_class = std::collections::BTreeMap::<u8, u32>::new();
            for &i in m {
                *by_class.entry(blobs[i].class).or_default() += blobs[i].area;
            }
            by_class.into_iter().max_by_key(|(_, a)| *a).map(|(c, _)| c)
        };
        let touches = |a: usize, b: usize| {
            members[a].iter().any(|&i| {
                members[b]
                    .iter()
                    .any(|&j| pixels_within(components, &blobs[i], &blobs[j], width, gap))
            })
        };
        let bridge = (0..n).find_map(|a| {
            if members[a].is_empty() {
                return None;
            }
            let own = class(&members[a]);
            let sides: Vec<usize> = (0..n)
                .filter(|&b| {
                    b != a && !members[b].is_empty() && class(&members[b]) != own && touches(a, b)
                })
                .collect();
            sides.iter().enumerate().find_map(|(k, &b)| {
                sides[k + 1..]
                    .iter()
                    .find(|&&c| class(&members[b]) == class(&members[c]))
                    .map(|&c| (a, b, c))
            })
        });
        let Some((a, b, c)) = bridge else {
            return;
        };
        // A printed band lies inside the wrapper's outline; an object lying across another (a
        // cube on a pencil) sticks out of it. Then the two sides are one object seen on both
        // sides of what covers its middle, and what covers it stays an object of its own.
        let sides: Vec<usize> = members[b].iter().chain(&members[c]).copied().collect();
        let printed_band = inside_outline(components, &members[a], &sides, width);
        let moved_in: &[usize] = if printed_band { &[a, c] } else { &[c] };
        for &moved in moved_in {
            let taken = std::mem::take(&mut members[moved]);
            members[b].extend(taken);
        }
    }
}

/// Whether most of the pixels of the group `inner` lie inside the convex outline of the group
/// `outer`: a label on a wrapper does, an object beside a turned square (inside its box, not
/// its outline) does not.
fn inside_outline(components: &Components, inner: &[usize], outer: &[usize], width: usize) -> bool {
    let blobs = components.blobs();
    let points = |m: &[usize]| -> Vec<[f64; 2]> {
        m.iter()
            .flat_map(|&i| components.pixels(&blobs[i]).iter())
            .map(|&p| [f64::from(p % width as u32), f64::from(p / width as u32)])
            .collect()
    };
    let hull = crate::rect::convex_hull(&points(outer));
    if hull.len() < 3 {
        return false;
    }
    // Counter-clockwise hull: inside is left of every edge (a pixel's width of slack).
    let inside = |p: &[f64; 2]| {
        (0..hull.len()).all(|k| {
            let (a, b) = (hull[k], hull[(k + 1) % hull.len()]);
            let cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
            cross >= -(b[0] - a[0]).hypot(b[1] - a[1])
        })
    };
    let pixels = points(inner);
    let within = pixels.iter().filter(|p| inside(p)).count();
    within * 5 >= pixels.len() * 4
}

fn box_area(b: [u32; 4]) -> u64 {
    u64::from(b[2] - b[0] + 1) * u64::from(b[3] - b[1] + 1)
}

/// Pixels shared by two boxes `[u_min, v_min, u_max, v_max]`.
fn overlap(a: [u32; 4], b: [u32; 4]) -> u64 {
    let w = (a[2].min(b[2]) + 1).saturating_sub(a[0].max(b[0]));
    let h = (a[3].min(b[3]) + 1).saturating_sub(a[1].max(b[1]));
    u64::from(w) * u64::from(h)
}

/// Whether some pixel of `a` lies within `gap` pixels (in both directions) of a pixel of `b`.
fn pixels_within(components: &Components, a: &Blob, b: &Blob, width: usize, gap: u32) -> bool {
    let (small, large) = if a.area <= b.area { (a, b) } else { (b, a) };
    // The larger blob's pixels as a set over its box.
    let (bw, bh) = (large.box_width() as usize, large.box_height() as usize);
    let mut mask = vec![false; bw * bh];
    for &p in components.pixels(large) {
        let (u, v) = (p as usize % width, p as usize / width);
        mask[(v - large.v_min as usize) * bw + (u - large.u_min as usize)] = true;
    }
    let g = gap as i64;
    components.pixels(small).iter().any(|&p| {
        let (u, v) = ((p as usize % width) as i64, (p as usize / width) as i64);
        (-g..=g).any(|dv| {
            (-g..=g).any(|du| {
                let (x, y) = (
                    u + du - i64::from(large.u_min),
                    v + dv - i64::from(large.v_min),
                );
                x >= 0
                    && y >= 0
                    && (x as usize) < bw
                    && (y as usize) < bh
                    && mask[y as usize * bw + x as usize]
            })
        })
    })
}

fn summarise(components: &Components, members: &[usize], unknown: u8, width: usize) -> Group {
    let blobs = components.blobs();
    let mut area_by_class = std::collections::BTreeMap::<u8, u32>::new();
    for &i in members {
        *area_by_class.entry(blobs[i].class).or_default() += blobs[i].area;
    }
    let class = area_by_class
        .iter()
        .max_by_key(|(c, a)| (**a, std::cmp::Reverse(**c)))
        .map(|(c, _)| *c)
        .unwrap_or(unknown);
    let mut pixels = Vec::new();
    for &i in members {
        if class == unknown || blobs[i].class != unknown {
            pixels.extend_from_slice(components.pixels(&blobs[i]));
        }
    }
    let (mut u_min, mut u_max, mut v_min, mut v_max) = (u32::MAX, 0, u32::MAX, 0);
    let (mut su, mut sv) = (0u64, 0u64);
    for &p in &pixels {
        let (u, v) = (p % width as u32, p / width as u32);
        u_min = u_min.min(u);
        u_max = u_max.max(u);
        v_min = v_min.min(v);
        v_max = v_max.max(v);
        su += u64::from(u);
        sv += u64::from(v);
    }
    let count = pixels.len().max(1) as f64;
    Group {
        class,
        u_min,
        u_max,
        v_min,
        v_max,
        u_mean: su as f64 / count,
        v_mean: sv as f64 / count,
        pixels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GAPS: Gaps = Gaps {
        join_px: 2,
        absorb_px: 2,
        sliver_px: 2,
    };

    fn wide_gaps() -> Gaps {
        Gaps {
            absorb_px: 8,
            ..GAPS
        }
    }

    #[test]
    fn touching_fragments_join_and_distant_objects_stay_apart() {
        // A red (1) square with a dark (9) rim on its right, a blue (2) piece 1 px from the
        // red's corner (together no convex whole), and a red square far away.
        let (w, h) = (40, 12);
        let mut map = vec![0u8; w * h];
        let mut fill = |u0: usize, u1: usize, v0: usize, v1: usize, c: u8| {
            for v in v0..v1 {
                for u in u0..u1 {
                    map[v * w + u] = c;
                }
            }
        };
        fill(2, 8, 2, 8, 1);
        fill(8, 9, 2, 8, 9);
        fill(9, 13, 9, 10, 2);
        fill(30, 36, 2, 8, 1);
        let mut c = Components::new();
        c.label(&map, w, h, 1);
        let groups = group_fragments(&c, 9, w, GAPS, |_, _| false);
        assert_eq!(
            groups.len(),
            3,
            "red with its rim, the blue piece, the far red: {groups:?}"
        );
        let first = groups
            .iter()
            .find(|g| g.u_min < 10 && g.class == 1)
            .unwrap();
        assert_eq!(first.pixels.len(), 36, "red pixels, not the dark rim");
        assert_eq!((first.u_max, first.v_max), (8 - 1, 7));
        let blue = groups.iter().find(|g| g.class == 2).unwrap();
        assert_eq!(blue.pixels.len(), 4, "two colours touching are two objects");
        // Red and blue halves flush (a square pushed against a cube, or a bar printed in two
        // halves: they look the same): two objects.
        let mut bar = vec![0u8; w * h];
        for v in 2..8 {
            for u in 2..22 {
                bar[v * w + u] = if u < 12 { 1 } else { 2 };
            }
        }
        c.label(&bar, w, h, 1);
        let groups = group_fragments(&c, 9, w, GAPS, |_, _| false);
        assert_eq!(groups.len(), 2, "{groups:?}");
        // A band of another colour across a wrapper: one object, measured on both colours.
        let mut banded = vec![0u8; w * h];
        for v in 2..8 {
            for u in 2..26 {
                banded[v * w + u] = if (12..16).contains(&u) { 2 } else { 1 };
            }
        }
        c.label(&banded, w, h, 1);
        let groups = group_fragments(&c, 9, w, GAPS, |_, _| false);
        assert_eq!(groups.len(), 1, "{groups:?}");
        assert_eq!((groups[0].class, groups[0].pixels.len()), (1, 144));
        // A blue cube lying across a red pencil sticks out of the pencil's outline: the cube is
        // one object, the pencil's two visible ends another.
        let mut across = vec![0u8; w * h];
        for v in 0..h {
            for u in 2..34 {
                if (14..22).contains(&u) {
                    across[v * w + u] = 2;
                } else if (5..7).contains(&v) {
                    across[v * w + u] = 1;
                }
            }
        }
        c.label(&across, w, h, 1);
        let groups = group_fragments(&c, 9, w, GAPS, |_, _| false);
        let mut found: Vec<(u8, usize)> =
            groups.iter().map(|g| (g.class, g.pixels.len())).collect();
        found.sort();
        assert_eq!(found, vec![(1, 2 * 2 * 12), (2, 8 * 12)], "{groups:?}");
        // A dark pen 4 px from a tray 4.6 times its area stays an object of its own (only
        // small dark pieces — a shadow's tail, a wrapper's twisted end — join a neighbour).
        let (w3, h3) = (60, 40);
        let mut pen_by_tray = vec![0u8; w3 * h3];
        for v in 0..h3 {
            for u in 0..w3 {
                if (2..38).contains(&u) && (2..34).contains(&v) {
                    pen_by_tray[v * w3 + u] = 2;
                } else if (42..49).contains(&u) && (2..38).contains(&v) {
                    pen_by_tray[v * w3 + u] = 9;
                }
            }
        }
        c.label(&pen_by_tray, w3, h3, 1);
        let groups = group_fragments(&c, 9, w3, wide_gaps(), |_, _| false);
        assert_eq!(groups.len(), 2, "{groups:?}");
        // Printing inside a wrapper: a small blue mark inside a large dark object joins it.
        let mut wrapper = vec![0u8; w * h];
        for v in 1..11 {
            for u in 2..30 {
                wrapper[v * w + u] = if (10..14).contains(&u) && (4..7).contains(&v) {
                    2
                } else {
                    9
                };
            }
        }
        c.label(&wrapper, w, h, 1);
        let groups = group_fragments(&c, 9, w, GAPS, |_, _| false);
        assert_eq!(groups.len(), 1, "{groups:?}");
        assert_eq!(groups[0].class, 9, "mostly dark: an unknown object");
        // A red cube beside a blue square turned by 45°: inside the square's box, outside its
        // outline — two objects.
        let (w2, h2) = (40, 40);
        let mut turned = vec![0u8; w2 * h2];
        for v in 0..h2 {
            for u in 0..w2 {
                let (du, dv) = ((u as i32 - 20).abs(), (v as i32 - 20).abs());
                if du + dv <= 16 {
                    turned[v * w2 + u] = 2;
                } else if (30..36).contains(&u) && (30..36).contains(&v) {
                    turned[v * w2 + u] = 1;
                }
            }
        }
        c.label(&turned, w2, h2, 1);
        let wide = Gaps {
            absorb_px: 8,
            ..GAPS
        };
        let groups = group_fragments(&c, 9, w2, wide, |_, _| false);
        assert_eq!(groups.len(), 2, "{groups:?}");
        // A dark strip (a shadow) touching a red and a blue square joins neither to the other.
        let mut bridged = vec![0u8; w * h];
        for v in 2..8 {
            for u in 2..20 {
                bridged[v * w + u] = match u {
                    2..=7 => 1,
                    8..=13 => 9,
                    _ => 2,
                };
            }
        }
        c.label(&bridged, w, h, 1);
        let groups = group_fragments(&c, 9, w, GAPS, |_, _| false);
        let classes: Vec<u8> = groups.iter().map(|g| g.class).collect();
        assert!(
            classes.contains(&1) && classes.contains(&2),
            "red and blue stay two objects: {classes:?}"
        );
        // Mostly dark: an unknown object measured on all its pixels.
        let mut dark = vec![0u8; w * h];
        for v in 2..10 {
            for u in 2..12 {
                dark[v * w + u] = if u == 5 && v == 5 { 1 } else { 9 };
            }
        }
        c.label(&dark, w, h, 1);
        let groups = group_fragments(&c, 9, w, GAPS, |_, _| false);
        assert_eq!(groups.len(), 1);
        assert_eq!((groups[0].class, groups[0].pixels.len()), (9, 80));
    }
}
