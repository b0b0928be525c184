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

/// What a talking UAV saw at one step.
#[derive(Debug, Clone, Default)]
struct Heard {
    time: f64,
    /// Messages received: (from, text).
    inbox: Vec<(String, String)>,
    /// Messages that did not get through: (to, strength).
    undelivered: Vec<(String, f64)>,
    /// The signal to the other UAV, dBm.
    signal: Option<f64>,
}

/// The `base` agent that says hello to `peer` every 5th step and notes what it hears.
struct Talker {
    inner: Box<dyn Agent>,
    me: &'static str,
    peer: &'static str,
    steps: u64,
    heard: Arc<Mutex<Vec<Heard>>>,
    /// Wall-clock milliseconds this agent takes at its steps (in turn), to vary the timing.
    jitter: &'static [u64],
}

impl Agent for Talker {
    fn name(&self) -> &str {
        "talker"
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
        self.heard.lock().unwrap().push(Heard {
            time,
            inbox: uav
                .inbox
                .iter()
                .map(|m| {
                    (
                        m.from.clone(),
                        String::from_utf8_lossy(&m.data).into_owned(),
                    )
                })
                .collect(),
            undelivered: uav
                .undelivered
                .iter()
                .map(|u| (u.message.to.clone(), u.strength))
                .collect(),
            signal: uav.signal.get(self.peer).copied(),
        });
        if let Some(ms) = self
            .jitter
            .get(self.steps as usize % self.jitter.len().max(1))
        {
            std::thread::sleep(std::time::Duration::from_millis(*ms));
        }
        self.steps += 1;
        let mut step = self.inner.step(uav, time);
        if self.steps.is_multiple_of(5) {
            step.send.push(ucc_client::radio::Outgoing {
                to: self.peer.into(),
                data: format!("hello from {} at {time}", self.me).into_bytes(),
            });
        }
        step
    }
}

/// A factory of [`Talker`]s (`me` talking to `peer`, sleeping `jitter`) and what they heard.
fn talker(
    me: &'static str,
    peer: &'static str,
    jitter: &'static [u64],
) -> (
    impl Fn() -> Box<dyn Agent> + Send + Sync + 'static,
    Arc<Mutex<Vec<Heard>>>,
) {
    let heard: Arc<Mutex<Vec<Heard>>> = Arc::default();
    let kept = heard.clone();
    let factory = move || {
        Box::new(Talker {
            inner: agents::create("base").unwrap(),
            me,
            peer,
            steps: 0,
            heard: heard.clone(),
            jitter,
        }) as Box<dyn Agent>
    };
    (factory, kept)
}

/// Eight thin walls between y = 2 and y = 4.1, 3 m high, 20 m wide.
fn walls_map() -> usar_server::sim::Map {
    let mut text =
        "level = \"Walls\"\n[[box]]\ncenter = [0.0, 0.0, 0.1]\nsize = [60.0, 60.0, 0.2]\n"
            .to_owned();
    for i in 0..8 {
        let y = 2.0 + 0.3 * f64::from(i);
        text.push_str(&format!(
            "[[box]]\ncenter = [0.0, {y}, -1.5]\nsize = [20.0, 0.1, 3.0]\n"
        ));
    }
    usar_server::sim::Map::from_toml(&text, std::path::Path::new("walls.toml")).unwrap()
}

