//! The tools (the Python server's 20, robotd's e-stop pair, and robotd's camera picture and
//! object naming), one module each, and the table that dispatches calls to them.
//!
//! A tool is one unit: its module defines a type implementing [`Tool`] that ties together
//! the tool's name, description, argument struct (whose derived schema is the `inputSchema`
//! and whose derived `Deserialize` reads the call's arguments through [`crate::args`]), data
//! type (whose derived schema is in the `outputSchema`) and handler. [`TOOLS`] lists them in
//! the contract's order; a call finds its tool there by name.
//!
//! Adding a tool: write `tools/<name>.rs` with its `Tool` impl, then add `mod <name>;` and
//! one `Entry::of::<…>()` line to [`TOOLS`]. The tests at the bottom check every entry.

use crate::args::{from_args, validation_text, FieldError};
use crate::{CallHooks, Registry, ToolOutput};
use robotd_protocol::Point2;
use schemars::JsonSchema;
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::{Map, Value};
use std::future::Future;
use std::pin::Pin;

mod add_object_name2object_labels;
mod calibrate;
mod clear_collision_detected;
mod emergency_stop;
mod get_camera_image;
mod get_detected_object;
mod get_detected_objects;
mod get_detected_objects_sorted;
mod get_largest_detected_object;
mod get_largest_free_space_with_center;
mod get_object_labels_as_string;
mod get_smallest_detected_object;
mod get_system_status;
mod get_workspace_coordinate_from_point;
mod label_object;
mod move2by;
mod move2observation_pose;
mod pick_object;
mod pick_place_object;
mod place_object;
mod push_object;
mod release_emergency_stop;
mod set_user_task;
mod speak;

/// Every tool, in the order of the contract (and of `tools/list`), robotd's own last (the
/// e-stop pair, then `get_camera_image` and `label_object`).
pub(crate) static TOOLS: &[Entry] = &[
    Entry::of::<pick_place_object::PickPlaceObject>(),
    Entry::of::<pick_object::PickObject>(),
    Entry::of::<place_object::PlaceObject>(),
    Entry::of::<push_object::PushObject>(),
    Entry::of::<move2by::Move2By>(),
    Entry::of::<move2observation_pose::Move2ObservationPose>(),
    Entry::of::<clear_collision_detected::ClearCollisionDetected>(),
    Entry::of::<calibrate::Calibrate>(),
    Entry::of::<get_detected_objects::GetDetectedObjects>(),
    Entry::of::<get_detected_object::GetDetectedObject>(),
    Entry::of::<get_largest_detected_object::GetLargestDetectedObject>(),
    Entry::of::<get_smallest_detected_object::GetSmallestDetectedObject>(),
    Entry::of::<get_detected_objects_sorted::GetDetectedObjectsSorted>(),
    Entry::of::<get_largest_free_space_with_center::GetLargestFreeSpaceWithCenter>(),
    Entry::of::<get_workspace_coordinate_from_point::GetWorkspaceCoordinateFromPoint>(),
    Entry::of::<get_object_labels_as_string::GetObjectLabelsAsString>(),
    Entry::of::<add_object_name2object_labels::AddObjectName2ObjectLabels>(),
    Entry::of::<get_system_status::GetSystemStatus>(),
    Entry::of::<speak::Speak>(),
    Entry::of::<set_user_task::SetUserTask>(),
    Entry::of::<emergency_stop::EmergencyStopTool>(),
    Entry::of::<release_emergency_stop::ReleaseEmergencyStop>(),
    Entry::of::<get_camera_image::GetCameraImage>(),
    Entry::of::<label_object::LabelObject>(),
];

/// The tool called `name`, if there is one.
pub(crate) fn find(name: &str) -> Option<&'static Entry> {
    TOOLS.iter().find(|t| t.name == name)
}

/// The arguments of a tool that takes none.
#[derive(Debug, serde::Deserialize, JsonSchema)]
pub(crate) struct NoArguments {}

/// The data of a tool with nothing to report but success: `{}`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Done {}

/// What a tool answers when it did its job: the contract's `✓ …` text and, usually, data.
pub(crate) struct Reply<D> {
    text: String,
    data: Option<D>,
    images: Vec<crate::ToolImage>,
}

impl<D> Reply<D> {
    /// A reply with data.
    pub(crate) fn new(text: impl Into<String>, data: D) -> Self {
        Self {
            text: text.into(),
            data: Some(data),
            images: Vec::new(),
        }
    }

    /// The reply with `image` after its text.
    pub(crate) fn with_image(mut self, image: crate::ToolImage) -> Self {
        self.images.push(image);
        self
    }

    /// A reply whose data is `null` (e.g. "no object found").
    pub(crate) fn without_data(text: impl Into<String>) -> Self {
        Self {
            text: text.into(),
            data: None,
            images: Vec::new(),
        }
    }
}

/// One tool. Failures are the contract's `❌ …` text (`Err`); they are ordinary replies to
/// the client, with `data: null`.
pub(crate) trait Tool {
    /// The tool's name, e.g. `pick_place_object`.
    const NAME: &'static str;
    /// What it does and how to call it, for people and LLMs.
    const DESCRIPTION: &'static str;
    /// Whether it moves the arm (long-running, cancellable, reports progress).
    const MOVES_ARM: bool = false;
    /// Its arguments: the `inputSchema`, and what [`from_args`] reads a call into.
    type Args: DeserializeOwned + JsonSchema + Send + std::fmt::Debug + 'static;
    /// Its `structuredContent.data` on success.
    type Data: Serialize + JsonSchema + 'static;

