//! `STA`: robot status (protocol.md §3.2, §6 for the UT2004 layout).

use super::line::Line;
use super::server::{Sta, StaLayout, VehicleStatus};
use crate::error::ParseError;
use crate::format::WireBuf;
use crate::value::{Reader, time};

impl Sta {
    pub(crate) fn read(r: Reader<'_, '_>) -> Result<Self, ParseError> {
        let vehicle = match r.opt_text("Type") {
            Some(kind) => Some(VehicleStatus {
                kind: kind.to_owned(),
                light_toggle: r.opt_bool("LightToggle")?,
                light_intensity: r.opt_i64("LightIntensity")?,
                front_steer: r.opt_f64("FrontSteer")?,
                rear_steer: r.opt_f64("RearSteer")?,
            }),
            None => None,
        };
        Ok(Self {
            time: time(&r)?,
            battery: r.i64("Battery")?,
            vehicle,
            layout: match r.opt_i64("View")? {
                Some(view) => StaLayout::Ut2004 { view },
                None => StaLayout::Udk,
            },
        })
    }

    /// UDK: `STA {Time} {Battery} [{Type} {LightToggle} {LightIntensity} {FrontSteer} {RearSteer}]`
    /// with integer steering; UT2004: `STA [{Type}] {Time} [{FrontSteer} {RearSteer}]
    /// [{LightToggle} {LightIntensity}] {Battery} {View}` with 4-decimal steering.
    pub(crate) fn write(&self, out: &mut impl WireBuf) {
        let mut w = Line::new(out, "STA");
        let v = self.vehicle.as_ref();
        match self.layout {
            StaLayout::Udk => {
                w.time(self.time).int("Battery", self.battery);
                if let Some(v) = v {
                    w.text("Type", &v.kind);
                    lights(&mut w, v);
                    for (key, s) in [("FrontSteer", v.front_steer), ("RearSteer", v.rear_steer)] {
                        if let Some(s) = s {
                            w.int(key, s as i64);
                        }
                    }
                }
            }
            StaLayout::Ut2004 { view } => {
                if let Some(v) = v {
                    w.text("Type", &v.kind);
                }
                w.time(self.time);
                if let Some(v) = v {
                    for (key, s) in [("FrontSteer", v.front_steer), ("RearSteer", v.rear_steer)] {
                        if let Some(s) = s {
                            w.fixed(key, s, 4);
                        }
                    }
                    lights(&mut w, v);
                }
                w.int("Battery", self.battery).int("View", view);
            }
        }
    }
}

fn lights<B: WireBuf>(w: &mut Line<'_, B>, v: &VehicleStatus) {
    if let Some(b) = v.light_toggle {
        w.bool("LightToggle", b);
    }
    if let Some(i) = v.light_intensity {
        w.int("LightIntensity", i);
    }
}

#[cfg(test)]
mod tests {
    use crate::messages::testutil::round_trip;
    use crate::{ServerMessage, Sta, StaLayout, Time};

    #[test]
    fn udk_layouts() {
        let m = round_trip("STA {Time 12.3456} {Battery 99999}");
        assert_eq!(
            m,
            ServerMessage::Sta(Sta {
                time: Time::udk(12.3456),
                battery: 99999,
                vehicle: None,
                layout: StaLayout::Udk
            })
        );
        let m = round_trip(
            "STA {Time 477.7582} {Battery 99999} {Type GroundVehicle} {LightToggle False} {LightIntensity 100} {FrontSteer 0} {RearSteer 0}",
        );
        let ServerMessage::Sta(sta) = m else { panic!() };
        let v = sta.vehicle.unwrap();
        assert_eq!(v.kind, "GroundVehicle");
        assert_eq!(v.light_toggle, Some(false));
        assert_eq!(v.light_intensity, Some(100));
        assert_eq!(v.front_steer, Some(0.0));
    }

    #[test]
    fn ut2004_layouts() {
        let m = round_trip(
            "STA {Type GroundVehicle} {Time 495.55} {FrontSteer 0.0000} {RearSteer 0.0000} {LightToggle False} {LightIntensity 0} {Battery 3600} {View -1}",
        );
        let ServerMessage::Sta(sta) = m else { panic!() };
        assert_eq!(
            sta.time,
            Time {
                seconds: 495.55,
                decimals: 2
            }
        );
        assert_eq!(sta.layout, StaLayout::Ut2004 { view: -1 });
        round_trip(
            "STA {Type AerialVehicle} {Time 268.50} {LightToggle False} {LightIntensity 0} {Battery 1192} {View -1}",
        );
    }

    #[test]
    fn errors_say_what_and_where() {
        let e = ServerMessage::parse_strict("STA {Time 1.0000} {Battery x}").unwrap_err();
        assert_eq!(e.to_string(), "sta: bad integer \"x\" in {Battery ..}");
        let e = ServerMessage::parse_strict("STA {Battery 1}").unwrap_err();
        assert_eq!(e.to_string(), "sta: missing {Time ..}");
    }
}
