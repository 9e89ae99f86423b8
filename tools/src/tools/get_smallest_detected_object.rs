//! `get_smallest_detected_object`: the smallest object the camera sees, by footprint area.

use super::get_largest_detected_object::extreme_object;
use super::{NoArguments, Reply, Tool};
use crate::view::Object;
use crate::{CallHooks, Registry};

pub(crate) struct GetSmallestDetectedObject;

impl Tool for GetSmallestDetectedObject {
    const NAME: &'static str = "get_smallest_detected_object";
    const DESCRIPTION: &'static str = "The smallest object the camera sees (by footprint area).";
    type Args = NoArguments;
    type Data = Object;

    async fn run(
        registry: &Registry,
        _: NoArguments,
        hooks: CallHooks,
    ) -> Result<Reply<Object>, String> {
        extreme_object(registry, &hooks, false).await
    }
}
