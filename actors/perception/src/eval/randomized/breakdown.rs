//! Where the randomized frames lose the sheet: by cause, and by blur, marker size and tilt.
//!
//! A found rate alone does not say what to fix. For every frame that has the whole sheet in
//! view, [`Breakdown::record`] looks at what became of each of the four true markers in both
//! looks for markers: the first look's candidate that covers its true centre
//! ([`CandidateTrace`]: never a candidate because its dark pixels joined a dark frame or pad
//! or were not dark at all, or which part of the ring check failed) and the second look's
//! blurred-profile fits near it ([`ModelFit`]: found, or which check refused it); when all
//! four were found, the sheet check that refused them. A frame's cause is its missed marker
//! that got least far, or the sheet check. The
//! found rates are also split by the photo's blur, the smallest true marker radius in pixels
//! and the camera's tilt, per sheet design.

use crate::markers::{CandidateOutcome, CandidateTrace};
use crate::pipeline::SheetStatus;
use robotd_vision::disc_scan::DiscCandidate;
use robotd_vision::ring_fit::{ModelFit, ModelReject};
use serde::Serialize;
use std::collections::BTreeMap;

/// The sheet designs, in the order of the case's `design_index`.
pub const DESIGNS: [&str; 3] = ["plain", "classic", "ned2"];
/// Upper ends of the marker-radius bins, pixels (the last bin is everything above).
const RADIUS_BINS: [f64; 5] = [8.0, 10.0, 12.0, 14.0, 17.0];
/// Upper ends of the tilt bins, degrees.
const TILT_BINS: [f64; 3] = [10.0, 20.0, 30.0];

/// What one true marker of a frame looked like to the finder.
#[derive(Debug, Clone, Copy)]
pub struct TrueMarker {
    /// Its centre in the raw image, pixels.
    pub centre_px: [f64; 2],
    /// Its outer radius in the image (the mean over directions), pixels.
    pub radius_px: f64,
}

/// Found / expected counts per design.
pub type PerDesign = [(usize, usize); 3];

/// The loss breakdown of a randomized run.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Breakdown {
    /// Frames with the sheet in view that did not find it, per cause and design.
    pub causes: BTreeMap<String, [usize; 3]>,
    /// What became of each true marker of the frames with the sheet in view, per design.
    pub markers: BTreeMap<String, [usize; 3]>,
    /// Found / expected per blur radius (0, 1, 2 px) and design.
    pub by_blur: BTreeMap<u32, PerDesign>,
    /// Found / expected per smallest marker radius bin (its upper end, px) and design.
    pub by_radius: BTreeMap<String, PerDesign>,
    /// Found / expected per tilt bin and design.
    pub by_tilt: BTreeMap<String, PerDesign>,
}

/// What became of a true marker in the two looks for markers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Seen {
    /// No candidate in either look.
    Nothing,
    /// The first look's candidate failed (and the second look had none, or did not run).
    First(CandidateOutcome),
    /// The second look's fit refused it (the first look's outcome beside it).
    Second(ModelReject, Option<CandidateOutcome>),
    /// Found by the second look (the blurred profile).
    Blurred,
    /// Found by the first look (the ring check).
    Rings,
}

impl Seen {
    fn found(self) -> bool {
        matches!(self, Seen::Blurred | Seen::Rings)
    }

    fn word(self) -> String {
        let first = |o: Option<CandidateOutcome>| match o {
            None => "no dark blobs at it".to_string(),
            Some(CandidateOutcome::TooLarge) => "joined with a larger dark area".into(),
            Some(CandidateOutcome::NotRingLike) => "one blob, small or elongated".into(),
            Some(CandidateOutcome::LowContrast) => "low contrast".into(),
            Some(CandidateOutcome::Ring(reject)) => format!("ring check: {reject:?}"),
            Some(CandidateOutcome::Duplicate) | Some(CandidateOutcome::Marker) => "marker".into(),
        };
        match self {
            Seen::Nothing => "no candidate in either look".into(),
            Seen::First(o) => format!("{}; no blurred candidate", first(Some(o))),
            Seen::Second(reject, _) => format!("blurred profile: {reject:?}"),
            Seen::Blurred => "marker (blurred profile)".into(),
            Seen::Rings => "marker (ring check)".into(),
        }
    }
}

