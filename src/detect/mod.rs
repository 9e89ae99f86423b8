//! `robotd detect IMAGE`: the built-in perception on one image file, to check a camera, a
//! lighting set-up or a new sheet before the robot relies on it.
//!
//! The image goes through the same [`Pipeline`] the perception actor runs on every frame:
//! the ring markers, the table plane they fix, the colour detector. The command reports what
//! each step found ([`report`]) and can draw it ([`annotate`], on `robotd_render::canvas`;
//! written as a PNG by the `image` crate).
//!
//! Two kinds of image are accepted:
//! - a camera view of the sheet with its four markers (the normal case). The camera is
//!   `--camera ned2` (the Ned2 wrist camera's intrinsics and lens distortion, 640×480 images),
//!   `--intrinsics FILE` (JSON or TOML with `width`, `height`, `fx`, `fy`, `cx`, `cy`,
//!   `distortion`), or, without either, a distortion-free pinhole guessed from the image size.
//!   Positions on the table come from the markers whatever the camera; the intrinsics matter
//!   for undoing the lens and for the parallax of tall objects.
//! - an image that is already the workspace square (the Niryo software's extracted workspace
//!   and its crops: marker centres at the image corners, reference top-left). This mode is
//!   used with `--warped`, or automatically when no sheet is found from markers and the image
//!   is about square with a quarter marker in each corner.
//!
//! The exit code is 0 whenever the image could be read — "no workspace in view" is a result,
//! not a failure; unreadable files, non-images, images over 8192 pixels a side and bad
//! options exit 1 with the reason.

mod annotate;
mod camera;
pub mod report;

