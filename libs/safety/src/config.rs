//! `[safety]`: the limits every motion must keep, who needs a human's approval, the audit log.

use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};

/// `[safety]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SafetyConfig {
    /// `autonomous`: motions run when they pass the limits. `supervised`: every motion also
    /// waits for a human's approval.
    #[serde(default)]
    pub mode: SafetyMode,
    /// How far the tool centre may leave the workspaces' rectangles, metres (0 … 0.2).
    #[serde(default = "SafetyConfig::fence_margin_m")]
    pub fence_margin_m: f64,
    /// Lowest height of the tool centre and of every lifted link, metres: the table top
    /// (−0.1 … 0.2).
    #[serde(default)]
    pub floor_z_m: f64,
    /// Highest height of the tool centre and of every link, metres (0.05 … 1.5).
    #[serde(default = "SafetyConfig::ceiling_z_m")]
    pub ceiling_z_m: f64,
    /// Farthest the tool centre may be from the base axis, metres (0.1 … 1.5); 0 = the
    /// robot model's own reach.
    #[serde(default)]
    pub max_reach_m: f64,
    /// Boxes neither the tool centre nor any link may enter (a fixture, a person's side of
    /// the table).
    #[serde(default)]
    pub keep_out: Vec<KeepOutBox>,
    /// Joint targets must stay this far inside each joint's limits, radians (0 … 0.5).
    #[serde(default = "SafetyConfig::joint_margin_rad")]
    pub joint_margin_rad: f64,
    /// Fastest tool-centre speed, m/s (0.01 … 2), for people and scripts.
    #[serde(default = "SafetyConfig::max_tcp_speed_m_s")]
    pub max_tcp_speed_m_s: f64,
    /// Fastest tool-centre speed for motions an LLM asked for (MCP, the agent, unnamed bus
    /// clients), m/s (0.01 … 2).
    #[serde(default = "SafetyConfig::llm_max_tcp_speed_m_s")]
    pub llm_max_tcp_speed_m_s: f64,
    /// Highest tool-centre acceleration, m/s² (0.1 … 20).
    #[serde(default = "SafetyConfig::max_tcp_acceleration_m_s2")]
    pub max_tcp_acceleration_m_s2: f64,
    /// Highest tool-centre acceleration for LLM motions, m/s² (0.1 … 20).
    #[serde(default = "SafetyConfig::llm_max_tcp_acceleration_m_s2")]
    pub llm_max_tcp_acceleration_m_s2: f64,
    /// Most arm and gripper motions per minute from one origin kind, all its sessions
    /// together; 0 = no limit (0 … 100000).
    #[serde(default = "SafetyConfig::motions_per_minute")]
    pub motions_per_minute: u32,
    /// Most motions per minute for LLM origins; 0 = no limit (0 … 100000).
    #[serde(default = "SafetyConfig::llm_motions_per_minute")]
    pub llm_motions_per_minute: u32,
    /// Tools that wait for a human's approval before anything moves (e.g. `push_object`);
    /// in `supervised` mode every motion does.
    #[serde(default)]
    pub approval_tools: Vec<String>,
    /// How long a request waits for approval before it is refused, seconds (1 … 3600).
    #[serde(default = "SafetyConfig::approval_timeout_s")]
    pub approval_timeout_s: u64,
    /// The audit log of motion requests.
    #[serde(default)]
    pub audit: AuditSection,
}

/// Whether motions need a human's approval.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SafetyMode {
    /// Motions that pass the limits run (tools in `approval_tools` still wait).
    #[default]
    Autonomous,
    /// Every motion waits for a human's approval.
    Supervised,
}

/// A box the tool centre must never enter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeepOutBox {
    /// What it protects, used in refusals.
    pub name: String,
    /// Lowest corner `[x, y, z]`, metres, base frame.
    pub min: [f64; 3],
    /// Highest corner `[x, y, z]`, metres.
    pub max: [f64; 3],
}

