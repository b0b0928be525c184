//! One UAV flown over the protocol: a running usar-server (lockstep via `SYNC`) or a real
//! USARSim (no lockstep: sensor time). Blocking I/O on a std `TcpStream`; the caller
//! releases the GIL around it.

use std::io::{BufRead, BufReader, ErrorKind, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use ucc_client::uav::UavState;
use usar_proto::{Barrier, Command, ServerMessage};

use crate::core::{Observations, Pose, SimError, drive, spawn};

/// How long a connection attempt and each read may take.
const TIMEOUT: Duration = Duration::from_secs(10);
/// How long to wait for the answer to `SYNC {Time 0}` (a real USARSim never answers).
const SYNC_PROBE: Duration = Duration::from_secs(2);

fn err(addr: &str, what: impl std::fmt::Display) -> SimError {
    SimError::Invalid(format!("server {addr}: {what}"))
}

/// A connection with one UAV.
#[derive(Debug)]
pub(crate) struct Remote {
    addr: String,
    reader: BufReader<TcpStream>,
    writer: TcpStream,
    state: UavState,
    lockstep: bool,
    /// Simulated time of the last barrier (lockstep) or last reading.
    time: f64,
    period: f64,
    line: String,
}

impl Remote {
    /// Connects, asks for lockstep, spawns `robot` at `pose` and waits one period.
    pub(crate) fn connect(
        addr: &str,
        robot: &str,
        pose: Pose,
        period: f64,
    ) -> Result<Self, SimError> {
        if !pose.iter().all(|v| v.is_finite()) {
            return Err(err(addr, format_args!("start not finite: {pose:?}")));
        }
        let target = addr
            .to_socket_addrs()
            .map_err(|e| err(addr, format_args!("bad address (want host:port): {e}")))?
            .next()
            .ok_or_else(|| err(addr, "address resolves to nothing"))?;
        let stream = TcpStream::connect_timeout(&target, TIMEOUT)
            .map_err(|e| err(addr, format_args!("cannot connect: {e}")))?;
        let _ = stream.set_nodelay(true);
        let writer = stream
            .try_clone()
            .map_err(|e| err(addr, format_args!("{e}")))?;
        let mut remote = Self {
            addr: addr.to_string(),
            reader: BufReader::new(stream),
            writer,
            state: UavState::new(),
            lockstep: false,
            time: 0.0,
            period,
            line: String::new(),
        };
        remote.send(&Command::Sync(Barrier::at(0.0)))?;
        remote.lockstep = remote.probe_sync()?;
        remote.send(&spawn(robot, "UAV", &pose))?;
        remote.advance()?;
        if remote.state.position.is_none() {
            return Err(err(
                addr,
                format_args!("the robot did not spawn at {pose:?} (no Position reading)"),
            ));
        }
        Ok(remote)
    }

    /// Whether the server runs in lockstep with us.
    pub(crate) fn is_lockstep(&self) -> bool {
        self.lockstep
    }

    fn probe_sync(&mut self) -> Result<bool, SimError> {
        self.set_timeout(SYNC_PROBE)?;
        loop {
            match self.read_message() {
                Ok(Some(ServerMessage::Sync(barrier))) => {
                    // The server's clock need not start at 0 (earlier clients ran it).
                    self.time = barrier.time.seconds;
                    self.set_timeout(TIMEOUT)?;
                    return Ok(true);
                }
                Ok(Some(m)) => {
                    self.state.apply(&m);
                }
                Ok(None) => return Err(err(&self.addr, "the server closed the connection")),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    self.set_timeout(TIMEOUT)?;
                    return Ok(false);
                }
                Err(e) => return Err(err(&self.addr, format_args!("read failed: {e}"))),
            }
        }
    }

    fn set_timeout(&self, t: Duration) -> Result<(), SimError> {
        self.reader
            .get_ref()
            .set_read_timeout(Some(t))
            .map_err(|e| err(&self.addr, format_args!("{e}")))
    }

    /// One line as a message; `Ok(None)` at end of stream; unreadable lines are skipped.
    fn read_message(&mut self) -> std::io::Result<Option<ServerMessage>> {
        loop {
            self.line.clear();
            if self.reader.read_line(&mut self.line)? == 0 {
                return Ok(None);
            }
            let line = self.line.trim_end_matches(['\r', '\n']);
            if let Ok(parsed) = ServerMessage::parse(line) {
                return Ok(Some(parsed.message));
            }
        }
    }

    fn send(&mut self, command: &Command) -> Result<(), SimError> {
        let mut line = String::new();
        command.write_to(&mut line);
        self.send_line(&line)
    }

    fn send_line(&mut self, line: &str) -> Result<(), SimError> {
        let result = self
            .writer
            .write_all(line.as_bytes())
            .and_then(|()| self.writer.write_all(b"\r\n"));
        result.map_err(|e| {
            err(
                &self.addr,
                format_args!("write failed (server closed?): {e}"),
            )
        })
    }

    /// Lockstep: releases the world for one period and reads up to the barrier's answer.
    /// Otherwise: reads until a reading stamped one period later than the last arrives.
    fn advance(&mut self) -> Result<(), SimError> {
        // Without lockstep the clock is only known from the readings: a fresh connection
        // waits one period past the first time stamp it sees.
        let mut target = (self.lockstep || self.time > 0.0).then_some(self.time + self.period);
        if self.lockstep {
            self.send(&Command::Sync(Barrier::at(self.time + self.period)))?;
        }
        loop {
            let message = match self.read_message() {
                Ok(Some(m)) => m,
                Ok(None) => return Err(err(&self.addr, "the server closed the connection")),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    return Err(err(
                        &self.addr,
                        format_args!("timed out: no answer within {} s", TIMEOUT.as_secs()),
                    ));
                }
                Err(e) => return Err(err(&self.addr, format_args!("read failed: {e}"))),
            };
            if let ServerMessage::Sync(barrier) = &message {
                if self.lockstep {
                    self.time = barrier.time.seconds;
                    return Ok(());
                }
                continue;
            }
            self.state.apply(&message);
            if self.lockstep {
                continue;
            }
            if let Some(t) = message.time() {
                let due = *target.get_or_insert(t + self.period);
                if t >= due - 1e-6 && self.state.position.is_some() {
                    self.time = t;
                    return Ok(());
                }
            }
        }
    }

    /// Sends the normalized command and waits one period.
    pub(crate) fn step(&mut self, action: [f64; 4]) -> Result<(), SimError> {
        self.send(&drive(&action))?;
        self.advance()
    }

    /// The UAV's observation (contact is not known remotely: always false).
    pub(crate) fn observe(&self) -> Observations {
        let mut obs = Observations::with_capacity(1);
        obs.push_state(&self.state, false, self.time);
        obs
    }
}
