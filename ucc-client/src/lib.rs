//! ucc-client: the UAV Control Center framework. (Overview to be written.)
pub mod wire;
