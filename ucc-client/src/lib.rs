//! ucc-client: the UAV Control Center, a framework for flying USARSim UAVs with agents —
//! against a real USARSim or usar-server; it does not depend on the simulator.
//!
//! Layout:
//!
//! * [`agent`] — the [`Agent`] trait and [`AgentFactory`]; [`agents`] — the built-in agents
//!   (`base`, `avoid`) and the registry of names the `ucc` program accepts;
//! * [`flight`] — one flight, sans I/O: server messages and time-outs in, commands and
//!   progress out; the greeting, the lockstep handshake and the spawn are its phases, its
//!   deadlines come from [`Flight::poll_timeout`] ([`FlightConfig`], [`FlightError`]);
//! * [`runner`] — [`run`]: connect, spawn, fly, repeat, over a [`Connection`];
//! * [`backend`] — [`Backend`]: a remote server, or one inside this process (`local`);
//! * [`settings`] — [`RunSettings`]; [`progress`] — [`Progress`] events and the
//!   [`Observer`]; [`stats`] — [`Summary`], [`Statistics`], the results table;
//! * [`output`] and [`picture`] — the per-iteration log, trajectory CSV, map picture, plots;
//! * [`connection`] — TCP connection to a server ([`lines`] frames the byte stream);
//! * [`uav`] — the UAV model: the latest reading of every sensor ([`UavState`]);
//! * [`geometry`] — coordinates and world/body frame rotations (nalgebra);
//! * [`mission`] — missions and mission files.
//!
//! Agents are pure: the flight hands them the state and the simulated time. Any type that
//! implements [`Agent`] flies, from any crate:
//!
//! ```no_run
//! use ucc_client::{Agent, Coordinates, Mission, MissionRefused, RunSettings, Step, UavState};
//!
//! /// Climbs until 2 m up, then reports its one mission done.
//! struct Climber { missions: Vec<Mission>, done: bool }
//!
//! impl Agent for Climber {
//!     fn name(&self) -> &str { "climber" }
//!     fn add_mission(&mut self, m: Mission) -> Result<(), MissionRefused> {
//!         self.missions.push(m);
//!         Ok(())
//!     }
//!     fn start(&mut self, _time: f64) {}
//!     fn stop(&mut self) {}
//!     fn step(&mut self, uav: &UavState, _time: f64) -> Step {
//!         let z = uav.position.as_ref().map_or(0.0, |p| p.value.z);
//!         let up = if z > -2.0 { 50.0 } else { 0.0 };
//!         Step {
//!             command: Some(ucc_client::SpeedCommand { up, ..Default::default() }),
//!             all_done: up == 0.0,
//!             ..Step::default()
//!         }
//!     }
//! }
//!
//! # async fn fly() -> Result<(), ucc_client::RunError> {
//! let settings = RunSettings {
//!     addr: "localhost:3000".into(),
//!     missions: vec![Mission::Hover { seconds: 1.0 }],
//!     ..RunSettings::default()
//! };
//! let factory = || Box::new(Climber { missions: vec![], done: false }) as Box<dyn Agent>;
//! let cancel = tokio_util::sync::CancellationToken::new();
//! let summary =
//!     ucc_client::run(&settings, &factory, &mut |p: &ucc_client::Progress| println!("{p}"), &cancel)
//!         .await?;
//! println!("{} iteration(s)", summary.iterations.len());
//! # Ok(())
//! # }
//! ```

pub mod agent;
pub mod agents;
pub mod backend;
pub mod camera;
pub mod connection;
pub mod error;
pub mod estimator;
pub mod figures;
pub mod flight;
pub mod geometry;
pub mod lines;
pub mod mission;
pub mod output;
pub mod picture;
pub mod progress;
pub mod radio;
pub mod record;
pub mod runner;
#[cfg(feature = "local")]
pub mod scenario;
pub mod settings;
pub mod speed;
pub mod stats;
pub mod uav;

pub use agent::{Agent, AgentEvent, AgentFactory, MissionRefused, SpeedCommand, Step};
pub use backend::Backend;
pub use connection::{Connection, ConnectionError};
pub use error::RunError;
pub use flight::{Flight, FlightConfig, FlightError};
pub use geometry::Coordinates;
pub use mission::{Mission, MissionError};
pub use progress::{Observer, Progress};
pub use runner::run;
pub use settings::{CameraSettings, Lockstep, Pictures, RadioSettings, RunSettings, Start};
pub use stats::{IterationStatus, IterationSummary, Statistics, Summary};
pub use uav::UavState;
