//! Answering requests: every detection and workspace question of the tools, and the updates
//! the skills report (an object picked, an object placed).
//!
//! [`check_request`] refuses a malformed request before anything is looked up;
//! [`SceneMemory::answer`] then dispatches on the request: object questions go to the
//! [queries] over the objects on the table of the current workspace, the largest free space
//! is searched by [`placeable_free_space`] (with the skills' sizes), label questions go to the
//! [label registry](crate::labels), picks and places to the [tracker](crate::tracker). A
//! placed object changes workspace when it is put down outside its own (by more than
//! [`PLACE_WORKSPACE_MARGIN_M`]) and inside another.

use super::SceneMemory;
use crate::free_space::placeable_free_space;
use crate::queries;
use robotd_protocol::geometry::Point2;
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::validate::Validate;
use robotd_protocol::workspace::{WorkspaceError, WorkspaceInfo, WorkspaceReply, WorkspaceRequest};

/// A placed object stays in its workspace when the place point lies within this distance of
/// it; otherwise it moves to a workspace that contains the point, metres.
pub const PLACE_WORKSPACE_MARGIN_M: f64 = 0.02;

/// The error a request earns before it is looked at further: a location filter without a
/// coordinate is [`WorkspaceError::CoordinateRequired`] (the tools' own text), any other
/// invalid field [`WorkspaceError::InvalidRequest`].
pub fn check_request(request: &WorkspaceRequest) -> Result<(), WorkspaceError> {
    if let WorkspaceRequest::GetObjects {
        location,
        coordinate: None,
        ..
    } = request
    {
        if location.needs_coordinate() {
            return Err(WorkspaceError::CoordinateRequired {
                location: *location,
            });
        }
    }
    request.validate().map_err(WorkspaceError::from)
}

impl SceneMemory {
    /// The objects of the current workspace on the table, first seen first.
    fn current_objects(&self) -> Vec<&DetectedObject> {
        match self.current_workspace() {
            Some(ws) => self.tracker.on_table(&ws.id).collect(),
            None => Vec::new(),
        }
    }

    fn workspace(&self, id: &str) -> Result<&WorkspaceInfo, WorkspaceError> {
        self.workspaces
            .iter()
            .find(|w| w.id == id.trim())
            .ok_or_else(|| WorkspaceError::UnknownWorkspace {
                workspace_id: id.to_owned(),
                known: self.known_ids(),
            })
    }

    /// The workspace a placed object belongs to: its own when `at` lies in it (within
    /// [`PLACE_WORKSPACE_MARGIN_M`]), else the first that contains `at`, else its own.
    fn place_workspace(&self, own: &str, at: Point2) -> String {
        let inside = |w: &&WorkspaceInfo| w.contains(at, PLACE_WORKSPACE_MARGIN_M);
        if self.workspaces.iter().filter(inside).any(|w| w.id == own) {
            return own.to_owned();
        }
        match self.workspaces.iter().find(inside) {
            Some(w) => w.id.clone(),
            None => own.to_owned(),
        }
    }

    /// Answers one request (checked with [`check_request`] first).
    pub fn answer(&mut self, request: &WorkspaceRequest) -> WorkspaceReply {
        match check_request(request).and_then(|()| self.answer_checked(request)) {
            Ok(reply) => reply,
            Err(error) => error.into(),
        }
    }

