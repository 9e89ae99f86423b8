//! Connected components of a class map: which pixels of the same class touch (8-connected).
//!
//! The detector classifies every pixel (0 = nothing, 1…255 = a class such as "dark" or a
//! colour index) and then asks which pixels form one blob. Two passes over the image with a
//! union-find of provisional labels, then the pixels grouped per blob; the buffers are kept
//! between frames, so labelling a frame allocates nothing once warmed up.

/// One blob: its class, size and where its pixels are.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blob {
    /// The class of its pixels.
    pub class: u8,
    /// Number of pixels.
    pub area: u32,
    /// Leftmost column.
    pub u_min: u32,
    /// Rightmost column.
    pub u_max: u32,
    /// Top row.
    pub v_min: u32,
    /// Bottom row.
    pub v_max: u32,
    /// Mean column (pixel centres).
    pub u_mean: f64,
    /// Mean row.
    pub v_mean: f64,
    /// Where its pixel indices start in [`Components::pixels`].
    start: u32,
}

impl Blob {
    /// Width of the bounding box, pixels.
    pub fn box_width(&self) -> u32 {
        self.u_max - self.u_min + 1
    }

    /// Height of the bounding box, pixels.
    pub fn box_height(&self) -> u32 {
        self.v_max - self.v_min + 1
    }
}

/// Reusable connected-component labelling.
#[derive(Debug, Default)]
pub struct Components {
    labels: Vec<u32>,
    parent: Vec<u32>,
    blob_of_root: Vec<u32>,
    pixels: Vec<u32>,
    blobs: Vec<Blob>,
}

impl Components {
    /// A labeller with no buffers yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Finds the blobs of `classes` (`width` × `height`, row-major; 0 = background) with at
    /// least `min_area` pixels.
    pub fn label(&mut self, classes: &[u8], width: usize, height: usize, min_area: u32) {
        let n = width * height;
        debug_assert_eq!(classes.len(), n);
        self.labels.clear();
        self.labels.resize(n, 0);
        self.parent.clear();
        self.parent.push(0); // label 0 = background
        self.blobs.clear();
        self.pixels.clear();
        if n == 0 || classes.len() < n {
            return;
        }

        // Pass 1: provisional labels, joining with the already-labelled neighbours (W, NW, N, NE).
        for v in 0..height {
            let row = v * width;
            for u in 0..width {
                let i = row + u;
                let c = classes[i];
                if c == 0 {
                    continue;
                }
                let mut label = 0u32;
                let mut join = |j: usize, labels: &[u32], parent: &mut Vec<u32>| {
                    if classes[j] == c {
                        let l = labels[j];
                        if label == 0 {
                            label = l;
                        } else if l != label {
                            union(parent, label, l);
                        }
                    }
                };
                if u > 0 {
                    join(i - 1, &self.labels, &mut self.parent);
                }
                if v > 0 {
                    let up = i - width;
                    if u > 0 {
                        join(up - 1, &self.labels, &mut self.parent);
                    }
                    join(up, &self.labels, &mut self.parent);
                    if u + 1 < width {
                        join(up + 1, &self.labels, &mut self.parent);
                    }
                }
                if label == 0 {
                    label = self.parent.len() as u32;
                    self.parent.push(label);
                }
                self.labels[i] = label;
            }
        }

        // Pass 2: resolve every label to its root, and gather per-root statistics.
        let count = self.parent.len();
        for l in 0..count as u32 {
            let root = find(&mut self.parent, l);
            self.parent[l as usize] = root;
        }
        self.blob_of_root.clear();
        self.blob_of_root.resize(count, u32::MAX);
        let mut sums: Vec<(u64, u64)> = Vec::new();
        for v in 0..height {
            for u in 0..width {
                let i = v * width + u;
                let l = self.labels[i];
                if l == 0 {
                    continue;
                }
                let root = self.parent[l as usize] as usize;
                let b = if self.blob_of_root[root] == u32::MAX {
                    self.blob_of_root[root] = self.blobs.len() as u32;
                    self.blobs.push(Blob {
                        class: classes[i],
                        area: 0,
                        u_min: u as u32,
                        u_max: u as u32,
                        v_min: v as u32,
                        v_max: v as u32,
                        u_mean: 0.0,
                        v_mean: 0.0,
                        start: 0,
                    });
                    sums.push((0, 0));
                    self.blobs.len() - 1
                } else {
                    self.blob_of_root[root] as usize
                };
                let blob = &mut self.blobs[b];
                blob.area += 1;
                blob.u_min = blob.u_min.min(u as u32);
                blob.u_max = blob.u_max.max(u as u32);
                blob.v_max = v as u32;
                sums[b].0 += u as u64;
                sums[b].1 += v as u64;
            }
        }
        for (blob, (su, sv)) in self.blobs.iter_mut().zip(&sums) {
            blob.u_mean = *su as f64 / f64::from(blob.area);
            blob.v_mean = *sv as f64 / f64::from(blob.area);
        }

        // Group pixel indices per blob (counting sort), dropping small blobs.
        let mut start = 0u32;
        let mut keep = vec![false; self.blobs.len()];
        for (k, blob) in self.blobs.iter_mut().enumerate() {
            if blob.area >= min_area {
                blob.start = start;
                start += blob.area;
                keep[k] = true;
            }
        }
        self.pixels.resize(start as usize, 0);
        let mut cursor: Vec<u32> = self.blobs.iter().map(|b| b.start).collect();
        for (i, &l) in self.labels.iter().enumerate() {
            if l == 0 {
                continue;
            }
            let b = self.blob_of_root[self.parent[l as usize] as usize] as usize;
            if keep[b] {
                self.pixels[cursor[b] as usize] = i as u32;
                cursor[b] += 1;
            }
        }
        let mut k = 0;
        self.blobs.retain(|_| {
            let kept = keep[k];
            k += 1;
            kept
        });
    }

