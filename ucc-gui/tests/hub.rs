//! The hub's answers to names, numbers and long runs (issue #23's defects 1, 3, 4, 5), without
//! a browser or a server.

use std::path::{Component, Path};

use ucc_gui::hub::{Action, Cursor, Hub, Request};

fn hub() -> Hub {
    Hub::new(
        "127.0.0.1:3000".into(),
        false,
        std::env::temp_dir().join("ucc-gui-hub-test"),
    )
}

fn create(hub: &mut Hub, name: &str) -> Result<u32, String> {
    match hub.apply(Request::Create {
        robot: "stsAirRobot".into(),
        agent: "base".into(),
        start: "0,0,-1".into(),
        name: name.into(),
    }) {
        Ok(Action::Created(id)) => Ok(id),
        Ok(other) => panic!("{other:?}"),
        Err(e) => Err(e.to_string()),
    }
}

fn goto(uav: u32, x: &str) -> Request {
    Request::AddMission {
        uav,
        kind: "GotoXyz".into(),
        x: x.into(),
        y: "0".into(),
        z: "-2".into(),
        seconds: String::new(),
    }
}

/// Defect 1: whatever the name, a run's files land directly in the log directory.
#[test]
fn names_never_lead_files_out_of_the_log_dir() {
    let mut hub = hub();
    let log_dir = hub.log_dir.clone();
    for name in [
        "../escaped",
        "/abs/path",
        "a/../../b",
        "..",
        ".hidden",
        "x\\..\\y",
    ] {
        let Ok(id) = create(&mut hub, name) else {
            continue; // refused with a message: fine too
        };
        hub.apply(goto(id, "1")).unwrap();
        let Ok(Action::Start(_, settings, _)) = hub.apply(Request::Start {
            uav: id,
            iterations: "1".into(),
        }) else {
            panic!("{name}: no start")
        };
        let file = settings.file("01.log").unwrap();
        assert_eq!(
            file.parent(),
            Some(log_dir.as_path()),
            "{name:?} writes {}",
            file.display()
        );
        let last = Path::new(file.file_name().unwrap());
        assert!(
            last.components().all(|c| matches!(c, Component::Normal(_))),
            "{name:?}: {last:?}"
        );
        assert!(
            !file.file_name().unwrap().to_string_lossy().starts_with('.'),
            "{name:?}: a hidden file {}",
            file.display()
        );
    }
    // The prefix form refuses what the default would not have produced.
    let id = create(&mut hub, "ok").unwrap();
    let e = hub
        .apply(Request::Options {
            uav: id,
            prefix: "../x".into(),
            pictures: "all".into(),
            autosave: true,
        })
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("file prefix: "), "{e}");
}

/// Defect 4: names with control characters, or absurdly long, are refused with a message.
#[test]
fn names_with_control_characters_or_too_long_are_refused() {
    let mut hub = hub();
    for name in ["a\tb", "a\nb", "a\rGETSTARTPOSES", "nul\0", "bell\u{7}"] {
        let e = create(&mut hub, name).unwrap_err();
        assert!(
            e.starts_with("name: ") && e.contains("control character"),
            "{name:?}: {e}"
        );
    }
    let long = "x".repeat(100_000);
    let e = create(&mut hub, &long).unwrap_err();
    assert!(e.starts_with("name: ") && e.contains("64"), "{e}");
    assert!(e.len() < 200, "the message does not repeat the name: {e}");
    assert!(create(&mut hub, &"y".repeat(64)).is_ok());
    // HTML is only text: it is accepted and shown as text by the page.
    assert!(create(&mut hub, "<b>bold</b>").is_ok());
}

