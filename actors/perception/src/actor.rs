//! The perception actor on the bus: camera frames in, detections out.
//!
//! It runs on a thread of its own (detection is CPU work that must not stall the async
//! actors) with a small single-threaded runtime for its bus ports. For each frame it takes the
//! newest one waiting (latest wins: under load it skips frames, it never falls behind), reads
//! the frame in place in shared memory, and publishes [`Detections`] on
//! `perception/detections` with the frame's id and capture time. A frame taken while the arm
//! moved, or away from the observation pose of the workspace in view, is published with
//! `steady = false`, so the workspace model ignores it. While the
//! gripper holds something (`gripper/state`), the held object hangs in the wrist camera's view
//! and would look like an object on the table: a detection under the tool that comes in over
//! the sheet's edge is dropped then ([`crate::held_object`]; a real object right there is
//! missed while holding).
//!
//! A detector that fails or panics on a frame costs that frame only: the failure is logged and
//! counted, and the next frame is processed as usual.
//!
//! The camera's intrinsics follow `camera/intrinsics`: a Ned2 sends its own calibration when
//! it connects, which can be long after robotd started, and the frames after that are
//! measured with it.

use crate::detector::FrameView;
use crate::external::KnownSheet;
use crate::external_detections::{self, ExternalStats};
use crate::labels::LabelTable;
use crate::pipeline::{Pipeline, SheetStatus};
use robotd_protocol::objects::Detections;
use robotd_runtime::bus::{Bus, BusError};
use robotd_topics::{
    ARM_STATE, CAMERA_FRAMES, CAMERA_INTRINSICS, GRIPPER_STATE, PERCEPTION_DETECTIONS,
    PERCEPTION_PIXEL_DETECTIONS,
};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Counters of the running actor (for health, metrics and benchmarks).
#[derive(Debug, Default)]
pub struct PerceptionStats {
    /// Frames processed.
    pub frames: AtomicU64,
    /// Frames in which a workspace sheet was found.
    pub frames_with_sheet: AtomicU64,
    /// Frames the detector failed on (error or panic).
    pub failures: AtomicU64,
    /// Processing time of the last frame, microseconds.
    pub last_processing_us: AtomicU64,
    /// Objects found in the last frame.
    pub last_objects: AtomicU64,
    /// What the last steady view from an observation pose showed (`None`: none yet).
    pub view: std::sync::Mutex<Option<WorkspaceView>>,
    /// Detections in pixels from detectors outside robotd ([`crate::external_detections`]).
    pub external: ExternalStats,
}

/// Whether the camera sees the workspace from its observation pose: what `/health` and
/// `get_system_status` report. Only views taken with the arm at rest at an observation pose
/// count (elsewhere the sheet may rightly be out of view).
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspaceView {
    /// The workspace whose observation pose the arm was at.
    pub workspace_id: String,
    /// Whether the sheet was found.
    pub visible: bool,
    /// What was seen, in words (why not, when not).
    pub reason: String,
    /// Capture time of that view, ns since the Unix epoch.
    pub taken_unix_ns: u64,
}

impl PerceptionStats {
    /// The last steady view from an observation pose.
    pub fn workspace_view(&self) -> Option<WorkspaceView> {
        self.view.lock().map(|v| v.clone()).unwrap_or_default()
    }
}