    /// Does the work and words the outcome.
    fn run(
        registry: &Registry,
        args: Self::Args,
        hooks: CallHooks,
    ) -> impl Future<Output = Result<Reply<Self::Data>, String>> + Send;

    /// Reads a call's arguments: strictly by default, every problem refused (see
    /// [`crate::args`]). A tool that must act whatever it is sent (`emergency_stop`) reads
    /// what it can and keeps the problems for its reply.
    fn read(arguments: &Map<String, Value>) -> Result<Self::Args, Vec<FieldError>> {
        from_args::<Self::Args>(arguments)
    }

    /// The reply to arguments with problems.
    fn invalid(errors: &[FieldError]) -> String {
        validation_text(Self::NAME, errors)
    }
}

/// Reads arguments and gives the argument struct's `Debug`, or the problems.
#[cfg(test)]
type ParseForTest = fn(&Map<String, Value>) -> Result<String, Vec<FieldError>>;

type CallFuture<'a> = Pin<Box<dyn Future<Output = ToolOutput> + Send + 'a>>;

/// A tool in the dispatch table: its [`Tool`] impl, type-erased.
pub(crate) struct Entry {
    pub(crate) name: &'static str,
    pub(crate) description: &'static str,
    pub(crate) moves_arm: bool,
    pub(crate) input_schema: fn() -> Map<String, Value>,
    pub(crate) output_schema: fn() -> Map<String, Value>,
    /// The argument names the deserializer reads (for the tests).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fields: fn() -> &'static [&'static str],
    /// Runs a call; the arguments' strings over their `maxLength` come with it
    /// ([`crate::limits::too_long`]).
    pub(crate) call: for<'a> fn(
        &'a Registry,
        &'a Map<String, Value>,
        CallHooks,
        Vec<FieldError>,
    ) -> CallFuture<'a>,
    /// Reads arguments as a call does, giving the argument struct's `Debug` (for the tests).
    #[cfg(test)]
    pub(crate) parse: ParseForTest,
}

impl Entry {
    /// The table entry of tool `T`.
    pub(crate) const fn of<T: Tool>() -> Self {
        Self {
            name: T::NAME,
            description: T::DESCRIPTION,
            moves_arm: T::MOVES_ARM,
            input_schema: crate::schema::input_schema::<T::Args>,
            output_schema: crate::schema::output_schema::<T::Data>,
            fields: crate::args::fields_of::<T::Args>,
            call: call::<T>,
            #[cfg(test)]
            parse: |args| T::read(args).map(|a| format!("{a:?}")),
        }
    }
}

/// Reads the arguments of tool `T`, runs it and turns its outcome into a [`ToolOutput`].
/// `too_long` (strings over their limit) are listed with the other problems of the arguments.
fn call<'a, T: Tool>(
    registry: &'a Registry,
    arguments: &'a Map<String, Value>,
    hooks: CallHooks,
    too_long: Vec<FieldError>,
) -> CallFuture<'a> {
    let args = match (T::read(arguments), too_long.is_empty()) {
        (args, true) => args,
        (Ok(_), false) => Err(too_long),
        (Err(problems), false) => Err(crate::limits::merge(
            problems,
            too_long,
            crate::args::fields_of::<T::Args>(),
        )),
    };
    Box::pin(async move {
        let args = match args {
            Ok(args) => args,
            Err(errors) => return ToolOutput::failed(T::invalid(&errors)),
        };
        match T::run(registry, args, hooks).await {
            Ok(Reply {
                text,
                data: None,
                images,
            }) => ToolOutput::ok(text, Value::Null, images),
            Ok(Reply {
                text,
                data: Some(data),
                images,
            }) => match serde_json::to_value(&data) {
                Ok(data) => ToolOutput::ok(text, data, images),
                Err(error) => ToolOutput::failed(format!(
                    "❌ Error in {}: the reply data could not be encoded: {error}",
                    T::NAME
                )),
            },
            Err(text) => ToolOutput::failed(text),
        }
    })
}

/// `[x.xxx, y.yyy]`, the contract's coordinate format.
pub(crate) fn pt(p: Point2) -> String {
    format!("[{:.3}, {:.3}]", p.x_m, p.y_m)
}

/// `[x, y]` for the data.
pub(crate) fn xy(p: Point2) -> [f64; 2] {
    [p.x_m, p.y_m]
}

/// Indented JSON, as the contract prints objects.
pub(crate) fn pretty<T: Serialize>(value: &T) -> String {
    serde_json::to_string_pretty(value).unwrap_or_else(|e| format!("<unprintable: {e}>"))
}

/// The one-line validation text of `speak` and `add_object_name2object_labels` when their
/// only argument is the problem: `❌ Validation Error: <field> must be a non-empty string`
/// (a text over its limit gets the usual list, which says so).
pub(crate) fn only_field_invalid(tool: &str, field: &str, errors: &[FieldError]) -> String {
    let too_long = |e: &FieldError| e.message.starts_with(crate::limits::STRING_TOO_LONG);
    if errors.iter().all(|e| e.field == field && !too_long(e)) {
        format!("❌ Validation Error: {field} must be a non-empty string")
    } else {
        validation_text(tool, errors)
    }
}

#[cfg(test)]
mod tests;
