//! Runs one skill: look (a fresh view from the observation pose), plan every pose, check every
//! pose against the workspaces and the arm's reach, and only then move — step by step, with a
//! progress message before each step and a cancel check between steps.

mod push;
#[cfg(test)]
mod tests;

use crate::geometry;
use crate::plan::{self, HeldPlan};
use crate::SkillsSettings;
use robotd_kinematics::{pose_to_isometry, Kinematics};
use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply, PathKind};
use robotd_protocol::envelope::unix_now_ns;
use robotd_protocol::gripper::{GripperCommand, GripperReply};
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::skills::{Skill, SkillError, SkillProgress, SkillReply};
use robotd_protocol::workspace::{WorkspaceInfo, WorkspaceQuery, WorkspaceReply, WorkspaceRequest};
use robotd_protocol::{Location, Point2, Pose};
use robotd_runtime::bus::{Client, Publisher};
use std::f64::consts::FRAC_PI_2;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// Which run may be cancelled, and whether it was; and cancels of runs that have not started
/// yet (waiting for approval or behind another skill), so they never start.
#[derive(Debug, Default)]
pub(crate) struct CancelFlag {
    pub(crate) run_id: AtomicU64,
    pub(crate) cancelled: AtomicBool,
    early: std::sync::Mutex<std::collections::VecDeque<u64>>,
}

/// Cancels of not-yet-started runs remembered (older ones are forgotten first).
const EARLY_CANCELS: usize = 1024;

impl CancelFlag {
    /// Remembers a cancel of `run_id`, which has not started.
    pub(crate) fn cancel_early(&self, run_id: u64) {
        let mut early = self.early.lock().unwrap_or_else(|e| e.into_inner());
        if early.len() >= EARLY_CANCELS {
            early.pop_front();
        }
        early.push_back(run_id);
    }

    /// Whether `run_id` was cancelled before it started (forgetting the cancel).
    pub(crate) fn take_early(&self, run_id: u64) -> bool {
        let mut early = self.early.lock().unwrap_or_else(|e| e.into_inner());
        match early.iter().position(|id| *id == run_id) {
            Some(i) => {
                early.remove(i);
                true
            }
            None => false,
        }
    }
}

/// The object in the gripper.
#[derive(Debug, Clone)]
struct Held {
    object: DetectedObject,
    /// Height of the TCP above the object's base while held, metres.
    tcp_above_base_m: f64,
    /// Gripper yaw it was picked with.
    yaw_rad: f64,
    /// Its own height, base to top, metres (a stacked object's centre of mass is above the
    /// object it stood on).
    height_m: f64,
}

/// The bus ports and state of the skills actor.
pub(crate) struct Runner {
    pub(crate) settings: SkillsSettings,
    pub(crate) kinematics: Kinematics,
    pub(crate) arm: Client<ArmCommand, ArmReply>,
    pub(crate) gripper: Client<GripperCommand, GripperReply>,
    pub(crate) workspace: Client<WorkspaceQuery, WorkspaceReply>,
    pub(crate) progress: Publisher<SkillProgress>,
    pub(crate) cancel: Arc<CancelFlag>,
    held: Option<Held>,
    /// Set while the tool is down near the table (between going down to grasp, release or
    /// push and lifting again): the height it must first rise to, straight up, before any
    /// joint-space move. A skill that fails down there leaves it set (see [`Self::rise_clear`]).
    clear_z: Option<f64>,
    /// The objects of the last look (to suggest where a held object can be put down).
    last_seen: Vec<DetectedObject>,
}

/// One running skill: its id and step counter.
struct Run {
    run_id: u64,
    step: u32,
    total: u32,
}

/// A planned tool pose: pointing down at (x, y, z), turned by yaw.
fn down(p: Point2, z: f64, yaw: f64) -> Pose {
    Pose::new(p.x_m, p.y_m, z, 0.0, FRAC_PI_2, yaw)
}