use anyhow::{Context, Result};
use camera::{camera_for, pinhole, pinhole_with, CameraModel};
use clap::Args;
use report::{marker_reports, object_report, Report, Timing};
use robotd_config::Config;
use robotd_perception::detector::{ColourDetector, ColourDetectorSettings, FrameView};
use robotd_perception::labels::LabelTable;
use robotd_perception::markers::MarkerObservation;
use robotd_perception::plane::TablePlane;
use robotd_perception::Pipeline;
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::workspace::WorkspaceInfo;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `robotd detect`.
#[derive(Debug, Args)]
pub struct DetectArgs {
    /// The image file (JPEG or PNG).
    pub image: PathBuf,
    /// Camera intrinsics file (JSON or TOML: width, height, fx, fy, cx, cy, distortion).
    #[arg(long, value_name = "FILE", conflicts_with = "camera")]
    pub intrinsics: Option<PathBuf>,
    /// A known camera instead of an intrinsics file.
    #[arg(long, value_enum)]
    pub camera: Option<CameraModel>,
    /// The workspace whose coordinates to report (default: the first configured).
    #[arg(long, value_name = "ID")]
    pub workspace: Option<String>,
    /// Treat the image as the workspace square already warped (marker centres at its corners).
    #[arg(long)]
    pub warped: bool,
    /// Write the image annotated with markers, sheet and objects to this PNG file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `robotd detect`.
pub fn run(args: &DetectArgs, config: &Config) -> Result<std::process::ExitCode> {
    let start = Instant::now();
    let image = robotd_vision::still::load(&args.image)?;
    let decode_ms = ms(start);
    let (width, height) = (image.width, image.height);

    let workspaces = config.robot.workspace_infos();
    let workspace = match &args.workspace {
        Some(id) => workspaces
            .iter()
            .find(|w| &w.id == id)
            .cloned()
            .with_context(|| {
                format!(
                    "no workspace '{id}' is configured (configured: {})",
                    workspaces
                        .iter()
                        .map(|w| w.id.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            })?,
        None => workspaces
            .first()
            .cloned()
            .context("no workspace is configured")?,
    };
    let table = match &config.perception.labels {
        Some(path) => LabelTable::load(path)?,
        None => LabelTable::builtin(),
    };
    let looks_warped =
        args.warped || robotd_vision::warped::looks_warped(&image.rgb, width, height);
    let (intrinsics, camera) = match camera_for(args, width, height) {
        Ok(found) => found,
        // A warped image has no camera of its own: the size of the camera's frames does not
        // matter for it.
        Err(_) if looks_warped => (pinhole(width, height), "warped".into()),
        Err(error) => return Err(error),
    };
    let frame = FrameView {
        rgb: &image.rgb,
        width,
        height,
        frame_id: 0,
        timestamp_unix_ns: 0,
    };

    let mut report = Report {
        image: args.image.display().to_string(),
        width,
        height,
        camera,
        workspace_id: workspace.id.clone(),
        mode: "none".into(),
        workspace_found: false,
        status: String::new(),
        markers: Vec::new(),
        objects: Vec::new(),
        timing: Timing {
            decode_ms,
            ..Timing::default()
        },
    };

    // The sheet from its markers (setting up the camera's undistortion table is not timed).
    let settings = config.perception.detector_settings();
    let mut pipeline = pipeline_for(&intrinsics, &workspace, &table, &settings)?;
    if args.camera.is_none() && args.intrinsics.is_none() {
        pipeline = pipeline.with_guessed_intrinsics();
    }
    let t0 = Instant::now();
    let (markers, located) = if args.warped {
        (pipeline.find_markers(&frame), None)
    } else {
        let (markers, located) = pipeline.locate_with_markers(&frame, &workspace);
        (markers, Some(located))
    };
    let mut sheet: Option<(Pipeline, TablePlane)> = None;
    let mut corners: Option<[MarkerObservation; 4]> = None;
    match located {
        Some(Ok((plane, four))) => {
            report.mode = "markers".into();
            report.status = match pipeline.sheets_in_view() {
                0 | 1 => "the workspace sheet and its four markers are in view".into(),
                n => format!(
                    "{n} workspace sheets are in view: the nearest (largest in the image) is used"
                ),
            };
            corners = Some(four);
            sheet = Some((pipeline, plane));
        }
        Some(Err(status)) if !looks_warped => {
            report.status = status.to_string();
        }
        _ => {
            // Already the workspace square: a virtual distortion-free camera straight above the
            // workspace's centre, at its observation pose's height (where the real camera that
            // took the picture about was), so raised objects' parallax is corrected about right.
            let across_m = (workspace.upper_left.y_m - workspace.lower_right.y_m).abs();
            let height_m = workspace.observation_pose.z_m.max(0.05);
            let f = height_m * width as f64 / across_m.max(1e-3);
            let warped = pipeline_for(
                &pinhole_with(width, height, f),
                &workspace,
                &table,
                &settings,
            )?;
            match warped.warped_plane(&workspace) {
                Some(plane) => {
                    report.mode = "warped".into();
                    report.camera = "warped (the image is the workspace square)".into();
                    report.status = if args.warped {
                        "the image is the workspace square (--warped)".into()
                    } else {
                        "no whole markers, but the image is the workspace square already \
                         (a quarter marker in each corner)"
                            .into()
                    };
                    sheet = Some((warped, plane));
                }
                None => report.status = "the warped image gives no table plane".into(),
            }
        }
    }
    report.timing.markers_ms = ms(t0);
    report.markers = marker_reports(&markers, corners.as_ref());

    let t1 = Instant::now();
    let mut plane_for_drawing = None;
    if let Some((mut pipeline, plane)) = sheet {
        let objects = pipeline
            .detect_on(&frame, &workspace, plane.clone())
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        report.workspace_found = true;
        report.objects = objects
            .iter()
            .map(|o| object_report(o, &workspace, &table, width, height))
            .collect();
        plane_for_drawing = Some((pipeline, plane));
    }
    report.timing.detect_ms = ms(t1);
    report.timing.perception_ms = report.timing.markers_ms + report.timing.detect_ms;

    if let Some(out) = &args.out {
        let mut rgb = image.rgb.clone();
        annotate::annotate(&mut rgb, &report, &workspace, plane_for_drawing.as_ref());
        image::save_buffer_with_format(
            out,
            &rgb,
            width as u32,
            height as u32,
            image::ExtendedColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .with_context(|| format!("writing {}", out.display()))?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", report.text());
    }
    Ok(std::process::ExitCode::SUCCESS)
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

fn pipeline_for(
    intrinsics: &CameraIntrinsics,
    workspace: &WorkspaceInfo,
    table: &LabelTable,
    settings: &ColourDetectorSettings,
) -> Result<Pipeline> {
    let detector = ColourDetector::new(table.clone(), settings.clone());
    Ok(Pipeline::new(
        intrinsics,
        vec![workspace.clone()],
        Box::new(detector),
    )?)
}
