//! Where `export` writes: `--out` checked before any work and the artefact replaced as a
//! set (a temporary sibling directory renamed over `--out`), so no file of an earlier export
//! survives beside a new `certificate.json` and a failed write leaves the earlier one intact.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use crate::ExportError;

/// The `format` of the artefact's `certificate.json`.
pub const EXPORT_FORMAT: &str = "suboptimal-mhe/export-certificate";

/// Checks an output directory before any work (the CLI's `--out`): what `check_out`
/// accepts, as a typed error.
///
/// # Errors
/// [`ExportError::Output`] when `dir` is a file, a directory that is not empty and holds no
/// earlier export, or cannot be read.
pub fn check_output_dir(dir: &Path) -> Result<(), ExportError> {
    check_out(dir).map_err(|e| ExportError::output(dir, &e))
}

/// Checks `--out` before any work: a path that does not exist (its parent must be
/// creatable), an empty directory, or an earlier export (a directory whose
/// `certificate.json` is an export certificate), which the new one replaces as a whole.
/// Anything else is refused, so `export` never deletes a directory it did not write.
pub(crate) fn check_out(out: &Path) -> Result<()> {
    let shown = out.display();
    let meta = match std::fs::symlink_metadata(out) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e).with_context(|| format!("--out `{shown}`: cannot read it")),
        Ok(m) => m,
    };
    if !meta.is_dir() {
        bail!(
            "--out `{shown}` exists and is not a directory; give a new directory (or an earlier \
             export's directory, which is replaced)"
        );
    }
    let mut entries = std::fs::read_dir(out)
        .with_context(|| format!("--out `{shown}`: cannot list the directory"))?;
    if entries.next().is_none() {
        return Ok(());
    }
    let ours = std::fs::read_to_string(out.join("certificate.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .is_some_and(|j| j["format"] == EXPORT_FORMAT);
    if !ours {
        bail!(
            "--out `{shown}` is a directory that is not empty and holds no artefact of `cargo \
             xtask export` (no certificate.json of format `{EXPORT_FORMAT}`); export replaces \
             its --out as a whole, so it refuses to delete this one: give a new or empty \
             directory"
        );
    }
    Ok(())
}

/// A sibling of `out` named `<name>.<tag>.<pid>`.
fn sibling(out: &Path, tag: &str) -> PathBuf {
    let name = out
        .file_name()
        .map_or_else(|| "export".into(), |n| n.to_string_lossy().into_owned());
    out.with_file_name(format!(".{name}.{tag}.{}", std::process::id()))
}

/// Writes the artefact with `write` into a temporary sibling directory of `out`, then
/// replaces `out` (checked by [`check_out`] again: it may have changed during the
/// certificate) by it: no file of an earlier export survives beside the new
/// `certificate.json`, and a failed write leaves the earlier export as it was.
pub(crate) fn replace_artefact(out: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    check_out(out)?;
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).with_context(|| {
            format!(
                "--out `{}`: cannot create its parent directory",
                out.display()
            )
        })?;
    }
    let stage = sibling(out, "export-new");
    let _ = std::fs::remove_dir_all(&stage);
    if let Err(e) = std::fs::create_dir(&stage)
        .with_context(|| format!("cannot create `{}`", stage.display()))
        .and_then(|()| write(&stage))
    {
        let _ = std::fs::remove_dir_all(&stage);
        return Err(e.context(format!(
            "nothing was replaced: `{}` is as it was",
            out.display()
        )));
    }
    let old = sibling(out, "export-old");
    let had_old = out.exists();
    if had_old {
        let _ = std::fs::remove_dir_all(&old);
        if let Err(e) = std::fs::rename(out, &old) {
            let _ = std::fs::remove_dir_all(&stage);
            return Err(e).with_context(|| format!("cannot replace `{}`", out.display()));
        }
    }
    if let Err(e) = std::fs::rename(&stage, out) {
        if had_old {
            let _ = std::fs::rename(&old, out);
        }
        let _ = std::fs::remove_dir_all(&stage);
        return Err(e).with_context(|| format!("cannot replace `{}`", out.display()));
    }
    if had_old {
        let _ = std::fs::remove_dir_all(&old);
    }
    Ok(())
}
