//! `robotd bench jpeg`: encoding a camera frame as JPEG, robotd's encoder (`jpeg-encoder`,
//! AVX2 when the CPU has it) beside the `image` crate's encoder it replaced, in the same run,
//! on the same rendered 640×480 frame of the default scene at the observation pose.
//!
//! Baseline: copying the frame's 921,600 bytes (the floor of anything that reads it). The
//! quality is the Redis edge's (85) and the dashboard's (80).

use super::Latency;
use anyhow::Result;
use robotd_driver::CameraDriver;
use robotd_runtime::bus::FRAME_BYTES;
use serde::Serialize;
use std::time::{Duration, Instant};

/// Everything `robotd bench jpeg` measures.
#[derive(Debug, Clone, Serialize)]
pub struct JpegFigures {
    /// robotd's encoder at quality 85, median ms.
    pub encode_q85_ms_p50: f64,
    /// robotd's encoder at quality 85, 99th percentile ms.
    pub encode_q85_ms_p99: f64,
    /// The `image` crate's encoder at quality 85, median ms.
    pub image_crate_q85_ms_p50: f64,
    /// robotd's encoder at quality 80 (the dashboard), median ms.
    pub encode_q80_ms_p50: f64,
    /// Copying the frame, median ms.
    pub copy_ms_p50: f64,
    /// Size of the q85 file, robotd's encoder, bytes.
    pub q85_bytes: usize,
    /// Size of the q85 file, the `image` crate's encoder, bytes.
    pub image_crate_q85_bytes: usize,
    /// Frames encoded per variant.
    pub frames: usize,
}

impl JpegFigures {
    /// The human-readable table.
    pub fn table(&self) -> String {
        format!(
            "robotd bench jpeg: {} frames of 640x480 per variant, same run\n\
             robotd encoder (jpeg-encoder) q85 p50 / p99  {:>6.2} / {:>6.2} ms  p50 ≤ 2 ms\n\
             image crate encoder q85 p50 (the old one)    {:>6.2} ms\n\
             robotd encoder q80 p50 (dashboard)           {:>6.2} ms\n\
             baseline: copy the frame p50                 {:>6.3} ms\n\
             file size q85: robotd / image crate          {} / {} bytes\n",
            self.frames,
            self.encode_q85_ms_p50,
            self.encode_q85_ms_p99,
            self.image_crate_q85_ms_p50,
            self.encode_q80_ms_p50,
            self.copy_ms_p50,
            self.q85_bytes,
            self.image_crate_q85_bytes,
        )
    }
}

fn ms(latency: Latency) -> (f64, f64) {
    (latency.p50_us / 1e3, latency.p99_us / 1e3)
}

/// Runs the measurements with `frames` frames per variant, interleaved.
pub fn run(frames: usize) -> Result<JpegFigures> {
    let (_robot, camera) = super::sim::observation_camera()?;
    let mut rgb = vec![0u8; FRAME_BYTES];
    camera
        .capture_into(&mut rgb)
        .map_err(|e| anyhow::anyhow!("render: {e}"))?;
    let (w, h) = (640, 480);
    let rgb = &rgb[..w as usize * h as usize * 3];
    let mut samples: [Vec<Duration>; 4] = Default::default();
    let (mut q85_bytes, mut image_bytes) = (0, 0);
    for i in 0..frames + 5 {
        let keep = i >= 5;
        let t = Instant::now();
        let copy = std::hint::black_box(rgb.to_vec());
        let copied = t.elapsed();
        drop(copy);
        let t = Instant::now();
        q85_bytes = robotd_render::encode_jpeg(rgb, w, h, 85)?.len();
        let q85 = t.elapsed();
        let t = Instant::now();
        image_bytes = robotd_render::encode_jpeg_with_image_crate(rgb, w, h, 85)?.len();
        let image = t.elapsed();
        let t = Instant::now();
        std::hint::black_box(robotd_render::encode_jpeg(rgb, w, h, 80)?);
        let q80 = t.elapsed();
        if keep {
            for (list, value) in samples.iter_mut().zip([q85, image, q80, copied]) {
                list.push(value);
            }
        }
    }
    let [mut q85, mut image, mut q80, mut copy] = samples;
    let (encode_q85_ms_p50, encode_q85_ms_p99) = ms(Latency::of(&mut q85));
    Ok(JpegFigures {
        encode_q85_ms_p50,
        encode_q85_ms_p99,
        image_crate_q85_ms_p50: ms(Latency::of(&mut image)).0,
        encode_q80_ms_p50: ms(Latency::of(&mut q80)).0,
        copy_ms_p50: ms(Latency::of(&mut copy)).0,
        q85_bytes,
        image_crate_q85_bytes: image_bytes,
        frames,
    })
}
