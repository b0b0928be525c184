//! `MissionTime`: whole minutes since the part was attached (the robot spawned).

use usar_proto::SenData;

use super::{NoSettings, Reading, Sensor, settings};
use crate::noise::Noise;
use crate::part::PartConfig;

/// MissionTime settings: none.
pub type MissionTimeConfig = NoSettings;

#[derive(Debug, Clone)]
struct MissionTime;

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let _: MissionTimeConfig = settings(part)?;
    Ok(Box::new(MissionTime))
}

impl Sensor for MissionTime {
    fn read(&mut self, at: &Reading<'_>, _noise: &mut Noise) -> SenData {
        SenData::MissionTime {
            name: at.name.to_string(),
            minutes: (at.since_spawn / 60.0).floor() as i64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    #[test]
    fn whole_minutes() {
        let (scene, me) = scene_with_wall(2.0);
        let mut sensor = make("MissionTime", "");
        let mut minutes = |t| match sensor.read(&reading(&scene, me, t), &mut quiet()) {
            SenData::MissionTime { minutes, .. } => minutes,
            other => panic!("{other:?}"),
        };
        assert_eq!(minutes(59.9), 0);
        assert_eq!(minutes(125.0), 2);
    }
}
