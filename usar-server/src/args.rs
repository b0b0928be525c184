//! The command-line options of a world that `usar-server` and `ucc run --local` share: one
//! `clap::Args` struct, so both programs spell, check and default them alike.

use std::path::PathBuf;

use crate::sim::map::Map;
use crate::sim::robots::RobotCatalog;
use crate::sim::{ConfigError, WindConfig, default_threads};
use crate::{ServerConfig, TimeScale};

/// The map, robots, seed, sensor threads, time scale and wind of a server.
#[derive(Debug, Clone, clap::Args)]
pub struct ServerArgs {
    /// Map: an embedded map name (any case; `usar-server --list-maps`) or a map file (TOML,
    /// see docs/maps.md).
    #[arg(long, value_name = "NAME|FILE")]
    pub map: Option<String>,
    /// Robot configurations (TOML, see docs/robots.md); default: the embedded catalog.
    #[arg(long, value_name = "FILE")]
    pub robots: Option<PathBuf>,
    /// Seed of every noise source; the same seed and commands give the same run.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Threads that read the robots' sensors (default: the machine's cores). The output is
    /// the same at any count.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// Simulated seconds per wall second (e.g. 1, 10, 0.5), or `max` for as fast as possible.
    #[arg(long, default_value = "1", value_name = "K|max")]
    pub time_scale: TimeScale,
    /// Mean wind for this run, `vx,vy[,vz]` m/s (x north, y east, z down; where the air
    /// goes), overriding the map's `[wind]`. Felt by robots with physics (stsQuadrotor).
    #[arg(long, value_name = "VX,VY[,VZ]", allow_hyphen_values = true,
          value_parser = crate::sim::wind::parse_velocity)]
    pub wind: Option<[f64; 3]>,
    /// Gust intensity for this run: standard deviation of the horizontal gusts, m/s
    /// (Dryden-type, seeded by --seed).
    #[arg(long, value_name = "M/S", allow_hyphen_values = true)]
    pub gusts: Option<f64>,
    /// Gust length scale for this run, m (default 20).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub gust_length: Option<f64>,
    /// Faults scheduled in simulated time (TOML, see docs/quadrotor.md#faults): `FAULT`
    /// lines for robots by spawn number, at fixed or seeded random times; or a recording,
    /// whose server `FAULT` lines are read back.
    #[arg(long, value_name = "FILE")]
    pub faults: Option<PathBuf>,
    /// Domain randomisation (TOML, see docs/quadrotor.md#domain-randomisation): each robot
    /// spawned draws its mass, inertia, k_F, k_M, motor constants, drag, wind and sensor
    /// noise from these ranges, seeded by --seed and its spawn number.
    #[arg(long, value_name = "FILE")]
    pub randomize: Option<PathBuf>,
    /// Physics ticks per simulated second (default 200: a 5 ms step; at most 1000). A
    /// sensor reads at most once a tick: a 500 Hz IMU needs 500 or 1000 (docs/robots.md#sensor-rates).
    #[arg(long, value_name = "HZ")]
    pub physics_rate: Option<f64>,
    /// A sensor's rate, `NAME=HZ` (e.g. `IMU=500`): the part named NAME of every robot class
    /// that has one reads HZ times a simulated second; repeatable. The rate must be a whole
    /// number of physics ticks (docs/robots.md#sensor-rates).
    #[arg(long, value_name = "NAME=HZ", value_parser = crate::sim::robots::parse_sensor_rate)]
    pub sensor_rate: Vec<(String, f64)>,
}

/// Options that do not make a world: a map or catalog that does not load, or wind out of
/// range. The text names the option.
#[derive(Debug, thiserror::Error)]
pub enum ArgsError {
    /// `--map` or `--robots` did not load.
    #[error("{option}: {error}")]
    File {
        /// `--map NAME` or `--robots FILE`.
        option: String,
        /// Why (part of the message, so not a `source`: the cause is said once).
        error: ConfigError,
    },
    /// `--wind`, `--gusts` or `--gust-length` out of range.
    #[error("--wind/--gusts/--gust-length: {0}")]
    Wind(String),
    /// `--faults FILE` did not load.
    #[error("--faults {0}")]
    Faults(String),
    /// `--randomize FILE` did not load.
    #[error("--randomize {0}")]
    Randomize(String),
    /// `--physics-rate` or `--sensor-rate` out of range, a sensor rate the physics rate
    /// cannot give, or a GPS on a map without an origin (the text names the robot, the
    /// sensor and the value).
    #[error("{0}")]
    Rates(String),
}

