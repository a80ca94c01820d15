//! Output files written atomically and replaced as a set.
//!
//! Every file `xtask` writes goes through an [`OutputSet`]: each file is first written to a
//! temporary name in its final directory (`NAME.<pid>.<n>.tmp`, the name the sweep's lock
//! cleans up after a killed writer), flushed and `fsync`ed; only when every file of the set
//! is on disk are they renamed into place, and the directory is synced. A write that fails
//! (full disk, quota, I/O error) removes the temporary files and leaves the previous output
//! untouched: a failed rerun never leaves a mixture of old and new files, nor a cut file.
//! [`write_atomic`] is the one-file case (`certify --json`, and `export`).
//!
//! The renames follow the staging order, and the file staged last can record the set
//! ([`OutputSet::manifest`]: every other file's name, size and hash): the sweep stages its
//! `runs.csv` and `points.csv` first and its `meta.json` last, so a kill before the commit
//! leaves the previous set, and a directory whose files match its `meta.json`'s `files` is
//! one complete set.
//!
//! Fault injection for tests: with the environment variable
//! `SUBOPTIMAL_MHE_FAULT_WRITE_BYTES=N`, the output sets of this process may write N bytes
//! in total; the write that crosses N writes the part that fits and then fails as a full
//! disk does.

use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::{Context, Result, anyhow, bail};

/// Environment variable of the fault injection (bytes this process may write).
pub const FAULT_ENV: &str = "SUBOPTIMAL_MHE_FAULT_WRITE_BYTES";

/// Counter of temporary names of this process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Bytes left under fault injection (`None`: not read yet; `Some(None)`: no injection).
static FAULT_LEFT: Mutex<Option<Option<u64>>> = Mutex::new(None);

/// A temporary name beside `path`: `NAME.<pid>.<n>.tmp`.
fn temp_path(path: &Path) -> PathBuf {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!("{name}.{}.{n}.tmp", std::process::id()))
}

/// Takes `n` bytes from the injected budget: how many may be written (all `n` without
/// injection).
fn take_budget(n: usize) -> usize {
    let mut left = FAULT_LEFT
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let budget = left.get_or_insert_with(|| {
        std::env::var(FAULT_ENV)
            .ok()
            .and_then(|v| v.trim().parse::<u64>().ok())
    });
    match budget {
        None => n,
        Some(b) => {
            let allowed = (*b).min(n as u64);
            *b -= allowed;
            allowed as usize
        }
    }
}

/// Writes `bytes` to a new file at `tmp`, flushed and synced; `budget` (tests) caps the
/// bytes written like a full disk.
fn write_synced(tmp: &Path, bytes: &[u8], budget: Option<&mut u64>) -> std::io::Result<()> {
    let mut f = fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(tmp)?;
    let mut allowed = take_budget(bytes.len());
    if let Some(b) = budget {
        allowed = allowed.min(usize::try_from(*b).unwrap_or(usize::MAX));
        *b -= allowed as u64;
    }
    f.write_all(&bytes[..allowed])?;
    if allowed < bytes.len() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::StorageFull,
            "no space left on device (injected)",
        ));
    }
    f.flush()?;
    f.sync_all()
}

/// Syncs a directory so that renames in it are durable (best effort where unsupported).
fn sync_dir(dir: &Path) -> Result<()> {
    match fs::File::open(dir).and_then(|d| d.sync_all()) {
        Ok(()) => Ok(()),
        // Some filesystems refuse fsync on a directory; the renames are still atomic.
        Err(e) if e.kind() == std::io::ErrorKind::InvalidInput => Ok(()),
        Err(e) => Err(e).with_context(|| format!("cannot sync `{}`", dir.display())),
    }
}

/// One staged file: its temporary and its final path, its size and FNV-1a hash.
#[derive(Debug)]
struct Staged {
    tmp: PathBuf,
    path: PathBuf,
    bytes: usize,
    fnv1a64: u64,
}

/// FNV-1a (64 bit) of `bytes`: the manifest's check that a file is the one staged.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Files of one run, staged under temporary names and renamed into place together by
/// [`OutputSet::commit`]; dropped uncommitted, it removes its temporary files.
#[derive(Debug)]
pub struct OutputSet {
    dir: PathBuf,
    staged: Vec<Staged>,
    /// Bytes this set may still write (tests: a disk that fills up).
    budget: Option<u64>,
}