impl Runner {
    pub(crate) fn new(
        settings: SkillsSettings,
        arm: Client<ArmCommand, ArmReply>,
        gripper: Client<GripperCommand, GripperReply>,
        workspace: Client<WorkspaceQuery, WorkspaceReply>,
        progress: Publisher<SkillProgress>,
        cancel: Arc<CancelFlag>,
    ) -> Self {
        Self {
            kinematics: Kinematics::new(settings.robot),
            settings,
            arm,
            gripper,
            workspace,
            progress,
            cancel,
            held: None,
            clear_z: None,
            last_seen: Vec::new(),
        }
    }

    /// Runs `skill`; always answers.
    pub(crate) async fn run(&mut self, run_id: u64, skill: Skill) -> SkillReply {
        // Publish the run id before looking for an early cancel: a cancel that comes in
        // between is then either seen here or sets `cancelled`.
        self.cancel.cancelled.store(false, Ordering::SeqCst);
        self.cancel.run_id.store(run_id, Ordering::SeqCst);
        if self.cancel.take_early(run_id) {
            self.cancel.run_id.store(0, Ordering::SeqCst);
            tracing::info!(
                skill = skill.name(),
                run_id,
                "skill cancelled before it started; nothing moved"
            );
            return SkillReply::failed(SkillError::Cancelled);
        }
        let mut run = Run {
            run_id,
            step: 0,
            total: 1,
        };
        let name = skill.name();
        let outcome = self.dispatch(&mut run, skill).await;
        self.cancel.run_id.store(0, Ordering::SeqCst);
        match outcome {
            Ok(reply) => {
                tracing::info!(skill = name, run_id, "skill done");
                reply
            }
            Err(error) => {
                if !matches!(error, SkillError::Cancelled) {
                    // Get the tool up from the table now, with or without what it holds,
                    // so the next skill starts clear. A stopped or colliding arm refuses;
                    // the next skill's first move then rises first.
                    if let Err(rise) = self.rise_clear().await {
                        tracing::warn!(skill = name, run_id, %rise, "could not lift the tool clear after the failure");
                    }
                }
                let still_held = self.held.as_ref().map(|h| h.object.label.clone());
                let put_down_at = self.held.as_ref().and_then(|held| {
                    let others: Vec<DetectedObject> = self
                        .last_seen
                        .iter()
                        .filter(|o| o.id != held.object.id)
                        .cloned()
                        .collect();
                    let plan = HeldPlan {
                        object: &held.object,
                        yaw_rad: held.yaw_rad,
                        tcp_above_base_m: held.tcp_above_base_m,
                    };
                    plan::free_spot(&self.settings, &others, &plan)
                });
                tracing::warn!(skill = name, run_id, %error, ?still_held, "skill failed");
                SkillReply::Failed {
                    error,
                    still_held,
                    put_down_at,
                }
            }
        }
    }