/// The first look's best outcome among the candidates whose box covers `m`'s centre.
fn first_look(m: &TrueMarker, candidates: &[CandidateTrace]) -> Option<CandidateOutcome> {
    let [u, v] = m.centre_px;
    candidates
        .iter()
        .filter(|c| {
            let [u0, u1, v0, v1] = c.box_px.map(f64::from);
            u >= u0 - 1.0 && u <= u1 + 1.0 && v >= v0 - 1.0 && v <= v1 + 1.0
        })
        .map(|c| c.outcome)
        .max()
}

/// What became of `m` in both looks: the second look's fits within a third of its radius.
fn seen(
    m: &TrueMarker,
    candidates: &[CandidateTrace],
    fits: &[(DiscCandidate, Option<ModelFit>)],
) -> Seen {
    let first = first_look(m, candidates);
    if matches!(
        first,
        Some(CandidateOutcome::Marker) | Some(CandidateOutcome::Duplicate)
    ) {
        return Seen::Rings;
    }
    let near =
        |c: [f64; 2]| (c[0] - m.centre_px[0]).hypot(c[1] - m.centre_px[1]) < m.radius_px / 3.0;
    let verdicts = fits
        .iter()
        .filter_map(|(_, f)| f.as_ref())
        .filter(|f| near(f.centre))
        .map(|f| f.verdict());
    let mut best: Option<Seen> = None;
    for v in verdicts {
        let s = match v {
            Ok(_) => Seen::Blurred,
            Err(reject) => Seen::Second(reject, first),
        };
        best = Some(best.map_or(s, |b| b.max(s)));
    }
    best.unwrap_or(match first {
        Some(o) => Seen::First(o),
        None => Seen::Nothing,
    })
}

fn bin_label(value: f64, ends: &[f64], unit: &str) -> String {
    let mut lo = 0.0;
    for &hi in ends {
        if value < hi {
            return format!("{lo:>4.0}-{hi:<3.0}{unit}");
        }
        lo = hi;
    }
    format!("{lo:>4.0}+   {unit}")
}

