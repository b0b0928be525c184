//! usar-server: a USARSim stand-in. (Overview to be written.)

pub mod net;
pub mod replay;
pub mod sim;

pub use net::{ServerConfig, ServerError, TimeScale, run};