    async fn dispatch(&mut self, run: &mut Run, skill: Skill) -> Result<SkillReply, SkillError> {
        use robotd_protocol::Validate;
        skill.validate()?;
        match skill {
            Skill::Pick {
                object_name,
                pick_at,
                z_offset_m,
            } => {
                run.total = 7;
                let object = self
                    .pick(run, &object_name, pick_at, z_offset_m, None)
                    .await?;
                self.finish(run).await?;
                Ok(done(Some(object), Some(pick_at), None))
            }
            Skill::Place { place_at, location } => {
                run.total = 7;
                let (object, at) = self.place(run, place_at, location).await?;
                self.finish(run).await?;
                Ok(done(Some(object), None, Some(at)))
            }
            Skill::PickPlace {
                object_name,
                pick_at,
                place_at,
                location,
                z_offset_m,
            } => {
                run.total = 12;
                let object = self
                    .pick(
                        run,
                        &object_name,
                        pick_at,
                        z_offset_m,
                        Some((place_at, location)),
                    )
                    .await?;
                let (_, at) = self.place(run, place_at, location).await?;
                self.finish(run).await?;
                let from = object_xy(&object);
                Ok(done(Some(object), Some(from), Some(at)))
            }
            Skill::MoveBy {
                object_name,
                pick_at,
                direction,
                distance_m,
                z_offset_m,
            } => {
                run.total = 12;
                // The contract: the place is `pick_coordinate` moved by `distance` (not the
                // object's own centre moved), which is also what the reply says.
                let target = direction.offset(pick_at, distance_m);
                let object = self
                    .pick(
                        run,
                        &object_name,
                        pick_at,
                        z_offset_m,
                        Some((target, Location::None)),
                    )
                    .await?;
                let (_, at) = self.place(run, target, Location::None).await?;
                self.finish(run).await?;
                let from = object_xy(&object);
                Ok(done(Some(object), Some(from), Some(at)))
            }
            Skill::Push {
                object_name,
                push_at,
                direction,
                distance_m,
            } => {
                run.total = 8;
                let (object, to) = self
                    .push(run, &object_name, push_at, direction, distance_m)
                    .await?;
                self.finish(run).await?;
                self.verify_push(&object, direction, distance_m).await?;
                let from = object_xy(&object);
                Ok(done(Some(object), Some(from), Some(to)))
            }
            Skill::GoToObservationPose { workspace_id } => {
                run.total = 1;
                self.step(
                    run,
                    format!("moving to the observation pose of '{workspace_id}'"),
                )?;
                self.rise_clear().await?;
                self.arm_command(ArmCommand::GoToObservationPose { workspace_id })
                    .await?;
                Ok(done(None, None, None))
            }
            Skill::Calibrate => {
                run.total = 1;
                self.step(run, "calibrating the arm".into())?;
                self.arm_command(ArmCommand::Calibrate).await?;
                Ok(done(None, None, None))
            }
            Skill::ClearCollision => {
                run.total = 1;
                self.step(run, "clearing the collision flag".into())?;
                self.arm_command(ArmCommand::ClearCollision).await?;
                Ok(done(None, None, None))
            }
        }
    }

    // -----------------------------------------------------------------------------------
    // Steps

    /// Publishes progress for the next step; refuses to go on once cancelled.
    fn step(&self, run: &mut Run, message: String) -> Result<(), SkillError> {
        self.check_cancel()?;
        run.step += 1;
        run.total = run.total.max(run.step);
        tracing::debug!(run_id = run.run_id, step = run.step, %message, "skill step");
        if let Err(error) = self.progress.publish(&SkillProgress {
            run_id: run.run_id,
            step: run.step,
            total: run.total,
            message,
        }) {
            tracing::debug!(%error, "skill progress not published");
        }
        Ok(())
    }

    fn check_cancel(&self) -> Result<(), SkillError> {
        if self.cancel.cancelled.load(Ordering::SeqCst) {
            Err(SkillError::Cancelled)
        } else {
            Ok(())
        }
    }

    async fn arm_command(&self, command: ArmCommand) -> Result<Pose, SkillError> {
        let reply = self
            .arm
            .request(&command, self.settings.command_timeout)
            .await
            .map_err(|e| SkillError::arm(format!("the arm did not answer: {e}")))?;
        match reply {
            ArmReply::Ok { pose } => Ok(pose),
            ArmReply::Error {
                error: ArmError::Stopped,
            } if self.cancel.cancelled.load(Ordering::SeqCst) => Err(SkillError::Cancelled),
            ArmReply::Error {
                error:
                    ArmError::UnknownWorkspace {
                        workspace_id,
                        known,
                    },
            } => Err(SkillError::UnknownWorkspace {
                workspace_id,
                known,
            }),
            ArmReply::Error { error } => Err(SkillError::arm(error.to_string())),
            other => Err(SkillError::arm(format!("unexpected arm reply {other:?}"))),
        }
    }

