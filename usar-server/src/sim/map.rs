//! Maps (stub until the simulation lands).
use std::path::Path;
/// A map.
#[derive(Debug, Clone)]
pub struct Map;
/// Map error.
#[derive(Debug, thiserror::Error)]
#[error("map error")]
pub struct MapError;
impl Map {
    /// Load.
    pub fn from_file(_path: &Path) -> Result<Self, MapError> {
        Ok(Self)
    }
    /// Embedded.
    pub fn embedded(_name: &str) -> Option<Self> {
        None
    }
    /// Names.
    pub fn embedded_names() -> &'static [&'static str] {
        &[]
    }
    /// Default.
    pub fn default_map() -> Self {
        Self
    }
    /// Level.
    pub fn level(&self) -> &str {
        "EmptyRoom"
    }
}
