//! `ucc conform HOST:PORT`: a conformance kit for any USARSim-protocol server
//! (docs/conformance.md says what each check means and where its rule comes from).
//!
//! A probe connection checks the NFO a server sends on connect and the GETSTARTPOSES answer.
//! Then, for each robot class (`--robot`, or [`DEFAULT_ROBOTS`]), a connection of its own
//! spawns one robot at the first start pose, watches its STA/SEN stream for a window of
//! simulated time, asks GETCONF and GETGEO for the robot and for every sensor type it
//! reports, drives, sets the camera's field of view where it has one, sends malformed lines
//! and checks the connection still answers; then disconnects (so that the next robot finds
//! its place free). While the first robot is in the world the side ports are tried: the
//! image server, USARTruth and the WSS.
//!
//! Every server line is read by `usar_proto`: a line of a known word must read in its typed
//! form and print back byte for byte (UDK's field names, order, spacing and number
//! formats); its numbers are then checked for plausible units.
//!
//! Exit status: 0 when every mandatory check passed (skips allowed), 1 when one failed, 2
//! for bad input (an address that does not parse, a server that cannot be reached).

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, ValueEnum};
use serde::Serialize;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::time::Instant;
use ucc_client::lines::{LineReader, write_line};
use usar_proto::{Command, Conf, Drive, Geo, Init, ItemQuery, Message, Nfo, ServerMessage, Set};

/// Robot classes tried when no `--robot` is given: UDK's stock robots and ours. A class the
/// server does not offer (no STA after INIT within `--spawn-wait`) is skipped.
pub(crate) const DEFAULT_ROBOTS: [&str; 6] = [
    "AirRobot",
    "stsAirRobot",
    "stsQuadrotor",
    "P3AT",
    "P2AT",
    "Kenaf",
];

/// The row of lines that start with no server word (`unknown-word-format`).
const UNKNOWN_WORD: &str = "UNKNOWN-WORD";

/// STA rate UDK sends (`StatusTimer=0.1`), and the plausible band around it, per simulated
/// second.
const STA_HZ: (f64, f64) = (5.0, 20.0);

/// A side port `--require` can make mandatory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Side {
    /// The image server (`--image-port`).
    Image,
    /// USARTruth (`--truth-port`).
    Truth,
    /// The Wireless Simulation Server (`--wss-port`).
    Wss,
}

/// `ucc conform`'s options.
#[derive(Args, Debug)]
pub(crate) struct ConformArgs {
    /// The server's control port, `host:port` (`127.0.0.1:3000`, `[::1]:3000`).
    #[arg(value_name = "HOST:PORT", value_parser = parse_target)]
    target: Target,
    /// A robot class to spawn and check (`AirRobot`, `USARBot.P3AT`, ...); repeatable. A
    /// named class that does not spawn fails. Default: AirRobot, stsAirRobot, stsQuadrotor,
    /// P3AT, P2AT and Kenaf, each skipped when the server does not offer it.
    #[arg(long, value_name = "CLASS")]
    robot: Vec<String>,
    /// The image server's port on HOST (USARSim: 5003).
    #[arg(long, default_value_t = 5003, value_name = "PORT")]
    image_port: u16,
    /// USARTruth's port on HOST (USARSim: 3989).
    #[arg(long, default_value_t = 3989, value_name = "PORT")]
    truth_port: u16,
    /// The WSS's port on HOST (50000).
    #[arg(long, default_value_t = 50000, value_name = "PORT")]
    wss_port: u16,
    /// Make a side port's checks mandatory (repeatable): a refused connection then fails
    /// instead of being skipped.
    #[arg(long, value_name = "image|truth|wss")]
    require: Vec<Side>,
    /// Print the results as one JSON object (for CI) instead of the table.
    #[arg(long)]
    json: bool,
    /// Wall-clock seconds to wait for any one answer (generous: a loaded machine is slow).
    #[arg(long, default_value_t = 30.0, value_name = "SECONDS", value_parser = seconds)]
    timeout: f64,
    /// Wall-clock seconds to wait for the first STA of a default class before counting it as
    /// not offered (UDK answers an unknown class with silence).
    #[arg(long, default_value_t = 5.0, value_name = "SECONDS", value_parser = seconds)]
    spawn_wait: f64,
    /// Simulated seconds of STA/SEN stream to watch per robot (rates are measured over it).
    #[arg(long, default_value_t = 2.0, value_name = "SECONDS", value_parser = seconds)]
    window: f64,
}

/// `host` and `port` of HOST:PORT.
#[derive(Debug, Clone)]
pub(crate) struct Target {
    host: String,
    port: u16,
}

impl Target {
    fn at(&self, port: u16) -> String {
        format!("{}:{port}", self.host)
    }
}

fn parse_target(text: &str) -> Result<Target, String> {
    let bad = || format!("expected HOST:PORT (e.g. 127.0.0.1:3000), not {text:?}");
    let (host, port) = text.rsplit_once(':').ok_or_else(bad)?;
    let port: u16 = port.parse().ok().filter(|p| *p > 0).ok_or_else(bad)?;
    let inner = host.trim_start_matches('[').trim_end_matches(']');
    if inner.is_empty() || inner.chars().any(|c| c.is_whitespace() || c.is_control()) {
        return Err(bad());
    }
    if inner.contains(':') && !host.starts_with('[') {
        return Err(format!(
            "write an IPv6 address in brackets: [{inner}]:{port}"
        ));
    }
    Ok(Target {
        host: host.to_owned(),
        port,
    })
}