    /// Rises straight up to [`Self::clear_z`] when a failed skill left the tool low over the
    /// table: a joint-space move from down there (to the observation pose, to the next
    /// object) could sweep the tool, or the object it holds, through its neighbours. Rises
    /// from wherever the tool is now, keeping its x, y and orientation.
    async fn rise_clear(&mut self) -> Result<(), SkillError> {
        let Some(clear_z) = self.clear_z else {
            return Ok(());
        };
        let pose = self.arm_command(ArmCommand::GetPose).await?;
        if pose.z_m < clear_z {
            tracing::info!(
                from_z = pose.z_m,
                to_z = clear_z,
                "lifting the tool clear of the table first"
            );
            self.move_to(
                Pose {
                    z_m: clear_z,
                    ..pose
                },
                PathKind::Linear,
            )
            .await?;
        }
        self.clear_z = None;
        Ok(())
    }

    async fn move_to(&self, pose: Pose, path: PathKind) -> Result<(), SkillError> {
        self.arm_command(ArmCommand::MoveToPose { target: pose, path })
            .await
            .map(|_| ())
    }

    async fn grip(&self, command: GripperCommand) -> Result<bool, SkillError> {
        let reply = self
            .gripper
            .request(&command, self.settings.command_timeout)
            .await
            .map_err(|e| SkillError::gripper(format!("the gripper did not answer: {e}")))?;
        match reply {
            GripperReply::State { holding, .. } => Ok(holding),
            GripperReply::Error { error } => Err(SkillError::gripper(error.to_string())),
        }
    }

    async fn ask(
        &self,
        request: WorkspaceRequest,
        fresh_after: Option<u64>,
    ) -> Result<WorkspaceReply, SkillError> {
        let query = WorkspaceQuery {
            request,
            fresh_after_unix_ns: fresh_after,
            max_wait_ms: 0,
        };
        self.workspace
            .request(&query, self.settings.command_timeout)
            .await
            .map_err(|e| {
                SkillError::perception(format!("the workspace model did not answer: {e}"))
            })?
            .into_result()
            .map_err(|e| SkillError::perception(e.to_string()))
    }

    /// Moves to `ws`'s observation pose and returns the objects of the first steady view
    /// taken there.
    async fn look(
        &mut self,
        run: &mut Run,
        ws: &WorkspaceInfo,
    ) -> Result<Vec<DetectedObject>, SkillError> {
        self.step(run, format!("looking at workspace '{}'", ws.id))?;
        self.rise_clear().await?;
        self.arm_command(ArmCommand::GoToObservationPose {
            workspace_id: ws.id.clone(),
        })
        .await?;
        let objects = self.objects_seen_after(unix_now_ns()).await?;
        self.last_seen.clone_from(&objects);
        Ok(objects)
    }

    /// Every object on the table, from a view taken after `unix_ns` (the workspace model
    /// waits for one).
    async fn objects_seen_after(&self, unix_ns: u64) -> Result<Vec<DetectedObject>, SkillError> {
        let reply = self
            .ask(
                WorkspaceRequest::GetObjects {
                    location: Location::None,
                    coordinate: None,
                    label: None,
                },
                Some(unix_ns),
            )
            .await?;
        match reply {
            WorkspaceReply::Objects { objects } => Ok(objects),
            other => Err(SkillError::perception(format!(
                "unexpected answer {other:?}"
            ))),
        }
    }

    /// Looks at `ws` and finds `name` near `at`: the objects seen, and that one.
    async fn look_for(
        &mut self,
        run: &mut Run,
        ws: &WorkspaceInfo,
        name: &str,
        at: Point2,
    ) -> Result<(Vec<DetectedObject>, DetectedObject), SkillError> {
        let objects = self.look(run, ws).await?;
        let object = find_object(&objects, name, at, self.settings.pick_radius_m)?;
        Ok((objects, object))
    }

    /// Refuses to start while the gripper holds something; `reason` says why from its label.
    fn refuse_while_holding(&self, reason: impl FnOnce(&str) -> String) -> Result<(), SkillError> {
        match &self.held {
            Some(held) => Err(SkillError::BadPlacement {
                reason: reason(&held.object.label),
            }),
            None => Ok(()),
        }
    }

    fn workspace(&self, what: &str, p: Point2) -> Result<WorkspaceInfo, SkillError> {
        plan::workspace_of(&self.settings, what, p)
    }

