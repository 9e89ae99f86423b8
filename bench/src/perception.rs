//! `robotd bench perception`: how fast and how well robotd sees.
//!
//! 1. One core: the perception pipeline (markers, table plane, colour detector) on frames of
//!    random simulated scenes, on a thread pinned to one CPU, beside the floor of reading the
//!    frame's 921,600 bytes once in the same run. Frames per second = 1 / median time.
//! 2. Accuracy on the same scenes against ground truth (recall, position, size, rotation,
//!    false positives; plus empty sheets).
//! 3. Through the bus: a frame published on `camera/frames` → the perception actor →
//!    `perception/detections` → the workspace model → its objects on `workspace/objects`,
//!    timed from the frame's publication.

use super::bus::pin_current_thread;
use super::Latency;
use anyhow::{bail, Context, Result};
use robotd_perception::detector::{ColourDetector, ColourDetectorSettings};
use robotd_perception::eval::{quantile, random_objects, rng, score, Lab};
use robotd_perception::labels::LabelTable;
use robotd_perception::{Perception, Pipeline};
use robotd_protocol::envelope::unix_now_ns;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::{CAMERA_FRAMES, WORKSPACE_OBJECTS};
use serde::Serialize;
use std::time::{Duration, Instant};

/// Everything `robotd bench perception` measures.
#[derive(Debug, Clone, Serialize)]
pub struct PerceptionFigures {
    /// Frames per second of the pipeline on one pinned core (1 / median frame time).
    pub fps_one_core: f64,
    /// Median pipeline time per 640×480 frame, ms.
    pub frame_ms_p50: f64,
    /// 99th percentile pipeline time, ms.
    pub frame_ms_p99: f64,
    /// Median time to read the frame's bytes once (floor), ms.
    pub read_floor_ms_p50: f64,
    /// Share of objects found.
    pub recall: f64,
    /// Objects on the table over all scenes.
    pub objects: usize,
    /// Detections that matched no object (random scenes and empty sheets).
    pub false_positives: usize,
    /// Median position error (centre of mass), mm.
    pub pos_err_p50_mm: f64,
    /// 95th percentile position error, mm.
    pub pos_err_p95_mm: f64,
    /// 95th percentile relative size error (worse of width and height), %.
    pub size_err_p95_pct: f64,
    /// Largest gripper-rotation error (modulo symmetry), degrees.
    pub rotation_err_max_deg: f64,
    /// Share of found objects named right.
    pub label_accuracy: f64,
    /// Median time from a frame's publication to its objects in the workspace model, ms.
    pub frame_to_objects_ms_p50: f64,
    /// 99th percentile of the same, ms.
    pub frame_to_objects_ms_p99: f64,
    /// Frames that went through the bus measurement.
    pub bus_frames: usize,
    /// Random scenes.
    pub scenes: usize,
}

impl PerceptionFigures {
    /// The human-readable table.
    pub fn table(&self) -> String {
        format!(
            "measure                                  value              target\n\
             pipeline fps, one core                   {:>8.1}           ≥ 30\n\
             pipeline per frame p50 / p99             {:>6.2} / {:>6.2} ms\n\
             read 921,600 B once (floor) p50          {:>8.3} ms\n\
             recall ({} objects, {} scenes)         {:>8.1} %         100 %\n\
             false positives                          {:>8}           0\n\
             position error p50 / p95                 {:>6.2} / {:>6.2} mm  p95 ≤ 3 mm\n\
             size error p95                           {:>8.1} %         ≤ 10 %\n\
             gripper rotation error max               {:>8.2} °         ≤ 5°\n\
             labels right                             {:>8.1} %\n\
             frame → objects in memory p50 / p99      {:>6.2} / {:>6.2} ms  p50 ≤ 50 ms\n",
            self.fps_one_core,
            self.frame_ms_p50,
            self.frame_ms_p99,
            self.read_floor_ms_p50,
            self.objects,
            self.scenes,
            self.recall * 100.0,
            self.false_positives,
            self.pos_err_p50_mm,
            self.pos_err_p95_mm,
            self.size_err_p95_pct,
            self.rotation_err_max_deg,
            self.label_accuracy * 100.0,
            self.frame_to_objects_ms_p50,
            self.frame_to_objects_ms_p99,
        )
    }
}

