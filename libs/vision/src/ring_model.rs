//! What a ring marker looks like through blur: the designs' radial profiles, blurred exactly.
//!
//! [`crate::rings`] needs each ring of a marker to come out dark and each gap light. A printed
//! Niryo marker's rings are a sixth of its radius wide — under 2 px for a marker of 10 px — and
//! a camera a little out of focus merges them into grey. What blur keeps is the marker's radial
//! profile, smoothed. This module knows that profile for every design ([`MarkerDesign`]) and for
//! the dark shapes that are not markers ([`Hypothesis`]): discs, rings of any width reaching
//! the outer edge, a disc of one grey inside a ring of another (a cube with shaded sides, a
//! bottle cap). [`fit_profile`] says how well each explains a measured radial profile, at the
//! best scale and the best blur, with the grey levels of its bands free (within 0..=255);
//! [`crate::ring_fit`] measures the profile and decides.
//!
//! The blurred profiles are computed exactly: the radial profile of concentric bands blurred
//! by a 2-D Gaussian of width σ is, at distance `t` from the centre,
//! `∫ band(ρ) · ρ/σ² · exp(−(ρ² + t²)/2σ²) · I₀(ρt/σ²) dρ` ([`blurred_bands`]).

use std::sync::OnceLock;

/// Profile samples per outer radius (the template table's resolution along a ray).
pub const PER_RADIUS: usize = 32;
/// Samples of a fitted profile: `t = j / PER_RADIUS` for `j < SAMPLES` (out to 1.44).
pub const SAMPLES: usize = 47;
/// Scales tried for a hypothesis, as factors on the measured radius.
pub const SCALES: [f64; 16] = [
    0.7, 0.75, 0.8, 0.85, 0.9, 0.95, 1.0, 1.05, 1.1, 1.15, 1.2, 1.25, 1.3, 1.35, 1.4, 1.45,
];
/// Samples of a measured profile: `t = i / (2 · PER_RADIUS)`, far enough for the largest scale.
pub const FINE: usize = 2 * SAMPLES * 3 / 2 + 4;
/// Blur widths (Gaussian σ, pixels) tried.
pub const BLUR_PX: [f64; 10] = [0.35, 0.6, 0.85, 1.1, 1.35, 1.6, 1.9, 2.2, 2.6, 3.0];
/// Blur widths of the table, as fractions of the outer radius.
const SIGMA_STEP: f64 = 0.015;
const SIGMAS: usize = 31;
/// Fitted grey levels may lie this far outside 0..=255 (noise, a slightly wrong blur).
const PLAUSIBLE_SLACK: f64 = 25.0;
/// Where the light disc a printed marker sits on ends (the classic sheet's stripes, the Ned2
/// sheet's black pad begin), as a fraction of the outer radius; beyond it the level is free.
pub const SURROUND_END: f64 = 1.3;

/// The marker designs robotd knows: the simulator's and Niryo's printed sheets', the reference
/// (upper-left) marker and the other three of each.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MarkerDesign {
    /// The simulator's reference: white centre, two dark rings.
    PlainReference,
    /// The simulator's other markers: solid centre disc, one dark ring around it.
    PlainOther,
    /// Niryo's printed reference: solid centre disc and two rings.
    PrintedReference,
    /// Niryo's printed other markers: a small dot and three rings.
    PrintedOther,
}

impl MarkerDesign {
    /// Every design.
    pub const ALL: [MarkerDesign; 4] = [
        Self::PlainReference,
        Self::PlainOther,
        Self::PrintedReference,
        Self::PrintedOther,
    ];

