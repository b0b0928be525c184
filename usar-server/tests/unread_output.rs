//! Output nobody reads never stops the server (issue #56): run as a CI harness often runs
//! it, with its stderr captured into a pipe that is never read, it answers every client and
//! ends on SIGTERM, its recordings complete; with stdout and stderr closed, the same. (It
//! used to stop answering after about 370 connections, once the 64 KiB pipe was full, and
//! SIGTERM no longer ended it.)

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{program, terminate};

/// Connections each test makes (each logs several lines at `debug`).
const CONNECTIONS: usize = 1_500;

/// Generous: the issue asks for 2 s; a loaded machine may take longer, a hang never ends.
const EXIT_DEADLINE: Duration = Duration::from_secs(10);

/// Makes `n` connections to `addr` one after the other, each from one of 100 loopback
/// addresses in turn (so no per-address cap is reached): connects, reads the NFO line,
/// sends a line, closes. Returns the first connection that was not answered, with why.
fn churn(addr: SocketAddr, n: usize) -> Result<(), String> {
    use tokio::io::{AsyncBufReadExt, AsyncWriteExt};
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    runtime.block_on(async {
        for i in 0..n {
            let answered = tokio::time::timeout(Duration::from_secs(10), async {
                let socket = tokio::net::TcpSocket::new_v4()?;
                socket.bind(SocketAddr::from(([127, 0, 0, 2 + (i % 100) as u8], 0)))?;
                let mut stream = tokio::io::BufReader::new(socket.connect(addr).await?);
                let mut line = String::new();
                stream.read_line(&mut line).await?;
                stream.write_all(b"GETSTARTPOSES\r\n").await?;
                std::io::Result::Ok(line)
            });
            match answered.await {
                Ok(Ok(line)) if line.starts_with("NFO") => {}
                Ok(Ok(line)) => return Err(format!("connection {i}: answered {line:?}")),
                Ok(Err(error)) => return Err(format!("connection {i}: {error}")),
                Err(_) => return Err(format!("connection {i}: not answered within 10 s")),
            }
        }
        Ok(())
    })
}

/// Sends SIGTERM and waits for the exit, at most [`EXIT_DEADLINE`]; prints the time taken.
fn stop(child: &mut Child, what: &str) -> std::process::ExitStatus {
    terminate(child);
    let sent = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            println!(
                "{what}: exited {:.3} s after SIGTERM",
                sent.elapsed().as_secs_f64()
            );
            return status;
        }
        if sent.elapsed() > EXIT_DEADLINE {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what}: still running {EXIT_DEADLINE:?} after SIGTERM");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("usar-unread-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn an_unread_stderr_pipe_never_stops_the_server_nor_its_shutdown() {
    let record = scratch("record");
    let mut child = program()
        .args(["--port", "0", "--image-port", "off", "--truth-port", "off"])
        .args(["--wss-port", "off", "--monitor-port", "off", "--record"])
        .arg(&record)
        .env("RUST_LOG", "debug")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped()) // never read
        .spawn()
        .unwrap();
    let _unread = child.stderr.take();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let addr: SocketAddr = line
        .strip_prefix("usar-server listening on ")
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|a| a.parse().ok())
        .unwrap_or_else(|| panic!("ready line: {line:?}"));

    let served = churn(addr, CONNECTIONS);
    // One client still connected at SIGTERM: its recording is finished too.
    let mut last = TcpStream::connect(addr).ok();
    if let Some(s) = &mut last {
        let mut nfo = [0u8; 3];
        let _ = s.read_exact(&mut nfo);
        let _ = s.write_all(b"GETSTARTPOSES\r\n");
        std::thread::sleep(Duration::from_millis(300));
    }
    let alive = child.try_wait().unwrap().is_none();
    let status = stop(&mut child, "unread stderr");
    served.unwrap();
    assert!(alive, "the server was running until SIGTERM");
    assert!(status.success(), "{status}");

    // Every connection was recorded, to the end, and each file is replayable.
    let mut files: Vec<_> = std::fs::read_dir(&record)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert_eq!(files.len(), CONNECTIONS + 1, "one file per connection");
    for file in [&files[0], files.last().unwrap()] {
        let text = std::fs::read_to_string(file).unwrap();
        assert!(text.contains("GETSTARTPOSES"), "{}: {text}", file.display());
        usar_server::replay::open(file)
            .unwrap_or_else(|e| panic!("{}: not replayable: {e}", file.display()));
    }
    std::fs::remove_dir_all(&record).unwrap();
}

#[test]
fn closed_stdout_and_stderr_never_stop_the_server_nor_its_shutdown() {
    // A free port (the ready line cannot be read: stdout is closed).
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let closed = || {
        let (read, write) = std::io::pipe().unwrap();
        drop(read);
        write
    };
    let mut child = program()
        .args(["--port", &port.to_string(), "--image-port", "off"])
        .args([
            "--truth-port",
            "off",
            "--wss-port",
            "off",
            "--monitor-port",
            "off",
        ])
        .env("RUST_LOG", "debug")
        .stdout(closed())
        .stderr(closed())
        .spawn()
        .unwrap();
    let addr = SocketAddr::from(([127, 0, 0, 1], port));
    let started = Instant::now();
    while TcpStream::connect(addr).is_err() {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the server ended ({status}) instead of serving");
        }
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "never listened"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let served = churn(addr, CONNECTIONS);
    let alive = child.try_wait().unwrap();
    let status = stop(&mut child, "closed stdout and stderr");
    served.unwrap();
    assert!(
        alive.is_none(),
        "the server ended ({alive:?}) before SIGTERM"
    );
    assert!(status.success(), "{status}");
}
