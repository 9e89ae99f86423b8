//! Push: look, plan the push from behind the object (fingers or palm first, whichever meets it
//! first), check every pose and the tool's path against the neighbours, push, lift, and
//! then check with a fresh view that the object moved about as far as asked.

use super::{down, object_xy, Run, Runner};
use crate::geometry::{self, top_z};
use crate::plan;
use robotd_protocol::arm::PathKind;
use robotd_protocol::envelope::unix_now_ns;
use robotd_protocol::gripper::GripperCommand;
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::skills::SkillError;
use robotd_protocol::workspace::WorkspaceRequest;
use robotd_protocol::{Direction, Point2};
use std::f64::consts::FRAC_PI_2;

impl Runner {
    pub(super) async fn push(
        &mut self,
        run: &mut Run,
        name: &str,
        at: Point2,
        direction: Direction,
        distance_m: f64,
    ) -> Result<(DetectedObject, Point2), SkillError> {
        let ws = self.workspace("push", at)?;
        self.refuse_while_holding(|label| {
            format!("the gripper holds '{label}'; place it before pushing")
        })?;
        let (objects, object) = self.look_for(run, &ws, name, at).await?;
        // A push would topple a stack or slide its top off: stacks come apart by picking.
        if let Some(other) = objects
            .iter()
            .find(|o| geometry::rests_on(o, &object) || geometry::rests_on(&object, o))
        {
            return Err(SkillError::BadPlacement {
                reason: format!(
                    "'{}' and '{}' are stacked; pushing would topple them, pick the top one off \
                     first",
                    object.label, other.label
                ),
            });
        }
        let end_of_object = direction.offset(object_xy(&object), distance_m);
        self.workspace("push", end_of_object)?;
        if let Some(problem) = plan::push_problem(&self.settings, &object, &objects, end_of_object)
        {
            return Err(SkillError::BadPlacement { reason: problem });
        }
        let low_z = self
            .settings
            .push_z_m
            .min(top_z(&object) / 2.0)
            .max(self.settings.min_tcp_z_m);
        // What meets the object first: the fingers, or the palm above them for tall objects.
        let reach = if top_z(&object) > low_z + self.settings.finger_length_m {
            self.settings.palm_reach_m
        } else {
            self.settings.finger_reach_m
        };
        let clearance = reach + self.settings.push_gap_m;
        let start = geometry::push_start(&object, direction, clearance);
        // The tool also crosses the gap before it touches, so the object moves `distance_m`.
        let end = direction.offset(start, distance_m + self.settings.push_gap_m);
        let yaw = match direction {
            Direction::Left | Direction::Right => FRAC_PI_2,
            Direction::Up | Direction::Down => 0.0,
        };
        if let Some(problem) =
            plan::push_tool_problem(&self.settings, &object, &objects, start, end, yaw, low_z)
        {
            return Err(SkillError::BadPlacement { reason: problem });
        }
        let travel_z = top_z(&object) + self.settings.approach_height_m;
        let plan = [
            ("the push approach", down(start, travel_z, yaw)),
            ("the push start", down(start, low_z, yaw)),
            ("the push end", down(end, low_z, yaw)),
            ("the push retreat", down(end, travel_z, yaw)),
        ];
        self.reachable(&plan)?;
        self.step(run, "closing the gripper".into())?;
        self.grip(GripperCommand::Close).await?;
        self.step(run, format!("moving behind '{}'", object.label))?;
        self.move_to(plan[0].1, PathKind::Joint).await?;
        self.step(run, "lowering".into())?;
        self.clear_z = Some(travel_z);
        self.move_to(plan[1].1, PathKind::Linear).await?;
        self.step(
            run,
            format!("pushing {:.1} mm {direction}", distance_m * 1000.0),
        )?;
        self.move_to(plan[2].1, PathKind::Linear).await?;
        self.step(run, "lifting".into())?;
        self.move_to(plan[3].1, PathKind::Linear).await?;
        self.clear_z = None;
        self.step(run, "opening the gripper".into())?;
        self.grip(GripperCommand::Open).await?;
        // Memory moves the object where the push should have put it, so the next view keeps
        // its id instead of seeing a new object beside a stale one.
        if let Err(error) = self
            .ask(
                WorkspaceRequest::ObjectPlaced {
                    object_id: object.id.clone(),
                    at: end_of_object,
                },
                None,
            )
            .await
        {
            tracing::warn!(%error, "the workspace model was not told of a push");
        }
        Ok((object, end_of_object))
    }
}

impl Runner {
    /// Checks with a fresh view that a pushed object moved about as far as asked.
    pub(super) async fn verify_push(
        &self,
        object: &DetectedObject,
        direction: Direction,
        distance_m: f64,
    ) -> Result<(), SkillError> {
        let objects = self.objects_seen_after(unix_now_ns()).await?;
        // The tracker may give an object that moved far a new id (the old one lingers until it
        // expires): take the same-label object nearest to where the push should have put it.
        let expected = direction.offset(object.xy(), distance_m);
        let Some(now) = objects
            .iter()
            .filter(|o| o.label == object.label)
            .min_by(|a, b| {
                a.xy()
                    .distance_to(&expected)
                    .total_cmp(&b.xy().distance_to(&expected))
            })
        else {
            return Err(SkillError::NotAsExpected {
                reason: format!(
                    "'{}' is no longer seen after the push (pushed off the workspace?)",
                    object.label
                ),
            });
        };
        let (ux, uy) = direction.unit_xy();
        let moved = (now.xy().x_m - object.xy().x_m) * ux + (now.xy().y_m - object.xy().y_m) * uy;
        let tolerance = (0.2 * distance_m).max(0.005);
        if (moved - distance_m).abs() > tolerance {
            return Err(SkillError::NotAsExpected {
                reason: format!(
                    "'{}' moved {:.1} mm {direction} instead of {:.1} mm (something blocks it?); \
                     it is now at [{:.3}, {:.3}]",
                    object.label,
                    moved * 1000.0,
                    distance_m * 1000.0,
                    now.xy().x_m,
                    now.xy().y_m
                ),
            });
        }
        Ok(())
    }
}
