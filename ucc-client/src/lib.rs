//! ucc-client: the UAV Control Center, a framework for flying USARSim UAVs with agents.
//!
//! Layout:
//!
//! * [`connection`] — TCP connection to a server: typed messages in, commands out
//!   ([`lines`] frames the byte stream);
//! * [`uav`] — the UAV model: the latest reading of every sensor ([`UavState`]);
//! * [`geometry`] — coordinates and world/body frame rotations (nalgebra);
//! * [`mission`] — missions and mission files;
//! * [`agent`] — the [`Agent`] trait; [`agents`] — the agents (`base`, `avoid`) and their registry;
//! * [`controller`] — spawn, fly every mission, repeat: [`run_missions`];
//! * [`record`] and [`picture`] — the per-iteration log, trajectory CSV and map pictures;
//! * [`wire`] — line decoding/encoding for `ucc decode` / `ucc encode`;
//! * [`tap`] — the recording proxy of `ucc tap`.
//!
//! Agents are pure: the controller hands them the state and the simulated time.
//!
//! ```
//! use ucc_client::{Agent, Coordinates, Mission, UavState, agents};
//!
//! let mut agent = agents::create("base").unwrap();
//! agent.add_mission(Mission::goto(Coordinates::new(5.0, 0.0, -2.0))).unwrap();
//! agent.start(0.0);
//!
//! let mut uav = UavState::new();
//! uav.position = Some(ucc_client::uav::Reading { value: Coordinates::zeros(), time: 0.0 });
//! let step = agent.step(&uav, 0.0);
//! let command = step.command.unwrap();
//! assert!(command.forward > 90.0 && command.up > 0.0); // ahead and up: fly forward, climb
//! ```

pub mod agent;
pub mod agents;
pub mod connection;
pub mod controller;
pub mod geometry;
pub mod lines;
pub mod mission;
pub mod picture;
pub mod record;
pub mod tap;
pub mod uav;
pub mod wire;

pub use agent::{Agent, AgentEvent, MissionRefused, SpeedCommand, Step};
pub use connection::{Connection, ConnectionError};
pub use controller::{
    IterationSummary, Pictures, Progress, RunConfig, RunError, Start, Statistics, Summary,
    run_missions,
};
pub use geometry::Coordinates;
pub use mission::{Mission, MissionError};
pub use uav::UavState;