    /// Checks that the arm reaches every pose of a plan, before anything moves.
    fn reachable(&self, plan: &[(&str, Pose)]) -> Result<(), SkillError> {
        for (what, pose) in plan {
            if let Err(e) = self.kinematics.inverse(&pose_to_isometry(pose), None) {
                return Err(SkillError::Unreachable {
                    what: (*what).to_owned(),
                    reason: e.to_string(),
                });
            }
        }
        Ok(())
    }

    /// Ends a motion skill at the safe pose: the observation pose of the first workspace.
    async fn finish(&self, run: &mut Run) -> Result<(), SkillError> {
        let ws = self.settings.workspaces[0].id.clone();
        self.step(run, "returning to the observation pose".into())?;
        self.arm_command(ArmCommand::GoToObservationPose { workspace_id: ws })
            .await?;
        Ok(())
    }

    // -----------------------------------------------------------------------------------
    // Pick

    /// Picks `name` near `at`. With `then_place`, the place is planned from the same view
    /// before anything moves: a place that cannot work means the pick does not start.
    async fn pick(
        &mut self,
        run: &mut Run,
        name: &str,
        at: Point2,
        z_offset_m: f64,
        then_place: Option<(Point2, Location)>,
    ) -> Result<DetectedObject, SkillError> {
        let ws = self.workspace("pick", at)?;
        if let Some((place, _)) = then_place {
            self.workspace("place", place)?;
        }
        self.refuse_while_holding(|label| {
            format!("the gripper already holds '{label}'; place it first")
        })?;
        let (objects, object) = self.look_for(run, &ws, name, at).await?;
        let width = geometry::grasp_width(&object);
        let max = self.settings.gripper_max_width_m;
        if width > max - 0.002 {
            return Err(SkillError::TooWide {
                object_name: object.label.clone(),
                width_mm: width * 1000.0,
                max_mm: max * 1000.0,
            });
        }
        // Of a stack, only the top comes off: the workspace model reports a stacked object at
        // its true height, on the top of the one it rests on.
        if let Some(upper) = objects.iter().find(|o| geometry::rests_on(o, &object)) {
            return Err(SkillError::BadPlacement {
                reason: format!(
                    "'{}' stands on top of '{}'; move '{}' first",
                    upper.label, object.label, upper.label
                ),
            });
        }
        let xy = object_xy(&object);
        let base_z = geometry::base_z(&object, &objects);
        let object_top = geometry::top_among(&object, &objects);
        let grasp_z = plan::grasp_height_on(&self.settings, &object, base_z, z_offset_m);
        let yaw = plan::grasp_yaw(&self.settings, &object, &objects, grasp_z)?;
        let held = HeldPlan {
            object: &object,
            yaw_rad: yaw,
            tcp_above_base_m: grasp_z - base_z,
        };
        if let Some((place_at, location)) = then_place {
            let others: Vec<DetectedObject> = objects
                .iter()
                .filter(|o| o.id != object.id)
                .cloned()
                .collect();
            plan::place_target(&self.settings, &others, &held, place_at, location)?;
        }
        let above_z = object_top + self.settings.approach_height_m;
        let above = down(xy, above_z, yaw);
        let grasp = down(xy, grasp_z, yaw);
        self.reachable(&[("the pick approach", above), ("the grasp pose", grasp)])?;

        self.step(run, "opening the gripper".into())?;
        self.grip(GripperCommand::Open).await?;
        self.step(run, format!("moving above '{}'", object.label))?;
        self.move_to(above, PathKind::Joint).await?;
        self.step(run, "lowering to the grasp".into())?;
        self.clear_z = Some(above.z_m);
        self.move_to(grasp, PathKind::Linear).await?;
        self.step(run, "closing the gripper".into())?;
        let holding = self.grip(GripperCommand::Close).await?;
        if holding {
            self.held = Some(Held {
                object: object.clone(),
                tcp_above_base_m: grasp_z - base_z,
                yaw_rad: yaw,
                height_m: object_top - base_z,
            });
        }
        self.step(run, "lifting".into())?;
        self.move_to(above, PathKind::Linear).await?;
        self.clear_z = None;
        // Still holding after the lift?
        if !holding || !self.grip(GripperCommand::GetState).await? {
            self.held = None;
            return Err(SkillError::GraspMissed { at: xy });
        }
        if let Err(error) = self
            .ask(
                WorkspaceRequest::ObjectPicked {
                    object_id: object.id.clone(),
                },
                None,
            )
            .await
        {
            tracing::warn!(%error, id = %object.id, "the workspace model was not told of a pick");
        }
        Ok(object)
    }

