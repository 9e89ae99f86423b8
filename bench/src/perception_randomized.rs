//! `robotd bench perception --randomized N`: perception on N randomized frames.
//!
//! The frames vary as real ones do (sheet design, light, white balance, lens, camera tilt and
//! turn, JPEG quality, distractors; see `robotd_perception::eval::randomized`), each scored
//! against ground truth. The pipeline runs on this one thread, pinned to one CPU, so the
//! frames per second are one core's. Beside it, the same run times the floor of reading each
//! frame's bytes once.

use super::bus::pin_current_thread;
use anyhow::{Context, Result};
use robotd_perception::eval::quantile;
use robotd_perception::eval::randomized::breakdown::Breakdown;
use robotd_perception::eval::randomized::{self, RandomizedFigures};
use serde::Serialize;

/// What the randomized benchmark reports.
#[derive(Debug, Clone, Serialize)]
pub struct RandomizedReport {
    /// Frames made.
    pub frames: usize,
    /// Seed of the run.
    pub seed: u64,
    /// Frames with a workspace reported more than 1 cm off at a corner.
    pub wrong_workspaces: usize,
    /// Share of the frames with the whole sheet in view where it was found.
    pub workspace_found: f64,
    /// Frames with the whole sheet in view.
    pub sheet_expected: usize,
    /// Frames with a marker covered or painted over / of those, found correctly anyway.
    pub covered: (usize, usize),
    /// Object recall, objects of 15 mm and more.
    pub recall: f64,
    /// Objects of 15 mm and more on found sheets.
    pub objects: usize,
    /// Object precision.
    pub precision: f64,
    /// Detections on found sheets.
    pub detections: usize,
    /// 95th percentile position error, mm.
    pub pos_err_p95_mm: f64,
    /// Median position error, mm.
    pub pos_err_p50_mm: f64,
    /// Frames per second of the pipeline on one core (mean).
    pub fps_one_core: f64,
    /// Mean time to read a frame's 921,600 bytes once, ms: the floor, same frames, same run.
    pub read_floor_ms: f64,
    /// Found / expected per sheet design.
    pub by_design: Vec<(String, usize, usize)>,
    /// Frames and false positives per distractor.
    pub by_distractor: Vec<(String, usize, usize)>,
    /// Seeds of frames with a wrong workspace (to look at).
    pub wrong_seeds: Vec<u64>,
    /// Where frames with the sheet in view lost it (cause per design; what became of each
    /// true marker), and the found rates by blur, smallest marker radius and camera tilt.
    pub losses: Breakdown,
}

impl RandomizedReport {
    fn from(figures: RandomizedFigures, seed: u64) -> Self {
        let mm: Vec<f64> = figures
            .position_errors_m
            .iter()
            .map(|e| e * 1000.0)
            .collect();
        RandomizedReport {
            frames: figures.frames,
            seed,
            wrong_workspaces: figures.wrong_workspaces,
            workspace_found: figures.found_rate(),
            sheet_expected: figures.sheet_expected,
            covered: (figures.covered, figures.covered_found),
            recall: figures.recall(),
            objects: figures.objects,
            precision: figures.precision(),
            detections: figures.detections,
            pos_err_p95_mm: quantile(&mm, 0.95),
            pos_err_p50_mm: quantile(&mm, 0.5),
            fps_one_core: figures.frames_per_second(),
            read_floor_ms: figures.read_floor_ms(),
            by_design: figures.by_design,
            by_distractor: figures.by_distractor,
            wrong_seeds: figures.wrong_seeds,
            losses: figures.breakdown,
        }
    }

    /// The human-readable table.
    pub fn table(&self) -> String {
        let mut out = format!(
            "randomized frames: {} (seed {})\n\
             measure                                  value              target\n\
             wrong workspaces (a corner > 1 cm off)   {:>8}           0\n\
             workspace found (whole sheet in view)    {:>8.1} %  of {}\n\
             marker covered/painted: found anyway     {:>8} of {}\n\
             object recall (≥ 15 mm)                  {:>8.1} %  of {}   ≥ 98 %\n\
             object precision                         {:>8.1} %  of {}   ≥ 98 %\n\
             position error p50 / p95                 {:>6.2} / {:>6.2} mm  p95 ≤ 3 mm\n\
             pipeline fps, one core (640×480)         {:>8.1}           ≥ 30\n\
             read the frame once (floor), per frame   {:>8.3} ms\n",
            self.frames,
            self.seed,
            self.wrong_workspaces,
            self.workspace_found * 100.0,
            self.sheet_expected,
            self.covered.1,
            self.covered.0,
            self.recall * 100.0,
            self.objects,
            self.precision * 100.0,
            self.detections,
            self.pos_err_p50_mm,
            self.pos_err_p95_mm,
            self.fps_one_core,
            self.read_floor_ms,
        );
        out.push_str("sheet design: found / in view\n");
        for (design, expected, found) in &self.by_design {
            out.push_str(&format!("  {design:<10} {found:>6} / {expected}\n"));
        }
        out.push_str("distractor: frames with it, false positives in them\n");
        for (name, frames, fps) in &self.by_distractor {
            out.push_str(&format!("  {name:<34} {frames:>6} {fps:>6}\n"));
        }
        out.push_str(&self.losses.table());
        if !self.wrong_seeds.is_empty() {
            out.push_str(&format!(
                "frames with a wrong workspace (seeds): {:?}\n",
                self.wrong_seeds
            ));
        }
        out
    }
}

/// Runs `frames` randomized frames from `seed`, pinned to one CPU; with `dump`, the frames
/// that went wrong are written there as PNG files.
/// With `frame_seeds`, only those frames (to look at one again).
pub fn run(
    frames: usize,
    seed: u64,
    frame_seeds: &[u64],
    dump: Option<&std::path::Path>,
) -> Result<RandomizedReport> {
    if let Some(dir) = dump {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let previous = pin_current_thread(0).ok();
    let figures = if frame_seeds.is_empty() {
        randomized::run(frames, seed, dump)
    } else {
        randomized::run_frames(frame_seeds, dump)
    }
    .context("randomized perception frames");
    if let Some(set) = previous {
        // SAFETY: restores the CPU set read by sched_getaffinity.
        unsafe {
            libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
        }
    }
    Ok(RandomizedReport::from(figures?, seed))
}
