//! Terminal output that cannot panic.
//!
//! `println!` panics when stdout is closed (`| head -1` under `set -o pipefail`) or full
//! (`> /dev/full`), which would abort the work and lose its files. Every terminal line of
//! `xtask` goes through [`outln!`] / [`errln!`] instead: a failed write is an ordinary I/O
//! error, remembered, and the stream is not written again. The work completes and its files
//! are written; [`exit_code`] then turns a lost stdout into exit code [`EXIT_STREAM`]
//! (when the run would otherwise have succeeded), and the first error is reported on
//! stderr if stderr still works.

use std::fmt;
use std::io::Write as _;
use std::process::ExitCode;
use std::sync::Mutex;

/// Exit code when the work succeeded and its files were written, but stdout (or stderr)
/// could not be written: closed pipe, full device.
pub const EXIT_STREAM: u8 = 5;

/// Which stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    Stdout,
    Stderr,
}

/// The first write error of each stream (`None`: no error so far).
static LOST: Mutex<[Option<String>; 2]> = Mutex::new([None, None]);

fn slot(stream: Stream) -> usize {
    match stream {
        Stream::Stdout => 0,
        Stream::Stderr => 1,
    }
}

/// Whether stdout and stderr were open when the process started (Linux).
///
/// The Rust runtime reopens a closed standard descriptor on `/dev/null` before `main`, so a
/// command run with stdout closed (`xtask … >&-`) would write into nothing and exit 0. This
/// probe runs from `.init_array`, before the runtime's reopening, and records which of the
/// two was closed; [`check_streams_at_start`] then counts that stream as lost (exit code
/// [`EXIT_STREAM`] for a run that otherwise succeeded; issue 37 item 14).
#[cfg(target_os = "linux")]
mod at_start {
    use std::sync::atomic::{AtomicU8, Ordering};

    /// Bit 0: stdout was closed; bit 1: stderr was closed.
    pub(super) static CLOSED: AtomicU8 = AtomicU8::new(0);

    extern "C" fn probe() {
        let mut bits = 0;
        for (fd, bit) in [(1, 1_u8), (2, 2_u8)] {
            // SAFETY: F_GETFD reads the flags of a descriptor number; no memory is passed,
            // and a closed number only returns -1 (EBADF).
            if unsafe { libc::fcntl(fd, libc::F_GETFD) } == -1 {
                bits |= bit;
            }
        }
        CLOSED.store(bits, Ordering::Relaxed);
    }

    /// Called by the C runtime before `main` (and before the Rust runtime's start-up).
    #[used]
    #[unsafe(link_section = ".init_array")]
    static PROBE: extern "C" fn() = probe;
}

/// Counts a standard stream that was closed when the process started as lost (see
/// the module `at_start`); call first in `main`. Elsewhere than Linux it does nothing.
pub fn check_streams_at_start() {
    #[cfg(target_os = "linux")]
    {
        let bits = at_start::CLOSED.load(std::sync::atomic::Ordering::Relaxed);
        let mut lost = LOST
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        for (bit, stream, name) in [(1, Stream::Stdout, "stdout"), (2, Stream::Stderr, "stderr")] {
            if bits & bit != 0 {
                lost[slot(stream)] = Some(format!("{name} was closed when the command started"));
            }
        }
    }
}

/// Prints a command-line parse result of clap (its help, its version, or a usage error)
/// through [`line`], so that a help written to a full or closed stdout is a lost stream
/// (exit code [`EXIT_STREAM`]), not a success; returns clap's exit code (0 for help and
/// version, 2 for a usage error).
pub fn clap_message(e: &clap::Error) -> ExitCode {
    let text = e.render().to_string();
    let stream = if e.use_stderr() {
        Stream::Stderr
    } else {
        Stream::Stdout
    };
    line(stream, format_args!("{}", text.trim_end()));
    ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2))
}

/// Writes `args` and a newline to `stream` unless an earlier write to it failed; a failure
/// is remembered (never a panic). Returns whether the line was written.
pub fn line(stream: Stream, args: fmt::Arguments<'_>) -> bool {
    let mut lost = LOST
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let i = slot(stream);
    if lost[i].is_some() {
        return false;
    }
    let written = match stream {
        Stream::Stdout => {
            let mut out = std::io::stdout().lock();
            writeln!(out, "{args}").and_then(|()| out.flush())
        }
        Stream::Stderr => {
            let mut err = std::io::stderr().lock();
            writeln!(err, "{args}").and_then(|()| err.flush())
        }
    };
    match written {
        Ok(()) => true,
        Err(e) => {
            lost[i] = Some(e.to_string());
            false
        }
    }
}

/// The first write error of `stream`, if any.
pub fn lost(stream: Stream) -> Option<String> {
    LOST.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)[slot(stream)]
    .clone()
}

/// The process's exit code: `code` unless the run succeeded and a stream was lost, then
/// [`EXIT_STREAM`] (with a note on stderr when stderr still works).
pub fn exit_code(code: ExitCode) -> ExitCode {
    let (out, err) = (lost(Stream::Stdout), lost(Stream::Stderr));
    if out.is_none() && err.is_none() {
        return code;
    }
    if let Some(e) = &out {
        // Exit code 5 only replaces success: a verdict or an error keeps its own code, and
        // the note must not claim otherwise.
        if code == ExitCode::SUCCESS {
            line(
                Stream::Stderr,
                format_args!(
                    "note: stdout could not be written ({e}); the work completed and its files \
                     were written (exit code {EXIT_STREAM})"
                ),
            );
        } else {
            line(
                Stream::Stderr,
                format_args!(
                    "note: stdout could not be written ({e}); the exit code is the command's own"
                ),
            );
        }
    }
    if code == ExitCode::SUCCESS {
        ExitCode::from(EXIT_STREAM)
    } else {
        code
    }
}

/// `println!` that never panics: a line on stdout through [`line`].
macro_rules! outln {
    () => {
        $crate::console::line($crate::console::Stream::Stdout, format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::console::line($crate::console::Stream::Stdout, format_args!($($arg)*))
    };
}

/// `eprintln!` that never panics: a line on stderr through [`line`].
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::console::line($crate::console::Stream::Stderr, format_args!($($arg)*))
    };
}
