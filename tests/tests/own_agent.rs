//! An agent from outside the crate, as docs/ucc.md shows it: the runner's statistics must be
//! right even when the agent reports no mission events (the defect: an agent that flew all
//! three waypoints got "0 missions in 0.0 simulated s" and `results.csv` said
//! `1,ok,0,0.0000`).

use tokio_util::sync::CancellationToken;
use ucc_client::{
    Agent, Coordinates, Lockstep, Mission, MissionRefused, Progress, RunSettings, Start, Step,
    UavState, agents,
};
use usar_server::{LocalServer, ServerConfig, TimeScale};

/// Flies like the built-in `base` agent but keeps its mission events to itself.
struct Silent(Box<dyn Agent>);

impl Agent for Silent {
    fn name(&self) -> &str {
        "silent"
    }
    fn add_mission(&mut self, m: Mission) -> Result<(), MissionRefused> {
        self.0.add_mission(m)
    }
    fn start(&mut self, time: f64) {
        self.0.start(time);
    }
    fn stop(&mut self) {
        self.0.stop();
    }
    fn step(&mut self, uav: &UavState, time: f64) -> Step {
        Step {
            events: Vec::new(),
            ..self.0.step(uav, time)
        }
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn an_agent_that_reports_no_missions_still_gets_them_counted() {
    let server = LocalServer::start(ServerConfig {
        time_scale: TimeScale::Max,
        lockstep: true,
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let dir = std::env::temp_dir().join(format!("ucc-own-agent-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let settings = RunSettings {
        addr: server.addr().to_string(),
        start: Start::at(Coordinates::new(0.0, 0.0, -1.0)),
        missions: [(1.5, 0.0), (1.5, 1.5), (0.0, 1.5)]
            .map(|(x, y)| Mission::goto(Coordinates::new(x, y, -1.5)))
            .to_vec(),
        lockstep: Lockstep::Required,
        log_dir: Some(dir.clone()),
        ..RunSettings::default()
    };
    let factory = || Box::new(Silent(agents::create("base").unwrap())) as Box<dyn Agent>;
    let mut warnings = Vec::new();
    let summary = ucc_client::run(
        &settings,
        &factory,
        &mut |p: &Progress| {
            if let Progress::Warning { message, .. } = p {
                warnings.push(message.clone());
            }
        },
        &CancellationToken::new(),
    )
    .await
    .unwrap();
    server.stop().await.unwrap();
    let iteration = &summary.iterations[0];
    assert!(iteration.is_done());
    assert_eq!(iteration.missions_done, 3);
    assert!(iteration.duration > 1.0, "{}", iteration.duration);
    assert!(
        warnings.iter().any(|w| w.contains("MissionDone")),
        "the agent is told what it should report: {warnings:?}"
    );
    let results = std::fs::read_to_string(dir.join("UCCLOG-results.csv")).unwrap();
    let row = results.lines().nth(1).unwrap();
    assert!(row.starts_with("1,ok,3,"), "{row}");
    std::fs::remove_dir_all(&dir).unwrap();
}