    /// The dark bands (inner, outer fractions of the outer radius), from the centre out.
    pub fn bands(self) -> &'static [(f64, f64)] {
        match self {
            Self::PlainReference => &[(0.2, 0.45), (0.7, 1.0)],
            Self::PlainOther => &[(0.0, 0.45), (0.7, 1.0)],
            Self::PrintedReference => &[(0.0, 0.3), (0.5, 0.7), (0.85, 1.0)],
            Self::PrintedOther => &[(0.0, 0.08), (0.25, 0.4), (0.55, 0.7), (0.85, 1.0)],
        }
    }

    /// Whether it is a printed (Niryo) design: on a light disc of [`SURROUND_END`] radii,
    /// beyond which the sheet is striped or black. The simulator's markers lie on plain paper.
    pub fn printed(self) -> bool {
        matches!(self, Self::PrintedReference | Self::PrintedOther)
    }

    /// Whether it is the reference marker of its sheet.
    pub fn reference(self) -> bool {
        matches!(self, Self::PlainReference | Self::PrintedReference)
    }

    /// The other design of the same sheet (reference ↔ other).
    pub fn sibling(self) -> Self {
        match self {
            Self::PlainReference => Self::PlainOther,
            Self::PlainOther => Self::PlainReference,
            Self::PrintedReference => Self::PrintedOther,
            Self::PrintedOther => Self::PrintedReference,
        }
    }

    /// Whether it is light an eighth of its radius from the centre (as [`crate::rings`]
    /// measures it).
    pub fn white_centre(self) -> bool {
        !self.bands().iter().any(|&(a, b)| a <= 0.125 && 0.125 <= b)
    }

    /// Dark rings (or disc) a ray crosses from an eighth of the radius outwards, as
    /// [`crate::rings`] counts them.
    pub fn rings(self) -> u8 {
        let centre = u8::from(!self.white_centre());
        let later = self.bands().iter().filter(|&&(a, _)| a > 0.125).count() as u8;
        centre + later
    }

    /// The outer ring's inner edge over the outer radius: the design's signature, as
    /// [`crate::rings`] measures it.
    pub fn ring_fraction(self) -> f64 {
        self.bands().last().map_or(0.0, |&(a, _)| a)
    }

    /// Its row of the template table.
    pub fn basis(self) -> usize {
        self as usize
    }

    /// Its hypothesis.
    pub fn hypothesis(self) -> Hypothesis {
        Hypothesis(self as usize)
    }
}

/// The bands of each basis profile of the table: the four designs, then the parts of the
/// shapes that are not markers, then the surround beyond [`SURROUND_END`].
const BASES: [&[(f64, f64)]; 14] = [
    &[(0.2, 0.45), (0.7, 1.0)],
    &[(0.0, 0.45), (0.7, 1.0)],
    &[(0.0, 0.3), (0.5, 0.7), (0.85, 1.0)],
    &[(0.0, 0.08), (0.25, 0.4), (0.55, 0.7), (0.85, 1.0)],
    &[(0.0, 1.0)],
    &[(0.3, 1.0)],
    &[(0.55, 1.0)],
    &[(0.8, 1.0)],
    &[(0.0, 0.3)],
    &[(0.0, 0.5)],
    &[(0.0, 0.7)],
    &[(0.5, 1.0)],
    &[(0.7, 1.0)],
    &[(SURROUND_END, 1e3)],
];
const SURROUND: usize = 13;

/// An explanation of a radial profile: bands whose grey levels are free (each basis one
/// level; a design's ink darker than its paper), and a free level beyond [`SURROUND_END`] or
/// paper all the way: the designs and the shapes that are not markers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Hypothesis(usize);

/// The bases of each hypothesis and whether the level beyond [`SURROUND_END`] is free: the
/// four designs (the simulator's on plain paper), then the shapes that are not markers — a
/// disc, rings reaching the outer edge, a disc of one grey inside a ring of another.
const HYPOTHESES: [(&[usize], bool); 11] = [
    (&[0], false),
    (&[1], false),
    (&[2], true),
    (&[3], true),
    (&[4], true),
    (&[5], true),
    (&[6], true),
    (&[7], true),
    (&[8, 5], true),
    (&[9, 11], true),
    (&[10, 12], true),
];

/// The dark discs and rings that are not markers.
pub const NOT_MARKERS: [Hypothesis; 4] =
    [Hypothesis(4), Hypothesis(5), Hypothesis(6), Hypothesis(7)];
/// A disc of one grey inside a ring of another: not markers either, with one free level more
/// than a design.
pub const TWO_LEVELS: [Hypothesis; 3] = [Hypothesis(8), Hypothesis(9), Hypothesis(10)];

