//! What the sheet tests share: the Ned2's workspace as configured, where each sheet design
//! lies on the table, and a render scene holding just that sheet.
#![allow(dead_code)]

use robotd_protocol::geometry::RobotModel;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_render::sheet_art::{sheet_art, SheetDesign, SheetPlacement};
use robotd_render::RenderScene;

pub fn workspace() -> WorkspaceInfo {
    robotd_protocol::workspace::builtin_workspaces(RobotModel::Ned2)[0].to_info(RobotModel::Ned2)
}

pub fn placement(design: SheetDesign) -> SheetPlacement {
    SheetPlacement {
        x_min: 0.163,
        x_max: 0.337,
        y_min: -0.087,
        y_max: 0.087,
        marker_radius_m: if design == SheetDesign::Classic {
            0.0105
        } else {
            0.010
        },
    }
}

pub fn sheet_scene(design: SheetDesign) -> RenderScene {
    let mut scene = RenderScene {
        background: [118, 96, 72],
        table_z_m: 0.0,
        quads: Vec::new(),
        discs: Vec::new(),
        solids: Vec::new(),
    };
    sheet_art(design, &placement(design), &mut scene);
    scene
}