impl Breakdown {
    /// Records one frame with the whole sheet in view: its design, blur, tilt, true markers,
    /// the finder's candidates and blurred-profile fits, the status and whether the sheet was
    /// found (correctly).
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &mut self,
        design: usize,
        blur_px: u32,
        tilt_deg: f64,
        truth: &[TrueMarker; 4],
        candidates: &[CandidateTrace],
        fits: &[(DiscCandidate, Option<ModelFit>)],
        status: &SheetStatus,
        found: bool,
    ) {
        let outcomes = truth.map(|m| seen(&m, candidates, fits));
        for o in outcomes {
            self.markers.entry(o.word()).or_default()[design] += 1;
        }
        let smallest = truth.iter().map(|m| m.radius_px).fold(f64::MAX, f64::min);
        let count = |row: &mut PerDesign| {
            row[design].1 += 1;
            if found {
                row[design].0 += 1;
            }
        };
        count(self.by_blur.entry(blur_px).or_default());
        count(
            self.by_radius
                .entry(bin_label(smallest, &RADIUS_BINS, "px"))
                .or_default(),
        );
        count(
            self.by_tilt
                .entry(bin_label(tilt_deg, &TILT_BINS, "°"))
                .or_default(),
        );
        if found {
            return;
        }
        let cause = if outcomes.iter().all(|o| o.found()) {
            match status {
                SheetStatus::NotASheet { failed, .. } => format!("sheet check: {failed:?}"),
                SheetStatus::Found => "found, but wrong".into(),
                other => format!("four markers, then {other:?}"),
            }
        } else {
            // The missed marker that got least far.
            let worst = outcomes.iter().filter(|o| !o.found()).min().copied();
            format!("marker missed: {}", worst.map_or(String::new(), Seen::word))
        };
        self.causes.entry(cause).or_default()[design] += 1;
    }

    /// The tables, as text.
    pub fn table(&self) -> String {
        let mut out =
            String::from("sheet in view, not found: cause                 plain classic   ned2\n");
        for (cause, n) in &self.causes {
            out.push_str(&format!(
                "  {cause:<44} {:>6} {:>6} {:>6}\n",
                n[0], n[1], n[2]
            ));
        }
        out.push_str("true markers (4 a frame): what became of them  plain classic   ned2\n");
        for (what, n) in &self.markers {
            out.push_str(&format!(
                "  {what:<44} {:>6} {:>6} {:>6}\n",
                n[0], n[1], n[2]
            ));
        }
        let rows = |title: &str, rows: Vec<(String, PerDesign)>| {
            let mut s = format!("found / in view by {title:<26} plain        classic      ned2\n");
            for (label, r) in rows {
                s.push_str(&format!("  {label:<42}"));
                for (found, expected) in r {
                    let pct = 100.0 * found as f64 / expected.max(1) as f64;
                    s.push_str(&format!(" {found:>4}/{expected:<4}{pct:>3.0}%"));
                }
                s.push('\n');
            }
            s
        };
        out.push_str(&rows(
            "blur (box radius, twice)",
            self.by_blur
                .iter()
                .map(|(b, r)| (format!("{b} px"), *r))
                .collect(),
        ));
        out.push_str(&rows(
            "smallest marker radius",
            self.by_radius
                .iter()
                .map(|(b, r)| (b.clone(), *r))
                .collect(),
        ));
        out.push_str(&rows(
            "camera tilt",
            self.by_tilt.iter().map(|(b, r)| (b.clone(), *r)).collect(),
        ));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::markers::SheetCheck;

    fn candidate(at: [u32; 2], outcome: CandidateOutcome) -> CandidateTrace {
        CandidateTrace {
            box_px: [at[0] - 5, at[0] + 5, at[1] - 5, at[1] + 5],
            outcome,
        }
    }

    #[test]
    fn a_frame_is_lost_to_its_earliest_failure() {
        let truth = [[50, 50], [150, 50], [50, 150], [150, 150]].map(|c| TrueMarker {
            centre_px: [f64::from(c[0]), f64::from(c[1])],
            radius_px: 9.0,
        });
        let mut b = Breakdown::default();
        let candidates = vec![
            candidate([50, 50], CandidateOutcome::Marker),
            candidate(
                [150, 50],
                CandidateOutcome::Ring(robotd_vision::rings::RingReject::RingWidth),
            ),
            candidate([50, 150], CandidateOutcome::TooLarge),
            candidate([150, 150], CandidateOutcome::Marker),
        ];
        let status = SheetStatus::MarkersMissing { seen: 2 };
        b.record(1, 2, 25.0, &truth, &candidates, &[], &status, false);
        assert_eq!(
            b.causes
                .get("marker missed: joined with a larger dark area; no blurred candidate"),
            Some(&[0, 1, 0])
        );
        assert_eq!(b.markers.get("marker (ring check)"), Some(&[0, 2, 0]));
        assert_eq!(b.by_blur.get(&2), Some(&[(0, 0), (0, 1), (0, 0)]));

        let all: Vec<_> = truth
            .iter()
            .map(|m| {
                candidate(
                    [m.centre_px[0] as u32, m.centre_px[1] as u32],
                    CandidateOutcome::Marker,
                )
            })
            .collect();
        let refused = SheetStatus::NotASheet {
            seen: 4,
            failed: SheetCheck::Appearance,
        };
        b.record(2, 0, 5.0, &truth, &all, &[], &refused, false);
        assert_eq!(b.causes.get("sheet check: Appearance"), Some(&[0, 0, 1]));
        b.record(0, 0, 5.0, &truth, &all, &[], &SheetStatus::Found, true);
        assert_eq!(b.by_blur.get(&0), Some(&[(1, 1), (0, 0), (0, 1)]));
        assert!(b.table().contains("sheet check: Appearance"));
    }
}