    // -----------------------------------------------------------------------------------
    // Place

    async fn place(
        &mut self,
        run: &mut Run,
        at: Point2,
        location: Location,
    ) -> Result<(DetectedObject, Point2), SkillError> {
        let ws = self.workspace("place", at)?;
        let Some(held) = self.held.clone() else {
            // The gripper may hold something robotd did not pick (a restart, a hand).
            return Err(SkillError::NothingHeld);
        };
        let objects = self.look(run, &ws).await?;
        let others: Vec<DetectedObject> = objects
            .into_iter()
            .filter(|o| o.id != held.object.id)
            .collect();
        let held_plan = HeldPlan {
            object: &held.object,
            yaw_rad: held.yaw_rad,
            tcp_above_base_m: held.tcp_above_base_m,
        };
        let (target, surface_z) =
            plan::place_target(&self.settings, &others, &held_plan, at, location)?;
        let release_z = plan::release_height(&self.settings, &held_plan, surface_z);
        let above_z = surface_z
            + held.height_m
            + held.tcp_above_base_m.max(0.0)
            + self.settings.approach_height_m;
        let above = down(target, above_z, held.yaw_rad);
        let release = down(target, release_z, held.yaw_rad);
        self.reachable(&[("the place approach", above), ("the release pose", release)])?;

        self.step(
            run,
            format!("moving above [{:.3}, {:.3}]", target.x_m, target.y_m),
        )?;
        self.move_to(above, PathKind::Joint).await?;
        self.step(run, "lowering".into())?;
        self.clear_z = Some(above.z_m);
        self.move_to(release, PathKind::Linear).await?;
        self.step(run, "opening the gripper".into())?;
        let still_holding = self.grip(GripperCommand::Open).await?;
        if still_holding {
            return Err(SkillError::gripper(
                "the gripper still holds the object after opening",
            ));
        }
        self.held = None;
        self.step(run, "lifting".into())?;
        self.move_to(above, PathKind::Linear).await?;
        self.clear_z = None;
        if let Err(error) = self
            .ask(
                WorkspaceRequest::ObjectPlaced {
                    object_id: held.object.id.clone(),
                    at: target,
                },
                None,
            )
            .await
        {
            tracing::warn!(%error, "the workspace model was not told of a place");
        }
        Ok((held.object, target))
    }
}

/// The object labelled `name` nearest `at`, within `radius_m`; otherwise the error names the
/// labels seen there.
fn find_object(
    objects: &[DetectedObject],
    name: &str,
    at: Point2,
    radius_m: f64,
) -> Result<DetectedObject, SkillError> {
    let near = |o: &&DetectedObject| o.xy().distance_to(&at) <= radius_m;
    objects
        .iter()
        .filter(near)
        .filter(|o| o.label_is(name))
        .min_by(|a, b| a.xy().distance_to(&at).total_cmp(&b.xy().distance_to(&at)))
        .cloned()
        .ok_or_else(|| SkillError::ObjectNotFound {
            object_name: name.to_owned(),
            at,
            nearby: objects
                .iter()
                .filter(near)
                .map(|o| o.label.clone())
                .collect(),
        })
}

fn object_xy(o: &DetectedObject) -> Point2 {
    o.xy()
}

fn done(object: Option<DetectedObject>, from: Option<Point2>, to: Option<Point2>) -> SkillReply {
    SkillReply::Done {
        object: object.map(Box::new),
        from,
        to,
    }
}
