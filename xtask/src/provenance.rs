//! Where a result came from: git revision, tool and compiler versions, time.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde::Serialize;

/// Recorded next to every output so a result can be traced to the code that made it.
#[derive(Debug, Clone, Serialize)]
pub struct Provenance {
    /// Name of the program that wrote the file.
    pub tool: String,
    /// Its version (the workspace version).
    pub tool_version: String,
    /// `git rev-parse HEAD` of the workspace, or `"unknown"` outside a git checkout.
    pub git_revision: String,
    /// True if tracked files differ from `git_revision`; `null` if git is unavailable.
    pub git_dirty: Option<bool>,
    /// `rustc --version` of the compiler on PATH, if any.
    pub rustc: Option<String>,
    /// Seconds since the Unix epoch when the file was written.
    pub created_unix: u64,
}

/// The workspace root (the parent of this crate's directory).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

fn command_output(program: &str, args: &[&str]) -> Option<String> {
    let out = Command::new(program).args(args).output().ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8(out.stdout).ok()?;
    Some(text.trim().to_string())
}

impl Provenance {
    /// Collects the provenance of the current process; never fails (unknowns are recorded).
    pub fn collect() -> Self {
        let root = workspace_root();
        let root = root.to_string_lossy();
        let git_revision = command_output("git", &["-C", &root, "rev-parse", "HEAD"])
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| "unknown".to_string());
        let git_dirty = command_output(
            "git",
            &["-C", &root, "status", "--porcelain", "--untracked-files=no"],
        )
        .map(|s| !s.is_empty());
        let created_unix = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        Self {
            tool: "xtask".to_string(),
            tool_version: env!("CARGO_PKG_VERSION").to_string(),
            git_revision,
            git_dirty,
            rustc: command_output("rustc", &["--version"]),
            created_unix,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn provenance_is_filled() {
        let p = Provenance::collect();
        assert_eq!(p.tool_version, env!("CARGO_PKG_VERSION"));
        // Either a 40-hex revision or the documented placeholder.
        let rev = &p.git_revision;
        assert!(
            rev == "unknown" || (rev.len() == 40 && rev.chars().all(|c| c.is_ascii_hexdigit())),
            "{rev}"
        );
        assert!(p.created_unix > 1_600_000_000);
        assert!(workspace_root().join("Cargo.toml").is_file());
    }

    #[test]
    fn missing_program_gives_none() {
        assert_eq!(
            command_output("this-program-does-not-exist-xtask", &[]),
            None
        );
    }
}
