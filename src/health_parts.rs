//! The parts of `/health` that `robotd serve` adds to the supervisor's report: what the camera
//! sees, detectors outside robotd, and motion safety.

/// `/health`'s `workspace_view`: whether the camera sees the workspace from the observation
/// pose (`null` before the first such view, or when the built-in detector does not run).
pub fn workspace_view_report(view: Option<&robotd_perception::WorkspaceView>) -> serde_json::Value {
    let Some(view) = view else {
        return serde_json::Value::Null;
    };
    let age_s =
        robotd_protocol::envelope::unix_now_ns().saturating_sub(view.taken_unix_ns) as f64 / 1e9;
    serde_json::json!({
        "workspace_id": view.workspace_id,
        "visible": view.visible,
        "reason": view.reason,
        "age_s": (age_s * 10.0).round() / 10.0,
    })
}

/// The `external_detections` part of `/health`: pixel detections from detectors on the bus.
pub fn external_detections_report(
    stats: &robotd_perception::external_detections::ExternalStats,
) -> serde_json::Value {
    use std::sync::atomic::Ordering;
    serde_json::json!({
        "placed": stats.placed.load(Ordering::Relaxed),
        "refused": stats.refused.load(Ordering::Relaxed),
        "last_refusal": stats.last_refusal.lock().ok().and_then(|r| r.clone()),
    })
}

/// The safety part of `/health`: e-stop, mode, approvals waiting.
pub fn safety_report(safety: &robotd_safety::Safety) -> serde_json::Value {
    let estop = safety.estop();
    serde_json::json!({
        "estop": {"engaged": estop.is_some(), "reason": estop},
        "mode": safety.config().mode,
        "approvals_waiting": safety.approvals().pending().len(),
        "audit_log": safety.audit().path(),
    })
}