impl Hypothesis {
    fn bases(self) -> &'static [usize] {
        HYPOTHESES[self.0].0
    }

    fn surround(self) -> bool {
        HYPOTHESES[self.0].1
    }

    fn is_design(self) -> bool {
        self.0 < 4
    }

    /// Its basis profiles (the constant first) at the table's blur index `s`.
    fn rows(self, s: usize) -> ([&'static [f64; SAMPLES]; 5], usize) {
        static ONES: [f64; SAMPLES] = [1.0; SAMPLES];
        let table = table();
        let mut rows = [&ONES; 5];
        let mut n = 1;
        for &b in self.bases() {
            rows[n] = &table[b][s];
            n += 1;
        }
        if self.surround() {
            rows[n] = &table[SURROUND][s];
            n += 1;
        }
        (rows, n)
    }
}

/// `I₀(x)·e^(−x)` (Abramowitz & Stegun 9.8.1–2, error below 2·10⁻⁷).
fn bessel_i0_scaled(x: f64) -> f64 {
    let x = x.abs();
    if x <= 3.75 {
        let y = (x / 3.75).powi(2);
        let i0 = 1.0
            + y * (3.515_622_9
                + y * (3.089_942_4
                    + y * (1.206_749_2 + y * (0.265_973_2 + y * (0.036_076_8 + y * 0.004_581_3)))));
        i0 * (-x).exp()
    } else {
        let y = 3.75 / x;
        let p = 0.398_942_28
            + y * (0.013_285_92
                + y * (0.002_253_19
                    + y * (-0.001_575_65
                        + y * (0.009_162_81
                            + y * (-0.020_577_06
                                + y * (0.026_355_37 + y * (-0.016_476_33 + y * 0.003_923_77)))))));
        p / x.sqrt()
    }
}

/// The share of a Gaussian blur of width `sigma` at distance `t` from the centre that falls on
/// the `bands` (inner, outer radii; same units): the blurred pattern's darkness there.
pub fn blurred_bands(bands: &[(f64, f64)], t: f64, sigma: f64) -> f64 {
    if sigma < 1e-6 {
        return f64::from(u8::from(bands.iter().any(|&(a, b)| a <= t && t <= b)));
    }
    let s2 = sigma * sigma;
    let mut total = 0.0;
    for &(a, b) in bands {
        let (lo, hi) = (a.max(t - 7.0 * sigma).max(0.0), b.min(t + 7.0 * sigma));
        if hi <= lo {
            continue;
        }
        // Simpson's rule with steps of at most a tenth of σ.
        let n = (((hi - lo) / (0.1 * sigma)).ceil() as usize)
            .max(2)
            .next_multiple_of(2);
        let h = (hi - lo) / n as f64;
        let f =
            |r: f64| r / s2 * (-(r - t).powi(2) / (2.0 * s2)).exp() * bessel_i0_scaled(r * t / s2);
        let mut sum = f(lo) + f(hi);
        for k in 1..n {
            sum += f(lo + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
        }
        total += sum * h / 3.0;
    }
    total.clamp(0.0, 1.0)
}

/// `[basis][sigma][sample]`: every basis profile at every blur width of the table.
type Table = Vec<[[f64; SAMPLES]; SIGMAS]>;

fn table() -> &'static Table {
    static TABLE: OnceLock<Table> = OnceLock::new();
    TABLE.get_or_init(|| {
        BASES
            .iter()
            .map(|bands| {
                let mut rows = [[0.0; SAMPLES]; SIGMAS];
                for (s, row) in rows.iter_mut().enumerate() {
                    for (j, x) in row.iter_mut().enumerate() {
                        *x = blurred_bands(
                            bands,
                            j as f64 / PER_RADIUS as f64,
                            s as f64 * SIGMA_STEP,
                        );
                    }
                }
                rows
            })
            .collect()
    })
}

/// The table's blur index for a blur of `blur_px` on a radius of `radius_px`.
fn sigma_index(blur_px: f64, radius_px: f64) -> usize {
    ((blur_px / radius_px / SIGMA_STEP).round() as usize).min(SIGMAS - 1)
}

/// The profile of basis `basis` of a marker of `radius_px` blurred by `blur_px`.
pub fn basis_profile(basis: usize, blur_px: f64, radius_px: f64) -> &'static [f64; SAMPLES] {
    &table()[basis][sigma_index(blur_px, radius_px)]
}