/// Two UAVs talk by radio through the WSS while one flies down behind eight walls: their
/// messages get through while the line of sight clears the walls' tops, then come back
/// undelivered with the signal below the cut-off, and the log says so.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_uavs_talk_until_one_flies_down_behind_walls() {
    use usar_server::net::wss::{self, WssConfig};
    let bind = async || tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let (main, monitor, wss_listener) = (bind().await, bind().await, bind().await);
    let (gamebots, monitor_at, wss_at) = (
        main.local_addr().unwrap(),
        monitor.local_addr().unwrap(),
        wss_listener.local_addr().unwrap(),
    );
    let shutdown = CancellationToken::new();
    let config = usar_server::ServerConfig {
        map: walls_map(),
        lockstep: true,
        time_scale: usar_server::TimeScale::Factor(2.0),
        ..usar_server::ServerConfig::default()
    };
    let side = usar_server::SideListeners {
        monitor: Some(monitor),
        ..usar_server::SideListeners::default()
    };
    tokio::spawn(usar_server::run_with(main, side, config, shutdown.clone()));
    // The WSS polls every 100 ms (1 s by default) so that links follow a short flight.
    let wss_config = WssConfig {
        poll: std::time::Duration::from_millis(100),
        ..WssConfig::new(monitor_at)
    };
    tokio::spawn(wss::serve(wss_listener, wss_config, shutdown.clone()));

    let dir = temp_dir("radio");
    let uav = |name: &str, start: Coordinates, missions: Vec<Mission>, peer: &str| RunSettings {
        addr: gamebots.to_string(),
        name: name.into(),
        prefix: name.into(),
        start: Start::at(start),
        missions,
        lockstep: ucc_client::Lockstep::Required,
        log_dir: Some(dir.clone()),
        pictures: ucc_client::Pictures::None,
        radio: Some(ucc_client::RadioSettings {
            wss: wss_at.to_string(),
            peers: vec![peer.into()],
        }),
        ..RunSettings::default()
    };
    // Robot1 hovers low on the near side; Robot2 starts high above the far side (the line
    // of sight passes over the walls) and flies down behind them, then waits there.
    let one = uav(
        "Robot1",
        Coordinates::new(0.0, 0.0, -1.0),
        vec![Mission::Hover { seconds: 12.0 }],
        "Robot2",
    );
    let two = uav(
        "Robot2",
        Coordinates::new(0.0, 6.0, -8.0),
        vec![
            Mission::Hover { seconds: 3.0 },
            Mission::goto(Coordinates::new(0.0, 6.0, -1.0)),
            Mission::Hover { seconds: 4.0 },
        ],
        "Robot1",
    );
    let ((f1, heard1), (f2, heard2)) = (
        talker("Robot1", "Robot2", &[]),
        talker("Robot2", "Robot1", &[]),
    );
    let cancel = CancellationToken::new();
    let (mut o1, mut o2) = (|_: &Progress| {}, |_: &Progress| {});
    let (r1, r2) = tokio::join!(
        ucc_client::run(&one, &f1, &mut o1, &cancel),
        ucc_client::run(&two, &f2, &mut o2, &cancel),
    );
    shutdown.cancel();
    r1.unwrap();
    r2.unwrap();
    let heard1: Vec<Heard> = heard1.lock().unwrap().clone();
    let heard2: Vec<Heard> = heard2.lock().unwrap().clone();

    // Robot1 heard Robot2 while it was high up.
    let got: Vec<&(String, String)> = heard1.iter().flat_map(|h| &h.inbox).collect();
    assert!(!got.is_empty(), "Robot1 heard nothing: {heard1:?}");
    assert!(
        got.iter()
            .all(|(from, text)| from == "Robot2" && text.starts_with("hello from Robot2"))
    );
    // In range at first, then out of range behind the walls.
    let in_range = |h: &&Heard| h.signal.is_some_and(|s| s > -93.0);
    let out = |h: &&Heard| h.signal.is_some_and(|s| s < -93.0);
    let first_in = heard2.iter().find(in_range).expect("in range at first");
    let first_out = heard2
        .iter()
        .find(out)
        .expect("out of range behind the walls");
    assert!(first_in.time < first_out.time);
    // Robot2's messages came back undelivered once behind the walls.
    let failed: Vec<&(String, f64)> = heard2.iter().flat_map(|h| &h.undelivered).collect();
    assert!(!failed.is_empty(), "{heard2:?}");
    assert!(
        failed
            .iter()
            .all(|(to, s)| to == "Robot1" && (s.is_nan() || *s < -93.0))
    );
    let log = std::fs::read_to_string(dir.join("Robot2-01.log")).unwrap();
    assert!(
        log.contains("radio: message to Robot1 not delivered"),
        "{log}"
    );
    // Nothing Robot2 sent from behind the walls arrived.
    let last_sent: f64 = got
        .iter()
        .map(|(_, t)| t.rsplit(' ').next().unwrap().parse().unwrap())
        .fold(0.0, f64::max);
    assert!(
        last_sent < first_out.time + 1.0,
        "{last_sent} {}",
        first_out.time
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// In lockstep with the in-process WSS (on the simulated clock), when a message arrives does
/// not depend on how long the agents take: the runner writes a step's messages before that
/// step's `SYNC`, so the WSS takes them at the barrier the world is held at, and delivers
/// them before the world steps on; the receiving runner takes them from its radio's sockets
/// before its agent's next step. So every message reaches the other agent at its first step
/// after the barrier the sender's step was at — whichever UAV joined first, however long
/// each agent thinks (the sender here sleeps a few milliseconds at some steps), and although
/// the second UAV's sensors read between barriers (its agent steps at the barriers only, and
/// the barriers are both UAVs' multiples of 0.1 s: a step's latest reading tells its barrier).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn in_lockstep_a_message_arrives_at_the_first_step_after_its_barrier() {
    let bind = async || tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let (main, monitor, wss) = (bind().await, bind().await, bind().await);
    let (gamebots, wss_at) = (main.local_addr().unwrap(), wss.local_addr().unwrap());
    let shutdown = CancellationToken::new();
    let config = usar_server::ServerConfig {
        map: walls_map(),
        lockstep: true,
        time_scale: usar_server::TimeScale::Max,
        ..usar_server::ServerConfig::default()
    };
    let side = usar_server::SideListeners {
        monitor: Some(monitor),
        wss: Some(wss),
        ..usar_server::SideListeners::default()
    };
    let server = tokio::spawn(usar_server::run_with(main, side, config, shutdown.clone()));
    let dir = temp_dir("lockstep-radio");
    let uav = |name: &str, start: Coordinates| RunSettings {
        addr: gamebots.to_string(),
        name: name.into(),
        prefix: name.into(),
        start: Start::at(start),
        missions: vec![Mission::Hover { seconds: 4.0 }],
        lockstep: ucc_client::Lockstep::Required,
        log_dir: Some(dir.clone()),
        pictures: ucc_client::Pictures::None,
        radio: Some(ucc_client::RadioSettings {
            wss: wss_at.to_string(),
            peers: Vec::new(),
        }),
        ..RunSettings::default()
    };
    let (one, two) = (
        uav("Robot1", Coordinates::new(0.0, 0.0, -1.0)),
        uav("Robot2", Coordinates::new(3.0, 0.0, -1.0)),
    );
    let ((f1, heard1), (f2, heard2)) = (
        talker("Robot1", "Robot2", &[0, 4, 0, 0, 9, 1, 0]),
        talker("Robot2", "Robot1", &[]),
    );
    // Each UAV on its own thread, as two programs would be.
    let cancel = CancellationToken::new();
    let fly = |settings: RunSettings, factory: Box<dyn Fn() -> Box<dyn Agent> + Send + Sync>| {
        let cancel = cancel.clone();
        std::thread::spawn(move || {
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            runtime.block_on(ucc_client::run(
                &settings,
                &factory,
                &mut |_: &Progress| {},
                &cancel,
            ))
        })
    };
    let (t1, t2) = (fly(one, Box::new(f1)), fly(two, Box::new(f2)));
    let (r1, r2) = tokio::task::spawn_blocking(move || (t1.join(), t2.join()))
        .await
        .unwrap();
    r1.unwrap().unwrap();
    r2.unwrap().unwrap();
    shutdown.cancel();
    server.await.unwrap().unwrap();
    std::fs::remove_dir_all(&dir).unwrap();

    // The barrier a step at `time` was taken at: lockstep's 0.1 s steps.
    let barrier = |time: f64| (time / 0.1 - 1e-6).ceil() * 0.1;
    let mut checked = 0;
    for (sender, receiver) in [(&heard1, &heard2), (&heard2, &heard1)] {
        let (sender, receiver) = (sender.lock().unwrap(), receiver.lock().unwrap());
        let sent: Vec<f64> = sender
            .iter()
            .enumerate()
            .filter(|(i, _)| (i + 1) % 5 == 0)
            .map(|(_, h)| h.time)
            .collect();
        for h in receiver.iter() {
            for (_, text) in &h.inbox {
                let at: f64 = text.rsplit(' ').next().unwrap().parse().unwrap();
                let first_after = receiver
                    .iter()
                    .map(|r| r.time)
                    .find(|t| *t > barrier(at) + 1e-6)
                    .unwrap();
                assert!(
                    (h.time - first_after).abs() < 1e-6,
                    "{text:?} (barrier {:.2}) arrived at {} instead of {first_after}",
                    barrier(at),
                    h.time
                );
                checked += 1;
            }
        }
        // In range all along (once the WSS knew both positions): every message sent before
        // the receiver's last step arrived or came back undelivered (those sent before the
        // WSS's first evaluation, at 1 s).
        let last = receiver.last().unwrap().time;
        let received: usize = receiver.iter().map(|h| h.inbox.len()).sum();
        let refused: usize = sender.iter().map(|h| h.undelivered.len()).sum();
        let due = sent
            .iter()
            .filter(|t| barrier(**t) + 0.1 < last - 1e-6)
            .count();
        assert!(
            received + refused >= due && refused <= 4,
            "{received} of {due} messages arrived, {refused} refused: {receiver:?}"
        );
    }
    assert!(checked >= 10, "only {checked} messages");
}
