//! The flight figures a control researcher asks for first (issue #54), flown by the `base`
//! agent through the server's own controller, in lockstep, in still air:
//!
//! * **step**: from a hover at (0, 0, -1), a GotoXyz 1 m ahead then a Hover there: the
//!   overshoot past the target along the step (metres; the target is 1 m, so also the
//!   fraction) and the time after which the UAV stays within 0.1 m of it;
//! * **hold**: a 60 s Hover at the spawn point: the largest distance from it and the largest
//!   heading change;
//! * **square**: four GotoXyz around a 2 m square at 1 m altitude: the largest distance of the
//!   path from the square's sides.
//!
//! The positions are the robot's position readings (10 Hz by default), so times are to the
//! reading. `usar-bench --flight` prints them for both robots; the workspace's `tests/`
//! crate holds them to the targets of docs/quadrotor.md.

use tokio_util::sync::CancellationToken;

use crate::geometry::Coordinates;
use crate::mission::Mission;
use crate::record::TrajectoryPoint;
use crate::settings::{Lockstep, Pictures, RunSettings, Start};
use crate::stats::IterationStatus;

/// The figures of one robot class.
#[derive(Debug, Clone, PartialEq)]
pub struct Figures {
    /// The robot class flown.
    pub robot: String,
    /// Metres past the target of the 1 m step (0 when it never passes it).
    pub overshoot: f64,
    /// Seconds from the step until the UAV stays within 0.1 m of the target.
    pub settling: f64,
    /// Metres: the farthest the UAV strayed from its point in a 60 s hover.
    pub hold: f64,
    /// Radians: the largest heading change in that hover.
    pub hold_yaw: f64,
    /// Metres: the farthest the path of the 2 m square strayed from its sides.
    pub square: f64,
}

/// The targets of issue #54 (docs/quadrotor.md): overshoot at most 5 % of the 1 m step,
/// settled within 0.1 m in at most 3 s, hover within 0.1 m and 0.05 rad, the square within
/// 0.3 m of its lines.
pub const TARGETS: Figures = Figures {
    robot: String::new(),
    overshoot: 0.05,
    settling: 3.0,
    hold: 0.1,
    hold_yaw: 0.05,
    square: 0.3,
};

impl Figures {
    /// The figures that miss their target, named (empty when all meet it).
    pub fn misses(&self) -> Vec<String> {
        let t = TARGETS;
        [
            ("overshoot", self.overshoot, t.overshoot),
            ("settling", self.settling, t.settling),
            ("hold", self.hold, t.hold),
            ("hold_yaw", self.hold_yaw, t.hold_yaw),
            ("square", self.square, t.square),
        ]
        .into_iter()
        .filter(|(_, v, limit)| v.is_nan() || v > limit)
        .map(|(name, v, limit)| format!("{name} {v:.3} (target {limit})"))
        .collect()
    }
}

impl std::fmt::Display for Figures {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:<14} step overshoot {:.3} m ({:.1} %), settled within 0.1 m after {:.2} s; \
             60 s hover within {:.3} m and {:.3} rad; 2 m square within {:.3} m of its sides",
            self.robot,
            self.overshoot,
            self.overshoot * 100.0,
            self.settling,
            self.hold,
            self.hold_yaw,
            self.square
        )
    }
}

/// Flies the three figures with `robot` against the lockstep server at `addr`.
///
/// # Errors
/// The run's error, or the iteration's failure, named with the robot.
pub async fn measure(addr: &str, robot: &str) -> Result<Figures, String> {
    let at = |x, y| Coordinates::new(x, y, -1.0);
    let step = fly(
        addr,
        robot,
        vec![Mission::goto(at(1.0, 0.0)), Mission::Hover { seconds: 8.0 }],
    )
    .await?;
    let t0 = step.first().map_or(0.0, |p| p.time);
    let overshoot = step.iter().map(|p| p.position.x - 1.0).fold(0.0, f64::max);
    let settling = step
        .iter()
        .filter(|p| (p.position - at(1.0, 0.0)).norm() > 0.1)
        .map(|p| p.time - t0)
        .fold(0.0, f64::max);
    let hover = fly(addr, robot, vec![Mission::Hover { seconds: 60.0 }]).await?;
    let hold = hover
        .iter()
        .map(|p| (p.position - at(0.0, 0.0)).norm())
        .fold(0.0, f64::max);
    let hold_yaw = hover
        .iter()
        .filter_map(|p| p.orientation)
        .map(|o| crate::geometry::wrap_angle(o.z).abs())
        .fold(0.0, f64::max);
    let corners = [at(0.0, 0.0), at(2.0, 0.0), at(2.0, 2.0), at(0.0, 2.0)];
    let square = fly(
        addr,
        robot,
        (1..=4).map(|i| Mission::goto(corners[i % 4])).collect(),
    )
    .await?;
    let square = square
        .iter()
        .map(|p| {
            (0..4)
                .map(|i| to_segment(p.position, corners[i], corners[(i + 1) % 4]))
                .fold(f64::MAX, f64::min)
        })
        .fold(0.0, f64::max);
    Ok(Figures {
        robot: robot.to_string(),
        overshoot,
        settling,
        hold,
        hold_yaw,
        square,
    })
}

/// [`measure`] for each of `robots` against a lockstep usar-server started in this process
/// (embedded defaults, as fast as lockstep allows).
///
/// # Errors
/// The server's or a flight's error.
#[cfg(feature = "local")]
pub async fn measure_local(robots: &[&str]) -> Result<Vec<Figures>, String> {
    let config = usar_server::ServerConfig {
        time_scale: usar_server::TimeScale::Max,
        ..usar_server::ServerConfig::default()
    };
    let server = crate::Backend::Local(Box::new(config))
        .start()
        .await
        .map_err(|e| e.to_string())?;
    let mut figures = Vec::new();
    for robot in robots {
        figures.push(measure(server.addr(), robot).await?);
    }
    server.stop().await.map_err(|e| e.to_string())?;
    Ok(figures)
}

/// Horizontal distance from `p` to the segment `a`–`b`.
pub fn to_segment(p: Coordinates, a: Coordinates, b: Coordinates) -> f64 {
    let (ab, ap) = ((b - a).xy(), (p - a).xy());
    if ab.norm_squared() == 0.0 {
        return ap.norm();
    }
    let t = (ap.dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
    (ap - ab * t).norm()
}

/// One iteration of `missions` from a hover at (0, 0, -1), heading north; its trajectory.
async fn fly(
    addr: &str,
    robot: &str,
    missions: Vec<Mission>,
) -> Result<Vec<TrajectoryPoint>, String> {
    let settings = RunSettings {
        addr: addr.to_string(),
        robot: robot.to_string(),
        start: Start::at(Coordinates::new(0.0, 0.0, -1.0)),
        missions,
        lockstep: Lockstep::Required,
        pictures: Pictures::None,
        ..RunSettings::default()
    };
    let base = crate::agents::base::INFO.create;
    let summary = crate::run(
        &settings,
        &base,
        &mut |_: &crate::Progress| {},
        &CancellationToken::new(),
    )
    .await
    .map_err(|e| format!("{robot}: {e}"))?;
    match summary.iterations.into_iter().next() {
        Some(it) if it.status == IterationStatus::Done => Ok(it.trajectory),
        Some(it) => Err(format!("{robot}: {:?}", it.status)),
        None => Err(format!("{robot}: no iteration flown")),
    }
}