/// `[safety.audit]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AuditSection {
    /// Whether motions are recorded.
    #[serde(default = "AuditSection::enabled")]
    pub enabled: bool,
    /// The active audit file; rotated files get `.1`, `.2`, …. Empty: `audit.jsonl` in
    /// `[telemetry] log_dir`.
    #[serde(default = "AuditSection::path")]
    pub path: String,
    /// Rotate when the active file would exceed this, bytes (4096 … 10 GiB).
    #[serde(default = "AuditSection::max_file_bytes")]
    pub max_file_bytes: u64,
    /// Rotated files kept (1 … 1000).
    #[serde(default = "AuditSection::keep_files")]
    pub keep_files: u32,
    /// Records waiting to be written; when full, motions are refused (16 … 1000000).
    #[serde(default = "AuditSection::queue")]
    pub queue: usize,
    /// The key file of the log's HMAC chain (64 hex digits), created with mode 0600 on the
    /// first start when missing. Empty: `audit.key` beside the audit file.
    #[serde(default = "AuditSection::path")]
    pub key_file: String,
}

impl Default for AuditSection {
    fn default() -> Self {
        Self {
            enabled: Self::enabled(),
            path: Self::path(),
            max_file_bytes: Self::max_file_bytes(),
            keep_files: Self::keep_files(),
            queue: Self::queue(),
            key_file: Self::path(),
        }
    }
}

impl AuditSection {
    fn enabled() -> bool {
        true
    }
    fn path() -> String {
        String::new()
    }
    fn max_file_bytes() -> u64 {
        64 * 1024 * 1024
    }
    fn keep_files() -> u32 {
        10
    }
    fn queue() -> usize {
        4096
    }
}

impl Default for SafetyConfig {
    fn default() -> Self {
        Self {
            mode: SafetyMode::default(),
            fence_margin_m: Self::fence_margin_m(),
            floor_z_m: 0.0,
            ceiling_z_m: Self::ceiling_z_m(),
            max_reach_m: 0.0,
            keep_out: Vec::new(),
            joint_margin_rad: Self::joint_margin_rad(),
            max_tcp_speed_m_s: Self::max_tcp_speed_m_s(),
            llm_max_tcp_speed_m_s: Self::llm_max_tcp_speed_m_s(),
            max_tcp_acceleration_m_s2: Self::max_tcp_acceleration_m_s2(),
            llm_max_tcp_acceleration_m_s2: Self::llm_max_tcp_acceleration_m_s2(),
            motions_per_minute: Self::motions_per_minute(),
            llm_motions_per_minute: Self::llm_motions_per_minute(),
            approval_tools: Vec::new(),
            approval_timeout_s: Self::approval_timeout_s(),
            audit: AuditSection::default(),
        }
    }
}

impl SafetyConfig {
    fn fence_margin_m() -> f64 {
        0.03
    }
    fn ceiling_z_m() -> f64 {
        // Above the Ned2's elbow at its highest observation pose (0.450 m at `gazebo_1`).
        0.55
    }
    fn joint_margin_rad() -> f64 {
        0.01
    }
    fn max_tcp_speed_m_s() -> f64 {
        1.0
    }
    fn llm_max_tcp_speed_m_s() -> f64 {
        0.5
    }
    fn max_tcp_acceleration_m_s2() -> f64 {
        10.0
    }
    fn llm_max_tcp_acceleration_m_s2() -> f64 {
        5.0
    }
    fn motions_per_minute() -> u32 {
        600
    }
    fn llm_motions_per_minute() -> u32 {
        240
    }
    fn approval_timeout_s() -> u64 {
        120
    }
}

/// The tool names a `[safety] approval_tools` entry may name.
pub const MOTION_TOOLS: [&str; 8] = [
    "pick_place_object",
    "pick_object",
    "place_object",
    "push_object",
    "move2observation_pose",
    "move2by",
    "calibrate",
    "clear_collision_detected",
];