/// Defect 5: coordinates beyond any map are refused, not drawn.
#[test]
fn huge_coordinates_are_refused() {
    let mut hub = hub();
    let id = create(&mut hub, "").unwrap();
    for x in ["1e8", "1e12", "-3e5"] {
        let e = hub.apply(goto(id, x)).unwrap_err().to_string();
        assert!(
            e.starts_with("mission x: ") && e.contains("100000"),
            "{x}: {e}"
        );
    }
    hub.apply(goto(id, "99999")).unwrap();
    let e = match hub.apply(Request::Create {
        robot: "stsAirRobot".into(),
        agent: "base".into(),
        start: "1e12,0,-1".into(),
        name: String::new(),
    }) {
        Err(e) => e.to_string(),
        Ok(a) => panic!("{a:?}"),
    };
    assert!(e.starts_with("start pose: ") && e.contains("100000"), "{e}");
}

/// Defect 3: the files of a long run are offered once each, and an update carries them only
/// when they change.
#[test]
fn files_are_listed_once_and_sent_when_they_change() {
    let mut hub = hub();
    let id = create(&mut hub, "").unwrap();
    hub.apply(goto(id, "1")).unwrap();
    hub.apply(Request::Start {
        uav: id,
        iterations: "100".into(),
    })
    .unwrap();
    let mut cursor = Cursor::default();
    let dir = hub.log_dir.clone();
    for i in 1..=100 {
        hub.new_iteration(id, i);
        let files = vec![
            dir.join(format!("UAV1-{i:02}.log")),
            dir.join("UAV1-overlay.png"),
            dir.join("UAV1-results.csv"),
        ];
        hub.written(id, &files);
    }
    let u = hub.update(&mut cursor);
    assert_eq!(u["uavs"][0]["files"]["total"], 102);
    let files = u["uavs"][0]["files"]["recent"].as_array().unwrap();
    assert!(files.len() <= ucc_gui::hub::update::RECENT_FILES);
    let names: Vec<&str> = files.iter().map(|f| f["name"].as_str().unwrap()).collect();
    assert!(names.contains(&"UAV1-100.log"), "{names:?}");
    assert_eq!(hub.uavs[0].files.len(), 102);
    let again = hub.update(&mut cursor);
    assert!(
        again["uavs"][0].get("files").is_none_or(|f| f.is_null()),
        "unchanged files are not sent again: {}",
        again["uavs"][0]
    );
}

/// The overlay of a long loop stays bounded in the hub (the page's memory follows).
#[test]
fn a_long_loop_keeps_the_overlay_bounded() {
    let mut hub = hub();
    let id = create(&mut hub, "").unwrap();
    hub.apply(goto(id, "1")).unwrap();
    hub.apply(Request::Start {
        uav: id,
        iterations: "10000".into(),
    })
    .unwrap();
    for i in 1..=2_000 {
        hub.new_iteration(id, i);
        for k in 0..200 {
            hub.sample(
                id,
                i,
                ucc_gui::hub::Live {
                    time: k as f64 * 0.1,
                    position: Some([k as f64 * 0.01, 0.0, -1.0]),
                    ..Default::default()
                },
            );
        }
    }
    let points: usize = hub.uavs[0].past.iter().map(Vec::len).sum();
    assert!(points <= 100_000, "{points} overlay points kept");
    assert!(hub.uavs[0].past.len() >= 10, "recent iterations kept");
}

/// Issue 20: the page gets the victims after the solids, each once, with its name and class.
#[test]
fn the_page_gets_the_victims_with_their_names() {
    let mut hub = hub();
    let map = usar_server::sim::Map::embedded("rescue").unwrap();
    hub.geometry = Some(ucc_client::picture::MapGeometry::from(&map));
    let geometry = hub.geometry_json();
    let entries = geometry.as_array().unwrap();
    let victims: Vec<(&str, &str)> = entries
        .iter()
        .filter_map(|e| Some((e["victim"].as_str()?, e["class"].as_str()?)))
        .collect();
    assert_eq!(
        victims,
        [
            ("Victim1", "FemaleVictim"),
            ("Victim2", "MaleVictim"),
            ("Victim3", "MaleVictim"),
            ("Victim4", "FemaleVictim")
        ]
    );
    let solids = entries.iter().filter(|e| e.get("victim").is_none()).count();
    assert_eq!(
        solids + 4,
        hub.geometry.as_ref().unwrap().footprints.len(),
        "victims are not drawn twice"
    );
}