/// Runs the benchmark over `scenes` random scenes and `bus_frames` frames through the bus.
pub fn run(scenes: usize, bus_frames: usize) -> Result<PerceptionFigures> {
    let mut lab = Lab::new(2.0, false).context("setting up the simulated camera")?;
    let table = LabelTable::builtin();
    let workspace = lab.workspace().clone();
    let mut rng = rng(2026);

    // 1 + 2: pipeline time on one pinned core, and accuracy.
    let previous = pin_current_thread(0).ok();
    let mut times = Vec::new();
    let mut floors = Vec::new();
    let mut positions = Vec::new();
    let mut sizes = Vec::new();
    let mut rotation_max: f64 = 0.0;
    let (mut objects, mut found, mut labels_ok, mut false_positives) = (0, 0, 0, 0);
    for scene in 0..scenes + 5 {
        // The last five scenes are empty sheets: anything found there is a false positive.
        let specs = if scene < scenes {
            random_objects(&mut rng, &table, &workspace, 5)
        } else {
            Vec::new()
        };
        lab.set_objects(&specs).context("placing objects")?;
        let (id, ts) = lab.capture().context("rendering")?;
        let mut last = None;
        for _ in 0..5 {
            let t = Instant::now();
            let sum: u64 = lab.frame().iter().map(|b| u64::from(*b)).sum();
            floors.push(t.elapsed());
            std::hint::black_box(sum);
            let t = Instant::now();
            let detections = lab.detect(id, ts).context("detecting")?;
            times.push(t.elapsed());
            last = Some(detections);
        }
        let detections = last.context("no detection ran")?;
        let frame = score(&lab.objects(), &detections.objects);
        false_positives += frame.false_positives;
        for o in &frame.objects {
            objects += 1;
            if let Some(p) = o.position_error_m {
                found += 1;
                positions.push(p * 1000.0);
                labels_ok += usize::from(o.label_ok);
            }
            if let Some(s) = o.size_error {
                sizes.push(s * 100.0);
            }
            if let Some(r) = o.rotation_error_rad {
                rotation_max = rotation_max.max(r.to_degrees());
            }
        }
    }
    if let Some(set) = previous {
        // SAFETY: restores the CPU set read by sched_getaffinity.
        unsafe {
            libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
        }
    }
    let pipeline = Latency::of(&mut times);
    let floor = Latency::of(&mut floors);

    // 3: through the bus, with the perception actor and the workspace model running.
    let (bus_p50, bus_p99, bus_count) = through_the_bus(&mut lab, bus_frames)?;

    Ok(PerceptionFigures {
        fps_one_core: 1e6 / pipeline.p50_us,
        frame_ms_p50: pipeline.p50_us / 1000.0,
        frame_ms_p99: pipeline.p99_us / 1000.0,
        read_floor_ms_p50: floor.p50_us / 1000.0,
        recall: found as f64 / objects.max(1) as f64,
        objects,
        false_positives,
        pos_err_p50_mm: quantile(&positions, 0.5),
        pos_err_p95_mm: quantile(&positions, 0.95),
        size_err_p95_pct: quantile(&sizes, 0.95),
        rotation_err_max_deg: rotation_max,
        label_accuracy: labels_ok as f64 / found.max(1) as f64,
        frame_to_objects_ms_p50: bus_p50,
        frame_to_objects_ms_p99: bus_p99,
        bus_frames: bus_count,
        scenes,
    })
}

/// Publishes `frames` frames of the lab's scene at 15 fps and times each until the workspace
/// model publishes the objects of that frame. Returns p50, p99 (ms) and the count measured.
fn through_the_bus(lab: &mut Lab, frames: usize) -> Result<(f64, f64, usize)> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let namespace = format!("bench-perc-{}", std::process::id());
    let table = LabelTable::builtin();
    let workspace = lab.workspace().clone();
    let specs = random_objects(&mut rng(7), &table, &workspace, 5);
    lab.set_objects(&specs)?;
    runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "bench-perception"))?;
        let pipeline = Pipeline::new(
            &lab.intrinsics(),
            vec![workspace.clone()],
            Box::new(ColourDetector::new(
                table.clone(),
                ColourDetectorSettings::default(),
            )),
        )?;
        let perception = Perception::start(&bus, pipeline, LabelTable::builtin())?;
        let model = robotd_workspace_model::WorkspaceModel::start(
            &bus,
            robotd_workspace_model::WorkspaceModelSettings::from_config(
                vec![workspace.clone()],
                table.labels(),
                &robotd_workspace_model::WorkspaceConfig::default(),
            ),
        )?;
        let mut objects = bus.subscriber(&WORKSPACE_OBJECTS)?;
        let publisher = bus.frame_publisher(&CAMERA_FRAMES)?;
        let mut latencies = Vec::new();
        let mut ticker = tokio::time::interval(Duration::from_millis(66));
        for i in 1..=frames as u64 {
            ticker.tick().await;
            let (_, _) = lab.capture()?;
            let mut frame = publisher.loan()?;
            frame.pixels_mut()[..lab.frame().len()].copy_from_slice(lab.frame());
            let header = frame.header_mut();
            header.frame_id = i;
            let published = unix_now_ns();
            header.timestamp_unix_ns = published;
            frame.send()?;
            let deadline = Instant::now() + Duration::from_secs(2);
            loop {
                let left = deadline.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    bail!("frame {i}: the workspace model published no objects within 2 s");
                }
                match tokio::time::timeout(left, objects.recv()).await {
                    Ok(Ok(msg)) if msg.body.frame_id == i => {
                        latencies.push(Duration::from_nanos(
                            unix_now_ns().saturating_sub(published),
                        ));
                        break;
                    }
                    Ok(Ok(_)) => continue,
                    Ok(Err(e)) => bail!("receiving objects: {e}"),
                    Err(_) => {
                        bail!("frame {i}: the workspace model published no objects within 2 s")
                    }
                }
            }
        }
        perception.shutdown();
        model.shutdown().await;
        let latency = Latency::of(&mut latencies);
        Ok((
            latency.p50_us / 1000.0,
            latency.p99_us / 1000.0,
            latencies.len(),
        ))
    })
}
