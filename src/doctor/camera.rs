//! `camera`: with a V4L2 camera configured (`robot.widowx.camera_url = "/dev/video0"`), does
//! the device open, capture video and give the size of its intrinsics in a format robotd
//! reads?
//!
//! The row opens the device as the driver does, negotiates the format and closes it again;
//! it captures no frame. An MJPEG stream (`http://…`) is not probed here: the running
//! service's `/health` says whether its frames arrive. Without a camera there is nothing to
//! check (`ok`).

use super::Check;
use std::path::Path;

const NAME: &str = "camera";

/// The configured camera source and the frame size of its intrinsics (`None`: no camera).
pub(super) fn check_camera(camera: Option<(String, (u32, u32))>) -> Check {
    let Some((source, size)) = camera else {
        return Check::ok(NAME, "no camera_url configured; no camera to check");
    };
    if !source.starts_with("/dev/") {
        return Check::ok(
            NAME,
            format!("{source} is an MJPEG stream: not probed here (see /health of the service)"),
        );
    }
    match robotd_driver_v4l2::probe(Path::new(&source), size) {
        Ok(gives) => Check::ok(NAME, format!("{source} gives {gives}")),
        Err(reason) => Check::problem(
            NAME,
            reason,
            "plug the camera in and check `v4l2-ctl --list-devices` (package v4l-utils); a \
             camera held by another program (a browser, mjpg-streamer) cannot be opened twice",
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::Status;

    #[test]
    fn no_camera_is_fine_and_a_missing_device_is_a_problem_with_its_reason() {
        assert_eq!(check_camera(None).status, Status::Ok);
        let row = check_camera(Some(("/dev/video-robotd-missing".into(), (640, 480))));
        assert_eq!(row.status, Status::Problem);
        assert!(row.found.contains("not found"), "{}", row.found);
        let row = check_camera(Some(("/dev/null".into(), (640, 480))));
        assert!(row.found.contains("not a V4L2 device"), "{}", row.found);
    }
}