    fn answer_checked(
        &mut self,
        request: &WorkspaceRequest,
    ) -> Result<WorkspaceReply, WorkspaceError> {
        let cloned = |o: Option<&DetectedObject>| o.cloned();
        let all_cloned = |v: Vec<&DetectedObject>| v.into_iter().cloned().collect();
        Ok(match request {
            WorkspaceRequest::GetObjects {
                location,
                coordinate,
                label,
            } => WorkspaceReply::Objects {
                objects: all_cloned(queries::matching(
                    self.current_objects(),
                    *location,
                    *coordinate,
                    label.as_deref(),
                )?),
            },
            WorkspaceRequest::GetObjectNear { coordinate, label } => WorkspaceReply::Object {
                object: cloned(queries::nearest(
                    self.current_objects(),
                    *coordinate,
                    label.as_deref(),
                )),
            },
            WorkspaceRequest::GetLargestObject => WorkspaceReply::Object {
                object: cloned(queries::largest(self.current_objects())),
            },
            WorkspaceRequest::GetSmallestObject => WorkspaceReply::Object {
                object: cloned(queries::smallest(self.current_objects())),
            },
            WorkspaceRequest::GetObjectsSorted { ascending } => WorkspaceReply::Objects {
                objects: all_cloned(queries::sorted_by_size(self.current_objects(), *ascending)),
            },
            WorkspaceRequest::GetLargestFreeSpace => {
                let ws = self
                    .current_workspace()
                    .ok_or_else(|| WorkspaceError::Unavailable {
                        reason: "no workspace is configured".into(),
                    })?;
                let objects: Vec<DetectedObject> = self.tracker.on_table(&ws.id).cloned().collect();
                let known: Vec<DetectedObject> =
                    objects.iter().chain(self.tracker.held()).cloned().collect();
                match placeable_free_space(
                    ws,
                    &objects,
                    &known,
                    self.settings.free_space_margin_m,
                    &self.skills,
                ) {
                    Some(free) => WorkspaceReply::FreeSpace {
                        area_m2: free.area_m2,
                        center: free.center,
                    },
                    None => WorkspaceReply::FreeSpace {
                        area_m2: 0.0,
                        center: ws.center(),
                    },
                }
            }
            WorkspaceRequest::GetWorkspacePoint {
                workspace_id,
                point,
            } => WorkspaceReply::Coordinate {
                coordinate: self.workspace(workspace_id)?.point(*point),
            },
            WorkspaceRequest::GetLabels => WorkspaceReply::Labels {
                labels: self.labels.labels().to_vec(),
                builtin: self.labels.builtin(),
            },
            WorkspaceRequest::AddLabel { label } => {
                let added = self
                    .labels
                    .add(label)
                    .map_err(|e| WorkspaceError::InvalidRequest {
                        reason: e.to_string(),
                    })?;
                WorkspaceReply::LabelAdded {
                    label: added.label,
                    already_known: added.already_known,
                }
            }
            WorkspaceRequest::GetObservationPose { workspace_id } => {
                WorkspaceReply::ObservationPose {
                    pose: self.workspace(workspace_id)?.observation_pose,
                }
            }
            WorkspaceRequest::ListWorkspaces => WorkspaceReply::Workspaces {
                workspaces: self.workspaces.clone(),
            },
            WorkspaceRequest::ObjectPicked { object_id } => {
                let object = self.tracker.pick(object_id).map_err(unknown_object)?;
                WorkspaceReply::Object {
                    object: Some(object.clone()),
                }
            }
            WorkspaceRequest::LabelObject { object_id, label } => {
                // The object first: an unknown id adds no label.
                self.tracker
                    .get(object_id)
                    .ok_or_else(|| unknown_object(self.tracker.unknown(object_id)))?;
                let added = self.labels.add(label).map_err(|e| match e {
                    crate::labels::LabelError::Empty => WorkspaceError::InvalidRequest {
                        reason: "label must be a non-empty string".into(),
                    },
                    other => WorkspaceError::InvalidRequest {
                        reason: other.to_string().replace("object_name", "label"),
                    },
                })?;
                let (object, previous, detected_as) = self
                    .tracker
                    .name(object_id, &added.label)
                    .map_err(unknown_object)?;
                WorkspaceReply::ObjectLabelled {
                    object: object.clone(),
                    previous,
                    detected_as,
                    label_added: !added.already_known,
                }
            }
            WorkspaceRequest::ObjectPlaced { object_id, at } => {
                let own = self
                    .tracker
                    .get(object_id)
                    .map(|o| o.workspace_id.clone())
                    .unwrap_or_default();
                let ws = self.place_workspace(&own, *at);
                let object = self
                    .tracker
                    .place(object_id, *at, &ws)
                    .map_err(unknown_object)?;
                WorkspaceReply::Object {
                    object: Some(object.clone()),
                }
            }
        })
    }
}

fn unknown_object(e: crate::tracker::UnknownObject) -> WorkspaceError {
    WorkspaceError::InvalidRequest {
        reason: e.to_string(),
    }
}
