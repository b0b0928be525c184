//! Robots (stub until the simulation lands).
use std::path::Path;
/// Catalog.
#[derive(Debug, Clone)]
pub struct RobotCatalog;
/// Error.
#[derive(Debug, thiserror::Error)]
#[error("robot config error")]
pub struct RobotConfigError;
impl RobotCatalog {
    /// Load.
    pub fn from_file(_path: &Path) -> Result<Self, RobotConfigError> {
        Ok(Self)
    }
    /// Embedded.
    pub fn embedded() -> Self {
        Self
    }
}