impl OutputSet {
    /// A set of files in `dir` (created if needed).
    pub fn new(dir: &Path) -> Result<Self> {
        fs::create_dir_all(dir)
            .with_context(|| format!("cannot create the output directory `{}`", dir.display()))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            staged: Vec::new(),
            budget: None,
        })
    }

    /// A set that fails like a full disk after `bytes` bytes (tests).
    #[cfg(test)]
    pub fn with_budget(dir: &Path, bytes: u64) -> Result<Self> {
        let mut s = Self::new(dir)?;
        s.budget = Some(bytes);
        Ok(s)
    }

    /// Stages `bytes` as `name` (a file name in the set's directory); returns its final
    /// path. Nothing is visible under the final name before [`commit`](Self::commit).
    pub fn add(&mut self, name: &str, bytes: &[u8]) -> Result<PathBuf> {
        let path = self.dir.join(name);
        if path.parent() != Some(self.dir.as_path()) {
            bail!("`{name}` is not a file name of `{}`", self.dir.display());
        }
        if self.staged.iter().any(|s| s.path == path) {
            bail!("`{}` is staged twice", path.display());
        }
        let tmp = temp_path(&path);
        if let Err(e) = write_synced(&tmp, bytes, self.budget.as_mut()) {
            let _ = fs::remove_file(&tmp);
            // "Intact" only when there is a previous output: a file of this set already in
            // place (issue 37 item 9: a first run on a full disk claimed one).
            let previous = path.is_file() || self.staged.iter().any(|s| s.path.is_file());
            let what = if previous {
                "nothing was replaced: the previous output is intact"
            } else {
                "nothing was written: there was no previous output here"
            };
            return Err(anyhow!(e))
                .with_context(|| format!("cannot write `{}` ({what})", path.display()));
        }
        self.staged.push(Staged {
            tmp,
            path: path.clone(),
            bytes: bytes.len(),
            fnv1a64: fnv1a64(bytes),
        });
        Ok(path)
    }

    /// The files staged so far, in order, as JSON `{"file", "bytes", "fnv1a64"}` (the hash
    /// as 16 hex digits): the manifest a file staged last (the sweep's `meta.json`) records,
    /// so a reader can check that the directory holds exactly that set. The renames of
    /// [`commit`](Self::commit) follow the staging order: the file staged last appears last.
    pub fn manifest(&self) -> serde_json::Value {
        serde_json::Value::Array(
            self.staged
                .iter()
                .map(|s| {
                    serde_json::json!({
                        "file": s.path.file_name().map(|n| n.to_string_lossy().into_owned()),
                        "bytes": s.bytes,
                        "fnv1a64": format!("{:016x}", s.fnv1a64),
                    })
                })
                .collect(),
        )
    }

    /// Renames every staged file into place and syncs the directory; returns the final
    /// paths in the order staged.
    pub fn commit(mut self) -> Result<Vec<PathBuf>> {
        let staged = std::mem::take(&mut self.staged);
        let mut done = Vec::with_capacity(staged.len());
        for (i, s) in staged.iter().enumerate() {
            if let Err(e) = fs::rename(&s.tmp, &s.path) {
                for rest in &staged[i..] {
                    let _ = fs::remove_file(&rest.tmp);
                }
                return Err(e).with_context(|| {
                    format!("cannot rename a finished file to `{}`", s.path.display())
                });
            }
            done.push(s.path.clone());
        }
        sync_dir(&self.dir)?;
        Ok(done)
    }

    /// [`commit`](Self::commit), then removes the files of the previous set (`previous`:
    /// file names relative to the directory, from its manifest) that the new set does not
    /// replace, so the directory holds one run's files, never a mixture.
    pub fn commit_replacing(self, previous: &[String]) -> Result<Vec<PathBuf>> {
        let dir = self.dir.clone();
        let done = self.commit()?;
        for name in previous {
            let path = dir.join(name);
            // Only plain names of this directory (a manifest is data, not a command).
            if path.parent() == Some(dir.as_path()) && !done.contains(&path) && path.is_file() {
                let _ = fs::remove_file(&path);
            }
        }
        Ok(done)
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        for s in &self.staged {
            let _ = fs::remove_file(&s.tmp);
        }
    }
}

/// Replaces `path` by `bytes` atomically (temporary file beside it, synced, renamed): a
/// reader sees the old file or the new one, never a part.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| anyhow!("`{}` is not a file path", path.display()))?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut set = OutputSet::new(dir)?;
    set.add(name, bytes)?;
    set.commit().map(|_| ())
}

/// Checks before any work that `dir` can hold the outputs: creates it if needed, refuses a
/// path that is not a directory, and writes (and removes) a probe file.
pub fn check_out_dir(dir: &Path, flag: &str) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        bail!(
            "{flag} `{}` is not a directory; give a directory for the outputs",
            dir.display()
        );
    }
    fs::create_dir_all(dir).with_context(|| {
        format!(
            "{flag} `{}`: cannot create the output directory; give a writable directory",
            dir.display()
        )
    })?;
    let probe = temp_path(&dir.join(".write-probe"));
    fs::write(&probe, b"probe").with_context(|| {
        format!(
            "{flag} `{}`: cannot write into the output directory; give a writable directory",
            dir.display()
        )
    })?;
    let _ = fs::remove_file(&probe);
    Ok(())
}

