//! Line injection (#26): a UAV name, a start tag or a robot class holding `\r\n` reached the
//! wire raw (a recording server logged an injected `GETSTARTPOSES` as its own command); TAB
//! and NUL were accepted too. `run` — which `ucc run` and every UAV of the browser control
//! center go through — refuses such a value before it connects, with an error that names it.

use tokio::io::AsyncReadExt;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use ucc_client::{
    ConnectionError, Coordinates, Mission, Progress, RunError, RunSettings, Start, agents,
};

#[tokio::test]
async fn a_name_tag_or_class_that_would_inject_a_line_is_refused_before_connecting() {
    // A server that records whatever reaches it.
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    let received = tokio::spawn(async move {
        let mut all = String::new();
        while let Ok(Ok((mut socket, _))) =
            tokio::time::timeout(std::time::Duration::from_secs(2), listener.accept()).await
        {
            let _ = socket.read_to_string(&mut all).await;
        }
        all
    });
    let good = RunSettings {
        addr,
        start: Start::Tag("Start1".into()),
        missions: vec![Mission::goto(Coordinates::new(2.0, 0.0, -2.0))],
        ..RunSettings::default()
    };
    let cases = [
        (
            RunSettings {
                name: "UAV1\r\nGETSTARTPOSES".into(),
                ..good.clone()
            },
            "INIT {Name ..}: \"UAV1\\r\\nGETSTARTPOSES\" holds a carriage return",
        ),
        (
            RunSettings {
                start: Start::Tag("Start1\nGETSTARTPOSES".into()),
                ..good.clone()
            },
            "INIT {Start ..}: \"Start1\\nGETSTARTPOSES\" holds a line feed",
        ),
        (
            RunSettings {
                robot: "stsAirRobot\t".into(),
                ..good.clone()
            },
            "INIT {ClassName ..}: \"USARBot.stsAirRobot\\t\" holds a tab",
        ),
        (
            RunSettings {
                name: "UAV\u{0}1".into(),
                ..good.clone()
            },
            "holds a NUL",
        ),
    ];
    let base = agents::info("base").unwrap().create;
    for (settings, message) in cases {
        let err = ucc_client::run(
            &settings,
            &base,
            &mut |_: &Progress| {},
            &CancellationToken::new(),
        )
        .await
        .unwrap_err();
        assert!(
            matches!(err, RunError::Connection(ConnectionError::Unsendable(_))),
            "{err}"
        );
        assert!(err.is_fatal());
        assert!(err.to_string().starts_with("cannot send "), "{err}");
        assert!(err.to_string().contains(message), "{err}");
    }
    assert_eq!(received.await.unwrap(), "", "nothing reached the server");
}