    /// The blobs of the last [`Components::label`] call, in raster order of their first pixel.
    pub fn blobs(&self) -> &[Blob] {
        &self.blobs
    }

    /// The pixel indices (`v × width + u`) of `blob`, in raster order.
    pub fn pixels(&self, blob: &Blob) -> &[u32] {
        &self.pixels[blob.start as usize..(blob.start + blob.area) as usize]
    }
}

fn find(parent: &mut [u32], mut l: u32) -> u32 {
    let mut root = l;
    while parent[root as usize] != root {
        root = parent[root as usize];
    }
    while parent[l as usize] != root {
        let next = parent[l as usize];
        parent[l as usize] = root;
        l = next;
    }
    root
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let ra = find(parent, a);
    let rb = find(parent, b);
    if ra != rb {
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        parent[hi as usize] = lo;
    }
}

/// The root of `i` in a union-find forest (`parent[root] == root`), halving the path on the
/// way: joining fragments of one object or one marker.
pub(crate) fn union_root(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separates_classes_and_joins_diagonals() {
        // A U shape of class 1 (joined only at the bottom), a diagonal pair of class 2,
        // and a class-3 pixel touching class 1 (stays separate).
        #[rustfmt::skip]
        let map: [u8; 30] = [
            1, 0, 1, 0, 2, 0,
            1, 0, 1, 0, 0, 2,
            1, 1, 1, 3, 0, 0,
            0, 0, 0, 0, 0, 0,
            0, 0, 0, 0, 0, 1,
        ];
        let mut c = Components::new();
        c.label(&map, 6, 5, 1);
        let blobs = c.blobs();
        assert_eq!(blobs.len(), 4, "{blobs:?}");
        let u = blobs.iter().find(|b| b.class == 1 && b.area == 7).unwrap();
        assert_eq!((u.u_min, u.u_max, u.v_min, u.v_max), (0, 2, 0, 2));
        assert_eq!(c.pixels(u), &[0, 2, 6, 8, 12, 13, 14]);
        let d = blobs.iter().find(|b| b.class == 2).unwrap();
        assert_eq!(d.area, 2);
        assert!((d.u_mean - 4.5).abs() < 1e-12 && (d.v_mean - 0.5).abs() < 1e-12);
        assert!(blobs.iter().any(|b| b.class == 3 && b.area == 1));

        c.label(&map, 6, 5, 2);
        assert_eq!(c.blobs().len(), 2, "small blobs are dropped");
    }

    #[test]
    fn empty_and_full_images() {
        let mut c = Components::new();
        c.label(&[0; 12], 4, 3, 1);
        assert!(c.blobs().is_empty());
        c.label(&[5; 12], 4, 3, 1);
        assert_eq!(c.blobs().len(), 1);
        assert_eq!(c.blobs()[0].area, 12);
        c.label(&[], 0, 0, 1);
        assert!(c.blobs().is_empty());
    }
}