fn seconds(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if (0.1..=3600.0).contains(&v) => Ok(v),
        _ => Err(format!("expected seconds from 0.1 to 3600, not {text:?}")),
    }
}

/// A check's result.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub(crate) enum Outcome {
    /// The server did what the protocol says.
    Pass,
    /// It did not.
    Fail,
    /// Not applicable here (a class not offered, a side port that is not there).
    Skip,
}

impl Outcome {
    fn word(self) -> &'static str {
        match self {
            Self::Pass => "pass",
            Self::Fail => "fail",
            Self::Skip => "skip",
        }
    }
}

/// One row of the report.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Check {
    /// `sta-format stsAirRobot`.
    check: String,
    result: Outcome,
    /// Whether a failure makes the exit status non-zero.
    mandatory: bool,
    /// What was checked, or what was wrong.
    detail: String,
    /// The offending line (a failure), as the server sent it.
    #[serde(skip_serializing_if = "Option::is_none")]
    line: Option<String>,
}

#[derive(Debug, Default, Serialize)]
struct Report {
    target: String,
    passed: bool,
    checks: Vec<Check>,
}

impl Report {
    fn add(&mut self, check: String, result: Outcome, detail: String, line: Option<String>) {
        self.checks.push(Check {
            check,
            result,
            mandatory: true,
            detail,
            line,
        });
    }
    fn pass(&mut self, check: String, detail: impl Into<String>) {
        self.add(check, Outcome::Pass, detail.into(), None);
    }
    fn fail(&mut self, check: String, detail: impl Into<String>, line: Option<&str>) {
        self.add(check, Outcome::Fail, detail.into(), line.map(str::to_owned));
    }
    fn skip(&mut self, check: String, detail: impl Into<String>) {
        self.add(check, Outcome::Skip, detail.into(), None);
    }
    fn failed(&self) -> bool {
        self.checks
            .iter()
            .any(|c| c.mandatory && c.result == Outcome::Fail)
    }
}

/// One line the server sent, as read.
struct Received {
    line: String,
    message: ServerMessage,
}

impl Received {
    /// Whether this is an STA line, typed or not (a server whose STA does not fit the layout
    /// still streams): its time, 0 when unreadable.
    fn sta_time(&self) -> Option<f64> {
        if !Message::word(&self.line).eq_ignore_ascii_case("STA") {
            return None;
        }
        Some(match &self.message {
            ServerMessage::Sta(sta) => sta.time.seconds,
            _ => Message::parse(&self.line)
                .ok()
                .and_then(|p| p.message.get("Time")?.trim().parse().ok())
                .unwrap_or(0.0),
        })
    }
}

/// A control-port connection: usar_proto reads every line, ucc_client's line framing.
struct Conn {
    lines: LineReader<OwnedReadHalf>,
    writer: OwnedWriteHalf,
}

impl Conn {
    async fn open(addr: &str, timeout: Duration) -> Result<Self, String> {
        let stream = tokio::time::timeout(timeout, TcpStream::connect(addr))
            .await
            .map_err(|_| format!("cannot connect to {addr}: no answer within {timeout:?}"))?
            .map_err(|e| format!("cannot connect to {addr}: {e}"))?;
        let _ = stream.set_nodelay(true);
        let (read, writer) = stream.into_split();
        Ok(Self {
            lines: LineReader::new(read),
            writer,
        })
    }

    /// Sends a line as it is (a malformed one too), with `\r\n`.
    async fn send_line(&mut self, line: &str) -> Result<(), String> {
        write_line(&mut self.writer, line)
            .await
            .map_err(|e| format!("cannot send {line:?}: {e}"))
    }

    async fn send(&mut self, command: &Command) -> Result<(), String> {
        command.check().map_err(|e| format!("cannot send {e}"))?;
        self.send_line(&command.to_string()).await
    }

    /// The next line, or `None` once `deadline` passed; an error when the server closed
    /// the connection or reading failed.
    async fn next(&mut self, deadline: Instant) -> Result<Option<Received>, String> {
        loop {
            let line = match tokio::time::timeout_at(deadline, self.lines.next_line()).await {
                Err(_) => return Ok(None),
                Ok(Ok(Some(line))) if line.trim().is_empty() => continue,
                Ok(Ok(Some(line))) => line,
                Ok(Ok(None)) => return Err("the server closed the connection".into()),
                Ok(Err(e)) => return Err(format!("connection lost: {e}")),
            };
            let message = ServerMessage::parse(&line)
                .map(|p| p.message)
                .unwrap_or_else(|_| ServerMessage::Other(Message::default()));
            return Ok(Some(Received { line, message }));
        }
    }

    async fn close(mut self) {
        let _ = self.writer.shutdown().await;
        // Wait (briefly) for the server to close its end: it then has removed the robot.
        let until = Instant::now() + Duration::from_secs(5);
        while let Ok(Some(_)) = self.next(until).await {}
    }
}

/// What a line breaks, if anything: the format (it does not read in its word's typed
/// layout, or prints back to other bytes) or the units (a number out of any plausible
/// range for its key).
fn line_problem(got: &Received) -> Option<String> {
    let word = Message::word(&got.line);
    if !ServerMessage::is_server_word(word) {
        return Some(format!("{word:?} is not a server message word"));
    }
    let known = ["NFO", "STA", "SEN", "CONF", "GEO", "ASTA", "EFF", "DIE"];
    if known.iter().any(|w| w.eq_ignore_ascii_case(word)) {
        if let ServerMessage::Other(_) = got.message {
            return Some(match ServerMessage::parse_strict(&got.line) {
                Err(e) => format!("does not fit the documented layout: {e}"),
                Ok(_) => "does not fit the documented layout".into(),
            });
        }
        let printed = got.message.to_string();
        if printed != got.line {
            return Some(format!(
                "field order, spacing or number format differs from UDK's: expected {printed:?}"
            ));
        }
    }
    units_problem(&got.line)
}

