//! The second look for markers, when the first found no sheet: blurred and small markers.
//!
//! [`MarkerFinder::find_markers`] sees a marker when its rings come out dark and its gaps
//! light. When they do not — a camera a little out of focus, a marker of a few pixels —
//! [`MarkerFinder::find_blurred_markers`] looks again on the same frame: dark discs with a
//! light rim ([`crate::disc_scan`]) are candidates, and a candidate is a marker when its
//! blurred radial profile is one of the known designs' with its role (reference or not) and
//! family clear ([`crate::ring_fit`]). The markers it finds are described as the ring check
//! describes its own (reference or not, design), so that the sheet checks treat both alike;
//! one that a dark disc or ring would explain as well is marked only *like* its design
//! ([`MarkerEvidence::Profile`]), and a sheet made with it must show its border too
//! ([`crate::sheet`]). Where fits overlap, the largest is kept: a marker's middle can look
//! like a smaller marker.

use crate::markers::{MarkerEvidence, MarkerFinder, MarkerObservation};
use crate::ring_fit::fit_marker;

/// At most this many candidates are fitted per frame (the most contrasted first).
const MAX_FITS: usize = 48;
/// Markers of fewer pixels of radius are not looked for: too few to tell the designs apart.
const MIN_RADIUS_PX: f64 = 6.0;

impl MarkerFinder {
    /// The blurred-profile fits of the last [`MarkerFinder::find_blurred_markers`] call: each
    /// candidate and what the fit found (to find out why a marker was missed).
    pub fn blurred_fits(
        &self,
    ) -> &[(
        crate::disc_scan::DiscCandidate,
        Option<crate::ring_fit::ModelFit>,
    )] {
        &self.fits
    }

    /// Markers of the frame last given to [`MarkerFinder::find_markers`] that its ring check
    /// could not see, found by their blurred profile; none within half a radius of a marker of
    /// `known`.
    pub fn find_blurred_markers(&mut self, known: &[MarkerObservation]) -> Vec<MarkerObservation> {
        self.fits.clear();
        let (w, h) = self.shade.size();
        if w < 16 || h < 16 {
            return Vec::new();
        }
        // A marker is about a seventeenth of its sheet's side, and the sheet is in the frame.
        let max_radius = w.min(h) as f64 / 12.0;
        let min_radius = MIN_RADIUS_PX.max(w.min(h) as f64 / 120.0);
        let candidates = self
            .scan
            .scan(&self.shade, min_radius, max_radius, MAX_FITS)
            .to_vec();
        let mut found: Vec<MarkerObservation> = Vec::new();
        for c in candidates {
            let near = |m: &MarkerObservation| {
                (m.centre_px[0] - c.centre[0]).hypot(m.centre_px[1] - c.centre[1])
                    < 0.5 * m.radius_px.max(c.radius_px)
            };
            if known.iter().any(near) {
                continue;
            }
            let fit = fit_marker(&self.shade, c.centre, c.radius_px);
            self.fits.push((c, fit));
            let Some(fit) = fit else {
                continue;
            };
            let Ok(distinct) = fit.verdict() else {
                continue;
            };
            let m = MarkerObservation {
                centre_px: fit.centre,
                radius_px: fit.radius_px,
                white_centre: fit.design.white_centre(),
                rings: fit.design.rings(),
                ring_changes: 0,
                paper_grey: fit.paper.clamp(0.0, 255.0) as u8,
                ring_fraction: fit.design.ring_fraction(),
                evidence: MarkerEvidence::Profile {
                    blur_px: fit.blur_px,
                    distinct,
                },
            };
            // Where fits overlap, the largest is the marker: its outer ring is its largest
            // round part (a smaller fit is its middle seen as a marker).
            let overlaps = |k: &MarkerObservation| {
                (k.centre_px[0] - m.centre_px[0]).hypot(k.centre_px[1] - m.centre_px[1])
                    < 0.5 * k.radius_px.max(m.radius_px)
            };
            if known.iter().any(overlaps) {
                continue;
            }
            if let Some(i) = found.iter().position(overlaps) {
                if found[i].radius_px < m.radius_px {
                    found[i] = m;
                }
                continue;
            }
            found.push(m);
        }
        found
    }
}
