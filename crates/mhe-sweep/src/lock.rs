//! One writer per output directory: a lock file holding the writer's pid, taken when a
//! sweep (or a merge) starts and removed when it ends, also on error ([`OutputLock`] is an
//! RAII guard).
//!
//! - A sweep without `--shard` and `sweep-merge` write the whole directory and take
//!   `DIR/.lock`; a shard takes `DIR/.lock.shard-I-of-N`, so the shards of one sweep can
//!   share a directory (the cluster recipe of `docs/sweeps.md`), but a shard never runs twice
//!   at once, and no shard runs while the whole directory is written (each side checks the
//!   other's lock after taking its own, so of two racing writers at most one proceeds).
//! - The lock file is created with its content in one step (written under a temporary
//!   name, then hard-linked to the lock's name, which fails if the lock exists), so a reader
//!   never sees an empty lock. Its first line is the pid, then the host and the scope.
//! - A lock whose process is gone is *stale* (a killed sweep): on Linux a pid is alive when
//!   `/proc/<pid>` exists; elsewhere, and for a lock of another host, it counts as alive.
//!   A stale lock is moved aside, checked to be the one judged stale, and replaced; the
//!   caller reports the takeover.

use std::fs;
use std::io::{ErrorKind, Write as _};
use std::path::{Path, PathBuf};

use super::error::{Result, SweepError, io_err};
use super::format::{temp_owner, temp_path};
use super::seeds::Shard;

/// Name of the lock of the whole directory.
const WHOLE_LOCK: &str = ".lock";
/// Prefix of the shard locks (`.lock.shard-I-of-N`).
const SHARD_LOCK_PREFIX: &str = ".lock.shard-";

/// Who holds (or held) a lock, as read from its file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Holder {
    /// The writer's process id.
    pub pid: u32,
    /// Its host name (None if not recorded).
    pub host: Option<String>,
    /// `whole` or `shard I/N`.
    pub scope: String,
}

impl Holder {
    fn ours(scope: String) -> Self {
        Self {
            pid: std::process::id(),
            host: host_name(),
            scope,
        }
    }

    fn render(&self) -> String {
        format!(
            "{}\nhost {}\nscope {}\n",
            self.pid,
            self.host.as_deref().unwrap_or(""),
            self.scope
        )
    }

    /// The lock file's text, or None if it holds no pid on its first line.
    fn parse(text: &str) -> Option<Self> {
        let mut lines = text.lines();
        let pid = lines.next()?.trim().parse().ok()?;
        let mut holder = Self {
            pid,
            host: None,
            scope: String::new(),
        };
        for l in lines {
            if let Some(h) = l.strip_prefix("host ") {
                holder.host = Some(h.trim().to_string()).filter(|h| !h.is_empty());
            } else if let Some(s) = l.strip_prefix("scope ") {
                holder.scope = s.trim().to_string();
            }
        }
        Some(holder)
    }

    /// Whether the process may still be running (see the module docs).
    fn alive(&self) -> bool {
        match (&self.host, host_name()) {
            (Some(theirs), Some(ours)) if *theirs != ours => true,
            _ => pid_alive(self.pid),
        }
    }

    /// `pid N`, with the host when it is not this one, and the shard.
    pub(super) fn describe(&self) -> String {
        let mut s = format!("pid {}", self.pid);
        if let (Some(theirs), ours) = (&self.host, host_name()) {
            if ours.as_deref() != Some(theirs.as_str()) {
                s.push_str(&format!(" on host {theirs}"));
            }
        }
        if self.scope.starts_with("shard") {
            s.push_str(&format!(", {}", self.scope));
        }
        s
    }
}

/// Whether process `pid` exists: `/proc/<pid>` on Linux (alive if `/proc` is not mounted).
#[cfg(target_os = "linux")]
pub(super) fn pid_alive(pid: u32) -> bool {
    !Path::new("/proc/self").exists() || Path::new("/proc").join(pid.to_string()).exists()
}

/// Whether process `pid` exists: not checkable here, so always alive.
#[cfg(not(target_os = "linux"))]
pub(super) fn pid_alive(_pid: u32) -> bool {
    true
}

fn host_name() -> Option<String> {
    #[cfg(target_os = "linux")]
    {
        fs::read_to_string("/proc/sys/kernel/hostname")
            .ok()
            .map(|h| h.trim().to_string())
            .filter(|h| !h.is_empty())
    }
    #[cfg(not(target_os = "linux"))]
    {
        None
    }
}

fn lock_name(shard: Option<Shard>) -> String {
    match shard {
        None => WHOLE_LOCK.to_string(),
        Some(s) => format!("{SHARD_LOCK_PREFIX}{}-of-{}", s.index, s.count),
    }
}

/// Creates `path` holding `text` if it does not exist: Ok(true) when created, Ok(false)
/// when it exists. Hard-linking a finished temporary file makes creation and content one
/// step; where hard links are unsupported, an exclusive create followed by the write.
fn create_with(path: &Path, text: &str) -> std::io::Result<bool> {
    let tmp = temp_path(path);
    let linked = fs::write(&tmp, text).and_then(|()| fs::hard_link(&tmp, path));
    let _ = fs::remove_file(&tmp);
    match linked {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == ErrorKind::AlreadyExists => Ok(false),
        Err(_) => match fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
        {
            Ok(mut f) => f.write_all(text.as_bytes()).map(|()| true),
            Err(e) if e.kind() == ErrorKind::AlreadyExists => Ok(false),
            Err(e) => Err(e),
        },
    }
}

