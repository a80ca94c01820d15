//! Scratch directories of xtask's tests (the binary's unit tests and `tests/cli`, which
//! include this file by path): one per test process and name under
//! `<temp>/suboptimal-mhe-tests/`, and the leftovers of finished test processes removed on
//! the first call — the reproduce fixtures alone are 74 MB per run, and a suite must not
//! grow `/tmp` by gigabytes per run (as it did: 491 directories after one session).

use std::path::{Path, PathBuf};
use std::sync::Once;

/// `<temp>/suboptimal-mhe-tests/<pid>-<prefix>-<name>`, created (not emptied: tests of one
/// process may share it). The first call of a process removes every entry of that root whose
/// leading pid is not a live process (read from `/proc`; where `/proc` does not exist
/// nothing is removed).
pub fn test_dir(prefix: &str, name: &str) -> PathBuf {
    let root = std::env::temp_dir().join("suboptimal-mhe-tests");
    static SWEEP: Once = Once::new();
    SWEEP.call_once(|| remove_finished(&root));
    let dir = root.join(format!("{}-{prefix}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("create a test directory under the temp dir");
    dir
}

/// Removes the entries of `root` left by processes that have exited.
fn remove_finished(root: &Path) {
    let proc_fs = Path::new("/proc");
    if !proc_fs.is_dir() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(root) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(|n| n.split('-').next()) else {
            continue;
        };
        if pid.parse::<u32>().is_ok() && !proc_fs.join(pid).exists() {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}