impl ServerArgs {
    /// The server these options describe (everything else as `ServerConfig::default()`).
    pub fn config(&self) -> Result<ServerConfig, ArgsError> {
        let map = match &self.map {
            None => Map::default_map(),
            Some(name) => Map::lookup(name).map_err(|error| ArgsError::File {
                option: format!("--map {name}"),
                error,
            })?,
        };
        let mut robots = match &self.robots {
            None => RobotCatalog::embedded(),
            Some(path) => RobotCatalog::from_file(path).map_err(|error| ArgsError::File {
                option: format!("--robots {}", path.display()),
                error,
            })?,
        };
        for (part, hz) in &self.sensor_rate {
            robots
                .set_sensor_rate(part, *hz)
                .map_err(|e| ArgsError::Rates(format!("--sensor-rate {part}={hz}: {e}")))?;
        }
        let dt = match self.physics_rate {
            None => crate::sim::SimConfig::default().dt,
            Some(hz) => crate::sim::robots::physics_step(hz)
                .map_err(|e| ArgsError::Rates(format!("--physics-rate: {e}")))?,
        };
        robots.check_rates(dt).map_err(|e| {
            ArgsError::Rates(format!("{e} (--physics-rate, --sensor-rate, --robots)"))
        })?;
        robots
            .check_map(&map)
            .map_err(|e| ArgsError::Rates(format!("{e} (--map, --robots)")))?;
        let wind = WindConfig::overridden(map.wind(), self.wind, self.gusts, self.gust_length)
            .map_err(ArgsError::Wind)?;
        let mut config = ServerConfig {
            map,
            robots,
            time_scale: self.time_scale,
            ..ServerConfig::default()
        };
        config.sim.seed = self.seed;
        config.sim.dt = dt;
        config.sim.threads = self.threads.map_or_else(default_threads, usize::from);
        config.sim.wind = wind;
        if let Some(path) = &self.faults {
            config.sim.faults =
                crate::sim::faults::FaultPlan::from_file(path).map_err(ArgsError::Faults)?;
        }
        if let Some(path) = &self.randomize {
            config.sim.randomize = Some(
                crate::sim::randomize::Randomization::from_file(path)
                    .map_err(ArgsError::Randomize)?,
            );
        }
        Ok(config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Program {
        #[command(flatten)]
        server: ServerArgs,
    }

    #[test]
    fn options_make_the_server_and_name_what_is_wrong() {
        let args =
            Program::parse_from(["p", "--map", "ARENA", "--seed", "7", "--time-scale", "max"]);
        let config = args.server.config().unwrap();
        assert_eq!(config.map.level(), Map::embedded("arena").unwrap().level());
        assert_eq!((config.sim.seed, config.time_scale), (7, TimeScale::Max));
        let bad = Program::parse_from(["p", "--map", "nowhere.toml"])
            .server
            .config();
        assert!(
            bad.unwrap_err()
                .to_string()
                .starts_with("--map nowhere.toml: ")
        );
        let args = Program::parse_from(["p", "--physics-rate", "1000", "--sensor-rate", "IMU=500"]);
        let config = args.server.config().unwrap();
        assert_eq!(config.sim.dt, 0.001);
        let imu = &config.robots.get("USARBot.stsQuadrotor").unwrap().parts;
        let imu = imu.iter().find(|p| p.name == "IMU").unwrap();
        assert_eq!(imu.interval, Some(0.002));
        for (args, shows) in [
            (
                &["p", "--sensor-rate", "IMU=500"][..],
                "robot USARBot.stsAirRobot: sensor IMU: rate 500 Hz (interval 0.002 s) is \
                 above the physics rate of 200 Hz",
            ),
            (
                &["p", "--physics-rate", "5000"][..],
                "--physics-rate: the physics rate must be a number of Hz from 1 to 1000, got 5000",
            ),
            (
                &["p", "--sensor-rate", "Nothing=5"][..],
                "--sensor-rate Nothing=5: sensor Nothing: no robot class has a sensor",
            ),
        ] {
            let e = Program::parse_from(args).server.config().unwrap_err();
            assert!(e.to_string().starts_with(shows), "{e}");
        }
        for bad in ["IMU=-5", "IMU=0", "IMU=fast"] {
            let e = Program::try_parse_from(["p", "--sensor-rate", bad])
                .err()
                .unwrap();
            assert!(e.to_string().contains("sensor IMU: the rate"), "{e}");
        }
        let bad = Program::parse_from(["p", "--gusts", "-1"]).server.config();
        assert!(
            bad.unwrap_err()
                .to_string()
                .starts_with("--wind/--gusts/--gust-length: ")
        );
    }
}