/// Issue 20: a run reads camera frames (while the panel asks) only for a robot class with a
/// camera on a server with an image server: a stsAirRobot's run asks nothing (no "no camera"
/// warning in every run's log), an AirRobot's does, switched off until a page asks.
#[test]
fn only_robots_with_a_camera_get_the_camera_setting() {
    let mut hub = hub();
    hub.image_server = Some("127.0.0.1:5003".into());
    hub.camera_classes = vec!["USARBot.AirRobot".into()];
    let mut settings_of = |robot: &str| {
        let Ok(Action::Created(id)) = hub.apply(Request::Create {
            robot: robot.into(),
            agent: "base".into(),
            start: "0,0,-1".into(),
            name: String::new(),
        }) else {
            panic!("not created");
        };
        hub.apply(goto(id, "1")).unwrap();
        let Ok(Action::Start(_, settings, _)) = hub.apply(Request::Start {
            uav: id,
            iterations: "1".into(),
        }) else {
            panic!("not started");
        };
        settings
    };
    assert!(settings_of("stsAirRobot").camera.is_none());
    let camera = settings_of("AirRobot")
        .camera
        .expect("the AirRobot's camera");
    assert_eq!(camera.server, "127.0.0.1:5003");
    assert!(!camera.is_active(), "no frames until a page asks");
}

/// Issue #26 (the browser soak): a long loop's log costs the hub little memory. Five lines an
/// iteration for 10,000 iterations keep only the newest few thousand (well under 1 MiB of
/// text), the newest last; the complete log of a run is its log files (`PREFIX-NN.log`).
#[test]
fn a_long_loop_keeps_a_small_log() {
    let mut hub = hub();
    for iteration in 1..=10_000 {
        for k in 0..5 {
            hub.log(
                1,
                "info",
                format!("[{iteration}] mission 1 GotoXyz reached at t={k}.25 s, 0.031 m away"),
            );
        }
    }
    assert!(hub.log.len() <= 5_000, "{} lines kept", hub.log.len());
    let text = hub.log_text(None, "");
    assert!(text.len() < 512 * 1024, "{} bytes of log kept", text.len());
    assert!(
        text.ends_with("[10000] mission 1 GotoXyz reached at t=4.25 s, 0.031 m away\n"),
        "the newest line is kept: {:?}",
        text.lines().last()
    );
}

fn at(x: f64, y: f64) -> ucc_gui::hub::Live {
    ucc_gui::hub::Live {
        time: 1.0,
        position: Some([x, y, -1.0]),
        attitude: Some([0.0, 0.0, 0.5]),
        velocity: Some([1.0, 0.0, 0.0]),
        ..Default::default()
    }
}

