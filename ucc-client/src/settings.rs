//! What a run is asked to do: [`RunSettings`] (server, robot, start, missions, iterations,
//! time limits, lockstep, outputs). The agent is not a setting: the runner takes an
//! [`AgentFactory`](crate::AgentFactory).

use std::path::PathBuf;
use std::str::FromStr;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use usar_proto::{Command, Init};

use crate::flight::FlightConfig;
pub use crate::flight::{Lockstep, Start};
use crate::geometry::{Coordinates, to_wire};
use crate::mission::Mission;
use crate::picture::MapGeometry;

/// Simulated seconds per lockstep barrier: the rate of the Position and STA streams.
pub const LOCKSTEP_STEP: f64 = 0.1;

/// How long to wait for the server's greeting and for a lockstep answer.
const HANDSHAKE: Duration = Duration::from_secs(2);

/// Which map pictures a run draws (in the log directory).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Pictures {
    /// Per iteration the map and the plots, and the overlay of all.
    #[default]
    All,
    /// Only the overlay of all iterations.
    Overlay,
    /// None.
    None,
}

impl FromStr for Pictures {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "all" => Ok(Self::All),
            "overlay" => Ok(Self::Overlay),
            "none" => Ok(Self::None),
            _ => Err(format!("expected all, overlay or none, not {s:?}")),
        }
    }
}

/// Camera frames for the agent (docs/camera.md): where the image server is and what to do
/// with the frames.
#[derive(Debug, Clone)]
pub struct CameraSettings {
    /// `host:port` of the image server (USARSim: TCP 5003). An in-process server fills in
    /// its own.
    pub server: String,
    /// Raw frames carry pixels as B, G, R (USARSim, and usar-server without
    /// `--image-rgb`).
    pub bgr: bool,
    /// A camera's tile in the image server's frame, pixels (USARSim's `CameraWidth` ×
    /// `CameraHeight`, 320 × 240): the UAV's frame is the tile at its camera's CONF
    /// `TextureOffsetX/Y`.
    pub tile: (u32, u32),
    /// Write every `save_every`-th frame received as a PNG into the log directory
    /// (`PREFIX-NN-frame-IIIII.png`); 0 writes none.
    pub save_every: u32,
    /// Read frames only while this is `true` (a viewer that shows them only while its
    /// panel is open: `ucc gui`); `None`: always.
    pub active: Option<Arc<AtomicBool>>,
}

impl Default for CameraSettings {
    fn default() -> Self {
        Self {
            server: "localhost:5003".into(),
            bgr: true,
            tile: (320, 240),
            save_every: 0,
            active: None,
        }
    }
}

impl CameraSettings {
    /// Whether frames are to be read now.
    pub fn is_active(&self) -> bool {
        self.active
            .as_ref()
            .is_none_or(|a| a.load(std::sync::atomic::Ordering::Relaxed))
    }
}

/// The UAV's radio through a Wireless Simulation Server (docs/wss.md).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RadioSettings {
    /// `host:port` of the WSS (TCP 50000). An in-process server fills in its own.
    pub wss: String,
    /// Other UAVs whose signal the agent sees at every step
    /// ([`UavState::signal`](crate::UavState::signal)), besides those it talked to.
    pub peers: Vec<String>,
}

/// Everything a run needs besides the agent.
#[derive(Debug, Clone)]
pub struct RunSettings {
    /// `host:port` of the server.
    pub addr: String,
    /// Robot class: `stsAirRobot`, `AirRobot`, or a full `Package.Class`.
    pub robot: String,
    /// The robot's name in the world.
    pub name: String,
    /// Where to spawn, every iteration.
    pub start: Start,
    /// The missions, flown in order, every iteration.
    pub missions: Vec<Mission>,
    /// How many times to fly them.
    pub iterations: usize,
    /// Where to write the logs, trajectories and pictures; `None` writes nothing.
    pub log_dir: Option<PathBuf>,
    /// File name prefix of everything written.
    pub prefix: String,
    /// Wall-clock limit for connecting.
    pub connect_timeout: Duration,
    /// Wall-clock limit for the first sensor data after INIT, and for any silence after.
    pub stream_timeout: Duration,
    /// Simulated seconds a single mission may take.
    pub mission_timeout: f64,
    /// Lockstep with the server.
    pub lockstep: Lockstep,
    /// Record every line of every iteration's connection: this file for the first,
    /// `NAME-2.EXT`, `NAME-3.EXT`, … for the next (docs/recording.md).
    pub record: Option<PathBuf>,
    /// Go on with the next iteration when one fails (a mission timeout, an empty battery, a
    /// spawn that gave no stream); the failure is counted in the [`Summary`](crate::Summary).
    /// Failures that would repeat every time (no server, unwritable files) always end the run.
    pub keep_going: bool,
    /// Which map pictures to draw.
    pub pictures: Pictures,
    /// The map's walls and obstacles, when known (a local server's map file), for the
    /// pictures; without it the pictures draw what the laser saw.
    pub map: Option<MapGeometry>,
    /// How many iterations [`Summary::iterations`](crate::Summary::iterations) keeps whole,
    /// trajectory included (default 100): a long loop's memory stays flat; the statistics,
    /// the results table, the overlay and the files cover every iteration.
    pub kept_iterations: usize,
    /// Camera frames for the agent ([`UavState::image`](crate::UavState::image)); `None`
    /// (the default) keeps state-only runs as fast as without an image server.
    pub camera: Option<CameraSettings>,
    /// The radio for the agent ([`Step::send`](crate::Step::send),
    /// [`UavState::inbox`](crate::UavState::inbox)); `None`: no radio.
    pub radio: Option<RadioSettings>,
}