/// The profile of the surround beyond [`SURROUND_END`] (see [`basis_profile`]).
pub fn surround_profile(blur_px: f64, radius_px: f64) -> &'static [f64; SAMPLES] {
    basis_profile(SURROUND, blur_px, radius_px)
}

/// How well a hypothesis explains a profile, at its best scale and blur.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfileFit {
    /// Residual, grey levels (root mean square over the samples).
    pub residual: f64,
    /// The scale, as a factor on the measured radius.
    pub scale: f64,
    /// The blur (Gaussian σ), pixels.
    pub blur_px: f64,
    /// The paper's grey level (the level where no band is).
    pub paper: f64,
    /// What each basis adds to the paper's level (negative: darker).
    pub bands: [f64; 2],
    /// What the surround adds (0 when it is paper).
    pub beyond: f64,
}

/// The inverse of the normal matrix of each hypothesis's bases at each blur index (row-major,
/// `n × n` for `n` bases with the constant): least squares then costs a few dot products.
fn inverses() -> &'static Vec<Vec<Option<Vec<f64>>>> {
    static INVERSES: OnceLock<Vec<Vec<Option<Vec<f64>>>>> = OnceLock::new();
    INVERSES.get_or_init(|| {
        (0..HYPOTHESES.len())
            .map(|h| {
                (0..SIGMAS)
                    .map(|s| {
                        let (rows, n) = Hypothesis(h).rows(s);
                        let normal = nalgebra::DMatrix::from_fn(n, n, |a, b| {
                            rows[a].iter().zip(rows[b]).map(|(x, y)| x * y).sum::<f64>()
                        });
                        // A blur so wide that two bases look alike leaves no fit there.
                        let inverse = normal.clone().try_inverse()?;
                        let check = &normal * &inverse;
                        let identity = nalgebra::DMatrix::<f64>::identity(n, n);
                        ((check - identity).amax() < 1e-6)
                            .then(|| inverse.transpose().as_slice().to_vec())
                    })
                    .collect()
            })
            .collect()
    })
}

/// The profile `fine` (grey levels at `t = i / (2 · PER_RADIUS)` of `radius_px`) resampled at
/// the table's samples for a marker `scale` times that radius.
pub fn resample(fine: &[f64; FINE], scale: f64) -> [f64; SAMPLES] {
    std::array::from_fn(|j| {
        let x = 2.0 * j as f64 * scale;
        let i = (x as usize).min(FINE - 2);
        let f = x - i as f64;
        fine[i] + f * (fine[i + 1] - fine[i])
    })
}