/// Checks that the parent directory of an output file exists or can be created and that
/// `path` is not a directory (before any work).
pub fn check_out_file(path: &Path, flag: &str) -> Result<()> {
    if path.is_dir() {
        bail!(
            "{flag} `{}` is a directory; give a file name",
            path.display()
        );
    }
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => check_out_dir(p, flag),
        _ => check_out_dir(Path::new("."), flag),
    }
}

/// Reads an input text file (a regular file of at most 16 MiB, UTF-8; a FIFO or device is
/// refused without opening it): [`lti_model::spec::format::read_limited`] with its message
/// unwrapped from the scenario's `<file>` key.
pub fn read_input(path: &Path) -> Result<String> {
    lti_model::spec::format::read_limited(path).map_err(|e| match e {
        lti_model::ModelError::Scenario { problem, .. } => anyhow!(problem),
        other => anyhow!(other),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn tmp_dir(tag: &str) -> PathBuf {
        let d = crate::test_dir::test_dir("output", tag);
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    fn listing(d: &Path) -> Vec<(String, String)> {
        let mut v: Vec<(String, String)> = fs::read_dir(d)
            .unwrap()
            .flatten()
            .map(|e| {
                (
                    e.file_name().to_string_lossy().into_owned(),
                    fs::read_to_string(e.path()).unwrap_or_default(),
                )
            })
            .collect();
        v.sort();
        v
    }

    /// A set that fails after N bytes, for every N inside it, leaves the previous complete
    /// set and no temporary file; with enough room the new set replaces it whole.
    #[test]
    fn a_set_that_fails_after_n_bytes_leaves_the_previous_set() {
        let d = tmp_dir("set");
        let old = [
            ("a.json", "old a"),
            ("b.csv", "old b, longer"),
            ("c.svg", "old c"),
        ];
        let mut first = OutputSet::new(&d).unwrap();
        for (n, t) in old {
            first.add(n, t.as_bytes()).unwrap();
        }
        first.commit().unwrap();
        let before = listing(&d);
        let new = [
            ("a.json", "NEW A"),
            ("b.csv", "NEW B, much longer"),
            ("c.svg", "NEW C!"),
        ];
        let total: usize = new.iter().map(|(_, t)| t.len()).sum();
        for budget in 0..total as u64 {
            let mut set = OutputSet::with_budget(&d, budget).unwrap();
            let failed = new.iter().any(|(n, t)| set.add(n, t.as_bytes()).is_err());
            assert!(failed, "budget {budget}");
            drop(set);
            assert_eq!(listing(&d), before, "budget {budget}");
        }
        let mut set = OutputSet::with_budget(&d, total as u64).unwrap();
        for (n, t) in new {
            set.add(n, t.as_bytes()).unwrap();
        }
        set.commit().unwrap();
        let after: Vec<(String, String)> = new
            .iter()
            .map(|(n, t)| (n.to_string(), t.to_string()))
            .collect();
        assert_eq!(listing(&d), after);
        let _ = fs::remove_dir_all(&d);
    }

    /// Issue 37 item 9: a first run on a full disk said "the previous output is intact"
    /// when there was none; it says nothing was written, and "intact" only with a previous set.
    #[test]
    fn a_failed_first_write_does_not_claim_a_previous_output() {
        let d = tmp_dir("first");
        let mut set = OutputSet::with_budget(&d, 3).unwrap();
        let e = format!("{:#}", set.add("a.json", b"too long").unwrap_err());
        assert!(e.contains("nothing was written"), "{e}");
        assert!(!e.contains("intact"), "{e}");
        drop(set);
        assert!(listing(&d).is_empty());
        let mut first = OutputSet::new(&d).unwrap();
        first.add("a.json", b"old").unwrap();
        first.commit().unwrap();
        let mut set = OutputSet::with_budget(&d, 3).unwrap();
        let e = format!("{:#}", set.add("a.json", b"too long").unwrap_err());
        assert!(e.contains("the previous output is intact"), "{e}");
        let _ = fs::remove_dir_all(&d);
    }

    #[test]
    fn output_paths_are_checked_before_work() {
        let d = tmp_dir("check");
        let file = d.join("f");
        fs::write(&file, "x").unwrap();
        let e = check_out_dir(&file, "--out").unwrap_err().to_string();
        assert!(e.contains("--out") && e.contains("not a directory"), "{e}");
        assert!(check_out_dir(&d.join("new/sub"), "--out").is_ok());
        let e = check_out_file(&d, "--json").unwrap_err().to_string();
        assert!(e.contains("is a directory"), "{e}");
        assert!(check_out_file(&d.join("x.json"), "--json").is_ok());
        assert_eq!(listing(&d).len(), 2); // f, new/ — the probes are gone
        let _ = fs::remove_dir_all(&d);
    }
}
