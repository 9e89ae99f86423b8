//! `replay`: with `robot.driver = "replay"`, can the recording be played as the robot, and
//! what does it hold?
//!
//! The row runs the replay driver's own check ([`robotd_driver_replay::inspect`], what
//! `robotd serve` runs before it starts): the file opens, is MCAP, has camera frames and arm
//! states, was recorded on `robot.replay.model`, and its frames fit the intrinsics in use. It
//! reads the file once (about a second per gigabyte) and decodes no image. A file that breaks
//! off (a recorder killed before it closed it) plays up to the break: a warning.
//!
//! Without the replay driver there is nothing to check (`ok`).

use super::Check;
use robotd_driver::ReplayConfig;

const NAME: &str = "replay";

/// `[robot.replay]` when the replay driver is configured (`None` otherwise).
pub(super) fn check_replay(replay: Option<&ReplayConfig>) -> Check {
    let Some(config) = replay else {
        return Check::ok(
            NAME,
            "robot.driver is not \"replay\"; no recording to check",
        );
    };
    match robotd_driver_replay::inspect(config) {
        Ok(checked) => {
            let contents = &checked.contents;
            let found = format!(
                "{}: {}; intrinsics: {}",
                contents.path.display(),
                contents.describe(),
                checked.intrinsics_from
            );
            match &contents.damaged {
                None => Check::ok(NAME, found),
                Some(_) => Check::warn(
                    NAME,
                    found,
                    "the replay stops where the file breaks off; record the session again to \
                     have all of it",
                ),
            }
        }
        Err(error) => Check::problem(
            NAME,
            error.to_string(),
            "give robot.replay.file a recording of `robotd record` or robotd serve's [record] \
             made on robot.replay.model, with the camera and arm/state in it",
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::Status;

    #[test]
    fn no_replay_is_fine_and_a_missing_recording_is_a_problem_naming_it() {
        assert_eq!(check_replay(None).status, Status::Ok);
        let config = ReplayConfig {
            file: Some("/nonexistent/session.mcap".into()),
            ..ReplayConfig::default()
        };
        let row = check_replay(Some(&config));
        assert_eq!(row.status, Status::Problem);
        assert!(
            row.found.contains("/nonexistent/session.mcap"),
            "{}",
            row.found
        );
        assert!(row.found.contains("no such file"), "{}", row.found);
        assert!(row.fix.is_some());
    }
}