/// The best fit of `hypothesis` to the profile `fine` of a candidate of `radius_px`, over the
/// scales `scales` and every blur; grey levels outside 0..=255 (by more than a little) are not
/// a fit. `None` when nothing fits.
pub fn fit_profile(
    fine: &[f64; FINE],
    radius_px: f64,
    hypothesis: Hypothesis,
    scales: &[f64],
) -> Option<ProfileFit> {
    let level = |g: f64| (-PLAUSIBLE_SLACK..=255.0 + PLAUSIBLE_SLACK).contains(&g);
    let inverses = &inverses()[hypothesis.0];
    let mut best: Option<ProfileFit> = None;
    for &scale in scales {
        let grey = resample(fine, scale);
        let grey_sq: f64 = grey.iter().map(|g| g * g).sum();
        let radius = scale * radius_px;
        let mut last = usize::MAX;
        for blur_px in BLUR_PX {
            let s = sigma_index(blur_px, radius);
            if s == last {
                continue; // the same blur on the table
            }
            last = s;
            let Some(inverse) = &inverses[s] else {
                continue;
            };
            let (rows, n) = hypothesis.rows(s);
            let mut rhs = [0.0; 5];
            for (r, row) in rhs.iter_mut().zip(&rows[..n]) {
                *r = row.iter().zip(&grey).map(|(x, g)| x * g).sum();
            }
            let mut c = [0.0; 5];
            for a in 0..n {
                c[a] = (0..n).map(|b| inverse[a * n + b] * rhs[b]).sum();
            }
            let explained: f64 = (0..n).map(|a| c[a] * rhs[a]).sum();
            let residual = ((grey_sq - explained).max(0.0) / SAMPLES as f64).sqrt();
            // Paper, each band and what lies beyond.
            let beyond = if hypothesis.surround() { c[n - 1] } else { 0.0 };
            let bands = [
                c[1],
                if hypothesis.bases().len() > 1 {
                    c[2]
                } else {
                    0.0
                },
            ];
            let plausible = level(c[0])
                && level(c[0] + bands[0])
                && level(c[0] + bands[1])
                && level(c[0] + beyond)
                && (bands[0] < 0.0 || !hypothesis.is_design());
            if plausible && best.is_none_or(|f| residual < f.residual) {
                best = Some(ProfileFit {
                    residual,
                    scale,
                    blur_px,
                    paper: c[0],
                    bands,
                    beyond,
                });
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blurred_bands_are_a_blurred_disc() {
        // A disc of radius 1 blurred by σ: at its centre 1 − exp(−1/2σ²), at its edge ~½.
        let disc = [(0.0, 1.0)];
        for sigma in [0.1, 0.3, 0.6] {
            let centre = blurred_bands(&disc, 0.0, sigma);
            let expected = 1.0 - (-1.0 / (2.0 * sigma * sigma)).exp();
            assert!((centre - expected).abs() < 1e-4, "σ {sigma}: {centre}");
            // At the edge a little under half (the disc curves away).
            let edge = blurred_bands(&disc, 1.0, sigma);
            assert!((0.35..0.5).contains(&edge), "σ {sigma}: {edge}");
        }
        assert_eq!(blurred_bands(&disc, 0.5, 0.0), 1.0);
        assert_eq!(blurred_bands(&disc, 1.5, 0.0), 0.0);
        // Far from every band, nothing.
        assert!(blurred_bands(&[(0.85, 1.0)], 0.0, 0.05) < 1e-9);
    }

    #[test]
    fn the_designs_signs_match_the_ring_check() {
        use MarkerDesign::*;
        assert!(PlainReference.white_centre() && !PlainOther.white_centre());
        assert!(!PrintedReference.white_centre() && PrintedOther.white_centre());
        assert_eq!([PlainReference.rings(), PlainOther.rings()], [2, 2]);
        assert_eq!([PrintedReference.rings(), PrintedOther.rings()], [3, 3]);
        assert_eq!(PlainOther.ring_fraction(), 0.7);
        assert_eq!(PrintedOther.ring_fraction(), 0.85);
        for d in MarkerDesign::ALL {
            assert_eq!(BASES[d.hypothesis().bases()[0]], d.bands());
            assert_eq!(d.sibling().sibling(), d);
            assert_ne!(d.sibling().reference(), d.reference());
        }
    }

    #[test]
    fn a_profile_is_explained_by_its_own_design_at_its_blur() {
        // The printed reference at radius 12 px, blurred by 1.1 px, paper 200, ink 40.
        let design = MarkerDesign::PrintedReference;
        let fine: [f64; FINE] = std::array::from_fn(|i| {
            let t = i as f64 / (2 * PER_RADIUS) as f64;
            200.0 - 160.0 * blurred_bands(design.bands(), t, 1.1 / 12.0)
        });
        let own = fit_profile(&fine, 12.0, design.hypothesis(), &SCALES).unwrap();
        assert!(own.residual < 1.0, "{own:?}");
        assert!(
            (own.scale - 1.0).abs() < 0.01 && (own.blur_px - 1.1).abs() < 0.3,
            "{own:?}"
        );
        assert!((own.paper - 200.0).abs() < 3.0 && (own.bands[0] + 160.0).abs() < 5.0);
        let sibling = fit_profile(&fine, 12.0, design.sibling().hypothesis(), &SCALES).unwrap();
        assert!(
            sibling.residual > 5.0 * own.residual.max(1.0),
            "{sibling:?}"
        );
        for h in NOT_MARKERS.into_iter().chain(TWO_LEVELS) {
            let other = fit_profile(&fine, 12.0, h, &SCALES).unwrap();
            assert!(
                other.residual > 3.0 * own.residual.max(1.0),
                "{h:?}: {other:?}"
            );
        }
    }
}