impl Default for RunSettings {
    fn default() -> Self {
        Self {
            addr: "localhost:3000".into(),
            robot: "stsAirRobot".into(),
            name: "UAV1".into(),
            start: Start::at(Coordinates::zeros()),
            missions: Vec::new(),
            iterations: 1,
            log_dir: None,
            prefix: "UCCLOG".into(),
            connect_timeout: Duration::from_secs(5),
            stream_timeout: Duration::from_secs(10),
            mission_timeout: 120.0,
            lockstep: Lockstep::Off,
            record: None,
            keep_going: false,
            pictures: Pictures::All,
            map: None,
            kept_iterations: 100,
            camera: None,
            radio: None,
        }
    }
}

impl RunSettings {
    /// The INIT class name: `robot` with `USARBot.` in front unless it names a package.
    pub fn class_name(&self) -> String {
        Init::qualified_class(&self.robot)
    }

    /// The INIT command of every iteration.
    pub fn init(&self) -> Command {
        let mut init = Init {
            class_name: self.class_name(),
            name: Some(self.name.clone()),
            ..Init::default()
        };
        match &self.start {
            Start::Pose { location, rotation } => {
                init.location = Some(to_wire(location));
                init.rotation = Some(to_wire(rotation));
            }
            Start::Tag(tag) => init.start = Some(tag.clone()),
        }
        Command::Init(init)
    }

    /// What one iteration's flight needs to know.
    pub fn flight(&self) -> FlightConfig {
        FlightConfig {
            addr: self.addr.clone(),
            init: self.init(),
            start: self.start.clone(),
            missions: self.missions.clone(),
            mission_timeout: self.mission_timeout,
            stream_timeout: self.stream_timeout,
            handshake_timeout: HANDSHAKE,
            lockstep: self.lockstep,
            lockstep_step: LOCKSTEP_STEP,
            camera_tile: self.camera.as_ref().map(|c| c.tile),
            radio: self.radio.is_some(),
            ends_on_crash: true,
        }
    }

    /// The path of an output file `PREFIX-name` in the log directory.
    pub fn file(&self, name: &str) -> Option<PathBuf> {
        self.log_dir
            .as_ref()
            .map(|d| d.join(format!("{}-{name}", self.prefix)))
    }

    /// The GotoXyz targets, in order.
    pub fn waypoints(&self) -> Vec<Coordinates> {
        self.missions.iter().filter_map(Mission::target).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn start_parsing() {
        assert_eq!(
            "1,2,-3".parse::<Start>().unwrap(),
            Start::at(Coordinates::new(1.0, 2.0, -3.0))
        );
        assert_eq!(
            "1,2,-3,0,0,1.57".parse::<Start>().unwrap(),
            Start::Pose {
                location: Coordinates::new(1.0, 2.0, -3.0),
                rotation: Coordinates::new(0.0, 0.0, 1.57)
            }
        );
        assert_eq!(
            "PlayerStart_1".parse::<Start>().unwrap(),
            Start::Tag("PlayerStart_1".into())
        );
        assert!("1,2".parse::<Start>().unwrap_err().contains("2 numbers"));
        assert!("1,a,2".parse::<Start>().is_err());
        // The defect: a pose with a number that is not one was taken as a PlayerStart tag.
        let nan = "nan,0,-1".parse::<Start>().unwrap_err();
        assert!(nan.contains("\"nan\" is not a number"), "{nan}");
        assert!("".parse::<Start>().is_err());
    }

    #[test]
    fn class_names() {
        let mut settings = RunSettings::default();
        assert_eq!(settings.class_name(), "USARBot.stsAirRobot");
        settings.robot = "MyPkg.Drone".into();
        assert_eq!(settings.class_name(), "MyPkg.Drone");
    }
}
