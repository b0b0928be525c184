//! The USARSim stand-in's world: synchronous, deterministic, no tokio, no sockets, no wall
//! clock. Time is `tick × dt`. The maps (`maps/`) and the robot catalog (`robots.toml`) are
//! embedded from this crate; `usar-server` puts it on the network.
//!
//! * [`World`] — map geometry, robots and their sensors; driven by [`World::command`] and
//!   [`World::step`].
//! * [`map`] — the map format (`docs/maps.md`) and the embedded maps.
//! * [`robots`] — the robot catalog format (`docs/robots.md`) and the embedded robots.
//! * [`part`] — one sensor part of a class ([`part::PartConfig`]), read by both.
//! * [`sensors`] — one file per sensor type and the registry that maps part types to them.
//!
//! Rapier types stay inside this crate. Frame everywhere: the protocol frame (x forward /
//! north, y right / east, z down; yaw + = clockwise seen from above).
//!
//! ```
//! use usar_sim::{map::Map, robots::RobotCatalog, SimConfig, World};
//! use usar_proto::{Command, Init};
//!
//! let mut world = World::new(Map::default_map(), RobotCatalog::embedded(), SimConfig::default());
//! let client = world.connect();
//! world.command(client, Command::Init(Init {
//!     class_name: "USARBot.AirRobot".into(),
//!     start: Some("Start1".into()),
//!     ..Init::default()
//! }));
//! let mut out = Vec::new();
//! for _ in 0..20 {
//!     world.step(&mut out); // 0.1 s
//! }
//! assert!(!out.is_empty());
//! ```

mod dynamics;
pub mod faults;
pub mod map;
mod noise;
mod obj;
pub mod part;
pub mod power;
pub mod prefetch;
pub mod quadrotor;
pub mod randomize;
pub mod render;
mod robot;
pub mod robots;
mod scene;
pub mod sensors;
mod upright;
pub mod wind;
mod world;

#[cfg(test)]
mod quadrotor_tests;
#[cfg(test)]
mod tests;

pub use map::{ConfigError, ConfigFile, Map, Placed, PlayerStart};
pub use noise::{ErrorModel, splitmix};
pub use render::Image;
pub use robots::{RobotCatalog, RobotClass, UnknownClass};
pub use wind::WindConfig;
pub use world::{CameraFrame, Printed, RobotTruth, World};

/// A connection as the simulation knows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ClientId(pub u64);

/// Simulation settings.
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// Seed of every noise source.
    pub seed: u64,
    /// Seconds per physics step (USARSim: 1/200).
    pub dt: f64,
    /// Threads that read the robots' sensors (robots move on one thread). The output is the
    /// same, byte for byte, at any count. Default: the machine's cores; 0 counts as 1.
    pub threads: usize,
    /// The wind for this run; `None`: the map's `[wind]` (calm when it has none).
    pub wind: Option<WindConfig>,
    /// Robots one connection may spawn (USARSim: one); further INITs are ignored (logged).
    pub robots_per_connection: usize,
    /// Faults scheduled in simulated time (`--faults FILE`, docs/quadrotor.md#faults).
    pub faults: faults::FaultPlan,
    /// Parameter ranges every robot spawned draws from (`--randomize FILE`,
    /// docs/quadrotor.md#domain-randomisation).
    pub randomize: Option<randomize::Randomization>,
    /// The image server's grid of camera tiles, which camera CONF lines report.
    pub tiles: Tiles,
}

/// How the image server lays out the cameras' pictures (USARSim's `Multiview`: tiles of
/// `CameraWidth` × `CameraHeight` from the top-left, `CameraTileX` to a row). Camera `i`
/// (in spawn order, then part order; a camera gets the lowest tile no other camera holds)
/// has its top-left pixel at `((i mod columns)·width, (i div columns)·height)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tiles {
    /// Tiles in a row (`CameraTileX`, 2).
    pub columns: u32,
    /// Rows of tiles in a frame (`CameraTileY`, 2); cameras past `columns × rows` have a
    /// tile outside the frame and are not shown.
    pub rows: u32,
    /// Tile width, pixels (`CameraWidth`, 320).
    pub width: u32,
    /// Tile height, pixels (`CameraHeight`, 240).
    pub height: u32,
}

impl Default for Tiles {
    fn default() -> Self {
        Self {
            columns: 2,
            rows: 2,
            width: 320,
            height: 240,
        }
    }
}

impl Tiles {
    /// The top-left pixel of tile `index`.
    pub fn offset(&self, index: usize) -> (i64, i64) {
        let columns = self.columns.max(1) as usize;
        (
            (index % columns) as i64 * i64::from(self.width),
            (index / columns) as i64 * i64::from(self.height),
        )
    }
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            dt: 1.0 / 200.0,
            threads: default_threads(),
            wind: None,
            robots_per_connection: 1,
            faults: faults::FaultPlan::default(),
            randomize: None,
            tiles: Tiles::default(),
        }
    }
}

/// The machine's cores (1 when unknown), asked once a process: the standard library reads
/// the cgroup files on every call (a syscall-heavy 2 % of a Python batch reset).
pub fn default_threads() -> usize {
    static CORES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *CORES
        .get_or_init(|| std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get))
}
