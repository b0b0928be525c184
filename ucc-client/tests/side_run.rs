//! The runner with the camera and the radio on (issue 20, the client side): camera frames
//! reach the agent and are written as PNG; agents talk by radio through the WSS.
#![cfg(feature = "local")]

use std::sync::{Arc, Mutex};

use tokio_util::sync::CancellationToken;
use ucc_client::backend::{Backend, Sides};
use ucc_client::{
    Agent, CameraSettings, Coordinates, Mission, MissionRefused, Progress, RunSettings, Start,
    Step, UavState, agents,
};

/// The `base` agent, recording what it is shown.
struct Watching<T: Send> {
    inner: Box<dyn Agent>,
    seen: Arc<Mutex<Vec<T>>>,
    look: fn(&UavState, f64) -> Option<T>,
}

impl<T: Send> Agent for Watching<T> {
    fn name(&self) -> &str {
        "watching"
    }
    fn add_mission(&mut self, mission: Mission) -> Result<(), MissionRefused> {
        self.inner.add_mission(mission)
    }
    fn start(&mut self, time: f64) {
        self.inner.start(time);
    }
    fn stop(&mut self) {
        self.inner.stop();
    }
    fn step(&mut self, uav: &UavState, time: f64) -> Step {
        if let Some(seen) = (self.look)(uav, time) {
            self.seen.lock().unwrap().push(seen);
        }
        self.inner.step(uav, time)
    }
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("ucc-side-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// An AirRobot flies with frames asked for: its agent sees its camera's tile, and every
/// 5th frame is a PNG in the log folder showing the same view.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn camera_frames_reach_the_agent_and_every_nth_is_written_as_png() {
    let config = usar_server::ServerConfig {
        map: usar_server::sim::Map::embedded("rescue").unwrap(),
        ..usar_server::ServerConfig::default()
    };
    let settings = RunSettings {
        robot: "AirRobot".into(),
        start: Start::at(Coordinates::new(-12.0, 0.0, -1.5)),
        missions: vec![Mission::goto(Coordinates::new(-9.0, 0.0, -1.5))],
        log_dir: Some(temp_dir("frames")),
        camera: Some(CameraSettings {
            save_every: 5,
            ..CameraSettings::default()
        }),
        ..RunSettings::default()
    };
    let server = Backend::Local(Box::new(config))
        .start_with(Sides::of(&settings))
        .await
        .unwrap();
    let settings = server.settings(settings);
    let seen = Arc::new(Mutex::new(Vec::new()));
    let factory = {
        let seen = seen.clone();
        move || {
            Box::new(Watching {
                inner: agents::create("base").unwrap(),
                seen: seen.clone(),
                look: |uav, _| {
                    uav.image
                        .as_ref()
                        .map(|i| (i.value.width, i.value.height, i.value.index, i.time))
                },
            }) as Box<dyn Agent>
        }
    };
    let summary = ucc_client::run(
        &settings,
        &factory,
        &mut |_: &Progress| {},
        &CancellationToken::new(),
    )
    .await
    .unwrap();
    server.stop().await.unwrap();
    assert_eq!(summary.flown, 1);
    let seen = seen.lock().unwrap().clone();
    assert!(
        seen.len() > 5,
        "the agent saw frames at most steps: {seen:?}"
    );
    assert!(seen.iter().all(|s| (s.0, s.1) == (320, 240)), "{seen:?}");
    // Several different frames, in order.
    let mut indices: Vec<u64> = seen.iter().map(|s| s.2).collect();
    indices.dedup();
    assert!(indices.len() > 2 && indices.is_sorted(), "{indices:?}");

    let dir = settings.log_dir.unwrap();
    let mut pngs: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.contains("-frame-"))
        .collect();
    pngs.sort();
    assert_eq!(pngs.first().unwrap(), "UCCLOG-01-frame-00001.png");
    assert!(pngs.iter().all(|n| {
        let i: u64 = n[16..21].parse().unwrap();
        i % 5 == 1
    }));
    let png = image::open(dir.join(&pngs[0])).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (320, 240));
    // The sky above, something else below (the AirRobot's camera looks a little down).
    assert_eq!(png.get_pixel(160, 2).0, usar_server::sim::render::SKY);
    assert_ne!(png.get_pixel(160, 237).0, usar_server::sim::render::SKY);
    let log = std::fs::read_to_string(dir.join("UCCLOG-01.log")).unwrap();
    assert!(log.contains("camera cams: its 320x240 tile"), "{log}");
    assert!(
        log.contains("written as UCCLOG-01-frame-NNNNN.png"),
        "{log}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Frames not asked for: no image server is needed and the agent sees none.
#[tokio::test]
async fn without_the_camera_setting_the_agent_sees_no_frames() {
    let settings = RunSettings {
        robot: "AirRobot".into(),
        start: Start::at(Coordinates::new(0.0, 0.0, -1.5)),
        missions: vec![Mission::Hover { seconds: 0.5 }],
        ..RunSettings::default()
    };
    let server = Backend::Local(Box::default())
        .start_with(Sides::of(&settings))
        .await
        .unwrap();
    let settings = server.settings(settings);
    assert!(settings.camera.is_none());
    let seen = Arc::new(Mutex::new(Vec::new()));
    let factory = {
        let seen = seen.clone();
        move || {
            Box::new(Watching {
                inner: agents::create("base").unwrap(),
                seen: seen.clone(),
                look: |uav, _| Some(uav.image.is_some()),
            }) as Box<dyn Agent>
        }
    };
    ucc_client::run(
        &settings,
        &factory,
        &mut |_: &Progress| {},
        &CancellationToken::new(),
    )
    .await
    .unwrap();
    server.stop().await.unwrap();
    let seen = seen.lock().unwrap();
    assert!(!seen.is_empty() && seen.iter().all(|s| !s), "{seen:?}");
}
