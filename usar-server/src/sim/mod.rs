//! The simulation: synchronous, deterministic, no tokio, no wall clock. Time is `tick × dt`.
//!
//! API contract used by `net` (the implementation lives in this folder):
//!
//! ```text
//! World::new(map: Map, robots: RobotCatalog, config: SimConfig) -> World
//! world.level() -> &str                       // map level name for the NFO
//! world.time() -> f64                         // simulated seconds
//! world.dt() -> f64                           // seconds per tick (1/200)
//! world.connect() -> ClientId                 // a new connection (no robot yet)
//! world.command(ClientId, Command) -> Vec<ServerMessage>   // immediate replies
//! world.disconnect(ClientId)                  // removes the connection's robot(s)
//! world.step(&mut Vec<(ClientId, ServerMessage)>)          // one tick; appends this tick's output
//! ```

pub mod map;
pub mod robots;

use usar_proto::{Command, ServerMessage};

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
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            dt: 1.0 / 200.0,
        }
    }
}

/// The world: map, robots, sensors.
#[derive(Debug, Default)]
pub struct World {
    tick: u64,
    dt: f64,
    next_client: u64,
}

impl World {
    /// A world from settings (map and robot catalog still to come).
    pub fn new(_map: map::Map, _robots: robots::RobotCatalog, config: SimConfig) -> Self {
        Self {
            tick: 0,
            dt: config.dt,
            next_client: 0,
        }
    }
    /// The map's level name.
    pub fn level(&self) -> &str {
        "EmptyRoom"
    }
    /// NFO time limit.
    pub fn time_limit(&self) -> i64 {
        20
    }
    /// Robots in the world.
    pub fn robot_count(&self) -> usize {
        0
    }
    /// Simulated seconds.
    pub fn time(&self) -> f64 {
        self.tick as f64 * self.dt
    }
    /// Seconds per tick.
    pub fn dt(&self) -> f64 {
        self.dt
    }
    /// Registers a connection.
    pub fn connect(&mut self) -> ClientId {
        self.next_client += 1;
        ClientId(self.next_client)
    }
    /// Applies one command; returns the immediate replies.
    pub fn command(&mut self, client: ClientId, command: Command) -> Vec<ServerMessage> {
        let _ = (client, command);
        Vec::new()
    }
    /// Removes a connection and its robots.
    pub fn disconnect(&mut self, client: ClientId) {
        let _ = client;
    }
    /// Advances one tick and appends the output of this tick.
    pub fn step(&mut self, out: &mut Vec<(ClientId, ServerMessage)>) {
        let _ = out;
        self.tick += 1;
    }
}