/// The perception actor could not start.
#[derive(Debug, thiserror::Error)]
pub enum PerceptionStartError {
    /// A bus port could not be opened.
    #[error("perception: cannot open its bus ports: {0}")]
    Bus(#[from] BusError),
    /// The thread could not be started.
    #[error("perception: cannot start its thread: {0}")]
    Thread(std::io::Error),
}

/// The running perception actor.
#[derive(Debug)]
pub struct Perception {
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
    stats: Arc<PerceptionStats>,
}

impl Perception {
    /// Starts the actor on `bus` with `pipeline`; `heights` places external detections of
    /// known labels at their top face. Returns once its bus ports are open, so a frame
    /// published afterwards is seen.
    pub fn start(
        bus: &Bus,
        pipeline: Pipeline,
        heights: LabelTable,
    ) -> Result<Perception, PerceptionStartError> {
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(PerceptionStats::default());
        let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<(), BusError>>();
        let thread = {
            let bus = bus.clone();
            let stop = stop.clone();
            let stats = stats.clone();
            std::thread::Builder::new()
                .name("perception".into())
                .spawn(move || run(bus, pipeline, heights, stop, stats, ready_tx))
                .map_err(PerceptionStartError::Thread)?
        };
        match ready_rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => {
                let _ = thread.join();
                return Err(e.into());
            }
            Err(_) => {
                let _ = thread.join();
                return Err(PerceptionStartError::Thread(std::io::Error::other(
                    "the perception thread ended while starting",
                )));
            }
        }
        Ok(Perception {
            stop,
            thread: Some(thread),
            stats,
        })
    }

    /// The actor's counters.
    pub fn stats(&self) -> Arc<PerceptionStats> {
        self.stats.clone()
    }

    /// Stops the actor and waits for its thread.
    pub fn shutdown(mut self) {
        self.stop_and_join();
    }