/// Reads a lock file: Ok(None) if it does not exist (any more).
fn read_lock(path: &Path) -> Result<Option<String>> {
    match fs::read(path) {
        Ok(bytes) => Ok(Some(String::from_utf8_lossy(&bytes).into_owned())),
        Err(e) if e.kind() == ErrorKind::NotFound => Ok(None),
        Err(e) => Err(io_err("read the lock file", path)(e)),
    }
}

fn locked(dir: &Path, lock: &Path, holder: Option<&Holder>) -> SweepError {
    SweepError::Locked {
        dir: dir.to_path_buf(),
        holder: holder.map_or_else(|| "pid unknown".to_string(), Holder::describe),
        lock: lock.to_path_buf(),
    }
}

/// The lock of an output directory, held while it exists; dropping it removes the lock
/// file (if it is still this writer's).
#[derive(Debug)]
pub(super) struct OutputLock {
    path: PathBuf,
    content: String,
}

impl OutputLock {
    /// Takes the lock of `dir` for the whole directory (`shard = None`) or one shard.
    /// Returns the lock and, when a stale lock was taken over, its former holder.
    pub(super) fn acquire(dir: &Path, shard: Option<Shard>) -> Result<(Self, Option<Holder>)> {
        let path = dir.join(lock_name(shard));
        let scope = shard.map_or_else(|| "whole".to_string(), |s| format!("shard {s}"));
        let content = Holder::ours(scope).render();
        let mut took_over = None;
        // A few rounds: a holder may release, or another writer take over, in between.
        for _ in 0..4 {
            if create_with(&path, &content).map_err(io_err("create the lock file", &path))? {
                let lock = Self { path, content };
                lock.check_other_scopes(dir, shard)?;
                return Ok((lock, took_over));
            }
            let Some(text) = read_lock(&path)? else {
                continue;
            };
            match Holder::parse(&text) {
                Some(h) if !h.alive() => {
                    take_over(&path, &text)?;
                    took_over = Some(h);
                }
                h => return Err(locked(dir, &path, h.as_ref())),
            }
        }
        let h = read_lock(&path)?.and_then(|t| Holder::parse(&t));
        Err(locked(dir, &path, h.as_ref()))
    }

    /// After taking a lock: no live writer of the other scope (the whole directory for a
    /// shard, any shard for the whole directory).
    fn check_other_scopes(&self, dir: &Path, shard: Option<Shard>) -> Result<()> {
        let others: Vec<PathBuf> = match shard {
            Some(_) => vec![dir.join(WHOLE_LOCK)],
            None => fs::read_dir(dir)
                .map_err(io_err("list the output directory", dir))?
                .filter_map(|e| e.ok())
                .filter(|e| {
                    e.file_name()
                        .to_str()
                        .is_some_and(|n| n.starts_with(SHARD_LOCK_PREFIX) && !n.ends_with(".tmp"))
                })
                .map(|e| e.path())
                .collect(),
        };
        for other in others {
            if let Some(text) = read_lock(&other)? {
                let h = Holder::parse(&text);
                if h.as_ref().is_none_or(Holder::alive) {
                    return Err(locked(dir, &other, h.as_ref()));
                }
            }
        }
        Ok(())
    }

    /// Removes temporary files (`NAME.<pid>.<n>.tmp`) of writers that are gone from `dirs`
    /// (the leftovers of killed sweeps). Only for the writer of the whole directory: it
    /// has checked that no shard of this directory is live.
    pub(super) fn remove_dead_temps(&self, dirs: &[&Path]) {
        for d in dirs {
            let Ok(rd) = fs::read_dir(d) else { continue };
            for e in rd.filter_map(|e| e.ok()) {
                let name = e.file_name();
                let owner = name.to_str().and_then(temp_owner);
                if owner.is_some_and(|pid| !pid_alive(pid)) {
                    let _ = fs::remove_file(e.path());
                }
            }
        }
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // Remove only our own lock (never one that another writer took over meanwhile).
        if fs::read_to_string(&self.path).is_ok_and(|t| t == self.content) {
            let _ = fs::remove_file(&self.path);
        }
    }
}

/// Replaces a stale lock: moves it aside and checks that what was moved is the stale text
/// (another writer may have taken over in between; then its lock is put back).
fn take_over(path: &Path, stale: &str) -> Result<()> {
    let aside = temp_path(path);
    match fs::rename(path, &aside) {
        Ok(()) => {}
        Err(e) if e.kind() == ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(io_err("move aside the stale lock file", path)(e)),
    }
    let moved = fs::read_to_string(&aside).unwrap_or_default();
    if moved != stale {
        // A fresh lock of another writer: restore it (unless yet another took the name).
        let _ = fs::hard_link(&aside, path);
    }
    let _ = fs::remove_file(&aside);
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn holder_text_round_trips_and_rejects_garbage() {
        let h = Holder {
            pid: 42,
            host: Some("node7".into()),
            scope: "shard 2/4".into(),
        };
        assert_eq!(Holder::parse(&h.render()), Some(h));
        assert_eq!(Holder::parse("x\n"), None);
        assert_eq!(Holder::parse(""), None);
        assert_eq!(Holder::parse("17").map(|h| h.pid), Some(17));
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn pid_liveness_and_other_hosts() {
        assert!(pid_alive(std::process::id()));
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        assert!(!pid_alive(pid));
        let elsewhere = Holder {
            pid,
            host: Some("surely-not-this-host.invalid".into()),
            scope: "whole".into(),
        };
        assert!(elsewhere.alive(), "a pid of another host cannot be checked");
        assert!(
            elsewhere
                .describe()
                .contains("on host surely-not-this-host.invalid")
        );
    }
}