fn entry(update: &serde_json::Value, id: u32) -> Option<serde_json::Value> {
    update["uavs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|u| u["id"] == id)
        .cloned()
}

/// #23, "send only what is in view": a UAV outside the page's map is sent a light summary (no
/// trail, no plots, no velocity), and its detail comes when the map is panned onto it.
#[test]
fn a_uav_out_of_view_gets_a_summary_and_its_detail_when_panned_into_view() {
    let mut hub = hub();
    let near = create(&mut hub, "Near").unwrap();
    let far = create(&mut hub, "Far").unwrap();
    let mut cursor = Cursor::default();
    cursor.selected = Some(near);
    hub.apply(Request::View {
        x0: -10.0,
        x1: 10.0,
        y0: -10.0,
        y1: 10.0,
    })
    .unwrap();
    cursor.view = Some([-10.0, 10.0, -10.0, 10.0]);
    for i in 0..20 {
        hub.sample(near, 1, at(f64::from(i) * 0.1, 0.0));
        hub.sample(far, 1, at(100.0 + f64::from(i) * 0.1, 100.0));
    }
    let first = hub.update(&mut cursor);
    let n = entry(&first, near).unwrap();
    assert_eq!(n["trail"].as_array().unwrap().len(), 20, "{n}");
    assert!(n["live"]["velocity"].is_array(), "{n}");
    let f = entry(&first, far).unwrap();
    assert!(
        f.get("trail").is_none(),
        "trail of a UAV out of view sent: {f}"
    );
    assert!(
        f.get("history").is_none(),
        "plots of a UAV out of view sent: {f}"
    );
    assert_eq!(f["live"]["summary"], true, "{f}");
    assert!(f["live"].get("velocity").is_none(), "{f}");
    assert_eq!(f["live"]["position"][0], 101.9, "{f}");
    assert!(f["info"]["name"] == "Far", "the list needs its info: {f}");
    // More samples within the summary period: nothing of it.
    hub.sample(far, 1, at(102.0, 100.0));
    let second = hub.update(&mut cursor);
    assert!(entry(&second, far).is_none(), "{second}");
    // Panned onto it: its whole trail (20 + 1 points) and full live state.
    hub.apply(Request::View {
        x0: 90.0,
        x1: 110.0,
        y0: 90.0,
        y1: 110.0,
    })
    .unwrap();
    cursor.view = Some([90.0, 110.0, 90.0, 110.0]);
    let third = hub.update(&mut cursor);
    let f = entry(&third, far).unwrap();
    assert_eq!(f["trail"].as_array().unwrap().len(), 21, "{f}");
    assert!(f["live"]["velocity"].is_array(), "{f}");
    assert!(f["live"].get("summary").is_none(), "{f}");
    assert!(
        f.get("history").is_none(),
        "plots only for the selected UAV: {f}"
    );
    // The selected UAV stays in detail wherever the map is.
    hub.sample(near, 1, at(5.0, 0.0));
    let fourth = hub.update(&mut cursor);
    let n = entry(&fourth, near).unwrap();
    assert_eq!(n["trail"].as_array().unwrap().len(), 1, "{n}");
    assert!(n["history"].is_array(), "{n}");
}

/// A view with its edges the wrong way round or not finite is refused with a message.
#[test]
fn a_bad_view_is_refused() {
    let mut hub = hub();
    let e = hub
        .apply(Request::View {
            x0: 1.0,
            x1: 0.0,
            y0: 0.0,
            y1: 1.0,
        })
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("view:"), "{e}");
    let e = hub
        .apply(Request::View {
            x0: f64::NAN,
            x1: 0.0,
            y0: 0.0,
            y1: 1.0,
        })
        .unwrap_err()
        .to_string();
    assert!(e.contains("view x0"), "{e}");
}

/// A long backlog of trail (a new page, a UAV coming into view) is sent thinned.
#[test]
fn a_long_trail_backlog_is_thinned() {
    let mut hub = hub();
    let id = create(&mut hub, "Long").unwrap();
    for i in 0..3000 {
        hub.sample(id, 1, at(f64::from(i) * 0.1, 0.0));
    }
    let update = hub.update(&mut Cursor::default());
    let trail = entry(&update, id).unwrap()["trail"]
        .as_array()
        .unwrap()
        .clone();
    assert!(trail.len() <= 501, "{}", trail.len());
    assert!((trail.last().unwrap()[0].as_f64().unwrap() - 299.9).abs() < 0.01);
}

