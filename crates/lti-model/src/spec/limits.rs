//! The size limits of what a scenario may read and imply, checked before anything large is
//! read or allocated: the input file's bytes ([`read_limited`], which also refuses FIFOs,
//! directories and devices) and the dense working set ([`check_dense_bytes`]). Re-exported
//! by [`super::format`].

use super::format::key_error;
use crate::error::Result;

/// Largest input file read (scenario, sweep config, P file): 16 MiB. A scenario of the
/// largest supported size is far smaller; without a cap `/dev/zero` reads forever.
pub const MAX_FILE_BYTES: u64 = 16 << 20;

/// Largest dense working set a scenario may imply (weights, condensed Hessians, prediction
/// matrices, traces, the MHE setup): 2 GiB, checked before anything is allocated. (The
/// 20-node thermal rod at M = 30, whose MHE setup with an exact solver per window is
/// estimated at ≈ 1.0 GiB and measured at 1.6 GB resident, fits; the one-state M = 300 of
/// issue 23, ≈ 5 GiB, does not.)
pub const MAX_DENSE_BYTES: f64 = (2u64 << 30) as f64;

const GIB: f64 = (1u64 << 30) as f64;

/// Reads a text file of at most [`MAX_FILE_BYTES`], refusing a larger (or endless) one with
/// a [`ModelError::Scenario`](crate::ModelError::Scenario) at key `"<file>"` before reading it all.
pub fn read_limited(path: &std::path::Path) -> Result<String> {
    use std::io::Read;
    let fail = |problem: String| key_error("<file>", problem);
    // Checked before opening: opening a FIFO blocks until a writer appears, and a device
    // or a directory is no input file.
    let meta = std::fs::metadata(path).map_err(|e| {
        fail(format!(
            "cannot read `{}`: {e}; check the path (relative paths are resolved from the \
             current directory)",
            path.display()
        ))
    })?;
    if !meta.is_file() {
        let kind = special_kind(&meta);
        return Err(fail(format!(
            "`{}` is {kind}, not a regular file; give a text file of at most {} MiB",
            path.display(),
            MAX_FILE_BYTES >> 20
        )));
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(fail(format!(
            "`{}` is larger than {} MiB ({} bytes), the limit for input files; is it the right \
             file?",
            path.display(),
            MAX_FILE_BYTES >> 20,
            meta.len()
        )));
    }
    let file = std::fs::File::open(path).map_err(|e| {
        fail(format!(
            "cannot read `{}`: {e}; check the path (relative paths are resolved from the \
             current directory)",
            path.display()
        ))
    })?;
    let mut bytes = Vec::new();
    file.take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| fail(format!("cannot read `{}`: {e}", path.display())))?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(fail(format!(
            "`{}` is larger than {} MiB, the limit for input files; is it the right file?",
            path.display(),
            MAX_FILE_BYTES >> 20
        )));
    }
    String::from_utf8(bytes).map_err(|e| {
        fail(format!(
            "`{}` is not UTF-8 text (invalid byte at offset {}); give a text file",
            path.display(),
            e.utf8_error().valid_up_to()
        ))
    })
}

/// What a path that is not a regular file is, for messages.
fn special_kind(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt as _;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

/// Refuses a working set of `bytes` (an estimate made before allocating) above
/// [`MAX_DENSE_BYTES`], naming `key`, what it is for and the estimate.
pub fn check_dense_bytes(key: &str, what: &str, bytes: f64) -> Result<()> {
    if bytes > MAX_DENSE_BYTES {
        return Err(key_error(
            key,
            format!(
                "implies {what} of about {:.1} GiB, above the limit of {:.0} GiB for dense \
                 matrices; reduce it (docs/limits.md)",
                bytes / GIB,
                MAX_DENSE_BYTES / GIB
            ),
        ));
    }
    Ok(())
}
