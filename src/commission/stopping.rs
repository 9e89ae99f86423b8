//! The stopping step of `robotd commission`: how long the real arm takes to stand still after
//! an e-stop, and how far its tool travels meanwhile, at commissioning's capped speed.
//!
//! As `robotd bench safety --stops` does against the fakes (whose simulated joints it reads
//! directly), the arm swings the tool across the workspace 10 cm above the sheet; when the
//! tool should have covered about 35 % of the way at the capped speed, the step publishes an
//! e-stop on `safety/estop`, the path of every entry point — on a clock, since a Ned2 reports
//! only at the ends of its segments. On a real arm there is no ground truth to read: the
//! figures come from the arm's own reports on `arm/state` (the tool pose the driver computes
//! from the joints it reads), so the time to standstill is known to one report period, and
//! the travel is counted from the last report before the e-stop — an upper bound (on a Ned2,
//! from the end of the segment before the one under way). Standstill is the last report whose
//! tool position changed by more than 0.05 mm; the arm counts as still once it reports its
//! motion over (`moving` false on `arm/state`) and 600 ms have passed without such a change
//! (a WidowX's joints can still coast after its driver stopped commanding them).
//!
//! The e-stop this step engaged is released by it (through the motion policy's
//! `safety/release`, origin `cli`) once the arm stands still — but only when the e-stop is
//! still this step's own: its reason names this run, an e-stop engaged by anyone else before
//! or during the step adds its reason to it, and the release asks the policy to release only
//! the run's own reason (`only_if_reason`). One engaged by anyone else stays engaged, and the
//! step fails saying so. The arm ends at rest where it stopped.

use super::session::Session;
use anyhow::{bail, Result};
use robotd_config::Config;
use robotd_protocol::geometry::Pose;
use serde::Serialize;
use std::time::{Duration, Instant};

/// The reason this run's e-stops carry, unique to the run, so that it releases only its own
/// (another `robotd commission` or an operator's e-stop carries another).
fn own_reason() -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or_default();
    format!(
        "robotd commission (process {}, run {nanos:09}): stopping distance",
        std::process::id()
    )
}

/// Stops measured.
pub const TRIALS: usize = 3;

/// Once the arm reports its motion over, how long its tool must not move to count as still.
const QUIET: Duration = Duration::from_millis(600);

/// What the stopping step measured.
#[derive(Debug, Clone, Serialize)]
pub struct StoppingReport {
    /// Stops measured.
    pub trials: usize,
    /// The tool's mean speed from the swing's first report of motion to the e-stop, m/s
    /// (median).
    pub mean_speed_m_s: f64,
    /// E-stop → standstill, ms (median), to one report period.
    pub time_ms_p50: f64,
    /// Worst stopping time, ms.
    pub time_ms_max: f64,
    /// Tool travel after the e-stop, mm (median).
    pub distance_mm_p50: f64,
    /// Worst tool travel, mm.
    pub distance_mm_max: f64,
    /// The speed cap the swings ran at, m/s.
    pub speed_cap_m_s: f64,
    /// Each stop's time to standstill, ms, in the order run.
    pub times_ms: Vec<f64>,
}

fn position(pose: &Pose) -> [f64; 3] {
    [pose.x_m, pose.y_m, pose.z_m]
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    a.iter()
        .zip(&b)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt()
}