/// The numbers of a line against plausible ranges for their keys (metres, radians, seconds,
/// not Unreal units or degrees).
fn units_problem(line: &str) -> Option<String> {
    let message = Message::parse(line).ok()?.message;
    let pairs = message.groups.iter().flat_map(|g| &g.pairs);
    let (mut min_range, mut max_range) = (None, None);
    for pair in pairs {
        let key = pair.key.to_ascii_lowercase();
        let numbers: Vec<f64> = pair
            .value
            .split(',')
            .filter_map(|v| v.trim().parse::<f64>().ok())
            .collect();
        let out = |limit: f64| numbers.iter().any(|v| v.is_nan() || v.abs() > limit);
        let tau = std::f64::consts::TAU + 0.01;
        let bad = match key.as_str() {
            "time" => out(1e7) || numbers.iter().any(|v| *v < 0.0),
            "location" | "pose" | "cog" => out(1e4),
            "orientation" | "rotation" => out(2.0 * tau),
            "fov" | "resolution" => out(tau),
            "range" => numbers.iter().any(|v| !(-1.0..=1000.0).contains(v)),
            "scaninterval" => numbers.iter().any(|v| !(*v > 0.0 && *v <= 60.0)),
            "minrange" => {
                min_range = numbers.first().copied();
                numbers.iter().any(|v| *v < 0.0)
            }
            "maxrange" => {
                max_range = numbers.first().copied();
                out(1e4)
            }
            _ => numbers.iter().any(|v| !v.is_finite()),
        };
        if bad {
            return Some(format!(
                "{{{} {}}}: a value out of the plausible range (metres, radians, seconds)",
                pair.key, pair.value
            ));
        }
    }
    if let (Some(min), Some(max)) = (min_range, max_range)
        && min > max
    {
        return Some(format!("MinRange {min} is above MaxRange {max}"));
    }
    None
}

/// The first offending line of each kind of line seen on a connection.
#[derive(Default)]
struct Watch {
    /// Message word → (lines seen, first problem and its line).
    words: BTreeMap<String, (usize, Option<(String, String)>)>,
    /// STA times, simulated seconds.
    sta_times: Vec<f64>,
    /// First STA time that went backwards.
    sta_backwards: Option<String>,
    /// SEN type → (lines, names seen).
    sen: BTreeMap<String, (usize, BTreeSet<String>)>,
    /// SEN lines from the window's start.
    counting: bool,
}

impl Watch {
    fn see(&mut self, got: &Received) {
        // Rows are named after server words only (a server sending anything else is one row).
        let word = Message::word(&got.line);
        let word = if ServerMessage::is_server_word(word) {
            word.to_ascii_uppercase()
        } else {
            UNKNOWN_WORD.to_owned()
        };
        let entry = self.words.entry(word.clone()).or_default();
        entry.0 += 1;
        if entry.1.is_none()
            && let Some(problem) = line_problem(got)
        {
            entry.1 = Some((problem, got.line.clone()));
        }
        match &got.message {
            _ if word == "STA" => {
                let Some(time) = got.sta_time() else {
                    return;
                };
                if self.sta_times.last().is_some_and(|t| time < *t) && self.sta_backwards.is_none()
                {
                    self.sta_backwards = Some(got.line.clone());
                }
                self.sta_times.push(time);
            }
            _ if word == "SEN" && self.counting => {
                let generic = Message::parse(&got.line).ok().map(|p| p.message);
                let kind = generic
                    .as_ref()
                    .and_then(|m| m.get("Type"))
                    .unwrap_or("?")
                    .to_owned();
                let entry = self.sen.entry(kind).or_default();
                entry.0 += 1;
                for g in generic.iter().flat_map(|m| &m.groups) {
                    for p in g
                        .pairs
                        .iter()
                        .filter(|p| p.key.eq_ignore_ascii_case("Name"))
                    {
                        entry.1.insert(p.value.clone());
                    }
                }
            }
            _ => {}
        }
    }

    /// One check per message word seen: `<word>-format <suffix>`.
    fn report(&self, report: &mut Report, suffix: &str) {
        for (word, (count, problem)) in &self.words {
            let check = format!("{}-format{suffix}", word.to_ascii_lowercase());
            match problem {
                None => report.pass(
                    check,
                    format!(
                        "{count} line{} in the documented layout",
                        if *count == 1 { "" } else { "s" }
                    ),
                ),
                // Lines of no server word: clients ignore them (UDK sends none; a server may
                // send an error line), so they are reported, not counted in the exit status.
                Some((problem, line)) if word == UNKNOWN_WORD => {
                    report.fail(check, format!("{problem} (advisory)"), Some(line));
                    if let Some(last) = report.checks.last_mut() {
                        last.mandatory = false;
                    }
                }
                Some((problem, line)) => report.fail(check, problem.clone(), Some(line)),
            }
        }
    }
}

/// The session of one connection: a [`Conn`] whose every line is watched.
struct Session {
    conn: Conn,
    watch: Watch,
    timeout: Duration,
}

impl Session {
    fn deadline(&self) -> Instant {
        Instant::now() + self.timeout
    }