impl Section for SafetyConfig {
    fn check(&self, checks: &mut Checks) {
        checks.range_f64("fence_margin_m", self.fence_margin_m, 0.0..=0.2, " m");
        checks.range_f64("floor_z_m", self.floor_z_m, -0.1..=0.2, " m");
        checks.range_f64("ceiling_z_m", self.ceiling_z_m, 0.05..=1.5, " m");
        if self.ceiling_z_m <= self.floor_z_m {
            checks.problem(
                "ceiling_z_m",
                format!(
                    "must be above floor_z_m ({} m), got {} m",
                    self.floor_z_m, self.ceiling_z_m
                ),
            );
        }
        if self.max_reach_m != 0.0 {
            checks.range_f64("max_reach_m", self.max_reach_m, 0.1..=1.5, " m (or 0)");
        }
        for (i, keep_out) in self.keep_out.iter().enumerate() {
            let key = format!("keep_out[{i}]");
            if keep_out.name.trim().is_empty() {
                checks.problem(&format!("{key}.name"), "must not be empty");
            }
            let finite = keep_out
                .min
                .iter()
                .chain(&keep_out.max)
                .all(|v| v.is_finite());
            if !finite || (0..3).any(|a| keep_out.min[a] >= keep_out.max[a]) {
                checks.problem(
                    &key,
                    "min must be finite and below max on every axis ([x, y, z] metres)",
                );
            }
        }
        checks.range_f64("joint_margin_rad", self.joint_margin_rad, 0.0..=0.5, " rad");
        for (key, value) in [
            ("max_tcp_speed_m_s", self.max_tcp_speed_m_s),
            ("llm_max_tcp_speed_m_s", self.llm_max_tcp_speed_m_s),
        ] {
            checks.range_f64(key, value, 0.01..=2.0, " m/s");
        }
        for (key, value) in [
            ("max_tcp_acceleration_m_s2", self.max_tcp_acceleration_m_s2),
            (
                "llm_max_tcp_acceleration_m_s2",
                self.llm_max_tcp_acceleration_m_s2,
            ),
        ] {
            checks.range_f64(key, value, 0.1..=20.0, " m/s²");
        }
        checks.range_u64(
            "motions_per_minute",
            self.motions_per_minute.into(),
            0..=100_000,
            "",
        );
        checks.range_u64(
            "llm_motions_per_minute",
            self.llm_motions_per_minute.into(),
            0..=100_000,
            "",
        );
        for (i, tool) in self.approval_tools.iter().enumerate() {
            if !MOTION_TOOLS.contains(&tool.as_str()) {
                checks.problem(
                    &format!("approval_tools[{i}]"),
                    format!(
                        "'{tool}' is not a motion tool; one of: {}",
                        MOTION_TOOLS.join(", ")
                    ),
                );
            }
        }
        checks.range_u64(
            "approval_timeout_s",
            self.approval_timeout_s,
            1..=3600,
            " s",
        );
        let audit = &self.audit;
        checks.range_u64(
            "audit.max_file_bytes",
            audit.max_file_bytes,
            4096..=10 * 1024 * 1024 * 1024,
            " bytes",
        );
        checks.range_u64("audit.keep_files", audit.keep_files.into(), 1..=1000, "");
        checks.range_u64("audit.queue", audit.queue as u64, 16..=1_000_000, "");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn problems(config: &SafetyConfig) -> Vec<(String, String)> {
        let mut out = Vec::new();
        config.check(&mut Checks::new("safety", &mut out));
        out
    }

    #[test]
    fn the_defaults_pass_and_bad_values_name_their_key() {
        assert_eq!(problems(&SafetyConfig::default()), Vec::new());
        let bad = SafetyConfig {
            floor_z_m: 0.3,
            ceiling_z_m: 0.2,
            llm_max_tcp_speed_m_s: f64::NAN,
            keep_out: vec![KeepOutBox {
                name: " ".into(),
                min: [0.3, 0.0, 0.0],
                max: [0.2, 0.1, 0.1],
            }],
            approval_tools: vec!["get_detected_objects".into()],
            audit: AuditSection {
                queue: 1,
                ..AuditSection::default()
            },
            ..SafetyConfig::default()
        };
        let keys: Vec<String> = problems(&bad).into_iter().map(|(k, _)| k).collect();
        assert_eq!(
            keys,
            [
                "safety.floor_z_m",
                "safety.ceiling_z_m",
                "safety.keep_out[0].name",
                "safety.keep_out[0]",
                "safety.llm_max_tcp_speed_m_s",
                "safety.approval_tools[0]",
                "safety.audit.queue",
            ]
        );
        let approval = problems(&bad)
            .into_iter()
            .find(|(k, _)| k == "safety.approval_tools[0]")
            .unwrap()
            .1;
        assert!(
            approval.starts_with(
                "'get_detected_objects' is not a motion tool; one of: pick_place_object"
            ),
            "{approval}"
        );
    }
}