/// Runs the step on `session`: [`TRIALS`] stops.
pub async fn run(
    session: &mut Session,
    config: &Config,
    workspace_id: Option<&str>,
    speed_cap_m_s: f64,
) -> Result<StoppingReport> {
    let workspaces = config.robot.workspaces();
    let Some(spec) = (match workspace_id {
        Some(id) => workspaces.iter().find(|w| w.id == id),
        None => workspaces.first(),
    }) else {
        bail!("no such workspace configured: the stopping step swings across the workspace");
    };
    if let Some(reason) = session.estop_reason().await? {
        bail!("the emergency stop is engaged ({reason}): release it first, nothing moved");
    }
    let [x, _] = spec.centre();
    let (left, right) = (spec.upper_left[1], spec.lower_right[1]);
    let down = |y: f64| Pose::new(x, y, 0.10, 0.0, std::f64::consts::FRAC_PI_2, 0.0);
    let ends = [down(left), down(right)];
    session
        .move_to(ends[0])
        .await
        .map_err(|e| anyhow::anyhow!("moving to the start of the swing {}: {e}", ends[0]))?;
    let (mut times, mut distances, mut speeds) = (Vec::new(), Vec::new(), Vec::new());
    let reason = own_reason();
    for trial in 0..TRIALS {
        let target = ends[(trial + 1) % 2];
        let from = position(&session.state(Duration::from_secs(5)).await?.tool_pose);
        let goal = position(&target);
        let motion = session.spawn_move(target)?;
        let deadline = Instant::now() + session.motion_timeout;
        // The e-stop goes out on a clock, not on a report: a Ned2 reports only at the ends of
        // its segments, and a stop sent right then would never catch one under way.
        let trigger = Duration::from_secs_f64(0.35 * distance(goal, from) / speed_cap_m_s);
        let mut started: Option<Instant> = None;
        let mut at_stop = from;
        loop {
            if Instant::now() > deadline || motion.is_finished() {
                let reason = match motion.await {
                    Ok(Err(e)) => e,
                    _ => "the swing ended before the e-stop went out".into(),
                };
                bail!("trial {trial}: {reason}");
            }
            if started.is_some_and(|t| t.elapsed() >= trigger) {
                break;
            }
            let Some(state) = session.next_state(Duration::from_millis(5)).await? else {
                continue;
            };
            let p = position(&state.tool_pose);
            if started.is_none() && distance(p, from) > 5e-4 {
                started = Some(Instant::now());
            }
            at_stop = p;
        }
        let sent = Instant::now();
        session.engage_estop(&reason)?;
        let speed = started.map_or(f64::NAN, |t| {
            distance(at_stop, from) / sent.duration_since(t).as_secs_f64()
        });
        let (mut last, mut last_change) = (at_stop, sent);
        // Standstill waits for the arm's own word that its motion is over (`moving` false on
        // `arm/state`): a robot that starts a segment late (a Ned2 plans before it moves)
        // reports nothing for longer than the quiet window while that segment is still to run.
        let mut over = false;
        while !over || last_change.elapsed() < QUIET {
            if sent.elapsed() > Duration::from_secs(10) {
                bail!(
                    "trial {trial}: the arm still reported motion 10 s after the e-stop; it \
                     stays e-stopped — check the arm before releasing"
                );
            }
            if let Some(state) = session.next_state(Duration::from_millis(100)).await? {
                over = !state.moving;
                let p = position(&state.tool_pose);
                if distance(p, last) > 5e-5 {
                    last = p;
                    last_change = Instant::now();
                }
            }
        }
        times.push((last_change - sent).as_secs_f64() * 1e3);
        distances.push(distance(last, at_stop) * 1e3);
        speeds.push(speed);
        let _ = motion.await;
        match session.estop_reason().await? {
            Some(now) if now == reason => {
                session
                    .release_estop("robotd commission: the stopping trial ended", &reason)
                    .await?
            }
            Some(other) => bail!(
                "the e-stop was engaged by someone else during the stopping step ({other}); it \
                 stays engaged"
            ),
            None => {}
        }
        if trial + 1 < TRIALS {
            // From the end the stopped swing was heading away from.
            session
                .move_to(ends[(trial + 1) % 2])
                .await
                .map_err(|e| anyhow::anyhow!("trial {trial}: finishing the swing: {e}"))?;
        }
    }
    let median = |values: &mut Vec<f64>| -> f64 {
        values.sort_by(f64::total_cmp);
        values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let max = |values: &[f64]| values.iter().copied().fold(0.0, f64::max);
    let times_ms = times.clone();
    Ok(StoppingReport {
        times_ms,
        trials: TRIALS,
        mean_speed_m_s: median(&mut speeds),
        time_ms_max: max(&times),
        time_ms_p50: median(&mut times),
        distance_mm_max: max(&distances),
        distance_mm_p50: median(&mut distances),
        speed_cap_m_s,
    })
}