    /// The next line, watched.
    async fn next(&mut self, deadline: Instant) -> Result<Option<Received>, String> {
        let got = self.conn.next(deadline).await?;
        if let Some(got) = &got {
            self.watch.see(got);
        }
        Ok(got)
    }

    /// Lines until an STA (returned, typed or not), `None` when the deadline passes.
    async fn next_sta(&mut self, deadline: Instant) -> Result<Option<Received>, String> {
        while let Some(got) = self.next(deadline).await? {
            if got.sta_time().is_some() {
                return Ok(Some(got));
            }
        }
        Ok(None)
    }

    /// Sends `command` and waits for the first line of word `word` (CONF, GEO, NFO).
    async fn ask(&mut self, command: &Command, word: &str) -> Result<Option<Received>, String> {
        self.conn.send(command).await?;
        let deadline = self.deadline();
        while let Some(got) = self.next(deadline).await? {
            if Message::word(&got.line).eq_ignore_ascii_case(word) {
                return Ok(Some(got));
            }
        }
        Ok(None)
    }

    /// Whether the connection still streams: the next STA arrives.
    async fn streams(&mut self) -> Result<bool, String> {
        let deadline = self.deadline();
        Ok(self.next_sta(deadline).await?.is_some())
    }
}

/// Runs `ucc conform`: prints the table (or JSON) and returns the exit status.
pub(crate) async fn conform(args: ConformArgs) -> anyhow::Result<ExitCode> {
    let addr = args.target.at(args.target.port);
    let timeout = Duration::from_secs_f64(args.timeout);
    let mut report = Report {
        target: addr.clone(),
        ..Report::default()
    };
    // The probe: NFO on connect, GETSTARTPOSES. A server that cannot be reached is bad input.
    let conn = match Conn::open(&addr, timeout).await {
        Ok(conn) => conn,
        Err(e) => {
            eprintln!("ucc conform: error: {e} (is the server running?)");
            return Ok(ExitCode::from(2));
        }
    };
    let mut probe = Session {
        conn,
        watch: Watch::default(),
        timeout,
    };
    let starts = match probe_checks(&mut probe, &mut report).await {
        Ok(starts) => starts,
        Err(e) => {
            report.fail("connection".into(), e, None);
            Vec::new()
        }
    };
    probe.watch.report(&mut report, "");
    probe.conn.close().await;

    let named = !args.robot.is_empty();
    let classes: Vec<String> = if named {
        args.robot.clone()
    } else {
        DEFAULT_ROBOTS.iter().map(|c| (*c).to_owned()).collect()
    };
    let mut sides_done = false;
    for (i, class) in classes.iter().enumerate() {
        robot_checks(
            &args,
            &mut report,
            class,
            i + 1,
            &starts,
            named,
            &mut sides_done,
        )
        .await;
    }
    if !sides_done {
        side_checks(&args, &mut report, None).await;
    }
    report.passed = !report.failed();
    if args.json {
        // Never a panic on a closed standard output (`ucc conform ... | head`): main's
        // status lines say how it ended.
        crate::status_line(format_args!("{}", serde_json::to_string_pretty(&report)?));
    } else {
        crate::status_line(format_args!("{}", table(&report).trim_end()));
    }
    Ok(if report.passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// NFO on connect and GETSTARTPOSES; the start tags.
async fn probe_checks(probe: &mut Session, report: &mut Report) -> Result<Vec<String>, String> {
    let deadline = probe.deadline();
    match probe.next(deadline).await? {
        Some(got) => match &got.message {
            ServerMessage::Nfo(Nfo::GameInfo { level, .. }) if line_problem(&got).is_none() => {
                report.pass("nfo-on-connect".into(), format!("level {level}"));
            }
            _ => report.fail(
                "nfo-on-connect".into(),
                "the first line is not NFO {Gametype ..} {Level ..} {TimeLimit ..}",
                Some(&got.line),
            ),
        },
        None => report.fail(
            "nfo-on-connect".into(),
            format!("no line within {:?} of connecting", probe.timeout),
            None,
        ),
    }
    let Some(got) = probe.ask(&Command::GetStartPoses, "NFO").await? else {
        report.fail(
            "getstartposes".into(),
            "no NFO {StartPoses ..} answer",
            Some("GETSTARTPOSES"),
        );
        return Ok(Vec::new());
    };
    match &got.message {
        ServerMessage::Nfo(Nfo::StartPoses { poses, .. }) => {
            let tags: Vec<String> = poses.iter().map(|p| p.name.clone()).collect();
            match line_problem(&got) {
                None => report.pass(
                    "getstartposes".into(),
                    format!("{} start poses: {}", tags.len(), tags.join(", ")),
                ),
                Some(problem) => report.fail("getstartposes".into(), problem, Some(&got.line)),
            }
            Ok(tags)
        }
        _ => {
            report.fail(
                "getstartposes".into(),
                "the answer is not NFO {StartPoses n} {tag x,y,z r,p,y ...}",
                Some(&got.line),
            );
            Ok(Vec::new())
        }
    }
}

/// The class name without its package, as the server prints it.
fn short(class: &str) -> &str {
    class.rsplit('.').next().unwrap_or(class)
}

/// Spawns `class` and checks everything about it; checks the side ports too while it is in
/// the world, unless `sides_done`.
async fn robot_checks(
    args: &ConformArgs,
    report: &mut Report,
    class: &str,
    index: usize,
    starts: &[String],
    named: bool,
    sides_done: &mut bool,
) {
    let timeout = Duration::from_secs_f64(args.timeout);
    let addr = args.target.at(args.target.port);
    let suffix = format!(" {}", short(class));
    let conn = match Conn::open(&addr, timeout).await {
        Ok(conn) => conn,
        Err(e) => {
            report.fail(format!("spawn{suffix}"), e, None);
            return;
        }
    };
    let mut session = Session {
        conn,
        watch: Watch::default(),
        timeout,
    };
    let name = format!("Conform{index}");
    let result = robot_session(
        args,
        report,
        &mut session,
        class,
        &name,
        starts,
        named,
        sides_done,
    )
    .await;
    let spawned = match result {
        Ok(spawned) => spawned,
        Err(e) => {
            report.fail(format!("connection{suffix}"), e, None);
            true
        }
    };
    if spawned {
        session.watch.report(report, &suffix);
    }
    session.conn.close().await;
}

#[allow(clippy::too_many_arguments)]
async fn robot_session(
    args: &ConformArgs,
    report: &mut Report,
    s: &mut Session,
    class: &str,
    name: &str,
    starts: &[String],
    named: bool,
    sides_done: &mut bool,
) -> Result<bool, String> {
    let suffix = format!(" {}", short(class));
    let check = |what: &str| format!("{what}{suffix}");
    let init = Init {
        class_name: Init::qualified_class(class),
        name: Some(name.to_owned()),
        start: starts.first().cloned(),
        location: starts.is_empty().then(Default::default),
        rotation: None,
    };
    let init = Command::Init(init);
    s.conn.send(&init).await?;
    let wait = if named {
        s.timeout
    } else {
        Duration::from_secs_f64(args.spawn_wait)
    };
    let first = s.next_sta(Instant::now() + wait).await?;
    let Some(first) = first else {
        let why = format!("no STA within {wait:?} after {init}");
        if named {
            report.fail(check("spawn"), why, None);
        } else {
            report.skip(check("spawn"), format!("not offered: {why}"));
        }
        return Ok(false);
    };
    report.pass(check("spawn"), format!("STA after {init}"));

    // The stream over a window of simulated time: STA and SEN rates.
    let start = first.sta_time().unwrap_or(0.0);
    s.watch.sta_times.clear();
    s.watch.counting = true;
    let deadline = s.deadline();
    let mut end = start;
    while end < start + args.window {
        match s.next(deadline).await? {
            Some(got) => {
                if let Some(time) = got.sta_time() {
                    end = time;
                }
            }
            None => break,
        }
    }
    s.watch.counting = false;
    let span = end - start;
    // STA intervals from the first STA (not in `sta_times` any more) to the last.
    let sta_count = s.watch.sta_times.len();
    if span <= 0.0 {
        report.fail(
            check("sta-rate"),
            format!("simulated time did not advance within {:?}", s.timeout),
            Some(&first.line),
        );
    } else {
        let hz = sta_count as f64 / span;
        let text = format!("{hz:.1} STA per simulated second over {span:.2} s");
        if (STA_HZ.0..=STA_HZ.1).contains(&hz) {
            report.pass(check("sta-rate"), text);
        } else {
            report.fail(
                check("sta-rate"),
                format!("{text}; UDK sends 10 (StatusTimer 0.1 s)"),
                Some(&first.line),
            );
        }
    }
    match &s.watch.sta_backwards {
        None => report.pass(check("sta-time"), "STA times never go backwards"),
        Some(line) => report.fail(check("sta-time"), "STA time went backwards", Some(line)),
    }
    let sen = std::mem::take(&mut s.watch.sen);
    if sen.is_empty() {
        report.skip(check("sen-rate"), "no SEN line in the window");
    } else if span > 0.0 {
        let slow: Vec<String> = sen
            .iter()
            .filter(|(_, (n, _))| (*n as f64 / span) < 0.5 || (*n as f64 / span) > 1000.0)
            .map(|(kind, (n, _))| format!("{kind} {:.1}/s", *n as f64 / span))
            .collect();
        let rates: Vec<String> = sen
            .iter()
            .map(|(kind, (n, _))| format!("{kind} {:.1}", *n as f64 / span))
            .collect();
        if slow.is_empty() {
            report.pass(
                check("sen-rate"),
                format!("per simulated second: {}", rates.join(", ")),
            );
        } else {
            report.fail(
                check("sen-rate"),
                format!("implausible rates (0.5 to 1000 per s): {}", slow.join(", ")),
                None,
            );
        }
    } else {
        report.skip(check("sen-rate"), "no simulated time to measure over");
    }

    // GETCONF / GETGEO for the robot.
    let robot = ItemQuery {
        kind: "Robot".into(),
        name: None,
    };
    let conf = s.ask(&Command::GetConf(robot.clone()), "CONF").await?;
    let mut ground = false;
    match &conf {
        Some(got) => match &got.message {
            ServerMessage::Conf(Conf::Robot { name: n })
                if n.eq_ignore_ascii_case(short(class)) =>
            {
                report.pass(check("getconf-robot"), format!("CONF {{Name {n}}}"));
            }
            ServerMessage::Conf(Conf::GroundVehicle { name: n, .. })
                if n.eq_ignore_ascii_case(short(class)) =>
            {
                ground = true;
                report.pass(check("getconf-robot"), format!("CONF ground vehicle {n}"));
            }
            _ => report.fail(
                check("getconf-robot"),
                format!(
                    "not CONF {{Name {}}} (or the ground-vehicle line)",
                    short(class)
                ),
                Some(&got.line),
            ),
        },
        None => report.fail(
            check("getconf-robot"),
            "no CONF answer",
            Some("GETCONF {Type Robot}"),
        ),
    }
    match s.ask(&Command::GetGeo(robot), "GEO").await? {
        Some(got) => match &got.message {
            ServerMessage::Geo(Geo::Robot { name: n } | Geo::GroundVehicle { name: n, .. })
                if n.eq_ignore_ascii_case(short(class)) =>
            {
                report.pass(check("getgeo-robot"), format!("GEO of {n}"));
            }
            _ => report.fail(
                check("getgeo-robot"),
                format!(
                    "not GEO {{Name {}}} (or the ground-vehicle line)",
                    short(class)
                ),
                Some(&got.line),
            ),
        },
        None => report.fail(
            check("getgeo-robot"),
            "no GEO answer",
            Some("GETGEO {Type Robot}"),
        ),
    }

    // GETCONF / GETGEO per sensor type: the same parts named; SEN names among them.
    let mut consistent = Vec::new();
    let mut inconsistent = None;
    let mut cameras = Vec::new();
    for (kind, (_, sen_names)) in &sen {
        let query = ItemQuery {
            kind: kind.clone(),
            name: None,
        };
        let conf = s.ask(&Command::GetConf(query.clone()), "CONF").await?;
        let geo = s.ask(&Command::GetGeo(query), "GEO").await?;
        let (Some(conf), Some(geo)) = (conf, geo) else {
            inconsistent.get_or_insert((
                format!("no CONF or GEO answer for a sensor type the robot reports: {kind}"),
                format!("GETCONF {{Type {kind}}}"),
            ));
            continue;
        };
        let conf_names = names(&conf.line);
        let geo_names = names(&geo.line);
        if kind.eq_ignore_ascii_case("Camera") {
            cameras.extend(conf_names.iter().cloned());
        }
        if conf_names != geo_names {
            inconsistent.get_or_insert((
                format!("{kind}: CONF names {conf_names:?}, GEO names {geo_names:?}"),
                geo.line.clone(),
            ));
        } else if !sen_names.is_subset(&conf_names) && kind != "Encoder" {
            inconsistent.get_or_insert((
                format!("{kind}: SEN names {sen_names:?} not all in CONF {conf_names:?}"),
                conf.line.clone(),
            ));
        } else {
            consistent.push(format!("{kind} ({})", conf_names.len()));
        }
    }
    match inconsistent {
        Some((why, line)) => report.fail(check("conf-geo"), why, Some(&line)),
        None if consistent.is_empty() => report.skip(check("conf-geo"), "no sensor type reported"),
        None => report.pass(
            check("conf-geo"),
            format!("same parts in CONF, GEO and SEN: {}", consistent.join(", ")),
        ),
    }

    // DRIVE: no answer; the stream goes on.
    let drive = if ground {
        Drive {
            left: Some(0.0),
            right: Some(0.0),
            ..Drive::default()
        }
    } else {
        Drive {
            altitude_velocity: Some(0.0),
            linear_velocity: Some(0.0),
            lateral_velocity: Some(0.0),
            rotational_velocity: Some(0.0),
            ..Drive::default()
        }
    };
    let drive = Command::Drive(drive);
    s.conn.send(&drive).await?;
    if s.streams().await? {
        report.pass(check("drive"), format!("{drive}: the stream goes on"));
    } else {
        report.fail(
            check("drive"),
            "no STA after a DRIVE",
            Some(&drive.to_string()),
        );
    }

    // SET on the camera, where the robot has one.
    match cameras.first() {
        None => report.skip(check("set-camera"), "no camera"),
        Some(camera) => {
            let set = Command::Set(Set {
                kind: "Camera".into(),
                name: Some(camera.clone()),
                opcode: "FOV".into(),
                params: Some("0".into()),
            });
            s.conn.send(&set).await?;
            if s.streams().await? {
                report.pass(check("set-camera"), format!("{set}: the stream goes on"));
            } else {
                report.fail(
                    check("set-camera"),
                    "no STA after SET",
                    Some(&set.to_string()),
                );
            }
        }
    }

    // Side ports while the robot is in the world.
    if !*sides_done {
        side_checks(args, report, Some(name)).await;
        *sides_done = true;
    }

    // Malformed lines: the connection must stay usable.
    let bad = [
        "DRIVE {AltitudeVelocity",
        "}{ not a command {{",
        "NOSUCHCOMMAND {Foo 1}",
        "GETCONF {Type",
        "\u{1}\u{7f}",
    ];
    for line in bad {
        s.conn.send_line(line).await?;
    }
    let again = Command::GetConf(ItemQuery {
        kind: "Robot".into(),
        name: None,
    });
    match s.ask(&again, "CONF").await {
        Ok(Some(_)) => report.pass(
            check("malformed-lines"),
            format!("{} malformed lines, then GETCONF answered", bad.len()),
        ),
        Ok(None) => report.fail(
            check("malformed-lines"),
            "no answer to GETCONF after malformed lines",
            Some(bad[0]),
        ),
        Err(e) => report.fail(
            check("malformed-lines"),
            format!("after malformed lines: {e}"),
            Some(bad[0]),
        ),
    }
    Ok(true)
}

/// Every `{Name ..}` value of a line (CONF, GEO, SEN), any layout.
fn names(line: &str) -> BTreeSet<String> {
    Message::parse(line)
        .map(|p| {
            p.message
                .groups
                .iter()
                .flat_map(|g| &g.pairs)
                .filter(|p| p.key.eq_ignore_ascii_case("Name"))
                .map(|p| p.value.clone())
                .collect()
        })
        .unwrap_or_default()
}

/// Opens a side port: `None` (and a skip or, when required, a failure) when it refuses.
async fn side_open(
    args: &ConformArgs,
    report: &mut Report,
    side: Side,
    port: u16,
    check: &str,
) -> Option<TcpStream> {
    let addr = args.target.at(port);
    let timeout = Duration::from_secs_f64(args.timeout);
    let required = args.require.contains(&side);
    let error = match tokio::time::timeout(timeout, TcpStream::connect(&addr)).await {
        Ok(Ok(stream)) => return Some(stream),
        Ok(Err(e)) => e.to_string(),
        Err(_) => format!("no answer within {timeout:?}"),
    };
    if required {
        report.fail(check.into(), format!("{addr}: {error}"), None);
    } else {
        report.skip(check.into(), format!("{addr}: {error} (not required)"));
    }
    None
}

/// The image server, USARTruth and the WSS, with `robot` in the world (if any).
async fn side_checks(args: &ConformArgs, report: &mut Report, robot: Option<&str>) {
    let timeout = Duration::from_secs_f64(args.timeout);
    if let Some(stream) = side_open(args, report, Side::Image, args.image_port, "image").await {
        let (result, detail) = image_check(stream, timeout).await;
        report.add("image".into(), result, detail, None);
    }
    if let Some(stream) = side_open(args, report, Side::Truth, args.truth_port, "usartruth").await {
        match truth_check(stream, timeout, robot).await {
            Ok(detail) => report.pass("usartruth".into(), detail),
            Err((why, line)) => report.fail("usartruth".into(), why, line.as_deref()),
        }
    }
    if let Some(stream) = side_open(args, report, Side::Wss, args.wss_port, "wss").await {
        match wss_check(stream, timeout, robot.unwrap_or("ConformWss")).await {
            Ok(detail) => report.pass("wss".into(), detail),
            Err((why, line)) => report.fail("wss".into(), why, line.as_deref()),
        }
    }
}

/// `OK`, then one frame: a type byte, a big-endian size, a payload that decodes.
async fn image_check(mut stream: TcpStream, timeout: Duration) -> (Outcome, String) {
    use usar_proto::image::{FrameParser, ImageRequest};
    if let Err(e) = stream.write_all(&ImageRequest::Full.to_bytes()).await {
        return (Outcome::Fail, format!("cannot send OK: {e}"));
    }
    let mut parser = FrameParser::new(ucc_client::camera::MAX_FRAME);
    let mut buf = vec![0u8; 1 << 16];
    let deadline = Instant::now() + timeout;
    loop {
        match parser.next_frame() {
            Err(e) => return (Outcome::Fail, format!("bad frame: {e}")),
            Ok(Some(frame)) => {
                return match ucc_client::camera::decode(&frame, true, 0) {
                    Ok(image) => (
                        Outcome::Pass,
                        format!(
                            "frame of type {}, {}x{}",
                            frame.kind, image.width, image.height
                        ),
                    ),
                    Err(e) => (Outcome::Fail, format!("frame does not decode: {e}")),
                };
            }
            Ok(None) => {}
        }
        match tokio::time::timeout_at(deadline, stream.read(&mut buf)).await {
            Err(_) => {
                return (
                    Outcome::Skip,
                    format!("connected, no frame within {timeout:?} (no camera in the world?)"),
                );
            }
            Ok(Ok(0)) => return (Outcome::Fail, "closed without a frame".into()),
            Ok(Ok(n)) => parser.push(&buf[..n]),
            Ok(Err(e)) => return (Outcome::Fail, format!("read failed: {e}")),
        }
    }
}

type SideResult = Result<String, (String, Option<String>)>;

/// The default query (an empty line): `{Name} {Class} {Time} {Location} {Rotation}` lines in
/// this order, then `{End}`; the spawned robot among them.
async fn truth_check(stream: TcpStream, timeout: Duration, robot: Option<&str>) -> SideResult {
    let (read, mut write) = stream.into_split();
    let mut lines = LineReader::new(read);
    write_line(&mut write, "")
        .await
        .map_err(|e| (format!("cannot send: {e}"), None))?;
    let deadline = Instant::now() + timeout;
    let mut actors = Vec::new();
    loop {
        let line = match tokio::time::timeout_at(deadline, lines.next_line()).await {
            Err(_) => return Err((format!("no {{End}} within {timeout:?}"), None)),
            Ok(Ok(Some(line))) => line,
            Ok(Ok(None)) => return Err(("closed before {End}".into(), None)),
            Ok(Err(e)) => return Err((format!("read failed: {e}"), None)),
        };
        if line.trim() == "{End}" {
            break;
        }
        let keys: Vec<String> = Message::parse(&line)
            .map(|p| {
                p.message
                    .groups
                    .iter()
                    .flat_map(|g| &g.pairs)
                    .map(|p| p.key.clone())
                    .collect()
            })
            .unwrap_or_default();
        if keys != ["Name", "Class", "Time", "Location", "Rotation"] || !line.starts_with('{') {
            return Err((
                "not {Name ..} {Class ..} {Time ..} {Location x,y,z} {Rotation r,p,y}".into(),
                Some(line),
            ));
        }
        if let Some(problem) = units_problem(&line) {
            return Err((problem, Some(line)));
        }
        actors.push(names(&line).into_iter().next().unwrap_or_default());
    }
    if let Some(robot) = robot
        && !actors.iter().any(|a| a == robot)
    {
        return Err((
            format!("the spawned robot {robot} is not among {actors:?}"),
            None,
        ));
    }
    Ok(format!("{} actors, then {{End}}", actors.len()))
}

/// `INIT {Robot r} {Port p}` → `INITREPLY {Status OK}`; `GETSS` of an unknown robot → `SS
/// {Robot ..} {Strength ..} ...` with a number (NaN/INF allowed).
async fn wss_check(stream: TcpStream, timeout: Duration, robot: &str) -> SideResult {
    let (read, mut write) = stream.into_split();
    let mut lines = LineReader::new(read);
    let deadline = Instant::now() + timeout;
    let mut ask = async |line: &str| -> Result<String, (String, Option<String>)> {
        write_line(&mut write, line)
            .await
            .map_err(|e| (format!("cannot send {line}: {e}"), None))?;
        match tokio::time::timeout_at(deadline, lines.next_line()).await {
            Ok(Ok(Some(reply))) => Ok(reply),
            Err(_) => Err((format!("no answer to {line} within {timeout:?}"), None)),
            Ok(Ok(None)) => Err((format!("closed after {line}"), None)),
            Ok(Err(e)) => Err((format!("read failed: {e}"), None)),
        }
    };
    let init = format!("INIT {{Robot {robot}}} {{Port 5874}}");
    let reply = ask(&init).await?;
    if reply != "INITREPLY {Status OK}" {
        return Err((
            format!("not INITREPLY {{Status OK}} for {init}"),
            Some(reply),
        ));
    }
    let reply = ask("GETSS {Robot ConformNoSuchRobot}").await?;
    let message = Message::parse(&reply).map(|p| p.message).ok();
    let fits = message.as_ref().is_some_and(|m| {
        let keys: Vec<&str> = m
            .groups
            .iter()
            .flat_map(|g| &g.pairs)
            .map(|p| p.key.as_str())
            .collect();
        m.kind == "SS"
            && keys.starts_with(&["Robot", "Strength"])
            && m.get("Strength")
                .is_some_and(|v| v.parse::<f64>().is_ok() || matches!(v, "NaN" | "INF" | "-INF"))
    });
    if !fits {
        return Err((
            "not SS {Robot ..} {Strength ..} [{Error ..}]".into(),
            Some(reply),
        ));
    }
    Ok(format!("INITREPLY, then {reply}"))
}

/// The report as a table: check, result, what was checked or wrong, the offending line.
fn table(report: &Report) -> String {
    let width = report
        .checks
        .iter()
        .map(|c| c.check.len())
        .max()
        .unwrap_or(5)
        .max(5);
    let mut out = format!(
        "{:<width$}  {:<6}  detail / offending line\n",
        "check", "result"
    );
    for c in &report.checks {
        let _ = writeln!(
            out,
            "{:<width$}  {:<6}  {}",
            c.check,
            c.result.word(),
            c.detail
        );
        if let Some(line) = &c.line {
            let _ = writeln!(out, "{:<width$}  {:<6}  > {line}", "", "");
        }
    }
    let count = |o: Outcome, mandatory: bool| {
        report
            .checks
            .iter()
            .filter(|c| c.result == o && c.mandatory == mandatory)
            .count()
    };
    let advisory = match count(Outcome::Fail, false) {
        0 => String::new(),
        n => format!(" (and {n} advisory)"),
    };
    let _ = writeln!(
        out,
        "{}: {} passed, {} failed{advisory}, {} skipped ({})",
        report.target,
        count(Outcome::Pass, true),
        count(Outcome::Fail, true),
        count(Outcome::Skip, true),
        if report.passed {
            "conforms"
        } else {
            "does NOT conform"
        }
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_parse_or_say_why() {
        let t = parse_target("127.0.0.1:3000").unwrap();
        assert_eq!((t.host.as_str(), t.port), ("127.0.0.1", 3000));
        assert_eq!(parse_target("[::1]:3000").unwrap().at(5003), "[::1]:5003");
        for bad in [
            "",
            "localhost",
            ":3000",
            "host:",
            "host:0",
            "host:99999",
            "::1:3000",
            "a b:1",
        ] {
            assert!(parse_target(bad).is_err(), "{bad}");
        }
    }

    fn got(line: &str) -> Received {
        Received {
            line: line.into(),
            message: ServerMessage::parse(line).unwrap().message,
        }
    }

    #[test]
    fn lines_are_checked_for_layout_and_units() {
        assert_eq!(
            line_problem(&got("STA {Time 12.3456} {Battery 99999}")),
            None
        );
        assert!(line_problem(&got("STA {Time 12.3456}")).is_some());
        assert!(line_problem(&got("STA {Battery 99999} {Time 12.3456}")).is_some());
        assert!(line_problem(&got("sta {Time 12.3456} {Battery 99999}")).is_some());
        assert!(line_problem(&got("STA {Time 12.3456} {Battery 99999.5}")).is_some());
        let geo = "GEO {Type Sonar} {Name F1} {Location 0.19,-0.12,0.00} {Orientation 0.00,0.00,-0.87}{Mount P3AT}";
        assert_eq!(line_problem(&got(geo)), None);
        // Unreal units where metres belong.
        let geo = "GEO {Type Sonar} {Name F1} {Location 19000.00,-0.12,0.00} {Orientation 0.00,0.00,-0.87}{Mount P3AT}";
        assert!(line_problem(&got(geo)).unwrap().contains("Location"));
        // Degrees where radians belong.
        let conf = "CONF {Type RangeScanner} {Name lms200} {MaxRange 20.0000} {MinRange 0.1000} {Resolution 0.0174} {Fov 180.0000} {Panning True} {Tilting False}";
        assert!(line_problem(&got(conf)).unwrap().contains("Fov"));
    }
}
