//! Scenarios (docs/scenarios.md): the thesis's search, relay, tracking and delivery tasks
//! as data ([`model`], read from a TOML file by [`spec`]), flown by team agents ([`crate::agents::team`]) on an
//! in-process world ([`engine`]), scored ([`metrics`]) and drawn ([`picture`]). [`run`]
//! loops iterations and writes the results table, the logs and the pictures.

pub mod engine;
pub mod metrics;
pub mod model;
pub mod picture;
pub mod run;
pub mod spec;

pub use engine::{Outcome, Prepared, fly};
pub use metrics::Metrics;
pub use run::{ScenarioRun, run_scenario};
pub use spec::{Kind, Scenario, ScenarioError};
