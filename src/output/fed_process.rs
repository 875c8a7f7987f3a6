//! A child process fed through its standard input under a watchdog: the bytes go to it from a
//! writer thread, and when the process stops taking them, or does not exit after its input
//! ends, for longer than the stall limit, it is killed and the caller gets an error instead of
//! a render that hangs forever. An encoder that stops reading (wedged on a network disk, waiting
//! on a terminal, a broken build) used to block the frame loop in a pipe write.

use std::io::{self, Read, Write};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How long a child may take a chunk, or take to exit after its input ends: the environment's
/// `STEREOTRACE_ENCODER_TIMEOUT` (seconds), else 300 s. ffmpeg reads a frame as it encodes one,
/// so only an encoder spending minutes on a single frame (none of ours at 16384 pixels wide)
/// would pass it.
pub fn stall_limit() -> Duration {
    std::env::var("STEREOTRACE_ENCODER_TIMEOUT")
        .ok()
        .and_then(|s| s.trim().parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0)
        .map_or(Duration::from_secs(300), Duration::from_secs_f64)
}

/// How often a blocked caller looks at the clock.
const POLL: Duration = Duration::from_millis(2);

pub struct FedProcess {
    child: Child,
    chunks: Option<SyncSender<Vec<u8>>>,
    writer: Option<JoinHandle<io::Result<()>>>,
    stderr: Option<JoinHandle<Vec<u8>>>,
    stall: Duration,
    /// The process has been waited for.
    exited: bool,
}

impl FedProcess {
    /// Starts `command` with piped standard input and standard error (its output is discarded).
    pub fn spawn(command: &mut Command, stall: Duration) -> io::Result<FedProcess> {
        let mut child = command
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()?;
        let stdin = child.stdin.take().expect("stdin was piped above");
        let mut err = child.stderr.take().expect("stderr was piped above");
        // One chunk in flight besides the one being written: enough to overlap tracing and
        // encoding, no more held in memory.
        let (chunks, rx) = sync_channel(1);
        Ok(FedProcess {
            child,
            chunks: Some(chunks),
            writer: Some(std::thread::spawn(move || write_all(stdin, rx))),
            stderr: Some(std::thread::spawn(move || {
                let mut text = Vec::new();
                let _ = err.read_to_end(&mut text);
                text
            })),
            stall,
            exited: false,
        })
    }

    /// Hands `bytes` to the process, waiting at most the stall limit for room.
    pub fn feed(&mut self, bytes: Vec<u8>) -> io::Result<()> {
        let chunks = self.chunks.as_ref().expect("fed only before finish");
        let t0 = Instant::now();
        let mut bytes = bytes;
        loop {
            match chunks.try_send(bytes) {
                Ok(()) => return Ok(()),
                Err(TrySendError::Full(b)) if t0.elapsed() < self.stall => {
                    bytes = b;
                    std::thread::sleep(POLL);
                }
                Err(TrySendError::Full(_)) => {
                    return Err(self.stalled("stopped reading its input"));
                }
                // The writer ended: the process closed its input. Its error says why.
                Err(TrySendError::Disconnected(_)) => {
                    return Err(self.join_writer().err().unwrap_or_else(|| {
                        io::Error::new(io::ErrorKind::BrokenPipe, "closed its input early")
                    }));
                }
            }
        }
    }

    /// Ends the input and waits for the process to exit (at most the stall limit for each);
    /// its exit status and what it wrote to standard error.
    pub fn finish(mut self) -> io::Result<(ExitStatus, String)> {
        drop(self.chunks.take());
        let t0 = Instant::now();
        while self.writer.as_ref().is_some_and(|w| !w.is_finished()) {
            if t0.elapsed() >= self.stall {
                return Err(self.stalled("stopped reading its input"));
            }
            std::thread::sleep(POLL);
        }
        // A write error here (a broken pipe) is the process's own doing: its status says more.
        let written = self.join_writer();
        let t0 = Instant::now();
        let status = loop {
            if let Some(s) = self.child.try_wait()? {
                self.exited = true;
                break s;
            }
            if t0.elapsed() >= self.stall {
                return Err(self.stalled("did not exit after its input ended"));
            }
            std::thread::sleep(POLL);
        };
        let stderr = self
            .stderr
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        let stderr = String::from_utf8_lossy(&stderr).trim().to_string();
        if status.success() {
            written?;
        }
        Ok((status, stderr))
    }

    fn join_writer(&mut self) -> io::Result<()> {
        match self.writer.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => Err(io::Error::other("the pipe's writer thread panicked")),
            None => Ok(()),
        }
    }

    /// Kills the process (which also frees a writer blocked on its pipe) and says why.
    fn stalled(&mut self, what: &str) -> io::Error {
        self.stop();
        io::Error::new(
            io::ErrorKind::TimedOut,
            format!(
                "the encoder {what} for {:.0} s and was stopped (STEREOTRACE_ENCODER_TIMEOUT sets the limit)",
                self.stall.as_secs_f64()
            ),
        )
    }

    /// Kills and reaps the process. Its writer and stderr threads are left to end on their own
    /// (when the pipes close): a grandchild that inherited a pipe could keep them blocked, and
    /// joining them would hang exactly as the watchdog exists to prevent.
    fn stop(&mut self) {
        drop(self.chunks.take());
        if !self.exited {
            let _ = self.child.kill();
            let _ = self.child.wait();
            self.exited = true;
        }
        drop(self.writer.take());
        drop(self.stderr.take());
    }
}

impl Drop for FedProcess {
    fn drop(&mut self) {
        self.stop();
    }
}

fn write_all(mut stdin: ChildStdin, chunks: Receiver<Vec<u8>>) -> io::Result<()> {
    for chunk in chunks {
        stdin.write_all(&chunk)?;
    }
    stdin.flush()
    // Dropping stdin closes the pipe: the process sees the end of its input.
}