/// Issue #56: two UAVs never write the same files. A second UAV of a name in use, or whose
/// name makes the same file names (`a.b` and `a_b`), is refused with a message naming both;
/// so is a file prefix another UAV writes; a default name skips the names taken.
#[test]
fn two_uavs_never_share_a_name_or_their_files() {
    let mut hub = hub();
    let first = create(&mut hub, "a.b").unwrap();
    let e = create(&mut hub, "a.b").unwrap_err();
    assert_eq!(
        e,
        format!("name: \"a.b\" is taken by UAV {first} (\"a.b\"): choose another name")
    );
    let e = create(&mut hub, "A.B").unwrap_err();
    assert!(e.starts_with("name: \"A.B\" is taken by UAV"), "{e}");
    let e = create(&mut hub, "a_b").unwrap_err();
    assert_eq!(
        e,
        format!(
            "name: \"a_b\" would write over the files of UAV {first} (\"a.b\"), a_b-NN.log…: \
             choose another name"
        )
    );
    // Another name and prefix: fine; then its prefix set to the first one's is refused.
    let second = create(&mut hub, "c").unwrap();
    let options = |uav, prefix: &str| Request::Options {
        uav,
        prefix: prefix.into(),
        pictures: "none".into(),
        autosave: true,
    };
    let e = hub.apply(options(second, "a_b")).unwrap_err().to_string();
    assert!(
        e.starts_with("file prefix: \"a_b\" would write over the files of UAV")
            && e.contains("(\"a.b\")"),
        "{e}"
    );
    hub.apply(options(second, "c2")).unwrap();
    hub.apply(options(second, "c2")).unwrap(); // its own prefix again
    // Both fly: their files differ.
    let mut files = Vec::new();
    for id in [first, second] {
        hub.apply(goto(id, "1")).unwrap();
        let Ok(Action::Start(_, settings, _)) = hub.apply(Request::Start {
            uav: id,
            iterations: "1".into(),
        }) else {
            panic!("no start")
        };
        files.push(settings.file("01.log").unwrap());
    }
    assert_ne!(files[0], files[1]);
    // A default name skips a name the user took.
    let taken = create(&mut hub, &format!("UAV{}", second + 2)).unwrap();
    let id = create(&mut hub, "").unwrap();
    assert_eq!(id, taken + 1);
    let names: Vec<String> = hub.uavs.iter().map(|u| u.name.clone()).collect();
    assert_eq!(names.last().unwrap(), &format!("UAV{id}-2"), "{names:?}");
    // A removed UAV's name is free again, when it wrote no file.
    hub.apply(Request::Remove { uav: taken }).unwrap();
    assert!(create(&mut hub, &format!("UAV{}", second + 2)).is_ok());
}

/// Issue #56: the files a UAV wrote are never written over in the same session, not after
/// it was removed (a new UAV of its name), nor after it took another prefix.
#[test]
fn files_of_a_removed_uav_or_an_old_prefix_are_kept() {
    let mut hub = hub();
    let gone = create(&mut hub, "Scout").unwrap();
    hub.written(gone, &[std::path::PathBuf::from("/logs/Scout-01.log")]);
    hub.apply(Request::Remove { uav: gone }).unwrap();
    let e = create(&mut hub, "scout").unwrap_err();
    assert_eq!(
        e,
        format!(
            "name: \"scout\" would write over the files that UAV {gone} (\"Scout\") wrote \
             earlier, Scout-NN.log…: choose another name"
        )
    );
    // A default name skips it too.
    let id = create(&mut hub, "").unwrap();
    let names: Vec<String> = hub.uavs.iter().map(|u| u.name.clone()).collect();
    assert_eq!(names, [format!("UAV{id}")]);
    // A UAV that wrote files and takes another prefix keeps its old files: another UAV may
    // not take the old prefix, it may go back to it.
    hub.written(
        id,
        &[std::path::PathBuf::from(format!("/logs/UAV{id}-01.log"))],
    );
    let options = |uav, prefix: &str| Request::Options {
        uav,
        prefix: prefix.into(),
        pictures: "none".into(),
        autosave: true,
    };
    hub.apply(options(id, "second")).unwrap();
    let other = create(&mut hub, "Other").unwrap();
    let e = hub
        .apply(options(other, &format!("uav{id}")))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with(&format!(
            "file prefix: \"uav{id}\" would write over the files that UAV {id}"
        )),
        "{e}"
    );
    hub.apply(options(id, &format!("UAV{id}"))).unwrap();
}
