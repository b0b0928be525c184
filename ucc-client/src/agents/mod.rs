//! The agents and their registry.
//!
//! A new built-in agent is one file in this folder (a type implementing [`Agent`], unit
//! tests with synthetic states) and one line in [`AGENTS`], which only names agents for the
//! `ucc` program: the runner takes any [`AgentFactory`](crate::AgentFactory), so an agent in
//! another crate needs no line here (see `ucc-client/examples/`).

pub mod avoid;
pub mod base;
#[cfg(feature = "local")]
pub mod team;

use crate::agent::Agent;

/// A registry entry: how the `ucc` program names and creates an agent.
#[derive(Debug, Clone, Copy)]
pub struct AgentInfo {
    /// The name given to `ucc run --agent`.
    pub name: &'static str,
    /// One line for `--help` and error messages.
    pub description: &'static str,
    /// Creates the agent with its default configuration.
    pub create: fn() -> Box<dyn Agent>,
}

/// Every agent the `ucc` program knows.
pub const AGENTS: &[AgentInfo] = &[base::INFO, avoid::INFO, base::THESIS];

/// The registry entry of `name`; its `create` is an [`AgentFactory`](crate::AgentFactory).
pub fn info(name: &str) -> Option<&'static AgentInfo> {
    AGENTS.iter().find(|a| a.name == name)
}

/// Creates the agent registered under `name`.
pub fn create(name: &str) -> Option<Box<dyn Agent>> {
    info(name).map(|a| (a.create)())
}

/// The registered names, comma separated (for messages).
pub fn names() -> String {
    AGENTS.iter().map(|a| a.name).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    #[test]
    fn registry_names_match_agents() {
        for info in super::AGENTS {
            assert_eq!((info.create)().name(), info.name);
        }
        assert!(super::create("nope").is_none());
        assert_eq!(super::names(), "base, avoid, thesis");
    }
}