    fn stop_and_join(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for Perception {
    fn drop(&mut self) {
        self.stop_and_join();
    }
}

/// What the actor knows about the arm.
#[derive(Debug, Default)]
struct ArmView {
    /// Motion and rest, from the arm's states.
    motion: robotd_protocol::arm::ArmMotion,
    /// Whether the gripper holds something (it then hangs in the wrist camera's view).
    holding: bool,
}

impl std::ops::Deref for ArmView {
    type Target = robotd_protocol::arm::ArmMotion;
    fn deref(&self) -> &Self::Target {
        &self.motion
    }
}

impl std::ops::DerefMut for ArmView {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.motion
    }
}

fn run(
    bus: Bus,
    mut pipeline: Pipeline,
    heights: LabelTable,
    stop: Arc<AtomicBool>,
    stats: Arc<PerceptionStats>,
    ready: std::sync::mpsc::Sender<Result<(), BusError>>,
) {
    let runtime = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            let _ = ready.send(Err(BusError::Transfer {
                topic: "perception".into(),
                reason: format!("cannot build its runtime: {e}"),
            }));
            return;
        }
    };
    runtime.block_on(async move {
        let ports = (|| {
            Ok::<_, BusError>((
                bus.frame_subscriber(&CAMERA_FRAMES)?,
                bus.subscriber(&ARM_STATE)?,
                bus.publisher(&PERCEPTION_DETECTIONS)?,
                bus.subscriber(&GRIPPER_STATE)?,
                bus.subscriber(&PERCEPTION_PIXEL_DETECTIONS)?,
                bus.subscriber(&CAMERA_INTRINSICS)?,
            ))
        })();
        let (
            mut frames,
            mut arm_states,
            publisher,
            mut gripper_states,
            mut pixel_detections,
            mut intrinsics,
        ) = match ports {
            Ok(p) => {
                let _ = ready.send(Ok(()));
                p
            }
            Err(e) => {
                let _ = ready.send(Err(e));
                return;
            }
        };
        tracing::info!(
            detector = pipeline.detector_name(),
            workspaces = pipeline.workspaces().len(),
            "perception started"
        );
        let mut arm = ArmView::default();
        let mut missing_sheet_streak = 0u64;
        let mut known_sheet: Option<KnownSheet> = None;
        let mut refused: Option<robotd_protocol::camera::CameraIntrinsics> = None;
        while !stop.load(Ordering::SeqCst) {
            while let Ok(Some(message)) = pixel_detections.try_recv() {
                let placed = external_detections::place(
                    &pipeline,
                    known_sheet.as_ref(),
                    &message.body,
                    &heights,
                    &stats.external,
                );
                if let Some(detections) = placed {
                    if let Err(error) = publisher.publish(&detections) {
                        tracing::warn!(%error, "perception: publishing external detections failed");
                    }
                }
            }
            let first =
                match tokio::time::timeout(Duration::from_millis(100), frames.recv()).await {
                    Err(_) => continue,
                    Ok(Err(error)) => {
                        tracing::warn!(%error, "perception: receiving a frame failed");
                        tokio::time::sleep(Duration::from_millis(50)).await;
                        continue;
                    }
                    Ok(Ok(sample)) => sample,
                };
            // Latest wins: skip to the newest frame waiting.
            let mut sample = first;
            while let Ok(Some(newer)) = frames.try_recv() {
                sample = newer;
            }
            while let Ok(Some(state)) = arm_states.try_recv() {
                arm.update(&state.body, state.sent_at_unix_ns);
            }
            while let Ok(Some(state)) = gripper_states.try_recv() {
                arm.holding = state.body.holding;
            }
            while let Ok(Some(now)) = intrinsics.try_recv() {
                match pipeline.set_intrinsics(&now.body) {
                    Ok(true) => tracing::info!(
                        fx = now.body.fx,
                        fy = now.body.fy,
                        cx = now.body.cx,
                        cy = now.body.cy,
                        distortion = ?now.body.distortion,
                        "perception: the camera's intrinsics changed; measuring with them"
                    ),
                    Ok(false) => {}
                    // Said once per unusable value, not once a second.
                    Err(error) if refused.as_ref() != Some(&now.body) => {
                        tracing::warn!(%error, "perception: unusable camera intrinsics, ignored");
                        refused = Some(now.body);
                    }
                    Err(_) => {}
                }
            }
            let header = *sample.header();
            let width = header.width as usize;
            let height = header.height as usize;
            let pixels = sample.pixels();
            let bytes = width * height * 3;
            if header.channels != 3 || header.encoding != 0 || pixels.len() < bytes {
                stats.failures.fetch_add(1, Ordering::Relaxed);
                tracing::warn!(
                    frame_id = header.frame_id,
                    width,
                    height,
                    channels = header.channels,
                    encoding = header.encoding,
                    "perception: skipping a frame that is not RGB8 of its stated size"
                );
                continue;
            }
            let frame = FrameView {
                rgb: &pixels[..bytes],
                width,
                height,
                frame_id: header.frame_id,
                timestamp_unix_ns: header.timestamp_unix_ns,
            };
            // Memory learns only from views taken standing still at an observation pose.
            let steady = arm.steady_at(header.timestamp_unix_ns)
                && arm
                    .tool_pose
                    .as_ref()
                    .is_none_or(|tool| pipeline.at_observation_pose(tool));
            // Where the driver's kinematics put the camera (all zeros: a driver that does not
            // know): a sheet elsewhere is not the configured workspace.
            let camera_at = [
                header.camera_pose[0],
                header.camera_pose[1],
                header.camera_pose[2],
            ];
            pipeline.expect_camera_at((camera_at != [0.0; 3]).then_some(camera_at));
            let started = Instant::now();
            let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                pipeline.process(&frame, arm.tool_pose.as_ref(), steady)
            }));
            let elapsed = started.elapsed();
            known_sheet = pipeline
                .last_sheet()
                .map(|(plane, workspace)| KnownSheet {
                    frame_id: header.frame_id,
                    timestamp_unix_ns: header.timestamp_unix_ns,
                    camera_pose: header.camera_pose,
                    steady,
                    workspace: workspace.clone(),
                    plane: plane.clone(),
                });
            stats.frames.fetch_add(1, Ordering::Relaxed);
            stats
                .last_processing_us
                .store(elapsed.as_micros() as u64, Ordering::Relaxed);
            let detections: Detections = match outcome {
                Ok(Ok((mut detections, status))) => {
                    if let (true, Some(tool)) = (arm.holding, arm.tool_pose.as_ref()) {
                        let workspace = pipeline.workspace_for(Some(tool));
                        detections.objects.retain(|o| {
                            !crate::held_object::is_held_object(o, tool, workspace)
                        });
                    }
                    // Only a view from a known arm pose says whether the workspace can be
                    // seen (frames before the first arm state come from anywhere).
                    if steady && arm.heard {
                        let view = WorkspaceView {
                            workspace_id: pipeline
                                .workspace_for(arm.tool_pose.as_ref())
                                .id
                                .clone(),
                            visible: status == SheetStatus::Found,
                            reason: status.to_string(),
                            taken_unix_ns: header.timestamp_unix_ns,
                        };
                        if let Ok(mut last) = stats.view.lock() {
                            *last = Some(view);
                        }
                    }
                    if status == SheetStatus::Found {
                        stats.frames_with_sheet.fetch_add(1, Ordering::Relaxed);
                        missing_sheet_streak = 0;
                    } else {
                        missing_sheet_streak += 1;
                        if missing_sheet_streak == 1 || missing_sheet_streak.is_multiple_of(300) {
                            tracing::debug!(?status, "perception: no workspace sheet in view");
                        }
                    }
                    detections
                }
                Ok(Err(error)) => {
                    stats.failures.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!(%error, frame_id = header.frame_id, "perception: detector failed");
                    continue;
                }
                Err(_) => {
                    stats.failures.fetch_add(1, Ordering::Relaxed);
                    tracing::error!(frame_id = header.frame_id, "perception: detector panicked on a frame");
                    continue;
                }
            };
            drop(sample);
            stats
                .last_objects
                .store(detections.objects.len() as u64, Ordering::Relaxed);
            if let Err(error) = publisher.publish(&detections) {
                tracing::warn!(%error, "perception: publishing detections failed");
            }
        }
        tracing::info!("perception stopped");
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::arm::ArmState;
    use robotd_protocol::geometry::Pose;

    fn state(moving: bool, still_since_unix_ns: u64) -> ArmState {
        ArmState {
            joints: Default::default(),
            tool_pose: Pose::new(0.17, 0.0, 0.28, 0.0, 1.3, 0.0),
            moving,
            collision_detected: false,
            calibrated: true,
            estop_engaged: false,
            still_since_unix_ns,
        }
    }

    #[test]
    fn without_an_arm_every_frame_is_steady() {
        assert!(ArmView::default().steady_at(1));
    }

    #[test]
    fn a_frame_counts_from_when_the_arm_came_to_rest() {
        let mut arm = ArmView::default();
        arm.update(&state(false, 90), 100);
        assert!(!arm.steady_at(89), "taken before the arm came to rest");
        assert!(arm.steady_at(95));
        arm.update(&state(true, 0), 200);
        assert!(!arm.steady_at(250), "moving");
        // The last "moving" state at 300; the arm stops at 310; a state says so at 320.
        arm.update(&state(true, 0), 300);
        arm.update(&state(false, 310), 320);
        assert!(!arm.steady_at(305), "taken while the arm still moved");
        assert!(arm.steady_at(315));
        // A motion from 400 to 410 that no "moving" state saw: frames before 410 are old.
        arm.update(&state(false, 410), 420);
        assert!(!arm.steady_at(405));
        assert!(arm.steady_at(411));
        // Idle states while it rests do not move the start of the rest.
        arm.update(&state(false, 410), 1420);
        assert!(arm.steady_at(500));
    }

    #[test]
    fn without_the_rest_time_the_first_rest_state_counts() {
        let mut arm = ArmView::default();
        arm.update(&state(true, 0), 300);
        arm.update(&state(false, 0), 320);
        assert!(!arm.steady_at(315), "taken while the arm still moved");
        assert!(arm.steady_at(321));
        arm.update(&state(false, 0), 1320);
        assert!(arm.steady_at(500));
    }
}
